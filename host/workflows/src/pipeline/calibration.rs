//! The calibration of one session as `robimu calibrate` runs it
//! (docs/model.md §8): [`Prepared::new`] (the pre-flight check, the IMU to
//! calibrate, the settings, the `effects` set, the noise choice) →
//! [`Prepared::fit`] (the fit under the noise choice, the whiteness of its
//! residuals, the other IMUs' noise, the verdict, the result record) →
//! [`Fitted::write`] (result.json and its convergence log), with
//! [`Prepared::fit_effects`] (effects.json) and [`Prepared::repeatability`]
//! (the verdict with time windows) beside.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::effects::resonance::Mode;
use robimu_model::effects::EffectSet;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::CalibrationResult;
use robimu_session::Session;
use robimu_solver::IterationRecord;

use super::noise_spec::{noise_choice, NoiseFileArg};
use super::{checked_mode, fatal_findings, PipelineError};
use crate::calibrate::fit::{fit, Fit, FitSpec, Start};
use crate::calibrate::noise_choice::{
    calibrate_with_noise_settle, other_imu_identifications, residual_identification, NoiseChoice,
    NoiseOutcome, Settle, MAX_REFITS,
};
use crate::calibrate::{check_measurements, CalibrateOptions, Calibration};
use crate::check::{check_session, CheckOptions, Severity};
use crate::diagnose::{effect_set, fit_json, setup_with};
use crate::noise_id::{IdOptions, Identification};
use crate::repeatability::{self, check_windows, Repeatability, Window};
use crate::verdict::{self, VerdictInput};
use robimu_session::result::VerdictRecord;

/// How a session is calibrated: `robimu calibrate`'s flags, by the same
/// names. [`Default`] is `robimu calibrate`'s defaults.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Parameters held at their prior mean: `lengths` and/or parameter names.
    pub freeze: Vec<String>,
    /// Fit without the priors.
    pub no_prior: bool,
    /// Knot spacing of the trajectory spline, s (`None`: chosen from the data).
    pub knot_spacing: Option<f64>,
    /// Catalogue effects fitted with the baseline (effects.json), e.g.
    /// `joint_elasticity`, `bias_drift:3`, `imu1/sensor_delay`.
    pub effects: Vec<String>,
    /// The `resonance` effect's mode (checked when `effects` is not empty).
    pub resonance: Mode,
    /// The IMU noise model: `auto`, `white` or a noise file's path.
    pub noise_model: String,
    /// `auto`'s refits and settling tolerance.
    pub settle: Settle,
    /// Calibrate IMU J of a multi-IMU session alone.
    pub imu: Option<usize>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            freeze: Vec::new(),
            no_prior: false,
            knot_spacing: None,
            effects: Vec::new(),
            resonance: Mode::default(),
            noise_model: "auto".into(),
            settle: Settle {
                max_refits: MAX_REFITS,
                ..Settle::default()
            },
            imu: None,
        }
    }
}

/// A session ready to calibrate ([`Prepared::new`]).
pub struct Prepared {
    /// The session (IMU J alone with [`Settings::imu`]).
    pub session: Session,
    /// Its robot.
    pub robot: Robot,
    /// The parameter vector's layout (every IMU of the session).
    pub layout: ParamLayout,
    /// The calibration options the settings give.
    pub opts: CalibrateOptions,
    /// The checked measurements.
    pub data: Measurements,
    /// The `effects` set, when given.
    pub effects: Option<EffectSet>,
    /// The noise model choice.
    pub choice: NoiseChoice,
    /// `auto`'s settling rule.
    pub settle: Settle,
}

/// A finished calibration ([`Prepared::fit`]).
pub struct Fitted {
    /// The calibration.
    pub cal: Calibration,
    /// What the noise choice did.
    pub noise: NoiseOutcome,
    /// The result file's contents (with the verdict, docs/model.md §8.5).
    pub result: CalibrationResult,
    /// The whiteness test of the final residuals when the noise choice is
    /// not `auto` (which has its own), for the verdict.
    pub whiteness: Option<Identification>,
    /// A multi-IMU fit's IMUs j ≥ 1: the identification from each one's residuals.
    pub other_imus: Vec<(usize, Identification)>,
}

impl Prepared {
    /// The session made ready to calibrate with `settings`: the pre-flight
    /// check (its warnings to `warn`, a fatal finding an error), IMU J
    /// alone when asked, the options, the checked measurements, the effect
    /// set and the noise choice (`file`: the noise file, read once by the
    /// caller with [`NoiseFileArg::from_flags`]).
    pub fn new(
        session: Session,
        robot: Robot,
        settings: &Settings,
        file: Option<&NoiseFileArg>,
        warn: impl FnMut(String),
    ) -> Result<Self, PipelineError> {
        Self::prepare(session, robot, settings, file, warn).map_err(PipelineError::input)
    }

