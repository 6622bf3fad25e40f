//! `robimu robots`: the built-in catalogue listed, printed and written as a
//! plain URDF, and the written URDF checked two ways — read back by
//! robimu's URDF reader (same flange pose as the built-in) and, for the
//! robots of issue 38's must-show list, by `tests/makers_fk.py --written`,
//! an independent numpy reader comparing it with the maker's own URDF
//! (tests/fixtures/makers/, whose header names the maker's file and commit).

use std::path::Path;
use std::process::Command;

use robimu_model::geom::Iso;
use robimu_model::kinematics::forward_kinematics;
use robimu_model::urdf::{robot_from_urdf_file, UrdfOptions};
use robimu_model::{Robot, BUILTIN_ROBOTS};

mod common;
use common::{robimu, robimu_ok, s};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// Pose of the maker's flange frame in the maker's base frame.
fn flange(r: &Robot, q: &[f64]) -> Iso {
    let base = r
        .description()
        .frames
        .as_ref()
        .map(|f| f.base_to_model.to_iso())
        .unwrap_or_else(Iso::identity);
    base.compose(&forward_kinematics(r.chain(), &vec![[0.0; 6]; r.dof()], q))
}

#[test]
fn robots_lists_every_builtin_with_its_joints_and_source() {
    let run = robimu_ok(["robots"]);
    for name in BUILTIN_ROBOTS {
        let r = Robot::builtin(name).unwrap();
        let line = run
            .stdout
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("{name} not listed:\n{}", run.stdout));
        let cols: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(cols[1], r.dof().to_string(), "{line}");
        if let Some(src) = &r.description().source {
            assert!(line.ends_with(src.as_str()), "{line}");
        }
    }
    let ur5e = run.stdout.lines().find(|l| l.starts_with("ur5e ")).unwrap();
    assert!(
        ur5e.contains("Universal_Robots_ROS2_Description 2.4.5"),
        "{ur5e}"
    );
}

#[test]
fn robots_show_prints_a_description_that_loads_as_the_builtin() {
    for name in ["ur5e", "fr3", "aubo_i5"] {
        let run = robimu_ok(["robots", "show", name]);
        let r = Robot::from_toml_str(&run.stdout).unwrap();
        assert_eq!(
            r.description(),
            Robot::builtin(name).unwrap().description(),
            "{name}"
        );
    }
    robimu(["robots", "show", "ur6"]).assert_fails(&["unknown robot `ur6`", "ur5e", "fr3"]);
}

#[test]
fn written_urdf_gives_the_builtins_flange_pose() {
    let dir = tempfile::tempdir().unwrap();
    let qs = [
        [0.0; 7],
        [0.3, -0.5, 1.2, 0.7, -1.1, 2.0, 0.4],
        [-1.4, 1.0, 0.6, -2.9, 0.2, -0.4, 1.9],
    ];
    for name in BUILTIN_ROBOTS {
        let path = dir.path().join(format!("{name}.urdf"));
        robimu_ok(["robots", "show", name, "--urdf", s(&path)]);
        let b = Robot::builtin(name).unwrap();
        let flange_link = b
            .description()
            .frames
            .as_ref()
            .map_or("flange".to_string(), |f| f.flange.clone());
        let opts = UrdfOptions {
            tip: Some(flange_link),
            ..UrdfOptions::default()
        };
        let (u, _) = robot_from_urdf_file(&path, &opts).unwrap();
        assert_eq!(u.dof(), b.dof(), "{name}");
        for q in &qs {
            let (pb, pu) = (flange(&b, &q[..b.dof()]), flange(&u, &q[..b.dof()]));
            let dp = (0..3)
                .map(|k| (pb.p[k] - pu.p[k]).abs())
                .fold(0.0, f64::max);
            let dr = (0..3)
                .flat_map(|i| (0..3).map(move |j| (i, j)))
                .map(|(i, j)| (pb.r[i][j] - pu.r[i][j]).abs())
                .fold(0.0, f64::max);
            assert!(dp < 1e-12 && dr < 1e-12, "{name}: {dp:e} m, {dr:e}");
        }
    }
}

