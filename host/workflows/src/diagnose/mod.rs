//! Model-discrepancy diagnosis: where the calibrated model and the
//! measurement disagree, which catalogued effect ([`robimu_model::effects`]) explains
//! it, and how much the gap shrinks when it is added. The algorithm is
//! docs/model.md §4.10 (ranking and stopping §4.9): the baseline
//! [`fit`](crate::calibrate::fit), the residual analysis ([`ResidualStats`]),
//! every candidate's Rao score at the current fit ([`score_all`]), the
//! winner added when significant (Bonferroni over the candidates) and
//! confirmed by a refit's likelihood ratio (the `search` module), under the noise
//! model of [`DiagnoseOptions::noise`] (identified again after each effect,
//! AR order capped at [`NOISE_MAX_ORDER`]), and the structure left
//! ([`unexplained`]).

pub(crate) mod ranking;
mod residuals;
pub mod resolution;
mod score;
mod search;

pub use ranking::{determination, Alternative, Determination, MAX_ALIASING};

pub use residuals::{regressor_p_value, residual_stats, welch, windowed_rms, ResidualStats};
pub use score::{score_all, Score};

use serde::Serialize;

use super::calibrate::fit::{fit, Fit, FitSpec, Start};
use super::calibrate::noise_choice::{self, NoiseChoice, Settle};
use super::calibrate::{choose_knots, noise_model_record, CalibrateError, CalibrateOptions};
use crate::noise_id::{identify, IdOptions, Identification};
use robimu_model::effects::resonance::Mode;
use robimu_model::effects::{self, CatalogueSetup, Effect, EffectSet, MassModel, SessionSpan};
use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::{JointState, MeasurementModel, ParamLayout, PerChannel, Robot, Spline};
use robimu_solver::problem::Problem;
use robimu_solver::LeastSquares;

/// Channel names in z order.
pub use robimu_model::IMU_CHANNELS as CHANNELS;

/// Why a diagnosis failed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The fit failed.
    #[error(transparent)]
    Calibrate(#[from] CalibrateError),
    /// An unknown effect.
    #[error(transparent)]
    Unknown(#[from] robimu_model::effects::UnknownEffect),
    /// The information matrix is singular (an effect is not determined by the data).
    #[error("the information about the effect parameters is singular: {0}")]
    Singular(String),
    /// A bad effect resolution.
    #[error(transparent)]
    Spec(#[from] robimu_model::effects::EffectSpecError),
}

impl From<robimu_solver::problem::ProblemError> for DiagnoseError {
    fn from(e: robimu_solver::problem::ProblemError) -> Self {
        Self::Calibrate(e.into())
    }
}

/// The session-level setup of the catalogue for `data` (default resonance mode).
pub fn setup_for(robot: &Robot, data: &Measurements, mass: Option<MassModel>) -> CatalogueSetup {
    setup_with(robot, data, mass, Mode::default())
}

/// [`setup_for`] with the resonance effect's mode.
pub(crate) fn setup_with(
    robot: &Robot,
    data: &Measurements,
    mass: Option<MassModel>,
    mode: Mode,
) -> CatalogueSetup {
    let t0 = data.imu_t.first().copied().unwrap_or(0.0);
    let t1 = data.imu_t.last().copied().unwrap_or(0.0);
    // the recorded joints as the calibration first fits them (default knots)
    let opts = CalibrateOptions::new(robot);
    let joints = (!data.joint_t.is_empty())
        .then(|| choose_knots(data, robot.dof(), &opts.sigma_q, opts.degree, None).ok())
        .flatten();
    let mut setup = CatalogueSetup::new(
        SessionSpan { t0, t1 },
        mass.unwrap_or_else(|| MassModel::for_robot(robot)),
        robot.gravity(),
        None,
    );
    setup.set_joints(mode, joints.as_ref().map(|f| &f.spline));
    setup.n_imus = data.n_imus();
    for j in 0..data.n_imus() {
        let v = data.imu(j);
        if let Some(temp) = v.temp {
            setup.set_imu_temperature(j, v.t, temp);
        }
    }
    setup
}

/// The effect set of `names` (labels, [`effects::by_label`]; order as
/// given): a per-sensor effect on its IMU's rows, a shared one on every IMU's.
pub fn effect_set(setup: &CatalogueSetup, names: &[String]) -> Result<EffectSet, DiagnoseError> {
    let mut set = EffectSet::new();
    for n in names {
        let (e, imu) = effects::by_label(setup, n)?;
        set.push_on(e, imu);
    }
    Ok(set)
}

/// The IMU of the per-sensor effect labelled `name` (a plain name: 0),
/// `None` for a shared effect ([`effects::PER_SENSOR`]).
pub fn effect_imu(name: &str) -> Option<usize> {
    let (imu, base) = effects::split_label(name)?;
    effects::is_per_sensor(base).then_some(imu.unwrap_or(0))
}

/// Whether the requested candidate `r` selects candidate label `c`: its
/// label, or, for IMU j's per-sensor effect, the plain effect name (which
/// selects that effect on every IMU).
fn is_requested(r: &str, c: &str) -> bool {
    let base = effects::split_label(c).map_or(c, |(_, n)| n);
    r == c || r == base
}

/// Fit the baseline plus the `names` effects from `start` (the
/// [`fit`](fn@crate::calibrate::fit::fit) with the effect set of `names`).
pub fn fit_effects(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    names: &[String],
    start: Start<'_>,
) -> Result<Fit, DiagnoseError> {
    let set = effect_set(setup, names)?;
    let spec = FitSpec {
        robot,
        data,
        effects: &set,
        start,
    };
    Ok(fit(&spec, opts, |_| {})?)
}

/// One effect added by the diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct FoundEffect {
    /// Effect name (its label: `imu<j>/<effect>` for IMU j ≥ 1's per-sensor effect).
    pub name: String,
    /// The IMU of a per-sensor effect (0 for a plain name), `None` (JSON
    /// `null`) for a shared one, the robot's (docs/model.md §9).
    pub imu: Option<usize>,
    /// Score statistic at the fit before it was added.
    pub statistic: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Score p-value.
    pub p_value: f64,
    /// Likelihood-ratio statistic of the refit, 2 (J_before − J_after).
    pub lr_statistic: f64,
    /// LR p-value.
    pub lr_p_value: f64,
    /// ΔBIC = −LR + k ln N (negative favours the effect).
    pub delta_bic: f64,
    /// Whitened residual RMS per channel before and after adding it.
    pub rms_before: [f64; 6],
    /// After.
    pub rms_after: [f64; 6],
    /// Its parameters right after it was added.
    pub parameters: Vec<AddedParameter>,
    /// Baseline parameters that moved by more than 1 σ when it was added.
    pub baseline_moves: Vec<ParameterMove>,
    /// All scores of that round, best first.
    pub scores: Vec<Score>,
    /// For an effect with a time resolution (`bias_drift`): the one chosen
    /// from the data ([`resolution`]); its score is `statistic`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resolution: Option<resolution::ResolutionChoice>,
    /// The other candidates of that round significant alone, each against
    /// this one ([`Alternative`], docs/model.md §4.9).
    pub alternatives: Vec<Alternative>,
    /// Those the data cannot tell from this one.
    pub ambiguous_with: Vec<String>,
    /// ρ²_max of its parameters against the effects added before it
    /// ([`Determination`]; 0 for the first).
    pub aliasing: f64,
}

/// An effect parameter's estimate right after its effect was added
/// (diagnosis.json: `[name, unit, value, sigma]`).
#[derive(Debug, Clone, PartialEq)]
pub struct AddedParameter {
    /// Parameter name.
    pub name: String,
    /// Its SI unit.
    pub unit: String,
    /// Its estimate, SI.
    pub value: f64,
    /// Its posterior σ.
    pub sigma: f64,
}

/// A baseline parameter that moved by more than its σ when an effect was
/// added (diagnosis.json: `[name, before, after, sigma]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterMove {
    /// Parameter name.
    pub name: String,
    /// Its estimate before, SI.
    pub before: f64,
    /// Its estimate after.
    pub after: f64,
    /// Its posterior σ after.
    pub sigma: f64,
}

