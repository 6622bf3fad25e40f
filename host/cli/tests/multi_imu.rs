//! Several IMUs in one session (docs/model.md §9): the joint fit is
//! consistent (a small Monte Carlo whose bounds fail on a wrong σ), the
//! shared parameters gain from every IMU, and `robimu simulate --imus`,
//! `calibrate` (joint) and `calibrate --imu J` work end to end.

use robimu_model::{ParamLayout, Robot};
use robimu_session::result::CalibrationResult;
use robimu_session::Truth;
use robimu_workflows::calibrate::noise_choice::NoiseChoice;
use robimu_workflows::calibrate::CalibrateOptions;
use robimu_workflows::montecarlo::{monte_carlo, MonteCarloOptions};
use robimu_workflows::simulate::SimulateOptions;

mod common;
use common::{robimu, robimu_ok, s};

/// error/σ pooled over a group of parameters and the runs: mean and std.
fn pooled(z: &[f64]) -> (f64, f64) {
    let n = z.len() as f64;
    let mean = z.iter().sum::<f64>() / n;
    let var = z.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// 12 runs of 40 s with two IMUs, truths from the priors. Pooled over the
/// runs, error/σ of IMU 0's own, IMU 1's own and the shared parameters each
/// has std within 0.15 of 1 (≥ 240 values each: a σ 20 % off fails), and
/// the shared angles' σ shrink by more than 1.2 against IMU 0 alone (√2 ideal).
#[test]
fn two_imu_monte_carlo_is_consistent_and_the_shared_sigma_shrink() {
    let robot = Robot::aubo_i5();
    let runs = 12;
    let opts = MonteCarloOptions {
        runs,
        duration: 40.0,
        seed: 3000,
        simulate: SimulateOptions::paper(&robot),
        calibrate: CalibrateOptions::new(&robot),
        noise: NoiseChoice::White,
        n_imus: 2,
        compare_imu0: true,
    };
    let res = monte_carlo(&robot, &opts, |_, _| {}).unwrap();
    let layout = ParamLayout::with_imus(&robot, 2);
    assert_eq!(res.dof, 76);
    let one = layout.imu_layout();
    let groups: [(&str, Vec<usize>); 3] = [
        ("shared", (0..48).filter(|&k| !one.is_per_imu(k)).collect()),
        ("IMU 0", (0..48).filter(|&k| one.is_per_imu(k)).collect()),
        ("IMU 1", (48..76).collect()),
    ];
    for (name, members) in &groups {
        let z: Vec<f64> = res
            .runs
            .iter()
            .flat_map(|r| {
                members
                    .iter()
                    .map(|&k| (r.estimate[k] - r.truth[k]) / r.sigma[k])
            })
            .collect();
        let (mean, std) = pooled(&z);
        eprintln!("{name}: {} values, mean {mean:+.3}, std {std:.3}", z.len());
        assert!(z.len() >= 240);
        assert!(mean.abs() < 0.15, "{name}: mean(error/σ) {mean:.3}");
        assert!((std - 1.0).abs() < 0.15, "{name}: std(error/σ) {std:.3}");
    }
    let gain = res.shared_sigma_gain(&layout);
    for (name, g) in &gain {
        eprintln!("{name}: σ(IMU 0 alone)/σ(both) {g:.3}");
    }
    let angles: Vec<&(String, f64)> = gain
        .iter()
        .filter(|(n, _)| {
            let k = one.index_of(n).unwrap();
            one.estimated_errors()
                .get(k)
                .is_some_and(|e| !e.is_translation())
        })
        .collect();
    assert_eq!(angles.len(), 9);
    for (name, g) in angles {
        assert!(*g > 1.2 && *g < 1.6, "{name}: gain {g:.3}");
    }
}

/// The study of issue 41 item 6: two IMUs, IMU 0 white at σ_z, IMU 1's
/// accelerometer AR(1) φ = 0.9 (75 ms at 120 Hz), simulated per IMU
/// ([`SimulateOptions::imu_noise`]) and fitted with `--noise-model auto`:
/// each IMU's noise identified from its own residuals and whitened by its
/// own model. `runs` sessions of `duration` s, seeds from `seed`; returns
/// per estimated parameter (name, mean, std of error/σ) and the runs.
fn different_noise_study(
    runs: usize,
    duration: f64,
    seed: u64,
    noise: NoiseChoice,
) -> robimu_workflows::montecarlo::MonteCarloResult {
    use robimu_model::noise::NoiseModel;
    let robot = Robot::aubo_i5();
    let sz = robot.sigma_z();
    let mut simulate = SimulateOptions::paper(&robot);
    simulate.imu_noise = vec![
        NoiseModel::white(sz).unwrap(),
        NoiseModel::ar1(sz, [Some(0.9), None], [0.0; 2]).unwrap(),
    ];
    let opts = MonteCarloOptions {
        runs,
        duration,
        seed,
        simulate,
        calibrate: CalibrateOptions::new(&robot),
        noise,
        n_imus: 2,
        compare_imu0: false,
    };
    let t0 = std::time::Instant::now();
    let res = monte_carlo(&robot, &opts, |_, _| {}).unwrap();
    let (lo, hi) = res
        .stats
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
            (lo.min(p.std), hi.max(p.std))
        });
    let refits: usize = res.runs.iter().map(|r| r.refits).sum();
    let warned = res.runs.iter().filter(|r| r.warning.is_some()).count();
    eprintln!(
        "{runs} runs of {duration} s ({:.0} s): std(error/σ) over {} parameters in [{lo:.3}, {hi:.3}]; NEES {:.1} in ({:.1}, {:.1}); {refits} refits, {warned} warnings",
        t0.elapsed().as_secs_f64(),
        res.stats.len(),
        res.nees_mean,
        res.nees_interval.0,
        res.nees_interval.1
    );
    for p in &res.stats {
        eprintln!("  {:<16} mean {:+.3} std {:.3}", p.name, p.mean, p.std);
    }
    res
}

