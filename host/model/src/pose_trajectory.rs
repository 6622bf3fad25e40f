//! The continuous-time pose of a posed body B in the world W (docs MODEL.md
//! §10: sessions with tool poses): position p(t) ∈ R³ and orientation
//! R(t) ∈ SO(3), R mapping B-frame coordinates into W, with the kinematics
//! §2–§4 need (ω_n, ω = Rᵀω_n, α_n, v, a_n, and those of the IMU point
//! p(t) + R(t)·p_I) and exact Jacobians with respect to the control points.
//!
//! Both parts share one clamped cubic knot vector with uniform interior knots
//! ([`Knots::uniform`], degree 3) and its m basis functions N_k:
//!
//! * position: the ordinary B-spline p(t) = Σ_k N_k(t) c_k (a 3-dimensional
//!   [`Spline`]);
//! * rotation: the cumulative B-spline on SO(3) (Kim, Kim & Shin 1995;
//!   Sommer et al. 2020, "Efficient derivative computation for cumulative
//!   B-splines on Lie groups", the cumulative form of their §3; Kalibr)
//!   R(t) = R_i · Π_{j=1..3} Exp(λ_j(t) d_j),  d_j = Log(R_{i+j−1}ᵀ R_{i+j}),
//!   where i is the first of the 4 control points non-zero at t and
//!   λ_j = Σ_{l≥j} N_{i+l} the cumulative basis (λ_0 = 1 by partition of
//!   unity; on clamped knots this is the general form, and R(t0) = R_0,
//!   R(t1) = R_{m−1}).
//!
//! Rotation control points are stored as rotation matrices R_k. Their local
//! parameterisation, used by every Jacobian here, is the right (body-frame)
//! perturbation R_k ← R_k·Exp(δ_k); position control points are perturbed
//! additively, c_k ← c_k + Δc_k. A Jacobian ([`Jac3x12`]) has one column per
//! local parameter of the 4 control points at t: column 3j + c is component c
//! of control point `first + j`.
//!
//! Derivatives of R(t) follow Sommer et al.'s recursive time derivatives
//! (their ω and ω̇ recursions for right-multiplied cumulative splines), here
//! in the body frame: with A_j = Exp(λ_j d_j), ω⁽⁰⁾ = ω̇⁽⁰⁾ = 0,
//!   ω⁽ʲ⁾ = A_jᵀ ω⁽ʲ⁻¹⁾ + λ̇_j d_j,
//!   ω̇⁽ʲ⁾ = A_jᵀ ω̇⁽ʲ⁻¹⁾ + (A_jᵀ ω⁽ʲ⁻¹⁾) × (λ̇_j d_j) + λ̈_j d_j,
//! so that Rᵀ Ṙ = [ω⁽³⁾]× (body rate ω), ω_n = R ω and α_n = ω̇_n = R ω̇⁽³⁾.
//! Their Jacobians are exact by forward-mode jets ([`Jet`]) seeded with
//! ∂d_j/∂δ_{i+j} = J_r⁻¹(d_j), ∂d_j/∂δ_{i+j−1} = −J_l⁻¹(d_j) and
//! ∂R_i/∂δ_i = R_i·hat(e_c).
//!
//! # Example
//!
//! A body spinning at 1.5 rad/s about z, sampled at 100 Hz for 2 s, fitted
//! with knots every 0.1 s; the IMU 0.2 m off the axis feels −ω²r.
//!
//! ```
//! use robimu_model::PoseSpline;
//!
//! let w = 1.5;
//! let times: Vec<f64> = (0..=200).map(|k| k as f64 * 0.01).collect();
//! let positions = vec![[0.0; 3]; times.len()];
//! let quats: Vec<[f64; 4]> = times
//!     .iter()
//!     .map(|t| [(0.5 * w * t).cos(), 0.0, 0.0, (0.5 * w * t).sin()])
//!     .collect();
//! let spline = PoseSpline::fit(&times, &positions, &quats, 0.1)?;
//! let imu = spline.imu_point(1.0, [0.2, 0.0, 0.0])?;
//! assert!((imu.omega[2] - w).abs() < 1e-9);
//! let a = (imu.a_n[0].powi(2) + imu.a_n[1].powi(2)).sqrt();
//! assert!((a - w * w * 0.2).abs() < 1e-9, "|a_n| = {a}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::geom::{
    add, cross, log_so3, matrix_from_quat, mul_mm, mul_mtv, mul_mv, scale, sub, transpose, M3, V3,
};
use crate::jet::{Jet, Scalar};
use crate::spline::{Basis, Knots, Spline, SplineError};

