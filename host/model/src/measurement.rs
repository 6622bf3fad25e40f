//! Predicted IMU measurement z = [s̃; ω̃] = `[ax, ay, az, gx, gy, gz]` at one
//! sample (paper eq. (10); docs/model.md §4) with exact Jacobians ∂z/∂x, ∂z/∂q,
//! ∂z/∂q̇, ∂z/∂q̈.
//!
//! The joint state is q(t_i + τ) and its derivatives; so
//! ∂z/∂τ = ∂z/∂q·q̇ + ∂z/∂q̇·q̈ + ∂z/∂q̈·q⃛, and for the spline coefficient
//! c_{j,i} (joint j, basis i; [`super::spline`]) at t = t_i + τ:
//! ∂z/∂c_{j,i} = ∂z/∂q_j·N_i(t) + ∂z/∂q̇_j·Ṅ_i(t) + ∂z/∂q̈_j·N̈_i(t).
//!
//! Usage: build a [`MeasurementModel`] once per x, then per sample evaluate the
//! spline ([`super::spline::Spline::evaluate`]) and call
//! [`MeasurementModel::jacobians`] with a reused [`MeasurementJacobians`].
//!
//! # Method
//!
//! Every parameter that moves the chain — joint angle q_j or generalized error
//! ε_ik — is a screw along the product of exponentials (3): its spatial twist
//! S = (w, v) in the base frame (w the unit axis, v = c × w for a point c on
//! it; w = 0 and v = direction for the translations ε_i1..3). With the spatial
//! velocity V = Σ_j S_j q̇_j, the spatial acceleration
//! V̇ = Σ_j A_j, A_j = S_j q̈_j + [V_{<j}, S_j] q̇_j, and the Lie bracket
//! [S1, S2] = (w1×w2, w1×v2 − w2×v1), the derivative with respect to a screw
//! k on link i is (Jacobi identity; V_≤, V_> split at link i):
//!
//! ```text
//! ∂V/∂θ_k = [S_k, V_>],     ∂V̇/∂θ_k = [S_k, V̇_>] − [[S_k, V_≤], V_>]
//! ∂p/∂θ_k = w_k × p + v_k,  ∂R/∂θ_k = [w_k]× R
//! ```
//!
//! and ω_n = V_w, ṗ = V_v + ω_n × p, p̈ = V̇_v + ω̇_n × p + ω_n × ṗ,
//! ω = Rᵀ ω_n, s = Rᵀ (p̈ − g) (eq. (5)), z through eq. (6). All exact; the
//! generic [`predict_generic`] (eq. (4) recursion, any [`Scalar`]) is an
//! independent second implementation used by the tests with [`super::jet::Jet`].

use super::geom::{self, add, cross, mul_mtv, mul_mv, scale, sub, Iso, M3, V3};
use super::imu::{self, ImuError, ImuIntrinsics};
use super::jet::Scalar;
use super::kinematics::{imu_motion, JointState, LinkTransform};
use super::lanes::{has_avx2, F64x4};
use super::params::{ModelParams, Offsets, ParamLayout, ParamLengthError};
use super::robot::Robot;
use super::MAX_JOINTS;

/// Why a measurement model cannot be built for a parameter vector.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ModelError {
    /// x has the wrong length.
    #[error(transparent)]
    ParamLength(#[from] ParamLengthError),
    /// Gravity or sensor parameters are out of their domain.
    #[error(transparent)]
    Imu(#[from] ImuError),
    /// The layout was built for a robot with another number of links.
    #[error("parameter layout has {layout} links but the robot has {robot}")]
    LayoutMismatch {
        /// Links in the layout.
        layout: usize,
        /// Links in the robot.
        robot: usize,
    },
}

/// The predicted measurement and its Jacobians at one sample. Columns are
/// `[f64; 6]` in z order `[ax, ay, az, gx, gy, gz]`.
/// With `S` = [`F64x4`], four samples' values lane by lane
/// ([`MeasurementModel::jacobians_x4`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MeasurementJacobians<S = f64> {
    /// Predicted z.
    pub z: [S; 6],
    /// ∂z/∂x, one column per entry of x (τ column included).
    pub dz_dx: Vec<[S; 6]>,
    /// ∂z/∂q_j, j < n.
    pub dz_dq: [[S; 6]; MAX_JOINTS],
    /// ∂z/∂q̇_j, j < n.
    pub dz_dqd: [[S; 6]; MAX_JOINTS],
    /// ∂z/∂q̈_j, j < n.
    pub dz_dqdd: [[S; 6]; MAX_JOINTS],
}

