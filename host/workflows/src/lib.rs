//! Workflows: what a user runs, built on the model ([`robimu_model`]),
//! problem and solver ([`robimu_solver`]) and session ([`robimu_session`]) layers.
//!
//! * [`allan`] — Allan deviation of a static IMU recording;
//! * [`baseline`] — the classical tracker-based robot and IMU calibrations;
//! * [`calibrate`] — the MAP calibration of one session, on [`calibrate::fit`],
//!   the one fit pipeline behind every estimate of x (calibration, diagnosis
//!   refits, repeatability windows, Monte Carlo runs);
//! * [`diagnose`] — model-discrepancy diagnosis with the effect catalogue;
//! * [`identifiability`] — σ against length, speed and random trajectories (paper §8.2, §8.4);
//! * [`montecarlo`] — consistency of the estimator over many simulated runs;
//! * [`noise`] — Σ_z and Σ_q of a recording by spline fitting (paper §8.1);
//! * [`plan`] — excitation trajectory planning (paper §7);
//! * [`repeatability`] — calibrations of k time windows against the full one;
//! * [`simulate`] — simulated sessions from a ground truth;
//! * [`time_offset`] — finding τ before linearising;
//! * [`tracker_offset`] — the tracker/robot time offset δ (paper §9);
//! * [`tracker`] — tracker poses and their registration to the robot (paper §9);
//! * [`validate`] — robot and IMU accuracy against an external tracker.

#![deny(missing_docs)]
#![allow(clippy::needless_range_loop)]

pub mod allan;
pub mod baseline;
pub mod calibrate;
pub mod diagnose;
pub mod identifiability;
pub mod montecarlo;
pub mod noise;
pub mod plan;
pub mod repeatability;
pub mod simulate;
pub mod time_offset;
pub mod tracker;
pub mod tracker_offset;
pub mod validate;