mod fit;
mod rotation_jet;
pub mod so3;
#[cfg(test)]
mod tests;
mod time_jet;

pub use fit::FitReport;
pub(crate) use rotation_jet::{rot_var, RotationSeeds, ROT_TIME, ROT_VARS};
use so3::{exp_s, left_jacobian_inv, right_jacobian, right_jacobian_inv};
pub use time_jet::{ImuPointJet, KinematicsJet};

/// Degree of both parts of the pose spline (cubic).
pub const DEGREE: usize = 3;
/// Control points that influence one time (degree + 1).
pub const ORDER: usize = DEGREE + 1;
/// Local parameters of the control points at one time, per part (4 × 3).
pub(crate) const LOCAL: usize = 3 * ORDER;
/// A 3×12 Jacobian: row r is the output's component r; column 3j + c is
/// component c of the local parameter of control point `first + j`.
pub type Jac3x12 = [[f64; LOCAL]; 3];

type J12 = Jet<LOCAL>;

/// R_i as a jet in its right perturbation δ (R_i Exp(δ), ∂R/∂δ_c =
/// R_i [e_c]×), δ_c being the jet's variable `var(c)`.
fn seeded_rotation<const N: usize>(r_i: &M3, var: impl Fn(usize) -> usize) -> M3<Jet<N>> {
    let mut r0: M3<Jet<N>> = r_i.map(|row| row.map(Jet::cst));
    for c in 0..3 {
        let mut e = [0.0; 3];
        e[c] = 1.0;
        let dr = mul_mm(r_i, &so3::hat(e));
        for (row, drow) in r0.iter_mut().zip(&dr) {
            for (x, dx) in row.iter_mut().zip(drow) {
                x.d[var(c)] = *dx;
            }
        }
    }
    r0
}

/// Why a pose spline could not be built or fitted.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PoseSplineError {
    /// The knots or an evaluation time (see [`SplineError`]).
    #[error(transparent)]
    Spline(#[from] SplineError),
    /// Buffers of different lengths.
    #[error("{what} has {found} entries; expected {expected}")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Given length.
        found: usize,
    },
    /// A sample's time, position or quaternion is not finite, or its
    /// quaternion is (nearly) zero.
    #[error("pose sample {index}: {what} is not finite or not a rotation")]
    BadSample {
        /// Sample index.
        index: usize,
        /// Which part of the sample.
        what: &'static str,
    },
}

/// A continuous-time pose of B in W (see the module doc): a cubic position
/// B-spline and a cumulative cubic B-spline on SO(3) on the same knots.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseSpline {
    position: Spline,
    rotation: Vec<M3>,
}

/// The pose of B in W at one time and its derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseState {
    /// R(t), B-frame coordinates into W.
    pub r: M3,
    /// p(t) (m).
    pub p: V3,
    /// ṗ(t) (m/s).
    pub v: V3,
    /// p̈(t) (m/s²): the world acceleration of B's origin.
    pub a: V3,
    /// World-frame angular velocity ω_n, Ṙ Rᵀ = [ω_n]× (rad/s).
    pub omega_n: V3,
    /// Body-frame angular velocity ω = Rᵀ ω_n, Rᵀ Ṙ = [ω]× (rad/s).
    pub omega: V3,
    /// World-frame angular acceleration α_n = ω̇_n (rad/s²).
    pub alpha_n: V3,
    /// Body-frame angular acceleration α = ω̇ = Rᵀ α_n (rad/s²).
    pub alpha: V3,
}

