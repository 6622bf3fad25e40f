//! Recording over simulated hardware: the real firmware core on a
//! pseudo-terminal and a simulated AUBO controller on loopback TCP, with a
//! hidden truth (robimu_hil). End to end, every fault switch, and a kill.
//!
//! These run in real time (a few seconds each; the end-to-end one 30 s), one
//! at a time ([`common::real_time_slot`]).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rand::SeedableRng;
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_hil_sim::aubo::FaultSwitches;
use robimu_hil_sim::device::SerialFaults;
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::{record, RecordError, RecordOptions, RecordSummary};
use robimu_session::{Session, Truth};
use robimu_workflows::calibrate::{calibrate, CalibrateOptions, Calibration};
use serialport::SerialPort;

mod common;
use common::{robimu, Run};

fn rig(seed: u64) -> SimRig {
    SimRig::spawn(&SimRigConfig::drawn(Robot::aubo_i5(), seed)).unwrap()
}

fn options(rig: &SimRig, out: &Path, plan: Option<Plan>, duration: f64) -> RecordOptions {
    options_for(rig.imu_port(), &rig.robot_spec(), out, plan, duration)
}

fn options_for(
    imu_port: &str,
    robot_spec: &str,
    out: &Path,
    plan: Option<Plan>,
    duration: f64,
) -> RecordOptions {
    RecordOptions {
        imu_port: imu_port.to_string(),
        extra_imu_ports: Vec::new(),
        baud: 921_600,
        robot_spec: RobotSpec::parse(robot_spec).unwrap(),
        robot: Robot::aubo_i5(),
        robot_name: "aubo_i5".into(),
        plan,
        duration,
        out: out.to_path_buf(),
        joint_rate: 125.0,
        rest: 1.0,
        sensor: SensorConfig::default(),
        interrupt: None,
    }
}

/// Calibrates the recorded session at `dir` and asserts every parameter
/// within 4σ of `truth`; returns the calibration.
fn calibrate_against_truth(dir: &Path, truth: &Truth, label: &str) -> Calibration {
    let robot = Robot::aubo_i5();
    let session = check_session(dir);
    let layout = ParamLayout::new(&robot);
    let cal = calibrate(
        &robot,
        &session.measurements(),
        &CalibrateOptions::new(&robot),
        |_| {},
    )
    .unwrap();
    let mut worst = (0.0, String::new());
    for (k, spec) in layout.specs().iter().enumerate() {
        let t = truth.get(&spec.name).unwrap();
        let z = (cal.x[k] - t) / cal.sigma[k];
        if z.abs() > worst.0 {
            worst = (z.abs(), spec.name.clone());
        }
    }
    eprintln!(
        "{label}: worst |error|/σ = {:.2} ({}); residual rms {:?}",
        worst.0, worst.1, cal.residual_rms
    );
    assert!(
        worst.0 < 4.0,
        "{} is {:.2} σ from the truth",
        worst.1,
        worst.0
    );
    cal
}

/// Every IMU time strictly increasing, every joint time non-decreasing,
/// and the sensor temperature recorded on every IMU row (the simulated
/// BNO055 holds 25 °C).
fn check_session(dir: &Path) -> Session {
    let s = Session::load(dir).unwrap();
    let m = s.measurements();
    let temp = m.imu_temp.as_deref().expect("imu.csv has a temp_c column");
    assert_eq!(temp.len(), m.imu_t.len());
    assert!(temp.iter().all(|&c| c == 25.0), "temperatures {temp:?}");
    assert!(
        m.imu_t.windows(2).all(|w| w[1] > w[0]),
        "IMU times not increasing"
    );
    assert!(m.joint_t.windows(2).all(|w| w[1] >= w[0]));
    s
}

#[test]
fn end_to_end_recording_recovers_the_hidden_truth_within_4_sigma() {
    let _slot = common::real_time_slot();
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(21);
    let traj = random_walk(&robot, 30.0, 1.0, &mut rng).unwrap();
    let plan = Plan::from_spline(&traj, 250.0);
    let rig = rig(21);
    let dir = tempfile::tempdir().unwrap();
    let summary = record(&options(&rig, dir.path(), Some(plan), 0.0), &mut |_| {}).unwrap();
    let truth = rig.truth().clone();
    drop(rig);
    let p = &summary.progress;
    // The link loses nothing (no spoiled frame) and every slot is either a
    // sample or one the board counted as missed.
    assert_eq!((p.crc_errors, p.bad_frames), (0, 0), "{p:?}");
    let rate = f64::from(SensorConfig::default().sample_rate_hz);
    common::assert_every_slot_accounted(
        p.imu_samples,
        p.seq_gaps,
        p.device_dropped,
        rate,
        summary.duration,
    );
    assert!(
        (31.5..33.0).contains(&summary.duration),
        "{}",
        summary.duration
    );
    assert!(p.imu_samples as f64 > 118.0 * summary.duration);
    assert!(p.joint_samples as f64 > 120.0 * summary.duration);
    let (_, fit) = summary.clock[0];
    assert!(
        (fit.drift_ppm() - 48.7).abs() < 2.0,
        "drift {}",
        fit.drift_ppm()
    );

    let cal = calibrate_against_truth(dir.path(), &truth, "AUBO");
    for r in cal.residual_rms {
        assert!((0.9..1.1).contains(&r), "whitened residual rms {r}");
    }
}

fn record_with(
    rig: &SimRig,
    dir: &Path,
    duration: f64,
    at: f64,
    fault: impl FnOnce() + Send,
) -> Result<RecordSummary, RecordError> {
    let opts = options(rig, dir, None, duration);
    std::thread::scope(|s| {
        s.spawn(move || {
            std::thread::sleep(Duration::from_secs_f64(at));
            fault();
        });
        record(&opts, &mut |_| {})
    })
}