/// The earlier effect a candidate is most aliased with (diagnosis.json:
/// `[name, rho2]`).
#[derive(Debug, Clone, PartialEq)]
pub struct AliasedWith {
    /// The effect's name.
    pub name: String,
    /// ρ²_max of the candidate's parameters against it.
    pub rho2: f64,
}

// The records above keep diagnosis.json's arrays (robimu-diagnosis/1).
impl Serialize for AddedParameter {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        (&self.name, &self.unit, self.value, self.sigma).serialize(s)
    }
}

impl Serialize for ParameterMove {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        (&self.name, self.before, self.after, self.sigma).serialize(s)
    }
}

impl Serialize for AliasedWith {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        (&self.name, self.rho2).serialize(s)
    }
}

/// A candidate significant against the current model whose refit was not
/// accepted: its parameters are not determined apart from the effects
/// already added ([`Determination`], docs/model.md §4.9), or its refit
/// failed (`lr_statistic` and `aliasing` NaN, `null` in JSON).
#[derive(Debug, Clone, Serialize)]
pub struct Rejected {
    /// Effect name.
    pub name: String,
    /// Its score statistic at the fit it was tested against.
    pub statistic: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Score p-value.
    pub p_value: f64,
    /// LR statistic of its refit.
    pub lr_statistic: f64,
    /// ρ²_max against the effects already added.
    pub aliasing: f64,
    /// The effect it is most aliased with, and that ρ²_max.
    pub aliased_with: Option<AliasedWith>,
    /// Why, in words.
    pub reason: String,
}

/// Largest AR order `Auto` identifies (see the module doc: an AR(1)
/// spectrum is monotone and cannot take up a narrow peak).
pub(crate) const NOISE_MAX_ORDER: usize = 1;