/// std(error/σ) pooled over IMU 1's own parameters, of `res`.
fn imu1_pooled_std(res: &robimu_workflows::montecarlo::MonteCarloResult) -> f64 {
    let z: Vec<f64> = res
        .runs
        .iter()
        .flat_map(|r| (48..76).map(move |k| (r.estimate[k] - r.truth[k]) / r.sigma[k]))
        .collect();
    pooled(&z).1
}

/// [`different_noise_study`] small enough for CI: 24 runs of 40 s. Every
/// run refits with IMU 1's own AR model; pooled over the runs, error/σ of
/// the shared, IMU 0's and IMU 1's parameters each has std within 0.15 of 1,
/// every parameter's std is within [0.6, 1.45] (24 runs: the std of one
/// std is ≈ 0.15) and the average NEES is in its 95 % χ² interval
/// (measured: groups 1.001, 1.017, 0.963; parameters 0.68–1.34; NEES 75.3
/// in (71.1, 81.0)). The same sessions fitted with one white model for
/// both IMUs (what IMU 0's white residuals chose before each IMU had its
/// own) give IMU 1's pooled std above 1.5 (measured 2.83, NEES 344): the
/// bounds see the difference.
#[test]
fn two_imus_with_different_noise_each_whitened_by_its_own_are_consistent() {
    let res = different_noise_study(24, 40.0, 5000, NoiseChoice::Auto);
    assert_eq!(res.dof, 76);
    assert!(res
        .runs
        .iter()
        .all(|r| r.refits >= 1 && r.warning.is_none()));
    let (lo, hi) = res.nees_interval;
    assert!((lo..=hi).contains(&res.nees_mean), "NEES {}", res.nees_mean);
    let one = ParamLayout::with_imus(&Robot::aubo_i5(), 2);
    let per_imu = one.imu_layout();
    let groups: [(&str, Vec<usize>); 3] = [
        (
            "shared",
            (0..48).filter(|&k| !per_imu.is_per_imu(k)).collect(),
        ),
        (
            "IMU 0",
            (0..48).filter(|&k| per_imu.is_per_imu(k)).collect(),
        ),
        ("IMU 1", (48..76).collect()),
    ];
    for (name, members) in &groups {
        let z: Vec<f64> = res
            .runs
            .iter()
            .flat_map(|r| {
                members
                    .iter()
                    .map(|&k| (r.estimate[k] - r.truth[k]) / r.sigma[k])
            })
            .collect();
        let (mean, std) = pooled(&z);
        eprintln!("{name}: {} values, mean {mean:+.3}, std {std:.3}", z.len());
        assert!(mean.abs() < 0.15, "{name}: mean(error/σ) {mean:.3}");
        assert!((std - 1.0).abs() < 0.15, "{name}: std(error/σ) {std:.3}");
    }
    for p in &res.stats {
        assert!(
            (0.6..=1.45).contains(&p.std),
            "{}: std {:.3}",
            p.name,
            p.std
        );
    }
    let white = different_noise_study(24, 40.0, 5000, NoiseChoice::White);
    let std = imu1_pooled_std(&white);
    eprintln!("one white model: IMU 1 std(error/σ) {std:.3}");
    assert!(std > 1.5, "{std:.3}");
}

