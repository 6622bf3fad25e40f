//! The solver's Newton stop (robimu_solver::lm, *The last step*) on
//! calibrations: the point it stops at is the minimum to its tolerance.

use super::*;
use crate::simulate::{random_session, SimulateOptions};
use robimu_solver::Termination;

/// On simulated sessions the Newton stop saves the last linearisation and
/// its estimate is the one of a solver that runs on until the cost stops
/// changing (no Newton stop, a function tolerance of 10⁻¹⁴), to the Newton
/// tolerance in σ; the σ agree to 10⁻³ relative (the covariance is from
/// the matrix one short step before the minimum).
#[test]
fn the_newton_stop_is_the_minimum_to_its_tolerance() {
    let robot = Robot::aubo_i5();
    let sim = SimulateOptions::paper(&robot);
    let opts = CalibrateOptions::new(&robot);
    let tol = opts.lm.newton_tolerance;
    let mut on = opts.clone();
    on.lm.newton_tolerance = 0.0;
    on.lm.function_tolerance = 1e-14;
    for (duration, seed) in [(60.0, 71), (120.0, 72)] {
        let s = random_session(&robot, duration, 1.0, &sim, seed).unwrap();
        let a = calibrate(&robot, &s.data, &opts, |_| {}).unwrap();
        let b = calibrate(&robot, &s.data, &on, |_| {}).unwrap();
        assert_eq!(a.summary.termination, Termination::NewtonTolerance);
        assert!(b.summary.termination.converged(), "{}", b.summary);
        assert!(
            a.summary.iterations.len() < b.summary.iterations.len(),
            "{} iterations against {}",
            a.summary.iterations.len(),
            b.summary.iterations.len()
        );
        for &k in &b.active {
            let e = (a.x[k] - b.x[k]).abs() / b.sigma[k];
            assert!(e < tol, "seed {seed}: x[{k}] off by {e:e} σ");
            let rel = (a.sigma[k] - b.sigma[k]).abs() / b.sigma[k];
            assert!(rel < 1e-3, "seed {seed}: σ[{k}] off by {rel:e}");
        }
    }
}
