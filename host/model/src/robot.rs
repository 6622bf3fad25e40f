//! Robot description: DH table, joint limits, default noise, IMU mount and
//! priors, gravity, and which generalized errors are estimated (docs/model.md §1, §6).
//!
//! Link `i` (1-based) has the standard DH transform (paper eq. (1))
//! `T_i(q_i) = Rz(q_i + θ0_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`, followed by the
//! generalized error transform `E_i` (eq. (2)); see [`super::kinematics`].
//!
//! # Joints that are not plain DH
//!
//! A joint may also carry a fixed transform `C_i` (its `origin`) after the DH
//! part, so that link i is `T_i(q_i)·C_i·E_i`:
//!
//! ```text
//! [R p; 0 1] = T_1(q_1)·C_1·E_1 · T_2(q_2)·C_2·E_2 ⋯ T_n(q_n)·C_n·E_n
//! ```
//!
//! Joint i always turns about the z axis of the frame before `T_i`. With every
//! `C_i = I` (no `origin` key) this is exactly docs/model.md §1. `C_i` describes
//! (a) a robot imported from URDF ([`super::urdf`]: DH part zero, `C_i` the
//! transform from joint i's frame to joint i+1's, each rotated so its axis is
//! z), or (b) a calibrated robot (`C_i` = the nominal `C_i` times the
//! estimated `E_i`, see `robimu_session::export`). The generalized errors `E_i` always
//! sit after `C_i`, i.e. on the fixed transform from joint i to joint i+1
//! expressed in the frame of joint i+1, as in docs/model.md §1.6 for DH robots.
//!
//! # TOML format
//!
//! All values are SI (m, rad, s, m/s², rad/s). One `[[joint]]` table per joint,
//! base to flange. `[priors]` and `[errors]` and `gravity` are optional; missing
//! prior keys take the paper's Table II values ([`Priors::default`]); a missing
//! `[errors]` table takes [`default_estimated_errors`] (the paper's Table II
//! pattern; other robots should supply a numerically found minimal set).
//!
//! ```toml
//! name = "planar_2r"
//! gravity = 9.81                     # m/s², optional (default 9.81)
//!
//! [[joint]]                          # joint 1
//! theta0 = 0.0                       # rad, joint angle offset θ0
//! d = 0.1                            # m
//! a = 0.3                            # m
//! alpha = 0.0                        # rad
//! q_min = -1.5707963267948966        # rad
//! q_max = 1.5707963267948966         # rad
//! qd_max = 0.5                       # rad/s (|q̇| ≤ qd_max)
//! qdd_max = 2.0                      # rad/s² (|q̈| ≤ qdd_max)
//! sigma_q = 1e-4                     # rad, joint sample noise σ
//! # optional: fixed transform C_i after the DH part (URDF origin convention,
//! # Trans(xyz)·Rz(yaw)·Ry(pitch)·Rx(roll); m, rad)
//! origin = { xyz = [0.0, 0.0, 0.0], rpy = [0.0, 0.0, 0.0] }
//!
//! [[joint]]                          # joint 2 (the flange)
//! theta0 = 0.0
//! d = 0.0
//! a = 0.25
//! alpha = 0.0
//! q_min = -2.0
//! q_max = 2.0
//! qd_max = 0.5
//! qdd_max = 2.0
//! sigma_q = 1e-4
//!
//! [noise]
//! sigma_z = [0.38, 0.21, 0.19, 0.0055850536, 0.0082030475, 0.0099483767]  # m/s² ×3, rad/s ×3
//!
//! [imu_mount]
//! position = [0.0252, 0.0783, 0.0182]     # m, IMU origin in the flange frame (ε_n1..3 prior mean)
//! position_sigma = 0.01                   # m
//! r_a = [3.141592653589793, 0.0, 0.0]     # rad, accelerometer rotation prior mean (z, y, x)
//! r_w = [3.141592653589793, 0.0, 0.0]     # rad, gyroscope rotation prior mean (z, y, x)
//! rotation_sigma = 0.08726646259971647    # rad
//!
//! [priors]                                # optional, every key optional
//! eps_length_sigma = 0.001                # m
//! eps_angle_sigma = 0.017453292519943295  # rad
//! g_xy_sigma = 0.5                        # m/s²
//! tau_sigma = 1.0                         # s
//! gamma_a_sigma = 0.02617993877991494     # rad
//! k_a_sigma = 0.1
//! b_a_sigma = 2.0                         # m/s²
//! gamma_w_sigma = 0.03490658503988659     # rad
//! k_w_sigma = 0.1
//! b_w_sigma = 0.08726646259971647         # rad/s
//!
//! [errors]                # optional: estimated ε as [link, k], link 1..n, k 1..6 (not n,4..6)
//! estimated = [[1, 1], [1, 6], [2, 1], [2, 2], [2, 3]]
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::geom::{self, Iso, M3};
use super::MAX_JOINTS;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Standard DH parameters of one revolute link (docs/model.md §1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DhLink {
    /// Joint angle offset θ0 (rad).
    pub theta0: f64,
    /// Offset along z, d (m).
    pub d: f64,
    /// Length along x, a (m).
    pub a: f64,
    /// Twist about x, α (rad).
    pub alpha: f64,
}

/// A fixed rigid transform in the URDF `<origin>` convention:
/// `Trans(xyz)·Rz(yaw)·Ry(pitch)·Rx(roll)`, `rpy = [roll, pitch, yaw]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Origin {
    /// Translation (m).
    #[serde(deserialize_with = "crate::arity::array")]
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (rad): fixed-axis X, then Y, then Z.
    #[serde(deserialize_with = "crate::arity::array")]
    pub rpy: [f64; 3],
}

