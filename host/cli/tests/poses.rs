//! `robimu simulate --source poses` and `robimu calibrate` of a session
//! with tool poses (issue 39, docs/model.md §7.9): a simulated session
//! passes the check, calibrates with every parameter within 4σ of its
//! truth and a result file the project's reader reads; bad sessions and
//! flags that do not apply fail with a message naming the cause.

mod common;

use std::path::Path;

use common::{robimu, robimu_ok, s};
use robimu_session::result::{CalibrationResult, Trust};
use robimu_session::Truth;

/// Length of the simulated session, s.
const DURATION: &str = "60";

fn simulate(dir: &Path, seed: &str) {
    let run = robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--duration",
        DURATION,
        "--seed",
        seed,
        "--out",
        s(dir),
    ]);
    assert!(run.stdout.contains("poses"), "{}", run.stdout);
}

/// `a − b`, angles wrapped to (−π, π].
fn difference(a: f64, b: f64, angle: bool) -> f64 {
    let d = a - b;
    if angle {
        let tau = std::f64::consts::TAU;
        d - tau * (d / tau).round()
    } else {
        d
    }
}

#[test]
fn simulated_pose_session_checks_and_calibrates_within_4_sigma() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    simulate(&dir, "5");
    for f in ["session.toml", "poses.csv", "imu.csv", "truth.toml"] {
        assert!(dir.join(f).is_file(), "{f} not written");
    }
    let meta = std::fs::read_to_string(dir.join("session.toml")).unwrap();
    assert!(meta.contains("source = \"poses\""), "{meta}");
    robimu_ok(["check", s(&dir)]);

    let out = tmp.path().join("r.json");
    let run = robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    assert!(run.stdout.contains("trust: "), "{}", run.stdout);
    assert!(
        run.stdout.contains("error/σ"),
        "table with the truth: {}",
        run.stdout
    );

    let result = CalibrationResult::read(&out).unwrap();
    assert_eq!(result.source.as_deref(), Some("poses"));
    assert_eq!(result.robot, None);
    assert_eq!(result.parameters.len(), 30);
    assert_eq!(result.covariance.names.len(), 30);
    let verdict = result.verdict.as_ref().unwrap();
    assert_ne!(verdict.trust, Trust::Bad, "{verdict:?}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(json["source"], "poses");
    assert_eq!(json["parameters"][5]["name"], "tau");

    let truth = Truth::read(&dir.join("truth.toml")).unwrap();
    let mut worst = (0.0f64, String::new());
    let mut zs = Vec::new();
    for p in &result.parameters {
        let t = truth.get(&p.name).unwrap();
        let z = difference(p.value, t, p.unit == "rad") / p.sigma;
        zs.push(format!("{} {z:+.2}", p.name));
        if z.abs() > worst.0 {
            worst = (z.abs(), p.name.clone());
        }
    }
    eprintln!("z = (estimate − truth)/σ: {}", zs.join(", "));
    eprintln!("largest |z| = {:.2} ({})", worst.0, worst.1);
    assert!(
        worst.0 < 4.0,
        "{} is {:.2}σ from its truth",
        worst.1,
        worst.0
    );
}

#[test]
fn a_broken_pose_session_is_refused_with_its_cause() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(
        dir.join("session.toml"),
        "format = \"robimu-session/1\"\nsource = \"poses\"\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("imu.csv"),
        "t,ax,ay,az,gx,gy,gz\n0,0,0,9.81,0,0,0\n0.01,0,0,9.81,0,0,0\n",
    )
    .unwrap();
    // no poses.csv
    let run = robimu(["calibrate", s(dir)]);
    run.assert_fails(&["poses.csv", "missing"]);
    // a NaN in poses.csv
    std::fs::write(
        dir.join("poses.csv"),
        "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n0.1,0,NaN,0,1,0,0,0\n",
    )
    .unwrap();
    let run = robimu(["calibrate", s(dir)]);
    run.assert_fails(&["poses.csv:3", "`py`"]);
    assert!(!dir.join("result.json").exists());
}

#[test]
fn flags_that_do_not_apply_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    let run = robimu([
        "simulate",
        "--source",
        "poses",
        "--robot",
        "aubo_i5",
        "--tracker",
        "--out",
        s(&dir),
    ]);
    run.assert_fails(&["--tracker: not for --source poses"]);
    let run = robimu(["simulate", "--pose-rate", "10", "--out", s(&dir)]);
    run.assert_fails(&["--pose-rate", "--source poses"]);
    let run = robimu(["simulate", "--imu-drift", "0.03", "--out", s(&dir)]);
    run.assert_fails(&["--imu-drift", "--source poses"]);
    let run = robimu([
        "simulate",
        "--source",
        "poses",
        "--imu-jitter=-0.001",
        "--out",
        s(&dir),
    ]);
    run.assert_fails(&["--imu-jitter must be ≥ 0"]);
    assert!(!dir.exists());
    simulate(&dir, "2");
    let run = robimu(["calibrate", s(&dir), "--windows", "3"]);
    run.assert_fails(&["--windows", "does not apply to a pose session"]);
}

/// `--source poses --robot NAME`: the flange on the motion of `simulate
/// --robot NAME` with the same seed, length and rate: the same imu.csv, and
/// the truth's IMU position is the robot truth's ε_n1..3.
#[test]
fn a_robots_flange_session_has_the_joint_sessions_imu_samples() {
    let tmp = tempfile::tempdir().unwrap();
    let (j, p) = (tmp.path().join("j"), tmp.path().join("p"));
    let common = [
        "--robot",
        "ur5e",
        "--duration",
        "8",
        "--rate",
        "50",
        "--seed",
        "9",
    ];
    let mut args = vec!["simulate", "--out", s(&j)];
    args.extend(common);
    robimu_ok(args);
    let mut args = vec!["simulate", "--source", "poses", "--out", s(&p)];
    args.extend(common);
    let run = robimu_ok(args);
    assert!(run.stdout.contains("poses"), "{}", run.stdout);
    let read = |d: &Path| std::fs::read(d.join("imu.csv")).unwrap();
    assert_eq!(read(&j), read(&p), "imu.csv differs");
    let (tj, tp) = (
        Truth::read(&j.join("truth.toml")).unwrap(),
        Truth::read(&p.join("truth.toml")).unwrap(),
    );
    assert_eq!(tp.get("p_imu_y"), tj.get("eps_6_2"));
    assert_eq!(tp.get("tau"), tj.get("tau"));
}

/// `simulate --source poses --effect sensor_delay=5` then `diagnose`: the
/// delay is named in the summary and in diagnosis.json (docs/model.md
/// §7.9); a joint-side candidate is refused with its reason.
#[test]
fn diagnose_names_an_injected_imu_effect_of_a_pose_session() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--duration",
        "30",
        "--effect",
        "sensor_delay=5",
        "--out",
        s(&dir),
    ]);
    let out = tmp.path().join("d");
    let run = robimu_ok(["diagnose", s(&dir), "--out", s(&out)]);
    assert!(run.text().contains("found sensor_delay"), "{}", run.text());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("diagnosis.json")).unwrap())
            .unwrap();
    assert_eq!(json["source"], "poses");
    assert_eq!(json["effects_found"][0]["name"], "sensor_delay");
    let run = robimu(["diagnose", s(&dir), "--candidates", "resonance"]);
    run.assert_fails(&["resonance", "does not apply to a pose session"]);
}
