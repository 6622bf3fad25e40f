//! A pose session with two IMUs on the body (docs/model.md §7.9, §9):
//! `robimu simulate --source poses --imus 2` writes imu1.csv and a truth of
//! 58 names; `robimu calibrate` estimates all 58 (IMU 1's as `imu1/…`, g
//! shared) within 4σ of the truth (60 s: at 40 s, seed 5, IMU 0's
//! gamma_a_zx is 4.0σ off even when IMU 0 is calibrated alone); its
//! exports are a joint result's (Kalibr's IMU list with each IMU's T_i_b
//! relative to IMU 0, one file per IMU, or IMU J alone with `--imu J`).

mod common;

use common::{robimu_ok, s};
use robimu_session::result::{CalibrationResult, Trust};
use robimu_session::Truth;

#[test]
fn two_imus_simulate_and_calibrate_within_4_sigma() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    let run = robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--imus",
        "2",
        "--duration",
        "60",
        "--seed",
        "5",
        "--out",
        s(&dir),
    ]);
    assert!(run.stdout.contains("2 IMUs"), "{}", run.stdout);
    for f in ["imu.csv", "imu1.csv", "truth.toml"] {
        assert!(dir.join(f).is_file(), "{f} not written");
    }
    assert!(!dir.join("imu2.csv").exists());
    let out = tmp.path().join("r.json");
    let run = robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    assert!(
        run.stdout.contains("estimating 58 parameters"),
        "{}",
        run.stdout
    );
    let result = CalibrationResult::read(&out).unwrap();
    assert_eq!(result.parameters.len(), 58);
    assert_eq!(result.covariance.names.len(), 58);
    assert_eq!(result.parameters[30].name, "imu1/p_imu_x");
    assert!(result.parameter("imu1/tau").is_some());
    assert!(result.parameter("imu1/g_x").is_none());
    let verdict = result.verdict.as_ref().unwrap();
    assert_ne!(verdict.trust, Trust::Bad, "{verdict:?}");
    let offsets = verdict.checks.iter().filter(|c| c.topic == "time offset");
    assert_eq!(offsets.count(), 2, "a τ test per IMU: {verdict:?}");
    let residuals = verdict
        .checks
        .iter()
        .find(|c| c.topic == "residuals")
        .unwrap();
    assert!(residuals.text.contains("imu1/gz"), "{}", residuals.text);

    let worst = worst_z(&dir, &out);
    exports_take_one_imu_at_a_time(tmp.path(), &out, &result);
    kalibr_list_of_two_imus(tmp.path(), &out, &result);
    assert!(
        worst.0 < 4.0,
        "{} is {:.2}σ from its truth",
        worst.1,
        worst.0
    );
}

