//! Motion segments of the reference: synchronised trapezoidal moves,
//! linear ramps, and cubic Hermite paths through waypoints a fixed
//! interval apart.

// Joint loops index several joint vectors in step.
#![allow(clippy::needless_range_loop)]

use super::{Joints, JOINTS};

/// One motion of the reference, as a function of the time `τ` since it
/// started.
#[derive(Clone, Debug)]
pub(crate) enum Segment {
    /// Synchronised trapezoidal move: `q0 + dq·s(τ)/d`.
    Trapezoid {
        q0: Joints,
        dq: Joints,
        d: f64,
        a: f64,
        t_acc: f64,
        duration: f64,
    },
    /// Straight from `from` to `to` in `duration` seconds.
    Linear {
        from: Joints,
        to: Joints,
        duration: f64,
    },
    /// Cubic Hermite path through `points`, `h` seconds apart.
    Spline { points: Vec<Joints>, h: f64 },
}

impl Segment {
    /// From `q0` to `q1` with the largest joint step at speed `v` and
    /// acceleration `a` (a triangle when `v` is not reached).
    pub(crate) fn trapezoid(q0: Joints, q1: Joints, v: f64, a: f64) -> Segment {
        let mut dq = [0.0; JOINTS];
        for i in 0..JOINTS {
            dq[i] = q1[i] - q0[i];
        }
        let d = dq.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let (t_acc, duration) = if d * a < v * v {
            let t = (d / a).sqrt();
            (t, 2.0 * t)
        } else {
            (v / a, d / v + v / a)
        };
        Segment::Trapezoid {
            q0,
            dq,
            d,
            a,
            t_acc,
            duration,
        }
    }

    /// How long it runs, s.
    pub(crate) fn duration(&self) -> f64 {
        match self {
            Segment::Trapezoid { duration, .. } | Segment::Linear { duration, .. } => *duration,
            Segment::Spline { points, h } => (points.len() - 1) as f64 * h,
        }
    }

