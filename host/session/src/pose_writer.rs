//! Writing a pose session (docs/model.md §7.9) row by row, as
//! [`crate::SessionWriter`] writes a joint session: buffered rows, values
//! in Rust's shortest round-trip form (a written session reads back to the
//! bit), [`PoseSessionWriter::flush`] to push them to the operating system.

use std::path::{Path, PathBuf};

use super::writer::CsvOut;
use super::{
    files, PoseMeasurements, PoseSessionMeta, SessionError, Truth, IMU_COLUMNS, POSE_COLUMNS,
};

/// An open pose session directory being written.
pub struct PoseSessionWriter {
    dir: PathBuf,
    poses: CsvOut,
    /// `imus[j]` is IMU j's file: `imu.csv` from the start, `imu<j>.csv`
    /// created on first use.
    imus: Vec<Option<CsvOut>>,
}

impl PoseSessionWriter {
    /// Create `dir` (and parents) and write `session.toml` and the headers
    /// of `poses.csv` and `imu.csv`. Existing session files in `dir` are
    /// replaced.
    pub fn create(dir: &Path, meta: &PoseSessionMeta) -> Result<Self, SessionError> {
        std::fs::create_dir_all(dir).map_err(|e| SessionError::io(dir, e))?;
        let meta_path = dir.join(files::META);
        std::fs::write(&meta_path, meta.to_toml()).map_err(|e| SessionError::io(&meta_path, e))?;
        let poses = CsvOut::create(
            dir.join(files::POSES),
            &format!("t,{}", POSE_COLUMNS.join(",")),
        )?;
        let mut w = Self {
            dir: dir.to_path_buf(),
            poses,
            imus: Vec::new(),
        };
        w.imu_out(0)?;
        Ok(w)
    }

    /// The directory being written.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Append a pose: t in s, p in m, `q = [w, x, y, z]` (written as given).
    pub fn pose(&mut self, t: f64, p: &[f64; 3], q: &[f64; 4]) -> Result<(), SessionError> {
        let row = [p[0], p[1], p[2], q[0], q[1], q[2], q[3]];
        self.poses.row(t, &row)
    }

    /// Append a sample of IMU 0: t in s, `z = [ax, ay, az, gx, gy, gz]`
    /// (m/s², rad/s).
    pub fn imu(&mut self, t: f64, z: &[f64; 6]) -> Result<(), SessionError> {
        self.imu_of(0, t, z)
    }

    /// Append a sample of IMU `j` (`imu<j>.csv` for j ≥ 1, created on its
    /// first sample).
    pub fn imu_of(&mut self, j: usize, t: f64, z: &[f64; 6]) -> Result<(), SessionError> {
        self.imu_out(j)?.row(t, z)
    }

    fn imu_out(&mut self, j: usize) -> Result<&mut CsvOut, SessionError> {
        if self.imus.len() <= j {
            self.imus.resize_with(j + 1, || None);
        }
        if self.imus[j].is_none() {
            let header = format!("t,{}", IMU_COLUMNS.join(","));
            self.imus[j] = Some(CsvOut::create(self.dir.join(files::imu_csv(j)), &header)?);
        }
        Ok(self.imus[j].as_mut().expect("created above"))
    }

    /// Append every pose and IMU sample of `data` (IMU 0's).
    pub fn measurements(&mut self, data: &PoseMeasurements) -> Result<(), SessionError> {
        for ((t, p), q) in data.pose_t.iter().zip(&data.pose_p).zip(&data.pose_q) {
            self.pose(*t, p, q)?;
        }
        for (t, z) in data.imu_t.iter().zip(&data.imu_z) {
            self.imu(*t, z)?;
        }
        Ok(())
    }

    /// Write `truth.toml` (for a simulation: the
    /// [`crate::pose_parameter_names`], which the reader requires).
    pub fn truth(&mut self, truth: &Truth) -> Result<(), SessionError> {
        let path = self.dir.join(files::TRUTH);
        std::fs::write(&path, truth.to_toml()).map_err(|e| SessionError::io(&path, e))
    }

    /// Push every buffered row to the operating system.
    pub fn flush(&mut self) -> Result<(), SessionError> {
        self.poses.flush()?;
        for out in self.imus.iter_mut().flatten() {
            out.flush()?;
        }
        Ok(())
    }

    /// Flush and close.
    pub fn finish(mut self) -> Result<PathBuf, SessionError> {
        self.flush()?;
        Ok(self.dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PoseNoise, PoseSession, POSE_PARAMETERS};

    #[test]
    fn written_pose_session_reads_back_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let meta = PoseSessionMeta {
            poses: Some(PoseNoise {
                sigma_p: Some(1e-4),
                sigma_r: Some(1e-3),
            }),
            ..Default::default()
        };
        let mut w = PoseSessionWriter::create(dir.path(), &meta).unwrap();
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let data = PoseMeasurements {
            pose_t: vec![0.0, 1.0 / 3.0, 0.7],
            pose_p: vec![[0.1, 0.2, 0.3], [1.0 / 7.0, -1e-300, 0.0], [0.0; 3]],
            pose_q: vec![
                [1.0, 0.0, 0.0, 0.0],
                [h, 0.0, h, 0.0],
                [0.0, 0.0, 0.0, -1.0],
            ],
            imu_t: vec![0.01, 0.02],
            imu_z: vec![[1.0 / 7.0, 2.0, 3.0, 4.0, 5.0, 6.0], [0.0; 6]],
        };
        w.measurements(&data).unwrap();
        w.imu_of(1, 0.5, &[7.0; 6]).unwrap();
        let truth = Truth {
            values: crate::pose_parameter_names(2)
                .into_iter()
                .enumerate()
                .map(|(k, n)| (n, k as f64 * 0.1))
                .collect(),
        };
        w.truth(&truth).unwrap();
        w.finish().unwrap();
        let s = PoseSession::read(dir.path()).unwrap();
        assert_eq!(s.meta, meta);
        assert_eq!(s.measurements(), data);
        assert_eq!(s.n_imus(), 2);
        assert_eq!(s.measurements_of_imu(1).unwrap().imu_z, [[7.0; 6]]);
        let x = s.truth_vector().unwrap();
        assert_eq!(x.len(), 58);
        assert_eq!(x[5], 0.5);
        assert_eq!(POSE_PARAMETERS[5], "tau");
    }
}
