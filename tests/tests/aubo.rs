//! The host's AUBO driver against the simulated ARCS controller.

// The normal equations are indexed by row and column.
#![allow(clippy::needless_range_loop)]

mod common;
use common::fit_sine;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::thread;
use std::time::{Duration, Instant};

use robimu_hil_sim::arm::{reading_errors, true_joints_at};
use robimu_hil_sim::aubo::{FaultSwitches, JointLimits, SimAubo, SimAuboConfig};
use robimu_record::controller::aubo::{AuboClient, AuboError, JointPoller, JointSample};
use serde_json::Value;

const TIMEOUT: Duration = Duration::from_secs(2);

fn spawn(lag: f64, noise: f64, limits: JointLimits, faults: FaultSwitches) -> (SimAubo, Instant) {
    let epoch = Instant::now();
    let sim = SimAubo::spawn(SimAuboConfig {
        epoch,
        tracking_lag_s: lag,
        encoder_noise_rad: noise,
        limits,
        faults,
        ..SimAuboConfig::default()
    })
    .expect("simulator starts");
    (sim, epoch)
}

#[test]
fn move_joint_reaches_target_within_velocity_and_acceleration_limits() {
    let limits = JointLimits::uniform(3.0, 1.0, 2.0);
    let (sim, _) = spawn(0.02, 1e-4, limits, FaultSwitches::default());
    let mut robot = AuboClient::connect(sim.addr(), TIMEOUT).unwrap();
    let target = [1.5, -0.75, 0.3, 0.0, 1.0, -1.5];
    // Asked for more than the limits: the controller clamps to 1 rad/s, 2 rad/s².
    robot.move_joint(&target, 5.0, 3.0).unwrap();
    robot.wait_idle(Duration::from_secs(10)).unwrap();
    thread::sleep(Duration::from_millis(300)); // 15 lag time constants
    let q = robot.joint_positions().unwrap();
    for j in 0..6 {
        assert!(
            (q[j] - target[j]).abs() < 1e-3,
            "joint {j}: {} vs {}",
            q[j],
            target[j]
        );
    }
    // Beyond the position limits: refused with AUBO_POS_BOUND_ERR.
    match robot.move_joint(&[3.5, 0.0, 0.0, 0.0, 0.0, 0.0], 1.0, 1.0) {
        Err(AuboError::Refused {
            method,
            code,
            message,
        }) => {
            assert_eq!(code, -18);
            assert!(
                method.ends_with("moveJoint") && message.contains("limit"),
                "{message}"
            );
        }
        other => panic!("expected a refusal, got {other:?}"),
    }

    // The true trajectory on a 2 ms grid: speed and acceleration by finite
    // differences (joint 0 moves farthest, so it sets the profile).
    let log = sim.true_trajectory();
    let (t0, t1) = (log[0].t, log.last().unwrap().t);
    let h = 0.002;
    let grid: Vec<f64> = (0..((t1 - t0) / h) as usize)
        .map(|k| true_joints_at(&log, t0 + k as f64 * h)[0])
        .collect();
    let vel: Vec<f64> = grid.windows(2).map(|w| (w[1] - w[0]) / h).collect();
    // Over 20 ms: the log is sampled irregularly (≤ 2 ms apart) and linear
    // interpolation adds about 5e-4 rad/s of velocity error, so this
    // estimate scatters by about ±0.03 rad/s² (the lag filter itself, a
    // positive unit-mass kernel, cannot exceed the reference's 2 rad/s²).
    let acc: Vec<f64> = vel
        .windows(11)
        .map(|w| (w[10] - w[0]) / (10.0 * h))
        .collect();
    let v_peak = vel.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let a_peak = acc.iter().fold(0.0_f64, |m, a| m.max(a.abs()));
    assert!(v_peak <= 1.0 * 1.01 && v_peak > 0.97, "peak speed {v_peak}");
    eprintln!("peak speed {v_peak} rad/s, peak acceleration {a_peak} rad/s²");
    assert!(
        a_peak <= 2.0 * 1.05 && a_peak > 1.6,
        "peak acceleration {a_peak}"
    );
    // Total displacement equals the commanded one (independent of the log).
    assert!((grid.last().unwrap() - grid[0] - 1.5).abs() < 1e-3);
    // Motion time: a trapezoid of 1.5 rad at 1 rad/s, 2 rad/s² lasts
    // 1.5/1 + 1/2 = 2 s; the true joint is moving (> 1% of v) about that long.
    let moving = vel.iter().filter(|v| v.abs() > 0.01).count() as f64 * h;
    assert!((moving - 2.0).abs() < 0.15, "moving for {moving} s");
    sim.stop();
}

