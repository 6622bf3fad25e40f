//! `session.toml` of a session with tool poses (docs/model.md §7.9):
//!
//! ```toml
//! format = "robimu-session/1"
//! source = "poses"           # required; no `robot` key
//! gravity = 9.81             # optional, m/s²
//! notes = "free text"        # optional
//! [poses]                    # optional, the pose noise (standard deviations)
//! sigma_p = 1e-4             # m
//! sigma_r = 1e-3             # rad, rotation angle
//! [noise]                    # optional, the IMU noise as in a joint session
//! sigma_z = [0.38, 0.21, 0.19, 0.0056, 0.0082, 0.0099]   # m/s² ×3, rad/s ×3
//! ar_z = [[0.9], [0.9], [0.9], [], [], []]   # optional, AR(p) φ per IMU channel
//! [imu]                      # optional, free-form description of the device
//! [imu.mount]                # optional, IMU 0's prior (keys of §9's mount table)
//! position = [0.02, 0.0, 0.05]   # m, p_imu on the posed body
//! position_sigma = 0.005     # m
//! r_a = [0.0, 0.0, 3.14159]  # rad, the sensor rotations' prior means
//! r_w = [0.0, 0.0, 3.14159]
//! rotation_sigma = 0.05      # rad
//! [imu1]                     # optional, IMU 1's description; [imu1.mount] its prior
//! ```
//!
//! The mount tables are read by the joint session's reader
//! ([`crate::meta`]); a missing key keeps MODEL.md §10's prior (IMU 0:
//! p_imu 0 ± 0.2 m, the sensor rotations found from the data with no
//! informative prior) or IMU 0's key (IMU j ≥ 1), as in a joint session.
//!
//! Unknown top-level keys are ignored, as in a joint session; the keys of
//! `[poses]` are checked (a typo there would silently change the weights).

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::error::toml_error;
use super::meta::{imu_tables, mount_priors};
use super::{
    MountPrior, NoiseOverride, NoiseShape, SessionError, SessionSource, SESSION_FORMAT,
    SOURCE_POSES,
};

/// The `[poses]` table: the pose noise of docs/model.md §7.9, as standard
/// deviations.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseNoise {
    /// σ_p of each position component, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_p: Option<f64>,
    /// σ_r of each component of the rotation error Exp(n_r), rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_r: Option<f64>,
}

/// Contents of a pose session's `session.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseSessionMeta {
    /// Always [`SESSION_FORMAT`].
    pub format: String,
    /// Always [`SOURCE_POSES`].
    pub source: String,
    /// Gravity magnitude g0, m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<f64>,
    /// The pose noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poses: Option<PoseNoise>,
    /// The IMU noise (`sigma_z` only: a pose session has no joints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseOverride>,
    /// Free-form description of the IMU device (IMU 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub imu: Option<toml::Table>,
    /// Free-form notes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
    /// The `[noise]` table's `ar_z` (docs/model.md §4.6), read and written
    /// beside [`Self::noise`]'s σ (`motion_z`, which scales with the joint
    /// accelerations, is refused).
    #[serde(skip)]
    pub noise_shape: Option<NoiseShape>,
    /// The `[imu<j>]` tables of IMU j ≥ 1 (docs/model.md §9).
    #[serde(skip)]
    pub imu_tables: BTreeMap<usize, toml::Table>,
    /// The `mount` sub-tables of `[imu]` (IMU 0) and `[imu<j>]`: each IMU's
    /// prior where it differs from MODEL.md §10's. Read from those tables
    /// (which keep them).
    #[serde(skip)]
    pub mounts: BTreeMap<usize, MountPrior>,
}

impl Default for PoseSessionMeta {
    fn default() -> Self {
        Self {
            format: SESSION_FORMAT.into(),
            source: SOURCE_POSES.into(),
            gravity: None,
            poses: None,
            noise: None,
            imu: None,
            notes: None,
            noise_shape: None,
            imu_tables: BTreeMap::new(),
            mounts: BTreeMap::new(),
        }
    }
}

impl PoseSessionMeta {
    /// Read and validate `path`.
    pub fn read(path: &Path) -> Result<Self, SessionError> {
        let text = crate::text::read(path)?;
        Self::parse(&text, path)
    }

