//! `robimu check`: the pre-flight check of a recording (docs/model.md §7.8).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_report::check::CheckTable;
use robimu_session::{PoseSession, Session, SessionSource};
use robimu_workflows::check::{
    check_pose_session, check_session, CheckOptions, CheckReport, Severity,
};

use crate::input::session_robot;

/// Check a recording before calibrating it.
///
/// Sample rates and gaps per stream, timestamps (monotonic, in seconds, one
/// clock), the overlap of the streams, the units of the accelerometer (|a|
/// at rest against g0) and the gyroscope (|ω| against the joint speeds
/// through the nominal kinematics), swapped columns, stuck channels,
/// saturation against the device's range, a motionless recording, and the
/// parameters the recorded motion cannot determine. Prints one row per
/// finding with its number and what to do; exits non-zero when a finding
/// is fatal (calibrate runs the same check first and stops there).
///
/// A session with tool poses (`source = "poses"`, poses.csv) is checked for
/// its streams' rates, gaps, jitter and overlap, quaternion sign flips and
/// norms, positions in mm, a start-up burst of late-stamped IMU samples and
/// saturated IMU channels.
#[derive(Debug, Clone, clap::Args)]
pub struct CheckCmd {
    /// Session directory (session.toml, joints.csv or poses.csv, imu.csv).
    pub session: PathBuf,
    /// Also write the findings as JSON to FILE.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Skip the excitation measure (the posterior σ under the recorded motion).
    #[arg(long)]
    pub no_excitation: bool,
}

impl CheckCmd {
    /// Check, print, write the JSON; an error when a finding is fatal.
    pub fn run(self) -> anyhow::Result<()> {
        let opts = CheckOptions {
            excitation: !self.no_excitation,
        };
        let report = check_dir(&self.session, &opts)?;
        let mut out = std::io::stdout().lock();
        writeln!(out, "session {}", self.session.display())?;
        write!(
            out,
            "{}",
            CheckTable {
                report: &report,
                min: Severity::Info
            }
        )?;
        out.flush()?;
        if let Some(path) = &self.json {
            std::fs::write(path, serde_json::to_string_pretty(&report)? + "\n")
                .with_context(|| format!("cannot write {}", path.display()))?;
            writeln!(out, "wrote {}", path.display())?;
        }
        fatal(&report, &self.session)
    }
}

/// The check of the session in `dir`: a session the reader refuses is one
/// fatal finding; a robot that cannot be resolved is an error.
///
/// A session with tool poses (`source = "poses"`, docs/model.md §7.9) is
/// checked by [`check_pose_session`] (it has no robot).
pub fn check_dir(dir: &Path, opts: &CheckOptions) -> anyhow::Result<CheckReport> {
    match SessionSource::of_dir(dir) {
        Err(e) => return Ok(CheckReport::unreadable(&e)),
        Ok(SessionSource::Poses) => {
            return Ok(match PoseSession::read(dir) {
                Ok(s) => check_pose_session(&s),
                Err(e) => CheckReport::unreadable(&e),
            })
        }
        Ok(SessionSource::Joints) => {}
    }
    let session = match Session::load(dir) {
        Ok(s) => s,
        Err(e) => return Ok(CheckReport::unreadable(&e)),
    };
    let robot = session_robot(&session)?;
    if session.joint_count() != robot.dof() {
        bail!(
            "{}: {} joint columns, but robot `{}` has {} joints",
            dir.join("joints.csv").display(),
            session.joint_count(),
            robot.name(),
            robot.dof()
        );
    }
    Ok(check_session(&session, &robot, opts))
}

/// An error naming the fatal findings, if any.
pub fn fatal(report: &CheckReport, dir: &Path) -> anyhow::Result<()> {
    robimu_workflows::pipeline::fatal_findings(report, dir)
}
