//! A bias random walk (the warm-up drift of a real IMU) hidden in a
//! simulated session: diagnose names `bias_drift` with a resolution chosen
//! from the data, adds no other effect, and the final model's baseline
//! parameters are back at the truth (issue 15's must-show).

use robimu_model::{ParamLayout, Robot};
use robimu_workflows::simulate::{add_bias_walk, random_session, simulate, SimulateOptions};

/// Session length, s.
const DURATION: f64 = 300.0;

/// The walk's scale in multiples of the paper's observed drift.
const SCALE: f64 = 20.0;

/// One session of `DURATION` s (truth from the priors, τ = 0.05 s, white
/// noise) with the bias walk added; diagnosed with the defaults. Returns
/// a line of statistics.
fn diagnosed_walk(seed: u64) -> String {
    let started = std::time::Instant::now();
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let opts = SimulateOptions::paper(&robot);
    let mut s = random_session(&robot, DURATION, 1.0, &opts, seed).unwrap();
    s.truth[layout.offsets().tau] = 0.05;
    let mut data = simulate(&robot, &layout, &s.truth, &s.trajectory, &opts, seed).unwrap();
    add_bias_walk(&mut data, SCALE, seed);
    let (_, d) = common::diagnose_all(&robot, &data);
    let names: Vec<&str> = d.found.iter().map(|f| f.name.as_str()).collect();
    let f = d.found.first().expect("an effect is found");
    let res = f
        .resolution
        .as_ref()
        .expect("bias_drift's resolution is chosen");
    let mut worst: (f64, &str) = (0.0, "");
    for (k, spec) in layout.specs().iter().enumerate() {
        if d.final_fit.sigma_x[k] > 0.0 {
            let z = ((d.final_fit.x[k] - s.truth[k]) / d.final_fit.sigma_x[k]).abs();
            if z > worst.0 {
                worst = (z, &spec.name);
            }
        }
    }
    let line = format!(
        "seed {seed}: found {names:?}; bias_drift score {:.0} ({} dof), M = {} of at most {} ({:?}); \
         next round {:?}; worst baseline parameter {} at {:.2} σ; final rms {:.3?}; noise identified {}; {:.0} s",
        f.statistic,
        f.dof,
        res.chosen,
        res.max,
        res.candidates.iter().map(|c| (c.resolution, c.statistic.round(), c.aic.round())).collect::<Vec<_>>(),
        d.found.get(1).map(|g| &g.scores).unwrap_or(&d.last_scores).iter().take(3).map(|s| (s.name.as_str(), s.statistic.round(), s.p_value)).collect::<Vec<_>>(),
        worst.1,
        worst.0,
        d.final_fit.residual_rms(),
        d.noise.identified,
        started.elapsed().as_secs_f64()
    );
    println!("{line}");
    assert_eq!(names, ["bias_drift"], "{line}");
    assert!(res.chosen > 1, "a random walk is not a line: {line}");
    assert!(worst.0 < 4.0, "{line}");
    line
}

/// Three seeds, each its own test so that they run in parallel (about
/// 60 s each alone).
#[test]
fn a_bias_random_walk_is_named_bias_drift_alone_and_the_baseline_is_restored() {
    diagnosed_walk(41);
}

#[test]
fn a_second_bias_random_walk_is_named_bias_drift_alone_and_the_baseline_is_restored() {
    diagnosed_walk(42);
}

#[test]
fn a_third_bias_random_walk_is_named_bias_drift_alone_and_the_baseline_is_restored() {
    diagnosed_walk(43);
}

mod common;
use common::{robimu, robimu_ok, s};

/// `simulate --bias-walk` adds exactly the library's walk (same seed) to
/// the IMU samples and records it; `calibrate --effects bias_drift:M` fits
/// the spline with M segments (6M parameters in effects.json); bad values
/// of either end with an error naming the cause.
#[test]
fn the_bias_walk_and_the_resolution_go_through_the_command_line() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = |name: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        let mut args = vec![
            "simulate",
            "--duration",
            "30",
            "--seed",
            "3",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        robimu_ok(&args);
        out
    };
    let plain = sim("plain", &[]);
    let walked = sim("walked", &["--bias-walk", "20"]);
    let load = |d: &std::path::Path| robimu_session::Session::load(d).unwrap();
    let (a, b) = (load(&plain), load(&walked));
    assert!(b
        .meta
        .notes
        .as_deref()
        .unwrap_or("")
        .contains("bias random walk 20x"));
    let (da, db) = (a.measurements(), b.measurements());
    assert_eq!(da.imu_t, db.imu_t);
    let walk = robimu_workflows::simulate::bias_walk(&da.imu_t, 20.0, 3);
    let mut largest: f64 = 0.0;
    for ((za, zb), w) in da.imu_z.iter().zip(&db.imu_z).zip(&walk) {
        for c in 0..6 {
            assert!(
                (zb[c] - za[c] - w[c]).abs() < 1e-9,
                "{} vs {}",
                zb[c] - za[c],
                w[c]
            );
            largest = largest.max(w[c].abs());
        }
    }
    assert!(largest > 1e-3, "the walk is there: {largest}");
    robimu(&[
        "simulate",
        "--bias-walk=-1",
        "--out",
        s(&tmp.path().join("x")),
    ])
    .assert_fails(&["--bias-walk", "non-negative"]);

    let result = tmp.path().join("cal.json");
    robimu_ok(&[
        "calibrate",
        s(&walked),
        "--out",
        s(&result),
        "--effects",
        "bias_drift:4",
    ]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("effects.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = json["effect_parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(names.len(), 24, "{names:?}");
    assert!(names.contains(&"bias_drift.gz_k4"), "{names:?}");
    for (bad, says) in [
        ("bias_drift:0", "from 1 to 64"),
        ("clock_drift:2", "has no resolution"),
    ] {
        robimu(&[
            "calibrate",
            s(&walked),
            "--out",
            s(&result),
            "--effects",
            bad,
        ])
        .assert_fails(&["--effects", says]);
    }
}
