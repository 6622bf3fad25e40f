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

use robimu_model::geom::M3;
use robimu_model::pose_measurement::rows::{
    prediction_rows, RowContext, SegmentCache, ACCEL_COLS, GYRO_COLS, GYRO_LOCAL,
};
use robimu_model::pose_measurement::{self as pm, CTRL};
use robimu_model::PoseSpline;

use super::{through_right_jacobians, PoseProblem, PoseProblemError, PER_CONTROL};
use crate::arrow::SelectedInverse;

/// Channels: the six IMU channels [ax, ay, az, gx, gy, gz], then the pose
/// positions (3 rows a sample) and rotations (3 rows a sample).
pub const FIT_CHANNELS: usize = 8;

/// RSS, rows and leverage per channel ([`PoseProblem::channel_fit`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelFit {
    /// Whitened residual sum of squares.
    pub rss: [f64; FIT_CHANNELS],
    /// Rows.
    pub rows: [usize; FIT_CHANNELS],
    /// Σ of the rows' leverages j_iᵀ A⁻¹ j_i.
    pub leverage: [f64; FIT_CHANNELS],
}

impl ChannelFit {
    /// σ̂_c / σ_c = √(RSS_c / (N_c − h_c)) (module doc); `None` where no
    /// degree of freedom is left.
    pub fn sigma_ratio(&self) -> [Option<f64>; FIT_CHANNELS] {
        std::array::from_fn(|c| {
            let dof = self.rows[c] as f64 - self.leverage[c];
            (dof > 0.0).then(|| (self.rss[c] / dof).sqrt())
        })
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

/// The noise levels that whiten a pose problem's rows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSigma {
    /// σ_z per IMU channel [ax, ay, az (m/s²), gx, gy, gz (rad/s)].
    pub sigma_z: [f64; 6],
    /// σ_p (m).
    pub sigma_p: f64,
    /// σ_r (rad).
    pub sigma_r: f64,
}

impl PoseSigma {
    /// In [`FIT_CHANNELS`] order.
    pub fn channels(&self) -> [f64; FIT_CHANNELS] {
        let z = self.sigma_z;
        [
            z[0],
            z[1],
            z[2],
            z[3],
            z[4],
            z[5],
            self.sigma_p,
            self.sigma_r,
        ]
    }

    /// Each channel's σ times `factor[c]`.
    pub fn scaled(&self, factor: [f64; FIT_CHANNELS]) -> Self {
        Self {
            sigma_z: std::array::from_fn(|c| self.sigma_z[c] * factor[c]),
            sigma_p: self.sigma_p * factor[6],
            sigma_r: self.sigma_r * factor[7],
        }
    }
}

impl PoseProblem {
    /// The σ that whiten the rows.
    pub fn sigma(&self) -> PoseSigma {
        PoseSigma {
            sigma_z: self.data.sigma_z,
            sigma_p: self.data.sigma_p,
            sigma_r: self.data.sigma_r,
        }
    }

    /// Whiten the rows with `s` from now on (every σ positive and finite).
    pub fn set_sigma(&mut self, s: PoseSigma) -> Result<(), PoseProblemError> {
        if !s.channels().iter().all(|v| v.is_finite() && *v > 0.0) {
            return Err(PoseProblemError::Input(
                "every σ must be positive and finite".into(),
            ));
        }
        self.data.sigma_z = s.sigma_z;
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
        let (sp, jr, nc) = (
            self.spline(theta)?,
            self.right_jacobians(theta),
            self.n_band(),
        );
        let mut fit = ChannelFit {
            rss: [0.0; FIT_CHANNELS],
            rows: [0; FIT_CHANNELS],
            leverage: [0.0; FIT_CHANNELS],
        };
        for k in 0..self.data.pose_t.len() {
            let b = self.pose_block(&sp, &jr, k)?;
            let c0 = PER_CONTROL * b.first;
            let m = gather(inv, &std::array::from_fn::<_, CTRL, _>(|l| c0 + l))?;
            for r in 0..6 {
                let c = 6 + r / 3;
                fit.rss[c] += b.r[r] * b.r[r];
                fit.rows[c] += 1;
                fit.leverage[c] += quadratic(&m, &b.j[r]);
            }
        }
        let (d, x) = (&self.data, self.x(theta));
        let w: [f64; 6] = d.sigma_z.map(|s| 1.0 / s);
        let stride = stride.max(1);
        let mut lev = Leverage::new(RowContext::new(x)?, nc, w, stride as f64);
        for (n, &i) in self.selected.iter().enumerate() {
            let z = if n % stride == 0 {
                lev.add(&sp, &jr, d.imu_t[i], inv, &mut fit.leverage)?
            } else {
                pm::predict(&sp, d.imu_t[i], x)?
            };
            for c in 0..6 {
                let e = (z[c] - d.imu_z[i][c]) * w[c];
                fit.rss[c] += e * e;
                fit.rows[c] += 1;
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
    nc: usize,
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
    fn new(ctx: RowContext, nc: usize, w: [f64; 6], weight: f64) -> Self {
        Self {
            ctx,
            seeds: SegmentCache::default(),
            nc,
            w,
            weight,
            seg: None,
        }
    }

    /// Add `weight` × the leverage of the sample at `t` to `out`; its
    /// prediction z.
    fn add(
        &mut self,
        sp: &PoseSpline,
        jr: &[M3],
        t: f64,
        inv: &SelectedInverse,
        out: &mut [f64; FIT_CHANNELS],
    ) -> Result<[f64; 6], PoseProblemError> {
        let mut rows = prediction_rows(sp, t, &self.ctx, &mut self.seeds)?;
        through_right_jacobians(&mut rows, jr);
        if self.seg.as_ref().is_none_or(|s| s.0 != rows.first) {
            let (c0, nc) = (PER_CONTROL * rows.first, self.nc);
            let local = |l: usize| if l < CTRL { c0 + l } else { nc + l - CTRL };
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

    use super::super::tests::small_problem;
    use super::*;
    use crate::LeastSquares;

    /// Per channel, the leverage is Σ_i j_iᵀ A⁻¹ j_i with j_i the rows of a
    /// finite-difference Jacobian of the residuals and A⁻¹ the dense
    /// inverse; the RSS is the residuals'; and over every row and the prior
    /// the leverages sum to the number of unknowns (tr A⁻¹A).
    #[test]
    fn leverage_and_rss_match_a_dense_computation() {
        let (mut p, theta) = small_problem();
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
        let np = 6 * p.data.pose_t.len();
        let channel = |r: usize| {
            if r < np {
                6 + (r % 6) / 3
            } else if r < np + 6 * p.selected().len() {
                (r - np) % 6
            } else {
                FIT_CHANNELS
            }
        };
        let (mut want_h, mut want_rss, mut want_n) = ([0.0; 9], [0.0; 9], [0usize; 9]);
        for r in 0..r0.len() {
            let c = channel(r);
            want_h[c] += lev[(r, r)];
            want_rss[c] += r0[r] * r0[r];
            want_n[c] += 1;
        }
        for c in 0..FIT_CHANNELS {
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
        for c in 0..FIT_CHANNELS {
            let dof = want_n[c] as f64 - want_h[c];
            let want = (want_rss[c] / dof).sqrt();
            assert!(
                (ratio[c].unwrap() - want).abs() < 1e-6 * want,
                "channel {c}"
            );
        }
    }
}
