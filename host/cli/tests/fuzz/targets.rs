//! The readers under fuzzing, each with its seed inputs (the project's
//! fixtures and freshly simulated sessions) and the library call that reads
//! them in-process.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use robimu_model::urdf::{robot_from_urdf_file, UrdfOptions};
use robimu_model::Robot;
use robimu_protocol::{
    encode_to_vec, DeviceDecoder, DeviceMessage, HostDecoder, HostMessage, ImuSample, Pong, Status,
};
use robimu_session::import::cdr::{encode, ImuMsg, JointStateMsg, Stamp};
use robimu_session::import::csv::read_csv_pair;
use robimu_session::import::ros2::{read_ros2, Ros2Options, TimeSource};
use robimu_session::import::Streams;
use robimu_session::{
    CalibrationResult, PoseSession, PoseSessionMeta, PoseSessionWriter, Session, SessionMeta,
};
use robimu_workflows::check::{check_pose_session, check_session, CheckOptions};
use robimu_workflows::noise::NoiseFile;

/// One seed input: the files of a directory, some of which a mutation may
/// change.
#[derive(Debug, Clone)]
pub struct Seed {
    /// Where it came from.
    pub label: String,
    /// `(name, bytes)`, written into the input's directory.
    pub files: Vec<(String, Vec<u8>)>,
    /// Indices into `files` of those mutated.
    pub mutable: Vec<usize>,
}

/// A reader under fuzzing.
pub struct Target {
    /// Its name in the report.
    pub name: &'static str,
    /// Its seed inputs.
    pub seeds: Vec<Seed>,
    /// Whether the reader rewrites its input files (each input is then
    /// written afresh).
    pub rewrites: bool,
    /// The reader on the input directory: `Err` is a refusal with its
    /// message.
    pub read: fn(&Path) -> Result<(), String>,
    /// The `robimu` command that reads the same input (the process-level
    /// mode): its arguments for the input directory and a scratch
    /// directory; `None` for readers no command reads alone.
    pub command: Option<fn(&Path, &Path) -> Vec<String>>,
}

fn arg(p: &Path) -> String {
    p.display().to_string()
}

fn cli_fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The regular files of `dir` (sorted), those whose name `mutable` accepts
/// marked mutable.
fn dir_seed(label: &str, dir: &Path, mutable: impl Fn(&str) -> bool) -> Seed {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().into_string().ok())
        .collect();
    names.sort();
    let files: Vec<(String, Vec<u8>)> = names
        .into_iter()
        .map(|n| {
            let bytes = std::fs::read(dir.join(&n)).unwrap();
            (n, bytes)
        })
        .collect();
    let mutable = (0..files.len()).filter(|&i| mutable(&files[i].0)).collect();
    Seed {
        label: label.to_string(),
        files,
        mutable,
    }
}

/// One file as a seed, under the name `name`.
fn file_seed(label: &str, name: &str, bytes: Vec<u8>) -> Seed {
    Seed {
        label: label.to_string(),
        files: vec![(name.to_string(), bytes)],
        mutable: vec![0],
    }
}

/// Every file of `dir` ending in `ext` as a one-file seed named `name`.
fn file_seeds(dir: &Path, ext: &str, name: &str) -> Vec<Seed> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| Some(e.ok()?.path()))
        .filter(|p| p.to_string_lossy().ends_with(ext))
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            let label = p.file_name().unwrap().to_string_lossy();
            file_seed(&label, name, std::fs::read(p).unwrap())
        })
        .collect()
}

/// Simulated sessions made once per run by the `robimu` program (one IMU,
/// two IMUs, a TOML robot, a URDF robot), under the test's target dir.
fn simulated() -> &'static [(String, PathBuf)] {
    static SIMS: OnceLock<Vec<(String, PathBuf)>> = OnceLock::new();
    SIMS.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-seeds");
        let f = cli_fixtures();
        let runs: [(&str, Vec<String>); 4] = [
            ("sim-1imu", vec![]),
            ("sim-2imu", vec!["--imus".into(), "2".into()]),
            (
                "sim-toml",
                vec!["--robot".into(), f.join("ur5.toml").display().to_string()],
            ),
            (
                "sim-urdf",
                vec![
                    "--robot".into(),
                    f.join("aubo_i5.urdf").display().to_string(),
                ],
            ),
        ];
        runs.into_iter()
            .map(|(name, extra)| {
                let dir = root.join(name);
                if !dir.join("imu.csv").is_file() {
                    let _ = std::fs::remove_dir_all(&dir);
                    let out = std::process::Command::new(env!("CARGO_BIN_EXE_robimu"))
                        .args(["simulate", "--duration", "8", "--seed", "5", "--out"])
                        .arg(&dir)
                        .args(&extra)
                        .output()
                        .unwrap();
                    assert!(
                        out.status.success(),
                        "simulate {name}: {}",
                        String::from_utf8_lossy(&out.stderr)
                    );
                }
                (name.to_string(), dir)
            })
            .collect()
    })
}

