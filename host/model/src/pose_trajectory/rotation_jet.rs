//! B's rotation kinematics as jets in only the 13 variables that enter
//! them (MODEL.md §10 with §4's t + τ): the time offset (variable
//! [`ROT_TIME`]) and the 12 local rotation parameters of the 4 control
//! points at t (variable [`rot_var`]`(j, c)`); the position part, linear in
//! its control points, as plain values (p̈, p⃛ and the weights N̈_j).
//! The same recursion as [`PoseSpline::kinematics_jet`], whose 30-variable
//! jets carry 17 zero gradients here (a test compares the two), except
//! that R(t) is not carried as a jet matrix: what the IMU needs of it is
//! the specific force of B's origin in B, Rᵀ(p̈ − g), carried as a jet
//! vector through the same products (Rᵀu = A_3ᵀA_2ᵀA_1ᵀR_iᵀu), and Exp is
//! Rodrigues' formula with [w]×² = wwᵀ − |w|²I.
//! The seeds of a segment (R_i and the differences d_j with their
//! Jacobians) are made once per segment ([`RotationSeeds`]).

use super::*;

/// Number of jet variables: time offset + 12 rotation parameters.
pub(crate) const ROT_VARS: usize = 1 + LOCAL;
/// The time-offset variable.
pub(crate) const ROT_TIME: usize = 0;

/// The variable of component c of the rotation parameter of control point
/// `first + j`.
pub(crate) const fn rot_var(j: usize, c: usize) -> usize {
    1 + 3 * j + c
}

type J13 = Jet<ROT_VARS>;

/// The seeds of one segment (first control point `first`): R_first and
/// d_j as jets in the rotation variables.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RotationSeeds {
    first: usize,
    r0: M3<J13>,
    d: [V3<J13>; DEGREE],
}

/// B's kinematics at one t ([`PoseSpline::rotation_jet`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RotationJet {
    /// Index of the first of the 4 control points at t.
    pub first: usize,
    /// R(t) (value).
    pub r: M3,
    /// Rᵀ(p̈ − g): the specific force of B's origin in B (m/s²).
    pub f: V3<J13>,
    /// Body rate ω (rad/s).
    pub omega: V3<J13>,
    /// Body angular acceleration ω̇ (rad/s²).
    pub alpha: V3<J13>,
    /// N̈_{first+j}(t): ∂p̈/∂c_{first+j} = N̈_j·I.
    pub ddn: [f64; ORDER],
}

impl PoseSpline {
    /// The seeds of the segment whose first control point is `first`.
    ///
    /// # Panics
    /// If `first + 3` is not a control point.
    pub(crate) fn rotation_seeds(&self, first: usize) -> RotationSeeds {
        let r_i = &self.rotation[first];
        let r0: M3<J13> = seeded_rotation(r_i, |c| rot_var(0, c));
        let d_val = self.differences(first);
        let d = std::array::from_fn(|j| {
            let mut dj = d_val[j].map(J13::cst);
            let (jl, jr) = (left_jacobian_inv(d_val[j]), right_jacobian_inv(d_val[j]));
            for r in 0..3 {
                for c in 0..3 {
                    dj[r].d[rot_var(j, c)] = -jl[r][c];
                    dj[r].d[rot_var(j + 1, c)] = jr[r][c];
                }
            }
            dj
        });
        RotationSeeds { first, r0, d }
    }

    /// B's kinematics at `t` with gravity `g` (module doc); `seeds` is
    /// reused when it is of t's segment, else replaced.
    pub(crate) fn rotation_jet(
        &self,
        t: f64,
        g: V3,
        seeds: &mut Option<RotationSeeds>,
    ) -> Result<RotationJet, SplineError> {
        let mut basis = Basis::default();
        self.knots().basis(t, &mut basis)?;
        let i = basis.first;
        let b = &basis.d;
        let s = match seeds {
            Some(s) if s.first == i => s,
            _ => seeds.insert(self.rotation_seeds(i)),
        };
        let lam: [[f64; DEGREE]; 4] =
            std::array::from_fn(|k| std::array::from_fn(|j| b[k][j + 1..ORDER].iter().sum()));
        let lam_s: [[J13; DEGREE]; 3] = std::array::from_fn(|k| {
            std::array::from_fn(|j| {
                let mut l = J13::cst(lam[k][j]);
                l.d[ROT_TIME] = lam[k + 1][j];
                l
            })
        });
        let (mut a, mut jerk) = ([0.0; 3], [0.0f64; 3]);
        for j in 0..ORDER {
            let c = self.position_control_point(i + j);
            a = add(a, scale(c, b[2][j]));
            jerk = add(jerk, scale(c, b[3][j]));
        }
        let mut u = sub(a, g).map(J13::cst);
        for c in 0..3 {
            u[c].d[ROT_TIME] = jerk[c];
        }
        let (r, omega, alpha, f) = recursion(s, &lam_s, u);
        Ok(RotationJet {
            first: i,
            r,
            f,
            omega,
            alpha,
            ddn: std::array::from_fn(|j| b[2][j]),
        })
    }
}

/// Exp by Rodrigues with [w]×² = wwᵀ − θ²I (as [`so3::exp_s`], series
/// below the same small angle).
fn exp_jet(w: V3<J13>) -> M3<J13> {
    let th2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let (a, b) = if th2.v < 1e-8 {
        (
            J13::cst(1.0) - th2 * (1.0 / 6.0) + th2 * th2 * (1.0 / 120.0),
            J13::cst(0.5) - th2 * (1.0 / 24.0) + th2 * th2 * (1.0 / 720.0),
        )
    } else {
        let th = th2.sqrt();
        let (s, c) = th.sin_cos();
        (s / th, (J13::cst(1.0) - c) / th2)
    };
    let bw = [b * w[0], b * w[1], b * w[2]];
    let aw = [a * w[0], a * w[1], a * w[2]];
    let (b01, b02, b12) = (bw[0] * w[1], bw[0] * w[2], bw[1] * w[2]);
    let one_bt = J13::cst(1.0) - b * th2;
    [
        [one_bt + bw[0] * w[0], b01 - aw[2], b02 + aw[1]],
        [b01 + aw[2], one_bt + bw[1] * w[1], b12 - aw[0]],
        [b02 - aw[1], b12 + aw[0], one_bt + bw[2] * w[2]],
    ]
}

/// The recursion of the parent module's doc (ω, ω̇) and Rᵀu, with R's value.
fn recursion(
    s: &RotationSeeds,
    lam: &[[J13; DEGREE]; 3],
    u: V3<J13>,
) -> (M3, V3<J13>, V3<J13>, V3<J13>) {
    let mut v = mul_mtv(&s.r0, u);
    let mut r = s.r0.map(|row| row.map(|x| x.v));
    let (mut w, mut al) = ([J13::cst(0.0); 3], [J13::cst(0.0); 3]);
    for j in 0..DEGREE {
        let a = exp_jet(scale(s.d[j], lam[0][j]));
        let wd = scale(s.d[j], lam[1][j]);
        let dd = scale(s.d[j], lam[2][j]);
        if j == 0 {
            // ω = ω̇ = 0 before the first factor
            al = dd;
            w = wd;
        } else {
            let at_w = mul_mtv(&a, w);
            al = add(add(mul_mtv(&a, al), cross(at_w, wd)), dd);
            w = add(at_w, wd);
        }
        v = mul_mtv(&a, v);
        r = mul_mm(&r, &a.map(|row| row.map(|x| x.v)));
    }
    (r, w, al, v)
}
