//! Universal Robots' kinematics YAML in and out, checked by an independent
//! reader: `tests/ur_kinematics_fk.py` (PyYAML and numpy) builds the chain
//! from the file the way the UR ROS 2 description's `ur_macro.xacro` does.
//!
//! A UR5e's factory calibration (tests/fixtures/ur/) is read as the nominal
//! model (`robots show ur5e --ur-kinematics`); a session simulated on it is
//! calibrated and exported (`export --format ur-kinematics`): the file gives
//! the calibrated model's tool0 pose, and a calibration that changed nothing
//! gives the factory file's own numbers back. Skipped, with a message,
//! without python3, numpy and PyYAML (`.ci/run` installs them).

use std::path::Path;
use std::process::Command;

use rand::{Rng, SeedableRng};
use robimu_model::kinematics::forward_kinematics;
use robimu_model::Robot;
use robimu_session::export::calibrated_params;
use robimu_session::export::ur::UrKinematics;
use robimu_session::result::CalibrationResult;

mod common;
use common::{robimu_ok, s};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

fn python(args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg(root().join("tests/ur_kinematics_fk.py"))
        .args(args)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    assert!(
        out.status.success(),
        "tests/ur_kinematics_fk.py {args:?}:\n{text}"
    );
    text
}

#[test]
fn ur_kinematics_yaml_round_trips_through_a_calibration() {
    let probe = Command::new("python3")
        .args(["-c", "import numpy, yaml"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        eprintln!("SKIPPED: python3 with numpy and PyYAML is needed (pip install numpy pyyaml)");
        return;
    }
    let factory = root().join("tests/fixtures/ur/ur5e_factory_calibration.yaml");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    // The factory calibration as the nominal model.
    let toml = d.join("my_ur5e.toml");
    let run = robimu_ok(["robots", "show", "ur5e", "--ur-kinematics", s(&factory)]);
    std::fs::write(&toml, &run.stdout).unwrap();
    let robot = Robot::from_toml_file(&toml).unwrap();
    assert_eq!(
        robot.description().calibration_hash.as_deref(),
        Some("calib_14698139022496758595")
    );

    // A session on it, calibrated.
    let session = d.join("s");
    robimu_ok([
        "simulate",
        "--robot",
        s(&toml),
        "--duration",
        "40",
        "--seed",
        "38",
        "--out",
        s(&session),
    ]);
    robimu_ok(["calibrate", s(&session)]);
    let result_path = session.join("result.json");

    // Exported: the independent reader's tool0 pose is the calibrated
    // model's, at 50 random configurations.
    let cal = d.join("calibrated.yaml");
    let run = robimu_ok([
        "export",
        "--calibration",
        s(&result_path),
        "--format",
        "ur-kinematics",
        "--out",
        s(&cal),
    ]);
    assert!(run.stderr.contains("not the IMU's mount"), "{}", run.stderr);
    let result = CalibrationResult::read(&result_path).unwrap();
    let params = calibrated_params(&robot, &result).unwrap();
    let mut eps = params.eps.clone();
    eps[5] = [0.0; 6]; // the IMU's position on the flange: not the flange
    let base = robot.description().frames.as_ref().unwrap().base_to_model;
    let mut rng = rand::rngs::StdRng::seed_from_u64(38);
    let mut csv = String::from("# q1..q6, tool0 position in base, rotation row by row\n");
    for _ in 0..50 {
        let q: Vec<f64> = robot
            .limits()
            .iter()
            .map(|l| rng.random_range(l.q_min..l.q_max))
            .collect();
        let t = base
            .to_iso()
            .compose(&forward_kinematics(robot.chain(), &eps, &q));
        csv.push_str(&common::pose_row(&q, &t));
    }
    let poses = d.join("poses.csv");
    std::fs::write(&poses, csv).unwrap();
    let text = python(&["fk", s(&cal), s(&poses), "1e-9"]);
    assert!(text.contains("50 configurations"), "{text}");
    // The calibration moved the links (by more than the check's tolerance).
    let (k0, k1) = (
        UrKinematics::from_yaml_file(&factory).unwrap(),
        UrKinematics::from_yaml_file(&cal).unwrap(),
    );
    let moved = k0
        .links
        .iter()
        .zip(&k1.links)
        .flat_map(|(a, b)| (0..3).map(move |i| (a.xyz[i] - b.xyz[i]).abs()))
        .fold(0.0, f64::max);
    assert!(moved > 1e-6, "the calibrated file equals the factory's");
    assert_eq!(k1.hash, k0.hash);

    // A calibration that changed nothing (every ε zero) exports the factory
    // file's numbers and hash.
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&result_path).unwrap()).unwrap();
    for p in json["parameters"].as_array_mut().unwrap() {
        if p["name"].as_str().unwrap().starts_with("eps_") {
            p["value"] = serde_json::json!(0.0);
        }
    }
    let zero = session.join("result_zero.json");
    std::fs::write(&zero, serde_json::to_string(&json).unwrap()).unwrap();
    let back = d.join("back.yaml");
    robimu_ok([
        "export",
        "--calibration",
        s(&zero),
        "--format",
        "ur-kinematics",
        "--out",
        s(&back),
    ]);
    python(&["same", s(&factory), s(&back)]);
    assert_eq!(UrKinematics::from_yaml_file(&back).unwrap(), k0);
}