/// Diagnosis settings.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Family-wise significance level α (Bonferroni over the catalogue).
    pub alpha: f64,
    /// Candidates considered (default: the whole catalogue; names the
    /// session's catalogue lacks, e.g. `temperature_bias` without a
    /// recorded temperature, are left out, also from the Bonferroni count).
    pub candidates: Vec<String>,
    /// Most effects added.
    pub max_effects: usize,
    /// Start the baseline fit from this x (e.g. a loaded calibration; no τ search).
    pub x_start: Option<Vec<f64>>,
    /// The IMU noise model of the fits and tests (default `Auto`; see the
    /// module doc); it decides, the calibration options' `noise` is not used.
    pub noise: NoiseChoice,
    /// How `Auto` identifies the noise (largest AR order
    /// [`NOISE_MAX_ORDER`], …).
    pub noise_id: IdOptions,
    /// Largest ρ² of a follow-up effect against the effects already added
    /// ([`Determination`]; default [`MAX_ALIASING`]).
    pub max_aliasing: f64,
    /// Effects in the baseline model besides the paper's (labels, e.g.
    /// `calibrate --effects`; default none): fitted from the start, never
    /// tested.
    pub base_effects: Vec<String>,
    /// How `Auto` settles the noise model after each fit.
    pub settle: Settle,
    /// `Auto`: the baseline's white fit when it is already made (the same
    /// fit from the nominal x, e.g. calibrate's): not fitted again.
    pub white_start: Option<Fit>,
    /// Compute the residual statistics before and after (the spectra,
    /// regressors and unexplained structure of diagnosis.json; default
    /// true); without, [`Diagnosis::stats_before`] and `stats_after` are
    /// empty and nothing is unexplained.
    pub residual_stats: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            alpha: 0.01,
            candidates: effects::NAMES.iter().map(|s| s.to_string()).collect(),
            max_effects: effects::NAMES.len(),
            x_start: None,
            noise: NoiseChoice::Auto,
            noise_id: IdOptions {
                max_order: NOISE_MAX_ORDER,
                ..IdOptions::default()
            },
            max_aliasing: MAX_ALIASING,
            base_effects: Vec::new(),
            settle: Settle::default(),
            white_start: None,
            residual_stats: true,
        }
    }
}

/// The noise model a diagnosis used, and how it came to it.
#[derive(Debug, Clone)]
pub struct NoiseUse {
    /// `white`, `given` or `auto`.
    pub choice: &'static str,
    /// `Auto`: the identification from the white baseline fit's raw
    /// residuals (its Ljung–Box p-values test their whiteness).
    pub white_test: Option<Identification>,
    /// `Auto`: whether the baseline was refitted with an identified (not
    /// white) model.
    pub identified: bool,
    /// `Auto`: effects after whose addition the re-identified model
    /// differed and the fit was redone with it.
    pub reidentified_after: Vec<String>,
    /// Why an identified model was not used (the fit kept its model).
    pub warnings: Vec<String>,
}

/// A channel whose final (prewhitened) residuals keep structure: a narrow
/// spectral peak (its [`peak_p_value`] below [`UNEXPLAINED_ALPHA`]/6,
/// Bonferroni over the bins and the six channels), or a correlation with a
/// regressor (its [`regressor_p_value`] below [`UNEXPLAINED_ALPHA`]/6,
/// Bonferroni over the regressors and the channels), or both.
#[derive(Debug, Clone, Serialize)]
pub struct Unexplained {
    /// Channel (`ax`…`gz`).
    pub channel: String,
    /// Frequency of the channel's largest peak, Hz.
    pub frequency_hz: f64,
    /// Peak power over the channel's median.
    pub peak_ratio: f64,
    /// Its p-value (flat spectrum, Bonferroni over the bins).
    pub p_value: f64,
    /// Whether the peak is significant.
    pub narrow_peak: bool,
    /// Whether the peak lies inside the motion's band
    /// ([`ResidualStats::motion_band_hz`]): where the regressors carry
    /// their power, so that the discrepancy can move the parameters.
    pub in_motion_band: bool,
    /// The regressor the channel's residuals follow most, with r and z = r√N.
    pub regressor: String,
    /// Correlation with it.
    pub r: f64,
    /// r√N.
    pub z: f64,
    /// Its p-value (Bonferroni over the regressors).
    pub regressor_p_value: f64,
    /// Whether the correlation is significant.
    pub follows_regressor: bool,
}

impl Unexplained {
    /// Whether this structure can move the parameters: a significant
    /// correlation with a regressor, or a narrow peak inside the motion's
    /// band (the regressors are functions of the motion and carry no power
    /// far above it, where a sensor's sampling artefact may peak).
    pub fn affects_parameters(&self) -> bool {
        self.follows_regressor || (self.narrow_peak && self.in_motion_band)
    }

    /// One line on this structure: the channel, its significant peak and
    /// regressor. `detailed` adds the peak's ratio and place against the
    /// motion's band, and names the top regressor even when it is not
    /// significant (diagnose's report); the verdict's line is the short one.
    pub fn describe(&self, detailed: bool) -> String {
        let mut parts = Vec::new();
        if self.narrow_peak && detailed {
            let band = if self.in_motion_band {
                "inside"
            } else {
                "above"
            };
            parts.push(format!(
                "narrow peak at {:.2} Hz ({:.1}× median power, p = {:.1e}, {band} the motion's band)",
                self.frequency_hz, self.peak_ratio, self.p_value
            ));
        } else if self.narrow_peak {
            parts.push(format!(
                "a narrow peak at {:.2} Hz (p = {:.1e})",
                self.frequency_hz, self.p_value
            ));
        }
        if detailed {
            let p = if self.follows_regressor {
                format!(", p = {:.1e}", self.regressor_p_value)
            } else {
                String::new()
            };
            parts.push(format!(
                "follows {} (r = {:+.3}, z = {:.1}{p})",
                self.regressor, self.r, self.z
            ));
        } else if self.follows_regressor {
            parts.push(format!(
                "follows {} (r = {:+.3}, p = {:.1e})",
                self.regressor, self.r, self.regressor_p_value
            ));
        }
        let sep = if detailed { "; " } else { ", " };
        format!("{} {}", self.channel, parts.join(sep))
    }
}

