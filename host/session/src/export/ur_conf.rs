//! A Universal Robots controller's own factory calibration file,
//! `calibration.conf` (on the controller, `/root/.urcontrol/calibration.conf`):
//! per joint the corrections of UR's published Denavit–Hartenberg
//! parameters, in its `[mounting]` section,
//!
//! ```text
//! [mounting]
//! delta_theta = [ δθ1, …, δθ6 ]
//! delta_a = [ δa1, …, δa6 ]
//! delta_d = [ δd1, …, δd6 ]
//! delta_alpha = [ δα1, …, δα6 ]
//! ```
//!
//! (rad and m; other keys and sections are ignored). The robot's kinematics
//! is the DH chain `T = Π_i Rz(q_i + θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)` from the
//! controller's `base` to its tool flange (ROS `tool0`), with
//! `θ_i = δθ_i`, `d_i = d_i⁰ + δd_i`, `a_i = a_i⁰ + δa_i`,
//! `α_i = α_i⁰ + δα_i` over the model's nominal table ([`nominal_dh`], UR's
//! "DH parameters for calculations of kinematics and dynamics").
//! [`UrKinematics::from_calibration_conf`] writes it in the form of the
//! kinematics YAML: as `Rz(θ_i)` and `Tz(d_i)` commute with the joint's
//! rotation `Rz(q_i)`, link i's origin is `Tx(a_{i−1})·Rx(α_{i−1})·Rz(θ_i)·Tz(d_i)`
//! (the shoulder's `Rz(θ1)·Tz(d1)`), and what follows joint 6,
//! `Tx(a6)·Rx(α6)`, must be the description's fixed `tool0` rotation (the
//! identity). For the nominal table this is the description's own
//! `default_kinematics.yaml` (the test below: tool0 of every built-in UR
//! robot to 3.5e-10, the description's π/2 carrying 9 decimals).

use std::path::Path;

use robimu_model::geom::{rot_x, rot_z, Iso};
use robimu_model::robot::Origin;

use super::ur::{UrKinematics, UrKinematicsError};

/// The hash written for a kinematics made from a `calibration.conf`: the
/// controller's own hash comes over its primary interface (what
/// `ur_calibration` reads), not in the file. The UR driver warns, and goes
/// on, when the hashes differ.
pub(crate) const CONF_HASH: &str = "calib_from_calibration_conf";