#[test]
fn path_buffer_sinusoid_is_followed_with_the_configured_lag_and_noise() {
    let (lag, noise) = (0.02, 1e-3);
    let (sim, epoch) = spawn(lag, noise, JointLimits::default(), FaultSwitches::default());
    let mut robot = AuboClient::connect(sim.addr(), TIMEOUT).unwrap();
    let (amp, f, h, duration) = (0.2, 1.0, 0.004, 3.0);
    let omega = std::f64::consts::TAU * f;
    let n = (duration / h) as usize + 1;
    let points: Vec<[f64; 6]> = (0..n)
        .map(|k| {
            let s = amp * (omega * k as f64 * h).sin();
            [s, -0.5 * s, 0.0, 0.0, 0.0, 0.0]
        })
        .collect();
    robot.path_buffer_alloc("sine", 2, n).unwrap();
    // Moving before evaluation is refused (AUBO_BAD_STATE).
    for chunk in points.chunks(100) {
        robot.path_buffer_append("sine", chunk).unwrap();
    }
    assert!(matches!(
        robot.path_buffer_move("sine"),
        Err(AuboError::Refused { code: -1, .. })
    ));
    robot
        .path_buffer_eval("sine", &[10.0; 6], &[3.0; 6], h)
        .unwrap();

    let poller = JointPoller::spawn(
        AuboClient::connect(sim.addr(), TIMEOUT).unwrap(),
        125.0,
        epoch,
    )
    .unwrap();
    let sent = epoch.elapsed().as_secs_f64();
    robot.path_buffer_move("sine").unwrap();
    let t_start = (sent + epoch.elapsed().as_secs_f64()) / 2.0;
    thread::sleep(Duration::from_secs_f64(duration + 0.1));
    let (_, rx) = poller.stop();
    let samples: Vec<JointSample> = rx.try_iter().map(|s| s.unwrap()).collect();

    // Steady state only: skip 10 time constants and the end.
    let window: Vec<&JointSample> = samples
        .iter()
        .filter(|s| s.t > t_start + 0.3 && s.t < t_start + duration - 0.05)
        .collect();
    assert!(window.len() > 250, "{} samples", window.len());
    let ts: Vec<f64> = window.iter().map(|s| s.t - t_start).collect();
    let ys: Vec<f64> = window.iter().map(|s| s.q[0]).collect();
    let (a, b, c, rms) = fit_sine(&ts, &ys, omega);
    // R sin(ωτ − φ): φ/ω is the time lag; a first-order lag τ delays a
    // sinusoid by atan(ωτ)/ω and scales it by 1/√(1+(ωτ)²).
    let phase = (-b).atan2(a);
    let lag_est = phase / omega;
    let lag_expected = (omega * lag).atan() / omega;
    assert!(
        (lag_est - lag_expected).abs() < 0.3 * lag_expected,
        "lag {lag_est} s, expected {lag_expected} s"
    );
    let gain = (a * a + b * b).sqrt() / amp;
    eprintln!("lag {lag_est} s (expected {lag_expected}), gain {gain}, noise {rms} rad");
    assert!(
        (gain - 1.0 / (1.0 + (omega * lag).powi(2)).sqrt()).abs() < 0.01,
        "gain {gain}"
    );
    assert!(c.abs() < 1e-3, "offset {c}");
    assert!(
        (rms - noise).abs() < 0.3 * noise,
        "noise {rms}, expected {noise}"
    );

    // Polled readings against the true trajectory at the same instants.
    let log = sim.true_trajectory();
    let (mean, sd) = reading_errors(&log, 1, window.iter().map(|s| (s.t, s.q[1])));
    assert!(
        mean.abs() < 3e-4 && (sd - noise).abs() < 0.3 * noise,
        "mean {mean} sd {sd}"
    );
    sim.stop();
}

