//! `robimu validate`: robot and IMU accuracy against an external tracker
//! (paper §9, Fig. 10–11), with the classical calibrations for comparison.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::ParamLayout;
use robimu_report::html::{tracker_alignment_text, validation_report_with};
use robimu_session::result::CalibrationResult;
use robimu_session::{read_table, Columns, Session, TRACKER_COLUMNS};
use robimu_workflows::tracker::{tracked_poses, TrackedPose};
use robimu_workflows::tracker_offset::{
    estimate_tracker_offset, to_session_clock, OffsetSearch, TrackerAlignment,
};
use robimu_workflows::validate::{
    imu_accuracy, imu_position_and_gravity, robot_accuracy, ImuAccuracy, ImuErrors, ImuGroundTruth,
    PoseErrors, RobotAccuracy,
};

use super::input::load_session;
use super::report::result_vector;

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
}

/// The poses of `path`, with joint angles from its `q1..qn` columns or `joints`.
fn read_poses(path: &Path, session: &Session, n: usize) -> anyhow::Result<Vec<TrackedPose>> {
    let table = read_table(path, Columns::Fixed(&TRACKER_COLUMNS))?;
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_path(path)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let header = rdr.headers()?.clone();
    let cols: Vec<Option<usize>> = (1..=n)
        .map(|j| header.iter().position(|h| h == format!("q{j}")))
        .collect();
    let extra = if cols.iter().all(Option::is_some) {
        let mut values = Vec::with_capacity(table.len() * n);
        for (row, rec) in rdr.records().enumerate() {
            let rec = rec.with_context(|| format!("{}: row {}", path.display(), row + 1))?;
            for (j, c) in cols.iter().enumerate() {
                let field = rec.get(c.expect("checked")).unwrap_or("");
                let v: f64 = field
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .with_context(|| {
                        format!(
                            "{}: row {}: q{} = `{field}` is not a number",
                            path.display(),
                            row + 1,
                            j + 1
                        )
                    })?;
                values.push(v);
            }
        }
        Some(values)
    } else {
        None
    };
    tracked_poses(&table, extra.as_deref(), Some(&session.joints), n)
        .with_context(|| format!("{}", path.display()))
}

/// validation.json: the numbers of the tables (SI units and mm/deg).
fn summary_json(
    acc: &RobotAccuracy,
    imu: Option<&ImuAccuracy>,
    alignment: Option<&TrackerAlignment>,
) -> serde_json::Value {
    use serde_json::json;
    let pose = |e: &PoseErrors| {
        json!({
            "mean_position_mm": 1e3 * e.mean_position(),
            "max_position_mm": 1e3 * e.max_position(),
            "mean_rotation_deg": e.mean_rotation().to_degrees(),
            "max_rotation_deg": e.max_rotation().to_degrees(),
        })
    };
    let mut v = json!({
        "robot_accuracy": {
            "train": acc.train,
            "test": acc.test,
            "nominal": pose(&acc.nominal),
            "calibrated": pose(&acc.calibrated),
            "classical": pose(&acc.classical),
        },
    });
    if let Some(imu) = imu {
        let errs = |e: &ImuErrors| {
            json!({
                "rms_gyro_deg_s": e.rms_gyro().to_degrees(),
                "rms_accel_m_s2": e.rms_accel(),
            })
        };
        v["imu_accuracy"] = json!({
            "train": imu.train,
            "test": imu.test,
            "nominal": errs(&imu.nominal),
            "calibrated": errs(&imu.calibrated),
            "classical": errs(&imu.classical),
        });
    }
    if let Some(a) = alignment {
        v["tracker_offset"] = json!({
            "delta_s": a.delta,
            "delta_ms": 1e3 * a.delta,
            "estimated": a.estimate.is_some(),
            "r_squared": a.estimate.map(|e| e.r_squared),
            "rms_deg_s": a.estimate.map(|e| e.rms.to_degrees()),
            "overlap_s": a.estimate.map(|e| e.overlap),
        });
    }
    v
}