/// The full study (issue 41 item 6): 200 runs of 60 s; every parameter's
/// std(error/σ) within [0.85, 1.15] (200 runs: the std of one std is
/// ≈ 0.05, so the band is 3 of them) and the average NEES in its 95 %
/// interval. Measured: 0.905–1.124 over the 76 parameters, NEES 75.9 in
/// (74.3, 77.7), 90 s. `cargo test --release -p robimu --test multi_imu
/// two_imus_with_different_noise_study -- --ignored --nocapture`.
#[test]
#[ignore = "a study: 200 two-IMU sessions (about 2 min in release)"]
fn two_imus_with_different_noise_study() {
    let res = different_noise_study(200, 60.0, 7000, NoiseChoice::Auto);
    assert!(res.runs.iter().all(|r| r.warning.is_none()));
    let (lo, hi) = (res.nees_interval.0, res.nees_interval.1);
    assert!((lo..=hi).contains(&res.nees_mean), "NEES {}", res.nees_mean);
    for p in &res.stats {
        assert!(
            (0.85..=1.15).contains(&p.std),
            "{}: std {:.3}",
            p.name,
            p.std
        );
    }
}

#[test]
fn simulate_and_calibrate_several_imus_and_one_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("three");
    let run = robimu_ok([
        "simulate",
        "--imus",
        "3",
        "--duration",
        "40",
        "--seed",
        "8",
        "--out",
        s(&dir),
    ]);
    assert!(run.stdout.contains("from 3 IMUs"), "{}", run.stdout);
    for f in ["imu.csv", "imu1.csv", "imu2.csv", "truth.toml"] {
        assert!(dir.join(f).exists(), "{f}");
    }
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::with_imus(&robot, 3);
    let truth = Truth::read(&dir.join("truth.toml")).unwrap();
    let x_true = truth.vector(&layout).unwrap();

    // the joint fit: every one of the 104 parameters, covariance over all
    let out = tmp.path().join("joint.json");
    let run = robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    assert!(
        run.stdout.contains("3 IMUs fitted jointly"),
        "{}",
        run.stdout
    );
    let joint = CalibrationResult::read(&out).unwrap();
    joint.validate().unwrap();
    assert_eq!(joint.parameters.len(), 104);
    assert_eq!(joint.covariance.names.len(), 104);
    for (p, t) in joint.parameters.iter().zip(&x_true) {
        let z = (p.value - t) / p.sigma;
        assert!(z.abs() < 4.5, "{}: error {z:.2} σ", p.name);
    }

    // IMU 2 alone: one-IMU names, its own truth
    let out2 = tmp.path().join("imu2.json");
    let run = robimu_ok(["calibrate", s(&dir), "--imu", "2", "--out", s(&out2)]);
    assert!(!run.stdout.contains("fitted jointly"), "{}", run.stdout);
    let alone = CalibrationResult::read(&out2).unwrap();
    assert_eq!(alone.parameters.len(), 48);
    let map = layout.imu_map(2);
    for (k, p) in alone.parameters.iter().enumerate() {
        assert_eq!(p.name, layout.imu_layout().specs()[k].name);
        let z = (p.value - x_true[map[k]]) / p.sigma;
        assert!(z.abs() < 4.5, "{}: error {z:.2} σ", p.name);
        // the joint fit knows the shared parameters better, IMU 2's own about as well
        let jp = joint.parameter(&layout.specs()[map[k]].name).unwrap();
        if !layout.imu_layout().is_per_imu(k) && p.sigma < 0.5 * p.prior_sigma {
            assert!(
                jp.sigma < p.sigma,
                "{}: {} vs {}",
                p.name,
                jp.sigma,
                p.sigma
            );
        }
    }
    // and the table compared IMU 2's estimates with IMU 2's truth
    assert!(run.stdout.contains("against the truth"), "{}", run.stdout);

    let run = robimu(["calibrate", s(&dir), "--imu", "3"]);
    assert!(!run.status.success());
    assert!(
        run.stderr.contains("--imu 3") && run.stderr.contains("has 3 IMUs"),
        "{}",
        run.stderr
    );
    // effects per IMU (docs/model.md §9): IMU 2's clock drift; an IMU the
    // session lacks is named
    let effects = tmp.path().join("fx.json");
    robimu_ok([
        "calibrate",
        s(&dir),
        "--effects",
        "imu2/clock_drift",
        "--out",
        s(&effects),
    ]);
    let fx: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("effects.json")).unwrap())
            .unwrap();
    assert_eq!(fx["effects"], serde_json::json!(["imu2/clock_drift"]));
    let run = robimu(["calibrate", s(&dir), "--effects", "imu3/clock_drift"]);
    assert!(!run.status.success());
    assert!(run.stderr.contains("no IMU 3"), "{}", run.stderr);
}

