//! The tracker/robot time offset δ (paper §9).
//!
//! An external tracker stamps its poses with its own clock. The paper first
//! aligned the tracker with the robot data, so that the tracker/IMU alignment
//! is the sum of that offset and the estimated robot/IMU offset τ. Here
//!
//! ```text
//! δ = t_tracker − t_session:  the tracker sample stamped t was taken at
//!                             session (robot) time t − δ;
//! an IMU sample stamped t_i  ↔  robot time t_i + τ  ↔  tracker time t_i + τ + δ
//! ```
//!
//! δ is found by matching angular speeds, which do not depend on the frames:
//! the marker body and the flange are one rigid body, so
//! |ω_marker|(t) = |ω_flange|(t − δ). Both are computed the same way: unit
//! quaternions of the tracked marker orientations, and of the flange
//! orientations F(q_k; ε) (eq. (3), calibrated ε) at the joint samples, are
//! fitted by degree-5 splines (one interior knot per 30 samples) and
//! |ω| = |2 vec(q̇ ⊗ q*)| / |q|² is sampled on a 10 ms grid. A coarse scan of
//! the mean squared difference over every lag whose overlap covers at least
//! half of the shorter recording is refined by a 1 ms scan around its
//! optimum and a parabola through the best three lags (as
//! [`time_offset`](super::time_offset) does for τ).

use super::time_offset::parabola_vertex;
use crate::tracker::{flange_eps, flange_pose, pose_from_row, ValidateError};
use robimu_model::geom::quat_from_matrix;
use robimu_model::geom::{dot, M3};
use robimu_model::{JointState, Knots, ParamLayout, Robot, Spline};
use robimu_session::Table;

fn input(m: impl Into<String>) -> ValidateError {
    ValidateError::Input(m.into())
}

/// Search settings.
#[derive(Debug, Clone, Copy)]
pub struct OffsetSearch {
    /// Step of the |ω| grids, s.
    pub grid_step: f64,
    /// Coarse lag step, s.
    pub coarse_step: f64,
    /// Fine lag step, s.
    pub fine_step: f64,
    /// Each recording must span at least this long (inside its spline's
    /// trusted span), s.
    pub min_duration: f64,
    /// Lags whose overlap is shorter than this fraction of the shorter
    /// recording are not tried.
    pub min_overlap: f64,
    /// Tracker (and joint) samples per interior spline knot.
    pub samples_per_knot: usize,
}

impl Default for OffsetSearch {
    fn default() -> Self {
        Self {
            grid_step: 0.01,
            coarse_step: 0.02,
            fine_step: 0.001,
            min_duration: 5.0,
            min_overlap: 0.5,
            samples_per_knot: 30,
        }
    }
}

/// The estimated offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerOffset {
    /// δ = t_tracker − t_session, s.
    pub delta: f64,
    /// Fraction of the tracked angular speed's variance explained by the
    /// robot's at δ (1 = perfect).
    pub r_squared: f64,
    /// RMS difference of the angular speeds at δ, rad/s.
    pub rms: f64,
    /// Length of the overlap at δ, s.
    pub overlap: f64,
}

/// The δ applied to a tracked motion: given by the user or estimated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerAlignment {
    /// δ = t_tracker − t_session, s.
    pub delta: f64,
    /// The estimate, when δ was estimated (`None`: given).
    pub estimate: Option<TrackerOffset>,
}

/// An angular speed |ω| (rad/s) on a uniform time grid.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AngularSpeed {
    /// Time of the first value, s.
    pub t0: f64,
    /// Grid step, s.
    pub step: f64,
    /// |ω| at t0 + k·step.
    pub values: Vec<f64>,
}

