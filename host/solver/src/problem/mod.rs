//! The calibration problem: residuals, priors and their exact Jacobians,
//! assembled straight into the arrowhead normal matrix (paper §6).
//!
//! Unknowns θ = [c, x_a]: the spline coefficients c (basis-major, `c[b·n + j]`,
//! the order of [`robimu_model::Spline`]) and the *estimated* (not frozen)
//! entries x_a of x. Residuals, each whitened by its standard deviation so the
//! MAP cost is J = ½‖r‖² (docs/model.md §4):
//!
//! * joint: r = (q_j − q(t_j)) / σ_q, linear in c;
//! * IMU: r = (z_i − h(x, q(u), q̇(u), q̈(u))) / σ_z at u = t_i + τ (eq. (10));
//! * prior: r = (x_k − x̂_k) / σ_k for each estimated parameter (eq. (16)).
//!
//! IMU samples are grouped by knot span; each group's stacked Jacobian J_g
//! gives the dense block J_gᵀ J_g over its p+1 basis functions and x_a, added
//! to the band, border and corner (never a global J).
//!
//! **Noise that is not white** (docs/model.md §4.6, [`robimu_model::noise`]).
//! With a [`NoiseModel`] in [`ProblemOptions::noise`] the IMU rows are the
//! generalised-least-squares ones: per channel, the raw residuals
//! r_i = z_i − h_i divided by their level s_i are prewhitened by the
//! channel's AR filter along the selected samples in time order,
//!
//! ```text
//! w_t = scale_t·(u_t − Σ_{k=1..m} a_k u_{t−k}),  u_i = r_i / s_i,
//! (a, scale_t) = ArNoise::whitening(t),  t = position in the segment,
//! ```
//!
//! so that ½‖w‖² = ½ rᵀΣ⁻¹r with Σ the block-Toeplitz covariance (exact,
//! no approximation at segment starts). Segments start at the first
//! selected sample and after every gap (a time step > 1.5× the median step
//! of the session's IMU stream); different segments are independent. The
//! levels s_i = sqrt(1 + c‖q̈(t_i+τ)‖²/σ²) are computed from the trajectory
//! the solve starts from, in its first [`crate::LeastSquares::begin_iteration`],
//! and **held fixed** for the whole solve (later iterations only set them
//! for samples a moved τ selects anew, from the same trajectory): they are
//! not differentiated, and they do not follow the iterates. Levels
//! recomputed from every iterate (reweighting at each iteration) can
//! oscillate: where the IMU rows weigh less the trajectory follows the joint
//! samples, its q̈ changes, and so do the levels — on a 62 s recording of the
//! demo's realistic twin (knots every 62.5 ms) the fit alternated between
//! two points for its 100 iterations. The noise choice's refits
//! (`robimu_workflows`) start each solve from the previous fit, so the
//! levels follow the trajectory from one refit to the next. Until the first
//! `begin_iteration` every level is 1.
//!
//! **Rows spanning knot intervals.** A whitened row of sample t combines the
//! raw Jacobian rows of samples t−m … t, whose basis functions may begin in
//! earlier knot spans: the row's band part covers the union of their
//! basis functions, from span `first(t) − E` to `first(t) + p_s` (p_s the
//! spline degree). The extra number of spans E is bounded a priori by
//! E = ⌊P·Δt_max / h_min⌋ + 1 (P the largest AR order, Δt_max = 1.5× the median
//! step the largest step inside a segment, h_min the shortest knot
//! interval), and the arrowhead band is widened to
//! w = (p_s + 1 + E)·n − 1 ([`Problem::bandwidth`]). The assembly keeps the
//! per-span grouping of the white case: a group holds the rows of the samples
//! whose own span is g, stacked over the band unknowns of spans g−E … g+p_s
//! (clipped at 0), and is flushed as one dense block. Each sample's raw
//! residual and Jacobian are computed once and kept in a ring of the last
//! P+1 samples, from which the whitened rows are combined; the two assembly
//! threads each recompute the P samples before their half. The effect
//! columns ([`EffectSet`]) are part of those rows and so are whitened alike.
//! With a white model (every channel white, no motion level) E = 0 and the
//! white assembly writes each sample's rows straight into the same per-span
//! stack (no ring: a row is its own sample's, scaled by 1/σ); the GLS loop
//! with P = 0 gives the same matrix (`gls_tests`) but copies every row once
//! more, which cost the white fit 4–9 % more CPU in `--bench calibrate`.
//!
//! **Several IMUs** (docs/model.md §9). With a [`ParamLayout::with_imus`]
//! layout of K IMUs the problem holds K streams: IMU j's samples, its own
//! sample selection from its own τ, its levels, and the map of its own
//! one-IMU vector into x ([`ParamLayout::imu_map`]). Each sample is
//! evaluated by the one-IMU [`MeasurementModel`] at its IMU's vector and its
//! rows carry only that IMU's ≤ 48 columns, scattered into the border through
//! the map: the data pass costs the same per sample for any K, the band and
//! the shared columns are common. K = 1 is the one-IMU problem (identity map).
//! Effects likewise: each stream carries the map of its effect columns into
//! θ_E ([`EffectSet::imu_map`]): a per-sensor effect of IMU j
//! ([`EffectSet::push_on`]) enters only IMU j's rows, a shared one every
//! IMU's rows with one parameter block (docs/model.md §9).
//! Each IMU has its own noise model ([`ProblemOptions::noise`]: its own
//! Σ_z of eq. (22), white or AR): its rows, levels and segments are
//! whitened by it alone. When any IMU's model is not white every IMU's rows
//! go through the GLS assembly (a white IMU's whitening is 1/σ alone, the
//! white rows' values) and E is that of the largest order over the IMUs.
//!
//! **The first iteration** ([`Problem::thin_first_iteration`]). From a
//! start far from the optimum (nominal x, the spline of the joint samples
//! alone) the first Gauss–Newton step is mostly the deterministic distance
//! to the optimum, which every k-th IMU sample determines as well as all
//! of them. So the solver's first iteration may use every k-th selected
//! sample with its rows weighted by √k (the cost then estimates the full
//! cost; its information is the full one's to sampling noise), and every
//! later iteration all of them ([`crate::LeastSquares::keeps_setup`] is
//! false while thinned, so the next iteration linearises anew). The first
//! step lands within the sampling noise of the thinned optimum, O(√k σ)
//! from the full one, well inside the region where the full iterations
//! converge quadratically: on the reference sessions the iteration count is
//! unchanged and the estimate the same to 6·10⁻⁷ σ (the cost's rounding
//! floor), for a first linearisation k times cheaper. The iteration log's
//! first line is the thinned cost. Only for white noise without effects
//! (refits start near the optimum anyway).
//!
//! Only the IMU samples whose u lies inside the joint-sample span (with a
//! small margin, [`Problem::margin`]) are used; the set is chosen by
//! [`Problem::select_samples`] from the current τ at the start of each
//! iteration and kept fixed while a step is tried, so that costs compare
//! like with like (docs/model.md §4: the set is updated as τ moves).