/// Family-wise level of the unexplained-structure tests over the channels.
pub const UNEXPLAINED_ALPHA: f64 = 0.01;

/// The channels of `s` with a significant narrow spectral peak or
/// regressor correlation.
///
/// Such structure is a discrepancy the model and noise model leave; it
/// moves the parameters (and their σ understate the error) when it follows
/// a regressor or peaks inside the motion's band
/// ([`Unexplained::affects_parameters`]).
pub fn unexplained(s: &ResidualStats) -> Vec<Unexplained> {
    let level = UNEXPLAINED_ALPHA / CHANNELS.len() as f64;
    CHANNELS
        .iter()
        .filter_map(|&c| {
            let p = s.spectral_peak_p[c].unwrap_or(1.0);
            let (frequency_hz, peak_ratio) = s.spectral_peak[c].unwrap_or_default();
            let (regressor, r, z) = s.top_regressor.get(c).cloned().unwrap_or_default();
            let regressor_p = regressor_p_value(z, s.regressors);
            let (narrow_peak, follows_regressor) = (p < level, regressor_p < level);
            let in_motion_band = s.motion_band_hz.is_some_and(|b| frequency_hz <= b);
            (narrow_peak || follows_regressor).then(|| Unexplained {
                channel: c.to_string(),
                frequency_hz,
                peak_ratio,
                p_value: p,
                narrow_peak,
                in_motion_band,
                regressor,
                r,
                z,
                regressor_p_value: regressor_p,
                follows_regressor,
            })
        })
        .collect()
}

/// The outcome of [`diagnose`].
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// The baseline fit.
    pub baseline: Fit,
    /// The final fit (baseline + every effect found).
    pub final_fit: Fit,
    /// Effects in the order they were added.
    pub found: Vec<FoundEffect>,
    /// The scores of the last round (none significant), best first.
    pub last_scores: Vec<Score>,
    /// Bonferroni threshold α/K used.
    pub threshold: f64,
    /// The candidates K offered.
    pub candidates: usize,
    /// Residual statistics before and after.
    pub stats_before: ResidualStats,
    /// After.
    pub stats_after: ResidualStats,
    /// Channels of the final fit with structure no candidate explains.
    pub unexplained: Vec<Unexplained>,
    /// Significant candidates not added (not determined apart from the
    /// effects already in the model), in the order they were tried.
    pub rejected: Vec<Rejected>,
    /// σ_z used (to display residuals in physical units).
    pub sigma_z: [f64; 6],
    /// The noise model (the baseline's in `baseline.noise`, the final one
    /// in `final_fit.noise`).
    pub noise: NoiseUse,
    /// The catalogue set-up of the final fit (with the resolutions chosen).
    pub setup: CatalogueSetup,
}

impl Diagnosis {
    /// The final model's effects as specs (`bias_drift:8`), as
    /// `calibrate --effects` takes them.
    pub fn final_specs(&self) -> Vec<String> {
        self.final_fit
            .effects
            .iter()
            .map(|e| self.setup.spec(e))
            .collect()
    }
    /// The `diagnosis.json` document (format `robimu-diagnosis/1`).
    pub fn to_json(&self, layout: &ParamLayout) -> serde_json::Value {
        let whiteness = self
            .noise
            .white_test
            .as_ref()
            .map(|id| PerChannel(std::array::from_fn(|c| id.channels[c].ljung_box_p)));
        serde_json::json!({
            "format": "robimu-diagnosis/1",
            "threshold": self.threshold,
            "noise_choice": self.noise.choice,
            "noise_identified": self.noise.identified,
            "noise_model": noise_model_record(&self.final_fit.noise),
            "noise_model_baseline": noise_model_record(&self.baseline.noise),
            "noise_whiteness_p": whiteness,
            "noise_reidentified_after": self.noise.reidentified_after,
            "noise_warnings": self.noise.warnings,
            "effects_found": self.found,
            "final_effect_specs": self.final_specs(),
            "last_scores": self.last_scores,
            "residual_rms_before": PerChannel(self.baseline.residual_rms()),
            "residual_rms_after": PerChannel(self.final_fit.residual_rms()),
            "residual_stats_before": self.stats_before,
            "residual_stats_after": self.stats_after,
            "unexplained": self.unexplained,
            "rejected": self.rejected,
            "final_model": fit_json(layout, &self.final_fit),
        })
    }
}

/// The final model of `d` fitted to `data`, other samples of the same
/// session (e.g. with a known signal taken out): the same effects, noise
/// model and knots, from the final fit's estimate.
pub fn refit_final(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    d: &Diagnosis,
) -> Result<Fit, DiagnoseError> {
    let f = &d.final_fit;
    fit_effects(
        robot,
        data,
        &with_noise_of(opts, f),
        &d.setup,
        &f.effects,
        Start::Refit(f),
    )
}