impl AngularSpeed {
    /// |ω| of a rigid body from its orientations `rotations` at `times`
    /// (quaternion spline, see the module doc), on a grid of `step` over the
    /// fit's trusted span (one knot span in from each end). `what` names the
    /// recording in errors.
    pub fn from_rotations(
        times: &[f64],
        rotations: &[M3],
        step: f64,
        samples_per_knot: usize,
        what: &str,
    ) -> Result<Self, ValidateError> {
        let m = times.len();
        let per_knot = samples_per_knot.max(1);
        if m != rotations.len() || m < 8 * per_knot {
            return Err(input(format!(
                "{what}: {m} samples are too few to find the tracker time offset (need at least {})",
                8 * per_knot
            )));
        }
        let (a, b) = (times[0], times[m - 1]);
        if times.iter().any(|t| !t.is_finite()) || b <= a || times.windows(2).any(|w| w[1] < w[0]) {
            return Err(input(format!(
                "{what}: the sample times are not increasing"
            )));
        }
        let mut att = Vec::with_capacity(4 * m);
        let mut prev = [1.0, 0.0, 0.0, 0.0];
        for r in rotations {
            let mut q = quat_from_matrix(r);
            if q.iter().zip(&prev).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
                q = q.map(|v| -v);
            }
            prev = q;
            att.extend(q);
        }
        let spacing = per_knot as f64 * (b - a) / (m - 1) as f64;
        let knots = Knots::uniform(a, b, spacing, 5).map_err(|e| input(format!("{what}: {e}")))?;
        let spline = Spline::fit(knots, 4, times, &att)
            .map_err(|e| input(format!("{what}: cannot fit the orientations: {e}")))?;
        let k = spline.knots();
        let margin = (k.end() - k.start()) / (k.num_coeffs() - k.degree()).max(1) as f64;
        let (lo, hi) = (k.start() + margin, k.end() - margin);
        let count = ((hi - lo) / step).floor() as usize + 1;
        let mut js = JointState::default();
        let mut values = Vec::with_capacity(count);
        for i in 0..count {
            let t = (lo + i as f64 * step).min(hi);
            spline
                .evaluate(t, &mut js)
                .map_err(|e| input(format!("{what}: {e}")))?;
            let q = [js.q[0], js.q[1], js.q[2], js.q[3]];
            let qd = [js.qd[0], js.qd[1], js.qd[2], js.qd[3]];
            let n2: f64 = q.iter().map(|v| v * v).sum();
            // vec(q̇ ⊗ q*) = q_w q̇_v − q̇_w q_v − q̇_v × q_v
            let (qv, qdv) = ([q[1], q[2], q[3]], [qd[1], qd[2], qd[3]]);
            let c = robimu_model::geom::cross(qdv, qv);
            let v: [f64; 3] = std::array::from_fn(|i| q[0] * qdv[i] - qd[0] * qv[i] - c[i]);
            values.push(2.0 * dot(v, v).sqrt() / n2);
        }
        Ok(Self {
            t0: lo,
            step,
            values,
        })
    }

    /// Time of the last value, s.
    pub fn end(&self) -> f64 {
        self.t0 + (self.values.len().max(1) - 1) as f64 * self.step
    }

    /// Length of the grid, s.
    pub fn duration(&self) -> f64 {
        self.end() - self.t0
    }

    /// |ω| at t, linearly interpolated; `None` outside the grid.
    pub fn at(&self, t: f64) -> Option<f64> {
        if !(t >= self.t0 && t <= self.end()) {
            return None;
        }
        let f = (t - self.t0) / self.step;
        let last = self.values.len() - 1;
        let k = (f.floor() as usize).min(last.saturating_sub(1));
        let a = f - k as f64;
        let (p, q) = (self.values[k], self.values[(k + 1).min(last)]);
        Some(p + a * (q - p))
    }
}

