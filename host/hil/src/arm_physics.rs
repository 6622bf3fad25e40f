//! The simulated arm's IMU signal from a second, independent implementation
//! of the chain (issue 15 item 3), with hidden effects the estimator's
//! model does not have.
//!
//! The chain is written as URDF writes one: joint j's `<origin>` O_j
//! (xyz, rpy) and axis a_j, link frames `L_j = L_{j−1}·O_j·Rot(a_j, q_j)`,
//! and the IMU frame `L_n·O_tip`. [`UrdfArm::from_model`] maps the model's
//! parameter vector x (docs/model.md §1–2) onto it: with
//! `F_i = Rz(θ0_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)·C_i·E_i` (eq. (1)–(3)),
//! `O_1 = E_0 = I`, `O_{i+1} = F_i`, `O_tip = F_n`, every axis z, gravity
//! from (g_x, g_y) (eq. (5)). The motion follows by the recursive
//! Newton–Euler forward pass in link coordinates (nalgebra), with the
//! gravity trick v̇_0 = −g so v̇ at the IMU is the specific force s:
//!
//! ```text
//! ω_j = Rᵀ ω_{j−1} + a_j q̇_j
//! ω̇_j = Rᵀ ω̇_{j−1} + a_j q̈_j + (Rᵀ ω_{j−1}) × a_j q̇_j
//! v̇_j = Rᵀ (v̇_{j−1} + ω̇_{j−1} × p_j + ω_{j−1} × (ω_{j−1} × p_j))
//! ```
//!
//! (R, p the rotation and translation of `O_j·Rot(a_j, q_j)`). Only
//! gravity (eq. (5)) and the sensor model (eq. (6), [`ImuIntrinsics::apply`])
//! are shared with the estimator. Hidden effects ([`ArmEffects`], each off unless set):
//!
//! * joint elasticity: the joints stand at `q + c∘τ_g(q)` (τ_g from a
//!   [`MassModel`], c per joint in rad/(N·m)), rates and accelerations by
//!   central differences of the deflection along the motion's Taylor
//!   expansion (±1 ms);
//! * a lightly damped structural mode: the IMU mount translates by d and
//!   turns by φ (base frame), each axis a base-excited oscillator
//!   `ẍ + 2ζω₀ẋ + ω₀²x = −β·f` driven by the flange's linear (for d) or
//!   angular (for φ) acceleration f, integrated along the sample times
//!   (RK4, forcing linear between samples, state carried); it adds R^T φ̇ to
//!   ω and `Rᵀ(d̈ − φ × (p̈ − g))` to s.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use robimu_model::effects::MassModel;
use robimu_model::{ImuIntrinsics, ModelError, ParamLayout, Robot};

/// Why an arm could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ArmPhysicsError {
    /// x does not fit the robot.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The elasticity has not one compliance per joint.
    #[error("joint elasticity needs one compliance per joint: {given} given, the robot has {dof}")]
    Compliance {
        /// Compliances given.
        given: usize,
        /// Joints.
        dof: usize,
    },
    /// A structural mode with a non-positive or non-finite frequency or damping.
    #[error("structural mode needs a positive frequency and damping ratio (got {frequency_hz} Hz, ζ = {damping_ratio})")]
    Mode {
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Damping ratio.
        damping_ratio: f64,
    },
}

/// A URDF `<origin>`: `Trans(xyz)·Rz(yaw)·Ry(pitch)·Rx(roll)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct UrdfOrigin {
    /// Translation, m.
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw, rad.
    pub rpy: [f64; 3],
}

impl UrdfOrigin {
    fn from_isometry(t: &Isometry3<f64>) -> Self {
        let (roll, pitch, yaw) = t.rotation.euler_angles();
        Self {
            xyz: t.translation.vector.into(),
            rpy: [roll, pitch, yaw],
        }
    }

    fn isometry(&self) -> Isometry3<f64> {
        let [r, p, y] = self.rpy;
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.xyz)),
            UnitQuaternion::from_euler_angles(r, p, y),
        )
    }
}

/// One revolute joint: its origin in the parent link and its axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct UrdfRevolute {
    /// `<origin>`.
    pub origin: UrdfOrigin,
    /// `<axis xyz>`, unit length.
    pub axis: [f64; 3],
}

/// The arm as a URDF chain with the IMU on its tip (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct UrdfArm {
    /// Joints, base to flange.
    pub joints: Vec<UrdfRevolute>,
    /// The IMU frame in the last link.
    pub tip: UrdfOrigin,
    /// Gravity in the base frame, m/s².
    pub gravity: [f64; 3],
    /// Accelerometer intrinsics (eq. (6)).
    pub accel: ImuIntrinsics,
    /// Gyroscope intrinsics (eq. (6)).
    pub gyro: ImuIntrinsics,
}

