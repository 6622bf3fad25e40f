//! Robot and IMU accuracy against a simulated tracker (paper §9, Fig. 10–11):
//! the calibration improves both over the nominal parameters and compares
//! with the classical tracker-based calibrations.

use rand::SeedableRng;
use robimu_model::params::draw_truth;
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_session::Table;
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};
use robimu_workflows::plan::{plan, PlanOptions};
use robimu_workflows::simulate::{
    simulate, simulated_registration, static_poses, tracked_motion, SimulateOptions,
};
use robimu_workflows::tracker::row_from_pose;
use robimu_workflows::tracker_offset::{estimate_tracker_offset, to_session_clock, OffsetSearch};
use robimu_workflows::validate::{
    imu_accuracy, imu_position_and_gravity, robot_accuracy, ImuAccuracy, ImuGroundTruth,
    RobotAccuracy,
};

/// Robot length errors (eps_i_1..3, i < n): frozen in both calibrations (paper §9).
fn lengths(robot: &Robot, layout: &ParamLayout) -> Vec<usize> {
    layout
        .estimated_errors()
        .iter()
        .filter(|e| e.is_length(robot.dof()))
        .filter_map(|e| layout.eps_index(e.link, e.k))
        .collect()
}

/// A truth drawn from the priors (its length errors scaled by
/// `length_scale`), a 300 s calibration with lengths frozen, 250 static
/// tracker poses (150/100) and a separate 60 s tracked motion.
fn scenario(seed: u64, length_scale: f64) -> (RobotAccuracy, ImuAccuracy, Vec<f64>) {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut truth = draw_truth(&layout, &mut rng);
    let frozen = lengths(&robot, &layout);
    for &k in &frozen {
        truth[k] *= length_scale;
    }
    let sim = SimulateOptions::paper(&robot);
    let traj = random_walk(&robot, 300.0, 1.0, &mut rng).unwrap();
    let data = simulate(&robot, &layout, &truth, &traj, &sim, seed + 1).unwrap();
    let mut opts = CalibrateOptions::new(&robot);
    opts.frozen = frozen.clone();
    let cal = calibrate(&robot, &data, &opts, |_| {}).unwrap();

    let poses = static_poses(&robot, &layout, &truth, 250, &sim, seed + 2).unwrap();
    let acc = robot_accuracy(&robot, &layout, &cal.x, &poses, 150, &frozen).unwrap();
    assert_eq!((acc.train, acc.test), (150, 100));
    // the registration recovers the simulated tracker placement
    let reg = simulated_registration();
    for i in 0..3 {
        assert!((acc.registration.tracker_base.p[i] - reg.tracker_base.p[i]).abs() < 5e-3);
    }

    let eval = random_walk(&robot, 60.0, 1.0, &mut rng).unwrap();
    let data2 = simulate(&robot, &layout, &truth, &eval, &sim, seed + 3).unwrap();
    let markers = tracked_motion(
        &robot,
        &layout,
        &truth,
        &eval,
        &data2.joint_t,
        true,
        seed + 4,
    )
    .unwrap();
    let tracker = Table {
        columns: robimu_session::TRACKER_COLUMNS.map(String::from).to_vec(),
        t: data2.joint_t.clone(),
        values: markers.iter().flat_map(row_from_pose).collect(),
    };
    let (p_imu, g) = imu_position_and_gravity(&robot, &layout, &cal.x).unwrap();
    let gt = ImuGroundTruth::fit(&tracker, &acc.baseline.registration, p_imu, g, 30).unwrap();
    let imu = imu_accuracy(
        &layout,
        &layout.nominal(),
        &cal.x,
        &gt,
        &data2.imu_t,
        &data2.imu_z,
    )
    .unwrap();
    let (n, c, k) = (&acc.nominal, &acc.calibrated, &acc.classical);
    eprintln!(
        "length errors x{length_scale}: position mean [mm] nominal {:.3}, calibrated {:.3}, classical {:.3}; rotation mean [deg] {:.4}, {:.4}, {:.4}",
        1e3 * n.mean_position(),
        1e3 * c.mean_position(),
        1e3 * k.mean_position(),
        n.mean_rotation().to_degrees(),
        c.mean_rotation().to_degrees(),
        k.mean_rotation().to_degrees()
    );
    eprintln!(
        "  gyro rms [deg/s] {:.3}, {:.3}, {:.3}; accel rms [m/s^2] {:.3}, {:.3}, {:.3}",
        imu.nominal.rms_gyro().to_degrees(),
        imu.calibrated.rms_gyro().to_degrees(),
        imu.classical.rms_gyro().to_degrees(),
        imu.nominal.rms_accel(),
        imu.calibrated.rms_accel(),
        imu.classical.rms_accel()
    );
    (acc, imu, truth)
}

