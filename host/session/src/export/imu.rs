//! The IMU intrinsics for other tools, and the inverse sensor model.
//!
//! The sensor model (docs/model.md §3, paper eq. (6)) is, per sensor,
//!
//! ```text
//! z = M·v + b,   M = K·Γ·R
//! v = M⁻¹·(z − b)            (the correction)
//! ```
//!
//! with v the physical vector (specific force s in m/s², angular rate ω in
//! rad/s) in robimu's IMU frame (origin at the IMU, axes those of the robot
//! flange), z the raw output. [`Correction`] writes M, M⁻¹ and b per sensor
//! for firmware or a driver; [`correct_rows`] applies it to an `imu.csv`.
//!
//! Kalibr's `scale-misalignment` IMU model takes the accelerometer axes as
//! the IMU frame `i`: `a_m = M_a·a_i + b_a`, `ω_m = M_g·C_gyro_i·ω_i + A·a_i + b_g`
//! (M lower triangular). In those terms `M_a = K_a·Γ_a`, `M_g = K_ω·Γ_ω`,
//! `C_gyro_i = R_ω·R_aᵀ`, `A = 0`, and `T_i_b` (body = robimu's IMU frame) has
//! the rotation `R_a` ([`kalibr_imu_yaml`]).

use serde::{Deserialize, Serialize};

use robimu_model::geom::{self, M3};
use robimu_model::{ImuIntrinsics, ModelParams};

use super::ExportError;

/// One sensor's correction: raw `z = M·v + b`, corrected `v = M⁻¹·(z − b)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorCorrection {
    /// Unit of z, b and v (`m/s^2` or `rad/s`).
    pub unit: String,
    /// M = K·Γ·R (rows).
    pub matrix: M3,
    /// M⁻¹ (rows).
    pub inverse: M3,
    /// b.
    pub bias: [f64; 3],
}

impl SensorCorrection {
    fn new(s: &ImuIntrinsics, unit: &str, name: &'static str) -> Result<Self, ExportError> {
        let matrix = s.matrix();
        let inverse = inverse(&matrix).ok_or(ExportError::Singular(name))?;
        Ok(Self {
            unit: unit.into(),
            matrix,
            inverse,
            bias: s.b,
        })
    }

    /// `M⁻¹·(z − b)`.
    pub fn apply(&self, z: [f64; 3]) -> [f64; 3] {
        geom::mul_mv(&self.inverse, geom::sub(z, self.bias))
    }
}

/// The correction file (TOML): `format`, then one table per sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Correction {
    /// Always [`CORRECTION_FORMAT`].
    pub format: String,
    /// Accelerometer (m/s²).
    pub accelerometer: SensorCorrection,
    /// Gyroscope (rad/s).
    pub gyroscope: SensorCorrection,
}

/// The `format` string of a correction file.
pub const CORRECTION_FORMAT: &str = "robimu-imu-correction/1";

impl Correction {
    /// From calibrated parameters.
    pub fn new(params: &ModelParams) -> Result<Self, ExportError> {
        Self::from_intrinsics(&params.accel, &params.gyro)
    }

    /// From the accelerometer and gyroscope intrinsics.
    pub fn from_intrinsics(
        accel: &ImuIntrinsics,
        gyro: &ImuIntrinsics,
    ) -> Result<Self, ExportError> {
        Ok(Self {
            format: CORRECTION_FORMAT.into(),
            accelerometer: SensorCorrection::new(accel, "m/s^2", "accelerometer")?,
            gyroscope: SensorCorrection::new(gyro, "rad/s", "gyroscope")?,
        })
    }

    /// The corrected `[ax, ay, az, gx, gy, gz]` (s and ω in robimu's IMU frame).
    pub fn apply(&self, z: &[f64; 6]) -> [f64; 6] {
        let a = self.accelerometer.apply([z[0], z[1], z[2]]);
        let w = self.gyroscope.apply([z[3], z[4], z[5]]);
        [a[0], a[1], a[2], w[0], w[1], w[2]]
    }