/// Reads `count` replies from a raw socket, parsing the bare-object stream.
fn read_replies(stream: &mut TcpStream, count: usize) -> Vec<Value> {
    stream.set_read_timeout(Some(TIMEOUT)).unwrap();
    let mut buf = Vec::new();
    let mut chunk = [0u8; 1024];
    loop {
        let mut it = serde_json::Deserializer::from_slice(&buf).into_iter::<Value>();
        let replies: Vec<Value> = it.by_ref().map_while(Result::ok).collect();
        if replies.len() >= count {
            return replies;
        }
        let n = stream.read(&mut chunk).expect("replies arrive");
        assert!(n > 0, "connection closed after {} replies", replies.len());
        buf.extend_from_slice(&chunk[..n]);
    }
}

#[test]
fn requests_split_across_writes_or_batched_in_one_write_are_all_answered() {
    let (sim, _) = spawn(0.02, 0.0, JointLimits::default(), FaultSwitches::default());
    let request = |id: u64, method: &str| {
        format!(r#"{{"jsonrpc":"2.0","method":"rob1.{method}","params":[],"id":{id}}}"#)
    };
    let text = format!(
        "{}{}\n {}",
        request(1, "RobotState.getJointPositions"),
        request(2, "MotionControl.isServoModeEnabled"),
        request(3, "RobotState.getJointPositions")
    );
    let mut stream = TcpStream::connect(sim.addr()).unwrap();
    stream.set_nodelay(true).unwrap();
    let bytes = text.as_bytes();
    let sizes = [1, 2, 3, 5, 7, 11, 13];
    let mut at = 0;
    for k in 0.. {
        if at >= bytes.len() {
            break;
        }
        let end = (at + sizes[k % sizes.len()]).min(bytes.len());
        stream.write_all(&bytes[at..end]).unwrap();
        stream.flush().unwrap();
        thread::sleep(Duration::from_millis(2));
        at = end;
    }
    let replies = read_replies(&mut stream, 3);
    let ids: Vec<u64> = replies.iter().map(|r| r["id"].as_u64().unwrap()).collect();
    assert_eq!(ids, vec![1, 2, 3]);
    assert_eq!(replies[0]["result"].as_array().unwrap().len(), 6);
    assert_eq!(replies[1]["result"], Value::Bool(false));

    // Five requests in one write.
    let batch: String = (10..15)
        .map(|id| request(id, "RobotState.getJointPositions"))
        .collect();
    stream.write_all(batch.as_bytes()).unwrap();
    let replies = read_replies(&mut stream, 5);
    let ids: Vec<u64> = replies.iter().map(|r| r["id"].as_u64().unwrap()).collect();
    assert_eq!(ids, (10..15).collect::<Vec<_>>());
    sim.stop();
}

#[test]
fn refused_and_malformed_commands_give_clear_errors() {
    let (sim, _) = spawn(0.02, 0.0, JointLimits::default(), FaultSwitches::default());
    let mut robot = AuboClient::connect(sim.addr(), TIMEOUT).unwrap();
    match robot.call("rob1.MotionControl.teleport", serde_json::json!([])) {
        Err(AuboError::Refused {
            code: -32601,
            message,
            ..
        }) => {
            assert!(message.contains("teleport"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    match robot.call(
        "rob1.MotionControl.moveJoint",
        serde_json::json!([[0.0, 1.0], 1.0, 1.0, 0, 0]),
    ) {
        Err(e @ AuboError::Refused { code: -32602, .. }) => {
            let text = e.to_string();
            assert!(text.contains("moveJoint") && text.contains("(q)"), "{text}")
        }
        other => panic!("{other:?}"),
    }
    let target = [0.1, 0.0, 0.0, 0.0, 0.0, -0.1];
    match robot.servo_joint(&target, 0.5) {
        Err(e @ AuboError::Refused { code: -13, .. }) => {
            let text = e.to_string();
            assert!(
                text.contains("servoJoint") && text.contains("servo mode"),
                "{text}"
            )
        }
        other => panic!("{other:?}"),
    }
    // In servo mode the same command is executed.
    robot.set_servo_mode(true).unwrap();
    robot.servo_joint(&target, 0.2).unwrap();
    thread::sleep(Duration::from_millis(500));
    let q = sim.true_joints();
    assert!(
        (q[0] - 0.1).abs() < 1e-4 && (q[5] + 0.1).abs() < 1e-4,
        "{q:?}"
    );
    // Too fast for the joint speed limit (π rad/s): refused.
    assert!(matches!(
        robot.servo_joint(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.1),
        Err(AuboError::Refused { code: -5, .. })
    ));
    robot.set_servo_mode(false).unwrap();
    // A robot in protective stop refuses motion.
    sim.set_faults(FaultSwitches {
        refuse_motion: true,
        ..FaultSwitches::default()
    });
    assert!(matches!(
        robot.move_joint(&[0.0; 6], 1.0, 1.0),
        Err(AuboError::Refused { code: -1, .. })
    ));
    robot.joint_positions().unwrap();
    sim.stop();
}

#[test]
fn late_replies_time_out_and_are_skipped_afterwards() {
    let (sim, _) = spawn(
        0.02,
        0.0,
        JointLimits::default(),
        FaultSwitches {
            reply_delay: Duration::from_millis(300),
            ..FaultSwitches::default()
        },
    );
    let timeout = Duration::from_millis(100);
    let mut robot = AuboClient::connect(sim.addr(), timeout).unwrap();
    let start = Instant::now();
    match robot.joint_positions() {
        Err(e @ AuboError::Timeout { .. }) => {
            assert!(e.to_string().contains("getJointPositions"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    let waited = start.elapsed();
    assert!(
        waited >= timeout && waited < Duration::from_millis(250),
        "{waited:?}"
    );
    sim.set_faults(FaultSwitches::default());
    thread::sleep(Duration::from_millis(350)); // the late reply arrives
    let q = robot
        .joint_positions()
        .expect("the late reply is skipped by id");
    assert_eq!(q, [0.0; 6]);
    sim.stop();
}

#[test]
fn dropped_connection_gives_disconnected() {
    let (sim, epoch) = spawn(
        0.02,
        0.0,
        JointLimits::default(),
        FaultSwitches {
            drop_connection_after: Some(3),
            ..FaultSwitches::default()
        },
    );
    let mut robot = AuboClient::connect(sim.addr(), TIMEOUT).unwrap();
    for _ in 0..3 {
        robot.joint_positions().unwrap();
    }
    match robot.joint_positions() {
        Err(e @ AuboError::Disconnected { .. }) => {
            assert!(e.to_string().contains("getJointPositions"), "{e}")
        }
        other => panic!("{other:?}"),
    }
    assert!(robot.joint_positions().is_err());

    // The poller reports the drop through its channel and stops.
    let poller = JointPoller::spawn(
        AuboClient::connect(sim.addr(), TIMEOUT).unwrap(),
        125.0,
        epoch,
    )
    .unwrap();
    let results: Vec<_> = poller.samples().iter().take(10).collect();
    assert_eq!(results.len(), 4);
    assert!(results[..3].iter().all(Result::is_ok));
    assert!(matches!(results[3], Err(AuboError::Disconnected { .. })));
    let (client, _) = poller.stop();
    assert!(client.is_none());
    sim.stop();
}

#[test]
fn polling_at_125_hz_for_2_s_yields_at_least_240_samples() {
    let (sim, epoch) = spawn(0.02, 1e-4, JointLimits::default(), FaultSwitches::default());
    let poller = JointPoller::spawn(
        AuboClient::connect(sim.addr(), TIMEOUT).unwrap(),
        125.0,
        epoch,
    )
    .unwrap();
    thread::sleep(Duration::from_secs(2));
    let (client, rx) = poller.stop();
    assert!(client.is_some());
    let samples: Vec<JointSample> = rx.try_iter().map(|s| s.unwrap()).collect();
    assert!(
        samples.len() >= 240 && samples.len() <= 260,
        "{} samples",
        samples.len()
    );
    let gaps: Vec<f64> = samples.windows(2).map(|w| w[1].t - w[0].t).collect();
    assert!(gaps.iter().all(|&g| g > 0.0));
    sim.stop();
}
