//! EuRoC/Kalibr IMU CSV files and a joints CSV on the same clock.
//!
//! ```text
//! IMU:    #timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],
//!                         a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]
//!         (Kalibr: timestamp,omega_x,omega_y,omega_z,alpha_x,alpha_y,alpha_z)
//! joints: #timestamp [ns],NAME1,…,NAMEn      (positions, rad)
//! ```
//!
//! The header is optional; a leading `#` is allowed. Which three columns
//! are the gyroscope is read from the names (`w_…`, `omega…`, `gyr…`,
//! `angular…` against `a_…`, `alpha…`, `acc…`, `linear…`); without a
//! header the EuRoC order (gyroscope first) is assumed. The session's
//! `imu.csv` is accelerometer first. A time column marked `[s]`, `[ms]` or
//! `[us]` is in that unit, otherwise in nanoseconds (EuRoC, Kalibr);
//! columns marked `[deg …]` are converted to radians. Later lines starting
//! with `#` are comments.

use std::path::Path;

use super::{imu_row, ImportError, JointRows, Streams, MAX_SPAN_NS};

/// A CSV file as its header (if any) and numbered rows of fields.
pub(crate) struct Raw {
    /// The first line when it is not numbers (a leading `#` taken off).
    pub header: Option<Vec<String>>,
    /// (line, fields) of every other line but comments and blank lines.
    pub rows: Vec<(u64, Vec<String>)>,
}

/// `path` as a header and rows (module doc: a leading `#` allowed, later
/// `#` lines comments); an error when no row holds data.
pub(crate) fn read_raw(path: &Path) -> Result<Raw, ImportError> {
    let file = std::fs::File::open(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut rdr = ::csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(::csv::Trim::All)
        .from_reader(file);
    let mut raw = Raw {
        header: None,
        rows: Vec::new(),
    };
    for record in rdr.records() {
        let record = record.map_err(|e| ImportError::Line {
            path: path.to_path_buf(),
            line: e.position().map_or(0, |p| p.line()),
            detail: e.to_string(),
        })?;
        let line = record.position().map_or(0, |p| p.line());
        let fields: Vec<String> = record.iter().map(str::to_string).collect();
        if fields.iter().all(String::is_empty) {
            continue;
        }
        let first = fields[0].as_str();
        let is_header = raw.header.is_none()
            && raw.rows.is_empty()
            && (first.starts_with('#') || first.parse::<f64>().is_err());
        if is_header {
            let mut names = fields;
            names[0] = names[0].trim_start_matches('#').trim().to_string();
            raw.header = Some(names);
        } else if !first.starts_with('#') {
            raw.rows.push((line, fields));
        }
    }
    if raw.rows.is_empty() {
        return Err(ImportError::Empty {
            what: path.display().to_string(),
        });
    }
    Ok(raw)
}

/// Nanoseconds per unit of the time column named `name`.
fn time_scale(name: Option<&str>) -> i64 {
    let name = name.unwrap_or("").to_ascii_lowercase();
    if name.contains("[s]") {
        1_000_000_000
    } else if name.contains("[ms]") {
        1_000_000
    } else if name.contains("[us]") || name.contains("[µs]") {
        1_000
    } else {
        1
    }
}

/// Radians per unit of a column named `name`.
fn angle_scale(name: &str) -> f64 {
    if name.to_ascii_lowercase().contains("[deg") {
        std::f64::consts::PI / 180.0
    } else {
        1.0
    }
}

fn parse_time(path: &Path, line: u64, text: &str, scale: i64) -> Result<i64, ImportError> {
    let bad = |detail: String| ImportError::Line {
        path: path.to_path_buf(),
        line,
        detail,
    };
    if let Ok(n) = text.parse::<i64>() {
        return n
            .checked_mul(scale)
            .ok_or_else(|| bad(format!("timestamp {text} is out of range")));
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && (x * scale as f64).abs() < 9.2e18 => {
            Ok((x * scale as f64).round() as i64)
        }
        _ => Err(bad(format!("timestamp {text:?} is not a number"))),
    }
}

/// The first timestamp of a file (its line and ns), against which every
/// later one is checked: a file spanning more than [`MAX_SPAN_NS`] has a
/// corrupted timestamp (a sign lost, a unit wrong, a zeroed field).
pub(crate) struct Span(pub(crate) Option<(u64, i64)>);

impl Span {
    pub(crate) fn check(&mut self, path: &Path, line: u64, t: i64) -> Result<(), ImportError> {
        let (first_line, first) = *self.0.get_or_insert((line, t));
        if (i128::from(t) - i128::from(first)).abs() > i128::from(MAX_SPAN_NS) {
            return Err(ImportError::Line {
                path: path.to_path_buf(),
                line,
                detail: format!(
                    "timestamp {t} ns is {:.3e} s from the first one ({first} ns, line {first_line}): \
                     more than the {} h a recording may span (a corrupted timestamp)",
                    (i128::from(t) - i128::from(first)) as f64 * 1e-9,
                    MAX_SPAN_NS / 3_600_000_000_000
                ),
            });
        }
        Ok(())
    }
}

fn parse_values(
    path: &Path,
    line: u64,
    fields: &[String],
    width: usize,
) -> Result<Vec<f64>, ImportError> {
    if fields.len() < width + 1 {
        return Err(ImportError::Line {
            path: path.to_path_buf(),
            line,
            detail: format!(
                "{} fields, expected a timestamp and {width} values",
                fields.len()
            ),
        });
    }
    fields[1..=width]
        .iter()
        .map(|f| match f.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(ImportError::Line {
                path: path.to_path_buf(),
                line,
                detail: format!("{f:?} is not a finite number"),
            }),
        })
        .collect()
}