impl Origin {
    /// The identity.
    pub const IDENTITY: Origin = Origin {
        xyz: [0.0; 3],
        rpy: [0.0; 3],
    };

    /// The transform `[R p; 0 1]`.
    pub fn to_iso(&self) -> Iso {
        Iso {
            r: rpy_matrix(self.rpy),
            p: self.xyz,
        }
    }

    /// The origin of a transform (see [`matrix_rpy`] for the angles).
    pub fn from_iso(t: &Iso) -> Self {
        Self {
            xyz: t.p,
            rpy: matrix_rpy(&t.r),
        }
    }
}

/// `Rz(yaw)·Ry(pitch)·Rx(roll)` for `rpy = [roll, pitch, yaw]` (URDF).
pub(crate) fn rpy_matrix(rpy: [f64; 3]) -> M3 {
    geom::rot_zyx([rpy[2], rpy[1], rpy[0]])
}

/// Roll, pitch, yaw of a rotation matrix (inverse of [`rpy_matrix`]); at
/// pitch ±90° (where only roll ∓ yaw is defined) yaw is set to 0. Of the
/// general and the gimbal-lock solution, the one that reproduces `r` best is
/// returned, so the result is exact to rounding everywhere.
pub(crate) fn matrix_rpy(r: &M3) -> [f64; 3] {
    let pitch = (-r[2][0]).atan2(r[2][1].hypot(r[2][2]));
    let general = [r[2][1].atan2(r[2][2]), pitch, r[1][0].atan2(r[0][0])];
    // yaw = 0: Rx(roll) = Ry(pitch)ᵀ·R.
    let m = geom::mul_mm(&geom::transpose(&geom::rot_y(pitch)), r);
    let locked = [m[2][1].atan2(m[1][1]), pitch, 0.0];
    let err = |a: [f64; 3]| {
        let q = rpy_matrix(a);
        let mut e = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                e = e.max((q[i][j] - r[i][j]).abs());
            }
        }
        e
    };
    if err(locked) < err(general) {
        locked
    } else {
        general
    }
}

/// One link of the chain: the DH transform `T_i(q)` and the fixed transform
/// `C_i` after it (`None` = identity, a plain DH link).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainLink {
    /// DH part.
    pub dh: DhLink,
    /// `C_i`, when not the identity.
    pub fixed: Option<Iso>,
}

/// Joint limits (paper Table III), SI.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLimits {
    /// Lower position limit (rad).
    pub q_min: f64,
    /// Upper position limit (rad).
    pub q_max: f64,
    /// Speed limit, |q̇| ≤ qd_max (rad/s).
    pub qd_max: f64,
    /// Acceleration limit, |q̈| ≤ qdd_max (rad/s²).
    pub qdd_max: f64,
}

/// One `[[joint]]` entry of the TOML file: DH, limits and joint noise.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointDescription {
    /// Joint angle offset θ0 (rad).
    pub theta0: f64,
    /// d (m).
    pub d: f64,
    /// a (m).
    pub a: f64,
    /// α (rad).
    pub alpha: f64,
    /// Lower position limit (rad).
    pub q_min: f64,
    /// Upper position limit (rad).
    pub q_max: f64,
    /// Speed limit (rad/s).
    pub qd_max: f64,
    /// Acceleration limit (rad/s²).
    pub qdd_max: f64,
    /// Joint sample noise σ (rad).
    pub sigma_q: f64,
    /// Fixed transform `C_i` after the DH part (absent: identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<Origin>,
}

/// Default IMU sample noise (standard deviations).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseDescription {
    /// σ of `[ax, ay, az, gx, gy, gz]`: m/s² ×3, rad/s ×3.
    #[serde(deserialize_with = "crate::arity::array")]
    pub sigma_z: [f64; 6],
}

/// Nominal IMU mount on the flange and its prior.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuMount {
    /// IMU origin in the flange frame (m): prior mean of ε_n1..3.
    #[serde(deserialize_with = "crate::arity::array")]
    pub position: [f64; 3],
    /// Prior σ of each position component (m).
    pub position_sigma: f64,
    /// Accelerometer rotation prior mean (r_a_z, r_a_y, r_a_x) (rad).
    #[serde(deserialize_with = "crate::arity::array")]
    pub r_a: [f64; 3],
    /// Gyroscope rotation prior mean (r_w_z, r_w_y, r_w_x) (rad).
    #[serde(deserialize_with = "crate::arity::array")]
    pub r_w: [f64; 3],
    /// Prior σ of every sensor rotation angle (rad).
    pub rotation_sigma: f64,
}

/// Prior standard deviations of the parameters not tied to the mount (SI).
/// Prior means are fixed by the model: ε 0, g_xy 0, τ 0, γ 0, k 1, b 0.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Priors {
    /// σ of robot length errors ε_i1..3 (m).
    pub eps_length_sigma: f64,
    /// σ of robot angle errors ε_i4..6 (rad).
    pub eps_angle_sigma: f64,
    /// σ of g_x, g_y (m/s²).
    pub g_xy_sigma: f64,
    /// σ of τ (s).
    pub tau_sigma: f64,
    /// σ of γ_a (rad).
    pub gamma_a_sigma: f64,
    /// σ of k_a.
    pub k_a_sigma: f64,
    /// σ of b_a (m/s²).
    pub b_a_sigma: f64,
    /// σ of γ_ω (rad).
    pub gamma_w_sigma: f64,
    /// σ of k_ω.
    pub k_w_sigma: f64,
    /// σ of b_ω (rad/s).
    pub b_w_sigma: f64,
}

