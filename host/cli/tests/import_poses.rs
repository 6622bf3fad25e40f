//! `robimu import poses` and `robimu import ros2 --poses` (issue 39 item 4,
//! docs/model.md §7.9): a simulated pose session written by the test as a
//! pose CSV (mm, x-y-z-w quaternions, ms) with an EuRoC IMU CSV, and as
//! ROS 2 MCAP recordings (PoseStamped, TransformStamped, /tf with two
//! frames) imports back to the simulated session's samples; bad input fails
//! naming the cause.

mod common;

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use common::{euroc_imu_csv, robimu, robimu_ok, s};
use nalgebra::{Quaternion, UnitQuaternion};
use robimu_session::import::cdr::{encode, ImuMsg, PoseMsg, Stamp};
use robimu_session::PoseSession;

/// Source clock of the recordings, ns: an epoch time for the bags; the
/// CSV files' times are 5 s after their clock's zero (ms in the pose file
/// keep ns resolution there).
const BAG_BASE_NS: i64 = 1_700_000_000_123_456_789;
const CSV_BASE_NS: i64 = 5_000_000_000;

/// Positions agree to 1e-12 m, quaternions (up to sign) to 1e-12 (1e-9
/// through Euler angles in degrees), times to 1.5 ns; IMU samples are
/// bit-exact.
const POSITION_TOL: f64 = 1e-12;
const QUATERNION_TOL: f64 = 1e-12;
const EULER_QUATERNION_TOL: f64 = 1e-9;
const TIME_TOL: f64 = 1.5e-9;

fn simulated(dir: &Path) -> PoseSession {
    robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--duration",
        "8",
        "--seed",
        "11",
        "--out",
        s(dir),
    ]);
    PoseSession::read(dir).unwrap()
}

/// The session's earliest sample time, s (the import's t = 0).
fn t_first(sim: &PoseSession) -> f64 {
    sim.poses.t[0].min(sim.imus[0].samples.t[0])
}

fn ns(base: i64, sim: &PoseSession, t: f64) -> i64 {
    base + ((t - t_first(sim)) * 1e9).round() as i64
}

/// |a − b| up to the quaternion's sign.
fn quaternion_distance(a: [f64; 4], b: [f64; 4]) -> f64 {
    let d = |sign: f64| {
        (0..4)
            .map(|i| (a[i] - sign * b[i]).abs())
            .fold(0.0, f64::max)
    };
    d(1.0).min(d(-1.0))
}

/// The imported session `got` has the simulated session's samples, times
/// shifted so that the earliest is 0.
fn assert_same_session(got: &PoseSession, sim: &PoseSession, what: &str) {
    assert_same_session_to(got, sim, what, QUATERNION_TOL);
}

/// [`assert_same_session`] with quaternions to `quat_tol`.
fn assert_same_session_to(got: &PoseSession, sim: &PoseSession, what: &str, quat_tol: f64) {
    let t0 = t_first(sim);
    assert_eq!(got.poses.len(), sim.poses.len(), "{what}: pose count");
    let (gp, sp) = (got.positions(), sim.positions());
    let (gq, sq) = (got.quaternions(), sim.quaternions());
    for k in 0..sim.poses.len() {
        let dt = (got.poses.t[k] - (sim.poses.t[k] - t0)).abs();
        assert!(dt < TIME_TOL, "{what}: pose {k} time off by {dt} s");
        let dp = (0..3)
            .map(|i| (gp[k][i] - sp[k][i]).abs())
            .fold(0.0, f64::max);
        assert!(dp < POSITION_TOL, "{what}: pose {k} position off by {dp} m");
        let dq = quaternion_distance(gq[k], sq[k]);
        assert!(dq < quat_tol, "{what}: pose {k} quaternion off by {dq}");
    }
    let (gi, si) = (&got.imus[0].samples, &sim.imus[0].samples);
    assert_eq!(gi.len(), si.len(), "{what}: IMU sample count");
    assert_eq!(gi.values, si.values, "{what}: IMU samples");
    for k in 0..si.len() {
        let dt = (gi.t[k] - (si.t[k] - t0)).abs();
        assert!(dt < TIME_TOL, "{what}: IMU sample {k} time off by {dt} s");
    }
    assert!(got
        .meta
        .notes
        .as_deref()
        .unwrap_or("")
        .contains("imported from"));
}