impl MeasurementJacobians {
    /// Storage for a parameter vector of `n_params` entries (allocate once, reuse).
    pub fn new(n_params: usize) -> Self {
        Self::zeros(n_params)
    }
}

impl<S: Scalar> MeasurementJacobians<S> {
    /// Zeroed storage for a parameter vector of `n_params` entries.
    pub fn zeros(n_params: usize) -> Self {
        let z = [S::cst(0.0); 6];
        Self {
            z,
            dz_dx: vec![z; n_params],
            dz_dq: [z; MAX_JOINTS],
            dz_dqd: [z; MAX_JOINTS],
            dz_dqdd: [z; MAX_JOINTS],
        }
    }
}

impl MeasurementJacobians<F64x4> {
    /// Lane `l`'s Jacobians into `out` (sized alike).
    pub fn lane_into(&self, l: usize, out: &mut MeasurementJacobians) {
        let one = |c: &[F64x4; 6]| c.map(|v| v.lane(l));
        out.z = one(&self.z);
        for (o, c) in out.dz_dx.iter_mut().zip(&self.dz_dx) {
            *o = one(c);
        }
        for j in 0..MAX_JOINTS {
            out.dz_dq[j] = one(&self.dz_dq[j]);
            out.dz_dqd[j] = one(&self.dz_dqd[j]);
            out.dz_dqdd[j] = one(&self.dz_dqdd[j]);
        }
    }
}

/// Spatial twist (w, v).
#[derive(Clone, Copy, Debug)]
struct Tw<S = f64> {
    w: V3<S>,
    v: V3<S>,
}

impl<S: Scalar> Tw<S> {
    #[inline(always)]
    fn zero() -> Self {
        Tw {
            w: [S::cst(0.0); 3],
            v: [S::cst(0.0); 3],
        }
    }
    #[inline(always)]
    fn add(self, o: Tw<S>) -> Tw<S> {
        Tw {
            w: add(self.w, o.w),
            v: add(self.v, o.v),
        }
    }
    #[inline(always)]
    fn sub(self, o: Tw<S>) -> Tw<S> {
        Tw {
            w: sub(self.w, o.w),
            v: sub(self.v, o.v),
        }
    }
    #[inline(always)]
    fn scale(self, s: S) -> Tw<S> {
        Tw {
            w: scale(self.w, s),
            v: scale(self.v, s),
        }
    }
    /// Lie bracket [self, o] = (w1×w2, w1×v2 − w2×v1).
    #[inline(always)]
    fn bracket(self, o: Tw<S>) -> Tw<S> {
        Tw {
            w: cross(self.w, o.w),
            v: sub(cross(self.w, o.v), cross(o.w, self.v)),
        }
    }
}

const NONE: usize = usize::MAX;

/// Per-link constants for the current x.
#[derive(Clone, Copy, Debug)]
struct LinkConst {
    theta0: f64,
    ca: f64,
    sa: f64,
    a: f64,
    d: f64,
    /// The fixed transform C_i after the DH part, when not the identity.
    fixed: Option<(M3, V3)>,
    /// (ε_i1, ε_i2, ε_i3).
    t: V3,
    /// Ry(ε4)·Rz(ε5)·Rx(ε6).
    e_rot: M3,
    e_rot_identity: bool,
    /// ε5 axis in the frame after the translation: Ry(ε4) e_z.
    ax5: V3,
    /// ε6 axis: Ry(ε4)·Rz(ε5) e_x.
    ax6: V3,
    /// Column of ε_i1..6 in x, or NONE.
    cols: [usize; 6],
}

/// Per-sensor constants: M = KΓR, ∂M/∂r, and K, Γ, R for the intrinsic columns.
#[derive(Clone, Copy, Debug)]
struct SensorConst {
    m: M3,
    dm_dr: [M3; 3],
    gr: M3,
    r: M3,
    k: V3,
    b: V3,
}

