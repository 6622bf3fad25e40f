//! The acquisition core against the register-level simulated BNO055.
// Register literals are grouped by bit field (bandwidth_range).
#![allow(clippy::unusual_byte_groupings)]

mod support;

use embedded_hal::i2c::{ErrorKind, I2c, NoAcknowledgeSource};
use robimu_firmware::acquisition::{TX_QUEUE_LEN, TX_RESERVE};
use robimu_firmware::{Config, Error};
use robimu_protocol::{
    AccelBandwidth, AccelRange, CommandError, CommandKind, CommandResult, DeviceInfo,
    DeviceMessage, GyroBandwidth, GyroRange, HostMessage, ImuSample, Pong, SensorConfig,
    SensorTiming, Status,
};
use support::{encode_time, Rig};

const BOOT_US: u64 = 650_000 + 19_000; // soft reset + switch to AMG (datasheet tables 1-2, 3-6)

/// The messages of one kind, in order (`kind` picks them out).
fn pick<T>(messages: &[DeviceMessage], kind: impl Fn(&DeviceMessage) -> Option<T>) -> Vec<T> {
    messages.iter().filter_map(kind).collect()
}

fn infos(messages: &[DeviceMessage]) -> Vec<DeviceInfo> {
    pick(messages, |m| match m {
        DeviceMessage::Info(i) => Some(*i),
        _ => None,
    })
}

fn statuses(messages: &[DeviceMessage]) -> Vec<Status> {
    pick(messages, |m| match m {
        DeviceMessage::Status(s) => Some(*s),
        _ => None,
    })
}

fn results(messages: &[DeviceMessage]) -> Vec<CommandResult> {
    pick(messages, |m| match m {
        DeviceMessage::CommandResult(r) => Some(*r),
        _ => None,
    })
}

/// Sum of the gaps in `seq` (wrapping).
fn seq_gaps(samples: &[ImuSample]) -> u32 {
    samples
        .windows(2)
        .map(|w| w[1].seq.wrapping_sub(w[0].seq) - 1)
        .sum()
}

/// Each sample's reading was latched at its timestamp (the simulated source
/// encodes the latch time in the accelerometer counts).
fn assert_timestamps_match_readings(samples: &[ImuSample]) {
    for s in samples {
        assert_eq!(s.accel_raw, encode_time(s.t_us), "seq {}", s.seq);
        assert_eq!(s.gyro_raw, [-1, 2, -3]);
        assert_eq!(s.temp_raw, 21);
    }
}

fn rig_config() -> Config {
    Config::default()
}

/// A rig booted and streaming since `ts`, which is returned.
fn streaming_rig(config: Config) -> (Rig, u64) {
    let mut rig = Rig::new(config, 5_000, 0);
    rig.core.start().unwrap();
    rig.link.send(&HostMessage::Start);
    let ts = rig.time.now();
    rig.poll();
    assert!(rig.core.is_streaming());
    (rig, ts)
}

#[test]
fn boot_waits_for_a_booting_chip_and_announces_the_device() {
    let mut rig = Rig::new(rig_config(), 1_000, 40);
    rig.core.start().unwrap();
    // 40 refused attempts, 10 ms apart, then reset and configuration.
    assert_eq!(rig.time.now(), 1_000 + 40 * 10_000 + BOOT_US);
    let sim = rig.bus.borrow();
    assert_eq!(sim.failed_transaction_count(), 40);
    assert_eq!(sim.reset_count(), 1);
    drop(sim);

    rig.host.receive(&rig.link.take_sent());
    assert_eq!(rig.host.raw[0], 0x00, "a lone delimiter comes first");
    assert_eq!(rig.host.messages.len(), 1);
    let DeviceMessage::Info(info) = rig.host.messages[0] else {
        panic!("expected DeviceInfo, got {:?}", rig.host.messages[0]);
    };
    assert_eq!(
        info,
        DeviceInfo {
            firmware_version: [0, 1, 0],
            protocol_version: 3,
            chip_id: 0xA0,
            accel_id: 0xFB,
            mag_id: 0x32,
            gyro_id: 0x0F,
            sw_revision: 0x0311,
            bootloader_revision: 0x15,
            config: SensorConfig::default(),
            accel_scale_mps2_per_lsb: 0.01,
            gyro_scale_rads_per_lsb: 1.0 / 900.0,
            temp_scale_c_per_lsb: 1.0,
            // the defaults' 62.5 Hz and 116 Hz: ODR 125 Hz and 1000 Hz
            timing: SensorTiming {
                accel_bandwidth_hz: 62.5,
                accel_odr_hz: 125.0,
                gyro_bandwidth_hz: 116.0,
                gyro_odr_hz: 1000.0,
            },
            sensor: 0,
            sensors: 1,
        }
    );
    let status = rig.core.status();
    assert_eq!(status.frames_sent, 1, "the lone delimiter is not a frame");
    assert_eq!(
        status.i2c_errors, 0,
        "boot-time refusals are expected, not errors"
    );
    assert!(!status.streaming);
}

