//! A pose stream from a CSV file with the user's columns and units (issue 39
//! item 4): a robot controller's TCP stream or a motion-capture export,
//! converted to what pose sessions store (docs MODEL.md §10): time in ns,
//! position in m, unit quaternion (w, x, y, z) of the body in the world.
//!
//! What the file may hold, chosen by [`PoseCsvOptions`]:
//!
//! * time in s, ms, µs or ns;
//! * position in m or mm;
//! * orientation as a quaternion in either order (`wxyz`, as ABB and
//!   MODEL.md write it, or `xyzw`, as ROS and Eigen's storage do), as Euler
//!   angles roll, pitch, yaw with R = Rz(yaw)·Ry(pitch)·Rx(roll) (URDF's
//!   `rpy`; KUKA's A, B, C are yaw, pitch, roll), in degrees or radians, or
//!   as a rotation vector (axis × angle, rad: Universal Robots' TCP pose
//!   `rx, ry, rz`);
//! * the inverse convention (the world in the body: a camera's view of a
//!   fixed target), inverted on reading;
//! * the inverse rotation alone (the orientation R_BW with the position of
//!   B in W, or JPL quaternions): transposed on reading.
//!
//! Columns are named as in the header (case-insensitive) or given by their
//! 0-based index. Every value must be finite; a quaternion must not be zero
//! (it is normalised: a non-unit one is `check`'s to report, from the raw
//! file).

use std::path::Path;

use robimu_model::geom::{
    exp_so3, matrix_from_quat, mul_mm, mul_mv, quat_from_matrix, rot_x, rot_y, rot_z, transpose,
};

use super::csv::{one_clock, read_imu_csv, read_raw, Span};
use super::{ImportError, Streams};

/// How the orientation is written.
#[derive(Debug, Clone, PartialEq)]
pub enum Orientation {
    /// A quaternion in four columns, in `order`.
    Quaternion {
        /// The columns, in the file's order.
        columns: [String; 4],
        /// Which component each column holds.
        order: QuaternionOrder,
    },
    /// Roll, pitch, yaw: R = Rz(yaw)·Ry(pitch)·Rx(roll).
    Euler {
        /// Roll, pitch, yaw columns.
        columns: [String; 3],
        /// Degrees (else radians).
        degrees: bool,
    },
    /// A rotation vector (axis × angle, rad).
    RotationVector {
        /// Its x, y, z columns.
        columns: [String; 3],
    },
}

/// The component order of a quaternion's four columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QuaternionOrder {
    /// w, x, y, z (MODEL.md §10).
    Wxyz,
    /// x, y, z, w (ROS messages, Eigen's storage).
    Xyzw,
}

/// Columns and units of a pose CSV file (module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseCsvOptions {
    /// The time column.
    pub time: String,
    /// Nanoseconds per unit of the time column (1e9: seconds).
    pub time_ns_per_unit: f64,
    /// The position's x, y, z columns.
    pub position: [String; 3],
    /// Metres per unit of the position (1e-3: millimetres).
    pub metres_per_unit: f64,
    /// The orientation.
    pub orientation: Orientation,
    /// The file gives the world in the body (inverted on reading).
    pub inverse: bool,
    /// The orientation is the inverse rotation (R_BW, or a JPL quaternion):
    /// transposed on reading, the position kept.
    pub conjugate: bool,
}

impl Default for PoseCsvOptions {
    /// MODEL.md §10's `poses.csv`: `t,px,py,pz,qw,qx,qy,qz`, s and m.
    fn default() -> Self {
        let s = |v: &str| v.to_string();
        Self {
            time: s("t"),
            time_ns_per_unit: 1e9,
            position: [s("px"), s("py"), s("pz")],
            metres_per_unit: 1.0,
            orientation: Orientation::Quaternion {
                columns: [s("qw"), s("qx"), s("qy"), s("qz")],
                order: QuaternionOrder::Wxyz,
            },
            inverse: false,
            conjugate: false,
        }
    }
}

