//! The diagnosis of a session with two IMUs (docs/model.md §9, §4.9): a
//! per-sensor effect is a candidate once per IMU (`imu1/g_sensitivity`),
//! a shared effect once, Bonferroni over all of them. g_sensitivity on IMU
//! 1 only is found as IMU 1's (not IMU 0's), a joint elasticity (the
//! robot's) once as shared, a null session gives nothing; `calibrate --effects` and
//! `diagnose` take the `imu<j>/` names on the command line.

use robimu_model::effects::{self, Effect};
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_workflows::diagnose::{
    effect_imu, inject_effects_on, setup_for, AddedParameter, Diagnosis,
};
use robimu_workflows::simulate::{random_session_imus, simulate, SimulateOptions};

mod common;
use common::{diagnose_all, robimu, robimu_ok, s};

/// Session length, s (that of host/cli/tests/diagnose.rs).
const DURATION: f64 = 90.0;

/// A two-IMU session (truths from the priors, τ 0.05 s and 0.03 s so that
/// the whole session overlaps) with `effect = magnitude` injected in its
/// exact form on IMU `imu` (`None`: on both, a shared effect); the truth and
/// the injected θ_e.
fn two_imu_session(
    seed: u64,
    effect: Option<(&str, f64, Option<usize>)>,
) -> (Robot, Measurements, Vec<f64>, Vec<f64>) {
    let robot = Robot::aubo_i5();
    let opts = SimulateOptions::paper(&robot);
    let mut s = random_session_imus(&robot, 2, DURATION, 1.0, &opts, seed).unwrap();
    let layout = ParamLayout::with_imus(&robot, 2);
    s.truth[layout.imu_index(0, "tau").unwrap()] = 0.05;
    s.truth[layout.imu_index(1, "tau").unwrap()] = 0.03;
    s.data = simulate(&robot, &layout, &s.truth, &s.trajectory, &opts, seed).unwrap();
    let mut theta = Vec::new();
    if let Some((name, m, imu)) = effect {
        let setup = setup_for(&robot, &s.data, None);
        let e = effects::by_name(&setup, name).unwrap();
        theta = e.injection(m);
        let injected: Vec<(Box<dyn Effect>, Vec<f64>)> = vec![(e, theta.clone())];
        inject_effects_on(&robot, &s.truth, &s.trajectory, &mut s.data, imu, &injected).unwrap();
    }
    (robot, s.data, s.truth, theta)
}

/// The candidates of a two-IMU session without temperature: the five
/// per-sensor effects twice, the three shared ones once (13), and the
/// Bonferroni level over them.
fn check_candidates(d: &Diagnosis) {
    let c = d.setup.candidates();
    assert_eq!(c.len(), 13, "{c:?}");
    for name in [
        "g_sensitivity",
        "imu1/g_sensitivity",
        "imu1/bias_drift",
        "encoder_scale",
    ] {
        assert!(c.iter().any(|n| n == name), "{name} missing from {c:?}");
    }
    assert!(!c.iter().any(|n| n == "imu1/encoder_scale"), "{c:?}");
    assert!((d.threshold - 0.01 / 13.0).abs() < 1e-15, "{}", d.threshold);
}

/// Each estimate within 4σ of the injected value.
fn check_estimates(name: &str, parameters: &[AddedParameter], injected: &[f64]) {
    assert_eq!(parameters.len(), injected.len(), "{name}");
    for (p, truth) in parameters.iter().zip(injected) {
        let (pname, v, s) = (&p.name, &p.value, &p.sigma);
        let z = (v - truth) / s;
        assert!(
            z.abs() < 4.0,
            "{name} {pname}: {v} ± {s} vs injected {truth}"
        );
    }
}

/// g_sensitivity (0.1, as in diagnose.rs) on IMU 1 only: `imu1/g_sensitivity`
/// is found, first and alone, estimated within 4σ, and IMU 0's
/// g_sensitivity is not found and not significant in the last round.
#[test]
fn g_sensitivity_on_imu_1_is_found_as_imu_1s() {
    let (robot, data, _, injected) = two_imu_session(12, Some(("g_sensitivity", 0.1, Some(1))));
    let (_, d) = diagnose_all(&robot, &data);
    check_candidates(&d);
    let names: Vec<&str> = d.found.iter().map(|f| f.name.as_str()).collect();
    println!(
        "found {names:?}; scores {:?}",
        d.found.first().map(|f| &f.scores)
    );
    assert_eq!(
        names,
        ["imu1/g_sensitivity"],
        "last scores {:?}",
        d.last_scores
    );
    let f = &d.found[0];
    assert_eq!(f.imu, Some(1));
    assert!(f.p_value < d.threshold);
    assert!(
        f.parameters[0].name.starts_with("imu1/g_sensitivity."),
        "{:?}",
        f.parameters
    );
    check_estimates(&f.name, &f.parameters, &injected);
    let imu0 = d
        .last_scores
        .iter()
        .find(|s| s.name == "g_sensitivity")
        .unwrap();
    assert!(imu0.p_value >= d.threshold, "{imu0:?}");
    // diagnosis.json names the IMU of the finding
    let json = d.to_json(&ParamLayout::with_imus(&robot, 2));
    assert_eq!(json["effects_found"][0]["name"], "imu1/g_sensitivity");
    assert_eq!(json["effects_found"][0]["imu"], 1);
    assert_eq!(
        json["final_model"]["effect_parameters"][0]["name"],
        "imu1/g_sensitivity.gx_sx"
    );
    assert_eq!(
        json["final_model"]["parameters"].as_array().unwrap().len(),
        76
    );
}

