//! Whole-process calibration speed, the way a user runs it: `robimu simulate`
//! writes a session directory, then the `robimu calibrate DIR` binary runs on
//! it several times (reading the CSVs, knot choice, τ search, the fit, the
//! whiteness test of `--noise-model auto`, the covariance, writing the
//! result). Prints per case the median and min wall time, the median user and
//! system CPU time and the largest peak resident memory of the child (GNU
//! `time`'s `%M`, i.e. wait4's maxrss; without /usr/bin/time only the wall
//! time is measured), and the machine's load average.
//!
//! Cases: 300 s at 120 Hz (always), and on the same session the whole
//! `robimu diagnose DIR` (baseline fit, noise identification, every
//! candidate's score, residual statistics, spectra, plots), with its ratio
//! to calibrate; with `--long`, also calibrate on 300 s at 1 kHz and 30 min
//! at 120 Hz (slow); with `--imus K` (K > 1), also calibrate on a 300 s
//! 120 Hz session of K IMUs (`simulate --imus K`, the joint fit of
//! docs/model.md §9), with its ratio to the one-IMU calibrate. The long
//! cases print their ratio to the 120 Hz calibrate. `--runs N` (default 7)
//! and `--bin PATH` (time another build of robimu, e.g. a copy of an older
//! one, on the same sessions) are optional. `--versus PATH` times another
//! build's `calibrate` interleaved run by run with this one's on every
//! case (so that both see the same machine: the figures of a shared
//! machine drift by tens of per cent within minutes; the other build goes
//! first on even runs and second on odd ones) and prints the ratio of their
//! medians — the back-to-back comparison issue 18 is measured by — and the
//! median and range of the run-by-run ratios.
//! `--poses` times instead `robimu calibrate DIR` on a pose session
//! (`robimu simulate --source poses --seed 1`: 60 s, 15 Hz tool poses with
//! 3 ms jitter, 100 Hz IMU; issue 39's target is 0.2 s), with `--versus`
//! interleaved as above.
//! `--ceres PATH` times the independent Ceres implementation of
//! `peers/ceres` (built by `peers/ceres/build.sh`) the same way on the
//! 300 s / 120 Hz case, given robimu's τ start and knot spacing (it does no
//! τ search or knot choice of its own), and prints how much slower it is.
//!
//! `cargo bench -p robimu --bench calibrate_process [-- --long --runs 7 --imus 3 --versus OLD --ceres PEER | --poses]`

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

mod process;
use process::{gnu_time, load};

/// One `robimu calibrate` run: wall, user and system time (s), peak RSS (MB).
struct Run {
    wall: f64,
    cpu: Option<(f64, f64, f64)>,
}

fn simulate(bin: &Path, dir: &Path, duration: f64, rate: f64, imus: usize) {
    let status = Command::new(bin)
        .args(["simulate", "--seed", "1", "--imus"])
        .arg(imus.to_string())
        .arg("--duration")
        .arg(duration.to_string())
        .arg("--rate")
        .arg(rate.to_string())
        .arg("--out")
        .arg(dir)
        .stdout(Stdio::null())
        .status()
        .expect("run robimu simulate");
    assert!(status.success(), "robimu simulate failed");
}

/// `robimu calibrate DIR` or `robimu diagnose DIR` (`what`), output in DIR
/// (a name of its own per binary `tag`).
fn run_once(what: &str, bin: &Path, dir: &Path, time: Option<&Path>, tag: &str) -> Run {
    let out = match what {
        "calibrate" => dir.join(format!("bench-result{tag}.json")),
        _ => dir.join(format!("bench-diagnosis{tag}")),
    };
    let args = [
        what.into(),
        dir.as_os_str().to_owned(),
        "--out".into(),
        out.into(),
    ];
    run_timed(bin, &args, dir, time, tag)
}