mod assemble;
pub use assemble::{ImuResiduals, Residuals};
#[cfg(test)]
mod gls_tests;
#[cfg(test)]
mod multi_effects_tests;
#[cfg(test)]
mod multi_tests;
#[cfg(test)]
mod select_tests;
#[cfg(test)]
mod thin_tests;
#[cfg(test)]
mod window_tests;

use std::ops::Range;

use crate::ArrowMatrix;
use robimu_model::effects::EffectSet;
use robimu_model::noise::NoiseModel;
pub use robimu_model::observations::Measurements;
use robimu_model::spline::MAX_DEGREE;
use robimu_model::{
    JointState, Knots, MeasurementModel, ModelError, ParamLayout, Robot, SpanPolynomials, Spline,
    SplineError,
};

/// Why the problem cannot be evaluated at some θ.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProblemError {
    /// x is outside the model's domain (e.g. |g_xy| ≥ g0).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The spline could not be evaluated.
    #[error(transparent)]
    Spline(#[from] SplineError),
    /// τ moved so far that a selected IMU sample left the joint-sample span.
    #[error("the time offset moved IMU samples outside the joint-sample span")]
    SampleOutOfSpan,
    /// No IMU sample overlaps the joint samples at this τ.
    #[error("no IMU sample falls inside the joint-sample span at tau = {tau} s")]
    NoOverlap {
        /// The time offset tried.
        tau: f64,
    },
    /// The layout and the observations do not have the same IMUs.
    #[error("the parameter layout has {layout} IMUs but the session has {data}")]
    ImuCount {
        /// IMUs of the layout.
        layout: usize,
        /// IMUs of the observations.
        data: usize,
    },
    /// An effect of an IMU the problem does not have.
    #[error("an effect is on IMU {imu} but the problem has {n_imus} IMUs")]
    EffectImu {
        /// The effect's IMU.
        imu: usize,
        /// IMUs of the problem.
        n_imus: usize,
    },
}