/// IMU 1 mounted 60 mm from IMU 0 (a plate of boards): with the robot's one
/// mount prior its position estimate is pulled off the truth; with
/// `[imu1.mount]` in session.toml (docs/model.md §9) the fit uses IMU 1's own
/// prior — for the joint fit and for `--imu 1` alone — and the estimates stay
/// within 4σ of the truth.
#[test]
fn an_imu_mounted_elsewhere_takes_its_own_mount_prior() {
    let tmp = tempfile::tempdir().unwrap();
    let drawn = tmp.path().join("drawn");
    robimu_ok([
        "simulate",
        "--imus",
        "2",
        "--duration",
        "40",
        "--seed",
        "21",
        "--out",
        s(&drawn),
    ]);
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::with_imus(&robot, 2);
    let mut truth = Truth::read(&drawn.join("truth.toml")).unwrap();
    let shift = [0.06, -0.02, 0.03];
    for (i, d) in shift.iter().enumerate() {
        let name = format!("imu1/eps_6_{}", i + 1);
        let v = truth.values.iter_mut().find(|(n, _)| *n == name).unwrap();
        v.1 += d;
    }
    let truth_file = tmp.path().join("truth.toml");
    std::fs::write(&truth_file, truth.to_toml()).unwrap();
    let dir = tmp.path().join("plate");
    robimu_ok([
        "simulate",
        "--imus",
        "2",
        "--duration",
        "40",
        "--seed",
        "21",
        "--truth",
        s(&truth_file),
        "--out",
        s(&dir),
    ]);
    let x_true = Truth::read(&dir.join("truth.toml"))
        .unwrap()
        .vector(&layout)
        .unwrap();
    let k1 = layout.index_of("imu1/eps_6_1").unwrap();
    let mount = robot.mount().position;

    // the robot's one mount prior: on 40 s the data alone know the position
    // to ≈ 7 mm, so the prior 60 mm away pulls the estimate far off the
    // truth (measured 4.9σ) — while every estimate stays within 4 prior σ
    let out = tmp.path().join("one_prior.json");
    robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    let r = CalibrationResult::read(&out).unwrap();
    let p = r.parameter("imu1/eps_6_1").unwrap();
    assert_eq!(p.prior, mount[0]);
    let z = (p.value - x_true[k1]) / p.sigma;
    assert!(z < -3.0, "imu1/eps_6_1 {z:.2} σ from the truth");
    let plausible = |r: &CalibrationResult| {
        let v = r.verdict.as_ref().expect("a verdict");
        v.checks
            .iter()
            .find(|c| c.topic == "plausible")
            .unwrap()
            .clone()
    };

    // IMU 1's own prior (the mount as drawn to 1 mm, σ 5 mm)
    let position: Vec<f64> = (0..3)
        .map(|i| (x_true[k1 + i] * 1000.0).round() / 1000.0)
        .collect();
    let toml = std::fs::read_to_string(dir.join("session.toml")).unwrap();
    std::fs::write(
        dir.join("session.toml"),
        format!(
            "{toml}\n[imu1.mount]\nposition = [{}, {}, {}]\nposition_sigma = 0.005\n",
            position[0], position[1], position[2]
        ),
    )
    .unwrap();
    let out = tmp.path().join("own_prior.json");
    robimu_ok(["calibrate", s(&dir), "--out", s(&out)]);
    let r = CalibrationResult::read(&out).unwrap();
    for i in 0..3 {
        let p = r.parameter(&format!("imu1/eps_6_{}", i + 1)).unwrap();
        assert_eq!((p.prior, p.prior_sigma), (position[i], 0.005), "{p:?}");
        // IMU 0 keeps the robot's
        assert_eq!(
            r.parameter(&format!("eps_6_{}", i + 1)).unwrap().prior,
            mount[i]
        );
    }
    assert!(plausible(&r).ok, "{:?}", plausible(&r));
    for (p, t) in r.parameters.iter().zip(&x_true) {
        let z = (p.value - t) / p.sigma;
        assert!(z.abs() < 4.5, "{}: error {z:.2} σ", p.name);
    }
    // IMU 1 alone: the one-IMU result's eps_6_* prior is IMU 1's
    let out = tmp.path().join("alone.json");
    robimu_ok(["calibrate", s(&dir), "--imu", "1", "--out", s(&out)]);
    let r = CalibrationResult::read(&out).unwrap();
    assert_eq!(r.parameter("eps_6_1").unwrap().prior, position[0]);

    // a misspelt key is named, with the file
    std::fs::write(
        dir.join("session.toml"),
        format!("{toml}\n[imu1.mount]\nposition_sd = 0.005\n"),
    )
    .unwrap();
    let run = robimu(["calibrate", s(&dir)]);
    assert!(!run.status.success());
    assert!(
        run.stderr.contains("[imu1.mount]") && run.stderr.contains("position_sd"),
        "{}",
        run.stderr
    );
}

