//! The calibration result file (docs/model.md §8), `result.json`:
//!
//! ```json
//! {
//!   "format": "robimu-result/1",
//!   "parameters": [
//!     {"name": "eps_1_1", "unit": "m", "value": 0.0, "prior": 0.0,
//!      "prior_sigma": 0.001, "sigma": 0.0, "frozen": false}
//!   ],
//!   "covariance": {"names": ["eps_1_1", "..."], "matrix": [[0.0]]}
//! }
//! ```
//!
//! Every parameter of x is listed by its §5 name in x order, in SI units, with
//! its estimate, prior mean and σ, and posterior σ (√diag of the marginal
//! covariance, eq. (24); 0 when frozen). `covariance` covers the estimated
//! parameters. The keys after these are this program's extras (solver run,
//! residuals, weak directions); readers ignore keys they do not know, and
//! [`CalibrationResult::parse`] accepts files without the extras.

use std::path::{Path, PathBuf};

use robimu_model::ParamLayout;
use serde::{Deserialize, Serialize};

pub use crate::result_model::{
    ActualPoseErrors, EffectEvidence, EffectParameterRecord, EffectRecord, ModelTestsRecord,
    PoseAccuracyRecord, PoseErrorStats, SignificantEffect,
};

/// The format string this version reads and writes.
pub const RESULT_FORMAT: &str = "robimu-result/1";

/// One parameter of x (SI units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterResult {
    /// docs/model.md §5 name.
    pub name: String,
    /// Unit string (`m`, `rad`, `m/s^2`, `s`, `1`, `rad/s`).
    pub unit: String,
    /// Estimate (the nominal value when frozen).
    pub value: f64,
    /// Prior mean x̂.
    pub prior: f64,
    /// Prior standard deviation.
    pub prior_sigma: f64,
    /// Posterior standard deviation (0 when frozen).
    pub sigma: f64,
    /// Held at its prior mean, not estimated.
    pub frozen: bool,
}

/// Marginal posterior covariance of the estimated parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CovarianceMatrix {
    /// Row and column names.
    pub names: Vec<String>,
    /// Rows, SI units.
    pub matrix: Vec<Vec<f64>>,
}

/// One parameter's share of a weak direction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DirectionShare {
    /// Parameter name.
    pub name: String,
    /// Squared component of the unit direction (the shares sum to at most 1).
    pub share: f64,
}

/// A parameter combination the data barely determines
/// (`robimu_workflows::calibrate::WeakDirection`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeakDirectionRecord {
    /// Data information along it relative to the prior's (0 = none).
    pub relative_information: f64,
    /// The parameters that make it up, largest share first.
    pub parameters: Vec<DirectionShare>,
}

/// The contents of `result.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationResult {
    /// Always [`RESULT_FORMAT`].
    pub format: String,
    /// Every parameter of x, in x order.
    pub parameters: Vec<ParameterResult>,
    /// Covariance of the estimated parameters.
    pub covariance: CovarianceMatrix,
    /// Robot name or description path, as the session names it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<String>,
    /// The session's source when it is not joint angles: `"poses"` for a
    /// session with tool poses (docs/model.md §7.9; robimu extension, absent
    /// for a joint session).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Session directory the result was computed from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub session: Option<String>,
    /// Whether the priors were used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub priors_used: Option<bool>,
    /// τ found from the data before the fit, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tau_initial: Option<f64>,
    /// Knot spacing of the estimated trajectory spline, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub knot_spacing: Option<f64>,
    /// Solver iterations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// MAP cost J at the start of the fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_cost: Option<f64>,
    /// MAP cost J at the optimum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_cost: Option<f64>,
    /// Why the solver stopped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub termination: Option<String>,
    /// RMS of the whitened IMU residuals per channel `[ax, ay, az, gx, gy, gz]`
    /// (about 1 when the noise model fits).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "robimu_model::arity::option"
    )]
    pub residual_rms: Option<[f64; 6]>,
    /// IMU samples used in the fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu_samples_used: Option<usize>,
    /// Parameter combinations the data barely determines.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub weak_directions: Vec<WeakDirectionRecord>,
    /// The IMU noise model the fit used (robimu extension, docs/model.md
    /// §4.6; absent in files from other tools or older versions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_model: Option<NoiseModelRecord>,
    /// The noise model the fit used for each IMU j ≥ 1 of a multi-IMU
    /// session, in IMU order (`noise_model` is IMU 0's; docs/model.md §8.2,
    /// §9; robimu extension, absent for one IMU).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub imu_noise_models: Vec<ImuNoiseModelRecord>,
    /// Why the fit kept `noise_model` although the residuals say otherwise
    /// (e.g. an identified model that did not settle; robimu extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_warning: Option<String>,
    /// Whether to trust the result: the verdict `calibrate` prints first
    /// (robimu extension, docs/model.md §8.2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub verdict: Option<VerdictRecord>,
    /// The catalogue effects in the fitted model besides the paper's
    /// (docs/model.md §8.6): empty when the tests kept the paper's model,
    /// absent with `--model paper` (robimu extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effects: Option<Vec<EffectRecord>>,
    /// The tests the written model passed or failed (robimu extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_tests: Option<ModelTestsRecord>,
    /// The flange pose accuracy before and after (docs/model.md §8.7;
    /// robimu extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose_accuracy: Option<PoseAccuracyRecord>,
    /// Which covariance `covariance` is when it is not the model's A⁻¹:
    /// the sandwich of a fit whose model the verdict found inadequate
    /// (docs/model.md §4.6, §8.5; robimu extension, absent for A⁻¹).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance_kind: Option<CovarianceKindRecord>,
}

