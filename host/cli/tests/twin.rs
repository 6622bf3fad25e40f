//! The twin in virtual time (`robimu_hil::twin::record_offline`): the same
//! simulated hardware as the real-time rig, recorded as fast as the
//! computer goes; checked against a real-time recording of the same seed,
//! and used for the realistic twin's end-to-end and null-session checks.

use std::path::Path;
use std::time::Instant;

use rand::SeedableRng;
use robimu_hil::rig::SimRigConfig;
use robimu_hil::twin::{record_offline, TwinOptions, TwinSummary};
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_record::motion::Plan;
use robimu_session::Session;
use robimu_workflows::calibrate::{calibrate, CalibrateOptions};

fn plan(seed: u64, duration: f64) -> Plan {
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let traj = random_walk(&robot, duration, 1.0, &mut rng).unwrap();
    Plan::from_spline(&traj, 250.0)
}

fn offline(config: &SimRigConfig, plan: &Plan, dir: &Path) -> TwinSummary {
    let t0 = Instant::now();
    let s = record_offline(config, plan, dir, &TwinOptions::default()).unwrap();
    eprintln!(
        "virtual-time recording of {:.1} s took {:.2} s ({} IMU, {} joint samples)",
        s.duration,
        t0.elapsed().as_secs_f64(),
        s.imu_samples,
        s.joint_samples
    );
    s
}

#[test]
fn scratch_ideal() {
    let robot = Robot::aubo_i5();
    let p = plan(21, 30.0);
    let mut config = SimRigConfig::drawn(robot.clone(), 21);
    config.initial = p.q[0];
    let dir = tempfile::tempdir().unwrap();
    let s = offline(&config, &p, dir.path());
    let session = Session::load(dir.path()).unwrap();
    let layout = ParamLayout::new(&robot);
    let t0 = Instant::now();
    let cal = calibrate(&robot, &session.measurements(), &CalibrateOptions::new(&robot), |_| {}).unwrap();
    eprintln!("calibrate {:.1}s", t0.elapsed().as_secs_f64());
    let mut worst = (0.0f64, String::new());
    for (k, spec) in layout.specs().iter().enumerate() {
        let z = (cal.x[k] - s.truth.get(&spec.name).unwrap()) / cal.sigma[k];
        if z.abs() > worst.0 { worst = (z.abs(), spec.name.clone()); }
    }
    eprintln!("worst {worst:?}, tau {} ± {}", cal.x[layout.offsets().tau], cal.sigma[layout.offsets().tau]);
    eprintln!("{}", std::fs::read_to_string(dir.path().join("session.toml")).unwrap());
}