/// Jacobians of a [`PoseState`] with respect to the control points at t
/// (the module doc's parameterisation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseJacobians {
    /// Index of the first of the 4 control points at t.
    pub first: usize,
    /// ∂p/∂c: N_{first+j}(t)·I blocks.
    pub p: Jac3x12,
    /// ∂ṗ/∂c: Ṅ_{first+j}(t)·I blocks.
    pub v: Jac3x12,
    /// ∂p̈/∂c: N̈_{first+j}(t)·I blocks.
    pub a: Jac3x12,
    /// Rotation: R(t; δ) = R(t)·Exp(J δ) to first order (body-frame).
    pub r: Jac3x12,
    /// ∂ω_n/∂δ.
    pub omega_n: Jac3x12,
    /// ∂ω/∂δ.
    pub omega: Jac3x12,
    /// ∂α_n/∂δ.
    pub alpha_n: Jac3x12,
    /// ∂α/∂δ.
    pub alpha: Jac3x12,
}

/// The kinematics of the IMU point p(t) + R(t)·p_I (MODEL.md §10: the IMU
/// frame has B's orientation; §2 takes ω_n, R and a_n from here).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuPointState {
    /// R(t), the IMU frame's orientation.
    pub r: M3,
    /// Position p + R p_I (m).
    pub p: V3,
    /// Velocity ṗ + ω_n × (R p_I) (m/s).
    pub v: V3,
    /// a_n = p̈ + α_n × (R p_I) + ω_n × (ω_n × (R p_I)) (m/s²).
    pub a_n: V3,
    /// ω_n (rad/s).
    pub omega_n: V3,
    /// ω = Rᵀ ω_n (rad/s), what a gyroscope in the IMU frame senses.
    pub omega: V3,
}

/// Jacobians of an [`ImuPointState`]. With respect to the position control
/// points, ∂p, ∂v, ∂a_n are N_{first+j}^{(k)}(t)·I blocks, as
/// [`PoseJacobians::p`], `v`, `a`; those are repeated here.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuPointJacobians {
    /// Index of the first of the 4 control points at t.
    pub first: usize,
    /// ∂p/∂c.
    pub p_position: Jac3x12,
    /// ∂v/∂c.
    pub v_position: Jac3x12,
    /// ∂a_n/∂c.
    pub a_n_position: Jac3x12,
    /// Rotation, as [`PoseJacobians::r`].
    pub r: Jac3x12,
    /// ∂p/∂δ.
    pub p_rotation: Jac3x12,
    /// ∂v/∂δ.
    pub v_rotation: Jac3x12,
    /// ∂a_n/∂δ.
    pub a_n_rotation: Jac3x12,
    /// ∂ω_n/∂δ.
    pub omega_n: Jac3x12,
    /// ∂ω/∂δ.
    pub omega: Jac3x12,
}

/// The residual of one pose sample (t, p̃, q̃) (MODEL.md §10: p̃ = p(t) + n_p,
/// R̃ = R(t)·Exp(n_r)) and its Jacobians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseResidual {
    /// Index of the first of the 4 control points at t.
    pub first: usize,
    /// e_p = p(t) − p̃ (m), an estimate of −n_p.
    pub e_p: V3,
    /// e_r = Log(R̃ᵀ R(t)) (rad), an estimate of −n_r.
    pub e_r: V3,
    /// ∂e_p/∂c (N_{first+j}(t)·I blocks).
    pub e_p_position: Jac3x12,
    /// ∂e_r/∂δ = J_r⁻¹(e_r)·[`PoseJacobians::r`].
    pub e_r_rotation: Jac3x12,
}

