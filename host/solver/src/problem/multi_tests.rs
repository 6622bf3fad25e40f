//! The multi-IMU problem (docs/model.md §9): K = 1 gives the numbers of the
//! one-IMU problem before the streams existed (stored golden checksums), and
//! the K = 2 assembly equals JᵀJ, Jᵀr and ½‖r‖² of the full residual vector
//! (joint, both IMUs', priors) with J by central differences.

use faer::Mat;
use robimu_model::effects::EffectSet;
use robimu_model::observations::ImuSamples;
use robimu_model::{JointState, ParamLayout};

use super::gls_tests::{linearized, noise_model, options, session, setup, Setup};
use super::{Measurements, Problem, ProblemError};
use crate::LeastSquares;

/// Checksums of one linearisation: cost, Σ g_i sin(i+1), Σ A_ij cos(i+2j).
fn checksums(p: &Problem<'_>, theta: &[f64]) -> [f64; 3] {
    let (a, g, c) = linearized(p, theta);
    let nt = theta.len();
    let sg: f64 = g
        .iter()
        .enumerate()
        .map(|(i, v)| v * ((i + 1) as f64).sin())
        .sum();
    let mut sa = 0.0;
    for i in 0..nt {
        for j in 0..nt {
            sa += a.get(i, j) * ((i + 2 * j) as f64).cos();
        }
    }
    [c, sg, sa]
}

pub(super) const SZ: [f64; 6] = [0.05, 0.06, 0.07, 0.01, 0.012, 0.014];

/// The problem of `layout` on `data` at θ = (spline, x) slightly moved, set up there.
fn problem_at<'a>(
    s: &'a Setup,
    layout: &'a ParamLayout,
    data: &'a Measurements,
    x: &[f64],
    noise: Option<robimu_model::noise::NoiseModel>,
) -> (Problem<'a>, Vec<f64>) {
    problem_with(s, layout, data, x, noise.into_iter().collect())
}

/// [`problem_at`] with one noise model per IMU ([`super::ProblemOptions::noise`]).
fn problem_with<'a>(
    s: &'a Setup,
    layout: &'a ParamLayout,
    data: &'a Measurements,
    x: &[f64],
    noise: Vec<robimu_model::noise::NoiseModel>,
) -> (Problem<'a>, Vec<f64>) {
    let opts = super::ProblemOptions {
        noise,
        ..options(s, None, SZ)
    };
    let mut p = Problem::new(
        &s.robot,
        layout,
        data,
        s.knots.clone(),
        x.to_vec(),
        &opts,
        EffectSet::none(),
    )
    .unwrap();
    let mut theta = p.theta(&s.spline, x);
    for (k, v) in theta.iter_mut().enumerate() {
        *v += 1e-3 * ((k as f64) * 0.37).sin();
    }
    p.begin_iteration(&theta).unwrap();
    (p, theta)
}

/// Printed by the one-IMU problem of main (d3fc17f) for these two setups
/// (white σ_z, then the AR model of `gls_tests`).
const GOLDEN: [[f64; 3]; 2] = [
    [651.0485350748841, -5210.395150322076, 262122014.06454706],
    [514.690725754248, 539.5571225913445, 131183943.26958343],
];

#[test]
fn one_imu_gives_the_numbers_of_the_one_imu_problem() {
    let s = setup();
    for (noise, want) in [None, Some(noise_model())].into_iter().zip(GOLDEN) {
        let (p, theta) = problem_at(&s, &s.layout, &s.data, &s.x, noise);
        let got = checksums(&p, &theta);
        // 1e-11: the joint samples' basis now comes from the span
        // polynomials, equal to the Cox–de Boor one to rounding (the
        // gradient checksum cancels terms ~10³ larger than itself)
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() <= 1e-11 * w.abs(), "{got:?} vs {want:?}");
        }
    }
}

/// A two-IMU session: IMU 1 with its own position, τ and intrinsics.
pub(super) fn two_imus(s: &Setup) -> (ParamLayout, Vec<f64>, Measurements) {
    let layout = ParamLayout::with_imus(&s.robot, 2);
    let mut x = layout.nominal();
    x[..s.x.len()].copy_from_slice(&s.x);
    for (k, v) in x.iter_mut().enumerate().skip(s.x.len()) {
        *v += 0.3 * layout.specs()[k].sigma * ((k as f64) * 0.9).cos();
    }
    let x1 = layout.imu_x(1, &x);
    let one = session(&s.robot, layout.imu_layout(), &x1, &s.spline);
    let mut data = s.data.clone();
    data.extra_imus.push(ImuSamples {
        t: one.imu_t.iter().map(|t| t + 0.0071).collect(),
        z: one.imu_z,
        temp: None,
    });
    (layout, x, data)
}

