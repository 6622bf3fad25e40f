//! Which IMU noise model a calibration uses (docs/model.md §4.6): white
//! (the paper's), a given one, or one identified from the calibration's own
//! residuals.
//!
//! `Auto` fits with white noise first and tests each channel's residuals
//! for whiteness (Ljung–Box, Bonferroni over the six channels at
//! [`WHITENESS_ALPHA`](crate::noise_id::WHITENESS_ALPHA)). When they pass,
//! or fail with no AR order or motion level the data support (the
//! identified model is white), that is the result. When they fail, the noise is identified from the raw
//! residuals r_i = z_i − h(x̂, q(t_i + τ̂)) ([`crate::noise_id::identify`]),
//! the data are refitted by generalised least squares with it, and the
//! noise is identified again from the new fit's residuals, until the model
//! settles (every channel's order unchanged, φ within
//! [`SETTLE_PHI`] and σ within [`SETTLE_SIGMA`] relative) or
//! [`MAX_REFITS`] refits ([`Settle`]); each refit starts from the
//! previous fit, and one whose residuals pass the whiteness test asks for
//! white noise again ([`wanted`]). A model that does not settle, or a refit that
//! fails, leaves the white result, with a warning (never an error where the
//! white fit succeeded). The loop ([`settle_noise`]) is the one diagnose
//! runs after each effect it adds.
//!
//! **Several IMUs** (docs/model.md §9). Each IMU has its own noise: the
//! test, the identification and the settling above run on every IMU's own
//! raw residuals under its own parameters ([`fit_identifications`]), and
//! each IMU's rows are whitened by its own model
//! ([`CalibrateOptions::imu_noise`]; the paper's Σ_z of eq. (22) per IMU):
//! a refit is made when any IMU asks for another model than it has, and
//! the models have settled when every IMU's has. One IMU is the case K = 1.

use robimu_model::lanes::{quads, F64x4};
use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::{
    Basis, JointState, MeasurementModel, ParamLayout, Robot, SpanPolynomials, Spline, MAX_JOINTS,
};
use robimu_solver::IterationRecord;

use super::fit::{fit, Fit, FitSpec, Start};
use super::{calibration_of, CalibrateError, CalibrateOptions, Calibration};
use crate::noise_id::{identify, IdOptions, Identification};

/// Most GLS refits of `Auto`.
pub const MAX_REFITS: usize = 4;
/// φ change below which the identified model has settled.
pub(crate) const SETTLE_PHI: f64 = 0.02;
/// Relative σ change below which the identified model has settled.
pub(crate) const SETTLE_SIGMA: f64 = 0.02;
/// Gradient tolerance of a refit (max |g_k|/√A_kk, [`robimu_solver::LmOptions`]):
/// every parameter's remaining Newton step below 1 % of its conditional σ
/// (the white fit ends about there, by its cost change).
pub(crate) const REFIT_GRADIENT: f64 = 1e-2;

/// The noise model to calibrate with.
#[derive(Debug, Clone, PartialEq)]
pub enum NoiseChoice {
    /// White noise of the options' σ_z.
    White,
    /// White unless the residuals show otherwise; then identified.
    Auto,
    /// This model.
    Given(Box<NoiseModel>),
}

/// What the noise choice did.
#[derive(Debug, Clone)]
pub struct NoiseOutcome {
    /// The identification from the white fit's residuals (`Auto`).
    pub white_test: Option<Identification>,
    /// The identification the final fit used (`Auto` with refits).
    pub identified: Option<Identification>,
    /// IMU j ≥ 1 of a multi-IMU session (`Auto`): the identification from
    /// the white fit's residuals (`extra_white_tests[j - 1]`; `white_test`
    /// is IMU 0's).
    pub extra_white_tests: Vec<Identification>,
    /// IMU j ≥ 1: the identification whose model the final fit used for it
    /// (`Auto` with refits; `identified` is IMU 0's).
    pub extra_identified: Vec<Identification>,
    /// GLS refits made.
    pub refits: usize,
    /// Why the white result was kept although the residuals are not white.
    pub warning: Option<String>,
}

/// How `Auto` iterates: the most GLS refits and when the identified model
/// has settled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settle {
    /// Most refits ([`MAX_REFITS`]).
    pub max_refits: usize,
    /// Largest change of any φ_k ([`SETTLE_PHI`]).
    pub phi: f64,
    /// Largest relative change of σ and of the motion gain ([`SETTLE_SIGMA`]).
    pub sigma: f64,
}

