//! `robimu calibrate-batch` (production batches, issue 16): one summary row
//! per session, the same estimates as `robimu calibrate`, broken and empty
//! sessions reported without stopping the batch, limits by name.

mod common;

use std::collections::HashMap;
use std::path::Path;

use common::{robimu, robimu_ok, s};

/// `robimu simulate --duration 60 --seed SEED --out DIR` (extra args after).
fn simulate(dir: &Path, seed: u64, extra: &[&str]) {
    let seed = seed.to_string();
    let mut args = vec![
        "simulate",
        "--duration",
        "60",
        "--seed",
        &seed,
        "--out",
        s(dir),
    ];
    args.extend_from_slice(extra);
    robimu_ok(args);
}

/// The summary CSV: one map column → value per row.
fn summary(path: &Path) -> Vec<HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().clone();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            header
                .iter()
                .zip(rec.iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

fn row<'a>(rows: &'a [HashMap<String, String>], session: &Path) -> &'a HashMap<String, String> {
    rows.iter()
        .find(|r| r["session"] == s(session))
        .unwrap_or_else(|| panic!("no row for {}", session.display()))
}

#[test]
fn batch_reports_every_session_and_matches_single_calibrations() {
    let tmp = tempfile::tempdir().unwrap();
    let lot = tmp.path().join("lot");
    for seed in 1..=3 {
        simulate(&lot.join(format!("s{seed}")), seed, &[]);
    }
    // a session whose imu.csv ends mid-line, and an empty directory
    let broken = lot.join("broken");
    simulate(&broken, 4, &[]);
    let imu = std::fs::read(broken.join("imu.csv")).unwrap();
    let cut = imu.len() / 2
        + imu[imu.len() / 2..]
            .iter()
            .position(|&c| c == b'\n')
            .unwrap();
    std::fs::write(broken.join("imu.csv"), &imu[..cut + 8]).unwrap();
    // a session recorded in degrees: read, but refused by the calibration
    let degrees = lot.join("degrees");
    simulate(&degrees, 5, &[]);
    let joints = std::fs::read_to_string(degrees.join("joints.csv")).unwrap();
    let mut lines = joints.lines();
    let mut text = format!("{}\n", lines.next().unwrap());
    for l in lines {
        let mut f = l.split(',');
        text.push_str(f.next().unwrap());
        for q in f {
            text.push_str(&format!(",{}", q.parse::<f64>().unwrap().to_degrees()));
        }
        text.push('\n');
    }
    std::fs::write(degrees.join("joints.csv"), text).unwrap();
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();

    // the single calibration of s2, written outside the session directory
    let single = tmp.path().join("single.json");
    robimu_ok(["calibrate", s(&lot.join("s2")), "--out", s(&single)]);

    let out = tmp.path().join("summary.csv");
    let run = robimu([
        "calibrate-batch",
        s(&lot),
        s(&empty),
        "--out",
        s(&out),
        "--jobs",
        "2",
    ]);
    run.assert_fails(&["3 of 6 units did not pass"]);
    let rows = summary(&out);
    assert_eq!(rows.len(), 6);
    let d = row(&rows, &degrees);
    assert_eq!(
        (d["status"].as_str(), d["limits"].as_str()),
        ("failed", "fail")
    );
    assert!(d["error"].contains("are the joints in radians?"), "{d:?}");
    let b = row(&rows, &broken);
    assert_eq!(b["status"], "unreadable");
    assert!(
        b["error"].contains("imu.csv") && b["error"].contains("expected at least 7 fields"),
        "{b:?}"
    );
    assert_eq!(b["limits"], "fail");
    let e = row(&rows, &empty);
    assert_eq!(e["status"], "unreadable");
    assert!(e["error"].contains("not a session directory"), "{e:?}");
    for seed in 1..=3 {
        let dir = lot.join(format!("s{seed}"));
        let r = row(&rows, &dir);
        assert_eq!((r["status"].as_str(), r["limits"].as_str()), ("ok", "pass"));
        assert!(dir.join("result.json").is_file());
        assert!(dir.join("result.convergence.csv").is_file());
    }

    // s2's row: the single run's estimates, σ, termination and residuals
    let r = row(&rows, &lot.join("s2"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&single).unwrap()).unwrap();
    let mut compared = 0;
    for p in json["parameters"].as_array().unwrap() {
        let name = p["name"].as_str().unwrap();
        let Some(v) = r.get(name) else { continue };
        let value: f64 = v.parse().unwrap();
        let sigma: f64 = r[&format!("{name}_sigma")].parse().unwrap();
        // the CSV prints every digit: equal up to serde_json's parsing of
        // result.json (not round-trip exact: within an ulp or two)
        let same = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * b.abs();
        assert!(
            same(value, p["value"].as_f64().unwrap()),
            "{name}: {value} vs {p}"
        );
        assert!(
            same(sigma, p["sigma"].as_f64().unwrap()),
            "{name} σ: {sigma} vs {p}"
        );
        compared += 1;
    }
    // the IMU's position, τ and 24 intrinsics; no robot error or gravity
    assert_eq!(compared, 28);
    assert!(!r.contains_key("g_x") && !r.contains_key("eps_2_4"));
    assert_eq!(r["termination"], json["termination"].as_str().unwrap());
    let rms: Vec<f64> = json["residual_rms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let accel = ((rms[0] * rms[0] + rms[1] * rms[1] + rms[2] * rms[2]) / 3.0).sqrt();
    let got: f64 = r["residual_rms_accel"].parse().unwrap();
    assert!((got - accel).abs() < 1e-12 * accel, "{got} vs {accel}");

    // a second batch would overwrite the result files: refused up front
    let again = robimu(["calibrate-batch", s(&lot), "--out", s(&out)]);
    again.assert_fails(&["already have a result file", "--force"]);
}

#[test]
fn limits_fail_the_unit_beyond_them_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    // one truth (drawn for seed 5) with the accelerometer biases set
    let base = tmp.path().join("base");
    simulate(&base, 5, &[]);
    let truth = std::fs::read_to_string(base.join("truth.toml")).unwrap();
    let with_bias = |bx: f64| {
        let lines: Vec<String> = truth
            .lines()
            .map(|l| match l.split(" = ").next() {
                Some("b_a_x") => format!("b_a_x = {bx}"),
                Some("b_a_y" | "b_a_z") => format!("{} = 0.05", &l[..5]),
                _ => l.to_string(),
            })
            .collect();
        lines.join("\n")
    };
    let lot = tmp.path().join("lot");
    let (good, bad) = (lot.join("good"), lot.join("bad"));
    for (dir, bx) in [(&good, 0.05), (&bad, 0.5)] {
        let t = tmp.path().join(format!("truth-{bx}.toml"));
        std::fs::write(&t, with_bias(bx)).unwrap();
        simulate(dir, 6, &["--truth", s(&t)]);
    }
    let limits = tmp.path().join("limits.toml");
    std::fs::write(
        &limits,
        "[limits]\nmax_abs_bias_accel = 0.3  # m/s^2\nmax_residual_rms_accel = 1.5\n",
    )
    .unwrap();
    let results = tmp.path().join("results");
    let out = tmp.path().join("summary.csv");
    let run = robimu([
        "calibrate-batch",
        s(&lot),
        "--limits",
        s(&limits),
        "--results",
        s(&results),
        "--out",
        s(&out),
    ]);
    run.assert_fails(&["1 of 2 units did not pass"]);
    let rows = summary(&out);
    let (g, b) = (row(&rows, &good), row(&rows, &bad));
    assert_eq!((g["status"].as_str(), g["limits"].as_str()), ("ok", "pass"));
    assert_eq!(g["failed_limits"], "");
    assert_eq!((b["status"].as_str(), b["limits"].as_str()), ("ok", "fail"));
    // only b_a_x is beyond 0.3
    assert!(
        b["failed_limits"].starts_with("max_abs_bias_accel (b_a_x 0.")
            && b["failed_limits"].ends_with(" > 0.3)")
            && !b["failed_limits"].contains("b_a_y"),
        "{b:?}"
    );
    let est: f64 = b["b_a_x"].parse().unwrap();
    let sigma: f64 = b["b_a_x_sigma"].parse().unwrap();
    assert!((est - 0.5).abs() < 5.0 * sigma, "{est} ± {sigma}");
    // --results: the files under DIR/NAME, none in the session directories
    assert!(results.join("bad/result.json").is_file());
    assert!(results.join("good/result.convergence.csv").is_file());
    assert!(!good.join("result.json").exists());

    // the unit within the limits alone passes: exit 0
    let ok = robimu_ok([
        "calibrate-batch",
        s(&good),
        "--limits",
        s(&limits),
        "--out",
        s(&out),
    ]);
    assert!(ok.stdout.contains("1 of 1 units pass"), "{}", ok.stdout);

    // an unknown key is named, before any session is calibrated
    std::fs::write(&limits, "[limits]\nmax_bias_accel = 0.3\n").unwrap();
    let run = robimu(["calibrate-batch", s(&good), "--limits", s(&limits)]);
    run.assert_fails(&["unknown field `max_bias_accel`", "limits.toml"]);
}

