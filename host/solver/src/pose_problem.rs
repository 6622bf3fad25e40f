//! The MAP problem of a pose session (MODEL.md §10; the joint-space
//! problem's arrangement, [`crate::problem`]): unknowns θ = [c, x] with c
//! the pose spline's control-point corrections, 6 per control point
//! (Δc_k, then φ_k with R_k = R_k0·Exp(φ_k) about the initial fit R_k0), and
//! x the 30 parameters ([`robimu_model::pose_measurement`]).
//!
//! Residuals, each whitened by its σ: pose samples (e_p = p(t_k) − p̃ with
//! σ_p, e_r = Log(R̃ᵀR(t_k)) with σ_r), IMU samples (σ_z per channel; a
//! sample whose t_i + τ is outside the pose span, or within
//! [`SPAN_MARGIN`] of its ends, is left out, the set chosen at every
//! iteration, §4) and the prior on x. Every residual touches
//! the 4 control points at its time, so the Gauss–Newton matrix is an
//! [`ArrowMatrix`] of half-bandwidth 23 bordered by x.

use faer::Mat;
use robimu_model::geom::{mul_mm, M3, V3};
use robimu_model::pose_measurement::rows::{
    prediction_rows, PoseRows, RowContext, SegmentCache, ACCEL_COLS, GYRO_COLS, GYRO_LOCAL,
};
use robimu_model::pose_measurement::{self as pm, PoseMeasurementError, CTRL, POSE_PARAMS, TAU};
use robimu_model::pose_trajectory::so3::{exp_s, right_jacobian};
use robimu_model::{PoseSpline, PoseSplineError};

use crate::arrow::ArrowMatrix;
use crate::lm::LeastSquares;

/// IMU samples are selected only when t_i + τ is at least this far (s)
/// inside the pose span, so that a step in τ smaller than this keeps every
/// selected sample on the spline (a sample pushed off it would make the
/// step fail, and Levenberg–Marquardt stall at the span's edge).
pub(crate) const SPAN_MARGIN: f64 = 0.1;

/// Band unknowns per control point.
pub(crate) const PER_CONTROL: usize = 6;

