//! A simulated AUBO arm controller on loopback TCP.
//!
//! [`SimAubo::spawn`] listens where [`SimAuboConfig::bind`] says and speaks
//! the JSON-RPC 2.0 interface of AUBO's ARCS controller (real port 30004):
//! requests and replies are bare JSON objects, concatenated with no
//! delimiter, so each connection parses its byte stream incrementally
//! ([`StreamParser`], shared with the host's client); whitespace between
//! objects is tolerated.
//!
//! Methods (names and parameter shapes as in the ARCS SDK headers'
//! JSON-RPC examples; `rob1` is the robot name):
//!
//! | method | params | result |
//! | --- | --- | --- |
//! | `rob1.RobotState.getJointPositions` | `[]` | six joint angles, rad |
//! | `rob1.MotionControl.moveJoint` | `[q, a, v, blend_radius, duration]` | status |
//! | `rob1.MotionControl.setServoMode` | `[enable]` | status |
//! | `rob1.MotionControl.isServoModeEnabled` | `[]` | bool |
//! | `rob1.MotionControl.servoJoint` | `[q, a, v, t, lookahead_time, gain]` | status |
//! | `rob1.MotionControl.pathBufferAlloc` | `[name, type, size]` | status |
//! | `rob1.MotionControl.pathBufferAppend` | `[name, [q, …]]` | status |
//! | `rob1.MotionControl.pathBufferEval` | `[name, a[6], v[6], t]` | status |
//! | `rob1.MotionControl.movePathBuffer` | `[name]` | status |
//! | `rob1.MotionControl.pathBufferFree` | `[name]` | status |
//! | `rob1.MotionControl.getExecId` | `[]` | id of the running motion, −1 idle |
//! | `rob1.MotionControl.stopJoint` | `[acc]` | status |
//!
//! As on the real controller, a refused motion is not a JSON-RPC error: the
//! result is a status code (0 success; negative an error, positive a
//! warning such as busy): −1 `AUBO_BAD_STATE`, −5 `AUBO_INVL_ARGUMENT`
//! (out of the velocity/acceleration limits, unknown buffer), −13
//! `AUBO_REQUEST_IGNORE` (`servoJoint` outside servo mode), −18
//! `AUBO_POS_BOUND_ERR` (a target beyond the position limits), 3
//! `AUBO_BUSY`. Protocol faults are JSON-RPC errors: −32700 parse error,
//! −32600 invalid request, −32601 unknown method, −32602 bad params.
//!
//! Motion model ([`crate::arm`]). Commands feed a reference `r(t)`:
//! `moveJoint` queues a synchronised trapezoidal move (speed and
//! acceleration `v`, `a` clamped to the joints' limits; `blend_radius` and
//! `duration` ignored);
//! `movePathBuffer` queues a path buffer of type 2 (the SDK's
//! "cubic_spline, recorded trajectory"), whose waypoints are `t` seconds
//! apart, `t` being the sampling interval given to `pathBufferEval` (the
//! SDK: "type 2: t is the sampling interval"); the buffer must hold at least
//! `size` points and be evaluated before it moves, and its first point must
//! be where the previous motion ends (within 0.01 rad). Waypoints are joined
//! by cubic Hermite segments with central-difference tangents. In servo
//! mode `servoJoint(q, …, t, …)` ramps the reference linearly to `q` over
//! `t` seconds. The true joint angles follow `r(t)` through a first-order
//! lag of time constant [`SimAuboConfig::tracking_lag_s`], integrated in
//! steps of at most 2 ms by a 500 Hz simulation thread and, exactly at the
//! request time, by each `getJointPositions`, whose reply adds Gaussian
//! encoder noise. Every integration step is logged with its time (seconds
//! since [`SimAuboConfig::epoch`]): [`SimAubo::true_trajectory`].
//!
//! Modules: `robot` (the arm as the ARCS commands drive it), `rpc` (the
//! JSON-RPC server), `virtual_arm` (the same arm on a virtual clock).

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::server::{self, lock, Core, Running, Server};

mod robot;
mod rpc;
mod virtual_arm;

use crate::arm::TrueSample;
pub use crate::arm::{Joints, TrueMotion, TrueState, JOINTS};
pub use robimu_controller_wire::StreamParser;
pub use robot::JointLimits;
pub use virtual_arm::VirtualAubo;

use robot::Robot;

/// ARCS status codes the simulator returns.
pub mod status {
    /// Success.
    pub const OK: i64 = 0;
    /// The previous command is still executing (warning: not accepted).
    pub const BUSY: i64 = 3;
    /// The robot is not in a state that accepts the command.
    pub const BAD_STATE: i64 = -1;
    /// An argument is out of range (velocity, acceleration, buffer, …).
    pub const INVL_ARGUMENT: i64 = -5;
    /// The command is ignored (servo command outside servo mode).
    pub const REQUEST_IGNORE: i64 = -13;
    /// A joint target is beyond the position limits.
    pub const POS_BOUND_ERR: i64 = -18;
}