/// The calibration options of the fits and tests under the noise of `f`
/// (`None` when white).
fn with_noise_of(opts: &CalibrateOptions, f: &Fit) -> CalibrateOptions {
    noise_choice::options_with(opts, noise_choice::fit_wants(f))
}

fn with_noise(opts: &CalibrateOptions, noise: Option<NoiseModel>) -> CalibrateOptions {
    CalibrateOptions {
        noise,
        imu_noise: Vec::new(),
        ..opts.clone()
    }
}

/// The noise identified ([`crate::noise_id::identify`]) from the raw IMU
/// residuals z_i − h(x̂, q(t_i + τ̂)) − C_e(i) θ̂_e of the fit `at` (its
/// effects included), with ‖q̈‖² of its trajectory as the motion regressor:
/// IMU 0's ([`identify_imus_at`] for every IMU's).
pub(crate) fn identify_at(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    id_opts: &IdOptions,
) -> Result<Identification, String> {
    identify_of(robot, data, opts, setup, at, id_opts, 1).map(|mut v| v.swap_remove(0))
}

/// [`identify_at`] for every IMU of the fit (IMU j's `[j]`), each from its
/// own residuals under its own parameters (docs/model.md §9: each IMU has
/// its own noise).
pub(crate) fn identify_imus_at(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    id_opts: &IdOptions,
) -> Result<Vec<Identification>, String> {
    identify_of(robot, data, opts, setup, at, id_opts, at.n_imus.max(1))
}

/// The identifications of the first `k` IMUs of `at`. An IMU the fit
/// whitened by the white model of σ_z has its residuals already (whitened
/// by σ_z: the same problem's at the same θ); another's are evaluated anew.
fn identify_of(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    at: &Fit,
    id_opts: &IdOptions,
    k: usize,
) -> Result<Vec<Identification>, String> {
    let layout = ParamLayout::with_imus(robot, data.n_imus());
    let tau_at = ParamLayout::new(robot).offsets().tau;
    let white = with_noise(opts, None);
    let known = |m: &NoiseModel| m.is_white() && m.sigma_z() == opts.sigma_z;
    let models: Vec<&NoiseModel> = noise_choice::fit_models(at).take(k).collect();
    let evaluated = if models.iter().all(|m| known(m)) {
        Vec::new()
    } else {
        with_problem_at(robot, data, &white, setup, &at.effects, at, |p, theta| {
            (0..k)
                .map(|j| Ok(p.imu_residuals_of(theta, j)?))
                .collect::<Result<Vec<_>, DiagnoseError>>()
        })
        .map_err(|e| e.to_string())?
    };
    let residuals = std::iter::once(&at.residuals).chain(&at.extra_residuals);
    let n = robot.dof();
    models
        .iter()
        .zip(residuals)
        .enumerate()
        .map(|(j, (m, own))| {
            let res = if known(m) { own } else { &evaluated[j] };
            let imu_t = data.imu(j).t;
            let tau = layout.imu_x(j, &at.x)[tau_at];
            let (mut t, mut r) = (Vec::new(), Vec::new());
            for &(i, w) in res {
                t.push(imu_t[i]);
                r.push(std::array::from_fn(|c| w[c] * opts.sigma_z[c]));
            }
            // ‖q̈‖² along the trajectory, the two halves of the samples on two threads
            let qdd2_of = |part: &[(usize, [f64; 6])]| -> Vec<f64> {
                let mut js = JointState::default();
                part.iter()
                    .map(|(i, _)| {
                        at.trajectory.evaluate_clamped(imu_t[*i] + tau, &mut js);
                        js.qdd[..n].iter().map(|a| a * a).sum()
                    })
                    .collect()
            };
            let (first, second) = res.split_at(res.len() / 2);
            let (mut qdd2, rest) = robimu_model::pair::join(|| qdd2_of(first), || qdd2_of(second));
            qdd2.extend(rest);
            identify(&t, &r, Some(&qdd2), id_opts).map_err(|e| match j {
                0 => e.to_string(),
                _ => format!("IMU {j}: {e}"),
            })
        })
        .collect()
}