    /// Parse and validate; `path` only names the file in errors. A joint
    /// session's `session.toml` (no `source = "poses"`) is refused as such.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SessionError> {
        let doc: toml::Table = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        if SessionSource::of_table(&doc, path)? != SessionSource::Poses {
            return Err(crate::source::not_poses(path));
        }
        if let Some(robot) = doc.get("robot") {
            return Err(SessionError::file(
                path,
                format!(
                    "robot = {robot}: a pose session has no robot (its motion is the poses of \
                     poses.csv, docs/model.md §7.9); remove the key"
                ),
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
        meta.validate(path)?;
        meta.noise_shape = NoiseShape::parse(text, path)?;
        if meta
            .noise_shape
            .as_ref()
            .is_some_and(|s| s.motion_z.is_some())
        {
            return Err(SessionError::file(
                path,
                "[noise] motion_z scales the IMU noise with the joint accelerations: a pose \
                 session has no joints (leave it out)",
            ));
        }
        meta.imu_tables = imu_tables(&doc, path)?;
        meta.mounts = mount_priors(meta.imu.as_ref(), &meta.imu_tables, path)?;
        meta.validate_mounts(path)?;
        Ok(meta)
    }

    /// Every mount prior's numbers finite and its σ positive; a
    /// `rotation_sigma` only beside prior means of the rotations (its own
    /// `r_a` or `r_w`, or IMU 0's): a pose session finds the rotations from
    /// the data, and a σ around those would count the data twice.
    fn validate_mounts(&self, path: &Path) -> Result<(), SessionError> {
        for (&j, m) in &self.mounts {
            let name = if j == 0 {
                "imu".into()
            } else {
                format!("imu{j}")
            };
            let bad =
                |what: String| Err(SessionError::file(path, format!("[{name}.mount] {what}")));
            let vectors = [("position", m.position), ("r_a", m.r_a), ("r_w", m.r_w)];
            for (key, v) in vectors {
                if let Some(v) = v.filter(|v| v.iter().any(|x| !x.is_finite())) {
                    return bad(format!(
                        "{key} = {v:?}: every component must be a finite number"
                    ));
                }
            }
            for (key, v) in [
                ("position_sigma", m.position_sigma),
                ("rotation_sigma", m.rotation_sigma),
            ] {
                if let Some(v) = v.filter(|v| !(v.is_finite() && *v > 0.0)) {
                    return bad(format!("{key} = {v} must be a positive number"));
                }
            }
            let given = MountPrior::of_imu(&self.mounts, j);
            if m.rotation_sigma.is_some() && given.r_a.is_none() && given.r_w.is_none() {
                return bad(
                    "rotation_sigma without r_a or r_w: a pose session finds the sensor \
                     rotations from the data (docs/model.md §7.9); give their prior means too, \
                     or leave rotation_sigma out"
                        .into(),
                );
            }
        }
        Ok(())
    }

    /// Every number a positive one; no joint noise.
    fn validate(&self, path: &Path) -> Result<(), SessionError> {
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(SessionError::file(
                    path,
                    format!("{what} = {v} must be a positive number"),
                ))
            }
        };
        if let Some(g) = self.gravity {
            positive("gravity", g)?;
        }
        if let Some(p) = &self.poses {
            if let Some(s) = p.sigma_p {
                positive("[poses] sigma_p (m)", s)?;
            }
            if let Some(s) = p.sigma_r {
                positive("[poses] sigma_r (rad)", s)?;
            }
        }
        if let Some(noise) = &self.noise {
            if noise.sigma_q.is_some() {
                return Err(SessionError::file(
                    path,
                    "[noise] sigma_q is the joint noise: a pose session has no joints (its pose \
                     noise is [poses] sigma_p, sigma_r)",
                ));
            }
            noise.validate(path)?;
        }
        Ok(())
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

    fn parse(text: &str) -> Result<PoseSessionMeta, SessionError> {
        PoseSessionMeta::parse(text, Path::new("s.toml"))
    }

    const HEAD: &str = "format = \"robimu-session/1\"\nsource = \"poses\"\n";

    #[test]
    fn round_trip_and_minimal() {
        let mut m = PoseSessionMeta {
            gravity: Some(9.80665),
            poses: Some(PoseNoise {
                sigma_p: Some(1e-4),
                sigma_r: Some(2e-3),
            }),
            noise: Some(NoiseOverride {
                sigma_z: Some([0.1, 0.2, 0.3, 0.01, 0.02, 0.03]),
                sigma_q: None,
            }),
            notes: Some("mocap".into()),
            ..Default::default()
        };
        m.imu_tables.insert(1, toml::Table::new());
        m.noise_shape = Some(NoiseShape {
            ar_z: Some(vec![vec![0.5], vec![], vec![], vec![], vec![], vec![0.25]]),
            motion_z: None,
        });
        assert_eq!(parse(&m.to_toml()).unwrap(), m);
        assert_eq!(parse(HEAD).unwrap(), PoseSessionMeta::default());
        let only_p = parse(&format!("{HEAD}[poses]\nsigma_p = 0.001\n")).unwrap();
        assert_eq!(only_p.poses.unwrap().sigma_r, None);
    }

    #[test]
    fn bad_files_name_the_cause() {
        let e = parse("format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n").unwrap_err();
        assert!(e.to_string().contains("this is a joint session"), "{e}");
        let e = parse(&format!("{HEAD}robot = \"aubo_i5\"\n")).unwrap_err();
        assert!(e.to_string().contains("has no robot"), "{e}");
        let e = parse(&format!("{HEAD}[poses]\nsigma_p = -1\n")).unwrap_err();
        assert!(e.to_string().contains("sigma_p (m) = -1"), "{e}");
        let e = parse(&format!("{HEAD}[poses]\nsigma_r = nan\n")).unwrap_err();
        assert!(e.to_string().contains("sigma_r (rad) = NaN"), "{e}");
        let e = parse(&format!("{HEAD}[poses]\nsigma_x = 1\n")).unwrap_err();
        assert!(
            e.to_string().contains("sigma_x") && e.to_string().starts_with("s.toml:"),
            "{e}"
        );
        let e = parse(&format!("{HEAD}[noise]\nsigma_q = [1e-4]\n")).unwrap_err();
        assert!(e.to_string().contains("has no joints"), "{e}");
        let e = parse(&format!("{HEAD}[noise]\nsigma_z = [1,1,1,1,1,0]\n")).unwrap_err();
        assert!(e.to_string().contains("positive"), "{e}");
        let e = parse("format = \"robimu-session/9\"\nsource = \"poses\"\n").unwrap_err();
        assert!(e.to_string().contains("robimu-session/1"), "{e}");
        let e = parse(&format!("{HEAD}imu1 = 3\n")).unwrap_err();
        assert!(e.to_string().contains("must be a table"), "{e}");
        let e = parse(&format!("{HEAD}[noise]\nmotion_z = [0,0,0,0,0,0]\n")).unwrap_err();
        assert!(e.to_string().contains("motion_z"), "{e}");
        let e = parse(&format!("{HEAD}[noise]\nar_z = [[2.0]]\n")).unwrap_err();
        assert!(e.to_string().contains("ar_z"), "{e}");
        let e = parse(&format!("{HEAD}gravity = 0\n")).unwrap_err();
        assert!(e.to_string().contains("gravity = 0"), "{e}");
    }

    #[test]
    fn mount_priors_are_read_per_imu_by_the_joint_reader() {
        let text = format!(
            "{HEAD}[imu]\nmodel = \"a\"\n[imu.mount]\nposition = [0.01, 0.02, 0.03]\n\
             r_a = [0.1, 0.2, 0.3]\nrotation_sigma = 0.05\n\
             [imu1]\n[imu1.mount]\nposition_sigma = 0.001\nrotation_sigma = 0.02\n"
        );
        let m = parse(&text).unwrap();
        assert_eq!(m.mounts.len(), 2);
        assert_eq!(m.mounts[&0].position, Some([0.01, 0.02, 0.03]));
        assert_eq!(m.mounts[&0].r_a, Some([0.1, 0.2, 0.3]));
        assert_eq!(m.mounts[&1].position_sigma, Some(0.001));
        assert_eq!(m.mounts[&1].position, None);
        // the tables keep them: written and read again, the same priors
        assert_eq!(parse(&m.to_toml()).unwrap().mounts, m.mounts);
        // the same tables read by the joint reader give the same priors
        let joint = crate::SessionMeta::parse(
            &text.replace("source = \"poses\"", "robot = \"aubo_i5\""),
            Path::new("j.toml"),
        )
        .unwrap();
        assert_eq!(joint.mounts, m.mounts);
    }

    #[test]
    fn bad_mount_priors_name_the_table_and_key() {
        let bad = |t: &str| parse(&format!("{HEAD}{t}")).unwrap_err().to_string();
        let e = bad("[imu1.mount]\nposition_sigma = 0\n");
        assert!(e.contains("[imu1.mount] position_sigma = 0"), "{e}");
        let e = bad("[imu.mount]\nr_w = [0, nan, 0]\n");
        assert!(e.contains("[imu.mount] r_w") && e.contains("finite"), "{e}");
        let e = bad("[imu.mount]\nposition = [0, 0]\n");
        assert!(e.contains("[imu.mount]"), "{e}");
        let e = bad("[imu.mount]\nsigma = 1\n");
        assert!(e.contains("[imu.mount]") && e.contains("sigma"), "{e}");
        let e = bad("[imu2.mount]\nrotation_sigma = 0.1\n");
        assert!(
            e.contains("[imu2.mount] rotation_sigma without r_a or r_w"),
            "{e}"
        );
        // IMU 0's rotation means make IMU j's σ meaningful
        parse(&format!(
            "{HEAD}[imu.mount]\nr_w = [0, 0, 1]\n[imu2.mount]\nrotation_sigma = 0.1\n"
        ))
        .unwrap();
    }
}
