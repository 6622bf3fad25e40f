//! The IMU accuracy of a tracked motion (paper Fig. 11): the tracker's
//! clock aligned with the session's (δ estimated from the angular speeds,
//! or given), splines fitted to the tracked IMU pose as the ground truth,
//! and the nominal, calibrated and classical IMU corrections against it.

use std::path::{Path, PathBuf};

use crate::tracker::{Registration, ValidateError};
use crate::tracker_offset::{
    estimate_tracker_offset, to_session_clock, OffsetSearch, TrackerAlignment,
};
use crate::validate::{imu_accuracy, imu_position_and_gravity, ImuAccuracy, ImuGroundTruth};
use robimu_model::{ParamLayout, Robot};
use robimu_session::Session;

/// Tracker samples per knot of the ground-truth splines.
const SAMPLES_PER_KNOT: usize = 30;

/// Why the IMU accuracy of a tracked motion could not be computed.
#[derive(Debug, thiserror::Error)]
pub(crate) enum MotionAccuracyError {
    /// The tracked motion (its file named) is not usable.
    #[error("{}", path.display())]
    Tracker {
        /// The motion's tracker.csv.
        path: PathBuf,
        /// Why.
        #[source]
        source: ValidateError,
    },
    /// The calibrated parameters give no IMU position or gravity.
    #[error(transparent)]
    Parameters(ValidateError),
    /// The corrected IMU samples could not be compared.
    #[error("cannot compute the IMU accuracy from {} (tracker time offset δ = {delta} s)", dir.display())]
    Accuracy {
        /// The motion's session directory.
        dir: PathBuf,
        /// δ, s.
        delta: f64,
        /// Why.
        #[source]
        source: ValidateError,
    },
}

/// δ of `motion`'s tracker.csv against its own joint samples under `x`.
pub(crate) fn align_tracker(
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
    motion: &Session,
) -> Result<TrackerAlignment, ValidateError> {
    let tracker = motion.tracker.as_ref().ok_or_else(no_motion)?;
    let data = motion.measurements();
    let search = OffsetSearch::default();
    let e = estimate_tracker_offset(
        robot,
        layout,
        x,
        tracker,
        &data.joint_t,
        &data.joint_q,
        &search,
    )?;
    Ok(TrackerAlignment {
        delta: e.delta,
        estimate: Some(e),
    })
}

fn no_motion() -> ValidateError {
    ValidateError::Input("the session has no tracked motion".into())
}

/// The IMU accuracy of the tracked `motion` (session directory `dir`, with
/// a tracker.csv) whose tracker clock is `delta` s ahead of the session's;
/// `registration` places the tracker against the robot base.
pub(crate) fn motion_imu_accuracy(
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
    registration: &Registration,
    motion: &Session,
    dir: &Path,
    delta: f64,
) -> Result<ImuAccuracy, MotionAccuracyError> {
    let path = dir.join(robimu_session::files::TRACKER);
    let tracked = |source| MotionAccuracyError::Tracker {
        path: path.clone(),
        source,
    };
    let tracker = motion
        .tracker
        .as_ref()
        .ok_or_else(|| tracked(no_motion()))?;
    let data = motion.measurements();
    let span = motion.joints.span().unwrap_or_default();
    let aligned = to_session_clock(tracker, delta, span).map_err(tracked)?;
    let (p_imu, g) =
        imu_position_and_gravity(robot, layout, x).map_err(MotionAccuracyError::Parameters)?;
    let gt =
        ImuGroundTruth::fit(&aligned, registration, p_imu, g, SAMPLES_PER_KNOT).map_err(tracked)?;
    imu_accuracy(layout, &layout.nominal(), x, &gt, &data.imu_t, &data.imu_z).map_err(|source| {
        MotionAccuracyError::Accuracy {
            dir: dir.to_path_buf(),
            delta,
            source,
        }
    })
}