/// Which sensor a column holds.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Sensor {
    Gyro,
    Acc,
}

fn sensor_of(name: &str) -> Option<Sensor> {
    let n = name.to_ascii_lowercase();
    if n.starts_with("w_")
        || n.starts_with("omega")
        || n.contains("gyr")
        || n.starts_with("angular")
    {
        Some(Sensor::Gyro)
    } else if n.starts_with("a_")
        || n.starts_with("alpha")
        || n.contains("acc")
        || n.starts_with("linear")
    {
        Some(Sensor::Acc)
    } else {
        None
    }
}

/// Reads an EuRoC/Kalibr IMU CSV into IMU samples (ns, session order).
pub(crate) fn read_imu_csv(path: &Path) -> Result<Vec<(i64, [f64; 6])>, ImportError> {
    let raw = read_raw(path)?;
    let (gyro_first, scales, tscale) = match &raw.header {
        None => (true, [1.0; 6], 1),
        Some(h) => {
            let kinds: Vec<Option<Sensor>> =
                h.iter().skip(1).take(6).map(|n| sensor_of(n)).collect();
            use Sensor::{Acc, Gyro};
            let gyro_first = match kinds.as_slice() {
                [Some(Gyro), Some(Gyro), Some(Gyro), Some(Acc), Some(Acc), Some(Acc)] => true,
                [Some(Acc), Some(Acc), Some(Acc), Some(Gyro), Some(Gyro), Some(Gyro)] => false,
                _ => {
                    return Err(ImportError::Line {
                        path: path.to_path_buf(),
                        line: 1,
                        detail: format!(
                            "cannot tell gyroscope from accelerometer columns in the header {:?} \
                             (expected EuRoC w_RS_S_x…, a_RS_S_x… or Kalibr omega_x…, alpha_x…)",
                            h.join(",")
                        ),
                    })
                }
            };
            let mut scales = [1.0; 6];
            for (k, s) in scales.iter_mut().enumerate() {
                if kinds[k] == Some(Gyro) {
                    *s = angle_scale(&h[k + 1]);
                }
            }
            (
                gyro_first,
                scales,
                time_scale(h.first().map(String::as_str)),
            )
        }
    };
    let mut out = Vec::with_capacity(raw.rows.len());
    let mut span = Span(None);
    for (line, fields) in &raw.rows {
        let t = parse_time(path, *line, &fields[0], tscale)?;
        let v = parse_values(path, *line, fields, 6)?;
        span.check(path, *line, t)?;
        let v: Vec<f64> = v.iter().zip(scales).map(|(x, s)| x * s).collect();
        let (gyro, acc) = if gyro_first {
            ([v[0], v[1], v[2]], [v[3], v[4], v[5]])
        } else {
            ([v[3], v[4], v[5]], [v[0], v[1], v[2]])
        };
        out.push((t, imu_row(gyro, acc)));
    }
    Ok(out)
}

