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
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::{CalibrationResult, EffectRecord};
use robimu_session::Session;
use robimu_solver::IterationRecord;

use robimu_model::effects::CatalogueSetup;
use robimu_session::result::{ModelTestsRecord, VerdictRecord};

use super::covariance_kind;
use super::model_choice::{effect_records, selection_tests, test_model, ModelChoice, MODEL_ALPHA};
use super::next_steps::next_steps;
use super::noise_spec::{noise_choice, NoiseFileArg};
use super::{checked_mode, fatal_findings, PipelineError};
use crate::calibrate::fit::Fit;
use crate::calibrate::noise_choice::{
    other_imu_identifications, residual_identification, NoiseChoice, NoiseOutcome, PaperFit,
    Settle, MAX_REFITS, REFIT_GRADIENT,
};
use crate::calibrate::{calibration_of, check_measurements, CalibrateOptions, Calibration};
use crate::check::{check_session, CheckOptions, Severity};
use crate::diagnose::{diagnose, effect_set, fit_json, identify_at, setup_with};
use crate::diagnose::{residual_stats, DiagnoseOptions, Diagnosis, ResidualStats};
use crate::noise_id::{IdOptions, Identification};
use crate::pose_accuracy::{pose_accuracy, Posterior};
use crate::repeatability::{self, check_windows, Repeatability, Window};
use crate::verdict::{self, VerdictInput};

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
    /// The model: the paper's, tested and extended by the effects the
    /// data show (default), or the paper's alone. `effects` fixes the set.
    pub model: ModelChoice,
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
            model: ModelChoice::default(),
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
    /// The catalogue's set-up for this session (the model's tests and
    /// effects).
    pub setup: CatalogueSetup,
    /// The labels of the `effects` set (empty without).
    pub effect_labels: Vec<String>,
    /// The model choice.
    pub model: ModelChoice,
    /// The noise model choice.
    pub choice: NoiseChoice,
    /// `auto`'s settling rule.
    pub settle: Settle,
}

