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
//! A session with tool poses instead of joint angles
//! (docs/model.md §7.9; `source = "poses"` in `session.toml`, [`SessionSource`])
//! has `poses.csv` in place of `joints.csv` and no robot: [`PoseSession`],
//! written by [`PoseSessionWriter`]. Each reader refuses the other kind.
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
mod pose_meta;
mod pose_session;
mod pose_writer;
pub mod poses;
pub mod result;
mod result_model;
mod source;
mod table;
mod text;
mod truth;
mod writer;

use std::path::{Path, PathBuf};

use robimu_model::observations::{ImuSamples, Measurements};
use robimu_model::Robot;

pub use error::toml_error;
pub use error::SessionError;
pub use meta::{
    check_ar_order_for_data, ImuTiming, MountPrior, NoiseOverride, NoiseShape, SessionMeta,
    SESSION_FORMAT,
};
pub use result::{
    CalibrationResult, CovarianceMatrix, MissingParameter, ParameterResult, ResultError, Trust,
    VerdictCheck, VerdictRecord, RESULT_FORMAT,
};
pub use table::{
    parse_table, parse_table_with, read_table, read_table_with, Columns, OptionalColumns, Table,
};
pub use truth::{Truth, TruthMismatch, TruthRow};
pub use writer::SessionWriter;

pub use pose_meta::{PoseNoise, PoseSessionMeta};
pub use pose_session::{
    pose_parameter_names, PoseMeasurements, PoseSession, MAX_POSITION, MIN_QUATERNION_NORM,
    POSE_COLUMNS, POSE_PARAMETERS,
};
pub use pose_writer::PoseSessionWriter;
pub use source::{SessionSource, SOURCE_JOINTS, SOURCE_POSES};

pub use export::imu::{ImuCsvError, SensorCorrection};
pub use export::ur::UrKinematicsError;
pub use export::ExportError;
pub use import::cdr::{CdrError, PoseMsg};
pub use import::pose_csv::{read_pose_csv, Orientation, PoseCsvOptions, PoseRows, QuaternionOrder};
pub use import::ImportError;
pub use poses::{PoseFile, PoseFileError};
pub use result::ImuSets;

/// `imu.csv` value columns.
pub use robimu_model::IMU_CHANNELS as IMU_COLUMNS;
/// The optional `imu.csv` column of the sensor temperature, °C (an extra
/// column after [`IMU_COLUMNS`], docs/model.md §7).
pub const IMU_TEMP_COLUMN: &str = "temp_c";
/// `tracker.csv` value columns.
pub const TRACKER_COLUMNS: [&str; 7] = ["px", "py", "pz", "qw", "qx", "qy", "qz"];

/// File names inside a session directory.
pub mod files {
    /// Metadata.
    pub const META: &str = "session.toml";

    pub use crate::export::imu::ImuCsvError;
    pub use crate::export::imu::SensorCorrection;
    pub use crate::export::ExportError;
    pub use crate::import::cdr::CdrError;
    pub use crate::import::ImportError;
    pub use crate::poses::PoseFile;
    pub use crate::poses::PoseFileError;
    pub use crate::result::ImuSets;
    /// Joint samples.
    pub const JOINTS: &str = "joints.csv";
    /// Tool poses of a pose session (docs/model.md §7.9), in place of [`JOINTS`].
    pub const POSES: &str = "poses.csv";
    /// IMU samples.
    pub const IMU: &str = "imu.csv";
    /// External tracker poses (validation only).
    pub const TRACKER: &str = "tracker.csv";
    /// True parameters (simulations only).
    pub const TRUTH: &str = "truth.toml";

    /// IMU `j`'s samples (docs/model.md §9): [`IMU`] for j = 0, else
    /// `imu<j>.csv`.
    pub fn imu_csv(j: usize) -> String {
        if j == 0 {
            IMU.to_string()
        } else {
            format!("imu{j}.csv")
        }
    }