#[test]
fn corrupted_and_dropped_bytes_are_counted_and_skipped() {
    let _slot = common::real_time_slot();
    let rig = rig(3);
    let dir = tempfile::tempdir().unwrap();
    let device = &rig.device;
    let s = record_with(&rig, dir.path(), 5.0, 1.0, || {
        device.set_serial_faults(SerialFaults {
            corrupt_probability: 2e-3,
            drop_probability: 2e-3,
        })
    })
    .unwrap();
    let p = &s.progress;
    assert!(p.crc_errors + p.bad_frames > 5, "{p:?}");
    assert!(p.seq_gaps > 5, "{p:?}");
    // ~13 bytes a frame: 4 ‰ of bytes spoil ~5 % of the frames.
    assert!(p.imu_samples as f64 > 0.85 * 120.0 * 5.0, "{p:?}");
    let session = check_session(dir.path());
    assert_eq!(session.measurements().imu_t.len() as u64, p.imu_samples);
    // AUBO sends no controller time: the joint columns of docs/model.md §7 only
    assert!(s.joint_clock.is_none());
    let joints = std::fs::read_to_string(dir.path().join("joints.csv")).unwrap();
    assert!(
        joints.starts_with("t,q1,q2,q3,q4,q5,q6\n"),
        "{}",
        &joints[..40]
    );
}

#[test]
fn a_board_reset_mid_stream_is_recovered_in_a_new_clock_segment() {
    let _slot = common::real_time_slot();
    let rig = rig(4);
    let dir = tempfile::tempdir().unwrap();
    let device = &rig.device;
    // segments of about 4 s each: long enough that the arrival jitter of a
    // loaded machine leaves each one's drift within the bound below
    let s = record_with(&rig, dir.path(), 9.0, 4.0, || device.reset()).unwrap();
    assert_eq!(s.progress.restarts, 1, "{:?}", s.progress);
    assert_eq!(s.clock.len(), 2);
    let session = check_session(dir.path());
    let t = session.measurements().imu_t;
    // At most a second lost to the reboot; the rest at 120 Hz.
    assert!(t.len() as f64 > 120.0 * 7.5, "{} samples", t.len());
    let largest_gap = t.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(largest_gap < 1.5, "gap {largest_gap}");
    // Both segments map onto one session clock: the drift of each is right.
    for (_, f) in &s.clock {
        assert!((f.drift_ppm() - 48.7).abs() < 50.0, "{f:?}");
    }
}

#[test]
fn a_vanished_port_stops_with_a_clear_error_and_keeps_the_data() {
    let _slot = common::real_time_slot();
    let rig = rig(5);
    let dir = tempfile::tempdir().unwrap();
    let device = &rig.device;
    let err = record_with(&rig, dir.path(), 10.0, 3.0, || device.vanish()).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("serial port") && text.contains("kept in"),
        "{text}"
    );
    let RecordError::Aborted { summary, .. } = err else {
        panic!("{text}")
    };
    assert!(summary.duration < 5.0);
    let session = check_session(dir.path());
    assert!(session.measurements().imu_t.len() > 250);
    assert!(session.measurements().joint_t.len() > 250);
}

/// Record with `opts` until `silence` is called once `now_silent` says so
/// (from the progress); the recording must then fail. Returns the error,
/// its text and how long after the silence the recording ended.
fn record_until_silenced(
    opts: &RecordOptions,
    now_silent: impl Fn(&robimu_record::RecordProgress) -> bool,
    silence: impl Fn(),
) -> (RecordError, String, Duration) {
    let mut silenced = None;
    let err = record(opts, &mut |p| {
        if silenced.is_none() && now_silent(p) {
            silence();
            silenced = Some(Instant::now());
        }
    })
    .unwrap_err();
    let took = silenced.expect("the source was silenced").elapsed();
    let text = err.to_string();
    eprintln!("{text}\nended {took:.2?} after the source went silent");
    assert!(took < Duration::from_secs(2), "ended {took:?} after");
    (err, text, took)
}

/// A board that goes silent with no I/O error (every byte it sends lost:
/// hung, or powered off behind a USB adapter that stays) ends the
/// recording within 2 s with the watchdog's error naming the port, and the
/// session recorded until then is intact and calibratable (every
/// parameter within 4σ of the hidden truth).
#[test]
fn a_silent_board_ends_the_recording_within_2_s_and_keeps_the_data() {
    let _slot = common::real_time_slot();
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(41);
    let traj = random_walk(&robot, 30.0, 1.0, &mut rng).unwrap();
    let rig = rig(41);
    let dir = tempfile::tempdir().unwrap();
    let device = &rig.device;
    let opts = options(&rig, dir.path(), Some(Plan::from_spline(&traj, 250.0)), 0.0);
    // silenced once 10 s of samples are in
    let (_, text, _) = record_until_silenced(
        &opts,
        |p| p.imu_samples > 1200,
        || {
            device.set_serial_faults(SerialFaults {
                corrupt_probability: 0.0,
                drop_probability: 1.0,
            })
        },
    );
    assert!(
        text.contains("went silent") && text.contains(rig.imu_port()) && text.contains("kept in"),
        "{text}"
    );
    let truth = rig.truth().clone();
    drop(rig);
    let session = check_session(dir.path());
    assert!(session.measurements().imu_t.len() > 1000);
    calibrate_against_truth(dir.path(), &truth, "silent board");
}