    fn prepare(
        mut session: Session,
        mut robot: Robot,
        settings: &Settings,
        file: Option<&NoiseFileArg>,
        warn: impl FnMut(String),
    ) -> anyhow::Result<Self> {
        preflight(&session, &robot, warn)?;
        let dir = session.dir.clone();
        if let Some(j) = settings.imu {
            let k = session.n_imus();
            session = session.only_imu(j).with_context(|| {
                format!(
                    "--imu {j}: the session {} has {k} IMU{} (0..{})",
                    dir.display(),
                    if k == 1 { "" } else { "s" },
                    k - 1
                )
            })?;
            // IMU j alone: its own mount prior is the one-IMU robot's
            robot = robot.with_mount(0, *robot.mount_of(j))?;
        }
        let data = session.measurements();
        let layout = ParamLayout::with_imus(&robot, data.n_imus());
        let opts = options(settings, &session, &robot, &layout, file)?;
        check_measurements(&robot, &data)
            .with_context(|| format!("cannot calibrate the session {}", dir.display()))?;
        let effects = effect_set_of(settings, &robot, &data)?;
        let choice = noise_choice(
            &settings.noise_model,
            &session,
            opts.sigma_z,
            data.imu_t.len(),
            file,
        )?;
        Ok(Self {
            session,
            robot,
            layout,
            opts,
            data,
            effects,
            choice,
            settle: settings.settle,
        })
    }

    /// The calibration with the noise choice (docs/model.md §4.6), its
    /// verdict and its result file's contents (not written); `report`
    /// sees each solver iteration.
    pub fn fit(&self, report: impl FnMut(&IterationRecord)) -> Result<Fitted, PipelineError> {
        let dir = &self.session.dir;
        let (cal, noise) = calibrate_with_noise_settle(
            &self.robot,
            &self.data,
            &self.opts,
            &self.choice,
            &self.settle,
            report,
        )
        .with_context(|| format!("cannot calibrate the session {}", dir.display()))
        .map_err(PipelineError::fit)?;
        let whiteness = (self.choice != NoiseChoice::Auto)
            .then(|| {
                residual_identification(&self.robot, &self.data, &cal, &IdOptions::default()).ok()
            })
            .flatten();
        let other_imus: Vec<(usize, Identification)> =
            other_imu_identifications(&self.robot, &self.data, &cal, &IdOptions::default())
                .into_iter()
                .filter_map(|(j, id)| id.ok().map(|id| (j, id)))
                .collect();
        let verdict = verdict::verdict(&VerdictInput {
            robot: &self.robot,
            calibration: &cal,
            noise: Some(&noise),
            whiteness: whiteness.as_ref(),
            repeatability: None,
            other_imus: &other_imus,
        });
        let mut result = result_record(&cal, &self.layout, &self.session, self.opts.use_prior);
        result.noise_warning = noise.warning.clone();
        result.verdict = Some(verdict);
        Ok(Fitted {
            cal,
            noise,
            result,
            whiteness,
            other_imus,
        })
    }

    /// The fit of the `effects` set from the calibration's x, written to
    /// effects.json next to the result file `path`; returns the fit and
    /// effects.json's path (`None` without effects).
    pub fn fit_effects(
        &self,
        cal: &Calibration,
        path: &Path,
    ) -> Result<Option<(Fit, PathBuf)>, PipelineError> {
        let Some(set) = &self.effects else {
            return Ok(None);
        };
        let spec = FitSpec {
            robot: &self.robot,
            data: &self.data,
            effects: set,
            start: Start::At(&cal.x),
        };
        let f = fit(&spec, &self.opts, |_| {})
            .with_context(|| format!("--effects: cannot fit {}", set.names().join(", ")))
            .map_err(PipelineError::fit)?;
        let epath = path.with_file_name("effects.json");
        let json = fit_json(&ParamLayout::with_imus(&self.robot, f.n_imus), &f);
        let text =
            serde_json::to_string_pretty(&json).map_err(|e| PipelineError::write(e.into()))?;
        std::fs::write(&epath, text)
            .with_context(|| format!("cannot write {}", epath.display()))
            .map_err(PipelineError::write)?;
        Ok(Some((f, epath)))
    }

    /// The session cut into `k` equal time windows for a repeatability
    /// study (refused before any fit when it cannot be cut).
    pub fn windows(&self, k: usize) -> Result<Vec<Window>, PipelineError> {
        check_windows(&self.data, k)
            .with_context(|| format!("--windows {k}: cannot split {}", self.session.dir.display()))
            .map_err(PipelineError::input)
    }

