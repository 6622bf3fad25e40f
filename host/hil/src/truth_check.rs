//! A calibration checked against the twin's hidden truth (docs/model.md
//! §4.8): the truth of the model a fit has (the baseline's, or with the
//! effects diagnose added), with each model's share of the twin's
//! structural mode, and the rows of estimate, σ and truth that `robimu
//! demo` prints.

use std::path::Path;

use anyhow::Context;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_session::result::CalibrationResult;
use robimu_session::{files, Session, Truth, TruthRow};
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};
use robimu_workflows::diagnose::{refit_final, Diagnosis};
use robimu_workflows::Fitted;

use crate::rig::SimRigConfig;
use crate::truth::{mode_signal, twin_truth, MotionSample, TwinTruth};

/// The twin's truth for the model with `effects`, at the session's IMU
/// samples (`powered_for`: how long the board ran before the session's
/// first sample; `imu_time_error`: the session clock mapping's error), the
/// model's share of the mode `mode` included.
pub fn session_truth(
    config: &SimRigConfig,
    hidden: &Truth,
    session: &Path,
    powered_for: f64,
    imu_time_error: f64,
    effects: &[String],
    mode: Option<&[(String, f64)]>,
) -> anyhow::Result<TwinTruth> {
    let s = Session::load(session)?;
    let timing = s.meta.imu_timing(&session.join(files::META))?;
    let since: Vec<f64> = s
        .measurements()
        .imu_t
        .iter()
        .map(|t| t + powered_for)
        .collect();
    Ok(twin_truth(
        config,
        hidden,
        timing.as_ref(),
        &since,
        effects,
        mode,
        imu_time_error,
    ))
}

/// Every estimated parameter of diagnose's final model against `truth`, x's
/// with the σ `sigma_x`.
fn final_model_rows(
    robot: &Robot,
    d: &Diagnosis,
    sigma_x: &[f64],
    truth: &TwinTruth,
) -> Vec<TruthRow> {
    let fit = &d.final_fit;
    let layout = ParamLayout::new(robot);
    let mut rows = Vec::new();
    for (k, spec) in layout.specs().iter().enumerate() {
        if let (Some(t), true) = (truth.get(&spec.name), sigma_x[k] > 0.0) {
            rows.push(TruthRow {
                name: spec.name.clone(),
                estimate: fit.x[k],
                sigma: sigma_x[k],
                truth: t,
                mode_share: truth.mode_share(&spec.name),
            });
        }
    }
    for (i, p) in fit.effect_params.iter().enumerate() {
        if let Some(t) = truth.get(&p.name) {
            rows.push(TruthRow {
                name: p.name.clone(),
                estimate: fit.theta_e[i],
                sigma: fit.sigma_e[i],
                truth: t,
                mode_share: truth.mode_share(&p.name),
            });
        }
    }
    rows
}

/// Every estimated parameter of a result file against `truth`.
pub fn result_rows(result: &CalibrationResult, truth: &TwinTruth) -> Vec<TruthRow> {
    result
        .parameters
        .iter()
        .filter(|p| !p.frozen && p.sigma > 0.0)
        .filter_map(|p| {
            Some(TruthRow {
                name: p.name.clone(),
                estimate: p.value,
                sigma: p.sigma,
                truth: truth.get(&p.name)?,
                mode_share: truth.mode_share(&p.name),
            })
        })
        .collect()
}

/// The twin's structural mode in a session (docs/model.md §4.8): the
/// session's samples with the mode's part of the signal taken out, and its
/// share of the baseline calibration. A model's share of the mode is its
/// estimate minus its estimate from those samples: what it absorbs of an
/// effect it does not have, which the truth it is compared with includes.
pub struct ModeShare {
    /// The session's samples without the mode's signal.
    still: Measurements,
    /// The calibration options of the session.
    opts: CalibrateOptions,
    /// Per parameter of x: the baseline calibration's share.
    pub baseline: Vec<(String, f64)>,
}

