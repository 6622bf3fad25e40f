//! Executing a plan on the arm.
//!
//! AUBO: a joint move to the plan's first pose, then the plan as one path
//! buffer of type 2 ("recorded trajectory": waypoints at a fixed interval,
//! the plan's sample interval), checked by the controller against the
//! robot's velocity and acceleration limits (`pathBufferEval`) before it
//! moves.

use std::time::Duration;

use crate::controller::aubo::{AuboClient, AuboError, Joints};
use robimu_model::Robot;

/// A plan: joint positions at a fixed interval.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Sample interval, s.
    pub dt: f64,
    /// Waypoints, rad.
    pub q: Vec<Joints>,
}

/// Why samples are not a plan the controller can execute.
#[derive(Debug, thiserror::Error)]
pub enum MotionPlanError {
    /// Not 6 joints.
    #[error("the plan has {0} joint columns; the AUBO driver drives 6")]
    Joints(usize),
    /// Too short.
    #[error("the plan has {0} samples; at least 2 are needed")]
    TooShort(usize),
    /// Not evenly spaced.
    #[error(
        "plan samples must be evenly spaced: interval {first} s, but {found} s before t = {t} s"
    )]
    Uneven {
        /// First interval.
        first: f64,
        /// Offending interval.
        found: f64,
        /// Where.
        t: f64,
    },
}

impl Plan {
    /// From sample times and row-major joint values (`n` per row).
    pub fn from_samples(t: &[f64], values: &[f64], n: usize) -> Result<Plan, MotionPlanError> {
        if n != 6 {
            return Err(MotionPlanError::Joints(n));
        }
        if t.len() < 2 {
            return Err(MotionPlanError::TooShort(t.len()));
        }
        let dt = t[1] - t[0];
        for k in 1..t.len() {
            let h = t[k] - t[k - 1];
            if dt.is_nan() || dt <= 0.0 || (h - dt).abs() > 1e-6 * dt.max(1e-3) + 1e-9 {
                return Err(MotionPlanError::Uneven {
                    first: dt,
                    found: h,
                    t: t[k],
                });
            }
        }
        let q = values
            .chunks_exact(6)
            .map(|r| std::array::from_fn(|j| r[j]))
            .collect();
        Ok(Plan { dt, q })
    }

    /// Samples `trajectory` (6 joints) every `1/rate` s over its span.
    pub fn from_spline(trajectory: &robimu_model::Spline, rate: f64) -> Plan {
        let (t0, t1) = (trajectory.knots().start(), trajectory.knots().end());
        let dt = 1.0 / rate;
        let count = ((t1 - t0) * rate).floor() as usize + 1;
        let mut js = robimu_model::JointState::default();
        let q = (0..count)
            .map(|k| {
                trajectory.state_at(t0 + k as f64 * dt, &mut js);
                std::array::from_fn(|j| js.q[j])
            })
            .collect();
        Plan { dt, q }
    }

    /// Writes `plan.csv` (header `t,q1,…,q6`; s, rad; docs/model.md §7's table form).
    pub fn write_csv(&self, path: &std::path::Path) -> std::io::Result<()> {
        let mut out = String::from("t,q1,q2,q3,q4,q5,q6\n");
        for (k, q) in self.q.iter().enumerate() {
            out.push_str(&format!("{:?}", k as f64 * self.dt));
            for v in q {
                out.push_str(&format!(",{v:?}"));
            }
            out.push('\n');
        }
        std::fs::write(path, out)
    }

    /// Length, s.
    pub fn duration(&self) -> f64 {
        (self.q.len().saturating_sub(1)) as f64 * self.dt
    }
}

/// Waypoints per `pathBufferAppend` call.
const APPEND_CHUNK: usize = 200;

/// Moves to the plan's start and waits until the arm is there.
pub(crate) fn move_to_start(
    client: &mut AuboClient,
    robot: &Robot,
    plan: &Plan,
) -> Result<(), AuboError> {
    let (v, a) = slowest(robot);
    client.move_joint(&plan.q[0], 0.5 * a, 0.5 * v)?;
    client.wait_idle(Duration::from_secs(120))
}

/// Executes the plan (the arm must be at its start) and waits for its end.
pub fn execute(client: &mut AuboClient, robot: &Robot, plan: &Plan) -> Result<(), AuboError> {
    let name = "robimu_plan";
    client.path_buffer_alloc(name, 2, plan.q.len())?;
    for chunk in plan.q.chunks(APPEND_CHUNK) {
        client.path_buffer_append(name, chunk)?;
    }
    let (a, v) = path_limits(robot);
    client.path_buffer_eval(name, &a, &v, plan.dt)?;
    client.path_buffer_move(name)?;
    client.wait_idle(Duration::from_secs_f64(plan.duration() + 60.0))
}

/// The acceleration and speed limits sent with a path buffer: the
/// controller checks finite differences of the waypoints, so a little
/// over the plan's limits (1.2×) for the differences' own error.
pub fn path_limits(robot: &Robot) -> (Joints, Joints) {
    let limit = |j: usize, f: fn(&robimu_model::robot::JointLimits) -> f64| {
        robot.limits().get(j).map_or(0.0, |l| f(l) * 1.2)
    };
    (
        std::array::from_fn(|j| limit(j, |l| l.qdd_max)),
        std::array::from_fn(|j| limit(j, |l| l.qd_max)),
    )
}

/// The smallest speed and acceleration limits over the joints.
fn slowest(robot: &Robot) -> (f64, f64) {
    robot
        .limits()
        .iter()
        .fold((f64::INFINITY, f64::INFINITY), |(v, a), l| {
            (v.min(l.qd_max), a.min(l.qdd_max))
        })
}
