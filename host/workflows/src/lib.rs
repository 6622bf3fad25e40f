//! Workflows: what a user runs, built on the model ([`robimu_model`]),
//! problem and solver ([`robimu_solver`]) and session ([`robimu_session`]) layers.
//!
//! * [`allan`] — Allan deviation of a static IMU recording;
//! * [`baseline`] — the classical tracker-based robot and IMU calibrations;
//! * [`check`] — the pre-flight check of a recording (units, rates, gaps, excitation);
//! * [`batch`] — production batches: many sessions in parallel, a summary, limits;
//! * [`calibrate`] — the MAP calibration of one session, on [`calibrate::fit`],
//!   the one fit pipeline behind every estimate of x (calibration, diagnosis
//!   refits, repeatability windows, Monte Carlo runs);
//! * [`diagnose`] — model-discrepancy diagnosis with the effect catalogue;
//! * [`identifiability`] — σ against length, speed and random trajectories (paper §8.2, §8.4);
//! * [`montecarlo`] — consistency of the estimator over many simulated runs;
//! * [`motion_accuracy`] — the IMU accuracy of a tracked motion (paper Fig. 11);
//! * [`noise`] — Σ_z and Σ_q of a recording by spline fitting (paper §8.1);
//! * [`pose_calibrate`] — calibrate an IMU from a pose stream (MODEL.md §10);
//! * [`noise_id`] — a channel's noise model (AR correlation, motion level) from its residuals;
//! * [`plan`] — excitation trajectory planning (paper §7);
//! * [`repeatability`] — calibrations of k time windows against the full one;
//! * [`simulate`] — simulated sessions from a ground truth;
//! * [`stats`] — χ² tail and Ljung–Box whiteness of residual sequences;
//! * [`time_offset`] — finding τ before linearising;
//! * [`tracker_offset`] — the tracker/robot time offset δ (paper §9);
//! * [`tracker`] — tracker poses and their registration to the robot (paper §9);
//! * [`verdict`] — whether a calibration can be trusted (`trust: good / doubtful / bad`);
//! * [`validate`] — robot and IMU accuracy against an external tracker.
//!
//! Main entry points: [`calibrate::calibrate`] (with [`calibrate::CalibrateOptions`];
//! it returns a [`calibrate::Calibration`]: x, its posterior σ and covariance,
//! the fitted trajectory, the solver's run), [`simulate::simulate`] and
//! [`simulate::random_session`] (sessions with a known truth) and
//! [`plan::plan`] (an excitation trajectory).
//!
//! # Example
//!
//! Simulate 20 s of random motion of an AUBO i5 (a truth drawn from the
//! priors, the paper's rates and noise), calibrate it and read the time offset
//! τ with its posterior σ:
//!
//! ```
//! use robimu_model::{ParamLayout, Robot};
//! use robimu_workflows::calibrate::{calibrate, CalibrateOptions};
//! use robimu_workflows::simulate::{random_session, SimulateOptions};
//!
//! let robot = Robot::aubo_i5();
//! let session = random_session(&robot, 20.0, 1.0, &SimulateOptions::paper(&robot), 1)?;
//! let cal = calibrate(&robot, &session.data, &CalibrateOptions::new(&robot), |_| {})?;
//!
//! let tau = ParamLayout::new(&robot).offsets().tau;
//! println!("τ = {:.5} ± {:.5} s", cal.x[tau], cal.sigma[tau]);
//! assert!(cal.sigma[tau] > 0.0);
//! assert!((cal.x[tau] - session.truth[tau]).abs() < 5.0 * cal.sigma[tau]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod allan;
pub mod baseline;
pub mod batch;
pub mod body_rate;
pub mod calibrate;
pub mod check;
pub mod convergence;
pub mod diagnose;
pub mod export;
pub mod identifiability;
pub mod import;
pub mod joint_offsets;
pub mod montecarlo;
pub mod motion_accuracy;
pub mod noise;
pub mod noise_id;
pub mod pipeline;
pub mod plan;
pub mod pose_accuracy;
pub mod pose_calibrate;
pub mod repeatability;
pub mod simulate;
pub mod stats;
pub mod time_offset;
pub mod tracker;
pub mod tracker_offset;
pub mod validate;
pub mod verdict;

