//! Cost, gradient and Gauss–Newton matrix of the problem, assembled per knot
//! span straight into the arrowhead storage (see the parent module).

use std::ops::Range;

use faer::{Accum, Mat, MatRef, Par};

use super::{Problem, ProblemError};
use crate::model::{Basis, JointState, MeasurementJacobians, MeasurementModel, Spline};
use crate::solver::ArrowMatrix;

/// Gauss–Newton matrix A = JᵀJ and gradient g = Jᵀr being accumulated.
struct Linearization<'m> {
    a: &'m mut ArrowMatrix,
    g: &'m mut [f64],
}

/// IMU samples stacked per flush of the group buffer.
const GROUP_CAP: usize = 200;

impl Problem<'_> {
    /// The cost ½‖r‖² at θ over the selected IMU samples.
    pub fn cost(&self, theta: &[f64]) -> Result<f64, ProblemError> {
        let x = self.x_of(theta);
        let model = self.model(&x)?;
        let spline = self.spline_of(theta);
        let mut cost = self.joint_terms(&spline, None) + self.prior_terms(&x, None, 0);
        for part in self.imu_parts() {
            cost += self.imu_terms(&model, &spline, &x, part, None)?;
        }
        Ok(cost)
    }

    /// Storage for [`Self::linearize`].
    pub fn new_matrix(&self) -> ArrowMatrix {
        ArrowMatrix::zeros(self.n_coeffs(), self.bandwidth(), self.active.len())
    }

    /// Linearise at θ: fill the Gauss–Newton matrix `a` and the gradient `g`
    /// (length nc + n_active), return the cost. The IMU terms are split over
    /// two threads.
    ///
    /// # Panics
    /// If `a` or `g` do not have the problem's dimensions.
    pub fn linearize(&self, theta: &[f64], a: &mut ArrowMatrix, g: &mut [f64]) -> Result<f64, ProblemError> {
        assert_eq!(a.dims(), self.new_matrix().dims());
        let x = self.x_of(theta);
        let model = self.model(&x)?;
        let spline = self.spline_of(theta);
        a.clear();
        g.fill(0.0);
        let [first, second] = self.imu_parts();
        let mut a2 = self.new_matrix();
        let mut g2 = vec![0.0; g.len()];
        let mut out = Linearization { a, g };
        let mut other = Linearization { a: &mut a2, g: &mut g2 };
        let (r1, r2) = std::thread::scope(|s| {
            let h = s.spawn(|| self.imu_terms(&model, &spline, &x, second, Some(&mut other)));
            let r1 = self.imu_terms(&model, &spline, &x, first, Some(&mut out));
            (r1, h.join().expect("assembly thread panicked"))
        });
        let mut cost = r1? + r2?;
        out.a.add_assign(&a2);
        for (u, v) in out.g.iter_mut().zip(&g2) {
            *u += v;
        }
        cost += self.joint_terms(&spline, Some(&mut out));
        let nc = self.n_coeffs();
        cost += self.prior_terms(&x, Some(&mut out), nc);
        Ok(cost)
    }

    /// Whitened IMU residuals r = (z − h)/σ_z at θ for every selected sample,
    /// with the index of the sample.
    pub fn imu_residuals(&self, theta: &[f64]) -> Result<Vec<(usize, [f64; 6])>, ProblemError> {
        let x = self.x_of(theta);
        let model = self.model(&x)?;
        let spline = self.spline_of(theta);
        let tau = x[self.layout.offsets().tau];
        let mut out = Vec::with_capacity(self.imu_range.len());
        let mut js = JointState::default();
        let mut basis = Basis::default();
        for i in self.imu_range.clone() {
            let u = self.data.imu_t[i] + tau;
            self.knots
                .basis(u, &mut basis)
                .map_err(|_| ProblemError::SampleOutOfSpan)?;
            spline.evaluate_basis(&basis, &mut js);
            let z = model.predict(&js);
            let zm = &self.data.imu_z[i];
            let r = std::array::from_fn(|c| (zm[c] - z[c]) * self.inv_sigma_z[c]);
            out.push((i, r));
        }
        Ok(out)
    }

    /// The selected IMU range split in two halves at a knot-span boundary.
    fn imu_parts(&self) -> [Range<usize>; 2] {
        let r = self.imu_range.clone();
        let mid = r.start + r.len() / 2;
        [r.start..mid, mid..r.end]
    }

    /// Joint residuals: cost, and (with `out`) their band and gradient terms.
    fn joint_terms(&self, spline: &Spline, mut out: Option<&mut Linearization<'_>>) -> f64 {
        let n = self.n;
        let c = spline.coeffs();
        let mut cost = 0.0;
        for (s, b) in self.joint_basis.iter().enumerate() {
            let qm = &self.data.joint_q[s * n..(s + 1) * n];
            for j in 0..n {
                let mut q = 0.0;
                for a in 0..b.count {
                    q += b.d[0][a] * c[(b.first + a) * n + j];
                }
                let w = self.inv_sigma_q[j];
                let r = (qm[j] - q) * w;
                cost += 0.5 * r * r;
                if let Some(out) = out.as_deref_mut() {
                    for a in 0..b.count {
                        let ia = (b.first + a) * n + j;
                        let ja = -b.d[0][a] * w;
                        out.g[ia] += ja * r;
                        for bb in 0..=a {
                            let ib = (b.first + bb) * n + j;
                            out.a.add_cc(ia, ib, ja * (-b.d[0][bb] * w));
                        }
                    }
                }
            }
        }
        cost
    }

    /// Prior residuals of the estimated parameters (θ's x part at `x0`).
    fn prior_terms(&self, x: &[f64], out: Option<&mut Linearization<'_>>, x0: usize) -> f64 {
        if !self.use_prior {
            return 0.0;
        }
        let mut cost = 0.0;
        let mut out = out;
        for (a, &k) in self.active.iter().enumerate() {
            let w = self.prior_inv_sigma[k];
            let r = (x[k] - self.prior_mean[k]) * w;
            cost += 0.5 * r * r;
            if let Some(out) = out.as_deref_mut() {
                out.g[x0 + a] += w * r;
                out.a.add_xx(a, a, w * w);
            }
        }
        cost
    }

    /// IMU residuals of the samples `range`: cost, and (with `out`) their
    /// Gauss–Newton blocks, flushed per knot span.
    fn imu_terms(
        &self,
        model: &MeasurementModel,
        spline: &Spline,
        x: &[f64],
        range: Range<usize>,
        mut out: Option<&mut Linearization<'_>>,
    ) -> Result<f64, ProblemError> {
        let n = self.n;
        let nl = (self.knots.degree() + 1) * n;
        let na = self.active.len();
        let cols = nl + na;
        let tau = x[self.layout.offsets().tau];
        let mut js = JointState::default();
        let mut basis = Basis::default();
        let mut jac = MeasurementJacobians::new(self.layout.len());
        let mut cost = 0.0;
        let linearize = out.is_some();
        let (mut jg, mut rg, mut local, mut glocal) = if linearize {
            (
                Mat::<f64>::zeros(6 * GROUP_CAP, cols),
                Mat::<f64>::zeros(6 * GROUP_CAP, 1),
                Mat::<f64>::zeros(cols, cols),
                Mat::<f64>::zeros(cols, 1),
            )
        } else {
            (Mat::new(), Mat::new(), Mat::new(), Mat::new())
        };
        let mut rows = 0usize;
        let mut group_first = usize::MAX;
        for i in range {
            let u = self.data.imu_t[i] + tau;
            self.knots
                .basis(u, &mut basis)
                .map_err(|_| ProblemError::SampleOutOfSpan)?;
            spline.evaluate_basis(&basis, &mut js);
            let zm = &self.data.imu_z[i];
            if !linearize {
                let z = model.predict(&js);
                for ch in 0..6 {
                    let r = (zm[ch] - z[ch]) * self.inv_sigma_z[ch];
                    cost += 0.5 * r * r;
                }
                continue;
            }
            let out = out.as_deref_mut().expect("linearize");
            if (basis.first != group_first && rows > 0) || rows + 6 > jg.nrows() {
                flush(
                    &mut jg,
                    &mut rg,
                    &mut local,
                    &mut glocal,
                    rows,
                    group_first * n,
                    nl,
                    na,
                    out,
                );
                rows = 0;
            }
            group_first = basis.first;
            model.jacobians(&js, &mut jac);
            for ch in 0..6 {
                let w = self.inv_sigma_z[ch];
                let r = (zm[ch] - jac.z[ch]) * w;
                cost += 0.5 * r * r;
                let row = rows + ch;
                rg[(row, 0)] = r;
                // ∂r/∂c_{first+a, j} = −(∂h/∂q_j N_a + ∂h/∂q̇_j N'_a + ∂h/∂q̈_j N''_a)/σ
                for a in 0..basis.count {
                    let (n0, n1, n2) = (basis.d[0][a], basis.d[1][a], basis.d[2][a]);
                    for j in 0..n {
                        jg[(row, a * n + j)] = -w
                            * (jac.dz_dq[j][ch] * n0
                                + jac.dz_dqd[j][ch] * n1
                                + jac.dz_dqdd[j][ch] * n2);
                    }
                }
                for (a, &k) in self.active.iter().enumerate() {
                    jg[(row, nl + a)] = -w * jac.dz_dx[k][ch];
                }
            }
            rows += 6;
        }
        if let Some(out) = out {
            if rows > 0 {
                flush(
                    &mut jg,
                    &mut rg,
                    &mut local,
                    &mut glocal,
                    rows,
                    group_first * n,
                    nl,
                    na,
                    out,
                );
            }
        }
        Ok(cost)
    }
}

