//! The pose spline with the evaluation time and the control points as
//! forward-mode jet variables (MODEL.md §10 with §4's t_i + τ): what the
//! Jacobian with respect to τ needs — the jerk p⃛ and the body angular
//! acceleration's rate ω̈ — comes exactly from the basis's third
//! derivative, by seeding each cumulative basis value λ_j^{(k)}(t) with
//! its time derivative λ_j^{(k+1)}(t).

use super::*;

/// Body-frame kinematics of B as jets: R, p̈, ω, ω̇ (module doc).
#[derive(Clone, Copy, Debug)]
pub struct KinematicsJet<const N: usize> {
    /// Index of the first of the 4 control points at t.
    pub first: usize,
    /// R(t).
    pub r: M3<Jet<N>>,
    /// p̈(t), B's origin, in W (m/s²).
    pub a: V3<Jet<N>>,
    /// Body rate ω (rad/s).
    pub omega: V3<Jet<N>>,
    /// Body angular acceleration ω̇ (rad/s²).
    pub alpha: V3<Jet<N>>,
}

/// The IMU point's R, ω (body) and a_n as jets ([`PoseSpline::imu_point_jet`]).
#[derive(Clone, Copy, Debug)]
pub struct ImuPointJet<const N: usize> {
    /// Index of the first of the 4 control points at t.
    pub first: usize,
    /// R(t).
    pub r: M3<Jet<N>>,
    /// ω = Rᵀ ω_n (rad/s).
    pub omega: V3<Jet<N>>,
    /// a_n of p + R p_I (m/s²).
    pub a_n: V3<Jet<N>>,
}

/// The recursion of the parent module's doc, with jet λ's.
pub(super) fn rot_kinematics_s<S: Scalar>(
    r0: &M3<S>,
    d: &[V3<S>; DEGREE],
    lam: &[[S; DEGREE]; 3],
) -> RotKin<S> {
    let zero = [S::cst(0.0); 3];
    let (mut r, mut w, mut al) = (*r0, zero, zero);
    for j in 0..DEGREE {
        let a = exp_s(scale(d[j], lam[0][j]));
        let wd = scale(d[j], lam[1][j]);
        let at_w = mul_mtv(&a, w);
        al = add(
            add(mul_mtv(&a, al), cross(at_w, wd)),
            scale(d[j], lam[2][j]),
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

/// A jet with value `v` and derivative `dv` along variable `var` (if any).
fn seeded<const N: usize>(v: f64, var: Option<usize>, dv: f64) -> Jet<N> {
    let mut j = Jet::<N>::cst(v);
    if let Some(k) = var {
        j.d[k] = dv;
    }
    j
}

impl PoseSpline {
    /// B's kinematics at `t` as jets in N variables: the time offset dt
    /// (t + dt, dt = 0) is variable `time_var`; the 4 control points at t
    /// are variables `ctrl_var + 6j + c` (position, c_k + Δc) and
    /// `ctrl_var + 6j + 3 + c` (rotation, R_k·Exp(δ)); `None` leaves them
    /// constant.
    ///
    /// # Panics
    /// If a variable index is ≥ N (`ctrl_var + 24 > N`).
    pub fn kinematics_jet<const N: usize>(
        &self,
        t: f64,
        time_var: Option<usize>,
        ctrl_var: Option<usize>,
    ) -> Result<KinematicsJet<N>, SplineError> {
        let mut basis = Basis::default();
        self.knots().basis(t, &mut basis)?;
        let i = basis.first;
        let b = &basis.d;
        // λ_j^{(k)} for j = 1..3, k = 0..3.
        let lam: [[f64; DEGREE]; 4] =
            std::array::from_fn(|k| std::array::from_fn(|j| b[k][j + 1..ORDER].iter().sum()));
        let lam_s: [[Jet<N>; DEGREE]; 3] = std::array::from_fn(|k| {
            std::array::from_fn(|j| seeded(lam[k][j], time_var, lam[k + 1][j]))
        });
        // p̈ = Σ N̈_j c_j, its time derivative Σ N⃛_j c_j.
        let mut a = [Jet::<N>::cst(0.0); 3];
        for j in 0..ORDER {
            let c = self.position_control_point(i + j);
            let w = seeded::<N>(b[2][j], time_var, b[3][j]);
            for r in 0..3 {
                let cj = seeded::<N>(c[r], ctrl_var.map(|v| v + 6 * j + r), 1.0);
                a[r] += w * cj;
            }
        }
        let r_i = &self.rotation[i];
        let r0: M3<Jet<N>> = match ctrl_var {
            Some(v) => seeded_rotation(r_i, |c| v + 3 + c),
            None => r_i.map(|row| row.map(Jet::cst)),
        };
        let d_val = self.differences(i);
        let d: [V3<Jet<N>>; DEGREE] = std::array::from_fn(|j| {
            let mut dj = d_val[j].map(Jet::cst);
            if let Some(v) = ctrl_var {
                let (jl, jr) = (left_jacobian_inv(d_val[j]), right_jacobian_inv(d_val[j]));
                for r in 0..3 {
                    for c in 0..3 {
                        dj[r].d[v + 6 * j + 3 + c] = -jl[r][c];
                        dj[r].d[v + 6 * (j + 1) + 3 + c] = jr[r][c];
                    }
                }
            }
            dj
        });
        let rk = rot_kinematics_s(&r0, &d, &lam_s);
        Ok(KinematicsJet {
            first: i,
            r: rk.r,
            a,
            omega: rk.omega,
            alpha: rk.alpha,
        })
    }

    /// The IMU point p + R·p_I (p_I given as jets) at `t` as jets (variables
    /// as [`Self::kinematics_jet`]): a_n = p̈ + α_n × (R p_I) + ω_n × (ω_n × (R p_I)).
    pub fn imu_point_jet<const N: usize>(
        &self,
        t: f64,
        p_imu: V3<Jet<N>>,
        time_var: Option<usize>,
        ctrl_var: Option<usize>,
    ) -> Result<ImuPointJet<N>, SplineError> {
        let k = self.kinematics_jet::<N>(t, time_var, ctrl_var)?;
        let rp = mul_mv(&k.r, p_imu);
        let (w_n, al_n) = (mul_mv(&k.r, k.omega), mul_mv(&k.r, k.alpha));
        let a_n = add(add(k.a, cross(al_n, rp)), cross(w_n, cross(w_n, rp)));
        Ok(ImuPointJet {
            first: k.first,
            r: k.r,
            omega: k.omega,
            a_n,
        })
    }

    /// The jerk p⃛(t) (m/s³, W) and the body angular acceleration's rate
    /// ω̈(t) (rad/s³, B), exact (module doc).
    pub fn jerk_and_omega_ddot(&self, t: f64) -> Result<(V3, V3), SplineError> {
        let k = self.kinematics_jet::<1>(t, Some(0), None)?;
        Ok((k.a.map(|x| x.d[0]), k.alpha.map(|x| x.d[0])))
    }
}
