//! Simulated pose sessions: a robot flange's has the joint session's IMU
//! samples and truth; and (issue 39, messy timing) sessions whose IMU
//! stamps carry arrival jitter and a drifting lag are calibrated with σ that
//! hold or get a verdict that is not "good" (through `robimu calibrate`'s
//! path: the session written, read, calibrated, judged).

use super::*;
use crate::pipeline::poses::{calibrate_pose_session, load_pose_session, pose_options};
use crate::pipeline::simulate::simulate_session;
use robimu_session::result::Trust;
use robimu_session::Truth;

/// The verdict and the normalised errors (x̂ − x)/σ of one session.
fn judged(dir: &std::path::Path, spec: &PoseSessionSpec) -> (Trust, Vec<f64>, String) {
    let mut spec = spec.clone();
    spec.out = dir.to_path_buf();
    simulate_pose_dir(&spec).unwrap();
    let session = load_pose_session(dir, |_| {}).unwrap();
    let truth = session.truth.clone().unwrap();
    let opts = pose_options(&session.meta, |_| {});
    let f = calibrate_pose_session(session, opts, |_| {}).unwrap();
    let pi = std::f64::consts::PI;
    let z = f
        .result
        .parameters
        .iter()
        .map(|p| {
            let mut e = p.value - truth.get(&p.name).unwrap();
            if p.name.starts_with("r_") {
                e = (e + pi).rem_euclid(2.0 * pi) - pi;
            }
            e / p.sigma
        })
        .collect();
    let v = f.result.verdict.unwrap();
    let drift = f.cal.tau_drift.map_or(f64::NAN, |d| d.statistic);
    let why = format!(
        "S {drift:.1}; {}; next: {}",
        v.reasons.join("; "),
        v.next_steps.join("; ")
    );
    (v.trust, z, why)
}

fn spec(robot: Option<&str>, jitter: f64, drift: f64, seed: u64) -> PoseSessionSpec {
    PoseSessionSpec {
        out: PathBuf::new(),
        duration: 60.0,
        seed,
        pose_rate: 15.0,
        pose_jitter: 0.003,
        imu_rate: 100.0,
        robot: robot.map(|n| Robot::builtin(n).unwrap()),
        imu_timing: ImuTiming { jitter, drift },
        imus: 1,
        effects: Vec::new(),
    }
}

#[test]
fn a_messy_session_is_not_good_and_a_clean_one_is() {
    let tmp = tempfile::tempdir().unwrap();
    let (t, z, why) = judged(tmp.path(), &spec(None, 0.0, 0.0, 4));
    assert_eq!(t, Trust::Good, "{why}");
    assert!(z.iter().all(|v| v.abs() < 4.0), "{z:?}");
    let (t, _, why) = judged(tmp.path(), &spec(None, 0.004, 0.030, 4));
    assert_ne!(t, Trust::Good);
    assert!(why.contains("time offset"), "{why}");
    // the timing first: the residuals' σ would only hide it
    assert!(why.contains("next: stamp the IMU's samples where"), "{why}");
    assert!(!why.contains("put the σ the residuals suggest"), "{why}");
    // a slow flange motion: the other parameters absorb much of the drift
    let (t, _, why) = judged(tmp.path(), &spec(Some("ur5e"), 0.004, 0.030, 4));
    assert_ne!(t, Trust::Good);
    assert!(why.contains("time offset: τ changes"), "{why}");
}

/// The fit's residual series (the report's figure) are the residuals the
/// noise identification summed: per channel their RMS is the result's
/// (computed apart, from the channels' RSS); one per sample in the fit;
/// an IMU the fit does not have is an error. The convergence log written
/// beside the result starts at the final solve's first cost and ends at
/// the result's final cost.
#[test]
fn the_fits_residual_series_and_convergence_log_match_the_result() {
    let tmp = tempfile::tempdir().unwrap();
    let mut sp = spec(None, 0.0, 0.0, 5);
    (sp.duration, sp.out) = (30.0, tmp.path().join("s"));
    simulate_pose_dir(&sp).unwrap();
    let session = load_pose_session(&sp.out, |_| {}).unwrap();
    let opts = pose_options(&session.meta, |_| {});
    let f = calibrate_pose_session(session, opts, |_| {}).unwrap();
    let r = f.imu_residuals(0).unwrap();
    assert_eq!(r.len(), f.cal.imu_used);
    assert!(r.windows(2).all(|w| w[1].0 > w[0].0));
    for c in 0..6 {
        let rms = (r.iter().map(|(_, e)| e[c] * e[c]).sum::<f64>() / r.len() as f64).sqrt();
        let want = f.cal.imu_rms[c];
        assert!(
            (rms - want).abs() < 1e-9 * want,
            "channel {c}: {rms} vs {want}"
        );
    }
    assert!(f.imu_residuals(1).is_err());
    let path = tmp.path().join("result.json");
    let history = f.write(&path).unwrap();
    let costs = crate::convergence::ConvergenceLog::read(&history)
        .unwrap()
        .costs();
    assert_eq!(costs[0], f.cal.summary.initial_cost);
    let last = *costs.last().unwrap();
    assert!((last - f.result.final_cost.unwrap()).abs() <= 1e-9 * last);
    assert_eq!(costs.len(), f.cal.iterations + 1);
}