impl SensorConst {
    fn new(s: &ImuIntrinsics) -> Self {
        let gamma = s.gamma_matrix();
        let kmat = [[s.k[0], 0.0, 0.0], [0.0, s.k[1], 0.0], [0.0, 0.0, s.k[2]]];
        let kg = geom::mul_mm(&kmat, &gamma);
        let (rz, ry, rx) = (
            geom::rot_z(s.r[0]),
            geom::rot_y(s.r[1]),
            geom::rot_x(s.r[2]),
        );
        let r = s.rotation();
        let hat = |a: V3| [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]];
        let (ex, ey, ez) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let d_rz = geom::mul_mm(&hat(ez), &r);
        let d_ry = geom::mul_mm(&geom::mul_mm(&rz, &hat(ey)), &geom::mul_mm(&ry, &rx));
        let d_rx = geom::mul_mm(&r, &hat(ex));
        Self {
            m: geom::mul_mm(&kg, &r),
            dm_dr: [
                geom::mul_mm(&kg, &d_rz),
                geom::mul_mm(&kg, &d_ry),
                geom::mul_mm(&kg, &d_rx),
            ],
            gr: geom::mul_mm(&gamma, &r),
            r,
            k: s.k,
            b: s.b,
        }
    }

    /// Columns ∂z/∂(γ, r, k, b) (12 × 3-vectors) for the physical vector v.
    #[inline(always)]
    fn intrinsic_columns<S: Scalar>(&self, v: V3<S>, out: &mut [[S; 6]], row: usize) {
        let u = mul_mv(&lift_m(&self.r), v);
        let w = mul_mv(&lift_m(&self.gr), v);
        let k = self.k;
        let (z, o) = (S::cst(0.0), S::cst(1.0));
        let mut put = |c: usize, d: V3<S>| {
            let col = &mut out[c];
            *col = [z; 6];
            col[row..row + 3].copy_from_slice(&d);
        };
        put(0, [z, u[0] * k[1], z]);
        put(1, [z, z, -(u[0] * k[2])]);
        put(2, [z, z, u[1] * k[2]]);
        for i in 0..3 {
            put(3 + i, mul_mv(&lift_m(&self.dm_dr[i]), v));
        }
        put(6, [w[0], z, z]);
        put(7, [z, w[1], z]);
        put(8, [z, z, w[2]]);
        put(9, [o, z, z]);
        put(10, [z, o, z]);
        put(11, [z, z, o]);
    }
}

/// The measurement model prepared for one parameter vector x (build once per
/// x, then evaluate any number of samples; evaluation does not allocate).
#[derive(Clone, Debug)]
pub struct MeasurementModel {
    n: usize,
    links: [LinkConst; MAX_JOINTS],
    g: V3,
    dg: [V3; 2],
    accel: SensorConst,
    gyro: SensorConst,
    offsets: Offsets,
    params: ModelParams,
}

/// Chain state for one sample (spatial quantities about the base origin).
struct Walk<S = f64> {
    /// Twists of the real joints.
    s: [Tw<S>; MAX_JOINTS],
    /// Σ_{l ≤ i} S_l q̇_l.
    v_le: [Tw<S>; MAX_JOINTS],
    /// Σ_{l ≤ i} A_l.
    a_le: [Tw<S>; MAX_JOINTS],
    /// Rotation of the ideal frame i (after T_i·C_i, before E_i).
    rg: [M3<S>; MAX_JOINTS],
    /// Origin of the real frame i (after Trans(ε_i1..3)).
    ph: [V3<S>; MAX_JOINTS],
    r: M3<S>,
    p: V3<S>,
}

/// Everything at one sample that the derivatives need. Twists here are
/// re-expressed about the IMU origin p (a constant shift of the coordinate
/// origin, which preserves brackets), so p-terms vanish: ṗ = V_v,
/// p̈ = V̇_v + ω_n × ṗ.
struct Motion<S = f64> {
    /// V, V̇ about p.
    v: Tw<S>,
    vd: Tw<S>,
    pd: V3<S>,
    /// p̈ − g.
    f: V3<S>,
    /// M_a Rᵀ, M_ω Rᵀ.
    ba: M3<S>,
    bw: M3<S>,
    /// ω (IMU frame), s.
    omega: V3<S>,
    s: V3<S>,
}

/// The chain split at link i, about p: V_≤ (the twist of links ≤ i),
/// V_> = V − V_≤ and X = V̇_> − [V_≤, V_>].
struct Split<S> {
    vle: Tw<S>,
    vgt: Tw<S>,
    x: Tw<S>,
}