/// A clean session with tool poses (docs/model.md §7.9), written once per
/// run by `PoseSessionWriter`: 10 s of a smooth motion, poses at 100 Hz,
/// IMU samples at 200 Hz.
fn pose_session() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-seeds/pose-session");
        let mut w = PoseSessionWriter::create(&dir, &PoseSessionMeta::default()).unwrap();
        for i in 0..1000 {
            let t = i as f64 * 0.01;
            let (s, c) = (0.5 * t).sin_cos();
            let (hs, hc) = (0.2 * t).sin_cos();
            w.pose(
                t,
                &[0.5 + 0.3 * c, 0.3 * s, 0.4],
                &[hc, 0.6 * hs, 0.0, 0.8 * hs],
            )
            .unwrap();
        }
        for i in 0..2000 {
            let t = i as f64 * 0.005;
            let z = [
                0.3 * (1.1 * t).sin(),
                0.2 * (0.9 * t).cos(),
                9.81 + 0.1 * (0.7 * t).sin(),
                0.4 * (0.5 * t).cos(),
                0.1 * (0.8 * t).sin(),
                0.32 + 0.05 * (0.6 * t).sin(),
            ];
            w.imu(t, &z).unwrap();
        }
        w.finish().unwrap()
    })
}

/// A pose session read, then checked: a fatal finding is a refusal.
fn read_pose_session(dir: &Path) -> Result<(), String> {
    let session = PoseSession::read(dir).map_err(|e| e.to_string())?;
    match check_pose_session(&session).fatal() {
        Some(f) => Err(f.message.clone()),
        None => Ok(()),
    }
}

/// The session files a mutation may change.
fn session_file(name: &str) -> bool {
    name.ends_with(".csv") || name.ends_with(".toml")
}

fn ros2_options() -> Ros2Options {
    Ros2Options {
        joints_topic: "/joint_states".into(),
        imu_topic: "/imu/data_raw".into(),
        time: TimeSource::Header,
        joint_names: None,
        names_required: false,
        poses: None,
    }
}