/// A UR controller whose RTDE data stream stops with the connection open
/// (no I/O error) ends the recording within 2 s with the watchdog's error
/// naming the controller (no joint sample for max(1 s, 20 periods)); the
/// plan is halted, and the 10 s recorded until then are intact and
/// calibratable (every parameter within 4σ of the hidden truth).
#[test]
fn a_silent_ur_controller_ends_the_recording_within_2_s_and_keeps_the_data() {
    let _slot = common::real_time_slot();
    use robimu_hil::rig::SimUrRig;
    use robimu_hil_sim::ur::FaultSwitches as UrFaults;
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    let traj = random_walk(&robot, 30.0, 1.0, &mut rng).unwrap();
    let plan = Plan::from_spline(&traj, 125.0);
    let mut config = SimRigConfig::drawn(robot.clone(), 42);
    config.initial = plan.q[0];
    let rig = SimUrRig::spawn(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let spec = rig.robot_spec();
    let opts = options_for(rig.imu_port(), &spec, dir.path(), Some(plan), 0.0);
    // silenced once 10 s of joint samples are in
    let (err, text, _) = record_until_silenced(
        &opts,
        |p| p.joint_samples > 1250,
        || {
            rig.ur.set_faults(UrFaults {
                stall_data: true,
                ..UrFaults::default()
            })
        },
    );
    assert!(
        text.contains(&format!("the robot controller {spec} went silent"))
            && text.contains("no joint sample for")
            && text.contains("the robot was stopped")
            && text.contains("kept in"),
        "{text}"
    );
    let RecordError::Aborted { summary, .. } = err else {
        panic!("{text}")
    };
    assert!(
        summary.progress.joint_samples > 1250,
        "{:?}",
        summary.progress
    );
    let truth = rig.truth().clone();
    drop(rig);
    let session = check_session(dir.path());
    assert_eq!(
        session.measurements().joint_t.len() as u64,
        summary.progress.joint_samples
    );
    calibrate_against_truth(dir.path(), &truth, "silent UR controller");
}

/// An AUBO controller that stops answering its polls with the connection
/// open ends the recording within 2 s with the watchdog's error (before
/// the 2 s reply timeout), the session up to then intact.
#[test]
fn a_silent_aubo_controller_ends_the_recording_within_2_s_and_keeps_the_data() {
    let _slot = common::real_time_slot();
    let rig = rig(43);
    let dir = tempfile::tempdir().unwrap();
    let spec = rig.robot_spec();
    let opts = options(&rig, dir.path(), None, 20.0);
    let (err, text, _) = record_until_silenced(
        &opts,
        |p| p.joint_samples > 375,
        || {
            rig.aubo.set_faults(FaultSwitches {
                silent: true,
                ..FaultSwitches::default()
            })
        },
    );
    assert!(
        text.contains(&format!("the robot controller {spec} went silent"))
            && text.contains("the limit is 1s")
            && text.contains("kept in"),
        "{text}"
    );
    let RecordError::Aborted { summary, .. } = err else {
        panic!("{text}")
    };
    assert!(summary.duration < 6.0, "{}", summary.duration);
    let session = check_session(dir.path());
    let m = session.measurements();
    assert_eq!(m.joint_t.len() as u64, summary.progress.joint_samples);
    assert!(
        m.joint_t.len() > 375 && m.imu_t.len() > 300,
        "{}",
        m.imu_t.len()
    );
}

#[test]
fn a_dropped_robot_connection_stops_with_a_clear_error_and_keeps_the_data() {
    let _slot = common::real_time_slot();
    let rig = rig(6);
    let dir = tempfile::tempdir().unwrap();
    let aubo = &rig.aubo;
    let err = record_with(&rig, dir.path(), 10.0, 2.0, || {
        aubo.set_faults(FaultSwitches {
            drop_connection_after: Some(0),
            ..FaultSwitches::default()
        })
    })
    .unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("robot connection") && text.contains("kept in"),
        "{text}"
    );
    let session = check_session(dir.path());
    assert!(session.measurements().imu_t.len() > 150);
}

#[test]
fn slow_robot_replies_lower_the_joint_rate_but_the_recording_goes_on() {
    let _slot = common::real_time_slot();
    let rig = rig(7);
    let dir = tempfile::tempdir().unwrap();
    let aubo = &rig.aubo;
    let s = record_with(&rig, dir.path(), 4.0, 0.0, || {
        aubo.set_faults(FaultSwitches {
            reply_delay: Duration::from_millis(20),
            ..FaultSwitches::default()
        })
    })
    .unwrap();
    let rate = s.progress.joint_samples as f64 / s.duration;
    assert!(rate < 60.0 && rate > 20.0, "joint rate {rate}");
    check_session(dir.path());
}

#[test]
fn a_robot_that_refuses_the_plan_gives_a_clear_error() {
    let _slot = common::real_time_slot();
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(8);
    let plan = Plan::from_spline(&random_walk(&robot, 10.0, 1.0, &mut rng).unwrap(), 250.0);
    let rig = rig(8);
    rig.aubo.set_faults(FaultSwitches {
        refuse_motion: true,
        ..FaultSwitches::default()
    });
    let dir = tempfile::tempdir().unwrap();
    let err = record(&options(&rig, dir.path(), Some(plan), 0.0), &mut |_| {}).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("refused") && text.contains("moveJoint"),
        "{text}"
    );
    // Refused before anything was recorded: no session left behind.
    assert!(!dir.path().join("session.toml").exists());
}

