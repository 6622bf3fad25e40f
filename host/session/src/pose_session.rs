//! A session with tool poses instead of joint angles
//! (docs/model.md §7.9): `session.toml` ([`PoseSessionMeta`], `source =
//! "poses"`), `poses.csv` (`t,px,py,pz,qw,qx,qy,qz`: s, m, a unit
//! quaternion w first of the posed body B in the world W), `imu.csv` and
//! `imu<j>.csv` as in a joint session, and for simulations `truth.toml`
//! with the [`pose_parameter_names`].
//!
//! Reading validates what the table reader does (header, every value a
//! finite number, time never decreasing) and the poses themselves: a
//! position beyond [`MAX_POSITION`] m is not in metres, a quaternion of norm
//! below [`MIN_QUATERNION_NORM`] is not a rotation. Whether the quaternions
//! are unit and the positions plausible metres is `robimu check`'s to say
//! (`robimu_workflows::check::poses`): they are read as they are.

use std::path::{Path, PathBuf};

use super::{
    files, read_table, Columns, ImuTable, PoseSessionMeta, SessionError, Table, Truth,
    TRACKER_COLUMNS,
};

/// `poses.csv` value columns (those of `tracker.csv`).
pub const POSE_COLUMNS: [&str; 7] = TRACKER_COLUMNS;
/// A position component beyond this (m) is refused: no tool or tracked body
/// is 10 km from its world origin (positions in mm stay below it up to
/// 10 m; `robimu check` names those).
pub const MAX_POSITION: f64 = 1e4;
/// A quaternion of norm below this is refused: it is no rotation (zeros
/// of a tracker that lost the body, or columns that are not a quaternion).
pub const MIN_QUATERNION_NORM: f64 = 0.1;

/// The parameters of a one-IMU pose session, in docs/model.md §7.9's order:
/// the IMU's position on the posed body, gravity, τ and the 24 sensor
/// parameters of §5.
pub const POSE_PARAMETERS: [&str; 30] = [
    "p_imu_x",
    "p_imu_y",
    "p_imu_z",
    "g_x",
    "g_y",
    "tau",
    "gamma_a_yz",
    "gamma_a_zy",
    "gamma_a_zx",
    "r_a_z",
    "r_a_y",
    "r_a_x",
    "k_a_x",
    "k_a_y",
    "k_a_z",
    "b_a_x",
    "b_a_y",
    "b_a_z",
    "gamma_w_yz",
    "gamma_w_zy",
    "gamma_w_zx",
    "r_w_z",
    "r_w_y",
    "r_w_x",
    "k_w_x",
    "k_w_y",
    "k_w_z",
    "b_w_x",
    "b_w_y",
    "b_w_z",
];

/// The parameter names of a pose session with `n_imus` IMUs: IMU 0's
/// [`POSE_PARAMETERS`], then for each IMU j ≥ 1 its own 28 (all but the
/// shared `g_x`, `g_y`) as `imu<j>/<name>` (docs/model.md §7.9, §9).
pub fn pose_parameter_names(n_imus: usize) -> Vec<String> {
    let mut names: Vec<String> = POSE_PARAMETERS.iter().map(|n| n.to_string()).collect();
    for j in 1..n_imus {
        let own = POSE_PARAMETERS.iter().filter(|n| !n.starts_with("g_"));
        names.extend(own.map(|n| format!("imu{j}/{n}")));
    }
    names
}

/// The samples of a pose session as plain data: the pose calibration's
/// input.
pub use robimu_model::observations::PoseMeasurements;

/// A pose session loaded into memory.
#[derive(Debug, Clone)]
pub struct PoseSession {
    /// The directory it was read from.
    pub dir: PathBuf,
    /// `session.toml`.
    pub meta: PoseSessionMeta,
    /// `poses.csv`: columns [`POSE_COLUMNS`].
    pub poses: Table,
    /// `imu.csv`, `imu1.csv`, …: `imus[j]` is IMU j (at least IMU 0).
    pub imus: Vec<ImuTable>,
    /// `truth.toml`, when present: exactly the [`pose_parameter_names`].
    pub truth: Option<Truth>,
}

impl PoseSession {
    /// Read and validate the pose session in `dir`. A joint session is
    /// refused as such (by its `session.toml`).
    pub fn read(dir: &Path) -> Result<Self, SessionError> {
        if !dir.is_dir() {
            return Err(SessionError::file(
                dir,
                "not a session directory (it does not exist or is not a directory)",
            ));
        }
        let meta = PoseSessionMeta::read(&dir.join(files::META))?;
        let (poses, imu) = robimu_model::pair::join(
            || read_poses(&dir.join(files::POSES)),
            || ImuTable::read(&dir.join(files::IMU)),
        );
        let mut imus = vec![imu?];
        let poses = poses?;
        imus.extend(crate::read_extra_imus(dir)?);
        let truth_path = dir.join(files::TRUTH);
        let truth = if truth_path.exists() {
            let truth = Truth::read(&truth_path)?;
            check_truth(&truth, imus.len(), &truth_path)?;
            Some(truth)
        } else {
            None
        };
        Ok(Self {
            dir: dir.to_path_buf(),
            meta,
            poses,
            imus,
            truth,
        })
    }