impl Default for Settle {
    fn default() -> Self {
        Self {
            max_refits: MAX_REFITS,
            phi: SETTLE_PHI,
            sigma: SETTLE_SIGMA,
        }
    }
}

/// Calibrate `data` with the noise model `choice` (see the module docs).
pub fn calibrate_with_noise(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    choice: &NoiseChoice,
    report: impl FnMut(&IterationRecord),
) -> Result<(Calibration, NoiseOutcome), CalibrateError> {
    calibrate_with_noise_settle(robot, data, opts, choice, &Settle::default(), report)
}

/// [`calibrate_with_noise`] with `Auto` iterating as `settle` says.
///
/// Each refit starts from the previous fit ([`Start::Refit`]: its knots,
/// trajectory and x; no τ search, no knot choice), so that a refit costs
/// the few Gauss–Newton steps from the white optimum to the GLS one.
pub(crate) fn calibrate_with_noise_settle(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    choice: &NoiseChoice,
    settle: &Settle,
    report: impl FnMut(&IterationRecord),
) -> Result<(Calibration, NoiseOutcome), CalibrateError> {
    let mut report = report;
    PaperFit::start(robot, data, opts, choice, &mut report)?
        .settle(robot, data, opts, settle, &mut report)
        .map(|(c, n, _, _)| (c, n))
}

/// The paper's calibration under a noise choice, in two stages: the first
/// fit ([`PaperFit::start`]: the white fit of `Auto`, or the fit with the
/// given model), then `Auto`'s settling ([`PaperFit::settle`]).
pub(crate) enum PaperFit {
    /// `White` or `Given`: the fit is final.
    Done(Box<(Calibration, Fit)>),
    /// `Auto`: the white fit, to settle.
    White(Box<(Calibration, Fit)>),
}

/// A calibration of the paper's model: its result, what the noise choice
/// did, the final fit and (`Auto`) the white fit it started from.
pub(crate) type PaperResult = (Calibration, NoiseOutcome, Fit, Option<Fit>);

fn no_outcome() -> NoiseOutcome {
    NoiseOutcome {
        white_test: None,
        identified: None,
        extra_white_tests: Vec::new(),
        extra_identified: Vec::new(),
        refits: 0,
        warning: None,
    }
}

impl PaperFit {
    /// The first fit of `choice`.
    pub(crate) fn start(
        robot: &Robot,
        data: &Measurements,
        opts: &CalibrateOptions,
        choice: &NoiseChoice,
        mut report: impl FnMut(&IterationRecord),
    ) -> Result<Self, CalibrateError> {
        // the choice's model for every IMU (Auto starts white)
        let with = |m: Option<NoiseModel>| CalibrateOptions {
            noise: m,
            imu_noise: Vec::new(),
            ..opts.clone()
        };
        let (o, done) = match choice {
            NoiseChoice::White => (with(None), true),
            NoiseChoice::Given(m) => (with(Some((**m).clone())), true),
            NoiseChoice::Auto => (with(None), false),
        };
        let f = fit(&FitSpec::baseline(robot, data), &o, &mut report)?;
        let cal = calibration_of(robot, &o, &f)?;
        Ok(match done {
            true => Self::Done(Box::new((cal, f))),
            false => Self::White(Box::new((cal, f))),
        })
    }

    /// The white fit of `Auto` (`None` for a given model).
    pub(crate) fn white(&self) -> Option<&Fit> {
        match self {
            Self::White(w) => Some(&w.1),
            Self::Done(_) => None,
        }
    }

