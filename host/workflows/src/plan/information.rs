//! The information about x that IMU samples along a known trajectory carry
//! (paper eq. (26), (31)), and the posterior covariance it gives.
//!
//! ```text
//! Λ = Σ_x̂⁻¹ + Σ_i J_iᵀ Σ_z⁻¹ J_i,   J_i = ∂z/∂x at q(t_i), q̇, q̈, q⃛   (26)
//! Σ_x = Λ⁻¹
//! ```
//!
//! Everything is in SI units (m, rad, s, m/s², rad/s, 1), linearised at the
//! nominal x. Samples are the IMU's at `rate` Hz on the global grid
//! t_k = k / rate. [`Sampling::Quadrature`] replaces the sum over one interval
//! by a midpoint rule at a lower rate, each point weighted by the number of
//! samples it stands for: the summand is a smooth function of t on every knot
//! span, so a few points per span give it to well below a percent (checked in
//! the tests) at a fraction of the cost — the planner's inner loop.
//!
//! **Noise that is not white** (docs/model.md §4.6, [`NoiseModel`]). With an
//! AR(p) model and a motion level per channel, (26) is the information of the
//! generalised least squares: Σ_i w_iᵀ w_i with the whitened rows of the
//! estimator ([`robimu_solver::problem`]), per channel c
//!
//! ```text
//! w_i = scale_t·(J_i/s_i − Σ_{k=1..m} a_k J_{i−k}/s_{i−k}),  (a, scale_t) = ArNoise::whitening(t)
//! ```
//!
//! (t = i − first sample of the trajectory, one segment; s_i the level at
//! q̈(t_i)). [`Sampling::Exact`] does exactly this (an interval [a, b)
//! re-evaluates the p samples before a, so blocks add up to the whole).
//! [`Sampling::Quadrature`]'s points are not consecutive samples: it uses the
//! smooth-signal limit — J varies slowly over the AR memory, so
//! J_{i−k} ≈ J_i and w_i ≈ (1 − Σφ_k)·J_i / (σ_e·s_i), a per-channel factor
//! (1 − Σφ)/σ_e = 1/(σ·√(S(0)/σ²)) in place of 1/σ (exact for white noise).
//! Its error is that of weighting every frequency of J by the noise power
//! at 0: in the frequency domain the exact information weights J's content
//! at angular frequency ω by 1/S(ω) = |1 − Σφ_k e^{−iωkΔt}|²/σ_e², which
//! for AR(1) of correlation time T is 1/S(0)·(1 + (ωT)² + …); so the
//! quadrature understates the information of a component of J at ω by the
//! relative (ωT)² (T = 20 ms, 1 Hz: 1.6 %; 50 ms: 10 %), and is exact for
//! constant regressors (biases, gravity).
//!
//! **Several IMUs** (docs/model.md §9). With the layout of K IMUs
//! ([`ParamLayout::with_imus`]) every IMU j is sampled on the same grid and
//! evaluated by the one-IMU model at its own 48 values (`imu_x(j, x)`, its own
//! linearisation point: position, rotations); its whitened rows are scattered
//! into x through `imu_map(j)`, so Λ = Σ⁻¹ + Σ_j P_jᵀ I_j P_j with I_j the
//! one-IMU information of IMU j (the noise model serves every IMU, as in
//! the fit). For K = 1 the map is the identity: exactly the one-IMU Λ.
use faer::{Accum, Mat, Par, Side};

use robimu_model::noise::NoiseModel;
use robimu_model::{
    JointState, MeasurementJacobians, MeasurementModel, ModelError, ParamLayout, Robot, Spline,
};

/// How the samples of an interval are evaluated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sampling {
    /// Every IMU sample.
    Exact,
    /// A midpoint rule with this many points per second.
    Quadrature(f64),
}