/// The problem of the baseline plus the `names` effects (`at`'s effects
/// first, in its order) at the fit `at`: its knots, x and θ, the further
/// effects' parameters at 0, the iteration begun there; `f` gets it and θ.
pub(crate) fn with_problem_at<T>(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    names: &[String],
    at: &Fit,
    f: impl FnOnce(&mut Problem<'_>, &[f64]) -> Result<T, DiagnoseError>,
) -> Result<T, DiagnoseError> {
    let layout = ParamLayout::with_imus(robot, data.n_imus());
    let set = effect_set(setup, names)?;
    let mut problem = Problem::new(
        robot,
        &layout,
        data,
        at.trajectory.knots().clone(),
        at.x.clone(),
        &opts.problem_options(),
        &set,
    )?;
    let mut theta = problem.theta(&at.trajectory, &at.x);
    theta[..at.theta.len()].copy_from_slice(&at.theta);
    problem.begin_iteration(&theta)?;
    f(&mut problem, &theta)
}

/// Refit `start` (same effects) with the noise identified from its
/// residuals (`ids`, one per IMU), identify again, until every IMU's settles (calibrate's
/// loop, [`noise_choice::settle_noise`]): the settled fit and the refits
/// made, or why not.
#[allow(clippy::too_many_arguments)]
fn settle_noise(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    start: &Fit,
    ids: Vec<Identification>,
    (id_opts, settle): (&IdOptions, &Settle),
    progress: &mut impl FnMut(&str),
) -> Result<(Fit, usize), String> {
    // each IMU its own model, from its own residuals (docs/model.md §9)
    let s = noise_choice::settle_noise(
        start.clone(),
        ids,
        settle,
        |current, want| {
            progress("refitting with the identified noise model");
            fit_effects(
                robot,
                data,
                &noise_choice::options_with(opts, want),
                setup,
                &current.effects,
                Start::Refit(current),
            )
            .map_err(|e| e.to_string())
        },
        |f| identify_imus_at(robot, data, opts, setup, f, id_opts),
    )?;
    Ok((s.fit, s.refits))
}

/// The baseline fit under `dopts.noise` (see the module doc).
fn baseline_fit(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    dopts: &DiagnoseOptions,
    progress: &mut impl FnMut(&str),
) -> Result<(Fit, NoiseUse), DiagnoseError> {
    let start = dopts.x_start.as_deref().map_or(Start::Nominal, Start::At);
    let base = &dopts.base_effects;
    let mut noise = NoiseUse {
        choice: "auto",
        white_test: None,
        identified: false,
        reidentified_after: Vec::new(),
        warnings: Vec::new(),
    };
    let given = match &dopts.noise {
        NoiseChoice::White => Some(None),
        NoiseChoice::Given(m) => Some(Some((**m).clone())),
        NoiseChoice::Auto => None,
    };
    if let Some(model) = given {
        noise.choice = if model.is_some() { "given" } else { "white" };
        let f = fit_effects(robot, data, &with_noise(opts, model), setup, base, start)?;
        return Ok((f, noise));
    }
    let white = match &dopts.white_start {
        Some(f) => f.clone(),
        None => fit_effects(robot, data, &with_noise(opts, None), setup, base, start)?,
    };
    progress("identifying the noise from the residuals");
    let ids = match identify_imus_at(robot, data, opts, setup, &white, &dopts.noise_id) {
        Ok(ids) => ids,
        Err(e) => {
            noise
                .warnings
                .push(format!("noise not identified ({e}); white noise kept"));
            return Ok((white, noise));
        }
    };
    noise.white_test = Some(ids[0].clone());
    match settle_noise(
        robot,
        data,
        opts,
        setup,
        &white,
        ids,
        (&dopts.noise_id, &dopts.settle),
        progress,
    ) {
        Ok((f, _)) => {
            noise.identified = !f.noise.is_white();
            Ok((f, noise))
        }
        Err(e) => {
            noise.warnings.push(format!(
                "{e}; the white-noise fit is kept and its tests count correlated samples as independent"
            ));
            Ok((white, noise))
        }
    }
}

/// The candidates of `requested` this session's catalogue has
/// (temperature_bias needs a recorded temperature, resonance a
/// trajectory), each per-sensor effect once per IMU (docs/model.md §9),
/// without those in the model already (`base`): the Bonferroni count.
pub(crate) fn offered_candidates(
    setup: &CatalogueSetup,
    requested: &[String],
    base: &[String],
) -> Vec<String> {
    let all = setup.candidates();
    let mut offered: Vec<String> = Vec::new();
    for r in requested {
        for c in all.iter().filter(|c| is_requested(r, c)) {
            if !offered.contains(c) && !base.contains(c) {
                offered.push(c.clone());
            }
        }
    }
    offered
}

/// Diagnose `data`: baseline fit, then add significant effects one at a time
/// (see the module doc).
pub fn diagnose(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    setup: &CatalogueSetup,
    dopts: &DiagnoseOptions,
    mut progress: impl FnMut(&str),
) -> Result<Diagnosis, DiagnoseError> {
    let offered = offered_candidates(setup, &dopts.candidates, &dopts.base_effects);
    let threshold = dopts.alpha / offered.len().max(1) as f64;
    // resolutions chosen below are set in this copy
    let mut setup = setup.clone();
    let setup = &mut setup;
    progress("fitting the baseline model");
    // the resonance's response (integrated on first use) on the other core
    // while the baseline is fitted: the scores are its first use
    let response = setup.mode_response.clone();
    let (baseline, noise) = std::thread::scope(|scope| {
        if let Some(r) = &response {
            scope.spawn(|| r.prepare());
        }
        baseline_fit(robot, data, opts, setup, dopts, &mut progress)
    })?;
    // the baseline's residual statistics on the other core while the
    // effects are searched (they need only the baseline fit)
    let stats_setup = setup.clone();
    let (stats_before, search) = std::thread::scope(|scope| {
        let before = scope.spawn(|| {
            if dopts.residual_stats {
                residual_stats(robot, data, &stats_setup, &baseline)
            } else {
                ResidualStats::default()
            }
        });
        let problem = search::SearchProblem {
            robot,
            data,
            opts,
            dopts,
            offered: &offered,
        };
        let search = search::search_effects(&problem, setup, &baseline, noise, &mut progress);
        (before.join().expect("residual statistics panicked"), search)
    });
    let search::Search {
        fit: current,
        found,
        rejected,
        last_scores,
        noise,
    } = search?;
    // with no effect added the final fit is the baseline itself
    let stats_after = if found.is_empty() || !dopts.residual_stats {
        stats_before.clone()
    } else {
        residual_stats(robot, data, setup, &current)
    };
    Ok(Diagnosis {
        unexplained: unexplained(&stats_after),
        rejected,
        baseline,
        final_fit: current,
        found,
        last_scores,
        threshold,
        candidates: offered.len(),
        stats_before,
        stats_after,
        sigma_z: opts.sigma_z,
        noise,
        setup: setup.clone(),
    })
}

/// Add the exact effect terms of `injected` to simulated IMU samples (each
/// effect's [`Effect::exact`] minus the baseline; several effects superpose,
/// their second-order cross terms left out). `data` came from
/// [`super::simulate::simulate`] with the same truth and trajectory; the
/// joint samples (the encoder readings) are unchanged. Every IMU of `data`
/// gets them ([`inject_effects_on`]).
pub fn inject_effects(
    robot: &Robot,
    truth: &[f64],
    trajectory: &Spline,
    data: &mut Measurements,
    injected: &[(Box<dyn Effect>, Vec<f64>)],
) -> Result<(), robimu_model::ModelError> {
    inject_effects_on(robot, truth, trajectory, data, None, injected)
}

/// [`inject_effects`] on IMU `imu`'s samples only (`None`: every IMU's, as
/// a shared effect); `truth` is x of [`ParamLayout::with_imus`] for the
/// session's IMUs, each IMU's term computed at its own parameters.
pub fn inject_effects_on(
    robot: &Robot,
    truth: &[f64],
    trajectory: &Spline,
    data: &mut Measurements,
    imu: Option<usize>,
    injected: &[(Box<dyn Effect>, Vec<f64>)],
) -> Result<(), robimu_model::ModelError> {
    let layout = ParamLayout::with_imus(robot, data.n_imus());
    let one = layout.imu_layout();
    let traj = effects::trajectory_fn(trajectory);
    for j in 0..data.n_imus() {
        if imu.is_some_and(|i| i != j) {
            continue;
        }
        let own = layout.imu_x(j, truth);
        let model = MeasurementModel::new(robot, one, &own)?;
        let tau = own[one.offsets().tau];
        let (ts, zs) = match j {
            0 => (&data.imu_t, &mut data.imu_z),
            _ => {
                let s = &mut data.extra_imus[j - 1];
                (&s.t, &mut s.z)
            }
        };
        for (t, z) in ts.iter().zip(zs.iter_mut()) {
            let ctx = effects::ExactContext {
                t: *t,
                tau,
                model: &model,
                trajectory: &traj,
            };
            let base = ctx.baseline();
            for (e, theta) in injected {
                let ze = e.exact(&ctx, theta, one);
                for c in 0..6 {
                    z[c] += ze[c] - base[c];
                }
            }
        }
    }
    Ok(())
}

/// The JSON of a fit: every parameter of x and every effect parameter (SI, with σ).
pub(crate) fn fit_json(layout: &ParamLayout, f: &Fit) -> serde_json::Value {
    let params: Vec<serde_json::Value> = layout
        .specs()
        .iter()
        .enumerate()
        .map(|(k, s)| {
            serde_json::json!({"name": s.name, "unit": s.unit.to_string(), "value": f.x[k], "sigma": f.sigma_x[k]})
        })
        .collect();
    let eff: Vec<serde_json::Value> = f
        .effect_params
        .iter()
        .enumerate()
        .map(|(e, p)| {
            serde_json::json!({"name": p.name, "unit": p.unit, "value": f.theta_e[e], "sigma": f.sigma_e[e]})
        })
        .collect();
    let constants: Vec<serde_json::Value> = f
        .effect_constants
        .iter()
        .map(|c| serde_json::json!({"name": c.name, "unit": c.unit, "value": c.value}))
        .collect();
    serde_json::json!({"effects": f.effects, "parameters": params, "effect_parameters": eff, "effect_constants": constants})
}

#[cfg(test)]
mod tests {
    use super::residuals::correlation;
    use super::residuals::{peak_p_value, welch_segments};
    use super::*;
    use crate::stats::{chi2_sf, ljung_box, ln_gamma};

    /// χ² upper-tail probabilities against tabulated quantiles.
    #[test]
    fn chi2_sf_matches_tables() {
        for (x, k, p) in [
            (3.841458820694124, 1.0, 0.05),
            (6.634896601021214, 1.0, 0.01),
            (18.307038053275146, 10.0, 0.05),
            (26.21696730553585, 12.0, 0.01),
            (2.705543454095404, 1.0, 0.10),
            (0.1148318018, 3.0, 0.99),
        ] {
            let got = chi2_sf(x, k);
            assert!(
                (got - p).abs() < 1e-8 * p.max(1e-3) + 1e-9,
                "χ²({k}) > {x}: {got} vs {p}"
            );
        }
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
    }

    /// Ljung–Box: white noise passes, an AR(1) series fails.
    #[test]
    fn ljung_box_separates_white_from_correlated() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let white: Vec<f64> = (0..5000).map(|_| StandardNormal.sample(&mut rng)).collect();
        let mut ar = vec![0.0; 5000];
        for i in 1..5000 {
            ar[i] = 0.2 * ar[i - 1] + white[i];
        }
        assert!(ljung_box(&white, 20).1 > 1e-3);
        assert!(ljung_box(&ar, 20).1 < 1e-10);
    }

    /// A constant regressor (a steady temperature) has correlation 0, not
    /// NaN and not rounding noise, even when its mean is not exact in binary.
    #[test]
    fn constant_series_have_zero_correlation() {
        let y: Vec<f64> = (0..1000)
            .map(|i| ((i * 7919) % 101) as f64 - 50.0)
            .collect();
        for c in [25.0, 24.7, 0.1, -1e-300] {
            let x = vec![c; y.len()];
            let n = x.len() as f64;
            let mean = x.iter().sum::<f64>() / n;
            println!("{c}: mean off by {:e}", mean - c);
            assert_eq!(correlation(&x, &y), 0.0, "{c}");
            assert_eq!(correlation(&y, &x), 0.0, "{c}");
        }
        // an independent check of the non-constant case: y against 2y + 1
        let x: Vec<f64> = y.iter().map(|v| 2.0 * v + 1.0).collect();
        assert!((correlation(&x, &y) - 1.0).abs() < 1e-12);
        let x: Vec<f64> = y.iter().map(|v| -v).collect();
        assert!((correlation(&x, &y) + 1.0).abs() < 1e-12);
    }

    /// Windowed RMS: equal windows from the first sample to the last, each
    /// the RMS of its own samples at their mean time.
    #[test]
    fn windowed_rms_of_known_series() {
        // 10 Hz for 3 s; first second ±1, second 3, third alternating ±2
        let t: Vec<f64> = (0..30).map(|i| 0.1 * i as f64).collect();
        let r: Vec<f64> = (0..30)
            .map(|i| match i / 10 {
                0 => [1.0, -1.0][i % 2],
                1 => 3.0,
                _ => [2.0, -2.0][i % 2],
            })
            .collect();
        let w = windowed_rms(&t, &r, 1.0);
        assert_eq!(w.len(), 3, "{w:?}");
        for (k, (tm, rms)) in w.iter().enumerate() {
            assert!((tm - (k as f64 + 0.45)).abs() < 1e-9, "{w:?}");
            assert!((rms - [1.0, 3.0, 2.0][k]).abs() < 1e-12, "{w:?}");
        }
        // 2.9 s span in windows of ~1.2 s: two of 1.45 s (15 samples each)
        let w = windowed_rms(&t, &r, 1.2);
        assert_eq!(w.len(), 2, "{w:?}");
        let second: f64 = r[15..].iter().map(|v| v * v).sum::<f64>() / 15.0;
        assert!((w[1].1 - second.sqrt()).abs() < 1e-12, "{w:?}");
        assert_eq!(windowed_rms(&t, &r, 10.0).len(), 1);
        assert_eq!(windowed_rms(&[3.0], &[-2.0], 1.0), [(3.0, 2.0)]);
        assert!(windowed_rms(&[], &[], 1.0).is_empty());
    }

    /// The peak test's level by Monte Carlo: on white series of 40 s at
    /// 120 Hz the fraction with p < 0.05 is at most 0.05 (Bonferroni over
    /// correlated bins makes it conservative, not void: above 0.01); a
    /// 0.3σ sinusoid gives p < 1e-10.
    #[test]
    fn peak_p_value_holds_its_level_on_white_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (n, runs, rate) = (4800, 250, 120.0);
        let k = welch_segments(n);
        assert_eq!(k, (n - 512) / 256 + 1);
        let p_of = |r: &[f64]| {
            let spec = welch(r, rate);
            let mut pw: Vec<f64> = spec.iter().map(|p| p.1).collect();
            pw.sort_by(f64::total_cmp);
            let median = pw[pw.len() / 2];
            let peak = spec.iter().skip(1).map(|p| p.1).fold(0.0, f64::max);
            peak_p_value(peak / median, k, spec.len() - 1)
        };
        let mut below = 0;
        for _ in 0..runs {
            let r: Vec<f64> = (0..n).map(|_| StandardNormal.sample(&mut rng)).collect();
            if p_of(&r) < 0.05 {
                below += 1;
            }
        }
        let rate_05 = below as f64 / runs as f64;
        println!("P(p < 0.05) on white noise: {rate_05}");
        assert!(rate_05 <= 0.05 + 3.0 * (0.05f64 * 0.95 / runs as f64).sqrt());
        assert!(rate_05 > 0.01, "{rate_05}");
        let r: Vec<f64> = (0..n)
            .map(|i| {
                let e: f64 = StandardNormal.sample(&mut rng);
                e + 0.3 * (2.0 * std::f64::consts::PI * 17.0 * i as f64 / rate).sin()
            })
            .collect();
        assert!(p_of(&r) < 1e-10, "{}", p_of(&r));
    }

    /// The Welch periodogram puts a sinusoid's power at its frequency.
    #[test]
    fn welch_peak_is_at_the_sinusoid() {
        let rate = 120.0;
        let r: Vec<f64> = (0..4000)
            .map(|i| (2.0 * std::f64::consts::PI * 7.3 * i as f64 / rate).sin())
            .collect();
        let spec = welch(&r, rate);
        let peak = spec.iter().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        assert!((peak.0 - 7.3).abs() < rate / 512.0, "peak at {} Hz", peak.0);
    }
}
