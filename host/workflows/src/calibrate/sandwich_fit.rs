//! The sandwich covariance A⁻¹BA⁻¹ of the fit as written — its effects,
//! its GLS whitening (docs/model.md §4.6 *Sandwich of the written fit*):
//! what x̂'s spread is when the model is inadequate.
//!
//! The fit minimises J = ½‖w(θ)‖², w the whitened rows (IMU rows whitened
//! along time by the noise model, joint rows by σ_q, priors). When the
//! model is right the whitened IMU residuals are independent, so the
//! per-row scores g_t = W_tᵀ w_t are too, B = Cov(Σ g_t) = A, and the
//! sandwich is A⁻¹: no kernel over lags is needed for the noise (the
//! whitening did that). When the model lacks a term d(t) that follows the
//! motion, w_t = W_t δθ + d̃_t + noise, and the misfit's scores W_tᵀ d̃_t are
//! correlated over the motion's own time scale. B is then estimated from
//! the scores of time windows of `window` s, G_w = Σ_{t∈w} g_t (IMU rows
//! at their sample times, joint rows at theirs; [`Problem::window_gradients`]),
//! with a Bartlett kernel of `lags` windows over the sequence:
//!
//! ```text
//! B̂ = Σ_w G_w G_wᵀ + Σ_{l=1..L} (1 − l/(L+1)) Σ_w (G_w G_{w−l}ᵀ + G_{w−l} G_wᵀ) + P,
//! ```
//!
//! P the priors' information (x and θ_E: the prior's score at a truth drawn
//! from it has covariance P). Only x's block is formed: ψ_w = R G_w with
//! R = [A⁻¹]_{x,·}, Σ_x = R B̂ Rᵀ (the spline coefficients and θ_E are
//! profiled out, as in [`super::sandwich`]).

use faer::Mat;
use robimu_model::effects::EffectSet;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_solver::problem::Problem;

use super::fit::Fit;
use super::{CalibrateError, CalibrateOptions};
use robimu_solver::LeastSquares;

/// The sandwich covariance of a fit's x.
#[derive(Debug, Clone)]
pub struct FitSandwich {
    /// √diag of Σ_x per entry of x (0 when frozen).
    pub sigma: Vec<f64>,
    /// Σ_x over the active entries of x, in the fit's `active` order.
    pub covariance: Mat<f64>,
    /// The windows' length, s.
    pub window: f64,
    /// The Bartlett kernel's lags, in windows.
    pub lags: usize,
}

/// The sandwich covariance (module doc) of the one-IMU fit `f` of `data`
/// made with `opts` and the effects `set` (those of `f`, in its order),
/// from windows of `window` s and a Bartlett kernel of `lags` windows.
pub fn fit_sandwich(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    set: &EffectSet,
    f: &Fit,
    window: f64,
    lags: usize,
) -> Result<FitSandwich, CalibrateError> {
    if f.n_imus != 1 || data.n_imus() != 1 {
        return Err(CalibrateError::Input(
            "the sandwich covariance is for a one-IMU fit".into(),
        ));
    }
    if set.names() != f.effects {
        return Err(CalibrateError::Input(
            "the sandwich covariance needs the fit's own effects".into(),
        ));
    }
    if !(window.is_finite() && window > 0.0) {
        return Err(CalibrateError::Input(format!(
            "the sandwich's window must be a positive number of seconds (got {window})"
        )));
    }
    let layout = ParamLayout::new(robot);
    let (problem, r) = problem_of_fit((robot, &layout, data), opts, set, f)?;
    let theta = &f.theta;
    let na = problem.active().len();
    let edges = window_edges(data, window)?;
    let mut psi = Mat::<f64>::zeros(edges.len() - 1, na);
    problem.window_gradients(theta, &edges, |w, g| {
        for i in 0..na {
            let mut s = 0.0;
            for (j, v) in g.iter().enumerate() {
                if *v != 0.0 {
                    s += r[(i, j)] * v;
                }
            }
            psi[(w, i)] = s;
        }
    })?;
    let mut b = bartlett(&psi, lags);
    if opts.use_prior {
        add_prior(&r, &problem, &layout, set, &mut b);
    }
    Ok(FitSandwich {
        sigma: sigma_of(&b, problem.active(), layout.len()),
        covariance: b,
        window,
        lags,
    })
}

/// Window edges every `window` s over the span of every sample of `data`.
fn window_edges(data: &Measurements, window: f64) -> Result<Vec<f64>, CalibrateError> {
    let ends = [data.joint_t.first(), data.imu_t.first()];
    let t0 = ends.iter().flatten().fold(f64::INFINITY, |a, &b| a.min(*b));
    let ends = [data.joint_t.last(), data.imu_t.last()];
    let t1 = ends
        .iter()
        .flatten()
        .fold(f64::NEG_INFINITY, |a, &b| a.max(*b));
    if t1.partial_cmp(&t0) != Some(std::cmp::Ordering::Greater) {
        return Err(CalibrateError::Input("no samples to window".into()));
    }
    let n = ((t1 - t0) / window).floor() as usize + 1;
    if n < 2 {
        return Err(CalibrateError::Input(format!(
            "a sandwich needs more than one window of {window} s"
        )));
    }
    Ok((0..=n).map(|w| t0 + w as f64 * window).collect())
}