/// A one-IMU result's exports are byte for byte those written before the
/// multi-IMU work (goldens of d3fc17f in fixtures/multi_imu/one_imu_golden:
/// Kalibr imu.yaml, correction file, robot TOML, corrected CSV; rewritten
/// once since, when result files came to be read to the bit — serde_json's
/// float_roundtrip — which moved a few last digits).
#[test]
fn one_imu_exports_are_unchanged() {
    let fixtures =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/multi_imu");
    let golden = fixtures.join("one_imu_golden");
    let tmp = tempfile::tempdir().unwrap();
    let result = fixtures.join("result1.json");
    for (format, file, extra) in [
        ("kalibr", "imu.yaml", &["--rate", "120"][..]),
        ("correction", "correction.toml", &[][..]),
        ("toml", "robot.toml", &[][..]),
    ] {
        let out = tmp.path().join(file);
        let mut args = vec![
            "export",
            "--calibration",
            s(&result),
            "--format",
            format,
            "--robot",
            "aubo_i5",
            "--out",
            s(&out),
        ];
        args.extend_from_slice(extra);
        robimu_ok(args);
        assert!(
            std::fs::read(&out).unwrap() == std::fs::read(golden.join(file)).unwrap(),
            "{file} differs from its golden"
        );
    }
    let out = tmp.path().join("corrected.csv");
    robimu_ok([
        "correct",
        "--calibration",
        s(&result),
        s(&fixtures.join("raw_imu.csv")),
        "--out",
        s(&out),
    ]);
    assert!(std::fs::read(&out).unwrap() == std::fs::read(golden.join("corrected.csv")).unwrap());
}

