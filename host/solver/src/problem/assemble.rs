//! Cost, gradient and Gauss–Newton matrix of the problem, assembled per knot
//! span straight into the arrowhead storage (see the parent module).

use std::ops::Range;

use faer::{Accum, Mat, MatRef, Par};

use super::{Problem, ProblemError, Stream};
use crate::gram::lower_gram;
use crate::ArrowMatrix;
use robimu_model::effects::SampleContext;
use robimu_model::spline::MAX_DEGREE;
use robimu_model::{
    Basis, Basis4, F64x4, JointState, MeasurementJacobians, MeasurementModel, Spline,
};

/// Where one IMU sample sits on the trajectory: its basis functions and
/// q(t_i + τ), and storage for its effect terms.
struct SampleEval {
    basis: Basis,
    js: JointState,
    effect: EffectScratch,
}

/// Per-sample storage of the effect terms: the baseline Jacobians the
/// effect columns are built from, and the columns ∂z/∂θ_E (both empty when
/// the problem has no effects).
struct EffectScratch {
    jac: MeasurementJacobians,
    cols: Vec<[f64; 6]>,
}

/// Every IMU's whitened residuals (sample index, r) at one θ
/// ([`Problem::cost_and_residuals`]).
#[derive(Debug, Clone)]
pub struct Residuals {
    /// The θ they are at.
    pub theta: Vec<f64>,
    /// IMU j's residuals, in sample order.
    pub imus: Vec<ImuResiduals>,
}

/// One IMU's whitened residuals: (sample index, r) in sample order.
pub type ImuResiduals = Vec<(usize, [f64; 6])>;

/// Gauss–Newton matrix A = JᵀJ and gradient g = Jᵀr being accumulated.
struct Linearization<'m> {
    a: &'m mut ArrowMatrix,
    g: &'m mut [f64],
}

/// IMU samples stacked per flush of a group buffer.
const GROUP_CAP: usize = 256;

/// One IMU stream evaluated at one θ: what every residual and Jacobian row
/// of its samples needs — the stream, the one-IMU measurement model of its
/// vector, the trajectory q(t) (eq. (20)), its τ and the effects' θ_E.
#[derive(Clone, Copy)]
struct StreamAt<'a> {
    st: &'a Stream<'a>,
    model: &'a MeasurementModel,
    spline: &'a Spline,
    tau: f64,
    theta_e: &'a [f64],
}

