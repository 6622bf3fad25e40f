//! `robimu import`: a simulated session written as a ROS 2 MCAP recording
//! and as EuRoC CSV files imports to the same session, which calibrates to
//! the result of the original; bad recordings fail naming the cause.

use std::collections::BTreeMap;
use std::io::{BufWriter, Cursor};
use std::path::{Path, PathBuf};

use rand::SeedableRng;
use robimu_model::observations::Measurements;
use robimu_model::params::draw_truth;
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_session::import::cdr::{encode, ImuMsg, JointStateMsg, Stamp};
use robimu_session::Session;
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};
use robimu_workflows::simulate::{simulate, SimulateOptions};

mod common;
use common::{euroc_imu_csv, robimu, robimu_ok, s};

/// Source clock of the recordings: an epoch time, ns.
const BASE_NS: i64 = 1_700_000_000_123_456_789;
const JOINTS: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];

/// The bags above name UR's joints (the fixtures' independent writer did
/// too) but hold an AUBO i5 session: the default robot, whose joints are
/// named otherwise, takes them in chain order by `--joint-names`.
const AS_CHAIN: [&str; 2] = [
    "--joint-names",
    "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint",
];

fn ns(t: f64) -> i64 {
    BASE_NS + (t * 1e9).round() as i64
}

fn simulated(duration: f64) -> (Robot, Vec<f64>, Measurements) {
    simulated_on(Robot::aubo_i5(), duration)
}

fn simulated_on(robot: Robot, duration: f64) -> (Robot, Vec<f64>, Measurements) {
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(21);
    let truth = draw_truth(&layout, &mut rng);
    let traj = random_walk(&robot, duration, 1.0, &mut rng).unwrap();
    let mut sim = SimulateOptions::paper(&robot);
    sim.imu_rate = 100.0;
    sim.joint_rate = 125.0;
    sim.imu_start = 0.0037;
    let data = simulate(&robot, &layout, &truth, &traj, &sim, 4).unwrap();
    (robot, truth, data)
}

/// Options for the MCAP test file.
struct McapSpec<'a> {
    joint_topic: &'a str,
    joint_schema: &'a str,
    message_encoding: &'a str,
    /// The joints of each arm message, indices into [`JOINTS`] (a
    /// permutation, or fewer).
    order: &'a [usize],
    /// Further joints in each arm message (name, position), after the arm's.
    extra: &'a [(&'a str, f64)],
}

impl Default for McapSpec<'_> {
    fn default() -> Self {
        McapSpec {
            joint_topic: "/joint_states",
            joint_schema: "sensor_msgs/msg/JointState",
            message_encoding: "cdr",
            order: &[0, 1, 2, 3, 4, 5],
            extra: &[],
        }
    }
}

