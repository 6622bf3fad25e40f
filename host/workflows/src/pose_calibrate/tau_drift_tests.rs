//! The score test of a constant τ on simulated sessions: silent on exact
//! stamps, and on a lag drifting by D over the recording it finds the
//! segments' τ the simulation put there (−D/4 per segment: a sample
//! stamped late by lag(t) reads the motion at its stamp + τ − lag(t)).

use super::*;
use crate::pose_calibrate::{
    calibrate_poses, draw_pose_truth, random_pose_motion, simulate_pose_session, ImuTiming,
    PoseCalibrationOptions, PoseNoise,
};

fn drift_of(seed: u64, timing: ImuTiming) -> TauDrift {
    let truth = draw_pose_truth(500 + seed);
    let motion = random_pose_motion(60.0, 600 + seed).unwrap();
    let mut data = simulate_pose_session(
        &truth,
        &motion,
        15.0,
        0.003,
        100.0,
        &PoseNoise::default(),
        seed,
    )
    .unwrap();
    timing.apply(&mut data, seed).unwrap();
    let cal = calibrate_poses(&data, &PoseCalibrationOptions::default()).unwrap();
    cal.tau_drift.expect("the test is formed")
}

#[test]
fn a_constant_tau_passes_and_a_drifting_lag_is_found_where_it_is() {
    let clean = drift_of(1, ImuTiming::default());
    assert!(clean.p_value >= P_DOUBT, "{clean:?}");
    let drift = 0.030;
    let messy = drift_of(1, ImuTiming { jitter: 0.0, drift });
    assert!(messy.p_value < 1e-6, "{messy:?}");
    for k in 0..SEGMENTS - 1 {
        let want = -drift / SEGMENTS as f64 * (k + 1) as f64;
        let (got, s) = (messy.delta[k], messy.delta_sigma[k]);
        assert!(
            (got - want).abs() < 4.0 * s + 0.1 * want.abs(),
            "segment {}: {got:.4} ± {s:.4} s, simulated {want:.4} s",
            k + 1
        );
    }
}
