//! A simulated Universal Robots controller on loopback TCP: RTDE for
//! readings, a URScript port for motion.
//!
//! [`SimUr::spawn`] opens two ports on [`SimUrConfig::bind`]:
//!
//! * RTDE (real port 30004): big-endian packages `uint16 size`, `uint8
//!   type`, payload. `V` (protocol version; 1 ..=
//!   [`SimUrConfig::max_protocol_version`] accepted), `O` (setup outputs:
//!   `double frequency` in version 2, then comma-separated names; the reply
//!   is a recipe id and the types, `NOT_FOUND` for an unknown name, recipe
//!   id 0 for a frequency outside `(0, control rate]`), `S` (start; refused
//!   without a recipe), `P` (pause), `v` (controller version: 5.15.0.0 at
//!   500 Hz, 3.15.0.0 at 125 Hz; `ur_rtde` asks it). After `V` the controller sends one `M`
//!   text message, which clients must skip. Outputs: `timestamp` (DOUBLE,
//!   s since the controller started: [`SimUrConfig::uptime_at_epoch_s`] +
//!   seconds since the epoch), `actual_q` (VECTOR6D, the true angles plus
//!   Gaussian encoder noise), `target_q` (VECTOR6D, the reference),
//!   `runtime_state` (UINT32: 2 playing, 1 stopped), `robot_mode` (INT32:
//!   7 running). Once started, a `U` package goes out at every control
//!   cycle of the requested period (cycles are multiples of 1/frequency
//!   since the epoch); a connection that falls behind skips to the latest
//!   cycle, as the real controller does.
//! * Script (real port 30002, the secondary interface): a connection sends
//!   one program and closes its write side. The program must be
//!   `def NAME():`, lines of `movej([6], a=A, v=V)`, `servoj([6], t=T,
//!   lookahead_time=L, gain=G)`, `stopj(A)`, then `end` and optionally
//!   `NAME()`; anything else is refused (the reason is kept:
//!   [`SimUr::script_errors`]) and the robot does not move. A program
//!   replaces the one running.
//!
//! Motion model. The reference `r(t)` ramps linearly: `movej` to its
//! target at speed `v` (the largest joint step over `v`), each `servoj` to
//! its target over `t` seconds. The true angles follow `r(t)` through a
//! first-order lag of time constant [`SimUrConfig::tracking_lag_s`],
//! integrated exactly for the piecewise-linear reference in steps of at
//! most 2 ms by a 500 Hz simulation thread; each step is logged
//! ([`SimUr::true_trajectory`]; times in seconds since the epoch), and a
//! data package's `actual_q` is the logged trajectory at its cycle time.
//!
//! Modules: `rtde` (the RTDE server), `script` (the URScript port and its
//! program form), `robot` (the arm as programs drive it, on the shared
//! motion model of [`crate::arm`]).

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::arm::{Joints, TrueMotion, TrueSample, TrueState, JOINTS};
use crate::server::{self, lock, Core, Running, Server};

mod robot;
mod rtde;
mod script;

pub use script::Command;

use robot::Robot;

/// Faults the simulator can inject; changeable while it runs
/// ([`SimUr::set_faults`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultSwitches {
    /// Wait before every reply to a control package (`V`, `O`, `S`, `P`).
    pub reply_delay: Duration,
    /// Close each RTDE connection after sending this many data packages.
    pub drop_connection_after: Option<usize>,
    /// Send no data package while set, keeping every connection open and
    /// answering control packages (a controller whose data stream hung: no
    /// I/O error reaches the client).
    pub stall_data: bool,
    /// Send every package in two writes 1 ms apart, cut at a varying point.
    pub split_writes: bool,
    /// Hold each data package back before sending it by a delay drawn
    /// uniformly from `[0, jitter_max]` (seeded by [`SimUrConfig::seed`]):
    /// network and scheduling jitter. Below the control period every cycle
    /// is still sent; its `timestamp` stays the cycle's time.
    pub jitter_max: Duration,
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimUrConfig {
    /// Where to listen; both ports are chosen freely on its address when its
    /// port is 0.
    pub bind: SocketAddr,
    /// The clock's zero: trajectory times are seconds since this instant.
    pub epoch: Instant,
    /// The controller's `timestamp` at the epoch, s (its uptime).
    pub uptime_at_epoch_s: f64,
    /// Control rate, Hz: 125 (CB-series) or 500 (e-Series); the largest
    /// output frequency.
    pub control_rate_hz: f64,
    /// Highest RTDE protocol version accepted.
    pub max_protocol_version: u16,
    /// Initial joint angles, rad.
    pub initial: Joints,
    /// Time constant of the first-order tracking lag, s (0: none).
    pub tracking_lag_s: f64,
    /// Standard deviation of the encoder noise on `actual_q`, rad.
    pub encoder_noise_rad: f64,
    /// Seed of the encoder noise.
    pub seed: u64,
    /// Injected faults.
    pub faults: FaultSwitches,
}