/// The data as a rosbag2-style MCAP file (uncompressed chunks), messages in
/// log-time order, log time 1 ms after the stamp; a gripper JointState on
/// the same topic every 50 joint samples (which the import skips).
fn write_mcap(path: &Path, data: &Measurements, spec: &McapSpec) {
    let file = BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(None)
        .create(file)
        .unwrap();
    let js = w
        .add_schema(spec.joint_schema, "ros2msg", b"std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n")
        .unwrap();
    let imu = w
        .add_schema(
            "sensor_msgs/msg/Imu",
            "ros2msg",
            b"# (definition omitted)\n",
        )
        .unwrap();
    let meta = BTreeMap::new();
    let jc = w
        .add_channel(js, spec.joint_topic, spec.message_encoding, &meta)
        .unwrap();
    let ic = w.add_channel(imu, "/imu/data_raw", "cdr", &meta).unwrap();
    let other = w.add_channel(imu, "/imu/other", "cdr", &meta).unwrap();
    // (stamp ns, channel, bytes)
    let mut msgs: Vec<(i64, u16, Vec<u8>)> = Vec::new();
    let n = data.joint_t.len();
    let width = data.joint_q.len() / n;
    for k in 0..n {
        let q = &data.joint_q[k * width..(k + 1) * width];
        let m = JointStateMsg {
            stamp: Stamp(ns(data.joint_t[k])),
            frame_id: String::new(),
            name: spec
                .order
                .iter()
                .map(|&j| JOINTS[j].to_string())
                .chain(spec.extra.iter().map(|e| e.0.to_string()))
                .collect(),
            position: spec
                .order
                .iter()
                .map(|&j| q[j])
                .chain(spec.extra.iter().map(|e| e.1))
                .collect(),
        };
        msgs.push((m.stamp.0, jc, encode::joint_state(&m)));
        if k % 50 == 0 {
            let g = JointStateMsg {
                stamp: m.stamp,
                frame_id: String::new(),
                name: vec!["gripper_finger".into()],
                position: vec![0.01],
            };
            msgs.push((m.stamp.0, jc, encode::joint_state(&g)));
        }
    }
    for (k, z) in data.imu_z.iter().enumerate() {
        let m = ImuMsg {
            stamp: Stamp(ns(data.imu_t[k])),
            frame_id: "imu_link".into(),
            angular_velocity: [z[3], z[4], z[5]],
            linear_acceleration: [z[0], z[1], z[2]],
        };
        msgs.push((m.stamp.0, ic, encode::imu(&m)));
        if k % 100 == 0 {
            msgs.push((m.stamp.0, other, encode::imu(&m)));
        }
    }
    msgs.sort_by_key(|m| m.0);
    for (seq, (stamp, channel, bytes)) in msgs.iter().enumerate() {
        let log = (*stamp + 1_000_000) as u64;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: *channel,
                sequence: seq as u32,
                log_time: log,
                publish_time: log,
            },
            bytes,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

/// The data as EuRoC `imu0/data.csv` (gyro first) and a joints CSV.
fn write_csv(dir: &Path, data: &Measurements) -> (PathBuf, PathBuf) {
    let imu = euroc_imu_csv(
        data.imu_t
            .iter()
            .zip(&data.imu_z)
            .map(|(t, z)| (ns(*t), *z)),
    );
    let mut joints = format!("#timestamp [ns],{}\n", JOINTS.join(","));
    let width = data.joint_q.len() / data.joint_t.len();
    for (k, t) in data.joint_t.iter().enumerate() {
        let q: Vec<String> = data.joint_q[k * width..(k + 1) * width]
            .iter()
            .map(|x| format!("{x:?}"))
            .collect();
        joints.push_str(&format!("{},{}\n", ns(*t), q.join(",")));
    }
    let (ip, jp) = (dir.join("imu0.csv"), dir.join("joints.csv"));
    std::fs::write(&ip, imu).unwrap();
    std::fs::write(&jp, joints).unwrap();
    (ip, jp)
}

#[test]
fn mcap_and_csv_imports_match_and_calibrate_like_the_original() {
    let (robot, truth, data) = simulated(40.0);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let bag = d.join("run.mcap");
    // Joint names in another order than the CSV's: the import reorders by
    // --joint-names.
    write_mcap(
        &bag,
        &data,
        &McapSpec {
            order: &[5, 4, 3, 2, 1, 0],
            ..McapSpec::default()
        },
    );
    let (imu_csv, joints_csv) = write_csv(d, &data);
    let (a, b) = (d.join("from_mcap"), d.join("from_csv"));
    let names = JOINTS.join(",");
    let text = robimu_ok(&[
        "import",
        "mcap",
        s(&bag),
        "--joints",
        "/joint_states",
        "--imu",
        "/imu/data_raw",
        "--joint-names",
        &names,
        "--out",
        s(&a),
    ])
    .text();
    assert!(
        text.contains(&format!("{} joint samples", data.joint_t.len())),
        "{text}"
    );
    robimu_ok(&[
        "import",
        "csv",
        s(&imu_csv),
        "--joints",
        s(&joints_csv),
        "--out",
        s(&b),
    ]);

    let sa = Session::load(&a).unwrap();
    let sb = Session::load(&b).unwrap();
    // Same samples, bit for bit (the gripper messages skipped).
    assert_eq!(sa.joints.t, sb.joints.t);
    assert_eq!(sa.joints.values, sb.joints.values);
    assert_eq!(sa.imu.t, sb.imu.t);
    assert_eq!(sa.imu.values, sb.imu.values);
    // Against the original: t = 0 is the first joint sample (t = 0 there),
    // times rounded to 1 ns, values exact, IMU columns in session order.
    let ma = sa.measurements();
    assert_eq!(ma.joint_q, data.joint_q);
    assert_eq!(ma.imu_z, data.imu_z);
    for (x, y) in ma.imu_t.iter().zip(&data.imu_t) {
        assert!((x - y).abs() < 1e-9, "{x} vs {y}");
    }

    // Calibrations of the imported and the original data agree to a
    // small fraction of their uncertainty.
    let opts = CalibrateOptions::new(&robot);
    let cal_a = calibrate(&robot, &ma, &opts, |_| {}).unwrap();
    let cal_o = calibrate(&robot, &data, &opts, |_| {}).unwrap();
    let layout = ParamLayout::new(&robot);
    let mut worst = 0.0_f64;
    let mut worst_truth = 0.0_f64;
    assert_eq!(truth.len(), layout.specs().len());
    for (k, x_true) in truth.iter().enumerate() {
        worst = worst.max((cal_a.x[k] - cal_o.x[k]).abs() / cal_o.sigma[k]);
        worst_truth = worst_truth.max((cal_a.x[k] - x_true).abs() / cal_a.sigma[k]);
    }
    eprintln!("imported vs original: worst |Δx|/σ = {worst:.2e}; vs truth {worst_truth:.2}");
    assert!(worst < 1e-3, "imported calibration differs by {worst} σ");
    assert!(
        worst_truth < 4.5,
        "imported calibration is {worst_truth} σ from the truth"
    );
}

/// The order in which the UR ROS 2 driver's joint_state_broadcaster
/// publishes the UR joints on /joint_states (the order of the state
/// interfaces in ros2_control's resource manager, not the chain's; reported
/// by its users, e.g. a `ros2 topic echo /joint_states` of a UR5e:
/// shoulder_lift, elbow, wrist 1–3, shoulder_pan).
const UR_DRIVER_ORDER: [usize; 6] = [1, 2, 3, 4, 5, 0];

/// Joint names decide the order: with a built-in robot (`ur5e`) or a URDF
/// robot, a bag listing UR's joints in the driver's order plus a gripper
/// joint imports to the same session as one in chain order, without
/// `--joint-names`; a missing joint is named in the error.
#[test]
fn ros2_joints_are_mapped_onto_the_chain_by_name() {
    let (_, _, data) = simulated_on(Robot::builtin("ur5e").unwrap(), 6.0);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (chain, driver, missing) = (
        d.join("chain.mcap"),
        d.join("driver.mcap"),
        d.join("missing.mcap"),
    );
    write_mcap(&chain, &data, &McapSpec::default());
    let gripper = [("robotiq_85_left_knuckle_joint", 0.37)];
    write_mcap(
        &driver,
        &data,
        &McapSpec {
            order: &UR_DRIVER_ORDER,
            extra: &gripper,
            ..McapSpec::default()
        },
    );
    write_mcap(
        &missing,
        &data,
        &McapSpec {
            order: &[1, 2, 3, 4, 0],
            extra: &gripper,
            ..McapSpec::default()
        },
    );
    let urdf = d.join("ur5e.urdf");
    robimu_ok(["robots", "show", "ur5e", "--urdf", s(&urdf)]);
    let import = |bag: &Path, robot: &str, out: &str| {
        let out = d.join(out);
        let run = robimu(["import", "ros2", s(bag), "--robot", robot, "--out", s(&out)]);
        (run, out)
    };
    let (run, a) = import(&chain, "ur5e", "chain");
    assert!(run.success(), "{}", run.text());
    for (robot, name) in [("ur5e", "driver"), (s(&urdf), "driver_urdf")] {
        let (run, b) = import(&driver, robot, name);
        assert!(run.success(), "{}", run.text());
        assert!(
            run.stdout.contains(&format!(
                "{} joint samples (joints {})",
                data.joint_t.len(),
                JOINTS.join(", ")
            )),
            "{}",
            run.stdout
        );
        let (sa, sb) = (Session::load(&a).unwrap(), Session::load(&b).unwrap());
        assert_eq!(sa.joints.t, sb.joints.t, "{name}");
        assert_eq!(sa.joints.values, sb.joints.values, "{name}");
        assert_eq!(sa.imu.t, sb.imu.t, "{name}");
        assert_eq!(sa.imu.values, sb.imu.values, "{name}");
        assert_eq!(sb.measurements().joint_q, data.joint_q, "{name}");
        robimu_ok(["check", s(&b)]);
    }
    let toml = std::fs::read_to_string(a.join("session.toml")).unwrap();
    assert!(toml.contains("robot = \"ur5e\""), "{toml}");
    // wrist_3_joint missing: named, with the joints the messages have.
    import(&missing, "ur5e", "missing").0.assert_fails(&[
        "robot `ur5e`'s joints",
        "lacks `wrist_3_joint`",
        "robotiq_85_left_knuckle_joint",
    ]);
    // Another robot's names (aubo_i5's, aubo_description's) are not the
    // UR driver's: named missing, with the joints the messages have.
    import(&driver, "aubo_i5", "aubo").0.assert_fails(&[
        "robot `aubo_i5`'s joints are picked by name",
        "lacks `shoulder_joint`",
        "its joints: shoulder_lift_joint",
        "--joint-names",
    ]);
}

#[test]
fn bad_recordings_fail_naming_the_cause() {
    let (_, _, data) = simulated(3.0);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out");
    let import = |bag: &Path, extra: &[&str]| {
        let mut args = vec!["import", "mcap", s(bag), "--out", s(&out)];
        if !extra.contains(&"--joint-names") {
            args.extend(AS_CHAIN);
        }
        args.extend_from_slice(extra);
        robimu(&args)
    };
    let bag = d.join("ok.mcap");
    write_mcap(&bag, &data, &McapSpec::default());
    // The defaults fit this file.
    let run = import(&bag, &[]);
    assert!(run.success(), "{}", run.text());
    // A missing topic: the topics there are are listed.
    import(&bag, &["--imu", "/imu/missing"]).assert_fails(&[
        "no topic /imu/missing",
        "/imu/data_raw [sensor_msgs/msg/Imu",
    ]);
    // A topic of another type.
    import(&bag, &["--joints", "/imu/other"])
        .assert_fails(&["carries sensor_msgs/msg/Imu, expected sensor_msgs/msg/JointState"]);
    // Another message encoding.
    let bad = d.join("json.mcap");
    write_mcap(
        &bad,
        &data,
        &McapSpec {
            message_encoding: "json",
            ..McapSpec::default()
        },
    );
    import(&bad, &[]).assert_fails(&["message encoding is \"json\""]);
    // Truncated: half the file.
    let bytes = std::fs::read(&bag).unwrap();
    let cut = d.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    import(&cut, &[]).assert_fails(&["not a readable MCAP file", "truncated"]);
    // Not MCAP at all.
    let junk = d.join("junk.mcap");
    std::fs::write(&junk, b"#timestamp,a,b\n1,2,3\n").unwrap();
    import(&junk, &[]).assert_fails(&["not a readable MCAP file"]);
    // A joint name not in the messages.
    import(&bag, &["--joint-names", "a,b,c,d,e,f"])
        .assert_fails(&["no message on /joint_states has all of the joints"]);
    // Five joints for a six-joint robot.
    let five = JOINTS[..5].join(",");
    import(&bag, &["--joint-names", &five]).assert_fails(&["5 joints imported", "has 6"]);
    // A message cut short inside an otherwise valid file.
    let mut w = mcap::Writer::new(Cursor::new(Vec::new())).unwrap();
    let sc = w.add_schema("sensor_msgs/msg/Imu", "ros2msg", b"").unwrap();
    let ch = w
        .add_channel(sc, "/imu/data_raw", "cdr", &BTreeMap::new())
        .unwrap();
    let jsc = w
        .add_schema("sensor_msgs/msg/JointState", "ros2msg", b"")
        .unwrap();
    let jch = w
        .add_channel(jsc, "/joint_states", "cdr", &BTreeMap::new())
        .unwrap();
    let header = |channel_id| mcap::records::MessageHeader {
        channel_id,
        sequence: 0,
        log_time: 5,
        publish_time: 5,
    };
    let js = encode::joint_state(&JointStateMsg {
        stamp: Stamp(5),
        frame_id: String::new(),
        name: JOINTS.map(String::from).to_vec(),
        position: vec![0.0; 6],
    });
    w.write_to_known_channel(&header(jch), &js).unwrap();
    let imu = encode::imu(&ImuMsg {
        stamp: Stamp(5),
        frame_id: String::new(),
        angular_velocity: [0.0; 3],
        linear_acceleration: [0.0; 3],
    });
    w.write_to_known_channel(&header(ch), &imu[..100]).unwrap();
    w.finish().unwrap();
    let short = d.join("short.mcap");
    std::fs::write(&short, w.into_inner().into_inner()).unwrap();
    import(&short, &[]).assert_fails(&["topic /imu/data_raw, message 0", "truncated"]);
    // CSV: a joints file with a bad line.
    let (imu_csv, joints_csv) = write_csv(d, &data);
    let mut text = std::fs::read_to_string(&joints_csv).unwrap();
    text.push_str("1,2,3\n");
    std::fs::write(&joints_csv, text).unwrap();
    robimu(&[
        "import",
        "csv",
        s(&imu_csv),
        "--joints",
        s(&joints_csv),
        "--out",
        s(&out),
    ])
    .assert_fails(&["joints.csv:", "3 fields"]);
}

// ---------------------------------------------------------------------------
// rosbag2 bags written by an independent writer (the Python `rosbags`
// package, scripts/make_ros2_bags.py) from the session in
// fixtures/ros2/source.

fn ros2_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/ros2")
        .join(name)
}