/// The basis at one t: the first control point, the values and first two
/// derivatives of the 4 non-zero N (`b[k][j]` = N_{first+j}^{(k)}) and of
/// the cumulative λ_1..λ_3 (`lam[k][j−1]`).
struct Local {
    first: usize,
    b: [[f64; ORDER]; 3],
    lam: [[f64; DEGREE]; 3],
}

/// Body-frame rotation kinematics at one t: R, ω, ω̇.
struct RotKin<S> {
    r: M3<S>,
    omega: V3<S>,
    alpha: V3<S>,
}

/// The recursions of the module doc: R(t), ω, ω̇ from the anchor R_i, the
/// differences d_j and the cumulative basis `lam` (value, λ̇, λ̈).
fn rot_kinematics<S: Scalar>(
    r0: &M3<S>,
    d: &[V3<S>; DEGREE],
    lam: &[[f64; DEGREE]; 3],
) -> RotKin<S> {
    let zero = [S::cst(0.0); 3];
    let (mut r, mut w, mut al) = (*r0, zero, zero);
    for j in 0..DEGREE {
        let a = exp_s(scale(d[j], S::cst(lam[0][j])));
        let wd = scale(d[j], S::cst(lam[1][j]));
        let at_w = mul_mtv(&a, w);
        al = add(
            add(mul_mtv(&a, al), cross(at_w, wd)),
            scale(d[j], S::cst(lam[2][j])),
        );
        w = add(at_w, wd);
        r = mul_mm(&r, &a);
    }
    RotKin {
        r,
        omega: w,
        alpha: al,
    }
}

/// The values and gradients of a jet 3-vector: (value, 3×12 Jacobian).
fn split(v: V3<J12>) -> (V3, Jac3x12) {
    (v.map(|x| x.v), v.map(|x| x.d))
}

/// The body-frame Jacobian of a rotation jet: column k = vee(Rᵀ ∂R/∂δ_k).
fn rotation_jacobian(r: &M3<J12>) -> (M3, Jac3x12) {
    let rv = r.map(|row| row.map(|x| x.v));
    let mut jac = [[0.0; LOCAL]; 3];
    for k in 0..LOCAL {
        let dr = r.map(|row| row.map(|x| x.d[k]));
        let w = so3::vee(&mul_mm(&transpose(&rv), &dr));
        for c in 0..3 {
            jac[c][k] = w[c];
        }
    }
    (rv, jac)
}

/// `N_{first+j}^{(k)}(t)·I` blocks of one basis row.
fn weight_blocks(w: &[f64; ORDER]) -> Jac3x12 {
    let mut jac = [[0.0; LOCAL]; 3];
    for j in 0..ORDER {
        for c in 0..3 {
            jac[c][3 * j + c] = w[j];
        }
    }
    jac
}

/// `M · J` for a 3×3 M and a 3×12 J.
fn mul_mj(m: &M3, j: &Jac3x12) -> Jac3x12 {
    let mut out = [[0.0; LOCAL]; 3];
    for r in 0..3 {
        for k in 0..LOCAL {
            out[r][k] = m[r][0] * j[0][k] + m[r][1] * j[1][k] + m[r][2] * j[2][k];
        }
    }
    out
}

/// A constant jet 3-vector.
fn cst3(v: V3) -> V3<J12> {
    v.map(J12::cst)
}

impl PoseSpline {
    /// A pose spline from its knots (degree 3) and control points (one
    /// position c_k and one rotation R_k per basis function; each R_k is
    /// re-orthonormalised).
    pub fn new(knots: Knots, positions: &[V3], rotations: &[M3]) -> Result<Self, PoseSplineError> {
        if knots.degree() != DEGREE {
            return Err(SplineError::BadDegree(knots.degree()).into());
        }
        let m = knots.num_coeffs();
        for (what, found) in [
            ("positions", positions.len()),
            ("rotations", rotations.len()),
        ] {
            if found != m {
                return Err(PoseSplineError::LengthMismatch {
                    what,
                    expected: m,
                    found,
                });
            }
        }
        let coeffs = positions.iter().flatten().copied().collect();
        Ok(Self {
            position: Spline::new(knots, 3, coeffs)?,
            rotation: rotations
                .iter()
                .map(|r| matrix_from_quat(crate::geom::quat_from_matrix(r)))
                .collect(),
        })
    }