    /// The `imu<j>.csv` files in a listing of names, by j ≥ 1 (ascending):
    /// `imu1.csv`, `imu2.csv`, … (`imu01.csv` or `imu0.csv` are not IMU files).
    pub fn extra_imu_indices<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<usize> {
        let mut js: Vec<usize> = names
            .into_iter()
            .filter_map(|n| imu_number(n.strip_suffix(".csv")?))
            .collect();
        js.sort_unstable();
        js
    }

    /// j of a name `imu<j>` with j ≥ 1 written without sign or leading zero
    /// (the `imu<j>.csv` file stems and `[imu<j>]` tables of §9); None for
    /// anything else (`imu`, `imu0`, `imu01`, `imu+1`, `imux`).
    pub fn imu_number(name: &str) -> Option<usize> {
        let d = name.strip_prefix("imu")?;
        let digits = !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit());
        if !digits || d.starts_with('0') {
            return None;
        }
        d.parse().ok()
    }
}

/// One IMU's file of a session: `imu.csv` or `imu<j>.csv` (docs/model.md §9).
#[derive(Debug, Clone)]
pub struct ImuTable {
    /// Columns [`IMU_COLUMNS`].
    pub samples: Table,
    /// The [`IMU_TEMP_COLUMN`] (°C), when the file has one.
    pub temp: Option<Vec<f64>>,
}

impl ImuTable {
    /// Read an IMU file: [`IMU_COLUMNS`] and the optional [`IMU_TEMP_COLUMN`].
    fn read(path: &Path) -> Result<Self, SessionError> {
        let (samples, mut extra) =
            read_table_with(path, Columns::Fixed(&IMU_COLUMNS), &[IMU_TEMP_COLUMN])?;
        Ok(Self {
            samples,
            temp: extra.pop().flatten(),
        })
    }
}