/// Faults the simulator can inject; changeable while it runs
/// ([`SimAubo::set_faults`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultSwitches {
    /// Wait before every reply.
    pub reply_delay: Duration,
    /// Close each connection, without a reply, when it sends a request after
    /// this many answered requests.
    pub drop_connection_after: Option<usize>,
    /// Refuse every motion command with `AUBO_BAD_STATE` (as a robot in
    /// protective stop does).
    pub refuse_motion: bool,
    /// Answer nothing while set: requests are read and dropped, every
    /// connection stays open (a hung controller: no I/O error reaches the
    /// client).
    pub silent: bool,
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimAuboConfig {
    /// Where to listen (`127.0.0.1:0`: any free loopback port).
    pub bind: SocketAddr,
    /// The clock's zero: trajectory times are seconds since this instant.
    pub epoch: Instant,
    /// Initial joint angles, rad.
    pub initial: Joints,
    /// Joint limits.
    pub limits: JointLimits,
    /// Time constant of the first-order tracking lag, s (0: none).
    pub tracking_lag_s: f64,
    /// Standard deviation of the encoder noise on reported angles, rad.
    pub encoder_noise_rad: f64,
    /// Per-joint encoder noise standard deviations, rad (overrides
    /// `encoder_noise_rad` when set).
    pub encoder_noise_per_joint: Option<Joints>,
    /// Seed of the encoder noise.
    pub seed: u64,
    /// Injected faults.
    pub faults: FaultSwitches,
}

impl Default for SimAuboConfig {
    fn default() -> Self {
        SimAuboConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            epoch: Instant::now(),
            initial: [0.0; JOINTS],
            limits: JointLimits::default(),
            tracking_lag_s: 0.02,
            encoder_noise_rad: 1e-4,
            encoder_noise_per_joint: None,
            seed: 1,
            faults: FaultSwitches::default(),
        }
    }
}

/// Why the simulated controller could not be started.
#[derive(Debug, thiserror::Error)]
pub enum SimAuboError {
    /// The listening socket could not be opened.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The requested address.
        addr: SocketAddr,
        /// The cause.
        source: std::io::Error,
    },
    /// A thread could not be started.
    #[error("cannot start a simulator thread: {0}")]
    Thread(#[source] std::io::Error),
}

impl TrueMotion for StateProbe {
    fn now(&self) -> TrueState {
        StateProbe::now(self)
    }
}

/// Reads the simulated arm's true state from another thread (a simulated
/// IMU on the flange uses it as its physics). Cloneable; keeps the
/// simulation's state alive but not its threads.
#[derive(Clone)]
pub struct StateProbe {
    shared: Arc<Shared>,
}

impl StateProbe {
    /// The true state now.
    pub fn now(&self) -> TrueState {
        let t = self.shared.core.now();
        lock(&self.shared.robot).state_at(t)
    }

    /// The simulation's epoch (time zero of [`TrueState::t`]).
    pub fn epoch(&self) -> Instant {
        self.shared.core.epoch
    }
}

/// A running simulated controller; stops when dropped.
pub struct SimAubo {
    addr: SocketAddr,
    sim: Running<Shared>,
}

impl SimAubo {
    /// Opens the socket and starts the simulation and accept threads.
    pub fn spawn(config: SimAuboConfig) -> Result<SimAubo, SimAuboError> {
        let (listener, addr) =
            server::listen(config.bind).map_err(|source| SimAuboError::Bind {
                addr: config.bind,
                source,
            })?;
        let mut sim = Running::new(Shared {
            core: Core::new(config.epoch),
            faults: Mutex::new(config.faults.clone()),
            robot: Mutex::new(Robot::new(&config)),
        });
        // Dropped on an error: stops the threads already started.
        sim.start("sim-aubo-motion", |s| {
            server::simulation_loop(&s.core, |t| lock(&s.robot).advance_to(t))
        })
        .map_err(SimAuboError::Thread)?;
        sim.start("sim-aubo-accept", move |s| {
            server::accept_loop(&listener, s, "sim-aubo-conn", rpc::serve_connection)
        })
        .map_err(SimAuboError::Thread)?;
        Ok(SimAubo { addr, sim })
    }

    /// The address clients connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Replaces the injected faults (effective from the next request).
    pub fn set_faults(&self, faults: FaultSwitches) {
        *lock(&self.sim.shared.faults) = faults;
    }

    /// The true joint trajectory so far (every integration step, ≥ 500 Hz).
    pub fn true_trajectory(&self) -> Vec<TrueSample> {
        lock(&self.sim.shared.robot).arm.log.clone()
    }

    /// Removes and returns the true trajectory logged so far.
    pub fn take_true_trajectory(&self) -> Vec<TrueSample> {
        std::mem::take(&mut lock(&self.sim.shared.robot).arm.log)
    }

    /// A handle that reads the true joint state (angles, velocities,
    /// accelerations) from any thread.
    pub fn state_probe(&self) -> StateProbe {
        StateProbe {
            shared: Arc::clone(&self.sim.shared),
        }
    }

    /// The true joint angles now.
    pub fn true_joints(&self) -> Joints {
        let now = self.sim.shared.core.now();
        let mut robot = lock(&self.sim.shared.robot);
        robot.advance_to(now);
        robot.arm.q
    }

    /// Stops every thread and closes every connection.
    pub fn stop(self) {
        drop(self);
    }
}

/// State shared by the simulator's threads.
struct Shared {
    core: Core,
    faults: Mutex<FaultSwitches>,
    robot: Mutex<Robot>,
}

impl Server for Shared {
    fn core(&self) -> &Core {
        &self.core
    }
}
