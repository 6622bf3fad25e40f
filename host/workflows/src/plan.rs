//! Excitation trajectory planning (paper §7): a cubic B-spline of joint
//! positions whose coefficients are chosen block by block to minimise the
//! largest eigenvalue of the posterior covariance Σ_x (eq. (32)–(33), with
//! the approximation (26), [`information`]).
//!
//! # Constraints (28), exactly
//!
//! A B-spline lies in the convex hull of its control points, and its
//! derivative is a B-spline whose control points are differences of them.
//! With uniform knot spacing h and p + 1 equal coefficients at each end (at
//! rest there, the padding blocks C_0 and C_{N_s+1}), every non-zero control
//! point of q̇ is (c_{i+1} − c_i)/h and of q̈ is (c_{i+2} − 2c_{i+1} + c_i)/h²,
//! so these linear constraints are sufficient:
//!
//! ```text
//! q_min ≤ c_i ≤ q_max,   |c_{i+1} − c_i| ≤ q̇_max·h,   |c_{i+2} − 2c_{i+1} + c_i| ≤ q̈_max·h²
//! ```
//!
//! With h ≥ 2 q̇_max/q̈_max (checked) the third follows from the second, and
//! the map `c_i = clamp(c_{i−1} + u_i·q̇_max·h, q_min, q_max)`, u_i ∈ [−1, 1],
//! reaches every feasible block from every feasible past: the optimiser works
//! on u in a box and never leaves the feasible set. The result is verified
//! densely (1 kHz) before it is returned.
//!
//! # Sequential optimisation (33)
//!
//! Block j owns N_c coefficient columns and the interval Ω_j = [y_{i0}, y_{i0+N_c})
//! (eq. (29)), whose samples depend only on it and on fixed earlier columns.
//! Its objective λ_max((Λ_{j−1} + I_j(C_j))⁻¹) is evaluated with the
//! quadrature of [`information::Sampling`]; the optimiser is random
//! candidates followed by a compass (pattern) search on u with halving steps.
//!
//! # Several IMUs (docs/model.md §9)
//!
//! With [`PlanOptions::imus`] = K the information is that of the K-IMU layout
//! ([`ParamLayout::with_imus`], summed over the IMUs, [`information`]) and the
//! criterion λ_max(Σ_x) spans all 20 + 28K parameters (the shared ones and
//! every IMU's own). Every IMU is linearised at its nominal mount
//! ([`Robot::mount_of`]: the robot's `imu_mount` unless the robot places it
//! elsewhere, [`Robot::with_mount`] — a plate of boards).

pub mod files;
pub mod information;

use faer::Mat;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use self::information::{
    lambda_max, without_robot_lengths, Information, InformationError, Sampling,
};
use robimu_model::noise::NoiseModel;
use robimu_model::{JointState, Knots, ParamLayout, Robot, Spline, SplineError};

/// Spline degree of a plan.
pub(crate) const DEGREE: usize = 3;

/// Planner settings.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanOptions {
    /// Trajectory length, s.
    pub duration: f64,
    /// Knot spacing h, s (≥ 2 q̇_max/q̈_max of every joint).
    pub knot_spacing: f64,
    /// Coefficient columns per block, N_c.
    pub block: usize,
    /// IMU sample rate the information is counted at, Hz.
    pub sample_rate: f64,
    /// Quadrature points per second in the optimiser.
    pub eval_rate: f64,
    /// Random candidates per block before the pattern search.
    pub candidates: usize,
    /// Objective evaluations per block (candidates included).
    pub evaluations: usize,
    /// Fraction of the velocity limit used (the acceleration follows).
    pub margin: f64,
    /// Seed of the optimiser.
    pub seed: u64,
    /// The IMU noise the plan is made for (None: white of the robot's σ_z);
    /// its AR coefficients are per sample at `sample_rate`
    /// ([`information`], docs/model.md §4.6).
    pub noise: Option<NoiseModel>,
    /// Number of IMUs K on the flange (docs/model.md §9), ≥ 1.
    pub imus: usize,
}

