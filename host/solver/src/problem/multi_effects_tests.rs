//! Effects on a K = 2 problem (docs/model.md §9): a per-sensor effect of
//! IMU 1 enters only IMU 1's rows, a shared effect both IMUs' rows with one
//! parameter block; the assembly equals JᵀJ, Jᵀr and ½‖r‖² of the full
//! residual vector (joints, both IMUs', priors of x and θ_E) with J by
//! central differences.

use robimu_model::effects::encoder_scale::EncoderScale;
use robimu_model::effects::g_sensitivity::GSensitivity;
use robimu_model::effects::EffectSet;
use robimu_model::JointState;

use super::gls_tests::{build, linearized, noise_model, options, setup};
use super::multi_tests::check_against_finite_differences;
use super::multi_tests::{two_imus, SZ};
use super::{Problem, ProblemError};
use crate::LeastSquares;

/// g_sensitivity on IMU 1, encoder_scale shared.
fn effects(n: usize) -> EffectSet {
    let mut set = EffectSet::new();
    set.push_on(Box::new(GSensitivity), Some(1));
    set.push(Box::new(EncoderScale::new(n)));
    set
}

#[test]
fn per_sensor_and_shared_effects_on_two_imus_are_the_gauss_newton_of_all_residuals() {
    let s = setup();
    let (layout, x, data) = two_imus(&s);
    let n = s.robot.dof();
    let set = effects(n);
    assert_eq!(set.names(), ["imu1/g_sensitivity", "encoder_scale"]);
    assert_eq!(set.params()[0].name, "imu1/g_sensitivity.gx_sx");
    assert_eq!(set.params()[9].name, "encoder_scale.kappa_1");
    // IMU 0 sees only the shared block, IMU 1 both
    assert_eq!(set.imu_map(0), (9..9 + n).collect::<Vec<_>>());
    assert_eq!(set.imu_map(1), (0..9 + n).collect::<Vec<_>>());
    for noise in [None, Some(noise_model())] {
        let mut p = Problem::new(
            &s.robot,
            &layout,
            &data,
            s.knots.clone(),
            x.clone(),
            &options(&s, noise, SZ),
            &set,
        )
        .unwrap();
        let mut theta = p.theta(&s.spline, &x);
        for (k, v) in theta.iter_mut().enumerate() {
            *v += 1e-3 * ((k as f64) * 0.37).sin();
        }
        let ne = p.n_effect_params();
        assert_eq!(ne, 9 + n);
        // the Jacobian at θ_E = 0, where the score tests linearise: the
        // assembly neglects ∂C_e/∂x θ_E (robimu_model::effects), exact there
        let theta_e = theta[theta.len() - ne..].to_vec();
        let nt0 = theta.len() - ne;
        theta[nt0..].fill(0.0);
        p.begin_iteration(&theta).unwrap();
        let resid_imu = |th: &[f64], j: usize| -> Vec<f64> {
            p.imu_residuals_of(th, j)
                .unwrap()
                .iter()
                .flat_map(|(_, w)| *w)
                .collect()
        };
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
            r.extend(resid_imu(th, 0));
            r.extend(resid_imu(th, 1));
            let xt = p.x_of(th);
            for &k in p.active() {
                let sp = &layout.specs()[k];
                r.push((xt[k] - sp.nominal) / sp.sigma);
            }
            for (pe, v) in set.params().iter().zip(p.effect_params_of(th)) {
                r.push(v / pe.prior_sigma);
            }
            r
        };
        let (a, jac, cost) = check_against_finite_differences(&p, &theta, resid);
        let nt = theta.len();
        // the cost at θ_E ≠ 0 is ½‖r‖² of the same residuals
        let mut with_e = theta.clone();
        with_e[nt0..].copy_from_slice(&theta_e);
        let r_e = resid(&with_e);
        let half_e: f64 = 0.5 * r_e.iter().map(|v| v * v).sum::<f64>();
        let cost_e = p.cost(&with_e).unwrap();
        assert!(
            (cost_e - half_e).abs() <= 1e-12 * half_e,
            "{cost_e} vs {half_e}"
        );
        assert!((cost_e - cost).abs() > 1e-6 * cost, "θ_E changes nothing");
        // the structure, against the numerical derivatives themselves: IMU
        // 0's residuals do not move with IMU 1's g_sensitivity, IMU 1's do;
        // both move with the shared encoder scale
        let e0 = nt - ne;
        let n_joint = data.joint_t.len() * n;
        let n0 = resid_imu(&theta, 0).len();
        let n1 = resid_imu(&theta, 1).len();
        let moves = |rows: std::ops::Range<usize>, col: usize| {
            rows.map(|r| jac[(r, col)].abs()).fold(0.0, f64::max)
        };
        let imu0 = n_joint..n_joint + n0;
        let imu1 = n_joint + n0..n_joint + n0 + n1;
        for e in 0..9 {
            assert_eq!(
                moves(imu0.clone(), e0 + e),
                0.0,
                "IMU 0 sees imu1/g_sensitivity"
            );
            assert!(
                moves(imu1.clone(), e0 + e) > 0.0,
                "IMU 1 misses its g_sensitivity"
            );
        }
        for e in 9..ne {
            assert!(moves(imu0.clone(), e0 + e) > 0.0);
            assert!(moves(imu1.clone(), e0 + e) > 0.0);
        }
        let nc = p.n_coeffs();
        let pos = |name: &str| {
            let k = layout.index_of(name).unwrap();
            nc + p.active().iter().position(|&a| a == k).unwrap()
        };
        assert_eq!(a.get(e0, pos("k_w_x")), 0.0);
        assert_ne!(a.get(e0, pos("imu1/k_w_x")), 0.0);
        assert_ne!(a.get(e0 + 9, pos("k_w_x")), 0.0);
        assert_ne!(a.get(e0 + 9, pos("imu1/k_w_x")), 0.0);
    }
}

