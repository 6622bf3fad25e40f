//! Identification of a channel's noise model from its residuals: the
//! correlation in time (a stationary AR(p), [`robimu_model::noise::ArNoise`])
//! and a level that follows the motion (docs/model.md §4.6).
//!
//! Input: the residuals r_i of one channel at sample times t_i and,
//! optionally, the motion regressor x_i = ‖q̈(t_i)‖². The stream is split
//! into segments where a step exceeds [`IdOptions::gap_factor`] × the median
//! step; no prediction reaches across a gap.
//!
//! * **AR order and coefficients**: Burg's method, pooled over the segments
//!   (the reflection coefficient of order m is 2Σf_t b_{t−1} / Σ(f_t² +
//!   b_{t−1}²), the forward and backward prediction errors summed over every
//!   segment), for p = 0..=p_max with p_max = min([`IdOptions::max_order`],
//!   N/20). The order minimises BIC = N ln v_p + p ln N (v_p the order-p
//!   prediction-error variance): an order is chosen only where the data
//!   support it (a coefficient costs ln N ≈ 10 in −2 ln L). Burg's
//!   estimate is always stationary (|k_m| ≤ 1 by Cauchy–Schwarz).
//! * **Motion level**: the residuals are whitened with the AR model; under
//!   σ²(t) = σ² + c x the whitened squares have E[w_i²] ∝ 1 + (c/σ²) x_i.
//!   Least squares of w_i² on (1, x_i) gives the slope κ = c/σ² with a
//!   heteroscedasticity-robust (HC1) standard error; c > 0 is accepted only
//!   when t = κ/se(κ) > [`IdOptions::motion_t`], otherwise c = 0. When
//!   accepted, σ² at rest is mean(r²)/(1 + κ x̄) and the AR is refitted to
//!   the residuals divided by their level s_i.
//! * **Residuals of a flexible fit** (a spline over time, `robimu noise`):
//!   the fit removes the noise's slow part, so even white noise leaves
//!   correlated residuals; [`identify_channel_with`] corrects the sample
//!   autocovariances by the fit's imprint on white noise, γ_k = c_k +
//!   S(0)·imprint_k (S(0) to a fixed point), and fits the AR to those by
//!   Levinson–Durbin.
//! * **Whiteness**: Ljung–Box ([`crate::stats::ljung_box`], 20 lags) on
//!   the residuals as given (H0: white) and on the whitened residuals (H0:
//!   the AR model is adequate; χ² with lags − p dof). Over the six IMU
//!   channels, [`white_by_bonferroni`] rejects whiteness of a channel when
//!   its p-value is below α/6.

use robimu_model::noise::{ArNoise, ChannelNoise, NoiseModel, NoiseModelError};
use robimu_session::IMU_COLUMNS;

use crate::stats::{chi2_sf, ljung_box, LJUNG_BOX_LAGS};

/// Fewest samples accepted: order 1 needs N/20 ≥ 1.
pub const MIN_SAMPLES: usize = 20;

/// Settings of the identification.
#[derive(Debug, Clone, PartialEq)]
pub struct IdOptions {
    /// Largest AR order tried (further limited to N/20).
    pub max_order: usize,
    /// A step longer than this × the median step starts a new segment.
    pub gap_factor: f64,
    /// t statistic above which a motion gain is accepted.
    pub motion_t: f64,
    /// Ljung–Box lags.
    pub lags: usize,
}

impl Default for IdOptions {
    /// p_max = 8, gaps at 1.5 × the median step, t > 4, 20 lags.
    fn default() -> Self {
        Self {
            max_order: 8,
            gap_factor: 1.5,
            motion_t: 4.0,
            lags: LJUNG_BOX_LAGS,
        }
    }
}

