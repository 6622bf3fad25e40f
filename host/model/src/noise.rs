//! Measurement noise that is not white (docs/model.md §4.6): per channel a
//! stationary autoregressive process AR(p) of marginal standard deviation σ,
//! optionally scaled by a level that follows the motion.
//!
//! A channel's noise is n_i = s_i·u_i with
//!
//! ```text
//! u_i = φ_1 u_{i−1} + … + φ_p u_{i−p} + e_i,   e_i ~ N(0, σ_e²),  Var(u_i) = σ²
//! s_i² = 1 + c·‖q̈(t_i)‖² / σ²          (c ≥ 0, in the channel's unit² per (rad/s²)²)
//! ```
//!
//! so that Var(n_i) = σ² + c‖q̈‖², and σ keeps the meaning of the white model's
//! σ (the paper's Σ_z, eq. (10)). The samples are assumed equally spaced
//! within a segment (a gap in the stream starts a new one).
//!
//! The generalised-least-squares whitening of a segment u_0…u_{N−1} is the
//! exact one (the inverse Cholesky factor of its Toeplitz covariance), from
//! the Levinson–Durbin recursion: sample t is whitened by the one-step
//! prediction error of the order-min(t, p) predictor,
//!
//! ```text
//! w_t = (u_t − Σ_{k=1..m} a_{m,k} u_{t−k}) / √v_m,   m = min(t, p),
//! ```
//!
//! where a_{m,·} are the order-m partial predictor coefficients and v_m its
//! prediction-error variance (v_0 = σ², v_p = σ_e²). The w_t are independent
//! standard normal; each couples only the p samples before it.

/// Why an AR noise model is not usable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NoiseModelError {
    /// σ or the motion gain is not a finite number of the right sign.
    #[error("{what} = {value} must be {must}")]
    Value {
        /// Which value.
        what: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        must: &'static str,
    },
    /// The AR coefficients do not describe a stationary process (a root of
    /// 1 − Σ φ_k z^k on or inside the unit circle: the noise would grow
    /// without bound).
    #[error(
        "AR coefficients {phi:?} are not stationary (reflection coefficient {k} of order {order} has |k| >= 1)"
    )]
    NotStationary {
        /// The coefficients φ_1…φ_p.
        phi: Vec<f64>,
        /// The order at which the step-down recursion failed.
        order: usize,
        /// That order's reflection coefficient.
        k: f64,
    },
    /// More AR coefficients than [`MAX_AR_ORDER`].
    #[error("AR order {order} is above the largest supported order {MAX_AR_ORDER}")]
    OrderTooHigh {
        /// The order given.
        order: usize,
    },
}

/// Largest AR order accepted (a whitened row couples this many samples).
pub const MAX_AR_ORDER: usize = 16;

/// A stationary AR(p) process of marginal standard deviation σ.
#[derive(Debug, Clone, PartialEq)]
pub struct ArNoise {
    phi: Vec<f64>,
    sigma: f64,
    /// Partial predictors a_{m,1..m} for m = 0..=p (Levinson–Durbin).
    partial: Vec<Vec<f64>>,
    /// Their prediction-error variances v_0 = σ², …, v_p = σ_e².
    v: Vec<f64>,
}

impl ArNoise {
    /// White noise of standard deviation `sigma`.
    pub fn white(sigma: f64) -> Result<Self, NoiseModelError> {
        Self::new(Vec::new(), sigma)
    }