impl Default for PlanOptions {
    /// 300 s, h = 0.5 s, N_c = 8, 120 Hz, quadrature 20 per s, 12 candidates,
    /// 240 evaluations per block, 99 % of the velocity limit, seed 1, white
    /// noise, one IMU at the nominal mount.
    fn default() -> Self {
        Self {
            duration: 300.0,
            knot_spacing: 0.5,
            block: 8,
            sample_rate: 120.0,
            eval_rate: 20.0,
            candidates: 12,
            evaluations: 240,
            margin: 0.99,
            seed: 1,
            noise: None,
            imus: 1,
        }
    }
}

/// Why a plan could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// An option is out of range.
    #[error("plan option {field} = {value} is out of range ({expected})")]
    BadOption {
        /// Which option.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// The knots are too close for the acceleration limit of a joint.
    #[error("knot spacing {spacing} s is below 2·qd_max/qdd_max = {min} s of joint {joint}; use a larger spacing")]
    KnotsTooFine {
        /// 1-based joint.
        joint: usize,
        /// The spacing.
        spacing: f64,
        /// The smallest allowed.
        min: f64,
    },
    /// The duration leaves no free coefficient.
    #[error("a {duration} s plan with knots every {spacing} s has no free coefficients (need more than {} knot spans)", 2 * DEGREE + 1)]
    TooShort {
        /// Duration.
        duration: f64,
        /// Knot spacing.
        spacing: f64,
    },
    /// The spline could not be built.
    #[error(transparent)]
    Spline(#[from] SplineError),
    /// The nominal model or the noise model is invalid.
    #[error(transparent)]
    Information(#[from] InformationError),
    /// The dense check found a limit violated (a bug: the constraints are sufficient).
    #[error("the planned trajectory violates a limit: {0}")]
    Violation(String),
}

/// A planned trajectory and its identifiability.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The joint trajectory (clamped cubic B-spline, at rest at both ends).
    pub spline: Spline,
    /// End time of each block's interval (s), the first entry the initial rest.
    pub times: Vec<f64>,
    /// λ_max(Σ_x) in SI after each entry of `times` (all samples counted).
    pub lambda_max: Vec<f64>,
    /// The same with the robot length parameters known.
    pub lambda_max_without_lengths: Vec<f64>,
    /// Final information Λ (prior included), SI, over `layout`.
    pub information: Mat<f64>,
    /// The parameters of Λ (K IMUs, docs/model.md §9).
    pub layout: ParamLayout,
    /// Objective evaluations spent.
    pub evaluations: usize,
}

fn bad(field: &'static str, value: f64, expected: &'static str) -> PlanError {
    PlanError::BadOption {
        field,
        value,
        expected,
    }
}

/// Feasible-set geometry of one plan (see the module doc).
struct Box6 {
    lo: Vec<f64>,
    hi: Vec<f64>,
    step: Vec<f64>,
}

impl Box6 {
    fn new(robot: &Robot, h: f64, margin: f64) -> Result<Self, PlanError> {
        let mut b = Self {
            lo: Vec::new(),
            hi: Vec::new(),
            step: Vec::new(),
        };
        for (j, lim) in robot.limits().iter().enumerate() {
            let v = margin * lim.qd_max;
            if 2.0 * v > lim.qdd_max * h * (1.0 + 1e-12) {
                return Err(PlanError::KnotsTooFine {
                    joint: j + 1,
                    spacing: h,
                    min: 2.0 * v / lim.qdd_max,
                });
            }
            let pad = 1e-6 * (lim.q_max - lim.q_min);
            b.lo.push(lim.q_min + pad);
            b.hi.push(lim.q_max - pad);
            b.step.push(v * h);
        }
        Ok(b)
    }

    /// Writes columns i0..i1 of `c` (n per column) from u ∈ [−1, 1]^{(i1−i0)·n}.
    fn apply(&self, c: &mut [f64], n: usize, i0: usize, i1: usize, u: &[f64]) {
        for i in i0..i1 {
            for j in 0..n {
                let prev = c[(i - 1) * n + j];
                let uk = u[(i - i0) * n + j].clamp(-1.0, 1.0);
                c[i * n + j] = (prev + uk * self.step[j]).clamp(self.lo[j], self.hi[j]);
            }
        }
    }
}

/// The knot spacing for a plan of `duration` s: `wanted`, or the least the
/// robot's limits allow (`2·margin·q̇_max/q̈_max` of its slowest-accelerating
/// joint: the UR arms' 180°/s at 100°/s² need 3.6 s) when that is larger,
/// rounded up so that whole segments fill the duration.
pub fn knot_spacing_for(robot: &Robot, duration: f64, wanted: f64, margin: f64) -> f64 {
    let least = robot
        .limits()
        .iter()
        .map(|l| 2.0 * margin * l.qd_max / l.qdd_max)
        .fold(wanted, f64::max);
    let segments = (duration / least).floor().max(1.0);
    duration / segments
}

/// Plans a trajectory for `robot` (see the module doc). `progress(block,
/// blocks, λ_max)` is called after each block with the quadrature estimate.
pub fn plan(
    robot: &Robot,
    opts: &PlanOptions,
    mut progress: impl FnMut(usize, usize, f64),
) -> Result<Plan, PlanError> {
    validate(opts)?;
    let n = robot.dof();
    let knots = Knots::uniform(0.0, opts.duration, opts.knot_spacing, DEGREE)?;
    let m = knots.num_coeffs();
    let pads = DEGREE + 1;
    if m <= 2 * pads {
        return Err(PlanError::TooShort {
            duration: opts.duration,
            spacing: opts.knot_spacing,
        });
    }
    let y = knots.knots().to_vec();
    let h = y[DEGREE + 1] - y[DEGREE];
    let geo = Box6::new(robot, h, opts.margin)?;
    if opts.imus == 0 {
        return Err(bad("imus", 0.0, "at least 1"));
    }
    let layout = ParamLayout::with_imus(robot, opts.imus);
    let x = layout.nominal();
    let noise = match &opts.noise {
        Some(m) => m.clone(),
        None => NoiseModel::white(robot.sigma_z()).map_err(InformationError::from)?,
    };
    let info_model = Information::at(robot, layout, &x, noise, opts.sample_rate)?;
    let keep_all: Vec<usize> = (0..info_model.dim()).collect();
    // at rest at mid-range, all columns (the padding blocks and the initial guess)
    let mut c = vec![0.0; m * n];
    for i in 0..m {
        for (j, lim) in robot.limits().iter().enumerate() {
            c[i * n + j] = 0.5 * (lim.q_min + lim.q_max);
        }
    }
    let mut spline = Spline::new(knots, n, c)?;
    let free_end = m - pads;
    let blocks: Vec<(usize, usize)> = (pads..free_end)
        .step_by(opts.block)
        .map(|i0| (i0, (i0 + opts.block).min(free_end)))
        .collect();
    let quad = Sampling::Quadrature(opts.eval_rate);
    // Λ_0: the prior and the initial rest [0, y_{p+1})
    let mut lam = info_model.prior();
    info_model.accumulate(&spline, 0.0, y[pads], false, 1.0, quad, &mut lam);
    let mut rng = rand::rngs::StdRng::seed_from_u64(opts.seed);
    let mut evaluations = 0;
    let nb = blocks.len();
    for (bi, &(i0, i1)) in blocks.iter().enumerate() {
        let last = i1 == free_end;
        let mut block = Block {
            info_model: &info_model,
            geo: &geo,
            lam: &lam,
            keep_all: &keep_all,
            n,
            m,
            columns: (i0, i1),
            interval: (y[i0], if last { y[m] } else { y[i1] }),
            last,
            quad,
            evaluations: &mut evaluations,
        };
        let (best, best_u) = block.random_candidates(opts, &mut rng, &mut spline);
        let (best, best_u) = block.compass_search(opts, &mut rng, &mut spline, best, best_u);
        let _ = block.eval(&best_u, &mut spline);
        let (a, b) = block.interval;
        info_model.accumulate(&spline, a, b, last, 1.0, quad, &mut lam);
        progress(bi + 1, nb, best);
    }
    check_limits(robot, &spline, 1000.0).map_err(PlanError::Violation)?;
    Ok(identifiability_over_time(
        &info_model,
        spline,
        (&y, m),
        &blocks,
        evaluations,
    ))
}

/// Checks the options (those checked before anything is computed).
fn validate(opts: &PlanOptions) -> Result<(), PlanError> {
    let pos = |v: f64| v.is_finite() && v > 0.0;
    if !pos(opts.duration) {
        return Err(bad("duration", opts.duration, "finite, > 0"));
    }
    if !pos(opts.knot_spacing) {
        return Err(bad("knot_spacing", opts.knot_spacing, "finite, > 0"));
    }
    if !pos(opts.sample_rate) {
        return Err(bad("sample_rate", opts.sample_rate, "finite, > 0"));
    }
    if !pos(opts.eval_rate) {
        return Err(bad("eval_rate", opts.eval_rate, "finite, > 0"));
    }
    if !(opts.margin > 0.0 && opts.margin <= 1.0) {
        return Err(bad("margin", opts.margin, "in (0, 1]"));
    }
    if opts.block == 0 {
        return Err(bad("block", 0.0, "at least 1"));
    }
    if opts.evaluations == 0 {
        return Err(bad("evaluations", 0.0, "at least 1"));
    }
    Ok(())
}

/// One block of spline columns being chosen: the objective λ_max of the
/// information after its interval, given Λ before it.
struct Block<'a> {
    info_model: &'a Information,
    geo: &'a Box6,
    /// Λ before the block.
    lam: &'a Mat<f64>,
    /// Every parameter (λ_max over all of Λ).
    keep_all: &'a [usize],
    /// Joints, spline columns.
    n: usize,
    m: usize,
    /// The columns i0..i1 the block sets.
    columns: (usize, usize),
    /// The time interval its information covers.
    interval: (f64, f64),
    /// Whether it is the last block (it also sets the columns after it, and
    /// its interval is closed).
    last: bool,
    quad: Sampling,
    /// Objective evaluations spent, over all blocks.
    evaluations: &'a mut usize,
}

