//! The MAP problem of a pose session (MODEL.md §10; the joint-space
//! problem's arrangement, [`crate::problem`]): unknowns θ = [c, x] with c
//! the pose spline's control-point corrections, 6 per control point
//! (Δc_k, then φ_k with R_k = R_k0·Exp(φ_k) about the initial fit R_k0), and
//! x the 30 parameters ([`robimu_model::pose_measurement`]); with K IMUs
//! (MODEL.md §9, §10) x is IMU 0's 30 then 28 per further IMU, one pose
//! spline serving all, each IMU's samples predicted from its own 30-vector
//! ([`pm::imu_indices`]) and their Jacobian columns scattered into x.
//!
//! Residuals, each whitened by its σ: pose samples (e_p = p(t_k) − p̃ with
//! σ_p, e_r = Log(R̃ᵀR(t_k)) with σ_r), IMU samples (σ_z per channel; a
//! sample whose t_i + τ is outside the pose span, or within
//! [`SPAN_MARGIN`] of its ends, is left out, the set chosen at every
//! iteration, §4) and the prior on x. Every residual touches
//! the 4 control points at its time, so the Gauss–Newton matrix is an
//! [`ArrowMatrix`] of half-bandwidth 23 bordered by x.

use std::ops::Range;

use faer::Mat;
use robimu_model::geom::{mul_mm, M3, V3};
use robimu_model::pose_measurement::rows::{
    prediction_rows, PoseRows, RowContext, SegmentCache, ACCEL_COLS, GYRO_COLS, GYRO_LOCAL,
};
use robimu_model::pose_measurement::{
    self as pm, imu_indices, imu_view, PoseMeasurementError, CTRL, POSE_PARAMS, TAU,
};
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

/// The samples and σ_z of IMU j ≥ 1 of a pose problem (IMU 0's are in
/// [`PoseData`]).
#[derive(Debug, Clone)]
pub struct PoseImuData {
    /// IMU sample times (s).
    pub imu_t: Vec<f64>,
    /// IMU samples [ax, ay, az, gx, gy, gz].
    pub imu_z: Vec<[f64; 6]>,
    /// σ_z per channel.
    pub sigma_z: [f64; 6],
}

/// The pose-session problem ([`LeastSquares`]; module doc).
#[derive(Debug, Clone)]
pub struct PoseProblem {
    base: PoseSpline,
    data: PoseData,
    more: Vec<PoseImuData>,
    /// The selected samples of each IMU.
    selected: Vec<Vec<usize>>,
}

/// IMU j's samples: times, values, σ_z.
struct ImuRef<'a> {
    t: &'a [f64],
    z: &'a [[f64; 6]],
    sigma_z: &'a [f64; 6],
}

/// The local Jacobian block of one residual group: rows × (24 band + 30 x)
/// and the whitened residuals.
struct Block {
    first: usize,
    rows: usize,
    j: [[f64; CTRL]; 6],
    r: [f64; 6],
}

/// Where the compact columns of IMU j's sample rows ([`pm::rows`]) go in
/// θ: local column l < 24 is the band unknown 6·first + l (the 4 control
/// points from `first`), l ≥ 24 is x's entry `x_index[l − 24]` (IMU j's
/// 30-vector, [`imu_indices`]), at nc + that in θ.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Columns {
    /// Band unknowns (θ's x starts here).
    nc: usize,
    /// x's index of each entry of the IMU's 30-vector.
    x_index: [usize; POSE_PARAMS],
}

impl Columns {
    /// θ's index of local column `l` of a row whose first control point is
    /// `first`.
    pub(crate) fn theta(&self, first: usize, l: usize) -> usize {
        if l < CTRL {
            PER_CONTROL * first + l
        } else {
            self.nc + self.x_index[l - CTRL]
        }
    }
}

impl PoseProblem {
    /// A problem about the initial spline `base` (θ's c = 0 is `base`).
    pub fn new(base: PoseSpline, data: PoseData) -> Result<Self, PoseProblemError> {
        Self::with_imus(base, data, Vec::new())
    }