    /// The TOML text, with a comment saying how to apply it.
    pub fn to_toml(&self) -> Result<String, ExportError> {
        Ok(format!(
            "# IMU correction written by robimu. Per sensor, raw z = matrix·v + bias\n\
             # (docs/model.md §3: matrix = K·Γ·R); apply v = inverse·(z − bias) to get the\n\
             # specific force (m/s²) and angular rate (rad/s) in the IMU frame (axes of\n\
             # the robot flange). Matrices are row-major: matrix[r][c].\n{}",
            toml::to_string(self)?
        ))
    }
}

/// The inverse of a 3×3 matrix (adjugate / determinant), `None` if singular.
pub fn inverse(m: &M3) -> Option<M3> {
    let c = |i: usize, j: usize| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    if !det.is_finite() || det.abs() <= 1e-12 * scale.powi(3) {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inv[i][j] = c(j, i) / det;
        }
    }
    Some(inv)
}

/// The inverse sensor model applied to every row of an IMU table
/// (`[ax, ay, az, gx, gy, gz]` per row): `Rᵀ·Γ⁻¹·K⁻¹·(z − b)` per sensor
/// ([`ImuIntrinsics::invert`]).
pub fn correct_rows(
    accel: &ImuIntrinsics,
    gyro: &ImuIntrinsics,
    rows: &[[f64; 6]],
) -> Result<Vec<[f64; 6]>, ExportError> {
    let singular = |name| move |_| ExportError::Singular(name);
    rows.iter()
        .map(|z| {
            let a = accel
                .invert([z[0], z[1], z[2]])
                .map_err(singular("accelerometer"))?;
            let w = gyro
                .invert([z[3], z[4], z[5]])
                .map_err(singular("gyroscope"))?;
            Ok([a[0], a[1], a[2], w[0], w[1], w[2]])
        })
        .collect()
}

/// What a Kalibr `imu.yaml` needs beyond the intrinsics.
#[derive(Clone, Debug, PartialEq)]
pub struct KalibrOptions {
    /// IMU sample rate (Hz): `update_rate`, and the noise density
    /// σ_c = σ_d / √rate of the per-sample σ_d.
    pub rate: f64,
    /// Per-sample σ of `[ax, ay, az, gx, gy, gz]` (m/s², rad/s); the largest
    /// of each sensor's three is written (Kalibr has one per sensor).
    pub sigma_z: [f64; 6],
    /// `rostopic`.
    pub rostopic: String,
    /// `accelerometer_random_walk` (m/s³/√Hz) and `gyroscope_random_walk`
    /// (rad/s²/√Hz). robimu's biases are constant, so these are not
    /// estimated; Kalibr divides by them (its bias-motion weight is 1/σ²),
    /// so they must be positive.
    pub random_walk: [f64; 2],
}

/// Default random walks for [`KalibrOptions::random_walk`]: placeholders of
/// the order of consumer MEMS IMUs (accelerometer 1e-3 m/s³/√Hz, gyroscope
/// 1e-4 rad/s²/√Hz); measure yours from a long static recording.
pub const DEFAULT_RANDOM_WALK: [f64; 2] = [1e-3, 1e-4];

fn yaml_matrix(indent: &str, m: &M3) -> String {
    m.iter()
        .map(|r| format!("{indent}- [{:?}, {:?}, {:?}]\n", r[0], r[1], r[2]))
        .collect()
}

