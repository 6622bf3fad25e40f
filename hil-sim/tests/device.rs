//! The simulated device seen from a host: open the pty path like a USB
//! serial port, command it, decode its frames.

use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use robimu_bno055_sim::SineSource;
use robimu_hil_sim::device::{SecondSensor, SimDevice, SimDeviceConfig};
use robimu_protocol::{
    encode_host, CommandKind, CommandResult, DeviceDecoder, DeviceMessage, HostMessage, ImuSample,
    Pong, MAX_FRAME_LEN,
};

struct Host {
    port: Box<dyn serialport::SerialPort>,
    decoder: DeviceDecoder,
    /// Messages that arrived after the one `wait_for` returned.
    pending: Vec<(Instant, DeviceMessage)>,
}

impl Host {
    fn open(path: &str) -> Self {
        let port = serialport::new(path, 921_600)
            .timeout(Duration::from_millis(5))
            .open()
            .unwrap();
        Self {
            port,
            decoder: DeviceDecoder::new(),
            pending: Vec::new(),
        }
    }

    fn send(&mut self, message: &HostMessage) {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = encode_host(message, &mut buf).unwrap();
        self.port.write_all(frame).unwrap();
    }

    /// Everything decoded within `duration`, with the host time of arrival.
    fn collect(&mut self, duration: Duration) -> Vec<(Instant, DeviceMessage)> {
        let end = Instant::now() + duration;
        let mut out = std::mem::take(&mut self.pending);
        let mut buf = [0u8; 4096];
        while Instant::now() < end {
            match self.port.read(&mut buf) {
                Ok(n) => {
                    let now = Instant::now();
                    for m in self.decoder.feed(&buf[..n]) {
                        out.push((now, m.unwrap()));
                    }
                }
                Err(e) if e.kind() == ErrorKind::TimedOut => {}
                Err(e) => panic!("serial read failed: {e}"),
            }
        }
        out
    }

    /// Waits up to `timeout` for the first message `pick` accepts.
    fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pick: impl FnMut(&DeviceMessage) -> Option<T>,
    ) -> Option<(Instant, T)> {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            let mut messages = self.collect(Duration::from_millis(10)).into_iter();
            while let Some((at, m)) = messages.next() {
                if let Some(t) = pick(&m) {
                    self.pending = messages.collect();
                    return Some((at, t));
                }
            }
        }
        None
    }
}

fn samples(messages: &[(Instant, DeviceMessage)]) -> Vec<ImuSample> {
    messages
        .iter()
        .filter_map(|(_, m)| match m {
            DeviceMessage::Sample(s) => Some(*s),
            _ => None,
        })
        .collect()
}

#[test]
fn a_host_streams_samples_at_the_configured_rate_over_the_pty() {
    let mut config = SimDeviceConfig {
        clock_offset_us: (1 << 32) - 1_500_000, // the device clock wraps during the test
        boot_busy_transactions: 20,
        ..SimDeviceConfig::new(Box::new(SineSource::new(120)))
    };
    config.config.sensor.sample_rate_hz = 120; // the paper's rig
    let device = SimDevice::spawn(config).unwrap();
    assert!(device.port_path().starts_with("/dev/"));
    let mut host = Host::open(device.port_path());

    host.send(&HostMessage::GetInfo);
    let (_, info) = host
        .wait_for(Duration::from_secs(5), |m| match m {
            DeviceMessage::Info(i) if i.chip_id == 0xA0 => Some(*i),
            _ => None,
        })
        .expect("DeviceInfo after boot");
    assert_eq!(info.config.sample_rate_hz, 120);

    host.send(&HostMessage::Start);
    let started = host.wait_for(Duration::from_secs(2), |m| match m {
        DeviceMessage::CommandResult(r) if r.command == CommandKind::Start => Some(*r),
        _ => None,
    });
    assert_eq!(
        started.map(|(_, r)| r),
        Some(CommandResult {
            command: CommandKind::Start,
            result: Ok(())
        })
    );
    let mut messages = host.collect(Duration::from_millis(2500));
    let streamed = samples(&messages).len();
    host.send(&HostMessage::Stop);
    // Keep what arrives until the Stop is answered: then nothing is in flight.
    let deadline = Instant::now() + Duration::from_secs(2);
    while Instant::now() < deadline
        && !messages.iter().any(
            |(_, m)| matches!(m, DeviceMessage::CommandResult(r) if r.command == CommandKind::Stop),
        )
    {
        messages.extend(host.collect(Duration::from_millis(10)));
    }
    let samples = samples(&messages);

    // Every gap in seq is a slot the device counted as dropped (on a loaded
    // machine a poll can come more than a period late); nothing is lost on
    // the link.
    let gaps: u32 = samples[0].seq
        + samples
            .windows(2)
            .map(|w| w[1].seq - w[0].seq - 1)
            .sum::<u32>();
    // Device-time rate: each reading taken at or after its deadline on the
    // fixed grid t0 + floor(k·10⁶/120), late by scheduling jitter only.
    let t0 = samples[0].t_us;
    let k0 = samples[0].seq;
    let mut late = Vec::new();
    let mut t = 0u64;
    for s in &samples {
        t += u64::from(s.t_us.wrapping_sub(t0)) - t; // unwrap relative to t0
        let k = u64::from(s.seq - k0);
        let deadline = k * 1_000_000 / 120;
        assert!(t + 20_000 >= deadline, "sample {k} early: {t} < {deadline}");
        late.push(t as i64 - deadline as i64);
    }
    late.sort_unstable();
    let median_late = late[late.len() / 2];
    assert!(median_late < 2_000, "median lateness {median_late} µs");
    // Host-time rate: about 120 per second over 2.5 s.
    assert!(
        (270..=330).contains(&streamed),
        "{streamed} samples in 2.5 s"
    );
    eprintln!(
        "{streamed} samples in 2.5 s, median lateness {median_late} µs, max {} µs, {gaps} missed",
        late[late.len() - 1]
    );

    let status = device.stop();
    assert_eq!(status.samples_dropped, gaps);
    assert!(gaps < 15, "{gaps} slots missed");
    assert_eq!(status.i2c_errors, 0);
    assert_eq!(status.samples_sent as usize, samples.len());
}