impl Block<'_> {
    /// The objective at u ∈ [−1, 1]^{(i1−i0)·n} (written into `spline`).
    fn eval(&mut self, u: &[f64], spline: &mut Spline) -> f64 {
        let (n, m, (i0, i1)) = (self.n, self.m, self.columns);
        let (a, b) = self.interval;
        let c = spline.coeffs_mut();
        self.geo.apply(c, n, i0, i1, u);
        if self.last {
            for i in i1..m {
                for j in 0..n {
                    c[i * n + j] = c[(i1 - 1) * n + j];
                }
            }
        }
        let mut l = self.lam.clone();
        self.info_model
            .accumulate(spline, a, b, self.last, 1.0, self.quad, &mut l);
        *self.evaluations += 1;
        lambda_max(&l, self.keep_all)
    }

    /// Random candidates (mixed bang-bang and interior directions): the
    /// best objective and its u.
    fn random_candidates(
        &mut self,
        opts: &PlanOptions,
        rng: &mut rand::rngs::StdRng,
        spline: &mut Spline,
    ) -> (f64, Vec<f64>) {
        let nu = (self.columns.1 - self.columns.0) * self.n;
        let mut best_u = vec![0.0; nu];
        let mut best = f64::INFINITY;
        for _ in 0..opts.candidates.max(1) {
            let u: Vec<f64> = (0..nu)
                .map(|_| {
                    let r: f64 = rng.random_range(-1.0..=1.0);
                    if rng.random_bool(0.5) {
                        r.signum()
                    } else {
                        r
                    }
                })
                .collect();
            let f = self.eval(&u, spline);
            if f < best {
                best = f;
                best_u = u;
            }
        }
        (best, best_u)
    }

    /// Compass search with halving steps from `best_u`, until the step is
    /// below 0.2 or the evaluations allowed (the candidates counted) are
    /// spent: the best objective and its u.
    fn compass_search(
        &mut self,
        opts: &PlanOptions,
        rng: &mut rand::rngs::StdRng,
        spline: &mut Spline,
        mut best: f64,
        mut best_u: Vec<f64>,
    ) -> (f64, Vec<f64>) {
        let nu = best_u.len();
        let mut used = opts.candidates.max(1);
        let mut step = 1.0;
        let mut order: Vec<usize> = (0..nu).collect();
        'search: while step >= 0.2 {
            let mut improved = false;
            for k in (1..nu).rev() {
                order.swap(k, rng.random_range(0..=k));
            }
            for &k in &order {
                for dir in [1.0, -1.0] {
                    if used >= opts.evaluations {
                        break 'search;
                    }
                    let old = best_u[k];
                    let new = (old + dir * step).clamp(-1.0, 1.0);
                    if new == old {
                        continue;
                    }
                    let mut u = best_u.clone();
                    u[k] = new;
                    used += 1;
                    let f = self.eval(&u, spline);
                    if f < best {
                        best = f;
                        best_u = u;
                        improved = true;
                        break;
                    }
                }
            }
            if !improved {
                step *= 0.5;
            }
        }
        (best, best_u)
    }
}