/// The imported session has the source's samples: values bit for bit, times
/// to the 1 ns of the bag's stamps.
fn assert_same_samples(imported: &Session, source: &Session, what: &str) {
    for (a, b) in [
        (&imported.joints, &source.joints),
        (&imported.imu, &source.imu),
    ] {
        assert_eq!(a.values, b.values, "{what}");
        assert_eq!(a.t.len(), b.t.len(), "{what}");
        for (x, y) in a.t.iter().zip(&b.t) {
            assert!((x - y).abs() <= 1e-9, "{what}: t {x} vs {y}");
        }
    }
}

#[test]
fn rosbags_bags_import_and_calibrate_like_the_source() {
    let robot = Robot::aubo_i5();
    let source = Session::load(&ros2_fixture("source")).unwrap();
    let opts = CalibrateOptions::new(&robot);
    let cal_src = calibrate(&robot, &source.measurements(), &opts, |_| {}).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // The directories (MCAP, sqlite3, split MCAP) and their single files;
    // `mcap` is an alias of `ros2`.
    let bags = [
        ("ros2", "run_mcap"),
        ("ros2", "run_db3"),
        ("ros2", "run_split"),
        ("mcap", "run_mcap/run_mcap.mcap"),
        ("ros2", "run_db3/run_db3.db3"),
    ];
    for (k, (cmd, bag)) in bags.iter().enumerate() {
        let out = dir.path().join(format!("s{k}"));
        let text = robimu_ok(&[
            "import",
            cmd,
            s(&ros2_fixture(bag)),
            "--out",
            s(&out),
            AS_CHAIN[0],
            AS_CHAIN[1],
        ])
        .text();
        assert!(
            text.contains("81 joint samples (joints shoulder_pan_joint,")
                && text.contains("161 IMU samples"),
            "{bag}: {text}"
        );
        let imported = Session::load(&out).unwrap();
        assert_same_samples(&imported, &source, bag);
        let cal = calibrate(&robot, &imported.measurements(), &opts, |_| {}).unwrap();
        let worst = (0..cal.x.len())
            .map(|i| (cal.x[i] - cal_src.x[i]).abs() / cal_src.sigma[i])
            .fold(0.0_f64, f64::max);
        eprintln!("{bag}: worst |Δx|/σ against the source = {worst:.1e}");
        assert!(worst <= 1e-6, "{bag}: calibration differs by {worst} σ");
    }
}