/// Whether python3 imports `modules` (the independent readers' numpy
/// and tomllib); if not, says the test is skipped and why (`.ci/run`
/// installs numpy, so CI never skips).
fn python_has(modules: &str) -> bool {
    let probe = Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .output();
    let ok = probe.is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!("SKIPPED: python3 (>= 3.11) importing {modules} is needed (pip install numpy)");
    }
    ok
}

/// The written URDF against the maker's, both read by the independent
/// numpy reader of tests/makers_fk.py. Skipped, with a message, without
/// python3 ≥ 3.11 and numpy (`.ci/run` installs numpy).
#[test]
fn written_urdf_equals_the_makers_by_an_independent_reader() {
    if !python_has("numpy, tomllib") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "ur5e", "ur10e", "fr3", "panda", "iiwa14", "gen3", "iiwa7", "xarm6", "xarm7", "aubo_i3",
        "aubo_i10",
    ] {
        let path = dir.path().join(format!("{name}.urdf"));
        robimu_ok(["robots", "show", name, "--urdf", s(&path)]);
        let out = Command::new("python3")
            .arg(root().join("tests/makers_fk.py"))
            .args(["--written", name, s(&path), s(root())])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        println!("{text}{}", String::from_utf8_lossy(&out.stderr));
        assert!(
            out.status.success() && text.trim_end().ends_with(" ok"),
            "{name}:\n{text}"
        );
    }
}

/// Every command that takes `--robot` takes a catalogue name: a short
/// simulated UR5e session names the robot, and `check` loads it.
#[test]
fn robot_flag_takes_catalogue_names() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    robimu_ok([
        "simulate",
        "--robot",
        "ur5e",
        "--duration",
        "5",
        "--seed",
        "3",
        "--out",
        s(&out),
    ]);
    let toml = std::fs::read_to_string(out.join("session.toml")).unwrap();
    assert!(toml.contains("robot = \"ur5e\""), "{toml}");
    robimu_ok(["check", s(&out)]);
    robimu([
        "simulate",
        "--robot",
        "ur6",
        "--out",
        s(&dir.path().join("x")),
    ])
    .assert_fails(&["unknown robot `ur6`", "ur5e", "iiwa14"]);
}

/// Issue 38's Monte Carlo of the catalogue's robots (UR5e, FR3, iiwa 14):
/// per run a truth drawn from the priors, a session simulated on a random
/// motion within the robot's published limits, calibrated as `robimu
/// calibrate` does (`auto` noise); error/σ of every parameter has mean 0
/// and std 1 when the σ are honest. `runs` runs of `duration` s from
/// `seed`; each parameter's std within `band`, the average NEES within its
/// 95 % interval.
fn robot_monte_carlo(name: &str, runs: usize, duration: f64, seed: u64, band: (f64, f64)) {
    use robimu_workflows::montecarlo::{monte_carlo, MonteCarloOptions};
    let robot = Robot::builtin(name).unwrap();
    let opts = MonteCarloOptions::study(&robot, runs, duration, seed, 1, None, "auto").unwrap();
    let mc = monte_carlo(&robot, &opts, |_, _| {}).unwrap();
    let (lo, hi) = mc.stats.iter().fold((f64::INFINITY, 0.0f64), |(l, h), s| {
        (l.min(s.std), h.max(s.std))
    });
    let worst_mean = mc.stats.iter().map(|s| s.mean.abs()).fold(0.0, f64::max);
    eprintln!(
        "{name}: {runs} runs of {duration} s, {} parameters: std(e/σ) in [{lo:.3}, {hi:.3}], max |mean| {worst_mean:.3}, NEES {:.2} in [{:.2}, {:.2}]",
        mc.dof, mc.nees_mean, mc.nees_interval.0, mc.nees_interval.1
    );
    for s in &mc.stats {
        assert!(
            (band.0..=band.1).contains(&s.std),
            "{name}: {} std(e/σ) = {:.3} outside {band:?}",
            s.name,
            s.std
        );
    }
    assert!(
        (mc.nees_interval.0..=mc.nees_interval.1).contains(&mc.nees_mean),
        "{name}: average NEES {:.2} outside [{:.2}, {:.2}]",
        mc.nees_mean,
        mc.nees_interval.0,
        mc.nees_interval.1
    );
}

