//! `robimu validate`'s computation: a calibration result against an external
//! tracker's static poses (robot accuracy) and, when a tracked motion is
//! available, against its tracked IMU pose (IMU accuracy), the tracker's
//! clock aligned with the session's (paper §9, Fig. 10–11).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::{ParamLayout, Robot};
use robimu_session::poses::read_pose_file;
use robimu_session::result::CalibrationResult;
use robimu_session::{files, Session};

use super::load_session;
use crate::motion_accuracy::{align_tracker, motion_imu_accuracy};
use crate::tracker::{tracked_poses, TrackedPose};
use crate::tracker_offset::TrackerAlignment;
use crate::validate::{robot_accuracy, ImuAccuracy, RobotAccuracy};

/// What to validate (`robimu validate`'s flags).
#[derive(Debug, Clone, Default)]
pub struct ValidateRequest {
    /// The session directory the calibration was computed from.
    pub session: PathBuf,
    /// The calibration result (result.json).
    pub calibration: PathBuf,
    /// The tracker's static poses (CSV, with `q1..qn` columns or timed
    /// against the session's joints.csv).
    pub tracker: PathBuf,
    /// Poses that fit the transforms and the classical calibration
    /// [default: 60 %].
    pub train: Option<usize>,
    /// A session with a tracked motion [default: `session` when it has a
    /// tracker.csv].
    pub motion: Option<PathBuf>,
    /// The tracker clock's offset δ, s [default: estimated].
    pub tracker_offset: Option<f64>,
    /// IMU J of a session of several IMUs [default: 0].
    pub imu: Option<usize>,
}

/// What [`validate_session`] found.
#[derive(Debug, Clone)]
pub struct Validation {
    /// The one-IMU layout the result was validated in.
    pub layout: ParamLayout,
    /// The result's one-IMU view of the IMU validated.
    pub result: CalibrationResult,
    /// The robot accuracy (static poses).
    pub robot: RobotAccuracy,
    /// The tracked motion's clock offset, when there is a tracked motion.
    pub alignment: Option<TrackerAlignment>,
    /// The IMU accuracy, when there is a tracked motion.
    pub imu: Option<ImuAccuracy>,
}

/// Validate the calibration of `req`.
pub fn validate_session(req: &ValidateRequest) -> anyhow::Result<Validation> {
    let (session, robot) = load_session(&req.session)?;
    let result = CalibrationResult::read(&req.calibration)?;
    let calibration = || format!("--calibration {}", req.calibration.display());
    // IMU J of a multi-IMU session and result, as a one-IMU pair
    let j = req.imu.unwrap_or(0);
    let result = result
        .imu(j)
        .map_err(anyhow::Error::msg)
        .with_context(calibration)?;
    let k = session.n_imus();
    let session = session.only_imu(j).with_context(|| {
        format!(
            "--imu {j}: the session {} has {k} IMU(s)",
            req.session.display()
        )
    })?;
    let robot = robot.with_mount(0, *robot.mount_of(j))?;
    let layout = ParamLayout::new(&robot);
    let x = result.values(&layout).with_context(calibration)?;
    let frozen = result.frozen(&layout);
    let poses = read_poses(&req.tracker, &session, robot.dof())
        .with_context(|| format!("--tracker {}", req.tracker.display()))?;
    let train = req
        .train
        .unwrap_or_else(|| (poses.len() as f64 * 0.6).round() as usize);
    if train < 3 || train >= poses.len() {
        bail!(
            "--train {train}: {} poses; need at least 3 to fit and 1 to hold out",
            poses.len()
        );
    }
    let acc = robot_accuracy(&robot, &layout, &x, &poses, train, &frozen)
        .context("cannot compute the robot accuracy")?;
    let motion_dir = req
        .motion
        .clone()
        .or_else(|| session.tracker.is_some().then(|| req.session.clone()));
    let (alignment, imu) = match motion_dir {
        None => (None, None),
        Some(dir) => {
            let motion = if dir == req.session {
                session.clone()
            } else {
                let m = Session::load(&dir)
                    .with_context(|| format!("--motion: cannot load {}", dir.display()))?;
                super::check_times(&m)?;
                m.only_imu(j).with_context(|| {
                    format!(
                        "--imu {j}: the --motion session {} has no IMU {j}",
                        dir.display()
                    )
                })?
            };
            let a = alignment(req, &robot, &layout, &x, &motion, &dir)?;
            let registration = &acc.baseline.registration;
            let imu =
                motion_imu_accuracy(&robot, &layout, &x, registration, &motion, &dir, a.delta)?;
            (Some(a), Some(imu))
        }
    };
    Ok(Validation {
        layout,
        result,
        robot: acc,
        alignment,
        imu,
    })
}

/// The tracker clock's offset δ of the tracked `motion` (directory `dir`):
/// the request's, else estimated.
fn alignment(
    req: &ValidateRequest,
    robot: &Robot,
    layout: &ParamLayout,
    x: &[f64],
    motion: &Session,
    dir: &Path,
) -> anyhow::Result<TrackerAlignment> {
    if motion.tracker.is_none() {
        bail!("--motion {}: no tracker.csv", dir.display());
    }
    match req.tracker_offset {
        Some(delta) if !delta.is_finite() => {
            bail!("--tracker-offset must be a number of seconds (got {delta})")
        }
        Some(delta) => Ok(TrackerAlignment {
            delta,
            estimate: None,
        }),
        None => align_tracker(robot, layout, x, motion).with_context(|| {
            format!(
                "cannot find the time offset of {} against its joint samples (give it with --tracker-offset SECONDS)",
                dir.join(files::TRACKER).display()
            )
        }),
    }
}

/// The poses of `path`, with joint angles from its `q1..qn` columns or the
/// session's joints.csv.
fn read_poses(path: &Path, session: &Session, n: usize) -> anyhow::Result<Vec<TrackedPose>> {
    let file = read_pose_file(path, n)?;
    tracked_poses(
        &file.table,
        file.joints.as_deref(),
        Some(&session.joints),
        n,
    )
    .with_context(|| format!("{}", path.display()))
}
