//! `session.toml`: what the recording is (docs/model.md §7).
//!
//! ```toml
//! format = "robimu-session/1"
//! robot = "aubo_i5"          # a built-in name, or a path to a robot description
//! gravity = 9.81             # optional, m/s²
//! notes = "free text"        # optional
//! [noise]                    # optional, standard deviations overriding the robot's defaults
//! sigma_z = [0.38, 0.21, 0.19, 0.0056, 0.0082, 0.0099]   # m/s² ×3, rad/s ×3
//! sigma_q = [6.6e-5, 8.7e-5, 7.5e-5, 1.8e-4, 1.8e-4, 1.5e-4]  # rad, one per joint
//! ar_z = [[0.9], [0.9], [0.9], [], [], []]   # optional, AR(p) φ per IMU channel ([] white)
//! motion_z = [1e-3, 1e-3, 1e-3, 0, 0, 0]     # optional, c of σ² + c‖q̈‖² per IMU channel
//! [imu]                      # optional, free-form description of the device; robimu
//! accel_bandwidth_hz = 62.5  #   record adds the sensors' low-pass bandwidths and
//! accel_odr_hz = 125.0       #   internal output data rates (optional keys,
//! gyro_bandwidth_hz = 116.0  #   [`ImuTiming`])
//! gyro_odr_hz = 1000.0
//! alias_margin_hz = 22.5     #   optional: the read rate's alias margin (robimu_protocol::alias)
//! [controller]               # optional, free-form description of the robot controller
//! ```
//! Unknown keys are kept out of the way (ignored), as the contract allows.

use std::collections::BTreeMap;
use std::path::Path;

use robimu_model::noise::{ArNoise, ChannelNoise, NoiseModel, NoiseModelError};
use serde::{Deserialize, Serialize};

use super::error::toml_error;
use super::SessionError;
use crate::IMU_COLUMNS;

/// The format string this version reads and writes.
pub const SESSION_FORMAT: &str = "robimu-session/1";

/// Contents of `session.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SessionMeta {
    /// Always [`SESSION_FORMAT`].
    pub format: String,
    /// Built-in robot name or path to a robot description (relative paths are
    /// relative to the session directory).
    pub robot: String,
    /// Gravity magnitude g0, m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<f64>,
    /// Noise standard deviations overriding the robot's defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseOverride>,
    /// Free-form description of the IMU device.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu: Option<toml::Table>,
    /// Free-form description of the robot controller (a recording keeps
    /// the fit of its clock here, `robimu_record::robot_clock`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<toml::Table>,
    /// Free-form notes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
    /// The `[noise]` table's keys for noise that is not white
    /// (docs/model.md §4.6): read from and written to the `[noise]` table
    /// beside [`Self::noise`]'s standard deviations.
    #[serde(skip)]
    pub noise_shape: Option<NoiseShape>,
    /// The `[imu<j>]` tables of a multi-IMU session (docs/model.md §9): the
    /// free-form description of IMU j ≥ 1, as [`Self::imu`] is IMU 0's.
    #[serde(skip)]
    pub imu_tables: std::collections::BTreeMap<usize, toml::Table>,
    /// The `mount` sub-tables of `[imu]` (IMU 0) and `[imu<j>]`: each IMU's
    /// mount prior where it differs from the robot's `[imu_mount]`
    /// (docs/model.md §9). Read from those tables (which keep them).
    #[serde(skip)]
    pub mounts: std::collections::BTreeMap<usize, MountPrior>,
}

/// The `[imu<j>]` tables of a `session.toml` document `doc`, a joint or a
/// pose session's (docs/model.md §9): the description of IMU j ≥ 1; each must
/// be a table. `path` names the file in errors.
pub(crate) fn imu_tables(
    doc: &toml::Table,
    path: &Path,
) -> Result<BTreeMap<usize, toml::Table>, SessionError> {
    let mut tables = BTreeMap::new();
    for (key, value) in doc {
        let Some(j) = crate::files::imu_number(key) else {
            continue;
        };
        let toml::Value::Table(t) = value else {
            return Err(SessionError::file(
                path,
                format!("`{key}` must be a table ([{key}]) describing IMU {j}"),
            ));
        };
        tables.insert(j, t.clone());
    }
    Ok(tables)
}

