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
//! [imu]                      # optional, free-form description of the device
//! [controller]               # optional, free-form description of the robot controller
//! ```
//! Unknown keys are kept out of the way (ignored), as the contract allows.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::SessionError;

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
}

/// The optional `[noise]` table: standard deviations in SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct NoiseOverride {
    /// σ of `ax, ay, az` (m/s²) and `gx, gy, gz` (rad/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
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

impl SessionMeta {
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
        }
    }

    /// Read and validate `path`.
    pub fn read(path: &Path) -> Result<Self, SessionError> {
        let text = std::fs::read_to_string(path).map_err(|e| SessionError::io(path, e))?;
        Self::parse(&text, path)
    }

    /// Parse and validate; `path` only names the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SessionError> {
        let meta: Self = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
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
        Ok(meta)
    }

    /// The TOML text of this description.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("session metadata always serialises")
    }
}

/// A TOML parse error of `path` as a [`SessionError`] naming the line.
pub fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> SessionError {
    let message = e.message().to_string();
    match e.span() {
        Some(span) => {
            let line = text[..span.start.min(text.len())].matches('\n').count() as u64 + 1;
            SessionError::line(path, line, message)
        }
        None => SessionError::file(path, message),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