/// The reported covariance widened to the sandwich A⁻¹BA⁻¹ of the written
/// fit (docs/model.md §4.6 *Sandwich of the written fit*).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CovarianceKindRecord {
    /// `"sandwich"`.
    pub kind: String,
    /// The verdict's check that found the model inadequate.
    pub reason: String,
    /// The score windows' length, s.
    pub window_s: f64,
    /// The Bartlett kernel's lags, in windows.
    pub lags: usize,
    /// Per estimated parameter, the factor its σ was multiplied by:
    /// max(1, sandwich σ / the model's σ).
    pub inflation: Vec<InflationRecord>,
}

/// One parameter's σ inflation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InflationRecord {
    /// Parameter name.
    pub name: String,
    /// σ factor (≥ 1).
    pub factor: f64,
}

/// How far a calibration can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Trust {
    /// Every check passed.
    Good,
    /// A check failed that makes the estimates or their σ questionable.
    Doubtful,
    /// The fit did not converge.
    Bad,
}

impl std::fmt::Display for Trust {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(match self {
            Trust::Good => "good",
            Trust::Doubtful => "doubtful",
            Trust::Bad => "bad",
        })
    }
}

/// The verdict on a calibration: one line per check, the trust and the
/// failed checks' reasons.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerdictRecord {
    /// The overall trust.
    pub trust: Trust,
    /// Why not good (empty when good).
    pub reasons: Vec<String>,
    /// Every check, in order.
    pub checks: Vec<VerdictCheck>,
    /// What to do next when the trust is not good: commands to paste.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub next_steps: Vec<String>,
}

/// One check of a [`VerdictRecord`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerdictCheck {
    /// What was checked (`converged`, `residuals`, `undetermined`, `plausible`, `repeatability`).
    pub topic: String,
    /// Whether it passed.
    pub ok: bool,
    /// What was found, with the numbers.
    pub text: String,
}

/// The IMU noise model of a fit, as written to result.json:
/// `{"kind": "white"}` (σ_z alone, the paper's model) or
/// `{"kind": "ar", "channels": [{"phi": [..], "sigma": .., "motion": ..}; 6]}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum NoiseModelRecord {
    /// White noise of constant level.
    White,
    /// Per channel `[ax, ay, az, gx, gy, gz]`: AR coefficients, marginal σ
    /// and motion gain.
    Ar {
        /// The six channels.
        channels: Vec<ChannelNoiseRecord>,
    },
}

/// The noise model of one IMU j ≥ 1 in result.json: `{"imu": "imu<j>",
/// "noise_model": {..}}`, `imu` the prefix of the IMU's parameter names
/// (docs/model.md §9).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImuNoiseModelRecord {
    /// The IMU's parameter-name prefix, `imu1`, `imu2`, ….
    pub imu: String,
    /// Its noise model, as [`CalibrationResult::noise_model`].
    pub noise_model: NoiseModelRecord,
}

/// One channel of [`NoiseModelRecord::Ar`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelNoiseRecord {
    /// AR coefficients φ_1…φ_p (empty: white).
    pub phi: Vec<f64>,
    /// Marginal σ at rest, in the channel's unit.
    pub sigma: f64,
    /// Motion gain c of σ²(t) = σ² + c‖q̈‖².
    pub motion: f64,
}

/// Why a result file could not be read, written or trusted.
#[derive(Debug, thiserror::Error)]
pub enum ResultError {
    /// The file could not be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The text is not JSON of the documented shape.
    #[error("{}:{line}:{column}: {message}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// The contents break the contract (docs/model.md §8).
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// A result without a parameter of the layout it is read for.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("the result has no parameter `{0}`: it was not computed for this robot")]
pub struct MissingParameter(pub String);

impl CalibrationResult {
    /// What `target` (an export format, a correction) cannot carry of
    /// this result: the catalogue effects of its model (docs/model.md
    /// §8.6), or `None` when it has none.
    pub fn effects_not_carried(&self, target: &str) -> Option<String> {
        let names: Vec<&str> = self
            .effects
            .iter()
            .flatten()
            .map(|e| e.name.as_str())
            .collect();
        (!names.is_empty()).then(|| {
            format!(
                "the calibration's model includes {} beyond the paper's, which {target} cannot carry: the parameters written were fitted with {}, but a reader of it gets the paper's model alone (result.json's `effects` has their parameters and σ)",
                names.join(", "),
                if names.len() == 1 { "it" } else { "them" }
            )
        })
    }

    /// x in `layout` order, every parameter taken by name.
    pub fn values(&self, layout: &ParamLayout) -> Result<Vec<f64>, MissingParameter> {
        layout
            .specs()
            .iter()
            .map(|s| {
                self.parameter(&s.name)
                    .map(|p| p.value)
                    .ok_or_else(|| MissingParameter(s.name.clone()))
            })
            .collect()
    }

    /// Indices in `layout` of the parameters the result held frozen.
    pub fn frozen(&self, layout: &ParamLayout) -> Vec<usize> {
        self.parameters
            .iter()
            .filter(|p| p.frozen)
            .filter_map(|p| layout.index_of(&p.name))
            .collect()
    }

    /// Index of parameter `name` in [`parameters`](Self::parameters).
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.parameters.iter().position(|p| p.name == name)
    }

    /// The parameter called `name`.
    pub fn parameter(&self, name: &str) -> Option<&ParameterResult> {
        self.parameters.iter().find(|p| p.name == name)
    }

    /// Covariance between two estimated parameters, by name.
    pub fn covariance_between(&self, a: &str, b: &str) -> Option<f64> {
        let names = &self.covariance.names;
        let i = names.iter().position(|n| n == a)?;
        let j = names.iter().position(|n| n == b)?;
        Some(self.covariance.matrix[i][j])
    }

    /// Check the contract of docs/model.md §8: the format string, finite numbers,
    /// unique names, and a square, symmetric covariance over exactly the
    /// estimated parameters whose diagonal gives their `sigma`; the
    /// parameters of every IMU complete (docs/model.md §9, [`Self::imu_sets`]).
    pub fn validate(&self) -> Result<(), String> {
        if self.format != RESULT_FORMAT {
            return Err(format!(
                "format is `{}`, this version reads `{RESULT_FORMAT}`",
                self.format
            ));
        }
        self.validate_parameters()?;
        self.validate_covariance()?;
        self.imu_sets()?;
        Ok(())
    }