fn assert_imu_pattern(imu: &ImuAccuracy) {
    // calibrated below nominal, close to the classical IMU calibration
    assert!(imu.calibrated.rms_gyro() * 2.0 < imu.nominal.rms_gyro());
    assert!(imu.calibrated.rms_accel() * 2.0 < imu.nominal.rms_accel());
    assert!((imu.calibrated.rms_gyro() / imu.classical.rms_gyro() - 1.0).abs() < 0.1);
    assert!((imu.calibrated.rms_accel() / imu.classical.rms_accel() - 1.0).abs() < 0.1);
}

#[test]
fn robot_errors_from_the_priors_calibrated_accuracy_three_times_nominal() {
    let (acc, imu, _) = scenario(21, 1.0);
    let (n, c) = (&acc.nominal, &acc.calibrated);
    assert!(
        c.mean_position() * 3.0 < n.mean_position(),
        "calibrated position error not 3x below nominal"
    );
    assert!(c.mean_rotation() * 3.0 < n.mean_rotation());
    assert_imu_pattern(&imu);
}

/// With the frozen lengths at their true (nominal) values the classical
/// calibration's model is exact: held-out errors at the tracker's noise level.
#[test]
fn with_correct_frozen_lengths_the_classical_calibration_reaches_tracker_noise() {
    let (acc, imu, truth) = scenario(22, 0.0);
    let (n, c, k) = (&acc.nominal, &acc.calibrated, &acc.classical);
    assert!(c.mean_position() * 3.0 < n.mean_position());
    assert!(
        k.mean_position() < 3e-4,
        "classical {} m",
        k.mean_position()
    );
    assert!(k.mean_rotation() < 0.1f64.to_radians());
    assert!(
        acc.baseline.residual_rms < 1.5,
        "{}",
        acc.baseline.residual_rms
    );
    // and recovers the true angle errors
    for (ix, name, v) in &acc.baseline.estimated {
        assert!(
            (v - truth[*ix]).abs() < 0.02f64.to_radians(),
            "{name}: classical {v} vs true {}",
            truth[*ix]
        );
    }
    assert_imu_pattern(&imu);
}

/// The paper's comparison (§9, Fig. 10): lengths frozen in both calibrations
/// — frozen as the paper froze them, by a near-zero prior, so the truth drawn
/// from the priors has them at nominal — and the IMU calibration run on a
/// planned excitation (the paper's optimal trajectory), 600 s (at the
/// paper's 300 s the ratio is 1.0–1.4, 1.15 on average: see docs/guide/validation.md).
/// Held-out position error at least 3× below nominal and within 20 % of the
/// classical tracker calibration, on each of five drawn robots and on average.
#[test]
fn planned_calibration_is_within_20_percent_of_the_classical_tracker_calibration() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let frozen = lengths(&robot, &layout);
    let opts = PlanOptions {
        duration: 600.0,
        ..PlanOptions::default()
    };
    let excitation = plan(&robot, &opts, |_, _, _| {}).unwrap().spline;
    let sim = SimulateOptions::paper(&robot);
    let (mut sum_cal, mut sum_classical) = (0.0, 0.0);
    for seed in 21..26u64 {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut truth = draw_truth(&layout, &mut rng);
        for &k in &frozen {
            truth[k] = 0.0;
        }
        let data = simulate(&robot, &layout, &truth, &excitation, &sim, seed + 1).unwrap();
        let mut opts = CalibrateOptions::new(&robot);
        opts.frozen = frozen.clone();
        let cal = calibrate(&robot, &data, &opts, |_| {}).unwrap();
        let poses = static_poses(&robot, &layout, &truth, 250, &sim, seed + 2).unwrap();
        let acc = robot_accuracy(&robot, &layout, &cal.x, &poses, 150, &frozen).unwrap();
        let (n, c, k) = (
            acc.nominal.mean_position(),
            acc.calibrated.mean_position(),
            acc.classical.mean_position(),
        );
        eprintln!(
            "seed {seed}: position mean [mm] nominal {:.3}, calibrated {:.3}, classical {:.3} (ratio {:.3}); rotation mean [deg] {:.4}, {:.4}, {:.4}",
            1e3 * n,
            1e3 * c,
            1e3 * k,
            c / k,
            acc.nominal.mean_rotation().to_degrees(),
            acc.calibrated.mean_rotation().to_degrees(),
            acc.classical.mean_rotation().to_degrees()
        );
        assert!(c * 3.0 < n, "seed {seed}: calibrated {c} vs nominal {n}");
        assert!(c / k <= 1.4, "seed {seed}: calibrated {c} vs classical {k}");
        assert!(acc.calibrated.mean_rotation() <= 1.2 * acc.classical.mean_rotation());
        sum_cal += c;
        sum_classical += k;
    }
    assert!((sum_cal / sum_classical - 1.0).abs() <= 0.2);
}

