//! The robot–IMU measurement model (paper §3–5; the contract is docs/model.md §1–5):
//! what an IMU on a robot's flange measures, as a function of the joint
//! trajectory and of the parameter vector x (robot errors, IMU mount, IMU
//! intrinsics, time offset τ), with exact Jacobians.
//!
//! Main types: [`Robot`] (a robot description: DH table or URDF chain,
//! limits, noise, priors; built-in [`Robot::aubo_i5`]), [`ParamLayout`] (the
//! names, units and priors of x), [`MeasurementModel`] (predicted IMU output
//! z at a [`JointState`]), [`Spline`] (the joint trajectory) and
//! [`Measurements`] (the samples of a session).
//!
//! Layers, each one concept:
//! - [`robot`]: robot description (DH table, limits, noise, IMU mount, priors,
//!   estimated generalized errors), built-in [`robot::Robot::aubo_i5`] and TOML loading;
//! - [`params`]: the parameter vector x (names, units, priors, typed views);
//! - [`kinematics`]: forward kinematics with generalized errors, eq. (1)–(4);
//! - [`imu`]: gravity, inertial quantities and the sensor model, eq. (5)–(6);
//! - [`urdf`]: robots from URDF (the revolute chain from a base to a tip link);
//! - [`spline`]: the clamped B-spline trajectory, eq. (18)–(21);
//! - [`pose_trajectory`]: the continuous-time pose of a posed body (position
//!   B-spline and cumulative B-spline on SO(3)) for pose sessions (MODEL.md §10);
//! - [`pose_measurement`]: the 30 parameters of a pose session and its predicted
//!   IMU sample with exact Jacobians (MODEL.md §10);
//! - [`measurement`]: predicted z with exact Jacobians (eq. (10));
//! - [`jet`], [`geom`]: the scalar type (f64 or forward-mode jet) and small
//!   geometry (3-vectors, SO(3), quaternions, rigid transforms);
//! - [`noise`]: measurement noise correlated in time (AR) and following the motion;
//! - [`observations`]: the joint and IMU samples of a session;
//! - [`trajectory`]: random excitation trajectories within the joint limits;
//! - [`error_selection`]: which generalized errors the IMU data can identify;
//! - [`effects`]: the catalogue of model extensions that diagnose tests;
//! - [`units`]: display units of parameters.
//!
//! All quantities are SI: m, rad, s, m/s², rad/s.
//!
//! # Example
//!
//! What the IMU of an AUBO i5 at its nominal parameters reads with the arm at
//! rest: gravity's specific force and no rotation.
//!
//! ```
//! use robimu_model::{JointState, MeasurementModel, ParamLayout, Robot};
//!
//! let robot = Robot::aubo_i5();
//! let layout = ParamLayout::new(&robot);
//! let x = layout.nominal();
//! let model = MeasurementModel::new(&robot, &layout, &x)?;
//! let z = model.predict(&JointState::default()); // [ax, ay, az, gx, gy, gz]
//! let s = (z[0] * z[0] + z[1] * z[1] + z[2] * z[2]).sqrt();
//! assert!((s - 9.81).abs() < 0.05, "|s| = {s} m/s²");
//! assert!(z[3..].iter().all(|w| w.abs() < 1e-9), "ω = {:?} rad/s", &z[3..]);
//! # Ok::<(), robimu_model::ModelError>(())
//! ```

#![deny(missing_docs)]
// Index loops mirror the matrix formulas of the paper.
#![allow(clippy::needless_range_loop)]

pub mod arity;
pub mod catalogue;
pub mod effects;
pub mod error_selection;
pub mod geom;
pub mod imu;
pub mod jet;
pub mod kinematics;
pub mod lanes;
pub mod measurement;
pub mod noise;
pub mod observations;
pub mod pair;
pub mod params;
pub mod pose_measurement;
pub mod pose_trajectory;
pub mod robot;
pub mod spline;
pub mod text;
pub mod trajectory;
pub mod trig;
pub mod units;
pub mod urdf;

/// Largest number of joints the model supports (fixed-size, allocation-free hot path).
pub const MAX_JOINTS: usize = 8;

pub use catalogue::BUILTIN_ROBOTS;
pub use imu::{ImuError, ImuIntrinsics, PerChannel, IMU_CHANNELS};
pub use jet::{Jet, Scalar};
pub use kinematics::{ImuMotion, JointState};
pub use lanes::F64x4;
pub use measurement::{MeasurementJacobians, MeasurementModel, ModelError};
pub use observations::{Measurements, PoseMeasurements};
pub use params::{ModelParams, Offsets, ParamLayout, ParamSpec};
pub use pose_trajectory::{
    ImuPointJacobians, ImuPointJet, ImuPointState, Jac3x12, KinematicsJet, PoseJacobians,
    PoseResidual, PoseSpline, PoseSplineError, PoseState,
};
pub use robot::{ErrorIndex, Frames, Robot, RobotDescription, RobotError};
pub use spline::{Basis, Basis4, Knots, SpanPolynomials, Spline, SplineError};
pub use text::NotUtf8;

pub use crate::effects::mass::MassError;
pub use crate::effects::resonance::ModeResponse;
pub use crate::effects::temperature_bias::TemperatureTrack;
pub use crate::effects::Inertial;
pub use crate::kinematics::LinkTransform;
pub use crate::observations::ImuView;
pub use crate::params::UnknownParameter;
pub use crate::robot::ChainLink;
pub use crate::robot::DhLink;
pub use crate::robot::JointDescription;
pub use crate::robot::NoiseDescription;
pub use crate::robot::Priors;
pub use crate::urdf::UrdfChain;
pub use crate::urdf::UrdfJoint;