/// Why the pose problem could not be built or evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseProblemError {
    /// A prediction failed (gravity out of range, …).
    #[error(transparent)]
    Measurement(#[from] PoseMeasurementError),
    /// The spline could not be built.
    #[error(transparent)]
    Spline(#[from] PoseSplineError),
    /// Inconsistent input.
    #[error("pose problem: {0}")]
    Input(String),
}

impl From<robimu_model::SplineError> for PoseProblemError {
    fn from(e: robimu_model::SplineError) -> Self {
        Self::Spline(e.into())
    }
}

/// The data and weights of a pose problem.
#[derive(Debug, Clone)]
pub struct PoseData {
    /// Pose sample times (s).
    pub pose_t: Vec<f64>,
    /// Measured positions p̃ (m).
    pub pose_p: Vec<V3>,
    /// Measured rotations R̃.
    pub pose_r: Vec<M3>,
    /// IMU sample times (s).
    pub imu_t: Vec<f64>,
    /// IMU samples [ax, ay, az, gx, gy, gz].
    pub imu_z: Vec<[f64; 6]>,
    /// σ_p (m).
    pub sigma_p: f64,
    /// σ_r (rad).
    pub sigma_r: f64,
    /// σ_z per channel.
    pub sigma_z: [f64; 6],
    /// Prior means of x.
    pub prior_mean: Vec<f64>,
    /// Prior σ of x.
    pub prior_sigma: Vec<f64>,
}

/// The pose-session problem ([`LeastSquares`]; module doc).
#[derive(Debug, Clone)]
pub struct PoseProblem {
    base: PoseSpline,
    data: PoseData,
    selected: Vec<usize>,
}

/// The local Jacobian block of one residual group: rows × (24 band + 30 x)
/// and the whitened residuals.
struct Block {
    first: usize,
    rows: usize,
    j: [[f64; CTRL]; 6],
    r: [f64; 6],
}

impl PoseProblem {
    /// A problem about the initial spline `base` (θ's c = 0 is `base`).
    pub fn new(base: PoseSpline, data: PoseData) -> Result<Self, PoseProblemError> {
        let n = data.pose_t.len();
        if data.pose_p.len() != n || data.pose_r.len() != n || data.imu_z.len() != data.imu_t.len()
        {
            return Err(PoseProblemError::Input(
                "sample buffers of different lengths".into(),
            ));
        }
        if data.prior_mean.len() != POSE_PARAMS || data.prior_sigma.len() != POSE_PARAMS {
            return Err(PoseProblemError::Input(
                "the prior needs 30 means and σ".into(),
            ));
        }
        let bad_sigma = (data.prior_sigma.iter().chain(&data.sigma_z))
            .chain([&data.sigma_p, &data.sigma_r])
            .any(|s| !(s.is_finite() && *s > 0.0));
        if bad_sigma {
            return Err(PoseProblemError::Input(
                "every σ must be positive and finite".into(),
            ));
        }
        Ok(Self {
            base,
            data,
            selected: Vec::new(),
        })
    }

    /// Number of band unknowns (6 per control point).
    pub fn n_band(&self) -> usize {
        PER_CONTROL * self.base.num_control_points()
    }

    /// Number of unknowns (band + 30).
    pub fn n_unknowns(&self) -> usize {
        self.n_band() + POSE_PARAMS
    }

    /// The IMU samples in the current cost (those with t_i + τ in the pose span).
    pub fn selected(&self) -> &[usize] {
        &self.selected
    }

    /// θ's x part.
    pub fn x<'a>(&self, theta: &'a [f64]) -> &'a [f64] {
        &theta[self.n_band()..]
    }

    /// The pose spline at θ.
    pub fn spline(&self, theta: &[f64]) -> Result<PoseSpline, PoseProblemError> {
        let m = self.base.num_control_points();
        let pos: Vec<V3> = (0..m)
            .map(|k| {
                let c = self.base.position_control_point(k);
                std::array::from_fn(|i| c[i] + theta[PER_CONTROL * k + i])
            })
            .collect();
        let rot: Vec<M3> = (0..m)
            .map(|k| {
                let phi = std::array::from_fn(|i| theta[PER_CONTROL * k + 3 + i]);
                mul_mm(&self.base.rotation_control_points()[k], &exp_s(phi))
            })
            .collect();
        Ok(PoseSpline::new(self.base.knots().clone(), &pos, &rot)?)
    }

    /// IMU samples whose t_i + τ is inside the pose span, [`SPAN_MARGIN`]
    /// from its ends.
    fn selection(&self, tau: f64) -> Vec<usize> {
        let k = self.base.knots();
        let (t0, t1) = (k.start() + SPAN_MARGIN, k.end() - SPAN_MARGIN);
        (0..self.data.imu_t.len())
            .filter(|&i| (t0..=t1).contains(&(self.data.imu_t[i] + tau)))
            .collect()
    }

    /// The whitened residual vector at θ: pose samples (6 each), selected
    /// IMU samples (6 each), prior (30).
    pub fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>, PoseProblemError> {
        let sp = self.spline(theta)?;
        let x = self.x(theta);
        let d = &self.data;
        let mut out = Vec::with_capacity(6 * (d.pose_t.len() + self.selected.len()) + POSE_PARAMS);
        for k in 0..d.pose_t.len() {
            let (e_p, e_r) = sp.pose_error_r(d.pose_t[k], d.pose_p[k], &d.pose_r[k])?;
            out.extend(e_p.iter().map(|v| v / d.sigma_p));
            out.extend(e_r.iter().map(|v| v / d.sigma_r));
        }
        for &i in &self.selected {
            let z = pm::predict(&sp, d.imu_t[i], x)?;
            out.extend((0..6).map(|c| (z[c] - d.imu_z[i][c]) / d.sigma_z[c]));
        }
        out.extend((0..POSE_PARAMS).map(|k| (x[k] - d.prior_mean[k]) / d.prior_sigma[k]));
        Ok(out)
    }

    /// Right Jacobians J_r(φ_k) of the rotation unknowns (∂δ/∂φ).
    fn right_jacobians(&self, theta: &[f64]) -> Vec<M3> {
        (0..self.base.num_control_points())
            .map(|k| right_jacobian(std::array::from_fn(|i| theta[PER_CONTROL * k + 3 + i])))
            .collect()
    }

    /// The whitened Jacobian block of pose sample k.
    fn pose_block(&self, sp: &PoseSpline, jr: &[M3], k: usize) -> Result<Block, PoseProblemError> {
        let d = &self.data;
        let e = sp.pose_residual_r(d.pose_t[k], d.pose_p[k], &d.pose_r[k])?;
        let mut b = Block {
            first: e.first,
            rows: 6,
            j: [[0.0; CTRL]; 6],
            r: [0.0; 6],
        };
        for r in 0..3 {
            b.r[r] = e.e_p[r] / d.sigma_p;
            b.r[3 + r] = e.e_r[r] / d.sigma_r;
            for j in 0..4 {
                for c in 0..3 {
                    b.j[r][6 * j + c] = e.e_p_position[r][3 * j + c] / d.sigma_p;
                    let m = &jr[e.first + j];
                    let v: f64 = (0..3).map(|l| e.e_r_rotation[r][3 * j + l] * m[l][c]).sum();
                    b.j[3 + r][6 * j + 3 + c] = v / d.sigma_r;
                }
            }
        }
        Ok(b)
    }
}