impl Default for Priors {
    /// The paper's Table II (docs/model.md §6), in SI.
    fn default() -> Self {
        Self {
            eps_length_sigma: 1e-3,
            eps_angle_sigma: 1.0 * DEG,
            g_xy_sigma: 0.5,
            tau_sigma: 1.0,
            gamma_a_sigma: 1.5 * DEG,
            k_a_sigma: 0.1,
            b_a_sigma: 2.0,
            gamma_w_sigma: 2.0 * DEG,
            k_w_sigma: 0.1,
            b_w_sigma: 5.0 * DEG,
        }
    }
}

/// One generalized error ε_{link,k}: `link` 1..=n, `k` 1..=6 (1..3 translation
/// x, y, z; 4..6 rotation y, z, x).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(from = "[usize; 2]", into = "[usize; 2]")]
pub struct ErrorIndex {
    /// Link, 1-based (E_0 is never estimated).
    pub link: usize,
    /// Component, 1-based.
    pub k: usize,
}

impl ErrorIndex {
    /// Whether this is a translation component (k = 1..3, metres).
    pub fn is_translation(&self) -> bool {
        self.k <= 3
    }

    /// Whether this is a robot length error of an `n`-joint robot: a
    /// translation ε_i1..3 of a link i < n (ε_n1..3 is the IMU position).
    pub fn is_length(&self, n: usize) -> bool {
        self.link < n && self.is_translation()
    }
}

impl From<[usize; 2]> for ErrorIndex {
    fn from(v: [usize; 2]) -> Self {
        Self {
            link: v[0],
            k: v[1],
        }
    }
}

impl From<ErrorIndex> for [usize; 2] {
    fn from(e: ErrorIndex) -> Self {
        [e.link, e.k]
    }
}

/// `[errors]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorsDescription {
    /// Estimated ε, in any order (stored sorted by link, then k).
    pub estimated: Vec<ErrorIndex>,
}

fn default_gravity() -> f64 {
    9.81
}

/// The plain, serde-facing robot description (the TOML file's shape).
/// Turn it into a validated [`Robot`] with [`Robot::new`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotDescription {
    /// Robot name.
    pub name: String,
    /// Gravity magnitude g0 (m/s²).
    #[serde(default = "default_gravity")]
    pub gravity: f64,
    /// Where the numbers come from (a built-in robot: the maker's
    /// description package and version).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Joint names, base to flange, as the robot's driver publishes them
    /// (empty: unnamed; then joint readings are taken in chain order).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joint_names: Vec<String>,
    /// The maker's base and flange frames (absent: the model's own).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<Frames>,
    /// The maker's identifier of the calibration these kinematics are (UR:
    /// the `hash` of the kinematics YAML, `calib_…`, which the UR driver
    /// compares with the controller's), kept so that an export names the
    /// calibration it refines.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration_hash: Option<String>,
    /// Joints, base to flange.
    #[serde(rename = "joint")]
    pub joints: Vec<JointDescription>,
    /// Default IMU noise.
    pub noise: NoiseDescription,
    /// IMU mount prior.
    pub imu_mount: ImuMount,
    /// Prior σ (defaults: paper Table II).
    #[serde(default)]
    pub priors: Priors,
    /// Estimated ε (default: [`default_estimated_errors`]).
    #[serde(default)]
    pub errors: Option<ErrorsDescription>,
    /// The mount priors of IMUs j ≥ 1 of a multi-IMU session that differ
    /// from [`Self::imu_mount`] (docs/model.md §9; set from the session's
    /// `[imu<j>.mount]` tables with [`Robot::with_mount`], not part of the
    /// robot TOML).
    #[serde(skip)]
    pub imu_mounts: std::collections::BTreeMap<usize, ImuMount>,
}

/// The maker's base and flange frames of a robot description: the model's
/// flange frame is the maker's flange frame `flange`; the model's base frame
/// (joint 1's frame, in which gravity is expressed) sits at `base_to_model`
/// in the maker's base frame `base`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Frames {
    /// Name of the maker's base frame (e.g. UR's `base`, Franka's `link0`).
    pub base: String,
    /// Name of the maker's flange frame (e.g. UR's `tool0`, Franka's `link8`).
    pub flange: String,
    /// The model's base frame in the maker's base frame.
    pub base_to_model: Origin,
}

/// Why a robot description was rejected.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The file could not be read.
    #[error("cannot read robot description {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The TOML text does not have the documented shape.
    #[error("robot description is not valid TOML of the documented shape: {0}")]
    Toml(#[from] toml::de::Error),
    /// No joints.
    #[error("robot `{0}` has no joints")]
    NoJoints(String),
    /// More joints than the model supports.
    #[error("robot has {n} joints; at most {max} are supported")]
    TooManyJoints {
        /// Joints given.
        n: usize,
        /// [`MAX_JOINTS`].
        max: usize,
    },
    /// A value is NaN or infinite.
    #[error("{field} is not a finite number")]
    NonFinite {
        /// Which value.
        field: String,
    },
    /// A standard deviation, limit or gravity that must be > 0 is not.
    #[error("{field} must be > 0 (got {value})")]
    NotPositive {
        /// Which value.
        field: String,
        /// The value found.
        value: f64,
    },
    /// A number beyond the range it can physically have.
    #[error("{field} = {value:e} is beyond its range (at most {max:e} in magnitude)")]
    OutOfRange {
        /// Which field.
        field: String,
        /// The value.
        value: f64,
        /// The largest magnitude allowed.
        max: f64,
    },
    /// `q_min >= q_max`.
    #[error("joint {joint}: q_min ({q_min}) must be below q_max ({q_max})")]
    EmptyRange {
        /// Joint, 1-based.
        joint: usize,
        /// Lower limit.
        q_min: f64,
        /// Upper limit.
        q_max: f64,
    },
    /// An estimated ε index that does not exist or cannot be estimated.
    #[error("estimated error eps_{link}_{k}: {reason}")]
    BadErrorIndex {
        /// Link.
        link: usize,
        /// Component.
        k: usize,
        /// Why it is rejected.
        reason: &'static str,
    },
    /// `joint_names` is neither empty nor one unique name per joint.
    #[error("joint_names: {0}")]
    BadJointNames(String),
    /// The same ε listed twice.
    #[error("estimated error eps_{link}_{k} is listed twice")]
    DuplicateErrorIndex {
        /// Link.
        link: usize,
        /// Component.
        k: usize,
    },
}