/// UR's nominal DH table of `model` (a built-in UR name): per joint
/// `[d, a, α]` (m, m, rad), θ⁰ = 0. `None` for a model that is not UR's.
pub(crate) fn nominal_dh(model: &str) -> Option<[[f64; 3]; 6]> {
    use std::f64::consts::FRAC_PI_2 as H;
    // d1, a2, a3, d4, d5, d6
    let (d1, a2, a3, d4, d5, d6) = match model {
        "ur3" => (0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819),
        "ur5" => (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
        "ur10" => (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
        "ur3e" => (0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
        "ur5e" => (0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
        "ur10e" => (0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
        "ur16e" => (0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655),
        "ur20" => (0.2363, -0.862, -0.7287, 0.201, 0.1593, 0.1543),
        "ur30" => (0.2363, -0.637, -0.5037, 0.201, 0.1593, 0.1543),
        _ => return None,
    };
    Some([
        [d1, 0.0, H],
        [0.0, a2, 0.0],
        [0.0, a3, 0.0],
        [d4, 0.0, H],
        [d5, 0.0, -H],
        [d6, 0.0, 0.0],
    ])
}

/// The DH corrections of a `calibration.conf`.
#[derive(Debug, Clone, PartialEq)]
pub struct UrCalibrationConf {
    /// δθ per joint, rad.
    pub delta_theta: [f64; 6],
    /// δa per joint, m.
    pub delta_a: [f64; 6],
    /// δd per joint, m.
    pub delta_d: [f64; 6],
    /// δα per joint, rad.
    pub delta_alpha: [f64; 6],
}

/// The largest correction read as plausible, m or rad. Loose: with joints
/// 2–4 parallel, a factory calibration may move d along them in large
/// pairs that cancel (a UR3's file: δd of −6.29, +8.57 and −2.28 m).
const MAX_DELTA: f64 = 10.0;

impl UrCalibrationConf {
    /// Reads the text of a `calibration.conf`.
    pub fn from_text(text: &str) -> Result<Self, UrKinematicsError> {
        let bad = |m: String| UrKinematicsError::Yaml(format!("not a UR calibration.conf: {m}"));
        let mut found: [Option<[f64; 6]>; 4] = [None; 4];
        const KEYS: [&str; 4] = ["delta_theta", "delta_a", "delta_d", "delta_alpha"];
        for (n, line) in text.lines().enumerate() {
            let Some((key, value)) = line.split_once('=') else {
                continue;
            };
            let Some(k) = KEYS.iter().position(|k| *k == key.trim()) else {
                continue;
            };
            let list = value
                .trim()
                .strip_prefix('[')
                .and_then(|v| v.strip_suffix(']'))
                .ok_or_else(|| bad(format!("line {}: {} is not a [ … ] list", n + 1, KEYS[k])))?;
            let values = list
                .split(',')
                .map(|v| v.trim().parse::<f64>())
                .collect::<Result<Vec<f64>, _>>()
                .map_err(|e| bad(format!("line {}: {}: {e}", n + 1, KEYS[k])))?;
            let six: [f64; 6] = values.as_slice().try_into().map_err(|_| {
                bad(format!(
                    "line {}: {} has {} values, expected 6 (one per joint)",
                    n + 1,
                    KEYS[k],
                    values.len()
                ))
            })?;
            if let Some(v) = six.iter().find(|v| !v.is_finite() || v.abs() > MAX_DELTA) {
                return Err(bad(format!(
                    "line {}: {} holds {v}, beyond ±{MAX_DELTA}",
                    n + 1,
                    KEYS[k]
                )));
            }
            if found[k].replace(six).is_some() {
                return Err(bad(format!("line {}: {} given twice", n + 1, KEYS[k])));
            }
        }
        let get = |k: usize| found[k].ok_or_else(|| bad(format!("no {} line", KEYS[k])));
        Ok(Self {
            delta_theta: get(0)?,
            delta_a: get(1)?,
            delta_d: get(2)?,
            delta_alpha: get(3)?,
        })
    }

    /// Reads the file at `path`.
    pub fn from_file(path: &Path) -> Result<Self, UrKinematicsError> {
        super::ur::read_file(path, Self::from_text)
    }

    /// No correction: the nominal table.
    pub fn zero() -> Self {
        Self {
            delta_theta: [0.0; 6],
            delta_a: [0.0; 6],
            delta_d: [0.0; 6],
            delta_alpha: [0.0; 6],
        }
    }
}

impl UrKinematics {
    /// The kinematics of the UR `model` (a built-in name: `ur5e`, …) with
    /// the factory corrections `conf`, in the kinematics YAML's form (see
    /// the module doc), hash [`CONF_HASH`].
    pub fn from_calibration_conf(
        model: &str,
        conf: &UrCalibrationConf,
    ) -> Result<Self, UrKinematicsError> {
        let table = nominal_dh(model).ok_or_else(|| {
            UrKinematicsError::NotUr(format!(
                "`{model}` has no UR DH table (ur3, ur5, ur10, ur3e, ur5e, ur10e, ur16e, ur20, ur30)"
            ))
        })?;
        let dh: [[f64; 4]; 6] = std::array::from_fn(|i| {
            let [d, a, alpha] = table[i];
            [
                conf.delta_theta[i],
                d + conf.delta_d[i],
                a + conf.delta_a[i],
                alpha + conf.delta_alpha[i],
            ]
        });
        // Tz(d)·Rz(θ) before joint i's rotation; Tx(a)·Rx(α) after it
        let before = |[theta, d, _, _]: [f64; 4]| {
            Iso::translation([0.0, 0.0, d]).compose(&Iso::rotation(rot_z(theta)))
        };
        let after = |[_, _, a, alpha]: [f64; 4]| {
            Iso::translation([a, 0.0, 0.0]).compose(&Iso::rotation(rot_x(alpha)))
        };
        let links: [Origin; 6] = std::array::from_fn(|i| {
            let t = match i {
                0 => before(dh[0]),
                _ => after(dh[i - 1]).compose(&before(dh[i])),
            };
            Origin::from_iso(&t)
        });
        let last = after(dh[5]);
        let mut off = last.p.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (r, row) in last.r.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                off = off.max((v - if r == c { 1.0 } else { 0.0 }).abs());
            }
        }
        if off > 1e-12 {
            return Err(UrKinematicsError::NotUr(format!(
                "joint 6's δa and δα must be 0 (the UR description fixes tool0 to wrist_3_link); they move tool0 by {off:.1e}"
            )));
        }
        Ok(Self {
            links,
            hash: CONF_HASH.to_string(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::kinematics::forward_kinematics;
    use robimu_model::Robot;

    fn tool0(r: &Robot, q: &[f64]) -> Iso {
        let base = r
            .description()
            .frames
            .as_ref()
            .unwrap()
            .base_to_model
            .to_iso();
        base.compose(&forward_kinematics(r.chain(), &vec![[0.0; 6]; 6], q))
    }

    /// UR's published DH tables, without corrections, are the UR ROS 2
    /// description's default kinematics (the built-in robots, generated
    /// from the maker's URDF): tool0 in base to 1e-9 (the description's
    /// rpy carry 9 decimals) at 200 configurations, for every UR model.
    #[test]
    fn the_nominal_dh_tables_are_the_descriptions_kinematics() {
        let mut q = [0.0; 6];
        for model in [
            "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e", "ur20", "ur30",
        ] {
            let builtin = Robot::builtin(model).unwrap();
            let k = UrKinematics::from_calibration_conf(model, &UrCalibrationConf::zero()).unwrap();
            let ours = k.nominal_robot(&builtin, "test").unwrap();
            let mut worst = 0.0f64;
            for n in 0..200 {
                for (j, v) in q.iter_mut().enumerate() {
                    *v = ((n * 7 + j * 13) as f64 * 0.731).sin() * 3.0;
                }
                let (a, b) = (tool0(&builtin, &q), tool0(&ours, &q));
                for i in 0..3 {
                    worst = worst.max((a.p[i] - b.p[i]).abs());
                    for j in 0..3 {
                        worst = worst.max((a.r[i][j] - b.r[i][j]).abs());
                    }
                }
            }
            eprintln!("{model}: worst {worst:.1e}");
            assert!(worst < 1e-8, "{model}: tool0 differs by {worst:.1e}");
        }
    }

    /// A calibration.conf's corrections give the DH chain with them,
    /// evaluated directly (Π Rz(q+θ)·Tz(d)·Tx(a)·Rx(α)), to 1e-12.
    #[test]
    fn the_corrections_give_the_corrected_dh_chain() {
        let text = "[mounting]\n\
            delta_theta = [ 4.6e-05, -0.0596, 0.1879, -0.1284, 1.87e-05, -3.7e-05]\n\
            delta_a = [ 3.7e-05, 0.00043, 0.0015, 3.5e-05, 5.1e-05, 0]\n\
            delta_d = [ 0.00022, -6.2913, 8.5694, -2.2780, -7.3e-05, 0.00041]\n\
            delta_alpha = [ 0.000118, 0.0023, 0.0120, 0.000466, -0.000234, 0]\n\
            joint_checksum = [ 1, 2, 3, 4, 5, 6 ]\n";
        let conf = UrCalibrationConf::from_text(text).unwrap();
        let builtin = Robot::builtin("ur3").unwrap();
        let robot = UrKinematics::from_calibration_conf("ur3", &conf)
            .unwrap()
            .nominal_robot(&builtin, "test")
            .unwrap();
        let table = nominal_dh("ur3").unwrap();
        let q = [0.3, -1.1, 0.7, 2.0, -0.4, 1.3];
        let mut t = Iso::identity();
        for i in 0..6 {
            let [d, a, alpha] = table[i];
            t = t
                .compose(&Iso::rotation(rot_z(q[i] + conf.delta_theta[i])))
                .compose(&Iso::translation([0.0, 0.0, d + conf.delta_d[i]]))
                .compose(&Iso::translation([a + conf.delta_a[i], 0.0, 0.0]))
                .compose(&Iso::rotation(rot_x(alpha + conf.delta_alpha[i])));
        }
        let ours = tool0(&robot, &q);
        for i in 0..3 {
            assert!(
                (ours.p[i] - t.p[i]).abs() < 1e-12,
                "{:?} vs {:?}",
                ours.p,
                t.p
            );
            for j in 0..3 {
                assert!((ours.r[i][j] - t.r[i][j]).abs() < 1e-12);
            }
        }
    }

    /// Bad files are named with the line and the cause.
    #[test]
    fn bad_files_are_refused_with_the_cause() {
        let ok = "delta_theta = [0,0,0,0,0,0]\ndelta_a = [0,0,0,0,0,0]\ndelta_d = [0,0,0,0,0,0]\n";
        for (text, want) in [
            (ok.to_string(), "no delta_alpha line"),
            (
                format!("{ok}delta_alpha = [0,0,0,0,0]\n"),
                "5 values, expected 6",
            ),
            (
                format!("{ok}delta_alpha = [0,0,0,0,0,x]\n"),
                "line 4: delta_alpha",
            ),
            (format!("{ok}delta_alpha = [0,0,0,0,0,1e308]\n"), "beyond"),
            (
                format!("{ok}delta_alpha = 0,0,0,0,0,0\n"),
                "not a [ … ] list",
            ),
            (format!("{ok}delta_a = [0,0,0,0,0,0]\n"), "given twice"),
        ] {
            let err = UrCalibrationConf::from_text(&text).unwrap_err().to_string();
            assert!(err.contains(want), "{want}: {err}");
        }
        let conf = UrCalibrationConf {
            delta_a: [0.0, 0.0, 0.0, 0.0, 0.0, 1e-3],
            ..UrCalibrationConf::zero()
        };
        let err = UrKinematics::from_calibration_conf("ur5e", &conf).unwrap_err();
        assert!(err.to_string().contains("joint 6"), "{err}");
        assert!(UrKinematics::from_calibration_conf("fr3", &UrCalibrationConf::zero()).is_err());
    }
}