    /// A problem with IMU 0 in `data` and IMU j ≥ 1 in `more[j − 1]`; the
    /// prior in `data` spans all 2 + 28·K parameters.
    pub fn with_imus(
        base: PoseSpline,
        data: PoseData,
        more: Vec<PoseImuData>,
    ) -> Result<Self, PoseProblemError> {
        let n = data.pose_t.len();
        let uneven = more.iter().any(|m| m.imu_t.len() != m.imu_z.len());
        if data.pose_p.len() != n
            || data.pose_r.len() != n
            || data.imu_z.len() != data.imu_t.len()
            || uneven
        {
            return Err(PoseProblemError::Input(
                "sample buffers of different lengths".into(),
            ));
        }
        let nx = pm::n_pose_params(1 + more.len());
        if data.prior_mean.len() != nx || data.prior_sigma.len() != nx {
            return Err(PoseProblemError::Input(format!(
                "the prior needs {nx} means and σ ({} IMU(s))",
                1 + more.len()
            )));
        }
        let bad_sigma = (data.prior_sigma.iter().chain(&data.sigma_z))
            .chain(more.iter().flat_map(|m| &m.sigma_z))
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
            selected: vec![Vec::new(); 1 + more.len()],
            more,
        })
    }

    /// Number of IMUs K.
    pub fn n_imus(&self) -> usize {
        1 + self.more.len()
    }

    /// Number of parameters x (2 + 28·K).
    pub fn n_x(&self) -> usize {
        pm::n_pose_params(self.n_imus())
    }

    /// The column map of IMU `j`'s rows.
    pub(crate) fn columns(&self, j: usize) -> Columns {
        Columns {
            nc: self.n_band(),
            x_index: imu_indices(j),
        }
    }

    fn imu(&self, j: usize) -> ImuRef<'_> {
        match j {
            0 => ImuRef {
                t: &self.data.imu_t,
                z: &self.data.imu_z,
                sigma_z: &self.data.sigma_z,
            },
            _ => {
                let m = &self.more[j - 1];
                ImuRef {
                    t: &m.imu_t,
                    z: &m.imu_z,
                    sigma_z: &m.sigma_z,
                }
            }
        }
    }

    /// Number of band unknowns (6 per control point).
    pub fn n_band(&self) -> usize {
        PER_CONTROL * self.base.num_control_points()
    }

    /// Number of unknowns (band + x).
    pub fn n_unknowns(&self) -> usize {
        self.n_band() + self.n_x()
    }

    /// IMU 0's samples in the current cost (those with t_i + τ in the pose span).
    pub fn selected(&self) -> &[usize] {
        &self.selected[0]
    }

    /// IMU `j`'s samples in the current cost.
    pub fn selected_of(&self, j: usize) -> &[usize] {
        &self.selected[j]
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

    /// IMU samples (times `imu_t`) whose t_i + τ is inside the pose span,
    /// [`SPAN_MARGIN`] from its ends.
    fn selection(&self, imu_t: &[f64], tau: f64) -> Vec<usize> {
        let k = self.base.knots();
        let (t0, t1) = (k.start() + SPAN_MARGIN, k.end() - SPAN_MARGIN);
        (0..imu_t.len())
            .filter(|&i| (t0..=t1).contains(&(imu_t[i] + tau)))
            .collect()
    }

    /// Every IMU's selection at θ.
    fn selections(&self, theta: &[f64]) -> Vec<Vec<usize>> {
        let x = self.x(theta);
        (0..self.n_imus())
            .map(|j| self.selection(self.imu(j).t, x[imu_indices(j)[TAU]]))
            .collect()
    }

    /// The whitened residual vector at θ: pose samples (6 each), selected
    /// IMU samples (6 each; IMU 0's, then IMU 1's, …), prior (all of x).
    pub fn residuals(&self, theta: &[f64]) -> Result<Vec<f64>, PoseProblemError> {
        let sp = self.spline(theta)?;
        let x = self.x(theta);
        let d = &self.data;
        let n_imu: usize = self.selected.iter().map(Vec::len).sum();
        let mut out = Vec::with_capacity(6 * (d.pose_t.len() + n_imu) + x.len());
        for k in 0..d.pose_t.len() {
            let (e_p, e_r) = sp.pose_error_r(d.pose_t[k], d.pose_p[k], &d.pose_r[k])?;
            out.extend(e_p.iter().map(|v| v / d.sigma_p));
            out.extend(e_r.iter().map(|v| v / d.sigma_r));
        }
        for (j, selected) in self.selected.iter().enumerate() {
            let (imu, xj) = (self.imu(j), imu_view(x, j));
            for &i in selected {
                let z = pm::predict(&sp, imu.t[i], &xj)?;
                out.extend((0..6).map(|c| (z[c] - imu.z[i][c]) / imu.sigma_z[c]));
            }
        }
        out.extend((0..x.len()).map(|k| (x[k] - d.prior_mean[k]) / d.prior_sigma[k]));
        Ok(out)
    }

    /// IMU `j`'s selected samples at θ: (t_i, z_i − ẑ_i), measured minus
    /// predicted, not whitened (m/s², rad/s).
    pub fn imu_residuals(
        &self,
        theta: &[f64],
        j: usize,
    ) -> Result<Vec<(f64, [f64; 6])>, PoseProblemError> {
        let (sp, imu) = (self.spline(theta)?, self.imu(j));
        let xj = imu_view(self.x(theta), j);
        (self.selected[j].iter())
            .map(|&i| {
                let z = pm::predict(&sp, imu.t[i], &xj)?;
                Ok((imu.t[i], std::array::from_fn(|c| imu.z[i][c] - z[c])))
            })
            .collect()
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
    /// (w_r² times each row's outer product, without a whitened copy of
    /// the rows.)
    fn add(&mut self, rows: &[[f64; C]; 3], w: &[f64], wr: &[f64]) {
        let [r0, r1, r2] = rows;
        let w2 = [w[0] * w[0], w[1] * w[1], w[2] * w[2]];
        for p in 0..C {
            let (y0, y1, y2) = (r0[p] * w2[0], r1[p] * w2[1], r2[p] * w2[2]);
            let row = &mut self.m[p];
            for q in 0..C {
                row[q] += y0 * r0[q] + y1 * r1[q] + y2 * r2[q];
            }
            self.g[p] += r0[p] * w[0] * wr[0] + r1[p] * w[1] * wr[1] + r2[p] * w[2] * wr[2];
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

    /// Add the sums to `a`, `g` (the columns at `cols`) and start empty.
    fn flush(&mut self, a: &mut ArrowMatrix, g: &mut [f64], cols: &Columns) {
        if self.first == usize::MAX {
            return;
        }
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
        for (p, v) in grad.iter().enumerate() {
            g[cols.theta(self.first, p)] += v;
        }
        let c0 = PER_CONTROL * self.first;
        a.add_local(c0, CTRL, &cols.x_index, self.local.as_ref());
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

/// `0..n` in two halves.
fn halves(n: usize) -> [Range<usize>; 2] {
    [0..n / 2, n / 2..n]
}

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
    /// Add IMU `j`'s selected samples `part` (positions in its selection)
    /// normal equations at `sp`, x (segment
    /// by segment, [`Segment`]; its 30-vector's columns at
    /// [`imu_indices`]); their cost.
    fn linearize_imu(
        &self,
        (j, part): (usize, Range<usize>),
        sp: &PoseSpline,
        jr: &[M3],
        x: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, PoseProblemError> {
        let (imu, cols) = (self.imu(j), self.columns(j));
        let ctx = RowContext::new(&imu_view(x, j))?;
        let w: [f64; 6] = imu.sigma_z.map(|s| 1.0 / s);
        let (mut seg, mut seeds, mut cost) = (Segment::new(), SegmentCache::default(), 0.0);
        for &i in &self.selected[j][part] {
            let mut rows = prediction_rows(sp, imu.t[i], &ctx, &mut seeds)?;
            through_right_jacobians(&mut rows, jr);
            if rows.first != seg.first {
                seg.flush(a, g, &cols);
                seg.first = rows.first;
            }
            let wr: [f64; 6] = std::array::from_fn(|c| (rows.z[c] - imu.z[i][c]) * w[c]);
            cost += 0.5 * wr.iter().map(|r| r * r).sum::<f64>();
            seg.add(&rows, &w, &wr);
        }
        seg.flush(a, g, &cols);
        Ok(cost)
    }
}

impl LeastSquares for PoseProblem {
    type Error = PoseProblemError;

    fn begin_iteration(&mut self, theta: &[f64]) -> Result<(), Self::Error> {
        self.selected = self.selections(theta);
        Ok(())
    }

    fn cost(&self, theta: &[f64]) -> Result<f64, Self::Error> {
        Ok(0.5 * self.residuals(theta)?.iter().map(|r| r * r).sum::<f64>())
    }

    /// The samples in two halves, one per thread ([`robimu_model::pair`]),
    /// as the joint-angle problem's linearisation.
    fn linearize(
        &self,
        theta: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, Self::Error> {
        a.clear();
        g.fill(0.0);
        let (sp, jr) = (self.spline(theta)?, self.right_jacobians(theta));
        let x = self.x(theta);
        let (mut a2, mut g2) = (self.new_matrix(), vec![0.0; g.len()]);
        let half = |h: usize, a: &mut ArrowMatrix, g: &mut [f64]| {
            let mut local = Mat::zeros(CTRL, CTRL);
            let mut cost = 0.0;
            for k in halves(self.data.pose_t.len())[h].clone() {
                let b = self.pose_block(&sp, &jr, k)?;
                cost += 0.5 * b.r.iter().map(|r| r * r).sum::<f64>();
                accumulate_pose(a, g, &b, &mut local);
            }
            for j in 0..self.n_imus() {
                let part = halves(self.selected[j].len())[h].clone();
                cost += self.linearize_imu((j, part), &sp, &jr, x, a, g)?;
            }
            Ok::<_, PoseProblemError>(cost)
        };
        let (c1, c2) = robimu_model::pair::join(|| half(0, a, g), || half(1, &mut a2, &mut g2));
        let mut cost = c1? + c2?;
        a.add_assign(&a2);
        for (u, v) in g.iter_mut().zip(&g2) {
            *u += v;
        }
        let (d, nc) = (&self.data, self.n_band());
        for k in 0..x.len() {
            let w = 1.0 / (d.prior_sigma[k] * d.prior_sigma[k]);
            let e = x[k] - d.prior_mean[k];
            a.add_xx(k, k, w);
            g[nc + k] += w * e;
            cost += 0.5 * w * e * e;
        }
        Ok(cost)
    }

    fn new_matrix(&self) -> ArrowMatrix {
        ArrowMatrix::zeros(self.n_band(), CTRL - 1, self.n_x())
    }

    fn keeps_setup(&self, theta: &[f64]) -> bool {
        self.selections(theta) == self.selected
    }
}

mod extra;
mod leverage;
pub use extra::ExtraSums;

#[cfg(test)]
mod tests;

pub use leverage::{ChannelFit, PoseSigma};
