//! The twin in virtual time (`robimu_hil::twin::record_offline`): the same
//! simulated hardware as the real-time rig, recorded as fast as the
//! computer goes. Checked against a real-time recording of the same seed
//! (same statistics, the same τ and sensor delay within their σ), then used
//! for the realistic twin's end-to-end check (`robimu demo --fast`) and its
//! null sessions (docs/model.md §4.8).

use std::path::Path;
use std::time::Instant;

use rand::SeedableRng;
use robimu_hil::rig::{SimRig, SimRigConfig};
use robimu_hil::truth::signal_delay;
use robimu_hil::twin::{record_offline, TwinOptions, TwinSummary};
use robimu_model::trajectory::random_walk;
use robimu_model::{ParamLayout, Robot};
use robimu_protocol::SensorConfig;
use robimu_record::controller::RobotSpec;
use robimu_record::motion::Plan;
use robimu_record::{record, RecordOptions};
use robimu_session::Session;
use robimu_workflows::calibrate::fit::Start;
use robimu_workflows::calibrate::noise_choice::{calibrate_with_noise, NoiseChoice};
use robimu_workflows::calibrate::CalibrateOptions;
use robimu_workflows::diagnose::{fit_effects, setup_for};

mod common;
use common::robimu_ok;

/// A random-walk plan (the record tests' kind) of `duration` s.
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

/// What one recording shows: IMU rate, clock drift, the identified
/// accelerometer φ and σ, τ and δ (`sensor_delay`) with their σ.
#[derive(Debug)]
struct Figures {
    rate_hz: f64,
    drift_ppm: f64,
    phi: [f64; 3],
    sigma: [f64; 6],
    tau: (f64, f64),
    delta: (f64, f64),
}

fn figures(dir: &Path) -> Figures {
    let robot = Robot::aubo_i5();
    let session = Session::load(dir).unwrap();
    let data = session.measurements();
    let span = data.imu_t.last().unwrap() - data.imu_t[0];
    let opts = CalibrateOptions::new(&robot);
    let (cal, _) = calibrate_with_noise(&robot, &data, &opts, &NoiseChoice::Auto, |_| {}).unwrap();
    let setup = setup_for(&robot, &data, None);
    let mut gls = opts.clone();
    gls.noise = Some(cal.noise_model.clone());
    let with_delay = fit_effects(
        &robot,
        &data,
        &gls,
        &setup,
        &["sensor_delay".to_string()],
        Start::Nominal,
    )
    .unwrap();
    let tau = ParamLayout::new(&robot).offsets().tau;
    let meta = std::fs::read_to_string(dir.join("session.toml")).unwrap();
    let meta: toml::Table = meta.parse().unwrap();
    let drift = meta["imu"]["clock"][0]["drift_ppm"].as_float().unwrap();
    let ch = &cal.noise_model.imu;
    Figures {
        rate_hz: (data.imu_t.len() - 1) as f64 / span,
        drift_ppm: drift,
        phi: std::array::from_fn(|c| ch[c].ar.phi().first().copied().unwrap_or(0.0)),
        sigma: std::array::from_fn(|c| ch[c].ar.sigma()),
        tau: (with_delay.x[tau], with_delay.sigma_x[tau]),
        delta: (with_delay.theta_e[0], with_delay.sigma_e[0]),
    }
}

/// The signal delays of the default sensor settings' bandwidths and ODRs
/// (session.toml's `[imu]` timing keys): gyroscope, accelerometer.
fn delays(dir: &Path) -> [f64; 2] {
    let session = Session::load(dir).unwrap();
    let t = session
        .meta
        .imu_timing(&dir.join("session.toml"))
        .unwrap()
        .expect("timing keys");
    [
        signal_delay(t.gyro_bandwidth_hz, t.gyro_odr_hz),
        signal_delay(t.accel_bandwidth_hz, t.accel_odr_hz),
    ]
}