    /// The knots (clamped, cubic, shared by position and rotation).
    pub fn knots(&self) -> &Knots {
        self.position.knots()
    }
    /// Number of control points m (of each part).
    pub fn num_control_points(&self) -> usize {
        self.rotation.len()
    }
    /// The position part as a 3-dimensional [`Spline`] (`coeffs[3k + c]`).
    pub fn position_spline(&self) -> &Spline {
        &self.position
    }
    /// Position control point c_k.
    pub fn position_control_point(&self, k: usize) -> V3 {
        let c = &self.position.coeffs()[3 * k..3 * k + 3];
        [c[0], c[1], c[2]]
    }
    /// The rotation control points R_k.
    pub fn rotation_control_points(&self) -> &[M3] {
        &self.rotation
    }

    /// Apply the local update of control point k: c_k ← c_k + dc,
    /// R_k ← R_k·Exp(dr) (the parameterisation of every Jacobian here).
    ///
    /// # Panics
    /// If k ≥ [`Self::num_control_points`].
    pub fn perturb(&mut self, k: usize, dc: V3, dr: V3) {
        for c in 0..3 {
            self.position.coeffs_mut()[3 * k + c] += dc[c];
        }
        self.rotation[k] = mul_mm(&self.rotation[k], &exp_s(dr));
    }

    /// The basis at t.
    fn local(&self, t: f64) -> Result<Local, SplineError> {
        let mut basis = Basis::default();
        self.knots().basis(t, &mut basis)?;
        let (mut b, mut lam) = ([[0.0; ORDER]; 3], [[0.0; DEGREE]; 3]);
        for k in 0..3 {
            b[k].copy_from_slice(&basis.d[k][..ORDER]);
            for j in 1..ORDER {
                lam[k][j - 1] = b[k][j..].iter().sum();
            }
        }
        Ok(Local {
            first: basis.first,
            b,
            lam,
        })
    }

    /// d_j = Log(R_{i+j−1}ᵀ R_{i+j}), j = 1..3, for i = `first`.
    fn differences(&self, first: usize) -> [V3; DEGREE] {
        std::array::from_fn(|j| {
            let (a, b) = (&self.rotation[first + j], &self.rotation[first + j + 1]);
            log_so3(&mul_mm(&transpose(a), b))
        })
    }

    /// p, ṗ, p̈ at the basis `loc`.
    fn position_rows(&self, loc: &Local) -> [V3; 3] {
        std::array::from_fn(|k| {
            (0..ORDER).fold([0.0; 3], |acc, j| {
                add(
                    acc,
                    scale(self.position_control_point(loc.first + j), loc.b[k][j]),
                )
            })
        })
    }

    /// The rotation kinematics as jets in the 12 local rotation parameters
    /// at `loc` (the seeds of the module doc).
    fn rot_jets(&self, loc: &Local) -> RotKin<J12> {
        let i = loc.first;
        let r_i = &self.rotation[i];
        let r0: M3<J12> = seeded_rotation(r_i, |c| c);
        let d_val = self.differences(i);
        let d: [V3<J12>; DEGREE] = std::array::from_fn(|j| {
            let (jl, jr) = (left_jacobian_inv(d_val[j]), right_jacobian_inv(d_val[j]));
            let mut dj = cst3(d_val[j]);
            for r in 0..3 {
                for c in 0..3 {
                    dj[r].d[3 * j + c] = -jl[r][c];
                    dj[r].d[3 * (j + 1) + c] = jr[r][c];
                }
            }
            dj
        });
        rot_kinematics(&r0, &d, &loc.lam)
    }

