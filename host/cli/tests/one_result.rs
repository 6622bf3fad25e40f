//! One command, one result a user can trust (docs/model.md §8.6): the
//! default calibration (the paper's model, tested, the effects the data
//! show added) on the twin in virtual time, against its hidden truth.
//!
//! * the realistic twin (elastic joints 2 and 3 at its default compliance,
//!   a 12 Hz mount mode, warm-up, datasheet chip): result.json within 4σ
//!   of the truth for every parameter and the verdict good;
//! * null sessions (the twin's hidden effects off): no effect added besides
//!   the chip's true `sensor_delay`;
//! * elastic joints at harmonic-drive stiffness (2·10⁴–10⁵ N·m/rad on
//!   every joint), 300 s: within 4σ, and a verdict that is never good
//!   while a score test rejects the written model.
//!
//! CI runs a few seeds; the figures run every seed:
//! `cargo test -p robimu --release --test one_result -- --ignored --nocapture`.

use std::path::Path;

use robimu_hil::rig::SimRigConfig;
use robimu_hil::truth_check::{fitted_check, session_truth, ModeShare};
use robimu_hil::twin::{record_offline, TwinOptions};
use robimu_model::Robot;
use robimu_record::motion::Plan;
use robimu_session::result::Trust;
use robimu_session::{files, Truth};
use robimu_workflows::plan::PlanOptions;
use robimu_workflows::{load_session, Fitted, Prepared, Settings};

mod common;

/// What one session's default calibration gave.
#[derive(Debug)]
struct Outcome {
    seed: u64,
    effects: Vec<String>,
    trust: Trust,
    /// The largest |z| against the truth, and its parameter.
    worst: (f64, String),
    /// Whether a score test rejects the written model.
    rejected: bool,
    /// Predicted and actual mean flange position error after, mm.
    pose_mm: (f64, f64),
}

/// The demo's planned excitation of `duration` s.
fn plan(robot: &Robot, seed: u64, duration: f64) -> Plan {
    let opts = PlanOptions {
        duration,
        seed,
        ..PlanOptions::default()
    };
    let planned = robimu_workflows::plan::plan(robot, &opts, |_, _, _| {}).unwrap();
    Plan::from_spline(&planned.spline, 250.0)
}

/// Records `config` on its plan into `dir`, calibrates by default, and
/// compares the result with the truth of the model it wrote.
fn run(mut config: SimRigConfig, seed: u64, duration: f64, dir: &Path) -> Outcome {
    let robot = config.robot.clone();
    let p = plan(&robot, seed, duration);
    config.initial = p.q[0];
    let summary = record_offline(&config, &p, dir, &TwinOptions::default()).unwrap();
    let hidden = Truth::read(&dir.join(files::TRUTH)).unwrap();
    let (session, robot) = load_session(dir).unwrap();
    // ROBIMU_ONE_RESULT_EFFECTS=a,b fixes the effects (`--effects a,b`), to
    // compare a model the selection did not choose with the same truth
    let settings = Settings {
        effects: std::env::var("ROBIMU_ONE_RESULT_EFFECTS")
            .map(|e| e.split(',').map(str::to_string).collect())
            .unwrap_or_default(),
        ..Settings::default()
    };
    let prepared = Prepared::new(session, robot.clone(), &settings, None, |_| {}).unwrap();
    let fitted: Fitted = prepared.fit(|_| {}).unwrap();
    let mode = ModeShare::of(&config, dir).unwrap();
    let truth_for = |effects: &[String], share: Option<&[(String, f64)]>| {
        session_truth(
            &config,
            &hidden,
            dir,
            summary.powered_for_s,
            summary.imu_time_error_s,
            effects,
            share,
        )
        .unwrap()
    };
    let rows = fitted_check(&robot, &fitted, mode.as_ref(), |e, share| {
        Ok(truth_for(e, share))
    })
    .unwrap()
    .rows;
    if let Ok(spec) = std::env::var("ROBIMU_ONE_RESULT_SANDWICH") {
        sandwich_study(&spec, &robot, &prepared, &fitted, &rows);
    }
    let worst = rows
        .iter()
        .map(|r| (r.z().abs(), r.name.clone()))
        .fold((0.0, String::new()), |a, b| if b.0 > a.0 { b } else { a });
    let result = &fitted.result;
    let pose = result.pose_accuracy.as_ref().unwrap();
    let outcome = Outcome {
        seed,
        effects: result
            .effects
            .as_ref()
            .unwrap()
            .iter()
            .map(|e| e.name.clone())
            .collect(),
        trust: result.verdict.as_ref().unwrap().trust,
        worst,
        rejected: !result.model_tests.as_ref().unwrap().significant.is_empty(),
        pose_mm: (
            pose.after.position_mean_mm,
            pose.actual_after.unwrap().stats.position_mean_mm,
        ),
    };
    eprintln!("{outcome:?}");
    outcome
}