/// Every target, in report order.
pub fn all() -> Vec<Target> {
    let f = cli_fixtures();
    let bags = ["run_mcap", "run_db3", "run_split"];
    let bag_seeds = |mutable: fn(&str) -> bool| -> Vec<Seed> {
        bags.iter()
            .map(|b| dir_seed(b, &f.join("ros2").join(b), mutable))
            .filter(|s| !s.mutable.is_empty())
            .collect()
    };
    let mut sessions: Vec<Seed> = simulated()
        .iter()
        .map(|(name, dir)| dir_seed(name, dir, session_file))
        .collect();
    for d in ["realtime_demo", "ros2/source"] {
        sessions.push(dir_seed(d, &f.join(d), session_file));
    }
    let mut urdfs = file_seeds(&repo().join("tests/fixtures/makers"), ".urdf", "robot.urdf");
    urdfs.extend(file_seeds(&f, ".urdf", "robot.urdf"));
    for s in &mut urdfs {
        // the flange of the makers' descriptions (robimu_model's catalogue)
        if let Some((_, tip)) = URDF_TIPS.iter().find(|(p, _)| s.label.starts_with(p)) {
            s.files.push(("tip".into(), tip.as_bytes().to_vec()));
        }
    }
    let mut robots = file_seeds(&repo().join("host/model/robots"), ".toml", "robot.toml");
    robots.extend(file_seeds(&f, ".toml", "robot.toml"));
    vec![
        Target {
            name: "session (CSV, TOML)",
            seeds: sessions,
            command: Some(|d, _| vec!["check".into(), arg(d)]),
            rewrites: false,
            read: read_session,
        },
        Target {
            name: "pose session (CSV, TOML)",
            seeds: vec![dir_seed("pose-session", pose_session(), session_file)],
            command: Some(|d, _| vec!["check".into(), arg(d)]),
            rewrites: false,
            read: read_pose_session,
        },
        Target {
            name: "robot TOML",
            seeds: robots,
            command: Some(|d, o| {
                vec![
                    "simulate".into(),
                    "--robot".into(),
                    arg(&d.join("robot.toml")),
                    "--duration".into(),
                    "2".into(),
                    "--out".into(),
                    arg(o),
                ]
            }),
            rewrites: false,
            read: |d| {
                Robot::from_toml_file(d.join("robot.toml"))
                    .map(drop)
                    .map_err(|e| e.to_string())
            },
        },
        Target {
            name: "robot URDF",
            seeds: urdfs,
            command: Some(|d, o| {
                let mut a = vec![
                    "simulate".into(),
                    "--robot".into(),
                    arg(&d.join("robot.urdf")),
                ];
                if let Ok(tip) = std::fs::read_to_string(d.join("tip")) {
                    a.extend(["--tip".into(), tip]);
                }
                a.extend(["--duration".into(), "2".into(), "--out".into(), arg(o)]);
                a
            }),
            rewrites: false,
            read: |d| {
                let opts = UrdfOptions {
                    tip: std::fs::read_to_string(d.join("tip")).ok(),
                    ..UrdfOptions::default()
                };
                robot_from_urdf_file(d.join("robot.urdf"), &opts)
                    .map(drop)
                    .map_err(|e| e.to_string())
            },
        },
        Target {
            name: "result.json",
            seeds: file_seeds(&f.join("multi_imu"), ".json", "result.json"),
            command: Some(|d, o| {
                vec![
                    "report".into(),
                    arg(&d.join("result.json")),
                    "--out".into(),
                    arg(o),
                ]
            }),
            rewrites: false,
            read: |d| {
                CalibrationResult::read(&d.join("result.json"))
                    .map(drop)
                    .map_err(|e| e.to_string())
            },
        },
        Target {
            name: "noise TOML",
            seeds: vec![file_seed("noise", "noise.toml", NOISE_TOML.into())],
            command: None,
            rewrites: false,
            read: |d| {
                NoiseFile::read_with_shape(&d.join("noise.toml"))
                    .map(drop)
                    .map_err(|e| e.to_string())
            },
        },
        Target {
            name: "bag metadata.yaml",
            seeds: bag_seeds(|n| n == "metadata.yaml"),
            command: Some(import_ros2),
            rewrites: false,
            read: read_bag,
        },
        Target {
            name: "MCAP",
            seeds: bag_seeds(|n| n.ends_with(".mcap")),
            command: Some(import_ros2),
            rewrites: false,
            read: read_bag,
        },
        Target {
            name: "rosbag2 sqlite3",
            seeds: bag_seeds(|n| n.ends_with(".db3")),
            command: Some(import_ros2),
            rewrites: false,
            read: read_bag,
        },
        Target {
            name: "CDR",
            seeds: cdr_seeds(),
            command: None,
            rewrites: false,
            read: read_cdr,
        },
        Target {
            name: "EuRoC CSV",
            seeds: vec![euroc_seed()],
            command: Some(|d, o| {
                vec![
                    "import".into(),
                    "csv".into(),
                    arg(&d.join("imu.csv")),
                    "--joints".into(),
                    arg(&d.join("joints.csv")),
                    "--out".into(),
                    arg(o),
                ]
            }),
            rewrites: false,
            read: |d| {
                read_csv_pair(&d.join("imu.csv"), &d.join("joints.csv"))
                    .map_err(|e| e.to_string())
                    .and_then(|s| import_readable(s, d))
            },
        },
        Target {
            name: "pose CSV import",
            seeds: vec![pose_csv_seed()],
            command: Some(|d, o| {
                vec![
                    "import".into(),
                    "poses".into(),
                    arg(&d.join("poses.csv")),
                    "--imu".into(),
                    arg(&d.join("imu.csv")),
                    "--units".into(),
                    "mm".into(),
                    "--quat-order".into(),
                    "xyzw".into(),
                    "--quat-cols".into(),
                    "qx,qy,qz,qw".into(),
                    "--time-unit".into(),
                    "ns".into(),
                    "--out".into(),
                    arg(o),
                ]
            }),
            rewrites: false,
            read: read_pose_csv_import,
        },
        Target {
            name: "serial frames (COBS/postcard)",
            seeds: vec![serial_seed()],
            command: None,
            rewrites: false,
            read: read_serial,
        },
        Target {
            name: "repair (pings.csv, joints/imu.csv)",
            seeds: vec![recording_seed()],
            command: Some(|d, _| vec!["repair".into(), arg(d)]),
            rewrites: true,
            read: |d| {
                robimu_record::repair::repair(d)
                    .map(drop)
                    .map_err(|e| e.to_string())
            },
        },
    ]
}

