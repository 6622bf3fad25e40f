//! The parts of result.json that say which model was fitted and what the
//! calibration buys (robimu extensions, docs/model.md §8.6–8.7): the
//! effects in the model and why each was added, the tests the written
//! model passed, and the flange pose accuracy before and after.

use serde::{Deserialize, Serialize};

/// One effect of the fitted model (docs/model.md §7), with its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectRecord {
    /// Its label (`joint_elasticity`, `imu1/sensor_delay`).
    pub name: String,
    /// The spec `calibrate --effects` takes for it (`bias_drift:8`).
    pub spec: String,
    /// Its parameters θ_E (SI), with posterior σ.
    pub parameters: Vec<EffectParameterRecord>,
    /// Why it was added (`None`: given with `--effects`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub evidence: Option<EffectEvidence>,
}

/// One parameter of an [`EffectRecord`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectParameterRecord {
    /// `effect.parameter`.
    pub name: String,
    /// SI unit.
    pub unit: String,
    /// Estimate.
    pub value: f64,
    /// Posterior σ.
    pub sigma: f64,
}

/// Why an effect was added: its score test at the model before it, the
/// refit's likelihood ratio, the whitened residual RMS before and after.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectEvidence {
    /// Rao score statistic.
    pub statistic: f64,
    /// Its degrees of freedom.
    pub dof: usize,
    /// Its p-value (compared with the Bonferroni threshold).
    pub p_value: f64,
    /// Likelihood-ratio statistic of the refit.
    pub lr_statistic: f64,
    /// Its p-value.
    pub lr_p_value: f64,
    /// Whitened residual RMS per channel `[ax, ay, az, gx, gy, gz]` before.
    #[serde(deserialize_with = "robimu_model::arity::array")]
    pub rms_before: [f64; 6],
    /// After.
    #[serde(deserialize_with = "robimu_model::arity::array")]
    pub rms_after: [f64; 6],
}

/// The tests of the written model (docs/model.md §8.6): the score test of
/// every catalogue effect not in it, Bonferroni over the candidates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelTestsRecord {
    /// `selected` (calibrate's default), `paper` or `given` (`--effects`).
    pub selection: String,
    /// Family-wise level α.
    pub alpha: f64,
    /// Candidates tested (the Bonferroni count).
    pub candidates: usize,
    /// Effects still significant against the written model (score p below
    /// α / candidates) that it does not include, with why.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub significant: Vec<SignificantEffect>,
    /// The largest score left, when it is not significant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub largest_remaining: Option<SignificantEffect>,
}

/// A catalogue effect's score test against the written model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SignificantEffect {
    /// Its label.
    pub name: String,
    /// Its score p-value.
    pub p_value: f64,
    /// Why the model does not include it (empty when it is not significant).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub reason: String,
}

/// The flange's pose error over the robot's workspace (docs/model.md
/// §8.7): predicted before calibration (the prior), after (the posterior),
/// the part of after that the undetermined parameters leave, and, where the
/// truth is known (simulation), the actual errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseAccuracyRecord {
    /// Random joint configurations within the limits.
    pub configurations: usize,
    /// Predicted with the prior (the catalogue's or factory model).
    pub before: PoseErrorStats,
    /// Predicted with the posterior.
    pub after: PoseErrorStats,
    /// Predicted with the posterior of the undetermined parameters alone
    /// (σ above 0.9 of the prior's, or frozen): what the data could not fix.
    pub after_undetermined: PoseErrorStats,
    /// Actual errors of the nominal model against the truth (simulation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actual_before: Option<ActualPoseErrors>,
    /// Actual errors of the calibrated model against the truth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actual_after: Option<ActualPoseErrors>,
}

/// Mean and 95th percentile of the flange's position and rotation error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseErrorStats {
    /// Mean position error, mm.
    pub position_mean_mm: f64,
    /// 95th percentile of the position error, mm.
    pub position_p95_mm: f64,
    /// Mean rotation error, degrees.
    pub rotation_mean_deg: f64,
    /// 95th percentile of the rotation error, degrees.
    pub rotation_p95_deg: f64,
}

/// Actual errors against a known truth, and how many fell inside the
/// predicted 95 % band of their configuration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ActualPoseErrors {
    /// The errors' statistics.
    #[serde(flatten)]
    pub stats: PoseErrorStats,
    /// Share of configurations whose position error is inside its predicted 95 % band.
    pub position_inside_band: f64,
    /// Share of configurations whose rotation error is inside its predicted 95 % band.
    pub rotation_inside_band: f64,
}
