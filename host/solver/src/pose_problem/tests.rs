//! The pose problem's gradient and Gauss–Newton matrix against finite
//! differences of its cost and residuals, and the τ-dependent selection.

use super::*;
use rand::{Rng, SeedableRng};
use robimu_model::geom::exp_so3;
use robimu_model::pose_measurement::pose_param_specs;
use robimu_model::Knots;

/// A small problem: a random spline over [0, 2] s, poses at 20 Hz, IMU at
/// 40 Hz (outputs arbitrary: only derivatives are tested).
pub(super) fn small_problem() -> (PoseProblem, Vec<f64>) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let knots = Knots::uniform(0.0, 2.0, 0.25, 3).unwrap();
    let m = knots.num_coeffs();
    let pos: Vec<V3> = (0..m)
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.2..0.2)))
        .collect();
    let mut r = exp_so3([1.0, 0.5, -0.3]);
    let rot: Vec<M3> = (0..m)
        .map(|_| {
            r = mul_mm(
                &r,
                &exp_so3(std::array::from_fn(|_| rng.random_range(-0.5..0.5))),
            );
            r
        })
        .collect();
    let base = PoseSpline::new(knots, &pos, &rot).unwrap();
    let pose_t: Vec<f64> = (0..=40).map(|k| k as f64 * 0.05).collect();
    let pose_p = pose_t
        .iter()
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.2..0.2)))
        .collect();
    let pose_r = pose_t
        .iter()
        .map(|_| exp_so3(std::array::from_fn(|_| rng.random_range(-2.0..2.0))))
        .collect();
    let imu_t: Vec<f64> = (0..80).map(|k| k as f64 * 0.025 + 0.003).collect();
    let imu_z = imu_t
        .iter()
        .map(|_| std::array::from_fn(|_| rng.random_range(-5.0..5.0)))
        .collect();
    let specs = pose_param_specs([0.5, 0.2, -1.0], [0.4, -0.3, 2.0]);
    let data = PoseData {
        pose_t,
        pose_p,
        pose_r,
        imu_t,
        imu_z,
        sigma_p: 0.01,
        sigma_r: 0.02,
        sigma_z: [0.3, 0.2, 0.2, 0.01, 0.01, 0.01],
        prior_mean: specs.iter().map(|s| s.nominal).collect(),
        prior_sigma: specs.iter().map(|s| s.sigma).collect(),
    };
    let p = PoseProblem::new(base, data).unwrap();
    let mut theta: Vec<f64> = (0..p.n_band())
        .map(|_| rng.random_range(-0.1..0.1))
        .collect();
    let mut x: Vec<f64> = specs
        .iter()
        .map(|s| s.nominal + 0.05 * rng.random_range(-1.0..1.0))
        .collect();
    x[TAU] = 0.13;
    theta.extend(x);
    (p, theta)
}

/// [`small_problem`] with a second IMU (its own times, samples, σ_z and
/// 28 parameters, MODEL.md §9): x of 58.
pub(super) fn two_imu_problem() -> (PoseProblem, Vec<f64>) {
    let (p, theta) = small_problem();
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let imu_t: Vec<f64> = (0..70).map(|k| k as f64 * 0.028 + 0.011).collect();
    let imu_z = imu_t
        .iter()
        .map(|_| std::array::from_fn(|_| rng.random_range(-5.0..5.0)))
        .collect();
    let more = PoseImuData {
        imu_t,
        imu_z,
        sigma_z: [0.2, 0.3, 0.25, 0.02, 0.01, 0.015],
    };
    let specs = pose_param_specs([-0.5, 1.2, 0.3], [0.1, 0.3, -2.0]);
    let mut data = p.data.clone();
    let own = |k: &usize| !(3..5).contains(k);
    data.prior_mean
        .extend((0..30).filter(own).map(|k| specs[k].nominal));
    data.prior_sigma
        .extend((0..30).filter(own).map(|k| specs[k].sigma));
    let two = PoseProblem::with_imus(p.base.clone(), data, vec![more]).unwrap();
    let mut theta = theta;
    let x1: Vec<f64> = (0..30)
        .filter(own)
        .map(|k| specs[k].nominal + 0.05 * rng.random_range(-1.0..1.0))
        .collect();
    theta.extend(x1);
    theta[two.n_band() + 30 + TAU - 2] = -0.07;
    (two, theta)
}

#[test]
fn gradient_and_normal_matrix_match_finite_differences() {
    check_derivatives(small_problem());
}

#[test]
fn two_imus_gradient_and_normal_matrix_match_finite_differences() {
    let (p, theta) = two_imu_problem();
    assert_eq!((p.n_imus(), p.n_x()), (2, 58));
    check_derivatives((p, theta));
}

