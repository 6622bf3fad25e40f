//! The generalised-least-squares assembly against an independent dense
//! reference: A = Jᵀ Σ⁻¹ J, g = Jᵀ Σ⁻¹ r and J = ½ rᵀ Σ⁻¹ r, with J the
//! unwhitened per-sample IMU Jacobian by finite differences and Σ the
//! block-Toeplitz covariance built from the autocovariances and levels.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use robimu_model::effects::EffectSet;
use robimu_model::noise::{ArNoise, ChannelNoise, NoiseModel};
use robimu_model::{JointState, Knots, MeasurementModel, ParamLayout, Robot, Spline};

use super::{Measurements, Problem, ProblemOptions};
use crate::LeastSquares;

/// A tiny session: 1 s, knots every 0.25 s, IMU at 50 Hz with a gap.
pub(super) fn session(
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
    spline: &Spline,
) -> Measurements {
    let n = robot.dof();
    let model = MeasurementModel::new(robot, layout, x).unwrap();
    let mut js = JointState::default();
    let joint_t: Vec<f64> = (0..=100).map(|k| k as f64 * 0.01).collect();
    let mut joint_q = Vec::new();
    for (s, &t) in joint_t.iter().enumerate() {
        spline.evaluate(t, &mut js).unwrap();
        for j in 0..n {
            joint_q.push(js.q[j] + 1e-4 * ((s * 7 + j * 3) as f64).sin());
        }
    }
    let mut imu_t = Vec::new();
    let mut imu_z = Vec::new();
    for k in 0..=50 {
        // a gap: samples 24..27 are missing
        if (24..27).contains(&k) {
            continue;
        }
        let t = k as f64 * 0.02 + 0.003;
        spline.evaluate_clamped(t + x[layout.offsets().tau], &mut js);
        let mut z = model.predict(&js);
        for (c, v) in z.iter_mut().enumerate() {
            *v += 0.05 * ((k * 13 + c * 5) as f64).sin();
        }
        imu_t.push(t);
        imu_z.push(z);
    }
    Measurements {
        joint_t,
        joint_q,
        imu_t,
        imu_z,
        imu_temp: None,
        extra_imus: Vec::new(),
    }
}

pub(super) fn noise_model() -> NoiseModel {
    let white = |s| ChannelNoise::white(s).unwrap();
    NoiseModel {
        imu: [
            ChannelNoise::new(ArNoise::new(vec![0.7], 0.05).unwrap(), 0.0).unwrap(),
            ChannelNoise::new(ArNoise::new(vec![1.1, -0.4], 0.08).unwrap(), 0.0).unwrap(),
            ChannelNoise::new(ArNoise::new(vec![0.5], 0.06).unwrap(), 2e-4).unwrap(),
            white(0.01),
            ChannelNoise::new(ArNoise::new(vec![-0.3, 0.2], 0.02).unwrap(), 0.0).unwrap(),
            white(0.015),
        ],
    }
}

pub(super) struct Setup {
    pub(super) robot: Robot,
    pub(super) layout: ParamLayout,
    pub(super) data: Measurements,
    pub(super) knots: Knots,
    pub(super) x: Vec<f64>,
    pub(super) spline: Spline,
}

pub(super) fn setup() -> Setup {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let mut x = layout.nominal();
    for (k, s) in layout.specs().iter().enumerate() {
        x[k] += 0.2 * s.sigma * ((k as f64) * 1.3).sin();
    }
    let knots = Knots::uniform(0.0, 1.0, 0.25, 3).unwrap();
    let n = robot.dof();
    let m = knots.num_coeffs();
    let coeffs = (0..m * n)
        .map(|i| 0.8 * ((i % n) as f64 * 0.7 + (i / n) as f64 * 0.9).sin())
        .collect();
    let spline = Spline::new(knots.clone(), n, coeffs).unwrap();
    let data = session(&robot, &layout, &x, &spline);
    Setup {
        robot,
        layout,
        data,
        knots,
        x,
        spline,
    }
}

pub(super) fn options(s: &Setup, noise: Option<NoiseModel>, sigma_z: [f64; 6]) -> ProblemOptions {
    ProblemOptions {
        sigma_q: vec![1e-3; s.robot.dof()],
        sigma_z,
        noise: noise.into_iter().collect(),
        use_prior: true,
        frozen: Vec::new(),
    }
}

/// The one-IMU problem of `s` with `opts` and the effects `set`.
pub(super) fn build<'a>(s: &'a Setup, opts: &ProblemOptions, set: &'a EffectSet) -> Problem<'a> {
    Problem::new(
        &s.robot,
        &s.layout,
        &s.data,
        s.knots.clone(),
        s.x.clone(),
        opts,
        set,
    )
    .unwrap()
}

/// The problem of `s` without effects, with `noise` and `sigma_z`.
pub(super) fn problem(s: &Setup, noise: Option<NoiseModel>, sigma_z: [f64; 6]) -> Problem<'_> {
    build(s, &options(s, noise, sigma_z), EffectSet::none())
}