/// Joint elasticity (5, as in diagnose.rs) seen by both IMUs: found once,
/// as the shared `joint_elasticity` (no IMU), estimated within 4σ.
#[test]
fn joint_elasticity_is_found_once_as_shared() {
    let (robot, data, _, injected) = two_imu_session(15, Some(("joint_elasticity", 5.0, None)));
    let (_, d) = diagnose_all(&robot, &data);
    check_candidates(&d);
    let names: Vec<&str> = d.found.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(
        names,
        ["joint_elasticity"],
        "last scores {:?}",
        d.last_scores
    );
    assert_eq!(d.found[0].imu, None);
    assert_eq!(effect_imu("joint_elasticity"), None);
    check_estimates("joint_elasticity", &d.found[0].parameters, &injected);
    println!("joint_elasticity: score {:.1}", d.found[0].statistic);
}

/// A two-IMU session without effects: nothing is found.
#[test]
fn null_two_imu_session_finds_nothing() {
    let (robot, data, _, _) = two_imu_session(21, None);
    let (_, d) = diagnose_all(&robot, &data);
    check_candidates(&d);
    assert!(
        d.found.is_empty(),
        "found {:?}",
        d.found.iter().map(|f| &f.name).collect::<Vec<_>>()
    );
    assert_eq!(d.last_scores.len(), 13);
}

/// The command line on a `simulate --imus 2` session: `calibrate --effects`
/// fits IMU 1's g_sensitivity and the shared encoder scale (effects.json
/// names them), refuses a shared effect with an IMU prefix and an IMU the
/// session lacks, naming why; `diagnose --candidates imu1/g_sensitivity`
/// offers that one candidate (threshold α/1) and writes diagnosis.json.
#[test]
fn calibrate_effects_and_diagnose_take_imu_names() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("two");
    robimu_ok([
        "simulate",
        "--imus",
        "2",
        "--duration",
        "40",
        "--seed",
        "5",
        "--out",
        s(&dir),
    ]);
    let out = tmp.path().join("result.json");
    robimu_ok([
        "calibrate",
        s(&dir),
        "--effects",
        "imu1/g_sensitivity,encoder_scale",
        "--out",
        s(&out),
    ]);
    let text = std::fs::read_to_string(tmp.path().join("effects.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        json["effects"],
        serde_json::json!(["imu1/g_sensitivity", "encoder_scale"])
    );
    let names: Vec<&str> = json["effect_parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(names.len(), 9 + 6);
    assert_eq!(names[0], "imu1/g_sensitivity.gx_sx");
    assert_eq!(names[9], "encoder_scale.kappa_1");
    assert_eq!(json["parameters"].as_array().unwrap().len(), 76);
    robimu([
        "calibrate",
        s(&dir),
        "--effects",
        "imu1/encoder_scale",
        "--out",
        s(&out),
    ])
    .assert_fails(&["imu1/encoder_scale", "shared by every IMU"]);
    robimu([
        "calibrate",
        s(&dir),
        "--effects",
        "imu2/g_sensitivity",
        "--out",
        s(&out),
    ])
    .assert_fails(&["imu2/g_sensitivity", "no IMU 2"]);
    let ddir = tmp.path().join("diag");
    let run = robimu_ok([
        "diagnose",
        s(&dir),
        "--candidates",
        "imu1/g_sensitivity",
        "--noise-model",
        "white",
        "--out",
        s(&ddir),
    ]);
    let text = std::fs::read_to_string(ddir.join("diagnosis.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["threshold"], 0.01, "{}", run.stdout);
    assert_eq!(json["last_scores"][0]["name"], "imu1/g_sensitivity");
    assert_eq!(json["effects_found"], serde_json::json!([]));
}
