//! Flags that several commands share, each group one clap struct that a
//! command flattens, and its conversion into the library's settings.

use std::path::PathBuf;

use robimu_model::effects::resonance::Mode;
use robimu_workflows::calibrate::noise_choice::{Settle, MAX_REFITS};
use robimu_workflows::pipeline::checked_mode;
use robimu_workflows::pipeline::noise_spec::NoiseFileArg;
use robimu_workflows::{ModelChoice, Settings};

/// The flags that set how a session is calibrated (`robimu calibrate`,
/// `robimu calibrate-batch`, docs/guide/calibrating.md).
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateFlags {
    /// Parameters to hold at their prior mean, comma-separated: `lengths`
    /// (the robot's length errors eps_i_1..3 of links i < n, not the IMU
    /// position) and/or parameter names (eps_2_4, tau, b_w_z, …).
    #[arg(long, value_delimiter = ',')]
    pub freeze: Vec<String>,
    /// Fit without the priors (fails when the data leaves some parameter
    /// combination undetermined).
    #[arg(long)]
    pub no_prior: bool,
    /// Knot spacing of the estimated trajectory spline, s [default: chosen
    /// from the data: halved from 1 s while the spline cannot follow the
    /// joint samples within their noise].
    #[arg(long)]
    pub knot_spacing: Option<f64>,
    /// Noise file whose `[noise]` table (session.toml's format, e.g. written
    /// by `robimu noise`) replaces the session's key by key: `sigma_z`,
    /// `sigma_q` replace the session's and the robot's σ, and `ar_z`,
    /// `motion_z` (when given) the session's noise model, which
    /// `--noise-model auto` then fits as given (docs/model.md §4.6, §7.2).
    #[arg(long, value_name = "FILE")]
    pub noise: Option<PathBuf>,
    /// Which model to fit: `select` (the paper's model, tested against every
    /// catalogue effect as `robimu diagnose` tests it; the effects the data
    /// show are added and the final model is the result) or `paper` (the
    /// paper's model alone; its tests still go into the verdict)
    /// (docs/model.md §8.6).
    #[arg(long, value_name = "select|paper", default_value = "select")]
    pub model: String,
    /// Fit exactly these catalogue effects with the paper's model, no
    /// search (comma-separated: g_sensitivity, size_effect, clock_drift,
    /// sensor_delay, bias_drift, joint_elasticity, encoder_scale,
    /// resonance, temperature_bias where imu.csv has a varying temp_c); the
    /// result is that model, its effects in result.json's `effects`, and
    /// effects.json (the fit's JSON) next to the result file.
    /// With several IMUs a per-sensor effect of IMU j ≥ 1 is `imu<j>/NAME`
    /// (docs/model.md §9). `bias_drift:M` sets its spline's M segments over the session (default
    /// 1, a linear drift; `robimu diagnose` chooses M and prints the spec).
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    /// The `resonance` effect's mode.
    #[command(flatten)]
    pub resonance: ResonanceMode,
    /// The IMU noise model: `auto` (white unless the residuals fail the
    /// whiteness test; then identified from them and refitted by
    /// generalised least squares; a `[noise]` table — the session's or
    /// `--noise`'s — that gives `ar_z`/`motion_z` is fitted with that
    /// model), `white` (the paper's model), or a noise FILE: the same as
    /// `--noise FILE`, with the resulting model (the file's keys over the
    /// session's) fitted as given even when it is white (docs/model.md
    /// §4.6, §7.2).
    #[arg(long, value_name = "white|auto|FILE", default_value = "auto")]
    pub noise_model: String,
    /// `--noise-model auto`: the most GLS refits while the identified model
    /// settles (at least 1).
    #[arg(long, value_name = "N", default_value_t = MAX_REFITS)]
    pub noise_refits: usize,
    /// `--noise-model auto`: the identified model has settled when, from one
    /// refit to the next, no AR coefficient moves by TOL or more and no σ or
    /// motion gain by TOL relative (0 never settles: the white result is
    /// kept with a warning) [default: 0.02].
    #[arg(long, value_name = "TOL")]
    pub noise_settle: Option<f64>,
    /// Calibrate IMU J of a multi-IMU session alone (docs/model.md §9; 0 is
    /// imu.csv, J ≥ 1 imu<J>.csv) as a one-IMU session: the result uses the
    /// one-IMU names (`tau`, `k_a_x`, … for IMU J's own parameters, without
    /// the `imu<J>/` prefix) and the truth is compared by those names.
    /// Without it every IMU of the session is calibrated jointly.
    #[arg(long, value_name = "J")]
    pub imu: Option<usize>,
}

