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
//! `C_gyro_i = R_ω·R_aᵀ`, `A = G·R_ωᵀ` (G of `g_sensitivity`, else 0), and
//! `T_i_b` (body = robimu's IMU frame) has the rotation `R_a`; the
//! `scale-misalignment-size-effect` lever arms are `R_a·r_y`, `R_a·r_z`
//! ([`KalibrIntrinsics`], [`kalibr_imu_yaml`]).

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
pub(crate) const CORRECTION_FORMAT: &str = "robimu-imu-correction/1";

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
    /// Noise densities (accelerometer m/s²/√Hz, gyroscope rad/s/√Hz) that
    /// replace σ_z/√rate, e.g. the Allan deviation's N.
    pub noise_density: Option<[f64; 2]>,
    /// Where the noise densities come from (a comment in the file).
    pub noise_source: String,
    /// `rostopic`.
    pub rostopic: String,
    /// Whose axes body b has, for the file's comments: [`FLANGE_AXES`]
    /// (a joint session's IMU frame) or [`POSED_BODY_AXES`] (a pose
    /// session's, docs/model.md §7.9).
    pub body_axes: &'static str,
    /// `accelerometer_random_walk` (m/s³/√Hz) and `gyroscope_random_walk`
    /// (rad/s²/√Hz). robimu's biases are constant, so these are not
    /// estimated by the calibration; Kalibr divides by them (its
    /// bias-motion weight is 1/σ²), so they must be positive.
    pub random_walk: [f64; 2],
    /// Where the random walks come from; `None`: they are placeholders.
    pub random_walk_source: Option<String>,
    /// The fitted `g_sensitivity` G (rows: gyroscope sensor axes; columns:
    /// specific force in robimu's IMU frame), docs/model.md §4.5.
    pub g_sensitivity: Option<M3>,
    /// The fitted `size_effect` lever arms r_y, r_z (m, robimu's IMU frame,
    /// relative to the x axis), docs/model.md §4.5.
    pub size_effect: Option<[[f64; 3]; 2]>,
}

/// [`KalibrOptions::body_axes`] of a joint session.
pub const FLANGE_AXES: &str = "axes of the robot flange";
/// [`KalibrOptions::body_axes`] of a pose session.
pub const POSED_BODY_AXES: &str = "axes of the posed body B";

/// Default random walks for [`KalibrOptions::random_walk`]: placeholders of
/// the order of consumer MEMS IMUs (accelerometer 1e-3 m/s³/√Hz, gyroscope
/// 1e-4 rad/s²/√Hz); measure yours from a long static recording.
pub const DEFAULT_RANDOM_WALK: [f64; 2] = [1e-3, 1e-4];

fn yaml_matrix(indent: &str, m: &M3) -> String {
    m.iter()
        .map(|r| format!("{indent}- [{:?}, {:?}, {:?}]\n", r[0], r[1], r[2]))
        .collect()
}

fn yaml_vector(v: &[f64; 3]) -> String {
    format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2])
}

/// The Kalibr IMU intrinsics of robimu's model (module doc; Kalibr's
/// `IccScaledMisalignedImu` / `…SizeEffectImu` measurement equations):
///
/// ```text
/// accelerometers.M = K_a·Γ_a         T_i_b rotation C_i_b = R_a
/// gyroscopes.M     = K_ω·Γ_ω         gyroscopes.C_gyro_i = R_ω·R_aᵀ
/// gyroscopes.A     = G·R_ωᵀ          (ω_m = M·C_gyro_b·ω + A·C_gyro_b·s, C_gyro_b = R_ω)
/// accelerometers.rx_i = 0, ry_i = R_a·r_y, rz_i = R_a·r_z
/// ```
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct KalibrIntrinsics {
    /// `T_i_b`'s rotation C_i_b.
    pub c_i_b: M3,
    /// `accelerometers.M`.
    pub m_accel: M3,
    /// `gyroscopes.M`.
    pub m_gyro: M3,
    /// `gyroscopes.A`, rad/s per m/s².
    pub a_gyro: M3,
    /// `gyroscopes.C_gyro_i`.
    pub c_gyro_i: M3,
    /// `accelerometers.rx_i`, `ry_i`, `rz_i` (m), when the size effect was fitted.
    pub levers: Option<[[f64; 3]; 3]>,
}