/// With every effect on IMU 0 or shared a one-IMU problem is today's: the
/// same matrix whether the effects are pushed as shared or on IMU 0.
#[test]
fn one_imu_effects_on_imu_0_are_the_shared_ones() {
    let s = setup();
    let n = s.robot.dof();
    let mut shared = EffectSet::new();
    shared.push(Box::new(GSensitivity));
    shared.push(Box::new(EncoderScale::new(n)));
    let mut on0 = EffectSet::new();
    on0.push_on(Box::new(GSensitivity), Some(0));
    on0.push(Box::new(EncoderScale::new(n)));
    assert_eq!(on0.names(), ["g_sensitivity", "encoder_scale"]);
    let opts = options(&s, None, SZ);
    let (p, q) = (build(&s, &opts, &shared), build(&s, &opts, &on0));
    let mut theta = p.theta(&s.spline, &s.x);
    for (k, v) in theta.iter_mut().enumerate() {
        *v += 1e-3 * ((k as f64) * 0.37).sin();
    }
    let (a, g, c) = linearized(&p, &theta);
    let (b, h, d) = linearized(&q, &theta);
    assert_eq!(c, d);
    assert_eq!(g, h);
    let nt = theta.len();
    for i in 0..nt {
        for j in 0..nt {
            assert_eq!(a.get(i, j), b.get(i, j));
        }
    }
    // an effect on an IMU the problem lacks is refused
    let mut on1 = EffectSet::new();
    on1.push_on(Box::new(GSensitivity), Some(1));
    let err = Problem::new(
        &s.robot,
        &s.layout,
        &s.data,
        s.knots.clone(),
        s.x.clone(),
        &opts,
        &on1,
    )
    .err()
    .unwrap();
    assert_eq!(err, ProblemError::EffectImu { imu: 1, n_imus: 1 });
}