impl<S: Scalar> Split<S> {
    /// dz of a position-like screw `sk` on link i (a twist about p):
    /// ∂V = [S, V_>], ∂V̇_v = [S, X]_v + [V_≤, ∂V]_v, ∂p = S_v. A function
    /// the compiler inlines (a closure here was compiled apart, without the
    /// caller's AVX2).
    #[inline(always)]
    fn screw(&self, sk: Tw<S>, mo: &Motion<S>) -> [S; 6] {
        let (omega_n, alpha_n) = (mo.v.w, mo.vd.w);
        let dv = sk.bracket(self.vgt);
        let dvd_v = add(bracket_v(sk, self.x), bracket_v(self.vle, dv));
        let dp = sk.v;
        let dpd = add(dv.v, cross(omega_n, dp));
        let dpdd = add(
            add(dvd_v, cross(alpha_n, dp)),
            add(cross(dv.w, mo.pd), cross(omega_n, dpd)),
        );
        let da = mul_mv(&mo.ba, sub(dpdd, cross(sk.w, mo.f)));
        let dw = mul_mv(&mo.bw, sub(dv.w, cross(sk.w, omega_n)));
        [da[0], da[1], da[2], dw[0], dw[1], dw[2]]
    }
}

#[inline(always)]
fn mul_m_mt<S: Scalar>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    // A Bᵀ
    let mut c = [[S::cst(0.0); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = geom::dot(a[i], b[j]);
        }
    }
    c
}

/// Re-expresses a spatial twist about the point p: (w, v + w × p).
#[inline(always)]
fn shift<S: Scalar>(x: Tw<S>, p: V3<S>) -> Tw<S> {
    Tw {
        w: x.w,
        v: add(x.v, cross(x.w, p)),
    }
}

/// The v part of the bracket [a, b]: a_w × b_v − b_w × a_v.
#[inline(always)]
fn bracket_v<S: Scalar>(a: Tw<S>, b: Tw<S>) -> V3<S> {
    sub(cross(a.w, b.v), cross(b.w, a.v))
}

/// A constant vector as a vector of `S`.
#[inline(always)]
fn lift<S: Scalar>(v: V3) -> V3<S> {
    v.map(S::cst)
}

/// A constant matrix as a matrix of `S`.
#[inline(always)]
fn lift_m<S: Scalar>(m: &M3) -> M3<S> {
    m.map(|row| row.map(S::cst))
}
impl MeasurementModel {
    /// Prepares the model for parameter vector `x` (in `layout` order).
    pub fn new(robot: &Robot, layout: &ParamLayout, x: &[f64]) -> Result<Self, ModelError> {
        let n = robot.dof();
        if layout.n_links() != n {
            return Err(ModelError::LayoutMismatch {
                layout: layout.n_links(),
                robot: n,
            });
        }
        let params = layout.unpack(x)?;
        let g = imu::gravity(params.g_xy, robot.gravity())?;
        let gz = g[2];
        // ∂g/∂g_x = (1, 0, g_x/√(g0² − g_x² − g_y²)) = (1, 0, −g_x/g_z).
        let dg = [[1.0, 0.0, -g[0] / gz], [0.0, 1.0, -g[1] / gz]];
        let empty = LinkConst {
            theta0: 0.0,
            ca: 1.0,
            sa: 0.0,
            a: 0.0,
            d: 0.0,
            fixed: None,
            t: [0.0; 3],
            e_rot: geom::identity(),
            e_rot_identity: true,
            ax5: [0.0, 0.0, 1.0],
            ax6: [1.0, 0.0, 0.0],
            cols: [NONE; 6],
        };
        let mut links = [empty; MAX_JOINTS];
        for (i, (link, e)) in robot.chain().iter().zip(&params.eps).enumerate() {
            let dh = &link.dh;
            let ry = geom::rot_y(e[3]);
            let ryz = geom::mul_mm(&ry, &geom::rot_z(e[4]));
            let mut cols = [NONE; 6];
            for (k, c) in cols.iter_mut().enumerate() {
                if let Some(ix) = layout.eps_index(i + 1, k + 1) {
                    *c = ix;
                }
            }
            links[i] = LinkConst {
                theta0: dh.theta0,
                ca: dh.alpha.cos(),
                sa: dh.alpha.sin(),
                a: dh.a,
                d: dh.d,
                fixed: link.fixed.map(|c| (c.r, c.p)),
                t: [e[0], e[1], e[2]],
                e_rot: geom::mul_mm(&ryz, &geom::rot_x(e[5])),
                e_rot_identity: e[3] == 0.0 && e[4] == 0.0 && e[5] == 0.0,
                ax5: geom::col(&ry, 2),
                ax6: geom::col(&ryz, 0),
                cols,
            };
        }
        Ok(Self {
            n,
            links,
            g,
            dg,
            accel: SensorConst::new(&params.accel),
            gyro: SensorConst::new(&params.gyro),
            offsets: layout.offsets(),
            params,
        })
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.n
    }
    /// Length of x.
    pub fn n_params(&self) -> usize {
        self.offsets.len
    }
    /// The typed view of x this model was built from.
    pub fn params(&self) -> &ModelParams {
        &self.params
    }
    /// Gravity g in the base frame (eq. (5)).
    pub fn gravity(&self) -> V3 {
        self.g
    }