/// How the problem is set up.
#[derive(Debug, Clone)]
pub struct ProblemOptions {
    /// σ of each joint position, rad.
    pub sigma_q: Vec<f64>,
    /// σ of `[ax, ay, az, gx, gy, gz]` (white noise; ignored when `noise` is given).
    pub sigma_z: [f64; 6],
    /// The noise model of each IMU (docs/model.md §4.6, §9): IMU j's is
    /// `noise[j]`, an IMU beyond the list has its last (one model serves
    /// every IMU); empty: white of `sigma_z` for every IMU, the paper's
    /// model. Each IMU's residuals are whitened by its own model (its
    /// Σ_z of eq. (22)); white models give exactly the white problem.
    pub noise: Vec<NoiseModel>,
    /// Include the prior residuals (off only for identifiability checks).
    pub use_prior: bool,
    /// Indices of x that are held fixed.
    pub frozen: Vec<usize>,
}

/// The non-zero basis functions' values at one joint sample (the joint
/// residuals need no derivative).
#[derive(Debug, Clone, Copy)]
struct JointBasis {
    first: usize,
    n: [f64; MAX_DEGREE + 1],
}

/// One IMU's samples in the problem (module doc, *Several IMUs*).
struct Stream<'a> {
    /// Sample times.
    t: &'a [f64],
    /// Samples `[ax, ay, az, gx, gy, gz]`.
    z: &'a [[f64; 6]],
    /// x index of each entry of the IMU's own vector.
    map: &'a [usize],
    /// Median step of the stream (segments break at > 1.5× it).
    median_dt: f64,
    /// The IMU's noise model ([`ProblemOptions::noise`]).
    noise: NoiseModel,
    /// 1/σ_z of its channels (times √thin while an iteration is thinned).
    inv_sigma_z: [f64; 6],
    /// Position of each selected sample in its segment (index i − imu_range.start).
    seg_pos: Vec<u32>,
    /// 1/s_i per channel for every sample (empty when no channel has a
    /// motion level; set for the selected samples by `begin_iteration`).
    inv_levels: Vec<[f64; 6]>,
    /// Whether `inv_levels[i]` has been set (each sample's level is set
    /// once per solve, module doc).
    level_set: Vec<bool>,
    /// Samples currently used.
    imu_range: Range<usize>,
    /// Per sensor (accelerometer, gyroscope): the estimated parameters its
    /// rows can depend on, as (index in the IMU's own vector, position in
    /// θ's x part); its effect column l follows as (n_own + l, n_active +
    /// effect_map[l]).
    sensor_columns: [Vec<(usize, usize)>; 2],
    /// The IMU's number j.
    index: usize,
    /// θ_E index of each of its effect columns ([`EffectSet::imu_map`]).
    effect_map: Vec<usize>,
}

/// The calibration problem for one session.
pub struct Problem<'a> {
    robot: &'a Robot,
    layout: &'a ParamLayout,
    /// The one-IMU layout each stream's model uses.
    imu_layout: &'a ParamLayout,
    data: &'a Measurements,
    knots: Knots,
    /// The basis of `knots` per span, for the IMU samples (evaluated at
    /// every cost and linearisation as τ moves).
    spans: SpanPolynomials,
    n: usize,
    inv_sigma_q: Vec<f64>,
    /// Every `thin`-th selected IMU sample is used (1: all; module doc,
    /// *The first iteration*).
    thin: usize,
    /// The thinning of the solver's first iteration (1: none).
    thin_first: usize,
    /// Iterations the solver has begun ([`crate::LeastSquares::begin_iteration`]).
    iterations_begun: usize,
    /// Every IMU's selected samples before the last change of selection
    /// (the cycle test of [`Self::reselect`]).
    previous_ranges: Vec<Range<usize>>,
    /// The selection is kept from now on ([`Self::reselect`]).
    selection_frozen: bool,
    /// The θ whose trajectory gives the motion levels (the first
    /// [`Self::update_levels`]'s; module doc).
    level_theta: Option<Vec<f64>>,
    /// Whether every IMU's noise model is white (then the white assembly
    /// runs; otherwise every IMU's rows go through the GLS one, a white
    /// IMU's whitening being its 1/σ alone).
    white: bool,
    /// Extra knot spans E a whitened row reaches back (0 when white).
    extra_spans: usize,
    /// The IMUs' samples (IMU j is `streams[j]`).
    streams: Vec<Stream<'a>>,
    prior_mean: Vec<f64>,
    prior_inv_sigma: Vec<f64>,
    use_prior: bool,
    /// x indices of θ's x part.
    active: Vec<usize>,
    /// The full x; frozen entries keep their value, estimated ones are
    /// overwritten from θ.
    x_base: Vec<f64>,
    joint_basis: Vec<JointBasis>,
    /// The joint residuals' part of the Gauss–Newton matrix: constant, as
    /// they are linear in c (built once).
    joint_normal: ArrowMatrix,
    /// Catalogue effects appended to the model (empty: the baseline model).
    effects: &'a EffectSet,
    /// The residuals of the solver's last cost ([`Self::take_residuals`]).
    end: Option<Residuals>,
}