#[test]
fn missing_busy_and_foreign_ports_are_named() {
    let _slot = common::real_time_slot();
    let rig = rig(9);
    let dir = tempfile::tempdir().unwrap();
    let mut opts = options(&rig, &dir.path().join("s"), None, 1.0);
    opts.imu_port = "/dev/robimu-no-such-port".into();
    let text = record(&opts, &mut |_| {}).unwrap_err().to_string();
    assert!(
        text.contains("no serial port /dev/robimu-no-such-port"),
        "{text}"
    );
    // A pseudo-terminal with nothing behind it: not a robimu board.
    let (_master, slave) = serialport::TTYPort::pair().unwrap();
    opts.imu_port = slave.name().unwrap();
    drop(slave);
    let text = record(&opts, &mut |_| {}).unwrap_err().to_string();
    assert!(text.contains("is not a robimu IMU board"), "{text}");
    // The board's port held open (exclusively) by another program.
    let _held = serialport::new(rig.imu_port(), 921_600).open().unwrap();
    opts.imu_port = rig.imu_port().to_string();
    let text = record(&opts, &mut |_| {}).unwrap_err().to_string();
    assert!(text.contains("is busy"), "{text}");
    assert!(!dir.path().join("s").exists());
}

/// Starts the `robimu record` program on `rig` with `args` (after --imu and
/// --robot) writing `out`, and waits up to `start_timeout` for the recording
/// to start (session.toml written).
fn start_recording(
    rig: &SimRig,
    args: &[&std::ffi::OsStr],
    out: &Path,
    stdout: Stdio,
    start_timeout: Duration,
) -> std::process::Child {
    let child = common::command()
        .args([
            "record",
            "--imu",
            rig.imu_port(),
            "--robot",
            &rig.robot_spec(),
        ])
        .args(args)
        .arg("--out")
        .arg(out)
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !out.join("session.toml").exists() {
        assert!(start.elapsed() < start_timeout, "recording never started");
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

/// `robimu record` killed with SIGKILL mid-run leaves a session that loads
/// (flushed every second), and `robimu repair` finishes it.
#[test]
fn a_recording_killed_with_sigkill_leaves_a_readable_session() {
    let _slot = common::real_time_slot();
    let rig = rig(10);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("killed");
    // Wait until the recording has started (session.toml written), then 3 s.
    let args = ["--no-move", "--duration", "60"].map(std::ffi::OsStr::new);
    let mut child = start_recording(&rig, &args, &out, Stdio::null(), Duration::from_secs(20));
    let started = Instant::now();
    std::thread::sleep(Duration::from_secs(3));
    child.kill().unwrap(); // SIGKILL
    let elapsed = started.elapsed().as_secs_f64();
    child.wait().unwrap();
    let session = check_session(&out);
    let imu = session.measurements().imu_t.len() as f64;
    // At most about a second lost.
    assert!(
        imu > 120.0 * (elapsed - 1.5),
        "{imu} IMU samples after {elapsed:.1} s"
    );
    let status = robimu([std::ffi::OsStr::new("repair"), out.as_os_str()]);
    let text = &status.stdout;
    assert!(status.success(), "{text}");
    assert!(text.contains("is readable"), "{text}");
    let repaired = check_session(&out);
    assert_eq!(repaired.measurements().imu_t.len() as f64, imu);
}

/// Ctrl-C (SIGINT) to `robimu record` while the plan runs: the robot is
/// halted, the recording is finished as at a normal end (IMU times mapped
/// by the final clock fit, nothing for `robimu repair` to do), the program
/// says so and exits non-zero.
#[test]
fn ctrl_c_halts_the_robot_and_finishes_the_session() {
    let _slot = common::real_time_slot();
    use robimu_record::controller::aubo::AuboClient;
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(31);
    let plan = Plan::from_spline(&random_walk(&robot, 30.0, 1.0, &mut rng).unwrap(), 250.0);
    let rig = rig(31);
    let dir = tempfile::tempdir().unwrap();
    let plan_dir = dir.path().join("plan");
    std::fs::create_dir_all(&plan_dir).unwrap();
    plan.write_csv(&plan_dir.join("plan.csv")).unwrap();
    let out = dir.path().join("interrupted");
    let args = [std::ffi::OsStr::new("--plan"), plan_dir.as_os_str()];
    let child = start_recording(&rig, &args, &out, Stdio::piped(), Duration::from_secs(60));
    // 1 s rest, then 3 s into the plan
    std::thread::sleep(Duration::from_secs(4));
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let output = Run::from(child.wait_with_output().unwrap());
    let stderr = &output.stderr;
    assert_eq!(output.code(), Some(1), "{stderr}");
    assert!(stderr.contains("interrupted (Ctrl-C)"), "{stderr}");
    assert!(stderr.contains("the robot was stopped"), "{stderr}");
    assert!(stderr.contains("are kept in"), "{stderr}");
    // the arm stands still (the plan had 26 s to go)
    let mut c = AuboClient::connect(rig.robot_addr(), Duration::from_secs(2)).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let a = c.joint_positions().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let b = c.joint_positions().unwrap();
    let moved = (0..6).map(|j| (a[j] - b[j]).abs()).fold(0.0, f64::max);
    assert!(moved < 2e-3, "the arm still moves: {moved} rad in 0.5 s");
    // finished like a normal end: the final clock fit is in session.toml
    let session = check_session(&out);
    let toml = std::fs::read_to_string(out.join("session.toml")).unwrap();
    assert!(toml.contains("drift_ppm"), "{toml}");
    let m = session.measurements();
    assert!(m.imu_t.len() > 120 * 3, "{} IMU samples", m.imu_t.len());
    assert!(
        m.joint_t.len() > 125 * 3,
        "{} joint samples",
        m.joint_t.len()
    );
    let repaired = robimu([std::ffi::OsStr::new("repair"), out.as_os_str()]);
    assert!(repaired.success());
    assert_eq!(check_session(&out).measurements().imu_t, m.imu_t);
}

/// A simulated UR controller (`config`) and IMU board for a UR recording of
/// `seconds` of random plan (seed `seed`, 125 Hz rows): the controller, the
/// board, the plan and the recording options (into `dir`, 0.5 s rest).
fn ur_setup(
    seed: u64,
    seconds: f64,
    config: robimu_hil_sim::ur::SimUrConfig,
    dir: &Path,
) -> (
    robimu_hil_sim::ur::SimUr,
    robimu_hil_sim::device::SimDevice,
    Plan,
    RecordOptions,
) {
    use robimu_hil_sim::device::{SimDevice, SimDeviceConfig};
    use robimu_hil_sim::ur::{SimUr, SimUrConfig};
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let plan = Plan::from_spline(&random_walk(&robot, seconds, 1.0, &mut rng).unwrap(), 125.0);
    let ur = SimUr::spawn(SimUrConfig {
        control_rate_hz: 125.0,
        initial: plan.q[0],
        ..config
    })
    .unwrap();
    let device = SimDevice::spawn(SimDeviceConfig::default()).unwrap();
    let spec = format!(
        "ur:127.0.0.1:{}:{}",
        ur.rtde_addr().port(),
        ur.script_addr().port()
    );
    let mut opts = options_for(device.port_path(), &spec, dir, Some(plan.clone()), 0.0);
    opts.rest = 0.5;
    (ur, device, plan, opts)
}

/// `record --robot ur:HOST:RTDE:SCRIPT` against the simulated UR controller
/// (RTDE at 125 Hz, the plan as one URScript program) with the simulated
/// IMU board: the plan runs to its end, the joints arrive at the
/// controller's rate, the session loads and follows the plan.
#[test]
fn recording_from_the_simulated_ur_controller_runs_the_plan() {
    let _slot = common::real_time_slot();
    let dir = tempfile::tempdir().unwrap();
    let (ur, _device, plan, opts) = ur_setup(12, 6.0, Default::default(), dir.path());
    let s = record(&opts, &mut |_| {}).unwrap();
    assert!(ur.script_errors().is_empty(), "{:?}", ur.script_errors());
    assert!((7.0..9.0).contains(&s.duration), "{}", s.duration);
    let rate = s.progress.joint_samples as f64 / s.duration;
    assert!((rate - 125.0).abs() < 5.0, "joint rate {rate}");
    let session = check_session(dir.path());
    let m = session.measurements();
    // The last joint sample is the plan's last pose (within lag and noise).
    let last = &m.joint_q[m.joint_q.len() - 6..];
    for (j, (q, want)) in last.iter().zip(plan.q[plan.q.len() - 1]).enumerate() {
        assert!((q - want).abs() < 3e-3, "joint {j}");
    }
}

/// Issue 5: record → calibrate end to end against the simulated UR
/// controller: the IMU board's physics follows the UR arm's true motion at
/// a hidden truth; the plan runs as one URScript `servoj` program, joints
/// come over RTDE at 125 Hz; the calibration recovers the truth within 4σ.
#[test]
fn ur_recording_recovers_the_hidden_truth_within_4_sigma() {
    let _slot = common::real_time_slot();
    use robimu_hil::rig::SimUrRig;
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(31);
    let traj = random_walk(&robot, 30.0, 1.0, &mut rng).unwrap();
    let plan = Plan::from_spline(&traj, 125.0);
    let mut config = SimRigConfig::drawn(robot.clone(), 31);
    config.initial = plan.q[0];
    let rig = SimUrRig::spawn(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = options_for(
        rig.imu_port(),
        &rig.robot_spec(),
        dir.path(),
        Some(plan),
        0.0,
    );
    let summary = record(&opts, &mut |_| {}).unwrap();
    let truth = rig.truth().clone();
    assert!(
        rig.ur.script_errors().is_empty(),
        "{:?}",
        rig.ur.script_errors()
    );
    drop(rig);
    assert!(summary.progress.joint_samples as f64 > 120.0 * summary.duration);
    calibrate_against_truth(dir.path(), &truth, "UR");
}

/// An interrupted recording on the simulated UR controller: the running
/// program is replaced by a `stopj` and the arm comes to rest far from the
/// plan's end; the session is finished.
#[test]
fn an_interrupted_ur_recording_stops_the_arm() {
    let _slot = common::real_time_slot();
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let dir = tempfile::tempdir().unwrap();
    let (ur, _device, _, mut opts) = ur_setup(13, 20.0, Default::default(), dir.path());
    let flag = Arc::new(AtomicBool::new(false));
    opts.interrupt = Some(flag.clone());
    let setter = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(3));
        flag.store(true, Ordering::Relaxed);
    });
    let err = record(&opts, &mut |_| {}).unwrap_err();
    setter.join().unwrap();
    let text = err.to_string();
    assert!(matches!(err, RecordError::Aborted { .. }), "{text}");
    assert!(
        text.contains("interrupted (Ctrl-C); the robot was stopped"),
        "{text}"
    );
    assert!(ur.script_errors().is_empty(), "{:?}", ur.script_errors());
    std::thread::sleep(Duration::from_millis(300));
    let a = ur.true_joints();
    std::thread::sleep(Duration::from_millis(500));
    let b = ur.true_joints();
    let moved = (0..6).map(|j| (a[j] - b[j]).abs()).fold(0.0, f64::max);
    assert!(moved < 1e-4, "the arm still moves: {moved} rad in 0.5 s");
    assert!(!ur.program_running());
    check_session(dir.path());
}

