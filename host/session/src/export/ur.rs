//! Universal Robots' kinematics YAML: the file the UR ROS 2 description
//! (`Universal_Robots_ROS2_Description`, `urdf/ur_macro.xacro`) reads as its
//! `kinematics_parameters_file`, and that `ur_calibration` writes from a
//! controller's factory calibration:
//!
//! ```yaml
//! kinematics:
//!   shoulder:  {x: …, y: …, z: …, roll: …, pitch: …, yaw: …}
//!   upper_arm: {…}
//!   forearm:   {…}
//!   wrist_1:   {…}
//!   wrist_2:   {…}
//!   wrist_3:   {…}
//!   hash: calib_…
//! ```
//!
//! The description builds the chain from it as
//! `base → O_shoulder·Rz(q1) · O_upper_arm·Rz(q2) · … · O_wrist_3·Rz(q6) · F → tool0`,
//! each `O` a URDF `<origin>` (xyz, then rpy as fixed-axis X, Y, Z), `base`
//! coinciding with `base_link_inertia` (both `Rz(π)` from `base_link`) and
//! `F` the fixed `wrist_3_link → flange → tool0` rotations
//! (`rpy 0 −π/2 −π/2`, then `π/2 0 π/2`, together the identity).
//!
//! A robimu robot of this structure (6 joints, the last link's fixed part
//! `F`: every built-in UR robot) maps onto it exactly: `O_shoulder` is
//! `[frames] base_to_model`, `O_{i+1}` the fixed part after joint i,
//! `Rz(θ0)·Tz(d)·Tx(a)·Rx(α)·C_i`, with a calibration's `E_i` folded in
//! (`C_i·E_i`, as the corrected robot TOML does). [`UrKinematics::nominal_robot`]
//! reads a factory calibration as a robot's nominal model;
//! [`UrKinematics::of_robot`] writes a (calibrated) robot back. Numbers that
//! a calibration did not change are written as they were read.

use std::path::Path;

use robimu_model::geom::Iso;
use robimu_model::kinematics::error_transform;
use robimu_model::robot::Origin;
use robimu_model::LinkTransform;
use robimu_model::{ModelParams, Robot, RobotError};
use serde::Deserialize;

/// The links of the kinematics YAML, base to flange.
const UR_LINKS: [&str; 6] = [
    "shoulder",
    "upper_arm",
    "forearm",
    "wrist_1",
    "wrist_2",
    "wrist_3",
];

/// Why a kinematics YAML could not be read, or a robot not written as one.
#[derive(Debug, thiserror::Error)]
pub enum UrKinematicsError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The text is not a kinematics YAML.
    #[error("not a UR kinematics YAML (kinematics: shoulder, upper_arm, forearm, wrist_1, wrist_2, wrist_3 each with x, y, z, roll, pitch, yaw; hash): {0}")]
    Yaml(String),
    /// The robot does not have UR's structure.
    #[error("not a robot of the UR description's structure: {0}")]
    NotUr(String),
    /// The robot built from the file is not valid.
    #[error(transparent)]
    Robot(#[from] RobotError),
}