/// The `mount` sub-tables of `[imu]` (`imu`, IMU 0) and of the `[imu<j>]`
/// `tables` as [`MountPrior`]s by IMU, a joint or a pose session's
/// (docs/model.md §9); an unknown key is refused naming the table.
pub(crate) fn mount_priors(
    imu: Option<&toml::Table>,
    tables: &BTreeMap<usize, toml::Table>,
    path: &Path,
) -> Result<BTreeMap<usize, MountPrior>, SessionError> {
    let named = imu.map(|t| (0, "imu".to_string(), t));
    let named = named
        .into_iter()
        .chain(tables.iter().map(|(j, t)| (*j, format!("imu{j}"), t)));
    let mut mounts = BTreeMap::new();
    for (j, name, t) in named {
        let Some(m) = t.get("mount") else { continue };
        let m = MountPrior::deserialize(m.clone())
            .map_err(|e| SessionError::file(path, format!("[{name}.mount]: {}", e.message())))?;
        mounts.insert(j, m);
    }
    Ok(mounts)
}

/// An IMU's mount prior in `session.toml` (`[imu.mount]`, `[imu<j>.mount]`,
/// docs/model.md §9), the keys of the robot's `[imu_mount]` (SI: m, rad),
/// each optional: a missing one keeps the robot's (IMU 0) or IMU 0's (j ≥ 1).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MountPrior {
    /// Prior mean of the IMU's position ε_n1..3 on the flange (m).
    #[serde(default, deserialize_with = "robimu_model::arity::option")]
    pub position: Option<[f64; 3]>,
    /// Prior σ of each position component (m).
    pub position_sigma: Option<f64>,
    /// Prior mean of the accelerometer rotation (r_a_z, r_a_y, r_a_x), rad.
    #[serde(default, deserialize_with = "robimu_model::arity::option")]
    pub r_a: Option<[f64; 3]>,
    /// Prior mean of the gyroscope rotation (r_w_z, r_w_y, r_w_x), rad.
    #[serde(default, deserialize_with = "robimu_model::arity::option")]
    pub r_w: Option<[f64; 3]>,
    /// Prior σ of every sensor rotation angle (rad).
    pub rotation_sigma: Option<f64>,
}

impl MountPrior {
    /// IMU `j`'s prior in a session's `mounts` (by IMU): its own keys over
    /// IMU 0's (docs/model.md §9).
    pub fn of_imu(mounts: &std::collections::BTreeMap<usize, MountPrior>, j: usize) -> Self {
        let base = mounts.get(&0).copied().unwrap_or_default();
        match mounts.get(&j) {
            Some(m) if j > 0 => m.or(&base),
            _ => base,
        }
    }

    /// These keys, the missing ones from `base`.
    pub fn or(&self, base: &MountPrior) -> MountPrior {
        MountPrior {
            position: self.position.or(base.position),
            position_sigma: self.position_sigma.or(base.position_sigma),
            r_a: self.r_a.or(base.r_a),
            r_w: self.r_w.or(base.r_w),
            rotation_sigma: self.rotation_sigma.or(base.rotation_sigma),
        }
    }

    /// `base` with the keys this table gives.
    pub fn over(&self, base: &robimu_model::robot::ImuMount) -> robimu_model::robot::ImuMount {
        robimu_model::robot::ImuMount {
            position: self.position.unwrap_or(base.position),
            position_sigma: self.position_sigma.unwrap_or(base.position_sigma),
            r_a: self.r_a.unwrap_or(base.r_a),
            r_w: self.r_w.unwrap_or(base.r_w),
            rotation_sigma: self.rotation_sigma.unwrap_or(base.rotation_sigma),
        }
    }
}

/// The `[noise]` table's optional keys for IMU noise correlated in time and
/// following the motion (docs/model.md §4.6), beside [`NoiseOverride`]'s
/// standard deviations (which give each channel's marginal σ at rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct NoiseShape {
    /// AR coefficients φ_1…φ_p of each IMU channel `ax…gz` (six lists; an
    /// empty list is white noise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ar_z: Option<Vec<Vec<f64>>>,
    /// c of σ²(t) = σ² + c‖q̈(t)‖² for each IMU channel (six values ≥ 0,
    /// the channel's unit² per (rad/s²)²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_z: Option<Vec<f64>>,
}