    /// R(t) and its body-frame Jacobian ([`PoseJacobians::r`]) at `loc`
    /// without jets: with R ← R·A_j, A_j = Exp(λ_j d_j), a perturbation ε of
    /// R becomes A_jᵀε, and A_j's own is J_r(λ_j d_j)·λ_j·∂d_j (∂d_j/∂δ the
    /// seeds of the module doc), so J ← A_jᵀJ + λ_j J_r(λ_j d_j) ∂d_j/∂δ
    /// from J = [I 0 0 0].
    fn rotation_and_jacobian(&self, loc: &Local) -> (M3, Jac3x12) {
        let i = loc.first;
        let mut r = self.rotation[i];
        let mut jac = [[0.0; LOCAL]; 3];
        for c in 0..3 {
            jac[c][c] = 1.0;
        }
        let d = self.differences(i);
        for j in 0..DEGREE {
            let phi = scale(d[j], loc.lam[0][j]);
            let a = exp_s(phi);
            let m = right_jacobian(phi).map(|row| row.map(|v| v * loc.lam[0][j]));
            let ml = mul_mm(&m, &left_jacobian_inv(d[j]));
            let mr = mul_mm(&m, &right_jacobian_inv(d[j]));
            jac = mul_mj(&transpose(&a), &jac);
            for row in 0..3 {
                for c in 0..3 {
                    jac[row][3 * j + c] -= ml[row][c];
                    jac[row][3 * (j + 1) + c] += mr[row][c];
                }
            }
            r = mul_mm(&r, &a);
        }
        (r, jac)
    }

    /// R(t) alone.
    pub fn rotation(&self, t: f64) -> Result<M3, SplineError> {
        let loc = self.local(t)?;
        let d = self.differences(loc.first);
        let mut r = self.rotation[loc.first];
        for j in 0..DEGREE {
            r = mul_mm(&r, &exp_s(scale(d[j], loc.lam[0][j])));
        }
        Ok(r)
    }

    /// The pose and its derivatives at t ∈ [t0, t1].
    pub fn evaluate(&self, t: f64) -> Result<PoseState, SplineError> {
        let loc = self.local(t)?;
        let d = self.differences(loc.first);
        let rk = rot_kinematics(&self.rotation[loc.first], &d, &loc.lam);
        let [p, v, a] = self.position_rows(&loc);
        Ok(PoseState {
            r: rk.r,
            p,
            v,
            a,
            omega_n: mul_mv(&rk.r, rk.omega),
            omega: rk.omega,
            alpha_n: mul_mv(&rk.r, rk.alpha),
            alpha: rk.alpha,
        })
    }

    /// [`Self::evaluate`] and the Jacobians with respect to the 4 + 4
    /// control points at t.
    pub fn jacobians(&self, t: f64) -> Result<(PoseState, PoseJacobians), SplineError> {
        let loc = self.local(t)?;
        let rk = self.rot_jets(&loc);
        let (r, jr) = rotation_jacobian(&rk.r);
        let (omega, j_omega) = split(rk.omega);
        let (alpha, j_alpha) = split(rk.alpha);
        let (omega_n, j_omega_n) = split(mul_mv(&rk.r, rk.omega));
        let (alpha_n, j_alpha_n) = split(mul_mv(&rk.r, rk.alpha));
        let [p, v, a] = self.position_rows(&loc);
        let state = PoseState {
            r,
            p,
            v,
            a,
            omega_n,
            omega,
            alpha_n,
            alpha,
        };
        let jac = PoseJacobians {
            first: loc.first,
            p: weight_blocks(&loc.b[0]),
            v: weight_blocks(&loc.b[1]),
            a: weight_blocks(&loc.b[2]),
            r: jr,
            omega_n: j_omega_n,
            omega: j_omega,
            alpha_n: j_alpha_n,
            alpha: j_alpha,
        };
        Ok((state, jac))
    }