#[test]
fn configuration_registers_are_set_in_the_chip() {
    let sensor = SensorConfig {
        accel_range: AccelRange::G16,
        accel_bandwidth: AccelBandwidth::Hz250,
        gyro_range: GyroRange::Dps500,
        gyro_bandwidth: GyroBandwidth::Hz47,
        sample_rate_hz: 200,
    };
    let mut rig = Rig::new(
        Config {
            sensor,
            ..rig_config()
        },
        0,
        0,
    );
    rig.core.start().unwrap();
    let sim = rig.bus.borrow();
    // Datasheet section 4.3: ACC_Config = bw(4:2) | range(1:0): 250 Hz = 0b101, 16 g = 0b11.
    assert_eq!(sim.register(1, 0x08), 0b101_11);
    // GYR_Config_0 = bw(5:3) | range(2:0): 47 Hz = 0b011, 500 °/s = 0b010.
    assert_eq!(sim.register(1, 0x0A), 0b011_010);
    assert_eq!(sim.register(1, 0x0B), 0x00, "gyro normal power");
    assert_eq!(sim.register(0, 0x3B), 0b0000_0010, "m/s², rad/s, °C");
    assert_eq!(sim.register(0, 0x3E), 0x00, "normal power");
    assert_eq!(sim.operation_mode(), 0x07, "AMG");
    assert_eq!(sim.page(), 0, "page 0 left selected for burst reads");
    assert_eq!(sim.ignored_write_count(), 0, "no write outside CONFIG mode");
}

/// `DeviceInfo::timing` (the protocol's table) agrees with what the
/// simulated chip does with the registers the core wrote (the simulator's
/// own datasheet table), for every bandwidth setting.
#[test]
fn device_info_reports_the_chips_bandwidths_and_internal_rates() {
    use robimu_bno055_sim::Sensor;
    let accel = [
        AccelBandwidth::Hz7_81,
        AccelBandwidth::Hz15_63,
        AccelBandwidth::Hz31_25,
        AccelBandwidth::Hz62_5,
        AccelBandwidth::Hz125,
        AccelBandwidth::Hz250,
        AccelBandwidth::Hz500,
        AccelBandwidth::Hz1000,
    ];
    let gyro = [
        GyroBandwidth::Hz523,
        GyroBandwidth::Hz230,
        GyroBandwidth::Hz116,
        GyroBandwidth::Hz47,
        GyroBandwidth::Hz23,
        GyroBandwidth::Hz12,
        GyroBandwidth::Hz64,
        GyroBandwidth::Hz32,
    ];
    for (accel_bandwidth, gyro_bandwidth) in accel.into_iter().zip(gyro) {
        let sensor = SensorConfig {
            accel_bandwidth,
            gyro_bandwidth,
            ..SensorConfig::default()
        };
        let mut rig = Rig::new(
            Config {
                sensor,
                ..rig_config()
            },
            0,
            0,
        );
        rig.core.start().unwrap();
        let t = rig.core.device_info().timing;
        let sim = rig.bus.borrow();
        let (a, g) = (sim.timing(Sensor::Accel), sim.timing(Sensor::Gyro));
        assert_eq!(
            f64::from(t.accel_bandwidth_hz),
            a.bandwidth_hz,
            "{sensor:?}"
        );
        assert_eq!(f64::from(t.accel_odr_hz), a.odr_hz, "{sensor:?}");
        assert_eq!(f64::from(t.gyro_bandwidth_hz), g.bandwidth_hz, "{sensor:?}");
        assert_eq!(f64::from(t.gyro_odr_hz), g.odr_hz, "{sensor:?}");
    }
}