/// The same rig (datasheet chip, vibration noise; seed 7) recorded in real
/// time over the pseudo-terminal and TCP, and in virtual time: the same
/// IMU rate (the real-time one up to 1 % lower on a loaded machine) and
/// clock drift, the same identified accelerometer noise (φ
/// within 0.05, σ within 20 %), and τ and δ each within 4σ of the chip's
/// delays (τ = −d_g, δ = d_a − d_g) and within 3 combined σ of each other.
/// (45 s: a 25 s recording in real time.)
#[test]
fn the_virtual_time_twin_records_what_the_real_time_rig_records() {
    let robot = Robot::aubo_i5();
    let p = plan(7, 25.0);
    let mut config = SimRigConfig::realistic_null(robot.clone(), 7).unwrap();
    config.initial = p.q[0];
    let virt = tempfile::tempdir().unwrap();
    offline(&config, &p, virt.path());
    let real = tempfile::tempdir().unwrap();
    let rig = SimRig::spawn(&config).unwrap();
    let opts = RecordOptions {
        imu_port: rig.imu_port().to_string(),
        extra_imu_ports: Vec::new(),
        baud: 921_600,
        robot_spec: RobotSpec::parse(&rig.robot_spec()).unwrap(),
        robot: robot.clone(),
        robot_name: "aubo_i5".into(),
        plan: Some(p.clone()),
        duration: 0.0,
        out: real.path().to_path_buf(),
        joint_rate: 125.0,
        rest: 1.0,
        sensor: SensorConfig::default(),
        interrupt: None,
    };
    record(&opts, &mut |_| {}).unwrap();
    drop(rig);
    let [dg, da] = delays(virt.path());
    assert_eq!([dg, da], delays(real.path()));
    let (v, r) = (figures(virt.path()), figures(real.path()));
    eprintln!(
        "virtual {v:?}\nreal    {r:?}\nwant τ {:.3} ms, δ {:.3} ms",
        -dg * 1e3,
        (da - dg) * 1e3
    );
    // A loaded machine can make the real-time board miss deadlines (it
    // drops and counts them, as the real one does): at the default 150 Hz
    // (6.7 ms deadlines) a loaded CI run measured 1.2 %; up to 3 % there.
    let rate = f64::from(SensorConfig::default().sample_rate_hz);
    assert!(
        r.rate_hz > 0.97 * rate && r.rate_hz < rate + 0.1,
        "{} vs {} Hz",
        v.rate_hz,
        r.rate_hz
    );
    assert!((v.rate_hz - rate).abs() < 0.1, "{} Hz", v.rate_hz);
    for f in [&v, &r] {
        assert!((f.drift_ppm - 48.7).abs() < 2.0, "drift {}", f.drift_ppm);
        let z_tau = (f.tau.0 + dg) / f.tau.1;
        let z_delta = (f.delta.0 - (da - dg)) / f.delta.1;
        assert!(
            z_tau.abs() < 4.0 && z_delta.abs() < 4.0,
            "τ {z_tau:.2}σ, δ {z_delta:.2}σ: {f:?}"
        );
    }
    for c in 0..3 {
        assert!((v.phi[c] - r.phi[c]).abs() < 0.05, "φ_{c}: {v:?} vs {r:?}");
    }
    for c in 0..6 {
        assert!(
            (v.sigma[c] / r.sigma[c] - 1.0).abs() < 0.2,
            "σ_{c}: {v:?} vs {r:?}"
        );
    }
    let apart = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() / a.1.hypot(b.1);
    assert!(apart(v.tau, r.tau) < 3.0, "τ {:?} vs {:?}", v.tau, r.tau);
    assert!(
        apart(v.delta, r.delta) < 3.0,
        "δ {:?} vs {:?}",
        v.delta,
        r.delta
    );
}

/// The clock mapping's error the twin reports
/// ([`TwinSummary::imu_time_error_s`], which the demo's τ truth adds) puts
/// the session's IMU times back where the board stamped them: on its poll
/// grid (virtual time advances by whole polls). Without it they sit half a
/// poll off (a ping is answered at the next poll and its echo read there).
#[test]
fn the_twins_imu_time_error_puts_the_samples_back_on_the_poll_grid() {
    let p = plan(2, 10.0);
    let mut config = SimRigConfig::realistic_null(Robot::aubo_i5(), 2).unwrap();
    config.initial = p.q[0];
    let dir = tempfile::tempdir().unwrap();
    let s = offline(&config, &p, dir.path());
    let poll = TwinOptions::default().poll_interval_s;
    let data = Session::load(dir.path()).unwrap().measurements();
    // the largest distance of a sample's time + e from the grid, in polls
    let off = |e: f64| {
        data.imu_t
            .iter()
            .map(|t| {
                let x = (t + e) / poll;
                (x - x.round()).abs()
            })
            .fold(0.0f64, f64::max)
    };
    let e = s.imu_time_error_s;
    assert!(
        off(e) < 0.02,
        "e = {e:.3e} s: {:.3} polls off the grid",
        off(e)
    );
    assert!(off(0.0) > 0.4, "without e: {:.3} polls off", off(0.0));
    assert!(
        (e / poll - 0.5).abs() < 0.02,
        "e = {e:.3e} s, poll {poll:.1e} s"
    );
}

