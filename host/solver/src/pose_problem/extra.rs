//! The sums of a Rao score test of extra columns against a pose problem
//! (docs/model.md §7.9, *diagnosis*): for columns C(i) = ∂z_i/∂θ_e (6 × k)
//! at each selected IMU sample, with W = diag(σ_z⁻²) and r_i = ẑ_i − z_i at θ,
//!
//! ```text
//! u = Σ C(i)ᵀ W r_i      D = Σ C(i)ᵀ W C(i)      B = Σ J_i(θ)ᵀ W C(i)   (n × k)
//! ```
//!
//! J_i the sample's Jacobian in θ's unknowns (spline and x, the rows of
//! [`PoseProblem::linearize`]). The test projects every unknown of θ out
//! with the fit's Gauss–Newton matrix A: V = D + P − Bᵀ A⁻¹ B.

use robimu_model::pose_measurement::imu_view;
use robimu_model::pose_measurement::inertial::{dz_dt_of, PoseImuSample};
use robimu_model::pose_measurement::rows::{
    prediction_rows, RowContext, SegmentCache, ACCEL_COLS, GYRO_LOCAL,
};

use super::{through_right_jacobians, PoseData, PoseProblem, PoseProblemError};

/// The sums of the module doc.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraSums {
    /// u (k).
    pub u: Vec<f64>,
    /// D (k × k), rows.
    pub d: Vec<Vec<f64>>,
    /// B by columns: k vectors of θ's length.
    pub b: Vec<Vec<f64>>,
}

impl PoseProblem {
    /// The data the problem was built on.
    pub fn data(&self) -> &PoseData {
        &self.data
    }

    /// The initial spline (θ's c = 0).
    pub fn base(&self) -> &robimu_model::PoseSpline {
        &self.base
    }

    /// The sums of `k` extra columns of IMU `imu`'s samples at θ (the
    /// selection of the last [`crate::LeastSquares::begin_iteration`]);
    /// `columns(m, sample, cols)` writes C(i) (k columns of 6, zeroed
    /// before) of the m-th selected sample, i =
    /// [`Self::selected_of`]`(imu)[m]`.
    pub fn extra_sums(
        &self,
        theta: &[f64],
        imu: usize,
        k: usize,
        mut columns: impl FnMut(usize, &PoseImuSample<'_>, &mut [[f64; 6]]),
    ) -> Result<ExtraSums, PoseProblemError> {
        let (sp, jr) = (self.spline(theta)?, self.right_jacobians(theta));
        let (d, xj) = (self.imu(imu), imu_view(self.x(theta), imu));
        let ctx = RowContext::new(&xj)?;
        let w2: [f64; 6] = d.sigma_z.map(|s| 1.0 / (s * s));
        let mut out = ExtraSums {
            u: vec![0.0; k],
            d: vec![vec![0.0; k]; k],
            b: vec![vec![0.0; theta.len()]; k],
        };
        let mut seeds = SegmentCache::default();
        let mut cols = vec![[0.0; 6]; k];
        let map = self.columns(imu);
        for (m, &i) in self.selected[imu].iter().enumerate() {
            let mut rows = prediction_rows(&sp, d.t[i], &ctx, &mut seeds)?;
            let sample = PoseImuSample::new(&sp, d.t[i], &xj, dz_dt_of(&rows));
            cols.iter_mut().for_each(|c| *c = [0.0; 6]);
            columns(m, &sample, &mut cols);
            through_right_jacobians(&mut rows, &jr);
            // W C(i), column by column
            let wc: Vec<[f64; 6]> = cols
                .iter()
                .map(|c| std::array::from_fn(|r| c[r] * w2[r]))
                .collect();
            for a in 0..k {
                out.u[a] += (0..6)
                    .map(|r| wc[a][r] * (rows.z[r] - d.z[i][r]))
                    .sum::<f64>();
                for b in 0..k {
                    out.d[a][b] += (0..6).map(|r| wc[a][r] * cols[b][r]).sum::<f64>();
                }
            }
            for r in 0..3 {
                for p in 0..ACCEL_COLS {
                    let (at, v) = (map.theta(rows.first, p), rows.accel[r][p]);
                    for (bj, wj) in out.b.iter_mut().zip(&wc) {
                        bj[at] += v * wj[r];
                    }
                }
                for (p, &l) in GYRO_LOCAL.iter().enumerate() {
                    let (at, v) = (map.theta(rows.first, l), rows.gyro[r][p]);
                    for (bj, wj) in out.b.iter_mut().zip(&wc) {
                        bj[at] += v * wj[3 + r];
                    }
                }
            }
        }
        Ok(out)
    }
}