/// The IMU samples' normal equations of one segment (the 4 control points
/// at their t + τ), summed in compact columns ([`pm::rows`]): the
/// accelerometer rows' 42 × 42 and the gyroscope rows' 25 × 25 products
/// (lower triangles), and their gradients; added to the matrix once per
/// segment.
struct Segment {
    first: usize,
    accel: Gram<ACCEL_COLS>,
    gyro: Gram<GYRO_COLS>,
    local: Mat<f64>,
}

/// One sensor's sums over a segment in its C compact columns: Σ wᵀw (the
/// full square; the flush reads the lower triangle) and the gradient
/// Σ wᵀ·(whitened residual), w the sample's three whitened rows.
struct Gram<const C: usize> {
    m: Box<[[f64; C]; C]>,
    g: [f64; C],
}

impl<const C: usize> Gram<C> {
    fn new() -> Self {
        Self {
            m: Box::new([[0.0; C]; C]),
            g: [0.0; C],
        }
    }

    /// Add the three `rows` weighted by `w`, their whitened residuals `wr`.
    fn add(&mut self, rows: &[[f64; C]; 3], w: &[f64], wr: &[f64]) {
        let a: [[f64; C]; 3] = std::array::from_fn(|r| rows[r].map(|v| v * w[r]));
        for p in 0..C {
            let (x0, x1, x2) = (a[0][p], a[1][p], a[2][p]);
            let row = &mut self.m[p];
            for q in 0..C {
                row[q] += x0 * a[0][q] + x1 * a[1][q] + x2 * a[2][q];
            }
            self.g[p] += x0 * wr[0] + x1 * wr[1] + x2 * wr[2];
        }
    }

    fn clear(&mut self) {
        *self.m = [[0.0; C]; C];
        self.g = [0.0; C];
    }
}

impl Segment {
    fn new() -> Self {
        Self {
            first: usize::MAX,
            accel: Gram::new(),
            gyro: Gram::new(),
            local: Mat::zeros(CTRL + POSE_PARAMS, CTRL + POSE_PARAMS),
        }
    }

    /// Add one sample's whitened rows (`wr`: whitened residuals), the
    /// three rows of a sensor in one pass over its sums.
    fn add(&mut self, rows: &PoseRows, w: &[f64; 6], wr: &[f64; 6]) {
        self.accel.add(&rows.accel, &w[..3], &wr[..3]);
        self.gyro.add(&rows.gyro, &w[3..], &wr[3..]);
    }

    /// Add the sums to `a`, `g` and start empty.
    fn flush(&mut self, a: &mut ArrowMatrix, g: &mut [f64], nc: usize) {
        if self.first == usize::MAX {
            return;
        }
        let n = CTRL + POSE_PARAMS;
        self.local.fill(0.0);
        let mut grad = [0.0; CTRL + POSE_PARAMS];
        for p in 0..ACCEL_COLS {
            for q in 0..=p {
                self.local[(p, q)] = self.accel.m[p][q];
            }
            grad[p] = self.accel.g[p];
        }
        for p in 0..GYRO_COLS {
            let lp = GYRO_LOCAL[p];
            for q in 0..GYRO_COLS {
                let lq = GYRO_LOCAL[q];
                if lq <= lp {
                    self.local[(lp, lq)] += self.gyro.m[p][q];
                }
            }
            grad[lp] += self.gyro.g[p];
        }
        let c0 = PER_CONTROL * self.first;
        for p in 0..n {
            if p < CTRL {
                g[c0 + p] += grad[p];
            } else {
                g[nc + p - CTRL] += grad[p];
            }
        }
        a.add_local(c0, CTRL, &ALL_X, self.local.as_ref());
        self.accel.clear();
        self.gyro.clear();
        self.first = usize::MAX;
    }
}

