//! The diagnosis of one session as `robimu diagnose` runs it (docs/model.md
//! §7): the session and its settings checked, the baseline fit started from
//! a given calibration when asked, then [`crate::diagnose::diagnose`]; and
//! its diagnosis.json.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::effects::resonance::Mode;
use robimu_model::effects::{self, MassModel};
use robimu_model::observations::Measurements;
use robimu_model::ParamLayout;
use robimu_session::result::CalibrationResult;

use super::input::load_session;
use super::noise_spec::{noise_choice, NoiseFileArg};
use super::{checked_mode, PipelineError};
use crate::calibrate::{check_measurements, CalibrateOptions};
use crate::diagnose::{diagnose, setup_with, DiagnoseOptions, Diagnosis};

/// How a session is diagnosed: `robimu diagnose`'s flags, by the same names.
#[derive(Debug, Clone)]
pub struct DiagnoseSettings {
    /// A calibration result to start the baseline fit from.
    pub calibration: Option<PathBuf>,
    /// Output directory (created before the fits).
    pub out: PathBuf,
    /// Family-wise significance level (divided by the number of candidates).
    pub alpha: f64,
    /// Mass model TOML for joint elasticity (default: the built-in estimate).
    pub mass_model: Option<PathBuf>,
    /// Candidates to consider (empty: the whole catalogue).
    pub candidates: Vec<String>,
    /// The `resonance` effect's mode.
    pub resonance: Mode,
    /// The IMU noise model: `auto`, `white` or a noise file's path.
    pub noise_model: String,
}

impl DiagnoseSettings {
    /// `robimu diagnose`'s defaults, writing into `out`.
    pub fn new(out: PathBuf) -> Self {
        Self {
            calibration: None,
            out,
            alpha: 0.01,
            mass_model: None,
            candidates: Vec::new(),
            resonance: Mode::default(),
            noise_model: "auto".into(),
        }
    }
}

/// A finished diagnosis with what its files are drawn from.
pub struct Diagnosed {
    /// The diagnosis.
    pub diagnosis: Diagnosis,
    /// The session's measurements (every IMU).
    pub data: Measurements,
    /// The parameter layout of every IMU of the session.
    pub layout: ParamLayout,
}

impl Diagnosed {
    /// Writes OUT/diagnosis.json (format `robimu-diagnosis/1`); returns its path.
    pub fn write_json(&self, out_dir: &Path) -> Result<PathBuf, PipelineError> {
        let path = out_dir.join("diagnosis.json");
        (|| -> anyhow::Result<()> {
            let json = self.diagnosis.to_json(&self.layout);
            std::fs::write(&path, serde_json::to_string_pretty(&json)?)
                .with_context(|| format!("cannot write {}", path.display()))?;
            Ok(())
        })()
        .map_err(PipelineError::write)?;
        Ok(path)
    }
}

/// Diagnoses the session in `dir` with `settings`; `progress` sees each
/// stage's message.
pub fn diagnose_session(
    dir: &Path,
    settings: &DiagnoseSettings,
    progress: impl FnMut(&str),
) -> Result<Diagnosed, PipelineError> {
    let Start {
        robot,
        data,
        layout,
        opts,
        dopts,
        setup,
    } = prepare(dir, settings).map_err(PipelineError::input)?;
    let diagnosis = diagnose(&robot, &data, &opts, &setup, &dopts, progress)
        .with_context(|| format!("cannot diagnose the session {}", dir.display()))
        .map_err(PipelineError::fit)?;
    Ok(Diagnosed {
        diagnosis,
        data,
        layout,
    })
}

/// What a diagnosis starts from.
struct Start {
    robot: robimu_model::Robot,
    data: Measurements,
    layout: ParamLayout,
    opts: CalibrateOptions,
    dopts: DiagnoseOptions,
    setup: effects::CatalogueSetup,
}

/// The session and settings checked in the order `robimu diagnose` reports
/// them, the output directory created.
fn prepare(dir: &Path, settings: &DiagnoseSettings) -> anyhow::Result<Start> {
    let (session, robot) = load_session(dir)?;
    if !(settings.alpha > 0.0 && settings.alpha < 1.0) {
        bail!("--alpha must be in (0, 1) (got {})", settings.alpha);
    }
    let out_dir = &settings.out;
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create the output directory {}", out_dir.display()))?;
    let mut opts = CalibrateOptions::new(&robot);
    (opts.sigma_z, opts.sigma_q) = session.noise(&robot)?;
    let data = session.measurements();
    // every IMU of the session (docs/model.md §9)
    let layout = ParamLayout::with_imus(&robot, data.n_imus());
    check_measurements(&robot, &data)
        .with_context(|| format!("cannot diagnose the session {}", dir.display()))?;
    let mass = match &settings.mass_model {
        Some(p) => Some(MassModel::from_toml_file(&robot, p).context("--mass-model")?),
        None => None,
    };
    let setup = setup_with(&robot, &data, mass, checked_mode(settings.resonance)?);
    let file = NoiseFileArg::from_flags(None, &settings.noise_model)?;
    if let Some(z) = file.as_ref().and_then(|f| f.file.noise.sigma_z) {
        opts.sigma_z = z;
    }
    let noise = noise_choice(
        &settings.noise_model,
        &session,
        opts.sigma_z,
        data.imu_t.len(),
        file.as_ref(),
    )?;
    let mut dopts = DiagnoseOptions {
        alpha: settings.alpha,
        noise,
        ..DiagnoseOptions::default()
    };
    if !settings.candidates.is_empty() {
        for c in &settings.candidates {
            effects::by_name(&setup, c).context("--candidates")?;
        }
        dopts.candidates = settings.candidates.clone();
        dopts.max_effects = settings.candidates.len();
    }
    if let Some(path) = &settings.calibration {
        dopts.x_start = Some(start_from(path, &layout, robot.name())?);
    }
    Ok(Start {
        robot,
        data,
        layout,
        opts,
        dopts,
        setup,
    })
}

/// x of the calibration result at `path`, by the layout's names.
fn start_from(path: &Path, layout: &ParamLayout, robot: &str) -> anyhow::Result<Vec<f64>> {
    let result = CalibrationResult::read(path)
        .with_context(|| format!("--calibration {}", path.display()))?;
    let mut x = layout.nominal();
    for (k, spec) in layout.specs().iter().enumerate() {
        match result.parameter(&spec.name) {
            Some(p) => x[k] = p.value,
            None => bail!(
                "--calibration {}: parameter `{}` is missing (is it for robot `{robot}`?)",
                path.display(),
                spec.name,
            ),
        }
    }
    Ok(x)
}
