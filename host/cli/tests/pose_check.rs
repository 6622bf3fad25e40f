//! `robimu check` on a session with tool poses (issue 39, docs/model.md
//! §7.9): a clean pose session (written with `PoseSessionWriter`: a smooth
//! motion, 100 Hz poses, 200 Hz IMU samples) passes; one with faults —
//! quaternion sign flips, a non-unit quaternion, a 2 s gap in the poses,
//! positions in mm, a start-up burst of late-stamped IMU samples, a
//! saturated gyroscope channel — is refused, each fault named with its
//! number; `calibrate` and `diagnose` take a pose session without a panic.

mod common;

use std::path::Path;

use common::{robimu, s};
use robimu_session::{PoseNoise, PoseSessionMeta, PoseSessionWriter};

/// Faults to put into the written session.
#[derive(Default, Clone, Copy)]
struct Faults {
    /// Negate q over 10..15 s and at the row at 30 s (4 flips).
    sign_flips: bool,
    /// |q| = 1.02 at the row at 12 s.
    non_unit: bool,
    /// No poses over 20..22 s.
    gap: bool,
    /// Positions ×1000.
    millimetres: bool,
    /// The first 40 IMU samples stamped 0.2 ms apart (up to 0.195 s).
    burst: bool,
    /// gz at +250 °/s over 60 samples.
    saturated: bool,
    /// A second IMU, imu1.csv (the first's samples), with a 2 s gap over
    /// 30..32 s, gz at +250 °/s over 60 samples from 40 s and gx stuck over
    /// 1.5 s from 10 s.
    imu1: bool,
}

/// p(t) on a slow curve, R(t) = Exp(0.4 t · axis) as [w, x, y, z].
fn pose(t: f64) -> ([f64; 3], [f64; 4]) {
    let (s, c) = (0.5 * t).sin_cos();
    let (hs, hc) = (0.2 * t).sin_cos();
    (
        [0.5 + 0.3 * c, 0.3 * s, 0.4 + 0.05 * (0.3 * t).sin()],
        [hc, 0.6 * hs, 0.0, 0.8 * hs],
    )
}

fn write_session(dir: &Path, faults: Faults) {
    let meta = PoseSessionMeta {
        poses: Some(PoseNoise {
            sigma_p: Some(1e-4),
            sigma_r: Some(1e-3),
        }),
        notes: Some("synthetic pose session (tests/pose_check.rs)".into()),
        ..Default::default()
    };
    let mut w = PoseSessionWriter::create(dir, &meta).unwrap();
    for i in 0..6000 {
        let t = i as f64 * 0.01;
        if faults.gap && t > 20.005 && t < 22.0 {
            continue;
        }
        let (mut p, mut q) = pose(t);
        if faults.sign_flips && ((1000..1500).contains(&i) || i == 3000) {
            q = q.map(|v| -v);
        }
        if faults.non_unit && i == 1200 {
            q = q.map(|v| 1.02 * v);
        }
        if faults.millimetres {
            p = p.map(|v| 1000.0 * v);
        }
        w.pose(t, &p, &q).unwrap();
    }
    for i in 0..12_000 {
        let mut t = i as f64 * 0.005;
        if faults.burst && i < 40 {
            t = 0.195 - (39 - i) as f64 * 0.0002;
        }
        let mut z = [
            0.3 * (1.1 * t).sin(),
            0.2 * (0.9 * t).cos(),
            9.81 + 0.1 * (0.7 * t).sin(),
            0.4 * (0.5 * t).cos(),
            0.1 * (0.8 * t).sin(),
            0.32 + 0.05 * (0.6 * t).sin(),
        ];
        if faults.saturated && (4000..4060).contains(&i) {
            z[5] = 250f64.to_radians();
        }
        w.imu(t, &z).unwrap();
        if faults.imu1 && !(t > 30.0025 && t < 32.0) {
            if (8000..8060).contains(&i) {
                z[5] = 250f64.to_radians();
            }
            if (2000..2300).contains(&i) {
                z[3] = 0.125;
            }
            w.imu_of(1, t, &z).unwrap();
        }
    }
    w.finish().unwrap();
}

