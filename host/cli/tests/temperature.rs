//! Temperature-following biases (docs/model.md §4.5): a simulated warm-up
//! read in whole degrees, with biases linear in the true temperature, is
//! diagnosed as `temperature_bias`, its coefficients and the baseline
//! recovered; the same through `simulate --temperature`, `calibrate
//! --effects` and `diagnose`, and the errors of sessions without one.

use robimu_model::effects;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_workflows::calibrate::fit::Fit;
use robimu_workflows::calibrate::CalibrateOptions;
use robimu_workflows::diagnose::{diagnose, setup_for, AddedParameter, DiagnoseOptions};
use robimu_workflows::simulate::{random_session, simulate, SimulateOptions, WarmUpTemperature};

mod common;
use common::{robimu, robimu_ok, s};

/// One milli-g, m/s².
const MG: f64 = 9.80665e-3;

/// Twice the datasheet's typical TCO: accelerometer mg/K, gyroscope °/s/K.
fn coefficients() -> [f64; 6] {
    let deg = std::f64::consts::PI / 180.0;
    [
        2.0 * MG,
        -1.2 * MG,
        1.6 * MG,
        0.030 * deg,
        -0.021 * deg,
        0.015 * deg,
    ]
}

/// A 90 s session (truth from the priors, τ = 0.05 s) warming up from 22 °C
/// towards 34 °C with τ = 30 s: `temp_c` in whole degrees, every channel's
/// bias k_c (T(t) − T̄) with T the true curve and T̄ its mean over the
/// samples (so the truth's biases are those at T̄). The injection is written
/// out here, not through the effect's code.
fn warm_session(seed: u64) -> (Robot, Measurements, Vec<f64>, [f64; 6], f64) {
    let robot = Robot::aubo_i5();
    let opts = SimulateOptions::paper(&robot);
    let mut s = random_session(&robot, 90.0, 1.0, &opts, seed).unwrap();
    let layout = ParamLayout::new(&robot);
    s.truth[layout.offsets().tau] = 0.05;
    let mut data = simulate(&robot, &layout, &s.truth, &s.trajectory, &opts, seed).unwrap();
    let warm = WarmUpTemperature::new(22.0, 34.0, 30.0).unwrap();
    let temp = warm.values(&data.imu_t);
    let mean = temp.iter().sum::<f64>() / temp.len() as f64;
    let k = coefficients();
    for (z, t) in data.imu_z.iter_mut().zip(&temp) {
        for c in 0..6 {
            z[c] += k[c] * (t - mean);
        }
    }
    data.imu_temp = Some(warm.readings(&data.imu_t));
    (robot, data, s.truth, k, mean)
}

/// Every baseline parameter of `f` within 4σ of `truth` and the whitened
/// residual RMS within 10 % of 1; the worst |z|.
fn check_baseline(f: &Fit, truth: &[f64], robot: &Robot) -> f64 {
    let rms = f.residual_rms();
    assert!(
        rms.iter().all(|r| (r - 1.0).abs() <= 0.1),
        "residual RMS {rms:?}"
    );
    let layout = ParamLayout::new(robot);
    let mut worst = (0.0, String::new());
    for (k, spec) in layout.specs().iter().enumerate() {
        if f.sigma_x[k] > 0.0 {
            let z = ((f.x[k] - truth[k]) / f.sigma_x[k]).abs();
            if z > worst.0 {
                worst = (z, spec.name.clone());
            }
        }
    }
    println!("worst baseline parameter {} at {:.2} σ", worst.1, worst.0);
    assert!(worst.0 < 4.0, "{} off by {:.2} σ", worst.1, worst.0);
    worst.0
}

