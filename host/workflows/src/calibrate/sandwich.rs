//! Sandwich (heteroscedasticity- and autocorrelation-consistent, HAC)
//! covariance of a white-noise fit's x: what the white estimate's spread
//! really is when the IMU noise is correlated in time (docs/model.md §4.6;
//! a cross-check of the GLS fit's σ, not used by `calibrate`).
//!
//! The white fit θ̂ = [ĉ, x̂] minimises J = ½‖e(θ)‖², e the joint, IMU and
//! prior residuals whitened by their assumed σ (eq. (22)). To first order
//! θ̂ − θ = −A⁻¹ g, with g = Σ_i J_iᵀ e_i the score at the truth and A = JᵀJ
//! the Gauss–Newton matrix at the optimum (priors included), so
//!
//! ```text
//! Σ_θ = A⁻¹ B A⁻¹,   B = Cov(g),
//! ```
//!
//! which is the reported A⁻¹ only when the rows are independent with unit
//! variance (B = A). B is estimated from the per-sample score contributions
//! g_t = J_tᵀ e_t at θ̂ (the six rows of IMU sample t together, the n rows
//! of a joint sample together):
//!
//! ```text
//! B̂ = Σ_t g_t g_tᵀ + Σ_{l=1..L} (1 − l/(L+1)) Σ_t (g_t g_{t−l}ᵀ + g_{t−l} g_tᵀ)   (IMU, Newey–West)
//!   + Σ_s g_s g_sᵀ                                                            (joint samples, white)
//!   + P                                                                       (prior)
//! ```
//!
//! over the selected IMU samples in time order (Bartlett kernel of
//! bandwidth L; cross-channel correlation included, segments after gaps
//! simply joined), the joint samples as independent (lag 0), and the
//! prior's information P = diag(1/σ_k²): the prior term's score at a truth
//! drawn from the prior has covariance P, so that with white noise
//! B = A in expectation and the sandwich is A⁻¹ (the Bayesian posterior
//! covariance that the Monte Carlo checks).
//!
//! **The spline coefficients are nuisance parameters.** θ holds ~1 800
//! coefficients besides x; B over θ is never formed. Σ_x = R B Rᵀ with
//! R = [A⁻¹]_{x,·} (the x rows of A⁻¹: one arrowhead solve per parameter),
//! so each contribution is reduced to its influence on x, ψ_t = R g_t, and
//! B̂ is accumulated over the 48-vectors ψ_t. This is the sandwich of x with
//! c profiled out: R g = S⁻¹ (g_x − A_xc A_cc⁻¹ g_c) (S the Schur complement),
//! the score of x with the spline directions projected out, and R A Rᵀ = S⁻¹.
//! The Bartlett sum is Ψᵀ W Ψ with W the banded Toeplitz matrix of the
//! kernel, computed as two running box sums (the triangle is a box
//! convolved with itself): O(N·48) for any L.
//!
//! **Bandwidth** ([`bandwidth`]): L = ⌈25 T/Δt⌉ from the largest
//! correlation time T of a noise model identified from the residuals
//! ([`robimu_model::noise::ArNoise::correlation_time`]; for AR(1) the
//! Bartlett kernel's downward bias of the long-run variance is then about
//! 2φ/((1 − φ²)(L + 1)) < 5 %), the Newey–West rule ⌊4 (N/100)^{2/9}⌋ when
//! it is white; at most N/4.

use faer::Mat;
use robimu_model::effects::EffectSet;
use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::{
    Basis, JointState, Knots, MeasurementJacobians, MeasurementModel, ParamLayout, Robot, Spline,
};

use super::fit::Fit;
use super::sandwich_fit::{bartlett, problem_of_fit, sigma_of};
use super::{CalibrateError, CalibrateOptions};

/// The sandwich covariance of a white fit's x.
#[derive(Debug, Clone)]
pub(crate) struct Sandwich {
    /// √diag of Σ_x per entry of x (0 when frozen).
    pub sigma: Vec<f64>,
}