/// R = Rz(r_z)·Ry(r_y)·Rx(r_x) (docs/model.md §3) of the sensor rotation
/// `prefix` (`r_a_`, `imu1/r_a_`) of `r`, written out element by element.
fn rotation_zyx(r: &CalibrationResult, prefix: &str) -> [[f64; 3]; 3] {
    let v = |axis: &str| r.parameter(&format!("{prefix}{axis}")).unwrap().value;
    let (z, y, x) = (v("z"), v("y"), v("x"));
    let (cz, sz, cy, sy, cx, sx) = (z.cos(), z.sin(), y.cos(), y.sin(), x.cos(), x.sin());
    [
        [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
        [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
        [-sy, cy * sx, cy * cx],
    ]
}

/// Kalibr's files of a two-IMU pose result without `--imu`: the IMU list
/// (`imu0:`, `imu1:`) at --out and list0.yaml, list1.yaml beside it; IMU 1's
/// T_i_b is [C | C·(p_0 − p_1)] with C IMU 1's accelerometer rotation and
/// p_j the positions p_imu on the body, its time_offset τ_1 − τ_0, all
/// computed here from the result's parameters.
fn kalibr_list_of_two_imus(tmp: &std::path::Path, out: &std::path::Path, r: &CalibrationResult) {
    let yaml = tmp.join("list.yaml");
    let run = robimu_ok([
        "export",
        "--calibration",
        s(out),
        "--format",
        "kalibr",
        "--out",
        s(&yaml),
    ]);
    for f in ["list.yaml", "list0.yaml", "list1.yaml"] {
        assert!(run.stdout.contains(f), "{f} not written: {}", run.stdout);
    }
    let read = |f: &str| -> serde_yaml::Value {
        serde_yaml::from_str(&std::fs::read_to_string(tmp.join(f)).unwrap()).unwrap()
    };
    let list = read("list.yaml");
    assert!(list["imu2"].is_null());
    let value = |n: &str| r.parameter(n).unwrap().value;
    for (j, prefix) in [(0usize, ""), (1, "imu1/")] {
        let c = rotation_zyx(r, &format!("{prefix}r_a_"));
        let d: Vec<f64> = ["x", "y", "z"]
            .iter()
            .map(|a| value(&format!("p_imu_{a}")) - value(&format!("{prefix}p_imu_{a}")))
            .collect();
        let dt = value(&format!("{prefix}tau")) - value("tau");
        // the list's entry and the file Kalibr's --imu reads carry the same
        for entry in [&list[format!("imu{j}")], &read(&format!("list{j}.yaml"))] {
            let t: Vec<Vec<f64>> = serde_yaml::from_value(entry["T_i_b"].clone()).unwrap();
            for row in 0..3 {
                let want_t: f64 = (0..3).map(|k| c[row][k] * d[k]).sum();
                assert!(
                    (t[row][3] - want_t).abs() < 1e-12,
                    "imu{j} T_i_b[{row}][3]: {t:?}"
                );
                for col in 0..3 {
                    assert!(
                        (t[row][col] - c[row][col]).abs() < 1e-12,
                        "imu{j} C_i_b: {t:?}"
                    );
                }
            }
            let offset = entry["time_offset"].as_f64().unwrap();
            assert!(
                (offset - dt).abs() < 1e-15,
                "imu{j} time_offset {offset} vs {dt}"
            );
            assert_eq!(
                entry["rostopic"].as_str(),
                Some(format!("/imu{j}").as_str())
            );
        }
    }
    // IMU 1 really sits elsewhere: its translation is not zero
    let t1: Vec<Vec<f64>> = serde_yaml::from_value(list["imu1"]["T_i_b"].clone()).unwrap();
    assert!((0..3).any(|row| t1[row][3].abs() > 1e-3), "{t1:?}");
    // the correction: one file per IMU, IMU 1's with its own bias
    let corr = tmp.join("corr.toml");
    robimu_ok([
        "export",
        "--calibration",
        s(out),
        "--format",
        "correction",
        "--out",
        s(&corr),
    ]);
    let c1 = std::fs::read_to_string(tmp.join("corr1.toml")).unwrap();
    assert!(c1.contains(&format!("{}", value("imu1/b_a_x"))), "{c1}");
    assert!(tmp.join("corr0.toml").is_file() && !corr.exists());
}

/// Kalibr's imu.yaml and the correction file of one IMU of a two-IMU pose
/// result (`--imu J`), IMU 1's from its `imu1/` parameters; `correct` of
/// imu1.csv uses IMU 1's.
fn exports_take_one_imu_at_a_time(
    tmp: &std::path::Path,
    out: &std::path::Path,
    r: &CalibrationResult,
) {
    let yaml = tmp.join("imu.yaml");
    let args = |extra: &[&str]| {
        let mut a = vec![
            "export",
            "--calibration",
            s(out),
            "--format",
            "kalibr",
            "--out",
            s(&yaml),
        ];
        a.extend_from_slice(extra);
        a.iter().map(|v| v.to_string()).collect::<Vec<String>>()
    };
    robimu_ok(args(&["--imu", "1"]));
    // IMU 1 alone in the form Kalibr's --imu reads (the keys at the top)
    let text = std::fs::read_to_string(&yaml).unwrap();
    assert!(text.contains("IMU 1 alone"), "{text}");
    let y: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
    assert_eq!(y["rostopic"].as_str(), Some("/imu1"), "{text}");
    let t_i_b: Vec<Vec<f64>> = serde_yaml::from_value(y["T_i_b"].clone()).unwrap();
    assert_eq!(t_i_b.len(), 4);
    let corr = tmp.join("c.toml");
    robimu_ok([
        "export",
        "--calibration",
        s(out),
        "--format",
        "correction",
        "--imu",
        "1",
        "--out",
        s(&corr),
    ]);
    let c = std::fs::read_to_string(&corr).unwrap();
    // IMU 1's accelerometer bias, not IMU 0's
    let b1 = r.parameter("imu1/b_a_x").unwrap().value;
    let b0 = r.parameter("b_a_x").unwrap().value;
    assert!(
        c.contains(&format!("{b1}")) && !c.contains(&format!("{b0}")),
        "{c}"
    );
    let session = tmp.join("s");
    let corrected = tmp.join("imu1_corrected.csv");
    robimu_ok([
        "correct",
        "--calibration",
        s(out),
        s(&session.join("imu1.csv")),
        "--out",
        s(&corrected),
    ]);
    assert!(corrected.is_file());
}

/// `[imu1.mount]` in a two-IMU pose session's session.toml is IMU 1's
/// prior (docs/model.md §7.9, §9): a position 1 cm off the truth with
/// σ = 1 µm pins `imu1/p_imu_*` there, while IMU 0's keep §10's prior; a
/// rotation mean with its σ reaches the result as `imu1/r_a_*`'s prior.
#[test]
fn imu1_mount_prior_reaches_the_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--imus",
        "2",
        "--duration",
        "30",
        "--seed",
        "3",
        "--out",
        s(&dir),
    ]);
    let truth = Truth::read(&dir.join("truth.toml")).unwrap();
    let t = |n: &str| truth.get(n).unwrap();
    let pinned = [
        t("imu1/p_imu_x") + 0.01,
        t("imu1/p_imu_y"),
        t("imu1/p_imu_z"),
    ];
    let r_a = [t("imu1/r_a_z"), t("imu1/r_a_y"), t("imu1/r_a_x")];
    let toml_path = dir.join("session.toml");
    let mut text = std::fs::read_to_string(&toml_path).unwrap();
    text.push_str(&format!(
        "\n[imu1.mount]\nposition = {pinned:?}\nposition_sigma = 1e-6\nr_a = {r_a:?}\nrotation_sigma = 0.02\n"
    ));
    std::fs::write(&toml_path, text).unwrap();
    let out = tmp.path().join("r.json");
    robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    let r = CalibrationResult::read(&out).unwrap();
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let p = r.parameter(&format!("imu1/p_imu_{axis}")).unwrap();
        assert_eq!((p.prior, p.prior_sigma), (pinned[k], 1e-6), "{p:?}");
        assert!((p.value - pinned[k]).abs() < 5e-6, "{p:?} not pinned");
        assert!(p.sigma <= 1e-6, "{p:?}");
        let p0 = r.parameter(&format!("p_imu_{axis}")).unwrap();
        assert_eq!((p0.prior, p0.prior_sigma), (0.0, 0.2), "{p0:?}");
    }
    // IMU 0's position, under §10's prior, is still found from the data
    let p0 = r.parameter("p_imu_x").unwrap();
    assert!((p0.value - t("p_imu_x")).abs() < 4.0 * p0.sigma, "{p0:?}");
    for (k, axis) in ["z", "y", "x"].iter().enumerate() {
        let p = r.parameter(&format!("imu1/r_a_{axis}")).unwrap();
        assert_eq!((p.prior, p.prior_sigma), (r_a[k], 0.02), "{p:?}");
        assert!(p.sigma < 0.02, "{p:?}");
        let p0 = r.parameter(&format!("r_a_{axis}")).unwrap();
        assert_eq!(p0.prior_sigma, std::f64::consts::PI, "{p0:?}");
    }
}