impl KalibrIntrinsics {
    /// From robimu's intrinsics and the fitted effects.
    pub fn new(params: &ModelParams, g: Option<&M3>, size: Option<&[[f64; 3]; 2]>) -> Self {
        let kg = |s: &ImuIntrinsics| {
            let mut m = s.gamma_matrix();
            for (row, k) in m.iter_mut().zip(s.k) {
                for e in row.iter_mut() {
                    *e *= k;
                }
            }
            m
        };
        let (ra, rw) = (params.accel.rotation(), params.gyro.rotation());
        Self {
            c_i_b: ra,
            m_accel: kg(&params.accel),
            m_gyro: kg(&params.gyro),
            a_gyro: g.map_or([[0.0; 3]; 3], |g| geom::mul_mm(g, &geom::transpose(&rw))),
            c_gyro_i: geom::mul_mm(&rw, &geom::transpose(&ra)),
            levers: size.map(|[ry, rz]| [[0.0; 3], geom::mul_mv(&ra, *ry), geom::mul_mv(&ra, *rz)]),
        }
    }
}

/// Kalibr's `imu.yaml` (its input keys, and the calibrated intrinsics in the
/// keys of its result file: model `scale-misalignment`, or
/// `scale-misalignment-size-effect` when the size effect was fitted; see
/// [`KalibrIntrinsics`]). `gyroscopes.A` is G from `g_sensitivity` when
/// fitted, else zero. The random walks are placeholders unless
/// [`KalibrOptions::random_walk_source`] names their source (robimu's model
/// has constant biases). The estimated biases are written as the extra keys
/// `accelerometers.b` / `gyroscopes.b` (Kalibr estimates biases as time
/// series and has no key for them).
///
/// Kalibr's size-effect equation adds axis k's lever acceleration to
/// component k of the specific force *before* M_a; robimu's (§4.5) adds
/// axis i's to the whole row i. They agree exactly when Γ_a = I and
/// otherwise differ by Σ_j (M_a)_ij·(C_i_b·(λ(r_i) − λ(r_j)))_j, a product
/// of a misalignment and a lever acceleration difference.
pub fn kalibr_imu_yaml(params: &ModelParams, opts: &KalibrOptions) -> String {
    let entry = kalibr_entry(params, opts, &KalibrPlacement::default());
    format!(
        "# Kalibr imu.yaml written by robimu. Noise densities: {noise}.\n\
         # Intrinsics from the calibration (IMU frame i = accelerometer axes; body b =\n\
         # robimu's IMU frame, {axes}, origin at the accelerometer x axis).\n\
         {walk}imu0:\n{body}",
        noise = opts.noise_source,
        axes = opts.body_axes,
        walk = walk_note(opts),
        body = indent(&entry),
    )
}

/// Where one IMU of several sits in Kalibr's multi-IMU terms (docs/model.md
/// §9): body b is IMU 0's robimu frame (axes of the robot flange, origin at
/// IMU 0's position p_0 = ε_n1..3), IMU j at p_j with time offset τ_j.
///
/// ```text
/// T_i_b = [C_i_b | C_i_b·(p_0 − p_j)]   (a point x_b of b is x_b + p_0 − p_j from IMU j)
/// time_offset = τ_j − τ_0                (Kalibr: t_imu0 = t_imuj + time_offset)
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KalibrPlacement {
    /// p_0 − p_j, m, in the flange axes.
    pub offset: [f64; 3],
    /// τ_j − τ_0, s.
    pub time_offset: f64,
}

impl KalibrPlacement {
    /// IMU `imu`'s placement relative to IMU `reference` (IMU 0), from
    /// their calibrated parameters (ε_n1..3 of the last link, τ).
    pub fn relative(reference: &ModelParams, imu: &ModelParams) -> Self {
        let p = |m: &ModelParams| {
            let last = m.eps.last().copied().unwrap_or([0.0; 6]);
            [last[0], last[1], last[2]]
        };
        Self {
            offset: geom::sub(p(reference), p(imu)),
            time_offset: imu.tau - reference.tau,
        }
    }
}

/// One IMU for [`kalibr_imu_list_yaml`] and [`kalibr_imu_input_yaml`].
#[derive(Clone, Debug)]
pub struct KalibrImu<'a> {
    /// Its calibrated parameters ([`crate::export::calibrated_params`] of
    /// `CalibrationResult::imu(j)`).
    pub params: &'a ModelParams,
    /// Its noise, rate, topic and effects.
    pub opts: &'a KalibrOptions,
    /// Where it is relative to IMU 0.
    pub placement: KalibrPlacement,
}

