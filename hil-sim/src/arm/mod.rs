//! The simulated arm both simulated controllers ([`crate::aubo`],
//! [`crate::ur`]) drive: a reference `r(t)` made of queued motion segments
//! (`segment`, `reference`), true joint angles following it through a
//! first-order lag (`follower`), and Gaussian encoder noise on what the
//! controllers report (`noise`).
//!
//! The lag `dq/dt = (r − q)/T` is integrated in steps of at most
//! 2 ms, exactly for a reference linear within each step, so the
//! result does not depend on how an interval is cut into steps; every step
//! is logged as a [`TrueSample`].

pub(crate) mod follower;
pub(crate) mod noise;
pub(crate) mod reference;
pub(crate) mod segment;

/// Number of joints of the simulated arm.
pub const JOINTS: usize = 6;

/// A joint vector, rad.
pub type Joints = [f64; JOINTS];

/// Largest integration step of the simulation, s.
pub(crate) const MAX_STEP_S: f64 = 0.002;

/// One time-stamped sample of the true joint angles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueSample {
    /// Seconds since the configured epoch.
    pub t: f64,
    /// True joint angles, rad.
    pub q: Joints,
}

/// The true joint angles at `t`, linearly interpolated in a true
/// trajectory `log` (sorted by time, at least two samples; clamped to its
/// ends).
pub fn true_joints_at(log: &[TrueSample], t: f64) -> Joints {
    let (k, u) = bracket(log, t);
    let (a, b) = (&log[k - 1], &log[k]);
    std::array::from_fn(|i| a.q[i] + u * (b.q[i] - a.q[i]))
}

/// How readings `(t, angle)` of joint `joint` differ from the true
/// trajectory `log` at their times ([`true_joints_at`]): the mean and the
/// (population) standard deviation of the differences, rad. The reported
/// angles' bias and encoder noise, as a client sees them.
pub fn reading_errors(
    log: &[TrueSample],
    joint: usize,
    readings: impl IntoIterator<Item = (f64, f64)>,
) -> (f64, f64) {
    let diffs: Vec<f64> = readings
        .into_iter()
        .map(|(t, q)| q - true_joints_at(log, t)[joint])
        .collect();
    let n = diffs.len() as f64;
    let mean = diffs.iter().sum::<f64>() / n;
    let sd = (diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n).sqrt();
    (mean, sd)
}

/// Where `t` falls in `log`: the index `k` of the later of the two samples
/// around it and the fraction `u` of the way from `k − 1` to `k`.
pub(crate) fn bracket(log: &[TrueSample], t: f64) -> (usize, f64) {
    let k = log.partition_point(|s| s.t < t).clamp(1, log.len() - 1);
    let (a, b) = (&log[k - 1], &log[k]);
    (k, ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0))
}

/// The true joint state at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueState {
    /// Seconds since the configured epoch.
    pub t: f64,
    /// Joint angles, rad.
    pub q: Joints,
    /// Joint velocities, rad/s.
    pub qd: Joints,
    /// Joint accelerations, rad/s².
    pub qdd: Joints,
}

/// Where a simulated IMU on the flange gets the arm's true motion: any
/// simulated controller's state probe.
pub trait TrueMotion: Send {
    /// The true state now.
    fn now(&self) -> TrueState;
}