/// `robimu demo --fast` on the realistic twin at its defaults: diagnose's
/// final model puts every parameter with a truth within 4σ of it
/// (truth_check.json), the truth includes a share of the mount mode that
/// raises the gyroscope gains, and the check is printed.
#[test]
fn the_demo_on_the_realistic_twin_recovers_the_truth_within_4_sigma() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let run = robimu_ok([
        "demo",
        "--fast",
        "--duration",
        "60",
        "--seed",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        run.stdout.contains("== 6. against the truth =="),
        "{}",
        run.stdout
    );
    let check: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("report/truth_check.json")).unwrap(),
    )
    .unwrap();
    let params = check["parameters"].as_array().unwrap();
    assert!(params.len() >= 48, "{check}");
    assert_eq!(check["twin"], "realistic");
    let beyond: Vec<String> = params
        .iter()
        .filter(|p| p["z"].as_f64().unwrap().abs() > 4.0)
        .map(|p| format!("{} {:+.2}σ", p["name"], p["z"]))
        .collect();
    assert!(beyond.is_empty(), "beyond 4σ: {beyond:?}\n{}", run.stdout);
    assert_eq!(check["all_within"], true);
    // the mount mode amplifies the flange's rotation below its frequency
    // (docs/model.md §4.8): the fit's share of it raises every gyroscope
    // gain, by a fraction of σ on 60 s
    for axis in ["x", "y", "z"] {
        let name = format!("k_w_{axis}");
        let p = params.iter().find(|p| p["name"] == name.as_str()).unwrap();
        let share = p["mode_share"].as_f64().unwrap() / p["sigma"].as_f64().unwrap();
        assert!(
            (0.2..3.0).contains(&share),
            "{name}: mode share {share:+.2}σ"
        );
    }
    assert!(
        run.stdout.contains("share of the twin's structural mode"),
        "{}",
        run.stdout
    );
    assert!(
        run.stdout.contains("truth check: every one of"),
        "{}",
        run.stdout
    );
}

/// Effects diagnose finds on a null session of the realistic twin
/// (hidden effects off) that are false alarms: anything but
/// `sensor_delay`, which the datasheet chip's filters make true.
fn null_false_alarms(seed: u64, duration: f64, rate_hz: u16) -> Vec<String> {
    let robot = Robot::aubo_i5();
    let p = plan(seed, duration);
    let mut config = SimRigConfig::realistic_null(robot.clone(), seed).unwrap();
    config.initial = p.q[0];
    if let Ok(ppm) = std::env::var("ROBIMU_TWIN_CHIP_PPM") {
        config.chip_clock_error_ppm = ppm.parse().unwrap();
    }
    let dir = tempfile::tempdir().unwrap();
    let mut opts = TwinOptions::default();
    opts.sensor.sample_rate_hz = rate_hz;
    record_offline(&config, &p, dir.path(), &opts).unwrap();
    let data = Session::load(dir.path()).unwrap().measurements();
    let (_, d) = common::diagnose_all(&robot, &data);
    let found: Vec<String> = d.found.iter().map(|f| f.name.clone()).collect();
    eprintln!("seed {seed} at {rate_hz} Hz: found {found:?}");
    found.into_iter().filter(|n| n != "sensor_delay").collect()
}

/// Seeds of the null-session test in CI (docs/performance.md's twin figure runs 20:
/// `cargo test -p robimu --release --test twin -- --ignored twenty`).
const NULL_SEEDS_CI: u64 = 3;

/// The sampling rate of the null sessions and the demo: the firmware's
/// default, the alias rule's choice (docs/model.md §4.8: 150 Hz; at the
/// paper's 120 Hz the accelerometer's data age beats at 125 − 120 = 5 Hz).
const RATE_HZ: u16 = robimu_protocol::DEFAULT_SAMPLE_RATE_HZ;

/// The number of null sessions (seeds 1..=`seeds`, 60 s at `rate_hz`) with
/// a false alarm.
fn null_sessions(seeds: u64, rate_hz: u16) -> usize {
    let alarms: Vec<(u64, Vec<String>)> = (1..=seeds)
        .map(|s| (s, null_false_alarms(s, 60.0, rate_hz)))
        .filter(|(_, a)| !a.is_empty())
        .collect();
    eprintln!(
        "false alarms in {} of {seeds} null sessions at {rate_hz} Hz: {alarms:?}",
        alarms.len()
    );
    alarms.len()
}

/// Null sessions of the realistic twin (datasheet chip with its +0.8 %
/// clock, vibration noise; warm-up, elasticity and mode off; 60 s at the
/// default rate): no false alarm in the first [`NULL_SEEDS_CI`] seeds.
#[test]
fn null_sessions_of_the_realistic_twin_raise_no_false_alarm() {
    assert_eq!(null_sessions(NULL_SEEDS_CI, RATE_HZ), 0);
}

/// The figure: at most 1 false alarm in 20 null sessions at the
/// default rate (`ROBIMU_TWIN_RATE=120` or `=100` runs them at an aliasing
/// rate, for contrast; `ROBIMU_TWIN_CHIP_PPM=0` with an exact chip clock).
#[test]
#[ignore = "20 sessions of 60 s with a full diagnosis each (about 3 min in release); docs/performance.md's twin figure"]
fn twenty_null_sessions_of_the_realistic_twin_raise_at_most_one_false_alarm() {
    let rate = std::env::var("ROBIMU_TWIN_RATE").map_or(RATE_HZ, |r| r.parse().unwrap());
    assert!(null_sessions(20, rate) <= 1);
}