/// Joint times from the UR controller's clock: RTDE packages held back by
/// a uniform 0–4 ms jitter (the simulator's `jitter_max`). The remapped
/// `t` of each joint row is compared with the instant the controller
/// sampled it (its `t_robot` on the simulator's clock) and with the raw
/// arrival time (`t_arrival`), each after removing its median offset (the
/// recorder's and the simulator's epochs differ by an unknown constant);
/// the recorded angles are compared with the true trajectory at either
/// time. `robimu repair` reproduces the times bit for bit.
#[test]
fn ur_joint_times_follow_the_controller_clock_despite_arrival_jitter() {
    let _slot = common::real_time_slot();
    use robimu_hil_sim::ur::{FaultSwitches as UrFaults, SimUrConfig};
    use robimu_record::repair::{repair, JointClock};
    let config = SimUrConfig {
        encoder_noise_rad: 1e-5,
        faults: UrFaults {
            jitter_max: Duration::from_millis(4),
            ..UrFaults::default()
        },
        ..SimUrConfig::default()
    };
    let uptime = config.uptime_at_epoch_s;
    let dir = tempfile::tempdir().unwrap();
    let (ur, _device, _, opts) = ur_setup(14, 6.0, config, dir.path());
    let s = record(&opts, &mut |_| {}).unwrap();
    let truth = ur.true_trajectory();
    drop(ur);
    let Some(JointClock::Mapped(fits)) = &s.joint_clock else {
        panic!("{:?}", s.joint_clock);
    };
    assert_eq!(fits.len(), 1);
    let fit = fits[0].1;
    // the simulator's clocks share one Instant: no drift beyond what a 6 s
    // fit of jittered arrivals resolves (32 ppm measured with the whole
    // test suite running on 2 cores); the arrival jitter is the injected
    // 0–4 ms plus the host's scheduling delays (4.6 ms RMS under that load)
    assert!(fit.drift_ppm().abs() < 100.0, "{fit:?}");
    assert!((1e-3..1e-2).contains(&fit.jitter_rms), "{fit:?}");

    let joints_csv = dir.path().join("joints.csv");
    let text = std::fs::read_to_string(&joints_csv).unwrap();
    assert!(text.starts_with("t,q1,q2,q3,q4,q5,q6,t_robot,t_arrival\n"));
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len() as u64, s.progress.joint_samples);
    let sampled: Vec<f64> = rows.iter().map(|r| r[7] - uptime).collect();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    // RMS of the time errors after removing their median, and that median
    let time_error = |col: usize| {
        let e: Vec<f64> = rows.iter().zip(&sampled).map(|(r, t)| r[col] - t).collect();
        let c = median(e.clone());
        let rms = (e.iter().map(|x| (x - c).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
        (rms, c)
    };
    let (rms_mapped, c_mapped) = time_error(0);
    let (rms_raw, c_raw) = time_error(8);
    // the angles against the truth at the row's time (on the simulator's clock)
    let true_q = |t: f64| {
        let k = truth.partition_point(|s| s.t < t).clamp(1, truth.len() - 1);
        let (a, b) = (&truth[k - 1], &truth[k]);
        let u = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
        std::array::from_fn::<f64, 6, _>(|j| a.q[j] + u * (b.q[j] - a.q[j]))
    };
    let angle_error = |col: usize, c: f64| {
        let ss: f64 = rows
            .iter()
            .map(|r| {
                let q = true_q(r[col] - c);
                (0..6).map(|j| (r[1 + j] - q[j]).powi(2)).sum::<f64>()
            })
            .sum();
        (ss / (6 * rows.len()) as f64).sqrt()
    };
    let (q_mapped, q_raw) = (angle_error(0, c_mapped), angle_error(8, c_raw));
    eprintln!(
        "UR joint times: RMS error {:.1} µs remapped vs {:.1} µs arrival; angle RMS error {:.2e} vs {:.2e} rad; envelope {:.2} ms below the median arrival; {fit:?}",
        rms_mapped * 1e6,
        rms_raw * 1e6,
        q_mapped,
        q_raw,
        (c_raw - c_mapped) * 1e3
    );
    assert!(rms_mapped < 2e-4, "remapped {rms_mapped}");
    assert!(rms_raw > 1e-3, "raw {rms_raw}");
    // the mapping is the lower envelope: about the median jitter (2 ms) below
    assert!(
        (0.001..0.003).contains(&(c_raw - c_mapped)),
        "{c_raw} {c_mapped}"
    );
    // at the remapped times only the encoder noise (1e-5 rad) is left
    assert!(
        q_mapped < 2e-5 && q_raw > 5.0 * q_mapped,
        "{q_mapped} vs {q_raw}"
    );

    // session.toml keeps the fit; repair gives the same times
    let meta = robimu_session::SessionMeta::read(&dir.path().join("session.toml")).unwrap();
    let clock = meta.controller.unwrap()["clock"]
        .as_array()
        .unwrap()
        .clone();
    assert_eq!(clock[0]["drift_ppm"].as_float(), Some(fit.drift_ppm()));
    let report = repair(dir.path()).unwrap();
    assert_eq!(report.joint_clock, s.joint_clock);
    assert_eq!(std::fs::read_to_string(&joints_csv).unwrap(), text);
    check_session(dir.path());
}

/// imu.csv's rows as (seq, [ax … gz], temp_c), by the header's names.
fn imu_rows(dir: &Path) -> Vec<(f64, [f64; 6], f64)> {
    let text = std::fs::read_to_string(dir.join("imu.csv")).unwrap();
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header: Vec<&str> = lines.next().unwrap().split(',').map(str::trim).collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (seq, temp) = (col("seq"), col("temp_c"));
    let z: Vec<usize> = ["ax", "ay", "az", "gx", "gy", "gz"].map(col).to_vec();
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            (v[seq], std::array::from_fn(|c| v[z[c]]), v[temp])
        })
        .collect()
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