impl<'a> Problem<'a> {
    /// Margin (s) kept between the selected IMU samples and the ends of the
    /// joint-sample span, so that a step in τ smaller than this keeps the
    /// selected set valid.
    pub const MARGIN: f64 = 0.05;

    /// Set up the problem. `x_base` is x with the values of the frozen
    /// entries (the others are overwritten by θ). The layout's IMUs are the
    /// first [`ParamLayout::n_imus`] of `data` (a one-IMU layout uses IMU 0
    /// of any session). The catalogue `effects`
    /// extend the model ([`EffectSet::none`] for the baseline alone): their
    /// parameters θ_E follow x_a in θ (θ = [c, x_a, θ_E]), enter the rows of
    /// the IMUs they are on ([`EffectSet::imu_map`]) through ∂z/∂θ_E ([`robimu_model::effects`]) and carry their
    /// zero-mean priors. An empty set adds no unknown and no per-sample work.
    ///
    /// # Panics
    /// If the sizes of `opts` or `x_base` do not match the robot.
    pub fn new(
        robot: &'a Robot,
        layout: &'a ParamLayout,
        data: &'a Measurements,
        knots: Knots,
        x_base: Vec<f64>,
        opts: &ProblemOptions,
        effects: &'a EffectSet,
    ) -> Result<Self, ProblemError> {
        let n = robot.dof();
        assert_eq!(opts.sigma_q.len(), n);
        assert_eq!(x_base.len(), layout.len());
        let active: Vec<usize> = (0..layout.len())
            .filter(|k| !opts.frozen.contains(k))
            .collect();
        let spans = SpanPolynomials::new(&knots);
        let joint_basis = joint_bases(&spans, &data.joint_t)?;
        let specs = layout.specs();
        let k_imus = layout.n_imus();
        if k_imus > data.n_imus() {
            return Err(ProblemError::ImuCount {
                layout: k_imus,
                data: data.n_imus(),
            });
        }
        if let Some(&imu) = effects.owners().iter().flatten().find(|&&j| j >= k_imus) {
            return Err(ProblemError::EffectImu {
                imu,
                n_imus: k_imus,
            });
        }
        let imu_layout = layout.imu_layout();
        let noise_of = |j: usize| match opts.noise.get(j).or(opts.noise.last()) {
            Some(m) => m.clone(),
            None => NoiseModel::white(opts.sigma_z).expect("positive sigma_z"),
        };
        let noises: Vec<NoiseModel> = (0..k_imus.max(1)).map(noise_of).collect();
        let white = noises.iter().all(NoiseModel::is_white);
        let motion = noises.iter().any(|m| m.imu.iter().any(|c| c.motion > 0.0));
        let max_order = noises.iter().map(NoiseModel::max_order).max().unwrap_or(0);
        let (n_own, na) = (imu_layout.len(), active.len());
        let streams: Vec<Stream> = (0..k_imus)
            .map(|j| {
                let view = data.imu(j);
                let map = layout.imu_map(j);
                let effect_map = effects.imu_map(j);
                let sensor_columns = [0, 1].map(|sensor| {
                    let mut cols: Vec<(usize, usize)> = (0..n_own)
                        .filter(|&k| sensor_depends_on(imu_layout, sensor, k))
                        .filter_map(|k| active.binary_search(&map[k]).ok().map(|a| (k, a)))
                        .collect();
                    cols.sort_by_key(|&(_, a)| a);
                    cols.extend(
                        effect_map
                            .iter()
                            .enumerate()
                            .map(|(l, &e)| (n_own + l, na + e)),
                    );
                    cols
                });
                Stream {
                    t: view.t,
                    z: view.z,
                    map,
                    median_dt: median_step(view.t),
                    inv_sigma_z: noises[j].sigma_z().map(|s| 1.0 / s),
                    noise: noises[j].clone(),
                    seg_pos: Vec::new(),
                    inv_levels: if motion {
                        vec![[1.0; 6]; view.t.len()]
                    } else {
                        Vec::new()
                    },
                    level_set: if motion {
                        vec![false; view.t.len()]
                    } else {
                        Vec::new()
                    },
                    imu_range: 0..0,
                    sensor_columns,
                    index: j,
                    effect_map,
                }
            })
            .collect();
        let extra_spans = if white {
            0
        } else {
            let dt = streams.iter().map(|s| s.median_dt).fold(0.0, f64::max);
            extra_spans(&knots, max_order, 1.5 * dt)
        };
        let mut p = Self {
            robot,
            layout,
            imu_layout,
            data,
            spans,
            knots,
            n,
            inv_sigma_q: opts.sigma_q.iter().map(|s| 1.0 / s).collect(),
            thin: 1,
            thin_first: 1,
            iterations_begun: 0,
            previous_ranges: Vec::new(),
            selection_frozen: false,
            level_theta: None,
            white,
            extra_spans,
            streams,
            prior_mean: specs.iter().map(|s| s.nominal).collect(),
            prior_inv_sigma: specs.iter().map(|s| 1.0 / s.sigma).collect(),
            use_prior: opts.use_prior,
            active,
            x_base,
            joint_basis,
            joint_normal: ArrowMatrix::zeros(0, 0, 0),
            effects,
            end: None,
        };
        p.joint_normal = p.joint_normal_matrix();
        let x = p.x_base.clone();
        p.select_all(&x)?;
        Ok(p)
    }

