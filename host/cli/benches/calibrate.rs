//! Calibration speed: a 300 s, 120 Hz AUBO i5 session (36,000 IMU + 36,000
//! joint samples; 1,818 spline coefficients + 48 parameters) calibrated from
//! nominal, τ search included. Prints the median wall time and peak memory.
//!
//! `cargo bench -p robimu --bench calibrate`

use std::time::Instant;

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
    let mut times = Vec::new();
    let mut iterations = 0;
    let mut coeffs = 0;
    for _ in 0..runs {
        let t = Instant::now();
        let cal = calibrate(&robot, &data, &opts, |_| {}).expect("calibrate");
        times.push(t.elapsed().as_secs_f64());
        iterations = cal.summary.iterations.len();
        coeffs = cal.trajectory.coeffs().len();
    }
    times.sort_by(f64::total_cmp);
    println!(
        "calibrate from nominal: median {:.3} s (min {:.3}, max {:.3}) over {runs} runs; {iterations} LM iterations; {coeffs} coefficients + {} parameters",
        times[runs / 2],
        times[0],
        times[runs - 1],
        layout.len()
    );
    if let Some(mb) = peak_rss_mb() {
        println!("peak memory (VmHWM, whole process incl. the simulated session): {mb:.0} MB");
    }
}
