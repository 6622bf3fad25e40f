//! The built-in robots: one description file each under `host/model/robots/`
//! (the TOML format of [`crate::robot`], its source cited in the file),
//! embedded in the program. `aubo_i5` is [`Robot::aubo_i5`] (docs/model.md §6).
//!
//! Each file was generated from the maker's own description (the URDF its
//! description package expands to, committed under `tests/fixtures/makers/`)
//! through [`crate::urdf`] and [`crate::error_selection`] by the ignored test
//! `catalogue::tests::regenerate` (`cargo test -p robimu-model --release
//! regenerate -- --ignored`); `tests/makers_fk.py` checks every file against
//! its fixture with an independent URDF reader.

use crate::robot::Robot;

/// (name, description file).
const FILES: &[(&str, &str)] = &[
    ("ur3", include_str!("../robots/ur3.toml")),
    ("ur5", include_str!("../robots/ur5.toml")),
    ("ur10", include_str!("../robots/ur10.toml")),
    ("ur3e", include_str!("../robots/ur3e.toml")),
    ("ur5e", include_str!("../robots/ur5e.toml")),
    ("ur10e", include_str!("../robots/ur10e.toml")),
    ("ur16e", include_str!("../robots/ur16e.toml")),
    ("ur20", include_str!("../robots/ur20.toml")),
    ("ur30", include_str!("../robots/ur30.toml")),
    ("fr3", include_str!("../robots/fr3.toml")),
    ("panda", include_str!("../robots/panda.toml")),
    ("iiwa14", include_str!("../robots/iiwa14.toml")),
    ("iiwa7", include_str!("../robots/iiwa7.toml")),
    ("gen3", include_str!("../robots/gen3.toml")),
    ("xarm6", include_str!("../robots/xarm6.toml")),
    ("xarm7", include_str!("../robots/xarm7.toml")),
    ("aubo_i3", include_str!("../robots/aubo_i3.toml")),
    ("aubo_i10", include_str!("../robots/aubo_i10.toml")),
];

/// Robots built into the program (`--robot NAME`, `robot = "NAME"`).
pub const BUILTIN_ROBOTS: &[&str] = &[
    "aubo_i5", "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e", "ur20", "ur30", "fr3",
    "panda", "iiwa14", "iiwa7", "gen3", "xarm6", "xarm7", "aubo_i3", "aubo_i10",
];

/// The description file of a built-in robot, as committed (its header cites
/// the source); `None` for `aubo_i5`, which is defined in code, and for
/// unknown names.
pub fn builtin_file(name: &str) -> Option<&'static str> {
    FILES.iter().find(|(n, _)| *n == name).map(|(_, f)| *f)
}

