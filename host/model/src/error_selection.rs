//! The identifiable set of generalized errors of any robot (docs/model.md §1):
//! which ε_ik the IMU data can determine, found numerically from the
//! identification Jacobian over a rich trajectory.
//!
//! # Method
//!
//! * Candidates: ε_i1..6 of links i = 1..n−1 and ε_n1..3 (E_0 is never
//!   estimated and E_n's rotation is fixed, docs/model.md §1).
//! * A random excitation trajectory ([`super::trajectory::random_walk`]) is
//!   sampled at `sample_rate`; at every sample the exact ∂z/∂x
//!   ([`MeasurementModel::jacobians`]) of the robot estimating all candidates is
//!   evaluated at a random point near the prior mean (x̂ + `perturbation`·σ·N(0, 1),
//!   away from special symmetric configurations), its rows whitened by σ_z
//!   and its columns scaled by the prior σ (so lengths and angles compare).
//!   The spline coefficients are left out: the joint positions are taken as
//!   measured, so only x is identified from z (eq. (10)).
//! * The 27 other parameters (g_xy, τ, both sensors' intrinsics) are always
//!   estimated: their columns come first and must be full rank; they are
//!   projected out (Householder QR).
//! * Column-pivoted QR of the projected candidate columns gives the numerical
//!   rank r: pivots |R_kk| > `tolerance`·|R_00|, and the gap between the last
//!   kept and the first dropped pivot.
//! * The set itself is chosen greedily in a fixed preference order, keeping a
//!   candidate when its residual against everything kept so far exceeds the
//!   same threshold. Preferred first: ε_i{1,2,4,6} (i < n) and ε_n{1,2,3};
//!   last: ε_i3 and ε_i5 for i < n, the translation along and rotation about
//!   the next joint's axis, which move through that revolute joint into
//!   E_{i+1} (Meggiolaro & Dubowsky). Within a class: flange to base (an
//!   error that can be moved towards the IMU is represented there), then by
//!   k. For the AUBO i5 this reproduces the paper's Table II pattern (base to
//!   flange would keep ε_14 instead of ε_42: an equally valid basis). The
//!   greedy count must equal r, else [`IdentifiableError::RankAmbiguous`].

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use crate::{
    ErrorIndex, JointState, MeasurementJacobians, MeasurementModel, ModelError, ParamLayout, Robot,
    RobotError, SplineError,
};

/// How to build and factor the identification Jacobian.
#[derive(Clone, Debug, PartialEq)]
pub struct IdentifiableOptions {
    /// Trajectory duration (s).
    pub duration: f64,
    /// Knot spacing of the random trajectory (s).
    pub knot_spacing: f64,
    /// Jacobian rows per second (each sample gives 6 rows).
    pub sample_rate: f64,
    /// Linearisation point: x̂ + `perturbation`·σ·N(0, 1) (in prior σ).
    pub perturbation: f64,
    /// Relative rank threshold on the QR pivots (|R_kk| > tolerance·|R_00|).
    pub tolerance: f64,
    /// Seed of the trajectory and the linearisation point.
    pub seed: u64,
}

impl Default for IdentifiableOptions {
    /// 60 s, knots every 1 s, 50 Hz, 0.5 σ, tolerance 1e-8, seed 1.
    fn default() -> Self {
        Self {
            duration: 60.0,
            knot_spacing: 1.0,
            sample_rate: 50.0,
            perturbation: 0.5,
            tolerance: 1e-8,
            seed: 1,
        }
    }
}