/// The bandwidth L for `samples` IMU samples `dt` apart whose noise is
/// `model` (module doc).
pub fn bandwidth(model: &NoiseModel, dt: f64, samples: usize) -> usize {
    let t = model
        .imu
        .iter()
        .map(|c| c.ar.correlation_time(dt))
        .fold(0.0, f64::max);
    let l = if t > 0.0 {
        (25.0 * t / dt).ceil() as usize
    } else {
        (4.0 * (samples as f64 / 100.0).powf(2.0 / 9.0)).floor() as usize
    };
    l.min(samples / 4)
}

/// The sandwich covariance (module doc) of the white-noise baseline fit `f`
/// of `data`, made with `opts`, with Bartlett bandwidth `bandwidth`.
pub fn sandwich(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    f: &Fit,
    bandwidth: usize,
) -> Result<Sandwich, CalibrateError> {
    if !f.noise.is_white() || !f.effects.is_empty() {
        return Err(CalibrateError::Input(
            "the sandwich covariance is for a white-noise fit of the baseline model".into(),
        ));
    }
    let layout = ParamLayout::new(robot);
    let (problem, r) = problem_of_fit((robot, &layout, data), opts, EffectSet::none(), f)?;
    let theta = &f.theta;
    let x = problem.x_of(theta);
    let inf = Influence {
        r: &r,
        nc: problem.n_coeffs(),
        spline: problem.spline_of(theta),
        knots: problem.knots(),
        n: robot.dof(),
        active: problem.active().to_vec(),
    };
    let tau = x[layout.offsets().tau];
    let model = problem.model(&x)?;
    let psi = inf.imu_scores(
        data,
        &model,
        tau,
        &opts.sigma_z,
        problem.imu_range(),
        &layout,
    )?;
    let mut b = bartlett(&psi, bandwidth);
    // joint samples: white, lag 0
    inf.add_joint_scores(data, &opts.sigma_q, &mut b)?;
    // the prior: R_x P R_xᵀ
    if opts.use_prior {
        inf.add_prior(&layout, &mut b);
    }
    Ok(Sandwich {
        sigma: sigma_of(&b, &inf.active, layout.len()),
    })
}

/// The influence ψ = R g of each sample's gradient g on x, at the fit.
struct Influence<'a> {
    /// [`influence_rows`].
    r: &'a Mat<f64>,
    /// Spline coefficients (the first unknowns).
    nc: usize,
    spline: Spline,
    knots: &'a Knots,
    /// Joints.
    n: usize,
    /// The active entries of x.
    active: Vec<usize>,
}

