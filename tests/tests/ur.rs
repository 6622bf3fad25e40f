//! The host's UR driver (RTDE + URScript) against the simulated controller.

// The normal equations are indexed by row and column.
#![allow(clippy::needless_range_loop)]

mod common;
use common::fit_sine;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::thread;
use std::time::{Duration, Instant};

use robimu_hil_sim::arm::reading_errors;
use robimu_hil_sim::ur::{FaultSwitches, SimUr, SimUrConfig};
use robimu_record::controller::ur::{
    FieldType, UrClient, UrError, UrPorts, UrRobot, SAMPLE_OUTPUTS,
};
use robimu_record::controller::JointSample;

const TIMEOUT: Duration = Duration::from_secs(2);

fn spawn(config: SimUrConfig) -> SimUr {
    SimUr::spawn(config).expect("simulator starts")
}

fn robot(sim: &SimUr, timeout: Duration) -> Result<UrRobot, UrError> {
    let ports = UrPorts {
        rtde: sim.rtde_addr().port(),
        script: sim.script_addr().port(),
    };
    UrRobot::connect("127.0.0.1", ports, timeout)
}

#[test]
fn negotiation_recipes_and_refusals() {
    let sim = spawn(SimUrConfig::default());
    let mut c = UrClient::connect(sim.rtde_addr(), TIMEOUT).unwrap();
    assert!(matches!(
        c.negotiate_version(3),
        Err(UrError::VersionRefused { version: 3 })
    ));
    c.negotiate_version(2).unwrap();
    // Start before any recipe: refused.
    assert!(matches!(c.start(), Err(UrError::Refused { .. })));
    let r = c.setup_outputs(125.0, &SAMPLE_OUTPUTS).unwrap();
    assert_eq!(r.types, vec![FieldType::Double, FieldType::Vector6D]);
    assert!(r.id >= 1);
    assert_eq!(r.size(), 56);
    // An unknown output: NOT_FOUND, named in the error.
    match c.setup_outputs(125.0, &["timestamp", "actual_qq"]) {
        Err(e @ UrError::BadRecipe { .. }) => {
            let text = e.to_string();
            assert!(
                text.contains("actual_qq") && text.contains("NOT_FOUND"),
                "{text}"
            );
        }
        other => panic!("{other:?}"),
    }
    // Faster than the controller's 500 Hz: refused.
    match c.setup_outputs(1000.0, &SAMPLE_OUTPUTS) {
        Err(e @ UrError::Refused { .. }) => assert!(e.to_string().contains("1000"), "{e}"),
        other => panic!("{other:?}"),
    }
    // A CB-series controller that speaks only version 1.
    let old = spawn(SimUrConfig {
        max_protocol_version: 1,
        ..SimUrConfig::default()
    });
    match robot(&old, TIMEOUT) {
        Err(e @ UrError::VersionRefused { version: 2 }) => {
            assert!(e.to_string().contains("version 2"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    // Nothing listening.
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    assert!(matches!(
        UrClient::connect(("127.0.0.1", port), TIMEOUT),
        Err(UrError::Connect { .. })
    ));
    sim.stop();
    old.stop();
}

/// Samples for `secs` from a poller at `rate`.
fn poll(robot: &UrRobot, rate: f64, epoch: Instant, secs: f64) -> Vec<JointSample> {
    let poller = robot.spawn_poller(rate, epoch).unwrap();
    thread::sleep(Duration::from_secs_f64(secs));
    let (client, rx) = poller.stop();
    assert!(client.is_some(), "the stream pauses cleanly");
    rx.try_iter().map(|s| s.unwrap()).collect()
}

#[test]
fn samples_arrive_at_the_configured_rate_on_the_controller_clock() {
    for (control, rate) in [(125.0, 125.0), (500.0, 500.0), (500.0, 125.0)] {
        let epoch = Instant::now();
        let uptime = 5000.25;
        let sim = spawn(SimUrConfig {
            epoch,
            control_rate_hz: control,
            uptime_at_epoch_s: uptime,
            ..SimUrConfig::default()
        });
        let robot = robot(&sim, TIMEOUT).unwrap();
        let samples = poll(&robot, rate, epoch, 1.0);
        let n = samples.len() as f64;
        // Cycles a busy host missed are skipped, never sent late.
        assert!(
            n >= 0.85 * rate && n <= 1.02 * rate,
            "{n} samples at {rate} Hz"
        );
        let period = 1.0 / rate;
        let mut missed = 0;
        for w in samples.windows(2) {
            let (a, b) = (w[0].robot_t.unwrap(), w[1].robot_t.unwrap());
            let cycles = (b - a) / period;
            assert!(
                cycles >= 0.999 && (cycles - cycles.round()).abs() < 1e-6,
                "controller timestamps {a} → {b} are not whole cycles of {period} s"
            );
            missed += cycles.round() as usize - 1;
        }
        // The host receives each package after its cycle, within a few ms.
        let mut latency: Vec<f64> = samples
            .iter()
            .map(|s| s.t - (s.robot_t.unwrap() - uptime))
            .collect();
        latency.sort_by(f64::total_cmp);
        let median = latency[latency.len() / 2];
        eprintln!("{rate} Hz: {n} samples, {missed} cycles missed, median latency {median:.2e} s");
        // Causal, and on the host's clock (scheduling on a busy machine
        // adds a few ms).
        assert!(latency[0] >= 0.0 && median < 0.02, "latency {median} s");
        sim.stop();
    }
}

#[test]
fn servoj_plan_is_followed_with_the_configured_lag_and_noise() {
    let (lag, noise) = (0.02, 1e-3);
    let epoch = Instant::now();
    let uptime = 100.0;
    let sim = spawn(SimUrConfig {
        epoch,
        uptime_at_epoch_s: uptime,
        control_rate_hz: 125.0,
        tracking_lag_s: lag,
        encoder_noise_rad: noise,
        ..SimUrConfig::default()
    });
    let robot = robot(&sim, TIMEOUT).unwrap();
    // A 1 Hz sinusoid on joints 1 and 2, one row per 8 ms control cycle.
    let (amp, f, dt, duration) = (0.2, 1.0, 0.008, 3.0);
    let omega = std::f64::consts::TAU * f;
    let plan: Vec<(f64, Vec<f64>)> = (0..=(duration / dt) as usize)
        .map(|k| {
            let t = k as f64 * dt;
            let s = amp * (omega * t).sin();
            (t, vec![s, -0.5 * s, 0.0, 0.0, 0.0, 0.0])
        })
        .collect();
    // Reading actual and target joints in the same packages.
    let mut c = UrClient::connect(sim.rtde_addr(), TIMEOUT).unwrap();
    c.negotiate_version(2).unwrap();
    c.setup_outputs(125.0, &["timestamp", "actual_q", "target_q"])
        .unwrap();
    c.start().unwrap();
    let planned = robot.execute_plan(&plan).unwrap();
    assert!((planned - duration).abs() < 1e-9);
    let start = Instant::now();
    let mut rows = Vec::new();
    while start.elapsed().as_secs_f64() < duration + 0.2 {
        rows.push(c.read_data().unwrap());
    }
    c.pause().unwrap();
    assert!(!sim.program_running(), "the program has ended");
    assert!(sim.script_errors().is_empty(), "{:?}", sim.script_errors());

    // Steady state: from 10 time constants after the motion starts (the
    // first cycle whose target moved) to the end of the plan.
    let t_of = |r: &Vec<Vec<f64>>| r[0][0] - uptime;
    let t_move = rows
        .iter()
        .find(|r| r[2][0] != 0.0)
        .map(t_of)
        .expect("the target moves");
    let window: Vec<&Vec<Vec<f64>>> = rows
        .iter()
        .filter(|r| t_of(r) > t_move + 0.3 && t_of(r) < t_move + duration - 0.05)
        .collect();
    // 331 cycles; a busy host may skip some (never send them late).
    eprintln!("{} rows, {} in the window", rows.len(), window.len());
    assert!(window.len() > 250, "{} samples", window.len());
    let ts: Vec<f64> = window.iter().map(|r| t_of(r)).collect();
    let actual: Vec<f64> = window.iter().map(|r| r[1][0]).collect();
    let target: Vec<f64> = window.iter().map(|r| r[2][0]).collect();
    let (aa, ab, ac, rms) = fit_sine(&ts, &actual, omega);
    let (ta, tb, _, target_rms) = fit_sine(&ts, &target, omega);
    // A first-order lag τ delays a sinusoid by atan(ωτ)/ω and scales it by
    // 1/√(1+(ωτ)²).
    let phase = |a: f64, b: f64| b.atan2(a);
    let lag_est = (phase(ta, tb) - phase(aa, ab)) / omega;
    let lag_expected = (omega * lag).atan() / omega;
    let gain = (aa * aa + ab * ab).sqrt() / (ta * ta + tb * tb).sqrt();
    eprintln!(
        "lag {lag_est} s (expected {lag_expected}), gain {gain}, noise {rms} rad, target fit rms {target_rms}"
    );
    assert!(
        (lag_est - lag_expected).abs() < 0.1 * lag_expected,
        "lag {lag_est} s, expected {lag_expected} s"
    );
    assert!(
        (gain - 1.0 / (1.0 + (omega * lag).powi(2)).sqrt()).abs() < 0.01,
        "gain {gain}"
    );
    assert!(
        ((ta * ta + tb * tb).sqrt() - amp).abs() < 1e-3,
        "target amplitude"
    );
    assert!(ac.abs() < 1e-3, "offset {ac}");
    assert!(
        (rms - noise).abs() < 0.2 * noise,
        "noise {rms}, expected {noise}"
    );

    // Reported angles against the true trajectory at their cycle times.
    let log = sim.true_trajectory();
    let (mean, sd) = reading_errors(&log, 1, window.iter().map(|r| (t_of(r), r[1][1])));
    assert!(
        mean.abs() < 2e-4 && (sd - noise).abs() < 0.2 * noise,
        "mean {mean} sd {sd}"
    );
    // The end pose is held.
    let end = sim.true_joints();
    let last = &plan.last().unwrap().1;
    assert!((end[0] - last[0]).abs() < 1e-3, "{end:?}");
    sim.stop();
}

#[test]
fn split_packages_and_text_messages_are_reassembled() {
    let sim = spawn(SimUrConfig {
        control_rate_hz: 125.0,
        faults: FaultSwitches {
            split_writes: true,
            ..FaultSwitches::default()
        },
        ..SimUrConfig::default()
    });
    // Every reply and data package arrives in two pieces; the text message
    // after the version reply is skipped.
    let mut c = UrClient::open_stream(sim.rtde_addr(), 125.0, TIMEOUT).unwrap();
    let epoch = Instant::now();
    let samples: Vec<_> = (0..40).map(|_| c.read_sample(epoch).unwrap()).collect();
    for w in samples.windows(2) {
        let cycles = (w[1].robot_t - w[0].robot_t) * 125.0;
        assert!((cycles - cycles.round()).abs() < 1e-6 && cycles > 0.5);
    }
    assert!(samples.iter().all(|s| s.q.iter().all(|x| x.abs() < 0.01)));
    c.pause().unwrap();

    // The simulator reassembles requests written a byte at a time.
    let mut raw = TcpStream::connect(sim.rtde_addr()).unwrap();
    raw.set_nodelay(true).unwrap();
    for b in [0u8, 5, b'V', 0, 2] {
        raw.write_all(&[b]).unwrap();
        thread::sleep(Duration::from_millis(2));
    }
    raw.set_read_timeout(Some(TIMEOUT)).unwrap();
    let mut reply = Vec::new();
    let mut chunk = [0u8; 64];
    while reply.len() < 4 {
        let n = raw.read(&mut chunk).unwrap();
        assert!(n > 0);
        reply.extend_from_slice(&chunk[..n]);
    }
    assert_eq!(&reply[..4], &[0, 4, b'V', 1]);
    sim.stop();
}

#[test]
fn dropped_connections_slow_replies_and_bad_programs_give_clear_errors() {
    let epoch = Instant::now();
    let sim = spawn(SimUrConfig {
        epoch,
        control_rate_hz: 125.0,
        faults: FaultSwitches {
            drop_connection_after: Some(5),
            ..FaultSwitches::default()
        },
        ..SimUrConfig::default()
    });
    let robot = robot(&sim, TIMEOUT).unwrap();
    let poller = robot.spawn_poller(125.0, epoch).unwrap();
    let results: Vec<_> = poller.samples().iter().take(10).collect();
    assert_eq!(results.len(), 6);
    assert!(results[..5].iter().all(Result::is_ok));
    match &results[5] {
        Err(e @ UrError::Disconnected { .. }) => {
            assert!(e.to_string().contains("reading data packages"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    let (client, _) = poller.stop();
    assert!(client.is_none());

    // Replies slower than the timeout.
    sim.set_faults(FaultSwitches {
        reply_delay: Duration::from_millis(300),
        ..FaultSwitches::default()
    });
    let timeout = Duration::from_millis(100);
    let mut c = UrClient::connect(sim.rtde_addr(), timeout).unwrap();
    let t = Instant::now();
    match c.negotiate_version(2) {
        Err(e @ UrError::Timeout { .. }) => {
            assert!(e.to_string().contains("protocol version"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    assert!(t.elapsed() < Duration::from_millis(250));
    sim.set_faults(FaultSwitches::default());

    // A plan the client refuses before sending, and a program the
    // controller refuses: the robot stays put.
    let bad_plan = vec![(0.0, vec![0.0; 6]), (0.0, vec![0.1; 6])];
    assert!(matches!(
        robot.execute_plan(&bad_plan),
        Err(UrError::Plan(_))
    ));
    let mut s = TcpStream::connect(sim.script_addr()).unwrap();
    s.write_all(b"def p():\n  speedj([0.5, 0, 0, 0, 0, 0], a=1.0, t=1.0)\nend\n")
        .unwrap();
    s.shutdown(std::net::Shutdown::Write).unwrap();
    let t = Instant::now();
    while sim.script_errors().is_empty() && t.elapsed() < TIMEOUT {
        thread::sleep(Duration::from_millis(5));
    }
    let errors = sim.script_errors();
    assert!(
        errors.len() == 1 && errors[0].contains("speedj"),
        "{errors:?}"
    );
    thread::sleep(Duration::from_millis(50));
    assert_eq!(sim.true_joints(), [0.0; 6]);
    sim.stop();
}

/// `ur_rtde`'s `RTDEReceiveInterface` (SDU Robotics' library from PyPI, the
/// one UR users script with) reads the simulated controller's joint
/// positions for 10 s with no error: protocol version, controller version,
/// output recipe and start as a real controller answers them. It connects
/// to the real RTDE port 30004, so the simulator listens there. Skipped
/// with a message where `ur_rtde` is not installed, except in CI
/// (`CI=true`), which installs it.
#[test]
fn ur_rtde_receive_interface_reads_the_joints() {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/ur_rtde_receive.py");
    let initial = [0.1, -1.2, 1.0, -0.5, 0.3, 0.7];
    let sim = SimUr::spawn(SimUrConfig {
        bind: "127.0.0.1:30004".parse().unwrap(),
        initial,
        ..SimUrConfig::default()
    })
    .expect("the simulator listens on 127.0.0.1:30004 (ur_rtde's fixed RTDE port)");
    let out = std::process::Command::new("python3")
        .args([script, "127.0.0.1", "10"])
        .output()
        .expect("run python3");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(3) && std::env::var("CI").is_err() {
        eprintln!("skipped: {stderr} (pip install ur-rtde to run this test)");
        return;
    }
    assert!(out.status.success(), "ur_rtde failed: {stderr}");
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("the script's JSON");
    eprintln!("{r}");
    // about 100 readings a second for 10 s (the script polls every 10 ms)
    let readings = r["readings"].as_u64().unwrap();
    assert!(readings >= 500, "{readings} readings in 10 s");
    // the controller's clock ran 10 s, with no hole longer than 0.1 s
    let span = r["last_timestamp"].as_f64().unwrap() - r["first_timestamp"].as_f64().unwrap();
    assert!((9.0..11.0).contains(&span), "controller time span {span} s");
    assert!(r["largest_gap_s"].as_f64().unwrap() < 0.1, "{r}");
    // the robot at rest at its initial angles (encoder noise 1e-4 rad)
    for (j, q0) in initial.iter().enumerate() {
        let q = r["mean_q"][j].as_f64().unwrap();
        assert!((q - q0).abs() < 1e-4, "joint {j}: {q} vs {q0}");
    }
    drop(sim);
}