/// Add JᵀJ and Jᵀr of the first `rows` rows of a group to `out`.
#[allow(clippy::too_many_arguments)]
fn flush(
    jg: &mut Mat<f64>,
    rg: &mut Mat<f64>,
    local: &mut Mat<f64>,
    glocal: &mut Mat<f64>,
    rows: usize,
    c0: usize,
    nl: usize,
    na: usize,
    out: &mut Linearization<'_>,
) {
    let j: MatRef<'_, f64> = jg.as_ref().subrows(0, rows);
    let r: MatRef<'_, f64> = rg.as_ref().subrows(0, rows);
    faer::linalg::matmul::matmul(
        local.as_mut(),
        Accum::Replace,
        j.transpose(),
        j,
        1.0,
        Par::Seq,
    );
    faer::linalg::matmul::matmul(
        glocal.as_mut(),
        Accum::Replace,
        j.transpose(),
        r,
        1.0,
        Par::Seq,
    );
    let xs: Vec<usize> = (0..na).collect();
    out.a.add_local(c0, nl, &xs, local.as_ref());
    let nc = out.a.dims().0;
    for a in 0..nl {
        out.g[c0 + a] += glocal[(a, 0)];
    }
    for a in 0..na {
        out.g[nc + a] += glocal[(nl + a, 0)];
    }
}