impl Problem<'_> {
    /// The cost ½‖r‖² at θ over the selected IMU samples.
    pub fn cost(&self, theta: &[f64]) -> Result<f64, ProblemError> {
        let x = self.x_of(theta);
        let models = self.models(&x)?;
        let spline = self.spline_of(theta);
        // each IMU's samples in two halves, one per thread
        let half = |h: usize| -> Result<f64, ProblemError> {
            let mut c = 0.0;
            for (st, model) in self.streams.iter().zip(&models) {
                let range = self.imu_parts(st)[h].clone();
                c += self.imu_terms(self.stream_at(st, model, &spline, &x, theta), range, None)?;
            }
            Ok(c + self.joint_terms(&spline, self.joint_parts()[h].clone(), None))
        };
        let (c1, c2) = robimu_model::pair::join(|| half(0), || half(1));
        Ok(c1?
            + c2?
            + self.prior_terms(&x, None, 0)
            + self.effect_prior_terms(self.effect_params_of(theta), None, 0))
    }

    /// [`Self::cost`] (the same bits) and every IMU's whitened residuals at
    /// θ, from one pass over the samples: the solver's last cost
    /// ([`crate::LeastSquares::end_cost`]) and the fit's residuals.
    pub fn cost_and_residuals(&self, theta: &[f64]) -> Result<(f64, Residuals), ProblemError> {
        let x = self.x_of(theta);
        let spline = self.spline_of(theta);
        // the IMU residuals on both cores, then the joint residuals' two halves
        let residuals = (0..self.streams.len())
            .map(|j| self.imu_residuals_of(theta, j))
            .collect::<Result<Vec<_>, _>>()?;
        let [p0, p1] = self.joint_parts();
        let joint = robimu_model::pair::join(
            || self.joint_terms(&spline, p0, None),
            || self.joint_terms(&spline, p1, None),
        );
        let joint = [joint.0, joint.1];
        // summed as `cost` sums: per half, stream after stream, sample by
        // sample, then the half's joint samples
        let half = |h: usize| {
            let mut c = 0.0;
            for (st, r) in self.streams.iter().zip(&residuals) {
                let [first, _] = self.imu_parts(st);
                let part = if h == 0 {
                    &r[..first.len()]
                } else {
                    &r[first.len()..]
                };
                let mut cs = 0.0;
                for (_, w) in part {
                    cs += 0.5 * w.iter().map(|v| v * v).sum::<f64>();
                }
                c += cs;
            }
            c + joint[h]
        };
        let cost = half(0)
            + half(1)
            + self.prior_terms(&x, None, 0)
            + self.effect_prior_terms(self.effect_params_of(theta), None, 0);
        Ok((
            cost,
            Residuals {
                theta: theta.to_vec(),
                imus: residuals,
            },
        ))
    }

    /// Storage for [`Self::linearize`].
    pub fn new_matrix(&self) -> ArrowMatrix {
        ArrowMatrix::zeros(
            self.n_coeffs(),
            self.bandwidth(),
            self.active.len() + self.n_effect_params(),
        )
    }

    /// Linearise at θ: fill the Gauss–Newton matrix `a` and the gradient `g`
    /// (length nc + n_active), return the cost. The IMU terms are split over
    /// two threads.
    ///
    /// # Panics
    /// If `a` or `g` do not have the problem's dimensions.
    pub fn linearize(
        &self,
        theta: &[f64],
        a: &mut ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, ProblemError> {
        assert_eq!(a.dims(), self.new_matrix().dims());
        let x = self.x_of(theta);
        let models = self.models(&x)?;
        let spline = self.spline_of(theta);
        a.clear();
        g.fill(0.0);
        let mut a2 = self.new_matrix();
        let mut g2 = vec![0.0; g.len()];
        let mut out = Linearization { a, g };
        let mut other = Linearization {
            a: &mut a2,
            g: &mut g2,
        };
        // each IMU's samples in two halves, one per thread, each IMU's rows
        // scattered to its own columns
        let half = |h: usize, lin: &mut Linearization<'_>| -> Result<f64, ProblemError> {
            let mut c = 0.0;
            for (st, model) in self.streams.iter().zip(&models) {
                let range = self.imu_parts(st)[h].clone();
                let ev = self.stream_at(st, model, &spline, &x, theta);
                c += self.imu_terms(ev, range, Some(&mut *lin))?;
            }
            let joints = self.joint_parts()[h].clone();
            Ok(c + self.joint_terms(&spline, joints, Some(&mut *lin.g)))
        };
        let (r1, r2) = robimu_model::pair::join(|| half(0, &mut out), || half(1, &mut other));
        let mut cost = r1? + r2?;
        out.a.add_assign(&a2);
        for (u, v) in out.g.iter_mut().zip(&g2) {
            *u += v;
        }
        out.a.add_band(&self.joint_normal);
        let nc = self.n_coeffs();
        cost += self.prior_terms(&x, Some(&mut out), nc);
        cost += self.effect_prior_terms(self.effect_params_of(theta), Some(&mut out), nc);
        Ok(cost)
    }

    /// The gradient Jᵀr at θ of the rows of each time window
    /// `[edges[w], edges[w+1])`, passed to `emit(w, g)` in order (g of
    /// length nc + n_active + n_E, the priors left out): the IMU samples
    /// whose time t_i lies in the window (GLS rows whitened with the
    /// samples before them, as in [`Self::linearize`]) and the joint
    /// samples in it. Summed over windows covering every sample, the
    /// gradient of [`Self::linearize`] less the priors'. The score
    /// contributions of a sandwich covariance (docs/model.md §4.6).
    ///
    /// # Panics
    /// If `edges` is not increasing.
    pub fn window_gradients(
        &self,
        theta: &[f64],
        edges: &[f64],
        mut emit: impl FnMut(usize, &[f64]),
    ) -> Result<(), ProblemError> {
        assert!(
            edges.windows(2).all(|e| e[0] < e[1]),
            "edges not increasing"
        );
        let x = self.x_of(theta);
        let models = self.models(&x)?;
        let spline = self.spline_of(theta);
        // A is accumulated but never read: only g is wanted
        let mut a = self.new_matrix();
        let mut g = vec![0.0; a.dims().0 + self.active.len() + self.n_effect_params()];
        // the samples of [lo, hi) within `range` of times `t` (sorted)
        let within = |t: &[f64], range: Range<usize>, lo: f64, hi: f64| {
            let s = &t[range.clone()];
            let a = s.partition_point(|&v| v < lo);
            let b = s.partition_point(|&v| v < hi);
            range.start + a..range.start + b
        };
        for (w, e) in edges.windows(2).enumerate() {
            g.fill(0.0);
            let mut lin = Linearization {
                a: &mut a,
                g: &mut g,
            };
            for (st, model) in self.streams.iter().zip(&models) {
                let range = within(st.t, st.imu_range.clone(), e[0], e[1]);
                if !range.is_empty() {
                    let ev = self.stream_at(st, model, &spline, &x, theta);
                    self.imu_terms(ev, range, Some(&mut lin))?;
                }
            }
            let joints = within(&self.data.joint_t, 0..self.data.joint_t.len(), e[0], e[1]);
            self.joint_terms(&spline, joints, Some(&mut g));
            emit(w, &g);
        }
        Ok(())
    }

    /// One-IMU models of every stream at the full x.
    fn models(&self, x: &[f64]) -> Result<Vec<MeasurementModel>, ProblemError> {
        (0..self.streams.len())
            .map(|j| self.model_of(j, x))
            .collect()
    }

    /// τ of stream `st` in the full x.
    fn tau_of(&self, st: &Stream<'_>, x: &[f64]) -> f64 {
        x[st.map[self.imu_layout.offsets().tau]]
    }

    /// Stream `st` evaluated at θ (x = x(θ), `model` its one-IMU model).
    fn stream_at<'a>(
        &'a self,
        st: &'a Stream<'a>,
        model: &'a MeasurementModel,
        spline: &'a Spline,
        x: &[f64],
        theta: &'a [f64],
    ) -> StreamAt<'a> {
        StreamAt {
            st,
            model,
            spline,
            tau: self.tau_of(st, x),
            theta_e: self.effect_params_of(theta),
        }
    }

    /// Whitened IMU residuals r = (z − h)/σ_z at θ for every selected sample
    /// of IMU 0, with the index of the sample.
    pub fn imu_residuals(&self, theta: &[f64]) -> Result<Vec<(usize, [f64; 6])>, ProblemError> {
        self.imu_residuals_of(theta, 0)
    }

    /// [`Self::imu_residuals`] of IMU `j`.
    pub fn imu_residuals_of(
        &self,
        theta: &[f64],
        j: usize,
    ) -> Result<Vec<(usize, [f64; 6])>, ProblemError> {
        debug_assert_eq!(self.thin, 1, "residuals of a thinned iteration");
        let st = &self.streams[j];
        let x = self.x_of(theta);
        let model = self.model_of(j, &x)?;
        let spline = self.spline_of(theta);
        let ev = self.stream_at(st, &model, &spline, &x, theta);
        // the two halves of the samples on two threads, each filling its
        // part of the output (one residual per sample, in order)
        let part =
            |range: Range<usize>, out: &mut [(usize, [f64; 6])]| -> Result<(), ProblemError> {
                let mut slots = out.iter_mut();
                let put = |i: usize, w: [f64; 6]| {
                    if let Some(slot) = slots.next() {
                        *slot = (i, w);
                    }
                };
                self.residuals(ev, range, put)
            };
        let [first, second] = self.imu_parts(st);
        let mut out = vec![(0, [0.0; 6]); st.imu_range.len()];
        let (lo, hi) = out.split_at_mut(first.len());
        let (a, b) = robimu_model::pair::join(|| part(first, lo), || part(second, hi));
        a?;
        b?;
        Ok(out)
    }

    /// Storage for one sample of stream `st` (the effect part empty without effects).
    fn sample_eval(&self, st: &Stream<'_>) -> SampleEval {
        let nx = if self.effects.is_empty() {
            0
        } else {
            self.imu_layout.len()
        };
        SampleEval {
            basis: Basis::default(),
            js: JointState::default(),
            effect: EffectScratch {
                jac: MeasurementJacobians::new(nx),
                cols: vec![[0.0; 6]; st.effect_map.len()],
            },
        }
    }

    /// Whitened residuals (z_i − h)/σ_z of the samples `range`, passed to
    /// `emit` in order: four at a time ([`Quad`], [`MeasurementModel::predict_x4`])
    /// without effects, else one by one ([`Self::whitened_residual`]). The
    /// values are the same bits either way.
    fn white_residuals(
        &self,
        ev: StreamAt<'_>,
        range: Range<usize>,
        at: &mut SampleEval,
        mut emit: impl FnMut(usize, [f64; 6]),
    ) -> Result<(), ProblemError> {
        if !self.effects.is_empty() {
            for i in range {
                emit(i, self.whitened_residual(ev, i, at)?);
            }
            return Ok(());
        }
        let StreamAt {
            st,
            model,
            spline,
            tau,
            ..
        } = ev;
        let mut quads = Quads::new(range, self.thin);
        let mut quad = Quad::default();
        while quads.next(self, st, spline, tau, &mut quad)? {
            let z = model.predict_x4(&quad.js);
            for (l, &i) in quad.idx[..quad.len].iter().enumerate() {
                let zm = &st.z[i];
                emit(
                    i,
                    std::array::from_fn(|c| (zm[c] - z[c].lane(l)) * st.inv_sigma_z[c]),
                );
            }
        }
        Ok(())
    }

    /// Whitened residual (z_i − h)/σ_z of IMU sample i; leaves the sample's
    /// basis and joint state in `at`. Without effects z is the baseline
    /// prediction alone; with them, the effect columns need the baseline
    /// Jacobians (computed into `at.effect`).
    fn whitened_residual(
        &self,
        ev: StreamAt<'_>,
        i: usize,
        at: &mut SampleEval,
    ) -> Result<[f64; 6], ProblemError> {
        let r = self.raw_residual(ev, i, at)?;
        Ok(std::array::from_fn(|c| r[c] * ev.st.inv_sigma_z[c]))
    }

    /// Raw residual z_i − h of IMU sample i (see [`Self::whitened_residual`]).
    fn raw_residual(
        &self,
        ev: StreamAt<'_>,
        i: usize,
        at: &mut SampleEval,
    ) -> Result<[f64; 6], ProblemError> {
        let (st, model) = (ev.st, ev.model);
        self.locate(st, ev.spline, ev.tau, i, at)?;
        let z = if self.effects.is_empty() {
            model.predict(&at.js)
        } else {
            let e = &mut at.effect;
            model.jacobians(&at.js, &mut e.jac);
            self.with_effect_terms(st, model, i, &at.js, &e.jac, ev.theta_e, &mut e.cols)
        };
        let zm = &st.z[i];
        Ok(std::array::from_fn(|c| zm[c] - z[c]))
    }

    /// z of sample i with the effect terms: the baseline `jac.z` (already
    /// evaluated) plus Σ ∂z/∂θ_E θ_E over the stream's effect columns
    /// (`st.effect_map`); leaves the columns in `cols`. With no effects this
    /// is `jac.z` (no column is built).
    #[allow(clippy::too_many_arguments)]
    fn with_effect_terms(
        &self,
        st: &Stream<'_>,
        model: &MeasurementModel,
        i: usize,
        js: &JointState,
        jac: &MeasurementJacobians,
        theta_e: &[f64],
        cols: &mut [[f64; 6]],
    ) -> [f64; 6] {
        let mut z = jac.z;
        let ctx = SampleContext::new(st.t[i], js, model, jac, self.imu_layout);
        self.effects.columns_for(st.index, &ctx, cols);
        for (col, &e) in cols.iter().zip(&st.effect_map) {
            let th = theta_e[e];
            for c in 0..6 {
                z[c] += col[c] * th;
            }
        }
        z
    }

    /// Zero-mean prior residuals θ_E/σ of the effect parameters (θ_E at `x0 + n_active`).
    fn effect_prior_terms(
        &self,
        theta_e: &[f64],
        mut out: Option<&mut Linearization<'_>>,
        x0: usize,
    ) -> f64 {
        let na = self.active.len();
        let mut cost = 0.0;
        for (e, (p, th)) in self.effects.params().iter().zip(theta_e).enumerate() {
            let w = 1.0 / p.prior_sigma;
            let r = th * w;
            cost += 0.5 * r * r;
            if let Some(out) = out.as_deref_mut() {
                out.g[x0 + na + e] += w * r;
                out.a.add_xx(na + e, na + e, w * w);
            }
        }
        cost
    }

    /// Basis functions and joint state q(t_i + τ) of IMU sample i.
    fn locate(
        &self,
        st: &Stream<'_>,
        spline: &Spline,
        tau: f64,
        i: usize,
        at: &mut SampleEval,
    ) -> Result<(), ProblemError> {
        let u = st.t[i] + tau;
        self.spans
            .basis(u, &mut at.basis)
            .map_err(|_| ProblemError::SampleOutOfSpan)?;
        spline.evaluate_basis(&at.basis, &mut at.js);
        Ok(())
    }

    /// The joint samples split in two halves (one per thread, beside the
    /// IMU halves of [`Self::imu_parts`]).
    fn joint_parts(&self) -> [Range<usize>; 2] {
        let m = self.joint_basis.len();
        [0..m / 2, m / 2..m]
    }

    /// The selected IMU range split in two halves (one per thread; a knot span
    /// cut in two is simply flushed twice, the sums are the same).
    fn imu_parts(&self, st: &Stream<'_>) -> [Range<usize>; 2] {
        let r = st.imu_range.clone();
        let mid = r.start + r.len() / 2;
        [r.start..mid, mid..r.end]
    }

    /// Joint residuals: cost, and (with `g`) their gradient terms (their
    /// Gauss–Newton block is the constant [`Self::joint_normal_matrix`]).
    fn joint_terms(
        &self,
        spline: &Spline,
        samples: Range<usize>,
        mut g: Option<&mut [f64]>,
    ) -> f64 {
        let n = self.n;
        let count = self.knots.degree() + 1;
        let c = spline.coeffs();
        let mut cost = 0.0;
        for (s, b) in self
            .joint_basis
            .iter()
            .enumerate()
            .take(samples.end)
            .skip(samples.start)
        {
            let qm = &self.data.joint_q[s * n..(s + 1) * n];
            // q_j = Σ_a N_a c_{first+a, j}, summed in a's order for every
            // joint at once (the coefficients of one a are contiguous)
            let mut q = [0.0; robimu_model::MAX_JOINTS];
            for a in 0..count {
                let ca = &c[(b.first + a) * n..(b.first + a + 1) * n];
                for (qj, cj) in q.iter_mut().zip(ca) {
                    *qj += b.n[a] * cj;
                }
            }
            let mut r = [0.0; robimu_model::MAX_JOINTS];
            for j in 0..n {
                r[j] = (qm[j] - q[j]) * self.inv_sigma_q[j];
                cost += 0.5 * r[j] * r[j];
            }
            if let Some(g) = g.as_deref_mut() {
                for a in 0..count {
                    let ga = &mut g[(b.first + a) * n..(b.first + a + 1) * n];
                    for ((gj, w), rj) in ga.iter_mut().zip(&self.inv_sigma_q).zip(&r) {
                        *gj += -b.n[a] * w * rj;
                    }
                }
            }
        }
        cost
    }

    /// JᵀJ of the joint residuals r = (q_j − Σ_a N_a c_{a,j})/σ_q: a band of
    /// half-bandwidth (p+1)·n − 1, no border.
    pub(super) fn joint_normal_matrix(&self) -> ArrowMatrix {
        let n = self.n;
        let count = self.knots.degree() + 1;
        let mut out = ArrowMatrix::zeros(self.n_coeffs(), count * n - 1, 0);
        // Σ N_a N_b over the samples of one span (the same `first`), then
        // into each joint's band with its weight 1/σ_q²
        let mut sums = [[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1];
        let mut flush = |first: usize, sums: &mut [[f64; MAX_DEGREE + 1]; MAX_DEGREE + 1]| {
            for j in 0..n {
                let w2 = self.inv_sigma_q[j] * self.inv_sigma_q[j];
                for a in 0..count {
                    for bb in 0..=a {
                        out.add_cc((first + a) * n + j, (first + bb) * n + j, w2 * sums[a][bb]);
                    }
                }
            }
            *sums = [[0.0; MAX_DEGREE + 1]; MAX_DEGREE + 1];
        };
        let mut first = None;
        for b in &self.joint_basis {
            if let Some(f) = first.filter(|&f| f != b.first) {
                flush(f, &mut sums);
            }
            first = Some(b.first);
            for a in 0..count {
                for bb in 0..=a {
                    sums[a][bb] += b.n[a] * b.n[bb];
                }
            }
        }
        if let Some(f) = first {
            flush(f, &mut sums);
        }
        out
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
    /// Gauss–Newton blocks, flushed per knot span. Accelerometer and gyroscope
    /// rows are stacked separately, each with only the x columns it depends
    /// on ([`Problem::sensor_columns`]).
    fn imu_terms(
        &self,
        ev: StreamAt<'_>,
        range: Range<usize>,
        out: Option<&mut Linearization<'_>>,
    ) -> Result<f64, ProblemError> {
        let Some(out) = out else {
            let mut cost = 0.0;
            self.residuals(ev, range, |_, r| {
                cost += 0.5 * r.iter().map(|v| v * v).sum::<f64>();
            })?;
            return Ok(cost);
        };
        if self.white {
            robimu_model::lanes::on_avx2(|| self.white_terms(ev, range, out))
        } else {
            robimu_model::lanes::on_avx2(|| self.gls_terms(ev, range, out))
        }
    }

    /// Whitened residuals of the samples `range`, passed to `emit` in order:
    /// r = (z − h)/σ_z for white noise ([`Self::white_residuals`]), else
    /// whitened along time ([`Self::gls_residuals`]).
    fn residuals(
        &self,
        ev: StreamAt<'_>,
        range: Range<usize>,
        emit: impl FnMut(usize, [f64; 6]),
    ) -> Result<(), ProblemError> {
        if !self.white {
            return self.gls_residuals(ev, range, emit);
        }
        let mut at = self.sample_eval(ev.st);
        self.white_residuals(ev, range, &mut at, emit)
    }

    /// The white Gauss–Newton terms of the samples `range` (see
    /// [`Self::imu_terms`]), four samples at a time; run as compiled for
    /// AVX2 where the CPU has it ([`robimu_model::lanes::on_avx2`]: the
    /// four-lane row writes then use its vector instructions; the results
    /// are the same bits).
    #[inline(always)]
    fn white_terms(
        &self,
        ev: StreamAt<'_>,
        range: Range<usize>,
        out: &mut Linearization<'_>,
    ) -> Result<f64, ProblemError> {
        let StreamAt {
            st,
            model,
            spline,
            tau,
            theta_e,
        } = ev;
        let nx = self.imu_layout.len();
        let n = self.n;
        let nl = (self.knots.degree() + 1) * n;
        let mut cost = 0.0;
        let mut jac = MeasurementJacobians::<F64x4>::zeros(nx);
        let mut blocks = [0, 1].map(|s| self.stack(st, s, 0));
        let mut group_first = usize::MAX;
        let mut quads = Quads::new(range, self.thin);
        let mut quad = Quad::default();
        let mut lanes = LaneEffects::new(self, st);
        while quads.next(self, st, spline, tau, &mut quad)? {
            let basis = &quad.basis;
            if (basis.first != group_first && blocks[0].rows > 0) || blocks[0].full() {
                for b in &mut blocks {
                    b.flush(out);
                }
            }
            if basis.first != group_first {
                for b in &mut blocks {
                    b.start_group(basis.first, 0, n);
                }
            }
            group_first = basis.first;
            model.jacobians_x4(&quad.js, &mut jac);
            let z = lanes.predictions(self, st, model, &quad, &jac, theta_e);
            // residuals, and the cost summed sample by sample as the scalar
            // assembly does
            let mut res = [[0.0; 6]; 4];
            for (l, &i) in quad.idx[..quad.len].iter().enumerate() {
                let zm = &st.z[i];
                for ch in 0..6 {
                    let r = (zm[ch] - z[l][ch]) * st.inv_sigma_z[ch];
                    cost += 0.5 * r * r;
                    res[l][ch] = r;
                }
            }
            for (sensor, block) in blocks.iter_mut().enumerate() {
                for c in 0..3 {
                    let ch = 3 * sensor + c;
                    let row = block.row(c);
                    // −w per lane, 0 on the lanes that repeat a sample
                    let w = F64x4(std::array::from_fn(|l| {
                        if l < quad.len {
                            -st.inv_sigma_z[ch]
                        } else {
                            -0.0
                        }
                    }));
                    block.r[row..row + 4].copy_from_slice(&res.map(|r| r[ch]));
                    let ld = block.ld();
                    let (j, columns) = (&mut block.j[row..], &block.columns);
                    let mut put = |col: usize, v: F64x4| {
                        j[col * ld..col * ld + 4].copy_from_slice(&v.0);
                    };
                    // ∂r/∂c_{first+a, j} = −(∂h/∂q_j N_a + ∂h/∂q̇_j N'_a + ∂h/∂q̈_j N''_a)/σ
                    // (the gyroscope's ∂h/∂q̈ is zero: its term is left out)
                    for a in 0..basis.count {
                        for jn in 0..n {
                            let d = if sensor == 0 {
                                dz_dc(&jac, basis, a, jn, ch)
                            } else {
                                jac.dz_dq[jn][ch] * basis.d[0][a]
                                    + jac.dz_dqd[jn][ch] * basis.d[1][a]
                            };
                            put(a * n + jn, w * d);
                        }
                    }
                    for (a, &(k, _)) in columns.iter().enumerate() {
                        put(nl + a, w * lanes.dz_dx(&jac, k, ch));
                    }
                }
                block.rows += 4;
            }
        }
        for b in &mut blocks {
            b.flush(out);
        }
        Ok(cost)
    }
}

/// Up to four consecutive samples of one knot span, evaluated together in
/// the lanes of [`F64x4`] ([`robimu_model::lanes`]). Lanes from `len` on
/// repeat the last sample; their rows are weighted by 0.
#[derive(Default)]
struct Quad {
    idx: [usize; 4],
    len: usize,
    basis: Basis4,
    js: JointState<F64x4>,
}

/// Cuts a range of samples into [`Quad`]s that never straddle a knot span.
struct Quads {
    next: usize,
    end: usize,
    /// Every `step`-th sample (the problem's thinning).
    step: usize,
    /// The knot span of the last sample (the first one tried for the next).
    mu: usize,
}

impl Quads {
    fn new(range: Range<usize>, step: usize) -> Self {
        Self {
            next: range.start,
            end: range.end,
            step,
            mu: 0,
        }
    }

    /// The next quad into `q` (its basis and joint state set); false at the end.
    fn next(
        &mut self,
        p: &Problem<'_>,
        st: &Stream<'_>,
        spline: &Spline,
        tau: f64,
        q: &mut Quad,
    ) -> Result<bool, ProblemError> {
        q.len = 0;
        let mut u = F64x4::splat(0.0);
        let mut mu = self.mu;
        while self.next < self.end && q.len < 4 {
            let i = self.next;
            let ui = st.t[i] + tau;
            let m = p
                .spans
                .span_near(ui, self.mu)
                .map_err(|_| ProblemError::SampleOutOfSpan)?;
            self.mu = m;
            if q.len > 0 && m != mu {
                break;
            }
            mu = m;
            u.0[q.len] = ui;
            q.idx[q.len] = i;
            q.len += 1;
            self.next += self.step;
        }
        if q.len == 0 {
            return Ok(false);
        }
        for l in q.len..4 {
            u.0[l] = u.0[q.len - 1];
            q.idx[l] = q.idx[q.len - 1];
        }
        p.spans.basis_x4(mu, u, &mut q.basis);
        spline.evaluate_basis_x4(&q.basis, &mut q.js);
        Ok(true)
    }
}

/// The predictions of a quad's lanes, with the effect terms when the
/// problem has effects (they are evaluated per sample from the lane's
/// scalar Jacobians, [`Problem::with_effect_terms`]).
struct LaneEffects {
    /// Scalar Jacobians of one lane (empty without effects).
    one: MeasurementJacobians,
    /// ∂z/∂θ_E of each lane.
    cols: [Vec<[f64; 6]>; 4],
}

impl LaneEffects {
    fn new(p: &Problem<'_>, st: &Stream<'_>) -> Self {
        let nx = if p.effects.is_empty() {
            0
        } else {
            p.imu_layout.len()
        };
        Self {
            one: MeasurementJacobians::new(nx),
            cols: std::array::from_fn(|_| vec![[0.0; 6]; st.effect_map.len()]),
        }
    }

    /// z of each lane (baseline + effect terms; effect columns kept).
    fn predictions(
        &mut self,
        p: &Problem<'_>,
        st: &Stream<'_>,
        model: &MeasurementModel,
        q: &Quad,
        jac: &MeasurementJacobians<F64x4>,
        theta_e: &[f64],
    ) -> [[f64; 6]; 4] {
        let mut z = [[0.0; 6]; 4];
        for l in 0..q.len {
            if p.effects.is_empty() {
                z[l] = jac.z.map(|v| v.lane(l));
            } else {
                jac.lane_into(l, &mut self.one);
                let js = lane_state(&q.js, l);
                z[l] = p.with_effect_terms(
                    st,
                    model,
                    q.idx[l],
                    &js,
                    &self.one,
                    theta_e,
                    &mut self.cols[l],
                );
            }
        }
        z
    }

    /// ∂z/∂θ column `k` (x columns, then effect columns), channel `ch`,
    /// over the lanes.
    #[inline(always)]
    fn dz_dx(&self, jac: &MeasurementJacobians<F64x4>, k: usize, ch: usize) -> F64x4 {
        match jac.dz_dx.get(k) {
            Some(d) => d[ch],
            None => self.column(k - jac.dz_dx.len(), ch),
        }
    }

    /// Effect column `e`, channel `ch`, over the lanes (0 beyond the quad).
    fn column(&self, e: usize, ch: usize) -> F64x4 {
        F64x4(std::array::from_fn(|l| {
            self.cols[l].get(e).map_or(0.0, |c| c[ch])
        }))
    }
}

/// ∂z/∂c_{first+a, j} of channel `ch` over a quad's lanes: ∂h/∂q_j N_a +
/// ∂h/∂q̇_j N'_a + ∂h/∂q̈_j N''_a (the spline coefficient's column, before
/// the residual's sign and weight).
#[inline(always)]
fn dz_dc(
    jac: &MeasurementJacobians<F64x4>,
    basis: &Basis4,
    a: usize,
    j: usize,
    ch: usize,
) -> F64x4 {
    jac.dz_dq[j][ch] * basis.d[0][a]
        + jac.dz_dqd[j][ch] * basis.d[1][a]
        + jac.dz_dqdd[j][ch] * basis.d[2][a]
}

/// Lane `l` of a four-lane joint state.
fn lane_state(js: &JointState<F64x4>, l: usize) -> JointState {
    let one = |v: &[F64x4; robimu_model::MAX_JOINTS]| v.map(|x| x.lane(l));
    JointState {
        q: one(&js.q),
        qd: one(&js.qd),
        qdd: one(&js.qdd),
        qddd: one(&js.qddd),
    }
}

/// Where a whitened row is made: sample `i` of the knot-span group
/// starting at basis function `group`, the ring of raw rows, each sensor's
/// row width.
#[derive(Clone, Copy)]
struct WhitenAt<'a> {
    i: usize,
    group: usize,
    ring: &'a [RawSample],
    widths: &'a [usize; 2],
}

