//! Two IMUs recorded over pseudo-terminals with the simulated AUBO
//! (docs/model.md §9), then calibrated jointly: two BNO055 on one board
//! (protocol 3's sensor field), two boards of one sensor each (one clock
//! fit per board, one board vanishing mid-run), and `robimu demo --imus 2`.
//! Every one of the 76 parameters within 4σ of the hidden truth.
//!
//! These run in real time (the recordings of 32 s take about 35 s each).

use std::path::Path;
use std::time::Duration;

use rand::SeedableRng;
use robimu_hil::rig::{ExtraBoard, SimRig, SimRigConfig};
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::{record, RecordError, RecordOptions};
use robimu_session::result::CalibrationResult;
use robimu_session::{Session, SessionMeta, Truth};
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};

mod common;
use common::{robimu, robimu_ok, s};

/// The joint fit (docs/model.md §9) of the `n_imus`-IMU session `dir`
/// against `truth`: asserts every parameter of
/// [`ParamLayout::with_imus`] within 4σ and every whitened residual RMS
/// within 10 % of 1, printing the worst.
fn joint_fit_within_4_sigma(dir: &Path, truth: &Truth, n_imus: usize, label: &str) {
    let robot = Robot::aubo_i5();
    let session = Session::load(dir).unwrap();
    assert_eq!(session.n_imus(), n_imus);
    let layout = ParamLayout::with_imus(&robot, n_imus);
    let x_true = truth.vector(&layout).unwrap();
    let cal = calibrate(
        &robot,
        &session.measurements(),
        &CalibrateOptions::new(&robot),
        |_| {},
    )
    .unwrap();
    assert_eq!(cal.x.len(), layout.len());
    assert_eq!(layout.len(), 20 + 28 * n_imus);
    let (mut worst, mut name) = (0.0, "");
    for (k, spec) in layout.specs().iter().enumerate() {
        let z = (cal.x[k] - x_true[k]) / cal.sigma[k];
        assert!(
            z.is_finite(),
            "{label}: {} has σ {}",
            spec.name,
            cal.sigma[k]
        );
        if z.abs() > worst {
            (worst, name) = (z.abs(), spec.name.as_str());
        }
    }
    eprintln!(
        "{label}: joint fit of {} parameters, worst |error|/σ = {worst:.2} ({name}); residual rms {:?}",
        layout.len(),
        cal.residual_rms
    );
    assert!(
        worst < 4.0,
        "{label}: {name} is {worst:.2} σ from the truth"
    );
    for r in &cal.residual_rms {
        assert!((0.9..1.1).contains(r), "{label}: whitened residual rms {r}");
    }
}