/// Poses read from a file: time (ns), position (m), quaternion (w, x, y, z),
/// in the file's row order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseRows {
    /// Times, ns.
    pub t_ns: Vec<i64>,
    /// Positions, m.
    pub p: Vec<[f64; 3]>,
    /// Unit quaternions (w, x, y, z), w ≥ 0.
    pub q: Vec<[f64; 4]>,
}

/// Reads the poses of `path` as `opts` describe them (module doc).
pub fn read_pose_csv(path: &Path, opts: &PoseCsvOptions) -> Result<PoseRows, ImportError> {
    let raw = read_raw(path)?;
    let columns = Columns::resolve(path, opts, raw.header.as_deref())?;
    let mut out = PoseRows::default();
    let mut span = Span(None);
    for (line, fields) in &raw.rows {
        let fields: Vec<&str> = fields.iter().map(String::as_str).collect();
        let (t, p, q) = columns.row(path, *line, &fields, opts)?;
        span.check(path, *line, t)?;
        out.t_ns.push(t);
        out.p.push(p);
        out.q.push(q);
    }
    Ok(out)
}

/// Reads the poses of `poses` (as `opts` describe them) and the IMU
/// samples of `imu` (an EuRoC/Kalibr IMU CSV, [`super::csv`]), on one clock,
/// into [`Streams`] for [`Streams::write_pose_session`].
pub fn read_pose_csv_pair(
    poses: &Path,
    opts: &PoseCsvOptions,
    imu: &Path,
) -> Result<Streams, ImportError> {
    let imu_samples = read_imu_csv(imu)?;
    let rows = read_pose_csv(poses, opts)?;
    one_clock(imu, &imu_samples, rows.t_ns.first().copied(), "poses")?;
    Ok(Streams {
        imu: imu_samples,
        poses: rows,
        ..Streams::default()
    })
}

/// The 0-based indices of the columns `opts` names.
struct Columns {
    time: usize,
    position: [usize; 3],
    orientation: Vec<usize>,
}

impl Columns {
    fn resolve(
        path: &Path,
        opts: &PoseCsvOptions,
        header: Option<&[String]>,
    ) -> Result<Self, ImportError> {
        let find = |name: &str| -> Result<usize, ImportError> {
            if let Some(i) =
                header.and_then(|h| h.iter().position(|c| c.eq_ignore_ascii_case(name)))
            {
                return Ok(i);
            }
            name.parse::<usize>().map_err(|_| ImportError::Line {
                path: path.to_path_buf(),
                line: 1,
                detail: match header {
                    Some(h) => format!("no column {name:?} (the header has {})", h.join(", ")),
                    None => format!("no header, so column {name:?} must be a 0-based index"),
                },
            })
        };
        let names: Vec<&String> = match &opts.orientation {
            Orientation::Quaternion { columns, .. } => columns.iter().collect(),
            Orientation::Euler { columns, .. } | Orientation::RotationVector { columns } => {
                columns.iter().collect()
            }
        };
        Ok(Self {
            time: find(&opts.time)?,
            position: [
                find(&opts.position[0])?,
                find(&opts.position[1])?,
                find(&opts.position[2])?,
            ],
            orientation: names
                .into_iter()
                .map(|n| find(n))
                .collect::<Result<_, _>>()?,
        })
    }

