//! Two IMUs on one posed body (MODEL.md §9, §10): against IMU 0 calibrated
//! alone on the same data, and a Monte Carlo of the normalised errors of
//! all 58 parameters.

use super::*;
use crate::pose_calibrate::tests::{env, ZStatistics};
use crate::pose_calibrate::{
    calibrate_pose_imus_with, calibrate_poses, random_pose_motion, PoseCalibration,
    PoseCalibrationOptions, PoseNoise,
};
use robimu_model::pose_measurement::{imu_indices, ACCEL, GYRO, ROT, TAU};

/// A `duration` s session of `n_imus` IMUs (poses 15 Hz with 3 ms jitter,
/// IMU 100 Hz) and its truth.
fn session(
    n_imus: usize,
    seed: u64,
    duration: f64,
) -> (Vec<f64>, robimu_model::PoseMeasurements, Vec<ImuSamples>) {
    let truth = draw_pose_imus_truth(1000 + seed, n_imus);
    let motion = random_pose_motion(duration, 2000 + seed).unwrap();
    let noise = PoseNoise::default();
    let (data, more) = simulate_pose_imus(
        &truth,
        n_imus,
        &motion,
        (15.0, 0.003),
        100.0,
        &noise,
        3000 + seed,
    )
    .unwrap();
    (truth, data, more)
}

/// Calibrate with the default options (knot spacing `POSE_MC_KNOTS` when
/// set).
fn calibrate(data: &robimu_model::PoseMeasurements, more: &[ImuSamples]) -> PoseCalibration {
    let opts = PoseCalibrationOptions {
        knot_spacing: env("POSE_MC_KNOTS"),
        ..Default::default()
    };
    calibrate_pose_imus_with(data, more, &opts, |_| {}, |_| {}).unwrap()
}

/// (x̂ − x)/σ for every parameter, the sensor rotations' errors wrapped to
/// (−π, π].
fn normalised(cal: &PoseCalibration, truth: &[f64], n_imus: usize) -> Vec<f64> {
    let pi = std::f64::consts::PI;
    let rot: Vec<usize> = (0..n_imus)
        .flat_map(|j| {
            let ix = imu_indices(j);
            (0..3).flat_map(move |i| [ix[ACCEL + ROT + i], ix[GYRO + ROT + i]])
        })
        .collect();
    (0..cal.x.len())
        .map(|k| {
            let e = cal.x[k] - truth[k];
            let e = if rot.contains(&k) {
                (e + pi).rem_euclid(2.0 * pi) - pi
            } else {
                e
            };
            e / cal.sigma[k]
        })
        .collect()
}

/// Two IMUs: every one of the 58 parameters within 4σ of the truth; IMU
/// 0's estimates against IMU 0 calibrated alone on the same data: no σ
/// larger, the difference within 4σ of its own σ (Hausman's
/// √(σ_alone² − σ_joint²): the second IMU adds information on the shared
/// g and, through the shared spline, on the gyroscope's parameters);
/// σ(g_x), σ(g_y) below 0.95 of alone.
#[test]
fn two_imus_agree_with_imu_0_alone_and_narrow_gravity() {
    let (truth, data, more) = session(2, 7, 40.0);
    let two = calibrate(&data, &more);
    assert_eq!(two.x.len(), 58);
    assert_eq!(two.names[30 + TAU - 2], "imu1/tau");
    assert_eq!(two.more.len(), 1);
    assert!(two.converged, "{}", two.termination);
    let z = normalised(&two, &truth, 2);
    for (k, v) in z.iter().enumerate() {
        assert!(v.abs() < 4.0, "{} off by {v:.2}σ", two.names[k]);
    }
    let one = calibrate_poses(&data, &PoseCalibrationOptions::default()).unwrap();
    for k in 0..30 {
        // Hausman: with IMU 0 alone consistent and the joint fit efficient,
        // Var(x̂_one − x̂_two) = σ_one² − σ_two²
        let (s1, s2) = (one.sigma[k], two.sigma[k]);
        assert!(
            s2 <= 1.001 * s1,
            "σ({}) grew: {s2:.3e} > {s1:.3e}",
            one.names[k]
        );
        let h = (two.x[k] - one.x[k]) / (s1 * s1 - s2 * s2).max(1e-6 * s1 * s1).sqrt();
        assert!(
            h.abs() < 4.0,
            "{}: {h:.2} σ of the difference from IMU 0 alone",
            one.names[k]
        );
    }
    for k in [3, 4] {
        assert!(
            two.sigma[k] < 0.95 * one.sigma[k],
            "σ({}) {:.3e} with two IMUs, {:.3e} alone",
            two.names[k],
            two.sigma[k],
            one.sigma[k]
        );
    }
    let tau1 = two.x[imu_indices(1)[TAU]];
    assert!((two.more[0].startup.tau - tau1).abs() < 0.02, "{tau1}");
    assert!(two.more[0].tau_drift.is_some());
}

