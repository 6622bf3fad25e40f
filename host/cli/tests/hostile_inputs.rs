//! Issue 41: inputs a fuzzer found to crash, hang or pass silently — each
//! refused through the program with a message naming the cause and a
//! non-zero exit (the ROS 2 recordings are in `import.rs`).

mod common;

use std::path::Path;

use common::{robimu, robimu_ok, s};

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// A simulated session of `seconds` in `dir`.
fn simulated(dir: &Path, seconds: &str) {
    robimu_ok([
        "simulate",
        "--duration",
        seconds,
        "--seed",
        "5",
        "--out",
        s(dir),
    ]);
}

/// Copies the session `src` to `dst` with `file`'s text rewritten by `f`.
fn altered(src: &Path, dst: &Path, file: &str, f: impl Fn(&str) -> String) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() {
            std::fs::copy(&p, dst.join(p.file_name().unwrap())).unwrap();
        }
    }
    let text = std::fs::read_to_string(src.join(file)).unwrap();
    std::fs::write(dst.join(file), f(&text)).unwrap();
}

/// Each CSV row's first field (t, s) in ns.
fn times_in_ns(text: &str) -> String {
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for line in lines {
        let (t, rest) = line.split_once(',').unwrap();
        let t: f64 = t.parse().unwrap();
        out.push_str(&format!("{:e},{rest}\n", t * 1e9));
    }
    out
}

#[test]
fn sessions_that_no_spline_can_fit_are_refused_by_every_command() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("good");
    simulated(&good, "20");
    // Joint and IMU times in ns: 64 GB of knots before; now refused as
    // check and calibrate refuse it.
    let ns = tmp.path().join("ns");
    altered(&good, &ns, "joints.csv", times_in_ns);
    let ns2 = tmp.path().join("ns2");
    altered(&ns, &ns2, "imu.csv", times_in_ns);
    let out = tmp.path().join("out");
    for args in [
        vec!["diagnose", s(&ns2), "--out", s(&out)],
        vec!["calibrate", s(&ns2), "--out", s(&out)],
        vec!["noise", s(&ns2), "--out", s(&out)],
    ] {
        robimu(&args).assert_fails(&["failed the check", "timestamps in ns?"]);
    }
    // `report` over a session whose streams do not overlap (IMU times
    // 10⁶ s late): refused before plotting.
    let result = tmp.path().join("result.json");
    robimu_ok(["calibrate", s(&good), "--out", s(&result)]);
    let late = tmp.path().join("late");
    altered(&good, &late, "imu.csv", |text| {
        let mut lines = text.lines();
        let mut out = format!("{}\n", lines.next().unwrap());
        for line in lines {
            let (t, rest) = line.split_once(',').unwrap();
            let t: f64 = t.parse().unwrap();
            out.push_str(&format!("{:?},{rest}\n", t + 1e6));
        }
        out
    });
    robimu([
        "report",
        s(&result),
        "--session",
        s(&late),
        "--out",
        s(&tmp.path().join("rep")),
    ])
    .assert_fails(&["failed the check", "do not overlap"]);
    // `[noise] sigma_z` with 7 values.
    let seven = tmp.path().join("seven");
    altered(&good, &seven, "session.toml", |text| {
        format!("{text}\n[noise]\nsigma_z = [0.1, 0.1, 0.1, 0.01, 0.01, 0.01, 0.01]\n")
    });
    robimu(["calibrate", s(&seven), "--out", s(&out)])
        .assert_fails(&["7 values where 6 are expected (ax ay az gx gy gz)"]);
}

#[test]
fn result_files_out_of_range_are_refused_on_read() {
    let tmp = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(fixture("multi_imu/result1.json")).unwrap();
    let write = |name: &str, text: &str| {
        let p = tmp.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let out = tmp.path().join("rep");
    // A value of 1e308 (the report printed "inf", its σ bars spun).
    let v: serde_json::Value = serde_json::from_str(&good).unwrap();
    let mut big = v.clone();
    big["parameters"][0]["value"] = serde_json::json!(1e308);
    let big = write("big.json", &big.to_string());
    robimu(["report", s(&big), "--out", s(&out)]).assert_fails(&["is beyond ±1e6"]);
    // A prior σ of 0.
    let mut zero = v.clone();
    zero["parameters"][0]["prior_sigma"] = serde_json::json!(0.0);
    let zero = write("zero.json", &zero.to_string());
    robimu(["report", s(&zero), "--out", s(&out)])
        .assert_fails(&["prior_sigma = 0: a prior σ must be > 0"]);
    // A gain of 1e-320: `correct` wrote NaN and -inf rows.
    let k = v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .position(|p| p["name"] == "k_a_x")
        .unwrap();
    let mut gain = v.clone();
    gain["parameters"][k]["value"] = serde_json::json!(1e-320);
    let gain = write("gain.json", &gain.to_string());
    robimu([
        "correct",
        "--calibration",
        s(&gain),
        s(&fixture("multi_imu/raw_imu.csv")),
        "--out",
        s(&tmp.path().join("c.csv")),
    ])
    .assert_fails(&["`k_a_x`: gain 1e-320 is outside [0.1, 10]"]);
    // Bytes that are not UTF-8: named by position.
    let mut bytes = good.clone().into_bytes();
    bytes[40] = 0xff;
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, bytes).unwrap();
    robimu(["report", s(&bad), "--out", s(&out)]).assert_fails(&[
        "bad.json:",
        "not UTF-8 text: invalid byte 0xff at byte offset 40",
    ]);
}

#[test]
fn robot_descriptions_out_of_range_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    // sigma_q = 1e308: simulate wrote inf joint angles.
    let toml = std::fs::read_to_string(fixture("ur5.toml")).unwrap();
    let huge = tmp.path().join("huge.toml");
    std::fs::write(&huge, toml.replacen("sigma_q = 1e-4", "sigma_q = 1e308", 1)).unwrap();
    robimu([
        "simulate",
        "--robot",
        s(&huge),
        "--duration",
        "5",
        "--out",
        s(&out),
    ])
    .assert_fails(&["joint 1 sigma_q = 1e308 is beyond its range"]);
    // A URDF nested 100 000 deep (a stack overflow) and one whose joints
    // loop (a hang).
    let deep = tmp.path().join("deep.urdf");
    std::fs::write(
        &deep,
        format!(
            "<robot name=\"r\">{}{}</robot>",
            "<a>".repeat(100_000),
            "</a>".repeat(100_000)
        ),
    )
    .unwrap();
    robimu([
        "simulate",
        "--robot",
        s(&deep),
        "--duration",
        "5",
        "--out",
        s(&out),
    ])
    .assert_fails(&["nested more than 256 levels deep"]);
    let joint = |name: &str, parent: &str, child: &str| {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/></joint>"#
        )
    };
    let looped = tmp.path().join("loop.urdf");
    std::fs::write(
        &looped,
        format!(
            "<robot name=\"r\">{}{}{}</robot>",
            joint("j0", "base", "l1"),
            joint("j1", "l2", "l3"),
            joint("j2", "l3", "l2")
        ),
    )
    .unwrap();
    robimu([
        "simulate",
        "--robot",
        s(&looped),
        "--duration",
        "5",
        "--out",
        s(&out),
    ])
    .assert_fails(&["the joints loop back on themselves"]);
}