pub(super) fn linearized(p: &Problem<'_>, theta: &[f64]) -> (crate::ArrowMatrix, Vec<f64>, f64) {
    let mut a = p.new_matrix();
    let mut g = vec![0.0; theta.len()];
    let cost = p.linearize(theta, &mut a, &mut g).unwrap();
    (a, g, cost)
}

#[test]
fn gls_assembly_equals_the_dense_generalised_least_squares() {
    let s = setup();
    let model = noise_model();
    let mut white1 = problem(&s, None, [1.0; 6]);
    let mut gls = problem(&s, Some(model.clone()), [1.0; 6]);
    assert!(gls.extra_spans() >= 1);
    assert!(gls.bandwidth() > white1.bandwidth());
    let theta = white1.theta(&s.spline, &s.x);
    white1.begin_iteration(&theta).unwrap();
    gls.begin_iteration(&theta).unwrap();
    assert_eq!(white1.imu_range(), gls.imu_range());
    let range = gls.imu_range();
    let ns = range.len();
    assert!(ns > 30, "{ns} samples");

    // Unwhitened residuals r (σ = 1) and their Jacobian by central differences.
    let raw = |th: &[f64]| -> Vec<f64> {
        white1
            .imu_residuals(th)
            .unwrap()
            .iter()
            .flat_map(|(_, r)| *r)
            .collect()
    };
    let r0 = raw(&theta);
    let nt = theta.len();
    let mut jac = Mat::<f64>::zeros(6 * ns, nt);
    for k in 0..nt {
        let h = 1e-6 * theta[k].abs().max(1e-2);
        let mut tp = theta.clone();
        tp[k] += h;
        let rp = raw(&tp);
        tp[k] -= 2.0 * h;
        let rm = raw(&tp);
        for row in 0..6 * ns {
            jac[(row, k)] = (rp[row] - rm[row]) / (2.0 * h);
        }
    }

    // Σ: per channel within a segment s_i s_j γ(|t_i − t_j|), else 0;
    // segments break where a step exceeds 1.5× the median step.
    let t = &s.data.imu_t;
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    steps.sort_by(f64::total_cmp);
    let median = steps[steps.len() / 2];
    let mut seg = vec![0usize; ns];
    let mut pos = vec![0usize; ns];
    for a in 1..ns {
        let i = range.start + a;
        if t[i] - t[i - 1] > 1.5 * median {
            seg[a] = seg[a - 1] + 1;
            pos[a] = 0;
        } else {
            seg[a] = seg[a - 1];
            pos[a] = pos[a - 1] + 1;
        }
    }
    assert!(seg[ns - 1] >= 1, "the test session must have a gap");
    let tau = s.x[s.layout.offsets().tau];
    let mut js = JointState::default();
    let levels: Vec<[f64; 6]> = range
        .clone()
        .map(|i| {
            s.spline.evaluate(t[i] + tau, &mut js).unwrap();
            let qdd2: f64 = js.qdd[..s.robot.dof()].iter().map(|v| v * v).sum();
            std::array::from_fn(|c| model.imu[c].level(qdd2))
        })
        .collect();
    assert!(
        levels.iter().any(|l| l[2] > 1.01),
        "a motion level is active"
    );
    let gammas: Vec<Vec<f64>> = model.imu.iter().map(|c| c.ar.autocovariance(ns)).collect();
    let sigma = Mat::<f64>::from_fn(6 * ns, 6 * ns, |ra, rb| {
        let (a, ca, b, cb) = (ra / 6, ra % 6, rb / 6, rb % 6);
        if ca != cb || seg[a] != seg[b] {
            return 0.0;
        }
        levels[a][ca] * levels[b][ca] * gammas[ca][pos[a].abs_diff(pos[b])]
    });
    let llt = sigma.llt(Side::Lower).unwrap();
    let r0m = Mat::<f64>::from_fn(6 * ns, 1, |i, _| r0[i]);
    let sinv_j = llt.solve(&jac);
    let sinv_r = llt.solve(&r0m);
    // Σ⁻¹ − I applied: the white σ = 1 problem has the same joint and prior terms.
    let d_a = jac.transpose() * (&sinv_j - &jac);
    let d_g = jac.transpose() * (&sinv_r - &r0m);
    let d_cost = 0.5 * ((r0m.transpose() * &sinv_r)[(0, 0)] - (r0m.transpose() * &r0m)[(0, 0)]);

    let (aw, gw, cw) = linearized(&white1, &theta);
    let (ag, gg, cg) = linearized(&gls, &theta);
    let cost_gls = gls.cost(&theta).unwrap();
    assert!((cost_gls - cg).abs() <= 1e-12 * cg.abs());
    assert!(
        ((cg - cw) - d_cost).abs() <= 1e-10 * cg.abs(),
        "cost: {} vs {d_cost}",
        cg - cw
    );
    let diag: Vec<f64> = (0..nt).map(|i| ag.get(i, i)).collect();
    let mut worst = 0.0f64;
    for i in 0..nt {
        for j in 0..nt {
            let got = ag.get(i, j) - aw.get(i, j);
            let scale = (diag[i] * diag[j]).sqrt();
            worst = worst.max((got - d_a[(i, j)]).abs() / scale);
        }
        let scale = diag[i].sqrt() * (2.0 * cg).sqrt();
        let got = gg[i] - gw[i];
        assert!(
            (got - d_g[(i, 0)]).abs() <= 1e-6 * scale,
            "g[{i}]: {got} vs {}",
            d_g[(i, 0)]
        );
    }
    assert!(
        worst < 1e-6,
        "A differs from the dense GLS by {worst:e} (relative)"
    );
    // Outside the white band the GLS matrix has entries: the widened band is used.
    let w = white1.bandwidth();
    let outside = (w + 1..=gls.bandwidth())
        .flat_map(|d| (d..white1.n_coeffs()).map(move |i| (i, i - d)))
        .any(|(i, j)| ag.get(i, j) != 0.0);
    assert!(outside, "no entry beyond the white band");
    // The whitened residuals have ½‖w‖² = the IMU part of the cost.
    let wres = gls.imu_residuals(&theta).unwrap();
    let half: f64 = 0.5
        * wres
            .iter()
            .flat_map(|(_, r)| *r)
            .map(|v| v * v)
            .sum::<f64>();
    let half_ref = 0.5 * (r0m.transpose() * &sinv_r)[(0, 0)];
    assert!((half - half_ref).abs() <= 1e-10 * half_ref);
}