/// What a calibration reports while it runs.
pub enum FitEvent<'a> {
    /// A solver iteration of the paper's model's fit.
    Iteration(&'a IterationRecord),
    /// A stage begins (the model's tests, the search for effects).
    Stage(&'a str),
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
    /// The fit of the model written (with its effects, residuals and
    /// trajectory).
    pub fit: Fit,
    /// The search that chose the model's effects, when it ran and added
    /// one, or the fit of a given `effects` set: the evidence.
    pub selection: Option<Diagnosis>,
    /// The written model's residual statistics (IMU 0), for the verdict's
    /// structure check.
    pub residual_stats: ResidualStats,
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
        let (setup, effect_labels) = effect_set_of(settings, &robot, &data)?;
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
            setup,
            effect_labels,
            model: settings.model,
            choice,
            settle: settings.settle,
        })
    }

    /// The calibration (docs/model.md §8.6): the paper's model with the
    /// noise choice (§4.6), tested against the catalogue's effects; with
    /// [`ModelChoice::Select`] and a significant one, the diagnosis's search
    /// adds what the data show and its final model is the result (a given
    /// `effects` set is fitted from the start instead). Then its verdict,
    /// pose accuracy and result file's contents (not written); `progress`
    /// sees each solver iteration and stage.
    pub fn fit(&self, mut progress: impl FnMut(FitEvent<'_>)) -> Result<Fitted, PipelineError> {
        if !self.effect_labels.is_empty() {
            let d = self.search(None, &mut progress)?;
            return self.fitted_with_effects(d, "given");
        }
        let mut iteration = |r: &IterationRecord| progress(FitEvent::Iteration(r));
        let start = PaperFit::start(
            &self.robot,
            &self.data,
            &self.opts,
            &self.choice,
            &mut iteration,
        )
        .with_context(|| self.cannot())
        .map_err(PipelineError::fit)?;
        let mut searched = None;
        if self.model == ModelChoice::Select {
            // the search's first round is the model's test (at its own
            // baseline, under the search's noise model); the paper's fit
            // is settled only when the search adds nothing
            progress(FitEvent::Stage(
                "testing the model and adding the effects the data show",
            ));
            let d = self.search(start.white().cloned(), &mut progress)?;
            if !d.found.is_empty() {
                return self.fitted_with_effects(d, "selected");
            }
            searched = Some(d);
        }
        let mut iteration = |r: &IterationRecord| progress(FitEvent::Iteration(r));
        let (cal, noise, fit, _) = start
            .settle(
                &self.robot,
                &self.data,
                &self.opts,
                &self.settle,
                &mut iteration,
            )
            .with_context(|| self.cannot())
            .map_err(PipelineError::fit)?;
        let (selection, reason) = match self.model {
            ModelChoice::Paper => (
                "paper",
                "not in the paper's model (--model paper): `robimu calibrate` without --model adds what the data show",
            ),
            ModelChoice::Select => (
                "selected",
                "significant at the paper's fit, but diagnose's search did not add it (`robimu diagnose` shows why)",
            ),
        };
        // the search's baseline is the paper's fit when both kept white
        // noise: its scores are the tests; else the tests at the paper's fit
        let tests = match searched.filter(|d| d.baseline.noise.is_white() && d.baseline.x == fit.x)
        {
            Some(d) => selection_tests(&d, selection),
            None => {
                progress(FitEvent::Stage(
                    "testing the model against the catalogue's effects",
                ));
                test_model(&self.robot, &self.data, &self.opts, &self.setup, &fit)
                    .with_context(|| format!("{}: the model's tests failed", self.cannot()))
                    .map_err(PipelineError::fit)?
                    .record(selection, reason)
            }
        };
        let effects = (self.model == ModelChoice::Select).then(Vec::new);
        Ok(self.fitted(cal, noise, fit, None, effects, tests))
    }

    /// "cannot calibrate the session DIR".
    fn cannot(&self) -> String {
        format!(
            "cannot calibrate the session {}",
            self.session.dir.display()
        )
    }

    /// The diagnosis's search for effects (docs/model.md §4.10) from the
    /// paper's model (`white`: its white fit, made already, with `auto`),
    /// or the fit of the given `effects` set and the tests of the others;
    /// without the residual statistics, which only diagnose reports.
    fn search(
        &self,
        white: Option<Fit>,
        progress: &mut impl FnMut(FitEvent<'_>),
    ) -> Result<Diagnosis, PipelineError> {
        let given = !self.effect_labels.is_empty();
        let dopts = DiagnoseOptions {
            alpha: MODEL_ALPHA,
            noise: self.choice.clone(),
            settle: self.settle,
            base_effects: self.effect_labels.clone(),
            white_start: white,
            residual_stats: false,
            max_effects: if given {
                0
            } else {
                DiagnoseOptions::default().max_effects
            },
            ..DiagnoseOptions::default()
        };
        // every fit of the search starts from a converged one (the white
        // fit, the previous model): it stops, as calibrate's GLS refits do,
        // when each parameter's remaining Newton step is below 1 % of its σ
        let mut opts = self.opts.clone();
        opts.lm.gradient_tolerance = opts.lm.gradient_tolerance.max(REFIT_GRADIENT);
        diagnose(&self.robot, &self.data, &opts, &self.setup, &dopts, |s| {
            progress(FitEvent::Stage(s))
        })
        .with_context(|| self.cannot())
        .map_err(PipelineError::fit)
    }

    /// The result of diagnose's final model `d` of this session (`robimu
    /// diagnose --report`): its verdict, pose accuracy and result record.
    pub fn fitted_from(&self, d: Diagnosis) -> Result<Fitted, PipelineError> {
        self.fitted_with_effects(d, "selected")
    }

    /// The result of the model `d` ended with (its effects added by the
    /// search, or given).
    fn fitted_with_effects(&self, d: Diagnosis, selection: &str) -> Result<Fitted, PipelineError> {
        let f = d.final_fit.clone();
        let opts = CalibrateOptions {
            noise: (!f.noise.is_white()).then(|| f.noise.clone()),
            ..self.opts.clone()
        };
        let mut cal = calibration_of(&self.robot, &opts, &f)
            .with_context(|| self.cannot())
            .map_err(PipelineError::fit)?;
        cal.tau_initial = d.baseline.tau_initial;
        let noise = self.final_noise(&d);
        let tests = selection_tests(&d, selection);
        let effects = effect_records(&f, &d.setup, Some(&d));
        Ok(self.fitted(cal, noise, f, Some(d), Some(effects), tests))
    }

    /// What the noise choice did for the final model of `d`: its raw
    /// residuals tested and identified as the search identifies them (AR
    /// order ≤ 1, docs/model.md §4.10), the model its fit used when not
    /// white, the search's warnings.
    fn final_noise(&self, d: &Diagnosis) -> NoiseOutcome {
        let ids = &DiagnoseOptions::default().noise_id;
        let f = &d.final_fit;
        let id = identify_at(&self.robot, &self.data, &self.opts, &d.setup, f, ids);
        let mut warnings = d.noise.warnings.clone();
        if let Err(e) = &id {
            warnings.push(format!(
                "the final model's residuals could not be tested ({e})"
            ));
        }
        let id = id.ok();
        NoiseOutcome {
            identified: id.clone().filter(|_| !f.noise.is_white()),
            white_test: id,
            extra_white_tests: Vec::new(),
            extra_identified: Vec::new(),
            refits: d.noise.reidentified_after.len(),
            warning: (!warnings.is_empty()).then(|| warnings.join("; ")),
        }
    }

    /// The verdict, pose accuracy and result record of `cal` (the fit of
    /// the model written: `fit`, chosen by `selection` when it has
    /// effects), `effects` its effects (`None`: `--model paper`), `tests`
    /// its tests. With effects the whiteness identification, which does not
    /// take effects into account, is left out (the final model's own test
    /// is `noise.white_test`).
    fn fitted(
        &self,
        mut cal: Calibration,
        noise: NoiseOutcome,
        fit: Fit,
        selection: Option<Diagnosis>,
        effects: Option<Vec<EffectRecord>>,
        tests: ModelTestsRecord,
    ) -> Fitted {
        let paper = selection.is_none();
        let whiteness = (paper && self.choice != NoiseChoice::Auto)
            .then(|| {
                residual_identification(&self.robot, &self.data, &cal, &IdOptions::default()).ok()
            })
            .flatten();
        // (with effects, their signal is in these residuals too: an IMU
        // whose residuals look correlated is named, never missed)
        let other_imus: Vec<(usize, Identification)> =
            other_imu_identifications(&self.robot, &self.data, &cal, &IdOptions::default())
                .into_iter()
                .filter_map(|(j, id)| id.ok().map(|id| (j, id)))
                .collect();
        let setup = selection.as_ref().map_or(&self.setup, |d| &d.setup);
        let stats = residual_stats(&self.robot, &self.data, setup, &fit);
        let mut verdict = self.verdict(VerdictInput {
            robot: &self.robot,
            calibration: &cal,
            noise: Some(&noise),
            whiteness: whiteness.as_ref(),
            repeatability: None,
            other_imus: &other_imus,
            model_tests: Some(&tests),
            residual_stats: Some(&stats),
            effects: effects.as_deref(),
        });
        // a model the structure check finds inadequate: its σ widened to
        // the sandwich of the written fit (docs/model.md §4.6, §8.5);
        // `--model paper` writes the paper's fit as it is
        let kind = match self.model {
            ModelChoice::Paper if effects.is_none() => None,
            _ => covariance_kind::widen(
                (&self.robot, &self.data, &self.opts),
                setup,
                &fit,
                &mut verdict,
                &mut cal,
            ),
        };
        let mut result = result_record(&cal, &self.layout, &self.session, self.opts.use_prior);
        result.covariance_kind = kind;
        result.noise_warning = noise.warning.clone();
        result.verdict = Some(verdict);
        result.effects = effects;
        result.model_tests = Some(tests);
        result.pose_accuracy = Some(self.pose_accuracy(&cal));
        Fitted {
            cal,
            noise,
            result,
            whiteness,
            other_imus,
            fit,
            selection,
            residual_stats: stats,
        }
    }

    /// The pose accuracy of `cal` (against the session's truth when it has one).
    fn pose_accuracy(&self, cal: &Calibration) -> robimu_session::result::PoseAccuracyRecord {
        let truth = self
            .session
            .truth
            .as_ref()
            .and_then(|t| t.vector(&self.layout).ok());
        let posterior = Posterior {
            x: &cal.x,
            sigma: &cal.sigma,
            active: &cal.active,
            covariance: &cal.covariance,
        };
        pose_accuracy(&self.robot, &self.layout, &posterior, truth.as_deref())
    }

    /// effects.json (the fit's JSON, as diagnosis.json's final model) next
    /// to the result file `path` when an `effects` set was given; returns
    /// its path.
    pub fn write_effects(
        &self,
        fitted: &Fitted,
        path: &Path,
    ) -> Result<Option<PathBuf>, PipelineError> {
        if self.effect_labels.is_empty() {
            return Ok(None);
        }
        let f = &fitted.fit;
        let epath = path.with_file_name("effects.json");
        let json = fit_json(&ParamLayout::with_imus(&self.robot, f.n_imus), f);
        let text =
            serde_json::to_string_pretty(&json).map_err(|e| PipelineError::write(e.into()))?;
        std::fs::write(&epath, text)
            .with_context(|| format!("cannot write {}", epath.display()))
            .map_err(PipelineError::write)?;
        Ok(Some(epath))
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
        full: &Fitted,
        windows: Vec<Window>,
        report: impl FnMut(usize, &IterationRecord),
    ) -> Result<(Repeatability, CalibrationResult), PipelineError> {
        let count = windows.len();
        let results = repeatability::calibrate_windows(&self.robot, windows, &self.opts, report)
            .with_context(|| format!("--windows {count}: {}", self.session.dir.display()))
            .map_err(PipelineError::fit)?;
        let study =
            repeatability::compare(&ParamLayout::new(&self.robot), full.cal.clone(), results);
        let mut result = full.result.clone();
        result.verdict = Some(self.verdict(VerdictInput {
            robot: &self.robot,
            calibration: &study.full,
            noise: Some(&full.noise),
            whiteness: full.whiteness.as_ref(),
            repeatability: Some(&study),
            other_imus: &full.other_imus,
            model_tests: full.result.model_tests.as_ref(),
            residual_stats: Some(&full.residual_stats),
            effects: full.result.effects.as_deref(),
        }));
        Ok((study, result))
    }

    /// The verdict on `input` (docs/model.md §8.5), with the next steps
    /// its checks call for when the model's tests were run.
    fn verdict(&self, input: VerdictInput<'_>) -> VerdictRecord {
        let mut verdict = verdict::verdict(&input);
        if let Some(tests) = input.model_tests {
            let names: Vec<String> = input
                .effects
                .unwrap_or_default()
                .iter()
                .map(|e| e.name.clone())
                .collect();
            verdict.next_steps = next_steps(&verdict, &self.session, tests, &names);
        }
        verdict
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

/// The catalogue's set-up for the session (the resonance mode checked
/// when `effects` are given) and the labels of the `effects` set (empty
/// without), checked to make a set the model can hold.
fn effect_set_of(
    settings: &Settings,
    robot: &Robot,
    data: &Measurements,
) -> anyhow::Result<(CatalogueSetup, Vec<String>)> {
    let specs: Vec<&str> = settings
        .effects
        .iter()
        .map(|s| s.trim())
        .filter(|s| !s.is_empty())
        .collect();
    let mode = match specs.is_empty() {
        true => settings.resonance,
        false => checked_mode(settings.resonance)?,
    };
    let mut setup = setup_with(robot, data, None, mode);
    if specs.is_empty() {
        return Ok((setup, Vec::new()));
    }
    let names = specs
        .iter()
        .map(|s| setup.apply_spec(s))
        .collect::<Result<Vec<_>, _>>()
        .context("--effects")?;
    // the set must be one the model can hold (each effect once, …)
    effect_set(&setup, &names).context("--effects")?;
    Ok((setup, names))
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