/// `robimu check DIR --json`: the run and its findings.
fn check(dir: &Path) -> (common::Run, Vec<serde_json::Value>) {
    let json = dir.join("check.json");
    let run = robimu(["check", s(dir), "--json", s(&json)]);
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (run, v["findings"].as_array().unwrap().clone())
}

#[track_caller]
fn finding<'a>(findings: &'a [serde_json::Value], kind: &str) -> &'a serde_json::Value {
    findings
        .iter()
        .find(|f| f["kind"] == kind)
        .unwrap_or_else(|| panic!("no `{kind}` finding in {findings:#?}"))
}

fn value(f: &serde_json::Value) -> f64 {
    f["value"].as_f64().unwrap()
}

fn message(f: &serde_json::Value) -> &str {
    f["message"].as_str().unwrap()
}

#[test]
fn a_clean_pose_session_passes_the_check() {
    let tmp = tempfile::tempdir().unwrap();
    write_session(tmp.path(), Faults::default());
    let (run, f) = check(tmp.path());
    assert!(run.success(), "{}{}", run.stdout, run.stderr);
    let kinds: Vec<&str> = f.iter().map(|f| f["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["rate", "rate", "overlap"], "{f:#?}");
    assert!((value(&f[0]) - 100.0).abs() < 1e-3, "{f:#?}");
    assert!(run.stdout.contains("poses.csv"), "{}", run.stdout);
}

#[test]
fn each_fault_of_a_pose_session_is_named_with_its_number() {
    let tmp = tempfile::tempdir().unwrap();
    let all = Faults {
        sign_flips: true,
        non_unit: true,
        gap: true,
        millimetres: true,
        burst: true,
        saturated: true,
        imu1: false,
    };
    write_session(tmp.path(), all);
    let (run, f) = check(tmp.path());
    assert!(!run.success(), "mm poses are fatal: {}", run.stdout);
    let out = run.text();

    let flips = finding(&f, "quaternion_sign");
    assert_eq!(value(flips), 4.0);
    assert!(out.contains("4 quaternion sign flips"), "{out}");

    let norm = finding(&f, "quaternion_norm");
    assert_eq!(value(norm), 1.0);
    assert!(
        message(norm).contains("1 of 5801 quaternions are not unit")
            && message(norm).contains("worst |q| = 1.020000 at t = 12.000 s"),
        "{}",
        message(norm)
    );

    let gap = f
        .iter()
        .find(|g| g["kind"] == "gap" && g["subject"] == "poses.csv")
        .unwrap_or_else(|| panic!("{f:#?}"));
    assert!((value(gap) - 2.0).abs() < 1e-6, "{gap:#}");
    assert!(
        message(gap).contains("largest gap 2.000 s at t = 20.000 s"),
        "{}",
        message(gap)
    );

    let mm = finding(&f, "pose_units");
    assert_eq!(mm["severity"], "fatal");
    assert!((value(mm) - 600.0).abs() < 1.0, "{mm:#}");
    assert!(message(mm).contains("poses in mm?"), "{}", message(mm));
    assert!(out.contains("--units mm"), "{out}");

    let burst = finding(&f, "startup_burst");
    assert_eq!(value(burst), 40.0);
    assert!(
        message(burst).contains("40 samples stamped within 7.8 ms"),
        "{}",
        message(burst)
    );

    let sat = finding(&f, "saturation");
    assert_eq!((sat["subject"].as_str(), value(sat)), (Some("gz"), 60.0));
    assert!(message(sat).contains("±250 °/s"), "{}", message(sat));

    // the run fails naming the fatal finding
    run.assert_fails(&["poses in mm?"]);
}

/// A second IMU's faults (docs/model.md §9): the gap, the saturated gyro
/// and the stuck channel of imu1.csv are named with imu1.csv and their
/// numbers; imu.csv, clean, has none.
#[test]
fn the_faults_of_imu1_csv_are_named_with_its_file() {
    let tmp = tempfile::tempdir().unwrap();
    let faults = Faults {
        imu1: true,
        ..Faults::default()
    };
    write_session(tmp.path(), faults);
    let (run, f) = check(tmp.path());
    let of = |kind: &str| -> Vec<&serde_json::Value> {
        f.iter().filter(|g| g["kind"] == kind).collect()
    };
    let rates = of("rate");
    assert_eq!(rates.len(), 3, "poses, imu.csv, imu1.csv: {f:#?}");
    assert!(rates.iter().any(|r| r["subject"] == "imu1.csv"), "{f:#?}");
    let gap = of("gap");
    assert_eq!(gap.len(), 1, "{f:#?}");
    assert_eq!(gap[0]["subject"], "imu1.csv");
    assert!((value(gap[0]) - 2.0).abs() < 1e-6, "{:#}", gap[0]);
    assert!(
        message(gap[0]).contains("imu1.csv: largest gap 2.000 s at t = 30.000 s"),
        "{}",
        message(gap[0])
    );
    let sat = of("saturation");
    assert_eq!(sat.len(), 1, "{f:#?}");
    assert_eq!(
        (sat[0]["subject"].as_str(), value(sat[0])),
        (Some("gz"), 60.0)
    );
    assert!(
        message(sat[0]).starts_with("imu1.csv: gz saturated"),
        "{}",
        message(sat[0])
    );
    let stuck = of("stuck");
    assert_eq!(stuck.len(), 1, "{f:#?}");
    assert_eq!(stuck[0]["subject"], "gx");
    assert!((value(stuck[0]) - 1.495).abs() < 1e-9, "{:#}", stuck[0]);
    assert!(
        message(stuck[0]).starts_with("imu1.csv: gx repeats 0.125 for ")
            && message(stuck[0]).contains("(300 rows from t = 10.000 s"),
        "{}",
        message(stuck[0])
    );
    assert!(run.stdout.contains("imu1.csv"), "{}", run.stdout);
    // with the range recorded in [imu1], counted against it and named
    let toml = tmp.path().join("session.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(&toml, format!("{text}\n[imu1]\ngyro_range = \"Dps250\"\n")).unwrap();
    let (_, f) = check(tmp.path());
    let sat = finding(&f, "saturation");
    assert_eq!(
        (sat["subject"].as_str(), value(sat)),
        (Some("gyroscope"), 60.0)
    );
    assert!(
        message(sat).starts_with("imu1.csv: gyroscope: 60 rows"),
        "{}",
        message(sat)
    );
}

#[test]
fn calibrate_and_check_name_a_pose_session_without_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    write_session(tmp.path(), Faults::default());
    let run = robimu([
        "calibrate",
        s(tmp.path()),
        "--out",
        s(&tmp.path().join("r.json")),
    ]);
    // calibrate takes a pose session (tests/poses.rs); on these samples,
    // which no IMU could have measured, it ends without a panic
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    assert!(
        run.text().contains("tool poses, 6000 poses"),
        "{}",
        run.text()
    );
    // diagnose takes it too (docs/model.md §7.9), without a panic
    let run = robimu(["diagnose", s(tmp.path()), "--out", s(&tmp.path().join("d"))]);
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    assert!(
        !run.text().contains("this is a pose session"),
        "{}",
        run.text()
    );
    // a broken poses.csv is one fatal finding naming file and line
    std::fs::write(
        tmp.path().join("poses.csv"),
        "t,px,py,pz,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n0.01,0,nan,0,1,0,0,0\n",
    )
    .unwrap();
    let (run, f) = check(tmp.path());
    assert!(!run.success());
    let u = finding(&f, "unreadable");
    assert!(message(u).contains("poses.csv:3"), "{}", message(u));
}
