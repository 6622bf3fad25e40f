//! A pose session with two IMUs on the body (docs/model.md §7.9, §9):
//! `robimu simulate --source poses --imus 2` writes imu1.csv and a truth of
//! 58 names; `robimu calibrate` estimates all 58 (IMU 1's as `imu1/…`, g
//! shared) within 4σ of the truth (60 s: at 40 s, seed 5, IMU 0's
//! gamma_a_zx is 4.0σ off even when IMU 0 is calibrated alone).

mod common;

use common::{robimu, robimu_ok, s};
use robimu_session::result::{CalibrationResult, Trust};
use robimu_session::Truth;

#[test]
fn two_imus_simulate_and_calibrate_within_4_sigma() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    let run = robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--imus",
        "2",
        "--duration",
        "60",
        "--seed",
        "5",
        "--out",
        s(&dir),
    ]);
    assert!(run.stdout.contains("2 IMUs"), "{}", run.stdout);
    for f in ["imu.csv", "imu1.csv", "truth.toml"] {
        assert!(dir.join(f).is_file(), "{f} not written");
    }
    assert!(!dir.join("imu2.csv").exists());
    let out = tmp.path().join("r.json");
    let run = robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    assert!(
        run.stdout.contains("estimating 58 parameters"),
        "{}",
        run.stdout
    );
    let result = CalibrationResult::read(&out).unwrap();
    assert_eq!(result.parameters.len(), 58);
    assert_eq!(result.covariance.names.len(), 58);
    assert_eq!(result.parameters[30].name, "imu1/p_imu_x");
    assert!(result.parameter("imu1/tau").is_some());
    assert!(result.parameter("imu1/g_x").is_none());
    let verdict = result.verdict.as_ref().unwrap();
    assert_ne!(verdict.trust, Trust::Bad, "{verdict:?}");
    let offsets = verdict.checks.iter().filter(|c| c.topic == "time offset");
    assert_eq!(offsets.count(), 2, "a τ test per IMU: {verdict:?}");
    let residuals = verdict
        .checks
        .iter()
        .find(|c| c.topic == "residuals")
        .unwrap();
    assert!(residuals.text.contains("imu1/gz"), "{}", residuals.text);

    let truth = Truth::read(&dir.join("truth.toml")).unwrap();
    let tau = std::f64::consts::TAU;
    let mut worst = (0.0f64, String::new());
    for p in &result.parameters {
        let mut d = p.value - truth.get(&p.name).unwrap();
        if p.unit == "rad" {
            d -= tau * (d / tau).round();
        }
        let z = d / p.sigma;
        if z.abs() > worst.0 {
            worst = (z.abs(), p.name.clone());
        }
    }
    exports_take_one_imu_at_a_time(tmp.path(), &out, &result);
    assert!(
        worst.0 < 4.0,
        "{} is {:.2}σ from its truth",
        worst.1,
        worst.0
    );
}

/// Kalibr's imu.yaml and the correction file of a two-IMU pose result: one
/// IMU per file (`--imu J`; without it an error naming the IMUs), IMU 1's
/// from its `imu1/` parameters; `correct` of imu1.csv uses IMU 1's.
fn exports_take_one_imu_at_a_time(
    tmp: &std::path::Path,
    out: &std::path::Path,
    r: &CalibrationResult,
) {
    let yaml = tmp.join("imu.yaml");
    let args = |extra: &[&str]| {
        let mut a = vec![
            "export",
            "--calibration",
            s(out),
            "--format",
            "kalibr",
            "--out",
            s(&yaml),
        ];
        a.extend_from_slice(extra);
        a.iter().map(|v| v.to_string()).collect::<Vec<String>>()
    };
    robimu(args(&[])).assert_fails(&["the result has 2 IMUs", "--imu J"]);
    robimu_ok(args(&["--imu", "1"]));
    let text = std::fs::read_to_string(&yaml).unwrap();
    assert!(text.contains("imu0:"), "{text}");
    let corr = tmp.join("c.toml");
    robimu_ok([
        "export",
        "--calibration",
        s(out),
        "--format",
        "correction",
        "--imu",
        "1",
        "--out",
        s(&corr),
    ]);
    let c = std::fs::read_to_string(&corr).unwrap();
    // IMU 1's accelerometer bias, not IMU 0's
    let b1 = r.parameter("imu1/b_a_x").unwrap().value;
    let b0 = r.parameter("b_a_x").unwrap().value;
    assert!(
        c.contains(&format!("{b1}")) && !c.contains(&format!("{b0}")),
        "{c}"
    );
    let session = tmp.join("s");
    let corrected = tmp.join("imu1_corrected.csv");
    robimu_ok([
        "correct",
        "--calibration",
        s(out),
        s(&session.join("imu1.csv")),
        "--out",
        s(&corrected),
    ]);
    assert!(corrected.is_file());
}