/// The raw (unwhitened) residual and Jacobian rows of one sample, kept in a
/// ring of the last P+1 samples for the whitening of the next ones.
struct RawSample {
    /// First basis function of the sample's knot span.
    first: usize,
    /// z_i − h_i.
    r: [f64; 6],
    /// 1/s_i per channel.
    inv_level: [f64; 6],
    /// Per sensor, its three channels' rows ∂r/∂θ (nl band entries, then
    /// the sensor's columns), one after the other.
    rows: [Vec<f64>; 2],
}

/// Lane l of `v` into the raw row entry `at` of `sensor` of ring slot
/// `slots[l]`, for each of a quad's samples.
#[inline(always)]
fn put_lanes(ring: &mut [RawSample], slots: &[usize], sensor: usize, at: usize, v: F64x4) {
    for (l, &k) in slots.iter().enumerate() {
        ring[k].rows[sensor][at] = v.lane(l);
    }
}

impl Problem<'_> {
    /// 1/s_i of sample i (1 without motion levels).
    fn inv_level(&self, st: &Stream<'_>, i: usize) -> [f64; 6] {
        st.inv_levels.get(i).copied().unwrap_or([1.0; 6])
    }

    /// The first sample whose raw terms the whitening of `range` needs.
    fn warm_start(&self, st: &Stream<'_>, range: &Range<usize>) -> usize {
        range
            .start
            .saturating_sub(st.noise.max_order())
            .max(st.imu_range.start)
    }

    /// Whitened residual of channel `ch` of sample `i`, from the ring.
    fn whiten(&self, st: &Stream<'_>, ring: &[RawSample], i: usize, ch: usize) -> f64 {
        let pos = st.seg_pos[i - st.imu_range.start] as usize;
        let (a, scale) = st.noise.imu[ch].ar.whitening(pos);
        let len = ring.len();
        let s = &ring[i % len];
        let mut u = s.r[ch] * s.inv_level[ch];
        for (k, ak) in a.iter().enumerate() {
            let p = &ring[(i - k - 1) % len];
            u -= ak * p.r[ch] * p.inv_level[ch];
        }
        scale * u
    }

    /// GLS-whitened residuals of the samples `range` (module doc), passed to
    /// `emit` in order.
    fn gls_residuals(
        &self,
        ev: StreamAt<'_>,
        range: Range<usize>,
        mut emit: impl FnMut(usize, [f64; 6]),
    ) -> Result<(), ProblemError> {
        let st = ev.st;
        let mut at = self.sample_eval(st);
        let mut ring: Vec<RawSample> = (0..=st.noise.max_order())
            .map(|_| RawSample {
                first: 0,
                r: [0.0; 6],
                inv_level: [1.0; 6],
                rows: [Vec::new(), Vec::new()],
            })
            .collect();
        let len = ring.len();
        for i in self.warm_start(st, &range)..range.end {
            let r = self.raw_residual(ev, i, &mut at)?;
            let slot = &mut ring[i % len];
            slot.r = r;
            slot.inv_level = self.inv_level(st, i);
            if i >= range.start {
                emit(i, std::array::from_fn(|ch| self.whiten(st, &ring, i, ch)));
            }
        }
        Ok(())
    }

    /// The GLS Gauss–Newton terms of the samples `range` (see
    /// [`Self::imu_terms`]), for noise that is not white: rows whitened
    /// along time, each combining the raw rows of up to P samples before it,
    /// which may lie in earlier knot spans (module doc); run as compiled for
    /// AVX2 where the CPU has it (the same bits).
    #[inline(always)]
    fn gls_terms(
        &self,
        ev: StreamAt<'_>,
        range: Range<usize>,
        out: &mut Linearization<'_>,
    ) -> Result<f64, ProblemError> {
        let (st, model) = (ev.st, ev.model);
        let mut cost = 0.0;
        let nx = self.imu_layout.len();
        let n = self.n;
        let nl = (self.knots.degree() + 1) * n;
        let extra = self.extra_spans;
        let widths = [0, 1].map(|s| nl + st.sensor_columns[s].len());
        // a quad's four samples and the P before the first of them
        let mut ring: Vec<RawSample> = (0..st.noise.max_order() + 4)
            .map(|_| RawSample {
                first: 0,
                r: [0.0; 6],
                inv_level: [1.0; 6],
                rows: widths.map(|w| vec![0.0; 3 * w]),
            })
            .collect();
        let mut jac = MeasurementJacobians::<F64x4>::zeros(nx);
        let mut lanes = LaneEffects::new(self, st);
        let mut quads = Quads::new(self.warm_start(st, &range)..range.end, 1);
        let mut quad = Quad::default();
        let mut blocks = [0, 1].map(|s| self.stack(st, s, extra * n));
        let mut row_buf = vec![0.0; nl + extra * n + widths[0].max(widths[1])];
        let mut group_first = usize::MAX;
        // the raw terms four samples at a time ([`Quad`], lane-wise
        // arithmetic: the bits of one sample at a time), then each sample's
        // whitened rows in order
        while quads.next(self, st, ev.spline, ev.tau, &mut quad)? {
            model.jacobians_x4(&quad.js, &mut jac);
            let z4 = lanes.predictions(self, st, model, &quad, &jac, ev.theta_e);
            self.raw_rows(st, &quad, &z4, &jac, &lanes, &widths, &mut ring);
            for &i in &quad.idx[..quad.len] {
                if i < range.start {
                    continue;
                }
                let g = quad.basis.first;
                if (g != group_first && blocks[0].rows > 0) || blocks[0].full() {
                    for b in &mut blocks {
                        b.flush(out);
                    }
                }
                if g != group_first {
                    for b in &mut blocks {
                        b.start_group(g, extra, n);
                    }
                    group_first = g;
                }
                let at = WhitenAt {
                    i,
                    group: g,
                    ring: &ring,
                    widths: &widths,
                };
                self.whitened_rows(st, at, &mut blocks, &mut row_buf, &mut cost);
            }
        }
        for b in &mut blocks {
            b.flush(out);
        }
        Ok(cost)
    }

    /// A quad's raw residuals, levels and Jacobian rows ∂r/∂θ into their
    /// ring slots (`ring[i % len]`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn raw_rows(
        &self,
        st: &Stream<'_>,
        quad: &Quad,
        z4: &[[f64; 6]; 4],
        jac: &MeasurementJacobians<F64x4>,
        lanes: &LaneEffects,
        widths: &[usize; 2],
        ring: &mut [RawSample],
    ) {
        let n = self.n;
        let deg = self.knots.degree();
        let nl = (deg + 1) * n;
        let len = ring.len();
        let basis = &quad.basis;
        let idx = &quad.idx[..quad.len];
        for (&i, z) in idx.iter().zip(z4) {
            let zm = &st.z[i];
            let slot = &mut ring[i % len];
            slot.first = basis.first;
            slot.r = std::array::from_fn(|c| zm[c] - z[c]);
            slot.inv_level = self.inv_level(st, i);
        }
        let slots: [usize; 4] = std::array::from_fn(|l| quad.idx[l] % len);
        let slots = &slots[..quad.len];
        for (sensor, &w) in widths.iter().enumerate() {
            for c in 0..3 {
                let ch = 3 * sensor + c;
                let at = c * w;
                // ∂r/∂c_{first+a, j} = −(∂h/∂q_j N_a + ∂h/∂q̇_j N'_a + ∂h/∂q̈_j N''_a)
                let minus = F64x4::splat(-1.0);
                for a in 0..=deg {
                    for j in 0..n {
                        let v = if a < basis.count {
                            minus * dz_dc(jac, basis, a, j, ch)
                        } else {
                            F64x4::splat(0.0)
                        };
                        put_lanes(ring, slots, sensor, at + a * n + j, v);
                    }
                }
                for (a, &(k, _)) in st.sensor_columns[sensor].iter().enumerate() {
                    let v = minus * lanes.dz_dx(jac, k, ch);
                    put_lanes(ring, slots, sensor, at + nl + a, v);
                }
            }
        }
    }

    /// Sample `at.i`'s whitened rows (each the raw rows of it and the P
    /// before it, weighted by the AR whitening at its place in its
    /// segment) into the row stacks `blocks`; ½u² of each added to `cost`
    /// in order.
    #[inline(always)]
    fn whitened_rows(
        &self,
        st: &Stream<'_>,
        at: WhitenAt<'_>,
        blocks: &mut [Stack; 2],
        row_buf: &mut [f64],
        cost: &mut f64,
    ) {
        let WhitenAt {
            i,
            group: g,
            ring,
            widths,
        } = at;
        let n = self.n;
        let nl = (self.knots.degree() + 1) * n;
        let len = ring.len();
        let pos = st.seg_pos[i - st.imu_range.start] as usize;
        for (sensor, block) in blocks.iter_mut().enumerate() {
            let w = widths[sensor];
            for c in 0..3 {
                let ch = 3 * sensor + c;
                let (a, scale) = st.noise.imu[ch].ar.whitening(pos);
                let row = block.row(c);
                let (b0, nl_cur) = (block.b0, block.nl_cur);
                let col = &mut row_buf[..nl_cur + block.columns.len()];
                col.fill(0.0);
                let mut u = 0.0;
                for k in 0..=a.len() {
                    let s = &ring[(i - k) % len];
                    let coef = scale * s.inv_level[ch] * if k == 0 { 1.0 } else { -a[k - 1] };
                    u += coef * s.r[ch];
                    assert!(
                        s.first >= b0 && s.first <= g,
                        "a whitened row reaches beyond the widened band"
                    );
                    let off = (s.first - b0) * n;
                    let raw = &s.rows[sensor][c * w..(c + 1) * w];
                    for (d, v) in col[off..off + nl].iter_mut().zip(&raw[..nl]) {
                        *d += coef * v;
                    }
                    for (d, v) in col[nl_cur..].iter_mut().zip(&raw[nl..]) {
                        *d += coef * v;
                    }
                }
                *cost += 0.5 * u * u;
                block.set_row(row, col);
                block.r[row] = u;
            }
            block.rows += 1;
        }
    }
}