    /// AR(p) with coefficients φ_1…φ_p and marginal standard deviation σ;
    /// refused unless σ > 0 and the process is stationary.
    pub fn new(phi: Vec<f64>, sigma: f64) -> Result<Self, NoiseModelError> {
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(NoiseModelError::Value {
                what: "sigma",
                value: sigma,
                must: "a positive number",
            });
        }
        if phi.len() > MAX_AR_ORDER {
            return Err(NoiseModelError::OrderTooHigh { order: phi.len() });
        }
        if let Some(&bad) = phi.iter().find(|v| !v.is_finite()) {
            return Err(NoiseModelError::Value {
                what: "an AR coefficient",
                value: bad,
                must: "a finite number",
            });
        }
        let k = step_down(&phi).map_err(|(order, k)| NoiseModelError::NotStationary {
            phi: phi.clone(),
            order,
            k,
        })?;
        // Step up again from the reflection coefficients: the partial
        // predictors of every order and their error variances.
        let p = phi.len();
        let mut partial = vec![Vec::new()];
        let mut v = vec![sigma * sigma];
        for m in 1..=p {
            let km = k[m - 1];
            let prev = &partial[m - 1];
            let mut a: Vec<f64> = (0..m - 1).map(|j| prev[j] - km * prev[m - 2 - j]).collect();
            a.push(km);
            partial.push(a);
            v.push(v[m - 1] * (1.0 - km * km));
        }
        Ok(Self {
            phi,
            sigma,
            partial,
            v,
        })
    }

    /// The coefficients φ_1…φ_p.
    pub fn phi(&self) -> &[f64] {
        &self.phi
    }

    /// The order p.
    pub fn order(&self) -> usize {
        self.phi.len()
    }

    /// Whether the model is white (p = 0).
    pub fn is_white(&self) -> bool {
        self.phi.is_empty()
    }

    /// Marginal standard deviation σ.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Standard deviation of the innovations e_i, σ_e ≤ σ.
    pub fn innovation_sigma(&self) -> f64 {
        self.v[self.order()].sqrt()
    }

    /// The whitening of sample t of a segment (t counted from the segment's
    /// first sample): `(a, scale)` with w_t = scale·(u_t − Σ_k a[k−1]·u_{t−k}).
    pub fn whitening(&self, t: usize) -> (&[f64], f64) {
        let m = t.min(self.order());
        (&self.partial[m], 1.0 / self.v[m].sqrt())
    }

    /// Autocovariances γ_0…γ_lags (γ_0 = σ²): for m ≤ p from the
    /// Levinson identity γ_m = k_m v_{m−1} + Σ_{j<m} a_{m−1,j} γ_{m−j}, beyond
    /// from the Yule–Walker recursion γ_m = Σ_k φ_k γ_{m−k}.
    pub fn autocovariance(&self, lags: usize) -> Vec<f64> {
        let p = self.order();
        let mut g = vec![self.sigma * self.sigma];
        for m in 1..=lags {
            let gm = if m <= p {
                let km = self.partial[m][m - 1];
                let prev = &self.partial[m - 1];
                let s: f64 = (0..m - 1).map(|j| prev[j] * g[m - 1 - j]).sum();
                s + km * self.v[m - 1]
            } else {
                (0..p).map(|k| self.phi[k] * g[m - 1 - k]).sum()
            };
            g.push(gm);
        }
        g
    }

    /// S(0)/σ²: the noise power at frequency 0 relative to white noise of
    /// the same σ, σ_e² / (σ²(1 − Σφ)²). A parameter that the data
    /// determine through slowly varying regressors (a bias) has its
    /// variance understated by this factor when the noise is taken as white.
    pub fn low_frequency_ratio(&self) -> f64 {
        let s: f64 = self.phi.iter().sum();
        self.v[self.order()] / (self.sigma * self.sigma * (1.0 - s) * (1.0 - s))
    }

    /// The effective number of independent samples per sample for a slowly
    /// varying regressor, 1 / [`Self::low_frequency_ratio`].
    pub fn effective_fraction(&self) -> f64 {
        1.0 / self.low_frequency_ratio()
    }

    /// The integrated correlation time dt·Σ_{k≥1} ρ_k (ρ the
    /// autocorrelation; S(0)/σ² = 1 + 2Σ_{k≥1} ρ_k): for AR(1) with
    /// φ = e^{−dt/T} it is ≈ T when T ≫ dt; 0 for white noise.
    pub fn correlation_time(&self, dt: f64) -> f64 {
        0.5 * dt * (self.low_frequency_ratio() - 1.0).max(0.0)
    }
}

/// The Levinson step-down recursion: reflection coefficients k_1…k_p of
/// φ_1…φ_p (k_p = φ_p), or the first order whose |k| ≥ 1 (not stationary).
fn step_down(phi: &[f64]) -> Result<Vec<f64>, (usize, f64)> {
    let p = phi.len();
    let mut k = vec![0.0; p];
    let mut a = phi.to_vec();
    for m in (1..=p).rev() {
        let km = a[m - 1];
        if km.is_nan() || km.abs() >= 1.0 {
            return Err((m, km));
        }
        k[m - 1] = km;
        let d = 1.0 - km * km;
        let prev: Vec<f64> = (0..m - 1).map(|j| (a[j] + km * a[m - 2 - j]) / d).collect();
        a = prev;
    }
    Ok(k)
}