#[test]
fn the_two_imu_assembly_is_the_gauss_newton_of_all_residuals() {
    let s = setup();
    let (layout, x, data) = two_imus(&s);
    for noise in [None, Some(noise_model())] {
        let (p, theta) = problem_at(&s, &layout, &data, &x, noise);
        assert_eq!(p.n_imus(), 2);
        assert_eq!(p.active().len(), 20 + 2 * 28);
        let n = s.robot.dof();
        // every residual of the MAP cost: joints, IMU 0, IMU 1, priors
        let resid = |th: &[f64]| -> Vec<f64> {
            let spline = p.spline_of(th);
            let mut js = JointState::default();
            let mut r = Vec::new();
            for (k, &t) in data.joint_t.iter().enumerate() {
                spline.evaluate(t, &mut js).unwrap();
                for j in 0..n {
                    r.push((data.joint_q[k * n + j] - js.q[j]) / 1e-3);
                }
            }
            for j in 0..2 {
                r.extend(
                    p.imu_residuals_of(th, j)
                        .unwrap()
                        .iter()
                        .flat_map(|(_, w)| *w),
                );
            }
            let xt = p.x_of(th);
            for &k in p.active() {
                let sp = &layout.specs()[k];
                r.push((xt[k] - sp.nominal) / sp.sigma);
            }
            r
        };
        let (a, _jac, _cost) = check_against_finite_differences(&p, &theta, resid);
        // IMU 1's own columns are coupled to IMU 0's only through the
        // shared ones and the trajectory: the corner block between IMU 0's
        // and IMU 1's own parameters is zero
        let nc = p.n_coeffs();
        let pos = |name: &str| {
            let k = layout.index_of(name).unwrap();
            nc + p.active().iter().position(|&a| a == k).unwrap()
        };
        assert_eq!(a.get(pos("imu1/k_a_x"), pos("k_a_x")), 0.0);
        assert_ne!(a.get(pos("imu1/k_a_x"), pos("g_x")), 0.0);
    }
}

#[test]
fn each_imu_is_evaluated_at_its_own_parameters() {
    let s = setup();
    let (layout, x, data) = two_imus(&s);
    let (p, theta) = problem_at(&s, &layout, &data, &x, None);
    let xt = p.x_of(&theta);
    for j in 0..2 {
        let alone = data.only_imu(j);
        let one = ParamLayout::new(&s.robot);
        let xj = layout.imu_x(j, &xt);
        let (mut q, _) = problem_at(&s, &one, &alone, &xj, None);
        let th1 = q.theta(&p.spline_of(&theta), &xj);
        q.begin_iteration(&th1).unwrap();
        assert_eq!(q.imu_range(), p.imu_range_of(j));
        assert_eq!(
            q.imu_residuals(&th1).unwrap(),
            p.imu_residuals_of(&theta, j).unwrap()
        );
    }
    // a layout with more IMUs than the session
    let three = ParamLayout::with_imus(&s.robot, 3);
    let opts = options(&s, None, SZ);
    let err = Problem::new(
        &s.robot,
        &three,
        &data,
        s.knots.clone(),
        three.nominal(),
        &opts,
        EffectSet::none(),
    )
    .err()
    .unwrap();
    assert_eq!(err, ProblemError::ImuCount { layout: 3, data: 2 });
}

/// Checks the assembled Gauss–Newton matrix, gradient and cost of `p` at
/// `theta` against central finite differences of `resid` (every whitened
/// residual and prior of the problem, in any order): A = JᵀJ and g = Jᵀr to
/// 1e-6 relative, cost = ½‖r‖² to 1e-12. Returns A, the numerical J and the cost.
pub(super) fn check_against_finite_differences(
    p: &Problem<'_>,
    theta: &[f64],
    resid: impl Fn(&[f64]) -> Vec<f64>,
) -> (crate::ArrowMatrix, Mat<f64>, f64) {
    let r0 = resid(theta);
    let nt = theta.len();
    let mut jac = Mat::<f64>::zeros(r0.len(), nt);
    for k in 0..nt {
        let h = 1e-6 * theta[k].abs().max(1e-2);
        let mut tp = theta.to_vec();
        tp[k] += h;
        let rp = resid(&tp);
        tp[k] -= 2.0 * h;
        let rm = resid(&tp);
        for row in 0..r0.len() {
            jac[(row, k)] = (rp[row] - rm[row]) / (2.0 * h);
        }
    }
    let (a, g, cost) = linearized(p, theta);
    let half: f64 = 0.5 * r0.iter().map(|v| v * v).sum::<f64>();
    assert!((cost - half).abs() <= 1e-12 * half, "{cost} vs {half}");
    assert!((p.cost(theta).unwrap() - cost).abs() <= 1e-12 * cost);
    let r0m = Mat::<f64>::from_fn(r0.len(), 1, |i, _| r0[i]);
    let jtj = jac.transpose() * &jac;
    let jtr = jac.transpose() * &r0m;
    let mut worst = 0.0f64;
    for i in 0..nt {
        for j in 0..nt {
            let scale = (a.get(i, i) * a.get(j, j)).sqrt();
            worst = worst.max((a.get(i, j) - jtj[(i, j)]).abs() / scale);
        }
        let scale = a.get(i, i).sqrt() * (2.0 * cost).sqrt();
        assert!((g[i] - jtr[(i, 0)]).abs() <= 1e-6 * scale, "g[{i}]");
    }
    assert!(worst < 1e-6, "A differs from JᵀJ by {worst:e} (relative)");
    (a, jac, cost)
}