    /// `Auto`'s settling from the white fit (see the module doc); a given
    /// model's fit as it is.
    pub(crate) fn settle(
        self,
        robot: &Robot,
        data: &Measurements,
        opts: &CalibrateOptions,
        settle: &Settle,
        mut report: impl FnMut(&IterationRecord),
    ) -> Result<PaperResult, CalibrateError> {
        let mut outcome = no_outcome();
        let (white, white_fit) = match self {
            Self::Done(d) => {
                let (cal, f) = *d;
                return Ok((cal, outcome, f, None));
            }
            Self::White(w) => *w,
        };
        let id_opts = IdOptions::default();
        let first = match fit_identifications(robot, data, &white_fit, &id_opts) {
            Ok(id) => id,
            Err(e) => {
                outcome.warning = Some(format!("noise not identified ({e}); white noise kept"));
                return Ok((white, outcome, white_fit.clone(), Some(white_fit)));
            }
        };
        outcome.white_test = Some(first[0].clone());
        outcome.extra_white_tests = first[1..].to_vec();
        let gls = |m: Vec<Option<NoiseModel>>| {
            let mut o = options_with(opts, m);
            o.lm.gradient_tolerance = o.lm.gradient_tolerance.max(REFIT_GRADIENT);
            o
        };
        let refits = std::cell::Cell::new(0);
        let settledfit = settle_noise(
            white_fit.clone(),
            first,
            settle,
            |previous, m| {
                refits.set(refits.get() + 1);
                let spec = FitSpec {
                    start: Start::Refit(previous),
                    ..FitSpec::baseline(robot, data)
                };
                fit(&spec, &gls(m), &mut report).map_err(|e| e.to_string())
            },
            |f| fit_identifications(robot, data, f, &id_opts),
        );
        outcome.refits = refits.get();
        match settledfit {
            Ok(s) if s.refits == 0 => Ok((white, outcome, white_fit.clone(), Some(white_fit))),
            Ok(s) => {
                let mut cal = calibration_of(robot, &gls(fit_wants(&s.fit)), &s.fit)?;
                cal.tau_initial = white.tau_initial;
                if let Some(mut used) = s.used {
                    outcome.extra_identified = used.split_off(1);
                    outcome.identified = used.pop();
                }
                Ok((cal, outcome, s.fit, Some(white_fit)))
            }
            Err(e) => {
                let kept = if e.starts_with("the identified noise model did not settle") {
                    "the white-noise result is kept and its σ are too small where the residuals are correlated"
                } else {
                    "white noise kept"
                };
                outcome.warning = Some(format!("{e}; {kept}"));
                Ok((white, outcome, white_fit.clone(), Some(white_fit)))
            }
        }
    }
}

/// The model an identification asks for: `None` (white) when every
/// channel passes the whiteness test or no AR order or motion level is
/// supported.
pub fn wanted(id: &Identification) -> Option<NoiseModel> {
    (!id.white.iter().all(|&w| w) && !id.model.is_white()).then(|| id.model.clone())
}

/// The outcome of [`settle_noise`].
#[derive(Debug, Clone)]
pub(crate) struct Settled {
    /// The settled fit (`start` itself when no refit was needed).
    pub fit: Fit,
    /// Refits made.
    pub refits: usize,
    /// The identifications (one per IMU identified) whose models the fit
    /// used (none without refit).
    pub used: Option<Vec<Identification>>,
}

/// `opts` with the noise model of each IMU (IMU j's `models[j]`, `None`:
/// white of σ_z; [`CalibrateOptions::imu_noise`]); one model, or every IMU
/// white, is `noise` alone (the one-IMU options exactly).
pub(crate) fn options_with(
    opts: &CalibrateOptions,
    mut models: Vec<Option<NoiseModel>>,
) -> CalibrateOptions {
    let mut o = opts.clone();
    o.noise = None;
    o.imu_noise = Vec::new();
    if models.len() == 1 {
        o.noise = models.pop().flatten();
    } else if models.iter().any(Option::is_some) {
        o.imu_noise = models
            .into_iter()
            .map(|m| {
                m.map_or_else(|| NoiseModel::white(opts.sigma_z), Ok)
                    .expect("positive sigma_z")
            })
            .collect();
    }
    o
}

/// The models of the fit `f` as [`options_with`] takes them (`None`: white).
pub(crate) fn fit_wants(f: &Fit) -> Vec<Option<NoiseModel>> {
    fit_models(f)
        .map(|m| (!m.is_white()).then(|| m.clone()))
        .collect()
}

/// The noise model of each IMU of the fit `f`, IMU 0's first.
pub(crate) fn fit_models(f: &Fit) -> impl Iterator<Item = &NoiseModel> {
    std::iter::once(&f.noise).chain(&f.extra_noise)
}