    /// Most thinning of the first iteration ([`Self::thin_first_iteration`]).
    pub const FIRST_THIN_MAX: usize = 8;
    /// Fewest IMU samples per knot interval a thinned iteration keeps.
    pub const THIN_SAMPLES_PER_SPAN: f64 = 16.0;

    /// Thin the solver's first iteration (module doc, *The first
    /// iteration*) to every k-th IMU sample, each weighted by √k, k the
    /// largest ≤ [`Self::FIRST_THIN_MAX`] that keeps
    /// [`Self::THIN_SAMPLES_PER_SPAN`] samples in the shortest knot interval.
    /// Only for white noise without effects (otherwise nothing changes).
    pub fn thin_first_iteration(&mut self) {
        if !(self.white && self.effects.is_empty()) {
            return;
        }
        let dt = self.streams.iter().map(|s| s.median_dt).fold(0.0, f64::max);
        let h = shortest_interval(&self.knots);
        let k = (h / (Self::THIN_SAMPLES_PER_SPAN * dt)).floor();
        self.thin_first_by(if k.is_finite() {
            (k as usize).clamp(1, Self::FIRST_THIN_MAX)
        } else {
            1
        });
    }

    /// Thin the first iteration by exactly `k` (white, no effects).
    pub(crate) fn thin_first_by(&mut self, k: usize) {
        if self.white && self.effects.is_empty() {
            self.thin_first = k.max(1);
        }
    }

    /// The thinning of the solver's first iteration (1: none).
    pub fn first_thinning(&self) -> usize {
        self.thin_first
    }

    /// Use every `k`-th selected IMU sample, weighted by √k.
    fn set_thin(&mut self, k: usize) {
        if k != self.thin {
            let scale = (k as f64).sqrt();
            for st in &mut self.streams {
                st.inv_sigma_z = st.noise.sigma_z().map(|s| scale / s);
            }
            self.thin = k;
        }
    }

    /// The margin in use (see [`Self::MARGIN`]).
    pub fn margin(&self) -> f64 {
        Self::MARGIN
    }

    /// Number of spline coefficients nc = m·n.
    pub fn n_coeffs(&self) -> usize {
        self.knots.num_coeffs() * self.n
    }

    /// Half-bandwidth of the coefficient block: (p+1+E)·n − 1, E the extra
    /// knot spans a whitened row reaches back (0 for white noise; module doc).
    pub fn bandwidth(&self) -> usize {
        (self.knots.degree() + 1 + self.extra_spans) * self.n - 1
    }

    /// IMU 0's noise model.
    pub fn noise(&self) -> &NoiseModel {
        &self.streams[0].noise
    }

    /// IMU `j`'s noise model ([`ProblemOptions::noise`]).
    pub fn noise_of(&self, j: usize) -> &NoiseModel {
        &self.streams[j].noise
    }

    /// Extra knot spans E a whitened IMU row reaches back (module doc).
    pub fn extra_spans(&self) -> usize {
        self.extra_spans
    }

    /// Set the levels s_i of the selected samples not yet set, from the
    /// trajectory of the θ of the first call, the solve's start (module doc:
    /// held for the whole solve; a later call only covers samples a moved τ
    /// selects anew). Nothing to do when no channel has a motion level.
    pub fn update_levels(&mut self, theta: &[f64]) -> Result<(), ProblemError> {
        if self.streams[0].inv_levels.is_empty() {
            return Ok(());
        }
        // the trajectory of the first call, for every later one; a sample's
        // t + τ at the τ that selects it (inside the span)
        let at = self
            .level_theta
            .get_or_insert_with(|| theta.to_vec())
            .clone();
        let spline = self.spline_of(&at);
        let x = self.x_of(theta);
        let tau_at = self.imu_layout.offsets().tau;
        let mut js = JointState::default();
        for s in &mut self.streams {
            let tau = x[s.map[tau_at]];
            for i in s.imu_range.clone() {
                if s.level_set[i] {
                    continue;
                }
                spline
                    .evaluate(s.t[i] + tau, &mut js)
                    .map_err(|_| ProblemError::SampleOutOfSpan)?;
                let qdd2: f64 = js.qdd[..self.n].iter().map(|v| v * v).sum();
                s.inv_levels[i] = std::array::from_fn(|c| 1.0 / s.noise.imu[c].level(qdd2));
                s.level_set[i] = true;
            }
        }
        Ok(())
    }

