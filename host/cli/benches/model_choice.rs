//! What choosing the model costs (docs/model.md §8.6), the way a user runs
//! it: `robimu calibrate DIR` (the paper's model, tested, the effects the
//! data show added) against `robimu calibrate DIR --model paper`, whole
//! process, on a session where the tests do find effects: 300 s of the
//! realistic twin in virtual time (datasheet chip, vibration noise,
//! warm-up, 12 Hz mount mode) with every joint elastic at 3·10⁴ N·m/rad,
//! a harmonic drive's stiffness. The two run interleaved (the paper's
//! first on even runs), and the bench prints each one's median and min
//! wall time, CPU and peak memory (GNU time), the ratio of the medians and
//! the run-by-run ratios, and the effects the default run added.
//!
//! `cargo bench -p robimu --bench model_choice [-- --runs 7 --stiffness 3e4 --duration 300 --keep DIR]`

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

use robimu_hil::rig::SimRigConfig;
use robimu_hil::twin::{record_offline, TwinOptions};
use robimu_model::Robot;
use robimu_record::motion::Plan;
use robimu_workflows::plan::PlanOptions;

mod process;
use process::{gnu_time, load};

/// The twin's session: `duration` s, every joint at `stiffness` N·m/rad.
fn record(dir: &Path, duration: f64, stiffness: f64) {
    let robot = Robot::aubo_i5();
    let opts = PlanOptions {
        duration,
        seed: 1,
        ..PlanOptions::default()
    };
    let planned = robimu_workflows::plan::plan(&robot, &opts, |_, _, _| {}).expect("plan");
    let plan = Plan::from_spline(&planned.spline, 250.0);
    let mut config = SimRigConfig::realistic(robot.clone(), 1).expect("the realistic twin");
    config.initial = plan.q[0];
    if let Some(e) = config
        .arm_physics
        .as_mut()
        .and_then(|a| a.elasticity.as_mut())
    {
        e.compliance = vec![1.0 / stiffness; robot.dof()];
    }
    record_offline(&config, &plan, dir, &TwinOptions::default()).expect("record the twin");
}

/// One `robimu calibrate DIR --out OUT [extra]`: wall s, and (user + sys s,
/// peak RSS MB) under GNU time.
fn run(bin: &Path, dir: &Path, extra: &[&str], tag: &str) -> (f64, Option<(f64, f64)>) {
    let out = dir.join(format!("bench-{tag}.json"));
    let report = dir.join(format!("time-{tag}.txt"));
    let mut cmd = match gnu_time() {
        Some(t) => {
            let mut c = Command::new(t);
            c.arg("-o").arg(&report).args(["-f", "%U %S %M"]).arg(bin);
            c
        }
        None => Command::new(bin),
    };
    cmd.arg("calibrate")
        .arg(dir)
        .arg("--out")
        .arg(&out)
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    let start = Instant::now();
    let status = cmd.status().expect("run robimu calibrate");
    let wall = start.elapsed().as_secs_f64();
    assert!(status.success(), "robimu calibrate {extra:?} failed");
    let cpu = gnu_time().and_then(|_| {
        let s = std::fs::read_to_string(&report).ok()?;
        let v: Vec<f64> = s
            .lines()
            .last()?
            .split_whitespace()
            .map(|w| w.parse().ok())
            .collect::<Option<_>>()?;
        (v.len() == 3).then(|| (v[0] + v[1], v[2] / 1024.0))
    });
    (wall, cpu)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn summary(label: &str, runs: &[(f64, Option<(f64, f64)>)]) -> f64 {
    let walls: Vec<f64> = runs.iter().map(|r| r.0).collect();
    let med = median(walls.clone());
    let min = walls.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut line = format!("{label}: wall median {med:.3} s, min {min:.3} s");
    if runs.iter().all(|r| r.1.is_some()) {
        let cpu = median(runs.iter().map(|r| r.1.unwrap().0).collect());
        let peak = runs.iter().map(|r| r.1.unwrap().1).fold(0.0, f64::max);
        line += &format!("; CPU median {cpu:.2} s; peak RSS {peak:.0} MB");
    }
    println!("{line}");
    med
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
    };
    let runs: usize = value("--runs").map_or(7, |v| v.parse().expect("--runs N"));
    let stiffness: f64 = value("--stiffness").map_or(3e4, |v| v.parse().expect("--stiffness K"));
    let duration: f64 = value("--duration").map_or(300.0, |v| v.parse().expect("--duration S"));
    assert!(runs > 0, "--runs must be at least 1");
    let bin = Path::new(env!("CARGO_BIN_EXE_robimu"));
    let work = tempfile::tempdir().expect("temporary directory");
    // --keep DIR: record the session there and leave it (to look into)
    let dir = value("--keep").map_or_else(|| work.path().join("session"), |d| d.into());
    let t0 = Instant::now();
    record(&dir, duration, stiffness);
    println!(
        "{}: {duration} s of the realistic twin, every joint at {stiffness:.0} N·m/rad (recorded in {:.1} s); {runs} runs each, interleaved; {} cores",
        bin.display(),
        t0.elapsed().as_secs_f64(),
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    let load_before = load();
    let (mut default, mut paper) = (Vec::new(), Vec::new());
    for i in 0..runs {
        if i % 2 == 0 {
            paper.push(run(bin, &dir, &["--model", "paper"], "paper"));
        }
        default.push(run(bin, &dir, &[], "default"));
        if i % 2 == 1 {
            paper.push(run(bin, &dir, &["--model", "paper"], "paper"));
        }
    }
    let p = summary("`robimu calibrate DIR --model paper`", &paper);
    let d = summary("`robimu calibrate DIR` (the model chosen)", &default);
    let ratios: Vec<f64> = default.iter().zip(&paper).map(|(a, b)| a.0 / b.0).collect();
    let (lo, hi) = ratios
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    println!(
        "default / --model paper: {:.2}x (run by run: median {:.2}x, {lo:.2}–{hi:.2}x); load average before {load_before}, after {}",
        d / p,
        median(ratios.clone()),
        load()
    );
    let text = std::fs::read_to_string(dir.join("bench-default.json")).expect("the result");
    let result: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    let effects: Vec<&str> = result["effects"]
        .as_array()
        .map(|a| a.iter().filter_map(|e| e["name"].as_str()).collect())
        .unwrap_or_default();
    println!(
        "the model chosen: the paper's + [{}]; trust {}",
        effects.join(", "),
        result["verdict"]["trust"]
    );
}