/// The comment above the entries of a multi-IMU file.
fn list_header(imus: &[KalibrImu<'_>]) -> String {
    let same = imus
        .iter()
        .all(|m| m.opts.noise_source == imus[0].opts.noise_source);
    let sources: Vec<String> = if same {
        vec![format!("every IMU: {}", imus[0].opts.noise_source)]
    } else {
        imus.iter()
            .enumerate()
            .map(|(j, m)| format!("imu{j}: {}", m.opts.noise_source))
            .collect()
    };
    let mut walks: Vec<String> = Vec::new();
    for m in imus {
        let w = walk_note(m.opts);
        if !walks.contains(&w) {
            walks.push(w);
        }
    }
    format!(
        "# Kalibr IMU file written by robimu from a calibration of {k} IMUs (docs/model.md §9).\n\
         # Noise densities: {sources}.\n\
         # Intrinsics from the calibration (IMU frame i = accelerometer axes). Body b = IMU 0's\n\
         # robimu frame ({axes}, origin at IMU 0); T_i_b's translation is\n\
         # C_i_b·(p_0 − p_j) from the IMU positions, time_offset = tau_j − tau_0 (on IMU 0's clock).\n\
         {walks}",
        k = imus.len(),
        axes = imus[0].opts.body_axes,
        sources = sources.join("; "),
        walks = walks.concat(),
    )
}

/// Kalibr's IMU list: `imu0:`, `imu1:`, … one entry per IMU, each as in
/// [`kalibr_imu_yaml`] with its own T_i_b and time_offset
/// ([`KalibrPlacement`]) — the form of the IMU file Kalibr writes after a
/// multi-IMU calibration (its `ImuSetParameters`).
pub fn kalibr_imu_list_yaml(imus: &[KalibrImu<'_>]) -> String {
    let mut out = list_header(imus);
    for (j, m) in imus.iter().enumerate() {
        out.push_str(&format!(
            "imu{j}:\n{}",
            indent(&kalibr_entry(m.params, m.opts, &m.placement))
        ));
    }
    out
}

/// One IMU as Kalibr's `--imu` input reads it (`kalibr_calibrate_imu_camera
/// --imu imu0.yaml imu1.yaml …`: the keys at the top level, its
/// `ImuParameters`), with the calibrated T_i_b, time_offset and intrinsics
/// of [`kalibr_imu_list_yaml`]'s entry as further keys. `j` names it.
pub fn kalibr_imu_input_yaml(j: usize, imus: &[KalibrImu<'_>]) -> String {
    let m = &imus[j];
    format!(
        "{}# IMU {j} alone, as kalibr_calibrate_imu_camera --imu reads it (IMU 0 first: the reference).\n{}",
        list_header(imus),
        kalibr_entry(m.params, m.opts, &m.placement)
    )
}

/// Every line of `text` indented by two spaces.
fn indent(text: &str) -> String {
    text.lines().map(|l| format!("  {l}\n")).collect()
}

/// The note on the random walks.
fn walk_note(opts: &KalibrOptions) -> String {
    match &opts.random_walk_source {
        Some(src) => format!("# Random walks: {src}.\n"),
        None => "# Random walks are not estimated by the calibration (constant biases):\n\
                 # the values below are PLACEHOLDERS (robimu export --noise allan.csv, or\n\
                 # --random-walk A,G).\n"
            .to_string(),
    }
}

/// One IMU's keys, at the top level (see [`kalibr_imu_yaml`]).
fn kalibr_entry(params: &ModelParams, opts: &KalibrOptions, place: &KalibrPlacement) -> String {
    let (a, g) = (&params.accel, &params.gyro);
    let k = KalibrIntrinsics::new(
        params,
        opts.g_sensitivity.as_ref(),
        opts.size_effect.as_ref(),
    );
    let largest = |v: &[f64]| v.iter().fold(0.0f64, |x, v| x.max(*v));
    let [acc_nd, gyr_nd] = opts.noise_density.unwrap_or([
        largest(&opts.sigma_z[..3]) / opts.rate.sqrt(),
        largest(&opts.sigma_z[3..]) / opts.rate.sqrt(),
    ]);
    let t = geom::mul_mv(&k.c_i_b, place.offset);
    let mut t_i_b = String::new();
    for r in 0..3 {
        let c = k.c_i_b[r];
        t_i_b.push_str(&format!(
            "- [{:?}, {:?}, {:?}, {:?}]\n",
            c[0],
            c[1],
            c[2],
            t[r] + 0.0
        ));
    }
    t_i_b.push_str("- [0.0, 0.0, 0.0, 1.0]\n");
    let model = if k.levers.is_some() {
        "scale-misalignment-size-effect"
    } else {
        "scale-misalignment"
    };
    let levers = k.levers.map_or(String::new(), |[rx, ry, rz]| {
        format!(
            "  rx_i: {}  # m\n  ry_i: {}  # m\n  rz_i: {}  # m\n",
            yaml_vector(&rx),
            yaml_vector(&ry),
            yaml_vector(&rz)
        )
    });
    let a_note = if opts.g_sensitivity.is_some() {
        "from g_sensitivity"
    } else {
        "g_sensitivity not fitted: zero"
    };
    format!(
        "T_i_b:\n{t_i_b}\
         accelerometer_noise_density: {acc_nd:?}  # [ m / s^2 / sqrt(Hz) ]\n\
         accelerometer_random_walk: {arw:?}  # [ m / s^3 / sqrt(Hz) ]\n\
         gyroscope_noise_density: {gyr_nd:?}  # [ rad / s / sqrt(Hz) ]\n\
         gyroscope_random_walk: {grw:?}  # [ rad / s^2 / sqrt(Hz) ]\n\
         model: {model}\n\
         rostopic: {topic}\n\
         time_offset: {dt:?}\n\
         update_rate: {rate:?}\n\
         accelerometers:\n  M:\n{ma}{levers}  b: {ab}  # m/s^2 (robimu extra)\n\
         gyroscopes:\n  A:  # (rad/s)/(m/s^2), {a_note}\n{za}  C_gyro_i:\n{cg}  M:\n{mg}  b: {gb}  # rad/s (robimu extra)\n",
        topic = opts.rostopic,
        rate = opts.rate,
        dt = place.time_offset + 0.0,
        arw = opts.random_walk[0],
        grw = opts.random_walk[1],
        ma = yaml_matrix("  ", &k.m_accel),
        za = yaml_matrix("  ", &k.a_gyro),
        cg = yaml_matrix("  ", &k.c_gyro_i),
        mg = yaml_matrix("  ", &k.m_gyro),
        ab = yaml_vector(&a.b),
        gb = yaml_vector(&g.b),
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

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::geom::{add, cross, mul_mm, mul_mv, transpose};
    use robimu_model::{ParamLayout, Robot};

    type Yaml = serde_yaml::Value;

    fn params(gamma_a: [f64; 3]) -> ModelParams {
        let layout = ParamLayout::new(&Robot::aubo_i5());
        let mut p = layout.unpack(&layout.nominal()).unwrap();
        p.accel = ImuIntrinsics {
            gamma: gamma_a,
            r: [0.03, -0.02, 1.2],
            k: [1.01, 0.98, 1.003],
            b: [0.1, -0.2, 0.05],
        };
        p.gyro = ImuIntrinsics {
            gamma: [-0.004, 0.006, 0.002],
            r: [0.035, -0.015, 1.21],
            k: [0.99, 1.02, 1.007],
            b: [0.01, 0.003, -0.02],
        };
        p
    }

    fn options(g: Option<M3>, size: Option<[[f64; 3]; 2]>) -> KalibrOptions {
        KalibrOptions {
            rate: 200.0,
            sigma_z: [0.02, 0.03, 0.01, 0.002, 0.001, 0.003],
            noise_density: None,
            noise_source: "test".into(),
            rostopic: "/imu0".into(),
            body_axes: FLANGE_AXES,
            random_walk: DEFAULT_RANDOM_WALK,
            random_walk_source: None,
            g_sensitivity: g,
            size_effect: size,
        }
    }

    fn matrix(v: &Yaml) -> M3 {
        let rows: Vec<Vec<f64>> = serde_yaml::from_value(v.clone()).unwrap();
        assert_eq!(rows.len(), 3);
        std::array::from_fn(|r| std::array::from_fn(|c| rows[r][c]))
    }

    fn vector(v: &Yaml) -> [f64; 3] {
        let x: Vec<f64> = serde_yaml::from_value(v.clone()).unwrap();
        [x[0], x[1], x[2]]
    }

    /// The lever acceleration ω̇ × r + ω × (ω × r).
    fn lever(w: [f64; 3], wd: [f64; 3], r: [f64; 3]) -> [f64; 3] {
        add(cross(wd, r), cross(w, cross(w, r)))
    }

    /// Kalibr's measurement equations (IccSensors.py, IccScaledMisalignedImu
    /// and IccScaledMisalignedSizeEffectImu, body point r_b = 0) with the
    /// matrices read from the YAML: (a_m, ω_m) for specific force s at the
    /// body origin, ω and ω̇ in the body frame.
    fn kalibr_model(y: &Yaml, s: [f64; 3], w: [f64; 3], wd: [f64; 3]) -> ([f64; 3], [f64; 3]) {
        kalibr_entry_model(&y["imu0"], s, w, wd)
    }

    /// [`kalibr_model`] of one entry (the keys of one IMU).
    fn kalibr_entry_model(
        imu: &Yaml,
        s: [f64; 3],
        w: [f64; 3],
        wd: [f64; 3],
    ) -> ([f64; 3], [f64; 3]) {
        let t: Vec<Vec<f64>> = serde_yaml::from_value(imu["T_i_b"].clone()).unwrap();
        let c_i_b: M3 = std::array::from_fn(|r| std::array::from_fn(|c| t[r][c]));
        let acc = &imu["accelerometers"];
        let gyr = &imu["gyroscopes"];
        let ma = matrix(&acc["M"]);
        let mut u = mul_mv(&c_i_b, s);
        if imu["model"].as_str() == Some("scale-misalignment-size-effect") {
            for (k, key) in ["rx_i", "ry_i", "rz_i"].iter().enumerate() {
                let r_b = mul_mv(&transpose(&c_i_b), vector(&acc[*key]));
                u[k] += mul_mv(&c_i_b, lever(w, wd, r_b))[k];
            }
        }
        let a = add(mul_mv(&ma, u), vector(&acc["b"]));
        let c_gyro_b = mul_mm(&matrix(&gyr["C_gyro_i"]), &c_i_b);
        let g = add(
            add(
                mul_mv(&matrix(&gyr["M"]), mul_mv(&c_gyro_b, w)),
                mul_mv(&matrix(&gyr["A"]), mul_mv(&c_gyro_b, s)),
            ),
            vector(&gyr["b"]),
        );
        (a, g)
    }

    /// robimu's model (docs/model.md §3 eq. (6), §4.5 g_sensitivity and
    /// size_effect): z_a,i = (M_a)_i·(s + λ(r_i)) + b_a (r_x = 0),
    /// z_ω = M_ω·ω + G·s + b_ω.
    fn robimu_model(
        p: &ModelParams,
        g: &M3,
        size: &[[f64; 3]; 2],
        s: [f64; 3],
        w: [f64; 3],
        wd: [f64; 3],
    ) -> ([f64; 3], [f64; 3]) {
        let ma = p.accel.matrix();
        let r = [[0.0; 3], size[0], size[1]];
        let a = std::array::from_fn(|i| {
            let f = add(s, lever(w, wd, r[i]));
            (0..3).map(|j| ma[i][j] * f[j]).sum::<f64>() + p.accel.b[i]
        });
        let gw = add(p.gyro.apply(w), mul_mv(g, s));
        (a, gw)
    }

    const G: M3 = [
        [1e-3, -4e-4, 2e-4],
        [3e-4, 8e-4, -6e-4],
        [-2e-4, 5e-4, 1.2e-3],
    ];
    const SIZE: [[f64; 3]; 2] = [[8e-4, -5e-4, 3e-4], [-4e-4, 7e-4, 6e-4]];

    #[test]
    fn kalibr_equations_with_the_exported_matrices_reproduce_robimus_model() {
        let vectors = [
            ([1.2, -9.6, 2.3], [0.7, -1.9, 2.6], [15.0, -8.0, 22.0]),
            ([-4.0, 3.0, 8.5], [-2.2, 0.4, -1.1], [-30.0, 12.0, 5.0]),
        ];
        // Without misalignment of the accelerometer the two size-effect
        // equations are the same: equal to rounding.
        for gamma_a in [[0.0; 3], [0.003, -0.005, 0.004]] {
            let p = params(gamma_a);
            let y: Yaml =
                serde_yaml::from_str(&kalibr_imu_yaml(&p, &options(Some(G), Some(SIZE)))).unwrap();
            let imu = &y["imu0"];
            assert_eq!(
                imu["model"].as_str(),
                Some("scale-misalignment-size-effect")
            );
            assert_eq!(vector(&imu["accelerometers"]["rx_i"]), [0.0; 3]);
            let ma = matrix(&imu["accelerometers"]["M"]);
            assert!(ma[0][1] == 0.0 && ma[0][2] == 0.0 && ma[1][2] == 0.0);
            for (s, w, wd) in vectors {
                let (ka, kg) = kalibr_model(&y, s, w, wd);
                let (ra, rg) = robimu_model(&p, &G, &SIZE, s, w, wd);
                for i in 0..3 {
                    assert!((kg[i] - rg[i]).abs() < 1e-12, "gyro {i}: {kg:?} vs {rg:?}");
                }
                // robimu − Kalibr = Σ_j (M_a)_ij (C_i_b (λ(r_i) − λ(r_j)))_j
                let c = p.accel.rotation();
                let r = [[0.0; 3], SIZE[0], SIZE[1]];
                let mk = matrix(&imu["accelerometers"]["M"]);
                for i in 0..3 {
                    let expected: f64 = (0..3)
                        .map(|j| {
                            let d = mul_mv(&c, geom::sub(lever(w, wd, r[i]), lever(w, wd, r[j])));
                            mk[i][j] * d[j]
                        })
                        .sum();
                    let diff = ra[i] - ka[i];
                    assert!(
                        (diff - expected).abs() < 1e-12,
                        "accel {i}: {diff} vs {expected}"
                    );
                    if gamma_a == [0.0; 3] {
                        assert!(diff.abs() < 1e-12, "accel {i}: {ka:?} vs {ra:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn kalibr_yaml_without_effects_has_zero_a_and_no_levers_and_says_placeholders() {
        let p = params([0.003, -0.005, 0.004]);
        let text = kalibr_imu_yaml(&p, &options(None, None));
        assert!(text.contains("PLACEHOLDERS"), "{text}");
        let y: Yaml = serde_yaml::from_str(&text).unwrap();
        let imu = &y["imu0"];
        assert_eq!(imu["model"].as_str(), Some("scale-misalignment"));
        assert!(imu["accelerometers"]["ry_i"].is_null());
        assert_eq!(matrix(&imu["gyroscopes"]["A"]), [[0.0; 3]; 3]);
        // No effects: Kalibr's equations are robimu's K·Γ·R v + b.
        let (s, w) = ([1.0, -9.0, 3.0], [0.5, -0.7, 1.3]);
        let (ka, kg) = kalibr_model(&y, s, w, [0.0; 3]);
        let (ra, rg) = (p.accel.apply(s), p.gyro.apply(w));
        for i in 0..3 {
            assert!((ka[i] - ra[i]).abs() < 1e-12 && (kg[i] - rg[i]).abs() < 1e-12);
        }
        // σ_az is not the largest: the densities are the largest σ / √rate.
        let nd = imu["accelerometer_noise_density"].as_f64().unwrap();
        assert_eq!(nd, 0.03 / 200f64.sqrt());
        let mut given = options(None, None);
        given.noise_density = Some([1e-3, 2e-4]);
        given.random_walk = [3e-3, 4e-5];
        given.random_walk_source = Some("allan.csv".into());
        let text = kalibr_imu_yaml(&p, &given);
        assert!(!text.contains("PLACEHOLDERS") && text.contains("Random walks: allan.csv"));
        let y: Yaml = serde_yaml::from_str(&text).unwrap();
        let imu = &y["imu0"];
        assert_eq!(imu["gyroscope_noise_density"].as_f64(), Some(2e-4));
        assert_eq!(imu["accelerometer_random_walk"].as_f64(), Some(3e-3));
    }

    /// IMU j of two: its own intrinsics, r_a, position and τ.
    fn second_imu() -> ModelParams {
        let mut p = params([0.002, 0.001, -0.003]);
        p.accel.r = [-0.04, 0.03, 1.9];
        p.gyro.r = [-0.03, 0.035, 1.88];
        p.accel.k = [0.97, 1.04, 1.0];
        p.gyro.b = [-0.02, 0.01, 0.004];
        p.eps[5][0] += 0.031;
        p.eps[5][1] -= 0.012;
        p.eps[5][2] += 0.007;
        p.tau = 0.0123;
        p
    }

    fn two_imus<'a>(
        p0: &'a ModelParams,
        p1: &'a ModelParams,
        o0: &'a KalibrOptions,
        o1: &'a KalibrOptions,
    ) -> Vec<KalibrImu<'a>> {
        vec![
            KalibrImu {
                params: p0,
                opts: o0,
                placement: KalibrPlacement::relative(p0, p0),
            },
            KalibrImu {
                params: p1,
                opts: o1,
                placement: KalibrPlacement::relative(p0, p1),
            },
        ]
    }

    /// Kalibr's multi-IMU terms: T_i_b of IMU 1 maps a point's coordinates
    /// in IMU 0's frame (flange axes, origin p_0) to IMU 1's accelerometer
    /// frame, R_a1·(x_f − p_1); an event at robot time T (stamped T − τ_j
    /// by IMU j, docs/model.md §4.2) is at t_1 + time_offset on IMU 0's
    /// clock; each entry's equations are that IMU's model; the flat
    /// `--imu` file has the list entry's keys at the top level.
    #[test]
    fn kalibr_list_places_each_imu_relative_to_imu_0() {
        let mut p0 = params([0.003, -0.005, 0.004]);
        p0.tau = -0.0042;
        let p1 = second_imu();
        let o0 = options(None, None);
        let mut o1 = options(Some(G), None);
        o1.rostopic = "/imu1".into();
        let imus = two_imus(&p0, &p1, &o0, &o1);
        let list: Yaml = serde_yaml::from_str(&kalibr_imu_list_yaml(&imus)).unwrap();
        let pos = |p: &ModelParams| [p.eps[5][0], p.eps[5][1], p.eps[5][2]];
        let x_f = [0.3, -0.2, 0.45];
        for (j, p) in [(0, &p0), (1, &p1)] {
            let e = &list[format!("imu{j}").as_str()];
            let t: Vec<Vec<f64>> = serde_yaml::from_value(e["T_i_b"].clone()).unwrap();
            let x_b = geom::sub(x_f, pos(&p0));
            let got: [f64; 3] =
                std::array::from_fn(|r| (0..3).map(|c| t[r][c] * x_b[c]).sum::<f64>() + t[r][3]);
            let want = mul_mv(&p.accel.rotation(), geom::sub(x_f, pos(p)));
            for r in 0..3 {
                assert!(
                    (got[r] - want[r]).abs() < 1e-15,
                    "imu{j}: {got:?} vs {want:?}"
                );
            }
            let big_t = 100.0;
            let (t0, tj) = (big_t - p0.tau, big_t - p.tau);
            let dt = e["time_offset"].as_f64().unwrap();
            assert!((tj + dt - t0).abs() < 1e-12, "imu{j}: {dt}");
            assert_eq!(e["rostopic"].as_str(), Some(["/imu0", "/imu1"][j]));
            let (s, w) = ([1.0, -9.0, 3.0], [0.5, -0.7, 1.3]);
            let (ka, kg) = kalibr_entry_model(e, s, w, [0.0; 3]);
            let g = if j == 1 { G } else { [[0.0; 3]; 3] };
            let (ra, rg) = (p.accel.apply(s), add(p.gyro.apply(w), mul_mv(&g, s)));
            for i in 0..3 {
                assert!((ka[i] - ra[i]).abs() < 1e-12 && (kg[i] - rg[i]).abs() < 1e-12);
            }
            // the flat --imu file: the same keys and values at the top level
            let flat: Yaml = serde_yaml::from_str(&kalibr_imu_input_yaml(j, &imus)).unwrap();
            assert_eq!(&flat, e, "imu{j}");
        }
        assert!(list["imu2"].is_null());
        // IMU 0's entry of the list is the one-IMU file's
        let one: Yaml = serde_yaml::from_str(&kalibr_imu_yaml(&p0, &o0)).unwrap();
        assert_eq!(one["imu0"], list["imu0"]);
        assert_eq!(list["imu0"]["time_offset"].as_f64(), Some(0.0));
    }
}