/// Reads a joints CSV (`timestamp,q1,…,qn`; ns and rad unless the header
/// says otherwise); returns the samples and the joint names of the header.
pub(crate) fn read_joints_csv(path: &Path) -> Result<(JointRows, Vec<String>), ImportError> {
    let raw = read_raw(path)?;
    let width = match &raw.header {
        Some(h) => h.len() - 1,
        None => raw.rows[0].1.len() - 1,
    };
    if width == 0 {
        return Err(ImportError::Line {
            path: path.to_path_buf(),
            line: raw.rows[0].0,
            detail: "no joint columns after the timestamp".into(),
        });
    }
    let names: Vec<String> = match &raw.header {
        Some(h) => h[1..].to_vec(),
        None => (1..=width).map(|i| format!("q{i}")).collect(),
    };
    let scales: Vec<f64> = names.iter().map(|n| angle_scale(n)).collect();
    let tscale = time_scale(raw.header.as_ref().map(|h| h[0].as_str()));
    let mut out = Vec::with_capacity(raw.rows.len());
    let mut span = Span(None);
    for (line, fields) in &raw.rows {
        let t = parse_time(path, *line, &fields[0], tscale)?;
        let q = parse_values(path, *line, fields, width)?;
        span.check(path, *line, t)?;
        out.push((t, q.iter().zip(&scales).map(|(x, s)| x * s).collect()));
    }
    Ok((out, names))
}

/// Reads both files into [`Streams`].
pub fn read_csv_pair(imu: &Path, joints: &Path) -> Result<Streams, ImportError> {
    let imu_path = imu;
    let imu = read_imu_csv(imu)?;
    let (joints, joint_names) = read_joints_csv(joints)?;
    one_clock(imu_path, &imu, joints.first().map(|j| j.0), "joints")?;
    Ok(Streams {
        joints,
        imu,
        joint_names,
        ..Streams::default()
    })
}

