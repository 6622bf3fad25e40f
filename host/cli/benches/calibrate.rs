//! Calibration speed: a 300 s, 120 Hz AUBO i5 session (36,000 IMU + 36,000
//! joint samples; 1,818 spline coefficients + 48 parameters) calibrated from
//! nominal, τ search included, with white noise and by generalised least
//! squares under AR(1) accelerometer noise. Prints the median wall time and peak memory.
//!
//! `cargo bench -p robimu --bench calibrate`

use std::time::Instant;

use robimu_model::noise::{ArNoise, ChannelNoise, NoiseModel};
use robimu_model::{ParamLayout, Robot};
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};
use robimu_workflows::simulate::{random_session, RandomSession, SimulateOptions};

fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

fn main() {
    let duration = 300.0;
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let RandomSession { truth, data, .. } =
        random_session(&robot, duration, 1.0, &SimulateOptions::paper(&robot), 2024)
            .expect("simulate");
    let opts = CalibrateOptions::new(&robot);
    println!(
        "session: {} IMU + {} joint samples, {:.0} s; truth tau = {:.3} s",
        data.imu_t.len(),
        data.joint_t.len(),
        duration,
        truth[layout.offsets().tau]
    );
    let runs = 7;
    // The same session fitted by generalised least squares: AR(1)
    // accelerometer noise with a 30 ms correlation time (robimu_solver::problem).
    let sz = robot.sigma_z();
    let phi = (-1.0f64 / (120.0 * 0.030)).exp();
    let mut gls = opts.clone();
    gls.noise = Some(NoiseModel {
        imu: std::array::from_fn(|c| {
            if c < 3 {
                ChannelNoise::new(ArNoise::new(vec![phi], sz[c]).expect("AR"), 0.0).expect("AR")
            } else {
                ChannelNoise::white(sz[c]).expect("white")
            }
        }),
    });
    let mut medians = Vec::new();
    for (label, opts) in [("white", &opts), ("GLS AR(1) accelerometer", &gls)] {
        let mut times = Vec::new();
        let mut iterations = 0;
        let mut coeffs = 0;
        for _ in 0..runs {
            let t = Instant::now();
            let cal = calibrate(&robot, &data, opts, |_| {}).expect("calibrate");
            times.push(t.elapsed().as_secs_f64());
            iterations = cal.summary.iterations.len();
            coeffs = cal.trajectory.coeffs().len();
        }
        times.sort_by(f64::total_cmp);
        println!(
            "calibrate from nominal, {label}: median {:.3} s (min {:.3}, max {:.3}) over {runs} runs; {iterations} LM iterations; {coeffs} coefficients + {} parameters",
            times[runs / 2],
            times[0],
            times[runs - 1],
            layout.len()
        );
        medians.push(times[runs / 2]);
    }
    println!("GLS / white time: {:.2}", medians[1] / medians[0]);
    if let Some(mb) = peak_rss_mb() {
        println!("peak memory (VmHWM, whole process incl. the simulated session): {mb:.0} MB");
    }
}