/// The solver's last cost with the residuals kept
/// ([`LeastSquares::end_cost`]) is [`Problem::cost`] to the bit, and the
/// residuals kept are those [`Problem::imu_residuals_of`] computes, for
/// white and GLS noise and two IMUs.
#[test]
fn the_end_cost_is_the_cost_and_keeps_the_residuals() {
    let s = setup();
    let (layout, x, data) = two_imus(&s);
    for noise in [None, Some(noise_model())] {
        let (mut p, theta) = problem_at(&s, &layout, &data, &x, noise);
        let cost = p.cost(&theta).unwrap();
        let want: Vec<_> = (0..2)
            .map(|j| p.imu_residuals_of(&theta, j).unwrap())
            .collect();
        assert_eq!(p.end_cost(&theta).unwrap(), cost);
        assert_eq!(p.take_residuals(&theta).unwrap(), want);
        // at another θ nothing is kept: computed anew
        let mut other = theta.clone();
        other[0] += 1e-3;
        p.end_cost(&theta).unwrap();
        let at_other: Vec<_> = (0..2)
            .map(|j| p.imu_residuals_of(&other, j).unwrap())
            .collect();
        assert_eq!(p.take_residuals(&other).unwrap(), at_other);
    }
}

/// Each IMU its own noise model (docs/model.md §9): IMU 0 white, IMU 1 the
/// AR model of `gls_tests`, and the reverse. Each IMU's whitened residuals
/// are those of the IMU alone under its own model (a one-IMU problem, an
/// independent path), and the assembly is the Gauss–Newton of all residuals
/// (central differences).
#[test]
fn each_imu_is_whitened_by_its_own_noise_model() {
    use robimu_model::noise::NoiseModel;
    let s = setup();
    let (layout, x, data) = two_imus(&s);
    let white = NoiseModel::white(SZ).unwrap();
    for models in [
        vec![white.clone(), noise_model()],
        vec![noise_model(), white.clone()],
    ] {
        let (p, theta) = problem_with(&s, &layout, &data, &x, models.clone());
        let xt = p.x_of(&theta);
        for (j, model) in models.iter().enumerate() {
            assert_eq!(p.noise_of(j), model);
            let alone = data.only_imu(j);
            let one = ParamLayout::new(&s.robot);
            let xj = layout.imu_x(j, &xt);
            // begun first at IMU j's part of θ: the motion levels are those
            // of the first θ a problem begins at
            let opts = super::ProblemOptions {
                noise: vec![model.clone()],
                ..options(&s, None, SZ)
            };
            let mut q = Problem::new(
                &s.robot,
                &one,
                &alone,
                s.knots.clone(),
                xj.clone(),
                &opts,
                EffectSet::none(),
            )
            .unwrap();
            let th1 = q.theta(&p.spline_of(&theta), &xj);
            q.begin_iteration(&th1).unwrap();
            let (a, b) = (
                q.imu_residuals(&th1).unwrap(),
                p.imu_residuals_of(&theta, j).unwrap(),
            );
            assert_eq!(a.len(), b.len());
            for ((ia, ra), (ib, rb)) in a.iter().zip(&b) {
                assert_eq!(ia, ib);
                for c in 0..6 {
                    assert!(
                        (ra[c] - rb[c]).abs() <= 1e-12 * (1.0 + ra[c].abs()),
                        "IMU {j}"
                    );
                }
            }
        }
        // the other IMU's model would whiten IMU j's residuals otherwise
        let (same, th) = problem_with(&s, &layout, &data, &x, vec![models[0].clone()]);
        assert_ne!(
            same.imu_residuals_of(&th, 1).unwrap(),
            p.imu_residuals_of(&theta, 1).unwrap()
        );
        let n = s.robot.dof();
        let resid = |th: &[f64]| -> Vec<f64> {
            let spline = p.spline_of(th);
            let mut js = JointState::default();
            let mut r = Vec::new();
            for (k, &t) in data.joint_t.iter().enumerate() {
                spline.evaluate(t, &mut js).unwrap();
                for j in 0..n {
                    r.push((data.joint_q[k * n + j] - js.q[j]) / 1e-3);
                }
            }
            for j in 0..2 {
                r.extend(
                    p.imu_residuals_of(th, j)
                        .unwrap()
                        .iter()
                        .flat_map(|(_, w)| *w),
                );
            }
            let xt = p.x_of(th);
            for &k in p.active() {
                let sp = &layout.specs()[k];
                r.push((xt[k] - sp.nominal) / sp.sigma);
            }
            r
        };
        check_against_finite_differences(&p, &theta, resid);
    }
}