#[test]
fn split_bag_files_are_read_as_the_metadata_lists_them() {
    let source = Session::load(&ros2_fixture("source")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    for f in ["run_split_0.mcap", "run_split_1.mcap"] {
        std::fs::copy(ros2_fixture("run_split").join(f), bag.join(f)).unwrap();
    }
    let meta = std::fs::read_to_string(ros2_fixture("run_split/metadata.yaml")).unwrap();
    let out = dir.path().join("out");
    let import = || {
        robimu(&[
            "import",
            "ros2",
            s(&bag),
            "--out",
            s(&out),
            AS_CHAIN[0],
            AS_CHAIN[1],
        ])
    };
    // Only the first file listed: the first half of the session.
    let first_only = meta.replace("  - run_split_1.mcap\n", "");
    assert_ne!(first_only, meta);
    std::fs::write(bag.join("metadata.yaml"), &first_only).unwrap();
    assert!(import().success());
    let half = Session::load(&out).unwrap();
    let n = half.imu.t.len();
    assert!(n > 60 && n < 100, "{n} of 161 IMU samples");
    assert_eq!(
        half.imu.values[..],
        source.imu.values[..half.imu.values.len()]
    );
    // Both files: the whole session, in order.
    std::fs::write(bag.join("metadata.yaml"), &meta).unwrap();
    assert!(import().success());
    assert_same_samples(&Session::load(&out).unwrap(), &source, "split");
    // A listed file that is missing is named.
    std::fs::remove_file(bag.join("run_split_1.mcap")).unwrap();
    import().assert_fails(&["lists run_split_1.mcap, which is not in"]);
    // Without metadata.yaml (a killed recording): the files by their index.
    std::fs::copy(
        ros2_fixture("run_split/run_split_1.mcap"),
        bag.join("run_split_1.mcap"),
    )
    .unwrap();
    std::fs::remove_file(bag.join("metadata.yaml")).unwrap();
    assert!(import().success());
    assert_same_samples(&Session::load(&out).unwrap(), &source, "no metadata");
}

#[test]
fn bad_bags_fail_naming_the_cause() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let import = |bag: &Path, extra: &[&str]| {
        let mut args = vec!["import", "ros2", s(bag), "--out", s(&out)];
        args.extend(AS_CHAIN);
        args.extend_from_slice(extra);
        robimu(&args)
    };
    // A topic the bag lacks: its topics with their types and counts, from
    // metadata.yaml (directories) or the storage (files).
    let listing = [
        "/imu/data_raw [sensor_msgs/msg/Imu, 161 messages]",
        "/joint_states [sensor_msgs/msg/JointState, 85 messages]",
        "/status [std_msgs/msg/String, 5 messages]",
    ];
    for bag in ["run_mcap", "run_db3", "run_db3/run_db3.db3", "run_split"] {
        let mut want = vec!["no topic /imu/missing (sensor_msgs/msg/Imu)"];
        want.extend_from_slice(&listing);
        import(&ros2_fixture(bag), &["--imu", "/imu/missing"]).assert_fails(&want);
    }
    import(&ros2_fixture("run_db3"), &["--joints", "/status"]).assert_fails(&[
        "topic /status: carries std_msgs/msg/String, expected sensor_msgs/msg/JointState",
    ]);
    // Broken metadata.yaml, an unknown storage, a file that is no bag.
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        "rosbag2_bagfile_information: [1, 2]\n",
    )
    .unwrap();
    import(&bag, &[]).assert_fails(&["metadata.yaml: not rosbag2 metadata"]);
    let meta = std::fs::read_to_string(ros2_fixture("run_mcap/metadata.yaml")).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        meta.replace("storage_identifier: mcap", "storage_identifier: cdr_json"),
    )
    .unwrap();
    import(&bag, &[]).assert_fails(&[
        "storage_identifier \"cdr_json\": robimu reads the storages mcap and sqlite3",
    ]);
    let junk = dir.path().join("junk.db3");
    std::fs::write(&junk, b"not a database at all").unwrap();
    import(&junk, &[]).assert_fails(&["neither MCAP nor sqlite3"]);
    // A sqlite3 file cut short.
    let db = std::fs::read(ros2_fixture("run_db3/run_db3.db3")).unwrap();
    let cut = dir.path().join("cut.db3");
    std::fs::write(&cut, &db[..db.len() / 3]).unwrap();
    import(&cut, &[]).assert_fails(&["cut.db3: not a readable rosbag2 sqlite3 file"]);
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    import(&empty, &[]).assert_fails(&["no metadata.yaml and no .mcap or .db3 file"]);
}

