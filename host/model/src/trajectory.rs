//! Random excitation trajectories within the joint limits, for simulation
//! and as the baseline of planning.
//!
//! A clamped B-spline per joint whose coefficients follow a random walk on
//! velocity (kept near but below the speed limit, reflected at the position
//! limits), at rest at both ends (the first and last p coefficients equal
//! their neighbours). Limits are then enforced exactly by shrinking the
//! motion about each joint's mean until the densely sampled speed and
//! acceleration are within the limits.

use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::{JointState, Knots, Robot, Spline, SplineError};

/// Largest |q̇| and |q̈| of each joint over a dense grid (`per_second` points per s).
pub fn max_rates(spline: &Spline, per_second: f64) -> (Vec<f64>, Vec<f64>) {
    let n = spline.dim();
    let (t0, t1) = (spline.knots().start(), spline.knots().end());
    let steps = ((t1 - t0) * per_second).ceil().max(1.0) as usize;
    let mut vmax = vec![0.0f64; n];
    let mut amax = vec![0.0f64; n];
    let mut js = JointState::default();
    for k in 0..=steps {
        let t = t0 + (t1 - t0) * k as f64 / steps as f64;
        spline.evaluate(t, &mut js).expect("t inside the spline");
        for j in 0..n {
            vmax[j] = vmax[j].max(js.qd[j].abs());
            amax[j] = amax[j].max(js.qdd[j].abs());
        }
    }
    (vmax, amax)
}

/// A random trajectory of `duration` s for `robot`, cubic, knots every
/// `knot_spacing` s, starting at t = 0 (see the module doc).
pub fn random_walk<R: Rng>(
    robot: &Robot,
    duration: f64,
    knot_spacing: f64,
    rng: &mut R,
) -> Result<Spline, SplineError> {
    let n = robot.dof();
    let degree = 3;
    let knots = Knots::uniform(0.0, duration, knot_spacing, degree)?;
    let m = knots.num_coeffs();
    let limits = robot.limits();
    let mut c = vec![0.0; m * n];
    for (j, lim) in limits.iter().enumerate() {
        let mid = 0.5 * (lim.q_min + lim.q_max);
        let half = 0.5 * (lim.q_max - lim.q_min);
        let (lo, hi) = (mid - 0.9 * half, mid + 0.9 * half);
        // coefficient differences ≈ velocity × spacing / 1 (cubic, uniform knots: q̇ ≈ Δc/Δt)
        let vmax = 0.8 * lim.qd_max;
        let dv = 0.5 * lim.qdd_max * knot_spacing;
        let mut q = mid + 0.5 * half * (rng.random::<f64>() - 0.5);
        let mut v = 0.0;
        for i in 0..m {
            let z: f64 = StandardNormal.sample(rng);
            v = (v + dv * z).clamp(-vmax, vmax);
            let next = q + v * knot_spacing;
            if next < lo || next > hi {
                v = -v;
            }
            q = (q + v * knot_spacing).clamp(lo, hi);
            c[i * n + j] = q;
        }
        // at rest at both ends
        for i in 1..=degree {
            c[i * n + j] = c[j];
            c[(m - 1 - i) * n + j] = c[(m - 1) * n + j];
        }
    }
    let mut spline = Spline::new(knots, n, c)?;
    enforce_limits(robot, &mut spline);
    Ok(spline)
}