/// ROBIMU_ONE_RESULT_SANDWICH=W:L,… prints, per window W s and lags L,
/// the sandwich σ of the written fit against the truth (the worst rows).
fn sandwich_study(
    spec: &str,
    robot: &Robot,
    prepared: &Prepared,
    fitted: &Fitted,
    rows: &[robimu_session::TruthRow],
) {
    use robimu_workflows::calibrate::sandwich_fit::{fit_sandwich, FitSandwich};
    let setup = fitted
        .selection
        .as_ref()
        .map_or(&prepared.setup, |d| &d.setup);
    let set = robimu_workflows::diagnose::effect_set(setup, &fitted.fit.effects).unwrap();
    let layout = robimu_model::ParamLayout::new(robot);
    let mut worst: Vec<&robimu_session::TruthRow> = rows.iter().collect();
    worst.sort_by(|a, b| b.z().abs().total_cmp(&a.z().abs()));
    for wl in spec.split(',') {
        let (w, l) = wl.split_once(':').unwrap();
        let (w, l): (f64, usize) = (w.parse().unwrap(), l.parse().unwrap());
        let t = std::time::Instant::now();
        let sw: FitSandwich = fit_sandwich(
            robot,
            &prepared.data,
            &prepared.opts,
            &set,
            &fitted.fit,
            w,
            l,
        )
        .unwrap();
        let mut zmax = (0.0f64, String::new());
        let mut line = String::new();
        for (i, r) in worst.iter().enumerate() {
            let Some(k) = layout.specs().iter().position(|s| s.name == r.name) else {
                continue;
            };
            let z = (r.estimate - r.truth) / sw.sigma[k];
            if z.abs() > zmax.0 {
                zmax = (z.abs(), r.name.clone());
            }
            if i < 5 {
                line += &format!(
                    " {} z {:.2} σ×{:.2} →{:.2};",
                    r.name,
                    r.z(),
                    sw.sigma[k] / r.sigma,
                    z
                );
            }
        }
        eprintln!(
            "sandwich W {w} s L {l} ({:.1} s): worst |z| {:.2} {};{line}",
            t.elapsed().as_secs_f64(),
            zmax.0,
            zmax.1
        );
    }
}

/// Sessions of `config(seed)` for `seeds`, `duration` s each; prints the
/// predicted and actual mean flange position error after calibration.
fn study(
    seeds: std::ops::RangeInclusive<u64>,
    duration: f64,
    config: impl Fn(u64) -> SimRigConfig,
) -> Vec<Outcome> {
    // ROBIMU_ONE_RESULT_KEEP=DIR keeps each session in DIR/<duration>-<seed>
    let keep = std::env::var_os("ROBIMU_ONE_RESULT_KEEP");
    // ROBIMU_ONE_RESULT_SEED=N runs seed N alone (to look at one session)
    let only: Option<u64> = std::env::var("ROBIMU_ONE_RESULT_SEED")
        .ok()
        .and_then(|s| s.parse().ok());
    let out: Vec<Outcome> = seeds
        .filter(|s| only.is_none_or(|o| o == *s))
        .map(|seed| {
            let tmp = tempfile::tempdir().unwrap();
            let dir = match &keep {
                Some(k) => Path::new(k).join(format!("{duration}-{seed}")),
                None => tmp.path().to_path_buf(),
            };
            run(config(seed), seed, duration, &dir)
        })
        .collect();
    let n = out.len().max(1) as f64;
    let predicted = out.iter().map(|o| o.pose_mm.0).sum::<f64>() / n;
    let actual = out.iter().map(|o| o.pose_mm.1).sum::<f64>() / n;
    let seeds: Vec<u64> = out.iter().map(|o| o.seed).collect();
    eprintln!(
        "seeds {seeds:?}: flange position error after, mean {predicted:.3} mm predicted, {actual:.3} mm actual"
    );
    out
}

/// The realistic twin: within 4σ and good in all but `allowed` sessions.
fn realistic(seeds: u64, allowed: usize) {
    let robot = Robot::aubo_i5();
    let out = study(1..=seeds, 60.0, |s| {
        SimRigConfig::realistic(robot.clone(), s).unwrap()
    });
    let beyond = out.iter().filter(|o| o.worst.0 > 4.0).count();
    let not_good = out.iter().filter(|o| o.trust != Trust::Good).count();
    eprintln!("realistic twin, {seeds} × 60 s: beyond 4σ in {beyond}, not good in {not_good}");
    assert!(beyond <= allowed, "{out:#?}");
    assert!(not_good <= allowed, "{out:#?}");
    for o in &out {
        assert!(o.effects.iter().any(|e| e == "joint_elasticity"), "{o:?}");
        assert!(!(o.rejected && o.trust == Trust::Good), "{o:?}");
    }
}

/// Null sessions: no effect but the chip's `sensor_delay` added in all but
/// `allowed`.
fn null(seeds: u64, allowed: usize) {
    let robot = Robot::aubo_i5();
    let out = study(1..=seeds, 60.0, |s| {
        SimRigConfig::realistic_null(robot.clone(), s).unwrap()
    });
    let alarms: Vec<&Outcome> = out
        .iter()
        .filter(|o| o.effects.iter().any(|e| e != "sensor_delay"))
        .collect();
    eprintln!(
        "null twin, {seeds} × 60 s: false alarms in {}",
        alarms.len()
    );
    assert!(alarms.len() <= allowed, "{alarms:#?}");
}

