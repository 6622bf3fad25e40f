//! The session directory, the interchange format of recordings and
//! simulations (docs/model.md §7):
//!
//! * `session.toml` — [`SessionMeta`]
//! * `joints.csv` — `t,q1,…,qn` (s, rad)
//! * `imu.csv` — `t,ax,ay,az,gx,gy,gz` (s, m/s², rad/s); optionally an
//!   extra column `temp_c`, the sensor temperature (°C), read when present
//! * `tracker.csv` — optional, `t,px,py,pz,qw,qx,qy,qz`
//! * `truth.toml` — optional, simulated sessions only ([`Truth`])
//!
//! Reading validates everything a later stage relies on and names the file and
//! line of the first problem. Writing goes through [`SessionWriter`], which
//! appends rows and flushes, so that a recording killed mid-run leaves a
//! readable session.
//!
//! Main types: [`Session`] (a loaded session: [`Session::load`],
//! [`Session::measurements`], [`Session::noise`]), [`CalibrationResult`] (the
//! result file, docs/model.md §8), [`SessionError`] (the file and line of a
//! problem); [`import`] reads ROS 2 recordings and CSV files, [`export`] writes
//! corrected robots and IMU corrections.
//!
//! # Example
//!
//! A two-joint session of two joint rows and one IMU row, written and loaded:
//!
//! ```
//! use robimu_session::Session;
//!
//! let dir = tempfile::tempdir()?;
//! let d = dir.path();
//! std::fs::write(d.join("session.toml"), "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n")?;
//! std::fs::write(d.join("joints.csv"), "t,q1,q2\n0,0,0\n1,0.1,0.2\n")?;
//! std::fs::write(d.join("imu.csv"), "t,ax,ay,az,gx,gy,gz\n0.5,0,0,9.81,0,0,0.01\n")?;
//!
//! let session = Session::load(d)?;
//! assert_eq!(session.joint_count(), 2);
//! let m = session.measurements();
//! assert_eq!((m.joint_t.len(), m.imu_t.len()), (2, 1));
//! assert_eq!(m.imu_z[0], [0.0, 0.0, 9.81, 0.0, 0.0, 0.01]);
//! // a broken file is named with its line
//! std::fs::write(d.join("joints.csv"), "t,q1,q2\n0,0,0\n1,x,0.2\n")?;
//! let e = Session::load(d).unwrap_err();
//! assert!(e.to_string().contains("joints.csv:3"), "{e}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]
#![allow(clippy::needless_range_loop)]

mod error;
pub mod export;
pub mod import;
mod meta;
pub mod poses;
pub mod result;
mod table;
mod truth;
mod writer;

use std::path::{Path, PathBuf};

use robimu_model::observations::Measurements;
use robimu_model::Robot;

pub use error::SessionError;
pub use meta::toml_error;
pub use meta::{
    check_ar_order_for_data, ImuTiming, NoiseOverride, NoiseShape, SessionMeta, SESSION_FORMAT,
};
pub use result::{
    CalibrationResult, CovarianceMatrix, MissingParameter, ParameterResult, ResultError, Trust,
    VerdictCheck, VerdictRecord, RESULT_FORMAT,
};
pub use table::{
    parse_table, parse_table_with, read_table, read_table_with, Columns, OptionalColumns, Table,
};
pub use truth::{Truth, TruthMismatch};
pub use writer::SessionWriter;

/// `imu.csv` value columns.
pub const IMU_COLUMNS: [&str; 6] = ["ax", "ay", "az", "gx", "gy", "gz"];
/// The optional `imu.csv` column of the sensor temperature, °C (an extra
/// column after [`IMU_COLUMNS`], docs/model.md §7).
pub const IMU_TEMP_COLUMN: &str = "temp_c";
/// `tracker.csv` value columns.
pub const TRACKER_COLUMNS: [&str; 7] = ["px", "py", "pz", "qw", "qx", "qy", "qz"];

/// File names inside a session directory.
pub mod files {
    /// Metadata.
    pub const META: &str = "session.toml";
    /// Joint samples.
    pub const JOINTS: &str = "joints.csv";
    /// IMU samples.
    pub const IMU: &str = "imu.csv";
    /// External tracker poses (validation only).
    pub const TRACKER: &str = "tracker.csv";
    /// True parameters (simulations only).
    pub const TRUTH: &str = "truth.toml";
}

/// A session loaded into memory.
#[derive(Debug, Clone)]
pub struct Session {
    /// The directory it was read from.
    pub dir: PathBuf,
    /// `session.toml`.
    pub meta: SessionMeta,
    /// `joints.csv`: columns `q1..qn`.
    pub joints: Table,
    /// `imu.csv`: columns [`IMU_COLUMNS`].
    pub imu: Table,
    /// `imu.csv`'s [`IMU_TEMP_COLUMN`] (°C, one per IMU row), when it has one.
    pub imu_temp: Option<Vec<f64>>,
    /// `tracker.csv`, when present.
    pub tracker: Option<Table>,
    /// `truth.toml`, when present.
    pub truth: Option<Truth>,
}

