//! `robimu validate`: robot and IMU accuracy against an external tracker
//! (paper §9, Fig. 10–11), with the classical calibrations for comparison.

use std::io::Write;
use std::path::PathBuf;

use robimu_report::html::{tracker_alignment_text, validation_report_with};
use robimu_report::validation::{write_validation_json, ImuAccuracyTable, RobotAccuracyTable};
use robimu_workflows::pipeline::validate::{validate_session, ValidateRequest};

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
        let v = validate_session(&ValidateRequest {
            session: self.session.clone(),
            calibration: self.calibration,
            tracker: self.tracker,
            train: self.train,
            motion: self.motion,
            tracker_offset: self.tracker_offset,
            imu: self.which_imu,
        })?;
        let mut out = std::io::stdout().lock();
        write!(out, "{}", RobotAccuracyTable(&v.robot))?;
        if let Some(a) = &v.alignment {
            writeln!(out, "{}", tracker_alignment_text(a))?;
        }
        if let Some(imu) = &v.imu {
            write!(out, "{}", ImuAccuracyTable(imu))?;
        }
        let dir = self
            .report
            .unwrap_or_else(|| self.session.join("validation"));
        let (imu, alignment) = (v.imu.as_ref(), v.alignment.as_ref());
        let path = validation_report_with(&dir, &v.layout, &v.result, &v.robot, imu, alignment)?;
        writeln!(out, "wrote {}", path.display())?;
        let json_path = write_validation_json(&dir, &v.robot, imu, alignment)?;
        writeln!(out, "wrote {}", json_path.display())?;
        Ok(())
    }
}