    /// Walks the chain: frames, joint twists, V and A prefix sums.
    #[inline(always)]
    fn walk<S: Scalar>(&self, js: &JointState<S>, wk: &mut Walk<S>) {
        let (mut vsum, mut asum) = (Tw::zero(), Tw::zero());
        let (mut r, mut p) = (geom::identity(), [S::cst(0.0); 3]);
        for i in 0..self.n {
            let l = &self.links[i];
            let w = geom::col(&r, 2);
            let sj = Tw { w, v: cross(p, w) };
            let aj = sj.scale(js.qdd[i]).add(vsum.bracket(sj).scale(js.qd[i]));
            vsum = vsum.add(sj.scale(js.qd[i]));
            asum = asum.add(aj);
            wk.s[i] = sj;
            wk.v_le[i] = vsum;
            wk.a_le[i] = asum;
            // R_G = R·Rz(θ)·Rx(α), p_G = p + R·(a c, a s, d).
            let (st, ct) = (js.q[i] + l.theta0).sin_cos();
            let mz = [
                [ct, -(st * l.ca), st * l.sa],
                [st, ct * l.ca, -(ct * l.sa)],
                [S::cst(0.0), S::cst(l.sa), S::cst(l.ca)],
            ];
            let mut rg = geom::mul_mm(&r, &mz);
            let mut pg = add(p, mul_mv(&r, [ct * l.a, st * l.a, S::cst(l.d)]));
            if let Some((cr, cp)) = &l.fixed {
                // The fixed C_i after the DH part: frame ·= [cr cp].
                pg = add(pg, mul_mv(&rg, lift(*cp)));
                rg = geom::mul_mm(&rg, &lift_m(cr));
            }
            let ph = add(pg, mul_mv(&rg, lift(l.t)));
            wk.rg[i] = rg;
            wk.ph[i] = ph;
            r = if l.e_rot_identity {
                rg
            } else {
                geom::mul_mm(&rg, &lift_m(&l.e_rot))
            };
            p = ph;
        }
        wk.r = r;
        wk.p = p;
    }

    #[inline(always)]
    fn new_walk<S: Scalar>() -> Walk<S> {
        let z = S::cst(0.0);
        Walk {
            s: [Tw::zero(); MAX_JOINTS],
            v_le: [Tw::zero(); MAX_JOINTS],
            a_le: [Tw::zero(); MAX_JOINTS],
            rg: [[[z; 3]; 3]; MAX_JOINTS],
            ph: [[z; 3]; MAX_JOINTS],
            r: [[z; 3]; 3],
            p: [z; 3],
        }
    }

    #[inline(always)]
    fn motion<S: Scalar>(&self, wk: &Walk<S>) -> Motion<S> {
        let n = self.n;
        let v = shift(wk.v_le[n - 1], wk.p);
        let vd = shift(wk.a_le[n - 1], wk.p);
        let pd = v.v;
        let pdd = add(vd.v, cross(v.w, pd));
        let f = sub(pdd, lift(self.g));
        let omega = mul_mtv(&wk.r, v.w);
        let s = mul_mtv(&wk.r, f);
        Motion {
            v,
            vd,
            pd,
            f,
            ba: mul_m_mt(&lift_m(&self.accel.m), &wk.r),
            bw: mul_m_mt(&lift_m(&self.gyro.m), &wk.r),
            omega,
            s,
        }
    }

