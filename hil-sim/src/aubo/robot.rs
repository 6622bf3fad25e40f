//! The simulated arm as the ARCS commands drive it: joint limits, joint
//! moves, servo mode, path buffers, execution ids, on the shared motion
//! model ([`crate::arm`]).

// Joint loops index several joint vectors in step.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;

use super::{status, SimAuboConfig};
use crate::arm::follower::Follower;
use crate::arm::noise::Noise;
use crate::arm::reference::Reference;
use crate::arm::segment::Segment;
use crate::arm::{Joints, TrueState, JOINTS};

/// How far a path buffer's first point may be from the planned position, rad.
const PATH_START_TOLERANCE: f64 = 0.01;

/// Per-joint limits of the simulated arm.
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimits {
    /// Lower position limits, rad.
    pub position_min: Joints,
    /// Upper position limits, rad.
    pub position_max: Joints,
    /// Speed limits, rad/s.
    pub velocity: Joints,
    /// Acceleration limits, rad/s².
    pub acceleration: Joints,
}

impl JointLimits {
    /// The same limits on every joint.
    pub fn uniform(position: f64, velocity: f64, acceleration: f64) -> Self {
        JointLimits {
            position_min: [-position; JOINTS],
            position_max: [position; JOINTS],
            velocity: [velocity; JOINTS],
            acceleration: [acceleration; JOINTS],
        }
    }

    fn within_position(&self, q: &Joints) -> bool {
        (0..JOINTS).all(|i| q[i] >= self.position_min[i] && q[i] <= self.position_max[i])
    }
}

impl Default for JointLimits {
    /// About an AUBO i5: ±175° joints (exactly: no less than its
    /// description's, so that a plan at the limit is accepted), 180°/s,
    /// 1000°/s².
    fn default() -> Self {
        JointLimits::uniform(175f64.to_radians(), std::f64::consts::PI, 17.4)
    }
}

/// A path buffer being filled.
#[derive(Debug)]
pub(crate) struct PathBuffer {
    size: usize,
    points: Vec<Joints>,
    interval: Option<f64>,
}

/// The simulated arm: reference, true angles, queued motions.
#[derive(Debug)]
pub(crate) struct Robot {
    limits: JointLimits,
    noise_rad: Joints,
    noise: Noise,
    /// The true angles and their log.
    pub(crate) arm: Follower,
    /// The queued motions.
    pub(crate) reference: Reference,
    /// Where the queued motions end.
    plan_end: Joints,
    next_exec_id: i64,
    pub(crate) servo_mode: bool,
    /// The servo-mode ramp and when it started.
    servo: Option<(f64, Segment)>,
    pub(crate) buffers: HashMap<String, PathBuffer>,
}

impl Robot {
    pub(crate) fn new(config: &SimAuboConfig) -> Robot {
        let t = config.epoch.elapsed().as_secs_f64();
        Robot {
            limits: config.limits.clone(),
            noise_rad: config
                .encoder_noise_per_joint
                .unwrap_or([config.encoder_noise_rad; JOINTS])
                .map(|s| s.max(0.0)),
            noise: Noise { state: config.seed },
            arm: Follower::new(t, config.initial, config.tracking_lag_s),
            reference: Reference::new(t, config.initial),
            plan_end: config.initial,
            next_exec_id: 1,
            servo_mode: false,
            servo: None,
            buffers: HashMap::new(),
        }
    }

    /// The reference at time `t` (retires finished motions).
    pub(crate) fn reference(&mut self, t: f64) -> Joints {
        reference_derivatives(&self.servo, &mut self.reference, t)[0]
    }

    /// The true joint angles and their first two derivatives at `t` (≥ the
    /// last integration time), with the exact reference
    /// ([`Follower::state`]).
    pub(crate) fn state_at(&mut self, t: f64) -> TrueState {
        self.advance_to(t);
        let reference = reference_derivatives(&self.servo, &mut self.reference, t.max(self.arm.t));
        self.arm.state(reference)
    }