/// CI's size: 30 runs of 40 s per robot. With 30 runs a std(e/σ) has a
/// sampling σ of 1/√60 ≈ 0.13, so each parameter is held to [0.5, 1.5]
/// (about 4 of those σ) and the average NEES, over all parameters at
/// once, to its 95 % interval.
#[test]
fn uncertainties_are_honest_on_ur5e_fr3_and_iiwa14() {
    for name in ["ur5e", "fr3", "iiwa14"] {
        robot_monte_carlo(name, 30, 40.0, 1, (0.5, 1.5));
    }
}

/// The figure: 300 runs of 300 s per robot, every parameter's
/// std(e/σ) within [0.85, 1.15] (sampling σ 0.04). About 3 min per robot
/// in release: `cargo test -p robimu --release --test robots -- --ignored
/// --nocapture three_hundred`.
#[test]
#[ignore = "300 runs of 300 s per robot (about 10 min in release)"]
fn three_hundred_runs_per_robot_have_honest_uncertainties() {
    for name in ["ur5e", "fr3", "iiwa14"] {
        robot_monte_carlo(name, 300, 300.0, 1, (0.85, 1.15));
    }
}

/// `export --format urdf` of a calibration of a built-in robot (UR5e, FR3:
/// 6 and 7 joints) writes its plain URDF with the calibrated kinematics: an
/// independent reader (`tests/makers_fk.py --poses`, numpy) gives the
/// calibrated model's flange pose in the maker's base frame to 1e-9 at 50
/// random configurations. The calibration moves every ε by up to 2 prior σ
/// (a few mm and mrad), far above the tolerance.
#[test]
fn a_built_in_robots_calibration_exports_as_a_urdf_with_its_kinematics() {
    use rand::{Rng, SeedableRng};
    use robimu_model::ParamLayout;
    use robimu_session::export::calibrated_params;
    use robimu_session::result::CalibrationResult;
    if !python_has("numpy") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for name in ["ur5e", "fr3"] {
        let robot = Robot::builtin(name).unwrap();
        let layout = ParamLayout::new(&robot);
        let mut rng = rand::rngs::StdRng::seed_from_u64(38);
        let result = dir.path().join(format!("{name}.json"));
        common::write_result_json(&result, name, &layout, |p| {
            p.nominal + p.sigma * rng.random_range(-2.0..2.0)
        });
        let urdf = dir.path().join(format!("{name}.urdf"));
        let run = robimu_ok([
            "export",
            "--calibration",
            s(&result),
            "--format",
            "urdf",
            "--out",
            s(&urdf),
        ]);
        assert!(run.stderr.contains("is not a URDF"), "{}", run.stderr);
        // the calibrated flange (the IMU's ε_n is the imu_link, not the flange)
        let cal = CalibrationResult::read(&result).unwrap();
        let mut eps = calibrated_params(&robot, &cal).unwrap().eps;
        *eps.last_mut().unwrap() = [0.0; 6];
        let frames = robot.description().frames.clone().unwrap();
        let mut csv = String::from("# q, flange position in base, rotation row by row\n");
        for _ in 0..50 {
            let q: Vec<f64> = robot
                .limits()
                .iter()
                .map(|l| rng.random_range(l.q_min..l.q_max))
                .collect();
            let t =
                frames
                    .base_to_model
                    .to_iso()
                    .compose(&forward_kinematics(robot.chain(), &eps, &q));
            csv.push_str(&common::pose_row(&q, &t));
        }
        let poses = dir.path().join(format!("{name}-poses.csv"));
        std::fs::write(&poses, csv).unwrap();
        let out = Command::new("python3")
            .arg(root().join("tests/makers_fk.py"))
            .args([
                "--poses",
                s(&urdf),
                &frames.base,
                &frames.flange,
                s(&poses),
                "1e-9",
            ])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        eprintln!("{text}{}", String::from_utf8_lossy(&out.stderr));
        assert!(
            out.status.success() && text.contains("50 configurations"),
            "{text}"
        );
        // and the nominal's pose differs from it by far more than that
        let q = vec![0.3; robot.dof()];
        let zero = vec![[0.0; 6]; robot.dof()];
        let (a, b) = (
            forward_kinematics(robot.chain(), &zero, &q),
            forward_kinematics(robot.chain(), &eps, &q),
        );
        let moved = (0..3).map(|i| (a.p[i] - b.p[i]).abs()).fold(0.0, f64::max);
        assert!(
            moved > 1e-4,
            "{name}: the calibration moved the flange by {moved} m"
        );
    }
}

