//! Production batch speed (issue 16's must-show: a batch of 20 single-IMU
//! 300 s sessions in ≤ 0.6× the sum of their single runs on 2 cores):
//! `robimu simulate --duration D --seed N` for N = 1..=S, then every session
//! calibrated by its own `robimu calibrate DIR` (one after the other, the
//! sum of their wall times) and all of them by one `robimu calibrate-batch`
//! (default `--jobs`, the available cores). Prints the wall times, the ratio,
//! the CPU time of each side (GNU `time`'s user + sys, when /usr/bin/time
//! exists) and the load average before and after each side (the machine may
//! be shared). `--serial` also times `calibrate-batch --jobs 1`.
//!
//! `cargo bench -p robimu --bench calibrate_batch [-- --sessions 20 --duration 300 --serial --bin PATH]`

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

mod process;
use process::{gnu_time, load};

/// `bin ARGS` under GNU time when there is one: wall time and user + sys
/// CPU time (s), and whether it exited with 0.
fn timed(
    bin: &Path,
    args: &[&str],
    time: Option<&Path>,
    report: &Path,
) -> (f64, Option<f64>, bool) {
    let mut cmd = match time {
        Some(t) => {
            let mut c = Command::new(t);
            c.arg("-o").arg(report).args(["-f", "%U %S"]).arg(bin);
            c
        }
        None => Command::new(bin),
    };
    cmd.args(args).stdout(Stdio::null()).stderr(Stdio::null());
    let start = Instant::now();
    let status = cmd.status().expect("run robimu");
    let wall = start.elapsed().as_secs_f64();
    let cpu = time.and_then(|_| {
        let s = std::fs::read_to_string(report).ok()?;
        let v: Vec<f64> = s
            .lines()
            .last()?
            .split_whitespace()
            .map(|w| w.parse().ok())
            .collect::<Option<_>>()?;
        (v.len() == 2).then(|| v[0] + v[1])
    });
    (wall, cpu, status.success())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
    };
    let sessions: usize = value("--sessions").map_or(20, |v| v.parse().expect("--sessions N"));
    let duration: f64 = value("--duration").map_or(300.0, |v| v.parse().expect("--duration S"));
    let serial = args.iter().any(|a| a == "--serial");
    let bin = value("--bin").map_or_else(
        || PathBuf::from(env!("CARGO_BIN_EXE_robimu")),
        PathBuf::from,
    );
    let time = gnu_time();
    let work = tempfile::tempdir().expect("temporary directory");
    let lot = work.path().join("lot");
    let s = |p: &Path| p.to_str().expect("UTF-8 temporary path").to_string();
    let mut dirs = Vec::new();
    for seed in 1..=sessions {
        let dir = lot.join(format!("s{seed:02}"));
        let status = Command::new(&bin)
            .args(["simulate", "--duration", &duration.to_string()])
            .args(["--seed", &seed.to_string(), "--out", &s(&dir)])
            .stdout(Stdio::null())
            .status()
            .expect("run robimu simulate");
        assert!(status.success(), "robimu simulate failed");
        dirs.push(dir);
    }
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    println!(
        "{}: {sessions} sessions of `robimu simulate --duration {duration} --seed N`, {cores} cores",
        bin.display()
    );
    let report = work.path().join("time.txt");
    let fmt_cpu = |c: Option<f64>| c.map_or(String::new(), |c| format!(", CPU {c:.1} s"));

    let before = load();
    let (mut wall_sum, mut cpu_sum) = (0.0, Some(0.0));
    for dir in &dirs {
        let out = s(&dir.join("single.json"));
        let (w, c, ok) = timed(&bin, &["calibrate", &s(dir), "--out", &out], time, &report);
        assert!(ok, "robimu calibrate failed on {}", dir.display());
        wall_sum += w;
        cpu_sum = cpu_sum.zip(c).map(|(a, b)| a + b);
    }
    println!(
        "sum of {sessions} single `robimu calibrate DIR` runs: wall {wall_sum:.1} s{}; load average before {before}, after {}",
        fmt_cpu(cpu_sum),
        load()
    );

    let mut jobs = vec![None];
    if serial {
        jobs.push(Some(1));
    }
    for j in jobs {
        let results = work.path().join(format!("results-{j:?}"));
        let summary = work.path().join("summary.csv");
        let mut a = vec![
            "calibrate-batch".to_string(),
            s(&lot),
            "--results".into(),
            s(&results),
            "--out".into(),
            s(&summary),
        ];
        if let Some(j) = j {
            a.extend(["--jobs".into(), j.to_string()]);
        }
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let before = load();
        let (w, c, ok) = timed(&bin, &a, time, &report);
        let label = j.map_or(format!("--jobs {cores} (default)"), |j| {
            format!("--jobs {j}")
        });
        println!(
            "`robimu calibrate-batch` {label}: wall {w:.1} s{} = {:.2}× the sum{}; load average before {before}, after {}",
            fmt_cpu(c),
            w / wall_sum,
            if ok { "" } else { " (some unit did not pass)" },
            load()
        );
    }
}