/// Why the identifiable set could not be determined.
#[derive(Debug, thiserror::Error)]
pub enum IdentifiableError {
    /// An option is not finite or not positive.
    #[error("identifiability option {field} must be finite and > 0 (got {value})")]
    BadOption {
        /// Which option.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// The robot with all candidates estimated is not a valid description.
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The trajectory could not be built.
    #[error("cannot build the excitation trajectory: {0}")]
    Trajectory(#[from] SplineError),
    /// The linearisation point is outside the model's domain.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The always-estimated parameters are not identifiable on their own.
    #[error("parameter {name} is not identifiable from this trajectory (pivot ratio {ratio:e})")]
    BaseRankDeficient {
        /// The parameter whose pivot fell below the threshold.
        name: String,
        /// Its |R_kk| / |R_00|.
        ratio: f64,
    },
    /// Pivoted QR and the preference-order selection disagree on the rank.
    #[error("ambiguous numerical rank: pivoted QR gives {pivoted}, the ordered selection {ordered}; change the tolerance or the trajectory")]
    RankAmbiguous {
        /// Rank from column-pivoted QR.
        pivoted: usize,
        /// Number kept by the ordered selection.
        ordered: usize,
    },
}

/// The identifiable generalized errors of a robot and the evidence for them.
#[derive(Clone, Debug, PartialEq)]
pub struct IdentifiableSet {
    /// The chosen ε, sorted by link then k (feed to [`Robot::with_estimated_errors`]).
    pub errors: Vec<ErrorIndex>,
    /// Numerical rank of the candidate columns after projecting out the 27
    /// always-estimated parameters (= `errors.len()`).
    pub rank: usize,
    /// Column-pivoted QR of the projected candidates: pivot order and
    /// |R_kk| / |R_00|, all candidates.
    pub pivots: Vec<(ErrorIndex, f64)>,
    /// |R_{r−1,r−1}| / |R_{r,r}|: last kept over first dropped pivot (∞ if none dropped).
    pub gap: f64,
    /// Smallest |R_kk| / |R_00| of the 27 always-estimated columns.
    pub base_min_pivot: f64,
    /// Smallest residual (relative to |R_00| of the candidates) of a chosen ε
    /// against the 27 and the chosen ε before it in preference order.
    pub chosen_min_residual: f64,
    /// Every dropped candidate with its residual against the span of the 27
    /// and all chosen ε, relative to |R_00| of the candidates.
    pub dropped: Vec<(ErrorIndex, f64)>,
}

/// The candidates of an n-link robot: ε_i1..6 (i < n), ε_n1..3.
pub fn candidate_errors(n: usize) -> Vec<ErrorIndex> {
    let mut v = Vec::new();
    for link in 1..=n {
        let kmax = if link == n { 3 } else { 6 };
        v.extend((1..=kmax).map(|k| ErrorIndex { link, k }));
    }
    v
}

/// The preference order of the selection (see the module doc).
pub(crate) fn preference_order(n: usize) -> Vec<ErrorIndex> {
    let next_axis = |e: &ErrorIndex| e.link < n && (e.k == 3 || e.k == 5);
    let mut all = candidate_errors(n);
    all.sort_by_key(|e| (std::cmp::Reverse(e.link), e.k));
    let mut v: Vec<ErrorIndex> = all.iter().copied().filter(|e| !next_axis(e)).collect();
    v.extend(all.iter().copied().filter(next_axis));
    v
}

/// The whitened, σ-scaled identification Jacobian (see the module doc).
#[derive(Clone, Debug)]
pub struct IdentificationMatrix {
    /// Rows (6 per sample).
    pub rows: usize,
    /// Column names: the 27 always-estimated parameters (docs/model.md §5 names,
    /// x order), then `eps_<link>_<k>` of every candidate.
    pub names: Vec<String>,
    /// The candidates, in the order of their columns (after the 27).
    pub candidates: Vec<ErrorIndex>,
    /// Column-major entries, `rows` per column.
    pub data: Vec<f64>,
}

impl IdentificationMatrix {
    /// Column j.
    pub fn col(&self, j: usize) -> &[f64] {
        &self.data[j * self.rows..(j + 1) * self.rows]
    }
}

fn check(field: &'static str, value: f64) -> Result<(), IdentifiableError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(IdentifiableError::BadOption { field, value })
    }
}

/// Builds the identification Jacobian of `robot` with every candidate ε.
pub fn identification_matrix(
    robot: &Robot,
    opts: &IdentifiableOptions,
) -> Result<IdentificationMatrix, IdentifiableError> {
    check("duration", opts.duration)?;
    check("knot_spacing", opts.knot_spacing)?;
    check("sample_rate", opts.sample_rate)?;
    check("tolerance", opts.tolerance)?;
    if !(opts.perturbation.is_finite() && opts.perturbation >= 0.0) {
        return Err(IdentifiableError::BadOption {
            field: "perturbation",
            value: opts.perturbation,
        });
    }
    let n = robot.dof();
    let candidates = candidate_errors(n);
    let full = robot.with_estimated_errors(candidates.clone())?;
    let layout = ParamLayout::new(&full);
    let mut rng = rand::rngs::StdRng::seed_from_u64(opts.seed);
    let x: Vec<f64> = layout
        .specs()
        .iter()
        .map(|s| {
            let z: f64 = StandardNormal.sample(&mut rng);
            s.nominal + opts.perturbation * s.sigma * z
        })
        .collect();
    let model = MeasurementModel::new(&full, &layout, &x)?;
    let traj = super::trajectory::random_walk(&full, opts.duration, opts.knot_spacing, &mut rng)?;
    let (t0, t1) = (traj.knots().start(), traj.knots().end());
    let samples = ((t1 - t0) * opts.sample_rate).floor() as usize + 1;
    let rows = 6 * samples;
    let ne = candidates.len();
    let np = layout.len();
    // Column order: the 27 (x indices ne..np), then the candidates (0..ne).
    let order: Vec<usize> = (ne..np).chain(0..ne).collect();
    let sigma = layout.sigmas();
    let wz = robot.sigma_z().map(|s| 1.0 / s);
    let mut data = vec![0.0; rows * np];
    let mut js = JointState::default();
    let mut jac = MeasurementJacobians::new(np);
    for s in 0..samples {
        let t = (t0 + s as f64 / opts.sample_rate).min(t1);
        traj.evaluate(t, &mut js)?;
        model.jacobians(&js, &mut jac);
        for (c, &ix) in order.iter().enumerate() {
            let col = &mut data[c * rows + 6 * s..c * rows + 6 * s + 6];
            for r in 0..6 {
                col[r] = jac.dz_dx[ix][r] * wz[r] * sigma[ix];
            }
        }
    }
    let names = order
        .iter()
        .map(|&ix| layout.specs()[ix].name.clone())
        .collect();
    Ok(IdentificationMatrix {
        rows,
        names,
        candidates,
        data,
    })
}

/// Householder QR workspace on a column-major matrix (columns can be
/// processed in any order; processed columns are frozen).
struct Qr {
    rows: usize,
    a: Vec<f64>,
    /// Rows already eliminated.
    k: usize,
}

impl Qr {
    fn col(&self, j: usize) -> &[f64] {
        &self.a[j * self.rows..(j + 1) * self.rows]
    }
    /// Norm of the not-yet-eliminated part of column j.
    /// Remove from `left` and return the column with the largest residual
    /// norm (the pivot of column-pivoted QR; the first one on ties).
    fn take_largest(&self, left: &mut Vec<usize>) -> usize {
        let (pos, _) = left
            .iter()
            .enumerate()
            .map(|(p, &c)| (p, self.residual(c)))
            .fold((0, -1.0), |b, x| if x.1 > b.1 { x } else { b });
        left.remove(pos)
    }