/// A controller's `calibration.conf` (DH corrections) read as the nominal
/// (`robots show ur5e --ur-calibration-conf`) and exported unchanged as UR's
/// kinematics YAML: the independent reader builds the UR description's
/// chain from that YAML and finds the corrected DH chain's tool0, computed
/// here as UR defines it (Π Rz(q+θ)·Tz(d)·Tx(a)·Rx(α) over UR's published
/// table plus the corrections), at 50 configurations to 1e-9. A file
/// without `delta_alpha` is refused naming it.
#[test]
fn a_controllers_calibration_conf_is_the_corrected_dh_chain() {
    let probe = Command::new("python3")
        .args(["-c", "import numpy, yaml"])
        .output();
    if !probe.is_ok_and(|o| o.status.success()) {
        eprintln!("SKIPPED: python3 with numpy and PyYAML is needed (pip install numpy pyyaml)");
        return;
    }
    use robimu_model::geom::{rot_x, rot_z, Iso};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let dt = [2.1e-5, -0.0317, 0.0462, -0.0145, 3.3e-5, -4.1e-5];
    let da = [2.9e-5, 3.1e-4, 8.2e-4, 1.7e-5, 4.4e-5, 0.0];
    let dd = [1.9e-4, 1.2731, -2.5103, 1.2371, -6.2e-5, 3.3e-4];
    let dal = [9.1e-5, 1.4e-3, 7.7e-3, 3.9e-4, -1.8e-4, 0.0];
    let list = |v: &[f64; 6]| {
        let items: Vec<String> = v.iter().map(|x| format!("{x:e}")).collect();
        format!("[ {} ]", items.join(", "))
    };
    let conf = d.join("calibration.conf");
    std::fs::write(
        &conf,
        format!(
            "[mounting]\ndelta_theta = {}\ndelta_a = {}\ndelta_d = {}\ndelta_alpha = {}\n",
            list(&dt),
            list(&da),
            list(&dd),
            list(&dal)
        ),
    )
    .unwrap();
    let run = robimu_ok(["robots", "show", "ur5e", "--ur-calibration-conf", s(&conf)]);
    let toml = d.join("my_ur5e.toml");
    std::fs::write(&toml, &run.stdout).unwrap();
    // a result that changed nothing, exported as UR's YAML
    let robot = Robot::from_toml_file(&toml).unwrap();
    let layout = robimu_model::ParamLayout::new(&robot);
    let result = d.join("result.json");
    common::write_result_json(&result, s(&toml), &layout, |p| p.nominal);
    let yaml = d.join("kinematics.yaml");
    robimu_ok([
        "export",
        "--calibration",
        s(&result),
        "--format",
        "ur-kinematics",
        "--out",
        s(&yaml),
    ]);
    // UR's DH table of the UR5e plus the corrections, evaluated directly
    let table = [
        [0.1625, 0.0, std::f64::consts::FRAC_PI_2],
        [0.0, -0.425, 0.0],
        [0.0, -0.3922, 0.0],
        [0.1333, 0.0, std::f64::consts::FRAC_PI_2],
        [0.0997, 0.0, -std::f64::consts::FRAC_PI_2],
        [0.0996, 0.0, 0.0],
    ];
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut csv = String::from("# q1..q6, tool0 position in base, rotation row by row\n");
    for _ in 0..50 {
        let q: [f64; 6] = std::array::from_fn(|_| rng.random_range(-3.0..3.0));
        let mut t = Iso::identity();
        for i in 0..6 {
            let [dn, an, aln] = table[i];
            t = t
                .compose(&Iso::rotation(rot_z(q[i] + dt[i])))
                .compose(&Iso::translation([an + da[i], 0.0, dn + dd[i]]))
                .compose(&Iso::rotation(rot_x(aln + dal[i])));
        }
        csv.push_str(&common::pose_row(&q, &t));
    }
    let poses = d.join("poses.csv");
    std::fs::write(&poses, csv).unwrap();
    let text = python(&["fk", s(&yaml), s(&poses), "1e-9"]);
    assert!(text.contains("50 configurations"), "{text}");

    let bad = d.join("bad.conf");
    std::fs::write(&bad, "[mounting]\ndelta_theta = [0,0,0,0,0,0]\n").unwrap();
    let run = common::robimu(["robots", "show", "ur5e", "--ur-calibration-conf", s(&bad)]);
    assert!(
        !run.success() && run.stderr.contains("delta_a"),
        "{}",
        run.stderr
    );
}