    /// Number of IMUs K of the problem.
    pub fn n_imus(&self) -> usize {
        self.streams.len()
    }

    /// x indices of the estimated parameters (θ's x part, in order).
    pub fn active(&self) -> &[usize] {
        &self.active
    }

    /// The knots of the trajectory spline.
    pub fn knots(&self) -> &Knots {
        &self.knots
    }

    /// The robot.
    pub fn robot(&self) -> &Robot {
        self.robot
    }

    /// The parameter layout.
    pub fn layout(&self) -> &ParamLayout {
        self.layout
    }

    /// The observations.
    pub fn data(&self) -> &Measurements {
        self.data
    }

    /// IMU 0's samples currently used.
    pub fn imu_range(&self) -> Range<usize> {
        self.streams[0].imu_range.clone()
    }

    /// IMU `j`'s samples currently used.
    pub fn imu_range_of(&self, j: usize) -> Range<usize> {
        self.streams[j].imu_range.clone()
    }

    /// θ from a spline and a full x (effect parameters, if any, at 0).
    pub fn theta(&self, spline: &Spline, x: &[f64]) -> Vec<f64> {
        let mut th = spline.coeffs().to_vec();
        th.extend(self.active.iter().map(|&k| x[k]));
        th.extend(std::iter::repeat_n(0.0, self.n_effect_params()));
        th
    }

    /// The effects in the model.
    pub fn effects(&self) -> &EffectSet {
        self.effects
    }

    /// Number of effect parameters θ_E.
    pub fn n_effect_params(&self) -> usize {
        self.effects.len()
    }