impl Problem<'_> {
    /// The row stack of `sensor` (0: accelerometer, 1: gyroscope) of stream
    /// `st`, `extra` band columns before its own (the GLS widening).
    fn stack(&self, st: &Stream<'_>, sensor: usize, extra: usize) -> Stack {
        let nl = (self.knots.degree() + 1) * self.n;
        let n_own = self.imu_layout.len();
        let channel = |k: usize| {
            (k < n_own)
                .then(|| single_channel(self.imu_layout, sensor, k))
                .flatten()
        };
        Stack::new(nl, extra, &st.sensor_columns[sensor], channel)
    }
}

/// The channel (0–2 within its sensor) of a column of a sensor's rows that
/// is non-zero in one channel only — the misalignments, gains and biases
/// of the sensor's own intrinsics (docs/model.md §3, eq. (6)): ∂z/∂γ_yz
/// is in y, ∂z/∂γ_zy and ∂z/∂γ_zx in z, ∂z/∂k_c and ∂z/∂b_c in c — or
/// `None` for a column that may be non-zero in every channel.
pub(super) fn single_channel(
    layout: &robimu_model::ParamLayout,
    sensor: usize,
    k: usize,
) -> Option<usize> {
    let o = layout.offsets();
    let base = if sensor == 0 { o.gamma_a } else { o.gamma_w };
    match k.checked_sub(base)? {
        0 => Some(1),
        1 | 2 => Some(2),
        e @ 6..=8 => Some(e - 6),
        e @ 9..=11 => Some(e - 9),
        _ => None,
    }
}