/// `MC_RUNS` (default 20) sessions from seed `MC_SEED0` (default 1) of
/// `MC_ROBOT`'s flange (unset: hand-held) with IMU stamps' jitter
/// `MC_JITTER` and lag drift `MC_DRIFT` (s, default 0): the share judged
/// good and, among those, std and mean of (x̂ − x)/σ per parameter and τ's.
/// Issue 39 asks: the good ones pass the Monte Carlo check (std ∈ [0.85,
/// 1.15], |mean| < 0.3, |τ| within 4σ). Without jitter and drift at most
/// 5 % may be not good.
#[test]
#[ignore = "Monte Carlo of ≥ 20 calibrations: run in release"]
fn monte_carlo_verdicts_under_messy_timing() {
    let var = |k: &str| std::env::var(k).ok();
    let num = |k: &str, d: f64| var(k).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (runs, seed0) = (num("MC_RUNS", 20.0) as u64, num("MC_SEED0", 1.0) as u64);
    let (jitter, drift) = (num("MC_JITTER", 0.0), num("MC_DRIFT", 0.0));
    let robot = var("MC_ROBOT");
    let tmp = tempfile::tempdir().unwrap();
    let mut good: Vec<Vec<f64>> = Vec::new();
    let t0 = std::time::Instant::now();
    for s in seed0..seed0 + runs {
        let (t, z, why) = judged(tmp.path(), &spec(robot.as_deref(), jitter, drift, s));
        println!("seed {s}: {t:?} z_tau {:+.2} {why}", z[5]);
        if t == Trust::Good {
            good.push(z);
        }
    }
    println!(
        "{:.2} s per session",
        t0.elapsed().as_secs_f64() / runs as f64
    );
    let share = good.len() as f64 / runs as f64;
    println!("good: {} of {runs} ({:.0} %)", good.len(), 100.0 * share);
    let mut worst = (0.0f64, 0.0f64);
    if good.len() >= 2 {
        let names = robimu_model::pose_measurement::pose_param_names();
        for (k, name) in names.iter().enumerate() {
            let v: Vec<f64> = good.iter().map(|z| z[k]).collect();
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let std = (v.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            println!("{name:12} mean {mean:+.2} std {std:.2}");
            worst = (worst.0.max((std - 1.0).abs()), worst.1.max(mean.abs()));
        }
        let tau_max = good.iter().map(|z| z[5].abs()).fold(0.0, f64::max);
        println!(
            "among good: max |std − 1| {:.2}, max |mean| {:.2}, max |z_tau| {tau_max:.2}",
            worst.0, worst.1
        );
        if jitter > 0.0 || drift > 0.0 {
            assert!(tau_max < 4.0, "a good session with τ {tau_max:.1}σ off");
        }
    }
    if jitter == 0.0 && drift == 0.0 {
        assert!(share >= 0.95, "clean sessions: {:.0} % good", 100.0 * share);
    }
}

#[test]
fn the_flange_sessions_imu_csv_is_the_joint_sessions_and_its_truth_maps() {
    let tmp = tempfile::tempdir().unwrap();
    let (jd, pd) = (tmp.path().join("joints"), tmp.path().join("poses"));
    simulate_session(&crate::pipeline::simulate::SessionSpec::plain(
        Robot::aubo_i5(),
        12.0,
        100.0,
        7,
        jd.clone(),
    ))
    .unwrap();
    let p = simulate_pose_dir(&PoseSessionSpec {
        out: pd.clone(),
        duration: 12.0,
        seed: 7,
        pose_rate: 20.0,
        pose_jitter: 0.003,
        imu_rate: 100.0,
        robot: Some(Robot::aubo_i5()),
        imu_timing: ImuTiming::default(),
        imus: 1,
        effects: Vec::new(),
    })
    .unwrap();
    let read = |d: &PathBuf| std::fs::read(d.join("imu.csv")).unwrap();
    assert_eq!(read(&jd), read(&pd), "imu.csv differs");
    assert!(
        (p.poses as f64 - 12.0 * 20.0).abs() <= 2.0,
        "{} poses",
        p.poses
    );
    let (tj, tp) = (
        Truth::read(&jd.join("truth.toml")).unwrap(),
        Truth::read(&pd.join("truth.toml")).unwrap(),
    );
    for (pose, joint) in [
        ("p_imu_x", "eps_6_1"),
        ("p_imu_y", "eps_6_2"),
        ("p_imu_z", "eps_6_3"),
    ]
    .into_iter()
    .chain(["g_x", "g_y", "tau", "gamma_a_yz", "r_a_x", "k_w_z", "b_w_x"].map(|n| (n, n)))
    {
        assert_eq!(tp.get(pose), tj.get(joint), "{pose} vs {joint}");
    }
}
