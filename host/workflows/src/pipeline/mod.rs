//! The pipelines a user runs, as the `robimu` program runs them and for
//! library users and the Python package alike: a session directory in,
//! typed results and the project's files out.
//!
//! * [`Prepared`] → [`Fitted`]: `robimu calibrate` (docs/model.md §8) with
//!   its [`Settings`];
//! * [`diagnose_session`]: `robimu diagnose` (docs/model.md §7) with its
//!   [`DiagnoseSettings`];
//! * [`jobs`] and [`calibrate_job`]: `robimu calibrate-batch`;
//! * [`poses::calibrate_pose_session`]: `robimu calibrate` of a session with
//!   tool poses; [`pose_simulate::simulate_pose_dir`]: `robimu simulate
//!   --source poses` (docs/model.md §7.9);
//! * [`simulate::simulate_session`]: `robimu simulate`; [`validate::validate_session`]:
//!   `robimu validate`;
//! * [`load_session`] and [`resolve_robot`]: a session and the robot it names.
//!
//! Errors are [`PipelineError`]s whose kind says whose fault it was (the
//! input, the fit, writing a file) and whose text is the program's message.
//!
//! ```no_run
//! use robimu_workflows::{load_session, Prepared, Settings};
//!
//! let dir = std::path::Path::new("session");
//! let (session, robot) = load_session(dir)?;
//! let prepared = Prepared::new(session, robot, &Settings::default(), None, |w| eprintln!("{w}"))?;
//! let fitted = prepared.fit(|_| {})?;
//! if let Some(pose) = &fitted.result.pose_accuracy {
//!     let (before, after) = (pose.before.position_mean_mm, pose.after.position_mean_mm);
//!     println!("flange position error {before:.2} mm → {after:.2} mm");
//! }
//! println!("{:?}", fitted.result.verdict);
//! fitted.write(&dir.join("result.json"))?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod batch;
mod calibration;
mod covariance_kind;
#[cfg(test)]
mod covariance_kind_montecarlo;
mod diagnosis;
mod input;
mod model_choice;
mod next_steps;
pub mod noise_spec;
pub mod pose_diagnosis;
mod pose_flange;
pub mod pose_simulate;
pub mod poses;
pub mod simulate;
pub mod validate;

pub use batch::{calibrate_job, jobs, Job};
pub use calibration::{write_result, FitEvent, Fitted, Prepared, Settings};
pub use diagnosis::{diagnose_session, DiagnoseSettings, Diagnosed};
pub use input::{
    check_times, fatal_findings, is_urdf, load_session, resolve_robot, session_robot, ChainLinks,
    RobotSource, BUILTIN_ROBOTS,
};
pub use model_choice::ModelChoice;

use robimu_model::effects::resonance::Mode;

/// Why a pipeline stopped; its text (and its causes, through
/// [`std::error::Error::source`]) is the program's message.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The input cannot be used: the session, a file it names, a setting.
    #[error(transparent)]
    Input(Box<dyn std::error::Error + Send + Sync + 'static>),
    /// The estimation failed (e.g. did not converge, singular).
    #[error(transparent)]
    Fit(Box<dyn std::error::Error + Send + Sync + 'static>),
    /// A result file could not be written.
    #[error(transparent)]
    Write(Box<dyn std::error::Error + Send + Sync + 'static>),
}

impl PipelineError {
    fn input(e: anyhow::Error) -> Self {
        Self::Input(e.into())
    }

    fn fit(e: anyhow::Error) -> Self {
        Self::Fit(e.into())
    }

    fn write(e: anyhow::Error) -> Self {
        Self::Write(e.into())
    }
}

/// The `resonance` effect's mode, checked: 0.5–50 Hz, damping in (0, 1).
pub fn checked_mode(mode: Mode) -> anyhow::Result<Mode> {
    let (f, z) = (mode.f_hz, mode.zeta);
    if !(0.5..=50.0).contains(&f) {
        anyhow::bail!("--resonance-hz must be between 0.5 and 50 Hz (got {f})");
    }
    if !(z > 0.0 && z < 1.0) {
        anyhow::bail!("--resonance-zeta must be between 0 and 1, exclusive (got {z})");
    }
    Ok(mode)
}