/// The warm-up must-show (issue 15): diagnose names `temperature_bias`
/// first and adds nothing else; its six coefficients are within 4σ of the
/// injected ones, and every baseline parameter within 4σ of the truth. The
/// truth's biases are those at the true mean temperature; the fit's are at
/// the reference of the smoothed whole-degree readings, so the truth is
/// moved by k (T_ref − T̄) (the definition of b, not a tolerance).
/// `bias_drift` explains nearly the same signal while the temperature
/// rises monotonically (printed: its score against temperature_bias's);
/// it loses on p-value (12 against 6 degrees of freedom) and is not
/// significant once temperature_bias is in.
#[test]
fn a_warm_up_is_named_temperature_bias_and_recovered() {
    let (robot, data, mut truth, k, mean) = warm_session(71);
    let setup = setup_for(&robot, &data, None);
    let track = setup.temperature.clone().expect("the readings vary");
    println!(
        "track: reference {:.3} °C (true mean {mean:.3}), range {:.2} K, knots every {:.1} s",
        track.reference(),
        track.range(),
        track.knot_spacing()
    );
    let opts = CalibrateOptions::new(&robot);
    let d = diagnose(
        &robot,
        &data,
        &opts,
        &setup,
        &DiagnoseOptions::default(),
        |_| {},
    )
    .unwrap();
    let names: Vec<&str> = d.found.iter().map(|f| f.name.as_str()).collect();
    let first = &d.found[0];
    let score = |n: &str| {
        let s = first.scores.iter().find(|s| s.name == n).unwrap();
        (s.statistic, s.dof, s.p_value)
    };
    println!(
        "found {names:?}; first round: temperature_bias {:?}, bias_drift {:?}; last round {:?}",
        score("temperature_bias"),
        score("bias_drift"),
        d.last_scores
            .iter()
            .map(|s| (s.name.as_str(), s.statistic))
            .collect::<Vec<_>>()
    );
    assert_eq!(names, ["temperature_bias"]);
    assert!(first.p_value < d.threshold);
    for (
        c,
        (
            AddedParameter {
                name,
                value: v,
                sigma,
                ..
            },
            want,
        ),
    ) in first.parameters.iter().zip(k).enumerate()
    {
        let z = (v - want) / sigma;
        println!("{name}: {v:.4e} ± {sigma:.1e} (injected {want:.4e}, {z:+.2} σ)");
        assert!(z.abs() < 4.0, "channel {c}: {name} {v} ± {sigma} vs {want}");
    }
    let layout = ParamLayout::new(&robot);
    let biases = ["b_a_x", "b_a_y", "b_a_z", "b_w_x", "b_w_y", "b_w_z"];
    for (c, b) in biases.iter().enumerate() {
        let i = layout.specs().iter().position(|s| s.name == *b).unwrap();
        truth[i] += k[c] * (track.reference() - mean);
    }
    check_baseline(&d.final_fit, &truth, &robot);
}

/// Through the CLI: `simulate --temperature` writes whole-degree readings
/// of the warm-up, `--effect temperature_bias=M` biases along it, and
/// `calibrate --effects temperature_bias` gets the injected coefficients
/// within 4σ; the effect is refused, saying why, where the session has no
/// temperature, and a malformed warm-up is refused.
#[test]
fn cli_simulate_with_a_warm_up_then_calibrate_the_temperature_coefficients() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("warm");
    robimu_ok([
        "simulate",
        "--duration",
        "40",
        "--seed",
        "5",
        "--temperature",
        "24,34,20",
        "--effect",
        "temperature_bias=3",
        "--out",
        s(&session),
    ]);
    let imu = std::fs::read_to_string(session.join("imu.csv")).unwrap();
    let mut lines = imu.lines();
    assert!(lines.next().unwrap().ends_with(",temp_c"));
    let rows: Vec<(f64, f64)> = lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[0], v[v.len() - 1])
        })
        .collect();
    // T = 34 − 10 e^{−t/20}, rounded to whole degrees
    for (t, temp) in &rows {
        let want = (34.0 - 10.0 * (-(t - rows[0].0) / 20.0).exp()).round();
        assert_eq!(*temp, want, "t = {t}");
    }
    assert!(rows.last().unwrap().1 - rows[0].1 >= 8.0);
    let run = robimu_ok(["calibrate", s(&session), "--effects", "temperature_bias"]);
    assert!(run.stdout.contains("temperature_bias.gx"), "{}", run.stdout);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(session.join("effects.json")).unwrap())
            .unwrap();
    // the injected pattern: the effect's documented `injection`
    let robot = Robot::aubo_i5();
    let mut setup = setup_for(&robot, &Measurements::default(), None);
    let ramp: Vec<f64> = (0..100).map(f64::from).collect();
    setup.set_temperature(&ramp, &ramp);
    let want = effects::by_name(&setup, "temperature_bias")
        .unwrap()
        .injection(3.0);
    let got = json["effect_parameters"].as_array().unwrap();
    assert_eq!(got.len(), 6);
    for (p, w) in got.iter().zip(&want) {
        let (v, sigma) = (p["value"].as_f64().unwrap(), p["sigma"].as_f64().unwrap());
        println!("{}: {v:.4e} ± {sigma:.1e} vs {w:.4e}", p["name"]);
        assert!(((v - w) / sigma).abs() < 4.0, "{p} vs {w}");
    }
    // T_ref, the temperature the baseline biases refer to: the mean of the
    // smoothed track, against the mean of the true warm-up curve
    let t_ref = json["effect_constants"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "temperature_bias.t_ref")
        .expect("effects.json names T_ref")["value"]
        .as_f64()
        .unwrap();
    let true_mean = rows
        .iter()
        .map(|(t, _)| 34.0 - 10.0 * (-(t - rows[0].0) / 20.0).exp())
        .sum::<f64>()
        / rows.len() as f64;
    assert!(
        (t_ref - true_mean).abs() < 0.25,
        "T_ref {t_ref} vs {true_mean}"
    );
    // no temperature column: refused with what it needs
    let plain = dir.path().join("plain");
    robimu([
        "simulate",
        "--duration",
        "20",
        "--effect",
        "temperature_bias=1",
        "--out",
        s(&plain),
    ])
    .assert_fails(&["temperature_bias", "not available", "temperature column"]);
    robimu_ok(["simulate", "--duration", "20", "--out", s(&plain)]);
    robimu(["calibrate", s(&plain), "--effects", "temperature_bias"])
        .assert_fails(&["--effects", "temperature column"]);
    robimu(["diagnose", s(&plain), "--candidates", "temperature_bias"])
        .assert_fails(&["--candidates", "not available"]);
    for bad in ["24,34", "24,x,20", "24,34,0"] {
        robimu([
            "simulate",
            "--duration",
            "20",
            "--temperature",
            bad,
            "--out",
            s(&plain),
        ])
        .assert_fails(&["--temperature", bad]);
    }
}

