//! Writing a session directory row by row.
//!
//! Rows are appended through buffered writers; [`SessionWriter::flush`] pushes
//! them to the operating system. A recorder calls it at least once a second,
//! so that a crash or a kill loses at most the last second, and what is on disk
//! is always a readable session (at worst with a truncated last line, which
//! `robimu repair` removes). Values are written in Rust's shortest
//! round-trip form, so reading a written session gives back the same numbers.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use robimu_model::observations::Measurements;

use super::{files, SessionError, SessionMeta, Truth, IMU_COLUMNS, TRACKER_COLUMNS};

/// An open session directory being written.
pub struct SessionWriter {
    dir: PathBuf,
    joints: CsvOut,
    imu: CsvOut,
    /// `imu<j>.csv` for j ≥ 1 (docs/model.md §9), created on first use.
    extra_imus: Vec<Option<CsvOut>>,
    imu_header: String,
    tracker: Option<CsvOut>,
    joint_count: usize,
}

/// One CSV file being written (shared with the pose-session writer).
pub(crate) struct CsvOut {
    path: PathBuf,
    out: BufWriter<File>,
}

impl CsvOut {
    pub(crate) fn create(path: PathBuf, header: &str) -> Result<Self, SessionError> {
        let file = File::create(&path).map_err(|e| SessionError::io(&path, e))?;
        let mut out = BufWriter::new(file);
        writeln!(out, "{header}").map_err(|e| SessionError::io(&path, e))?;
        Ok(Self { path, out })
    }

    pub(crate) fn row(&mut self, t: f64, values: &[f64]) -> Result<(), SessionError> {
        let mut line = String::with_capacity(24 * (values.len() + 1));
        line.push_str(&format!("{t:?}"));
        for v in values {
            line.push(',');
            line.push_str(&format!("{v:?}"));
        }
        line.push('\n');
        self.out
            .write_all(line.as_bytes())
            .map_err(|e| SessionError::io(&self.path, e))
    }

    pub(crate) fn flush(&mut self) -> Result<(), SessionError> {
        self.out
            .flush()
            .map_err(|e| SessionError::io(&self.path, e))
    }
}

impl SessionWriter {
    /// Create `dir` (and parents) and write `session.toml` and the CSV headers
    /// for a robot with `joint_count` joints. Existing session files in `dir`
    /// are replaced.
    pub fn create(
        dir: &Path,
        meta: &SessionMeta,
        joint_count: usize,
    ) -> Result<Self, SessionError> {
        Self::create_with_imu_extra(dir, meta, joint_count, &[])
    }

    /// [`Self::create`] with extra `imu.csv` columns after the required ones
    /// (docs/model.md §7 lets readers ignore them), written by [`Self::imu_extra`].
    pub fn create_with_imu_extra(
        dir: &Path,
        meta: &SessionMeta,
        joint_count: usize,
        imu_extra: &[&str],
    ) -> Result<Self, SessionError> {
        Self::create_with_extra(dir, meta, joint_count, &[], imu_extra)
    }

    /// [`Self::create_with_imu_extra`] with extra `joints.csv` columns too,
    /// written by [`Self::joint_extra`].
    pub fn create_with_extra(
        dir: &Path,
        meta: &SessionMeta,
        joint_count: usize,
        joint_extra: &[&str],
        imu_extra: &[&str],
    ) -> Result<Self, SessionError> {
        std::fs::create_dir_all(dir).map_err(|e| SessionError::io(dir, e))?;
        let meta_path = dir.join(files::META);
        std::fs::write(&meta_path, meta.to_toml()).map_err(|e| SessionError::io(&meta_path, e))?;
        let jheader: Vec<String> = std::iter::once("t".to_string())
            .chain((1..=joint_count).map(|i| format!("q{i}")))
            .chain(joint_extra.iter().map(|c| c.to_string()))
            .collect();
        let joints = CsvOut::create(dir.join(files::JOINTS), &jheader.join(","))?;
        let mut imu_header = format!("t,{}", IMU_COLUMNS.join(","));
        for name in imu_extra {
            imu_header.push(',');
            imu_header.push_str(name);
        }
        let imu = CsvOut::create(dir.join(files::IMU), &imu_header)?;
        Ok(Self {
            dir: dir.to_path_buf(),
            joints,
            imu,
            extra_imus: Vec::new(),
            imu_header,
            tracker: None,
            joint_count,
        })
    }

    /// The directory being written.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Append a joint sample (t in s, q in rad).
    ///
    /// # Panics
    /// If `q.len()` is not the joint count given to [`Self::create`].
    #[track_caller]
    pub fn joint(&mut self, t: f64, q: &[f64]) -> Result<(), SessionError> {
        assert_eq!(q.len(), self.joint_count, "joint sample width");
        self.joints.row(t, q)
    }