/// Adds the priors' part R P Rᵀ (x's and θ_E's) to `b`.
fn add_prior(
    r: &Mat<f64>,
    problem: &Problem,
    layout: &ParamLayout,
    set: &EffectSet,
    b: &mut Mat<f64>,
) {
    let (nc, na) = (problem.n_coeffs(), problem.active().len());
    let specs = layout.specs();
    let info = problem
        .active()
        .iter()
        .map(|&k| 1.0 / (specs[k].sigma * specs[k].sigma))
        .chain(
            set.params()
                .iter()
                .map(|p| 1.0 / (p.prior_sigma * p.prior_sigma)),
        );
    for (c, w) in info.enumerate() {
        for p in 0..na {
            for q in 0..na {
                b[(p, q)] += r[(p, nc + c)] * w * r[(q, nc + c)];
            }
        }
    }
}

/// The problem of the fit `f` of `data` as it was solved — its knots, x,
/// effects `set` and noise model (white: `opts`' σ) — and its influence
/// rows R at f's θ ([`influence_rows`]).
pub(super) fn problem_of_fit<'a>(
    (robot, layout, data): (&'a Robot, &'a ParamLayout, &'a Measurements),
    opts: &CalibrateOptions,
    set: &'a EffectSet,
    f: &Fit,
) -> Result<(Problem<'a>, Mat<f64>), CalibrateError> {
    let opts = CalibrateOptions {
        noise: (!f.noise.is_white()).then(|| f.noise.clone()),
        ..opts.clone()
    };
    let mut problem = Problem::new(
        robot,
        layout,
        data,
        f.trajectory.knots().clone(),
        f.x.clone(),
        &opts.problem_options(),
        set,
    )?;
    let r = influence_rows(&mut problem, &f.theta)?;
    Ok((problem, r))
}

/// √diag of Σ_x (`b`, over the `active` entries) per entry of an x of
/// `len` entries, 0 where frozen.
pub(super) fn sigma_of(b: &Mat<f64>, active: &[usize], len: usize) -> Vec<f64> {
    let mut sigma = vec![0.0; len];
    for (c, &k) in active.iter().enumerate() {
        sigma[k] = b[(c, c)].max(0.0).sqrt();
    }
    sigma
}

/// R = [A⁻¹]_{x,·} (active × all unknowns [c, x_a, θ_E]) of the normal
/// matrix A at θ: row a is A⁻¹ e_{nc+a} (A symmetric).
pub(super) fn influence_rows(
    problem: &mut Problem,
    theta: &[f64],
) -> Result<Mat<f64>, CalibrateError> {
    problem.begin_iteration(theta)?;
    let (nc, na) = (problem.n_coeffs(), problem.active().len());
    let nu = nc + na + problem.n_effect_params();
    let mut a = problem.new_matrix();
    let mut g = vec![0.0; nu];
    problem.linearize(theta, &mut a, &mut g)?;
    let factor = a
        .factor()
        .map_err(|e| CalibrateError::Input(format!("the normal matrix: {e}")))?;
    let mut r = Mat::<f64>::zeros(na, nu);
    let mut col = vec![0.0; nu];
    for i in 0..na {
        col.fill(0.0);
        col[nc + i] = 1.0;
        factor.solve_in_place(&mut col);
        for (j, v) in col.iter().enumerate() {
            r[(i, j)] = *v;
        }
    }
    Ok(r)
}

/// Σ_{t,s} w(t − s) ψ_t ψ_sᵀ over the rows ψ_t of `psi`, w the Bartlett
/// kernel 1 − |l|/(L+1) for |l| ≤ L: Ψᵀ (box ∗ box ∗ Ψ) / (L + 1).
pub(super) fn bartlett(psi: &Mat<f64>, l: usize) -> Mat<f64> {
    let (len, na) = (psi.nrows(), psi.ncols());
    let mut v = Mat::<f64>::zeros(len, na);
    // u runs L past the end, where it still sums the last ψ
    let ext = len + l;
    let mut u = vec![0.0; ext];
    for c in 0..na {
        // u_t = Σ_{k=0..L} ψ_{t−k} (ψ = 0 outside the series)
        let mut run = 0.0;
        for t in 0..ext {
            if t < len {
                run += psi[(t, c)];
            }
            if t > l {
                run -= psi[(t - l - 1, c)];
            }
            u[t] = run;
        }
        // v_t = Σ_{k=0..L} u_{t+k} = Σ_d (L + 1 − |d|) ψ_{t+d}
        let mut run: f64 = u[len..].iter().sum();
        for t in (0..len).rev() {
            run += u[t];
            if t + l + 1 < ext {
                run -= u[t + l + 1];
            }
            v[(t, c)] = run;
        }
    }
    let mut b = psi.transpose() * &v;
    let scale = 1.0 / (l + 1) as f64;
    for p in 0..na {
        for q in 0..p {
            let s = 0.5 * (b[(p, q)] + b[(q, p)]) * scale;
            b[(p, q)] = s;
            b[(q, p)] = s;
        }
        b[(p, p)] *= scale;
    }
    b
}
