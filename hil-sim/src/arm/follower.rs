//! The true joint angles: a first-order lag behind the reference,
//! integrated exactly for a reference linear within each step and logged.

// Joint loops index several joint vectors in step.
#![allow(clippy::needless_range_loop)]

use super::{Joints, TrueSample, TrueState, JOINTS, MAX_STEP_S};

/// The true angles following a reference through the lag `T`.
#[derive(Debug)]
pub(crate) struct Follower {
    /// The lag's time constant `T`, s (0: the angles are the reference).
    pub(crate) lag_s: f64,
    /// True joint angles at `t`.
    pub(crate) q: Joints,
    /// Time of the last integration step, s since the epoch.
    pub(crate) t: f64,
    /// The reference at `t`.
    pub(crate) r_prev: Joints,
    /// Every integration step so far.
    pub(crate) log: Vec<TrueSample>,
}

impl Follower {
    /// At rest at `initial` at time `t`, with lag `lag_s` (negative: none).
    pub(crate) fn new(t: f64, initial: Joints, lag_s: f64) -> Self {
        Follower {
            lag_s: lag_s.max(0.0),
            q: initial,
            t,
            r_prev: initial,
            log: vec![TrueSample { t, q: initial }],
        }
    }

    /// Integrates the lag up to time `t` in steps of at most
    /// [`MAX_STEP_S`], `reference(t')` being the reference at each step's
    /// end `t'` (called once per step, in order).
    pub(crate) fn advance_to(&mut self, t: f64, mut reference: impl FnMut(f64) -> Joints) {
        while self.t < t {
            let h = (t - self.t).min(MAX_STEP_S);
            let t_next = self.t + h;
            let r = reference(t_next);
            lag_step(&mut self.q, &self.r_prev, &r, h, self.lag_s);
            self.r_prev = r;
            self.t = t_next;
            self.log.push(TrueSample {
                t: self.t,
                q: self.q,
            });
        }
    }

    /// The true state at the last integration time, the reference there
    /// being `reference = [r, ṙ, r̈]`: with a lag `T`, `q̇ = (r − q)/T` and
    /// `q̈ = (ṙ − q̇)/T` (the lag's own equation, with the exact reference);
    /// without one the reference's own derivatives.
    pub(crate) fn state(&self, reference: [Joints; 3]) -> TrueState {
        let [r, rd, rdd] = reference;
        let mut state = TrueState {
            t: self.t,
            q: self.q,
            qd: rd,
            qdd: rdd,
        };
        if self.lag_s > 0.0 {
            for i in 0..JOINTS {
                state.qd[i] = (r[i] - self.q[i]) / self.lag_s;
                state.qdd[i] = (rd[i] - state.qd[i]) / self.lag_s;
            }
        }
        state
    }
}

/// One step of the first-order tracking lag `dq/dt = (r − q)/T` over `h`
/// seconds, exact for a reference linear from `r_prev` to `r` within the
/// step: with `r = r₀ + s·t`, `q − r + sT` decays as `e^(−t/T)`. `T = 0`
/// tracks the reference exactly.
fn lag_step(q: &mut Joints, r_prev: &Joints, r: &Joints, h: f64, lag_s: f64) {
    let decay = if lag_s > 0.0 { (-h / lag_s).exp() } else { 0.0 };
    for i in 0..JOINTS {
        let s = (r[i] - r_prev[i]) / h;
        let tail = s * lag_s;
        q[i] = r[i] - tail + (q[i] - r_prev[i] + tail) * decay;
    }
}