    /// Append a joint sample with the values of the extra columns given to
    /// [`Self::create_with_extra`].
    ///
    /// # Panics
    /// If `q.len()` is not the joint count given to [`Self::create_with_extra`].
    #[track_caller]
    pub fn joint_extra(&mut self, t: f64, q: &[f64], extra: &[f64]) -> Result<(), SessionError> {
        assert_eq!(q.len(), self.joint_count, "joint sample width");
        let mut values = Vec::with_capacity(q.len() + extra.len());
        values.extend_from_slice(q);
        values.extend_from_slice(extra);
        self.joints.row(t, &values)
    }

    /// Append an IMU sample: t in s, `z = [ax, ay, az, gx, gy, gz]` (m/s², rad/s).
    pub fn imu(&mut self, t: f64, z: &[f64; 6]) -> Result<(), SessionError> {
        self.imu_of(0, t, z)
    }

    /// Append an IMU sample with the values of the extra columns given to
    /// [`Self::create_with_imu_extra`].
    pub fn imu_extra(&mut self, t: f64, z: &[f64; 6], extra: &[f64]) -> Result<(), SessionError> {
        self.imu_extra_of(0, t, z, extra)
    }

    /// Append a sample of IMU `j` (docs/model.md §9): to `imu.csv` for
    /// j = 0, else to `imu<j>.csv`, created with `imu.csv`'s header (extra
    /// columns included) on its first sample.
    pub fn imu_of(&mut self, j: usize, t: f64, z: &[f64; 6]) -> Result<(), SessionError> {
        self.imu_out(j)?.row(t, z)
    }

    /// [`Self::imu_of`] with the values of the extra columns.
    pub fn imu_extra_of(
        &mut self,
        j: usize,
        t: f64,
        z: &[f64; 6],
        extra: &[f64],
    ) -> Result<(), SessionError> {
        let mut values = Vec::with_capacity(6 + extra.len());
        values.extend_from_slice(z);
        values.extend_from_slice(extra);
        self.imu_out(j)?.row(t, &values)
    }

    fn imu_out(&mut self, j: usize) -> Result<&mut CsvOut, SessionError> {
        if j == 0 {
            return Ok(&mut self.imu);
        }
        if self.extra_imus.len() < j {
            self.extra_imus.resize_with(j, || None);
        }
        if self.extra_imus[j - 1].is_none() {
            self.extra_imus[j - 1] = Some(CsvOut::create(
                self.dir.join(files::imu_csv(j)),
                &self.imu_header,
            )?);
        }
        Ok(self.extra_imus[j - 1].as_mut().expect("created above"))
    }

    /// Append a tracker pose: t in s, `[px, py, pz, qw, qx, qy, qz]` (m, unit quaternion).
    pub fn tracker(&mut self, t: f64, pose: &[f64; 7]) -> Result<(), SessionError> {
        if self.tracker.is_none() {
            self.tracker = Some(CsvOut::create(
                self.dir.join(files::TRACKER),
                &format!("t,{}", TRACKER_COLUMNS.join(",")),
            )?);
        }
        self.tracker.as_mut().expect("created above").row(t, pose)
    }

    /// Append every joint and IMU sample of `data` (every IMU's, docs/model.md §9).
    ///
    /// # Panics
    /// If `data`'s joint rows are not the joint count given to [`Self::create`].
    #[track_caller]
    pub fn measurements(&mut self, data: &Measurements) -> Result<(), SessionError> {
        for (t, q) in data
            .joint_t
            .iter()
            .zip(data.joint_q.chunks_exact(self.joint_count))
        {
            self.joint(*t, q)?;
        }
        for j in 0..data.n_imus() {
            // an IMU without samples still gets its file (with the header)
            self.imu_out(j)?;
            let imu = data.imu(j);
            for (t, z) in imu.t.iter().zip(imu.z) {
                self.imu_of(j, *t, z)?;
            }
        }
        Ok(())
    }

    /// Write `truth.toml`.
    pub fn truth(&mut self, truth: &Truth) -> Result<(), SessionError> {
        let path = self.dir.join(files::TRUTH);
        std::fs::write(&path, truth.to_toml()).map_err(|e| SessionError::io(&path, e))
    }