/// |ω| of the tracked marker body, from the tracker table (tracker clock).
pub(crate) fn tracker_angular_speed(
    tracker: &Table,
    search: &OffsetSearch,
) -> Result<AngularSpeed, ValidateError> {
    if tracker.width() != 7 {
        return Err(input(format!(
            "a tracker table has 7 value columns (px, py, pz, qw, qx, qy, qz), not {}",
            tracker.width()
        )));
    }
    let rotations = (0..tracker.len())
        .map(|i| {
            pose_from_row(tracker.row(i)).map(|p| p.r).map_err(|e| {
                input(format!(
                    "tracker sample {} (t = {} s): {e}",
                    i + 1,
                    tracker.t[i]
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    AngularSpeed::from_rotations(
        &tracker.t,
        &rotations,
        search.grid_step,
        search.samples_per_knot,
        "the tracked motion",
    )
}

/// |ω| of the flange from the joint samples (session clock), by forward
/// kinematics F(q; ε) with the generalized errors of `x`.
pub(crate) fn flange_angular_speed(
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
    joint_t: &[f64],
    joint_q: &[f64],
    search: &OffsetSearch,
) -> Result<AngularSpeed, ValidateError> {
    let n = robot.dof();
    if joint_q.len() != joint_t.len() * n {
        return Err(input(format!(
            "the joint samples do not have {n} angles each (robot `{}`)",
            robot.name()
        )));
    }
    let eps = flange_eps(layout, x)?;
    let rotations: Vec<M3> = joint_q
        .chunks_exact(n)
        .map(|q| flange_pose(robot, &eps, q).r)
        .collect();
    AngularSpeed::from_rotations(
        joint_t,
        &rotations,
        search.grid_step,
        search.samples_per_knot,
        "the joint samples",
    )
}

/// Overlap [lo, hi] of the tracker grid with the robot grid shifted by δ
/// (both on the tracker clock).
fn overlap(tracker: &AngularSpeed, robot: &AngularSpeed, delta: f64) -> (f64, f64) {
    (
        tracker.t0.max(robot.t0 + delta),
        tracker.end().min(robot.end() + delta),
    )
}

/// Mean squared difference, variance of the tracker's |ω| and overlap at δ,
/// using every `stride`-th tracker grid point.
fn mismatch(
    tracker: &AngularSpeed,
    robot: &AngularSpeed,
    delta: f64,
    stride: usize,
) -> Option<(f64, f64, f64)> {
    let (lo, hi) = overlap(tracker, robot, delta);
    if hi <= lo {
        return None;
    }
    let (mut ss, mut s1, mut s2, mut count) = (0.0, 0.0, 0.0, 0usize);
    let first = ((lo - tracker.t0) / tracker.step).ceil().max(0.0) as usize;
    for k in (first..tracker.values.len()).step_by(stride.max(1)) {
        let t = tracker.t0 + k as f64 * tracker.step;
        if t > hi {
            break;
        }
        let Some(r) = robot.at(t - delta) else {
            continue;
        };
        let w = tracker.values[k];
        ss += (w - r) * (w - r);
        s1 += w;
        s2 += w * w;
        count += 1;
    }
    if count < 10 {
        return None;
    }
    let c = count as f64;
    Some((ss / c, (s2 / c - (s1 / c).powi(2)).max(0.0), hi - lo))
}

/// Find δ (see the module doc) from the two angular speeds.
pub(crate) fn find_tracker_offset(
    tracker: &AngularSpeed,
    robot: &AngularSpeed,
    search: &OffsetSearch,
) -> Result<TrackerOffset, ValidateError> {
    for (what, s) in [
        ("the tracked motion", tracker),
        ("the joint samples", robot),
    ] {
        if s.duration() < search.min_duration {
            return Err(input(format!(
                "{what} spans only {:.2} s after the spline fit: too short to find the tracker time offset (needs at least {} s; give it with --tracker-offset)",
                s.duration().max(0.0),
                search.min_duration
            )));
        }
    }
    let need = search.min_overlap * tracker.duration().min(robot.duration());
    let (lo, hi) = (tracker.t0 - robot.end(), tracker.end() - robot.t0);
    let stride = ((search.coarse_step / tracker.step).round() as usize).max(1);
    let steps = ((hi - lo) / search.coarse_step).ceil() as usize;
    let mut best: Option<(f64, f64)> = None;
    for k in 0..=steps {
        let delta = lo + k as f64 * search.coarse_step;
        let (a, b) = overlap(tracker, robot, delta);
        if b - a < need {
            continue;
        }
        if let Some((msd, _, _)) = mismatch(tracker, robot, delta, stride) {
            if best.is_none_or(|(_, m)| msd < m) {
                best = Some((delta, msd));
            }
        }
    }
    let Some((coarse, _)) = best else {
        return Err(input(
            "the tracked motion and the joint samples do not overlap enough at any time offset",
        ));
    };
    let n_fine = (2.0 * search.coarse_step / search.fine_step).round() as i64;
    let fine: Vec<(f64, f64, f64, f64)> = (-n_fine..=n_fine)
        .filter_map(|k| {
            let delta = coarse + k as f64 * search.fine_step;
            mismatch(tracker, robot, delta, 1).map(|(m, v, o)| (delta, m, v, o))
        })
        .collect();
    let ib = (0..fine.len())
        .min_by(|&a, &b| fine[a].1.total_cmp(&fine[b].1))
        .ok_or_else(|| input("the tracked motion and the joint samples do not overlap"))?;
    let (mut delta, msd, var, overlap) = fine[ib];
    let r_squared = if var > 0.0 { 1.0 - msd / var } else { 0.0 };
    if r_squared < 0.5 {
        return Err(input(format!(
            "the tracked angular speed does not follow the robot's at any time offset (best R² = {r_squared:.2} at δ = {delta:.3} s): is the tracker recording from the same motion as the joint samples, and does the robot rotate?"
        )));
    }
    if ib > 0 && ib + 1 < fine.len() {
        delta += parabola_vertex(fine[ib - 1].1, fine[ib].1, fine[ib + 1].1, search.fine_step);
    }
    Ok(TrackerOffset {
        delta,
        r_squared,
        rms: msd.sqrt(),
        overlap,
    })
}

/// δ of a tracked motion against the joint samples of the same run, with
/// the flange kinematics of `x` (the calibrated parameters).
pub fn estimate_tracker_offset(
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
    tracker: &Table,
    joint_t: &[f64],
    joint_q: &[f64],
    search: &OffsetSearch,
) -> Result<TrackerOffset, ValidateError> {
    let tw = tracker_angular_speed(tracker, search)?;
    let rw = flange_angular_speed(robot, layout, x, joint_t, joint_q, search)?;
    find_tracker_offset(&tw, &rw, search)
}

/// The tracker table on the session clock (t − δ), after checking that it
/// still overlaps the joint samples' span `[a, b]`.
pub fn to_session_clock(
    tracker: &Table,
    delta: f64,
    joints: (f64, f64),
) -> Result<Table, ValidateError> {
    let (ta, tb) = tracker
        .span()
        .ok_or_else(|| input("the tracked motion has no samples"))?;
    let (a, b) = joints;
    if !delta.is_finite() || tb - delta <= a || ta - delta >= b {
        return Err(input(format!(
            "with the tracker time offset δ = {delta} s the tracked motion ({ta}..{tb} s on the tracker clock, {}..{} s on the session clock) does not overlap the joint samples ({a}..{b} s)",
            ta - delta,
            tb - delta
        )));
    }
    Ok(Table {
        t: tracker.t.iter().map(|t| t - delta).collect(),
        ..tracker.clone()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::geom::exp_so3;

    /// A body turning about a fixed axis with angle θ(t) = sin(t) + 0.3 sin(2.3 t):
    /// |ω| = |θ̇|, exact.
    fn spin(times: &[f64]) -> Vec<M3> {
        times
            .iter()
            .map(|&t| {
                let th = t.sin() + 0.3 * (2.3 * t).sin();
                exp_so3([0.48 * th, -0.6 * th, 0.64 * th])
            })
            .collect()
    }

    #[test]
    fn angular_speed_matches_the_exact_rate_and_the_offset_is_found() {
        let s = OffsetSearch::default();
        let tr: Vec<f64> = (0..2400).map(|k| 100.0 + k as f64 / 120.0).collect();
        let w = AngularSpeed::from_rotations(&tr, &spin(&tr), 0.01, 30, "t").unwrap();
        let mut worst: f64 = 0.0;
        for (k, v) in w.values.iter().enumerate() {
            let t = w.t0 + k as f64 * w.step;
            let exact = (t.cos() + 0.69 * (2.3 * t).cos()).abs();
            worst = worst.max((v - exact).abs());
        }
        assert!(worst < 1e-4, "{worst}");
        // the same motion on a clock 100 s − 0.2317 s behind
        let delta = 0.2317;
        let session: Vec<f64> = (0..3000).map(|k| k as f64 / 100.0 + 90.0).collect();
        let shifted: Vec<f64> = session.iter().map(|t| t + delta).collect();
        let r = AngularSpeed::from_rotations(&session, &spin(&shifted), 0.01, 30, "r").unwrap();
        let est = find_tracker_offset(&w, &r, &s).unwrap();
        assert!((est.delta - delta).abs() < 2e-4, "{est:?}");
        assert!(est.r_squared > 0.999, "{est:?}");
        // a still body cannot be aligned; a short one is refused
        let still: Vec<M3> = tr.iter().map(|_| exp_so3([0.1, 0.2, 0.3])).collect();
        let ws = AngularSpeed::from_rotations(&tr, &still, 0.01, 30, "t").unwrap();
        let e = find_tracker_offset(&ws, &r, &s).unwrap_err().to_string();
        assert!(e.contains("does not follow"), "{e}");
        let short = &tr[..300];
        let wshort = AngularSpeed::from_rotations(short, &spin(short), 0.01, 30, "t").unwrap();
        let e = find_tracker_offset(&wshort, &r, &s)
            .unwrap_err()
            .to_string();
        assert!(e.contains("too short"), "{e}");
        let e = AngularSpeed::from_rotations(&tr[..100], &spin(&tr[..100]), 0.01, 30, "tiny")
            .unwrap_err()
            .to_string();
        assert!(e.contains("tiny") && e.contains("too few"), "{e}");
    }
}