/// The Ceres peer on DIR, started where robimu's result `start` says (its
/// `tau_initial` and `knot_spacing`).
fn run_ceres(peer: &Path, dir: &Path, start: &Path, time: Option<&Path>) -> Run {
    let text = std::fs::read_to_string(start).expect("read robimu's result");
    let result: serde_json::Value = serde_json::from_str(&text).expect("robimu's result is JSON");
    let number = |key: &str| {
        result[key]
            .as_f64()
            .unwrap_or_else(|| panic!("robimu's result has no {key}"))
            .to_string()
    };
    let args = [
        dir.as_os_str().to_owned(),
        "--tau".into(),
        number("tau_initial").into(),
        "--knot-spacing".into(),
        number("knot_spacing").into(),
        "--out".into(),
        dir.join("bench-result-ceres.json").into(),
    ];
    run_timed(peer, &args, dir, time, "-ceres")
}

/// One run of `bin args`, under GNU `time` when there is one.
fn run_timed(
    bin: &Path,
    args: &[std::ffi::OsString],
    dir: &Path,
    time: Option<&Path>,
    tag: &str,
) -> Run {
    let report = dir.join(format!("time{tag}.txt"));
    let mut cmd = match time {
        Some(t) => {
            let mut c = Command::new(t);
            c.arg("-o").arg(&report).args(["-f", "%U %S %M"]).arg(bin);
            c
        }
        None => Command::new(bin),
    };
    cmd.args(args).stdout(Stdio::null()).stderr(Stdio::null());
    let start = Instant::now();
    let status = cmd
        .status()
        .unwrap_or_else(|e| panic!("run {}: {e}", bin.display()));
    let wall = start.elapsed().as_secs_f64();
    assert!(status.success(), "{} {args:?} failed", bin.display());
    let cpu = time.and_then(|_| {
        let s = std::fs::read_to_string(&report).ok()?;
        let v: Vec<f64> = s
            .lines()
            .last()?
            .split_whitespace()
            .map(|w| w.parse().ok())
            .collect::<Option<_>>()?;
        (v.len() == 3).then(|| (v[0], v[1], v[2] / 1024.0))
    });
    Run { wall, cpu }
}

/// The median and the least of run times.
fn median_min(v: &[f64]) -> (f64, f64) {
    (
        median(v.to_vec()),
        v.iter().cloned().fold(f64::INFINITY, f64::min),
    )
}

/// The other build's figures beside ours (`walls`, median `med`), run
/// interleaved with them (`theirs`).
fn versus_text(other: &Path, theirs: &[f64], walls: &[f64], med: f64) -> String {
    let (their, their_min) = median_min(theirs);
    format!(
        "; versus {} interleaved: median {their:.3} s, min {their_min:.3} s, {:.2}x this one's{}",
        other.display(),
        their / med,
        pairwise(theirs, walls)
    )
}

/// The run-by-run ratios of interleaved runs (each `theirs[i] / ours[i]`,
/// timed seconds apart): their median and range, which a drift of the
/// machine over the whole bench moves less than the ratio of the medians.
fn pairwise(theirs: &[f64], ours: &[f64]) -> String {
    let r: Vec<f64> = theirs.iter().zip(ours).map(|(a, b)| a / b).collect();
    if r.len() < 2 {
        return String::new();
    }
    let (lo, hi) = r
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    format!(" (run by run: median {:.2}x, {lo:.2}–{hi:.2}x)", median(r))
}

/// The program a `--bin`, `--versus` or `--ceres` flag names. `cargo bench`
/// runs this bench in the package's directory (host/cli), so a relative path
/// is taken from the workspace root, where the README's commands are typed
/// (`--ceres peers/ceres/robimu_ceres`), unless it names a file from here.
fn program(flag: &str, path: &str) -> PathBuf {
    let given = PathBuf::from(path);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let found = if given.is_relative() && !given.is_file() {
        root.join(&given)
    } else {
        given
    };
    if !found.is_file() {
        eprintln!(
            "{flag} {path}: no such program (relative paths are taken from the workspace root {}; \
             peers/ceres/build.sh builds the Ceres peer)",
            root.display()
        );
        std::process::exit(2);
    }
    found
}

