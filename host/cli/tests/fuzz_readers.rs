//! Issue 41: every reader of what users feed robimu, fuzzed in-process on
//! stable Rust — seeds from the project's fixtures and fresh simulated
//! sessions, mutated (bit flips, truncation, inserted garbage, NaN/inf/1e308
//! in numeric fields, duplicated/reordered/deleted lines, wrong field
//! counts, deep nesting, invalid UTF-8, hostile 64-bit length fields) and
//! read by the library's own call; a panic, a call over 2 s, an empty error
//! or an import that writes what the session reader refuses is a finding.
//!
//! CI runs a bounded campaign (`.ci/run`):
//!
//! ```text
//! ROBIMU_FUZZ_SECONDS=60 cargo test -p robimu --test fuzz_readers -- --ignored --nocapture
//! ```
//!
//! A campaign: `ROBIMU_FUZZ_SECONDS=3600 ROBIMU_FUZZ_INPUTS=20000
//! ROBIMU_FUZZ_SEED=<n>` (default seed: the clock, printed);
//! `ROBIMU_FUZZ_ONLY=MCAP` fuzzes the targets whose name contains it;
//! `ROBIMU_FUZZ_MESSAGES=1` lists each target's distinct refusals;
//! `ROBIMU_FUZZ_PROCESS=1` (or `=PATH` of a `robimu` program, e.g. the
//! release build) runs the program's command for each input instead (check,
//! simulate --robot, report, import ros2/csv, repair): a clear message and
//! a non-zero exit, or exit 0, and no panic, signal or run over
//! `ROBIMU_FUZZ_ABORT_SECONDS`. Each
//! finding is kept under `target/tmp/fuzz-findings/<seed>/` with a
//! `finding.txt`; a call still running after `ROBIMU_FUZZ_ABORT_SECONDS`
//! (default 20) ends the run naming its input.
//!
//! Campaigns on issue 41's code (debug build, 2 shared cores): in-process,
//! 24 000 inputs (seed 1796495104896665956, 57 s): 0 panics, 0 empty
//! errors, 0 calls over 2 s (longest 0.12 s), 20 719 refused with a
//! message, 3 281 read; process-level, 20 000 runs of the program (seed
//! 1796495161732416554, 344 s): 0 panics or signals, every non-zero exit
//! with an `error: ` line (18 092), 0 runs over 20 s (longest 0.30 s),
//! 1 908 exits 0. Earlier runs found the CSV import's `t - t0` overflow
//! and the mcap crate's chunk underflow (regression tests in
//! `robimu_session::import`).
//!
//! Fresh campaigns on 2026-12-06 (pose-session and pose CSV import targets
//! added, aubo_i5 naming its joints): in-process 24 000 inputs over 14
//! targets (seed 1796517017860854669, 255 s under a load of ~6): 0 panics,
//! 0 silent, 0 calls over 2 s (longest 0.23 s), 20 724 refused with a
//! message, 3 276 read; process-level 20 000 runs over 11 commands (seed
//! 1796517279698382757, 339 s): 0 panics or signals, every non-zero exit
//! with an error line (17 987), 0 runs over 20 s (longest 0.28 s), 2 013
//! exits 0 (inputs the program read as valid; in-process, an accepted
//! import is also read back by the session reader, and none was refused).

mod fuzz;

use std::time::{Duration, Instant};

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    let v = std::env::var(name).ok()?;
    Some(
        v.parse()
            .unwrap_or_else(|_| panic!("{name}={v:?} is not a valid value")),
    )
}

#[test]
#[ignore = "a fuzz campaign: run by .ci/run with a time budget"]
fn fuzz_campaign() {
    let seed = env("ROBIMU_FUZZ_SEED").unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos() as u64
    });
    let budget = fuzz::Budget {
        seed,
        time: Duration::from_secs_f64(env("ROBIMU_FUZZ_SECONDS").unwrap_or(60.0)),
        inputs: env("ROBIMU_FUZZ_INPUTS").unwrap_or(usize::MAX),
        abort_after: Duration::from_secs_f64(env("ROBIMU_FUZZ_ABORT_SECONDS").unwrap_or(20.0)),
        only: std::env::var("ROBIMU_FUZZ_ONLY").ok(),
        process: std::env::var_os("ROBIMU_FUZZ_PROCESS").map(|b| {
            if b == "1" {
                std::path::PathBuf::from(env!("CARGO_BIN_EXE_robimu"))
            } else {
                b.into()
            }
        }),
    };
    println!("fuzz campaign: seed {seed} (ROBIMU_FUZZ_SEED={seed} repeats it)");
    let start = Instant::now();
    let (counts, findings) = fuzz::campaign(&budget);
    println!("{}", fuzz::table(&counts, start.elapsed(), seed));
    if std::env::var_os("ROBIMU_FUZZ_MESSAGES").is_some() {
        for (name, c) in &counts {
            println!(
                "{name}: {} distinct refusals (first 60 characters)",
                c.messages.len()
            );
            for m in &c.messages {
                println!("    {m}");
            }
        }
    }
    let total: usize = counts.iter().map(|(_, c)| c.findings()).sum();
    assert!(
        total == 0,
        "{total} findings (seed {seed}), kept in:\n{}",
        findings
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join("\n")
    );
    // every target was fed
    assert!(counts.iter().all(|(_, c)| c.inputs > 0), "{counts:?}");
}

/// Each target's seeds, unmutated, are read without error: the harness
/// feeds every reader something it accepts, so that mutations start from
/// valid inputs.
#[test]
fn every_seed_is_read() {
    for t in fuzz::targets::all() {
        assert!(!t.seeds.is_empty(), "{}: no seeds", t.name);
        for s in &t.seeds {
            let dir = tempfile::tempdir().unwrap();
            for (name, bytes) in &s.files {
                std::fs::write(dir.path().join(name), bytes).unwrap();
            }
            assert!(!s.mutable.is_empty(), "{} {}", t.name, s.label);
            if let Err(e) = (t.read)(dir.path()) {
                panic!("{}: seed {} refused: {e}", t.name, s.label);
            }
        }
    }
}

/// Issue 41: every text reader names where a file stops being UTF-8 (line,
/// column, byte offset), as result.json's does — robot TOML and URDF, noise
/// TOML, bag metadata.yaml and repair's CSVs said "stream did not contain
/// valid UTF-8" before.
#[test]
fn text_that_is_not_utf8_is_refused_at_its_byte() {
    let cases = [
        ("robot TOML", "robot.toml"),
        ("robot URDF", "robot.urdf"),
        ("result.json", "result.json"),
        ("noise TOML", "noise.toml"),
        ("bag metadata.yaml", "metadata.yaml"),
        ("repair", "pings.csv"),
        ("repair", "joints.csv"),
        ("repair", "session.toml"),
        ("session", "session.toml"),
    ];
    let targets = fuzz::targets::all();
    for (target, file) in cases {
        let t = targets.iter().find(|t| t.name.starts_with(target)).unwrap();
        let seed = &t.seeds[0];
        let dir = tempfile::tempdir().unwrap();
        for (name, bytes) in &seed.files {
            let mut bytes = bytes.clone();
            if name == file {
                // a byte 0xff as the third byte of line 2
                let at = bytes.iter().position(|&b| b == b'\n').unwrap() + 3;
                bytes.insert(at, 0xff);
            }
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let e = (t.read)(dir.path()).unwrap_err();
        assert!(
            e.contains(file) && e.contains("not UTF-8 text: invalid byte 0xff at byte offset"),
            "{target} {file}: {e}"
        );
        assert!(e.contains("(line 2, column 3)"), "{target} {file}: {e}");
    }
}