/// Kalibr's `imu.yaml` (input keys, and the calibrated `scale-misalignment`
/// intrinsics of its result file; see the module doc). The random walks are
/// the given placeholders: robimu's model has constant biases. The estimated biases are written
/// as the extra keys `accelerometers.b` / `gyroscopes.b` (Kalibr estimates
/// biases as time series and has no key for them).
pub fn kalibr_imu_yaml(params: &ModelParams, opts: &KalibrOptions) -> String {
    let (a, g) = (&params.accel, &params.gyro);
    let kg = |s: &ImuIntrinsics| {
        let mut m = s.gamma_matrix();
        for (row, k) in m.iter_mut().zip(s.k) {
            for e in row.iter_mut() {
                *e *= k;
            }
        }
        m
    };
    let ra = a.rotation();
    let c_gyro_i = geom::mul_mm(&g.rotation(), &geom::transpose(&ra));
    let acc_nd = opts.sigma_z[..3].iter().fold(0.0f64, |x, v| x.max(*v)) / opts.rate.sqrt();
    let gyr_nd = opts.sigma_z[3..].iter().fold(0.0f64, |x, v| x.max(*v)) / opts.rate.sqrt();
    let mut t_i_b = String::new();
    for r in 0..3 {
        t_i_b.push_str(&format!(
            "  - [{:?}, {:?}, {:?}, 0.0]\n",
            ra[r][0], ra[r][1], ra[r][2]
        ));
    }
    t_i_b.push_str("  - [0.0, 0.0, 0.0, 1.0]\n");
    format!(
        "# Kalibr imu.yaml written by robimu: noise densities from the per-sample\n\
         # noise σ and the rate; scale-misalignment intrinsics from the calibration\n\
         # (IMU frame i = accelerometer axes; body b = robimu's IMU frame, axes of the\n\
         # robot flange). Random walks are not estimated by robimu (constant biases):\n\
         # the values below are placeholders (robimu export --random-walk A,G).\n\
         imu0:\n  \
         T_i_b:\n{t_i_b}  \
         accelerometer_noise_density: {acc_nd:?}  # [ m / s^2 / sqrt(Hz) ]\n  \
         accelerometer_random_walk: {arw:?}  # [ m / s^3 / sqrt(Hz) ]\n  \
         gyroscope_noise_density: {gyr_nd:?}  # [ rad / s / sqrt(Hz) ]\n  \
         gyroscope_random_walk: {grw:?}  # [ rad / s^2 / sqrt(Hz) ]\n  \
         model: scale-misalignment\n  \
         rostopic: {topic}\n  \
         time_offset: 0.0\n  \
         update_rate: {rate:?}\n  \
         accelerometers:\n    M:\n{ma}    b: [{ab0:?}, {ab1:?}, {ab2:?}]  # m/s^2 (robimu extra)\n  \
         gyroscopes:\n    A:\n{za}    C_gyro_i:\n{cg}    M:\n{mg}    b: [{gb0:?}, {gb1:?}, {gb2:?}]  # rad/s (robimu extra)\n",
        topic = opts.rostopic,
        rate = opts.rate,
        arw = opts.random_walk[0],
        grw = opts.random_walk[1],
        ma = yaml_matrix("    ", &kg(a)),
        za = yaml_matrix("    ", &[[0.0; 3]; 3]),
        cg = yaml_matrix("    ", &c_gyro_i),
        mg = yaml_matrix("    ", &kg(g)),
        ab0 = a.b[0],
        ab1 = a.b[1],
        ab2 = a.b[2],
        gb0 = g.b[0],
        gb1 = g.b[1],
        gb2 = g.b[2],
    )
}

/// An IMU CSV could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}", path.display())]
pub struct ImuCsvError {
    /// The file.
    pub path: std::path::PathBuf,
    /// Why.
    #[source]
    pub source: csv::Error,
}

/// Writes samples `[ax, ay, az, gx, gy, gz]` at times `t` as an imu.csv
/// (header `t,ax,ay,az,gx,gy,gz`, SI, numbers in their shortest decimal form).
pub fn write_imu_csv(
    path: &std::path::Path,
    t: &[f64],
    rows: &[[f64; 6]],
) -> Result<(), ImuCsvError> {
    let fail = |source| ImuCsvError {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_path(path).map_err(fail)?;
    w.write_record(["t", "ax", "ay", "az", "gx", "gy", "gz"])
        .map_err(fail)?;
    for (t, z) in t.iter().zip(rows) {
        let mut rec = vec![t.to_string()];
        rec.extend(z.iter().map(|v| v.to_string()));
        w.write_record(&rec).map_err(fail)?;
    }
    w.flush().map_err(|e| fail(e.into()))
}