impl ValidateCmd {
    /// Validate, print and write the report.
    pub fn run(self) -> anyhow::Result<()> {
        let (session, robot) = load_session(&self.session)?;
        let layout = ParamLayout::new(&robot);
        let result = CalibrationResult::read(&self.calibration)?;
        let x = result_vector(&layout, &result)
            .with_context(|| format!("--calibration {}", self.calibration.display()))?;
        let frozen: Vec<usize> = result
            .parameters
            .iter()
            .filter(|p| p.frozen)
            .filter_map(|p| layout.index_of(&p.name))
            .collect();
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
        let mut alignment = None;
        let imu: Option<ImuAccuracy> = match motion_dir {
            None => None,
            Some(dir) => {
                let motion = if dir == self.session {
                    session.clone()
                } else {
                    Session::load(&dir)
                        .with_context(|| format!("--motion: cannot load {}", dir.display()))?
                };
                let tracker = motion
                    .tracker
                    .as_ref()
                    .with_context(|| format!("--motion {}: no tracker.csv", dir.display()))?;
                let tracker_path = dir.join("tracker.csv");
                let data = motion.measurements();
                let a = match self.tracker_offset {
                    Some(delta) => {
                        if !delta.is_finite() {
                            bail!("--tracker-offset must be a number of seconds (got {delta})");
                        }
                        TrackerAlignment {
                            delta,
                            estimate: None,
                        }
                    }
                    None => {
                        let e = estimate_tracker_offset(
                            &robot,
                            &layout,
                            &x,
                            tracker,
                            &data.joint_t,
                            &data.joint_q,
                            &OffsetSearch::default(),
                        )
                        .with_context(|| {
                            format!(
                                "cannot find the time offset of {} against its joint samples (give it with --tracker-offset SECONDS)",
                                tracker_path.display()
                            )
                        })?;
                        TrackerAlignment {
                            delta: e.delta,
                            estimate: Some(e),
                        }
                    }
                };
                alignment = Some(a);
                let span = motion.joints.span().unwrap_or_default();
                let aligned = to_session_clock(tracker, a.delta, span)
                    .with_context(|| format!("{}", tracker_path.display()))?;
                let (p_imu, g) = imu_position_and_gravity(&robot, &layout, &x)?;
                let gt = ImuGroundTruth::fit(&aligned, &acc.baseline.registration, p_imu, g, 30)
                    .with_context(|| format!("{}", tracker_path.display()))?;
                Some(
                    imu_accuracy(
                        &layout,
                        &layout.nominal(),
                        &x,
                        &gt,
                        &data.imu_t,
                        &data.imu_z,
                    )
                    .with_context(|| {
                        format!(
                            "cannot compute the IMU accuracy from {} (tracker time offset δ = {} s)",
                            dir.display(),
                            a.delta
                        )
                    })?,
                )
            }
        };
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "robot accuracy on {} held-out poses ({} fit the transforms and the classical calibration):",
            acc.test, acc.train
        )?;
        writeln!(
            out,
            "{:<26} {:>12} {:>10} {:>12} {:>10}",
            "parameters", "mean [mm]", "max [mm]", "mean [deg]", "max [deg]"
        )?;
        for (name, e) in [
            ("nominal", &acc.nominal),
            ("calibrated", &acc.calibrated),
            ("classical (tracker)", &acc.classical),
        ] {
            writeln!(
                out,
                "{:<26} {:>12.3} {:>10.3} {:>12.4} {:>10.4}",
                name,
                1e3 * e.mean_position(),
                1e3 * e.max_position(),
                e.mean_rotation().to_degrees(),
                e.max_rotation().to_degrees()
            )?;
        }
        if let Some(a) = &alignment {
            writeln!(out, "{}", tracker_alignment_text(a))?;
        }
        if let Some(imu) = &imu {
            writeln!(
                out,
                "IMU accuracy on {} held-out samples ({} fit the classical IMU calibration):",
                imu.test, imu.train
            )?;
            writeln!(
                out,
                "{:<26} {:>16} {:>18}",
                "intrinsics", "rms |dw| [deg/s]", "rms |ds| [m/s^2]"
            )?;
            for (name, e) in [
                ("nominal", &imu.nominal),
                ("calibrated", &imu.calibrated),
                ("classical (tracker)", &imu.classical),
            ] {
                writeln!(
                    out,
                    "{:<26} {:>16.3} {:>18.3}",
                    name,
                    e.rms_gyro().to_degrees(),
                    e.rms_accel()
                )?;
            }
        }
        let dir = self
            .report
            .clone()
            .unwrap_or_else(|| self.session.join("validation"));
        let path = validation_report_with(
            &dir,
            &layout,
            &result,
            &acc,
            imu.as_ref(),
            alignment.as_ref(),
        )?;
        writeln!(out, "wrote {}", path.display())?;
        let json_path = dir.join("validation.json");
        let json = summary_json(&acc, imu.as_ref(), alignment.as_ref());
        std::fs::write(&json_path, serde_json::to_string_pretty(&json)? + "\n")
            .with_context(|| format!("cannot write {}", json_path.display()))?;
        writeln!(out, "wrote {}", json_path.display())?;
        Ok(())
    }
}