/// Compressed bags (rosbags' per-file zstd of a sqlite3 bag and per-message
/// zstd of an MCAP bag): refused naming the feature in a build without it.
#[cfg(not(feature = "mcap-compression"))]
#[test]
fn compressed_bags_without_the_feature_name_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for (bag, per) in [
        ("run_zstd_file", "per file"),
        ("run_zstd_message", "per message"),
        ("run_zstd_file/run_zstd_file.db3.zstd", "per file"),
    ] {
        robimu(&["import", "ros2", s(&ros2_fixture(bag)), "--out", s(&out)]).assert_fails(&[
            &format!("zstd-compressed ({per})"),
            "built without the `mcap-compression` feature",
            "--features mcap-compression",
        ]);
    }
}

/// With the feature, the compressed bags import to the source session.
#[cfg(feature = "mcap-compression")]
#[test]
fn compressed_bags_import_like_the_source() {
    let source = Session::load(&ros2_fixture("source")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for bag in [
        "run_zstd_file",
        "run_zstd_message",
        "run_zstd_file/run_zstd_file.db3.zstd",
    ] {
        robimu_ok(&[
            "import",
            "ros2",
            s(&ros2_fixture(bag)),
            "--out",
            s(&out),
            AS_CHAIN[0],
            AS_CHAIN[1],
        ]);
        assert_same_samples(&Session::load(&out).unwrap(), &source, bag);
    }
}

// ---------------------------------------------------------------------------
// Damaged and hostile recordings (issue 41): each is refused naming the
// cause, never a panic, a hang or a silently wrong session.

/// An IMU message: `stamp` ns, `[ax, ay, az, gx, gy, gz]`.
fn imu_msg(stamp: i64, z: [f64; 6]) -> Vec<u8> {
    encode::imu(&ImuMsg {
        stamp: Stamp(stamp),
        frame_id: String::new(),
        angular_velocity: [z[3], z[4], z[5]],
        linear_acceleration: [z[0], z[1], z[2]],
    })
}

/// A small MCAP recording: five unnamed 6-joint messages every 10 ms from
/// [`BASE_NS`] on a topic of type `joint_type`, and the IMU messages `imu`
/// (CDR bytes) every 5 ms from [`BASE_NS`] (log times).
fn small_mcap(path: &Path, joint_type: &str, imu: &[Vec<u8>]) {
    let mut w = mcap::Writer::new(Cursor::new(Vec::new())).unwrap();
    let meta = BTreeMap::new();
    let isc = w.add_schema(IMU_TYPE, "ros2msg", b"").unwrap();
    let ich = w.add_channel(isc, "/imu/data_raw", "cdr", &meta).unwrap();
    let jsc = w.add_schema(joint_type, "ros2msg", b"").unwrap();
    let jch = w.add_channel(jsc, "/joint_states", "cdr", &meta).unwrap();
    let header = |channel_id, t: i64| mcap::records::MessageHeader {
        channel_id,
        sequence: 0,
        log_time: t as u64,
        publish_time: t as u64,
    };
    for k in 0..5 {
        let t = BASE_NS + k * 10_000_000;
        let js = encode::joint_state(&JointStateMsg {
            stamp: Stamp(t),
            frame_id: String::new(),
            name: JOINTS.map(String::from).to_vec(),
            position: vec![0.1 * k as f64; 6],
        });
        w.write_to_known_channel(&header(jch, t), &js).unwrap();
    }
    for (k, bytes) in imu.iter().enumerate() {
        let t = BASE_NS + k as i64 * 5_000_000;
        w.write_to_known_channel(&header(ich, t), bytes).unwrap();
    }
    w.finish().unwrap();
    std::fs::write(path, w.into_inner().into_inner()).unwrap();
}

const IMU_TYPE: &str = "sensor_msgs/msg/Imu";

/// Good IMU messages every 5 ms from [`BASE_NS`], `n` of them.
fn good_imu(n: i64) -> Vec<Vec<u8>> {
    (0..n)
        .map(|k| imu_msg(BASE_NS + k * 5_000_000, [0.0, 0.0, 9.81, 0.0, 0.0, 0.0]))
        .collect()
}

/// Top-level MCAP records of `bytes`: (offset, opcode, length).
fn mcap_records(bytes: &[u8]) -> Vec<(usize, u8, u64)> {
    let mut out = Vec::new();
    let mut o = 8;
    while o + 9 <= bytes.len() - 8 {
        let len = u64::from_le_bytes(bytes[o + 1..o + 9].try_into().unwrap());
        out.push((o, bytes[o], len));
        o += 9 + len as usize;
    }
    out
}

#[test]
fn damaged_mcap_records_are_refused_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out");
    let import = |bag: &Path| {
        robimu([
            "import",
            "ros2",
            s(bag),
            "--out",
            s(&out),
            AS_CHAIN[0],
            AS_CHAIN[1],
        ])
    };
    let good = d.join("good.mcap");
    small_mcap(&good, "sensor_msgs/msg/JointState", &good_imu(9));
    assert!(import(&good).success(), "{}", import(&good).text());
    let bytes = std::fs::read(&good).unwrap();
    let records = mcap_records(&bytes);
    // A top-level record (the header, after the magic) of length 2^64 - 1.
    let mut top = bytes.clone();
    top[9..17].copy_from_slice(&u64::MAX.to_le_bytes());
    let f = d.join("top.mcap");
    std::fs::write(&f, &top).unwrap();
    import(&f).assert_fails(&["top.mcap: not a readable MCAP file", "length exceeds limit"]);
    // A record inside a chunk of length 2^64 - 1.
    let &(chunk, _, _) = records.iter().find(|r| r.1 == 0x06).expect("a chunk");
    let body = chunk + 9;
    let clen = u32::from_le_bytes(bytes[body + 28..body + 32].try_into().unwrap()) as usize;
    let first = body + 32 + clen + 8;
    let mut inner = bytes.clone();
    inner[first + 1..first + 9].copy_from_slice(&u64::MAX.to_le_bytes());
    let f = d.join("inner.mcap");
    std::fs::write(&f, &inner).unwrap();
    // (refused before the mcap crate reads it: a length within the file but
    // beyond the chunk underflowed the crate's count, the fuzz harness found)
    import(&f).assert_fails(&[
        "inner.mcap: not a readable MCAP file",
        "a record in the chunk at byte",
        "claims 18446744073709551615 bytes where the chunk has",
    ]);
    // A chunk whose opcode is corrupted: refused, not skipped with its
    // messages (here the second file of a split bag).
    let bag = d.join("bag");
    std::fs::create_dir(&bag).unwrap();
    for f in ["metadata.yaml", "run_split_0.mcap", "run_split_1.mcap"] {
        std::fs::copy(ros2_fixture("run_split").join(f), bag.join(f)).unwrap();
    }
    let second = bag.join("run_split_1.mcap");
    let mut split = std::fs::read(&second).unwrap();
    let &(chunk, _, _) = mcap_records(&split)
        .iter()
        .find(|r| r.1 == 0x06)
        .expect("a chunk");
    for opcode in [0x46, 0xc6] {
        split[chunk] = opcode;
        std::fs::write(&second, &split).unwrap();
        import(&bag).assert_fails(&[
            "run_split_1.mcap: not a readable MCAP file",
            &format!("unknown opcode 0x{opcode:02x}"),
        ]);
    }
}