/// The tracker's own clock (paper §9: the tracker is first aligned with the
/// robot data): tracker timestamps shifted by δ, the offset found from the
/// angular speeds within 2 ms, and the IMU accuracy with the estimated δ
/// applied within 3 % of the unshifted case. The IMU accuracy uses the true
/// parameters as the "calibration" and the true tracker placement (the
/// ground truth is what is tested here, not the calibration).
#[test]
fn tracker_time_offset_is_recovered_and_the_imu_accuracy_is_unchanged() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(31);
    let truth = draw_truth(&layout, &mut rng);
    let sim = SimulateOptions::paper(&robot);
    let eval = random_walk(&robot, 60.0, 1.0, &mut rng).unwrap();
    let data = simulate(&robot, &layout, &truth, &eval, &sim, 32).unwrap();
    let markers = tracked_motion(&robot, &layout, &truth, &eval, &data.joint_t, true, 33).unwrap();
    let values: Vec<f64> = markers.iter().flat_map(row_from_pose).collect();
    let table = |shift: f64| Table {
        columns: robimu_session::TRACKER_COLUMNS.map(String::from).to_vec(),
        t: data.joint_t.iter().map(|t| t + shift).collect(),
        values: values.clone(),
    };
    let reg = simulated_registration();
    let (p_imu, g) = imu_position_and_gravity(&robot, &layout, &truth).unwrap();
    let accuracy = |tracker: &Table| {
        let gt = ImuGroundTruth::fit(tracker, &reg, p_imu, g, 30).unwrap();
        imu_accuracy(
            &layout,
            &layout.nominal(),
            &truth,
            &gt,
            &data.imu_t,
            &data.imu_z,
        )
        .unwrap()
    };
    let reference = accuracy(&table(0.0));
    let search = OffsetSearch::default();
    let span = (data.joint_t[0], *data.joint_t.last().unwrap());
    let nominal = layout.nominal();
    for (shift, x, what) in [
        (0.137, &truth, "true"),
        (0.137, &nominal, "nominal"),
        (0.0, &truth, "true"),
        (-3.21, &truth, "true"),
        (1000.137, &truth, "true"),
    ] {
        let tracker = table(shift);
        let est = estimate_tracker_offset(
            &robot,
            &layout,
            x,
            &tracker,
            &data.joint_t,
            &data.joint_q,
            &search,
        )
        .unwrap();
        eprintln!(
            "shift {shift} s ({what} kinematics): delta {:.3} ms off, R² {:.5}, rms {:.3} deg/s, overlap {:.1} s",
            1e3 * (est.delta - shift),
            est.r_squared,
            est.rms.to_degrees(),
            est.overlap
        );
        assert!((est.delta - shift).abs() < 2e-3, "shift {shift}: {est:?}");
        assert!(est.r_squared > 0.9, "{est:?}");
        let imu = accuracy(&to_session_clock(&tracker, est.delta, span).unwrap());
        for (a, b, name) in [
            (&imu.nominal, &reference.nominal, "nominal"),
            (&imu.calibrated, &reference.calibrated, "calibrated"),
            (&imu.classical, &reference.classical, "classical"),
        ] {
            eprintln!(
                "  {name}: gyro {:.4} vs {:.4} deg/s, accel {:.4} vs {:.4} m/s^2",
                a.rms_gyro().to_degrees(),
                b.rms_gyro().to_degrees(),
                a.rms_accel(),
                b.rms_accel()
            );
            assert!(
                (a.rms_gyro() / b.rms_gyro() - 1.0).abs() < 0.03,
                "{name} gyro"
            );
            assert!(
                (a.rms_accel() / b.rms_accel() - 1.0).abs() < 0.03,
                "{name} accel"
            );
        }
    }
    // left on the tracker clock, the ground truth is 137 ms late: the
    // calibrated errors grow far beyond the aligned ones
    let late = accuracy(&table(0.137));
    assert!(late.calibrated.rms_gyro() > 3.0 * reference.calibrated.rms_gyro());

    // bad input: a different motion, a too short one, no overlap
    let other = random_walk(&robot, 60.0, 1.0, &mut rng).unwrap();
    let wrong = tracked_motion(&robot, &layout, &truth, &other, &data.joint_t, true, 34).unwrap();
    let wrong = Table {
        values: wrong.iter().flat_map(row_from_pose).collect(),
        ..table(0.137)
    };
    let e = estimate_tracker_offset(
        &robot,
        &layout,
        &truth,
        &wrong,
        &data.joint_t,
        &data.joint_q,
        &search,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("does not follow"), "{e}");
    let short = Table {
        t: data.joint_t[..480].to_vec(),
        values: values[..7 * 480].to_vec(),
        ..table(0.0)
    };
    let e = estimate_tracker_offset(
        &robot,
        &layout,
        &truth,
        &short,
        &data.joint_t,
        &data.joint_q,
        &search,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("too short"), "{e}");
    let e = to_session_clock(&table(0.137), 100.0, span)
        .unwrap_err()
        .to_string();
    assert!(e.contains("does not overlap"), "{e}");
}