#[test]
fn samples_come_at_exactly_the_rate_without_drift_for_ten_minutes() {
    let rate = 333u64;
    let step = 211u64;
    let config = Config {
        sensor: SensorConfig {
            sample_rate_hz: rate as u16,
            ..SensorConfig::default()
        },
        ..rig_config()
    };
    // Start 3 s before the 32-bit µs clock wraps.
    let mut rig = Rig::new(config, (1 << 32) - 3_000_000 - BOOT_US, 0);
    rig.core.start().unwrap();
    rig.link.send(&HostMessage::Start);
    let ts = rig.time.now();
    let duration = 600_000_000u64;
    rig.run(duration, step);

    let samples = rig.host.samples();
    // Polls at ts + j·step for j·step < duration; deadlines at ts + floor(k·10⁶/rate).
    let last_poll = (duration - 1) / step * step;
    let expected = ((last_poll + 1) * rate).div_ceil(1_000_000);
    assert_eq!(samples.len() as u64, expected);
    let mut t = ts; // unwrapped device time
    for (k, s) in samples.iter().enumerate() {
        assert_eq!(s.seq, k as u32);
        if k > 0 {
            t += u64::from(s.t_us.wrapping_sub(samples[k - 1].t_us));
        } else {
            assert_eq!(s.t_us, ts as u32);
        }
        let deadline = ts + k as u64 * 1_000_000 / rate;
        assert!(
            t >= deadline && t < deadline + step,
            "sample {k} at {t}, deadline {deadline}"
        );
    }
    assert_timestamps_match_readings(&samples);
    let status = rig.core.status();
    assert_eq!(status.samples_sent as usize, samples.len());
    assert_eq!(status.samples_dropped, 0);
    assert_eq!(status.i2c_errors, 0);
    // One burst per sample, one temperature read per second (+ the health check).
    let transactions = u64::from(rig.bus.borrow().transaction_count());
    let seconds = duration / 1_000_000;
    assert!(
        transactions <= expected + 2 * seconds + 100,
        "{transactions} bus transactions"
    );
}