/// The one settle loop of `Auto` (calibrate's, diagnose's after each
/// effect): from the fit `start` and the identifications `ids` from its
/// residuals (IMU j's `ids[j]`; diagnose identifies IMU 0's alone), refit
/// (`refit(previous, models)`, one per identification, `None` for white)
/// with the models [`wanted`] asks for and identify again (`identify`),
/// until every IMU's wanted model is the one the fit used for it
/// ([`settled`], or both white) or `settle.max_refits` refits; else why not.
pub(crate) fn settle_noise(
    start: Fit,
    mut ids: Vec<Identification>,
    settle: &Settle,
    mut refit: impl FnMut(&Fit, Vec<Option<NoiseModel>>) -> Result<Fit, String>,
    mut identify: impl FnMut(&Fit) -> Result<Vec<Identification>, String>,
) -> Result<Settled, String> {
    let mut current = start;
    let mut used = None;
    for k in 0..=settle.max_refits {
        let want: Vec<Option<NoiseModel>> = ids.iter().map(wanted).collect();
        let same = want
            .iter()
            .zip(fit_models(&current))
            .all(|(want, used)| match want {
                None => used.is_white(),
                Some(m) => !used.is_white() && settled(m, used, settle),
            });
        if same {
            return Ok(Settled {
                fit: current,
                refits: k,
                used,
            });
        }
        if k == settle.max_refits {
            break;
        }
        current = refit(&current, want)
            .map_err(|e| format!("the refit with the identified noise failed ({e})"))?;
        used = Some(ids);
        ids = identify(&current)
            .map_err(|e| format!("noise identification failed after refit {} ({e})", k + 1))?;
    }
    Err(format!(
        "the identified noise model did not settle in {} refits",
        settle.max_refits
    ))
}

/// Whether two identified models agree (same orders, φ within
/// `settle.phi`, σ and motion gain within `settle.sigma` relative).
pub fn settled(a: &NoiseModel, b: &NoiseModel, settle: &Settle) -> bool {
    a.imu.iter().zip(&b.imu).all(|(a, b)| {
        let (pa, pb) = (a.ar.phi(), b.ar.phi());
        pa.len() == pb.len()
            && pa.iter().zip(pb).all(|(x, y)| (x - y).abs() < settle.phi)
            && (a.ar.sigma() / b.ar.sigma() - 1.0).abs() < settle.sigma
            && (a.motion - b.motion).abs() <= settle.sigma * a.motion.max(b.motion)
    })
}

/// The noise identified from the raw IMU residuals of `cal`, with ‖q̈‖² of
/// its trajectory as the motion regressor.
pub(crate) fn residual_identification(
    robot: &Robot,
    data: &Measurements,
    cal: &Calibration,
    opts: &IdOptions,
) -> Result<Identification, String> {
    identification_of(robot, data, &cal.x, &cal.trajectory, None, opts)
}

/// The identification from the raw residuals of every IMU j ≥ 1 of a
/// multi-IMU calibration (docs/model.md §9), each under its own parameters:
/// `(j, identification or why none)`. The verdict checks these against the
/// model the fit used for that IMU ([`Calibration::extra_noise_models`]).
pub(crate) fn other_imu_identifications(
    robot: &Robot,
    data: &Measurements,
    cal: &Calibration,
    opts: &IdOptions,
) -> Vec<(usize, Result<Identification, String>)> {
    let k = data.n_imus();
    let layout = ParamLayout::with_imus(robot, k);
    if cal.x.len() != layout.len() {
        return Vec::new();
    }
    (1..k)
        .map(|j| {
            let x = layout.imu_x(j, &cal.x);
            let id = identification_of(robot, &data.only_imu(j), &x, &cal.trajectory, None, opts);
            (j, id)
        })
        .collect()
}

/// The identification from the raw residuals of every IMU of the fit `f`
/// (IMU j's `[j]`), each under its own parameters (docs/model.md §9): IMU 0's
/// is [`residual_identification`] of its calibration. An IMU whitened by a
/// white model, in a fit without effects, hands over its residuals for the
/// samples it used: whitened by its σ_z (docs/model.md §4.4), times σ_z they
/// are the raw ones, so that only the samples in its end margins are
/// predicted again.
pub(crate) fn fit_identifications(
    robot: &Robot,
    data: &Measurements,
    f: &Fit,
    opts: &IdOptions,
) -> Result<Vec<Identification>, String> {
    let layout = ParamLayout::with_imus(robot, f.n_imus);
    let residuals = std::iter::once(&f.residuals).chain(&f.extra_residuals);
    fit_models(f)
        .zip(residuals)
        .enumerate()
        .map(|(j, (noise, residuals))| {
            let known = (noise.is_white() && f.effects.is_empty()).then(|| Known {
                residuals,
                sigma: noise.sigma_z(),
            });
            if j == 0 {
                identification_of(robot, data, &f.x, &f.trajectory, known, opts)
            } else {
                let x = layout.imu_x(j, &f.x);
                identification_of(robot, &data.only_imu(j), &x, &f.trajectory, known, opts)
                    .map_err(|e| format!("IMU {j}: {e}"))
            }
        })
        .collect()
}