/// Why a channel's noise could not be identified.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NoiseIdError {
    /// Too few samples for any AR order.
    #[error(
        "{channel}: {count} residuals are too few to identify the noise (need at least {need})"
    )]
    TooShort {
        /// The channel.
        channel: String,
        /// Samples given.
        count: usize,
        /// Samples needed.
        need: usize,
    },
    /// Lengths differ, values are not finite, times do not increase, or the
    /// residuals are all zero.
    #[error("{channel}: {message}")]
    BadSamples {
        /// The channel.
        channel: String,
        /// What is wrong.
        message: String,
    },
    /// The identified model was refused by the model layer.
    #[error("{channel}: {source}")]
    Model {
        /// The channel.
        channel: String,
        /// The cause.
        source: NoiseModelError,
    },
}

/// Burg's estimates of every order 0..=p_max, pooled over segments.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Burg {
    /// Reflection coefficients k_1…k_pmax.
    pub reflection: Vec<f64>,
    /// Prediction-error variances v_0 (the mean square) … v_pmax.
    pub error_variance: Vec<f64>,
    /// Samples used (the sum of the segment lengths).
    pub samples: usize,
}

impl Burg {
    /// The AR coefficients φ_1…φ_p of order p ≤ p_max (Levinson step-up of
    /// k_1…k_p).
    pub fn phi(&self, p: usize) -> Vec<f64> {
        let mut a: Vec<f64> = Vec::new();
        for &k in &self.reflection[..p] {
            let m = a.len() + 1;
            let mut next: Vec<f64> = (0..m - 1).map(|j| a[j] - k * a[m - 2 - j]).collect();
            next.push(k);
            a = next;
        }
        a
    }

    /// BIC of order p: N ln v_p + p ln N.
    pub fn bic(&self, p: usize) -> f64 {
        let n = self.samples as f64;
        n * self.error_variance[p].ln() + p as f64 * n.ln()
    }

    /// The order of least BIC.
    pub fn best_order(&self) -> usize {
        (0..self.error_variance.len())
            .min_by(|&a, &b| self.bic(a).total_cmp(&self.bic(b)))
            .unwrap_or(0)
    }
}

/// Burg's method over `segments` (each a run of equally spaced samples,
/// taken as zero-mean), orders 0..=`max_order`.
pub(crate) fn burg(segments: &[&[f64]], max_order: usize) -> Burg {
    let samples: usize = segments.iter().map(|s| s.len()).sum();
    let mut f: Vec<Vec<f64>> = segments.iter().map(|s| s.to_vec()).collect();
    let mut b = f.clone();
    let ss: f64 = f.iter().flatten().map(|v| v * v).sum();
    let mut v = vec![ss / samples.max(1) as f64];
    let mut reflection = Vec::with_capacity(max_order);
    // order 1's sums; each order's update then sums the next order's terms
    // as it makes them (Σ over segments, t ascending: the order of a pass
    // of their own)
    let (mut num, mut den) = (0.0, 0.0);
    if max_order >= 1 {
        for fs in &f {
            for w in fs.windows(2) {
                // f_t and b_{t−1} (b = f at order 0), t = 1..len
                let (ft, bt) = (w[1], w[0]);
                num += ft * bt;
                den += ft * ft + bt * bt;
            }
        }
    }
    for m in 1..=max_order {
        let k = if den > 0.0 { 2.0 * num / den } else { 0.0 };
        (num, den) = (0.0, 0.0);
        for (fs, bs) in f.iter_mut().zip(b.iter_mut()) {
            if fs.len() <= m {
                continue;
            }
            // b_{t−1} of order m − 1 kept before b_{t−1} is overwritten;
            // `made`: b_{t−1} of order m
            let mut prev = bs[m - 1];
            let mut made = None;
            let next = m < max_order;
            for (f, b) in fs[m..].iter_mut().zip(&mut bs[m..]) {
                let (ft, bt) = (*f, prev);
                prev = *b;
                *f = ft - k * bt;
                *b = bt - k * ft;
                // order m + 1's terms, t = m + 1..len
                if let (true, Some(bt)) = (next, made) {
                    let ft = *f;
                    num += ft * bt;
                    den += ft * ft + bt * bt;
                }
                made = Some(*b);
            }
        }
        reflection.push(k);
        v.push(v[m - 1] * (1.0 - k * k));
    }
    Burg {
        reflection,
        error_variance: v,
        samples,
    }
}