/// The noise of one measured channel: an AR process scaled by a level that
/// may follow the motion.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelNoise {
    /// The correlation in time and the marginal σ at rest.
    pub ar: ArNoise,
    /// c of σ²(t) = σ² + c‖q̈(t)‖² (channel unit² per (rad/s²)²); 0: constant level.
    pub motion: f64,
}

impl ChannelNoise {
    /// White noise of standard deviation `sigma`, constant level.
    pub fn white(sigma: f64) -> Result<Self, NoiseModelError> {
        Ok(Self {
            ar: ArNoise::white(sigma)?,
            motion: 0.0,
        })
    }

    /// `ar` with the motion gain `motion` (≥ 0).
    pub fn new(ar: ArNoise, motion: f64) -> Result<Self, NoiseModelError> {
        if !(motion.is_finite() && motion >= 0.0) {
            return Err(NoiseModelError::Value {
                what: "the motion gain",
                value: motion,
                must: "a non-negative number",
            });
        }
        Ok(Self { ar, motion })
    }

    /// Whether this is white noise of constant level (the paper's model).
    pub fn is_white(&self) -> bool {
        self.ar.is_white() && self.motion == 0.0
    }

    /// s_i: the level at a joint acceleration of norm² `qdd2` relative to rest.
    pub fn level(&self, qdd2: f64) -> f64 {
        let s = self.ar.sigma();
        (1.0 + self.motion * qdd2 / (s * s)).sqrt()
    }
}

/// The noise of the six IMU channels `[ax, ay, az, gx, gy, gz]` (the
/// estimator's Σ_z when every channel is white and of constant level).
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseModel {
    /// One model per channel, in the session's column order.
    pub imu: [ChannelNoise; 6],
}

impl NoiseModel {
    /// White noise of standard deviations `sigma_z` (the paper's model).
    pub fn white(sigma_z: [f64; 6]) -> Result<Self, NoiseModelError> {
        let mut imu = Vec::with_capacity(6);
        for s in sigma_z {
            imu.push(ChannelNoise::white(s)?);
        }
        Ok(Self {
            imu: imu.try_into().expect("six channels"),
        })
    }

    /// AR(1) per sensor at the marginal σ `sigma_z`: `phi[0]` the
    /// accelerometer's coefficient (ax, ay, az), `phi[1]` the gyroscope's
    /// (`None`: white), `motion[s]` each sensor's motion gain c (§4.6). The
    /// vibration model of issue 14 is `ar1(σ, [Some(φ), None], [c, 0])`;
    /// φ = e^{−dt/T} for a correlation time T at sample spacing dt.
    pub fn ar1(
        sigma_z: [f64; 6],
        phi: [Option<f64>; 2],
        motion: [f64; 2],
    ) -> Result<Self, NoiseModelError> {
        let mut imu = Vec::with_capacity(6);
        for (c, s) in sigma_z.into_iter().enumerate() {
            let ar = ArNoise::new(phi[c / 3].into_iter().collect(), s)?;
            imu.push(ChannelNoise::new(ar, motion[c / 3])?);
        }
        Ok(Self {
            imu: imu.try_into().expect("six channels"),
        })
    }

    /// Whether every channel is white of constant level.
    pub fn is_white(&self) -> bool {
        self.imu.iter().all(ChannelNoise::is_white)
    }

    /// The marginal σ of each channel at rest.
    pub fn sigma_z(&self) -> [f64; 6] {
        std::array::from_fn(|c| self.imu[c].ar.sigma())
    }

    /// The largest AR order over the channels (how many samples back a
    /// whitened residual reaches).
    pub fn max_order(&self) -> usize {
        self.imu.iter().map(|c| c.ar.order()).max().unwrap_or(0)
    }
}

/// Draws a [`NoiseModel`]'s noise sample by sample along one segment, from
/// standard normal draws e_t: per channel the whitening inverted exactly,
/// u_t = Σ_k a_k u_{t−k} + e_t / scale with `(a, scale)` = [`ArNoise::whitening`]`(t)`
/// (the stationary process from t = 0, no burn-in), then n_t = s_t·u_t with
/// s_t = [`ChannelNoise::level`]. A white channel of constant level gives
/// σ·e_t exactly. Keeps only the last p values of each channel.
#[derive(Debug, Clone)]
pub struct NoiseSampler {
    model: NoiseModel,
    t: usize,
    /// u_{t−1}, u_{t−2}, … (most recent first), at most p per channel.
    past: [Vec<f64>; 6],
}