    /// The joint angles at `tau` (clamped to the segment).
    pub(crate) fn eval(&self, tau: f64) -> Joints {
        match self {
            Segment::Trapezoid {
                q0,
                dq,
                d,
                a,
                t_acc,
                duration,
            } => {
                if *d == 0.0 {
                    return *q0;
                }
                let tau = tau.clamp(0.0, *duration);
                let v_peak = a * t_acc;
                let s = if tau < *t_acc {
                    0.5 * a * tau * tau
                } else if tau <= duration - t_acc {
                    0.5 * a * t_acc * t_acc + v_peak * (tau - t_acc)
                } else {
                    let r = duration - tau;
                    d - 0.5 * a * r * r
                };
                let mut q = *q0;
                for i in 0..JOINTS {
                    q[i] += dq[i] * s / d;
                }
                q
            }
            Segment::Linear { from, to, duration } => {
                let u = if *duration > 0.0 {
                    (tau / duration).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                let mut q = *from;
                for i in 0..JOINTS {
                    q[i] += (to[i] - from[i]) * u;
                }
                q
            }
            Segment::Spline { points, h } => spline_eval(points, *h, tau),
        }
    }

    /// Where it ends.
    pub(crate) fn end(&self) -> Joints {
        match self {
            Segment::Linear { to, .. } => *to,
            _ => self.eval(self.duration()),
        }
    }

    /// The reference and its first two time derivatives at `tau`.
    pub(crate) fn eval_derivatives(&self, tau: f64) -> [Joints; 3] {
        if let Segment::Spline { points, h } = self {
            return spline_derivatives(points, *h, tau);
        }
        let mut out = [self.eval(tau), [0.0; JOINTS], [0.0; JOINTS]];
        match self {
            Segment::Trapezoid {
                dq,
                d,
                a,
                t_acc,
                duration,
                ..
            } => {
                if *d == 0.0 || tau <= 0.0 || tau >= *duration {
                    return out;
                }
                let (v, acc) = if tau < *t_acc {
                    (a * tau, *a)
                } else if tau <= duration - t_acc {
                    (a * t_acc, 0.0)
                } else {
                    (a * (duration - tau), -a)
                };
                for i in 0..JOINTS {
                    out[1][i] = dq[i] * v / d;
                    out[2][i] = dq[i] * acc / d;
                }
            }
            Segment::Linear { from, to, duration } => {
                if *duration > 0.0 && tau > 0.0 && tau < *duration {
                    for i in 0..JOINTS {
                        out[1][i] = (to[i] - from[i]) / duration;
                    }
                }
            }
            Segment::Spline { .. } => {}
        }
        out
    }
}

/// The central-difference tangent (one-sided at the ends) of joint `i` at
/// waypoint `j`, per waypoint interval.
fn tangent(points: &[Joints], j: usize, i: usize) -> f64 {
    let n = points.len();
    let lo = j.saturating_sub(1);
    let hi = (j + 1).min(n - 1);
    (points[hi][i] - points[lo][i]) / (hi - lo) as f64
}

/// The waypoint `k` before `tau` and the fraction `u` of the way to `k + 1`
/// (at least two points).
fn locate(n: usize, h: f64, tau: f64) -> (usize, f64) {
    let x = (tau / h).clamp(0.0, (n - 1) as f64);
    let k = (x.floor() as usize).min(n - 2);
    (k, x - k as f64)
}

/// Cubic Hermite interpolation with central-difference tangents (one-sided
/// at the ends).
pub(crate) fn spline_eval(points: &[Joints], h: f64, tau: f64) -> Joints {
    let n = points.len();
    if n == 1 {
        return points[0];
    }
    let (k, u) = locate(n, h, tau);
    let (h00, h10, h01, h11) = (
        2.0 * u * u * u - 3.0 * u * u + 1.0,
        u * u * u - 2.0 * u * u + u,
        -2.0 * u * u * u + 3.0 * u * u,
        u * u * u - u * u,
    );
    let mut q = [0.0; JOINTS];
    for i in 0..JOINTS {
        q[i] = h00 * points[k][i]
            + h10 * tangent(points, k, i)
            + h01 * points[k + 1][i]
            + h11 * tangent(points, k + 1, i);
    }
    q
}

/// [`spline_eval`] and its first two derivatives with respect to time.
fn spline_derivatives(points: &[Joints], h: f64, tau: f64) -> [Joints; 3] {
    let n = points.len();
    let mut out = [spline_eval(points, h, tau), [0.0; JOINTS], [0.0; JOINTS]];
    if n == 1 || tau < 0.0 || tau > (n - 1) as f64 * h {
        return out;
    }
    let (k, u) = locate(n, h, tau);
    let d1 = [
        6.0 * u * u - 6.0 * u,
        3.0 * u * u - 4.0 * u + 1.0,
        -6.0 * u * u + 6.0 * u,
        3.0 * u * u - 2.0 * u,
    ];
    let d2 = [
        12.0 * u - 6.0,
        6.0 * u - 4.0,
        -12.0 * u + 6.0,
        6.0 * u - 2.0,
    ];
    for i in 0..JOINTS {
        let c = [
            points[k][i],
            tangent(points, k, i),
            points[k + 1][i],
            tangent(points, k + 1, i),
        ];
        out[1][i] = (0..4).map(|j| d1[j] * c[j]).sum::<f64>() / h;
        out[2][i] = (0..4).map(|j| d2[j] * c[j]).sum::<f64>() / (h * h);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_matches_closed_form() {
        // 1 rad at v = 0.5, a = 1: t_acc 0.5 s, total 1/0.5 + 0.5 = 2.5 s.
        let q1 = [1.0, -0.5, 0.0, 0.0, 0.0, 0.25];
        let seg = Segment::trapezoid([0.0; JOINTS], q1, 0.5, 1.0);
        assert!((seg.duration() - 2.5).abs() < 1e-12);
        // Halfway in time is halfway in distance (symmetry).
        let mid = seg.eval(1.25);
        assert!((mid[0] - 0.5).abs() < 1e-12 && (mid[1] + 0.25).abs() < 1e-12);
        // End of acceleration: a t²/2 = 0.125.
        assert!((seg.eval(0.5)[0] - 0.125).abs() < 1e-12);
        assert_eq!(seg.end(), q1);
    }

    #[test]
    fn spline_interpolates_waypoints_and_a_line_exactly() {
        let points: Vec<Joints> = (0..5).map(|k| [0.1 * k as f64; JOINTS]).collect();
        for k in 0..5 {
            assert!(
                (spline_eval(&points, 0.01, 0.01 * k as f64)[0] - 0.1 * k as f64).abs() < 1e-12
            );
        }
        // A line stays a line between points.
        assert!((spline_eval(&points, 0.01, 0.025)[3] - 0.25).abs() < 1e-12);
    }

    #[test]
    fn a_linear_ramp_ends_exactly_at_its_target_and_has_its_rate_inside() {
        let (from, to) = ([0.1; JOINTS], [0.3, 0.7, -0.2, 0.0, 0.1, 1.0]);
        let seg = Segment::Linear {
            from,
            to,
            duration: 0.3,
        };
        assert_eq!(seg.end(), to);
        let [q, qd, qdd] = seg.eval_derivatives(0.15);
        for i in 0..JOINTS {
            assert!((q[i] - (from[i] + to[i]) / 2.0).abs() < 1e-12);
            assert!((qd[i] - (to[i] - from[i]) / 0.3).abs() < 1e-12);
            assert_eq!(qdd[i], 0.0);
        }
        assert_eq!(seg.eval_derivatives(0.3)[1], [0.0; JOINTS]);
    }
}