    /// Number of IMUs K.
    pub fn n_imus(&self) -> usize {
        self.imus.len()
    }

    /// The positions p (m), one per pose row.
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.poses
            .values
            .chunks_exact(7)
            .map(|r| [r[0], r[1], r[2]])
            .collect()
    }

    /// The quaternions `[w, x, y, z]` as written, one per pose row.
    pub fn quaternions(&self) -> Vec<[f64; 4]> {
        self.poses
            .values
            .chunks_exact(7)
            .map(|r| [r[3], r[4], r[5], r[6]])
            .collect()
    }

    /// The poses and IMU 0's samples as plain data (no IMU samples for a
    /// session built without IMU 0).
    pub fn measurements(&self) -> PoseMeasurements {
        self.with_imu(self.imus.first().map(|f| &f.samples))
    }

    /// The poses and IMU `j`'s samples; `None` without an IMU `j`.
    pub fn measurements_of_imu(&self, j: usize) -> Option<PoseMeasurements> {
        Some(self.with_imu(Some(&self.imus.get(j)?.samples)))
    }

    fn with_imu(&self, imu: Option<&Table>) -> PoseMeasurements {
        PoseMeasurements {
            pose_t: self.poses.t.clone(),
            pose_p: self.positions(),
            pose_q: self.quaternions(),
            imu_t: imu.map(|f| f.t.clone()).unwrap_or_default(),
            imu_z: imu.map(crate::imu_rows).unwrap_or_default(),
        }
    }

    /// The true parameters in [`pose_parameter_names`] order, when the
    /// session has a truth (checked on reading to list exactly those).
    pub fn truth_vector(&self) -> Option<Vec<f64>> {
        let truth = self.truth.as_ref()?;
        pose_parameter_names(self.n_imus())
            .iter()
            .map(|n| truth.get(n))
            .collect()
    }
}

/// Read `poses.csv`: the table, then every position within
/// [`MAX_POSITION`] and every quaternion's norm above
/// [`MIN_QUATERNION_NORM`].
fn read_poses(path: &Path) -> Result<Table, SessionError> {
    if !path.exists() {
        return Err(SessionError::file(
            path,
            "missing: a pose session has its poses in poses.csv (t,px,py,pz,qw,qx,qy,qz; \
             docs/model.md §7.9)",
        ));
    }
    let table = read_table(path, Columns::Fixed(&POSE_COLUMNS))?;
    for (i, row) in table.values.chunks_exact(7).enumerate() {
        let at = || format!("data row {} (t = {} s)", i + 1, table.t[i]);
        if let Some(c) = (0..3).find(|&c| row[c].abs() > MAX_POSITION) {
            return Err(SessionError::file(
                path,
                format!(
                    "{}, column `{}`: {} m is beyond {MAX_POSITION} m: poses.csv holds \
                     metres (docs/model.md §7.9)",
                    at(),
                    POSE_COLUMNS[c],
                    row[c]
                ),
            ));
        }
        let norm = row[3..7].iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm < MIN_QUATERNION_NORM {
            return Err(SessionError::file(
                path,
                format!(
                    "{}, columns `qw,qx,qy,qz`: ({}, {}, {}, {}) of norm {norm} is not a \
                     rotation (a unit quaternion, w first)",
                    at(),
                    row[3],
                    row[4],
                    row[5],
                    row[6]
                ),
            ));
        }
    }
    Ok(table)
}