impl NoiseSampler {
    /// A sampler at the start of a segment.
    pub fn new(model: NoiseModel) -> Self {
        Self {
            model,
            t: 0,
            past: Default::default(),
        }
    }

    /// The model sampled.
    pub fn model(&self) -> &NoiseModel {
        &self.model
    }

    /// Start a new segment (a gap in the stream): forget the past.
    pub fn restart(&mut self) {
        self.t = 0;
        self.past.iter_mut().for_each(Vec::clear);
    }

    /// The noise of the next sample from the standard normal draws `e` (one
    /// per channel), at a joint acceleration of norm² `qdd2`.
    pub fn next(&mut self, e: [f64; 6], qdd2: f64) -> [f64; 6] {
        let t = self.t;
        self.t += 1;
        std::array::from_fn(|c| {
            let ch = &self.model.imu[c];
            if ch.is_white() {
                return ch.ar.sigma() * e[c];
            }
            let u = if ch.ar.is_white() {
                ch.ar.sigma() * e[c]
            } else {
                let (a, scale) = ch.ar.whitening(t);
                let past = &mut self.past[c];
                let u = a
                    .iter()
                    .zip(past.iter())
                    .map(|(ak, uk)| ak * uk)
                    .sum::<f64>()
                    + e[c] / scale;
                past.insert(0, u);
                past.truncate(ch.ar.order());
                u
            };
            ch.level(qdd2) * u
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Autocovariances by the impulse response ψ of the AR filter, summed
    /// directly (an independent route from the Levinson recursion).
    fn autocovariance_by_impulse_response(phi: &[f64], sigma_e: f64, lags: usize) -> Vec<f64> {
        let n = 20_000;
        let mut psi = vec![0.0; n];
        psi[0] = 1.0;
        for i in 1..n {
            psi[i] = (1..=phi.len().min(i))
                .map(|k| phi[k - 1] * psi[i - k])
                .sum();
        }
        (0..=lags)
            .map(|h| sigma_e * sigma_e * (0..n - h).map(|i| psi[i] * psi[i + h]).sum::<f64>())
            .collect()
    }

    fn models() -> Vec<ArNoise> {
        vec![
            ArNoise::new(vec![0.8], 0.3).unwrap(),
            ArNoise::new(vec![0.95], 1.0).unwrap(),
            ArNoise::new(vec![1.2, -0.5], 0.02).unwrap(),
            ArNoise::new(vec![0.5, 0.2, -0.3], 2.0).unwrap(),
            ArNoise::white(0.7).unwrap(),
        ]
    }

    #[test]
    fn autocovariance_matches_the_impulse_response() {
        for m in models() {
            let g = m.autocovariance(8);
            let want = autocovariance_by_impulse_response(m.phi(), m.innovation_sigma(), 8);
            for h in 0..=8 {
                assert!(
                    (g[h] - want[h]).abs() < 1e-9 * want[0],
                    "{:?} lag {h}: {} vs {}",
                    m.phi(),
                    g[h],
                    want[h]
                );
            }
        }
    }

    /// The whitening is the exact inverse Cholesky factor: L Σ Lᵀ = I for
    /// the Toeplitz covariance Σ of a segment.
    #[test]
    fn whitening_makes_a_segment_independent_with_unit_variance() {
        for m in models() {
            let n = 12;
            let g = m.autocovariance(n);
            let mut l = vec![vec![0.0; n]; n];
            for t in 0..n {
                let (a, scale) = m.whitening(t);
                l[t][t] = scale;
                for (k, ak) in a.iter().enumerate() {
                    l[t][t - k - 1] = -scale * ak;
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let mut s = 0.0;
                    for a in 0..n {
                        for b in 0..n {
                            s += l[i][a] * g[a.abs_diff(b)] * l[j][b];
                        }
                    }
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((s - want).abs() < 1e-9, "{:?} ({i},{j}) = {s}", m.phi());
                }
            }
        }
    }

    #[test]
    fn ar1_summaries_have_their_closed_forms() {
        let (phi, sigma) = (0.9_f64, 0.5);
        let m = ArNoise::new(vec![phi], sigma).unwrap();
        assert!((m.innovation_sigma() - sigma * (1.0 - phi * phi).sqrt()).abs() < 1e-15);
        // S(0)/σ² = (1 + φ)/(1 − φ)
        assert!((m.low_frequency_ratio() - (1.0 + phi) / (1.0 - phi)).abs() < 1e-12);
        // φ = e^{−dt/T}: dt·Σρ_k = dt·φ/(1 − φ) = dt/(e^{dt/T} − 1) ≈ T − dt/2
        let (dt, t) = (1.0_f64 / 120.0, 0.05);
        let m = ArNoise::new(vec![(-dt / t).exp()], 1.0).unwrap();
        let exact = dt / ((dt / t).exp() - 1.0);
        assert!((m.correlation_time(dt) - exact).abs() < 1e-12 * t);
        assert!((m.correlation_time(dt) - (t - dt / 2.0)).abs() < 0.01 * t);
        assert_eq!(ArNoise::white(1.0).unwrap().low_frequency_ratio(), 1.0);
    }

    /// The per-sensor AR(1) model: each accelerometer channel's
    /// autocovariance is σ²φ^k at rest and its level follows the motion;
    /// the gyroscope is white and constant unless given; bad values refused.
    #[test]
    fn ar1_per_sensor_has_the_given_correlation_and_levels() {
        let sz = [0.02, 0.03, 0.04, 0.001, 0.002, 0.003];
        let (phi, c) = (0.75, 4e-4);
        let m = NoiseModel::ar1(sz, [Some(phi), None], [c, 0.0]).unwrap();
        assert_eq!(m.sigma_z(), sz);
        assert_eq!(m.max_order(), 1);
        for (k, ch) in m.imu.iter().enumerate() {
            let g = ch.ar.autocovariance(3);
            if k < 3 {
                for (lag, gl) in g.iter().enumerate() {
                    let want = sz[k] * sz[k] * phi.powi(lag as i32);
                    assert!((gl - want).abs() < 1e-15, "channel {k} lag {lag}");
                }
                // σ² + c‖q̈‖² at ‖q̈‖² = 2
                let var = (sz[k] * ch.level(2.0)).powi(2);
                assert!((var - (sz[k] * sz[k] + 2.0 * c)).abs() < 1e-15);
            } else {
                assert!(ch.is_white(), "channel {k}");
                assert_eq!(g[1], 0.0);
            }
        }
        let both = NoiseModel::ar1(sz, [None, Some(0.5)], [0.0, c]).unwrap();
        assert!(both.imu[..3].iter().all(ChannelNoise::is_white));
        assert_eq!(both.imu[4].ar.phi(), &[0.5]);
        assert_eq!(both.imu[5].motion, c);
        assert!(NoiseModel::ar1(sz, [Some(1.0), None], [0.0; 2]).is_err());
        assert!(NoiseModel::ar1(sz, [Some(0.5), None], [-1.0, 0.0]).is_err());
    }

    #[test]
    fn explosive_or_meaningless_models_are_refused() {
        assert!(matches!(
            ArNoise::new(vec![1.0], 1.0),
            Err(NoiseModelError::NotStationary { order: 1, .. })
        ));
        assert!(matches!(
            ArNoise::new(vec![0.5, 0.6], 1.0),
            Err(NoiseModelError::NotStationary { .. })
        ));
        assert!(ArNoise::new(vec![-1.5], 1.0).is_err());
        assert!(ArNoise::new(vec![0.5], 0.0).is_err());
        assert!(ArNoise::new(vec![0.5], -1.0).is_err());
        assert!(ArNoise::new(vec![f64::NAN], 1.0).is_err());
        assert!(ArNoise::new(vec![0.01; MAX_AR_ORDER + 1], 1.0).is_err());
        let ar = ArNoise::new(vec![0.5], 1.0).unwrap();
        assert!(ChannelNoise::new(ar.clone(), -0.1).is_err());
        let c = ChannelNoise::new(ar, 0.25).unwrap();
        assert!((c.level(4.0) - 2.0_f64.sqrt()).abs() < 1e-15);
        let msg = ArNoise::new(vec![1.1], 1.0).unwrap_err().to_string();
        assert!(msg.contains("not stationary"), "{msg}");
    }
}