/// `simulate --imu-position J=X,Y,Z` places IMU J (a plate of IMUs): its
/// truth is drawn around that mount, session.toml carries the mount prior
/// and calibrate uses it.
#[test]
fn simulate_places_an_imu_and_calibrate_takes_its_mount() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("plate");
    robimu_ok([
        "simulate",
        "--imus",
        "2",
        "--imu-position",
        "1=0.09,-0.05,0.06",
        "--duration",
        "40",
        "--seed",
        "5",
        "--out",
        s(&dir),
    ]);
    let meta = robimu_session::SessionMeta::read(&dir.join("session.toml")).unwrap();
    assert_eq!(meta.mounts[&1].position, Some([0.09, -0.05, 0.06]));
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::with_imus(&robot, 2);
    let x_true = Truth::read(&dir.join("truth.toml"))
        .unwrap()
        .vector(&layout)
        .unwrap();
    let k1 = layout.index_of("imu1/eps_6_1").unwrap();
    // drawn from the 10 mm prior around the placed mount
    for (i, p) in [0.09, -0.05, 0.06].iter().enumerate() {
        assert!(
            (x_true[k1 + i] - p).abs() < 0.05,
            "{} vs {p}",
            x_true[k1 + i]
        );
    }
    let out = tmp.path().join("r.json");
    let html = tmp.path().join("html");
    robimu_ok(["calibrate", s(&dir), "--out", s(&out), "--report", s(&html)]);
    let r = CalibrationResult::read(&out).unwrap();
    assert_eq!(r.parameter("imu1/eps_6_2").unwrap().prior, -0.05);
    // calibrate --report: one residual figure per IMU, the same as
    // `robimu report` draws from the result file
    let again = tmp.path().join("again");
    robimu_ok(["report", s(&out), "--session", s(&dir), "--out", s(&again)]);
    for f in ["residuals_imu0.svg", "residuals_imu1.svg", "trajectory.svg"] {
        let a = std::fs::read(html.join(f)).unwrap();
        assert!(a == std::fs::read(again.join(f)).unwrap(), "{f} differs");
    }
    for (p, t) in r.parameters.iter().zip(&x_true) {
        let z = (p.value - t) / p.sigma;
        assert!(z.abs() < 4.5, "{}: error {z:.2} σ", p.name);
    }
    let run = robimu([
        "simulate",
        "--imus",
        "2",
        "--imu-position",
        "2=0,0,0",
        "--out",
        s(&tmp.path().join("x")),
    ]);
    assert!(!run.status.success());
    assert!(run.stderr.contains("there are 2 IMUs"), "{}", run.stderr);
}

/// `validate --imu J`: IMU J's parameters on its own samples (imu<J>.csv)
/// against the tracked motion: as good as the classical tracker calibration
/// of that IMU, far better than nominal. (IMU 0's parameters on IMU 1's
/// samples give 20 °/s, measured.)
#[test]
fn validate_takes_the_imu_asked_for() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    robimu_ok([
        "simulate",
        "--imus",
        "2",
        "--tracker",
        "--duration",
        "60",
        "--seed",
        "4",
        "--out",
        s(&dir),
    ]);
    robimu_ok(["calibrate", s(&dir)]);
    let result = dir.join("result.json");
    let poses = dir.join("poses.csv");
    let gyro = |j: &str| {
        let report = tmp.path().join(format!("v{j}"));
        robimu_ok([
            "validate",
            s(&dir),
            "--calibration",
            s(&result),
            "--tracker",
            s(&poses),
            "--imu",
            j,
            "--report",
            s(&report),
        ]);
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(report.join("validation.json")).unwrap())
                .unwrap();
        let rms = |k: &str| v["imu_accuracy"][k]["rms_gyro_deg_s"].as_f64().unwrap();
        (rms("nominal"), rms("calibrated"), rms("classical"))
    };
    for j in ["0", "1"] {
        let (nominal, calibrated, classical) = gyro(j);
        assert!(
            calibrated < 0.2 * nominal,
            "IMU {j}: {calibrated} vs nominal {nominal}"
        );
        assert!(
            calibrated < 1.1 * classical,
            "IMU {j}: {calibrated} vs classical {classical}"
        );
    }
    let run = robimu([
        "validate",
        s(&dir),
        "--calibration",
        s(&result),
        "--tracker",
        s(&poses),
        "--imu",
        "2",
    ]);
    assert!(!run.status.success());
    assert!(run.stderr.contains("--imu 2"), "{}", run.stderr);
}