    /// Integrates the tracking lag up to time `t`.
    pub(crate) fn advance_to(&mut self, t: f64) {
        let (servo, reference) = (&self.servo, &mut self.reference);
        self.arm
            .advance_to(t, |t| reference_derivatives(servo, reference, t)[0]);
    }

    /// What `getJointPositions` answers: the true angles plus encoder noise.
    pub(crate) fn measured(&mut self) -> Joints {
        self.noise.measure(self.arm.q, &self.noise_rad)
    }

    pub(crate) fn exec_id(&self) -> i64 {
        if self.servo_mode {
            return if self.servo.is_some() { 0 } else { -1 };
        }
        self.reference.queue.front().map_or(-1, |(id, _)| *id)
    }

    pub(crate) fn enqueue(&mut self, seg: Segment) {
        if self.reference.is_idle() {
            self.reference.front_start = self.arm.t;
        }
        self.plan_end = seg.end();
        let id = self.next_exec_id;
        self.next_exec_id += 1;
        self.reference.queue.push_back((id, seg));
    }

    pub(crate) fn move_joint(&mut self, q: Joints, a: f64, v: f64) -> i64 {
        if self.servo_mode {
            return status::BAD_STATE;
        }
        if !self.limits.within_position(&q) {
            return status::POS_BOUND_ERR;
        }
        if a <= 0.0 || v <= 0.0 {
            return status::INVL_ARGUMENT;
        }
        let v = self.limits.velocity.iter().fold(v, |m, &x| m.min(x));
        let a = self.limits.acceleration.iter().fold(a, |m, &x| m.min(x));
        let seg = Segment::trapezoid(self.plan_end, q, v, a);
        self.enqueue(seg);
        status::OK
    }

    pub(crate) fn set_servo_mode(&mut self, enable: bool, now: f64) -> i64 {
        if enable == self.servo_mode {
            return status::OK;
        }
        if enable {
            if !self.reference.is_idle() {
                return status::BUSY;
            }
            self.servo_mode = true;
            self.servo = None;
        } else {
            let r = self.reference(now);
            self.servo_mode = false;
            self.servo = None;
            self.reference.hold = r;
            self.plan_end = r;
        }
        status::OK
    }

    pub(crate) fn servo_joint(&mut self, q: Joints, t: f64, now: f64) -> i64 {
        if !self.servo_mode {
            return status::REQUEST_IGNORE;
        }
        if !self.limits.within_position(&q) {
            return status::POS_BOUND_ERR;
        }
        if t <= 0.0 {
            return status::INVL_ARGUMENT;
        }
        let from = self.reference(now);
        if (0..JOINTS).any(|i| (q[i] - from[i]).abs() / t > self.limits.velocity[i]) {
            return status::INVL_ARGUMENT;
        }
        let ramp = Segment::Linear {
            from,
            to: q,
            duration: t,
        };
        self.servo = Some((now, ramp));
        status::OK
    }

    pub(crate) fn path_alloc(&mut self, name: &str, kind: f64, size: f64) -> i64 {
        if kind != 2.0 || size < 2.0 || size.fract() != 0.0 {
            return status::INVL_ARGUMENT;
        }
        self.buffers.insert(
            name.to_string(),
            PathBuffer {
                size: size as usize,
                points: Vec::new(),
                interval: None,
            },
        );
        status::OK
    }

    pub(crate) fn path_append(&mut self, name: &str, points: Vec<Joints>) -> i64 {
        let limits = &self.limits;
        let Some(buf) = self.buffers.get_mut(name) else {
            return status::INVL_ARGUMENT;
        };
        if !points.iter().all(|q| limits.within_position(q)) {
            return status::POS_BOUND_ERR;
        }
        buf.points.extend(points);
        buf.interval = None;
        status::OK
    }