/// Rows of one sensor's whitened Jacobian for the samples of knot span g,
/// over the band unknowns of spans b0 = max(g − E, 0) … g + p_s, then the
/// sensor's x columns: first those non-zero in every channel ("dense"),
/// then those of one channel only ([`single_channel`]), channel by channel.
/// Stored column-major, each channel's rows a segment of its own (row
/// `c·seg + i`), so that the four lanes of a quad are one store and channel
/// c's rows are multiplied over the dense columns and the single-channel
/// ones up to its own only ([`Stack::flush`]; JᵀJ flops −21 % for the
/// accelerometer and gyroscope of the reference setup). The white assembly
/// uses it with E = 0 (its rows are its own samples', four per channel and
/// quad), the GLS one with the E of the widened band (one row per channel
/// and sample).
struct Stack {
    nl: usize,
    /// The sensor's x columns (index in the IMU's own vector, position in
    /// θ's x part), dense ones first, then channel 0's, 1's, 2's.
    columns: Vec<(usize, usize)>,
    /// Position in the caller's column order of each of `columns`.
    order: Vec<usize>,
    /// Single-channel x columns of each channel, as positions in `columns`.
    sparse: [Range<usize>; 3],
    /// J, column-major with column stride 3·`seg`.
    j: Vec<f64>,
    /// Row capacity of one channel's segment.
    seg: usize,
    r: Vec<f64>,
    /// Rows of each channel's segment in use.
    rows: usize,
    local: Mat<f64>,
    glocal: Mat<f64>,
    x_index: Vec<usize>,
    /// First span of the group's band unknowns.
    b0: usize,
    /// Band columns of the current group, (g − b0)·n + nl.
    nl_cur: usize,
    /// Its first band unknown, b0·n.
    c0: usize,
}