/// With the arm at rest the true signal is constant, so each channel's
/// deviation from its mean is the noise: its lag-1 autocorrelation over
/// pairs of consecutive samples (no `seq` gap) is the AR(1) φ, per firmware
/// read (the ideal chip draws the noise per read).
#[test]
// channel loops index several per-channel arrays
#[allow(clippy::needless_range_loop)]
fn the_rigs_vibration_noise_has_the_configured_correlation() {
    let _slot = common::real_time_slot();
    let phi = 0.8;
    let config = SimRigConfig::drawn(Robot::aubo_i5(), 41)
        .with_vibration_noise(phi, 1e-3)
        .unwrap();
    let rig = SimRig::spawn(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    record(&options(&rig, dir.path(), None, 8.0), &mut |_| {}).unwrap();
    drop(rig);
    let rows = imu_rows(dir.path());
    assert!(rows.len() > 900, "{} rows", rows.len());
    let sigma = Robot::aubo_i5().sigma_z();
    for c in 0..6 {
        let x: Vec<f64> = rows.iter().map(|r| r.1[c]).collect();
        let m = mean(&x);
        let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64;
        let (mut num, mut pairs) = (0.0, 0);
        for w in rows.windows(2) {
            if w[1].0 == w[0].0 + 1.0 {
                num += (w[1].1[c] - m) * (w[0].1[c] - m);
                pairs += 1;
            }
        }
        let r1 = num / pairs as f64 / var;
        let want = if c < 3 { phi } else { 0.0 };
        // sampling error sqrt((1 − φ²)/N) ≈ 0.02 (accel), 0.03 (gyro)
        eprintln!(
            "channel {c}: r1 {r1:.3} (want {want}), σ {:.4} (robot {:.4})",
            var.sqrt(),
            sigma[c]
        );
        assert!(
            (r1 - want).abs() < 0.09,
            "channel {c}: lag-1 correlation {r1}, want {want}"
        );
        // the marginal σ is the robot's (correlated samples: a wider margin
        // on the accelerometer; LSB quantisation adds a little on the gyro)
        let tol = if c < 3 { 0.25 } else { 0.15 };
        assert!(
            (var.sqrt() / sigma[c] - 1.0).abs() < tol,
            "channel {c}: σ {}",
            var.sqrt()
        );
    }
}

/// A warm-up from 20 °C to 36 °C with τ = 4 s: the temperature column
/// rises along the exponential (τ recovered from it), and the biases move
/// with it: the drop of the mean reading between the first and the last
/// two seconds is the bias offset times the drop of f = (36 − T)/16.
#[test]
// channel loops index several per-channel arrays
#[allow(clippy::needless_range_loop)]
fn the_rigs_warm_up_shows_in_the_temperature_column_and_the_biases() {
    let _slot = common::real_time_slot();
    let mut config = SimRigConfig::drawn(Robot::aubo_i5(), 43);
    let offset = [2.0, 0.0, 0.0, 0.05, 0.0, 0.0];
    config.warm_up = Some(robimu_hil::rig::WarmUp {
        time_constant_s: 4.0,
        temp_start_c: 20.0,
        temp_end_c: 36.0,
        bias_start_offset: offset,
    });
    let rig = SimRig::spawn(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    record(&options(&rig, dir.path(), None, 10.0), &mut |_| {}).unwrap();
    drop(rig);
    let s = Session::load(dir.path()).unwrap();
    let m = s.measurements();
    let temp = m.imu_temp.clone().unwrap();
    assert!(
        temp.windows(2).all(|w| w[1] >= w[0]),
        "temperature not rising"
    );
    assert!(
        temp[0] < 33.0 && *temp.last().unwrap() >= 35.0,
        "{} … {}",
        temp[0],
        temp.last().unwrap()
    );
    // log(36 − T) = const − t/τ: least squares over rows still ≥ 2 °C away
    let (mut ts, mut ls) = (Vec::new(), Vec::new());
    for (t, c) in m.imu_t.iter().zip(&temp) {
        if 36.0 - c >= 2.0 {
            ts.push(*t);
            ls.push((36.0 - c).ln());
        }
    }
    let (mt, ml) = (mean(&ts), mean(&ls));
    let slope = ts
        .iter()
        .zip(&ls)
        .map(|(t, l)| (t - mt) * (l - ml))
        .sum::<f64>()
        / ts.iter().map(|t| (t - mt).powi(2)).sum::<f64>();
    let tau = -1.0 / slope;
    eprintln!(
        "warm-up τ from the temperature column: {tau:.2} s ({} rows)",
        ts.len()
    );
    assert!((tau - 4.0).abs() < 0.8, "τ {tau}");
    // the biases follow the same curve
    let rows = imu_rows(dir.path());
    let n = 240; // two seconds at 120 Hz
    let f = |r: &[(f64, [f64; 6], f64)]| {
        mean(&r.iter().map(|x| (36.0 - x.2) / 16.0).collect::<Vec<_>>())
    };
    let z =
        |r: &[(f64, [f64; 6], f64)], c: usize| mean(&r.iter().map(|x| x.1[c]).collect::<Vec<_>>());
    let (first, last) = (&rows[..n], &rows[rows.len() - n..]);
    let df = f(first) - f(last);
    assert!(df > 0.2, "f drops by {df}");
    let sigma = Robot::aubo_i5().sigma_z();
    for c in 0..6 {
        let dz = z(first, c) - z(last, c);
        let want = offset[c] * df;
        // noise of the two means, plus the rounding of T in f (≤ 1/32)
        let tol = 5.0 * sigma[c] * (2.0 / n as f64).sqrt() + offset[c] / 32.0;
        eprintln!("channel {c}: drop {dz:.4}, want {want:.4} ± {tol:.4}");
        assert!((dz - want).abs() < tol, "channel {c}: {dz} vs {want}");
    }
}

/// The rig with the simulated BNO055 in datasheet mode (filters, internal
/// rates, the chip's own saturation and quantisation): at rest each
/// channel's mean is the hidden truth's prediction and its spread the
/// robot's σ (white noise drawn per internal update; 120 Hz reads of the
/// 125 Hz and 1000 Hz updates see each update at most once).
#[test]
// channel loops index several per-channel arrays
#[allow(clippy::needless_range_loop)]
fn the_rig_with_a_datasheet_chip_reads_the_truth_at_rest() {
    let _slot = common::real_time_slot();
    let robot = Robot::aubo_i5();
    let mut config = SimRigConfig::drawn(robot.clone(), 45);
    config.chip = robimu_hil::rig::ChipModel::Datasheet;
    let rig = SimRig::spawn(&config).unwrap();
    let truth: Vec<f64> = {
        let layout = ParamLayout::new(&robot);
        layout
            .specs()
            .iter()
            .map(|s| rig.truth().get(&s.name).unwrap())
            .collect()
    };
    let dir = tempfile::tempdir().unwrap();
    record(&options(&rig, dir.path(), None, 4.0), &mut |_| {}).unwrap();
    drop(rig);
    let session = Session::load(dir.path()).unwrap();
    // the board's reported timing is in session.toml's [imu] table
    let timing = session
        .meta
        .imu_timing(&dir.path().join("session.toml"))
        .unwrap()
        .expect("[imu] timing keys");
    assert_eq!(
        [
            timing.accel_bandwidth_hz,
            timing.accel_odr_hz,
            timing.gyro_bandwidth_hz,
            timing.gyro_odr_hz
        ],
        [62.5, 125.0, 116.0, 1000.0]
    );
    let m = session.measurements();
    let layout = ParamLayout::new(&robot);
    let model = robimu_model::MeasurementModel::new(&robot, &layout, &truth).unwrap();
    let dof = robot.dof();
    let q: Vec<f64> = (0..dof)
        .map(|j| {
            mean(
                &m.joint_q
                    .iter()
                    .skip(j)
                    .step_by(dof)
                    .copied()
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    let zero = vec![0.0; dof];
    let predicted = model.predict(&robimu_model::JointState::from_slices(
        &q, &zero, &zero, &zero,
    ));
    let sigma = robot.sigma_z();
    let n = m.imu_z.len() as f64;
    assert!(n > 400.0);
    for c in 0..6 {
        let x: Vec<f64> = m.imu_z.iter().map(|z| z[c]).collect();
        let mu = mean(&x);
        let sd = (x.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / n).sqrt();
        eprintln!(
            "channel {c}: mean {mu:.4} vs {:.4}, σ {sd:.4} vs {:.4}",
            predicted[c], sigma[c]
        );
        assert!(
            (mu - predicted[c]).abs() < 5.0 * sigma[c] / n.sqrt() + 0.01,
            "channel {c}"
        );
        assert!((sd / sigma[c] - 1.0).abs() < 0.15, "channel {c}: σ {sd}");
    }
}

/// A rig recording with the datasheet chip at the rig's bandwidths
/// (accelerometer 62.5 Hz, ODR 125 Hz; gyroscope 116 Hz, ODR 1000 Hz; 120 Hz
/// reads), diagnosed: sensor_delay is named first, δ within 4σ of the
/// accelerometer's effective delay minus the gyroscope's. Each sensor's
/// effective delay is its filter's group delay plus the mean age of the
/// held register value at an asynchronous read, 1/(2·ODR):
/// (3.28 + 4.00) − (1.77 + 0.50) = +5.01 ms. (Measured on one 45 s
/// recording: δ = 4.2 ± 1.3 ms by `calibrate --effects sensor_delay`,
/// score 10.3, just short of the Bonferroni level; hence 90 s.)
#[test]
#[ignore = "110 s of real-time recording, whose data differ run to run (a loaded machine drops samples); with the LM stationary stop it passed (sensor_delay first, 4.17 ± 0.81 ms vs 5.01; resonance second); the virtual-time twin tests in tests/twin.rs cover the datasheet chip in CI"]
fn a_datasheet_chip_is_diagnosed_with_its_sensor_delay() {
    let _slot = common::real_time_slot();
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(33);
    let traj = random_walk(&robot, 90.0, 1.0, &mut rng).unwrap();
    let plan = Plan::from_spline(&traj, 250.0);
    let mut config = SimRigConfig::drawn(robot.clone(), 33);
    config.chip = robimu_hil::rig::ChipModel::Datasheet;
    let rig = SimRig::spawn(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    record(&options(&rig, dir.path(), Some(plan), 0.0), &mut |_| {}).unwrap();
    drop(rig);
    let session = Session::load(dir.path()).unwrap();
    let timing = session
        .meta
        .imu_timing(&dir.path().join("session.toml"))
        .unwrap()
        .expect("[imu] timing keys");
    let delay = |bw: f64, odr: f64| {
        robimu_bno055_sim::Timing {
            bandwidth_hz: bw,
            odr_hz: odr,
        }
        .group_delay_s()
            + 0.5 / odr
    };
    let want = delay(timing.accel_bandwidth_hz, timing.accel_odr_hz)
        - delay(timing.gyro_bandwidth_hz, timing.gyro_odr_hz);
    let data = session.measurements();
    let (_, d) = common::diagnose_all(&robot, &data);
    let names: Vec<&str> = d.found.iter().map(|f| f.name.as_str()).collect();
    eprintln!("found {names:?}; want δ {:.2} ms", want * 1e3);
    let f = d.found.first().expect("an effect is found");
    assert_eq!(f.name, "sensor_delay", "found {names:?}: {:?}", f.scores);
    let (v, s) = (&f.parameters[0].value, &f.parameters[0].sigma);
    eprintln!("δ {:.2} ± {:.2} ms", v * 1e3, s * 1e3);
    assert!(((v - want) / s).abs() < 4.0, "δ {v} ± {s} vs {want}");
}