#[test]
fn the_device_clock_runs_with_the_configured_offset_and_drift() {
    let drift_ppm = 20_000.0; // 2 %: 20 ms per second, far above host jitter
    let device = SimDevice::spawn(SimDeviceConfig {
        clock_offset_us: 1_000_000_000,
        clock_drift_ppm: drift_ppm,
        ..SimDeviceConfig::default()
    })
    .unwrap();
    let mut host = Host::open(device.port_path());
    let ping = |host: &mut Host, nonce: u32| {
        let sent = Instant::now();
        host.send(&HostMessage::Ping { nonce });
        let (received, pong) = host
            .wait_for(Duration::from_secs(5), |m| match m {
                DeviceMessage::Pong(p) if p.nonce == nonce => Some(*p),
                _ => None,
            })
            .expect("pong");
        (sent, received, pong)
    };
    let (s1, r1, p1) = ping(&mut host, 1);
    std::thread::sleep(Duration::from_secs(2));
    let (s2, r2, p2) = ping(&mut host, 2);
    assert!(matches!(p1, Pong { nonce: 1, .. }));
    // The device clock started at the offset (boot takes under 2 s).
    assert!(p1.t_us >= 1_000_000_000 && p1.t_us < 1_000_000_000 + 5_000_000);
    // Device time elapsed / host time elapsed = 1 + drift, within the
    // round-trip uncertainty of the two pings.
    let device_us = f64::from(p2.t_us.wrapping_sub(p1.t_us));
    let host_min = (s2 - r1).as_secs_f64() * 1e6;
    let host_max = (r2 - s1).as_secs_f64() * 1e6;
    let factor = 1.0 + drift_ppm * 1e-6;
    assert!(
        device_us >= host_min * factor - 1_000.0 && device_us <= host_max * factor + 1_000.0,
        "device {device_us} µs for host {host_min}..{host_max} µs"
    );
    device.stop();
}

/// Two BNO055 on the board's one bus, each with its own source: both
/// announce themselves, and every tick streams one sample of each with the
/// same `seq`, sensor 1's readings from its own source.
#[test]
fn a_two_sensor_board_streams_both_sensors_over_the_pty() {
    let device = SimDevice::spawn(SimDeviceConfig {
        second: Some(SecondSensor {
            source: Box::new(SineSource::new(77)),
            chip_clock_error_ppm: 0.0,
        }),
        ..SimDeviceConfig::new(Box::new(SineSource::new(120)))
    })
    .unwrap();
    let mut host = Host::open(device.port_path());
    host.send(&HostMessage::GetInfo);
    let mut infos = Vec::new();
    let end = Instant::now() + Duration::from_secs(5);
    while infos.len() < 2 && Instant::now() < end {
        for (_, m) in host.collect(Duration::from_millis(20)) {
            if let DeviceMessage::Info(i) = m {
                infos.push(i);
            }
        }
    }
    assert!(infos.len() >= 2, "{infos:?}");
    assert_eq!((infos[0].sensor, infos[0].sensors), (0, 2));
    assert_eq!((infos[1].sensor, infos[1].sensors), (1, 2));
    host.send(&HostMessage::Start);
    let messages = host.collect(Duration::from_millis(1500));
    host.send(&HostMessage::Stop);
    let all = samples(&messages);
    for (k, period) in [(0u8, 120u32), (1, 77)] {
        let mine: Vec<_> = all.iter().filter(|s| s.sensor == k).collect();
        assert!(mine.len() > 150, "sensor {k}: {} samples", mine.len());
        let reference = SineSource::new(period);
        // each reading is one of its own source's (the temperature reads
        // in between latch none: the ideal chip latches per data burst)
        let mut n = 0u64;
        for s in &mine {
            let found = (n..n + 4)
                .find(|&m| {
                    let r = reference.reading(m);
                    r.accel == s.accel_raw && r.gyro == s.gyro_raw
                })
                .unwrap_or_else(|| panic!("sensor {k}: {s:?} is not from its source"));
            n = found + 1;
        }
    }
    let seqs = |k: u8| -> std::collections::BTreeSet<u32> {
        all.iter()
            .filter(|s| s.sensor == k)
            .map(|s| s.seq)
            .collect()
    };
    let (a, b) = (seqs(0), seqs(1));
    let common = a.intersection(&b).count();
    assert!(common + 2 >= a.len().max(b.len()), "ticks differ");
    device.stop();
}