impl Session {
    /// Read and validate the session in `dir`.
    pub fn load(dir: &Path) -> Result<Self, SessionError> {
        if !dir.is_dir() {
            return Err(SessionError::file(
                dir,
                "not a session directory (it does not exist or is not a directory)",
            ));
        }
        let meta = SessionMeta::read(&dir.join(files::META))?;
        // the two streams are parsed on two threads (joints.csv's error first)
        let (joints, imu) = std::thread::scope(|s| {
            let imu = s.spawn(|| {
                read_table_with(
                    &dir.join(files::IMU),
                    Columns::Fixed(&IMU_COLUMNS),
                    &[IMU_TEMP_COLUMN],
                )
            });
            let joints = read_table(&dir.join(files::JOINTS), Columns::Joints);
            (joints, imu.join().expect("imu.csv reader panicked"))
        });
        let joints = joints?;
        let (imu, mut extra) = imu?;
        let imu_temp = extra.pop().flatten();
        let tracker_path = dir.join(files::TRACKER);
        let tracker = if tracker_path.exists() {
            Some(read_table(&tracker_path, Columns::Fixed(&TRACKER_COLUMNS))?)
        } else {
            None
        };
        let truth_path = dir.join(files::TRUTH);
        let truth = if truth_path.exists() {
            Some(Truth::read(&truth_path)?)
        } else {
            None
        };
        if let Some(noise) = &meta.noise {
            if let Some(sq) = &noise.sigma_q {
                if sq.len() != joints.width() {
                    return Err(SessionError::file(
                        dir.join(files::META),
                        format!(
                            "[noise] sigma_q has {} values but joints.csv has {} joints",
                            sq.len(),
                            joints.width()
                        ),
                    ));
                }
            }
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            meta,
            joints,
            imu,
            imu_temp,
            tracker,
            truth,
        })
    }

    /// Number of joints in `joints.csv`.
    pub fn joint_count(&self) -> usize {
        self.joints.width()
    }

    /// The samples as the calibrator's [`Measurements`].
    pub fn measurements(&self) -> Measurements {
        Measurements {
            joint_t: self.joints.t.clone(),
            joint_q: self.joints.values.clone(),
            imu_t: self.imu.t.clone(),
            imu_z: self
                .imu
                .values
                .chunks_exact(6)
                .map(|z| [z[0], z[1], z[2], z[3], z[4], z[5]])
                .collect(),
            imu_temp: self.imu_temp.clone(),
        }
    }

    /// Noise standard deviations `(σ_z, σ_q)`: `robot`'s defaults, overridden
    /// by the session's `[noise]` table.
    pub fn noise(&self, robot: &Robot) -> Result<([f64; 6], Vec<f64>), SessionError> {
        let noise = self.meta.noise.clone().unwrap_or_default();
        let sigma_z = noise.sigma_z.unwrap_or_else(|| robot.sigma_z());
        let sigma_q = noise.sigma_q.unwrap_or_else(|| robot.sigma_q().to_vec());
        if sigma_q.len() != robot.dof() {
            return Err(SessionError::file(
                self.dir.join(files::META),
                format!(
                    "[noise] sigma_q has {} values but robot `{}` has {} joints",
                    sigma_q.len(),
                    robot.name(),
                    robot.dof()
                ),
            ));
        }
        Ok((sigma_z, sigma_q))
    }

    /// The IMU noise model (docs/model.md §4.6): [`Self::noise`]'s σ_z with
    /// the `[noise]` table's `ar_z` and `motion_z` (white when absent).
    pub fn noise_model(
        &self,
        robot: &Robot,
    ) -> Result<robimu_model::noise::NoiseModel, SessionError> {
        let (sigma_z, _) = self.noise(robot)?;
        self.meta
            .noise_model(sigma_z)
            .map_err(|e| SessionError::file(self.dir.join(files::META), format!("[noise]: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(name), text).unwrap();
    }

    #[test]
    fn load_minimal_session_and_report_missing_files() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let e = Session::load(d).unwrap_err();
        assert!(e.to_string().contains("session.toml"), "{e}");
        write(
            d,
            "session.toml",
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n",
        );
        let e = Session::load(d).unwrap_err();
        assert!(e.to_string().contains("joints.csv"), "{e}");
        write(d, "joints.csv", "t,q1,q2\n0,0,0\n1,0.1,0.2\n");
        write(d, "imu.csv", "t,ax,ay,az,gx,gy,gz\n0.5,0,0,9.81,0,0,0\n");
        let s = Session::load(d).unwrap();
        assert_eq!(s.joint_count(), 2);
        assert_eq!(s.imu.row(0), [0.0, 0.0, 9.81, 0.0, 0.0, 0.0]);
        assert!(s.tracker.is_none() && s.truth.is_none() && s.imu_temp.is_none());
        assert!(s.measurements().imu_temp.is_none());
        write(
            d,
            "session.toml",
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n[noise]\nsigma_q = [1e-4]\n",
        );
        let e = Session::load(d).unwrap_err();
        assert!(
            e.to_string()
                .contains("sigma_q has 1 values but joints.csv has 2"),
            "{e}"
        );
        let e = Session::load(&d.join("nope")).unwrap_err();
        assert!(e.to_string().contains("not a session directory"), "{e}");
    }
}
