//! The fit's share of each residual channel (docs/model.md §7.9, noise):
//! per channel c the whitened residual sum of squares RSS_c, the number of
//! rows N_c and the leverage h_c = Σ_{i∈c} j_iᵀ A⁻¹ j_i (j_i the whitened
//! Jacobian row, A the Gauss–Newton matrix with the prior). For a linear
//! model with the right σ, E[RSS_c] = N_c − h_c, so
//! σ̂_c² = σ_c² · RSS_c / (N_c − h_c) is the channel's noise level with the
//! part the fit absorbed (the spline's and x's) put back; the raw RMS is
//! low by √(1 − h_c/N_c).
//!
//! A⁻¹ is read on the arrowhead's pattern ([`SelectedInverse`]): every row
//! touches the 4 control points at its time and x.
//!
//! Channels, 6K + 2 of them with K IMUs: IMU j's [ax, ay, az, gx, gy, gz]
//! at 6j..6j + 6, then the pose positions (3 rows a sample) and rotations
//! (3 rows a sample) ([`ChannelFit`]).

use robimu_model::geom::M3;
use robimu_model::pose_measurement::rows::{
    prediction_rows, RowContext, SegmentCache, ACCEL_COLS, GYRO_COLS, GYRO_LOCAL,
};
use robimu_model::pose_measurement::{self as pm, imu_view, CTRL};
use robimu_model::PoseSpline;

use super::{through_right_jacobians, Columns, PoseProblem, PoseProblemError, PER_CONTROL};
use crate::arrow::SelectedInverse;

/// RSS, rows and leverage per channel ([`PoseProblem::channel_fit`]; the
/// channels' order in the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelFit {
    /// Whitened residual sum of squares.
    pub rss: Vec<f64>,
    /// Rows.
    pub rows: Vec<usize>,
    /// Σ of the rows' leverages j_iᵀ A⁻¹ j_i.
    pub leverage: Vec<f64>,
}

impl ChannelFit {
    fn zeros(n_imus: usize) -> Self {
        let n = 6 * n_imus + 2;
        Self {
            rss: vec![0.0; n],
            rows: vec![0; n],
            leverage: vec![0.0; n],
        }
    }

    /// σ̂_c / σ_c = √(RSS_c / (N_c − h_c)) (module doc); `None` where no
    /// degree of freedom is left.
    pub fn sigma_ratio(&self) -> Vec<Option<f64>> {
        (0..self.rss.len())
            .map(|c| {
                let dof = self.rows[c] as f64 - self.leverage[c];
                (dof > 0.0).then(|| (self.rss[c] / dof).sqrt())
            })
            .collect()
    }
}

/// The noise levels that whiten a pose problem's rows.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseSigma {
    /// σ_z of each IMU per channel [ax, ay, az (m/s²), gx, gy, gz (rad/s)].
    pub sigma_z: Vec<[f64; 6]>,
    /// σ_p (m).
    pub sigma_p: f64,
    /// σ_r (rad).
    pub sigma_r: f64,
}

impl PoseSigma {
    /// In the channels' order (module doc).
    pub fn channels(&self) -> Vec<f64> {
        let mut v: Vec<f64> = self.sigma_z.iter().flatten().copied().collect();
        v.extend([self.sigma_p, self.sigma_r]);
        v
    }

    /// Each channel's σ times `factor[c]` (the channels' order).
    pub fn scaled(&self, factor: &[f64]) -> Self {
        let k = self.sigma_z.len();
        Self {
            sigma_z: (0..k)
                .map(|j| std::array::from_fn(|c| self.sigma_z[j][c] * factor[6 * j + c]))
                .collect(),
            sigma_p: self.sigma_p * factor[6 * k],
            sigma_r: self.sigma_r * factor[6 * k + 1],
        }
    }
}

/// A⁻¹ on the unknowns `idx` (C of them), dense.
fn gather<const C: usize>(
    inv: &SelectedInverse,
    idx: &[usize; C],
) -> Result<Box<[[f64; C]; C]>, PoseProblemError> {
    let mut m = Box::new([[0.0; C]; C]);
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate().take(a + 1) {
            let v = inv.get(i, j).ok_or_else(|| {
                PoseProblemError::Input("the inverse lacks an entry of a row's support".into())
            })?;
            m[a][b] = v;
            m[b][a] = v;
        }
    }
    Ok(m)
}

/// vᵀ M v.
fn quadratic<const C: usize>(m: &[[f64; C]; C], v: &[f64; C]) -> f64 {
    let mut s = 0.0;
    for (row, vp) in m.iter().zip(v) {
        if *vp != 0.0 {
            let mv: f64 = row.iter().zip(v).map(|(a, b)| a * b).sum();
            s += vp * mv;
        }
    }
    s
}

impl PoseProblem {
    /// The σ that whiten the rows.
    pub fn sigma(&self) -> PoseSigma {
        PoseSigma {
            sigma_z: (0..self.n_imus()).map(|j| *self.imu(j).sigma_z).collect(),
            sigma_p: self.data.sigma_p,
            sigma_r: self.data.sigma_r,
        }
    }

