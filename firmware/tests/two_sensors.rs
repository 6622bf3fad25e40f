//! Two BNO055 on one bus (0x28, 0x29): both sampled on the same tick,
//! each with its own frames, counters and re-initialisation (protocol 3).

mod support;

use robimu_firmware::Config;
use robimu_protocol::{
    CommandError, CommandKind, DeviceInfo, DeviceMessage, HostMessage, ImuSample, SensorConfig,
    Status,
};
use support::{encode_time, TwoRig};

fn infos(messages: &[DeviceMessage]) -> Vec<DeviceInfo> {
    messages
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::Info(i) => Some(*i),
            _ => None,
        })
        .collect()
}

fn statuses(messages: &[DeviceMessage]) -> Vec<Status> {
    messages
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::Status(s) => Some(*s),
            _ => None,
        })
        .collect()
}

fn of_sensor(samples: &[ImuSample], k: u8) -> Vec<ImuSample> {
    samples.iter().filter(|s| s.sensor == k).copied().collect()
}

fn seq_gaps(samples: &[ImuSample]) -> u32 {
    samples
        .windows(2)
        .map(|w| w[1].seq.wrapping_sub(w[0].seq) - 1)
        .sum()
}

fn config_100hz() -> Config {
    Config {
        sensor: SensorConfig {
            sample_rate_hz: 100,
            ..SensorConfig::default()
        },
        ..Config::default()
    }
}

fn streaming(config: Config) -> TwoRig {
    let mut rig = TwoRig::two(config, 5_000);
    rig.core.start().unwrap();
    rig.link.send(&HostMessage::Start);
    rig.run(100, 100);
    assert!(rig.core.is_streaming());
    rig
}

/// Boot announces both sensors; every tick reads sensor 0 then sensor 1,
/// with one `seq`, each stamped just before its own burst (the simulated
/// source encodes the latch time in the counts); one `Status` per sensor
/// per period.
#[test]
fn both_sensors_are_read_on_every_tick_and_announced_and_reported_apart() {
    let mut rig = streaming(config_100hz());
    rig.run(10_000_000, 100);
    let messages = &rig.host.messages;
    let info = infos(messages);
    assert_eq!(info.len(), 2);
    assert_eq!((info[0].sensor, info[0].sensors), (0, 2));
    assert_eq!((info[1].sensor, info[1].sensors), (1, 2));
    assert_eq!(info[1].chip_id, 0xA0);

    let samples = rig.host.samples();
    let (s0, s1) = (of_sensor(&samples, 0), of_sensor(&samples, 1));
    assert_eq!(s0.len() + s1.len(), samples.len(), "only sensors 0 and 1");
    assert!(s0.len() >= 999, "{} samples in 10 s at 100 Hz", s0.len());
    assert_eq!(s0.len(), s1.len());
    for (a, b) in s0.iter().zip(&s1) {
        assert_eq!(a.seq, b.seq, "same tick");
        assert_eq!(a.accel_raw, encode_time(a.t_us));
        assert_eq!(b.accel_raw, encode_time(b.t_us));
        let lag = b.t_us.wrapping_sub(a.t_us);
        assert!(lag < 1_000, "sensor 1 read {lag} µs after sensor 0");
    }
    assert_eq!(seq_gaps(&s0), 0);
    assert_eq!(seq_gaps(&s1), 0);

    let st = statuses(messages);
    assert!(st.len() >= 18, "{} statuses", st.len());
    for pair in st.chunks(2) {
        assert_eq!(pair[0].sensor, 0);
        assert_eq!(pair[1].sensor, 1);
        assert_eq!(
            pair[0].frames_sent, pair[1].frames_sent,
            "the board's count"
        );
    }
    for k in 0..2 {
        let s = rig.core.status_of(k);
        assert_eq!(s.sensor as usize, k);
        assert_eq!(s.samples_dropped, 0);
        assert_eq!(s.i2c_errors, 0);
    }
}

/// Failures of sensor 1 alone are retried, counted and re-initialised on
/// sensor 1's counters; sensor 0 keeps streaming and loses only the slots
/// the blocking re-initialisation (650 ms reset) takes. On each sensor the
/// `seq` gaps add up to its own `samples_dropped`.
#[test]
fn one_sensor_failing_is_reinitialised_alone_and_the_other_keeps_streaming() {
    let mut rig = streaming(config_100hz());
    rig.run(1_500_000, 100);
    rig.bus.borrow_mut().chip_mut(1).unwrap().fail_next(3 * 3);
    rig.run(3_000_000, 100);

    let (st0, st1) = (rig.core.status_of(0), rig.core.status_of(1));
    assert_eq!(st1.i2c_errors, 9);
    assert_eq!(st1.sensor_reinits, 1);
    assert_eq!((st0.i2c_errors, st0.sensor_reinits), (0, 0));
    let bus = rig.bus.borrow();
    assert_eq!(bus.chip(0).unwrap().reset_count(), 1, "boot only");
    assert_eq!(bus.chip(1).unwrap().reset_count(), 2, "boot and re-init");
    drop(bus);

    let samples = rig.host.samples();
    let (s0, s1) = (of_sensor(&samples, 0), of_sensor(&samples, 1));
    assert_eq!(seq_gaps(&s0), st0.samples_dropped);
    assert_eq!(seq_gaps(&s1), st1.samples_dropped);
    // the three failed slots are sensor 1's alone
    assert_eq!(st1.samples_dropped, st0.samples_dropped + 3);
    assert!(st0.samples_dropped > 60, "the re-init blocks the loop");
    // a fresh DeviceInfo for sensor 1 only
    let info = infos(&rig.host.messages);
    assert_eq!(info.iter().map(|i| i.sensor).collect::<Vec<_>>(), [0, 1, 1]);
    // both stream again, on the same ticks
    let last0: Vec<_> = s0.iter().rev().take(100).map(|s| s.seq).collect();
    let last1: Vec<_> = s1.iter().rev().take(100).map(|s| s.seq).collect();
    assert_eq!(last0, last1);
}

/// A board set for two sensors whose second chip does not answer: boot
/// reports it, the first is up, and `Start` is refused as a sensor fault.
#[test]
fn a_missing_second_sensor_is_reported_and_start_refused() {
    let mut rig = TwoRig::two(config_100hz(), 5_000);
    *rig.bus.borrow_mut() = robimu_bno055_sim::Bno055Bus::one(robimu_bno055_sim::Bno055Sim::new(
        0x28,
        support::TimeSource(rig.time.clone()),
    ));
    assert!(rig.core.start().is_err());
    assert!(rig.core.sensor_ready_of(0));
    assert!(!rig.core.sensor_ready_of(1));
    rig.link.send(&HostMessage::Start);
    rig.run(100, 100);
    let results: Vec<_> = rig
        .host
        .messages
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::CommandResult(r) => Some(*r),
            _ => None,
        })
        .collect();
    assert_eq!(results.len(), 1);
    assert_eq!(results[0].command, CommandKind::Start);
    assert_eq!(results[0].result, Err(CommandError::SensorFault));
    assert!(!rig.core.is_streaming());
}