/// On noise-free sessions (σ given, not identified) τ's error is the pose
/// spline's approximation bias alone, the same for both IMUs: its RMS in
/// σ_τ over both IMUs of four 60 s sessions is small at the default knots
/// for two IMUs (1.125 / pose rate) and not at one IMU's (1.5 / rate).
#[test]
fn two_imus_default_knots_keep_tau_unbiased() {
    let opts = |h| PoseCalibrationOptions {
        knot_spacing: h,
        identify_noise: false,
        ..Default::default()
    };
    let free = PoseNoise {
        sigma_p: 0.0,
        sigma_r: 0.0,
        sigma_z: [0.0; 6],
    };
    let bias = |h: Option<f64>| {
        let mut z2 = 0.0;
        for seed in 20..24 {
            let truth = draw_pose_imus_truth(seed, 2);
            let motion = random_pose_motion(60.0, seed).unwrap();
            let (data, more) =
                simulate_pose_imus(&truth, 2, &motion, (15.0, 0.003), 100.0, &free, seed).unwrap();
            let cal = calibrate_pose_imus_with(&data, &more, &opts(h), |_| {}, |_| {}).unwrap();
            z2 += normalised(&cal, &truth, 2)[..]
                .iter()
                .enumerate()
                .filter(|(k, _)| [TAU, imu_indices(1)[TAU]].contains(k))
                .map(|(_, z)| z * z)
                .sum::<f64>();
        }
        (z2 / 8.0).sqrt()
    };
    let (fine, coarse) = (bias(None), bias(Some(0.1)));
    println!("τ bias RMS: {fine:.2} σ at the default, {coarse:.2} σ at 0.1 s");
    assert!(fine < 0.35 && coarse > 0.5, "{fine:.2}, {coarse:.2}");
}

/// Poses that cannot carry the finer knots of several IMUs (a 0.3 s gap:
/// the pose-only fit at 1.125 / rate is singular, at 1.5 / rate not) are
/// fitted at one IMU's knots.
#[test]
fn a_pose_gap_falls_back_to_one_imus_knots() {
    let (_, mut data, more) = session(2, 9, 20.0);
    let kept: Vec<usize> = (0..data.pose_t.len())
        .filter(|&i| !(10.0..10.3).contains(&data.pose_t[i]))
        .collect();
    data.pose_t = kept.iter().map(|&i| data.pose_t[i]).collect();
    data.pose_p = kept.iter().map(|&i| data.pose_p[i]).collect();
    data.pose_q = kept.iter().map(|&i| data.pose_q[i]).collect();
    let (h1, h2) = (
        crate::pose_calibrate::default_knot_spacing(&data.pose_t),
        crate::pose_calibrate::default_knot_spacing_for(&data.pose_t, 2),
    );
    let fit = |h| robimu_model::PoseSpline::fit(&data.pose_t, &data.pose_p, &data.pose_q, h);
    assert!(fit(h2).is_err() && fit(h1).is_ok(), "{h1} {h2}");
    let cal = calibrate(&data, &more);
    assert_eq!(cal.knot_spacing, h1);
}

#[test]
fn a_bad_second_imu_is_a_clear_error() {
    let (_, data, mut more) = session(2, 8, 10.0);
    more[0].z[5][2] = f64::NAN;
    let opts = PoseCalibrationOptions::default();
    let e = calibrate_pose_imus_with(&data, &more, &opts, |_| {}, |_| {}).unwrap_err();
    assert!(
        e.to_string().contains("IMU 1: a sample is not finite"),
        "{e}"
    );
    let e = simulate_pose_imus(
        &[0.0; 30],
        2,
        &random_pose_motion(5.0, 1).unwrap(),
        (15.0, 0.0),
        100.0,
        &PoseNoise::default(),
        1,
    )
    .unwrap_err();
    assert!(e.to_string().contains("need 58 parameters"), "{e}");
}

/// Monte Carlo of `MC_RUNS` (default 50) two-IMU calibrations of 60 s
/// sessions (seeds from `MC_SEED0`, default 100; `MC_IMUS=1` calibrates
/// their IMU 0 alone): per parameter of the 58
/// the normalised errors' std and mean, held to their n-run scatter's
/// 3.3σ bounds (as `tests::monte_carlo_normalised_errors_are_standard`),
/// every τ within 4σ.
#[test]
#[ignore = "Monte Carlo of ≥ 50 two-IMU calibrations: run in release"]
fn monte_carlo_two_imus_normalised_errors_are_standard() {
    let (runs, seed0) = (env("MC_RUNS").unwrap_or(50), env("MC_SEED0").unwrap_or(100));
    // MC_IMUS=1: IMU 0 of the same sessions alone, for comparison
    let k: usize = env("MC_IMUS").unwrap_or(2);
    let taus: Vec<usize> = (0..k).map(|j| imu_indices(j)[TAU]).collect();
    let mut names = Vec::new();
    let zs: Vec<Vec<f64>> = (0..runs)
        .map(|s| {
            let (truth, data, more) = session(2, seed0 + s, 60.0);
            let cal = calibrate(&data, &more[..k - 1]);
            let z = normalised(&cal, &truth[..cal.x.len()], k);
            let z_tau: Vec<String> = taus.iter().map(|&t| format!("{:+.2}", z[t])).collect();
            println!(
                "run {s}: z_τ {}, {} iterations",
                z_tau.join(" "),
                cal.iterations
            );
            names = cal.names;
            z
        })
        .collect();
    let stats = ZStatistics::of(&names, &zs);
    assert!(
        zs.iter().all(|z| taus.iter().all(|&t| z[t].abs() < 4.0)),
        "τ beyond 4σ in a run"
    );
    stats.assert_per_parameter_standard();
}