impl ModeShare {
    /// None when the twin has no mode. The mode's signal ([`mode_signal`])
    /// follows the baseline calibration's trajectory at each IMU sample.
    pub fn of(config: &SimRigConfig, session: &Path) -> anyhow::Result<Option<Self>> {
        if config.arm_physics.as_ref().is_none_or(|a| a.mode.is_none()) {
            return Ok(None);
        }
        let s = Session::load(session)?;
        let data = s.measurements();
        let robot = &config.robot;
        let n = robot.dof();
        let mut opts = CalibrateOptions::new(robot);
        (opts.sigma_z, opts.sigma_q) = s.noise(robot)?;
        let with =
            calibrate(robot, &data, &opts, |_| {}).context("cannot calibrate for the truth")?;
        let layout = ParamLayout::new(robot);
        let (tau, spline) = (with.x[layout.offsets().tau], &with.trajectory);
        let mut js = robimu_model::JointState::default();
        let (index, motion): (Vec<usize>, Vec<MotionSample>) = data
            .imu_t
            .iter()
            .enumerate()
            .filter(|(_, &t)| spline.knots().contains(t + tau))
            .map(|(i, &t)| {
                spline.evaluate_clamped(t + tau, &mut js);
                let sample = MotionSample {
                    t,
                    q: js.q[..n].to_vec(),
                    qd: js.qd[..n].to_vec(),
                    qdd: js.qdd[..n].to_vec(),
                };
                (i, sample)
            })
            .unzip();
        let Some(dz) = mode_signal(config, &motion)? else {
            return Ok(None);
        };
        let mut still = data.clone();
        for (&i, d) in index.iter().zip(&dz) {
            for (z, d) in still.imu_z[i].iter_mut().zip(d) {
                *z -= d;
            }
        }
        let without =
            calibrate(robot, &still, &opts, |_| {}).context("cannot calibrate for the truth")?;
        let baseline = differences(&layout, &with.x, &without.x, &[], &[], &[]);
        Ok(Some(Self {
            still,
            opts,
            baseline,
        }))
    }

    /// The share of diagnose's final model: its estimate minus its refit
    /// to the samples without the mode.
    pub fn of_final(&self, robot: &Robot, d: &Diagnosis) -> anyhow::Result<Vec<(String, f64)>> {
        let f = &d.final_fit;
        let without = refit_final(robot, &self.still, &self.opts, d)
            .context("cannot refit diagnose's model for the truth")?;
        let names: Vec<String> = f.effect_params.iter().map(|p| p.name.clone()).collect();
        Ok(differences(
            &ParamLayout::new(robot),
            &f.x,
            &without.x,
            &names,
            &f.theta_e,
            &without.theta_e,
        ))
    }
}

/// A calibration's model against the twin's truth of that model.
pub struct FittedCheck {
    /// The model's effects (empty: the paper's).
    pub effects: Vec<String>,
    /// Its estimated parameters against the truth.
    pub rows: Vec<TruthRow>,
    /// The truth of the model.
    pub truth: TwinTruth,
}

/// The model `calibrate` wrote (`fitted`: the paper's, or the final model
/// of its search or of a given effect set) against the twin's truth of
/// that model: `truth_for(effect parameter names, the model's share of the
/// mode)` ([`session_truth`]), the share from `mode` when the twin has one.
pub fn fitted_check(
    robot: &Robot,
    fitted: &Fitted,
    mode: Option<&ModeShare>,
    truth_for: impl Fn(&[String], Option<&[(String, f64)]>) -> anyhow::Result<TwinTruth>,
) -> anyhow::Result<FittedCheck> {
    Ok(match &fitted.selection {
        Some(d) => {
            let names: Vec<String> = d
                .final_fit
                .effect_params
                .iter()
                .map(|p| p.name.clone())
                .collect();
            let share = mode.map(|m| m.of_final(robot, d)).transpose()?;
            let truth = truth_for(&names, share.as_deref())?;
            FittedCheck {
                effects: d.final_fit.effects.clone(),
                // x's σ as written (widened where the model is shown
                // inadequate, docs/model.md §8.5), θ_E's the fit's
                rows: final_model_rows(robot, d, &fitted.cal.sigma, &truth),
                truth,
            }
        }
        None => {
            let truth = truth_for(&[], mode.map(|m| m.baseline.as_slice()))?;
            FittedCheck {
                effects: Vec::new(),
                rows: result_rows(&fitted.result, &truth),
                truth,
            }
        }
    })
}

/// (name, a − b) of every parameter of x and every effect parameter.
fn differences(
    layout: &ParamLayout,
    x_a: &[f64],
    x_b: &[f64],
    effect_names: &[String],
    e_a: &[f64],
    e_b: &[f64],
) -> Vec<(String, f64)> {
    let x = layout
        .specs()
        .iter()
        .map(|s| s.name.clone())
        .zip(x_a.iter().zip(x_b));
    let e = effect_names.iter().cloned().zip(e_a.iter().zip(e_b));
    x.chain(e).map(|(n, (a, b))| (n, a - b)).collect()
}