#[test]
fn commands_are_answered() {
    let mut rig = Rig::new(rig_config(), 0, 0);
    rig.core.start().unwrap();
    rig.host.receive(&rig.link.take_sent());
    rig.host.take();

    rig.link.send(&HostMessage::Ping { nonce: 0xDEAD_BEEF });
    rig.link.send(&HostMessage::GetInfo);
    rig.link.send(&HostMessage::GetStatus);
    rig.time.advance(123);
    let now = rig.time.now() as u32;
    rig.poll();
    let messages = rig.host.take();
    assert_eq!(messages.len(), 3);
    assert_eq!(
        messages[0],
        DeviceMessage::Pong(Pong {
            nonce: 0xDEAD_BEEF,
            t_us: now
        })
    );
    assert!(matches!(messages[1], DeviceMessage::Info(i) if i.chip_id == 0xA0));
    let DeviceMessage::Status(status) = messages[2] else {
        panic!("expected Status");
    };
    assert!(!status.streaming);
    assert_eq!(status.t_us, now);

    // Invalid rates.
    for rate in [0u16, 1001] {
        let bad = SensorConfig {
            sample_rate_hz: rate,
            ..SensorConfig::default()
        };
        rig.link.send(&HostMessage::Configure(bad));
        rig.poll();
        assert_eq!(
            rig.host.take(),
            [DeviceMessage::CommandResult(CommandResult {
                command: CommandKind::Configure,
                result: Err(CommandError::InvalidConfig)
            })]
        );
    }

    // A valid reconfiguration, applied to the chip from AMG mode.
    let new = SensorConfig {
        accel_range: AccelRange::G8,
        accel_bandwidth: AccelBandwidth::Hz125,
        gyro_range: GyroRange::Dps250,
        gyro_bandwidth: GyroBandwidth::Hz23,
        sample_rate_hz: 50,
    };
    rig.link.send(&HostMessage::Configure(new));
    rig.poll();
    let messages = rig.host.take();
    assert_eq!(
        messages[0],
        DeviceMessage::CommandResult(CommandResult {
            command: CommandKind::Configure,
            result: Ok(())
        })
    );
    assert!(matches!(messages[1], DeviceMessage::Info(i) if i.config == new));
    {
        let sim = rig.bus.borrow();
        assert_eq!(sim.register(1, 0x08), 0b100_10); // 125 Hz, ±8 g
        assert_eq!(sim.register(1, 0x0A), 0b100_011); // 23 Hz, ±250 °/s
        assert_eq!(sim.operation_mode(), 0x07);
        assert_eq!(sim.page(), 0);
        assert_eq!(sim.ignored_write_count(), 0);
        assert_eq!(
            sim.reset_count(),
            1,
            "reconfiguration does not reset the chip"
        );
    }

    // Start, then 1 s at 50 Hz.
    rig.link.send(&HostMessage::Start);
    rig.run(1_000_000, 100);
    let messages = rig.host.take();
    assert_eq!(
        messages[0],
        DeviceMessage::CommandResult(CommandResult {
            command: CommandKind::Start,
            result: Ok(())
        })
    );
    let samples: Vec<ImuSample> = support::Host {
        messages: messages.clone(),
        ..Default::default()
    }
    .samples();
    assert_eq!(samples.len(), 50);

    // While streaming: Configure is refused, Start is idempotent.
    rig.link
        .send(&HostMessage::Configure(SensorConfig::default()));
    rig.link.send(&HostMessage::Start);
    rig.poll();
    let messages = rig.host.take();
    assert_eq!(
        results(&messages),
        [
            CommandResult {
                command: CommandKind::Configure,
                result: Err(CommandError::Busy)
            },
            CommandResult {
                command: CommandKind::Start,
                result: Ok(())
            }
        ]
    );

    // Stop: no more samples, no status frames.
    rig.link.send(&HostMessage::Stop);
    rig.poll();
    assert_eq!(
        results(&rig.host.take()),
        [CommandResult {
            command: CommandKind::Stop,
            result: Ok(())
        }]
    );
    rig.run(3_000_000, 1_000);
    assert!(rig.host.take().is_empty());
    assert!(!rig.core.is_streaming());

    // Garbage is counted, and the next command still answered.
    rig.link.send_bytes(&[0x05, 0x11, 0x22, 0x33, 0x44, 0x00]);
    rig.link.send(&HostMessage::Ping { nonce: 1 });
    rig.poll();
    assert_eq!(rig.core.status().rx_errors, 1);
    assert!(matches!(
        rig.host.take()[..],
        [DeviceMessage::Pong(Pong { nonce: 1, .. })]
    ));
}

#[test]
fn status_is_sent_every_period_while_streaming() {
    let (mut rig, ts) = streaming_rig(rig_config());
    rig.run(5_500_000, 100);
    let messages = rig.host.take();
    let status = statuses(&messages);
    assert_eq!(status.len(), 5);
    for (n, s) in status.iter().enumerate() {
        assert_eq!(
            u64::from(s.t_us),
            (ts + (n as u64 + 1) * 1_000_000) % (1 << 32)
        );
        assert!(s.streaming);
        // Samples queued before the status frame, all delivered before it.
        let position = messages
            .iter()
            .position(|m| *m == DeviceMessage::Status(*s))
            .unwrap();
        let before = messages[..position]
            .iter()
            .filter(|m| matches!(m, DeviceMessage::Sample(_)))
            .count();
        assert_eq!(s.samples_sent as usize, before);
    }
    // After a poll has flushed everything, every decoded frame was counted
    // (boot Info, Start result, samples, status).
    assert_eq!(rig.core.status().frames_sent as usize, messages.len());
}