/// The rows of an IMU table as `[ax, ay, az, gx, gy, gz]` samples.
fn imu_rows(table: &Table) -> Vec<[f64; 6]> {
    table
        .values
        .chunks_exact(6)
        .map(|z| [z[0], z[1], z[2], z[3], z[4], z[5]])
        .collect()
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
    /// `imu1.csv`, `imu2.csv`, … of a multi-IMU session (docs/model.md §9):
    /// `extra_imus[j - 1]` is IMU j; empty for one IMU.
    pub extra_imus: Vec<ImuTable>,
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
        let (joints, imu) = robimu_model::pair::join(
            || read_table(&dir.join(files::JOINTS), Columns::Joints),
            || ImuTable::read(&dir.join(files::IMU)),
        );
        let joints = joints?;
        let ImuTable {
            samples: imu,
            temp: imu_temp,
        } = imu?;
        let extra_imus = read_extra_imus(dir)?;
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
            extra_imus,
            tracker,
            truth,
        })
    }

    /// Number of IMUs K (docs/model.md §9).
    pub fn n_imus(&self) -> usize {
        1 + self.extra_imus.len()
    }

    /// IMU `j` of a multi-IMU session as a one-IMU session (docs/model.md
    /// §9): its samples as `imu.csv`'s, its `[imu<j>]` table (and mount
    /// prior) as `[imu]`'s — IMU 0's mount where it has none — and a truth
    /// under the one-IMU names (`imu<j>/X` as `X`, the other IMUs' left out).
    /// `None` when the session has no IMU `j`.
    pub fn only_imu(&self, j: usize) -> Option<Session> {
        if j >= self.n_imus() {
            return None;
        }
        let mut s = self.clone();
        if j == 0 {
            s.extra_imus.clear();
            s.meta.imu_tables.clear();
            s.meta.mounts.retain(|&i, _| i == 0);
        } else {
            let ImuTable { samples, temp } = s.extra_imus.swap_remove(j - 1);
            (s.imu, s.imu_temp) = (samples, temp);
            s.extra_imus.clear();
            s.meta.imu = s.meta.imu_tables.remove(&j);
            s.meta.imu_tables.clear();
            if s.meta.mounts.contains_key(&j) {
                // IMU j's keys over IMU 0's (docs/model.md §9), as IMU 0's
                s.meta.mounts = [(0, MountPrior::of_imu(&s.meta.mounts, j))].into();
            } else {
                s.meta.mounts.retain(|&i, _| i == 0);
            }
        }
        s.truth = self.truth.as_ref().map(|t| t.of_imu(j));
        Some(s)
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
            imu_z: imu_rows(&self.imu),
            imu_temp: self.imu_temp.clone(),
            extra_imus: self
                .extra_imus
                .iter()
                .map(|f| ImuSamples {
                    t: f.samples.t.clone(),
                    z: imu_rows(&f.samples),
                    temp: f.temp.clone(),
                })
                .collect(),
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

/// Read `imu1.csv`, `imu2.csv`, … of `dir` (docs/model.md §9): they must be
/// consecutive from 1; a gap names the missing file.
fn read_extra_imus(dir: &Path) -> Result<Vec<ImuTable>, SessionError> {
    let listing = std::fs::read_dir(dir).map_err(|e| SessionError::io(dir, e))?;
    let names: Vec<String> = listing
        .filter_map(|e| e.ok())
        .filter_map(|e| e.file_name().into_string().ok())
        .collect();
    let js = files::extra_imu_indices(names.iter().map(String::as_str));
    let mut out = Vec::with_capacity(js.len());
    for (i, &j) in js.iter().enumerate() {
        if j != i + 1 {
            return Err(SessionError::file(
                dir.join(files::imu_csv(j)),
                format!(
                    "{} is missing: IMU files must be consecutive from imu1.csv (docs/model.md §9)",
                    files::imu_csv(i + 1)
                ),
            ));
        }
        out.push(ImuTable::read(&dir.join(files::imu_csv(j)))?);
    }
    Ok(out)
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

    #[test]
    fn extra_imu_files_load_in_order_and_a_gap_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write(
            d,
            "session.toml",
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n",
        );
        write(d, "joints.csv", "t,q1\n0,0\n1,0.1\n");
        write(d, "imu.csv", "t,ax,ay,az,gx,gy,gz\n0.5,0,0,9.81,0,0,0\n");
        write(d, "imu2.csv", "t,ax,ay,az,gx,gy,gz\n0.5,2,0,9.81,0,0,0\n");
        let e = Session::load(d).unwrap_err();
        assert!(
            e.to_string().contains("imu2.csv") && e.to_string().contains("imu1.csv is missing"),
            "{e}"
        );
        write(
            d,
            "imu1.csv",
            "t,ax,ay,az,gx,gy,gz,temp_c\n0.25,1,0,9.81,0,0,0,30\n0.75,1,0,9.81,0,0,0,31\n",
        );
        // not IMU files: ignored
        write(d, "imu01.csv", "junk");
        write(d, "imux.csv", "junk");
        let s = Session::load(d).unwrap();
        assert_eq!(s.n_imus(), 3);
        let m = s.measurements();
        assert_eq!(m.n_imus(), 3);
        assert_eq!(m.imu(1).t, &[0.25, 0.75]);
        assert_eq!(m.imu(1).temp, Some(&[30.0, 31.0][..]));
        assert_eq!(m.imu(2).z[0][0], 2.0);
        write(d, "imu1.csv", "t,ax,ay,az,gx,gy,gz\n0.25,1,0,x,0,0,0\n");
        let e = Session::load(d).unwrap_err();
        assert!(e.to_string().contains("imu1.csv:2"), "{e}");
    }

    #[test]
    fn imu_file_names() {
        assert_eq!(files::imu_csv(0), "imu.csv");
        assert_eq!(files::imu_csv(3), "imu3.csv");
        let names = [
            "imu.csv",
            "imu10.csv",
            "imu2.csv",
            "imu0.csv",
            "imu02.csv",
            "imu+3.csv",
            "imu1.csv",
            "x.csv",
        ];
        assert_eq!(files::extra_imu_indices(names), vec![1, 2, 10]);
        assert_eq!(files::imu_number("imu7"), Some(7));
        for not_imu in ["imu", "imu0", "imu01", "imu+1", "imux", "imu1.csv"] {
            assert_eq!(files::imu_number(not_imu), None, "{not_imu}");
        }
    }
}