    fn residual(&self, j: usize) -> f64 {
        self.col(j)[self.k..]
            .iter()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt()
    }
    /// Eliminates column `j` (a Householder reflection on rows k..), applying
    /// it to the columns in `rest`; returns |R_kk|.
    fn eliminate(&mut self, j: usize, rest: &[usize]) -> f64 {
        let (m, k) = (self.rows, self.k);
        let alpha = self.residual(j);
        let mut v = self.col(j)[k..].to_vec();
        let sign = if v[0] >= 0.0 { 1.0 } else { -1.0 };
        v[0] += sign * alpha;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        if vv > 0.0 {
            for &c in rest {
                let col = &mut self.a[c * m + k..(c + 1) * m];
                let d: f64 = col.iter().zip(&v).map(|(a, b)| a * b).sum();
                let f = 2.0 * d / vv;
                for (a, b) in col.iter_mut().zip(&v) {
                    *a -= f * b;
                }
            }
        }
        self.k += 1;
        alpha
    }
}

/// The identifiable ε of `robot` (see the module doc).
pub fn identifiable_errors(
    robot: &Robot,
    opts: &IdentifiableOptions,
) -> Result<IdentifiableSet, IdentifiableError> {
    let mat = identification_matrix(robot, opts)?;
    let n = robot.dof();
    let ne = mat.candidates.len();
    let nb = mat.names.len() - ne;
    let mut qr = Qr {
        rows: mat.rows,
        a: mat.data.clone(),
        k: 0,
    };
    // 1. The 27 always-estimated columns, column-pivoted; project them out.
    let mut left: Vec<usize> = (0..nb).collect();
    let mut base_r00 = 0.0;
    let mut base_min_pivot = f64::INFINITY;
    while !left.is_empty() {
        let c = qr.take_largest(&mut left);
        let rest: Vec<usize> = left.iter().copied().chain(nb..nb + ne).collect();
        let r = qr.eliminate(c, &rest);
        if base_r00 == 0.0 {
            base_r00 = r;
        }
        let ratio = if base_r00 > 0.0 { r / base_r00 } else { 0.0 };
        if ratio.is_nan() || ratio <= opts.tolerance {
            return Err(IdentifiableError::BaseRankDeficient {
                name: mat.names[c].clone(),
                ratio,
            });
        }
        base_min_pivot = base_min_pivot.min(ratio);
    }
    let projected = qr.a.clone();
    let k0 = qr.k;
    // 2. Column-pivoted QR of the projected candidates: rank and gap.
    let mut left: Vec<usize> = (nb..nb + ne).collect();
    let mut pivots = Vec::with_capacity(ne);
    let mut r00 = 0.0;
    while !left.is_empty() {
        let c = qr.take_largest(&mut left);
        let r = qr.eliminate(c, &left);
        if r00 == 0.0 {
            r00 = r;
        }
        pivots.push((
            mat.candidates[c - nb],
            if r00 > 0.0 { r / r00 } else { 0.0 },
        ));
    }
    let rank = pivots.iter().take_while(|p| p.1 > opts.tolerance).count();
    let gap = match (rank, pivots.get(rank)) {
        (0, _) => f64::NAN,
        (_, None) => f64::INFINITY,
        (r, Some(next)) => pivots[r - 1].1 / next.1,
    };
    // 3. Ordered selection.
    qr.a = projected;
    qr.k = k0;
    let col_of = |e: &ErrorIndex| nb + mat.candidates.iter().position(|c| c == e).unwrap();
    let order: Vec<usize> = preference_order(n).iter().map(col_of).collect();
    let mut kept = Vec::new();
    let mut dropped_cols = Vec::new();
    let mut chosen_min_residual = f64::INFINITY;
    for (p, &c) in order.iter().enumerate() {
        let res = qr.residual(c) / r00;
        if res > opts.tolerance {
            chosen_min_residual = chosen_min_residual.min(res);
            let rest: Vec<usize> = order[p + 1..]
                .iter()
                .chain(&dropped_cols)
                .copied()
                .collect();
            qr.eliminate(c, &rest);
            kept.push(mat.candidates[c - nb]);
        } else {
            dropped_cols.push(c);
        }
    }
    if kept.len() != rank {
        return Err(IdentifiableError::RankAmbiguous {
            pivoted: rank,
            ordered: kept.len(),
        });
    }
    let dropped = dropped_cols
        .iter()
        .map(|&c| (mat.candidates[c - nb], qr.residual(c) / r00))
        .collect();
    kept.sort();
    Ok(IdentifiableSet {
        errors: kept,
        rank,
        pivots,
        gap,
        base_min_pivot,
        chosen_min_residual,
        dropped,
    })
}