impl Default for CalibrateFlags {
    /// `robimu calibrate`'s defaults.
    fn default() -> Self {
        Self {
            freeze: Vec::new(),
            no_prior: false,
            knot_spacing: None,
            noise: None,
            effects: Vec::new(),
            resonance: Default::default(),
            noise_model: "auto".into(),
            model: "select".into(),
            noise_refits: MAX_REFITS,
            noise_settle: None,
            imu: None,
        }
    }
}

impl CalibrateFlags {
    /// The library's settings of these flags (`--noise-refits` and
    /// `--noise-settle` checked; the resonance mode is checked where
    /// `--effects` uses it).
    pub fn settings(&self) -> anyhow::Result<Settings> {
        Ok(Settings {
            freeze: self.freeze.clone(),
            no_prior: self.no_prior,
            knot_spacing: self.knot_spacing,
            effects: self.effects.clone(),
            resonance: self.resonance.unchecked(),
            noise_model: self.noise_model.clone(),
            settle: self.settle()?,
            imu: self.imu,
            model: self.model_choice()?,
        })
    }

    /// `--model`, checked against `--effects`.
    fn model_choice(&self) -> anyhow::Result<ModelChoice> {
        let model = match self.model.trim() {
            "select" => ModelChoice::Select,
            "paper" => ModelChoice::Paper,
            other => anyhow::bail!("--model `{other}`: expected `select` or `paper`"),
        };
        let effects = self.effects.iter().any(|e| !e.trim().is_empty());
        if effects && model == ModelChoice::Paper {
            anyhow::bail!("--model paper and --effects contradict each other: --effects fits the paper's model with those effects");
        }
        Ok(model)
    }

    /// The noise file of `--noise FILE` or `--noise-model FILE`, read once:
    /// its flag, path, σ and model keys. Two different files are refused.
    pub fn noise_file(&self) -> anyhow::Result<Option<NoiseFileArg>> {
        NoiseFileArg::from_flags(self.noise.as_deref(), &self.noise_model)
    }

    /// `--noise-refits` and `--noise-settle`.
    fn settle(&self) -> anyhow::Result<Settle> {
        if self.noise_refits == 0 {
            anyhow::bail!("--noise-refits must be at least 1");
        }
        let mut settle = Settle {
            max_refits: self.noise_refits,
            ..Settle::default()
        };
        if let Some(tol) = self.noise_settle {
            if !(tol.is_finite() && tol >= 0.0) {
                anyhow::bail!("--noise-settle must be a number >= 0 (got {tol})");
            }
            (settle.phi, settle.sigma) = (tol, tol);
        }
        Ok(settle)
    }
}

/// The `resonance` effect's mode (`--resonance-hz`, `--resonance-zeta`).
#[derive(Debug, Clone, clap::Args)]
pub struct ResonanceMode {
    /// Natural frequency of the `resonance` effect's mode, Hz (0.5–50).
    #[arg(long, value_name = "HZ", default_value_t = 10.0)]
    pub resonance_hz: f64,
    /// Damping ratio of the `resonance` effect's mode (0–1, exclusive).
    #[arg(long, value_name = "ZETA", default_value_t = 0.05)]
    pub resonance_zeta: f64,
}

impl Default for ResonanceMode {
    fn default() -> Self {
        let m = Mode::default();
        Self {
            resonance_hz: m.f_hz,
            resonance_zeta: m.zeta,
        }
    }
}

impl ResonanceMode {
    /// The mode as given (checked where it is used).
    pub fn unchecked(&self) -> Mode {
        Mode {
            f_hz: self.resonance_hz,
            zeta: self.resonance_zeta,
        }
    }

    /// The checked mode.
    pub fn mode(&self) -> anyhow::Result<Mode> {
        checked_mode(self.unchecked())
    }
}

/// Base and tip link of a URDF robot (`--base`, `--tip`); `None`: the URDF's
/// root link, and its only leaf link.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct UrdfLinks {
    /// URDF robots: the base link of the chain [default: the root link].
    #[arg(long = "base", value_name = "LINK")]
    pub base: Option<String>,
    /// URDF robots: the tip (flange) link of the chain [default: the only leaf link].
    #[arg(long = "tip", value_name = "LINK")]
    pub tip: Option<String>,
}