#[test]
fn implausible_samples_and_bag_listings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out");
    let import = |bag: &Path, extra: &[&str]| {
        let mut args = vec!["import", "ros2", s(bag), "--out", s(&out)];
        args.extend(AS_CHAIN);
        args.extend_from_slice(extra);
        robimu(&args)
    };
    let with_imu = |name: &str, k: usize, bytes: Vec<u8>| {
        let mut imu = good_imu(9);
        imu[k] = bytes;
        let f = d.join(name);
        small_mcap(&f, "sensor_msgs/msg/JointState", &imu);
        f
    };
    // NaN and infinite values.
    let t4 = BASE_NS + 20_000_000;
    let f = with_imu(
        "nan.mcap",
        4,
        imu_msg(t4, [0.0, f64::NAN, 9.81, 0.0, 0.0, 0.0]),
    );
    import(&f, &[]).assert_fails(&["topic /imu/data_raw, message 4", "value 1 is NaN"]);
    let f = with_imu(
        "inf.mcap",
        4,
        imu_msg(t4, [0.0, 0.0, 9.81, 0.0, 0.0, f64::NEG_INFINITY]),
    );
    import(&f, &[]).assert_fails(&["message 4", "value 5 is -inf"]);
    // A zeroed stamp, one going back, one in a far future.
    let f = with_imu("zero.mcap", 4, imu_msg(0, [0.0; 6]));
    import(&f, &[]).assert_fails(&["message 4", "time 0 ns: a zeroed or unset stamp"]);
    let f = with_imu("back.mcap", 4, imu_msg(BASE_NS - 5_000_000_000, [0.0; 6]));
    import(&f, &[]).assert_fails(&["message 4", "before the topic's previous message"]);
    let f = with_imu(
        "far.mcap",
        4,
        imu_msg(BASE_NS + 100 * 86_400_000_000_000, [0.0; 6]),
    );
    import(&f, &[]).assert_fails(&["message 4", "more than the 24 h a recording may"]);
    // header.stamp.nanosec of 10^9 or more (bytes 8..12 of the CDR message).
    let mut bytes = imu_msg(t4, [0.0; 6]);
    bytes[8..12].copy_from_slice(&1_500_000_000u32.to_le_bytes());
    let f = with_imu("nanosec.mcap", 4, bytes);
    import(&f, &[]).assert_fails(&["message 4", "header.stamp.nanosec is 1500000000"]);
    // A joint named twice.
    let good = with_imu("good.mcap", 4, imu_msg(t4, [0.0, 0.0, 9.81, 0.0, 0.0, 0.0]));
    assert!(import(&good, &[]).success());
    import(&good, &["--joint-names", "a,b,c,a,e,f"]).assert_fails(&["joint `a` is named twice"]);
    // A split bag whose second file carries another type on the joint topic.
    let split = d.join("split");
    std::fs::create_dir(&split).unwrap();
    std::fs::copy(&good, split.join("run_0.mcap")).unwrap();
    small_mcap(
        &split.join("run_1.mcap"),
        "std_msgs/msg/String",
        &good_imu(9),
    );
    import(&split, &[])
        .assert_fails(&["run_1.mcap: topic /joint_states: carries std_msgs/msg/String"]);
    // A storage file listed twice in metadata.yaml.
    let bag = d.join("bag");
    std::fs::create_dir(&bag).unwrap();
    for f in ["metadata.yaml", "run_split_0.mcap", "run_split_1.mcap"] {
        std::fs::copy(ros2_fixture("run_split").join(f), bag.join(f)).unwrap();
    }
    let meta = std::fs::read_to_string(bag.join("metadata.yaml")).unwrap();
    let twice = meta.replace(
        "  - run_split_1.mcap\n",
        "  - run_split_1.mcap\n  - run_split_1.mcap\n",
    );
    assert_ne!(twice, meta);
    std::fs::write(bag.join("metadata.yaml"), twice).unwrap();
    import(&bag, &[]).assert_fails(&["relative_file_paths lists run_split_1.mcap twice"]);
    // metadata.yaml nested 100 000 levels deep: refused at once.
    let deep = format!("rosbag2_bagfile_information: {}\n", "[".repeat(100_000));
    std::fs::write(bag.join("metadata.yaml"), deep).unwrap();
    let start = std::time::Instant::now();
    import(&bag, &[]).assert_fails(&["metadata.yaml: line 1: nested more than 64 levels deep"]);
    assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
}
