//! Simulated hardware wired to the model: the hidden-truth rig that
//! `robimu demo` and the end-to-end tests record from.
//!
//! * [`physics`]: a BNO055 sample source that computes what an IMU on the
//!   simulated arm's flange measures (docs/model.md §2–3 with a hidden truth),
//!   with noise, quantisation and saturation as the chip has them.
//! * [`arm_physics`]: the same signal from an independent URDF-style chain
//!   (Newton–Euler forward pass), with joint elasticity and a structural
//!   mode the estimator's model does not have.
//! * [`rig`]: a simulated AUBO controller and a simulated IMU board (the
//!   real firmware core on a pseudo-terminal) sharing one true motion.
//! * [`truth`]: the values a calibration of a twin session should find
//!   for the parameters the twin's physics makes effective (τ, sensor
//!   delay, biases under a warm-up).
//! * [`twin`]: the same rig's session recorded on a virtual clock, as fast
//!   as the computer goes (for tests and Monte Carlo).
//!
//! Main types: [`rig::SimRigConfig`] (the robot, its hidden truth, clock
//! errors) and the running rigs [`rig::SimRig`] (AUBO) and [`rig::SimUrRig`]
//! (Universal Robots), which `robimu record` connects to like real hardware.
//!
//! # Example
//!
//! ```
//! use robimu_hil::rig::{SimRig, SimRigConfig};
//! use robimu_model::Robot;
//!
//! // an AUBO i5 whose true parameters are drawn from its priors (seed 7)
//! let rig = SimRig::spawn(&SimRigConfig::drawn(Robot::aubo_i5(), 7))?;
//! println!("robimu record --imu {} --robot {}", rig.imu_port(), rig.robot_spec());
//! assert!(rig.robot_spec().starts_with("aubo:"));
//! assert!(rig.truth().get("tau").is_some());
//! # Ok::<(), robimu_hil::rig::RigError>(())
//! ```

#![deny(missing_docs)]

pub mod arm_physics;
pub mod physics;
pub mod rig;
pub mod truth;
pub mod truth_check;
pub mod twin;

pub use crate::arm_physics::{ArmPhysicsError, StructuralMode};
pub use crate::rig::RigError;
pub use crate::rig::SecondImu;
/// A calibration's model against the twin's truth ([`truth_check::fitted_check`]).
pub use crate::truth_check::FittedCheck;
pub use crate::twin::TwinError;
