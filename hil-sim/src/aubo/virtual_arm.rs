//! The simulated AUBO arm on a virtual clock, without server or threads.

use super::robot::Robot;
use super::{status, SimAuboConfig};
use crate::arm::{Joints, TrueState};

/// The simulated controller's motion model on a virtual clock: the same
/// reference, tracking lag and encoder noise as [`SimAubo`](super::SimAubo), without the
/// server or threads, for twins recorded in virtual time
/// (`robimu_hil::twin`). Time is seconds from zero, set by the caller.
#[derive(Debug)]
pub struct VirtualAubo {
    robot: Robot,
}

impl VirtualAubo {
    /// The arm of `config` (its initial pose, limits, lag, encoder noise and
    /// seed; `bind`, `epoch` and `faults` are not used) at time zero.
    pub fn new(config: &SimAuboConfig) -> Self {
        let mut robot = Robot::new(config);
        robot.arm.t = 0.0;
        robot.reference.front_start = 0.0;
        robot.arm.log.clear();
        Self { robot }
    }

    /// Queues a path buffer of `points` `h` seconds apart, as
    /// `robimu record`'s AUBO driver sends it (alloc, append, eval with
    /// limits `a`, `v`, move) at time `t`; `Err` is the controller's
    /// refusing status code.
    pub fn play_path(
        &mut self,
        t: f64,
        points: &[Joints],
        h: f64,
        a: Joints,
        v: Joints,
    ) -> Result<(), i64> {
        let name = "virtual";
        self.robot.advance_to(t);
        let check = |code: i64| {
            if code == status::OK {
                Ok(())
            } else {
                Err(code)
            }
        };
        check(self.robot.path_alloc(name, 2.0, points.len() as f64))?;
        check(self.robot.path_append(name, points.to_vec()))?;
        check(self.robot.path_eval(name, a, v, h))?;
        check(self.robot.move_path(name))?;
        self.robot.buffers.clear();
        Ok(())
    }

    /// The true state at `t` (not before the last query's time).
    pub fn state_at(&mut self, t: f64) -> TrueState {
        self.robot.state_at(t)
    }

    /// What `getJointPositions` answers at `t`: the true angles plus
    /// encoder noise.
    pub fn joint_positions(&mut self, t: f64) -> Joints {
        self.robot.advance_to(t);
        self.robot.measured()
    }

    /// Whether no motion runs at `t` (`getExecId` is −1).
    pub fn idle_at(&mut self, t: f64) -> bool {
        self.robot.advance_to(t);
        let _ = self.robot.reference(t);
        self.robot.exec_id() == -1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::JOINTS;

    /// The virtual-time arm plays a path buffer as the server does: it
    /// refuses one that does not start where the arm stands (status −5),
    /// follows the waypoints through the lag (at the end within the lag's
    /// tail of the last point), and is idle once the path has run.
    #[test]
    fn the_virtual_arm_plays_a_path_buffer_through_its_lag() {
        let config = SimAuboConfig {
            tracking_lag_s: 0.02,
            encoder_noise_rad: 0.0,
            ..SimAuboConfig::default()
        };
        let h = 0.004;
        let points: Vec<Joints> = (0..500)
            .map(|k| {
                core::array::from_fn(|i| {
                    0.2 * (1.0 - (k as f64 * h * (1.0 + i as f64 * 0.2)).cos())
                })
            })
            .collect();
        let (a, v) = ([100.0; JOINTS], [10.0; JOINTS]);
        let mut arm = VirtualAubo::new(&config);
        let mut shifted = points.clone();
        shifted[0][0] += 0.1;
        assert_eq!(
            arm.play_path(0.5, &shifted, h, a, v),
            Err(status::INVL_ARGUMENT)
        );
        assert!(arm.idle_at(0.5));
        arm.play_path(1.0, &points, h, a, v).unwrap();
        assert!(!arm.idle_at(1.5));
        let end = 1.0 + (points.len() - 1) as f64 * h;
        assert!(!arm.idle_at(end - 0.01));
        assert!(arm.idle_at(end + 1e-6));
        // five lag constants after the end the arm stands at the last point
        let q = arm.joint_positions(end + 0.1);
        let last = points[points.len() - 1];
        for i in 0..JOINTS {
            assert!(
                (q[i] - last[i]).abs() < 1e-3 * last[i].abs().max(1e-2),
                "{q:?} vs {last:?}"
            );
        }
        // and at rest: q̇ = (r − q)/T vanishes
        let s = arm.state_at(end + 0.2);
        assert!(s.qd.iter().all(|v| v.abs() < 1e-3), "{s:?}");
    }
}
