//! The flange pose session against the joint session of the same motion:
//! (issue 39) the same sensor parameters from both calibrations within
//! their σ. (Its files against the joint session's: `pose_simulate`'s tests.)

use super::*;
use crate::calibrate::{calibrate, CalibrateOptions};
use crate::pose_calibrate::{calibrate_poses, PoseCalibrationOptions};
use robimu_model::pose_measurement::ACCEL;

/// The sensor parameters (x̂, σ) of both calibrations of one AUBO i5 motion.
fn both_ways(duration: f64, seed: u64) -> (Vec<String>, [Vec<f64>; 4]) {
    let robot = Robot::aubo_i5();
    let m = simulate_motion(&SessionSpec::plain(
        robot.clone(),
        duration,
        100.0,
        seed,
        PathBuf::new(),
    ))
    .unwrap();
    let joint = calibrate(&robot, &m.data, &CalibrateOptions::new(&robot), |_| {}).unwrap();
    let f = flange_session(
        robot.clone(),
        1,
        duration,
        100.0,
        seed,
        100.0,
        0.0,
        &PoseNoise::default(),
    )
    .unwrap();
    assert_eq!(f.data.imu_t, m.data.imu_t);
    let opts = PoseCalibrationOptions {
        sigma_z: f.sigma_z,
        ..Default::default()
    };
    let pose = calibrate_poses(&f.data, &opts).unwrap();
    let o = m.layout.offsets().gamma_a;
    let names = pose.names[ACCEL..].to_vec();
    for (k, n) in names.iter().enumerate() {
        assert_eq!(&m.layout.specs()[o + k].name, n);
    }
    (
        names,
        [
            joint.x[o..o + 24].to_vec(),
            joint.sigma[o..o + 24].to_vec(),
            pose.x[ACCEL..].to_vec(),
            pose.sigma[ACCEL..].to_vec(),
        ],
    )
}

/// Issue 39: the same data through the robot description (joint angles)
/// and through the flange's pose stream of the same motion at the same
/// rate (100 Hz) agree on the 24 sensor parameters within their σ:
/// |x_joint − x_pose| / √(σ_joint² + σ_pose²) < 3 for each (seed
/// `AGREE_SEED`, default 3).
#[test]
fn joint_and_pose_calibrations_of_one_motion_agree_on_the_sensor() {
    let seed = std::env::var("AGREE_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let (names, [xj, sj, xp, sp]) = both_ways(60.0, seed);
    let mut worst = (0.0f64, String::new());
    for k in 0..24 {
        let pi = std::f64::consts::PI;
        let mut d = xj[k] - xp[k];
        if names[k].starts_with("r_") {
            d = (d + pi).rem_euclid(2.0 * pi) - pi; // the same angle
        }
        let z = d / (sj[k] * sj[k] + sp[k] * sp[k]).sqrt();
        println!(
            "{:12} joint {:+.6e} ± {:.2e}  pose {:+.6e} ± {:.2e}  z {z:+.2}",
            names[k], xj[k], sj[k], xp[k], sp[k]
        );
        if z.abs() > worst.0 {
            worst = (z.abs(), names[k].clone());
        }
    }
    println!("worst |z| {:.2} ({})", worst.0, worst.1);
    assert!(
        worst.0 < 3.0,
        "{} differs by {:.2} combined σ",
        worst.1,
        worst.0
    );
}