impl Robot {
    /// A built-in robot by name (one of [`BUILTIN_ROBOTS`]), or `None`.
    pub fn builtin(name: &str) -> Option<Self> {
        if name == "aubo_i5" {
            return Some(Robot::aubo_i5());
        }
        // Every file is parsed by the tests; a failure here cannot happen in
        // a tested build, and is reported as an unknown robot rather than a
        // panic.
        Robot::from_toml_str(builtin_file(name)?).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_selection::{identifiable_errors, IdentifiableOptions};
    use crate::geom::Iso;
    use crate::kinematics::forward_kinematics;
    use crate::urdf::{parse_joints, robot_from_urdf_str, UrdfOptions};

    const MAKERS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tests/fixtures/makers");

    /// How each file is made: name, chain base link in the fixture, tip
    /// (flange) link, source, joint noise σ (rad), acceleration limit (rad/s²).
    struct Spec {
        name: &'static str,
        base_frame: &'static str,
        tip: &'static str,
        source: &'static str,
        sigma_q: f64,
        qdd_max: Vec<f64>,
    }

    const UR_SRC: &str = "UniversalRobots/Universal_Robots_ROS2_Description 2.4.5 (commit 2221ec0f720fb1af99339eb891639b499b62f1da): config/MODEL/default_kinematics.yaml, config/MODEL/joint_limits.yaml, urdf/ur_macro.xacro";

    const FRANKA_SRC: &str = "frankaemika/franka_description (commit b299b39d9692bfae795184df32a98ce7778d56af, 2025-03-21): robots/ARM/kinematics.yaml, robots/ARM/joint_limits.yaml, robots/common/franka_arm.xacro; acceleration limits from Franka's FCI documentation (robot and interface specifications)";

    fn specs() -> Vec<Spec> {
        let mut v = ur_specs();
        // Franka: the description has no acceleration limits; these are the
        // q̈_max of Franka's FCI documentation ("Robot and interface
        // specifications": FR3 10 rad/s² on every joint; FER/Panda
        // 15, 7.5, 10, 12.5, 15, 20, 20 rad/s²). Joint noise: not published;
        // 1e-4 rad assumed.
        v.push(Spec {
            name: "fr3",
            base_frame: "fr3_link0",
            tip: "fr3_link8",
            source: FRANKA_SRC.replace("ARM", "fr3").leak(),
            sigma_q: 1e-4,
            qdd_max: vec![10.0; 7],
        });
        v.push(Spec {
            name: "panda",
            base_frame: "fer_link0",
            tip: "fer_link8",
            source: FRANKA_SRC.replace("ARM", "fer").leak(),
            sigma_q: 1e-4,
            qdd_max: vec![15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
        });
        // KUKA LBR iiwa 14 R820: acceleration limits are Drake's
        // `drake:acceleration` values in the same file (KUKA's datasheet gives
        // none); joint noise 1e-4 rad assumed.
        v.push(Spec {
            name: "iiwa14",
            base_frame: "iiwa_link_0",
            tip: "iiwa_link_ee_kuka",
            source: "RobotLocomotion/drake (commit 0b6a9c384d8cd7200a2015c7c36b52fca21d8635): manipulation/models/iiwa_description/urdf/iiwa14_no_collision.urdf (KUKA publishes no ROS description; derived from IFL-CAMP iiwa_stack); acceleration limits: its drake:acceleration values",
            sigma_q: 1e-4,
            qdd_max: vec![8.57, 8.57, 8.74, 11.36, 12.23, 15.72, 15.72],
        });
        // Kinova Gen3 7-DoF: speed limits from the URDF (1.3963 rad/s large
        // actuators, 1.2218 small; the package's MoveIt joint_limits.yaml says
        // 0.8727 for all: ambiguous, the URDF's match Kinova's datasheet);
        // acceleration limits from arms/gen3/7dof/config/joint_limits.yaml.
        // Joints 1, 3, 5, 7 are continuous (unlimited): limited to ±π here.
        v.push(Spec {
            name: "gen3",
            base_frame: "base_link",
            tip: "end_effector_link",
            source: "Kinovarobotics/ros2_kortex (commit 1fdbef345954b326627dc3792981e18e2221450b): kortex_description/robots/gen3_2f85.urdf (tf prefix removed), kortex_description/arms/gen3/7dof/config/joint_limits.yaml (accelerations)",
            sigma_q: 1e-4,
            qdd_max: vec![1.0, 1.0, 1.0, 1.0, 10.0, 10.0, 10.0],
        });
        // KUKA LBR iiwa 7 R800: Drake carries no URDF of it (an SDF with
        // placeholder speeds of 10 rad/s and no flange frame); lbr-stack's
        // description has KUKA's datasheet position and speed limits and
        // KUKA's media flange (`lbr_link_ee`, 126 mm beyond joint 6). KUKA
        // publishes no acceleration limit: 10 rad/s² on every joint is the
        // stack's MoveIt configuration's
        // (lbr_moveit_config/iiwa7_moveit_config/config/joint_limits.yaml).
        // Joint noise 1e-4 rad assumed.
        v.push(Spec {
            name: "iiwa7",
            base_frame: "lbr_link_0",
            tip: "lbr_link_ee",
            source: "lbr-stack/lbr_fri_ros2_stack (commit 218d723f817c61314988833611effddc5333ca6c): lbr_description/urdf/iiwa7/iiwa7_description.xacro, lbr_description/urdf/iiwa7/joint_limits.yaml (KUKA's datasheet limits; KUKA publishes no ROS description); acceleration limits: lbr_moveit_config/iiwa7_moveit_config/config/joint_limits.yaml",
            sigma_q: 1e-4,
            qdd_max: vec![10.0; 7],
        });
        // UFactory xArm 6 and 7: position limits the xacro's defaults
        // (`limited:=false`, UFactory's datasheet ranges), speed 3.14 rad/s
        // from the URDF (UFactory's 180°/s; the MoveIt joint_limits.yaml says
        // 2.14); acceleration 10 rad/s² from xarm_moveit_config's
        // joint_limits.yaml. Joint noise 1e-4 rad assumed.
        for (name, dof) in [("xarm6", 6), ("xarm7", 7)] {
            v.push(Spec {
                name,
                base_frame: "link_base",
                tip: "link_eef",
                source: "xArm-Developer/xarm_ros2 (branch humble, commit 5109131e7870c7d6e1075042d531e659d072cdb0): xarm_description/config/kinematics/default/MODEL_default_kinematics.yaml, xarm_description/urdf/MODEL/MODEL.urdf.xacro, xarm_description/urdf/xarm_device_macro.xacro; acceleration limits: xarm_moveit_config/config/MODEL/joint_limits.yaml",
                sigma_q: 1e-4,
                qdd_max: vec![10.0; dof],
            });
        }
        // AUBO i3 and i10: the URDF gives position limits (±3.04 rad) but
        // speed 0; speed and acceleration limits from the maker's MoveIt
        // configuration (aubo_iN_moveit_config/config/joint_limits.yaml:
        // 30 rad/s² for joints 1–3, 25 for 4–6). Joint noise 1e-4 rad
        // assumed.
        for name in ["aubo_i3", "aubo_i10"] {
            v.push(Spec {
                name,
                base_frame: "base_link",
                tip: "wrist3_Link",
                source: "AuboRobot/aubo_robot (branch Noetic, commit 6709931195cab90d388b34f10c00611982db3dcf): aubo_description/urdf/MODEL.urdf; speed and acceleration limits: MODEL_moveit_config/config/joint_limits.yaml",
                sigma_q: 1e-4,
                qdd_max: vec![30.0, 30.0, 30.0, 25.0, 25.0, 25.0],
            });
        }
        v
    }

    fn ur_specs() -> Vec<Spec> {
        // UR: the description publishes no acceleration limit
        // (has_acceleration_limits: false); 100°/s² (the paper's Table III
        // value) is a conservative planning limit, not UR's. Joint noise:
        // UR publishes none; 1e-4 rad assumed (RTDE actual_q).
        [
            "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e", "ur20", "ur30",
        ]
        .into_iter()
        .map(|name| Spec {
            name,
            base_frame: "base",
            tip: "tool0",
            source: UR_SRC,
            sigma_q: 1e-4,
            qdd_max: vec![100f64.to_radians(); 6],
        })
        .collect()
    }

    fn fixture(name: &str) -> String {
        std::fs::read_to_string(format!("{MAKERS}/{name}.urdf")).unwrap()
    }

    /// The maker's base frame in the URDF's root link: the identity, or the
    /// fixed joint from the root to it.
    fn root_to_frame(urdf: &str, root: &str, frame: &str) -> Iso {
        if root == frame {
            return Iso::identity();
        }
        let (_, joints) = parse_joints(urdf).unwrap();
        let j = joints
            .iter()
            .find(|j| j.parent == root && j.child == frame && j.kind == "fixed")
            .unwrap_or_else(|| panic!("no fixed joint {root} -> {frame}"));
        j.origin.to_iso()
    }

    /// The fixture's robot (chain from the root link), and the pose of the
    /// model base in the maker's base frame.
    fn from_fixture(spec: &Spec) -> (Robot, Iso) {
        let urdf = fixture(spec.name);
        let opts = UrdfOptions {
            tip: Some(spec.tip.into()),
            sigma_q: spec.sigma_q,
            ..UrdfOptions::default()
        };
        let (robot, chain) = robot_from_urdf_str(&urdf, &opts).unwrap();
        let mut d = robot.description().clone();
        for (j, a) in d.joints.iter_mut().zip(&spec.qdd_max) {
            j.qdd_max = *a;
        }
        let robot = Robot::new(d).unwrap();
        let f = robot.description().frames.clone().unwrap();
        let base = root_to_frame(&urdf, &chain.base, spec.base_frame)
            .inverse()
            .compose(&f.base_to_model.to_iso());
        (robot, base)
    }

    #[test]
    #[ignore = "regenerates host/model/robots/*.toml"]
    fn regenerate() {
        for spec in specs() {
            let (robot, base) = from_fixture(&spec);
            let mut d = robot.description().clone();
            d.name = spec.name.into();
            d.source = Some(spec.source.replace("MODEL", spec.name));
            d.frames.as_mut().unwrap().flange = spec.tip.into();
            let f = d.frames.as_mut().unwrap();
            f.base = spec.base_frame.into();
            f.base_to_model = crate::robot::Origin::from_iso(&base);
            // UR: the default kinematics' `hash` (scripts/ur_urdf.py writes
            // it into the fixture's header).
            d.calibration_hash = fixture(spec.name)
                .split_once("(hash ")
                .map(|(_, rest)| rest.split(')').next().unwrap().to_string());
            let robot = Robot::new(d).unwrap();
            let set = identifiable_errors(&robot, &IdentifiableOptions::default()).unwrap();
            let robot = robot.with_estimated_errors(set.errors).unwrap();
            let text = format!(
                "# Built-in robot `{}` (robimu robot description, host/model/src/robot.rs).\n\
                 # Source: {}.\n\
                 # Generated from tests/fixtures/makers/{}.urdf by\n\
                 # `cargo test -p robimu-model --release regenerate -- --ignored`;\n\
                 # [errors]: the minimal set found numerically (error_selection).\n\n{}",
                spec.name,
                robot.description().source.as_deref().unwrap(),
                spec.name,
                toml::to_string(robot.description()).unwrap()
            );
            let path = format!("{}/robots/{}.toml", env!("CARGO_MANIFEST_DIR"), spec.name);
            std::fs::write(path, text).unwrap();
        }
    }

    fn pose_err(a: &Iso, b: &Iso) -> (f64, f64) {
        let dp = (0..3).map(|k| (a.p[k] - b.p[k]).abs()).fold(0.0, f64::max);
        let r = crate::geom::mul_mm(&crate::geom::transpose(&a.r), &b.r);
        let dr = crate::geom::log_so3(&r);
        (dp, crate::geom::dot(dr, dr).sqrt())
    }

    #[test]
    fn every_builtin_loads_and_is_listed() {
        for name in BUILTIN_ROBOTS {
            let r = Robot::builtin(name).unwrap_or_else(|| panic!("{name}"));
            assert_eq!(r.name(), *name);
            if *name != "aubo_i5" {
                let d = r.description();
                assert!(d.source.is_some() && d.frames.is_some(), "{name}");
                assert_eq!(d.joint_names.len(), r.dof(), "{name}");
                assert!(d.errors.is_some(), "{name}: minimal error set");
            }
        }
        assert_eq!(FILES.len() + 1, BUILTIN_ROBOTS.len());
        assert!(Robot::builtin("ur6").is_none());
    }

    #[test]
    fn bad_joint_names_are_rejected_with_the_reason() {
        let mut d = Robot::builtin("ur5e").unwrap().description().clone();
        d.joint_names.pop();
        let e = Robot::new(d.clone()).unwrap_err().to_string();
        assert!(e.contains("5 names for 6 joints"), "{e}");
        d.joint_names.push("shoulder_pan_joint".into());
        let e = Robot::new(d).unwrap_err().to_string();
        assert!(e.contains("`shoulder_pan_joint` is listed twice"), "{e}");
    }

    /// `robot_to_urdf` written and read back (robimu's URDF reader) gives the
    /// same flange pose in the maker's base frame, for every built-in.
    #[test]
    fn urdf_written_for_each_builtin_reads_back_to_the_same_flange_pose() {
        use crate::urdf::robot_to_urdf;
        let qs = [
            [0.0; 7],
            [0.3, -0.5, 1.2, 0.7, -1.1, 2.0, 0.4],
            [-1.4, 1.0, 0.6, -2.9, 0.2, -0.4, 1.9],
        ];
        for name in BUILTIN_ROBOTS {
            let b = Robot::builtin(name).unwrap();
            let text = robot_to_urdf(&b);
            let (u, _) = robot_from_urdf_str(&text, &UrdfOptions::default()).unwrap();
            let frames = |r: &Robot| {
                r.description()
                    .frames
                    .as_ref()
                    .map(|f| f.base_to_model.to_iso())
                    .unwrap_or_else(Iso::identity)
            };
            let n = b.dof();
            assert_eq!(u.dof(), n);
            for (lb, lu) in b.limits().iter().zip(u.limits()) {
                assert_eq!(
                    (lb.q_min, lb.q_max, lb.qd_max),
                    (lu.q_min, lu.q_max, lu.qd_max)
                );
            }
            if !b.description().joint_names.is_empty() {
                assert_eq!(b.description().joint_names, u.description().joint_names);
            }
            let eps = vec![[0.0; 6]; n];
            for q in &qs {
                let pb = frames(&b).compose(&forward_kinematics(b.chain(), &eps, &q[..n]));
                let pu = frames(&u).compose(&forward_kinematics(u.chain(), &eps, &q[..n]));
                let (dp, dr) = pose_err(&pb, &pu);
                assert!(dp < 1e-12 && dr < 1e-12, "{name}: {dp:e} m, {dr:e} rad");
            }
        }
    }

    /// Each built-in's nominal flange pose in the maker's base frame equals
    /// the fixture's (the maker's URDF through robimu's URDF reader) at 200
    /// random configurations.
    #[test]
    fn builtins_match_their_maker_urdf() {
        let mut rng = 0x2545F4914F6CDD1Du64;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for spec in specs() {
            let b = Robot::builtin(spec.name).unwrap();
            let (u, ubase) = from_fixture(&spec);
            let bbase = b
                .description()
                .frames
                .as_ref()
                .unwrap()
                .base_to_model
                .to_iso();
            let n = b.dof();
            assert_eq!(u.dof(), n);
            assert_eq!(b.description().joint_names, u.description().joint_names);
            for (lb, lu) in b.limits().iter().zip(u.limits()) {
                assert_eq!(lb, lu, "{}", spec.name);
            }
            let eps = vec![[0.0; 6]; n];
            let mut worst = (0.0f64, 0.0f64);
            for _ in 0..200 {
                let q: Vec<f64> = b
                    .limits()
                    .iter()
                    .map(|l| l.q_min + (l.q_max - l.q_min) * next())
                    .collect();
                let pb = bbase.compose(&forward_kinematics(b.chain(), &eps, &q));
                let pu = ubase.compose(&forward_kinematics(u.chain(), &eps, &q));
                let (dp, dr) = pose_err(&pb, &pu);
                worst = (worst.0.max(dp), worst.1.max(dr));
            }
            assert!(
                worst.0 < 1e-12 && worst.1 < 1e-12,
                "{}: {worst:?}",
                spec.name
            );
        }
    }
}