fn options(rig: &SimRig, out: &Path, plan: Option<Plan>, duration: f64) -> RecordOptions {
    RecordOptions {
        imu_port: rig.imu_port().to_string(),
        extra_imu_ports: rig.extra_imu_ports(),
        baud: 921_600,
        robot_spec: RobotSpec::parse(&rig.robot_spec()).unwrap(),
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

/// A 30 s random walk of the AUBO i5 (seeded), sampled as a plan.
fn plan(seed: u64) -> Plan {
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    Plan::from_spline(&random_walk(&robot, 30.0, 1.0, &mut rng).unwrap(), 250.0)
}

/// The drift of segment 0 in a session.toml IMU table's `clock` list.
fn table_drift_ppm(table: &toml::Table) -> f64 {
    table["clock"].as_array().unwrap()[0]["drift_ppm"]
        .as_float()
        .unwrap()
}

/// Every time of every IMU strictly increasing and with a temperature.
fn check_imu_times(session: &Session) {
    let m = session.measurements();
    for j in 0..session.n_imus() {
        let imu = m.imu(j);
        assert!(imu.t.len() > 100, "IMU {j}: {} samples", imu.t.len());
        assert!(
            imu.t.windows(2).all(|w| w[1] > w[0]),
            "IMU {j} times not increasing"
        );
        assert_eq!(imu.temp.map(<[f64]>::len), Some(imu.t.len()), "IMU {j}");
    }
}

#[test]
fn two_sensors_on_one_board_record_the_section_9_session_and_calibrate_jointly_within_4_sigma() {
    let _slot = common::real_time_slot();
    let rig = SimRig::spawn(&SimRigConfig::drawn_two_imus(Robot::aubo_i5(), 23)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut lines = 0;
    let summary = record(&options(&rig, dir.path(), Some(plan(23)), 0.0), &mut |p| {
        lines = lines.max(p.imus.len())
    })
    .unwrap();
    let truth = rig.truth().clone();
    drop(rig);
    // the hidden truth of both sensors, §9 names
    std::fs::write(dir.path().join("truth.toml"), truth.to_toml()).unwrap();
    assert!(truth.get("imu1/k_a_x").is_some() && truth.get("imu1/eps_6_1").is_some());
    assert_ne!(
        truth.get("imu1/eps_6_1"),
        truth.get("eps_6_1"),
        "another lever arm"
    );

    // one progress line per IMU, one board and its clock fit
    assert_eq!(lines, 2);
    let p = &summary.progress;
    assert_eq!(p.imus.len(), 2);
    assert_eq!(summary.boards.len(), 1);
    assert_eq!(summary.boards[0].devices.len(), 2);
    let (_, fit) = summary.clock[0];
    assert!(
        (fit.drift_ppm() - 48.7).abs() < 2.0,
        "drift {}",
        fit.drift_ppm()
    );
    for imu in &p.imus {
        assert!(imu.samples as f64 > 118.0 * summary.duration, "{imu:?}");
        // every slot a sample or one the board counted as missed
        common::assert_every_slot_accounted(
            imu.samples,
            imu.seq_gaps,
            imu.device_dropped,
            f64::from(SensorConfig::default().sample_rate_hz),
            summary.duration,
        );
    }
    assert_eq!(p.imu_samples, p.imus[0].samples + p.imus[1].samples);
    assert_eq!((p.crc_errors, p.bad_frames), (0, 0), "{p:?}");

    // the §9 session: imu.csv, imu1.csv, [imu1]
    let session = Session::load(dir.path()).unwrap();
    assert_eq!(session.n_imus(), 2);
    check_imu_times(&session);
    let meta = SessionMeta::read(&dir.path().join("session.toml")).unwrap();
    let t1 = &meta.imu_tables[&1];
    assert_eq!(t1["sensor"].as_integer(), Some(1));
    assert_eq!(t1["board"].as_integer(), Some(0));
    assert_eq!(t1["pings"].as_str(), Some("pings.csv"));
    assert!(t1.get("clock").is_some(), "{t1:?}");
    assert_eq!(meta.imu.as_ref().unwrap()["sensor"].as_integer(), Some(0));

    joint_fit_within_4_sigma(dir.path(), &truth, 2, "one board, two sensors");
}

/// The AUBO rig with a second board of one sensor, its clock 3.456 s ahead
/// and 31.2 ppm slow (the first board's: 1.234 s, 48.7 ppm fast).
fn two_board_rig(seed: u64) -> SimRig {
    let config = SimRigConfig::drawn(Robot::aubo_i5(), seed);
    let extra = ExtraBoard::drawn(&config.robot, seed ^ 0xB0A2D, 3_456_000, -31.2);
    SimRig::spawn_boards(&config, &[extra]).unwrap()
}

/// `robimu record --imu PORT --imu PORT2` from two boards of one sensor
/// each: imu.csv and imu1.csv, one ping log and clock fit per board (each
/// its own drift), and the joint fit within 4σ.
#[test]
fn two_boards_record_one_clock_fit_each_and_calibrate_jointly_within_4_sigma() {
    let _slot = common::real_time_slot();
    let rig = two_board_rig(41);
    let dir = tempfile::tempdir().unwrap();
    let plan_dir = dir.path().join("plan");
    std::fs::create_dir_all(&plan_dir).unwrap();
    plan(41).write_csv(&plan_dir.join("plan.csv")).unwrap();
    let out = dir.path().join("session");
    let ports = rig.extra_imu_ports();
    assert_eq!(ports.len(), 1);
    let run = robimu_ok([
        "record",
        "--imu",
        rig.imu_port(),
        "--imu",
        ports[0].as_str(),
        "--robot",
        rig.robot_spec().as_str(),
        "--plan",
        s(&plan_dir),
        "--out",
        s(&out),
    ]);
    let truth = rig.truth().clone();
    drop(rig);
    eprintln!("{}", run.stdout);
    // the summary: one line per IMU, each board's clock fit with its drift
    let line = |start: &str| -> String {
        let found = run.stdout.lines().find(|l| l.starts_with(start));
        found
            .unwrap_or_else(|| panic!("no `{start}`:\n{}", run.stdout))
            .to_string()
    };
    assert!(line("IMU 1 (imu1.csv, ").contains(&format!("{} sensor 0", ports[0])));
    let board1 = line(&format!("board {} clock segment 0", ports[0]));
    let drift = |l: &str| -> f64 {
        let rest = &l[l.find("drift ").unwrap() + 6..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    assert!((drift(&board1) + 31.2).abs() < 2.0, "{board1}");
    let board0 = line("clock segment 0");
    assert!((drift(&board0) - 48.7).abs() < 2.0, "{board0}");
    assert!(truth.get("imu1/k_w_z").is_some() && truth.get("imu2/k_w_z").is_none());

    let session = Session::load(&out).unwrap();
    assert_eq!(session.n_imus(), 2);
    check_imu_times(&session);
    for f in ["imu.csv", "imu1.csv", "pings.csv", "pings1.csv"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let meta = SessionMeta::read(&out.join("session.toml")).unwrap();
    let t0 = meta.imu.as_ref().unwrap();
    let t1 = &meta.imu_tables[&1];
    assert_eq!(t0["board"].as_integer(), Some(0));
    assert_eq!(t1["board"].as_integer(), Some(1));
    assert_eq!(t1["sensor"].as_integer(), Some(0));
    assert_eq!(t1["pings"].as_str(), Some("pings1.csv"));
    assert_eq!(t1["port"].as_str(), Some(ports[0].as_str()), "{t1:?}");
    // each board's own clock fit: its own drift
    let (d0, d1) = (table_drift_ppm(t0), table_drift_ppm(t1));
    eprintln!("clock drift: board 0 {d0:+.2} ppm, board 1 {d1:+.2} ppm");
    assert!((d0 - 48.7).abs() < 2.0, "board 0 drift {d0}");
    assert!((d1 + 31.2).abs() < 2.0, "board 1 drift {d1}");
    // about as many samples from each board, at ≥ 118 Hz over ~32 s
    let m = session.measurements();
    let (n0, n1) = (m.imu(0).t.len() as f64, m.imu(1).t.len() as f64);
    assert!(
        n0 > 118.0 * 31.5 && n1 > 118.0 * 31.5,
        "{n0} and {n1} samples"
    );
    // the boards' times on one session clock: they span the same interval
    let (a, b) = (m.imu(0).t, m.imu(1).t);
    assert!((a[0] - b[0]).abs() < 0.3, "starts {} vs {}", a[0], b[0]);
    let (ea, eb) = (a[a.len() - 1], b[b.len() - 1]);
    assert!((ea - eb).abs() < 0.3, "ends {ea} vs {eb}");

    joint_fit_within_4_sigma(&out, &truth, 2, "two boards");
}

/// Board 1 vanishing 3 s into the recording: the recording ends with the
/// error naming that board's port (and, from the program, a non-zero
/// exit), and everything recorded so far from both boards and the robot is
/// kept as a §9 session.
#[test]
fn one_of_two_boards_vanishing_ends_the_recording_with_its_name_and_keeps_all_data() {
    let _slot = common::real_time_slot();
    let rig = two_board_rig(42);
    let dir = tempfile::tempdir().unwrap();
    let opts = options(&rig, dir.path(), None, 10.0);
    let board1 = &rig.boards[0];
    // about 3 s of both boards recorded (not 3 s of wall time: on a loaded
    // machine the recording may start late), then the first one vanishes
    let err = record(&opts, &mut |p| {
        if p.imus.iter().all(|i| i.samples >= 450) {
            board1.vanish();
        }
    })
    .unwrap_err();
    let text = err.to_string();
    eprintln!("{text}");
    let port1 = board1.port_path();
    assert!(
        text.contains("serial port") && text.contains(port1) && text.contains("kept in"),
        "{text}"
    );
    assert!(!text.contains(&format!("{} ", rig.imu_port())), "{text}");
    let RecordError::Aborted { summary, .. } = err else {
        panic!("{text}")
    };
    assert!(summary.duration < 5.0, "{}", summary.duration);
    assert_eq!(summary.boards.len(), 2);
    let session = Session::load(dir.path()).unwrap();
    assert_eq!(session.n_imus(), 2);
    check_imu_times(&session);
    let m = session.measurements();
    // about 3 s of each board and of the robot
    for j in 0..2 {
        assert!(m.imu(j).t.len() > 250, "IMU {j}: {}", m.imu(j).t.len());
    }
    assert_eq!(
        (m.imu(0).t.len() + m.imu(1).t.len()) as u64,
        summary.progress.imu_samples
    );
    assert!(m.joint_t.len() > 250, "{}", m.joint_t.len());
    drop(rig);

    // the program: the same, exit non-zero with the error
    let rig = two_board_rig(43);
    let out = dir.path().join("cli");
    let ports = rig.extra_imu_ports();
    let run = std::thread::scope(|sc| {
        sc.spawn(|| {
            std::thread::sleep(Duration::from_secs(3));
            rig.boards[0].vanish();
        });
        robimu([
            "record",
            "--imu",
            rig.imu_port(),
            "--imu",
            ports[0].as_str(),
            "--robot",
            rig.robot_spec().as_str(),
            "--no-move",
            "--duration",
            "10",
            "--out",
            s(&out),
        ])
    });
    run.assert_fails(&[ports[0].as_str(), "kept in"]);
    let session = Session::load(&out).unwrap();
    assert_eq!(session.n_imus(), 2);
    check_imu_times(&session);
}

/// `robimu demo --imus 2 --ideal`: two sensors on the one simulated board,
/// recorded, calibrated jointly, reported, and every one of the 76
/// parameters checked against the truth.
#[test]
fn demo_with_two_imus_records_calibrates_jointly_and_checks_the_truth() {
    let _slot = common::real_time_slot();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let run = robimu_ok([
        "demo",
        "--imus",
        "2",
        "--ideal",
        "--duration",
        "20",
        "--out",
        s(&out),
    ]);
    eprintln!("{}", run.stdout);
    assert!(run.stdout.contains("0 CRC errors"), "{}", run.stdout);
    assert!(run.stdout.contains("IMU 1 (imu1.csv, "), "{}", run.stdout);
    assert!(
        run.stdout.contains("2 IMUs fitted jointly"),
        "{}",
        run.stdout
    );
    let session = out.join("session");
    let s2 = Session::load(&session).unwrap();
    assert_eq!(s2.n_imus(), 2);
    let result = CalibrationResult::read(&session.join("result.json")).unwrap();
    assert_eq!(result.parameters.len(), 76);
    // the truth check compares every estimated parameter of both IMUs
    let check: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("report/truth_check.json")).unwrap(),
    )
    .unwrap();
    let rows = check["parameters"].as_array().unwrap();
    let estimated = result.parameters.iter().filter(|p| !p.frozen).count();
    assert_eq!(rows.len(), estimated);
    assert!(rows.iter().any(|r| r["name"] == "imu1/k_a_x"));
    let truth = Truth::read(&session.join("truth.toml")).unwrap();
    for r in rows {
        let name = r["name"].as_str().unwrap();
        let p = result.parameter(name).unwrap();
        let z = (p.value - truth.get(name).unwrap()) / p.sigma;
        assert!((z - r["z"].as_f64().unwrap()).abs() < 1e-9, "{name}");
    }
    assert_eq!(check["all_within"], true, "{}", run.stdout);
    assert!(
        run.stdout.contains("truth check: every one of"),
        "{}",
        run.stdout
    );

    // the fast twin and the realistic twin read one sensor: named errors
    let run = robimu([
        "demo",
        "--imus",
        "2",
        "--fast",
        "--ideal",
        "--duration",
        "10",
    ]);
    run.assert_fails(&["--imus 2", "--fast"]);
    let run = robimu(["demo", "--imus", "2", "--duration", "10"]);
    run.assert_fails(&["--imus 2", "--ideal"]);
    let run = robimu(["demo", "--imus", "3", "--ideal"]);
    run.assert_fails(&["--imus"]);
}