/// Each file spans at most a day (`Span`); the IMU file and the `other`
/// file (first time `first`, ns) must start within a day of each other.
pub(crate) fn one_clock(
    imu_path: &Path,
    imu: &[(i64, [f64; 6])],
    first: Option<i64>,
    other: &str,
) -> Result<(), ImportError> {
    if let (Some(&(a, _)), Some(b)) = (imu.first(), first) {
        if (i128::from(b) - i128::from(a)).abs() > i128::from(MAX_SPAN_NS) {
            return Err(ImportError::Joints {
                path: imu_path.to_path_buf(),
                detail: format!(
                    "the IMU file starts at {a} ns and the {other} file at {b} ns, more than {} h \
                     apart: they are not on one clock",
                    MAX_SPAN_NS / 3_600_000_000_000
                ),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn euroc_kalibr_and_headerless_files_agree() {
        let d = tempfile::tempdir().unwrap();
        let euroc = file(
            d.path(),
            "euroc.csv",
            "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],\
             a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n\
             1403636579758555392,-0.099134701513277898,0.14032447466056357,0.0,8.1476917083333333,-0.37592158333333331,-2.4026292499999999\n",
        );
        let kalibr = file(
            d.path(),
            "kalibr.csv",
            "timestamp,alpha_x,alpha_y,alpha_z,omega_x,omega_y,omega_z\n\
             1403636579758555392,8.1476917083333333,-0.37592158333333331,-2.4026292499999999,-0.099134701513277898,0.14032447466056357,0.0\n",
        );
        let bare = file(
            d.path(),
            "bare.csv",
            "1403636579758555392,-0.099134701513277898,0.14032447466056357,0,8.1476917083333333,-0.37592158333333331,-2.4026292499999999\n# a comment\n",
        );
        let expected = [
            8.147_691_708_333_333,
            -0.375_921_583_333_333_3,
            -2.402_629_25,
            -0.099_134_701_513_277_9,
            0.14032447466056357,
            0.0,
        ];
        let e = read_imu_csv(&euroc).unwrap();
        assert_eq!(e, vec![(1_403_636_579_758_555_392, expected)]);
        assert_eq!(read_imu_csv(&bare).unwrap(), e);
        // Kalibr: accelerometer first here, timestamps in ns.
        assert_eq!(read_imu_csv(&kalibr).unwrap(), e);
        // Seconds when the header says so; degrees converted.
        let secs = file(
            d.path(),
            "secs.csv",
            "t [s],gyr_x [deg/s],gyr_y [deg/s],gyr_z [deg/s],acc_x,acc_y,acc_z\n2.5,180,0,-90,1,2,3\n",
        );
        let s = read_imu_csv(&secs).unwrap();
        assert_eq!(s[0].0, 2_500_000_000);
        let pi = std::f64::consts::PI;
        assert_eq!(s[0].1, [1.0, 2.0, 3.0, pi, 0.0, -pi / 2.0]);
    }

    #[test]
    fn joints_file_and_errors() {
        let d = tempfile::tempdir().unwrap();
        let j = file(
            d.path(),
            "j.csv",
            "#timestamp [ns],shoulder,elbow\n10,0.5,-0.5\n20,0.6,-0.4\n",
        );
        let (rows, names) = read_joints_csv(&j).unwrap();
        assert_eq!(names, vec!["shoulder", "elbow"]);
        assert_eq!(rows, vec![(10, vec![0.5, -0.5]), (20, vec![0.6, -0.4])]);
        let bad = file(
            d.path(),
            "bad.csv",
            "#timestamp [ns],a,b\n10,0.5,-0.5\n20,0.6\n",
        );
        let e = read_joints_csv(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.csv:3:") && e.contains("2 fields"), "{e}");
        let nan = file(d.path(), "nan.csv", "10,0.5,-0.5\n20,0.6,nan\n");
        let e = read_joints_csv(&nan).unwrap_err().to_string();
        assert!(
            e.contains("nan.csv:2:") && e.contains("not a finite number"),
            "{e}"
        );
        let header = file(d.path(), "h.csv", "t,x,y,z,u,v,w\n1,0,0,0,0,0,0\n");
        let e = read_imu_csv(&header).unwrap_err().to_string();
        assert!(e.contains("h.csv:1:") && e.contains("gyroscope"), "{e}");
        let empty = file(d.path(), "e.csv", "#timestamp [ns],a\n");
        let e = read_joints_csv(&empty).unwrap_err().to_string();
        assert!(e.contains("no samples"), "{e}");
        let e = read_imu_csv(&d.path().join("missing.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.csv"), "{e}");
    }

    /// Issue 41, found by the fuzz harness (host/cli/tests/fuzz_readers.rs):
    /// a joints timestamp of -2⁶³ among epoch times overflowed `t - t0`
    /// (a panic in debug builds, a wrapped session in release); a zeroed
    /// one made a session spanning 44 years. Each is refused at its line,
    /// as is a pair of files a day apart.
    #[test]
    fn timestamps_beyond_a_day_of_the_first_are_refused_at_their_line() {
        let d = tempfile::tempdir().unwrap();
        let imu = file(
            d.path(),
            "imu.csv",
            "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z
             1403636579758555392,0,0,0,0,0,9.8
1403636579768555392,0,0,0,0,0,9.8
",
        );
        for (name, t) in [("min.csv", "-9223372036854775808"), ("zero.csv", "-0")] {
            let j = file(
                d.path(),
                name,
                &format!(
                    "#timestamp [ns],q1
1403636579758555392,0.1
{t},0.2
"
                ),
            );
            let e = read_csv_pair(&imu, &j).unwrap_err().to_string();
            assert!(
                e.contains(&format!("{name}:3: timestamp "))
                    && e.contains("from the first one (1403636579758555392 ns, line 2)")
                    && e.contains("more than the 24 h a recording may span"),
                "{e}"
            );
        }
        let far = file(
            d.path(),
            "far.csv",
            "#timestamp [ns],q1
1000,0.1
2000,0.2
",
        );
        let e = read_csv_pair(&imu, &far).unwrap_err().to_string();
        assert!(
            e.contains("the IMU file starts at 1403636579758555392 ns and the joints file at 1000 ns, more than 24 h apart"),
            "{e}"
        );
    }
}