/// Index ranges of the segments of `t`: a step above `gap_factor` × the
/// median step starts a new one.
pub fn segments(t: &[f64], gap_factor: f64) -> Vec<std::ops::Range<usize>> {
    segments_at(t, gap_factor, median_step(t))
}

/// [`segments`] with the median step `median` of `t` given.
fn segments_at(t: &[f64], gap_factor: f64, median: f64) -> Vec<std::ops::Range<usize>> {
    if t.len() < 2 {
        return std::iter::once(0..t.len()).collect();
    }
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..t.len() {
        if t[i] - t[i - 1] > gap_factor * median {
            out.push(start..i);
            start = i;
        }
    }
    out.push(start..t.len());
    out
}

/// The segments and the median step of one stream's times, shared by its
/// channels.
struct Timing {
    segs: Vec<std::ops::Range<usize>>,
    dt: f64,
}

impl Timing {
    fn of(t: &[f64], gap_factor: f64) -> Self {
        let dt = median_step(t);
        Self {
            segs: segments_at(t, gap_factor, dt),
            dt,
        }
    }
}

/// The median step of `t`, s (0 for fewer than two samples).
fn median_step(t: &[f64]) -> f64 {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return 0.0;
    }
    let mid = steps.len() / 2;
    *steps.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The whitened residuals w_t of each segment under `ar` (unit variance
/// when the model holds), concatenated.
pub fn whiten(ar: &ArNoise, r: &[f64], segs: &[std::ops::Range<usize>]) -> Vec<f64> {
    let mut w = Vec::with_capacity(r.len());
    let p = ar.order();
    let (a, scale) = ar.whitening(p);
    for s in segs {
        let u = &r[s.clone()];
        let head = p.min(u.len());
        for t in 0..head {
            let (a, scale) = ar.whitening(t);
            let pred: f64 = a.iter().enumerate().map(|(k, ak)| ak * u[t - k - 1]).sum();
            w.push(scale * (u[t] - pred));
        }
        // from sample p on, the order-p predictor: u_{t−1} … u_{t−p} is
        // the window before u_t, latest first
        for (win, &ut) in u.windows(p + 1).zip(&u[head..]) {
            let pred: f64 = a
                .iter()
                .zip(win[..p].iter().rev())
                .map(|(ak, uk)| ak * uk)
                .sum();
            w.push(scale * (ut - pred));
        }
    }
    w
}

/// The identified noise of one channel, with what a white model would miss.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelIdentification {
    /// The channel's name.
    pub channel: String,
    /// The model: AR at rest and the motion gain.
    pub noise: ChannelNoise,
    /// AR order p chosen by BIC.
    pub order: usize,
    /// φ_1…φ_p.
    pub phi: Vec<f64>,
    /// Asymptotic standard errors of φ (√diag(σ_e² Γ_p⁻¹ / N)).
    pub phi_std_error: Vec<f64>,
    /// Marginal σ at rest, the channel's unit.
    pub sigma: f64,
    /// Motion gain c (unit² per (rad/s²)²), 0 unless significant.
    pub motion: f64,
    /// t statistic of the motion slope (0 without a motion regressor).
    pub motion_t: f64,
    /// Integrated correlation time, s.
    pub correlation_time_s: f64,
    /// N_eff/N for a slowly varying regressor (1/low-frequency ratio).
    pub n_eff_fraction: f64,
    /// Factor by which a white model understates the σ of a slowly
    /// determined parameter: √(S(0)/σ²).
    pub sigma_understatement: f64,
    /// Ljung–Box p-value of the residuals as given (H0: white).
    pub ljung_box_p: f64,
    /// Ljung–Box p-value of the whitened residuals (H0: the AR is adequate).
    pub ljung_box_whitened_p: f64,
    /// Factor by which the correlation left in the whitened residuals
    /// still understates the σ of a slowly determined parameter (√ of
    /// their low-frequency ratio, from an AR fitted to them by BIC; 1 when
    /// the model captures the correlation): how much a failed
    /// `ljung_box_whitened_p` matters.
    pub whitened_understatement: f64,
    /// Samples and segments used.
    pub samples: usize,
    /// Segments (runs without a gap).
    pub segments: usize,
    /// Median sample step, s.
    pub dt: f64,
}