/// The IMU information model of one robot linearised at a point x (its
/// nominal parameters unless given), for one or several IMUs (module doc).
pub struct Information {
    /// One measurement model per IMU, each at its own 48 values.
    models: Vec<MeasurementModel>,
    layout: ParamLayout,
    noise: NoiseModel,
    /// Per channel the quadrature's factor (1 − Σφ)/σ_e (1/σ when white).
    smooth: [f64; 6],
    rate: f64,
}

/// Why an information model cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InformationError {
    /// The nominal model is invalid.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The noise model is invalid (e.g. a σ not positive).
    #[error("IMU noise: {0}")]
    Noise(#[from] robimu_model::noise::NoiseModelError),
    /// The linearisation point does not fit the layout.
    #[error(
        "the linearisation point has {found} values but the layout of {imus} IMU(s) has {expected}"
    )]
    PointLength {
        /// The layout's length.
        expected: usize,
        /// The point's.
        found: usize,
        /// The layout's IMUs.
        imus: usize,
    },
}

impl Information {
    /// `robot` at its nominal x, white IMU noise `sigma_z`, `rate` samples per second.
    pub fn new(robot: &Robot, sigma_z: [f64; 6], rate: f64) -> Result<Self, InformationError> {
        Self::with_noise(robot, NoiseModel::white(sigma_z)?, rate)
    }

    /// `robot` at its nominal x, IMU noise `noise` (its AR coefficients per
    /// sample at `rate`; module doc), `rate` samples per second.
    pub fn with_noise(
        robot: &Robot,
        noise: NoiseModel,
        rate: f64,
    ) -> Result<Self, InformationError> {
        let layout = ParamLayout::new(robot);
        let x = layout.nominal();
        Self::at(robot, layout, &x, noise, rate)
    }

    /// `robot` with the IMUs of `layout` (one or several, docs/model.md §9),
    /// linearised at `x` (in `layout` order: each IMU's own position and
    /// rotations are its values there), IMU noise `noise` for every IMU,
    /// `rate` samples per second.
    pub fn at(
        robot: &Robot,
        layout: ParamLayout,
        x: &[f64],
        noise: NoiseModel,
        rate: f64,
    ) -> Result<Self, InformationError> {
        if x.len() != layout.len() {
            return Err(InformationError::PointLength {
                expected: layout.len(),
                found: x.len(),
                imus: layout.n_imus(),
            });
        }
        let models = (0..layout.n_imus())
            .map(|j| MeasurementModel::new(robot, layout.imu_layout(), &layout.imu_x(j, x)))
            .collect::<Result<Vec<_>, _>>()?;
        let smooth = std::array::from_fn(|c| {
            let ar = &noise.imu[c].ar;
            (1.0 - ar.phi().iter().sum::<f64>()) / ar.innovation_sigma()
        });
        Ok(Self {
            models,
            layout,
            noise,
            smooth,
            rate,
        })
    }

    /// The IMU noise model assumed.
    pub fn noise(&self) -> &NoiseModel {
        &self.noise
    }

    /// The layout of x.
    pub fn layout(&self) -> &ParamLayout {
        &self.layout
    }

    /// Number of IMUs K.
    pub fn n_imus(&self) -> usize {
        self.models.len()
    }

    /// Number of parameters.
    pub fn dim(&self) -> usize {
        self.layout.len()
    }

    /// IMU sample rate, Hz.
    pub fn rate(&self) -> f64 {
        self.rate
    }

    /// The prior information Σ_x̂⁻¹ (diagonal).
    pub fn prior(&self) -> Mat<f64> {
        let s = self.layout.sigmas();
        Mat::from_fn(s.len(), s.len(), |i, j| {
            if i == j {
                1.0 / (s[i] * s[i])
            } else {
                0.0
            }
        })
    }

    /// Grid indices k (t_k = k / rate) of the samples in [a, b) (b included
    /// when `last`).
    fn sample_indices(&self, a: f64, b: f64, last: bool) -> std::ops::Range<i64> {
        let k0 = (a * self.rate - 1e-9).ceil() as i64;
        let mut k = k0;
        loop {
            let t = k as f64 / self.rate;
            if t > b + 1e-12 || (!last && t >= b - 1e-12) {
                break;
            }
            k += 1;
        }
        k0..k
    }

