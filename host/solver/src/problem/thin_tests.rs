//! The thinned first iteration (module doc, *The first iteration*): its
//! cost is the MAP cost of every k-th sample weighted by √k, it ends with
//! the first iteration, and a solve with it reaches the minimum of a solve
//! without it.

use robimu_model::effects::EffectSet;

use super::gls_tests::{options, problem, setup};
use super::multi_tests::SZ;
use super::Problem;
use crate::{solve, LeastSquares, LmOptions};

#[test]
fn the_thinned_cost_is_every_kth_sample_weighted_by_k() {
    let s = setup();
    let (mut full, mut thin) = (problem(&s, None, SZ), problem(&s, None, SZ));
    let mut theta = full.theta(&s.spline, &s.x);
    for (k, v) in theta.iter_mut().enumerate() {
        *v += 1e-3 * ((k as f64) * 0.37).sin();
    }
    full.begin_iteration(&theta).unwrap();
    let k = 3;
    thin.thin_first_by(k);
    thin.begin_iteration(&theta).unwrap();
    assert!(
        !thin.keeps_setup(&theta),
        "a thinned iteration is followed by a full one"
    );
    assert!(full.keeps_setup(&theta));
    // the reference: the full problem's residuals, every k-th of each half
    // (the halves of the two threads) counted k times
    let r = full.imu_residuals(&theta).unwrap();
    let half = r.len() / 2;
    let imu: f64 = [&r[..half], &r[half..]]
        .iter()
        .flat_map(|part| part.iter().step_by(k))
        .map(|(_, w)| 0.5 * k as f64 * w.iter().map(|v| v * v).sum::<f64>())
        .sum();
    let rest = full.cost(&theta).unwrap()
        - r.iter()
            .map(|(_, w)| 0.5 * w.iter().map(|v| v * v).sum::<f64>())
            .sum::<f64>();
    let want = imu + rest;
    let got = thin.cost(&theta).unwrap();
    assert!((got - want).abs() <= 1e-12 * want, "{got} vs {want}");
    let mut a = thin.new_matrix();
    let mut g = vec![0.0; theta.len()];
    let lin = thin.linearize(&theta, &mut a, &mut g).unwrap();
    assert!((lin - want).abs() <= 1e-12 * want, "{lin} vs {want}");
    // the next iteration uses every sample again
    thin.begin_iteration(&theta).unwrap();
    assert_eq!(thin.cost(&theta).unwrap(), full.cost(&theta).unwrap());
    assert!(thin.keeps_setup(&theta));
}

#[test]
fn a_solve_with_a_thinned_first_iteration_reaches_the_same_minimum() {
    let s = setup();
    let none = EffectSet::none();
    let mut x0 = s.layout.nominal();
    x0[s.layout.offsets().tau] = s.x[s.layout.offsets().tau];
    let run = |k: usize| {
        let mut p = Problem::new(
            &s.robot,
            &s.layout,
            &s.data,
            s.knots.clone(),
            x0.clone(),
            &options(&s, None, SZ),
            none,
        )
        .unwrap();
        p.thin_first_by(k);
        let theta0 = p.theta(&s.spline, &x0);
        // converged to the cost's rounding, so that the paths' ends agree
        let opts = LmOptions {
            function_tolerance: 1e-15,
            ..LmOptions::default()
        };
        let sol = solve(&mut p, theta0, &opts, |_| {}).unwrap();
        assert!(sol.summary.termination.converged(), "{}", sol.summary);
        let cov = sol.factor.covariance_x();
        let sigma: Vec<f64> = (0..cov.nrows()).map(|a| cov[(a, a)].sqrt()).collect();
        let nc = p.n_coeffs();
        (sol.theta[nc..].to_vec(), sigma)
    };
    let (full, sigma) = run(1);
    let (thin, _) = run(2);
    for (a, ((x, y), s)) in full.iter().zip(&thin).zip(&sigma).enumerate() {
        assert!((x - y).abs() <= 1e-6 * s, "x[{a}]: {x} vs {y} (σ {s})");
    }
}