/// A TOML document's optional `[noise]` table, read for its shape keys only.
#[derive(Deserialize)]
struct ShapeDocument {
    #[serde(default)]
    noise: Option<NoiseShape>,
}

impl NoiseShape {
    /// Whether neither key is given.
    pub fn is_empty(&self) -> bool {
        self.ar_z.is_none() && self.motion_z.is_none()
    }

    /// Check both keys: six channels each, every AR model stationary of
    /// order ≤ [`robimu_model::noise::MAX_AR_ORDER`] with finite
    /// coefficients, every motion gain a number ≥ 0. `path` names the file.
    pub fn validate(&self, path: &Path) -> Result<(), SessionError> {
        let count = |key: &str, n: usize| -> Result<(), SessionError> {
            if n == IMU_COLUMNS.len() {
                Ok(())
            } else {
                Err(SessionError::file(
                    path,
                    format!(
                        "[noise] {key} has {n} entries, it needs six: one per IMU channel {}",
                        IMU_COLUMNS.join(", ")
                    ),
                ))
            }
        };
        if let Some(ar) = &self.ar_z {
            count("ar_z", ar.len())?;
            for (c, phi) in ar.iter().enumerate() {
                ArNoise::new(phi.clone(), 1.0).map_err(|e| {
                    SessionError::file(
                        path,
                        format!("[noise] ar_z, channel {}: {e}", IMU_COLUMNS[c]),
                    )
                })?;
            }
        }
        if let Some(motion) = &self.motion_z {
            count("motion_z", motion.len())?;
            for (c, m) in motion.iter().enumerate() {
                if !(m.is_finite() && *m >= 0.0) {
                    return Err(SessionError::file(
                        path,
                        format!(
                            "[noise] motion_z, channel {}: {m} must be a non-negative number",
                            IMU_COLUMNS[c]
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The IMU noise model: channel c an AR process of coefficients
    /// `ar_z[c]` (white when absent) and marginal σ `sigma_z[c]` at rest,
    /// with motion gain `motion_z[c]` (0 when absent).
    pub fn noise_model(&self, sigma_z: [f64; 6]) -> Result<NoiseModel, NoiseModelError> {
        let mut imu = Vec::with_capacity(6);
        for (c, &sigma) in sigma_z.iter().enumerate() {
            let phi = self
                .ar_z
                .as_ref()
                .and_then(|a| a.get(c).cloned())
                .unwrap_or_default();
            let motion = self
                .motion_z
                .as_ref()
                .and_then(|m| m.get(c).copied())
                .unwrap_or(0.0);
            imu.push(ChannelNoise::new(ArNoise::new(phi, sigma)?, motion)?);
        }
        Ok(NoiseModel {
            imu: imu.try_into().expect("six channels"),
        })
    }

    /// The keys that describe `model` (its σ go to [`NoiseOverride::sigma_z`]);
    /// `None` when it is white of constant level.
    pub fn from_model(model: &NoiseModel) -> Option<Self> {
        let ar = model.imu.iter().any(|c| !c.ar.is_white());
        let motion = model.imu.iter().any(|c| c.motion != 0.0);
        let shape = Self {
            ar_z: ar.then(|| model.imu.iter().map(|c| c.ar.phi().to_vec()).collect()),
            motion_z: motion.then(|| model.imu.iter().map(|c| c.motion).collect()),
        };
        (!shape.is_empty()).then_some(shape)
    }

    /// The largest AR order given (0 when white).
    pub fn max_order(&self) -> usize {
        self.ar_z.iter().flatten().map(Vec::len).max().unwrap_or(0)
    }

    /// The shape keys of a TOML document's `[noise]` table (session.toml or a
    /// `--noise` file), validated; `None` when it has neither key. `path`
    /// only names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Option<Self>, SessionError> {
        let doc: ShapeDocument = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        match doc.noise.filter(|s| !s.is_empty()) {
            Some(shape) => {
                shape.validate(path)?;
                Ok(Some(shape))
            }
            None => Ok(None),
        }
    }

    /// [`Self::parse`] of the file `path`.
    pub fn read(path: &Path) -> Result<Option<Self>, SessionError> {
        let text = crate::text::read(path)?;
        Self::parse(&text, path)
    }
}

/// Refuse an AR noise model of order `order` for a fit of `samples` samples
/// per channel when the order is not small beside the data (p ≥ N/10): the
/// whitening would rest on too few samples per coefficient.
pub fn check_ar_order_for_data(order: usize, samples: usize) -> Result<(), String> {
    if order > 0 && order.saturating_mul(10) >= samples {
        return Err(format!(
            "the noise model's AR order {order} is too high for {samples} samples \
             (it must stay below a tenth of them)"
        ));
    }
    Ok(())
}

/// The optional `[noise]` table: standard deviations in SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct NoiseOverride {
    /// σ of `ax, ay, az` (m/s²) and `gx, gy, gz` (rad/s).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "robimu_model::arity::option"
    )]
    pub sigma_z: Option<[f64; 6]>,
    /// σ of each joint position, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_q: Option<Vec<f64>>,
}

impl NoiseOverride {
    /// Check that every standard deviation given is a positive number;
    /// `path` names the file in the error.
    pub fn validate(&self, path: &Path) -> Result<(), SessionError> {
        let all = self
            .sigma_z
            .iter()
            .flatten()
            .chain(self.sigma_q.iter().flatten());
        for s in all {
            if !(s.is_finite() && *s > 0.0) {
                return Err(SessionError::file(
                    path,
                    format!("[noise]: standard deviation {s} must be a positive number"),
                ));
            }
        }
        Ok(())
    }
}

/// The IMU's internal timing, as `robimu record` writes it into session.toml's
/// `[imu]` table (docs/model.md §7): each sensor's low-pass bandwidth and
/// internal output data rate (the BNO055 filters at the bandwidth and
/// updates its registers at the ODR; the board's reads are asynchronous).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuTiming {
    /// Accelerometer bandwidth, Hz.
    pub accel_bandwidth_hz: f64,
    /// Accelerometer internal output data rate, Hz.
    pub accel_odr_hz: f64,
    /// Gyroscope bandwidth, Hz.
    pub gyro_bandwidth_hz: f64,
    /// Gyroscope internal output data rate, Hz.
    pub gyro_odr_hz: f64,
}

impl ImuTiming {
    /// The `[imu]` keys, in the order of the fields.
    pub const KEYS: [&'static str; 4] = [
        "accel_bandwidth_hz",
        "accel_odr_hz",
        "gyro_bandwidth_hz",
        "gyro_odr_hz",
    ];

    fn values(&self) -> [f64; 4] {
        [
            self.accel_bandwidth_hz,
            self.accel_odr_hz,
            self.gyro_bandwidth_hz,
            self.gyro_odr_hz,
        ]
    }

    /// Writes the four keys into an `[imu]` table.
    pub fn insert_into(&self, table: &mut toml::Table) {
        for (key, v) in Self::KEYS.iter().zip(self.values()) {
            table.insert((*key).into(), v.into());
        }
    }

    /// The timing in an `[imu]` table: `None` when none of the keys is
    /// there (sessions recorded before them, or by other tools); an error
    /// naming the key when only some are, or one is not a positive number.
    /// `path` names the file.
    pub fn from_table(table: &toml::Table, path: &Path) -> Result<Option<Self>, SessionError> {
        if Self::KEYS.iter().all(|k| !table.contains_key(*k)) {
            return Ok(None);
        }
        let mut v = [0.0; 4];
        for (slot, key) in v.iter_mut().zip(Self::KEYS) {
            let value = match table.get(key) {
                Some(toml::Value::Float(f)) => *f,
                Some(toml::Value::Integer(i)) => *i as f64,
                Some(other) => {
                    return Err(SessionError::file(
                        path,
                        format!("[imu] {key} = {other} is not a number of Hz"),
                    ))
                }
                None => {
                    return Err(SessionError::file(
                        path,
                        format!(
                            "[imu] has some of {} but not {key}: give all four or none",
                            Self::KEYS.join(", ")
                        ),
                    ))
                }
            };
            if !(value.is_finite() && value > 0.0) {
                return Err(SessionError::file(
                    path,
                    format!("[imu] {key} = {value} must be a positive frequency, Hz"),
                ));
            }
            *slot = value;
        }
        Ok(Some(Self {
            accel_bandwidth_hz: v[0],
            accel_odr_hz: v[1],
            gyro_bandwidth_hz: v[2],
            gyro_odr_hz: v[3],
        }))
    }
}

impl SessionMeta {
    /// The IMU's timing from the `[imu]` table ([`ImuTiming::from_table`]),
    /// `None` without one.
    pub fn imu_timing(&self, path: &Path) -> Result<Option<ImuTiming>, SessionError> {
        match &self.imu {
            Some(table) => ImuTiming::from_table(table, path),
            None => Ok(None),
        }
    }

    /// A description for a built-in or file robot with everything else default.
    pub fn new(robot: impl Into<String>) -> Self {
        Self {
            format: SESSION_FORMAT.into(),
            robot: robot.into(),
            gravity: None,
            noise: None,
            imu: None,
            controller: None,
            notes: None,
            noise_shape: None,
            imu_tables: Default::default(),
            mounts: Default::default(),
        }
    }

    /// The IMU noise model of this session at the standard deviations
    /// `sigma_z` (the `[noise]` table's or the robot's): white unless the
    /// table has `ar_z` or `motion_z`.
    pub fn noise_model(&self, sigma_z: [f64; 6]) -> Result<NoiseModel, NoiseModelError> {
        self.noise_shape
            .clone()
            .unwrap_or_default()
            .noise_model(sigma_z)
    }

    /// Read and validate `path`.
    pub fn read(path: &Path) -> Result<Self, SessionError> {
        let text = crate::text::read(path)?;
        Self::parse(&text, path)
    }

    /// Parse and validate; `path` only names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SessionError> {
        let doc: toml::Table = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        if crate::SessionSource::of_table(&doc, path)? == crate::SessionSource::Poses {
            return Err(crate::source::not_joints(path));
        }
        if !doc.contains_key("robot") {
            return Err(SessionError::file(
                path,
                "no `robot` key: a joint session names its robot (a built-in name or a path, \
                 docs/model.md §7.2); a session with tool poses says source = \"poses\" (§7.9)",
            ));
        }
        let mut meta: Self = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        if meta.format != SESSION_FORMAT {
            return Err(SessionError::file(
                path,
                format!(
                    "format is `{}`, this version reads `{SESSION_FORMAT}`",
                    meta.format
                ),
            ));
        }
        if let Some(g) = meta.gravity {
            if !(g.is_finite() && g > 0.0) {
                return Err(SessionError::file(
                    path,
                    format!("gravity = {g} must be a positive number"),
                ));
            }
        }
        if let Some(noise) = &meta.noise {
            noise.validate(path)?;
        }
        meta.noise_shape = NoiseShape::parse(text, path)?;
        meta.imu_tables = imu_tables(&doc, path)?;
        meta.mounts = mount_priors(meta.imu.as_ref(), &meta.imu_tables, path)?;
        Ok(meta)
    }

    /// The TOML text of this description.
    pub fn to_toml(&self) -> String {
        let mut doc = toml::Table::try_from(self).expect("session metadata always serialises");
        if let Some(shape) = self.noise_shape.as_ref().filter(|s| !s.is_empty()) {
            let keys = toml::Table::try_from(shape).expect("the noise shape always serialises");
            let table = doc
                .entry("noise")
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(t) = table {
                t.extend(keys);
            }
        }
        for (j, t) in &self.imu_tables {
            doc.insert(format!("imu{j}"), toml::Value::Table(t.clone()));
        }
        toml::to_string(&doc).expect("session metadata always serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn imu_timing_keys_are_optional_all_or_none_and_positive() {
        let path = Path::new("s.toml");
        let parse = |imu: &str| {
            let text = format!("format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n{imu}");
            SessionMeta::parse(&text, path).unwrap().imu_timing(path)
        };
        // no [imu], or one without the keys: as before
        assert_eq!(parse("").unwrap(), None);
        assert_eq!(parse("[imu]\nport = \"/dev/ttyUSB0\"\n").unwrap(), None);
        let t = ImuTiming {
            accel_bandwidth_hz: 62.5,
            accel_odr_hz: 125.0,
            gyro_bandwidth_hz: 116.0,
            gyro_odr_hz: 1000.0,
        };
        // what the recorder writes reads back
        let mut table = toml::Table::new();
        t.insert_into(&mut table);
        let mut meta = SessionMeta::new("aubo_i5");
        meta.imu = Some(table);
        let back = SessionMeta::parse(&meta.to_toml(), path).unwrap();
        assert_eq!(back.imu_timing(path).unwrap(), Some(t));
        // integers are numbers of Hz too
        let ok = parse("[imu]\naccel_bandwidth_hz = 62.5\naccel_odr_hz = 125\ngyro_bandwidth_hz = 116\ngyro_odr_hz = 1000\n");
        assert_eq!(ok.unwrap(), Some(t));
        let err = parse("[imu]\naccel_bandwidth_hz = 62.5\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("not accel_odr_hz") && err.contains("s.toml"),
            "{err}"
        );
        let err = parse("[imu]\naccel_bandwidth_hz = 62.5\naccel_odr_hz = -125\ngyro_bandwidth_hz = 116\ngyro_odr_hz = 1000\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("accel_odr_hz = -125") && err.contains("positive"),
            "{err}"
        );
        let err = parse("[imu]\naccel_bandwidth_hz = \"fast\"\naccel_odr_hz = 1\ngyro_bandwidth_hz = 1\ngyro_odr_hz = 1\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("accel_bandwidth_hz") && err.contains("not a number"),
            "{err}"
        );
    }

    #[test]
    fn round_trip_and_defaults() {
        let mut m = SessionMeta::new("aubo_i5");
        m.gravity = Some(9.80665);
        m.noise = Some(NoiseOverride {
            sigma_z: Some([0.1, 0.2, 0.3, 0.01, 0.02, 0.03]),
            sigma_q: None,
        });
        let back = SessionMeta::parse(&m.to_toml(), Path::new("s.toml")).unwrap();
        assert_eq!(back, m);
        let min = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\nextra = 3\n",
            Path::new("s.toml"),
        )
        .unwrap();
        assert_eq!(min, SessionMeta::new("aubo_i5"));
    }

    #[test]
    fn bad_files_name_the_cause() {
        let p = Path::new("s.toml");
        let e =
            SessionMeta::parse("format = \"robimu-session/2\"\nrobot = \"x\"\n", p).unwrap_err();
        assert!(
            e.to_string()
                .contains("this version reads `robimu-session/1`"),
            "{e}"
        );
        let e = SessionMeta::parse("format = \"robimu-session/1\"\n", p).unwrap_err();
        assert!(e.to_string().contains("robot"), "{e}");
        let e = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"x\"\ngravity = = 3\n",
            p,
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("s.toml:3:"), "{e}");
        let e = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"x\"\n[noise]\nsigma_z = [1,2,3,4,5,-6]\n",
            p,
        )
        .unwrap_err();
        assert!(e.to_string().contains("must be a positive number"), "{e}");
        let e = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"x\"\n[noise]\nsigma_z = [1,2,3]\n",
            p,
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("s.toml:4:"), "{e}");
        // Issue 41: bytes that are not UTF-8 are placed.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("session.toml");
        std::fs::write(&path, b"format = \"robimu-session/1\"\nrobot = \"\xff\"\n").unwrap();
        let e = SessionMeta::read(&path).unwrap_err().to_string();
        assert!(
            e.contains("session.toml:2: not UTF-8 text: invalid byte 0xff at byte offset 37"),
            "{e}"
        );
        // Issue 41: seven values are refused too, not the seventh dropped.
        let e = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"x\"\n[noise]\nsigma_z = [1,2,3,4,5,6,7]\n",
            p,
        )
        .unwrap_err();
        assert!(
            e.to_string().starts_with("s.toml:4:")
                && e.to_string()
                    .contains("7 values where 6 are expected (ax ay az gx gy gz)"),
            "{e}"
        );
    }

    const HEAD: &str = "format = \"robimu-session/1\"\nrobot = \"x\"\n[noise]\n";

    fn bad(keys: &str) -> String {
        SessionMeta::parse(&format!("{HEAD}{keys}"), Path::new("s.toml"))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn noise_shape_round_trips_and_builds_the_model() {
        let mut m = SessionMeta::new("aubo_i5");
        m.noise = Some(NoiseOverride {
            sigma_z: Some([0.1, 0.2, 0.3, 0.01, 0.02, 0.03]),
            sigma_q: None,
        });
        let shape = NoiseShape {
            ar_z: Some(vec![
                vec![0.9],
                vec![1.2, -0.5],
                vec![],
                vec![0.3],
                vec![],
                vec![],
            ]),
            motion_z: Some(vec![1e-3, 0.0, 2.5e-4, 0.0, 0.0, 1e-6]),
        };
        m.noise_shape = Some(shape.clone());
        let text = m.to_toml();
        assert!(text.contains("ar_z") && text.contains("motion_z"), "{text}");
        let back = SessionMeta::parse(&text, Path::new("s.toml")).unwrap();
        assert_eq!(back, m);
        let sz = [0.1, 0.2, 0.3, 0.01, 0.02, 0.03];
        let model = back.noise_model(sz).unwrap();
        assert_eq!(model.sigma_z(), sz);
        assert_eq!(model.imu[1].ar.phi(), &[1.2, -0.5]);
        assert_eq!(model.imu[2].motion, 2.5e-4);
        assert_eq!(model.max_order(), 2);
        assert_eq!(NoiseShape::from_model(&model), Some(shape.clone()));
        assert_eq!(shape.max_order(), 2);
        // only one key; and a [noise] table with only shape keys
        let mut m2 = SessionMeta::new("aubo_i5");
        m2.noise_shape = Some(NoiseShape {
            ar_z: None,
            motion_z: Some(vec![0.0, 0.0, 0.0, 1e-4, 0.0, 0.0]),
        });
        let back = SessionMeta::parse(&m2.to_toml(), Path::new("s.toml")).unwrap();
        // (the table it writes reads back as a [noise] table without σ)
        m2.noise = Some(NoiseOverride::default());
        assert_eq!(back, m2);
        assert_eq!(
            SessionMeta::parse(&m2.to_toml(), Path::new("s.toml")).unwrap(),
            m2
        );
        // white: no keys, and the model is white
        assert_eq!(
            NoiseShape::from_model(&NoiseModel::white(sz).unwrap()),
            None
        );
        assert!(SessionMeta::new("x").noise_model(sz).unwrap().is_white());
        // the old files have no shape
        let plain =
            SessionMeta::parse(&format!("{HEAD}sigma_q = [1e-4]\n"), Path::new("s.toml")).unwrap();
        assert_eq!(plain.noise_shape, None);
    }

    #[test]
    fn a_noise_file_gives_its_shape() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("noise.toml");
        std::fs::write(&path, "[noise]\nar_z = [[0.5], [], [], [], [], []]\n").unwrap();
        let s = NoiseShape::read(&path).unwrap().unwrap();
        assert_eq!(s.ar_z.unwrap()[0], vec![0.5]);
        std::fs::write(&path, "[noise]\nsigma_z = [1, 1, 1, 1, 1, 1]\n").unwrap();
        assert_eq!(NoiseShape::read(&path).unwrap(), None);
        std::fs::write(&path, "[noise]\nar_z = [[1.5], [], [], [], [], []]\n").unwrap();
        let e = NoiseShape::read(&path).unwrap_err().to_string();
        assert!(
            e.contains("noise.toml") && e.contains("ar_z, channel ax"),
            "{e}"
        );
    }

    #[test]
    fn bad_noise_shapes_name_the_key_and_channel() {
        let e = bad("ar_z = [[0.5], [], [], [], [1.0], []]\n");
        assert!(
            e.starts_with("s.toml: [noise] ar_z, channel gy:") && e.contains("not stationary"),
            "{e}"
        );
        // explosive AR(2) (a root inside the unit circle)
        let e = bad("ar_z = [[], [0.5, 0.6], [], [], [], []]\n");
        assert!(
            e.contains("ar_z, channel ay") && e.contains("not stationary"),
            "{e}"
        );
        let e = bad("ar_z = [[], [], [nan], [], [], []]\n");
        assert!(
            e.contains("ar_z, channel az") && e.contains("finite"),
            "{e}"
        );
        let e = bad("ar_z = [[], [], []]\n");
        assert!(e.contains("ar_z has 3 entries, it needs six"), "{e}");
        let long = vec!["0.01"; robimu_model::noise::MAX_AR_ORDER + 1].join(", ");
        let e = bad(&format!("ar_z = [[], [], [], [], [], [{long}]]\n"));
        assert!(
            e.contains("ar_z, channel gz") && e.contains("above the largest supported order"),
            "{e}"
        );
        let e = bad("motion_z = [0, 0, 0, -1e-3, 0, 0]\n");
        assert!(
            e.contains("motion_z, channel gx: -0.001 must be a non-negative number"),
            "{e}"
        );
        let e = bad("motion_z = [0, 0, nan, 0, 0, 0]\n");
        assert!(e.contains("motion_z, channel az: NaN"), "{e}");
        let e = bad("motion_z = [0, 0]\n");
        assert!(e.contains("motion_z has 2 entries"), "{e}");
        // not numbers: a TOML error with the line
        let e = bad("ar_z = [\"a\"]\n");
        assert!(e.starts_with("s.toml:4:"), "{e}");
    }

    #[test]
    fn an_order_beyond_the_data_is_refused() {
        assert!(check_ar_order_for_data(0, 0).is_ok());
        assert!(check_ar_order_for_data(2, 21).is_ok());
        let e = check_ar_order_for_data(2, 20).unwrap_err();
        assert!(e.contains("AR order 2 is too high for 20 samples"), "{e}");
        assert!(check_ar_order_for_data(1, 5).is_err());
    }

    #[test]
    fn imu_j_tables_round_trip_and_a_non_table_is_refused() {
        let text = "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n[imu]\nchip = \"BNO055\"\n\
                    [imu1]\nchip = \"BNO055\"\naddress = 41\n[imu2]\nport = \"/dev/ttyUSB1\"\n";
        let meta = SessionMeta::parse(text, Path::new("session.toml")).unwrap();
        assert_eq!(meta.imu_tables.len(), 2);
        assert_eq!(meta.imu_tables[&1]["address"].as_integer(), Some(41));
        let back = SessionMeta::parse(&meta.to_toml(), Path::new("session.toml")).unwrap();
        assert_eq!(back, meta);
        let e = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\nimu1 = 3\n",
            Path::new("session.toml"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("`imu1` must be a table"), "{e}");
    }

    #[test]
    fn mount_tables_are_read_per_imu_and_an_unknown_key_is_named() {
        let text = "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n\
                    [imu1]\nchip = \"BNO055\"\n[imu1.mount]\nposition = [0.08, 0.0, 0.02]\n\
                    position_sigma = 0.002\n";
        let meta = SessionMeta::parse(text, Path::new("session.toml")).unwrap();
        assert_eq!(meta.mounts.len(), 1);
        let m = meta.mounts[&1];
        assert_eq!(m.position, Some([0.08, 0.0, 0.02]));
        assert_eq!(m.position_sigma, Some(0.002));
        assert_eq!((m.r_a, m.rotation_sigma), (None, None));
        let robot = robimu_model::Robot::aubo_i5();
        let over = m.over(robot.mount());
        assert_eq!(over.position, [0.08, 0.0, 0.02]);
        assert_eq!(over.r_a, robot.mount().r_a);
        // written back with its [imu1] table
        let back = SessionMeta::parse(&meta.to_toml(), Path::new("session.toml")).unwrap();
        assert_eq!(back.mounts, meta.mounts);
        let e = SessionMeta::parse(
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n[imu.mount]\nposition_sd = 0.01\n",
            Path::new("session.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("[imu.mount]") && e.contains("unknown field `position_sd`"),
            "{e}"
        );
    }
}