/// `export --format ros2-control` of a UR5e calibration: read by an
/// independent reader (`tests/ros2_control_offsets.py`: ElementTree for
/// the transmissions as ros2_control's SimpleTransmission applies them,
/// joint = actuator / reduction + offset; numpy FK of the nominal and the
/// calibrated URDFs) on its own 200 configurations, the offsets bring the
/// nominal flange closer to the calibrated one, the opposite sign takes it
/// further, and both means agree with the export's note to 10 %.
#[test]
fn ros2_control_offsets_do_what_the_export_says() {
    use rand::{Rng, SeedableRng};
    use robimu_model::ParamLayout;
    if !python_has("numpy") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let robot = Robot::builtin("ur5e").unwrap();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(40);
    let result = dir.path().join("ur5e.json");
    common::write_result_json(&result, "ur5e", &layout, |p| {
        p.nominal + p.sigma * rng.random_range(-2.0..2.0)
    });
    let [nominal, calibrated, offsets] =
        ["nominal.urdf", "calibrated.urdf", "offsets.xml"].map(|f| dir.path().join(f));
    robimu_ok(["robots", "show", "ur5e", "--urdf", s(&nominal)]);
    robimu_ok([
        "export",
        "--calibration",
        s(&result),
        "--format",
        "urdf",
        "--out",
        s(&calibrated),
    ]);
    let run = robimu_ok([
        "export",
        "--calibration",
        s(&result),
        "--format",
        "ros2-control",
        "--out",
        s(&offsets),
    ]);
    // the note: "... nominal A mm, ...; with these offsets B mm, ..."
    let number_after = |text: &str, key: &str| -> f64 {
        let rest = &text[text.find(key).unwrap_or_else(|| panic!("{key} in {text}")) + key.len()..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    let said_nominal = number_after(&run.stderr, "limits: nominal ");
    let said_with = number_after(&run.stderr, "with these offsets ");
    let out = Command::new("python3")
        .arg(root().join("tests/ros2_control_offsets.py"))
        .args([s(&nominal), s(&calibrated), s(&offsets), "base", "tool0"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let get = |key: &str| number_after(&text, &format!("{key}="));
    let (none, plus, minus) = (get("nominal"), get("plus"), get("minus"));
    eprintln!("export: {said_nominal} → {said_with} mm; independent: {none} → {plus} mm (opposite sign {minus} mm)");
    assert!(plus < none && plus < minus, "{text}");
    assert!(
        (none / said_nominal - 1.0).abs() < 0.1,
        "{none} vs {said_nominal}"
    );
    assert!(
        (plus / said_with - 1.0).abs() < 0.1,
        "{plus} vs {said_with}"
    );
}