impl Default for SimUrConfig {
    fn default() -> Self {
        SimUrConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            epoch: Instant::now(),
            uptime_at_epoch_s: 1234.5,
            control_rate_hz: 500.0,
            max_protocol_version: 2,
            initial: [0.0; JOINTS],
            tracking_lag_s: 0.02,
            encoder_noise_rad: 1e-4,
            seed: 1,
            faults: FaultSwitches::default(),
        }
    }
}

/// Why the simulated controller could not be started.
#[derive(Debug, thiserror::Error)]
pub enum SimUrError {
    /// A listening socket could not be opened.
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

/// A running simulated UR controller; stops when dropped.
pub struct SimUr {
    rtde: SocketAddr,
    script: SocketAddr,
    sim: Running<Shared>,
}

struct Shared {
    core: Core,
    config: SimUrConfig,
    faults: Mutex<FaultSwitches>,
    robot: Mutex<Robot>,
    script_errors: Mutex<Vec<String>>,
}

impl Server for Shared {
    fn core(&self) -> &Core {
        &self.core
    }
}

impl SimUr {
    /// Opens the two ports and starts the simulation and accept threads.
    pub fn spawn(config: SimUrConfig) -> Result<SimUr, SimUrError> {
        let listen =
            |addr| server::listen(addr).map_err(|source| SimUrError::Bind { addr, source });
        let (rtde_l, rtde) = listen(config.bind)?;
        let mut script_bind = config.bind;
        if script_bind.port() != 0 {
            script_bind.set_port(script_bind.port().wrapping_add(1));
        }
        let (script_l, script) = listen(script_bind)?;
        let mut sim = Running::new(Shared {
            core: Core::new(config.epoch),
            faults: Mutex::new(config.faults.clone()),
            robot: Mutex::new(Robot::new(&config)),
            script_errors: Mutex::new(Vec::new()),
            config,
        });
        // Dropped on an error: stops the threads already started.
        sim.start("sim-ur-motion", |s| {
            server::simulation_loop(&s.core, |t| lock(&s.robot).advance_to(t))
        })
        .map_err(SimUrError::Thread)?;
        sim.start("sim-ur-rtde", move |s| {
            server::accept_loop(&rtde_l, s, "sim-ur-conn", rtde::serve_rtde)
        })
        .map_err(SimUrError::Thread)?;
        sim.start("sim-ur-script", move |s| {
            server::accept_loop(&script_l, s, "sim-ur-conn", script::serve_script)
        })
        .map_err(SimUrError::Thread)?;
        Ok(SimUr { rtde, script, sim })
    }

    /// A handle that reads the true joint state (angles, velocities,
    /// accelerations) from any thread.
    pub fn state_probe(&self) -> UrStateProbe {
        UrStateProbe {
            shared: Arc::clone(&self.sim.shared),
        }
    }

    /// The RTDE address.
    pub fn rtde_addr(&self) -> SocketAddr {
        self.rtde
    }

    /// The URScript address.
    pub fn script_addr(&self) -> SocketAddr {
        self.script
    }

    /// Replaces the injected faults (effective from the next package).
    pub fn set_faults(&self, faults: FaultSwitches) {
        *lock(&self.sim.shared.faults) = faults;
    }

    /// The true joint trajectory so far (every integration step, ≥ 500 Hz).
    pub fn true_trajectory(&self) -> Vec<TrueSample> {
        lock(&self.sim.shared.robot).arm.log.clone()
    }

    /// The true joint angles now.
    pub fn true_joints(&self) -> Joints {
        let now = self.sim.shared.core.now();
        let mut robot = lock(&self.sim.shared.robot);
        robot.advance_to(now);
        robot.arm.q
    }

    /// Why programs sent to the script port were refused, oldest first.
    pub fn script_errors(&self) -> Vec<String> {
        lock(&self.sim.shared.script_errors).clone()
    }

    /// Whether a program is running.
    pub fn program_running(&self) -> bool {
        let now = self.sim.shared.core.now();
        let mut robot = lock(&self.sim.shared.robot);
        robot.advance_to(now);
        !robot.reference.is_idle()
    }

    /// Stops every thread and closes every connection.
    pub fn stop(self) {
        drop(self);
    }
}

/// Reads the simulated UR arm's true state from another thread.
#[derive(Clone)]
pub struct UrStateProbe {
    shared: Arc<Shared>,
}

impl TrueMotion for UrStateProbe {
    fn now(&self) -> TrueState {
        let t = self.shared.core.now();
        lock(&self.shared.robot).true_state(t)
    }
}