/// The plan with the identifiability measure against time, every sample
/// counted (with and without the robot lengths), and the final Λ; `y` the
/// knots, `m` the number of columns.
fn identifiability_over_time(
    info_model: &Information,
    spline: Spline,
    (y, m): (&[f64], usize),
    blocks: &[(usize, usize)],
    evaluations: usize,
) -> Plan {
    let pads = DEGREE + 1;
    let free_end = m - pads;
    let keep_all: Vec<usize> = (0..info_model.dim()).collect();
    let keep_no_len = without_robot_lengths(info_model.layout());
    let mut lam = info_model.prior();
    let mut times = vec![y[pads]];
    info_model.accumulate(&spline, 0.0, y[pads], false, 1.0, Sampling::Exact, &mut lam);
    let mut lmax = vec![lambda_max(&lam, &keep_all)];
    let mut lmax_nl = vec![lambda_max(&lam, &keep_no_len)];
    for &(i0, i1) in blocks {
        let last = i1 == free_end;
        let b = if last { y[m] } else { y[i1] };
        info_model.accumulate(&spline, y[i0], b, last, 1.0, Sampling::Exact, &mut lam);
        times.push(b);
        lmax.push(lambda_max(&lam, &keep_all));
        lmax_nl.push(lambda_max(&lam, &keep_no_len));
    }
    Plan {
        spline,
        times,
        lambda_max: lmax,
        lambda_max_without_lengths: lmax_nl,
        information: lam,
        layout: info_model.layout().clone(),
        evaluations,
    }
}

