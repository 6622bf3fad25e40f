//! `robimu report`, `robimu export` and `robimu correct` on a pose session's
//! result (issue 39 item 2, docs/model.md §7.9): the HTML report has the
//! verdict, the 30 parameters with σ and the residuals' RMS; Kalibr's
//! imu.yaml and the correction file carry the calibrated intrinsics (checked
//! against the result's own numbers and by applying them to the simulated
//! truth's sensor model); `correct` inverts the sensor model; the robot
//! formats fail saying a pose session has no robot.

mod common;

use std::path::Path;

use common::{robimu, robimu_ok, s};
use robimu_model::ImuIntrinsics;
use robimu_session::result::{CalibrationResult, NoiseModelRecord};
use robimu_session::{read_table, Columns, PoseSession, IMU_COLUMNS};

/// A simulated, calibrated pose session: (session dir, result.json).
fn calibrated(tmp: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let dir = tmp.join("s");
    robimu_ok([
        "simulate",
        "--source",
        "poses",
        "--duration",
        "40",
        "--seed",
        "7",
        "--out",
        s(&dir),
    ]);
    let result = tmp.join("result.json");
    let report = tmp.join("fit-report");
    let run = robimu_ok([
        "calibrate",
        s(&dir),
        "--out",
        s(&result),
        "--report",
        s(&report),
    ]);
    assert!(
        run.stdout.contains("result.convergence.csv"),
        "{}",
        run.stdout
    );
    (dir, result)
}

/// Sensor `s` (`a` or `w`) of the result's parameters.
fn intrinsics(r: &CalibrationResult, s: &str) -> ImuIntrinsics {
    let v = |n: String| r.parameter(&n).unwrap().value;
    let v3 = |p: &str, axes: [&str; 3]| axes.map(|a| v(format!("{p}_{s}_{a}")));
    ImuIntrinsics {
        gamma: v3("gamma", ["yz", "zy", "zx"]),
        r: v3("r", ["z", "y", "x"]),
        k: v3("k", ["x", "y", "z"]),
        b: v3("b", ["x", "y", "z"]),
    }
}