impl Stack {
    fn new(
        nl: usize,
        extra: usize,
        columns: &[(usize, usize)],
        channel: impl Fn(usize) -> Option<usize>,
    ) -> Self {
        let mut order: Vec<usize> = (0..columns.len()).collect();
        // dense first (key 0), then by channel (1 + c); stable: θ order within
        order.sort_by_key(|&a| channel(columns[a].0).map_or(0, |c| 1 + c));
        let n_dense = order
            .iter()
            .take_while(|&&a| channel(columns[a].0).is_none())
            .count();
        let count = |c: usize| {
            order
                .iter()
                .filter(|&&a| channel(columns[a].0) == Some(c))
                .count()
        };
        let (c0n, c1n, c2n) = (count(0), count(1), count(2));
        let sparse = [
            n_dense..n_dense + c0n,
            n_dense + c0n..n_dense + c0n + c1n,
            n_dense + c0n + c1n..n_dense + c0n + c1n + c2n,
        ];
        let columns: Vec<(usize, usize)> = order.iter().map(|&a| columns[a]).collect();
        // every column is dense or one channel's: channel 2's rows span them
        // all (`flush` overwrites the block with its products)
        assert_eq!(sparse[2].end, columns.len(), "a column of no channel 0–2");
        let cols = nl + extra + columns.len();
        let seg = GROUP_CAP;
        Self {
            nl,
            x_index: columns.iter().map(|&(_, a)| a).collect(),
            columns,
            order,
            sparse,
            j: vec![0.0; cols * 3 * seg],
            seg,
            r: vec![0.0; 3 * seg],
            rows: 0,
            local: Mat::zeros(cols, cols),
            glocal: Mat::zeros(cols, 1),
            b0: 0,
            nl_cur: nl,
            c0: 0,
        }
    }