    /// Calibrates each window and compares it with the full calibration
    /// `full` (`report(window, iteration)`); returns the study and the
    /// verdict with it, which replaces `full`'s in its result record.
    pub fn repeatability(
        &self,
        full: Fitted,
        windows: Vec<Window>,
        report: impl FnMut(usize, &IterationRecord),
    ) -> Result<(Repeatability, CalibrationResult), PipelineError> {
        let count = windows.len();
        let Fitted {
            cal,
            noise,
            mut result,
            whiteness,
            other_imus,
        } = full;
        let results = repeatability::calibrate_windows(&self.robot, windows, &self.opts, report)
            .with_context(|| format!("--windows {count}: {}", self.session.dir.display()))
            .map_err(PipelineError::fit)?;
        let study = repeatability::compare(&ParamLayout::new(&self.robot), cal, results);
        let verdict: VerdictRecord = verdict::verdict(&VerdictInput {
            robot: &self.robot,
            calibration: &study.full,
            noise: Some(&noise),
            whiteness: whiteness.as_ref(),
            repeatability: Some(&study),
            other_imus: &other_imus,
        });
        result.verdict = Some(verdict);
        Ok((study, result))
    }
}

impl Fitted {
    /// Writes the result file at `path` and the solver's iteration history
    /// next to it (NAME.convergence.csv); returns the history's path.
    pub fn write(&self, path: &Path) -> Result<PathBuf, PipelineError> {
        write_result(&self.result, &self.cal, path)
    }
}

/// Writes `result` at `path` and `cal`'s iteration history next to it;
/// returns the history's path.
pub fn write_result(
    result: &CalibrationResult,
    cal: &Calibration,
    path: &Path,
) -> Result<PathBuf, PipelineError> {
    let history = crate::convergence::convergence_path(path);
    (|| -> anyhow::Result<()> {
        result.write(path)?;
        crate::convergence::ConvergenceLog::from_summary(&cal.summary).write(&history)?;
        Ok(())
    })()
    .map_err(PipelineError::write)?;
    Ok(history)
}

/// The check of the recording before the fit (`robimu check` without the
/// excitation measure, which the calibration's own σ replace): warnings to
/// `warn`, a fatal finding stops the calibration with its message.
fn preflight(session: &Session, robot: &Robot, mut warn: impl FnMut(String)) -> anyhow::Result<()> {
    let report = check_session(session, robot, &CheckOptions { excitation: false });
    for f in report.of(Severity::Warning) {
        warn(format!("{} ({})", f.message, f.action));
    }
    fatal_findings(&report, &session.dir).map_err(|e| {
        anyhow::anyhow!(
            "{e}; `robimu check {}` lists every finding",
            session.dir.display()
        )
    })
}

/// The calibration options of `settings`: the session's σ (replaced by the
/// noise file's), `freeze`, `no_prior`, `knot_spacing`.
fn options(
    settings: &Settings,
    session: &Session,
    robot: &Robot,
    layout: &ParamLayout,
    file: Option<&NoiseFileArg>,
) -> anyhow::Result<CalibrateOptions> {
    let mut opts = CalibrateOptions::new(robot);
    (opts.sigma_z, opts.sigma_q) = session.noise(robot)?;
    if let Some(f) = file {
        if let Some(z) = f.file.noise.sigma_z {
            opts.sigma_z = z;
        }
        if let Some(q) = &f.file.noise.sigma_q {
            if q.len() != robot.dof() {
                bail!(
                    "{} {}: [noise] sigma_q has {} values but robot `{}` has {} joints",
                    f.flag,
                    f.path.display(),
                    q.len(),
                    robot.name(),
                    robot.dof()
                );
            }
            opts.sigma_q = q.clone();
        }
    }
    opts.frozen = layout
        .select(&settings.freeze)
        .map_err(|e| anyhow::anyhow!("--freeze: {e}"))?;
    opts.use_prior = !settings.no_prior;
    if let Some(h) = settings.knot_spacing {
        if !(h.is_finite() && h > 0.0) {
            bail!("--knot-spacing must be a positive number of seconds (got {h})");
        }
    }
    opts.knot_spacing = settings.knot_spacing;
    Ok(opts)
}

/// The `effects` set (`None` without effects: then the catalogue, and its
/// resonance response to the joint trajectory, is never set up).
fn effect_set_of(
    settings: &Settings,
    robot: &Robot,
    data: &Measurements,
) -> anyhow::Result<Option<EffectSet>> {
    let specs: Vec<&str> = settings
        .effects
        .iter()
        .map(|s| s.trim())
        .filter(|s| !s.is_empty())
        .collect();
    if specs.is_empty() {
        return Ok(None);
    }
    let mut setup = setup_with(robot, data, None, checked_mode(settings.resonance)?);
    let names = specs
        .iter()
        .map(|s| setup.apply_spec(s))
        .collect::<Result<Vec<_>, _>>()
        .context("--effects")?;
    Ok(Some(effect_set(&setup, &names).context("--effects")?))
}

/// The result record of `cal`, with the session's robot and path.
fn result_record(
    cal: &Calibration,
    layout: &ParamLayout,
    session: &Session,
    use_prior: bool,
) -> CalibrationResult {
    let dir = &session.dir;
    let mut result = cal.to_result(layout);
    result.robot = Some(session.meta.robot.clone());
    result.session = Some(
        std::path::absolute(dir)
            .unwrap_or_else(|_| dir.to_path_buf())
            .display()
            .to_string(),
    );
    result.priors_used = Some(use_prior);
    result
}