/// The rig's warm-up (`SimRigConfig::warm_up`: die temperature and biases
/// along one exponential from power-up, the `TEMP` register in whole
/// degrees) in a 75 s recording in real time, biases of twice the typical
/// TCO: diagnose (without `resonance`, see below) names `temperature_bias`
/// and nothing else, its coefficients within 4σ of the hidden ones, and
/// with it every baseline parameter is within 4σ of the truth's at the
/// session's reference temperature. Run by hand:
/// `cargo test -p robimu --test temperature -- --ignored --nocapture`.
#[test]
#[ignore = "records 75 s in real time"]
fn a_rig_recording_of_a_warm_up_is_diagnosed() {
    use robimu_hil::rig::{SimRig, SimRigConfig, WarmUp};
    use robimu_record::controller::RobotSpec;
    use robimu_record::motion::Plan;
    use robimu_record::{record, RecordOptions};
    use robimu_session::Session;

    let robot = Robot::aubo_i5();
    let k = coefficients();
    let (start, end) = (22.0, 34.0);
    let mut config = SimRigConfig::drawn(robot.clone(), 31);
    config.warm_up = Some(WarmUp {
        time_constant_s: 30.0,
        temp_start_c: start,
        temp_end_c: end,
        bias_start_offset: k.map(|v| v * (start - end)),
    });
    let mut rng = <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(31);
    let traj = robimu_model::trajectory::random_walk(&robot, 75.0, 1.0, &mut rng).unwrap();
    let rig = SimRig::spawn(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = RecordOptions {
        imu_port: rig.imu_port().to_string(),
        extra_imu_ports: Vec::new(),
        baud: 921_600,
        robot_spec: RobotSpec::parse(&rig.robot_spec()).unwrap(),
        robot: robot.clone(),
        robot_name: "aubo_i5".into(),
        plan: Some(Plan::from_spline(&traj, 250.0)),
        duration: 0.0,
        out: dir.path().to_path_buf(),
        joint_rate: 125.0,
        rest: 1.0,
        sensor: robimu_protocol::SensorConfig::default(),
        interrupt: None,
    };
    record(&opts, &mut |_| {}).unwrap();
    let truth = rig.truth().clone();
    drop(rig);
    let data = Session::load(dir.path()).unwrap().measurements();
    let temp = data.imu_temp.as_deref().unwrap();
    let setup = setup_for(&robot, &data, None);
    let track = setup.temperature.clone().expect("the temperature varies");
    println!(
        "recorded {} IMU samples, {:.0} → {:.0} °C; track reference {:.2} °C, range {:.2} K, knots every {:.1} s",
        data.imu_t.len(),
        temp[0],
        temp[temp.len() - 1],
        track.reference(),
        track.range(),
        track.knot_spacing()
    );
    let opts = CalibrateOptions::new(&robot);
    // the rig's recordings show a discrepancy proportional to q̈ that
    // `resonance` takes up with or without a warm-up (score 241 on a 75 s
    // recording at 25 °C); it is left out here
    let mut dopts = DiagnoseOptions::default();
    dopts.candidates.retain(|c| c != "resonance");
    let d = diagnose(&robot, &data, &opts, &setup, &dopts, |_| {}).unwrap();
    let names: Vec<&str> = d.found.iter().map(|f| f.name.as_str()).collect();
    let first = &d.found[0];
    let score = |n: &str| {
        let s = first.scores.iter().find(|s| s.name == n).unwrap();
        (s.statistic, s.dof, s.p_value)
    };
    println!(
        "found {names:?}; first round: temperature_bias {:?}, bias_drift {:?}",
        score("temperature_bias"),
        score("bias_drift")
    );
    assert_eq!(names, ["temperature_bias"]);
    for (
        AddedParameter {
            name,
            value: v,
            sigma,
            ..
        },
        want,
    ) in first.parameters.iter().zip(k)
    {
        let z = (v - want) / sigma;
        println!("{name}: {v:.4e} ± {sigma:.1e} (hidden {want:.4e}, {z:+.2} σ)");
        assert!(z.abs() < 4.0, "{name}");
    }
    // the truth's biases are the settled ones (at 34 °C); the fit's are at
    // the reference temperature
    let layout = ParamLayout::new(&robot);
    let biases = ["b_a_x", "b_a_y", "b_a_z", "b_w_x", "b_w_y", "b_w_z"];
    let mut x = truth.vector(&layout).unwrap();
    for (c, b) in biases.iter().enumerate() {
        let i = layout.specs().iter().position(|s| s.name == *b).unwrap();
        x[i] += k[c] * (track.reference() - end);
    }
    check_baseline(&d.final_fit, &x, &robot);
}