/// The pose-session case (`--poses`): simulate, then `runs` calibrations
/// (interleaved with `versus`'s when given); one line of figures.
fn pose_case(bin: &Path, work: &Path, runs: usize, time: Option<&Path>, versus: Option<&Path>) {
    let dir = work.join("poses");
    let status = Command::new(bin)
        .args(["simulate", "--source", "poses", "--seed", "1", "--out"])
        .arg(&dir)
        .stdout(Stdio::null())
        .status()
        .expect("run robimu simulate");
    assert!(status.success(), "robimu simulate --source poses failed");
    let load_before = load();
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    for i in 0..runs {
        let other = |theirs: &mut Vec<f64>| {
            if let Some(o) = versus {
                theirs.push(run_once("calibrate", o, &dir, time, "-versus").wall);
            }
        };
        if i % 2 == 0 {
            other(&mut theirs);
        }
        ours.push(run_once("calibrate", bin, &dir, time, ""));
        if i % 2 == 1 {
            other(&mut theirs);
        }
    }
    let walls: Vec<f64> = ours.iter().map(|r| r.wall).collect();
    let (med, min) = median_min(&walls);
    let max = walls.iter().cloned().fold(0.0, f64::max);
    let mut line = format!(
        "calibrate, pose session (`robimu simulate --source poses --seed 1`: 60 s, 15 Hz poses, 100 Hz IMU): \
         wall median {med:.3} s, min {min:.3} s, max {max:.3} s"
    );
    if ours.iter().all(|r| r.cpu.is_some()) {
        let user = median(ours.iter().map(|r| r.cpu.unwrap().0).collect());
        let sys = median(ours.iter().map(|r| r.cpu.unwrap().1).collect());
        let peak = ours.iter().map(|r| r.cpu.unwrap().2).fold(0.0, f64::max);
        line += &format!("; CPU median user {user:.2} s + sys {sys:.2} s; peak RSS {peak:.0} MB");
    }
    if let Some(o) = versus {
        line += &versus_text(o, &theirs, &walls, med);
    }
    println!(
        "{line}; load average before {load_before}, after {}",
        load()
    );
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let long = args.iter().any(|a| a == "--long");
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
    };
    let runs: usize = value("--runs").map_or(7, |v| v.parse().expect("--runs N"));
    assert!(runs > 0, "--runs must be at least 1");
    let imus: usize = value("--imus").map_or(1, |v| v.parse().expect("--imus K"));
    assert!(imus > 0, "--imus must be at least 1");
    let bin = value("--bin").map_or_else(
        || PathBuf::from(env!("CARGO_BIN_EXE_robimu")),
        |p| program("--bin", p),
    );
    let versus = value("--versus").map(|p| program("--versus", p));
    let ceres = value("--ceres").map(|p| program("--ceres", p));
    let time = gnu_time();
    let work = tempfile::tempdir().expect("temporary directory");
    if args.iter().any(|a| a == "--poses") {
        println!(
            "{}: {runs} runs; {} cores",
            bin.display(),
            std::thread::available_parallelism().map_or(0, |n| n.get())
        );
        pose_case(&bin, work.path(), runs, time, versus.as_deref());
        return;
    }
    let mut cases = vec![("300 s at 120 Hz", 300.0, 120.0, 1)];
    if imus > 1 {
        cases.push(("300 s at 120 Hz", 300.0, 120.0, imus));
    }
    if long {
        cases.push(("300 s at 1 kHz", 300.0, 1000.0, 1));
        cases.push(("30 min at 120 Hz", 1800.0, 120.0, 1));
    }
    // calibrate's wall and CPU on the first (one-IMU) case
    let mut one_imu: Option<(f64, Option<f64>)> = None;
    // calibrate's wall on the 120 Hz case, for the long cases' ratios
    let mut base_wall: Option<f64> = None;
    println!(
        "{}: `robimu calibrate DIR` on sessions of `robimu simulate --seed 1`; {runs} runs per case; {} cores",
        bin.display(),
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    for (k, (label, duration, rate, imus)) in cases.into_iter().enumerate() {
        let dir = work.path().join(format!("s{duration}-{rate}-{imus}"));
        simulate(&bin, &dir, duration, rate, imus);
        let whats: &[&str] = if k == 0 {
            &["calibrate", "diagnose"]
        } else {
            &["calibrate"]
        };
        let mut calibrate_median = None;
        for &what in whats {
            let load_before = load();
            let other = versus.as_ref().filter(|_| what == "calibrate");
            let peer = ceres.as_ref().filter(|_| what == "calibrate" && k == 0);
            let mut theirs = Vec::new();
            let mut peers = Vec::new();
            let results: Vec<Run> = (0..runs)
                .map(|i| {
                    // the other build first on even runs, second on odd ones
                    // (no build always runs right after the same one)
                    let versus_run = |theirs: &mut Vec<f64>| {
                        if let Some(o) = other {
                            theirs.push(run_once(what, o, &dir, time, "-versus").wall);
                        }
                    };
                    if i % 2 == 0 {
                        versus_run(&mut theirs);
                    }
                    let run = run_once(what, &bin, &dir, time, "");
                    if i % 2 == 1 {
                        versus_run(&mut theirs);
                    }
                    if let Some(p) = peer {
                        peers.push(run_ceres(p, &dir, &dir.join("bench-result.json"), time));
                    }
                    run
                })
                .collect();
            let walls: Vec<f64> = results.iter().map(|r| r.wall).collect();
            let (med, min) = median_min(&walls);
            let mut line = format!(
                "{what}, {label} (`robimu simulate --duration {duration} --rate {rate} --seed 1 --imus {imus}`): wall median {med:.3} s, min {min:.3} s",
            );
            let cpu: Vec<(f64, f64, f64)> = results.iter().filter_map(|r| r.cpu).collect();
            let mut cpu_total = None;
            if cpu.len() == results.len() {
                let user = median(cpu.iter().map(|c| c.0).collect());
                let sys = median(cpu.iter().map(|c| c.1).collect());
                let peak = cpu.iter().map(|c| c.2).fold(0.0, f64::max);
                cpu_total = Some(user + sys);
                line += &format!(
                    "; CPU median user {user:.2} s + sys {sys:.2} s; peak RSS {peak:.0} MB"
                );
            }
            if k == 0 && what == "calibrate" {
                one_imu = Some((med, cpu_total));
            }
            if what == "calibrate" && imus == 1 {
                match base_wall {
                    None => base_wall = Some(med),
                    Some(b) => line += &format!("; {:.2}x the 120 Hz calibrate's wall", med / b),
                }
            }
            if let Some(o) = other {
                line += &versus_text(o, &theirs, &walls, med);
            }
            if !peers.is_empty() {
                let peer_walls: Vec<f64> = peers.iter().map(|r| r.wall).collect();
                let (their, their_min) = median_min(&peer_walls);
                line += &format!(
                    "; Ceres peer interleaved: median {their:.3} s, min {their_min:.3} s, {:.2}x this one's{}",
                    their / med,
                    pairwise(&peer_walls, &walls)
                );
                if peers.iter().all(|r| r.cpu.is_some()) {
                    let user = median(peers.iter().map(|r| r.cpu.unwrap().0).collect());
                    let peak = peers.iter().map(|r| r.cpu.unwrap().2).fold(0.0, f64::max);
                    line += &format!(" (CPU median user {user:.2} s, peak RSS {peak:.0} MB)");
                }
            }
            if imus > 1 {
                if let Some((c, c_cpu)) = one_imu {
                    line += &format!("; {:.2}x the one-IMU calibrate's wall", med / c);
                    if let (Some(a), Some(b)) = (cpu_total, c_cpu) {
                        line += &format!(", {:.2}x its CPU", a / b);
                    }
                }
            }
            match calibrate_median {
                None => calibrate_median = Some((med, cpu_total)),
                Some((c, c_cpu)) => {
                    line += &format!("; {:.2}x calibrate's wall", med / c);
                    if let (Some(a), Some(b)) = (cpu_total, c_cpu) {
                        line += &format!(", {:.2}x its CPU", a / b);
                    }
                }
            }
            println!(
                "{line}; load average before {load_before}, after {}",
                load()
            );
        }
    }
}
