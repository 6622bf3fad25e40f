//! Static poses measured by a tracker (`robimu validate --tracker`): a
//! tracker table (`t` and [`TRACKER_COLUMNS`]) whose rows may also carry the
//! joint angles in extra columns `q1..qn`.

use std::path::{Path, PathBuf};

use crate::{read_table, Columns, SessionError, Table, TRACKER_COLUMNS};

/// Why a pose file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum PoseFileError {
    /// The tracker columns are not readable.
    #[error(transparent)]
    Table(#[from] SessionError),
    /// The file could not be opened for its joint columns.
    #[error("cannot read {}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: csv::Error,
    },
    /// The header could not be read.
    #[error(transparent)]
    Header(csv::Error),
    /// A row could not be read.
    #[error("{}: row {row}", path.display())]
    Row {
        /// The file.
        path: PathBuf,
        /// 1-based data row.
        row: usize,
        /// Why.
        #[source]
        source: csv::Error,
    },
    /// The file could not be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A joint angle is not a number.
    #[error("{}: row {row}: q{joint} = `{field}` is not a number", path.display())]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based data row.
        row: usize,
        /// 1-based joint.
        joint: usize,
        /// The field.
        field: String,
    },
}

/// The contents of a pose file.
#[derive(Debug, Clone)]
pub struct PoseFile {
    /// The tracker columns.
    pub table: Table,
    /// The joint angles, `n` a row, when every column `q1..qn` is present.
    pub joints: Option<Vec<f64>>,
}

/// One static pose of a pose file: its time, the tracker's pose
/// `[px, py, pz, qw, qx, qy, qz]` and the joint angles.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRow {
    /// Time, s.
    pub t: f64,
    /// The tracker's pose (m, unit quaternion).
    pub pose: [f64; 7],
    /// The joint angles, rad.
    pub q: Vec<f64>,
}

/// Writes a pose file of `n`-joint poses (`t`, [`TRACKER_COLUMNS`],
/// `q1..qn`) headed by the comment `# {comment}`.
pub fn write_pose_file(
    path: &Path,
    comment: &str,
    n: usize,
    rows: &[PoseRow],
) -> Result<(), PoseFileError> {
    let qs: Vec<String> = (1..=n).map(|j| format!("q{j}")).collect();
    let mut text = format!(
        "# {comment}\nt,{},{}\n",
        TRACKER_COLUMNS.join(","),
        qs.join(",")
    );
    for p in rows {
        let row: Vec<String> = p
            .pose
            .iter()
            .chain(&p.q)
            .map(|v| format!("{v:?}"))
            .collect();
        text.push_str(&format!("{:?},{}\n", p.t, row.join(",")));
    }
    std::fs::write(path, text).map_err(|source| PoseFileError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes a tracker table (`t` and [`TRACKER_COLUMNS`]): the pose
/// `[px, py, pz, qw, qx, qy, qz]` at each time.
pub fn write_tracker_file(path: &Path, rows: &[(f64, [f64; 7])]) -> Result<(), PoseFileError> {
    let mut text = format!("t,{}\n", TRACKER_COLUMNS.join(","));
    for (t, pose) in rows {
        let row: Vec<String> = pose.iter().map(|v| format!("{v:?}")).collect();
        text.push_str(&format!("{t:?},{}\n", row.join(",")));
    }
    std::fs::write(path, text).map_err(|source| PoseFileError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads the pose file `path` of an `n`-joint robot.
pub fn read_pose_file(path: &Path, n: usize) -> Result<PoseFile, PoseFileError> {
    let table = read_table(path, Columns::Fixed(&TRACKER_COLUMNS))?;
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_path(path)
        .map_err(|source| PoseFileError::Open {
            path: path.to_path_buf(),
            source,
        })?;
    let header = rdr.headers().map_err(PoseFileError::Header)?.clone();
    let cols: Option<Vec<usize>> = (1..=n)
        .map(|j| header.iter().position(|h| h == format!("q{j}")))
        .collect();
    let Some(cols) = cols else {
        return Ok(PoseFile {
            table,
            joints: None,
        });
    };
    let mut values = Vec::with_capacity(table.len() * n);
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|source| PoseFileError::Row {
            path: path.to_path_buf(),
            row: row + 1,
            source,
        })?;
        for (j, &c) in cols.iter().enumerate() {
            let field = rec.get(c).unwrap_or("");
            let v = field
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| PoseFileError::NotANumber {
                    path: path.to_path_buf(),
                    row: row + 1,
                    joint: j + 1,
                    field: field.to_string(),
                })?;
            values.push(v);
        }
    }
    Ok(PoseFile {
        table,
        joints: Some(values),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_files_round_trip_and_bad_joints_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.csv");
        let rows = [
            PoseRow {
                t: 0.5,
                pose: [0.1, 0.2, 0.3, 1.0, 0.0, 0.0, 0.0],
                q: vec![0.25, -1.0 / 3.0],
            },
            PoseRow {
                t: 1.5,
                pose: [0.4, 0.5, 0.6, 0.0, 1.0, 0.0, 0.0],
                q: vec![1e-7, 2.0],
            },
        ];
        write_pose_file(&path, "static poses", 2, &rows).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("# static poses\nt,px,py,pz,qw,qx,qy,qz,q1,q2\n"));
        let file = read_pose_file(&path, 2).unwrap();
        assert_eq!(file.table.t, [0.5, 1.5]);
        assert_eq!(file.table.row(1), rows[1].pose);
        assert_eq!(file.joints.unwrap(), [0.25, -1.0 / 3.0, 1e-7, 2.0]);
        // without q3 the joints come from elsewhere
        assert!(read_pose_file(&path, 3).unwrap().joints.is_none());

        let motion = dir.path().join("tracker.csv");
        write_tracker_file(&motion, &[(0.0, rows[0].pose), (0.25, rows[1].pose)]).unwrap();
        assert!(read_pose_file(&motion, 1).unwrap().joints.is_none());

        std::fs::write(&path, "t,px,py,pz,qw,qx,qy,qz,q1\n0,0,0,0,1,0,0,0,x\n").unwrap();
        let err = read_pose_file(&path, 1).unwrap_err();
        assert!(
            matches!(&err, PoseFileError::NotANumber { row: 1, joint: 1, field, .. } if field == "x"),
            "{err}"
        );
        assert!(err
            .to_string()
            .ends_with("poses.csv: row 1: q1 = `x` is not a number"));
    }
}