    /// Each parameter: a unique name, finite numbers within ±[`MAX_MAGNITUDE`],
    /// standard deviations ≥ 0 (prior σ > 0), gains within [`GAIN_RANGE`].
    fn validate_parameters(&self) -> Result<(), String> {
        if self.parameters.is_empty() {
            return Err("`parameters` is empty".into());
        }
        for (i, p) in self.parameters.iter().enumerate() {
            if p.name.is_empty() {
                return Err(format!("parameter {} has an empty name", i + 1));
            }
            if self.parameters[..i].iter().any(|q| q.name == p.name) {
                return Err(format!("parameter `{}` is listed twice", p.name));
            }
            let numbers = [
                ("value", p.value),
                ("prior", p.prior),
                ("prior_sigma", p.prior_sigma),
                ("sigma", p.sigma),
            ];
            for (field, v) in numbers {
                if !v.is_finite() {
                    return Err(format!("`{}`: {field} = {v} is not finite", p.name));
                }
                if v.abs() > MAX_MAGNITUDE {
                    return Err(format!(
                        "`{}`: {field} = {v:e} is beyond ±{MAX_MAGNITUDE:e}, which no parameter \
                         (m, rad, s, scale factor, m/s², rad/s) can be",
                        p.name
                    ));
                }
            }
            if p.sigma < 0.0 || p.prior_sigma < 0.0 {
                return Err(format!(
                    "`{}`: standard deviations must not be negative",
                    p.name
                ));
            }
            if p.prior_sigma == 0.0 {
                return Err(format!(
                    "`{}`: prior_sigma = 0: a prior σ must be > 0 (a frozen parameter is \
                     marked `frozen`)",
                    p.name
                ));
            }
            let base = split_imu_name(&p.name).map_or(p.name.as_str(), |(_, b)| b);
            if base.starts_with("k_") && !(GAIN_RANGE.0..=GAIN_RANGE.1).contains(&p.value) {
                return Err(format!(
                    "`{}`: gain {:e} is outside [{}, {}] (a sensor's scale factor is within a \
                     few % of 1)",
                    p.name, p.value, GAIN_RANGE.0, GAIN_RANGE.1
                ));
            }
        }
        Ok(())
    }

    /// The covariance: one unique row and column per estimated parameter,
    /// finite, symmetric, its diagonal the parameters' σ².
    fn validate_covariance(&self) -> Result<(), String> {
        let estimated: Vec<&ParameterResult> =
            self.parameters.iter().filter(|p| !p.frozen).collect();
        let cov = &self.covariance;
        let n = cov.names.len();
        if n != estimated.len() {
            return Err(format!(
                "covariance has {n} names but {} parameters are estimated (not frozen)",
                estimated.len()
            ));
        }
        if cov.matrix.len() != n {
            return Err(format!(
                "covariance matrix has {} rows for {n} names",
                cov.matrix.len()
            ));
        }
        for (i, row) in cov.matrix.iter().enumerate() {
            if row.len() != n {
                return Err(format!(
                    "covariance row {} (`{}`) has {} entries, expected {n}",
                    i + 1,
                    cov.names[i],
                    row.len()
                ));
            }
            if let Some(v) = row.iter().find(|v| !v.is_finite()) {
                return Err(format!(
                    "covariance row `{}` has a non-finite entry {v}",
                    cov.names[i]
                ));
            }
        }
        for (i, name) in cov.names.iter().enumerate() {
            if cov.names[..i].contains(name) {
                return Err(format!("covariance lists `{name}` twice"));
            }
            let Some(p) = estimated.iter().find(|p| &p.name == name) else {
                return Err(format!(
                    "covariance names `{name}`, which is not an estimated parameter"
                ));
            };
            let var = cov.matrix[i][i];
            if var < 0.0 {
                return Err(format!("covariance: variance of `{name}` is negative"));
            }
            let sd = var.sqrt();
            if (p.sigma - sd).abs() > 1e-4 * sd.max(p.sigma) + f64::MIN_POSITIVE {
                return Err(format!(
                    "`{name}`: sigma = {} but the covariance diagonal gives {sd}",
                    p.sigma
                ));
            }
            for j in 0..i {
                let (a, b) = (cov.matrix[i][j], cov.matrix[j][i]);
                let scale = (cov.matrix[i][i] * cov.matrix[j][j]).sqrt();
                if (a - b).abs() > 1e-9 * scale + f64::MIN_POSITIVE {
                    return Err(format!(
                        "covariance is not symmetric: ({name}, {}) = {a} but ({}, {name}) = {b}",
                        cov.names[j], cov.names[j]
                    ));
                }
            }
        }
        Ok(())
    }

    /// Pretty-printed JSON text.
    ///
    /// # Errors
    /// If the result breaks the contract ([`validate`](Self::validate)).
    pub fn to_json(&self) -> Result<String, String> {
        self.validate()?;
        serde_json::to_string_pretty(self).map_err(|e| e.to_string())
    }

