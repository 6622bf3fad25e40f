//! Simulated hardware wired to the model: the hidden-truth rig that
//! `robimu demo` and the end-to-end tests record from.
//!
//! * [`physics`]: a BNO055 sample source that computes what an IMU on the
//!   simulated arm's flange measures (docs/model.md §2–3 with a hidden truth),
//!   with noise, quantisation and saturation as the chip has them.
//! * [`rig`]: a simulated AUBO controller and a simulated IMU board (the
//!   real firmware core on a pseudo-terminal) sharing one true motion.

#![deny(missing_docs)]

pub mod physics;
pub mod rig;
