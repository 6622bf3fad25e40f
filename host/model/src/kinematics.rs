//! Forward kinematics with generalized errors (paper §3.1, eq. (1)–(4); docs/model.md §1).
//!
//! ```text
//! T_i(q_i) = Rz(q_i + θ0_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)                  (1)
//! E_i = Trans(ε_i1, ε_i2, ε_i3)·Ry(ε_i4)·Rz(ε_i5)·Rx(ε_i6)          (2)
//! [R p; 0 1] = E_0·T_1·E_1 ⋯ T_n·E_n,   E_0 = I                      (3)
//! ```
//!
//! `eps[i-1]` holds ε_i1..6 of link i = 1..n; E_n is the IMU mount (its rotation
//! ε_n4..6 is 0 in the model, see [`super::params`], but these functions apply
//! whatever they are given). Functions are generic over [`Scalar`], so a
//! [`super::jet::Jet`] gives exact derivatives of any output.

use super::geom::{self, add, cross, scale, sub, zero3, Iso, V3};
use super::jet::Scalar;
use super::robot::{ChainLink, DhLink};
use super::MAX_JOINTS;

/// A revolute joint's link transform as a function of its angle: the DH
/// `T_i(q)` ([`DhLink`]) or `T_i(q)·C_i` ([`ChainLink`]).
pub trait LinkTransform {
    /// The transform at joint angle `q`.
    fn transform<S: Scalar>(&self, q: S) -> Iso<S>;
}

impl LinkTransform for DhLink {
    #[inline(always)]
    fn transform<S: Scalar>(&self, q: S) -> Iso<S> {
        link_transform(self, q)
    }
}

impl LinkTransform for ChainLink {
    #[inline(always)]
    fn transform<S: Scalar>(&self, q: S) -> Iso<S> {
        let t = link_transform(&self.dh, q);
        match &self.fixed {
            None => t,
            Some(c) => t.compose(&Iso {
                r: c.r.map(|row| row.map(S::cst)),
                p: c.p.map(S::cst),
            }),
        }
    }
}

/// Joint position, velocity, acceleration and jerk (q, q̇, q̈, q⃛) at one time;
/// entries beyond the robot's n joints are ignored. With `S` =
/// [`crate::lanes::F64x4`], four samples' states lane by lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JointState<S = f64> {
    /// q (rad).
    pub q: [S; MAX_JOINTS],
    /// q̇ (rad/s).
    pub qd: [S; MAX_JOINTS],
    /// q̈ (rad/s²).
    pub qdd: [S; MAX_JOINTS],
    /// q⃛ (rad/s³), used only for the τ derivative.
    pub qddd: [S; MAX_JOINTS],
}

impl JointState {
    /// From slices of equal length n ≤ [`MAX_JOINTS`].
    ///
    /// # Panics
    /// If the lengths differ or exceed [`MAX_JOINTS`].
    #[track_caller]
    pub fn from_slices(q: &[f64], qd: &[f64], qdd: &[f64], qddd: &[f64]) -> Self {
        let n = q.len();
        assert!(n <= MAX_JOINTS, "at most {MAX_JOINTS} joints");
        assert!(
            qd.len() == n && qdd.len() == n && qddd.len() == n,
            "q, q̇, q̈, q⃛ must have equal lengths"
        );
        let mut s = Self::default();
        s.q[..n].copy_from_slice(q);
        s.qd[..n].copy_from_slice(qd);
        s.qdd[..n].copy_from_slice(qdd);
        s.qddd[..n].copy_from_slice(qddd);
        s
    }
}

/// The DH link transform T_i(q) (eq. (1)).
pub(crate) fn link_transform<S: Scalar>(dh: &DhLink, q: S) -> Iso<S> {
    let (st, ct) = (q + dh.theta0).sin_cos();
    let (sa, ca) = (dh.alpha.sin(), dh.alpha.cos());
    let z = S::cst(0.0);
    Iso {
        r: [
            [ct, -(st * ca), st * sa],
            [st, ct * ca, -(ct * sa)],
            [z, S::cst(sa), S::cst(ca)],
        ],
        p: [ct * dh.a, st * dh.a, S::cst(dh.d)],
    }
}

/// The generalized error transform E_i (eq. (2)).
pub fn error_transform<S: Scalar>(eps: &[S; 6]) -> Iso<S> {
    let r = geom::mul_mm(
        &geom::mul_mm(&geom::rot_y(eps[3]), &geom::rot_z(eps[4])),
        &geom::rot_x(eps[5]),
    );
    Iso {
        r,
        p: [eps[0], eps[1], eps[2]],
    }
}