/// Two IMUs whose noise differs: IMU 0 white, IMU 1's accelerometer AR(1)
/// (φ = 0.9, 75 ms at 120 Hz; drawn here by its recursion, not by the
/// library's sampler). `calibrate` (auto) identifies each IMU's noise from
/// its own residuals: result.json's `noise_model` is IMU 0's (white) and
/// `imu_noise_models` IMU 1's (AR(1), φ near 0.9), and the verdict's
/// residuals check passes: the IMUs differ, but each is whitened by its
/// own. Fitted with one white model (`--noise-model white`) IMU 1's
/// residuals ask for another: the verdict names IMU 1. With both white,
/// neither names it and the file has `imu_noise_models` white.
#[test]
fn an_imu_whose_noise_differs_is_named_in_the_verdict_only_when_not_its_own() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    use robimu_session::result::NoiseModelRecord;
    use robimu_session::{SessionMeta, SessionWriter};
    use robimu_workflows::simulate::random_session_imus;

    let robot = Robot::aubo_i5();
    let layout = ParamLayout::with_imus(&robot, 2);
    let mut opts = SimulateOptions::paper(&robot);
    opts.noise = false;
    let clean = random_session_imus(&robot, 2, 60.0, 1.0, &opts, 11).unwrap();
    let sz = robot.sigma_z();
    let tmp = tempfile::tempdir().unwrap();
    let result_of = |phi: f64, name: &str, model: &str| {
        let mut data = clean.data.clone();
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let mut e = move || -> f64 { StandardNormal.sample(&mut rng) };
        for z in data.imu_z.iter_mut() {
            for (c, v) in z.iter_mut().enumerate() {
                *v += sz[c] * e();
            }
        }
        let mut past = [0.0; 3];
        for (i, z) in data.extra_imus[0].z.iter_mut().enumerate() {
            for (c, v) in z.iter_mut().enumerate() {
                let n = if c < 3 {
                    let u = if i == 0 {
                        e()
                    } else {
                        phi * past[c] + (1.0 - phi * phi).sqrt() * e()
                    };
                    past[c] = u;
                    u
                } else {
                    e()
                };
                *v += sz[c] * n;
            }
        }
        let dir = tmp.path().join(name);
        if !dir.exists() {
            let mut w = SessionWriter::create(&dir, &SessionMeta::new("aubo_i5"), 6).unwrap();
            w.measurements(&data).unwrap();
            w.truth(&Truth::of(&layout, &clean.truth)).unwrap();
            w.finish().unwrap();
        }
        let out = tmp.path().join(format!("{name}-{model}.json"));
        robimu_ok([
            "calibrate",
            s(&dir),
            "--noise-model",
            model,
            "--out",
            s(&out),
        ]);
        let r = CalibrationResult::read(&out).unwrap();
        let check = r
            .verdict
            .clone()
            .unwrap()
            .checks
            .into_iter()
            .find(|c| c.topic == "residuals")
            .unwrap();
        (r, check)
    };
    // each IMU its own: not named
    let (r, own) = result_of(0.9, "ar1", "auto");
    assert!(own.ok && !own.text.contains("IMU 1 ("), "{own:?}");
    assert_eq!(r.noise_model, Some(NoiseModelRecord::White));
    assert_eq!(r.imu_noise_models.len(), 1);
    assert_eq!(r.imu_noise_models[0].imu, "imu1");
    let NoiseModelRecord::Ar { channels } = &r.imu_noise_models[0].noise_model else {
        panic!("{:?}", r.imu_noise_models)
    };
    for (c, ch) in channels.iter().enumerate() {
        if c < 3 {
            assert!(
                ch.phi.len() == 1 && (ch.phi[0] - 0.9).abs() < 0.05,
                "{ch:?}"
            );
        } else {
            assert!(ch.phi.is_empty(), "{ch:?}");
        }
        assert!((ch.sigma / sz[c] - 1.0).abs() < 0.15, "{ch:?}");
    }
    // one white model for both: IMU 1's σ are not its noise's
    let (r, one) = result_of(0.9, "ar1", "white");
    assert!(!one.ok && one.text.contains("IMU 1 ("), "{one:?}");
    assert_eq!(r.imu_noise_models[0].noise_model, NoiseModelRecord::White);
    // both white
    let (r, same) = result_of(0.0, "white", "auto");
    assert!(same.ok, "{same:?}");
    assert_eq!(r.imu_noise_models[0].noise_model, NoiseModelRecord::White);
}