    /// Quadrature points and weights of [a, b).
    fn quadrature_points(a: f64, b: f64, per_second: f64, rate: f64) -> Vec<(f64, f64)> {
        let cells = ((b - a) * per_second).ceil().max(1.0) as usize;
        let w = rate * (b - a) / cells as f64;
        (0..cells)
            .map(|c| (a + (b - a) * (c as f64 + 0.5) / cells as f64, w))
            .collect()
    }

    /// ∂z/∂x of IMU `imu` at t of `trajectory` played `speed` times faster,
    /// each channel divided by its level, into column `col` of `out`
    /// (6·count columns, channel-minor), its entry k into row `rows[k]`;
    /// scaled by `factor[c]`.
    #[allow(clippy::too_many_arguments)]
    fn scaled_rows(
        &self,
        imu: usize,
        rows: &[usize],
        trajectory: &Spline,
        t: f64,
        speed: f64,
        factor: &[f64; 6],
        js: &mut JointState,
        jac: &mut MeasurementJacobians,
        out: &mut Mat<f64>,
        col: usize,
    ) {
        trajectory.evaluate_clamped(t, js);
        for j in 0..trajectory.dim() {
            js.qd[j] *= speed;
            js.qdd[j] *= speed * speed;
            js.qddd[j] *= speed * speed * speed;
        }
        self.models[imu].jacobians(js, jac);
        let qdd2: f64 = js.qdd[..trajectory.dim()].iter().map(|v| v * v).sum();
        let f: [f64; 6] = std::array::from_fn(|c| factor[c] / self.noise.imu[c].level(qdd2));
        for (&ix, dz) in rows.iter().zip(&jac.dz_dx) {
            for r in 0..6 {
                out[(ix, 6 * col + r)] = dz[r] * f[r];
            }
        }
    }

    /// Adds to `info` the information of the samples in [a, b) (or [a, b] when
    /// `last`) of `trajectory` played `speed` times faster with the sample rate
    /// scaled alike (so the samples see the same positions; q̇ ×speed,
    /// q̈ ×speed², q⃛ ×speed³; the AR coefficients stay per sample); a and b
    /// are times of the original trajectory.
    #[allow(clippy::too_many_arguments)]
    pub fn accumulate(
        &self,
        trajectory: &Spline,
        a: f64,
        b: f64,
        last: bool,
        speed: f64,
        sampling: Sampling,
        info: &mut Mat<f64>,
    ) {
        let np = self.dim();
        let np1 = self.layout.imu_layout().len();
        let imus = self.models.len();
        let mut js = JointState::default();
        let mut jac = MeasurementJacobians::new(np1);
        let jt = match sampling {
            Sampling::Exact => {
                let ks = self.sample_indices(a, b, last);
                if ks.is_empty() {
                    return;
                }
                // the whitened rows reach p samples back, within the trajectory
                let first = (trajectory.knots().start() * self.rate - 1e-9).ceil() as i64;
                let p = self.noise.max_order() as i64;
                let k_lo = (ks.start - p).max(first).min(ks.start);
                let count = (ks.end - ks.start) as usize;
                let back = (ks.start - k_lo) as usize;
                let own: Vec<usize> = (0..np1).collect();
                let mut raw = Mat::<f64>::zeros(np1, 6 * (back + count));
                let mut jt = Mat::<f64>::zeros(np, 6 * count * imus);
                for imu in 0..imus {
                    for (s, k) in (k_lo..ks.end).enumerate() {
                        let t = (k as f64 / self.rate).min(b);
                        self.scaled_rows(
                            imu, &own, trajectory, t, speed, &[1.0; 6], &mut js, &mut jac,
                            &mut raw, s,
                        );
                    }
                    let map = self.layout.imu_map(imu);
                    for s in 0..count {
                        let pos = (ks.start + s as i64 - first).max(0) as usize;
                        for (r, ch) in self.noise.imu.iter().enumerate() {
                            let (coef, scale) = ch.ar.whitening(pos);
                            let here = 6 * (back + s) + r;
                            for (ix, &row) in map.iter().enumerate() {
                                let mut v = raw[(ix, here)];
                                for (k, ak) in coef.iter().enumerate() {
                                    v -= ak * raw[(ix, here - 6 * (k + 1))];
                                }
                                jt[(row, 6 * (imu * count + s) + r)] = scale * v;
                            }
                        }
                    }
                }
                jt
            }
            Sampling::Quadrature(per_second) => {
                let pts = Self::quadrature_points(a, b, per_second, self.rate);
                let mut jt = Mat::<f64>::zeros(np, 6 * pts.len() * imus);
                for imu in 0..imus {
                    let map = self.layout.imu_map(imu);
                    for (s, &(t, w)) in pts.iter().enumerate() {
                        let f = self.smooth.map(|v| v * w.sqrt());
                        let col = imu * pts.len() + s;
                        self.scaled_rows(
                            imu, map, trajectory, t, speed, &f, &mut js, &mut jac, &mut jt, col,
                        );
                    }
                }
                jt
            }
        };
        faer::linalg::matmul::matmul(
            info.as_mut(),
            Accum::Add,
            jt.as_ref(),
            jt.transpose(),
            1.0,
            Par::Seq,
        );
    }

