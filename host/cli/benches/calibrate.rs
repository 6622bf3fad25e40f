//! Calibration speed: a 300 s, 120 Hz AUBO i5 session (36,000 IMU + 36,000
//! joint samples; 1,818 spline coefficients + 48 parameters) calibrated from
//! nominal, τ search included: with white noise and by generalised least
//! squares with a given AR(1) accelerometer model on a white-noise session,
//! then white against `--noise-model auto` (whiteness test, identification,
//! warm-started GLS refits; docs/model.md §4.6) on a session whose
//! accelerometer noise is AR(1) of 30 ms. Prints the median wall time and peak memory.
//!
//! `cargo bench -p robimu --bench calibrate`

use std::time::Instant;

use robimu_model::noise::NoiseModel;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_workflows::calibrate::noise_choice::{calibrate_with_noise, NoiseChoice};
use robimu_workflows::calibrate::{CalibrateOptions, Calibration};
use robimu_workflows::simulate::{random_session, RandomSession, SimulateOptions};

fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Median, min and max wall time of `runs` calibrations, and the last one.
fn time(runs: usize, mut f: impl FnMut() -> Calibration) -> ([f64; 3], Calibration) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs {
        let t = Instant::now();
        last = Some(f());
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (
        [times[runs / 2], times[0], times[runs - 1]],
        last.expect("runs > 0"),
    )
}

fn main() {
    let duration = 300.0;
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let session = |noise_model: Option<NoiseModel>| -> (Vec<f64>, Measurements) {
        let sim = SimulateOptions {
            noise_model,
            ..SimulateOptions::paper(&robot)
        };
        let RandomSession { truth, data, .. } =
            random_session(&robot, duration, 1.0, &sim, 2024).expect("simulate");
        (truth, data)
    };
    let (truth, data) = session(None);
    let opts = CalibrateOptions::new(&robot);
    println!(
        "session: {} IMU + {} joint samples, {:.0} s; truth tau = {:.3} s",
        data.imu_t.len(),
        data.joint_t.len(),
        duration,
        truth[layout.offsets().tau]
    );
    let runs = 7;
    // AR(1) accelerometer noise with a 30 ms correlation time, the paper's σ.
    let sz = robot.sigma_z();
    let phi = (-1.0f64 / (120.0 * 0.030)).exp();
    let ar1 = NoiseModel::ar1(sz, [Some(phi), None], [0.0; 2]).expect("AR(1)");
    let (_, correlated) = session(Some(ar1.clone()));
    let given = NoiseChoice::Given(Box::new(ar1));
    let cases: [(&str, &Measurements, NoiseChoice); 4] = [
        ("white session, white", &data, NoiseChoice::White),
        ("white session, GLS given AR(1)", &data, given),
        ("AR(1) session, white", &correlated, NoiseChoice::White),
        ("AR(1) session, auto", &correlated, NoiseChoice::Auto),
    ];
    let mut medians = Vec::new();
    for (label, data, choice) in &cases {
        let mut refits = 0;
        let ([med, min, max], cal) = time(runs, || {
            let (cal, outcome) =
                calibrate_with_noise(&robot, data, &opts, choice, |_| {}).expect("calibrate");
            refits = outcome.refits;
            cal
        });
        println!(
            "calibrate from nominal, {label}: median {med:.3} s (min {min:.3}, max {max:.3}) over {runs} runs; {} LM iterations, {refits} GLS refits; {} coefficients + {} parameters",
            cal.summary.iterations.len(),
            cal.trajectory.coeffs().len(),
            layout.len()
        );
        medians.push(med);
    }
    println!(
        "GLS given / white time: {:.2}; auto / white time on the AR(1) session: {:.2}",
        medians[1] / medians[0],
        medians[3] / medians[2]
    );
    if let Some(mb) = peak_rss_mb() {
        println!("peak memory (VmHWM, whole process incl. the simulated sessions): {mb:.0} MB");
    }
}