impl Influence<'_> {
    /// ψ = R g for a sparse g: band entries from `first·n`, then x_a.
    fn apply(&self, first: usize, band: &[f64], gx: &[f64], out: &mut [f64]) {
        let (r, nc) = (self.r, self.nc);
        for (i, o) in out.iter_mut().enumerate() {
            let mut s = 0.0;
            for (j, v) in band.iter().enumerate() {
                s += r[(i, first + j)] * v;
            }
            for (j, v) in gx.iter().enumerate() {
                s += r[(i, nc + j)] * v;
            }
            *o = s;
        }
    }

    /// Ψ: one row ψ_t per IMU sample of `range` (white residuals with σ
    /// `sz`, under `model` with time offset `tau`).
    fn imu_scores(
        &self,
        data: &Measurements,
        model: &MeasurementModel,
        tau: f64,
        sz: &[f64; 6],
        range: std::ops::Range<usize>,
        layout: &ParamLayout,
    ) -> Result<Mat<f64>, CalibrateError> {
        let (n, na, knots) = (self.n, self.active.len(), self.knots);
        let len = range.len();
        let mut psi = Mat::<f64>::zeros(len, na);
        let (mut basis, mut js) = (Basis::default(), JointState::default());
        let mut jac = MeasurementJacobians::new(layout.len());
        let nl = (knots.degree() + 1) * n;
        let (mut band, mut gx, mut out) = (vec![0.0; nl], vec![0.0; na], vec![0.0; na]);
        for (row, i) in range.enumerate() {
            knots.basis(data.imu_t[i] + tau, &mut basis)?;
            self.spline.evaluate_basis(&basis, &mut js);
            model.jacobians(&js, &mut jac);
            band.fill(0.0);
            gx.fill(0.0);
            for ch in 0..6 {
                let w = 1.0 / sz[ch];
                let e = (data.imu_z[i][ch] - jac.z[ch]) * w;
                // J = −∂h/∂θ / σ
                for a in 0..basis.count {
                    let (n0, n1, n2) = (basis.d[0][a], basis.d[1][a], basis.d[2][a]);
                    for j in 0..n {
                        band[a * n + j] -= w
                            * e
                            * (jac.dz_dq[j][ch] * n0
                                + jac.dz_dqd[j][ch] * n1
                                + jac.dz_dqdd[j][ch] * n2);
                    }
                }
                for (ga, &k) in gx.iter_mut().zip(&self.active) {
                    *ga -= w * e * jac.dz_dx[k][ch];
                }
            }
            self.apply(basis.first * n, &band[..basis.count * n], &gx, &mut out);
            for (c, v) in out.iter().enumerate() {
                psi[(row, c)] = *v;
            }
        }
        Ok(psi)
    }

    /// Adds ψ_s ψ_sᵀ of every joint sample (white, lag 0; σ `sigma_q`) to `b`.
    fn add_joint_scores(
        &self,
        data: &Measurements,
        sigma_q: &[f64],
        b: &mut Mat<f64>,
    ) -> Result<(), CalibrateError> {
        let (n, na, knots) = (self.n, self.active.len(), self.knots);
        let coeffs = self.spline.coeffs();
        let mut basis = Basis::default();
        let nl = (knots.degree() + 1) * n;
        let (mut band, gx, mut out) = (vec![0.0; nl], vec![0.0; na], vec![0.0; na]);
        for (s, &t) in data.joint_t.iter().enumerate() {
            knots.basis(t, &mut basis)?;
            band.fill(0.0);
            for j in 0..n {
                let mut q = 0.0;
                for a in 0..basis.count {
                    q += basis.d[0][a] * coeffs[(basis.first + a) * n + j];
                }
                let w = 1.0 / sigma_q[j];
                let e = (data.joint_q[s * n + j] - q) * w;
                for a in 0..basis.count {
                    band[a * n + j] -= w * e * basis.d[0][a];
                }
            }
            self.apply(basis.first * n, &band[..basis.count * n], &gx, &mut out);
            for p in 0..na {
                for q in 0..na {
                    b[(p, q)] += out[p] * out[q];
                }
            }
        }
        Ok(())
    }

    /// Adds the prior's part R_x P R_xᵀ to `b`.
    fn add_prior(&self, layout: &ParamLayout, b: &mut Mat<f64>) {
        let (r, nc, na) = (self.r, self.nc, self.active.len());
        let specs = layout.specs();
        for (c, &k) in self.active.iter().enumerate() {
            let info = 1.0 / (specs[k].sigma * specs[k].sigma);
            for p in 0..na {
                for q in 0..na {
                    b[(p, q)] += r[(p, nc + c)] * info * r[(q, nc + c)];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box-sum form equals the Bartlett double sum written out.
    #[test]
    fn bartlett_matches_the_double_sum() {
        let (len, na, l) = (40, 3, 5);
        let psi = Mat::from_fn(len, na, |t, c| ((t * 7 + c * 3) as f64 * 0.37).sin());
        let b = bartlett(&psi, l);
        for p in 0..na {
            for q in 0..na {
                let mut s = 0.0;
                for t in 0..len {
                    for u in 0..len {
                        let d = t.abs_diff(u);
                        if d <= l {
                            s += (1.0 - d as f64 / (l + 1) as f64) * psi[(t, p)] * psi[(u, q)];
                        }
                    }
                }
                assert!((b[(p, q)] - s).abs() < 1e-12 * s.abs().max(1.0), "{p},{q}");
            }
        }
    }
}