/// A truth must list exactly the [`pose_parameter_names`] of `n_imus` IMUs.
fn check_truth(truth: &Truth, n_imus: usize, path: &Path) -> Result<(), SessionError> {
    let names = pose_parameter_names(n_imus);
    if let Some((n, _)) = truth.values.iter().find(|(n, _)| !names.contains(n)) {
        return Err(SessionError::file(
            path,
            format!(
                "`{n}` is not a parameter of a pose session with {n_imus} IMU(s) (docs/model.md \
                 §7.9: p_imu_x, p_imu_y, p_imu_z, g_x, g_y, tau and the sensor parameters)"
            ),
        ));
    }
    if let Some(n) = names.iter().find(|n| truth.get(n).is_none()) {
        return Err(SessionError::file(path, format!("`{n}` is missing")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(name), text).unwrap();
    }

    const META: &str = "format = \"robimu-session/1\"\nsource = \"poses\"\n";
    const IMU: &str = "t,ax,ay,az,gx,gy,gz\n0.5,0,0,9.81,0,0,0.01\n";

    fn minimal() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write(d, "session.toml", META);
        write(
            d,
            "poses.csv",
            "t,px,py,pz,qw,qx,qy,qz\n0,0.1,0.2,0.3,1,0,0,0\n1,0.1,0.2,0.4,0,1,0,0\n",
        );
        write(d, "imu.csv", IMU);
        dir
    }

    #[test]
    fn reads_a_minimal_pose_session() {
        let dir = minimal();
        let s = PoseSession::read(dir.path()).unwrap();
        assert_eq!(s.n_imus(), 1);
        let m = s.measurements();
        assert_eq!(m.pose_t, [0.0, 1.0]);
        assert_eq!(m.pose_p[1], [0.1, 0.2, 0.4]);
        assert_eq!(m.pose_q[1], [0.0, 1.0, 0.0, 0.0]);
        assert_eq!(m.imu_z, [[0.0, 0.0, 9.81, 0.0, 0.0, 0.01]]);
        assert!(s.measurements_of_imu(1).is_none());
        assert!(s.truth.is_none() && s.truth_vector().is_none());
    }

    #[test]
    fn bad_pose_files_name_file_row_and_column() {
        let dir = minimal();
        let d = dir.path();
        let err = |d: &Path| PoseSession::read(d).unwrap_err().to_string();
        write(d, "poses.csv", "t,px,py,pz,qw,qx,qy\n0,0,0,0,1,0,0\n");
        assert!(err(d).contains("missing column `qz`"), "{}", err(d));
        write(
            d,
            "poses.csv",
            "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,0,inf,0,1,0,0,0\n",
        );
        let e = err(d);
        assert!(e.contains("poses.csv:3") && e.contains("`py`"), "{e}");
        write(
            d,
            "poses.csv",
            "t,px,py,pz,qw,qx,qy,qz\n1,0,0,0,1,0,0,0\n0.5,0,0,0,1,0,0,0\n",
        );
        assert!(err(d).contains("time goes backwards"), "{}", err(d));
        write(
            d,
            "poses.csv",
            "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n1,0,0,2e4,1,0,0,0\n",
        );
        let e = err(d);
        assert!(
            e.contains("data row 2 (t = 1 s), column `pz`") && e.contains("metres"),
            "{e}"
        );
        write(d, "poses.csv", "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,0,0,0,0\n");
        let e = err(d);
        assert!(
            e.contains("data row 1") && e.contains("not a rotation"),
            "{e}"
        );
        std::fs::remove_file(d.join("poses.csv")).unwrap();
        assert!(err(d).contains("poses.csv: missing"), "{}", err(d));
    }

    /// The two readers refuse each other's sessions with a message naming
    /// the kind, never a panic.
    #[test]
    fn joint_and_pose_readers_refuse_each_others_sessions() {
        let dir = minimal();
        let e = crate::Session::load(dir.path()).unwrap_err().to_string();
        assert!(e.contains("this is a pose session"), "{e}");
        write(
            dir.path(),
            "session.toml",
            "format = \"robimu-session/1\"\nrobot = \"aubo_i5\"\n",
        );
        let e = PoseSession::read(dir.path()).unwrap_err().to_string();
        assert!(e.contains("this is a joint session"), "{e}");
        write(
            dir.path(),
            "session.toml",
            "format = \"robimu-session/1\"\n",
        );
        let e = crate::Session::load(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("no `robot` key") && e.contains("source = \"poses\""),
            "{e}"
        );
        let e = PoseSession::read(&dir.path().join("nope")).unwrap_err();
        assert!(e.to_string().contains("not a session directory"), "{e}");
    }

    /// The model's layout of x ([`robimu_model::pose_measurement::imu_indices`])
    /// puts each IMU's parameters at their names.
    #[test]
    fn names_follow_the_models_layout_of_x() {
        use robimu_model::pose_measurement::{imu_indices, n_pose_params};
        let names = pose_parameter_names(3);
        assert_eq!(names.len(), n_pose_params(3));
        for j in 0..3 {
            for (k, &i) in imu_indices(j).iter().enumerate() {
                let own = POSE_PARAMETERS[k];
                let want = match j {
                    0 => own.to_string(),
                    _ if own.starts_with("g_") => own.to_string(),
                    _ => format!("imu{j}/{own}"),
                };
                assert_eq!(names[i], want);
            }
        }
    }

    #[test]
    fn a_truth_lists_exactly_the_pose_parameters() {
        let dir = minimal();
        let d = dir.path();
        let names = pose_parameter_names(2);
        assert_eq!(names.len(), 30 + 28);
        assert_eq!(names[30], "imu1/p_imu_x");
        assert!(!names.iter().any(|n| n == "imu1/g_x"));
        let x: Vec<f64> = (0..30).map(|k| k as f64 / 8.0).collect();
        let truth = Truth {
            values: POSE_PARAMETERS
                .iter()
                .zip(&x)
                .map(|(n, v)| (n.to_string(), *v))
                .collect(),
        };
        write(d, "truth.toml", &truth.to_toml());
        let s = PoseSession::read(d).unwrap();
        assert_eq!(s.truth_vector().unwrap(), x);
        let mut short = truth.clone();
        short.values.retain(|(n, _)| n != "tau");
        write(d, "truth.toml", &short.to_toml());
        let e = PoseSession::read(d).unwrap_err().to_string();
        assert!(e.contains("truth.toml: `tau` is missing"), "{e}");
        let mut joint = truth;
        joint.values.push(("eps_1_1".into(), 0.0));
        write(d, "truth.toml", &joint.to_toml());
        let e = PoseSession::read(d).unwrap_err().to_string();
        assert!(e.contains("`eps_1_1` is not a parameter"), "{e}");
    }
}