/// `check`'s reading of a session: the reader, the robot it names, the
/// fatal stream tests, then the check itself (without the excitation
/// measure, a computation rather than a reading).
fn read_session(dir: &Path) -> Result<(), String> {
    Session::load(dir).map_err(|e| e.to_string())?;
    let (session, robot) =
        robimu_workflows::pipeline::load_session(dir).map_err(|e| format!("{e:#}"))?;
    session.noise_model(&robot).map_err(|e| e.to_string())?;
    let report = check_session(&session, &robot, &CheckOptions { excitation: false });
    match report.fatal() {
        Some(f) => Err(f.message.clone()),
        None => Ok(()),
    }
}

/// `import ros2` of the bag in `dir`: an accepted bag must make a session
/// that the session reader accepts (no silently invalid session).
/// `robimu import ros2 DIR --out OUT --joint-names …` (the fixtures name
/// UR's joints in an AUBO i5 session: taken in chain order).
fn import_ros2(dir: &Path, out: &Path) -> Vec<String> {
    vec![
        "import".into(),
        "ros2".into(),
        arg(dir),
        "--out".into(),
        arg(out),
        "--joint-names".into(),
        "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint"
            .into(),
    ]
}

fn read_bag(dir: &Path) -> Result<(), String> {
    let streams = read_ros2(dir, &ros2_options()).map_err(|e| e.to_string())?;
    import_readable(streams, dir)
}

/// Writes imported `streams` as a session next to `dir` and reads it back:
/// an import that succeeds must not write what the reader refuses.
fn import_readable(streams: Streams, dir: &Path) -> Result<(), String> {
    let out = dir.with_extension("imported");
    let meta = SessionMeta::parse(
        "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n",
        &out.join("session.toml"),
    )
    .unwrap();
    match streams.write_session(&out, &meta) {
        // refused while writing: a named error
        Err(e) => Err(e.to_string()),
        Ok(_) => Session::load(&out).map(drop).map_err(|e| {
            panic!("import accepted what the session reader refuses: {e}");
        }),
    }
}