/// Shrink each joint's motion about its mean until its densely sampled speed
/// and acceleration respect the limits (with a 2 % margin).
pub(crate) fn enforce_limits(robot: &Robot, spline: &mut Spline) {
    let n = spline.dim();
    let (vmax, amax) = max_rates(spline, 200.0);
    let m = spline.knots().num_coeffs();
    for (j, lim) in robot.limits().iter().enumerate() {
        let s = (0.98 * lim.qd_max / vmax[j].max(1e-300))
            .min(0.98 * lim.qdd_max / amax[j].max(1e-300))
            .min(1.0);
        if s < 1.0 {
            let c = spline.coeffs_mut();
            let mean = (0..m).map(|i| c[i * n + j]).sum::<f64>() / m as f64;
            for i in 0..m {
                c[i * n + j] = mean + s * (c[i * n + j] - mean);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn random_walk_respects_every_limit_and_rests_at_the_ends() {
        let robot = Robot::aubo_i5();
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let s = random_walk(&robot, 60.0, 1.0, &mut rng).unwrap();
        let (v, a) = max_rates(&s, 1000.0);
        let mut js = JointState::default();
        for (j, lim) in robot.limits().iter().enumerate() {
            assert!(
                v[j] <= lim.qd_max * 1.0001,
                "joint {j} speed {} > {}",
                v[j],
                lim.qd_max
            );
            assert!(
                a[j] <= lim.qdd_max * 1.0001,
                "joint {j} accel {} > {}",
                a[j],
                lim.qdd_max
            );
            // it moves: at least a fifth of the speed limit somewhere
            assert!(v[j] > 0.2 * lim.qd_max, "joint {j} barely moves: {}", v[j]);
        }
        for t in (0..=60_000).map(|k| k as f64 * 1e-3) {
            s.evaluate(t, &mut js).unwrap();
            for (j, lim) in robot.limits().iter().enumerate() {
                assert!(
                    js.q[j] >= lim.q_min && js.q[j] <= lim.q_max,
                    "joint {j} at t={t}"
                );
            }
        }
        for t in [0.0, 60.0] {
            s.evaluate(t, &mut js).unwrap();
            for j in 0..6 {
                assert!(js.qd[j].abs() < 1e-12 && js.qdd[j].abs() < 1e-12);
            }
        }
    }
}

/// Knot spacing used to represent a sampled plan, s: fine enough that a plan
/// made of any smooth spline with knots ≥ 0.5 s apart is reproduced to well
/// below the joint noise.
pub const PLAN_KNOT_SPACING: f64 = 0.05;

/// A trajectory from joint positions sampled densely in time (a plan's
/// `plan.csv`: `t`, then `q[s·n + j]`), as a cubic spline with knots every
/// [`PLAN_KNOT_SPACING`] s (or every 4 samples, whichever is longer) fitted by
/// least squares.
pub fn from_samples(n: usize, t: &[f64], q: &[f64]) -> Result<Spline, SplineError> {
    let (Some(&a), Some(&b)) = (t.first(), t.last()) else {
        return Err(SplineError::EmptyInterval { t0: 0.0, t1: 0.0 });
    };
    let spacing = PLAN_KNOT_SPACING.max(4.0 * (b - a) / t.len().max(1) as f64);
    let knots = Knots::uniform(a, b, spacing, 3)?;
    Spline::fit(knots, n, t, q)
}

#[cfg(test)]
mod plan_tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn a_sampled_plan_is_reproduced_with_its_derivatives() {
        let robot = Robot::aubo_i5();
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let plan = random_walk(&robot, 20.0, 1.0, &mut rng).unwrap();
        // sampled at 250 Hz, as a controller would take it
        let t: Vec<f64> = (0..=5000).map(|k| k as f64 / 250.0).collect();
        let mut q = Vec::new();
        let mut js = JointState::default();
        for &ti in &t {
            plan.evaluate(ti, &mut js).unwrap();
            q.extend_from_slice(&js.q[..6]);
        }
        let back = from_samples(6, &t, &q).unwrap();
        let mut jb = JointState::default();
        for k in 0..2000 {
            let ti = 0.01 * k as f64 + 0.003;
            plan.evaluate(ti, &mut js).unwrap();
            back.evaluate(ti, &mut jb).unwrap();
            for j in 0..6 {
                assert!((js.q[j] - jb.q[j]).abs() < 1e-8, "q at {ti}");
                assert!((js.qd[j] - jb.qd[j]).abs() < 1e-6, "q̇ at {ti}");
                assert!((js.qdd[j] - jb.qdd[j]).abs() < 1e-3, "q̈ at {ti}");
            }
        }
    }
}
