//! The score test of a constant τ on simulated sessions: silent on exact
//! stamps, and on a lag drifting by D over the recording it finds the
//! segments' τ the simulation put there (−D/4 per segment: a sample
//! stamped late by lag(t) reads the motion at its stamp + τ − lag(t)),
//! with the σ given (the noise identification would take part of the
//! drift for noise).

use super::*;
use crate::pose_calibrate::{
    calibrate_poses, draw_pose_truth, random_pose_motion, simulate_pose_session, ImuTiming,
    PoseCalibrationOptions, PoseNoise,
};

fn drift_of(seed: u64, timing: ImuTiming, identify_noise: bool) -> TauDrift {
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
    let opts = PoseCalibrationOptions {
        identify_noise,
        ..Default::default()
    };
    let cal = calibrate_poses(&data, &opts).unwrap();
    cal.tau_drift.expect("the test is formed")
}

#[test]
fn a_constant_tau_passes_and_a_drifting_lag_is_found_where_it_is() {
    let clean = drift_of(1, ImuTiming::default(), true);
    assert!(clean.p_value >= P_DOUBT, "{clean:?}");
    let drift = 0.030;
    let timing = ImuTiming { jitter: 0.0, drift };
    // the noise identification takes part of the drift for noise (σ_r
    // doubles here): the test still rejects, the segments' τ are
    // pulled towards 0 (−5, −13, −20 ms); located with the σ given
    let identified = drift_of(1, timing, true);
    assert!(identified.p_value < 1e-6, "{identified:?}");
    let messy = drift_of(1, timing, false);
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