#[test]
fn injected_i2c_errors_are_retried_counted_and_survived() {
    let config = Config {
        sensor: SensorConfig {
            sample_rate_hz: 100,
            ..SensorConfig::default()
        },
        ..rig_config()
    };
    let (mut rig, _) = streaming_rig(config);
    rig.run(1_500_000, 100); // the next poll takes the slot at 1.5 s: a burst read
    rig.bus.borrow_mut().fail_next(2);
    rig.run(1_000_000, 100);
    let status = rig.core.status();
    assert_eq!(status.i2c_errors, 2);
    assert_eq!(status.samples_dropped, 0, "the third attempt succeeded");

    rig.bus.borrow_mut().fail_next(3); // all three attempts of the slot at 2.5 s
    rig.run(1_000_000, 100);
    let status = rig.core.status();
    assert_eq!(status.i2c_errors, 5);
    assert_eq!(status.samples_dropped, 1);
    assert_eq!(status.sensor_reinits, 0);

    let samples = rig.host.samples();
    assert_eq!(seq_gaps(&samples), 1);
    let missing = samples
        .windows(2)
        .find(|w| w[1].seq != w[0].seq + 1)
        .unwrap();
    assert_eq!(missing[0].seq, 249, "slot 250 (2.5 s) was lost");
    assert_eq!(samples.len(), 350 - 1);
    assert_timestamps_match_readings(&samples);
}

#[test]
fn repeated_failures_reinitialise_the_sensor_and_streaming_resumes() {
    let config = Config {
        sensor: SensorConfig {
            sample_rate_hz: 100,
            ..SensorConfig::default()
        },
        ..rig_config()
    };
    let (mut rig, ts) = streaming_rig(config);
    rig.run(1_500_000, 100);
    rig.bus.borrow_mut().fail_next(3 * 3); // three slots, three attempts each
    rig.run(3_000_000, 100);

    let status = rig.core.status();
    assert_eq!(status.i2c_errors, 9);
    assert_eq!(status.sensor_reinits, 1);
    assert_eq!(
        rig.bus.borrow().reset_count(),
        2,
        "boot and re-initialisation"
    );
    let samples = rig.host.samples();
    // Every slot is either delivered or counted as dropped.
    assert_eq!(seq_gaps(&samples), status.samples_dropped);
    let slots = samples.last().unwrap().seq + 1;
    assert_eq!(slots, status.samples_sent + status.samples_dropped);
    // Three failed slots (1.50, 1.51, 1.52 s); the re-initialisation in the
    // 1.52 s poll ends at 2.189 s, so slots 1.53 ..= 2.17 s are missed and
    // slot 2.18 s is read late, at 2.1891 s.
    assert_eq!(status.samples_dropped, 3 + 65);
    // A fresh DeviceInfo announced the re-initialised sensor.
    assert_eq!(infos(&rig.host.messages).len(), 2);
    // Streaming resumed on the original deadline grid with valid readings.
    let late = samples.iter().find(|s| s.seq == 218).unwrap();
    assert_eq!(u64::from(late.t_us.wrapping_sub(ts as u32)), 2_189_100);
    let after: Vec<_> = samples.iter().filter(|s| s.seq > 218).collect();
    assert_eq!(after.len(), 450 - 219);
    for s in &after {
        let offset = u64::from(s.t_us.wrapping_sub(ts as u32));
        assert_eq!(
            offset,
            u64::from(s.seq) * 10_000,
            "seq {} off the 10 ms grid",
            s.seq
        );
    }
    assert_timestamps_match_readings(&samples);
}

#[test]
fn a_chip_that_reset_itself_is_detected_and_reinitialised() {
    let config = Config {
        sensor: SensorConfig {
            sample_rate_hz: 100,
            ..SensorConfig::default()
        },
        ..rig_config()
    };
    let (mut rig, _) = streaming_rig(config);
    rig.run(1_500_000, 100);
    // A brown-out: the chip restarts in CONFIG mode with default registers.
    rig.bus.borrow_mut().write(0x28, &[0x3F, 0x20]).unwrap();
    rig.run(2_000_000, 100);

    let status = rig.core.status();
    assert_eq!(status.sensor_reinits, 1);
    assert_eq!(rig.bus.borrow().operation_mode(), 0x07);
    let samples = rig.host.samples();
    // In CONFIG mode the chip outputs zeros: slots 1.50 s ..= 2.00 s (the
    // check at 2 s runs after that slot's read).
    let zeros = samples.iter().filter(|s| s.accel_raw == [0; 3]).count();
    assert_eq!(zeros, 51);
    let last = samples.last().unwrap();
    assert_eq!(last.accel_raw, encode_time(last.t_us));
}