/// The paper's Table II pattern for an n-joint arm: ε_1{1,6},
/// ε_i{1,2,4,6} for i = 2..n−1, ε_n{1,2,3} (21 values for n = 6).
pub fn default_estimated_errors(n: usize) -> Vec<ErrorIndex> {
    let mut v = Vec::new();
    if n == 0 {
        return v;
    }
    if n >= 2 {
        v.push(ErrorIndex { link: 1, k: 1 });
        v.push(ErrorIndex { link: 1, k: 6 });
    }
    for link in 2..n {
        for k in [1, 2, 4, 6] {
            v.push(ErrorIndex { link, k });
        }
    }
    for k in 1..=3 {
        v.push(ErrorIndex { link: n, k });
    }
    v
}

/// A validated robot description.
#[derive(Clone, Debug, PartialEq)]
pub struct Robot {
    desc: RobotDescription,
    links: Vec<DhLink>,
    chain: Vec<ChainLink>,
    limits: Vec<JointLimits>,
    sigma_q: Vec<f64>,
    estimated: Vec<ErrorIndex>,
}

fn finite(field: impl FnOnce() -> String, v: f64) -> Result<(), RobotError> {
    if !v.is_finite() {
        return Err(RobotError::NonFinite { field: field() });
    }
    if v.abs() > MAX_MAGNITUDE {
        return Err(RobotError::OutOfRange {
            field: field(),
            value: v,
            max: MAX_MAGNITUDE,
        });
    }
    Ok(())
}

/// The largest magnitude any number of a robot description may have (m,
/// rad, rad/s, rad/s², m/s²).
const MAX_MAGNITUDE: f64 = 1e6;
/// The largest joint sample σ (rad): an encoder is far better.
pub(crate) const MAX_SIGMA_Q: f64 = 0.1;
/// The largest IMU sample σ: accelerometer (m/s²), gyroscope (rad/s).
pub(crate) const MAX_SIGMA_Z: [f64; 2] = [10.0, 1.0];

/// A σ: positive and at most `max`.
fn sigma(field: impl Fn() -> String, v: f64, max: f64) -> Result<(), RobotError> {
    positive(&field, v)?;
    if v > max {
        return Err(RobotError::OutOfRange {
            field: field(),
            value: v,
            max,
        });
    }
    Ok(())
}

/// Every number of a mount finite, its σ positive (`what` names it).
fn check_mount(what: &str, m: &ImuMount) -> Result<(), RobotError> {
    for i in 0..3 {
        finite(|| format!("{what}.position[{i}]"), m.position[i])?;
        finite(|| format!("{what}.r_a[{i}]"), m.r_a[i])?;
        finite(|| format!("{what}.r_w[{i}]"), m.r_w[i])?;
    }
    positive(|| format!("{what}.position_sigma"), m.position_sigma)?;
    positive(|| format!("{what}.rotation_sigma"), m.rotation_sigma)
}

fn positive(field: impl Fn() -> String, v: f64) -> Result<(), RobotError> {
    finite(&field, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(RobotError::NotPositive {
            field: field(),
            value: v,
        })
    }
}

impl Robot {
    /// Validates a description: 1..=[`MAX_JOINTS`] joints, finite values,
    /// positive σ/limits/gravity, q_min < q_max, estimated ε within links
    /// 1..=n and k 1..=6, not ε_n4..6 (fixed: redundant with R_a, R_ω), no duplicates.
    pub fn new(desc: RobotDescription) -> Result<Self, RobotError> {
        let n = desc.joints.len();
        if n == 0 {
            return Err(RobotError::NoJoints(desc.name.clone()));
        }
        if n > MAX_JOINTS {
            return Err(RobotError::TooManyJoints { n, max: MAX_JOINTS });
        }
        positive(|| "gravity".into(), desc.gravity)?;
        check_joints(&desc.joints)?;
        check_joint_names(&desc.joint_names, n)?;
        if let Some(f) = &desc.frames {
            for (k, v) in f
                .base_to_model
                .xyz
                .iter()
                .chain(&f.base_to_model.rpy)
                .enumerate()
            {
                finite(|| format!("frames.base_to_model component {}", k + 1), *v)?;
            }
        }
        check_noise_mounts_priors(&desc)?;
        let estimated = estimated_errors(&desc, n)?;
        let links: Vec<DhLink> = desc
            .joints
            .iter()
            .map(|j| DhLink {
                theta0: j.theta0,
                d: j.d,
                a: j.a,
                alpha: j.alpha,
            })
            .collect();
        let chain = desc
            .joints
            .iter()
            .zip(&links)
            .map(|(j, &dh)| ChainLink {
                dh,
                fixed: j.origin.map(|o| o.to_iso()),
            })
            .collect();
        let limits = desc
            .joints
            .iter()
            .map(|j| JointLimits {
                q_min: j.q_min,
                q_max: j.q_max,
                qd_max: j.qd_max,
                qdd_max: j.qdd_max,
            })
            .collect();
        let sigma_q = desc.joints.iter().map(|j| j.sigma_q).collect();
        Ok(Self {
            desc,
            links,
            chain,
            limits,
            sigma_q,
            estimated,
        })
    }