#[test]
fn report_kalibr_export_and_correct_work_on_a_pose_result() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (session, result_path) = calibrated(d);
    let result = CalibrationResult::read(&result_path).unwrap();
    assert_eq!(result.source.as_deref(), Some("poses"));

    // report: the verdict, every parameter with its σ, the residual figure
    let report_dir = d.join("report");
    robimu_ok(["report", s(&result_path), "--out", s(&report_dir)]);
    let html = std::fs::read_to_string(report_dir.join("report.html")).unwrap();
    let verdict = result.verdict.as_ref().unwrap();
    assert!(
        html.to_lowercase()
            .contains(&format!("{:?}", verdict.trust).to_lowercase()),
        "verdict {:?} not on the page",
        verdict.trust
    );
    for p in &result.parameters {
        assert!(html.contains(&p.name), "{} not on the page", p.name);
    }
    assert_eq!(result.parameters.len(), 30);
    // the calibration's whitened residual RMS, not a refitted spline's
    let rms = result.residual_rms.unwrap();
    assert!(
        html.contains(&format!("gz {:.2}", rms[5])),
        "residual RMS not on the page"
    );
    assert!(html.contains("No residual figure from the result file alone"));
    assert!(!html.contains("Joint trajectory"));
    assert!(report_dir.join("posterior_sigma.svg").is_file());
    // the convergence log `calibrate` wrote beside the result
    assert!(report_dir.join("convergence.svg").is_file());

    // `calibrate --report`: the residuals along the fit's own pose spline,
    // their RMS in the figure that of the result (whitened RMS × σ used)
    let fit_report = d.join("fit-report");
    let html = std::fs::read_to_string(fit_report.join("report.html")).unwrap();
    assert!(
        html.contains("the pose spline of the fit"),
        "no residual caption"
    );
    assert!(!html.contains("No residual figure"));
    let svg = std::fs::read_to_string(fit_report.join("residuals.svg")).unwrap();
    // the band is the fit's σ_z: session.toml's, or the identified ones
    // the result's noise model records
    let sigma_ax = match result.noise_model.as_ref().unwrap() {
        NoiseModelRecord::Ar { channels } => channels[0].sigma,
        _ => 0.38,
    };
    let want = format!("noise σ {sigma_ax:.3} m/s^2");
    assert!(svg.contains(&want), "{want} not in the residual figure");

    // Kalibr: Kalibr's equations (scale-misalignment model) with the
    // exported matrices reproduce the sensor model of the result's own
    // parameters: a = M_a·C_i_b·s + b_a, ω = M_g·C_gyro_i·C_i_b·ω_b + b_g
    let yaml = d.join("imu.yaml");
    let run = robimu_ok([
        "export",
        "--calibration",
        s(&result_path),
        "--format",
        "kalibr",
        "--out",
        s(&yaml),
    ]);
    assert!(run.stdout.contains("wrote"), "{}", run.stdout);
    let yaml_text = std::fs::read_to_string(&yaml).unwrap();
    assert!(
        yaml_text.contains("axes of the posed body B"),
        "{yaml_text}"
    );
    assert!(!yaml_text.contains("flange"), "{yaml_text}");
    let y: serde_yaml::Value = serde_yaml::from_str(&yaml_text).unwrap();
    let imu0 = &y["imu0"];
    assert_eq!(imu0["model"].as_str(), Some("scale-misalignment"));
    let pose = PoseSession::read(&session).unwrap();
    let rate = pose.imus[0].samples.median_rate().unwrap();
    assert!((imu0["update_rate"].as_f64().unwrap() - rate).abs() < 1e-9 * rate);
    let m3 = |v: &serde_yaml::Value| -> [[f64; 3]; 3] {
        let rows: Vec<Vec<f64>> = serde_yaml::from_value(v.clone()).unwrap();
        std::array::from_fn(|r| std::array::from_fn(|c| rows[r][c]))
    };
    let v3 = |v: &serde_yaml::Value| -> [f64; 3] {
        let x: Vec<f64> = serde_yaml::from_value(v.clone()).unwrap();
        [x[0], x[1], x[2]]
    };
    let mul = |m: &[[f64; 3]; 3], v: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|r| (0..3).map(|c| m[r][c] * v[c]).sum())
    };
    let t_i_b: Vec<Vec<f64>> = serde_yaml::from_value(imu0["T_i_b"].clone()).unwrap();
    let c_i_b: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| t_i_b[r][c]));
    let (acc, gyr) = (intrinsics(&result, "a"), intrinsics(&result, "w"));
    for (sf, w) in [
        ([1.2, -9.6, 2.3], [0.7, -1.9, 2.6]),
        ([-4.0, 3.0, 8.5], [-2.2, 0.4, -1.1]),
    ] {
        let a = mul(&m3(&imu0["accelerometers"]["M"]), mul(&c_i_b, sf));
        let b_a = v3(&imu0["accelerometers"]["b"]);
        let g_b = mul(&m3(&imu0["gyroscopes"]["C_gyro_i"]), mul(&c_i_b, w));
        let g = mul(&m3(&imu0["gyroscopes"]["M"]), g_b);
        let b_g = v3(&imu0["gyroscopes"]["b"]);
        let (za, zw) = (acc.apply(sf), gyr.apply(w));
        for k in 0..3 {
            assert!(
                (a[k] + b_a[k] - za[k]).abs() < 1e-9,
                "accel {k}: {a:?} vs {za:?}"
            );
            assert!(
                (g[k] + b_g[k] - zw[k]).abs() < 1e-9,
                "gyro {k}: {g:?} vs {zw:?}"
            );
        }
    }

    // correction file: z = M·v + b per sensor
    let corr = d.join("correction.toml");
    robimu_ok([
        "export",
        "--calibration",
        s(&result_path),
        "--format",
        "correction",
        "--out",
        s(&corr),
    ]);
    let c: toml::Table = toml::from_str(&std::fs::read_to_string(&corr).unwrap()).unwrap();
    let floats = |v: &toml::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_float().unwrap())
            .collect()
    };
    for (want, name) in [(&acc, "accelerometer"), (&gyr, "gyroscope")] {
        let b = floats(&c[name]["bias"]);
        let m: Vec<Vec<f64>> = c[name]["matrix"]
            .as_array()
            .unwrap()
            .iter()
            .map(floats)
            .collect();
        let v = [0.3, -1.2, 9.4];
        let z = want.apply(v);
        for i in 0..3 {
            let mv: f64 = (0..3).map(|k| m[i][k] * v[k]).sum::<f64>() + b[i];
            assert!((mv - z[i]).abs() < 1e-9, "{name} row {i}: {mv} vs {}", z[i]);
        }
    }

    // correct: the corrected samples, put through the sensor model again,
    // give the raw samples back
    let imu = session.join("imu.csv");
    let out = d.join("corrected.csv");
    robimu_ok([
        "correct",
        "--calibration",
        s(&result_path),
        s(&imu),
        "--out",
        s(&out),
    ]);
    let raw = read_table(&imu, Columns::Fixed(&IMU_COLUMNS)).unwrap();
    let fixed = read_table(&out, Columns::Fixed(&IMU_COLUMNS)).unwrap();
    assert_eq!(raw.len(), fixed.len());
    for i in (0..raw.len()).step_by(97) {
        let (r, f) = (raw.row(i), fixed.row(i));
        let za = acc.apply([f[0], f[1], f[2]]);
        let zw = gyr.apply([f[3], f[4], f[5]]);
        for k in 0..3 {
            assert!((za[k] - r[k]).abs() < 1e-9, "sample {i} accel {k}");
            assert!((zw[k] - r[3 + k]).abs() < 1e-12, "sample {i} gyro {k}");
        }
    }

    // the robot formats cannot apply: named, no panic
    for format in ["urdf", "toml", "ur-kinematics", "ros2-control"] {
        robimu([
            "export",
            "--calibration",
            s(&result_path),
            "--format",
            format,
            "--out",
            s(&d.join("x.out")),
        ])
        .assert_fails(&["a pose session has no robot", &format!("--format {format}")]);
    }
    robimu([
        "export",
        "--calibration",
        s(&result_path),
        "--format",
        "kalibr",
        "--robot",
        "ur5e",
        "--out",
        s(&d.join("y.yaml")),
    ])
    .assert_fails(&["--robot: a pose session has no robot"]);
}
