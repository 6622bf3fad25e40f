//! `robimu validate`: robot and IMU accuracy against an external tracker
//! (paper §9, Fig. 10–11), with the classical calibrations for comparison.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::ParamLayout;
use robimu_report::html::{tracker_alignment_text, validation_report_with};
use robimu_report::validation::{write_validation_json, ImuAccuracyTable, RobotAccuracyTable};
use robimu_session::poses::read_pose_file;
use robimu_session::result::CalibrationResult;
use robimu_session::{files, Session};
use robimu_workflows::motion_accuracy::{align_tracker, motion_imu_accuracy};
use robimu_workflows::tracker::{tracked_poses, TrackedPose};
use robimu_workflows::tracker_offset::TrackerAlignment;
use robimu_workflows::validate::robot_accuracy;

use super::input::load_session;

/// Validate a calibration against an external tracker.
///
/// Robot accuracy (paper Fig. 10): static poses measured by the tracker
/// (`--tracker`: a CSV `t,px,py,pz,qw,qx,qy,qz` in docs/model.md §7's tracker
/// format, with the joint angles in extra columns `q1..qn`, or else taken
/// from the session's joints.csv at each pose's time). The first poses
/// solve the tracker-to-base and flange-to-marker transforms, the rest are
/// held out; position and rotation errors are reported with the nominal,
/// the calibrated and a classical (tracker) calibration's parameters, the
/// latter estimating the same generalized errors, with the result's frozen
/// parameters frozen too.
///
/// IMU accuracy (paper Fig. 11): when a tracked motion is available (the
/// session's tracker.csv, or `--motion`), splines fitted to the tracked IMU
/// pose give the true angular rate and specific force; the IMU output
/// corrected with the nominal, calibrated and a classical (tracker) IMU
/// calibration is compared against them. The tracker's clock is aligned
/// with the session's first: the offset δ is estimated by matching the
/// angular speed of the tracked marker with the flange's (forward kinematics
/// along the joint samples), or given with --tracker-offset. Writes
/// validation.html with histograms (PNG/SVG too) and validation.json.
#[derive(Debug, Clone, clap::Args)]
pub struct ValidateCmd {
    /// Session directory the calibration was computed from.
    pub session: PathBuf,
    /// The calibration result (result.json).
    #[arg(long)]
    pub calibration: PathBuf,
    /// Static poses measured by the tracker (CSV, see above).
    #[arg(long, value_name = "POSES")]
    pub tracker: PathBuf,
    /// Poses used to fit the transforms and the classical calibration; the
    /// rest are held out [default: 60 %, as the paper's 150 of 250].
    #[arg(long)]
    pub train: Option<usize>,
    /// Session directory with a tracked motion (tracker.csv and imu.csv) for
    /// the IMU accuracy [default: SESSION when it has a tracker.csv].
    #[arg(long)]
    pub motion: Option<PathBuf>,
    /// Directory for validation.html, validation.json and the figures
    /// [default: SESSION/validation].
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Time offset δ = t_tracker − t_session of the tracked motion, s (the
    /// tracker sample stamped t was taken at session time t − δ) [default:
    /// estimated by matching the tracked marker's angular speed with the
    /// flange's from the joint samples].
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub tracker_offset: Option<f64>,
    /// A session of several IMUs (docs/model.md §9): validate IMU J (its
    /// parameters from the result, its samples imu<J>.csv) [default: 0].
    #[arg(long = "imu", value_name = "J")]
    pub which_imu: Option<usize>,
}

impl ValidateCmd {
    /// Validate, print and write the report.
    pub fn run(self) -> anyhow::Result<()> {
        let (session, robot) = load_session(&self.session)?;
        let result = CalibrationResult::read(&self.calibration)?;
        // IMU J of a multi-IMU session and result, as a one-IMU pair
        let j = self.which_imu.unwrap_or(0);
        let result = result
            .imu(j)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("--calibration {}", self.calibration.display()))?;
        let k = session.n_imus();
        let session = session.only_imu(j).with_context(|| {
            format!(
                "--imu {j}: the session {} has {k} IMU(s)",
                self.session.display()
            )
        })?;
        let robot = robot.with_mount(0, *robot.mount_of(j))?;
        let layout = ParamLayout::new(&robot);
        let x = result
            .values(&layout)
            .with_context(|| format!("--calibration {}", self.calibration.display()))?;
        let frozen = result.frozen(&layout);
        let poses = read_poses(&self.tracker, &session, robot.dof())
            .with_context(|| format!("--tracker {}", self.tracker.display()))?;
        let train = self
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
        let motion_dir = self
            .motion
            .clone()
            .or_else(|| session.tracker.is_some().then(|| self.session.clone()));
        let (alignment, imu) = match motion_dir {
            None => (None, None),
            Some(dir) => {
                let motion = if dir == self.session {
                    session.clone()
                } else {
                    let m = Session::load(&dir)
                        .with_context(|| format!("--motion: cannot load {}", dir.display()))?;
                    m.only_imu(j).with_context(|| {
                        format!(
                            "--imu {j}: the --motion session {} has no IMU {j}",
                            dir.display()
                        )
                    })?
                };
                let a = self.alignment(&robot, &layout, &x, &motion, &dir)?;
                let registration = &acc.baseline.registration;
                let imu =
                    motion_imu_accuracy(&robot, &layout, &x, registration, &motion, &dir, a.delta)?;
                (Some(a), Some(imu))
            }
        };
        let mut out = std::io::stdout().lock();
        write!(out, "{}", RobotAccuracyTable(&acc))?;
        if let Some(a) = &alignment {
            writeln!(out, "{}", tracker_alignment_text(a))?;
        }
        if let Some(imu) = &imu {
            write!(out, "{}", ImuAccuracyTable(imu))?;
        }
        let dir = self
            .report
            .clone()
            .unwrap_or_else(|| self.session.join("validation"));
        let (imu, alignment) = (imu.as_ref(), alignment.as_ref());
        let path = validation_report_with(&dir, &layout, &result, &acc, imu, alignment)?;
        writeln!(out, "wrote {}", path.display())?;
        let json_path = write_validation_json(&dir, &acc, imu, alignment)?;
        writeln!(out, "wrote {}", json_path.display())?;
        Ok(())
    }

    /// The tracker clock's offset δ of the tracked `motion` (directory
    /// `dir`): --tracker-offset, else estimated.
    fn alignment(
        &self,
        robot: &robimu_model::Robot,
        layout: &ParamLayout,
        x: &[f64],
        motion: &Session,
        dir: &Path,
    ) -> anyhow::Result<TrackerAlignment> {
        if motion.tracker.is_none() {
            bail!("--motion {}: no tracker.csv", dir.display());
        }
        match self.tracker_offset {
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