#[derive(Deserialize)]
struct File {
    kinematics: Kinematics,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Kinematics {
    shoulder: Link,
    upper_arm: Link,
    forearm: Link,
    wrist_1: Link,
    wrist_2: Link,
    wrist_3: Link,
    hash: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Link {
    x: f64,
    y: f64,
    z: f64,
    roll: f64,
    pitch: f64,
    yaw: f64,
}

impl Link {
    fn origin(&self) -> Origin {
        Origin {
            xyz: [self.x, self.y, self.z],
            rpy: [self.roll, self.pitch, self.yaw],
        }
    }
}

/// A UR kinematics YAML: the six link origins and the calibration's hash.
#[derive(Debug, Clone, PartialEq)]
pub struct UrKinematics {
    /// `shoulder` … `wrist_3` (in this order).
    pub links: [Origin; 6],
    /// `hash` (`calib_…`: the UR driver compares it with the controller's).
    pub hash: String,
}

/// `parse` of the text of the file at `path`, its format errors prefixed
/// with the path.
pub(crate) fn read_file<T>(
    path: &Path,
    parse: impl FnOnce(&str) -> Result<T, UrKinematicsError>,
) -> Result<T, UrKinematicsError> {
    let text =
        robimu_model::text::read_to_string(path).map_err(|source| UrKinematicsError::Io {
            path: path.display().to_string(),
            source,
        })?;
    parse(&text).map_err(|e| match e {
        UrKinematicsError::Yaml(m) => UrKinematicsError::Yaml(format!("{}: {m}", path.display())),
        e => e,
    })
}

/// `F`: the fixed rotation from `wrist_3_link` to `tool0` in the UR
/// description (`wrist_3 → flange`, rpy `0 −π/2 −π/2`; `flange → tool0`,
/// rpy `π/2 0 π/2`).
fn ur_tool0() -> Origin {
    use std::f64::consts::FRAC_PI_2;
    let flange = Origin {
        xyz: [0.0; 3],
        rpy: [0.0, -FRAC_PI_2, -FRAC_PI_2],
    };
    let tool0 = Origin {
        xyz: [0.0; 3],
        rpy: [FRAC_PI_2, 0.0, FRAC_PI_2],
    };
    Origin::from_iso(&flange.to_iso().compose(&tool0.to_iso()))
}

/// The fixed part of link i, `Rz(θ0)·Tz(d)·Tx(a)·Rx(α)·C_i`.
fn fixed_part(robot: &Robot, i: usize) -> Iso {
    robot.chain()[i].transform(0.0)
}

/// Of the two roll-pitch-yaw triples of `o`'s rotation (and their 2π
/// shifts), the one nearest `near`: a calibrated link keeps the branch of
/// its nominal numbers (UR's `wrist_3` is `roll π/2, pitch π, yaw π`).
fn rpy_near(o: Origin, near: [f64; 3]) -> Origin {
    use std::f64::consts::{PI, TAU};
    let [r, p, y] = o.rpy;
    let shift = |v: f64, to: f64| v + TAU * ((to - v) / TAU).round();
    let best = [[r, p, y], [r + PI, PI - p, y + PI]]
        .map(|c| [0, 1, 2].map(|k| shift(c[k], near[k])))
        .into_iter()
        .min_by(|a, b| {
            let d = |c: &[f64; 3]| (0..3).map(|k| (c[k] - near[k]).abs()).sum::<f64>();
            d(a).total_cmp(&d(b))
        })
        .expect("two candidates");
    Origin {
        xyz: o.xyz,
        rpy: best,
    }
}

/// A YAML float that YAML 1.1 readers (PyYAML, which xacro uses) take as a
/// float: shortest round-trip digits, with a `.` and a signed exponent.
fn yaml_f64(v: f64) -> String {
    let s = format!("{v:?}");
    match s.split_once('e') {
        None => s,
        Some((m, e)) => {
            let m = if m.contains('.') {
                m.to_string()
            } else {
                format!("{m}.0")
            };
            let e = if e.starts_with('-') {
                e.to_string()
            } else {
                format!("+{e}")
            };
            format!("{m}e{e}")
        }
    }
}

impl UrKinematics {
    /// Reads the YAML text.
    pub fn from_yaml_str(text: &str) -> Result<Self, UrKinematicsError> {
        let f: File =
            serde_yaml::from_str(text).map_err(|e| UrKinematicsError::Yaml(e.to_string()))?;
        let k = f.kinematics;
        let links = [
            &k.shoulder,
            &k.upper_arm,
            &k.forearm,
            &k.wrist_1,
            &k.wrist_2,
            &k.wrist_3,
        ]
        .map(Link::origin);
        if let Some(bad) = links
            .iter()
            .zip(UR_LINKS)
            .find(|(o, _)| !o.xyz.iter().chain(&o.rpy).all(|v| v.is_finite()))
        {
            return Err(UrKinematicsError::Yaml(format!(
                "{}: a number is not finite",
                bad.1
            )));
        }
        Ok(Self {
            links,
            hash: k.hash,
        })
    }

    /// Reads the YAML file at `path`.
    pub fn from_yaml_file(path: &Path) -> Result<Self, UrKinematicsError> {
        read_file(path, Self::from_yaml_str)
    }

    /// The YAML text, after `comment` (each line prefixed with `# `).
    pub fn to_yaml(&self, comment: &str) -> String {
        let mut out: String = comment.lines().map(|l| format!("# {l}\n")).collect();
        out.push_str("kinematics:\n");
        for (name, o) in UR_LINKS.iter().zip(&self.links) {
            out.push_str(&format!("  {name}:\n"));
            let keys = ["x", "y", "z", "roll", "pitch", "yaw"];
            for (k, v) in keys.iter().zip(o.xyz.iter().chain(&o.rpy)) {
                out.push_str(&format!("    {k}: {}\n", yaml_f64(*v)));
            }
        }
        out.push_str(&format!("  hash: {}\n", self.hash));
        out
    }

    /// `model` (a UR robot, e.g. the built-in of the same type: its joint
    /// names, limits, noise, priors and error set) with these kinematics as
    /// its nominal model: `base_to_model` the shoulder's origin, joint i's
    /// fixed part the next link's origin, joint 6's UR's `tool0` rotation
    /// (see the module doc); frames `base` / `tool0`. `file` is named in `source`.
    pub fn nominal_robot(&self, model: &Robot, file: &str) -> Result<Robot, UrKinematicsError> {
        if model.dof() != 6 {
            return Err(UrKinematicsError::NotUr(format!(
                "robot `{}` has {} joints, UR's 6",
                model.name(),
                model.dof()
            )));
        }
        let mut d = model.description().clone();
        for (i, j) in d.joints.iter_mut().enumerate() {
            (j.theta0, j.d, j.a, j.alpha) = (0.0, 0.0, 0.0, 0.0);
            j.origin = Some(if i + 1 < 6 {
                self.links[i + 1]
            } else {
                ur_tool0()
            });
        }
        d.frames = Some(robimu_model::Frames {
            base: "base".into(),
            flange: "tool0".into(),
            base_to_model: self.links[0],
        });
        d.source = Some(format!(
            "UR kinematics {file} (hash {}) over `{}`{}",
            self.hash,
            model.name(),
            model
                .description()
                .source
                .as_ref()
                .map(|s| format!(" ({s})"))
                .unwrap_or_default()
        ));
        d.calibration_hash = Some(self.hash.clone());
        Ok(Robot::new(d)?)
    }

    /// The kinematics of `robot` with the generalized errors `eps` folded
    /// in (`C_i·E_i` for joints 1–5; `eps[5]`, the IMU's position on the
    /// flange, has no place in the file), `hash` the robot's
    /// `calibration_hash` or `hash`. Refused unless the robot has 6 joints
    /// and its last fixed part is UR's `tool0` rotation (to 1e-9).
    pub fn of_robot(
        robot: &Robot,
        eps: &[[f64; 6]],
        hash: &str,
    ) -> Result<Self, UrKinematicsError> {
        if robot.dof() != 6 || eps.len() != 6 {
            return Err(UrKinematicsError::NotUr(format!(
                "robot `{}` has {} joints, UR's 6",
                robot.name(),
                robot.dof()
            )));
        }
        let last = fixed_part(robot, 5);
        let f = ur_tool0().to_iso();
        let off = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| (last.r[i][j] - f.r[i][j]).abs())
            .chain(last.p.iter().map(|v| v.abs()))
            .fold(0.0, f64::max);
        if off > 1e-9 {
            return Err(UrKinematicsError::NotUr(format!(
                "the UR description fixes tool0 to wrist_3_link (rpy 0 −π/2 −π/2, then π/2 0 π/2); robot `{}`'s last link differs by {off:.1e}",
                robot.name()
            )));
        }
        let d = robot.description();
        let mut links = [Origin::IDENTITY; 6];
        links[0] = d
            .frames
            .as_ref()
            .map_or(Origin::IDENTITY, |f| f.base_to_model);
        for i in 0..5 {
            let j = &d.joints[i];
            let stored = j.origin.unwrap_or(Origin::IDENTITY);
            let plain = [j.theta0, j.d, j.a, j.alpha].iter().all(|v| *v == 0.0);
            links[i + 1] = if plain && eps[i].iter().all(|v| *v == 0.0) {
                stored
            } else {
                let t = fixed_part(robot, i).compose(&error_transform(&eps[i]));
                rpy_near(Origin::from_iso(&t), stored.rpy)
            };
        }
        Ok(Self {
            links,
            hash: d
                .calibration_hash
                .clone()
                .unwrap_or_else(|| hash.to_string()),
        })
    }
}

/// The calibrated `robot` (its generalized errors `params.eps`) as a UR
/// kinematics YAML, with a header saying what the file does not carry.
pub fn calibrated_ur_yaml(
    robot: &Robot,
    params: &ModelParams,
    hash_if_unknown: &str,
) -> Result<String, UrKinematicsError> {
    let k = UrKinematics::of_robot(robot, &params.eps, hash_if_unknown)?;
    Ok(k.to_yaml(&format!(
        "UR kinematics of `{}` calibrated by robimu: pass it to the UR ROS 2 description\n\
         as kinematics_params (kinematics_parameters_file). It carries the joint\n\
         geometry only (base to tool0); not carried: the IMU's mount and intrinsics,\n\
         the time offset, and effects such as joint elasticity.\n\
         hash: {} (the nominal's: the controller keeps its\n\
         own calibration, and the UR driver compares this hash with it).",
        robot.name(),
        k.hash
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::kinematics::forward_kinematics;

    const UR5E_DEFAULT: &str = "kinematics:
  shoulder:
    x: 0
    y: 0
    z: 0.1625
    roll: 0
    pitch: 0
    yaw: 0
  upper_arm:
    x: 0
    y: 0
    z: 0
    roll: 1.570796327
    pitch: 0
    yaw: 0
  forearm:
    x: -0.425
    y: 0
    z: 0
    roll: 0
    pitch: 0
    yaw: 0
  wrist_1:
    x: -0.3922
    y: 0
    z: 0.1333
    roll: 0
    pitch: 0
    yaw: 0
  wrist_2:
    x: 0
    y: -0.0997
    z: -2.044881182297852e-11
    roll: 1.570796327
    pitch: 0
    yaw: 0
  wrist_3:
    x: 0
    y: 0.09959999999999999
    z: -2.042830148012698e-11
    roll: 1.570796326589793
    pitch: 3.141592653589793
    yaw: 3.141592653589793
  hash: calib_12788084448423163542
";

    fn flange(r: &Robot, eps: &[[f64; 6]], q: &[f64]) -> Iso {
        let b = r.description().frames.as_ref().unwrap().base_to_model;
        let mut e = eps.to_vec();
        e[5] = [0.0; 6];
        b.to_iso().compose(&forward_kinematics(r.chain(), &e, q))
    }

    #[test]
    fn the_default_ur5e_file_is_the_builtin_ur5e_and_writes_back_unchanged() {
        let k = UrKinematics::from_yaml_str(UR5E_DEFAULT).unwrap();
        let b = Robot::builtin("ur5e").unwrap();
        let r = k.nominal_robot(&b, "default_kinematics.yaml").unwrap();
        let eps = vec![[0.0; 6]; 6];
        for q in [[0.0; 6], [0.3, -1.2, 2.0, -0.4, 1.1, -2.5]] {
            let (a, c) = (flange(&b, &eps, &q), flange(&r, &eps, &q));
            for i in 0..3 {
                assert!((a.p[i] - c.p[i]).abs() < 1e-15);
                for j in 0..3 {
                    assert!((a.r[i][j] - c.r[i][j]).abs() < 1e-15);
                }
            }
        }
        let back = UrKinematics::of_robot(&r, &eps, "x").unwrap();
        assert_eq!(back, k);
        // The builtin writes the same hash and the same links (wrist_3's
        // rotation with other roll-pitch-yaw numbers: the URDF reader's).
        let kb = UrKinematics::of_robot(&b, &eps, "x").unwrap();
        assert_eq!(kb.hash, k.hash);
        for (x, y) in kb.links.iter().zip(&k.links) {
            let (x, y) = (x.to_iso(), y.to_iso());
            for i in 0..3 {
                assert!((x.p[i] - y.p[i]).abs() < 1e-15);
                for j in 0..3 {
                    assert!((x.r[i][j] - y.r[i][j]).abs() < 1e-15);
                }
            }
        }
        // ... and its YAML reads back to them.
        let text = back.to_yaml("a comment");
        assert!(text.contains("z: -2.044881182297852e-11"), "{text}");
        assert_eq!(UrKinematics::from_yaml_str(&text).unwrap(), k);
    }

    #[test]
    fn a_calibrated_robot_writes_its_errors_into_the_links() {
        let b = UrKinematics::from_yaml_str(UR5E_DEFAULT)
            .unwrap()
            .nominal_robot(&Robot::builtin("ur5e").unwrap(), "default")
            .unwrap();
        let mut eps = vec![[0.0; 6]; 6];
        for (i, e) in eps.iter_mut().enumerate().take(5) {
            *e = [1e-3, -2e-3, 5e-4, 2e-4 * i as f64, -1e-4, 3e-4];
        }
        eps[5] = [0.03, 0.01, 0.02, 0.0, 0.0, 0.0];
        let k = UrKinematics::of_robot(&b, &eps, "x").unwrap();
        let r = UrKinematics::from_yaml_str(&k.to_yaml(""))
            .unwrap()
            .nominal_robot(&b, "f")
            .unwrap();
        let zero = vec![[0.0; 6]; 6];
        let q = [0.7, -0.9, 1.4, 0.2, -2.2, 1.0];
        let (a, c) = (flange(&b, &eps, &q), flange(&r, &zero, &q));
        for i in 0..3 {
            assert!((a.p[i] - c.p[i]).abs() < 1e-14, "{:?} {:?}", a.p, c.p);
        }
        // wrist_3 keeps the branch of its nominal numbers.
        assert!(
            (k.links[5].rpy[1] - std::f64::consts::PI).abs() < 0.01,
            "{:?}",
            k.links[5]
        );
    }

    #[test]
    fn floats_are_written_as_yaml_1_1_floats() {
        assert_eq!(yaml_f64(1e-5), "1.0e-5");
        assert_eq!(yaml_f64(-2.5e16), "-2.5e+16");
        assert_eq!(yaml_f64(0.0), "0.0");
        assert_eq!(yaml_f64(0.1625), "0.1625");
    }

    #[test]
    fn bad_files_and_robots_are_refused_with_the_reason() {
        let e = UrKinematics::from_yaml_str("kinematics:\n  shoulder: {x: 0}\n").unwrap_err();
        assert!(e.to_string().contains("not a UR kinematics YAML"), "{e}");
        let e = UrKinematics::of_robot(&Robot::aubo_i5(), &[[0.0; 6]; 6], "x").unwrap_err();
        assert!(e.to_string().contains("last link differs"), "{e}");
        let e = UrKinematics::of_robot(&Robot::builtin("fr3").unwrap(), &[[0.0; 6]; 7], "x")
            .unwrap_err();
        assert!(e.to_string().contains("UR's 6"), "{e}");
    }
}
