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

use faer::{Accum, Mat, Par, Side};

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

/// The IMU information model of one robot at its nominal parameters.
pub struct Information {
    model: MeasurementModel,
    layout: ParamLayout,
    wz: [f64; 6],
    rate: f64,
}

impl Information {
    /// `robot` at its nominal x, IMU noise `sigma_z`, `rate` samples per second.
    pub fn new(robot: &Robot, sigma_z: [f64; 6], rate: f64) -> Result<Self, ModelError> {
        let layout = ParamLayout::new(robot);
        let model = MeasurementModel::new(robot, &layout, &layout.nominal())?;
        Ok(Self {
            model,
            layout,
            wz: sigma_z.map(|s| 1.0 / s),
            rate,
        })
    }

    /// The layout of x.
    pub fn layout(&self) -> &ParamLayout {
        &self.layout
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

    /// Sample times and weights of [a, b) (b included when `last`).
    fn points(&self, a: f64, b: f64, last: bool, sampling: Sampling) -> Vec<(f64, f64)> {
        match sampling {
            Sampling::Exact => {
                let k0 = (a * self.rate - 1e-9).ceil() as i64;
                let mut v = Vec::new();
                let mut k = k0;
                loop {
                    let t = k as f64 / self.rate;
                    if t > b + 1e-12 || (!last && t >= b - 1e-12) {
                        break;
                    }
                    v.push((t.min(b), 1.0));
                    k += 1;
                }
                v
            }
            Sampling::Quadrature(per_second) => {
                let cells = ((b - a) * per_second).ceil().max(1.0) as usize;
                let w = self.rate * (b - a) / cells as f64;
                (0..cells)
                    .map(|c| (a + (b - a) * (c as f64 + 0.5) / cells as f64, w))
                    .collect()
            }
        }
    }

    /// Adds to `info` the information of the samples in [a, b) (or [a, b] when
    /// `last`) of `trajectory` played `speed` times faster with the sample rate
    /// scaled alike (so the samples see the same positions; q̇ ×speed,
    /// q̈ ×speed², q⃛ ×speed³); a and b are times of the original trajectory.
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
        let pts = self.points(a, b, last, sampling);
        if pts.is_empty() {
            return;
        }
        let rows = 6 * pts.len();
        let mut jt = Mat::<f64>::zeros(np, rows);
        let mut js = JointState::default();
        let mut jac = MeasurementJacobians::new(np);
        for (s, &(t, w)) in pts.iter().enumerate() {
            trajectory.evaluate_clamped(t, &mut js);
            for j in 0..trajectory.dim() {
                js.qd[j] *= speed;
                js.qdd[j] *= speed * speed;
                js.qddd[j] *= speed * speed * speed;
            }
            self.model.jacobians(&js, &mut jac);
            let sw = w.sqrt();
            for (ix, col) in jac.dz_dx.iter().enumerate() {
                for r in 0..6 {
                    jt[(ix, 6 * s + r)] = col[r] * self.wz[r] * sw;
                }
            }
        }
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
pub fn without_robot_lengths(layout: &ParamLayout) -> Vec<usize> {
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
pub fn robot_lengths(layout: &ParamLayout) -> Vec<usize> {
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