    /// The effect parameters θ_E of θ.
    pub fn effect_params_of<'t>(&self, theta: &'t [f64]) -> &'t [f64] {
        &theta[self.n_coeffs() + self.active.len()..]
    }

    /// The full x of θ.
    pub fn x_of(&self, theta: &[f64]) -> Vec<f64> {
        let nc = self.n_coeffs();
        let mut x = self.x_base.clone();
        for (a, &k) in self.active.iter().enumerate() {
            x[k] = theta[nc + a];
        }
        x
    }

    /// The trajectory spline of θ.
    pub fn spline_of(&self, theta: &[f64]) -> Spline {
        let nc = self.n_coeffs();
        Spline::new(self.knots.clone(), self.n, theta[..nc].to_vec())
            .expect("coefficient count matches the knots")
    }

    /// Choose IMU 0's samples whose t + τ lies in the joint span (less the margin).
    pub fn select_samples(&mut self, tau: f64) -> Result<(), ProblemError> {
        self.select_stream(0, tau)
    }

    /// Choose every IMU's samples at its τ in `x`.
    fn select_all(&mut self, x: &[f64]) -> Result<(), ProblemError> {
        let tau_at = self.imu_layout.offsets().tau;
        for j in 0..self.streams.len() {
            let tau = x[self.streams[j].map[tau_at]];
            self.select_stream(j, tau)?;
        }
        Ok(())
    }

    /// Choose IMU `j`'s samples whose t + τ lies in the joint span (less the margin).
    fn select_stream(&mut self, j: usize, tau: f64) -> Result<(), ProblemError> {
        let range = self.samples_at(j, tau)?;
        self.apply_range(j, range);
        Ok(())
    }

    /// The solver's re-selection at the start of an iteration (x at θ):
    /// every IMU's samples at its τ, unless that returns the selection to
    /// the one before the last change. Then τ has stepped back and forth
    /// across a sample's edge (each selection's optimum lies in the other's
    /// τ range, and the solver would alternate between the two costs until
    /// its iteration limit, seen on a recorded session): the samples both
    /// selections hold are kept from then on (they stay inside the span
    /// while τ moves by less than the margin).
    fn reselect(&mut self, x: &[f64]) -> Result<(), ProblemError> {
        if self.selection_frozen {
            return Ok(());
        }
        let tau_at = self.imu_layout.offsets().tau;
        let wanted = (0..self.streams.len())
            .map(|j| self.samples_at(j, x[self.streams[j].map[tau_at]]))
            .collect::<Result<Vec<_>, _>>()?;
        let current: Vec<Range<usize>> = self.streams.iter().map(|s| s.imu_range.clone()).collect();
        if wanted == current {
            return Ok(());
        }
        let cycle = wanted == self.previous_ranges;
        self.previous_ranges = current.clone();
        for (j, (w, c)) in wanted.into_iter().zip(current).enumerate() {
            let range = if cycle {
                w.start.max(c.start)..w.end.min(c.end)
            } else {
                w
            };
            self.apply_range(j, range);
        }
        self.selection_frozen = cycle;
        Ok(())
    }

    /// Selects IMU `j`'s samples `range` (their AR segment positions too).
    fn apply_range(&mut self, j: usize, range: Range<usize>) {
        let Range { start: lo, end: hi } = range;
        let white = self.white;
        let s = &mut self.streams[j];
        s.imu_range = lo..hi;
        if !white {
            let gap = 1.5 * s.median_dt;
            s.seg_pos.clear();
            let mut pos = 0u32;
            for i in lo..hi {
                if i > lo && s.t[i] - s.t[i - 1] > gap {
                    pos = 0;
                }
                s.seg_pos.push(pos);
                pos = pos.saturating_add(1);
            }
        }
    }

    /// The samples of IMU `j` [`Self::select_stream`] chooses at τ.
    fn samples_at(&self, j: usize, tau: f64) -> Result<Range<usize>, ProblemError> {
        let (a, b) = (
            self.knots.start() + Self::MARGIN,
            self.knots.end() - Self::MARGIN,
        );
        let t = self.streams[j].t;
        let lo = t.partition_point(|&ti| ti + tau < a);
        let hi = t.partition_point(|&ti| ti + tau <= b);
        if hi <= lo {
            return Err(ProblemError::NoOverlap { tau });
        }
        Ok(lo..hi)
    }

    /// Every IMU's whitened residuals at θ (IMU j at `[j]`, in sample order):
    /// kept from the solver's last cost when it was at θ
    /// ([`crate::LeastSquares::end_cost`]), else computed now.
    pub fn take_residuals(&mut self, theta: &[f64]) -> Result<Vec<ImuResiduals>, ProblemError> {
        match self.end.take() {
            Some(r) if r.theta == theta => Ok(r.imus),
            _ => (0..self.streams.len())
                .map(|j| self.imu_residuals_of(theta, j))
                .collect(),
        }
    }

    /// IMU 0's measurement model at x.
    pub fn model(&self, x: &[f64]) -> Result<MeasurementModel, ProblemError> {
        self.model_of(0, x)
    }

    /// IMU `j`'s measurement model at the full x (its own vector through its map).
    pub fn model_of(&self, j: usize, x: &[f64]) -> Result<MeasurementModel, ProblemError> {
        let own: Vec<f64> = self.streams[j].map.iter().map(|&k| x[k]).collect();
        Ok(MeasurementModel::new(self.robot, self.imu_layout, &own)?)
    }
}

/// The basis of every joint sample, the two halves on two threads.
fn joint_bases(spans: &SpanPolynomials, t: &[f64]) -> Result<Vec<JointBasis>, SplineError> {
    // written in place, half by each thread (no growth, no copy)
    let mut out = vec![
        JointBasis {
            first: 0,
            n: [0.0; MAX_DEGREE + 1]
        };
        t.len()
    ];
    let part = |ts: &[f64], out: &mut [JointBasis]| -> Result<(), SplineError> {
        let mut span = 0;
        for (&t, b) in ts.iter().zip(out) {
            b.first = spans.values_near(t, &mut span, &mut b.n)?;
        }
        Ok(())
    };
    let (lo, hi) = t.split_at(t.len() / 2);
    let (out_lo, out_hi) = out.split_at_mut(lo.len());
    let (a, b) = robimu_model::pair::join(|| part(lo, out_lo), || part(hi, out_hi));
    a?;
    b?;
    Ok(out)
}

/// Median of the steps of `t` (0 with fewer than two samples).
fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// E = ⌊order·dt_max / h_min⌋ + 1: how many knot spans `order` steps of at most
/// `dt_max` can cross (h_min the shortest non-empty knot interval).
fn extra_spans(knots: &Knots, order: usize, dt_max: f64) -> usize {
    if order == 0 {
        return 0;
    }
    let h_min = shortest_interval(knots);
    // An interval of length L contains at most ⌊L/h_min⌋ + 1 knots.
    (order as f64 * dt_max / h_min).floor() as usize + 1
}

