//! The score test of a constant τ on simulated sessions: silent on exact
//! stamps, and on a lag drifting by D over the recording it finds the
//! segments' τ the simulation put there (−D/4 per segment: a sample
//! stamped late by lag(t) reads the motion at its stamp + τ − lag(t)),
//! with the σ given (the noise identification would take part of the
//! drift for noise).

use super::*;
use crate::pose_calibrate::simulate::test_support::{simulated, SessionSpec};
use crate::pose_calibrate::{calibrate_poses, draw_pose_truth, ImuTiming, PoseCalibrationOptions};
use faer::linalg::solvers::DenseSolveCore;

fn drift_of(seed: u64, timing: ImuTiming, identify_noise: bool) -> TauDrift {
    let spec = SessionSpec {
        timing,
        ..Default::default()
    };
    let data = simulated(&draw_pose_truth(500 + seed), 60.0, 600 + seed, seed, &spec).data;
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

/// The test before it was one user of [`super::super::score`]: segment k's
/// score and τ column from a linearisation of the problem with only its
/// IMU samples (no pose samples, each less τ's prior). An independent
/// route to the same numbers.
fn by_segment_linearisation(
    problem: &PoseProblem,
    theta: &[f64],
    factor: &ArrowFactor,
) -> (f64, Vec<f64>, Vec<f64>) {
    use robimu_model::pose_measurement::{POSE_PARAMS, TAU};
    use robimu_solver::{LeastSquares, PoseData};
    let (data, selected) = (problem.data(), problem.selected());
    let (n, m) = (theta.len(), SEGMENTS - 1);
    let nc = n - POSE_PARAMS;
    let w_tau = data.prior_sigma[TAU].powi(-2);
    let e_tau = theta[nc + TAU] - data.prior_mean[TAU];
    let (mut g, mut cols) = (Vec::new(), Vec::new());
    for k in 1..SEGMENTS {
        let range = selected.len() * k / SEGMENTS..selected.len() * (k + 1) / SEGMENTS;
        let seg = PoseData {
            pose_t: Vec::new(),
            pose_p: Vec::new(),
            pose_r: Vec::new(),
            imu_t: selected[range.clone()]
                .iter()
                .map(|&i| data.imu_t[i])
                .collect(),
            imu_z: selected[range].iter().map(|&i| data.imu_z[i]).collect(),
            prior_mean: data.prior_mean.clone(),
            prior_sigma: data.prior_sigma.clone(),
            ..*data
        };
        let mut p = PoseProblem::new(problem.base().clone(), seg).unwrap();
        p.begin_iteration(theta).unwrap();
        let mut a = p.new_matrix();
        let mut gk = vec![0.0; n];
        p.linearize(theta, &mut a, &mut gk).unwrap();
        let mut c: Vec<f64> = (0..n).map(|i| a.get(i, nc + TAU)).collect();
        c[nc + TAU] -= w_tau;
        g.push(gk[nc + TAU] - w_tau * e_tau);
        cols.push(c);
    }
    let v = faer::Mat::from_fn(m, m, |a, b| {
        let mut s = cols[b].clone();
        factor.solve_in_place(&mut s);
        let cross: f64 = cols[a].iter().zip(&s).map(|(x, y)| x * y).sum();
        if a == b {
            cols[a][nc + TAU] - cross
        } else {
            -cross
        }
    });
    let v_inv = v.llt(faer::Side::Lower).unwrap().inverse();
    let delta: Vec<f64> = (0..m)
        .map(|a| -(0..m).map(|b| v_inv[(a, b)] * g[b]).sum::<f64>())
        .collect();
    let s = -g.iter().zip(&delta).map(|(a, b)| a * b).sum::<f64>();
    let sigma = (0..m).map(|a| v_inv[(a, a)].sqrt()).collect();
    (s, delta, sigma)
}

#[test]
fn the_extra_column_sums_give_the_segment_linearisations_numbers() {
    for drift in [0.0, 0.030] {
        let spec = SessionSpec {
            timing: ImuTiming { jitter: 0.0, drift },
            ..Default::default()
        };
        let data = simulated(&draw_pose_truth(503), 30.0, 603, 3, &spec).data;
        let (cal, fit) = crate::pose_calibrate::fit_poses(
            &data,
            &[],
            &PoseCalibrationOptions::default(),
            |_| {},
            |_| {},
        )
        .unwrap();
        let got = cal.tau_drift.expect("formed");
        let (s, delta, sigma) = by_segment_linearisation(&fit.problem, &fit.theta, &fit.factor);
        let near = |a: f64, b: f64| (a - b).abs() <= 1e-7 * (a.abs() + b.abs()) + 1e-12;
        assert!(
            near(got.statistic, s),
            "drift {drift}: S {} vs {s}",
            got.statistic
        );
        for k in 0..SEGMENTS - 1 {
            assert!(near(got.delta[k], delta[k]), "δ {k}: {got:?} vs {delta:?}");
            assert!(near(got.delta_sigma[k], sigma[k]), "σ {k}");
        }
    }
}