/// The rows' rotation columns (∂/∂δ of the local perturbation) into θ's
/// rotation unknowns φ (R_k = R_k0·Exp(φ_k)): times J_r(φ_k), as the pose
/// blocks.
fn through_right_jacobians(rows: &mut PoseRows, jr: &[M3]) {
    for j in 0..4 {
        let m = &jr[rows.first + j];
        for r in 0..3 {
            let a: [f64; 3] = std::array::from_fn(|l| rows.accel[r][6 * j + 3 + l]);
            let g: [f64; 3] = std::array::from_fn(|l| rows.gyro[r][3 * j + l]);
            for c in 0..3 {
                rows.accel[r][6 * j + 3 + c] = (0..3).map(|l| a[l] * m[l][c]).sum();
                rows.gyro[r][3 * j + c] = (0..3).map(|l| g[l] * m[l][c]).sum();
            }
        }
    }
}

/// Every x index.
const ALL_X: [usize; POSE_PARAMS] = {
    let mut v = [0; POSE_PARAMS];
    let mut k = 0;
    while k < POSE_PARAMS {
        v[k] = k;
        k += 1;
    }
    v
};

/// Add a pose block's JᵀJ and Jᵀr (band columns only).
fn accumulate_pose(a: &mut ArrowMatrix, g: &mut [f64], b: &Block, local: &mut Mat<f64>) {
    let c0 = PER_CONTROL * b.first;
    for p in 0..CTRL {
        for q in 0..=p {
            local[(p, q)] = (0..b.rows).map(|r| b.j[r][p] * b.j[r][q]).sum();
        }
        g[c0 + p] += (0..b.rows).map(|r| b.j[r][p] * b.r[r]).sum::<f64>();
    }
    a.add_local(c0, CTRL, &[], local.as_ref().submatrix(0, 0, CTRL, CTRL));
}

impl PoseProblem {
    /// Add the selected IMU samples' normal equations at `sp`, x (segment by
    /// segment, [`Segment`]); their cost.
    fn linearize_imu(
        &self,
        sp: &PoseSpline,
        jr: &[M3],
        x: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, PoseProblemError> {
        let d = &self.data;
        let ctx = RowContext::new(x)?;
        let w: [f64; 6] = d.sigma_z.map(|s| 1.0 / s);
        let (mut seg, mut seeds, mut cost) = (Segment::new(), SegmentCache::default(), 0.0);
        for &i in &self.selected {
            let mut rows = prediction_rows(sp, d.imu_t[i], &ctx, &mut seeds)?;
            through_right_jacobians(&mut rows, jr);
            if rows.first != seg.first {
                seg.flush(a, g, self.n_band());
                seg.first = rows.first;
            }
            let wr: [f64; 6] = std::array::from_fn(|c| (rows.z[c] - d.imu_z[i][c]) * w[c]);
            cost += 0.5 * wr.iter().map(|r| r * r).sum::<f64>();
            seg.add(&rows, &w, &wr);
        }
        seg.flush(a, g, self.n_band());
        Ok(cost)
    }
}

impl LeastSquares for PoseProblem {
    type Error = PoseProblemError;

    fn begin_iteration(&mut self, theta: &[f64]) -> Result<(), Self::Error> {
        self.selected = self.selection(theta[self.n_band() + TAU]);
        Ok(())
    }

    fn cost(&self, theta: &[f64]) -> Result<f64, Self::Error> {
        Ok(0.5 * self.residuals(theta)?.iter().map(|r| r * r).sum::<f64>())
    }

    fn linearize(
        &self,
        theta: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, Self::Error> {
        a.clear();
        g.fill(0.0);
        let (sp, jr, nc) = (
            self.spline(theta)?,
            self.right_jacobians(theta),
            self.n_band(),
        );
        let x = self.x(theta);
        let mut local = Mat::zeros(CTRL, CTRL);
        let mut cost = 0.0;
        for k in 0..self.data.pose_t.len() {
            let b = self.pose_block(&sp, &jr, k)?;
            cost += 0.5 * b.r.iter().map(|r| r * r).sum::<f64>();
            accumulate_pose(a, g, &b, &mut local);
        }
        cost += self.linearize_imu(&sp, &jr, x, a, g)?;
        let d = &self.data;
        for k in 0..POSE_PARAMS {
            let w = 1.0 / (d.prior_sigma[k] * d.prior_sigma[k]);
            let e = x[k] - d.prior_mean[k];
            a.add_xx(k, k, w);
            g[nc + k] += w * e;
            cost += 0.5 * w * e * e;
        }
        Ok(cost)
    }

    fn new_matrix(&self) -> ArrowMatrix {
        ArrowMatrix::zeros(self.n_band(), CTRL - 1, POSE_PARAMS)
    }

    fn keeps_setup(&self, theta: &[f64]) -> bool {
        self.selection(theta[self.n_band() + TAU]) == self.selected
    }
}

mod extra;
pub use extra::ExtraSums;

#[cfg(test)]
mod tests;