    /// One row's time (ns), position (m) and quaternion (w first, w ≥ 0).
    fn row(
        &self,
        path: &Path,
        line: u64,
        fields: &[&str],
        opts: &PoseCsvOptions,
    ) -> Result<(i64, [f64; 3], [f64; 4]), ImportError> {
        let bad = |detail: String| ImportError::Line {
            path: path.to_path_buf(),
            line,
            detail,
        };
        let value = |i: usize| -> Result<f64, ImportError> {
            let f = fields
                .get(i)
                .ok_or_else(|| bad(format!("{} fields, column {} missing", fields.len(), i + 1)))?;
            match f.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(x),
                _ => Err(bad(format!(
                    "column {}: {f:?} is not a finite number",
                    i + 1
                ))),
            }
        };
        let t = value(self.time)? * opts.time_ns_per_unit;
        if t.abs() >= 9.2e18 {
            return Err(bad(format!("time {t:e} ns is out of range")));
        }
        // decimal times in an integer unit of ns (epoch s or ns) keep
        // every digit to the ns
        let scale = opts.time_ns_per_unit;
        let exact = fields
            .get(self.time)
            .filter(|_| scale >= 1.0 && scale.fract() == 0.0 && scale <= 1e9)
            .and_then(|f| decimal_ns(f, scale as i64));
        let mut p = [0.0; 3];
        for (k, &i) in self.position.iter().enumerate() {
            p[k] = value(i)? * opts.metres_per_unit;
        }
        let o: Vec<f64> = self
            .orientation
            .iter()
            .map(|&i| value(i))
            .collect::<Result<_, _>>()?;
        let r = match &opts.orientation {
            Orientation::Quaternion { order, .. } => {
                let q = match order {
                    QuaternionOrder::Wxyz => [o[0], o[1], o[2], o[3]],
                    QuaternionOrder::Xyzw => [o[3], o[0], o[1], o[2]],
                };
                if q.iter().map(|v| v * v).sum::<f64>() < 1e-12 {
                    return Err(bad("the quaternion is zero: no rotation".into()));
                }
                matrix_from_quat(q)
            }
            Orientation::Euler { degrees, .. } => {
                let k = if *degrees {
                    std::f64::consts::PI / 180.0
                } else {
                    1.0
                };
                let (roll, pitch, yaw) = (o[0] * k, o[1] * k, o[2] * k);
                mul_mm(&rot_z(yaw), &mul_mm(&rot_y(pitch), &rot_x(roll)))
            }
            Orientation::RotationVector { .. } => exp_so3([o[0], o[1], o[2]]),
        };
        let r = if opts.conjugate { transpose(&r) } else { r };
        let (r, p) = if opts.inverse {
            let rt = transpose(&r);
            let q = mul_mv(&rt, p);
            (rt, [-q[0], -q[1], -q[2]])
        } else {
            (r, p)
        };
        Ok((exact.unwrap_or(t.round() as i64), p, quat_from_matrix(&r)))
    }
}