    pub(crate) fn path_eval(&mut self, name: &str, a: Joints, v: Joints, t: f64) -> i64 {
        let limits = &self.limits;
        let Some(buf) = self.buffers.get_mut(name) else {
            return status::INVL_ARGUMENT;
        };
        if buf.points.len() < buf.size || buf.points.len() < 2 || t <= 0.0 {
            return status::INVL_ARGUMENT;
        }
        for i in 0..JOINTS {
            let v_max = v[i].min(limits.velocity[i]);
            let a_max = a[i].min(limits.acceleration[i]);
            let p = &buf.points;
            let too_fast = p.windows(2).any(|w| (w[1][i] - w[0][i]).abs() / t > v_max);
            let too_sharp = p
                .windows(3)
                .any(|w| (w[2][i] - 2.0 * w[1][i] + w[0][i]).abs() / (t * t) > a_max);
            if too_fast || too_sharp {
                return status::INVL_ARGUMENT;
            }
        }
        buf.interval = Some(t);
        status::OK
    }

    pub(crate) fn move_path(&mut self, name: &str) -> i64 {
        if self.servo_mode {
            return status::BAD_STATE;
        }
        let Some(buf) = self.buffers.get(name) else {
            return status::INVL_ARGUMENT;
        };
        let Some(h) = buf.interval else {
            return status::BAD_STATE;
        };
        let start = buf.points[0];
        if (0..JOINTS).any(|i| (start[i] - self.plan_end[i]).abs() > PATH_START_TOLERANCE) {
            return status::INVL_ARGUMENT;
        }
        let seg = Segment::Spline {
            points: buf.points.clone(),
            h,
        };
        self.enqueue(seg);
        status::OK
    }

    /// Stops at once: the reference holds where it is now.
    pub(crate) fn stop_motion(&mut self, now: f64) {
        let r = self.reference(now);
        self.reference.queue.clear();
        self.servo = None;
        self.reference.hold = r;
        self.plan_end = r;
    }
}

/// The reference and its first two time derivatives at `t`: the servo ramp
/// in servo mode, else the queued motions (retiring finished ones).
fn reference_derivatives(
    servo: &Option<(f64, Segment)>,
    reference: &mut Reference,
    t: f64,
) -> [Joints; 3] {
    match servo {
        Some((t0, ramp)) => ramp.eval_derivatives(t - t0),
        None => reference.derivatives(t),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `state_at`'s velocities and accelerations against central differences
    /// of its angles and velocities along a path-buffer motion with lag.
    #[test]
    fn true_state_derivatives_match_finite_differences() {
        for lag in [0.02, 0.0] {
            let config = SimAuboConfig {
                tracking_lag_s: lag,
                ..SimAuboConfig::default()
            };
            let mut robot = Robot::new(&config);
            let t0 = robot.arm.t;
            let points: Vec<Joints> = (0..400)
                .map(|k| {
                    let s = k as f64 * 0.004;
                    core::array::from_fn(|i| 0.3 * (s * (1.0 + i as f64 * 0.3)).sin())
                })
                .collect();
            robot.enqueue(Segment::Spline { points, h: 0.004 });
            let h = 1e-4;
            let states: Vec<TrueState> = (0..12000)
                .map(|k| robot.state_at(t0 + 0.2 + k as f64 * h))
                .collect();
            let mut worst = [0.0f64; 2];
            for k in (1000..11000).step_by(97) {
                for i in 0..JOINTS {
                    let qd = (states[k + 1].q[i] - states[k - 1].q[i]) / (2.0 * h);
                    let qdd = (states[k + 1].qd[i] - states[k - 1].qd[i]) / (2.0 * h);
                    worst[0] = worst[0].max((qd - states[k].qd[i]).abs());
                    worst[1] = worst[1].max((qdd - states[k].qdd[i]).abs());
                }
            }
            // Speeds up to ~0.8 rad/s, accelerations up to ~1.5 rad/s². Without
            // a lag the Hermite reference's q̈ jumps at waypoints (4 ms apart),
            // which central differences straddle.
            let tol = if lag > 0.0 {
                [1e-6, 1e-3]
            } else {
                [1e-5, 3e-2]
            };
            assert!(worst[0] < tol[0], "lag {lag}: velocity error {}", worst[0]);
            assert!(
                worst[1] < tol[1],
                "lag {lag}: acceleration error {}",
                worst[1]
            );
        }
    }
}