/// Whitened residuals (sample index, r/σ_z) of a white fit at the x and
/// trajectory of an identification, in sample order, and σ_z.
struct Known<'a> {
    residuals: &'a [(usize, [f64; 6])],
    sigma: [f64; 6],
}

/// [`residual_identification`] at `x` and the joint trajectory `trajectory`
/// (`known`: the residuals of some samples, see [`fit_identifications`]).
/// The trajectory is evaluated by its span polynomials; the samples in two
/// halves, one per thread, joined in order.
fn identification_of(
    robot: &Robot,
    data: &Measurements,
    x: &[f64],
    trajectory: &Spline,
    known: Option<Known<'_>>,
    opts: &IdOptions,
) -> Result<Identification, String> {
    // IMU 0 (the prefix of x; docs/model.md §9)
    let layout = ParamLayout::new(robot);
    let x = &x[..layout.len()];
    let model = MeasurementModel::new(robot, &layout, x).map_err(|e| e.to_string())?;
    let tau = x[layout.offsets().tau];
    let n = robot.dof();
    let spans = SpanPolynomials::new(trajectory.knots());
    let known = known.unwrap_or(Known {
        residuals: &[],
        sigma: [1.0; 6],
    });
    let part = |range: std::ops::Range<usize>, cap: usize| {
        let (mut t, mut r, mut qdd2) = (
            Vec::with_capacity(cap),
            Vec::<[f64; 6]>::with_capacity(cap),
            Vec::with_capacity(cap),
        );
        let (mut js, mut b) = (JointState::default(), Basis::default());
        let mut qdd = [[F64x4::splat(0.0); MAX_JOINTS]; 1];
        let mut next = known.residuals.partition_point(|(i, _)| *i < range.start);
        let mut hint = 0;
        // four samples at a time: their q̈ from one four-lane basis when they
        // share a knot span (the bits of the scalar basis), else one by one
        for (quad, len) in quads(range) {
            let u = F64x4(quad.map(|i| data.imu_t[i] + tau));
            // q̈ alone (the row Spline::evaluate_basis computes)
            let inside = trajectory.rows_x4(&spans, u, [2], &mut hint, &mut qdd);
            for l in 0..len {
                let i = quad[l];
                if !inside[l] {
                    continue;
                }
                let (ti, z) = (data.imu_t[i], &data.imu_z[i]);
                while next < known.residuals.len() && known.residuals[next].0 < i {
                    next += 1;
                }
                let ri = match known.residuals.get(next) {
                    Some(&(k, w)) if k == i => std::array::from_fn(|c| w[c] * known.sigma[c]),
                    _ => {
                        spans.basis(ti + tau, &mut b).expect("inside the span");
                        trajectory.evaluate_basis(&b, &mut js);
                        let pred = model.predict(&js);
                        std::array::from_fn(|c| z[c] - pred[c])
                    }
                };
                t.push(ti);
                r.push(ri);
                qdd2.push(
                    qdd[0][..n]
                        .iter()
                        .map(|a| a.lane(l) * a.lane(l))
                        .sum::<f64>(),
                );
            }
        }
        (t, r, qdd2)
    };
    let len = data.imu_t.len().min(data.imu_z.len());
    let mid = len / 2;
    // the first half's storage holds the whole (no copy when joined)
    let ((mut t, mut r, mut qdd2), (t2, r2, q2)) =
        robimu_model::pair::join(|| part(0..mid, len), || part(mid..len, 0));
    t.extend(t2);
    r.extend(r2);
    qdd2.extend(q2);
    identify(&t, &r, Some(&qdd2), opts).map_err(|e| e.to_string())
}

#[cfg(test)]
#[path = "noise_choice_tests.rs"]
mod tests;