    /// Prior plus the information of the whole trajectory (all samples).
    pub fn total(&self, trajectory: &Spline, speed: f64, sampling: Sampling) -> Mat<f64> {
        let mut info = self.prior();
        let (t0, t1) = (trajectory.knots().start(), trajectory.knots().end());
        self.accumulate(trajectory, t0, t1, true, speed, sampling, &mut info);
        info
    }
}

/// Largest eigenvalue of Σ = Λ⁻¹ over the parameters `keep` (the others
/// known exactly): 1 / λ_min of Λ restricted to `keep`.
pub fn lambda_max(info: &Mat<f64>, keep: &[usize]) -> f64 {
    let k = keep.len();
    let sub = Mat::from_fn(k, k, |i, j| info[(keep[i], keep[j])]);
    match sub.self_adjoint_eigenvalues(Side::Lower) {
        Ok(ev) => 1.0 / ev.iter().copied().fold(f64::INFINITY, f64::min),
        Err(_) => f64::NAN,
    }
}

/// Σ = Λ⁻¹ over `keep` (row-major k × k), or None when Λ is not positive definite.
pub fn covariance(info: &Mat<f64>, keep: &[usize]) -> Option<Mat<f64>> {
    use faer::linalg::solvers::DenseSolveCore;
    let k = keep.len();
    let sub = Mat::from_fn(k, k, |i, j| info[(keep[i], keep[j])]);
    sub.llt(Side::Lower).ok().map(|l| l.inverse())
}

/// Indices of x except the robot length parameters ε_ik, k ≤ 3, i < n (the
/// paper's nine for the AUBO i5; the IMU position ε_n1..3 stays).
pub(crate) fn without_robot_lengths(layout: &ParamLayout) -> Vec<usize> {
    let n = layout.n_links();
    (0..layout.len())
        .filter(|&i| {
            !layout
                .estimated_errors()
                .get(i)
                .is_some_and(|e| e.is_length(n))
        })
        .collect()
}

/// The robot length parameters (see [`without_robot_lengths`]).
pub(crate) fn robot_lengths(layout: &ParamLayout) -> Vec<usize> {
    let keep = without_robot_lengths(layout);
    (0..layout.len()).filter(|i| !keep.contains(i)).collect()
}

/// The posterior σ of every parameter under the information `info` (SI),
/// `None` when `info` is not positive definite.
pub fn posterior_sigma(info: &Mat<f64>) -> Option<Vec<f64>> {
    let all: Vec<usize> = (0..info.nrows()).collect();
    let cov = covariance(info, &all)?;
    Some(all.iter().map(|&k| cov[(k, k)].max(0.0).sqrt()).collect())
}