/// σ_e² Γ_p⁻¹ / N diagonal, square-rooted (Cholesky of the p×p Toeplitz Γ).
fn phi_std_errors(ar: &ArNoise, n: usize) -> Vec<f64> {
    let p = ar.order();
    if p == 0 {
        return Vec::new();
    }
    let g = ar.autocovariance(p);
    let mut l = vec![vec![0.0; p]; p];
    for i in 0..p {
        for j in 0..=i {
            let mut s = g[i - j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            l[i][j] = if i == j {
                s.max(0.0).sqrt()
            } else {
                s / l[j][j]
            };
        }
    }
    let se2 = ar.innovation_sigma().powi(2);
    (0..p)
        .map(|c| {
            // column c of Γ⁻¹ = L⁻ᵀ L⁻¹ e_c; its c-th entry is ‖L⁻¹ e_c‖².
            let mut y = vec![0.0; p];
            for i in 0..p {
                let mut s = if i == c { 1.0 } else { 0.0 };
                for k in 0..i {
                    s -= l[i][k] * y[k];
                }
                y[i] = s / l[i][i];
            }
            let d: f64 = y.iter().map(|v| v * v).sum();
            (se2 * d / n as f64).sqrt()
        })
        .collect()
}

/// Least squares y = α + κx with the HC1 standard error of κ: (α, κ, se κ).
fn robust_slope(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    if sxx <= 0.0 {
        return (my, 0.0, f64::INFINITY);
    }
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let kappa = sxy / sxx;
    let alpha = my - kappa * mx;
    let meat: f64 = x
        .iter()
        .zip(y)
        .map(|(a, b)| {
            let e = b - alpha - kappa * a;
            (a - mx) * (a - mx) * e * e
        })
        .sum();
    let se = (meat * n / (n - 2.0).max(1.0)).sqrt() / sxx;
    (alpha, kappa, se)
}

/// Ljung–Box p-value of the concatenated segments with `dof` degrees of freedom.
fn ljung_box_p(r: &[f64], lags: usize, dof: usize) -> f64 {
    let (q, _) = ljung_box(r, lags);
    chi2_sf(q, dof.max(1) as f64)
}

/// Identify the noise of one channel from its residuals `r` at times `t`
/// (with the motion regressor `qdd2` = ‖q̈‖² per sample, when given); see
/// the module doc.
#[cfg(test)]
pub(crate) fn identify_channel(
    channel: &str,
    t: &[f64],
    r: &[f64],
    qdd2: Option<&[f64]>,
    opts: &IdOptions,
) -> Result<ChannelIdentification, NoiseIdError> {
    identify_channel_with(channel, t, r, qdd2, opts, None)
}

/// Σ over segments of Σ_t u_t u_{t−k}, over the total sample count, k = 0..=lags.
fn pooled_autocovariance(parts: &[&[f64]], lags: usize) -> Vec<f64> {
    let n: usize = parts.iter().map(|p| p.len()).sum();
    (0..=lags)
        .map(|k| {
            parts
                .iter()
                .map(|u| (k..u.len()).map(|i| u[i] * u[i - k]).sum::<f64>())
                .sum::<f64>()
                / n.max(1) as f64
        })
        .collect()
}

/// Levinson–Durbin on autocovariances γ_0…γ_pmax, as a [`Burg`] (orders
/// stop before the first |k| ≥ 1, where γ is not positive definite).
fn levinson(g: &[f64], samples: usize) -> Burg {
    let mut a: Vec<f64> = Vec::new();
    let mut v = vec![g[0]];
    let mut reflection = Vec::new();
    for m in 1..g.len() {
        let s: f64 = (0..m - 1).map(|j| a[j] * g[m - 1 - j]).sum();
        let k = (g[m] - s) / v[m - 1];
        if k.is_nan() || k.abs() >= 1.0 {
            break;
        }
        let mut next: Vec<f64> = (0..m - 1).map(|j| a[j] - k * a[m - 2 - j]).collect();
        next.push(k);
        a = next;
        reflection.push(k);
        v.push(v[m - 1] * (1.0 - k * k));
    }
    Burg {
        reflection,
        error_variance: v,
        samples,
    }
}

/// The AR fit of `parts`: Burg, or with an `imprint` the corrected
/// Yule–Walker fit (γ_k = c_k + S(0)·imprint_k, S(0) = σ_e²/(1 − Σφ)² to a
/// fixed point). Returns (φ, γ_0).
fn fit_ar(parts: &[&[f64]], p_max: usize, imprint: Option<&[f64]>) -> (Vec<f64>, f64) {
    let Some(imp) = imprint else {
        let b = burg(parts, p_max);
        let p = b.best_order();
        return (b.phi(p), b.error_variance[0]);
    };
    let n: usize = parts.iter().map(|p| p.len()).sum();
    let p_max = p_max.min(imp.len() - 1);
    let c = pooled_autocovariance(parts, p_max);
    let mut s0 = c[0] / (1.0 - imp[0]).max(1e-3);
    let mut out = (Vec::new(), c[0] + s0 * imp[0]);
    for _ in 0..50 {
        let g: Vec<f64> = (0..=p_max).map(|k| c[k] + s0 * imp[k]).collect();
        let b = levinson(&g, n);
        let p = b.best_order();
        let phi = b.phi(p);
        let sum: f64 = phi.iter().sum();
        let next = b.error_variance[p] / ((1.0 - sum) * (1.0 - sum)).max(1e-12);
        out = (phi, g[0]);
        if (next - s0).abs() <= 1e-9 * s0 {
            break;
        }
        s0 = next;
    }
    out
}

/// Ljung–Box p-value with `dof` degrees of freedom; with an `imprint` the
/// autocovariances are first corrected as for white noise (S(0) = γ_0).
fn ljung_box_corrected(r: &[f64], lags: usize, dof: usize, imprint: Option<&[f64]>) -> f64 {
    let Some(imp) = imprint else {
        return ljung_box_p(r, lags, dof);
    };
    let n = r.len();
    let lags = lags.min(imp.len() - 1).min(n.saturating_sub(2));
    let c = pooled_autocovariance(&[r], lags);
    let s0 = c[0] / (1.0 - imp[0]).max(1e-3);
    let g0 = c[0] + s0 * imp[0];
    if g0 <= 0.0 {
        return 1.0;
    }
    let nf = n as f64;
    let q: f64 = (1..=lags)
        .map(|k| {
            let rho = (c[k] + s0 * imp[k]) / g0;
            rho * rho / (nf - k as f64)
        })
        .sum::<f64>()
        * nf
        * (nf + 2.0);
    chi2_sf(q, dof.max(1) as f64)
}

/// [`identify_channel`] for residuals of a linear fit (a spline over time)
/// that has left its `imprint` on them: for unit white noise the fit's
/// residuals have E[c_k] = δ_k − imprint_k (k = 0…, at least p_max and the
/// Ljung–Box lags; estimate it by fitting white draws). The AR is then
/// fitted to autocovariances corrected by S(0)·imprint_k — valid when the
/// fit varies slowly on the noise's correlation time — and Ljung–Box tests
/// the corrected autocorrelations.
pub(crate) fn identify_channel_with(
    channel: &str,
    t: &[f64],
    r: &[f64],
    qdd2: Option<&[f64]>,
    opts: &IdOptions,
    imprint: Option<&[f64]>,
) -> Result<ChannelIdentification, NoiseIdError> {
    identify_channel_timed(channel, t, r, qdd2, opts, imprint, None)
}

/// [`identify_channel_with`] with the [`Timing`] of `t` given (computed here
/// when `None`).
fn identify_channel_timed(
    channel: &str,
    t: &[f64],
    r: &[f64],
    qdd2: Option<&[f64]>,
    opts: &IdOptions,
    imprint: Option<&[f64]>,
    timing: Option<&Timing>,
) -> Result<ChannelIdentification, NoiseIdError> {
    let bad = |message: String| NoiseIdError::BadSamples {
        channel: channel.to_string(),
        message,
    };
    let n = r.len();
    if t.len() != n || qdd2.is_some_and(|x| x.len() != n) {
        return Err(bad(format!(
            "{} times, {} residuals and {} motion values",
            t.len(),
            n,
            qdd2.map_or(n, <[f64]>::len)
        )));
    }
    if n < MIN_SAMPLES {
        return Err(NoiseIdError::TooShort {
            channel: channel.to_string(),
            count: n,
            need: MIN_SAMPLES,
        });
    }
    let finite = |v: &[f64]| v.iter().position(|x| !x.is_finite());
    if let Some(i) = finite(t)
        .or_else(|| finite(r))
        .or_else(|| qdd2.and_then(finite))
    {
        return Err(bad(format!("sample {} is not finite", i + 1)));
    }
    if let Some(i) = (1..n).find(|&i| t[i] <= t[i - 1]) {
        return Err(bad(format!("time does not increase at sample {}", i + 1)));
    }
    let model_err = |source| NoiseIdError::Model {
        channel: channel.to_string(),
        source,
    };
    let own;
    let timing = match timing {
        Some(timing) => timing,
        None => {
            own = Timing::of(t, opts.gap_factor);
            &own
        }
    };
    let segs = &timing.segs;
    let p_max = opts.max_order.min(n / 20);
    let mean = r.iter().sum::<f64>() / n as f64;
    let r: Vec<f64> = r.iter().map(|v| v - mean).collect();
    let fit = |u: &[f64]| {
        let parts: Vec<&[f64]> = segs.iter().map(|s| &u[s.clone()]).collect();
        fit_ar(&parts, p_max, imprint)
    };
    let (mut phi, ms) = fit(&r);
    if ms <= 0.0 {
        return Err(bad("every residual is zero".into()));
    }
    let mut sigma2 = ms;
    let (mut motion, mut motion_t) = (0.0, 0.0);
    if let Some(x) = qdd2 {
        let ar = ArNoise::new(phi.clone(), ms.sqrt()).map_err(model_err)?;
        let w2: Vec<f64> = whiten(&ar, &r, segs).iter().map(|w| w * w).collect();
        let (alpha, kappa, se) = robust_slope(x, &w2);
        motion_t = if se > 0.0 { kappa / se } else { 0.0 };
        if kappa > 0.0 && alpha > 0.0 && motion_t > opts.motion_t {
            let kappa = kappa / alpha;
            // refit the correlation to the residuals at the level of rest;
            // their mean square is σ² at rest (≈ mean(r²)/(1 + κ x̄))
            let u: Vec<f64> = r
                .iter()
                .zip(x)
                .map(|(v, xi)| v / (1.0 + kappa * xi).sqrt())
                .collect();
            let (phi2, ms2) = fit(&u);
            phi = phi2;
            sigma2 = ms2;
            motion = kappa * sigma2;
        }
    }
    let ar = ArNoise::new(phi.clone(), sigma2.sqrt()).map_err(model_err)?;
    let noise = ChannelNoise::new(ar.clone(), motion).map_err(model_err)?;
    let dt = timing.dt;
    // whitened residuals at the level of rest (levels divided out)
    let level: Vec<f64> = match qdd2 {
        Some(x) => x.iter().map(|&xi| noise.level(xi)).collect(),
        None => vec![1.0; n],
    };
    let u: Vec<f64> = r.iter().zip(&level).map(|(v, s)| v / s).collect();
    let w = whiten(&ar, &u, segs);
    let p = ar.order();
    let whitened_understatement = match fit(&w) {
        (phi_w, ms_w) if ms_w > 0.0 => {
            ArNoise::new(phi_w, ms_w.sqrt()).map_or(1.0, |a| a.low_frequency_ratio().sqrt())
        }
        _ => 1.0,
    };
    Ok(ChannelIdentification {
        whitened_understatement,
        channel: channel.to_string(),
        order: p,
        phi_std_error: phi_std_errors(&ar, n),
        phi,
        sigma: ar.sigma(),
        motion,
        motion_t,
        correlation_time_s: ar.correlation_time(dt),
        n_eff_fraction: ar.effective_fraction(),
        sigma_understatement: ar.low_frequency_ratio().sqrt(),
        ljung_box_p: ljung_box_corrected(&r, opts.lags, opts.lags, imprint),
        ljung_box_whitened_p: ljung_box_corrected(
            &w,
            opts.lags,
            opts.lags.saturating_sub(p),
            imprint,
        ),
        samples: n,
        segments: segs.len(),
        dt,
        noise,
    })
}

/// Whether each channel is white under a family-wise test at level `alpha`
/// (Bonferroni: white unless p < α / number of channels).
pub(crate) fn white_by_bonferroni(p_values: &[f64], alpha: f64) -> Vec<bool> {
    let m = p_values.len().max(1) as f64;
    p_values.iter().map(|&p| p >= alpha / m).collect()
}

/// Family-wise level of the whiteness test over the six IMU channels.
pub const WHITENESS_ALPHA: f64 = 0.01;

/// The identified noise of the six IMU channels.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The model, channel by channel.
    pub model: NoiseModel,
    /// The per-channel reports, `[ax, ay, az, gx, gy, gz]`.
    pub channels: Vec<ChannelIdentification>,
    /// Whether each channel's residuals pass as white (Ljung–Box,
    /// Bonferroni over the six at [`WHITENESS_ALPHA`]).
    pub white: [bool; 6],
}