/// The shortest non-empty knot interval.
fn shortest_interval(knots: &Knots) -> f64 {
    knots
        .knots()
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&h| h > 0.0)
        .fold(f64::INFINITY, f64::min)
}

/// Whether the rows of `sensor` (0: accelerometer, 1: gyroscope) can depend
/// on `x[k]` (docs/model.md §1–3): the gyroscope sees only rotations — no robot
/// length errors ε_i{1,2,3}, no gravity, no accelerometer intrinsics — and the
/// accelerometer sees no gyroscope intrinsics.
pub(crate) fn sensor_depends_on(layout: &ParamLayout, sensor: usize, k: usize) -> bool {
    let o = layout.offsets();
    let gyro_intrinsics = k >= o.gamma_w;
    if sensor == 0 {
        return !gyro_intrinsics;
    }
    if k < o.g_xy {
        return layout.estimated_errors()[k].k >= 4;
    }
    k == o.tau || gyro_intrinsics
}

impl crate::LeastSquares for Problem<'_> {
    type Error = ProblemError;
    fn begin_iteration(&mut self, theta: &[f64]) -> Result<(), ProblemError> {
        self.iterations_begun += 1;
        self.set_thin(if self.iterations_begun == 1 {
            self.thin_first
        } else {
            1
        });
        let x = self.x_of(theta);
        self.reselect(&x)?;
        self.update_levels(theta)
    }
    fn cost(&self, theta: &[f64]) -> Result<f64, ProblemError> {
        Problem::cost(self, theta)
    }
    /// The cost, keeping the residuals for [`Problem::take_residuals`].
    fn end_cost(&mut self, theta: &[f64]) -> Result<f64, ProblemError> {
        let (cost, r) = self.cost_and_residuals(theta)?;
        self.end = Some(r);
        Ok(cost)
    }
    fn linearize(
        &self,
        theta: &[f64],
        a: &mut crate::ArrowMatrix,
        g: &mut [f64],
    ) -> Result<f64, ProblemError> {
        Problem::linearize(self, theta, a, g)
    }
    fn new_matrix(&self) -> crate::ArrowMatrix {
        Problem::new_matrix(self)
    }
    /// The same samples at θ's τ (the motion levels are the solve's, module
    /// doc), and no thinning (the next iteration uses every sample).
    fn keeps_setup(&self, theta: &[f64]) -> bool {
        if self.thin > 1 {
            return false;
        }
        if self.selection_frozen {
            return true;
        }
        let x = self.x_of(theta);
        let tau_at = self.imu_layout.offsets().tau;
        self.streams
            .iter()
            .enumerate()
            .all(|(j, s)| self.samples_at(j, x[s.map[tau_at]]).ok() == Some(s.imu_range.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::{JointState, MeasurementJacobians};

    /// The structural sparsity used by the assembly must match the model:
    /// every column a sensor is said not to depend on is exactly zero.
    #[test]
    fn sensor_columns_match_the_model_jacobian() {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        let mut x = layout.nominal();
        for (k, s) in layout.specs().iter().enumerate() {
            x[k] += 0.3 * s.sigma * ((k as f64) * 1.7).sin();
        }
        let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
        let mut jac = MeasurementJacobians::new(layout.len());
        for t in [0.1, 0.7, 2.3] {
            let f =
                |a: f64, b: f64| [0, 1, 2, 3, 4, 5].map(|j: usize| a * (t * (j as f64 + b)).sin());
            let (q, qd, qdd, qddd) = (f(1.0, 1.0), f(0.5, 2.0), f(0.9, 0.5), f(0.3, 1.5));
            let js = JointState::from_slices(&q, &qd, &qdd, &qddd);
            model.jacobians(&js, &mut jac);
            for k in 0..layout.len() {
                for sensor in 0..2 {
                    let used = sensor_depends_on(&layout, sensor, k);
                    let col = &jac.dz_dx[k][3 * sensor..3 * sensor + 3];
                    // a single-channel column is zero in the other channels
                    if let Some(c) = assemble::single_channel(&layout, sensor, k) {
                        assert!(used, "{}", layout.specs()[k].name);
                        for (d, v) in col.iter().enumerate() {
                            assert!(
                                (d == c) == (*v != 0.0),
                                "{} sensor {sensor} channel {d}: {v}",
                                layout.specs()[k].name
                            );
                        }
                    }
                    if !used {
                        assert!(
                            col.iter().all(|v| *v == 0.0),
                            "{} sensor {sensor}: {col:?}",
                            layout.specs()[k].name
                        );
                    } else {
                        assert!(
                            col.iter().any(|v| *v != 0.0),
                            "{} sensor {sensor} is all zero",
                            layout.specs()[k].name
                        );
                    }
                }
            }
        }
    }
}