/// Every joint at stiffness k (N·m/rad): the seeds spread k over 2·10⁴–10⁵.
fn elastic_config(robot: &Robot, seed: u64, seeds: u64) -> SimRigConfig {
    let mut config = SimRigConfig::realistic(robot.clone(), seed).unwrap();
    let k = 2e4 * 5f64.powf((seed - 1) as f64 / (seeds.max(2) - 1) as f64);
    let arm = config.arm_physics.as_mut().unwrap();
    let e = arm.elasticity.as_mut().unwrap();
    e.compliance = vec![1.0 / k; robot.dof()];
    config
}

/// Elastic joints at harmonic-drive stiffness, 300 s: within 4σ in all but
/// `allowed`, and never good while the model is rejected.
fn elastic(seeds: u64, allowed: usize) {
    let robot = Robot::aubo_i5();
    let out = study(1..=seeds, 300.0, |s| elastic_config(&robot, s, seeds));
    let beyond = out.iter().filter(|o| o.worst.0 > 4.0).count();
    eprintln!("elastic joints, {seeds} × 300 s: beyond 4σ in {beyond}");
    // the verdict: never good while a score test rejects the written
    // model, nor for a result beyond 4σ (the structure check, §8.5)
    for o in &out {
        assert!(!(o.rejected && o.trust == Trust::Good), "{o:?}");
        assert!(!(o.worst.0 > 4.0 && o.trust == Trust::Good), "{o:?}");
    }
    assert!(beyond <= allowed, "{out:#?}");
}

/// Where the tests find nothing the default result is the paper's, bit
/// for bit: `--model paper` and the default give the same parameters and
/// covariance (the default with `effects: []`, `--model paper` without the
/// key), and both equal the library's paper calibration.
#[test]
fn the_paper_model_is_unchanged_and_the_default_keeps_it_when_nothing_is_missing() {
    use robimu_workflows::calibrate::noise_choice::{calibrate_with_noise, NoiseChoice};
    use robimu_workflows::calibrate::CalibrateOptions;
    let tmp = tempfile::tempdir().unwrap();
    let s = tmp.path().join("s");
    let sd = s.to_str().unwrap();
    common::robimu_ok(["simulate", "--duration", "40", "--seed", "5", "--out", sd]);
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join(name)).unwrap()).unwrap()
    };
    let out = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    common::robimu_ok([
        "calibrate",
        sd,
        "--out",
        &out("paper.json"),
        "--model",
        "paper",
    ]);
    common::robimu_ok(["calibrate", sd, "--out", &out("default.json")]);
    let (paper, default) = (read("paper.json"), read("default.json"));
    assert_eq!(paper["parameters"], default["parameters"]);
    assert_eq!(paper["covariance"], default["covariance"]);
    assert!(paper.get("effects").is_none());
    assert_eq!(default["effects"], serde_json::json!([]));
    assert_eq!(
        default["model_tests"]["significant"],
        serde_json::Value::Null
    );
    // the library's paper calibration, independently of the pipeline
    let (session, robot) = load_session(&s).unwrap();
    let mut opts = CalibrateOptions::new(&robot);
    (opts.sigma_z, opts.sigma_q) = session.noise(&robot).unwrap();
    let data = session.measurements();
    let (cal, _) = calibrate_with_noise(&robot, &data, &opts, &NoiseChoice::Auto, |_| {}).unwrap();
    let values: Vec<f64> = paper["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["value"].as_f64().unwrap())
        .collect();
    let settings = Settings {
        model: robimu_workflows::ModelChoice::Paper,
        ..Settings::default()
    };
    let (session2, robot2) = load_session(&s).unwrap();
    let prepared = Prepared::new(session2, robot2, &settings, None, |_| {}).unwrap();
    let fitted = prepared.fit(|_| {}).unwrap();
    assert_eq!(
        fitted.cal.x, cal.x,
        "the pipeline's --model paper, bit for bit"
    );
    // (result.json read back exactly: serde_json's float_roundtrip)
    assert_eq!(values, cal.x, "bit for bit");
}

#[test]
fn default_calibrate_on_the_realistic_twin_is_within_4_sigma_and_good() {
    realistic(2, 0);
}

#[test]
fn default_calibrate_adds_nothing_on_null_sessions() {
    null(2, 0);
}

#[test]
fn default_calibrate_on_stiff_elastic_joints_is_within_4_sigma() {
    elastic(1, 0);
}

#[test]
#[ignore = "20 realistic sessions of 60 s (the issue's figure; about 2 min in release)"]
fn twenty_realistic_sessions() {
    realistic(20, 1);
}

#[test]
#[ignore = "20 null sessions of 60 s (the issue's figure)"]
fn twenty_null_sessions() {
    null(20, 1);
}

#[test]
#[ignore = "10 elastic sessions of 300 s (the issue's figure)"]
fn ten_elastic_sessions() {
    elastic(10, 0);
}