/// Identify the six IMU channels from residuals `r[i] = [ax, …, gz]` at
/// times `t` (and the motion regressor ‖q̈‖², when given).
pub fn identify(
    t: &[f64],
    r: &[[f64; 6]],
    qdd2: Option<&[f64]>,
    opts: &IdOptions,
) -> Result<Identification, NoiseIdError> {
    // the accelerometer's channels on a second thread (the first error in
    // channel order is reported)
    let timing = Timing::of(t, opts.gap_factor);
    let run = |cs: std::ops::Range<usize>| -> Vec<Result<ChannelIdentification, NoiseIdError>> {
        cs.map(|c| {
            let rc: Vec<f64> = r.iter().map(|v| v[c]).collect();
            identify_channel_timed(IMU_COLUMNS[c], t, &rc, qdd2, opts, None, Some(&timing))
        })
        .collect()
    };
    let (gyro, accel) = robimu_model::pair::join(|| run(3..6), || run(0..3));
    let channels = accel
        .into_iter()
        .chain(gyro)
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Identification::from_channels(channels))
}

impl Identification {
    /// The six channels' identifications `[ax, …, gz]` gathered, with the
    /// family-wise whiteness decision.
    ///
    /// # Panics
    /// When not given exactly six channels.
    pub fn from_channels(channels: Vec<ChannelIdentification>) -> Self {
        assert_eq!(channels.len(), 6, "six IMU channels");
        let p: Vec<f64> = channels.iter().map(|c| c.ljung_box_p).collect();
        let white = white_by_bonferroni(&p, WHITENESS_ALPHA);
        Self {
            model: NoiseModel {
                imu: std::array::from_fn(|c| channels[c].noise.clone()),
            },
            white: std::array::from_fn(|c| white[c]),
            channels,
        }
    }
}

#[cfg(test)]
#[path = "noise_id_tests.rs"]
mod tests;