/// Checks q, q̇, q̈ of `spline` against the robot's limits at `per_second`
/// points per second (and at both ends); the first violation as text.
pub fn check_limits(robot: &Robot, spline: &Spline, per_second: f64) -> Result<(), String> {
    let (t0, t1) = (spline.knots().start(), spline.knots().end());
    let steps = ((t1 - t0) * per_second).ceil().max(1.0) as usize;
    let mut js = JointState::default();
    for k in 0..=steps {
        let t = t0 + (t1 - t0) * k as f64 / steps as f64;
        spline.evaluate(t, &mut js).map_err(|e| e.to_string())?;
        for (j, lim) in robot.limits().iter().enumerate() {
            let tol = 1e-9;
            if js.q[j] < lim.q_min - tol || js.q[j] > lim.q_max + tol {
                return Err(format!("q{} = {} rad at t = {t} s", j + 1, js.q[j]));
            }
            if js.qd[j].abs() > lim.qd_max * (1.0 + tol) {
                return Err(format!("q̇{} = {} rad/s at t = {t} s", j + 1, js.qd[j]));
            }
            if js.qdd[j].abs() > lim.qdd_max * (1.0 + tol) {
                return Err(format!("q̈{} = {} rad/s² at t = {t} s", j + 1, js.qdd[j]));
            }
        }
    }
    Ok(())
}