pub use pipeline::{
    calibrate_job, diagnose_session, is_urdf, load_session, resolve_robot, session_robot,
    DiagnoseSettings, Diagnosed, FitEvent, Fitted, Job, ModelChoice, PipelineError, Prepared,
    Settings, BUILTIN_ROBOTS,
};

pub use diagnose::{Alternative, Determination, Score};

pub use crate::allan::AllanError;
pub use crate::allan::AllanPoint;
pub use crate::allan::NoiseTerms;
pub use crate::baseline::ImuBaseline;
pub use crate::baseline::LinearSensor;
pub use crate::baseline::RobotBaseline;
pub use crate::batch::limits::LimitsError;
pub use crate::batch::summary::SessionOutcome;
pub use crate::calibrate::fit::FitSpec;
pub use crate::calibrate::TrajectoryFit;
pub use crate::check::Finding;
pub use crate::convergence::ConvergenceError;
pub use crate::diagnose::resolution::ResolutionChoice;
pub use crate::diagnose::resolution::ResolutionScore;
pub use crate::diagnose::AliasedWith;
pub use crate::diagnose::DiagnoseError;
pub use crate::diagnose::NoiseUse;
pub use crate::diagnose::ParameterMove;
pub use crate::diagnose::Unexplained;
pub use crate::identifiability::BaselineMedians;
pub use crate::identifiability::CheckError;
pub use crate::identifiability::ErrorMoments;
pub use crate::identifiability::GainError;
pub use crate::import::JointsByName;
pub use crate::joint_offsets::joint_offsets;
pub use crate::joint_offsets::JointOffsets;
pub use crate::joint_offsets::ROTATION_LENGTH;
pub use crate::montecarlo::MonteCarloError;
pub use crate::montecarlo::ParamStats;
pub use crate::montecarlo::PoseCoverage;
pub use crate::montecarlo::RunOutcome;
pub use crate::noise::NoiseError;
pub use crate::noise_id::ChannelIdentification;
pub use crate::noise_id::NoiseIdError;
pub use crate::pipeline::validate::Validation;
pub use crate::plan::files::PlanFileError;
pub use crate::plan::information::InformationError;
pub use crate::plan::PlanError;
pub use crate::pose_calibrate::calibrate_pose_imus_with;
pub use crate::pose_calibrate::calibrate_poses;
pub use crate::pose_calibrate::calibrate_poses_with;
pub use crate::pose_calibrate::diagnose::{
    diagnose_poses, NotApplicable, PoseDiagnoseOptions, PoseDiagnosis,
};
pub use crate::pose_calibrate::draw_pose_imus_truth;
pub use crate::pose_calibrate::draw_pose_truth;
pub use crate::pose_calibrate::random_pose_motion;
pub use crate::pose_calibrate::simulate_pose_imus;
pub use crate::pose_calibrate::simulate_pose_session;
pub use crate::pose_calibrate::ImuSamples;
pub use crate::pose_calibrate::ImuTiming;
pub use crate::pose_calibrate::NoiseLevels;
pub use crate::pose_calibrate::PoseCalibration;
pub use crate::pose_calibrate::PoseCalibrationError;
pub use crate::pose_calibrate::PoseCalibrationOptions;
pub use crate::pose_calibrate::PoseImuFit;
pub use crate::pose_calibrate::Startup;
pub use crate::pose_calibrate::TauDrift;
pub use crate::repeatability::GroupSpread;
pub use crate::repeatability::ParameterSpread;
pub use crate::repeatability::RepeatabilityError;
pub use crate::repeatability::WindowResult;
pub use crate::simulate::SimulateError;
pub use crate::time_offset::TauError;
pub use crate::time_offset::TauSearch;
pub use crate::tracker::Registration;
pub use crate::tracker::TrackedPose;
pub use crate::tracker::ValidateError;
pub use crate::tracker_offset::TrackerOffset;
pub use crate::verdict::VerdictInput;