/// What the forward pass gives at the IMU.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ImuKinematics {
    /// IMU frame rotation in the base frame.
    pub r: Matrix3<f64>,
    /// ω, IMU frame.
    pub omega: Vector3<f64>,
    /// ω̇, IMU frame.
    pub alpha: Vector3<f64>,
    /// Specific force s = Rᵀ(p̈ − g), IMU frame.
    pub s: Vector3<f64>,
}

fn rot_axis(axis: Vector3<f64>, angle: f64) -> Isometry3<f64> {
    Isometry3::rotation(axis * angle)
}

impl UrdfArm {
    /// The chain of `robot` at the model's parameter vector `x` (layout
    /// order; τ is not part of the arm).
    pub fn from_model(robot: &Robot, layout: &ParamLayout, x: &[f64]) -> Result<Self, ModelError> {
        if layout.n_links() != robot.dof() {
            return Err(ModelError::LayoutMismatch {
                layout: layout.n_links(),
                robot: robot.dof(),
            });
        }
        let p = layout.unpack(x).map_err(ModelError::from)?;
        // gravity (eq. (5)) and the sensor model (eq. (6)) are shared
        let gravity = robimu_model::imu::gravity(p.g_xy, robot.gravity())?;
        let (x_axis, y_axis, z_axis) = (Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis());
        let mut joints = Vec::with_capacity(robot.dof());
        let mut origin = Isometry3::identity();
        for (link, e) in robot.chain().iter().zip(&p.eps) {
            joints.push(UrdfRevolute {
                origin: UrdfOrigin::from_isometry(&origin),
                axis: [0.0, 0.0, 1.0],
            });
            let dh = &link.dh;
            let mut f = Isometry3::rotation(z_axis.into_inner() * dh.theta0)
                * Isometry3::translation(0.0, 0.0, dh.d)
                * Isometry3::translation(dh.a, 0.0, 0.0)
                * Isometry3::rotation(x_axis.into_inner() * dh.alpha);
            if let Some(c) = &link.fixed {
                let r = Matrix3::from_fn(|i, j| c.r[i][j]);
                f *= Isometry3::from_parts(
                    Translation3::from(Vector3::from(c.p)),
                    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
                );
            }
            f = f
                * Isometry3::translation(e[0], e[1], e[2])
                * Isometry3::rotation(y_axis.into_inner() * e[3])
                * Isometry3::rotation(z_axis.into_inner() * e[4])
                * Isometry3::rotation(x_axis.into_inner() * e[5]);
            origin = f;
        }
        Ok(Self {
            joints,
            tip: UrdfOrigin::from_isometry(&origin),
            gravity,
            accel: p.accel,
            gyro: p.gyro,
        })
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The recursive Newton–Euler forward pass (module doc) at (q, q̇, q̈).
    ///
    /// # Panics
    /// If the slices are shorter than [`UrdfArm::dof`].
    pub fn kinematics(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> ImuKinematics {
        let mut w = Vector3::zeros();
        let mut wd = Vector3::zeros();
        let mut vd = -Vector3::from(self.gravity);
        let mut r_base = Matrix3::identity();
        for (j, joint) in self.joints.iter().enumerate() {
            let a = Vector3::from(joint.axis);
            let t = joint.origin.isometry() * rot_axis(a, q[j]);
            let p = t.translation.vector;
            let rt = t.rotation.to_rotation_matrix().matrix().transpose();
            let vd_at = vd + wd.cross(&p) + w.cross(&w.cross(&p));
            let w_in = rt * w;
            w = w_in + a * qd[j];
            wd = rt * wd + a * qdd[j] + w_in.cross(&(a * qd[j]));
            vd = rt * vd_at;
            r_base *= t.rotation.to_rotation_matrix().matrix();
        }
        let t = self.tip.isometry();
        let p = t.translation.vector;
        let rt = t.rotation.to_rotation_matrix().matrix().transpose();
        let vd_at = vd + wd.cross(&p) + w.cross(&w.cross(&p));
        r_base *= t.rotation.to_rotation_matrix().matrix();
        ImuKinematics {
            r: r_base,
            omega: rt * w,
            alpha: rt * wd,
            s: rt * vd_at,
        }
    }

    /// The sensor output `[ax, ay, az, gx, gy, gz]` for ω and s (eq. (6)).
    pub fn output(&self, omega: Vector3<f64>, s: Vector3<f64>) -> [f64; 6] {
        let a = self.accel.apply(s.into());
        let g = self.gyro.apply(omega.into());
        [a[0], a[1], a[2], g[0], g[1], g[2]]
    }
}

/// Joints deflecting under their gravity load: q_actual = q + c∘τ_g(q).
#[derive(Clone, Debug)]
pub struct Elasticity {
    /// The mass model giving τ_g.
    pub mass: MassModel,
    /// Compliance c_j per joint, rad/(N·m).
    pub compliance: Vec<f64>,
}

/// A structural mode of the IMU mount (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StructuralMode {
    /// f₀ = ω₀/2π, Hz.
    pub frequency_hz: f64,
    /// ζ.
    pub damping_ratio: f64,
    /// β of the translation (1: a mass on a spring on the flange).
    pub translation_gain: f64,
    /// β of the rotation.
    pub rotation_gain: f64,
}

impl Default for StructuralMode {
    /// 12 Hz, ζ = 0.02, β = 1 for both.
    fn default() -> Self {
        Self {
            frequency_hz: 12.0,
            damping_ratio: 0.02,
            translation_gain: 1.0,
            rotation_gain: 1.0,
        }
    }
}

/// The hidden effects of the arm; [`Default`] has none.
#[derive(Clone, Debug, Default)]
pub struct ArmEffects {
    /// Joint elasticity under gravity load.
    pub elasticity: Option<Elasticity>,
    /// A structural mode excited by the motion.
    pub mode: Option<StructuralMode>,
}

/// Time step of the deflection's differences, s.
const DEFLECTION_STEP: f64 = 1e-3;
/// Largest RK4 step of the structural mode, s.
const MODE_STEP: f64 = 2.5e-4;

/// The mode's state and its last forcing.
#[derive(Clone, Copy, Debug)]
struct ModeState {
    t: f64,
    /// d, φ (6), then their rates (6).
    x: [f64; 12],
    force: [f64; 6],
}

/// The arm with its hidden effects, evaluated sample by sample.
#[derive(Clone, Debug)]
pub(crate) struct ArmPhysics {
    arm: UrdfArm,
    effects: ArmEffects,
    g0: f64,
    mode: Option<ModeState>,
}

impl ArmPhysics {
    /// `arm` with `effects`; `g0` is the mass model's gravity magnitude.
    pub fn new(arm: UrdfArm, effects: ArmEffects, g0: f64) -> Result<Self, ArmPhysicsError> {
        if let Some(e) = &effects.elasticity {
            if e.compliance.len() != arm.dof() || e.mass.dof() != arm.dof() {
                return Err(ArmPhysicsError::Compliance {
                    given: e.compliance.len(),
                    dof: arm.dof(),
                });
            }
        }
        if let Some(m) = &effects.mode {
            let ok = |v: f64| v.is_finite() && v > 0.0;
            if !ok(m.frequency_hz) || !ok(m.damping_ratio) {
                return Err(ArmPhysicsError::Mode {
                    frequency_hz: m.frequency_hz,
                    damping_ratio: m.damping_ratio,
                });
            }
        }
        Ok(Self {
            arm,
            effects,
            g0,
            mode: None,
        })
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.arm.dof()
    }