/// `text`, a plain decimal (`-12.345`, no exponent), times `scale` ns,
/// rounded to the ns in integer arithmetic; `None` for anything else or out
/// of range.
fn decimal_ns(text: &str, scale: i64) -> Option<i64> {
    let (negative, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let (int, frac) = digits.split_once('.').unwrap_or((digits, ""));
    let all_digits = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    if int.is_empty() && frac.is_empty() || !all_digits(int) || !all_digits(frac) {
        return None;
    }
    let frac = &frac[..frac.len().min(18)];
    let whole: i128 = if int.is_empty() { 0 } else { int.parse().ok()? };
    let num: i128 = if frac.is_empty() {
        0
    } else {
        frac.parse().ok()?
    };
    let den = 10i128.pow(frac.len() as u32);
    let scale = i128::from(scale);
    let ns = whole.checked_mul(scale)? + (num * scale + den / 2) / den;
    i64::try_from(if negative { -ns } else { ns }).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, UnitQuaternion, Vector3};

    fn write(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.csv");
        std::fs::write(&path, text).unwrap();
        (dir, path)
    }

    /// |q − q'| up to sign.
    fn quat_distance(a: [f64; 4], b: [f64; 4]) -> f64 {
        let d = |s: f64| {
            (0..4)
                .map(|i| (a[i] - s * b[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        d(1.0).min(d(-1.0))
    }

    fn nalgebra_wxyz(q: UnitQuaternion<f64>) -> [f64; 4] {
        [q.w, q.i, q.j, q.k]
    }

    /// The default is MODEL.md §10's file; a ROS-ordered (x, y, z, w)
    /// quaternion in mm and ms gives the same poses.
    #[test]
    fn model_md_files_and_ros_ordered_quaternions_in_mm_read_alike() {
        let q = UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1);
        let w = nalgebra_wxyz(q);
        let (_d, a) = write(&format!(
            "t,px,py,pz,qw,qx,qy,qz\n0.5,0.1,-0.2,0.3,{},{},{},{}\n",
            w[0], w[1], w[2], w[3]
        ));
        let rows = read_pose_csv(&a, &PoseCsvOptions::default()).unwrap();
        assert_eq!(rows.t_ns, vec![500_000_000]);
        assert_eq!(rows.p, vec![[0.1, -0.2, 0.3]]);
        assert!(quat_distance(rows.q[0], w) < 1e-15);
        let (_d, b) = write(&format!(
            "stamp_ms,x,y,z,ox,oy,oz,ow\n500,100,-200,300,{},{},{},{}\n",
            w[1], w[2], w[3], w[0]
        ));
        let opts = PoseCsvOptions {
            time: "stamp_ms".into(),
            time_ns_per_unit: 1e6,
            position: ["x".into(), "y".into(), "z".into()],
            metres_per_unit: 1e-3,
            orientation: Orientation::Quaternion {
                columns: ["ox".into(), "oy".into(), "oz".into(), "ow".into()],
                order: QuaternionOrder::Xyzw,
            },
            inverse: false,
            conjugate: false,
        };
        let rows_b = read_pose_csv(&b, &opts).unwrap();
        assert_eq!(rows_b.t_ns, rows.t_ns);
        for k in 0..3 {
            assert!((rows_b.p[0][k] - rows.p[0][k]).abs() < 1e-15);
        }
        assert!(quat_distance(rows_b.q[0], rows.q[0]) < 1e-15);
    }

    /// Epoch times in integer ns (or s) are read to the ns; fractional
    /// ones through f64.
    #[test]
    fn integer_epoch_times_keep_every_digit() {
        let (_d, a) = write("t,px,py,pz,qw,qx,qy,qz\n1700000000123456789,0,0,0,1,0,0,0\n");
        let ns = PoseCsvOptions {
            time_ns_per_unit: 1.0,
            ..PoseCsvOptions::default()
        };
        assert_eq!(
            read_pose_csv(&a, &ns).unwrap().t_ns,
            vec![1_700_000_000_123_456_789]
        );
        let (_d, b) =
            write("t,px,py,pz,qw,qx,qy,qz\n1700000000,0,0,0,1,0,0,0\n0.25,0,0,0,1,0,0,0\n");
        let s = read_pose_csv(&b, &PoseCsvOptions::default());
        // a second row a day before the first: refused at its line
        let e = s.unwrap_err().to_string();
        assert!(e.contains("poses.csv:3") && e.contains("24 h"), "{e}");
        let (_d, c) = write(
            "t,px,py,pz,qw,qx,qy,qz\n1700000000,0,0,0,1,0,0,0\n1700000000.25,0,0,0,1,0,0,0\n",
        );
        let rows = read_pose_csv(&c, &PoseCsvOptions::default()).unwrap();
        assert_eq!(
            rows.t_ns,
            vec![1_700_000_000_000_000_000, 1_700_000_000_250_000_000]
        );
    }

    /// Euler angles (degrees) and rotation vectors against nalgebra's own
    /// conversions (an independent implementation), and the inverse
    /// convention against nalgebra's inverse isometry.
    #[test]
    fn euler_angles_rotation_vectors_and_the_inverse_agree_with_nalgebra() {
        let (roll, pitch, yaw) = (25.0f64, -40.0f64, 130.0f64);
        let (_d, e) = write(&format!("0,1,2,3,{roll},{pitch},{yaw}\n"));
        let idx = |i: usize| i.to_string();
        let opts = PoseCsvOptions {
            time: idx(0),
            position: [idx(1), idx(2), idx(3)],
            orientation: Orientation::Euler {
                columns: [idx(4), idx(5), idx(6)],
                degrees: true,
            },
            ..PoseCsvOptions::default()
        };
        let got = read_pose_csv(&e, &opts).unwrap().q[0];
        let want = UnitQuaternion::from_euler_angles(
            roll.to_radians(),
            pitch.to_radians(),
            yaw.to_radians(),
        );
        assert!(quat_distance(got, nalgebra_wxyz(want)) < 1e-14);
        // UR's rotation vector
        let rv = Vector3::new(0.4, -1.9, 0.7);
        let (_d, v) = write(&format!(
            "t,x,y,z,rx,ry,rz\n1,0,0,0,{},{},{}\n",
            rv.x, rv.y, rv.z
        ));
        let opts = PoseCsvOptions {
            position: ["x".into(), "y".into(), "z".into()],
            orientation: Orientation::RotationVector {
                columns: ["rx".into(), "ry".into(), "rz".into()],
            },
            ..PoseCsvOptions::default()
        };
        let got = read_pose_csv(&v, &opts).unwrap().q[0];
        assert!(quat_distance(got, nalgebra_wxyz(UnitQuaternion::from_scaled_axis(rv))) < 1e-14);
        // the inverse: the file holds T_BW, the reader returns T_WB
        let r = Rotation3::from_scaled_axis(rv);
        let p = Vector3::new(0.3, -0.1, 0.8);
        let inv_r = r.inverse();
        let inv_p = -(inv_r * p);
        let iq = UnitQuaternion::from_rotation_matrix(&inv_r);
        let (_d, f) = write(&format!(
            "t,px,py,pz,qw,qx,qy,qz\n0,{},{},{},{},{},{},{}\n",
            inv_p.x, inv_p.y, inv_p.z, iq.w, iq.i, iq.j, iq.k
        ));
        let rows = read_pose_csv(
            &f,
            &PoseCsvOptions {
                inverse: true,
                ..PoseCsvOptions::default()
            },
        )
        .unwrap();
        for k in 0..3 {
            assert!((rows.p[0][k] - p[k]).abs() < 1e-14, "{:?}", rows.p[0]);
        }
        let want = UnitQuaternion::from_rotation_matrix(&r);
        assert!(quat_distance(rows.q[0], nalgebra_wxyz(want)) < 1e-14);
        // the inverse rotation alone (nalgebra's conjugate), position kept
        let c = want.conjugate();
        let (_d, g) = write(&format!(
            "t,px,py,pz,qw,qx,qy,qz\n0,{},{},{},{},{},{},{}\n",
            p.x, p.y, p.z, c.w, c.i, c.j, c.k
        ));
        let conj = PoseCsvOptions {
            conjugate: true,
            ..PoseCsvOptions::default()
        };
        let rows = read_pose_csv(&g, &conj).unwrap();
        assert_eq!(rows.p[0], [p.x, p.y, p.z]);
        assert!(quat_distance(rows.q[0], nalgebra_wxyz(want)) < 1e-14);
    }

    /// Bad input names the file, the line and the cause.
    #[test]
    fn bad_files_name_the_cause() {
        let cases = [
            (
                "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,0,0,0,0\n",
                "quaternion is zero",
            ),
            (
                "t,px,py,pz,qw,qx,qy,qz\n0,nan,0,0,1,0,0,0\n",
                "not a finite number",
            ),
            ("t,px,py,pz,qw,qx,qy,qz\n0,0,0\n", "column 4 missing"),
            ("t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n", "no column \"px\""),
            ("0,0,0,0,1,0,0,0\n", "must be a 0-based index"),
            ("t,px,py,pz,qw,qx,qy,qz\n", "poses.csv"),
            (
                "t,px,py,pz,qw,qx,qy,qz\n1e300,0,0,0,1,0,0,0\n",
                "out of range",
            ),
        ];
        for (text, want) in cases {
            let (_d, path) = write(text);
            let e = read_pose_csv(&path, &PoseCsvOptions::default())
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