/// A session of two IMUs (docs/model.md §9) is one joint fit and two units:
/// a row per IMU with its own 28 parameters under their §5 names (the
/// single joint `robimu calibrate`'s `imu1/…` values for IMU 1) and its
/// own verdict against the limits.
#[test]
fn a_two_imu_session_gives_one_row_per_imu() {
    let tmp = tempfile::tempdir().unwrap();
    let lot = tmp.path().join("lot");
    let dir = lot.join("pair");
    simulate(&dir, 7, &["--imus", "2"]);
    let single = tmp.path().join("single.json");
    robimu_ok(["calibrate", s(&dir), "--out", s(&single)]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&single).unwrap()).unwrap();
    let params = json["parameters"].as_array().unwrap();
    let value = |name: &str| {
        params
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("{name} not in the result"))["value"]
            .as_f64()
            .unwrap()
    };
    // a gyroscope-bias limit between the two IMUs' largest |b_w|: one passes
    let worst = |prefix: &str| {
        ["b_w_x", "b_w_y", "b_w_z"]
            .map(|n| value(&format!("{prefix}{n}")).abs())
            .into_iter()
            .fold(0.0, f64::max)
    };
    let (w0, w1) = (worst(""), worst("imu1/"));
    let limit = 0.5 * (w0 + w1);
    let limits = tmp.path().join("limits.toml");
    std::fs::write(&limits, format!("[limits]\nmax_abs_bias_gyro = {limit}\n")).unwrap();
    let out = tmp.path().join("summary.csv");
    let run = robimu([
        "calibrate-batch",
        s(&lot),
        "--limits",
        s(&limits),
        "--out",
        s(&out),
        "--force",
    ]);
    run.assert_fails(&["1 of 2 units did not pass"]);
    let rows = summary(&out);
    assert_eq!(rows.len(), 2);
    for (j, prefix) in [(0, ""), (1, "imu1/")] {
        let r = &rows[j];
        assert_eq!(r["imu"], j.to_string());
        assert_eq!(r["status"], "ok");
        let mut compared = 0;
        for p in params {
            let name = p["name"].as_str().unwrap();
            let Some(base) = name.strip_prefix(prefix) else {
                continue;
            };
            if base.starts_with("imu") {
                continue;
            }
            let Some(v) = r.get(base) else { continue };
            let v: f64 = v.parse().unwrap();
            let want = p["value"].as_f64().unwrap();
            assert!(
                (v - want).abs() <= 4.0 * f64::EPSILON * want.abs(),
                "IMU {j} {base}: {v} vs {want}"
            );
            compared += 1;
        }
        assert_eq!(compared, 28, "IMU {j}");
        let fails = r["limits"] == "fail";
        assert_eq!(fails, if j == 0 { w0 > limit } else { w1 > limit }, "{r:?}");
        assert_eq!(
            fails,
            r["failed_limits"].starts_with("max_abs_bias_gyro (b_w_"),
            "{r:?}"
        );
    }
}