    /// The joints' actual (q, q̇, q̈) for the commanded ones (elasticity).
    pub fn actual_joints(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> [Vec<f64>; 3] {
        let n = self.dof();
        let (q, qd, qdd) = (&q[..n], &qd[..n], &qdd[..n]);
        let Some(e) = &self.effects.elasticity else {
            return [q.to_vec(), qd.to_vec(), qdd.to_vec()];
        };
        let delta = |h: f64| -> Vec<f64> {
            let qh: Vec<f64> = (0..n)
                .map(|j| q[j] + h * qd[j] + 0.5 * h * h * qdd[j])
                .collect();
            let tau = e.mass.gravity_torques(&qh, self.g0);
            (0..n).map(|j| e.compliance[j] * tau[j]).collect()
        };
        let h = DEFLECTION_STEP;
        let (d0, dp, dm) = (delta(0.0), delta(h), delta(-h));
        [
            (0..n).map(|j| q[j] + d0[j]).collect(),
            (0..n)
                .map(|j| qd[j] + (dp[j] - dm[j]) / (2.0 * h))
                .collect(),
            (0..n)
                .map(|j| qdd[j] + (dp[j] - 2.0 * d0[j] + dm[j]) / (h * h))
                .collect(),
        ]
    }

    /// The noise-free sensor output at arm time `t` for the commanded joint
    /// state; with a structural mode, calls must come in time order (the
    /// mode integrates from the previous call; the first starts it at rest
    /// relative to the flange's quasi-static deflection).
    pub fn signal(&mut self, t: f64, q: &[f64], qd: &[f64], qdd: &[f64]) -> [f64; 6] {
        let [qa, qda, qdda] = self.actual_joints(q, qd, qdd);
        let k = self.arm.kinematics(&qa, &qda, &qdda);
        let Some(mode) = self.effects.mode else {
            return self.arm.output(k.omega, k.s);
        };
        let g = Vector3::from(self.arm.gravity);
        let pdd = k.r * k.s + g;
        let alpha_n = k.r * k.alpha;
        let force = [pdd[0], pdd[1], pdd[2], alpha_n[0], alpha_n[1], alpha_n[2]];
        let state = self.advance_mode(&mode, t, force);
        let w0 = 2.0 * std::f64::consts::PI * mode.frequency_hz;
        let acc = mode_rhs(&mode, w0, &state.x, &force);
        let d_dd = Vector3::new(acc[6], acc[7], acc[8]);
        let phi = Vector3::new(state.x[3], state.x[4], state.x[5]);
        let phi_d = Vector3::new(state.x[9], state.x[10], state.x[11]);
        let rt = k.r.transpose();
        let omega = k.omega + rt * phi_d;
        let s = k.s + rt * (d_dd - phi.cross(&(pdd - g)));
        self.arm.output(omega, s)
    }

    fn advance_mode(&mut self, mode: &StructuralMode, t: f64, force: [f64; 6]) -> ModeState {
        let w0 = 2.0 * std::f64::consts::PI * mode.frequency_hz;
        let state = match self.mode {
            None => {
                // quasi-static start: x = −β f/ω₀², ẋ = 0
                let mut x = [0.0; 12];
                for c in 0..6 {
                    x[c] = -gain(mode, c) * force[c] / (w0 * w0);
                }
                ModeState { t, x, force }
            }
            Some(prev) if t > prev.t => {
                let steps = ((t - prev.t) / MODE_STEP).ceil().max(1.0);
                let h = (t - prev.t) / steps;
                let f_at = |u: f64| -> [f64; 6] {
                    std::array::from_fn(|c| prev.force[c] + (force[c] - prev.force[c]) * u)
                };
                let mut x = prev.x;
                let n = steps as usize;
                for i in 0..n {
                    let (u0, u1) = (i as f64 / steps, (i + 1) as f64 / steps);
                    let fm = f_at(0.5 * (u0 + u1));
                    let k1 = mode_rhs(mode, w0, &x, &f_at(u0));
                    let k2 = mode_rhs(mode, w0, &axpy(&x, 0.5 * h, &k1), &fm);
                    let k3 = mode_rhs(mode, w0, &axpy(&x, 0.5 * h, &k2), &fm);
                    let k4 = mode_rhs(mode, w0, &axpy(&x, h, &k3), &f_at(u1));
                    for c in 0..12 {
                        x[c] += h / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
                    }
                }
                ModeState { t, x, force }
            }
            // the same instant again (or out of order): no integration
            Some(prev) => ModeState { force, ..prev },
        };
        self.mode = Some(state);
        state
    }

    /// The mode's displacement (d, φ) now (zeros before the first sample).
    #[cfg(test)]
    pub fn mode_displacement(&self) -> [f64; 6] {
        self.mode
            .map_or([0.0; 6], |m| std::array::from_fn(|c| m.x[c]))
    }
}

fn gain(mode: &StructuralMode, c: usize) -> f64 {
    if c < 3 {
        mode.translation_gain
    } else {
        mode.rotation_gain
    }
}

fn axpy(x: &[f64; 12], a: f64, y: &[f64; 12]) -> [f64; 12] {
    std::array::from_fn(|c| x[c] + a * y[c])
}

/// d/dt of (x, ẋ): ẍ = −β f − 2ζω₀ẋ − ω₀²x per axis.
fn mode_rhs(mode: &StructuralMode, w0: f64, x: &[f64; 12], f: &[f64; 6]) -> [f64; 12] {
    let mut d = [0.0; 12];
    for c in 0..6 {
        d[c] = x[6 + c];
        d[6 + c] =
            -gain(mode, c) * f[c] - 2.0 * mode.damping_ratio * w0 * x[6 + c] - w0 * w0 * x[c];
    }
    d
}

#[cfg(test)]
#[path = "arm_physics_tests.rs"]
mod tests;
