//! The simulated UR arm as programs drive it: a program's `movej` and
//! `servoj` are linear ramps of the reference, on the shared motion model
//! ([`crate::arm`]); the log also keeps the reference, so that a data
//! package can report the state at its cycle time after the fact.

// Joint loops index several joint vectors in step.
#![allow(clippy::needless_range_loop)]

use super::script::Command;
use super::SimUrConfig;
use crate::arm::follower::Follower;
use crate::arm::noise::Noise;
use crate::arm::reference::Reference;
use crate::arm::segment::Segment;
use crate::arm::{bracket, Joints, TrueState, JOINTS};

/// The simulated arm.
pub(crate) struct Robot {
    noise_rad: Joints,
    noise: Noise,
    /// The true angles and their log.
    pub(crate) arm: Follower,
    /// The running program's ramps.
    pub(crate) reference: Reference,
    /// The reference at each logged step.
    ref_log: Vec<Joints>,
}

impl Robot {
    pub(crate) fn new(config: &SimUrConfig) -> Robot {
        let t = config.epoch.elapsed().as_secs_f64();
        Robot {
            noise_rad: [config.encoder_noise_rad.max(0.0); JOINTS],
            noise: Noise { state: config.seed },
            arm: Follower::new(t, config.initial, config.tracking_lag_s),
            reference: Reference::new(t, config.initial),
            ref_log: vec![config.initial],
        }
    }

    /// Replaces the running program by `cmds`, starting at `now`.
    pub(crate) fn run(&mut self, cmds: Vec<Command>, now: f64) {
        let mut from = self.reference.at(now);
        self.reference.queue.clear();
        self.reference.hold = from;
        self.reference.front_start = now;
        for c in cmds {
            let (to, duration) = match c {
                Command::MoveJ { q, v } => {
                    let d = (0..JOINTS).fold(0.0_f64, |m, i| m.max((q[i] - from[i]).abs()));
                    (q, d / v)
                }
                Command::ServoJ { q, t } => (q, t),
                Command::StopJ => continue,
            };
            let ramp = Segment::Linear { from, to, duration };
            from = to;
            self.reference.queue.push_back((0, ramp));
        }
    }

    /// The true state at `t`: `q̇ = (r − q)/T`, `q̈ = (ṙ − q̇)/T` with the
    /// ramps' own rates (without a lag, the reference's; q̈ = 0 within a
    /// ramp).
    pub(crate) fn true_state(&mut self, t: f64) -> TrueState {
        self.advance_to(t);
        let reference = self.reference.derivatives(t.max(self.arm.t));
        self.arm.state(reference)
    }

    /// Integrates the lag up to `t`, logging the reference at each step.
    pub(crate) fn advance_to(&mut self, t: f64) {
        let (reference, ref_log) = (&mut self.reference, &mut self.ref_log);
        self.arm.advance_to(t, |t| {
            let r = reference.at(t);
            ref_log.push(r);
            r
        });
    }

    /// `q` as the encoders report it: plus Gaussian noise.
    pub(crate) fn measure(&mut self, q: Joints) -> Joints {
        self.noise.measure(q, &self.noise_rad)
    }

    /// The true angles and the reference at `t`: integrated forward, or
    /// interpolated in the log (steps ≤ 2 ms) when the simulation is
    /// already past `t`.
    pub(crate) fn state_at(&mut self, t: f64) -> (Joints, Joints) {
        if t >= self.arm.t {
            self.advance_to(t);
            return (self.arm.q, self.arm.r_prev);
        }
        let log = &self.arm.log;
        let (k, u) = bracket(log, t);
        let (a, b) = (&log[k - 1], &log[k]);
        let (mut q, mut r) = (a.q, self.ref_log[k - 1]);
        for i in 0..JOINTS {
            q[i] += u * (b.q[i] - a.q[i]);
            r[i] += u * (self.ref_log[k][i] - r[i]);
        }
        (q, r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn program_ramps_the_reference_through_the_lag() {
        let config = SimUrConfig {
            tracking_lag_s: 0.0,
            ..SimUrConfig::default()
        };
        let mut r = Robot::new(&config);
        let t0 = r.arm.t;
        r.run(
            vec![
                Command::MoveJ {
                    q: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                    v: 2.0,
                },
                Command::ServoJ {
                    q: [1.0, 0.2, 0.0, 0.0, 0.0, 0.0],
                    t: 0.1,
                },
            ],
            t0,
        );
        // movej: 1 rad at 2 rad/s = 0.5 s, then servoj 0.1 s.
        assert!((r.state_at(t0 + 0.25).0[0] - 0.5).abs() < 1e-9);
        assert!((r.state_at(t0 + 0.55).0[1] - 0.1).abs() < 1e-9);
        assert_eq!(r.state_at(t0 + 1.0).0, [1.0, 0.2, 0.0, 0.0, 0.0, 0.0]);
        // In the past: interpolated from the log.
        let (q, reference) = r.state_at(t0 + 0.251);
        assert!((q[0] - 0.502).abs() < 1e-9 && (reference[0] - 0.502).abs() < 1e-9);
    }
}