#[test]
fn a_backed_up_link_drops_samples_without_blocking() {
    let rate = u32::from(rig_config().sensor.sample_rate_hz);
    let (mut rig, _) = streaming_rig(rig_config());
    rig.run(1_000_000, 100);
    rig.link.set_writable(false); // the double panics on any write now
    rig.run(500_000, 100);
    rig.link.send(&HostMessage::Ping { nonce: 77 });
    rig.run(1_500_000, 100);
    let blocked = rig.core.status();
    assert!(rig.core.tx_queued() <= TX_QUEUE_LEN);
    // Two blocked seconds at the default rate; only a few frames fit the queue.
    let fitted = (TX_QUEUE_LEN - TX_RESERVE) / 30; // sample frames are 30..37 bytes
    assert!(blocked.samples_dropped >= 2 * rate - fitted as u32 - 2);
    assert_eq!(
        rig.core.control_frames_dropped(),
        0,
        "replies fit the reserve"
    );

    rig.link.set_writable(true);
    rig.run(1_000_000, 100);
    let status = rig.core.status();
    let samples = rig.host.samples();
    assert_eq!(seq_gaps(&samples), status.samples_dropped);
    assert_eq!(samples.len() as u32, status.samples_sent);
    assert_eq!(samples.last().unwrap().seq + 1, 4 * rate);
    assert!(rig
        .host
        .messages
        .iter()
        .any(|m| matches!(m, DeviceMessage::Pong(Pong { nonce: 77, .. }))));
    assert_timestamps_match_readings(&samples);
}

#[test]
fn a_chip_that_never_answers_times_out_and_is_retried_later() {
    let mut rig = Rig::new(rig_config(), 0, 1_000_000);
    let err = rig.core.start().unwrap_err();
    assert_eq!(
        err,
        Error::Bus(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address))
    );
    // Attempts every 10 ms until the 1000 ms timeout, including both ends.
    assert_eq!(rig.time.now(), 1_000_000);
    assert_eq!(rig.bus.borrow().transaction_count(), 101);
    rig.host.receive(&rig.link.take_sent());
    assert_eq!(infos(&rig.host.messages)[0].chip_id, 0, "identity unknown");

    // Start while the chip is down: one attempt, refused.
    rig.link.send(&HostMessage::Start);
    rig.poll();
    assert_eq!(
        results(&rig.host.take()),
        [CommandResult {
            command: CommandKind::Start,
            result: Err(CommandError::SensorFault)
        }]
    );
    assert_eq!(rig.core.status().i2c_errors, 1);

    // The chip comes up; the core retries after its back-off.
    rig.bus.borrow_mut().set_busy(0);
    rig.run(900_000, 1_000);
    assert!(!rig.core.sensor_ready());
    rig.run(200_000, 1_000);
    assert!(rig.core.sensor_ready());
    assert_eq!(rig.core.status().sensor_reinits, 1);
    assert_eq!(infos(&rig.host.messages)[0].chip_id, 0xA0);
}

#[test]
fn autostart_streams_without_a_command_and_bad_settings_are_refused() {
    let config = Config {
        autostart: true,
        ..rig_config()
    };
    let mut rig = Rig::new(config, 0, 0);
    rig.core.start().unwrap();
    rig.run(1_000_000, 100);
    assert_eq!(
        rig.host.samples().len(),
        usize::from(rig_config().sensor.sample_rate_hz)
    );

    let mut rig = Rig::new(
        Config {
            i2c_address: 0x30,
            ..config
        },
        0,
        0,
    );
    assert_eq!(rig.core.start(), Err(Error::InvalidAddress(0x30)));
    assert_eq!(rig.bus.borrow().transaction_count(), 0);

    let mut rig = Rig::new(
        Config {
            sensor: SensorConfig {
                sample_rate_hz: 0,
                ..SensorConfig::default()
            },
            ..config
        },
        0,
        0,
    );
    assert_eq!(rig.core.start(), Err(Error::InvalidSampleRate(0)));
    assert!(rig.core.sensor_ready());
    assert!(!rig.core.is_streaming());
}