/// Pose of the IMU frame in the base frame (eq. (3)).
///
/// # Panics
/// If `eps` or `q` do not have one entry per link.
#[track_caller]
pub fn forward_kinematics<S: Scalar, L: LinkTransform>(
    links: &[L],
    eps: &[[S; 6]],
    q: &[S],
) -> Iso<S> {
    assert_eq!(eps.len(), links.len(), "one ε row per link");
    assert_eq!(q.len(), links.len(), "one q per joint");
    let mut f = Iso::identity();
    for ((link, e), &qi) in links.iter().zip(eps).zip(q) {
        f = f.compose(&link.transform(qi)).compose(&error_transform(e));
    }
    f
}

/// Pose and motion of the IMU frame, all in the base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuMotion<S = f64> {
    /// Pose [R p].
    pub pose: Iso<S>,
    /// Angular velocity ω_n (Ṙ Rᵀ = \[ω_n\]×).
    pub omega_n: V3<S>,
    /// Angular acceleration α_n = ω̇_n.
    pub alpha_n: V3<S>,
    /// Linear velocity v_n = ṗ.
    pub v_n: V3<S>,
    /// Linear acceleration a_n = p̈.
    pub a_n: V3<S>,
}

/// Pose, velocity and acceleration of the IMU frame from (q, q̇, q̈) by the
/// Newton recursion of eq. (4): joint i turns about the z axis of the real frame
/// i−1 (after E_{i−1}) through its origin; ρ_i = p_i − p_{i−1}.
///
/// ```text
/// ω_i = ω_{i−1} + z_i q̇_i,   α_i = α_{i−1} + z_i q̈_i + ω_{i−1} × z_i q̇_i
/// v_i = v_{i−1} + ω_i × ρ_i,  a_i = a_{i−1} + α_i × ρ_i + ω_i × (ω_i × ρ_i)
/// ```
///
/// # Panics
/// If `eps`, `q`, `qd` or `qdd` do not have one entry per link.
#[track_caller]
pub(crate) fn imu_motion<S: Scalar, L: LinkTransform>(
    links: &[L],
    eps: &[[S; 6]],
    q: &[S],
    qd: &[S],
    qdd: &[S],
) -> ImuMotion<S> {
    let n = links.len();
    assert_eq!(eps.len(), n, "one ε row per link");
    assert!(
        q.len() == n && qd.len() == n && qdd.len() == n,
        "one q, q̇, q̈ per joint"
    );
    let mut f = Iso::identity();
    let (mut w, mut al, mut v, mut a) = (zero3(), zero3(), zero3(), zero3());
    for i in 0..n {
        let z = geom::col(&f.r, 2);
        let zqd = scale(z, qd[i]);
        al = add(add(al, scale(z, qdd[i])), cross(w, zqd));
        w = add(w, zqd);
        let next = f
            .compose(&links[i].transform(q[i]))
            .compose(&error_transform(&eps[i]));
        let rho = sub(next.p, f.p);
        v = add(v, cross(w, rho));
        a = add(add(a, cross(al, rho)), cross(w, cross(w, rho)));
        f = next;
    }
    ImuMotion {
        pose: f,
        omega_n: w,
        alpha_n: al,
        v_n: v,
        a_n: a,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::Robot;
    use nalgebra::{Matrix4, Rotation3, Translation3, Vector3};
    use std::f64::consts::PI;

    fn dh_nalgebra(dh: &DhLink, q: f64) -> Matrix4<f64> {
        Rotation3::from_axis_angle(&Vector3::z_axis(), q + dh.theta0).to_homogeneous()
            * Translation3::new(0.0, 0.0, dh.d).to_homogeneous()
            * Translation3::new(dh.a, 0.0, 0.0).to_homogeneous()
            * Rotation3::from_axis_angle(&Vector3::x_axis(), dh.alpha).to_homogeneous()
    }

    fn eps_nalgebra(e: &[f64; 6]) -> Matrix4<f64> {
        Translation3::new(e[0], e[1], e[2]).to_homogeneous()
            * Rotation3::from_axis_angle(&Vector3::y_axis(), e[3]).to_homogeneous()
            * Rotation3::from_axis_angle(&Vector3::z_axis(), e[4]).to_homogeneous()
            * Rotation3::from_axis_angle(&Vector3::x_axis(), e[5]).to_homogeneous()
    }

    fn assert_iso_eq(a: &Iso, b: &Matrix4<f64>, tol: f64) {
        for i in 0..3 {
            for j in 0..3 {
                assert!(
                    (a.r[i][j] - b[(i, j)]).abs() < tol,
                    "R[{i}][{j}] {a:?} vs {b}"
                );
            }
            assert!((a.p[i] - b[(i, 3)]).abs() < tol, "p[{i}] {a:?} vs {b}");
        }
    }

    #[test]
    fn fk_matches_an_independent_nalgebra_dh_product() {
        let robot = Robot::aubo_i5();
        let eps_cases: [[[f64; 6]; 6]; 2] = [[[0.0; 6]; 6], {
            let mut e = [[0.0; 6]; 6];
            for (i, row) in e.iter_mut().enumerate() {
                for (k, v) in row.iter_mut().enumerate() {
                    *v = 0.003 * ((i * 6 + k) as f64 * 0.77).sin();
                }
            }
            e[5] = [0.0252, 0.0783, 0.0182, 0.0, 0.0, 0.0];
            e
        }];
        let qs = [
            [0.0; 6],
            [0.3, -0.5, 1.2, 0.7, -1.1, 2.0],
            [-1.4, 1.0, 0.6, -2.9, 0.2, -0.4],
        ];
        for eps in &eps_cases {
            for q in &qs {
                let mut m = Matrix4::identity();
                for i in 0..6 {
                    m = m * dh_nalgebra(&robot.links()[i], q[i]) * eps_nalgebra(&eps[i]);
                }
                let f = forward_kinematics(robot.links(), eps, q);
                assert_iso_eq(&f, &m, 1e-14);
            }
        }
    }

    #[test]
    fn aubo_zero_pose_by_hand() {
        // Nominal AUBO i5 at q = 0, IMU at the flange origin: the arm stands
        // upright. Derived by hand frame by frame: p = (0, −(d2 + d6),
        // d1 + a2 + a3 + d5); flange axes x = (1,0,0), y = (0,0,1), z = (0,−1,0).
        let robot = Robot::aubo_i5();
        let f = forward_kinematics(robot.links(), &[[0.0; 6]; 6], &[0.0; 6]);
        let p = [0.0, -(0.1215 + 0.094), 0.122 + 0.408 + 0.376 + 0.1025];
        let r = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];
        for i in 0..3 {
            assert!((f.p[i] - p[i]).abs() < 1e-12, "{:?}", f.p);
            for j in 0..3 {
                assert!((f.r[i][j] - r[i][j]).abs() < 1e-12, "{:?}", f.r);
            }
        }
    }

    #[test]
    fn error_transform_is_the_paper_eq2_matrix() {
        let e = [0.011, -0.022, 0.033, 0.4, -0.7, 1.3];
        let (c4, s4) = (e[3].cos(), e[3].sin());
        let (c5, s5) = (e[4].cos(), e[4].sin());
        let (c6, s6) = (e[5].cos(), e[5].sin());
        let paper = [
            [c4 * c5, s6 * s4 - c6 * c4 * s5, c6 * s4 + c4 * s6 * s5],
            [s5, c6 * c5, -c5 * s6],
            [-c5 * s4, c4 * s6 + c6 * s4 * s5, c6 * c4 - s6 * s4 * s5],
        ];
        let t = error_transform(&e);
        for i in 0..3 {
            for j in 0..3 {
                assert!((t.r[i][j] - paper[i][j]).abs() < 1e-15, "[{i}][{j}]");
            }
            assert_eq!(t.p[i], e[i]);
        }
    }

    #[test]
    fn dh_transform_is_the_paper_eq1_matrix() {
        let dh = DhLink {
            theta0: 0.3,
            d: 0.12,
            a: 0.4,
            alpha: -PI / 3.0,
        };
        let q = 0.9;
        let th = q + dh.theta0;
        let (ct, st, ca, sa) = (th.cos(), th.sin(), dh.alpha.cos(), dh.alpha.sin());
        let paper = [
            [ct, -ca * st, sa * st, dh.a * ct],
            [st, ct * ca, -sa * ct, dh.a * st],
            [0.0, sa, ca, dh.d],
        ];
        let t = link_transform(&dh, q);
        for i in 0..3 {
            for j in 0..3 {
                assert!((t.r[i][j] - paper[i][j]).abs() < 1e-15);
            }
            assert!((t.p[i] - paper[i][3]).abs() < 1e-15);
        }
    }
}