    /// Validate and write to `path`.
    pub fn write(&self, path: &Path) -> Result<(), ResultError> {
        let text = self.to_json().map_err(|message| ResultError::Invalid {
            path: path.to_path_buf(),
            message,
        })?;
        std::fs::write(path, text + "\n").map_err(|source| ResultError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Read and validate `path` (text that is not UTF-8 is refused at its
    /// line, column and byte offset).
    pub fn read(path: &Path) -> Result<Self, ResultError> {
        let bytes = std::fs::read(path).map_err(|source| ResultError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let text = crate::text::utf8(&bytes).map_err(|e| ResultError::Json {
            path: path.to_path_buf(),
            line: e.line,
            column: e.column,
            message: e.to_string(),
        })?;
        Self::parse(text, path)
    }

    /// Parse and validate; `path` only names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ResultError> {
        let result: Self = serde_json::from_str(text).map_err(|e| ResultError::Json {
            path: path.to_path_buf(),
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        result.validate().map_err(|message| ResultError::Invalid {
            path: path.to_path_buf(),
            message,
        })?;
        Ok(result)
    }
}

/// The largest magnitude a parameter's value, prior or σ may have.
pub(crate) const MAX_MAGNITUDE: f64 = 1e6;
/// The range of a sensor gain (`k_*`, a scale factor near 1).
pub(crate) const GAIN_RANGE: (f64, f64) = (0.1, 10.0);

/// The parameters each IMU has (docs/model.md §9): its flange position
/// `eps_<n>_1..3` (`imu_link` = n, the last link), `tau` and the 24 sensor
/// parameters, by their §5 names in x order.
pub(crate) fn imu_base_names(imu_link: usize) -> Vec<String> {
    let mut names: Vec<String> = (1..=3).map(|k| format!("eps_{imu_link}_{k}")).collect();
    names.push("tau".into());
    for s in ["a", "w"] {
        for (block, axes) in [
            ("gamma", ["yz", "zy", "zx"]),
            ("r", ["z", "y", "x"]),
            ("k", ["x", "y", "z"]),
            ("b", ["x", "y", "z"]),
        ] {
            names.extend(axes.iter().map(|a| format!("{block}_{s}_{a}")));
        }
    }
    names
}

/// The name of parameter `base` (a §5 name) of IMU `j`: `base` itself for
/// IMU 0, `imu<j>/base` for j ≥ 1 (docs/model.md §9).
pub(crate) fn imu_parameter_name(j: usize, base: &str) -> String {
    if j == 0 {
        base.to_string()
    } else {
        format!("imu{j}/{base}")
    }
}

/// `imu<j>/base` as `(j, base)`; `None` for a name without an IMU prefix.
/// `j` is whatever digits follow `imu` (0 and zero-padded numbers
/// included, so that [`CalibrationResult::imu_sets`] can refuse them).
pub fn split_imu_name(name: &str) -> Option<(&str, &str)> {
    let (prefix, base) = name.split_once('/')?;
    let digits = prefix.strip_prefix("imu")?;
    (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())).then_some((digits, base))
}

/// `eps_<i>_<k>` as (i, k).
fn eps_indices(name: &str) -> Option<(usize, usize)> {
    let (i, k) = name.strip_prefix("eps_")?.split_once('_')?;
    Some((i.parse().ok()?, k.parse().ok()?))
}

/// Which parameters of a result are shared and which belong to which IMU
/// (docs/model.md §9), as indices into [`CalibrationResult::parameters`] in
/// file order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ImuSets {
    /// The robot errors other than the IMU position, g_x, g_y, and any
    /// other parameter of no IMU.
    pub shared: Vec<usize>,
    /// `imus[j]`: IMU j's parameters (IMU 0's under their §5 names, IMU
    /// j ≥ 1's as `imu<j>/…`); one entry for a one-IMU result.
    pub imus: Vec<Vec<usize>>,
    /// The last link n, whose `eps_n_1..3` are an IMU's position (0 when
    /// the result has no robot errors).
    pub imu_link: usize,
}

impl ImuSets {
    /// The number of IMUs K.
    pub fn len(&self) -> usize {
        self.imus.len()
    }

    /// Never: a result has at least IMU 0.
    pub fn is_empty(&self) -> bool {
        self.imus.is_empty()
    }
}

impl CalibrationResult {
    /// The shared parameters and each IMU's (docs/model.md §9), from the
    /// names alone: a name `imu<j>/X` is IMU j's; an unprefixed name is
    /// IMU 0's when it is one of the 28 of [`imu_base_names`] (of a pose
    /// session's result, docs/model.md §7.9: `p_imu_x`, `p_imu_y`,
    /// `p_imu_z` for the position) or some IMU j ≥ 1 has `imu<j>/` of it (an
    /// effect fitted per IMU), else shared.
    ///
    /// # Errors
    /// Names the cause when the IMUs are not numbered 1, 2, … without a
    /// gap, when an `imu<j>/` name is of a shared parameter, or when an IMU
    /// lacks one of the 28 parameters another IMU has.
    pub fn imu_sets(&self) -> Result<ImuSets, String> {
        let imu_link = self
            .parameters
            .iter()
            .filter_map(|p| {
                let base = split_imu_name(&p.name).map_or(p.name.as_str(), |(_, b)| b);
                eps_indices(base).map(|(i, _)| i)
            })
            .max()
            .unwrap_or(0);
        let mut own = imu_base_names(imu_link);
        if self.parameters.iter().any(|p| p.name == "p_imu_x") {
            own.splice(0..3, ["p_imu_x", "p_imu_y", "p_imu_z"].map(String::from));
        }
        let is_shared_base = |base: &str| match eps_indices(base) {
            Some((i, k)) => !(i == imu_link && k <= 3),
            None => base == "g_x" || base == "g_y",
        };
        // (j, base) of every prefixed name
        let mut prefixed: Vec<(usize, usize, &str)> = Vec::new();
        for (idx, p) in self.parameters.iter().enumerate() {
            let Some((digits, base)) = split_imu_name(&p.name) else {
                continue;
            };
            let j: usize = digits
                .parse()
                .map_err(|_| format!("`{}`: IMU number {digits} is too large", p.name))?;
            if j == 0 || digits.starts_with('0') {
                return Err(format!(
                    "`{}`: IMU 0 keeps the plain names and IMU j ≥ 1 is `imu<j>/` with j unpadded (docs/model.md §9)",
                    p.name
                ));
            }
            if base.is_empty() || is_shared_base(base) {
                return Err(format!(
                    "`{}`: `{base}` is shared by all IMUs and has no per-IMU copy (docs/model.md §9)",
                    p.name
                ));
            }
            prefixed.push((idx, j, base));
        }
        let k = 1 + prefixed.iter().map(|&(_, j, _)| j).max().unwrap_or(0);
        for j in 1..k {
            if !prefixed.iter().any(|&(_, i, _)| i == j) {
                let next = (j + 1..k)
                    .find(|i| prefixed.iter().any(|&(_, x, _)| x == *i))
                    .unwrap_or(k - 1);
                return Err(format!(
                    "the result has `imu{next}/` parameters but none of IMU {j} (`imu{j}/…`): IMUs are numbered 1, 2, … without a gap (docs/model.md §9)"
                ));
            }
        }
        let per_imu_effect =
            |name: &str| k > 1 && prefixed.iter().any(|&(_, _, base)| base == name);
        let mut sets = ImuSets {
            shared: Vec::new(),
            imus: vec![Vec::new(); k],
            imu_link,
        };
        for (idx, p) in self.parameters.iter().enumerate() {
            if let Some(&(_, j, _)) = prefixed.iter().find(|&&(i, _, _)| i == idx) {
                sets.imus[j].push(idx);
            } else if own.contains(&p.name) || per_imu_effect(&p.name) {
                sets.imus[0].push(idx);
            } else {
                sets.shared.push(idx);
            }
        }
        if k > 1 {
            // every IMU has each of the 28 that any IMU has
            let base_of = |idx: usize| {
                let n = &self.parameters[idx].name;
                split_imu_name(n).map_or(n.as_str(), |(_, b)| b)
            };
            let wanted: Vec<&String> = own
                .iter()
                .filter(|b| {
                    sets.imus
                        .iter()
                        .flatten()
                        .any(|&i| base_of(i) == b.as_str())
                })
                .collect();
            for (j, set) in sets.imus.iter().enumerate() {
                let missing: Vec<String> = wanted
                    .iter()
                    .filter(|b| !set.iter().any(|&i| base_of(i) == b.as_str()))
                    .map(|b| format!("`{}`", imu_parameter_name(j, b)))
                    .collect();
                if !missing.is_empty() {
                    return Err(format!(
                        "IMU {j} of {k} lacks {} (every IMU has the same {} parameters: position, tau and the 24 sensor parameters, docs/model.md §9)",
                        missing.join(", "),
                        wanted.len()
                    ));
                }
            }
        }
        Ok(sets)
    }

    /// The noise model the fit used for IMU `j` (docs/model.md §8.2, §9):
    /// IMU 0's `noise_model`, IMU j ≥ 1's entry `imu<j>` of
    /// `imu_noise_models` (a file without one: `noise_model`, the one model
    /// every IMU had before each had its own).
    pub fn noise_model_of(&self, j: usize) -> Option<&NoiseModelRecord> {
        let own = format!("imu{j}");
        self.imu_noise_models
            .iter()
            .find(|r| j > 0 && r.imu == own)
            .map(|r| &r.noise_model)
            .or(self.noise_model.as_ref())
    }

    /// The number of IMUs K of the result (1 when it has no `imu<j>/`
    /// names, or when they are not a valid set).
    pub fn imu_count(&self) -> usize {
        self.imu_sets().map_or(1, |s| s.len())
    }

    /// IMU `j` of a (multi-IMU) result as a one-IMU result: the shared
    /// parameters, and IMU j's under their §5 names in place of IMU 0's
    /// (IMU 0's own effects left out for j ≥ 1), with the covariance of
    /// those. Every reader of one-IMU results (exports, corrections, the
    /// report's residuals) reads IMU j through it. For j ≥ 1 the extras of
    /// IMU 0's data (`tau_initial`, `residual_rms`, `imu_samples_used`) are
    /// dropped. `imu(0)` of a one-IMU result is the result itself.
    ///
    /// # Errors
    /// When the result has no IMU j, or its IMU sets are invalid.
    pub fn imu(&self, j: usize) -> Result<CalibrationResult, String> {
        let sets = self.imu_sets()?;
        let k = sets.len();
        if j >= k {
            return Err(if k == 1 {
                format!("--imu {j}: the result has one IMU (IMU 0)")
            } else {
                format!("--imu {j}: the result has {k} IMUs, 0 to {}", k - 1)
            });
        }
        let base_of = |idx: usize| {
            let n = &self.parameters[idx].name;
            split_imu_name(n).map_or(n.clone(), |(_, b)| b.to_string())
        };
        // (index into parameters, name in the view), in file order with
        // IMU j's parameters in the place of IMU 0's
        let mut picked: Vec<(usize, String)> = Vec::new();
        for (idx, p) in self.parameters.iter().enumerate() {
            if sets.shared.contains(&idx) {
                picked.push((idx, p.name.clone()));
            } else if sets.imus[0].contains(&idx) {
                let twin = sets.imus[j].iter().find(|&&i| base_of(i) == p.name);
                if let Some(&i) = twin {
                    picked.push((i, p.name.clone()));
                }
            }
        }
        for &i in &sets.imus[j] {
            let base = base_of(i);
            if !picked.iter().any(|(_, n)| *n == base) {
                picked.push((i, base));
            }
        }
        let parameters: Vec<ParameterResult> = picked
            .iter()
            .map(|(i, name)| ParameterResult {
                name: name.clone(),
                ..self.parameters[*i].clone()
            })
            .collect();
        let cov_index = |i: usize| {
            let name = &self.parameters[i].name;
            self.covariance.names.iter().position(|n| n == name)
        };
        let rows: Vec<(usize, String)> = picked
            .iter()
            .filter_map(|(i, name)| cov_index(*i).map(|c| (c, name.clone())))
            .collect();
        let covariance = CovarianceMatrix {
            names: rows.iter().map(|(_, n)| n.clone()).collect(),
            matrix: rows
                .iter()
                .map(|(a, _)| {
                    rows.iter()
                        .map(|(b, _)| self.covariance.matrix[*a][*b])
                        .collect()
                })
                .collect(),
        };
        let mut view = CalibrationResult {
            parameters,
            covariance,
            ..self.clone()
        };
        if j > 0 {
            view.tau_initial = None;
            view.residual_rms = None;
            view.imu_samples_used = None;
        }
        Ok(view)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small result with a frozen parameter and a correlated 2×2 covariance.
    fn sample() -> CalibrationResult {
        let (va, vb, c): (f64, f64, f64) = (4.0e-8, 2.25e-2, -1.0e-5);
        let p = |name: &str, unit: &str, value: f64, sigma: f64, frozen: bool| ParameterResult {
            name: name.into(),
            unit: unit.into(),
            value,
            prior: 0.0,
            prior_sigma: 1e-3,
            sigma,
            frozen,
        };
        CalibrationResult {
            format: RESULT_FORMAT.into(),
            parameters: vec![
                p("eps_1_1", "m", 1.0 / 3.0 * 1e-3, va.sqrt(), false),
                p("eps_1_6", "rad", 0.0, 0.0, true),
                p("tau", "s", -std::f64::consts::E, vb.sqrt(), false),
            ],
            covariance: CovarianceMatrix {
                names: vec!["eps_1_1".into(), "tau".into()],
                matrix: vec![vec![va, c], vec![c, vb]],
            },
            robot: Some("aubo_i5".into()),
            source: None,
            session: Some("/tmp/s".into()),
            priors_used: Some(true),
            tau_initial: Some(-2.7),
            knot_spacing: Some(0.5),
            iterations: Some(7),
            initial_cost: Some(1e6),
            final_cost: Some(1234.5),
            termination: Some("converged".into()),
            residual_rms: Some([1.0, 0.99, 1.01, 1.0, 1.0, 0.98]),
            imu_samples_used: Some(3600),
            noise_model: Some(NoiseModelRecord::Ar {
                channels: vec![
                    ChannelNoiseRecord {
                        phi: vec![0.75],
                        sigma: 0.02,
                        motion: 1e-4,
                    };
                    6
                ],
            }),
            imu_noise_models: vec![ImuNoiseModelRecord {
                imu: "imu1".into(),
                noise_model: NoiseModelRecord::White,
            }],
            noise_warning: Some("kept".into()),
            verdict: None,
            effects: None,
            model_tests: None,
            pose_accuracy: None,
            covariance_kind: None,
            weak_directions: vec![WeakDirectionRecord {
                relative_information: 1e-3,
                parameters: vec![DirectionShare {
                    name: "eps_1_1".into(),
                    share: 0.9,
                }],
            }],
        }
    }

    #[test]
    fn noise_model_records_carry_their_kind() {
        let w = serde_json::to_value(NoiseModelRecord::White).unwrap();
        assert_eq!(w, serde_json::json!({"kind": "white"}));
        let ar = NoiseModelRecord::Ar {
            channels: vec![ChannelNoiseRecord {
                phi: vec![0.5, -0.1],
                sigma: 0.3,
                motion: 0.0,
            }],
        };
        let v = serde_json::to_value(&ar).unwrap();
        assert_eq!(v["kind"], "ar");
        assert_eq!(v["channels"][0]["phi"][1], -0.1);
        assert_eq!(serde_json::from_value::<NoiseModelRecord>(v).unwrap(), ar);
        // an IMU j ≥ 1's: named by its parameter prefix
        let imu = ImuNoiseModelRecord {
            imu: "imu2".into(),
            noise_model: ar.clone(),
        };
        let v = serde_json::to_value(&imu).unwrap();
        assert_eq!(v["imu"], "imu2");
        assert_eq!(v["noise_model"]["kind"], "ar");
        assert_eq!(
            serde_json::from_value::<ImuNoiseModelRecord>(v).unwrap(),
            imu
        );
        let r = sample();
        assert_eq!(r.noise_model_of(0), r.noise_model.as_ref());
        assert_eq!(r.noise_model_of(1), Some(&NoiseModelRecord::White));
        assert_eq!(r.noise_model_of(2), r.noise_model.as_ref());
        // absent for one IMU: nothing written
        let mut one = sample();
        one.imu_noise_models.clear();
        assert!(!one.to_json().unwrap().contains("imu_noise_models"));
    }

    #[test]
    fn round_trip_is_exact() {
        let r = sample();
        let text = r.to_json().unwrap();
        let back = CalibrationResult::parse(&text, Path::new("r.json")).unwrap();
        assert_eq!(back, r);
        assert_eq!(back.covariance_between("tau", "eps_1_1"), Some(-1.0e-5));
        assert_eq!(back.covariance_between("eps_1_6", "tau"), None);
        assert_eq!(back.index_of("tau"), Some(2));
        // the required keys of docs/model.md §8, read without this crate's types
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["format"], "robimu-result/1");
        let p = &v["parameters"][1];
        for key in [
            "name",
            "unit",
            "value",
            "prior",
            "prior_sigma",
            "sigma",
            "frozen",
        ] {
            assert!(p.get(key).is_some(), "missing {key}");
        }
        assert_eq!(p["frozen"], true);
        assert_eq!(v["covariance"]["matrix"][1][1], 2.25e-2);
    }

    /// Issue 41: numbers beyond their physical range and bytes that are not
    /// UTF-8 are refused on read, naming the parameter or the position.
    #[test]
    fn out_of_range_numbers_and_bad_bytes_are_refused() {
        let refused = |edit: &dyn Fn(&mut CalibrationResult), want: &str| {
            let mut r = sample();
            edit(&mut r);
            let text = serde_json::to_string_pretty(&r).unwrap();
            let e = CalibrationResult::parse(&text, Path::new("r.json"))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{e}");
        };
        refused(
            &|r| r.parameters[0].value = 1e308,
            "`eps_1_1`: value = 1e308 is beyond ±1e6",
        );
        refused(
            &|r| r.parameters[1].prior_sigma = 0.0,
            "`eps_1_6`: prior_sigma = 0: a prior σ must be > 0",
        );
        refused(
            &|r| {
                r.parameters[1].name = "k_a_x".into();
                r.parameters[1].value = 1e-320;
            },
            "`k_a_x`: gain 1e-320 is outside [0.1, 10]",
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("result.json");
        let mut bytes = sample().to_json().unwrap().into_bytes();
        let at = bytes.iter().position(|&b| b == b'\n').unwrap() + 3;
        bytes[at] = 0xfe;
        std::fs::write(&path, &bytes).unwrap();
        let e = CalibrationResult::read(&path).unwrap_err().to_string();
        assert!(
            e.contains("result.json:2:3: not UTF-8 text: invalid byte 0xfe at byte offset"),
            "{e}"
        );
    }

    #[test]
    fn files_with_only_the_required_keys_and_unknown_extras_are_read() {
        let text = r#"{"format": "robimu-result/1", "from": "another tool",
            "parameters": [{"name": "tau", "unit": "s", "value": 0.5, "prior": 0,
              "prior_sigma": 1, "sigma": 0.1, "frozen": false}],
            "covariance": {"names": ["tau"], "matrix": [[0.01]]}}"#;
        let r = CalibrationResult::parse(text, Path::new("r.json")).unwrap();
        assert_eq!(r.parameters[0].value, 0.5);
        assert!(r.final_cost.is_none() && r.weak_directions.is_empty());
    }

    #[test]
    fn broken_files_name_the_cause() {
        let check = |r: CalibrationResult, want: &str| {
            let text = serde_json::to_string_pretty(&r).unwrap();
            let e = CalibrationResult::parse(&text, Path::new("r.json")).unwrap_err();
            assert!(e.to_string().contains(want), "{e} (wanted {want})");
        };
        let mut r = sample();
        r.format = "robimu-result/2".into();
        check(r, "this version reads `robimu-result/1`");
        let mut r = sample();
        r.covariance.matrix[0][1] = 0.0;
        check(r, "not symmetric");
        let mut r = sample();
        r.covariance.matrix[1].pop();
        check(r, "row 2 (`tau`) has 1 entries");
        let mut r = sample();
        r.parameters[2].sigma *= 1.01;
        check(r, "covariance diagonal gives");
        let mut r = sample();
        r.parameters[1].frozen = false;
        check(r, "covariance has 2 names but 3 parameters are estimated");
        let mut r = sample();
        r.covariance.names[1] = "eps_1_6".into();
        r.parameters[1].frozen = false;
        r.parameters[2].frozen = true;
        r.parameters[1].sigma = r.parameters[2].sigma;
        r.parameters[2].sigma = 0.0;
        assert!(r.validate().is_ok());
        r.covariance.names[1] = "g_x".into();
        check(r, "`g_x`, which is not an estimated parameter");
        // JSON errors carry the line
        let e = CalibrationResult::parse("{\n\"format\": 3\n}", Path::new("r.json")).unwrap_err();
        assert!(e.to_string().starts_with("r.json:2:"), "{e}");
        // non-finite values are refused when writing, not turned into null
        let mut r = sample();
        r.parameters[0].value = f64::NAN;
        assert!(r.to_json().unwrap_err().contains("not finite"));
    }

    const RESULT1: &str = include_str!("../../cli/tests/fixtures/multi_imu/result1.json");
    const RESULT2: &str = include_str!("../../cli/tests/fixtures/multi_imu/result2.json");
    const RESULT3: &str = include_str!("../../cli/tests/fixtures/multi_imu/result3.json");

    fn fixture(text: &str) -> CalibrationResult {
        CalibrationResult::parse(text, Path::new("result.json")).unwrap()
    }

    /// `r` without parameter `name` (and its covariance row and column).
    fn without(mut r: CalibrationResult, name: &str) -> CalibrationResult {
        r.parameters.retain(|p| p.name != name);
        if let Some(c) = r.covariance.names.iter().position(|n| n == name) {
            r.covariance.names.remove(c);
            r.covariance.matrix.remove(c);
            for row in &mut r.covariance.matrix {
                row.remove(c);
            }
        }
        r
    }

    /// `r` with every name `from…` renamed `to…`.
    fn renamed(mut r: CalibrationResult, from: &str, to: &str) -> CalibrationResult {
        let f = |n: &mut String| {
            if let Some(rest) = n.strip_prefix(from) {
                *n = format!("{to}{rest}");
            }
        };
        r.parameters.iter_mut().for_each(|p| f(&mut p.name));
        r.covariance.names.iter_mut().for_each(f);
        r
    }

    #[test]
    fn imu_sets_of_one_two_and_three_imus_from_the_names() {
        for (text, k) in [(RESULT1, 1), (RESULT2, 2), (RESULT3, 3)] {
            let r = fixture(text);
            let sets = r.imu_sets().unwrap();
            assert_eq!(sets.len(), k);
            assert_eq!(r.imu_count(), k);
            assert_eq!(sets.imu_link, 6);
            assert_eq!(sets.shared.len(), 20, "18 robot errors and g_x, g_y");
            assert_eq!(r.parameters.len(), 20 + 28 * k);
            for (j, set) in sets.imus.iter().enumerate() {
                let mut names: Vec<String> =
                    set.iter().map(|&i| r.parameters[i].name.clone()).collect();
                let mut want: Vec<String> = imu_base_names(6)
                    .iter()
                    .map(|b| imu_parameter_name(j, b))
                    .collect();
                names.sort();
                want.sort();
                assert_eq!(names, want, "IMU {j}");
            }
            for &i in &sets.shared {
                let n = &r.parameters[i].name;
                assert!(n.starts_with("g_") || (n.starts_with("eps_") && !n.starts_with("eps_6_")));
            }
        }
        // a file with only the required keys and one parameter: one IMU
        assert_eq!(sample().imu_count(), 1);
    }

    /// A pose session's result of two IMUs (docs/model.md §7.9): g shared,
    /// each IMU's 28 with `p_imu_*` its position; IMU 1's view has the 30
    /// one-IMU names in their order with IMU 1's values.
    #[test]
    fn a_two_imu_pose_result_splits_into_its_imus() {
        // a pose session's names (pose_session.rs's, spelled out here)
        let mut base: Vec<String> = ["p_imu_x", "p_imu_y", "p_imu_z", "g_x", "g_y"]
            .map(String::from)
            .to_vec();
        base.extend(imu_base_names(0).into_iter().skip(3));
        let mut names = base.clone();
        names.extend(
            base[..3]
                .iter()
                .chain(&base[5..])
                .map(|n| format!("imu1/{n}")),
        );
        let mut r = sample();
        r.parameters = names
            .iter()
            .enumerate()
            .map(|(i, n)| ParameterResult {
                name: n.clone(),
                unit: "1".into(),
                value: i as f64,
                prior: 0.0,
                prior_sigma: 1.0,
                sigma: 0.1,
                frozen: false,
            })
            .collect();
        r.covariance = CovarianceMatrix {
            names: names.clone(),
            matrix: (0..58)
                .map(|a| (0..58).map(|b| if a == b { 0.01 } else { 0.0 }).collect())
                .collect(),
        };
        let sets = r.imu_sets().unwrap();
        assert_eq!(sets.len(), 2);
        assert_eq!(sets.shared, [3, 4]);
        assert_eq!(sets.imus[0].len(), 28);
        let v = r.imu(1).unwrap();
        let got: Vec<&str> = v.parameters.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(got, base);
        assert_eq!(v.parameters[0].value, 30.0);
        assert_eq!(v.parameters[3].value, 3.0);
        assert_eq!(v.parameters[5].value, 33.0);
        assert_eq!(v.covariance.names.len(), 30);
    }

    #[test]
    fn an_imu_of_a_multi_imu_result_reads_as_a_one_imu_result() {
        let one = fixture(RESULT1);
        assert_eq!(
            one.imu(0).unwrap(),
            one,
            "IMU 0 of one IMU is the result itself"
        );
        let three = fixture(RESULT3);
        for j in 0..3 {
            let v = three.imu(j).unwrap();
            v.validate().unwrap();
            // the one-IMU names in the one-IMU order
            let names: Vec<&str> = v.parameters.iter().map(|p| p.name.as_str()).collect();
            let want: Vec<&str> = one.parameters.iter().map(|p| p.name.as_str()).collect();
            assert_eq!(names, want, "IMU {j}");
            for p in &v.parameters {
                let own = three
                    .parameter(&imu_parameter_name(j, &p.name))
                    .filter(|_| imu_base_names(6).contains(&p.name))
                    .or_else(|| three.parameter(&p.name))
                    .unwrap();
                assert_eq!(
                    (p.value, p.sigma, p.frozen),
                    (own.value, own.sigma, own.frozen)
                );
            }
            // covariances as in the full matrix, shared and own
            let tau = imu_parameter_name(j, "tau");
            let k = imu_parameter_name(j, "k_w_z");
            assert_eq!(
                v.covariance_between("tau", "eps_5_6"),
                three.covariance_between(&tau, "eps_5_6")
            );
            assert_eq!(
                v.covariance_between("k_w_z", "tau"),
                three.covariance_between(&k, &tau)
            );
            assert_eq!(v.covariance.names.len(), one.covariance.names.len());
            assert_eq!(v.tau_initial.is_some(), j == 0);
        }
        // IMU 1's position differs from IMU 0's: the view takes IMU 1's
        let v1 = three.imu(1).unwrap();
        assert_eq!(
            v1.parameter("eps_6_2").unwrap().value,
            three.parameter("imu1/eps_6_2").unwrap().value
        );
        assert_ne!(
            v1.parameter("eps_6_2").unwrap().value,
            three.parameter("eps_6_2").unwrap().value
        );
        assert_eq!(
            three.imu(3).unwrap_err(),
            "--imu 3: the result has 3 IMUs, 0 to 2"
        );
        assert_eq!(
            one.imu(1).unwrap_err(),
            "--imu 1: the result has one IMU (IMU 0)"
        );
    }

    #[test]
    fn incomplete_imu_sets_name_what_is_missing() {
        let check = |r: CalibrationResult, want: &str| {
            let text = serde_json::to_string(&r).unwrap();
            let e = CalibrationResult::parse(&text, Path::new("r.json")).unwrap_err();
            assert!(e.to_string().contains(want), "{e}\n(wanted {want})");
        };
        let two = fixture(RESULT2);
        check(
            without(two.clone(), "imu1/k_a_x"),
            "IMU 1 of 2 lacks `imu1/k_a_x` (every IMU has the same 28 parameters",
        );
        check(
            without(without(two.clone(), "imu1/tau"), "imu1/eps_6_3"),
            "IMU 1 of 2 lacks `imu1/eps_6_3`, `imu1/tau`",
        );
        check(without(two.clone(), "b_w_z"), "IMU 0 of 2 lacks `b_w_z`");
        check(
            renamed(two.clone(), "imu1/", "imu2/"),
            "`imu2/` parameters but none of IMU 1 (`imu1/…`)",
        );
        let three = fixture(RESULT3);
        check(
            without(renamed(three, "imu1/", "imu9/"), "imu9/tau"),
            "`imu2/` parameters but none of IMU 1",
        );
        check(
            renamed(two.clone(), "imu1/", "imu0/"),
            "`imu0/eps_6_1`: IMU 0 keeps the plain names",
        );
        check(renamed(two.clone(), "imu1/", "imu01/"), "j unpadded");
        let mut shared = two.clone();
        shared.parameters[0].name = "imu1/eps_1_1".into();
        check(shared, "`imu1/eps_1_1`: `eps_1_1` is shared by all IMUs");
        let mut g = two;
        let i = g.index_of("g_y").unwrap();
        g.parameters[i].name = "imu1/g_y".into();
        let c = g.covariance.names.iter().position(|n| n == "g_y").unwrap();
        g.covariance.names[c] = "imu1/g_y".into();
        check(g, "`imu1/g_y`: `g_y` is shared");
        // a one-IMU result without some of the 28 still reads (other tools)
        assert!(without(fixture(RESULT1), "k_a_x").validate().is_ok());
    }
}