fn read_cdr(dir: &Path) -> Result<(), String> {
    if let Ok(b) = std::fs::read(dir.join("joint_state.cdr")) {
        JointStateMsg::decode(&b).map_err(|e| e.to_string())?;
    }
    if let Ok(b) = std::fs::read(dir.join("imu.cdr")) {
        ImuMsg::decode(&b).map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn cdr_seeds() -> Vec<Seed> {
    let js = JointStateMsg {
        stamp: Stamp(1_700_000_000_123_456_789),
        frame_id: "base_link".into(),
        name: (1..=6).map(|i| format!("joint{i}")).collect(),
        position: vec![0.1, -0.2, 0.3, -0.4, 0.5, -0.6],
    };
    let imu = ImuMsg {
        stamp: Stamp(1_700_000_000_223_456_789),
        frame_id: "imu_link".into(),
        angular_velocity: [0.01, -0.02, 0.03],
        linear_acceleration: [0.1, 0.2, 9.81],
    };
    vec![
        file_seed("JointState", "joint_state.cdr", encode::joint_state(&js)),
        file_seed("Imu", "imu.cdr", encode::imu(&imu)),
    ]
}

/// The board's frames (`device.bin`) and the host's (`host.bin`), each fed
/// in chunks of 1 to 64 bytes to its decoder; every byte must be accounted
/// for.
fn read_serial(dir: &Path) -> Result<(), String> {
    let device = std::fs::read(dir.join("device.bin")).map_err(|e| e.to_string())?;
    let host = std::fs::read(dir.join("host.bin")).map_err(|e| e.to_string())?;
    let mut errors = 0usize;
    let mut d = DeviceDecoder::new();
    for chunk in chunks(&device) {
        errors += d.feed(chunk).filter(Result::is_err).count();
    }
    accounted(
        "device",
        d.stats().bytes_received,
        d.pending_len(),
        device.len(),
    );
    let mut h = HostDecoder::new();
    for chunk in chunks(&host) {
        errors += h.feed(chunk).filter(Result::is_err).count();
    }
    accounted(
        "host",
        h.stats().bytes_received,
        h.pending_len(),
        host.len(),
    );
    if errors > 0 {
        Err(format!("{errors} frames refused"))
    } else {
        Ok(())
    }
}

/// `bytes` in chunks of 1 to 64 bytes (each length from its first byte).
fn chunks(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut at = 0;
    std::iter::from_fn(move || {
        let first = *bytes.get(at)?;
        let len = (1 + first as usize % 64).min(bytes.len() - at);
        at += len;
        Some(&bytes[at - len..at])
    })
}

fn accounted(name: &str, received: u64, pending: usize, fed: usize) {
    assert_eq!(received, fed as u64, "{name} decoder: bytes counted");
    assert!(
        pending <= fed,
        "{name} decoder holds {pending} of {fed} bytes"
    );
}

fn serial_seed() -> Seed {
    let mut bytes = Vec::new();
    for seq in 0..20u32 {
        let m = DeviceMessage::Sample(ImuSample {
            sensor: (seq % 2) as u8,
            seq,
            t_us: 1000 * seq,
            accel_raw: [12, -40, 1000],
            gyro_raw: [3, -2, 1],
            temp_raw: 25,
        });
        bytes.extend(encode_to_vec(&m).unwrap());
    }
    bytes.extend(encode_to_vec(&DeviceMessage::Pong(Pong { nonce: 7, t_us: 9 })).unwrap());
    bytes.extend(encode_to_vec(&DeviceMessage::Status(Status::default())).unwrap());
    let mut host = Vec::new();
    for m in [
        HostMessage::Start,
        HostMessage::Ping { nonce: 3 },
        HostMessage::Stop,
    ] {
        host.extend(encode_to_vec(&m).unwrap());
    }
    Seed {
        label: "board frames".into(),
        files: vec![("device.bin".into(), bytes), ("host.bin".into(), host)],
        mutable: vec![0, 1],
    }
}

/// The flange link of the makers' URDFs whose chain has several leaves
/// (the others have one leaf).
const URDF_TIPS: [(&str, &str); 10] = [
    ("ur", "tool0"),
    ("axes_3r", "tool0"),
    ("fr3", "fr3_link8"),
    ("panda", "fer_link8"),
    ("iiwa14", "iiwa_link_ee_kuka"),
    ("iiwa7", "lbr_link_ee"),
    ("gen3", "end_effector_link"),
    ("xarm", "link_eef"),
    ("aubo_i3", "wrist3_Link"),
    ("aubo_i10", "wrist3_Link"),
];

const NOISE_TOML: &str = "[noise]\nsigma_z = [0.02, 0.02, 0.02, 0.002, 0.002, 0.002]\nsigma_q = [1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4]\nar_z = [[0.5], [0.5], [0.5], [], [], []]\n";

/// An EuRoC IMU file and a joints file on one nanosecond clock (10 s).
fn euroc_seed() -> Seed {
    let mut imu = String::from(
        "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n",
    );
    let mut joints = String::from("#timestamp [ns],q1,q2,q3,q4,q5,q6\n");
    let t0: i64 = 1_403_636_579_758_555_392;
    for k in 0..1000i64 {
        let t = k as f64 * 0.01;
        imu.push_str(&format!(
            "{},{:.6},{:.6},0.01,0.1,0.2,{:.6}\n",
            t0 + k * 10_000_000,
            0.1 * t.sin(),
            0.1 * t.cos(),
            9.81 + 0.01 * t.sin()
        ));
        if k % 2 == 0 {
            let q = 0.3 * (0.5 * t).sin();
            joints.push_str(&format!(
                "{},{q:.6},{:.6},{q:.6},{:.6},{q:.6},0\n",
                t0 + k * 10_000_000 + 3_000_000,
                -q,
                2.0 * q
            ));
        }
    }
    Seed {
        label: "EuRoC pair".into(),
        files: vec![
            ("imu.csv".into(), imu.into()),
            ("joints.csv".into(), joints.into()),
        ],
        mutable: vec![0, 1],
    }
}

/// A pose CSV in the units a controller writes (ns, mm, an xyzw
/// quaternion) beside an EuRoC IMU CSV on the same clock.
fn pose_csv_seed() -> Seed {
    let mut seed = euroc_seed();
    let mut poses = String::from("t,px,py,pz,qx,qy,qz,qw\n");
    let t0: i64 = 1_403_636_579_758_555_392;
    for k in 0..150i64 {
        let t = k as f64 / 15.0;
        let (s, c) = (0.5 * 0.3 * t).sin_cos();
        poses.push_str(&format!(
            "{},{:.3},{:.3},400.0,0,{s:.9},0,{c:.9}\n",
            t0 + k * 66_666_667,
            500.0 + 100.0 * t.cos(),
            100.0 * t.sin()
        ));
    }
    // an IMU whose every channel moves (a pose session's check refuses a
    // constant one): the body turns at 0.3 rad/s about y
    let mut imu = String::from(
        "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n",
    );
    for k in 0..1000i64 {
        let t = k as f64 * 0.01;
        let wiggle = |f: f64| 0.01 * (f * t).sin();
        imu.push_str(&format!(
            "{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}\n",
            t0 + k * 10_000_000,
            wiggle(37.0),
            0.3 + wiggle(23.0),
            wiggle(41.0),
            0.1 + wiggle(29.0),
            0.2 + wiggle(31.0),
            9.81 + wiggle(43.0)
        ));
    }
    seed.label = "pose CSV and EuRoC IMU".into();
    seed.files[0] = ("imu.csv".into(), imu.into());
    seed.files[1] = ("poses.csv".into(), poses.into());
    seed
}

/// `import poses` in-process: the reader with the seed's columns and
/// units, then the session written and read back (an accepted file must
/// make a session the reader accepts).
fn read_pose_csv_import(dir: &Path) -> Result<(), String> {
    use robimu_session::import::read_pose_csv_pair;
    use robimu_session::{Orientation, PoseCsvOptions, QuaternionOrder};
    let s = |v: &str| v.to_string();
    let opts = PoseCsvOptions {
        time_ns_per_unit: 1.0,
        metres_per_unit: 1e-3,
        orientation: Orientation::Quaternion {
            columns: [s("qx"), s("qy"), s("qz"), s("qw")],
            order: QuaternionOrder::Xyzw,
        },
        ..PoseCsvOptions::default()
    };
    let streams = read_pose_csv_pair(&dir.join("poses.csv"), &opts, &dir.join("imu.csv"))
        .map_err(|e| e.to_string())?;
    let out = dir.with_extension("imported");
    if let Err(e) = streams.write_pose_session(&out, &PoseSessionMeta::default()) {
        return Err(e.to_string());
    }
    if let Err(e) = PoseSession::read(&out) {
        panic!("import accepted what the pose-session reader refuses: {e}");
    }
    // the check's fatal findings are refusals, named
    read_pose_session(&out)
}

/// A recording as `robimu record` leaves it (a UR controller's clock
/// columns in joints.csv, the board's device times, segments and ping log),
/// its last IMU line cut.
fn recording_seed() -> Seed {
    let meta = "format = \"robimu-session/1\"\nrobot = \"ur5e\"\n";
    let mut joints = String::from("t,q1,q2,q3,q4,q5,q6,t_robot,t_arrival\n");
    let mut imu = String::from("t,ax,ay,az,gx,gy,gz,t_device,segment,seq\n");
    let mut pings = String::from("host_send,host_recv,device,segment\n");
    for k in 0..500 {
        let t = k as f64 * 0.008;
        let q = 0.2 * t.sin();
        joints.push_str(&format!(
            "{:.6},{q:.6},{q:.6},{q:.6},{q:.6},{q:.6},{q:.6},{:.6},{:.6}\n",
            t + 0.0004,
            1000.0 + t,
            t + 0.0004
        ));
    }
    for k in 0..800 {
        let t = k as f64 * 0.005;
        let segment = u32::from(k >= 400);
        imu.push_str(&format!(
            "{t:.6},0.1,0.2,9.81,0.01,0.02,0.03,{:.6},{segment},{k}\n",
            5.0 + t - 0.001
        ));
    }
    imu.push_str("4.0,0.1,0.2");
    for k in 0..40 {
        let t = k as f64 * 0.1;
        let segment = u32::from(t >= 2.0);
        pings.push_str(&format!(
            "{t:.6},{:.6},{:.6},{segment}\n",
            t + 0.002,
            5.0 + t
        ));
    }
    Seed {
        label: "UR recording".into(),
        files: vec![
            ("session.toml".into(), meta.into()),
            ("joints.csv".into(), joints.into()),
            ("imu.csv".into(), imu.into()),
            ("pings.csv".into(), pings.into()),
        ],
        mutable: vec![0, 1, 2, 3],
    }
}