/// `sim`'s IMU as an EuRoC imu0/data.csv (ns, gyroscope first).
fn write_euroc_imu(path: &Path, sim: &PoseSession) {
    let imu = &sim.imus[0].samples;
    let rows = (0..imu.len()).map(|k| {
        let z: [f64; 6] = imu.row(k).try_into().unwrap();
        (ns(CSV_BASE_NS, sim, imu.t[k]), z)
    });
    std::fs::write(path, euroc_imu_csv(rows)).unwrap();
}

/// `sim`'s poses as a controller might log them: ms, mm, quaternion
/// x, y, z, w, extra columns, a header of its own names.
fn write_pose_csv(path: &Path, sim: &PoseSession, mutate: impl Fn(usize, &mut Vec<String>)) {
    let mut text = String::from("stamp_ms,status,X,Y,Z,q_x,q_y,q_z,q_w\n");
    let (p, q) = (sim.positions(), sim.quaternions());
    for k in 0..sim.poses.len() {
        let t_ms = ns(CSV_BASE_NS, sim, sim.poses.t[k]) as f64 * 1e-6;
        let mut row: Vec<String> = [t_ms, 1.0]
            .into_iter()
            .chain(p[k].iter().map(|v| v * 1e3))
            .chain([q[k][1], q[k][2], q[k][3], q[k][0]])
            .map(|v| format!("{v:?}"))
            .collect();
        mutate(k, &mut row);
        text.push_str(&row.join(","));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

/// The flags that describe [`write_pose_csv`]'s file.
const CSV_FLAGS: [&str; 12] = [
    "--time-col",
    "stamp_ms",
    "--time-unit",
    "ms",
    "--position-cols",
    "X,Y,Z",
    "--units",
    "mm",
    "--quat-order",
    "xyzw",
    "--quat-cols",
    "q_x,q_y,q_z,q_w",
];

#[test]
fn a_pose_csv_in_mm_with_xyzw_quaternions_imports_to_the_simulated_session() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let sim = simulated(&d.join("sim"));
    let (poses, imu, out) = (d.join("tcp.csv"), d.join("imu0.csv"), d.join("imported"));
    write_pose_csv(&poses, &sim, |_, _| {});
    write_euroc_imu(&imu, &sim);
    let mut args = vec![
        "import",
        "poses",
        s(&poses),
        "--imu",
        s(&imu),
        "--out",
        s(&out),
    ];
    args.extend_from_slice(&CSV_FLAGS);
    let run = robimu_ok(&args);
    assert!(
        run.stdout
            .contains(&format!("{} pose samples", sim.poses.len())),
        "{}",
        run.stdout
    );
    let got = PoseSession::read(&out).unwrap();
    assert_same_session(&got, &sim, "pose CSV");
    robimu_ok(["check", s(&out)]);
    // the same poses as roll, pitch, yaw in degrees (nalgebra's Euler
    // angles: R = Rz(yaw)·Ry(pitch)·Rx(roll)), times in s, metres
    let euler = d.join("euler.csv");
    let mut text = String::from("time,x,y,z,roll,pitch,yaw\n");
    let (p, q) = (sim.positions(), sim.quaternions());
    for k in 0..sim.poses.len() {
        let uq =
            UnitQuaternion::from_quaternion(Quaternion::new(q[k][0], q[k][1], q[k][2], q[k][3]));
        let (r, pi, y) = uq.euler_angles();
        let t = ns(CSV_BASE_NS, &sim, sim.poses.t[k]) as f64 * 1e-9;
        let row = [
            t,
            p[k][0],
            p[k][1],
            p[k][2],
            r.to_degrees(),
            pi.to_degrees(),
            y.to_degrees(),
        ];
        let row: Vec<String> = row.iter().map(|v| format!("{v:?}")).collect();
        text.push_str(&(row.join(",") + "\n"));
    }
    std::fs::write(&euler, text).unwrap();
    let out_e = d.join("imported_euler");
    robimu_ok([
        "import",
        "poses",
        s(&euler),
        "--imu",
        s(&imu),
        "--time-col",
        "time",
        "--position-cols",
        "x,y,z",
        "--euler-cols",
        "roll,pitch,yaw",
        "--euler-deg",
        "--out",
        s(&out_e),
    ]);
    let got = PoseSession::read(&out_e).unwrap();
    assert_same_session_to(&got, &sim, "Euler CSV", EULER_QUATERNION_TOL);
    // the inverse rotation (x, y, z negated: R_BW, JPL), read with --conjugate
    let conj = d.join("conjugate.csv");
    write_pose_csv(&conj, &sim, |_, row| {
        for v in &mut row[5..8] {
            *v = format!("{:?}", -v.parse::<f64>().unwrap());
        }
    });
    let out_c = d.join("imported_conjugate");
    let mut args = vec![
        "import",
        "poses",
        s(&conj),
        "--imu",
        s(&imu),
        "--out",
        s(&out_c),
    ];
    args.extend_from_slice(&CSV_FLAGS);
    args.push("--conjugate");
    robimu_ok(&args);
    assert_same_session(&PoseSession::read(&out_c).unwrap(), &sim, "conjugated CSV");
    let bad = d.join("bad");
    // a missing column names the columns there are
    let mut a = vec![
        "import",
        "poses",
        s(&poses),
        "--imu",
        s(&imu),
        "--out",
        s(&bad),
    ];
    a.extend_from_slice(&["--time-col", "stamp_ms", "--time-unit", "ms"]);
    robimu(&a).assert_fails(&["tcp.csv", "no column \"px\"", "stamp_ms, status, X, Y, Z"]);
    // quaternion columns named in another order than --quat-order
    let mut a1 = a.clone();
    a1.extend_from_slice(&["--position-cols", "X,Y,Z", "--units", "mm"]);
    a1.extend_from_slice(&["--quat-cols", "q_x,q_y,q_z,q_w"]);
    robimu(&a1).assert_fails(&["the names say the order xyzw", "pass --quat-order xyzw"]);
    let mut a2 = a.clone();
    a2.extend_from_slice(&["--position-cols", "X,Y"]);
    robimu(&a2).assert_fails(&["--position-cols: 2 columns given, 3 needed"]);
    // a non-finite value names its line and column
    let nan = d.join("nan.csv");
    write_pose_csv(&nan, &sim, |k, row| {
        if k == 3 {
            row[7] = "NaN".into();
        }
    });
    let mut a3 = vec![
        "import",
        "poses",
        s(&nan),
        "--imu",
        s(&imu),
        "--out",
        s(&bad),
    ];
    a3.extend_from_slice(&CSV_FLAGS);
    robimu(&a3).assert_fails(&["nan.csv:5", "column 8: \"NaN\" is not a finite number"]);
    // the Euler flags need their columns; quaternion and Euler columns exclude each other
    let mut a4 = a3.clone();
    a4.push("--euler-deg");
    robimu(&a4).assert_fails(&["--euler-cols"]);
    assert!(!bad.exists(), "a failed import wrote {}", bad.display());
}

/// Messages of one topic: (stamp ns, CDR bytes).
type Messages = Vec<(i64, Vec<u8>)>;

/// A change made to the poses of a recording.
type Mutation = Box<dyn Fn(&mut Vec<PoseMsg>)>;

/// An MCAP recording (rosbag2 profile) with the IMU on /imu/data_raw and
/// `poses`: (topic, type, messages).
fn write_bag(path: &Path, sim: &PoseSession, poses: &[(&str, &str, Messages)]) {
    let file = BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(None)
        .create(file)
        .unwrap();
    let meta = BTreeMap::new();
    let imu_schema = w
        .add_schema("sensor_msgs/msg/Imu", "ros2msg", b"# (omitted)\n")
        .unwrap();
    let ic = w
        .add_channel(imu_schema, "/imu/data_raw", "cdr", &meta)
        .unwrap();
    let mut msgs: Vec<(i64, u16, Vec<u8>)> = Vec::new();
    let imu = &sim.imus[0].samples;
    for k in 0..imu.len() {
        let z = imu.row(k);
        let m = ImuMsg {
            stamp: Stamp(ns(BAG_BASE_NS, sim, imu.t[k])),
            frame_id: "imu_link".into(),
            angular_velocity: [z[3], z[4], z[5]],
            linear_acceleration: [z[0], z[1], z[2]],
        };
        msgs.push((m.stamp.0, ic, encode::imu(&m)));
    }
    for (topic, type_name, list) in poses {
        let schema = w
            .add_schema(type_name, "ros2msg", b"# (omitted)\n")
            .unwrap();
        let c = w.add_channel(schema, topic, "cdr", &meta).unwrap();
        msgs.extend(list.iter().map(|(t, b)| (*t, c, b.clone())));
    }
    msgs.sort_by_key(|m| m.0);
    for (seq, (stamp, channel, bytes)) in msgs.iter().enumerate() {
        let log = (*stamp + 2_000_000) as u64;
        let header = mcap::records::MessageHeader {
            channel_id: *channel,
            sequence: seq as u32,
            log_time: log,
            publish_time: log,
        };
        w.write_to_known_channel(&header, bytes).unwrap();
    }
    w.finish().unwrap();
}

/// The session's poses as messages of `child` in `parent`.
fn pose_msgs(sim: &PoseSession, parent: &str, child: &str) -> Vec<PoseMsg> {
    let (p, q) = (sim.positions(), sim.quaternions());
    (0..sim.poses.len())
        .map(|k| PoseMsg {
            stamp: Stamp(ns(BAG_BASE_NS, sim, sim.poses.t[k])),
            frame_id: parent.into(),
            child_frame_id: child.into(),
            position: p[k],
            orientation: q[k],
        })
        .collect()
}

#[test]
fn ros2_pose_stamped_transform_stamped_and_tf_import_to_the_simulated_session() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let sim = simulated(&d.join("sim"));
    let tool = pose_msgs(&sim, "base", "tool0");
    // /tf: each message has the tool's transform and a camera's (another
    // frame, fixed), as robot_state_publisher and a driver mix them
    let camera = PoseMsg {
        child_frame_id: "camera".into(),
        frame_id: "world".into(),
        position: [0.5, 0.0, 1.2],
        orientation: [0.0, 1.0, 0.0, 0.0],
        ..tool[0].clone()
    };
    let tf: Messages = tool
        .iter()
        .map(|m| {
            let cam = PoseMsg {
                stamp: m.stamp,
                ..camera.clone()
            };
            (m.stamp.0, encode::tf(&[cam, m.clone()]))
        })
        .collect();
    let stamped: Messages = tool
        .iter()
        .map(|m| (m.stamp.0, encode::pose_stamped(m)))
        .collect();
    let single: Messages = tool
        .iter()
        .map(|m| (m.stamp.0, encode::transform_stamped(m)))
        .collect();
    let bag = d.join("run.mcap");
    write_bag(
        &bag,
        &sim,
        &[
            ("/tcp_pose", "geometry_msgs/msg/PoseStamped", stamped),
            (
                "/tcp_transform",
                "geometry_msgs/msg/TransformStamped",
                single,
            ),
            ("/tf", "tf2_msgs/msg/TFMessage", tf),
        ],
    );
    let import = |out: &PathBuf, extra: &[&str]| {
        let mut args = vec!["import", "ros2", s(&bag), "--imu", "/imu/data_raw"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", s(out)]);
        robimu(&args)
    };
    for (name, extra) in [
        ("pose_stamped", &["--poses", "/tcp_pose"][..]),
        ("transform_stamped", &["--poses", "/tcp_transform"][..]),
        ("tf", &["--poses", "/tf", "--frame", "tool0"][..]),
    ] {
        let out = d.join(name);
        let run = import(&out, extra);
        assert!(run.success(), "{name}: {}", run.text());
        assert!(
            run.stdout
                .contains(&format!("{} pose samples", sim.poses.len())),
            "{}",
            run.stdout
        );
        let got = PoseSession::read(&out).unwrap();
        assert_same_session(&got, &sim, name);
        if name == "tf" {
            let notes = got.meta.notes.clone().unwrap_or_default();
            assert!(notes.contains("poses of tool0 in base"), "{notes}");
        }
    }
    // bad input: named, non-zero exit, never a panic
    let bad = d.join("bad");
    import(&bad, &["--poses", "/tf"]).assert_fails(&[
        "transforms of 2 frames",
        "camera (in world,",
        "tool0 (in base,",
        "--frame",
    ]);
    import(&bad, &["--poses", "/tf", "--frame", "tool1"]).assert_fails(&[
        "no transform of frame \"tool1\"",
        "the frames present: camera (in world,",
        "tool0 (in base,",
    ]);
    import(&bad, &["--poses", "/tcp_pose", "--frame", "tool0"])
        .assert_fails(&["--frame tool0", "names no child frame"]);
    import(&bad, &["--poses", "/imu/data_raw"])
        .assert_fails(&["carries sensor_msgs/msg/Imu, expected geometry_msgs/msg/PoseStamped or"]);
    import(&bad, &["--poses", "/nope"])
        .assert_fails(&["no topic /nope", "/tf [tf2_msgs/msg/TFMessage"]);
    import(&bad, &["--poses", "/tcp_pose", "--robot", "ur5e"])
        .assert_fails(&["--robot: not with --poses"]);
    robimu([
        "import",
        "ros2",
        s(&bag),
        "--frame",
        "tool0",
        "--out",
        s(&bad),
    ])
    .assert_fails(&["--poses"]);
    assert!(!bad.exists(), "a failed import wrote {}", bad.display());
}

#[test]
fn ros2_poses_that_are_not_measurements_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let sim = simulated(&d.join("sim"));
    let mut tool = pose_msgs(&sim, "base", "tool0");
    let bad = d.join("bad");
    let cases: [(&str, Mutation, &str); 3] = [
        (
            "nan",
            Box::new(|m| m[4].position[1] = f64::NAN),
            "message 4 (log time",
        ),
        (
            "zero",
            Box::new(|m| m[2].orientation = [0.0; 4]),
            "of norm 0 is not a rotation",
        ),
        (
            "frames",
            Box::new(|m| m[7].frame_id = "odom".into()),
            "the ones before it in \"base\": poses must be in one fixed frame",
        ),
    ];
    // each message alone on /tf, bagged as NAME.mcap, imported to `out`
    let import = |name: &str, msgs: &[PoseMsg], out: &Path| {
        let list = msgs
            .iter()
            .map(|m| (m.stamp.0, encode::tf(std::slice::from_ref(m))))
            .collect();
        let bag = d.join(format!("{name}.mcap"));
        write_bag(&bag, &sim, &[("/tf", "tf2_msgs/msg/TFMessage", list)]);
        let args = ["import", "ros2", s(&bag), "--imu", "/imu/data_raw"];
        robimu(args.into_iter().chain(["--poses", "/tf", "--out", s(out)]))
    };
    for (name, mutate, want) in cases {
        let mut msgs = tool.clone();
        mutate(&mut msgs);
        import(name, &msgs, &bad).assert_fails(&[want]);
    }
    // the one frame of a topic is taken without --frame
    tool.truncate(20);
    let out = d.join("one");
    let run = import("one", &tool, &out);
    assert!(run.success(), "{}", run.text());
    assert_eq!(PoseSession::read(&out).unwrap().poses.len(), 20);
    assert!(!bad.exists());
}