    /// Whiten the rows with `s` from now on (σ_z for every IMU, every σ
    /// positive and finite).
    pub fn set_sigma(&mut self, s: &PoseSigma) -> Result<(), PoseProblemError> {
        if s.sigma_z.len() != self.n_imus() {
            return Err(PoseProblemError::Input(format!(
                "σ_z for {} IMUs, the problem has {}",
                s.sigma_z.len(),
                self.n_imus()
            )));
        }
        if !s.channels().iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(PoseProblemError::Input(
                "every σ must be positive and finite".into(),
            ));
        }
        self.data.sigma_z = s.sigma_z[0];
        for (m, z) in self.more.iter_mut().zip(&s.sigma_z[1..]) {
            m.sigma_z = *z;
        }
        self.data.sigma_p = s.sigma_p;
        self.data.sigma_r = s.sigma_r;
        Ok(())
    }

    /// RSS, rows and leverage per channel at θ (module doc), with `inv` the
    /// selected inverse of the Gauss–Newton matrix at θ (the solve's final
    /// factor). The IMU rows' leverage is summed over every `stride`-th
    /// sample, times `stride` (a sample's leverage changes smoothly with the
    /// motion, and an error ε in h_c moves σ̂_c by ε·h_c/(2(N_c − h_c)),
    /// about ε/20 here). Call after
    /// [`crate::LeastSquares::begin_iteration`] at θ.
    pub fn channel_fit(
        &self,
        theta: &[f64],
        inv: &SelectedInverse,
        stride: usize,
    ) -> Result<ChannelFit, PoseProblemError> {
        let (sp, jr) = (self.spline(theta)?, self.right_jacobians(theta));
        let k_imus = self.n_imus();
        let mut fit = ChannelFit::zeros(k_imus);
        let (cp, cr) = (6 * k_imus, 6 * k_imus + 1);
        for k in 0..self.data.pose_t.len() {
            let b = self.pose_block(&sp, &jr, k)?;
            let c0 = PER_CONTROL * b.first;
            let m = gather(inv, &std::array::from_fn::<_, CTRL, _>(|l| c0 + l))?;
            for r in 0..6 {
                let c = if r < 3 { cp } else { cr };
                fit.rss[c] += b.r[r] * b.r[r];
                fit.rows[c] += 1;
                fit.leverage[c] += quadratic(&m, &b.j[r]);
            }
        }
        let x = self.x(theta);
        for j in 0..k_imus {
            let (imu, xj) = (self.imu(j), imu_view(x, j));
            let w: [f64; 6] = imu.sigma_z.map(|s| 1.0 / s);
            let stride = stride.max(1);
            let cols = self.columns(j);
            let mut lev = Leverage::new(RowContext::new(&xj)?, cols, w, stride as f64);
            let mut out = [0.0; 6];
            for (n, &i) in self.selected[j].iter().enumerate() {
                let z = if n % stride == 0 {
                    lev.add(&sp, &jr, imu.t[i], inv, &mut out)?
                } else {
                    pm::predict(&sp, imu.t[i], &xj)?
                };
                for c in 0..6 {
                    let e = (z[c] - imu.z[i][c]) * w[c];
                    fit.rss[6 * j + c] += e * e;
                    fit.rows[6 * j + c] += 1;
                }
            }
            for c in 0..6 {
                fit.leverage[6 * j + c] = out[c];
            }
        }
        Ok(fit)
    }
}

/// The IMU rows' leverage, sample by sample, with A⁻¹ gathered once per
/// segment (the 4 control points at t + τ).
struct Leverage {
    ctx: RowContext,
    seeds: SegmentCache,
    /// Where the rows' compact columns go in θ.
    cols: Columns,
    w: [f64; 6],
    weight: f64,
    seg: Option<Seg>,
}

/// A segment's first control point and A⁻¹ on its accelerometer and
/// gyroscope columns.
type Seg = (
    usize,
    Box<[[f64; ACCEL_COLS]; ACCEL_COLS]>,
    Box<[[f64; GYRO_COLS]; GYRO_COLS]>,
);

impl Leverage {
    fn new(ctx: RowContext, cols: Columns, w: [f64; 6], weight: f64) -> Self {
        Self {
            ctx,
            seeds: SegmentCache::default(),
            cols,
            w,
            weight,
            seg: None,
        }
    }

