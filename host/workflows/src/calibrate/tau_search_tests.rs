//! The τ search ([`crate::time_offset`]) on sessions whose knots the
//! calibration chooses ([`super::choose_knots`]); here rather than in
//! `time_offset` so that module never names the calibration that uses it.

use super::choose_knots;
use crate::body_rate::BodyRate;
use crate::simulate::{random_session, SimulateOptions};
use crate::time_offset::{find_tau, TauSearch};
use robimu_model::{MeasurementModel, ParamLayout, Robot};

/// The coarse scan on 500 of the 4000 samples, its best local minima
/// refitted on all, finds the τ of the coarse scan on all 4000 (the
/// former search), bit for bit, on simulated sessions whose τ is drawn
/// from its prior (±1 s), and that τ is the truth's to a few ms.
#[test]
fn thinned_coarse_scan_finds_the_full_scans_tau() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let sim = SimulateOptions::paper(&robot);
    let model = MeasurementModel::new(&robot, &layout, &layout.nominal()).unwrap();
    let rate = BodyRate::new(&robot, &model);
    let thinned = TauSearch::default();
    let full = TauSearch {
        coarse_samples: thinned.max_samples,
        ..thinned
    };
    for seed in 0..6 {
        let s = random_session(&robot, 60.0, 1.0, &sim, 500 + seed).unwrap();
        let data = &s.data;
        let tf = choose_knots(data, robot.dof(), robot.sigma_q(), 3, None).unwrap();
        let gyro: Vec<[f64; 3]> = data.imu_z.iter().map(|z| [z[3], z[4], z[5]]).collect();
        let a = find_tau(&rate, &tf.spline, &data.imu_t, &gyro, &thinned).unwrap();
        let b = find_tau(&rate, &tf.spline, &data.imu_t, &gyro, &full).unwrap();
        assert_eq!(a, b, "seed {seed}");
        let truth = s.truth[layout.offsets().tau];
        assert!(
            (a.tau - truth).abs() < 5e-3,
            "seed {seed}: {} vs {truth}",
            a.tau
        );
    }
}