    /// Parses and validates the TOML format documented in the module doc.
    pub fn from_toml_str(text: &str) -> Result<Self, RobotError> {
        Self::new(toml::from_str(text)?)
    }

    /// Reads, parses and validates a TOML file.
    pub fn from_toml_file(path: impl AsRef<Path>) -> Result<Self, RobotError> {
        let path = path.as_ref();
        let text = crate::text::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(&text)
    }

    /// The AUBO i5 reference setup of docs/model.md §6 (paper §8), in SI.
    pub fn aubo_i5() -> Self {
        use std::f64::consts::{FRAC_PI_2, PI};
        // (θ0, d, a, α, q_min°, q_max°, q̇max °/s, σ_q °)
        type Row = (f64, f64, f64, f64, f64, f64, f64, f64);
        let table: [Row; 6] = [
            (PI, 0.122, 0.0, -FRAC_PI_2, -90.0, 90.0, 10.0, 0.0038),
            (-FRAC_PI_2, 0.1215, 0.408, PI, -75.0, 75.0, 10.0, 0.0050),
            (0.0, 0.0, 0.376, PI, 30.0, 120.0, 10.0, 0.0043),
            (
                -FRAC_PI_2, 0.0, 0.0, -FRAC_PI_2, -175.0, 175.0, 25.0, 0.0105,
            ),
            (0.0, 0.1025, 0.0, FRAC_PI_2, -90.0, 90.0, 25.0, 0.0101),
            (0.0, 0.094, 0.0, 0.0, -175.0, 175.0, 25.0, 0.0086),
        ];
        let joints = table
            .iter()
            .map(
                |&(theta0, d, a, alpha, lo, hi, vmax, sq)| JointDescription {
                    theta0,
                    d,
                    a,
                    alpha,
                    q_min: lo * DEG,
                    q_max: hi * DEG,
                    qd_max: vmax * DEG,
                    qdd_max: 100.0 * DEG,
                    sigma_q: sq * DEG,
                    origin: None,
                },
            )
            .collect();
        let desc = RobotDescription {
            name: "aubo_i5".into(),
            gravity: 9.81,
            source: None,
            // aubo_description's names (as aubo_i3's and aubo_i10's), each
            // turning as the paper's model does
            joint_names: [
                "shoulder_joint",
                "upperArm_joint",
                "foreArm_joint",
                "wrist1_joint",
                "wrist2_joint",
                "wrist3_joint",
            ]
            .map(String::from)
            .to_vec(),
            frames: None,
            calibration_hash: None,
            joints,
            noise: NoiseDescription {
                sigma_z: [0.38, 0.21, 0.19, 0.32 * DEG, 0.47 * DEG, 0.57 * DEG],
            },
            imu_mount: ImuMount {
                position: [0.0252, 0.0783, 0.0182],
                position_sigma: 0.010,
                r_a: [PI, 0.0, 0.0],
                r_w: [PI, 0.0, 0.0],
                rotation_sigma: 5.0 * DEG,
            },
            priors: Priors::default(),
            errors: Some(ErrorsDescription {
                estimated: default_estimated_errors(6),
            }),
            imu_mounts: Default::default(),
        };
        Self::new(desc).expect("the built-in AUBO i5 description is valid")
    }

    /// Name.
    pub fn name(&self) -> &str {
        &self.desc.name
    }
    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.links.len()
    }
    /// DH table, base to flange: the DH part of each joint only. The full
    /// joint transforms (with any fixed `C_i`) are [`Robot::chain`].
    pub fn links(&self) -> &[DhLink] {
        &self.links
    }
    /// The kinematic chain, base to flange: DH part and fixed `C_i` per joint.
    pub fn chain(&self) -> &[ChainLink] {
        &self.chain
    }
    /// Joint limits.
    pub fn limits(&self) -> &[JointLimits] {
        &self.limits
    }
    /// Default joint noise σ_q per joint (rad).
    pub fn sigma_q(&self) -> &[f64] {
        &self.sigma_q
    }
    /// Default IMU noise σ_z `[ax, ay, az, gx, gy, gz]` (m/s², rad/s).
    pub fn sigma_z(&self) -> [f64; 6] {
        self.desc.noise.sigma_z
    }
    /// IMU mount prior.
    pub fn mount(&self) -> &ImuMount {
        &self.desc.imu_mount
    }
    /// IMU j's mount prior (docs/model.md §9): its own when
    /// [`Self::with_mount`] gave one, else IMU 0's [`Self::mount`].
    pub fn mount_of(&self, j: usize) -> &ImuMount {
        self.desc.imu_mounts.get(&j).unwrap_or(&self.desc.imu_mount)
    }
    /// The robot with IMU j's mount prior set to `mount` (j = 0: the
    /// robot's own [`Self::mount`]); refused when a number is not finite or
    /// a σ not positive.
    pub fn with_mount(&self, j: usize, mount: ImuMount) -> Result<Self, RobotError> {
        let mut d = self.desc.clone();
        if j == 0 {
            d.imu_mount = mount;
        } else {
            d.imu_mounts.insert(j, mount);
        }
        Self::new(d)
    }
    /// Prior σ.
    pub fn priors(&self) -> &Priors {
        &self.desc.priors
    }
    /// Gravity magnitude g0 (m/s²).
    pub fn gravity(&self) -> f64 {
        self.desc.gravity
    }
    /// Estimated ε, sorted by link then k.
    pub fn estimated_errors(&self) -> &[ErrorIndex] {
        &self.estimated
    }
    /// The underlying description (e.g. to modify and re-validate).
    pub fn description(&self) -> &RobotDescription {
        &self.desc
    }
    /// A copy with another estimated ε set (e.g. one found numerically).
    pub fn with_estimated_errors(&self, set: Vec<ErrorIndex>) -> Result<Self, RobotError> {
        let mut d = self.desc.clone();
        d.errors = Some(ErrorsDescription { estimated: set });
        Self::new(d)
    }
    /// A copy with another gravity magnitude g0.
    pub fn with_gravity(&self, g0: f64) -> Result<Self, RobotError> {
        let mut d = self.desc.clone();
        d.gravity = g0;
        Self::new(d)
    }
}