    /// Pose of the IMU frame and the IMU-frame inertial quantities (ω, s)
    /// (eq. (3), (5)) at the joint state.
    pub fn inertial(&self, js: &JointState) -> (Iso, V3, V3) {
        let mut wk = Self::new_walk();
        self.walk(js, &mut wk);
        let mo = self.motion(&wk);
        (Iso { r: wk.r, p: wk.p }, mo.omega, mo.s)
    }

    /// Predicted z = [s̃; ω̃] at the joint state q(t_i + τ) (eq. (6), (10)).
    pub fn predict(&self, js: &JointState) -> [f64; 6] {
        self.predict_lanes(js)
    }

    /// [`Self::predict`] of four samples at once, lane by lane (bit-identical
    /// to four scalar calls; [`crate::lanes`]).
    pub fn predict_x4(&self, js: &JointState<F64x4>) -> [F64x4; 6] {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx,avx2")]
            fn avx2(m: &MeasurementModel, js: &JointState<F64x4>) -> [F64x4; 6] {
                m.predict_lanes(js)
            }
            if has_avx2() {
                // SAFETY: the CPU has AVX and AVX2 (checked just above).
                return unsafe { avx2(self, js) };
            }
        }
        self.predict_lanes(js)
    }

    #[inline(always)]
    fn predict_lanes<S: Scalar>(&self, js: &JointState<S>) -> [S; 6] {
        let mut wk = Self::new_walk();
        self.walk(js, &mut wk);
        let mo = self.motion(&wk);
        self.output(&mo)
    }

    #[inline(always)]
    fn output<S: Scalar>(&self, mo: &Motion<S>) -> [S; 6] {
        let a = add(mul_mv(&lift_m(&self.accel.m), mo.s), lift(self.accel.b));
        let w = add(mul_mv(&lift_m(&self.gyro.m), mo.omega), lift(self.gyro.b));
        [a[0], a[1], a[2], w[0], w[1], w[2]]
    }

    /// z and all Jacobians at the joint state (q, q̇, q̈, q⃛ at t_i + τ).
    ///
    /// # Panics
    /// If `out` was not sized for this model's x (`MeasurementJacobians::new(self.n_params())`).
    #[track_caller]
    pub fn jacobians(&self, js: &JointState, out: &mut MeasurementJacobians) {
        self.check_size(out.dz_dx.len());
        self.jacobians_lanes(js, out);
    }

    /// [`Self::jacobians`] of four samples at once, lane by lane
    /// (bit-identical to four scalar calls; [`crate::lanes`]).
    ///
    /// # Panics
    /// If `out` was not sized for this model's x (`MeasurementJacobians::zeros(self.n_params())`).
    #[track_caller]
    pub fn jacobians_x4(&self, js: &JointState<F64x4>, out: &mut MeasurementJacobians<F64x4>) {
        self.check_size(out.dz_dx.len());
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx,avx2")]
            fn avx2(
                m: &MeasurementModel,
                js: &JointState<F64x4>,
                out: &mut MeasurementJacobians<F64x4>,
            ) {
                m.jacobians_lanes(js, out)
            }
            if has_avx2() {
                // SAFETY: the CPU has AVX and AVX2 (checked just above).
                return unsafe { avx2(self, js, out) };
            }
        }
        self.jacobians_lanes(js, out)
    }

    #[track_caller]
    fn check_size(&self, n: usize) {
        assert_eq!(n, self.offsets.len, "Jacobian storage sized for another x");
    }

    /// The Jacobians for any lane type (f64: one sample; [`F64x4`]: four).
    #[inline(always)]
    fn jacobians_lanes<S: Scalar>(&self, js: &JointState<S>, out: &mut MeasurementJacobians<S>) {
        let mut wk = Self::new_walk();
        self.walk(js, &mut wk);
        let mo = self.motion(&wk);
        out.z = self.output(&mo);
        let n = self.n;
        let p = wk.p;
        let (v, vd) = (mo.v, mo.vd);
        let (omega_n, alpha_n) = (v.w, vd.w);
        let zero = S::cst(0.0);

        let mut vle_prev = Tw::zero();
        for i in 0..n {
            // Split at link i, about p: V_≤, V_>, and X = V̇_> − [V_≤, V_>].
            let vle = shift(wk.v_le[i], p);
            let vgt = v.sub(vle);
            let x = vd.sub(shift(wk.a_le[i], p)).sub(vle.bracket(vgt));
            let split = Split { vle, vgt, x };
            let sj = shift(wk.s[i], p);
            out.dz_dq[i] = split.screw(sj, &mo);
            let l = &self.links[i];
            let rg = &wk.rg[i];
            let c = sub(wk.ph[i], p);
            for k in 0..6 {
                let col = l.cols[k];
                if col == NONE {
                    continue;
                }
                let tw = match k {
                    0..=2 => {
                        // Translation (w = 0): ∂V = (0, −V_>w × d), no gyro effect.
                        let d = geom::col(rg, k);
                        let dv_v = cross(d, vgt.w);
                        let dvd_v = add(cross(d, x.w), cross(vle.w, dv_v));
                        let dpd = add(dv_v, cross(omega_n, d));
                        let dpdd = add(add(dvd_v, cross(alpha_n, d)), cross(omega_n, dpd));
                        let da = mul_mv(&mo.ba, dpdd);
                        out.dz_dx[col] = [da[0], da[1], da[2], zero, zero, zero];
                        continue;
                    }
                    _ => {
                        let ax = match k {
                            3 => geom::col(rg, 1),
                            4 => mul_mv(rg, lift(l.ax5)),
                            _ => mul_mv(rg, lift(l.ax6)),
                        };
                        Tw {
                            w: ax,
                            v: cross(c, ax),
                        }
                    }
                };
                out.dz_dx[col] = split.screw(tw, &mo);
            }
            // Joint rate: ∂V/∂q̇_j = S_j, ∂V̇/∂q̇_j = [V_<, S_j] + [S_j, V_>];
            // joint acceleration: ∂V̇/∂q̈_j = S_j.
            let dvd_v = add(bracket_v(vle_prev, sj), bracket_v(sj, vgt));
            let dpd = sj.v;
            let dpdd = add(dvd_v, add(cross(sj.w, mo.pd), cross(omega_n, dpd)));
            let da = mul_mv(&mo.ba, dpdd);
            let dw = mul_mv(&mo.bw, sj.w);
            out.dz_dqd[i] = [da[0], da[1], da[2], dw[0], dw[1], dw[2]];
            let da = mul_mv(&mo.ba, dpd);
            out.dz_dqdd[i] = [da[0], da[1], da[2], zero, zero, zero];
            vle_prev = vle;
        }
        let o = &self.offsets;
        for (c, dg) in self.dg.iter().enumerate() {
            let da = mul_mv(&mo.ba, lift(*dg));
            out.dz_dx[o.g_xy + c] = [-da[0], -da[1], -da[2], zero, zero, zero];
        }
        let mut tau = [zero; 6];
        for j in 0..n {
            for (r, t) in tau.iter_mut().enumerate() {
                *t += out.dz_dq[j][r] * js.qd[j]
                    + out.dz_dqd[j][r] * js.qdd[j]
                    + out.dz_dqdd[j][r] * js.qddd[j];
            }
        }
        out.dz_dx[o.tau] = tau;
        self.accel
            .intrinsic_columns(mo.s, &mut out.dz_dx[o.gamma_a..o.gamma_a + 12], 0);
        self.gyro
            .intrinsic_columns(mo.omega, &mut out.dz_dx[o.gamma_w..o.gamma_w + 12], 3);
    }
}

/// Reference prediction over any [`Scalar`]: eq. (3)–(6) via
/// [`imu_motion`] (the eq. (4) recursion) and [`imu`]; with a
/// [`super::jet::Jet`] it gives exact derivatives by forward-mode AD.
///
/// # Panics
/// If the slices do not have one entry per link.
#[track_caller]
pub fn predict_generic<S: Scalar, L: LinkTransform>(
    links: &[L],
    g0: f64,
    params: &ModelParams<S>,
    q: &[S],
    qd: &[S],
    qdd: &[S],
) -> Result<[S; 6], ImuError> {
    let m = imu_motion(links, &params.eps, q, qd, qdd);
    let g = imu::gravity(params.g_xy, g0)?;
    let (omega, s) = imu::inertial(&m.pose.r, m.omega_n, m.a_n, g);
    Ok(imu::sensor_output(&params.accel, &params.gyro, omega, s))
}

#[cfg(test)]
#[path = "measurement_tests.rs"]
mod tests;