    /// The IMU point's kinematics at t for the IMU at `p_imu` in B (§10).
    pub fn imu_point(&self, t: f64, p_imu: V3) -> Result<ImuPointState, SplineError> {
        let s = self.evaluate(t)?;
        let rp = mul_mv(&s.r, p_imu);
        let w = s.omega_n;
        Ok(ImuPointState {
            r: s.r,
            p: add(s.p, rp),
            v: add(s.v, cross(w, rp)),
            a_n: add(add(s.a, cross(s.alpha_n, rp)), cross(w, cross(w, rp))),
            omega_n: w,
            omega: s.omega,
        })
    }

    /// [`Self::imu_point`] and its Jacobians with respect to the control points.
    pub fn imu_point_jacobians(
        &self,
        t: f64,
        p_imu: V3,
    ) -> Result<(ImuPointState, ImuPointJacobians), SplineError> {
        let loc = self.local(t)?;
        let rk = self.rot_jets(&loc);
        let (omega_n, alpha_n) = (mul_mv(&rk.r, rk.omega), mul_mv(&rk.r, rk.alpha));
        let rp = mul_mv(&rk.r, cst3(p_imu));
        let [p0, v0, a0] = self.position_rows(&loc);
        let (p, p_rotation) = split(add(cst3(p0), rp));
        let (v, v_rotation) = split(add(cst3(v0), cross(omega_n, rp)));
        let acc = add(cross(alpha_n, rp), cross(omega_n, cross(omega_n, rp)));
        let (a_n, a_n_rotation) = split(add(cst3(a0), acc));
        let (r, jr) = rotation_jacobian(&rk.r);
        let (omega_n, j_omega_n) = split(omega_n);
        let (omega, j_omega) = split(rk.omega);
        let state = ImuPointState {
            r,
            p,
            v,
            a_n,
            omega_n,
            omega,
        };
        let jac = ImuPointJacobians {
            first: loc.first,
            p_position: weight_blocks(&loc.b[0]),
            v_position: weight_blocks(&loc.b[1]),
            a_n_position: weight_blocks(&loc.b[2]),
            r: jr,
            p_rotation,
            v_rotation,
            a_n_rotation,
            omega_n: j_omega_n,
            omega: j_omega,
        };
        Ok((state, jac))
    }

    /// The residual of the pose sample (t, p̃, q̃) (q̃ = [w, x, y, z], either
    /// sign) and its Jacobians (MODEL.md §10).
    pub fn pose_residual(
        &self,
        t: f64,
        p_meas: V3,
        q_meas: [f64; 4],
    ) -> Result<PoseResidual, SplineError> {
        self.pose_residual_r(t, p_meas, &matrix_from_quat(q_meas))
    }

    /// The residual values (e_p, e_r) of [`Self::pose_residual_r`] alone,
    /// without the Jacobians.
    pub fn pose_error_r(&self, t: f64, p_meas: V3, r_meas: &M3) -> Result<(V3, V3), SplineError> {
        let loc = self.local(t)?;
        let d = self.differences(loc.first);
        let mut r = self.rotation[loc.first];
        for j in 0..DEGREE {
            r = mul_mm(&r, &exp_s(scale(d[j], loc.lam[0][j])));
        }
        let [p, _, _] = self.position_rows(&loc);
        Ok((sub(p, p_meas), log_so3(&mul_mm(&transpose(r_meas), &r))))
    }

    /// [`Self::pose_residual`] with the measured rotation as a matrix R̃.
    pub fn pose_residual_r(
        &self,
        t: f64,
        p_meas: V3,
        r_meas: &M3,
    ) -> Result<PoseResidual, SplineError> {
        let loc = self.local(t)?;
        let (r, jr) = self.rotation_and_jacobian(&loc);
        let e_r = log_so3(&mul_mm(&transpose(r_meas), &r));
        let [p, _, _] = self.position_rows(&loc);
        Ok(PoseResidual {
            first: loc.first,
            e_p: sub(p, p_meas),
            e_r,
            e_p_position: weight_blocks(&loc.b[0]),
            e_r_rotation: mul_mj(&right_jacobian_inv(e_r), &jr),
        })
    }
}