/// IMU 1's residuals in the 2-IMU problem are those of a one-IMU problem
/// with IMU 1's samples as IMU 0 and its 30-vector as x; IMU 0's and the
/// poses' are the one-IMU problem's of IMU 0.
#[test]
fn two_imus_residuals_are_each_imus_own() {
    let (mut p, theta) = two_imu_problem();
    p.begin_iteration(&theta).unwrap();
    let nb = p.n_band();
    let r = p.residuals(&theta).unwrap();
    let one = |j: usize| {
        let imu = p.imu(j);
        let mut d = p.data.clone();
        (d.imu_t, d.imu_z, d.sigma_z) = (imu.t.to_vec(), imu.z.to_vec(), *imu.sigma_z);
        let x = imu_view(p.x(&theta), j);
        d.prior_mean = imu_view(&p.data.prior_mean, j).to_vec();
        d.prior_sigma = imu_view(&p.data.prior_sigma, j).to_vec();
        let mut q = PoseProblem::new(p.base.clone(), d).unwrap();
        let mut th = theta[..nb].to_vec();
        th.extend(x);
        q.begin_iteration(&th).unwrap();
        (q.selected().len(), q.residuals(&th).unwrap())
    };
    let (n0, r0) = one(0);
    let (n1, r1) = one(1);
    assert_eq!((n0, n1), (p.selected_of(0).len(), p.selected_of(1).len()));
    assert!(n1 > 50 && n1 != n0, "{n0} {n1}");
    let np = 6 * p.data.pose_t.len();
    assert_eq!(r[..np + 6 * n0], r0[..np + 6 * n0]);
    assert_eq!(r[np + 6 * n0..np + 6 * (n0 + n1)], r1[np..np + 6 * n1]);
    assert_eq!(r.len(), np + 6 * (n0 + n1) + 58);
}

/// Each IMU's unwhitened residuals (measured minus predicted, at its
/// selected samples' times) are −σ_z times its whitened residuals in
/// [`PoseProblem::residuals`].
#[test]
fn imu_residuals_are_the_whitened_ones_unwhitened() {
    let (mut p, theta) = two_imu_problem();
    p.begin_iteration(&theta).unwrap();
    let r = p.residuals(&theta).unwrap();
    let mut at = 6 * p.data.pose_t.len();
    for j in 0..2 {
        let (imu, got) = (p.imu(j), p.imu_residuals(&theta, j).unwrap());
        assert_eq!(got.len(), p.selected_of(j).len());
        for ((t, e), &i) in got.iter().zip(p.selected_of(j)) {
            assert_eq!(*t, imu.t[i]);
            for c in 0..6 {
                let want = -r[at + c] * imu.sigma_z[c];
                assert!((e[c] - want).abs() < 1e-12 * (1.0 + want.abs()), "{j} {c}");
            }
            at += 6;
        }
    }
}

fn check_derivatives((mut p, theta): (PoseProblem, Vec<f64>)) {
    p.begin_iteration(&theta).unwrap();
    let n = p.n_unknowns();
    let mut a = p.new_matrix();
    let mut g = vec![0.0; n];
    let cost = p.linearize(&theta, &mut a, &mut g).unwrap();
    assert!((cost - p.cost(&theta).unwrap()).abs() < 1e-9 * cost);
    let r0 = p.residuals(&theta).unwrap();
    let h = 1e-6;
    let mut jac = vec![vec![0.0; n]; r0.len()];
    for k in 0..n {
        let (mut tp, mut tm) = (theta.clone(), theta.clone());
        tp[k] += h;
        tm[k] -= h;
        let fd_cost = (p.cost(&tp).unwrap() - p.cost(&tm).unwrap()) / (2.0 * h);
        assert!(
            (g[k] - fd_cost).abs() < 1e-5 * (1.0 + fd_cost.abs()),
            "g[{k}] = {} vs {fd_cost}",
            g[k]
        );
        let (rp, rm) = (p.residuals(&tp).unwrap(), p.residuals(&tm).unwrap());
        for r in 0..r0.len() {
            jac[r][k] = (rp[r] - rm[r]) / (2.0 * h);
        }
    }
    let mut worst: f64 = 0.0;
    let scale = (0..n).map(|i| a.get(i, i)).fold(0.0, f64::max);
    for i in 0..n {
        for j in 0..n {
            let fd: f64 = jac.iter().map(|row| row[i] * row[j]).sum();
            worst = worst.max((a.get(i, j) - fd).abs());
        }
    }
    assert!(
        worst < 1e-6 * scale,
        "‖A − JᵀJ‖max = {worst} (scale {scale})"
    );
}

#[test]
fn imu_samples_outside_the_span_are_left_out_as_tau_moves() {
    let (mut p, mut theta) = small_problem();
    let nb = p.n_band();
    p.begin_iteration(&theta).unwrap();
    let n0 = p.selected().len();
    // t_i + 0.13 within SPAN_MARGIN of the ends: the last samples drop out
    assert!(n0 < 75 && n0 > 65, "{n0}");
    theta[nb + TAU] = -0.5;
    assert!(!p.keeps_setup(&theta));
    p.begin_iteration(&theta).unwrap();
    assert!(p
        .selected()
        .iter()
        .all(|&i| p.data.imu_t[i] >= 0.5 + SPAN_MARGIN - 1e-12));
    assert!(p.cost(&theta).unwrap().is_finite());
}

#[test]
fn bad_input_is_an_error() {
    let (p, _) = small_problem();
    let mut d = p.data.clone();
    d.sigma_p = 0.0;
    assert!(matches!(
        PoseProblem::new(p.base.clone(), d),
        Err(PoseProblemError::Input(_))
    ));
    let mut d = p.data.clone();
    d.pose_p.pop();
    assert!(PoseProblem::new(p.base.clone(), d).is_err());
}