/// The largest |estimate − truth| / σ over the result at `out` against the
/// session's truth.toml in `dir` (angles compared modulo 2π), and its name.
fn worst_z(dir: &std::path::Path, out: &std::path::Path) -> (f64, String) {
    let result = CalibrationResult::read(out).unwrap();
    let truth = Truth::read(&dir.join("truth.toml")).unwrap();
    let tau = std::f64::consts::TAU;
    let mut worst = (0.0f64, String::new());
    for p in &result.parameters {
        let mut d = p.value - truth.get(&p.name).unwrap();
        if p.unit == "rad" {
            d -= tau * (d / tau).round();
        }
        if (d / p.sigma).abs() > worst.0 {
            worst = ((d / p.sigma).abs(), p.name.clone());
        }
    }
    worst
}

/// `simulate --source poses --robot aubo_i5 --imus 2`: the flange carries
/// the robot's two IMUs as `simulate --robot aubo_i5 --imus 2` places them
/// (imu.csv and imu1.csv byte for byte those of the joint session of the
/// same seed, IMU 1's position truth its `imu1/eps_6_*`), and `calibrate`
/// finds all 58 within 4σ of the truth.
#[test]
fn two_imus_on_a_robots_flange() {
    let tmp = tempfile::tempdir().unwrap();
    let (poses, joints) = (tmp.path().join("p"), tmp.path().join("j"));
    let common = [
        "--robot",
        "aubo_i5",
        "--imus",
        "2",
        "--duration",
        "60",
        "--seed",
        "4",
    ];
    let mut args = vec![
        "simulate",
        "--source",
        "poses",
        "--rate",
        "100",
        "--out",
        s(&poses),
    ];
    args.extend(common);
    let run = robimu_ok(args);
    assert!(run.stdout.contains("2 IMUs"), "{}", run.stdout);
    let mut args = vec!["simulate", "--rate", "100", "--out", s(&joints)];
    args.extend(common);
    robimu_ok(args);
    for f in ["imu.csv", "imu1.csv"] {
        let read = |d: &std::path::Path| std::fs::read(d.join(f)).unwrap();
        assert!(
            read(&poses) == read(&joints),
            "{f} differs from the joint session's"
        );
    }
    let (tp, tj) = (
        Truth::read(&poses.join("truth.toml")).unwrap(),
        Truth::read(&joints.join("truth.toml")).unwrap(),
    );
    assert_eq!(tp.values.len(), 58);
    for (pose, joint) in [
        ("imu1/p_imu_x", "imu1/eps_6_1"),
        ("imu1/p_imu_z", "imu1/eps_6_3"),
        ("imu1/tau", "imu1/tau"),
        ("imu1/k_w_y", "imu1/k_w_y"),
        ("g_x", "g_x"),
        ("p_imu_y", "eps_6_2"),
    ] {
        assert_eq!(tp.get(pose), tj.get(joint), "{pose}");
    }
    let out = tmp.path().join("r.json");
    let run = robimu_ok(["calibrate", s(&poses), "--out", s(&out)]);
    assert!(
        run.stdout.contains("estimating 58 parameters"),
        "{}",
        run.stdout
    );
    let (z, name) = worst_z(&poses, &out);
    println!("worst |z| {z:.2} ({name})");
    assert!(z < 4.0, "{name} is {z:.2}σ from its truth");
}
