//! Simulated robimu hardware for tests and demos without a board.
//!
//! * [`device`]: the real firmware core ([`robimu_firmware::Acquisition`])
//!   over the register-level simulated BNO055, in a background thread, with
//!   its serial side on a pseudo-terminal that a host opens like `/dev/ttyUSB0`.
//! * [`arm`]: the simulated arm's motion model both simulated controllers
//!   drive: queued reference segments, a first-order tracking lag, encoder
//!   noise, the logged true trajectory.
//! * [`aubo`]: a simulated AUBO arm controller speaking ARCS JSON-RPC on
//!   loopback TCP, with tracking lag, encoder noise and injectable faults.
//! * [`ur`]: a simulated Universal Robots controller: RTDE and a URScript
//!   port on loopback TCP, with tracking lag, encoder noise and faults.
#![deny(missing_docs)]

pub mod arm;
pub mod aubo;
pub mod device;
mod server;
pub mod ur;

pub use crate::arm::TrueSample;
pub use crate::aubo::StateProbe;
pub use crate::device::DriftingClock;
pub use crate::ur::UrStateProbe;