/// The GLS code path with a white model reproduces the white assembly (also
/// with a band widened by one span), and a white `NoiseModel` gives exactly
/// the `sigma_z` problem.
#[test]
fn the_gls_path_reduces_to_the_white_one() {
    let s = setup();
    let sz = [0.05, 0.06, 0.07, 0.01, 0.012, 0.014];
    let mk = |noise| {
        let mut p = problem(&s, noise, sz);
        let theta = p.theta(&s.spline, &s.x);
        p.begin_iteration(&theta).unwrap();
        (p, theta)
    };
    let (plain, theta) = mk(None);
    let (given, _) = mk(Some(NoiseModel::white(sz).unwrap()));
    let (forced, _) = mk(Some(NoiseModel::white(sz).unwrap()));
    let mut forced = forced;
    forced.white = false;
    forced.extra_spans = 1;
    let tau = s.x[s.layout.offsets().tau];
    forced.select_samples(tau).unwrap();
    let (a0, g0, c0) = linearized(&plain, &theta);
    let (a1, g1, c1) = linearized(&given, &theta);
    assert_eq!((c0, &g0), (c1, &g1));
    let (a2, g2, c2) = linearized(&forced, &theta);
    assert!((c2 - c0).abs() <= 1e-12 * c0);
    let nt = theta.len();
    for i in 0..nt {
        assert!((g2[i] - g0[i]).abs() <= 1e-12 * (g0[i].abs() + 1e-300).max(1e-9 * c0));
        for j in 0..nt {
            assert_eq!(a0.get(i, j), a1.get(i, j));
            let scale = (a0.get(i, i) * a0.get(j, j)).sqrt();
            assert!(
                (a2.get(i, j) - a0.get(i, j)).abs() <= 1e-12 * scale,
                "({i},{j}) {} vs {}",
                a2.get(i, j),
                a0.get(i, j)
            );
        }
    }
    assert!((forced.cost(&theta).unwrap() - c0).abs() <= 1e-12 * c0);
}

/// The motion levels are set from the trajectory of the solve's first
/// iteration and held (module doc): a second `begin_iteration` at another
/// trajectory leaves every level, and so the cost, as it was; a trial step
/// that keeps the samples keeps the setup; a new problem at the other
/// trajectory has other levels (they do depend on q̈).
#[test]
fn motion_levels_are_held_for_the_whole_solve() {
    let s = setup();
    let model = noise_model();
    let mut p = problem(&s, Some(model.clone()), [1.0; 6]);
    let theta = p.theta(&s.spline, &s.x);
    p.begin_iteration(&theta).unwrap();
    let levels = p.streams[0].inv_levels.clone();
    let cost = p.cost(&theta).unwrap();
    // another trajectory: q̈ of every span changed, τ (and so the samples) not
    let nc = p.n_coeffs();
    let mut other = theta.clone();
    for (i, c) in other[..nc].iter_mut().enumerate() {
        *c += 0.3 * (i as f64 * 0.37).cos();
    }
    assert!(p.keeps_setup(&other));
    p.begin_iteration(&other).unwrap();
    assert_eq!(p.streams[0].inv_levels, levels);
    assert_eq!(p.cost(&theta).unwrap(), cost);
    let mut q = problem(&s, Some(model), [1.0; 6]);
    q.begin_iteration(&other).unwrap();
    let range = q.imu_range();
    let changed = range
        .filter(|&i| q.streams[0].inv_levels[i][2] != levels[i][2])
        .count();
    assert!(changed > 0, "the levels of another trajectory differ");
}