    /// Push every buffered row to the operating system.
    pub fn flush(&mut self) -> Result<(), SessionError> {
        self.joints.flush()?;
        self.imu.flush()?;
        for out in self.extra_imus.iter_mut().flatten() {
            out.flush()?;
        }
        if let Some(t) = &mut self.tracker {
            t.flush()?;
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
    use super::super::Session;
    use super::*;

    #[test]
    fn written_session_reads_back_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = SessionWriter::create(dir.path(), &SessionMeta::new("aubo_i5"), 2).unwrap();
        let ts = [0.0, 1.0 / 3.0, 0.7];
        for &t in &ts {
            w.joint(t, &[t.sin(), -1e-300 * t]).unwrap();
            w.imu(
                t + 0.01,
                &[1.0 / 7.0, 2.0, 3.0, 4.0, 5.0, std::f64::consts::PI],
            )
            .unwrap();
        }
        w.tracker(0.5, &[0.1, 0.2, 0.3, 1.0, 0.0, 0.0, 0.0])
            .unwrap();
        w.truth(&Truth {
            values: vec![("tau".into(), 0.1)],
        })
        .unwrap();
        w.finish().unwrap();
        let s = Session::load(dir.path()).unwrap();
        assert_eq!(s.joints.t, ts);
        assert_eq!(s.joints.row(1), [ts[1].sin(), -1e-300 * ts[1]]);
        assert_eq!(s.imu.row(2)[5], std::f64::consts::PI);
        assert_eq!(s.imu.row(0)[0], 1.0 / 7.0);
        assert_eq!(s.tracker.unwrap().len(), 1);
        assert_eq!(s.truth.unwrap().get("tau"), Some(0.1));
        assert_eq!(s.imu_temp, None, "no temperature column, none read");
    }

    /// A multi-IMU session (docs/model.md §9): `imu<j>.csv` written through
    /// [`SessionWriter::imu_of`] and [`SessionWriter::measurements`], and a
    /// truth with quoted `imu<j>/` names, read back exactly.
    #[test]
    fn several_imus_and_their_truth_read_back() {
        use robimu_model::observations::ImuSamples;
        let dir = tempfile::tempdir().unwrap();
        let mut w = SessionWriter::create(dir.path(), &SessionMeta::new("aubo_i5"), 1).unwrap();
        let data = Measurements {
            joint_t: vec![0.0, 1.0],
            joint_q: vec![0.5, 0.25],
            imu_t: vec![0.5],
            imu_z: vec![[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]],
            imu_temp: None,
            extra_imus: vec![
                ImuSamples {
                    t: vec![0.25, 0.75],
                    z: vec![[0.1; 6], [1.0 / 3.0; 6]],
                    temp: None,
                },
                ImuSamples {
                    t: vec![0.5],
                    z: vec![[2.0; 6]],
                    temp: None,
                },
            ],
        };
        w.measurements(&data).unwrap();
        w.imu_of(3, 0.5, &[7.0; 6]).unwrap();
        w.truth(&Truth {
            values: vec![("tau".into(), 0.1), ("imu1/k_a_x".into(), 1.02)],
        })
        .unwrap();
        w.finish().unwrap();
        let s = Session::load(dir.path()).unwrap();
        assert_eq!(s.n_imus(), 4);
        let m = s.measurements();
        assert_eq!(m.extra_imus[0], data.extra_imus[0]);
        assert_eq!(m.imu(2).z, &[[2.0; 6]]);
        assert_eq!(m.imu(3).z, &[[7.0; 6]]);
        let truth = s.truth.unwrap();
        assert_eq!(truth.get("imu1/k_a_x"), Some(1.02));
        assert_eq!(truth.get("tau"), Some(0.1));
    }

    /// The temperature column (as the recorder writes it, after other extra
    /// columns) reads back exactly into the session and its measurements.
    #[test]
    fn temperature_column_round_trips() {
        use super::super::IMU_TEMP_COLUMN;
        let dir = tempfile::tempdir().unwrap();
        let mut w = SessionWriter::create_with_imu_extra(
            dir.path(),
            &SessionMeta::new("aubo_i5"),
            1,
            &["seq", IMU_TEMP_COLUMN],
        )
        .unwrap();
        let temps = [24.0, 24.5, -3.25, 1.0 / 3.0];
        for (k, &c) in temps.iter().enumerate() {
            let t = 0.01 * k as f64;
            w.joint(t, &[0.1]).unwrap();
            w.imu_extra(t, &[0.0, 0.0, 9.81, 0.0, 0.0, 0.1], &[k as f64, c])
                .unwrap();
        }
        w.finish().unwrap();
        let s = Session::load(dir.path()).unwrap();
        assert_eq!(s.imu_temp.as_deref(), Some(&temps[..]));
        let m = s.measurements();
        assert_eq!(m.imu_temp.as_deref(), Some(&temps[..]));
        assert_eq!(m.imu_z[3][5], 0.1, "the required columns are unchanged");
    }
}