/// The paper's random baseline (§8.2): every coefficient uniform within the
/// position limits (at rest at both ends, p + 1 equal coefficients), then the
/// motion about mid-range shrunk until the densely sampled velocity and
/// acceleration are within the limits.
pub(crate) fn random_uniform<R: Rng>(
    robot: &Robot,
    duration: f64,
    knot_spacing: f64,
    rng: &mut R,
) -> Result<Spline, SplineError> {
    let n = robot.dof();
    let knots = Knots::uniform(0.0, duration, knot_spacing, DEGREE)?;
    let m = knots.num_coeffs();
    let lims = robot.limits();
    let mut c = vec![0.0; m * n];
    for i in 0..m {
        for (j, lim) in lims.iter().enumerate() {
            c[i * n + j] = rng.random_range(lim.q_min..=lim.q_max);
        }
    }
    for j in 0..n {
        for i in 1..=DEGREE {
            c[i * n + j] = c[j];
            c[(m - 1 - i) * n + j] = c[(m - 1) * n + j];
        }
    }
    let mut spline = Spline::new(knots, n, c)?;
    let (vmax, amax) = robimu_model::trajectory::max_rates(&spline, 200.0);
    let c = spline.coeffs_mut();
    for (j, lim) in lims.iter().enumerate() {
        let s = (0.98 * lim.qd_max / vmax[j].max(1e-300))
            .min(0.98 * lim.qdd_max / amax[j].max(1e-300))
            .min(1.0);
        let mid = 0.5 * (lim.q_min + lim.q_max);
        for i in 0..m {
            c[i * n + j] = mid + s * (c[i * n + j] - mid);
        }
    }
    Ok(spline)
}

/// Samples of `spline` at `rate` Hz from its start (its end included):
/// times and positions `q[s·n + j]`.
pub fn sample(spline: &Spline, rate: f64) -> (Vec<f64>, Vec<f64>) {
    let (t0, t1) = (spline.knots().start(), spline.knots().end());
    let n = spline.dim();
    let count = ((t1 - t0) * rate + 1e-9).floor() as usize;
    let mut t: Vec<f64> = (0..=count).map(|k| t0 + k as f64 / rate).collect();
    if t1 - t[count] > 1e-9 {
        t.push(t1);
    }
    let mut q = Vec::with_capacity(t.len() * n);
    let mut js = JointState::default();
    for &ti in &t {
        spline
            .evaluate(ti.min(t1), &mut js)
            .expect("t inside the spline");
        q.extend_from_slice(&js.q[..n]);
    }
    (t, q)
}

/// A spline written out: `PLAN_DIR/spline.toml`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SplineFile {
    /// Degree p.
    pub degree: usize,
    /// The full clamped knot vector, s.
    pub knots: Vec<f64>,
    /// `coefficients[j]`: joint j+1's coefficients, rad.
    pub coefficients: Vec<Vec<f64>>,
}

impl SplineFile {
    /// The file of a spline.
    pub fn of(spline: &Spline) -> Self {
        let n = spline.dim();
        let c = spline.coeffs();
        let m = c.len() / n;
        Self {
            degree: spline.knots().degree(),
            knots: spline.knots().knots().to_vec(),
            coefficients: (0..n)
                .map(|j| (0..m).map(|i| c[i * n + j]).collect())
                .collect(),
        }
    }

    /// The spline it describes.
    pub fn spline(&self) -> Result<Spline, SplineError> {
        let knots = Knots::new(self.degree, self.knots.clone())?;
        let n = self.coefficients.len();
        let m = knots.num_coeffs();
        if let Some(bad) = self.coefficients.iter().find(|r| r.len() != m) {
            return Err(SplineError::LengthMismatch {
                what: "coefficient row",
                expected: m,
                found: bad.len(),
            });
        }
        let mut c = vec![0.0; m * n];
        for (j, row) in self.coefficients.iter().enumerate() {
            for (i, v) in row.iter().enumerate() {
                c[i * n + j] = *v;
            }
        }
        Spline::new(knots, n.max(1), c)
    }
}