/// Checks every joint's DH parameters, limits, σ and fixed origin.
fn check_joint_names(names: &[String], n: usize) -> Result<(), RobotError> {
    if names.is_empty() {
        return Ok(());
    }
    if names.len() != n {
        return Err(RobotError::BadJointNames(format!(
            "{} names for {n} joints",
            names.len()
        )));
    }
    for (i, a) in names.iter().enumerate() {
        if a.is_empty() {
            return Err(RobotError::BadJointNames(format!(
                "joint {} has an empty name",
                i + 1
            )));
        }
        if names[..i].contains(a) {
            return Err(RobotError::BadJointNames(format!("`{a}` is listed twice")));
        }
    }
    Ok(())
}

fn check_joints(joints: &[JointDescription]) -> Result<(), RobotError> {
    for (i, j) in joints.iter().enumerate() {
        let f = |name: &str| format!("joint {} {name}", i + 1);
        for (name, v) in [
            ("theta0", j.theta0),
            ("d", j.d),
            ("a", j.a),
            ("alpha", j.alpha),
        ] {
            finite(|| f(name), v)?;
        }
        finite(|| f("q_min"), j.q_min)?;
        finite(|| f("q_max"), j.q_max)?;
        if j.q_min >= j.q_max {
            return Err(RobotError::EmptyRange {
                joint: i + 1,
                q_min: j.q_min,
                q_max: j.q_max,
            });
        }
        positive(|| f("qd_max"), j.qd_max)?;
        positive(|| f("qdd_max"), j.qdd_max)?;
        sigma(|| f("sigma_q"), j.sigma_q, MAX_SIGMA_Q)?;
        if let Some(o) = &j.origin {
            for k in 0..3 {
                finite(|| f(&format!("origin.xyz[{k}]")), o.xyz[k])?;
                finite(|| f(&format!("origin.rpy[{k}]")), o.rpy[k])?;
            }
        }
    }
    Ok(())
}

/// Checks the noise σ, the IMU mounts and the priors' σ.
fn check_noise_mounts_priors(desc: &RobotDescription) -> Result<(), RobotError> {
    for (i, &s) in desc.noise.sigma_z.iter().enumerate() {
        sigma(|| format!("noise.sigma_z[{i}]"), s, MAX_SIGMA_Z[i / 3])?;
    }
    check_mount("imu_mount", &desc.imu_mount)?;
    for (j, m) in &desc.imu_mounts {
        check_mount(&format!("imu{j}.mount"), m)?;
    }
    let p = &desc.priors;
    for (name, v) in [
        ("eps_length_sigma", p.eps_length_sigma),
        ("eps_angle_sigma", p.eps_angle_sigma),
        ("g_xy_sigma", p.g_xy_sigma),
        ("tau_sigma", p.tau_sigma),
        ("gamma_a_sigma", p.gamma_a_sigma),
        ("k_a_sigma", p.k_a_sigma),
        ("b_a_sigma", p.b_a_sigma),
        ("gamma_w_sigma", p.gamma_w_sigma),
        ("k_w_sigma", p.k_w_sigma),
        ("b_w_sigma", p.b_w_sigma),
    ] {
        positive(|| format!("priors.{name}"), v)?;
    }
    Ok(())
}