    /// Whether a quad's four rows per channel no longer fit.
    fn full(&self) -> bool {
        self.rows + 4 > self.seg
    }

    /// The next free row of channel `c`'s segment.
    fn row(&self, c: usize) -> usize {
        c * self.seg + self.rows
    }

    /// The column stride of J.
    #[inline(always)]
    fn ld(&self) -> usize {
        3 * self.seg
    }

    /// Row `row` from its values over the current group's columns, the x
    /// columns in the caller's order.
    fn set_row(&mut self, row: usize, values: &[f64]) {
        let ld = 3 * self.seg;
        let nl = self.nl_cur;
        for (c, &v) in values[..nl].iter().enumerate() {
            self.j[c * ld + row] = v;
        }
        for (p, &a) in self.order.iter().enumerate() {
            self.j[(nl + p) * ld + row] = values[nl + a];
        }
    }

    /// Begin the rows of span `g` (the stack must be empty).
    fn start_group(&mut self, g: usize, extra: usize, n: usize) {
        debug_assert_eq!(self.rows, 0);
        self.b0 = g.saturating_sub(extra);
        self.nl_cur = (g - self.b0) * n + self.nl;
        self.c0 = self.b0 * n;
    }

    /// Add JᵀJ (lower triangle) and Jᵀr of the stacked rows to `out`, and
    /// empty the stack. Channel c's rows are multiplied over the columns up
    /// to its own single-channel ones (the dense columns, then channel 0's,
    /// …, c's: the earlier channels' columns are zero in its rows, and the
    /// later ones' are skipped). Channel 2's rows span every column: its
    /// products are written first (no clearing of the block), the others
    /// added.
    fn flush(&mut self, out: &mut Linearization<'_>) {
        let rows = self.rows;
        if rows == 0 {
            return;
        }
        let (nl, cols) = (self.nl_cur, self.nl_cur + self.columns.len());
        let ld = 3 * self.seg;
        let mut local = self.local.as_mut().submatrix_mut(0, 0, cols, cols);
        let mut glocal = self.glocal.as_mut().submatrix_mut(0, 0, cols, 1);
        // channel 2 first: its block covers every column (Self::new), so it
        // overwrites the block and the others add to it
        for c in [2, 1, 0] {
            let accum = if c == 2 { Accum::Replace } else { Accum::Add };
            // channel c's rows: a column-major block of `rows` rows
            let at = c * self.seg;
            let w = nl + self.sparse[c].end;
            let jc = MatRef::from_column_major_slice_with_stride(
                &self.j[at..at + (w - 1) * ld + rows],
                rows,
                w,
                ld,
            );
            let rc = MatRef::from_column_major_slice(&self.r[at..at + rows], rows, 1);
            lower_gram(local.as_mut().submatrix_mut(0, 0, w, w), accum, jc);
            faer::linalg::matmul::matmul(
                glocal.as_mut().submatrix_mut(0, 0, w, 1),
                accum,
                jc.transpose(),
                rc,
                1.0,
                Par::Seq,
            );
        }
        let c0 = self.c0;
        out.a.add_local(c0, nl, &self.x_index, local.as_ref());
        let nc = out.a.dims().0;
        for a in 0..nl {
            out.g[c0 + a] += glocal[(a, 0)];
        }
        for (b, &xa) in self.x_index.iter().enumerate() {
            out.g[nc + xa] += glocal[(nl + b, 0)];
        }
        self.rows = 0;
    }
}
