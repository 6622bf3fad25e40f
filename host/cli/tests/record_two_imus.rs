//! Two BNO055 on one simulated board (protocol 3), recorded over the
//! pseudo-terminal with the simulated AUBO, then calibrated: docs/model.md §9
//! session files and every parameter within 4σ of the hidden truth.
//!
//! Until the joint K-IMU fit lands, each IMU is calibrated alone: IMU 0 from
//! the session as recorded, IMU 1 from a copy whose `imu.csv` is `imu1.csv`
//! and against the truth's `imu1/` names without the prefix (the shared
//! robot errors and gravity as they are). [`calibrate_each_imu_alone`] is
//! the one place to switch to the joint fit.

use std::path::Path;

use rand::SeedableRng;
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::{record, RecordOptions};
use robimu_session::{Session, SessionMeta, Truth};
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};

/// Calibrates the one-IMU session `dir` and returns the worst
/// |error|/σ against `truth` (§5 names), with its name.
fn worst_z(dir: &Path, truth: &Truth) -> (f64, String, Vec<f64>) {
    let robot = Robot::aubo_i5();
    let session = Session::load(dir).unwrap();
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
        let t = truth
            .get(&spec.name)
            .unwrap_or_else(|| panic!("{} not in the truth", spec.name));
        let z = (cal.x[k] - t) / cal.sigma[k];
        if z.abs() > worst.0 {
            worst = (z.abs(), spec.name.clone());
        }
    }
    (worst.0, worst.1, cal.residual_rms.to_vec())
}

/// IMU `j`'s view of a §9 truth: its own `imu<j>/` entries under their §5
/// names, the shared ones as they are.
fn truth_of_imu(truth: &Truth, j: usize) -> Truth {
    let prefix = format!("imu{j}/");
    let own: Vec<(String, f64)> = truth
        .values
        .iter()
        .filter_map(|(n, v)| n.strip_prefix(&prefix).map(|n| (n.to_string(), *v)))
        .collect();
    let mut values: Vec<(String, f64)> = truth
        .values
        .iter()
        .filter(|(n, _)| !n.contains('/'))
        .filter(|(n, _)| j == 0 || !own.iter().any(|(o, _)| o == n))
        .cloned()
        .collect();
    if j > 0 {
        values.extend(own);
    }
    Truth { values }
}

/// Each IMU of the two-IMU session `dir` calibrated alone (see the module
/// documentation): the worst |error|/σ of each, against `truth`.
fn calibrate_each_imu_alone(dir: &Path, truth: &Truth) -> Vec<(f64, String, Vec<f64>)> {
    let imu1 = tempfile::tempdir().unwrap();
    for f in ["session.toml", "joints.csv"] {
        std::fs::copy(dir.join(f), imu1.path().join(f)).unwrap();
    }
    std::fs::copy(dir.join("imu1.csv"), imu1.path().join("imu.csv")).unwrap();
    vec![
        worst_z(dir, &truth_of_imu(truth, 0)),
        worst_z(imu1.path(), &truth_of_imu(truth, 1)),
    ]
}

#[test]
fn two_sensors_on_one_board_record_the_section_9_session_and_calibrate_within_4_sigma() {
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(23);
    let traj = random_walk(&robot, 30.0, 1.0, &mut rng).unwrap();
    let plan = Plan::from_spline(&traj, 250.0);
    let rig = SimRig::spawn(&SimRigConfig::drawn_two_imus(robot.clone(), 23)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = RecordOptions {
        imu_port: rig.imu_port().to_string(),
        extra_imu_ports: Vec::new(),
        baud: 921_600,
        robot_spec: RobotSpec::parse(&rig.robot_spec()).unwrap(),
        robot: robot.clone(),
        robot_name: "aubo_i5".into(),
        plan: Some(plan),
        duration: 0.0,
        out: dir.path().to_path_buf(),
        joint_rate: 125.0,
        rest: 1.0,
        sensor: SensorConfig::default(),
        interrupt: None,
    };
    let mut lines = 0;
    let summary = record(&opts, &mut |p| lines = lines.max(p.imus.len())).unwrap();
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
        assert!(imu.seq_gaps as f64 <= 0.005 * imu.samples as f64, "{imu:?}");
    }
    assert_eq!(p.imu_samples, p.imus[0].samples + p.imus[1].samples);
    assert_eq!(p.crc_errors, 0);

    // the §9 session: imu.csv, imu1.csv, [imu1]
    let session = Session::load(dir.path()).unwrap();
    assert_eq!(session.n_imus(), 2);
    let meta = SessionMeta::read(&dir.path().join("session.toml")).unwrap();
    let t1 = &meta.imu_tables[&1];
    assert_eq!(t1["sensor"].as_integer(), Some(1));
    assert_eq!(t1["pings"].as_str(), Some("pings.csv"));
    assert!(t1.get("clock").is_some(), "{t1:?}");
    assert_eq!(meta.imu.as_ref().unwrap()["sensor"].as_integer(), Some(0));
    let m = session.measurements();
    let imu1 = &m.extra_imus[0];
    assert!(
        imu1.t.windows(2).all(|w| w[1] > w[0]),
        "imu1 times increasing"
    );
    assert_eq!(imu1.temp.as_ref().map(Vec::len), Some(imu1.t.len()));

    for (j, (worst, name, rms)) in calibrate_each_imu_alone(dir.path(), &truth)
        .into_iter()
        .enumerate()
    {
        eprintln!("IMU {j}: worst |error|/σ = {worst:.2} ({name}); residual rms {rms:?}");
        assert!(
            worst < 4.0,
            "IMU {j}: {name} is {worst:.2} σ from the truth"
        );
        for r in rms {
            assert!(
                (0.9..1.1).contains(&r),
                "IMU {j}: whitened residual rms {r}"
            );
        }
    }
}
