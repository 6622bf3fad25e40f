//! A pose session with two IMUs on the body (docs/model.md §7.9, §9):
//! `robimu simulate --source poses --imus 2` writes imu1.csv and a truth of
//! 58 names; `robimu calibrate` estimates all 58 (IMU 1's as `imu1/…`, g
//! shared) within 4σ of the truth (60 s: at 40 s, seed 5, IMU 0's
//! gamma_a_zx is 4.0σ off even when IMU 0 is calibrated alone).

mod common;

use common::{robimu_ok, s};
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
    assert!(
        worst.0 < 4.0,
        "{} is {:.2}σ from its truth",
        worst.1,
        worst.0
    );
}