    /// Add `weight` × the leverage of the sample at `t` to `out` (the
    /// IMU's six channels); its prediction z.
    fn add(
        &mut self,
        sp: &PoseSpline,
        jr: &[M3],
        t: f64,
        inv: &SelectedInverse,
        out: &mut [f64; 6],
    ) -> Result<[f64; 6], PoseProblemError> {
        let mut rows = prediction_rows(sp, t, &self.ctx, &mut self.seeds)?;
        through_right_jacobians(&mut rows, jr);
        if self.seg.as_ref().is_none_or(|s| s.0 != rows.first) {
            let (first, cols) = (rows.first, &self.cols);
            let local = |l: usize| cols.theta(first, l);
            let a_idx: [usize; ACCEL_COLS] = std::array::from_fn(local);
            let g_idx: [usize; GYRO_COLS] = GYRO_LOCAL.map(local);
            self.seg = Some((rows.first, gather(inv, &a_idx)?, gather(inv, &g_idx)?));
        }
        let (_, ma, mg) = self.seg.as_ref().expect("set above");
        let w = &self.w;
        for r in 0..3 {
            let va: [f64; ACCEL_COLS] = rows.accel[r].map(|v| v * w[r]);
            let vg: [f64; GYRO_COLS] = rows.gyro[r].map(|v| v * w[3 + r]);
            out[r] += self.weight * quadratic(ma, &va);
            out[3 + r] += self.weight * quadratic(mg, &vg);
        }
        Ok(rows.z)
    }
}

#[cfg(test)]
mod tests {
    use faer::linalg::solvers::DenseSolveCore;
    use faer::{Mat, Side};

    use super::super::tests::{small_problem, two_imu_problem};
    use super::*;
    use crate::LeastSquares;

    /// Per channel, the leverage is Σ_i j_iᵀ A⁻¹ j_i with j_i the rows of a
    /// finite-difference Jacobian of the residuals and A⁻¹ the dense
    /// inverse; the RSS is the residuals'; and over every row and the prior
    /// the leverages sum to the number of unknowns (tr A⁻¹A). With one IMU
    /// and with two.
    #[test]
    fn leverage_and_rss_match_a_dense_computation() {
        check_against_dense(small_problem());
        check_against_dense(two_imu_problem());
    }

    fn check_against_dense((mut p, theta): (PoseProblem, Vec<f64>)) {
        p.begin_iteration(&theta).unwrap();
        let n = p.n_unknowns();
        let mut a = p.new_matrix();
        let mut g = vec![0.0; n];
        p.linearize(&theta, &mut a, &mut g).unwrap();
        let fit = p
            .channel_fit(&theta, &a.factor().unwrap().selected_inverse(), 1)
            .unwrap();
        let inv = Mat::from_fn(n, n, |i, j| a.get(i, j))
            .llt(Side::Lower)
            .unwrap()
            .inverse();
        let r0 = p.residuals(&theta).unwrap();
        let h = 1e-6;
        let mut jac = Mat::<f64>::zeros(r0.len(), n);
        for k in 0..n {
            let (mut tp, mut tm) = (theta.clone(), theta.clone());
            tp[k] += h;
            tm[k] -= h;
            let (rp, rm) = (p.residuals(&tp).unwrap(), p.residuals(&tm).unwrap());
            for r in 0..r0.len() {
                jac[(r, k)] = (rp[r] - rm[r]) / (2.0 * h);
            }
        }
        let lev = &jac * &inv * jac.transpose();
        // residuals(): poses (6 each), IMU 0's samples, IMU 1's, …, prior
        let (k_imus, np) = (p.n_imus(), 6 * p.data.pose_t.len());
        let nch = 6 * k_imus + 2;
        let mut channel = vec![nch; r0.len()];
        for r in 0..np {
            channel[r] = 6 * k_imus + (r % 6) / 3;
        }
        let mut r = np;
        for j in 0..k_imus {
            for _ in 0..6 * p.selected_of(j).len() {
                channel[r] = 6 * j + (r - np) % 6;
                r += 1;
            }
        }
        let (mut want_h, mut want_rss, mut want_n) = (
            vec![0.0; nch + 1],
            vec![0.0; nch + 1],
            vec![0usize; nch + 1],
        );
        for r in 0..r0.len() {
            let c = channel[r];
            want_h[c] += lev[(r, r)];
            want_rss[c] += r0[r] * r0[r];
            want_n[c] += 1;
        }
        assert_eq!(fit.rss.len(), nch);
        for c in 0..nch {
            assert!(
                (fit.leverage[c] - want_h[c]).abs() < 1e-5 * (1.0 + want_h[c]),
                "channel {c}: leverage {} vs {}",
                fit.leverage[c],
                want_h[c]
            );
            assert!((fit.rss[c] - want_rss[c]).abs() < 1e-9 * (1.0 + want_rss[c]));
            assert_eq!(fit.rows[c], want_n[c], "channel {c}");
        }
        let total: f64 = want_h.iter().sum();
        assert!((total - n as f64).abs() < 1e-4 * n as f64, "{total} vs {n}");
        let ratio = fit.sigma_ratio();
        for c in 0..nch {
            let dof = want_n[c] as f64 - want_h[c];
            let want = (want_rss[c] / dof).sqrt();
            assert!(
                (ratio[c].unwrap() - want).abs() < 1e-6 * want,
                "channel {c}"
            );
        }
    }
}
