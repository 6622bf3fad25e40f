//! Recording pipeline throughput: 600 000 `ImuSample` frames (83 minutes at
//! 120 Hz) pushed through a pseudo-terminal as fast as it takes them (a
//! writer thread on the master side, the host opening the slave by path as
//! it opens /dev/ttyUSB0), then everything the host does with them in
//! `robimu record` — COBS/CRC decoding ([`LinkReader`]), device-clock
//! unwrapping, the clock fit from ping echoes (one every 12 samples, as at
//! 10 Hz), the session's CSV rows with a flush every 120 frames — and the
//! final re-mapping of every IMU time (`repair::remap_imu_times`).
//!
//! `cargo bench -p robimu --bench record`. Target: ≥ 1000 frames/s (the
//! board streams at most 1 kHz). Checks every frame reached imu.csv.

use std::io::Write;
use std::time::{Duration, Instant};

use robimu_protocol::{encode_device, DeviceMessage, ImuSample, MAX_FRAME_LEN};
use robimu_record::clock_fit::Echo;
use robimu_record::imu::ImuEvent;
use robimu_record::link::{DeviceClock, LinkReader};
use robimu_record::repair::remap_imu_times;
use robimu_record::SessionSink;
use robimu_session::SessionMeta;

const FRAMES: u32 = 600_000;

fn main() {
    let mut bytes = Vec::with_capacity(FRAMES as usize * 30);
    let mut buf = [0u8; MAX_FRAME_LEN];
    for seq in 0..FRAMES {
        let msg = DeviceMessage::Sample(ImuSample {
            sensor: 0,
            seq,
            t_us: 4_000_000_000u32.wrapping_add(seq.wrapping_mul(8_333)),
            accel_raw: [(seq % 2000) as i16, -((seq % 1500) as i16), 981],
            gyro_raw: [(seq % 700) as i16, 12, -((seq % 300) as i16)],
            temp_raw: 25,
        });
        let frame = encode_device(&msg, &mut buf).expect("frame fits");
        bytes.extend_from_slice(frame);
    }
    let dir = tempfile::tempdir().expect("temporary directory");
    let start = Instant::now();
    let mut sink =
        SessionSink::create(dir.path(), &SessionMeta::new("aubo_i5"), 6).expect("session created");
    let (mut master, slave) = serialport::TTYPort::pair().expect("pseudo-terminal pair");
    let path = serialport::SerialPort::name(&slave).expect("slave path");
    drop(slave);
    let port = serialport::new(&path, 921_600)
        .timeout(Duration::from_millis(500))
        .open()
        .expect("open the slave");
    let total_bytes = bytes.len();
    let writer = std::thread::spawn(move || {
        serialport::SerialPort::set_timeout(&mut master, Duration::from_secs(5)).expect("timeout");
        for chunk in bytes.chunks(4096) {
            master.write_all(chunk).expect("pty write");
        }
        master.flush().expect("pty flush");
        // Keep the master open until the reader is done.
        master
    });
    let mut reader: LinkReader<_> = LinkReader::new(port);
    let mut clock = DeviceClock::new();
    let mut count = 0u32;
    while count < FRAMES {
        let msg = match reader.next_message() {
            Ok(Some(msg)) => msg,
            Ok(None) => continue,
            Err(robimu_record::link::LinkError::Read(e))
                if e.kind() == std::io::ErrorKind::TimedOut =>
            {
                continue
            }
            Err(e) => panic!("pty read: {e}"),
        };
        let Some(t_us) = clock.observe(&msg) else {
            continue;
        };
        let DeviceMessage::Sample(s) = msg else {
            continue;
        };
        let device = t_us as f64 * 1e-6;
        if count % 12 == 0 {
            // The echo a 10 Hz ping would give: host clock = device − 4000 s.
            let host = device - 4000.0;
            sink.handle(ImuEvent::Echo {
                segment: 0,
                echo: Echo {
                    host_send: host - 1e-4,
                    host_recv: host + 1e-4,
                    device,
                },
            })
            .expect("echo");
        }
        let z = [
            f64::from(s.accel_raw[0]) * 0.01,
            f64::from(s.accel_raw[1]) * 0.01,
            f64::from(s.accel_raw[2]) * 0.01,
            f64::from(s.gyro_raw[0]) / 900.0,
            f64::from(s.gyro_raw[1]) / 900.0,
            f64::from(s.gyro_raw[2]) / 900.0,
        ];
        sink.handle(ImuEvent::Sample {
            sensor: 0,
            segment: 0,
            device,
            seq: s.seq,
            z,
            temp: f64::from(s.temp_raw),
        })
        .expect("sample");
        count += 1;
        if count % 120 == 0 {
            sink.flush().expect("flush");
        }
    }
    drop(writer.join().expect("writer"));
    let written = sink.progress.imu_samples;
    let stats = *reader.stats();
    assert_eq!(stats.bytes_received as usize, total_bytes);
    assert_eq!(stats.errors(), 0);
    let path = sink.finish().expect("finish");
    let streaming = start.elapsed().as_secs_f64();
    remap_imu_times(&path).expect("remap");
    let total = start.elapsed().as_secs_f64();
    assert_eq!(count, FRAMES);
    assert_eq!(written, u64::from(FRAMES));
    let rows = std::fs::read_to_string(path.join("imu.csv"))
        .expect("imu.csv")
        .lines()
        .count();
    assert_eq!(rows, FRAMES as usize + 1);
    println!(
        "recording pipeline through a pty: {FRAMES} frames ({total_bytes} bytes) in {total:.2} s ({:.0} frames/s; streaming part {:.0} frames/s, final re-mapping {:.2} s)",
        f64::from(FRAMES) / total,
        f64::from(FRAMES) / streaming,
        total - streaming
    );
}