/// The estimated error parameters (the description's, or the default
/// set), checked (identifiable, no duplicate) and sorted.
fn estimated_errors(desc: &RobotDescription, n: usize) -> Result<Vec<ErrorIndex>, RobotError> {
    let mut estimated = match &desc.errors {
        Some(e) => e.estimated.clone(),
        None => default_estimated_errors(n),
    };
    for e in &estimated {
        let bad = |reason| RobotError::BadErrorIndex {
            link: e.link,
            k: e.k,
            reason,
        };
        if e.link == 0 {
            return Err(bad("E_0 (the base pose) is not identifiable from the IMU"));
        }
        if e.link > n {
            return Err(bad("link beyond the last joint"));
        }
        if !(1..=6).contains(&e.k) {
            return Err(bad("k must be 1..6"));
        }
        if e.link == n && e.k >= 4 {
            return Err(bad(
                "the IMU frame rotation is fixed (redundant with r_a, r_w)",
            ));
        }
    }
    estimated.sort();
    if let Some(w) = estimated.windows(2).find(|w| w[0] == w[1]) {
        return Err(RobotError::DuplicateErrorIndex {
            link: w[0].link,
            k: w[0].k,
        });
    }
    Ok(estimated)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// AUBO i5 written out by hand in the TOML format, SI numbers typed as
    /// decimals (not generated from the built-in).
    const AUBO_TOML: &str = r#"
name = "aubo_i5"
gravity = 9.81

[[joint]]
theta0 = 3.141592653589793
d = 0.122
a = 0.0
alpha = -1.5707963267948966
q_min = -1.5707963267948966
q_max = 1.5707963267948966
qd_max = 0.17453292519943295
qdd_max = 1.7453292519943295
sigma_q = 6.632251157578452e-5

[[joint]]
theta0 = -1.5707963267948966
d = 0.1215
a = 0.408
alpha = 3.141592653589793
q_min = -1.3089969389957472
q_max = 1.3089969389957472
qd_max = 0.17453292519943295
qdd_max = 1.7453292519943295
sigma_q = 8.726646259971648e-5

[[joint]]
theta0 = 0.0
d = 0.0
a = 0.376
alpha = 3.141592653589793
q_min = 0.5235987755982988
q_max = 2.0943951023931953
qd_max = 0.17453292519943295
qdd_max = 1.7453292519943295
sigma_q = 7.504915783575618e-5

[[joint]]
theta0 = -1.5707963267948966
d = 0.0
a = 0.0
alpha = -1.5707963267948966
q_min = -3.0543261909900767
q_max = 3.0543261909900767
qd_max = 0.4363323129985824
qdd_max = 1.7453292519943295
sigma_q = 1.8325957145940461e-4

[[joint]]
theta0 = 0.0
d = 0.1025
a = 0.0
alpha = 1.5707963267948966
q_min = -1.5707963267948966
q_max = 1.5707963267948966
qd_max = 0.4363323129985824
qdd_max = 1.7453292519943295
sigma_q = 1.7627825445142729e-4

[[joint]]
theta0 = 0.0
d = 0.094
a = 0.0
alpha = 0.0
q_min = -3.0543261909900767
q_max = 3.0543261909900767
qd_max = 0.4363323129985824
qdd_max = 1.7453292519943295
sigma_q = 1.5009831567151233e-4

[noise]
sigma_z = [0.38, 0.21, 0.19, 5.585053606381854e-3, 8.203047484373349e-3, 9.948376736367678e-3]

[imu_mount]
position = [0.0252, 0.0783, 0.0182]
position_sigma = 0.01
r_a = [3.141592653589793, 0.0, 0.0]
r_w = [3.141592653589793, 0.0, 0.0]
rotation_sigma = 0.08726646259971647

[priors]
eps_length_sigma = 0.001
eps_angle_sigma = 0.017453292519943295
g_xy_sigma = 0.5
tau_sigma = 1.0
gamma_a_sigma = 0.02617993877991494
k_a_sigma = 0.1
b_a_sigma = 2.0
gamma_w_sigma = 0.03490658503988659
k_w_sigma = 0.1
b_w_sigma = 0.08726646259971647

[errors]
estimated = [[1, 1], [1, 6],
  [2, 1], [2, 2], [2, 4], [2, 6],
  [3, 1], [3, 2], [3, 4], [3, 6],
  [4, 1], [4, 2], [4, 4], [4, 6],
  [5, 1], [5, 2], [5, 4], [5, 6],
  [6, 1], [6, 2], [6, 3]]
"#;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-15 * (1.0 + a.abs().max(b.abs()))
    }

    #[test]
    fn toml_equivalent_of_aubo_i5_loads_to_the_same_description() {
        let a = Robot::aubo_i5();
        let b = Robot::from_toml_str(AUBO_TOML).unwrap();
        assert_eq!(a.name(), b.name());
        assert_eq!(a.dof(), 6);
        assert_eq!(b.dof(), 6);
        assert!(close(a.gravity(), b.gravity()));
        for i in 0..6 {
            let (x, y) = (a.links()[i], b.links()[i]);
            for (u, v) in [
                (x.theta0, y.theta0),
                (x.d, y.d),
                (x.a, y.a),
                (x.alpha, y.alpha),
            ] {
                assert!(close(u, v), "joint {} DH {u} vs {v}", i + 1);
            }
            let (x, y) = (a.limits()[i], b.limits()[i]);
            for (u, v) in [
                (x.q_min, y.q_min),
                (x.q_max, y.q_max),
                (x.qd_max, y.qd_max),
                (x.qdd_max, y.qdd_max),
            ] {
                assert!(close(u, v), "joint {} limits {u} vs {v}", i + 1);
            }
            assert!(close(a.sigma_q()[i], b.sigma_q()[i]), "sigma_q {}", i + 1);
        }
        for i in 0..6 {
            assert!(close(a.sigma_z()[i], b.sigma_z()[i]), "sigma_z {i}");
        }
        let (x, y) = (a.mount(), b.mount());
        for i in 0..3 {
            assert!(close(x.position[i], y.position[i]));
            assert!(close(x.r_a[i], y.r_a[i]));
            assert!(close(x.r_w[i], y.r_w[i]));
        }
        assert!(close(x.position_sigma, y.position_sigma));
        assert!(close(x.rotation_sigma, y.rotation_sigma));
        let (x, y) = (a.priors(), b.priors());
        for (u, v) in [
            (x.eps_length_sigma, y.eps_length_sigma),
            (x.eps_angle_sigma, y.eps_angle_sigma),
            (x.g_xy_sigma, y.g_xy_sigma),
            (x.tau_sigma, y.tau_sigma),
            (x.gamma_a_sigma, y.gamma_a_sigma),
            (x.k_a_sigma, y.k_a_sigma),
            (x.b_a_sigma, y.b_a_sigma),
            (x.gamma_w_sigma, y.gamma_w_sigma),
            (x.k_w_sigma, y.k_w_sigma),
            (x.b_w_sigma, y.b_w_sigma),
        ] {
            assert!(close(u, v), "prior {u} vs {v}");
        }
        assert_eq!(a.estimated_errors(), b.estimated_errors());
        assert_eq!(a.estimated_errors().len(), 21);
    }

    #[test]
    fn aubo_i5_matches_model_md_units() {
        let r = Robot::aubo_i5();
        // Σ_q given in degrees, Σ_z gyro part in °/s: converted to SI.
        assert!((r.sigma_q()[3] - 0.0105_f64.to_radians()).abs() < 1e-18);
        assert!((r.sigma_z()[5] - 0.57_f64.to_radians()).abs() < 1e-18);
        assert!((r.limits()[2].q_min - 30f64.to_radians()).abs() < 1e-15);
        assert!((r.limits()[3].qd_max - 25f64.to_radians()).abs() < 1e-15);
    }

    #[test]
    fn validation_errors_name_the_cause() {
        let bad = AUBO_TOML.replace("sigma_q = 8.726646259971648e-5", "sigma_q = -1.0");
        let e = Robot::from_toml_str(&bad).unwrap_err();
        assert!(e.to_string().contains("joint 2 sigma_q"), "{e}");
        // Issue 41: numbers beyond their physical range, arrays of another
        // length.
        let bad = AUBO_TOML.replace("sigma_q = 8.726646259971648e-5", "sigma_q = 1e308");
        let e = Robot::from_toml_str(&bad).unwrap_err().to_string();
        assert!(
            e.contains("joint 2 sigma_q = 1e308 is beyond its range"),
            "{e}"
        );
        let bad = AUBO_TOML.replace("sigma_z = [0.38,", "sigma_z = [0.38, 0.1,");
        let e = Robot::from_toml_str(&bad).unwrap_err().to_string();
        assert!(
            e.contains("7 values where 6 are expected (ax ay az gx gy gz)"),
            "{e}"
        );
        let bad = AUBO_TOML.replace("sigma_q = 8.726646259971648e-5", "sigma_q = 0.5");
        let e = Robot::from_toml_str(&bad).unwrap_err().to_string();
        assert!(
            e.contains("sigma_q = 5e-1 is beyond its range (at most 1e-1"),
            "{e}"
        );
        let bad = AUBO_TOML.replace("[6, 1], [6, 2], [6, 3]]", "[6, 1], [6, 2], [6, 4]]");
        let e = Robot::from_toml_str(&bad).unwrap_err();
        assert!(
            matches!(e, RobotError::BadErrorIndex { link: 6, k: 4, .. }),
            "{e}"
        );
        let bad = AUBO_TOML.replace("[1, 1], [1, 6],", "[1, 1], [1, 1],");
        let e = Robot::from_toml_str(&bad).unwrap_err();
        assert!(
            matches!(e, RobotError::DuplicateErrorIndex { link: 1, k: 1 }),
            "{e}"
        );
        let bad = AUBO_TOML.replace("q_min = 0.5235987755982988", "q_min = 2.5");
        let e = Robot::from_toml_str(&bad).unwrap_err();
        assert!(matches!(e, RobotError::EmptyRange { joint: 3, .. }), "{e}");
        let bad = AUBO_TOML.replace("d = 0.122", "dd = 0.122");
        assert!(matches!(
            Robot::from_toml_str(&bad),
            Err(RobotError::Toml(_))
        ));
        let e = Robot::from_toml_file("/nonexistent/robot.toml").unwrap_err();
        assert!(e.to_string().contains("/nonexistent/robot.toml"), "{e}");
    }

    #[test]
    fn module_doc_example_loads() {
        let src = include_str!("robot.rs");
        let start = src.find("//! ```toml\n").unwrap() + "//! ```toml\n".len();
        let len = src[start..].find("//! ```\n").unwrap();
        let text: String = src[start..start + len]
            .lines()
            .map(|l| l.strip_prefix("//!").unwrap().trim_start())
            .collect::<Vec<_>>()
            .join("\n");
        let r = Robot::from_toml_str(&text).unwrap();
        assert_eq!(r.name(), "planar_2r");
        assert_eq!(r.dof(), 2);
        assert_eq!(r.links()[1].a, 0.25);
        assert_eq!(r.estimated_errors().len(), 5);
    }

    #[test]
    fn optional_tables_take_defaults() {
        let text = AUBO_TOML
            .split("[priors]")
            .next()
            .unwrap()
            .replace("gravity = 9.81\n", "");
        let r = Robot::from_toml_str(&text).unwrap();
        assert_eq!(r.gravity(), 9.81);
        assert_eq!(r.priors(), &Priors::default());
        assert_eq!(r.estimated_errors(), Robot::aubo_i5().estimated_errors());
    }

    #[test]
    fn a_joint_origin_is_the_fixed_transform_after_the_dh_part() {
        let text = AUBO_TOML.replacen(
            "sigma_q = 6.632251157578452e-5",
            "sigma_q = 6.632251157578452e-5\norigin = { xyz = [0.1, -0.2, 0.3], rpy = [0.4, -0.5, 0.6] }",
            1,
        );
        let r = Robot::from_toml_str(&text).unwrap();
        let c = r.chain()[0].fixed.expect("joint 1 has an origin");
        // Rz(yaw)·Ry(pitch)·Rx(roll), written out: the URDF convention.
        let (sr, cr, sp, cp, sy, cy) = (
            0.4f64.sin(),
            0.4f64.cos(),
            (-0.5f64).sin(),
            (-0.5f64).cos(),
            0.6f64.sin(),
            0.6f64.cos(),
        );
        let want = [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ];
        for i in 0..3 {
            for j in 0..3 {
                assert!((c.r[i][j] - want[i][j]).abs() < 1e-15);
            }
        }
        assert_eq!(c.p, [0.1, -0.2, 0.3]);
        assert!(r.chain()[1..].iter().all(|l| l.fixed.is_none()));
        let bad = text.replacen("xyz = [0.1,", "xyz = [nan,", 1);
        let e = Robot::from_toml_str(&bad).unwrap_err().to_string();
        assert!(e.contains("origin.xyz[0]"), "{e}");
    }
}
