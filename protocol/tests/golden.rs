//! Golden byte vectors: the exact frames of protocol version 3, checked in
//! at `tests/golden/frames.txt` (version 2's, kept to test the refusal, in
//! `tests/golden/frames_v2.txt`), and pinned against independent references
//! (bitwise CRC-32C, textbook COBS, hand-built postcard payloads).
//!
//! Regenerate the file ONLY for a deliberate wire change (which also bumps
//! `PROTOCOL_VERSION`): `ROBIMU_BLESS=1 cargo test -p robimu-protocol --test golden`.

mod common;

use std::collections::BTreeSet;
use std::path::PathBuf;

use common::*;
use robimu_protocol::*;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Golden {
    Device(DeviceMessage),
    Host(HostMessage),
}

fn realistic_info() -> DeviceInfo {
    DeviceInfo {
        firmware_version: [0, 1, 0],
        protocol_version: PROTOCOL_VERSION,
        chip_id: 0xA0,
        accel_id: 0xFB,
        mag_id: 0x32,
        gyro_id: 0x0F,
        sw_revision: 0x0311,
        bootloader_revision: 0x15,
        // the paper's rig's 120 Hz (the golden frames were recorded with
        // it; the default rate is a setting, not part of the wire format)
        config: SensorConfig {
            sample_rate_hz: 120,
            ..SensorConfig::default()
        },
        accel_scale_mps2_per_lsb: 0.01,
        gyro_scale_rads_per_lsb: 1.0 / 900.0,
        temp_scale_c_per_lsb: 1.0,
        timing: SensorTiming::of(&SensorConfig::default()),
        sensor: 0,
        sensors: 1,
    }
}

/// The second BNO055 (0x29) of a two-sensor board.
fn second_sensor_info() -> DeviceInfo {
    DeviceInfo {
        sensor: 1,
        sensors: 2,
        sw_revision: 0x0308,
        ..realistic_info()
    }
}

fn realistic_sample() -> ImuSample {
    // About 50 minutes after boot, lying flat: gravity on z (9.81 m/s²).
    ImuSample {
        sensor: 0,
        seq: 360_123,
        t_us: 3_001_025_000,
        accel_raw: [12, -35, 981],
        gyro_raw: [3, -2, 1],
        temp_raw: 27,
    }
}

fn realistic_status() -> Status {
    Status {
        t_us: 3_001_030_000,
        streaming: true,
        samples_sent: 360_124,
        samples_dropped: 2,
        i2c_errors: 1,
        sensor_reinits: 0,
        frames_sent: 363_130,
        rx_errors: 0,
        sensor: 0,
    }
}

fn max_config() -> SensorConfig {
    SensorConfig {
        sample_rate_hz: u16::MAX,
        ..SensorConfig::default()
    }
}

/// Every variant with realistic values, then the worst case of each.
fn golden_messages() -> Vec<(&'static str, Golden)> {
    use DeviceMessage as D;
    use Golden::{Device, Host};
    use HostMessage as H;
    vec![
        ("device/info", Device(D::Info(realistic_info()))),
        ("device/sample", Device(D::Sample(realistic_sample()))),
        ("device/status", Device(D::Status(realistic_status()))),
        // protocol 3: the second sensor of a two-BNO055 board, read on
        // the same tick (same seq, 1.2 ms later) and upside down
        ("device/info_sensor1", Device(D::Info(second_sensor_info()))),
        (
            "device/sample_sensor1",
            Device(D::Sample(ImuSample {
                sensor: 1,
                t_us: 3_001_026_200,
                accel_raw: [-20, 41, -979],
                gyro_raw: [-1, 4, 0],
                temp_raw: 29,
                ..realistic_sample()
            })),
        ),
        (
            "device/status_sensor1",
            Device(D::Status(Status {
                sensor: 1,
                samples_sent: 360_120,
                samples_dropped: 5,
                i2c_errors: 7,
                sensor_reinits: 1,
                ..realistic_status()
            })),
        ),
        (
            "device/pong",
            Device(D::Pong(Pong {
                nonce: 0xDEAD_BEEF,
                t_us: 1_234_567,
            })),
        ),
        (
            "device/command_result_ok",
            Device(D::CommandResult(CommandResult {
                command: CommandKind::Start,
                result: Ok(()),
            })),
        ),
        (
            "device/command_result_err",
            Device(D::CommandResult(CommandResult {
                command: CommandKind::Configure,
                result: Err(CommandError::InvalidConfig),
            })),
        ),
        (
            "host/configure",
            Host(H::Configure(SensorConfig {
                accel_range: AccelRange::G8,
                accel_bandwidth: AccelBandwidth::Hz125,
                gyro_range: GyroRange::Dps500,
                gyro_bandwidth: GyroBandwidth::Hz230,
                sample_rate_hz: 200,
            })),
        ),
        ("host/start", Host(H::Start)),
        ("host/stop", Host(H::Stop)),
        ("host/ping", Host(H::Ping { nonce: 0xDEAD_BEEF })),
        ("host/get_info", Host(H::GetInfo)),
        ("host/get_status", Host(H::GetStatus)),
        (
            "device/info_max",
            Device(D::Info(DeviceInfo {
                sw_revision: u16::MAX,
                config: max_config(),
                sensor: u8::MAX,
                sensors: u8::MAX,
                ..realistic_info()
            })),
        ),
        (
            "device/sample_max",
            Device(D::Sample(ImuSample {
                sensor: u8::MAX,
                seq: u32::MAX,
                t_us: u32::MAX,
                accel_raw: [i16::MIN; 3],
                gyro_raw: [i16::MIN; 3],
                temp_raw: i8::MIN,
            })),
        ),
        (
            "device/status_max",
            Device(D::Status(Status {
                t_us: u32::MAX,
                streaming: true,
                samples_sent: u32::MAX,
                samples_dropped: u32::MAX,
                i2c_errors: u32::MAX,
                sensor_reinits: u32::MAX,
                frames_sent: u32::MAX,
                rx_errors: u32::MAX,
                sensor: u8::MAX,
            })),
        ),
        (
            "device/pong_max",
            Device(D::Pong(Pong {
                nonce: u32::MAX,
                t_us: u32::MAX,
            })),
        ),
        (
            "device/command_result_max",
            Device(D::CommandResult(CommandResult {
                command: CommandKind::Stop,
                result: Err(CommandError::Busy),
            })),
        ),
        ("host/configure_max", Host(H::Configure(max_config()))),
        ("host/ping_max", Host(H::Ping { nonce: u32::MAX })),
    ]
}

fn encode_golden(g: &Golden) -> Vec<u8> {
    match g {
        Golden::Device(m) => frame_of(m),
        Golden::Host(m) => frame_of(m),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    assert!(s.len() % 2 == 0, "odd hex length: {s}");
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex digit"))
        .collect()
}

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/frames.txt")
}

fn golden_v2_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/frames_v2.txt")
}

const HEADER: &str = "\
# robimu wire protocol v3: golden frames, `<name> <hex of the whole frame, 0x00 delimiter included>`.
# frame = COBS(version ++ postcard(message) ++ crc32c_le(version ++ payload)) ++ 00
# Checked by protocol/tests/golden.rs. Regenerate ONLY for a deliberate wire change (and bump
# PROTOCOL_VERSION): ROBIMU_BLESS=1 cargo test -p robimu-protocol --test golden
";

fn read_golden_file() -> Vec<(String, Vec<u8>)> {
    read_golden(&golden_path())
}

fn read_golden(path: &std::path::Path) -> Vec<(String, Vec<u8>)> {
    let text = std::fs::read_to_string(path).expect("golden file present");
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            let (name, hex) = l.split_once(' ').expect("`name hex` line");
            (name.to_string(), unhex(hex.trim()))
        })
        .collect()
}

#[test]
fn frames_match_the_golden_file() {
    let messages = golden_messages();
    if std::env::var_os("ROBIMU_BLESS").is_some() {
        let mut text = HEADER.to_string();
        for (name, g) in &messages {
            text += &format!("{name} {}\n", hex(&encode_golden(g)));
        }
        std::fs::write(golden_path(), text).expect("write golden file");
    }
    let file = read_golden_file();
    let names: Vec<_> = messages.iter().map(|(n, _)| n.to_string()).collect();
    let file_names: Vec<_> = file.iter().map(|(n, _)| n.clone()).collect();
    assert_eq!(file_names, names, "golden file lists other messages");
    for ((name, g), (_, expected)) in messages.iter().zip(&file) {
        assert_eq!(
            hex(&encode_golden(g)),
            hex(expected),
            "{name}: encoding differs from the golden frame"
        );
    }
}

#[test]
fn golden_file_bytes_decode_back() {
    let messages = golden_messages();
    let file = read_golden_file();
    // One stream with all frames, fed byte by byte to both decoders.
    let mut device = DeviceDecoder::new();
    let mut host = HostDecoder::new();
    for ((name, g), (_, bytes)) in messages.iter().zip(&file) {
        let decoded = match g {
            Golden::Device(_) => {
                let out: Vec<_> = bytes
                    .iter()
                    .flat_map(|b| device.feed(&[*b]).collect::<Vec<_>>())
                    .collect();
                out.into_iter()
                    .map(|r| r.map(Golden::Device))
                    .collect::<Vec<_>>()
            }
            Golden::Host(_) => {
                let out: Vec<_> = bytes
                    .iter()
                    .flat_map(|b| host.feed(&[*b]).collect::<Vec<_>>())
                    .collect();
                out.into_iter()
                    .map(|r| r.map(Golden::Host))
                    .collect::<Vec<_>>()
            }
        };
        assert_eq!(decoded, vec![Ok(*g)], "{name}");
    }
    assert_eq!(device.stats().errors() + host.stats().errors(), 0);
}

#[test]
fn golden_messages_cover_every_variant() {
    let mut device = BTreeSet::new();
    let mut host = BTreeSet::new();
    for (_, g) in golden_messages() {
        match g {
            Golden::Device(m) => device.insert(device_variant(&m)),
            Golden::Host(m) => host.insert(host_variant(&m)),
        };
    }
    assert_eq!(
        device,
        BTreeSet::from(["Info", "Sample", "Status", "Pong", "CommandResult"])
    );
    assert_eq!(
        host,
        BTreeSet::from(["Configure", "Start", "Stop", "Ping", "GetInfo", "GetStatus"])
    );
}

#[test]
fn crc_is_crc32c_castagnoli() {
    // The standard CRC-32C check value (RFC 3720 / iSCSI; "check" in the
    // Williams catalogue), and the bitwise reference agrees.
    assert_eq!(crc32c(b"123456789"), 0xE306_9283);
    assert_eq!(ref_crc32c(b"123456789"), 0xE306_9283);
    // RFC 3720 B.4 test vector: 32 bytes of zeros.
    assert_eq!(crc32c(&[0u8; 32]), 0x8A91_36AA);
    assert_eq!(crc32c(b""), 0);
}

#[test]
fn every_golden_frame_equals_the_reference_encoder() {
    for (name, g) in golden_messages() {
        let mut buf = [0u8; 64];
        let payload = match &g {
            Golden::Device(m) => postcard::to_slice(m, &mut buf),
            Golden::Host(m) => postcard::to_slice(m, &mut buf),
        }
        .expect("postcard");
        assert_eq!(
            encode_golden(&g),
            ref_frame(PROTOCOL_VERSION, payload),
            "{name}"
        );
    }
}

/// Postcard payloads written out by hand from the wire rules (variant index,
/// LEB128 varints, zigzag for signed, raw bytes for u8/i8/bool, LE f32).
#[test]
fn payloads_match_hand_built_wire_format() {
    let s = realistic_sample();
    let mut sample = vec![1u8, s.sensor]; // DeviceMessage::Sample, sensor (protocol 3)
    sample.extend(leb(s.seq.into()));
    sample.extend(leb(s.t_us.into()));
    for v in s.accel_raw.iter().chain(&s.gyro_raw) {
        sample.extend(zz((*v).into()));
    }
    sample.push(s.temp_raw as u8);
    // 360123 = 0x57EBB: 3 bytes; 3001025000 needs 5; accel 24/69/1962: 1+2+2.
    assert_eq!(sample.len(), 1 + 1 + 3 + 5 + (1 + 1 + 2) + 3 + 1);
    assert_eq!(
        frame_of(&DeviceMessage::Sample(s)),
        ref_frame(PROTOCOL_VERSION, &sample)
    );

    let st = realistic_status();
    let mut status = vec![2u8]; // DeviceMessage::Status
    status.extend(leb(st.t_us.into()));
    status.push(1); // streaming
    for c in [
        st.samples_sent,
        st.samples_dropped,
        st.i2c_errors,
        st.sensor_reinits,
        st.frames_sent,
        st.rx_errors,
    ] {
        status.extend(leb(c.into()));
    }
    status.push(st.sensor); // protocol 3
    assert_eq!(
        frame_of(&DeviceMessage::Status(st)),
        ref_frame(PROTOCOL_VERSION, &status)
    );

    let info = realistic_info();
    let mut inf = vec![0u8, 0, 1, 0, PROTOCOL_VERSION, 0xA0, 0xFB, 0x32, 0x0F];
    inf.extend(leb(0x0311));
    inf.push(0x15);
    inf.extend([1, 3, 0, 2]); // G4, Hz62_5, Dps2000, Hz116 (variant indices)
    inf.extend(leb(120));
    // scales, then (protocol 2) accel bandwidth and ODR, gyro bandwidth and
    // ODR of the defaults: 62.5 Hz → 125 Hz, 116 Hz → 1000 Hz (datasheet
    // tables 3-8, 3-9)
    for f in [0.01f32, 1.0 / 900.0, 1.0, 62.5, 125.0, 116.0, 1000.0] {
        inf.extend(f.to_le_bytes());
    }
    inf.extend([0, 1]); // protocol 3: sensor 0 of 1
    assert_eq!(
        frame_of(&DeviceMessage::Info(info)),
        ref_frame(PROTOCOL_VERSION, &inf)
    );
    // the second sensor of two: software revision 0x0308, sensor 1 of 2
    let mut inf1 = inf.clone();
    let n = inf1.len();
    inf1[n - 2..].copy_from_slice(&[1, 2]);
    assert_eq!(leb(0x0311), [0x91, 0x06]);
    assert_eq!(&inf1[9..11], &[0x91, 0x06]);
    inf1[9..11].copy_from_slice(&leb(0x0308));
    assert_eq!(
        frame_of(&DeviceMessage::Info(second_sensor_info())),
        ref_frame(PROTOCOL_VERSION, &inf1)
    );

    // Ping 0xDEADBEEF: [3] ++ LEB128 = ef fd b6 f5 0d.
    assert_eq!(leb(0xDEAD_BEEF), [0xEF, 0xFD, 0xB6, 0xF5, 0x0D]);
    let ping = frame_of(&HostMessage::Ping { nonce: 0xDEAD_BEEF });
    assert_eq!(
        ping,
        ref_frame(PROTOCOL_VERSION, &[3, 0xEF, 0xFD, 0xB6, 0xF5, 0x0D])
    );

    // Start: the smallest frame, version 03, variant 01, CRC; no zero byte
    // anywhere, so COBS is a single block: header 07, the 6 bytes, delimiter.
    let crc = ref_crc32c(&[3, 1]).to_le_bytes();
    assert!(!crc.contains(&0));
    let mut start = vec![7, 3, 1];
    start.extend(crc);
    start.push(0);
    assert_eq!(frame_of(&HostMessage::Start), start);
}

#[test]
fn worst_case_sizes_match_the_documented_table() {
    let len = |name: &str| {
        let (_, g) = golden_messages()
            .into_iter()
            .find(|(n, _)| *n == name)
            .expect("named golden message");
        encode_golden(&g).len()
    };
    assert_eq!(len("device/info_max"), 57);
    assert_eq!(len("device/sample_max"), 38);
    assert_eq!(len("device/status_max"), 45);
    assert_eq!(len("device/pong_max"), 18);
    assert_eq!(len("device/command_result_max"), 11);
    assert_eq!(len("host/configure_max"), 15);
    assert_eq!(len("host/ping_max"), 13);
    assert_eq!(len("host/start"), 8);
    assert_eq!(DEVICE_MAX_FRAME_LEN, len("device/info_max"));
    assert_eq!(HOST_MAX_FRAME_LEN, len("host/configure_max"));
    assert_eq!(MAX_FRAME_LEN, 57);
    assert_eq!(max_frame_len(DEVICE_MAX_PAYLOAD_LEN), DEVICE_MAX_FRAME_LEN);
    // The sample at rest quoted in the docs.
    assert_eq!(len("device/sample"), 25);
}

#[cfg(feature = "use-std")]
#[test]
fn encode_to_vec_matches_the_golden_frames() {
    for (name, g) in golden_messages() {
        let v = match &g {
            Golden::Device(m) => encode_to_vec(m),
            Golden::Host(m) => encode_to_vec(m),
        }
        .expect("encodes");
        assert_eq!(v, encode_golden(&g), "{name}");
    }
}

/// The `DeviceInfo` frame of protocol version 1 (as checked in before the
/// step to version 2): a version-2 receiver refuses it by its version and
/// keeps the version it found, so a host can name the mismatch.
#[test]
fn a_version_1_frame_is_refused_by_its_version() {
    let v1_info = unhex("02010102010b01a0fb320f91061501030b02780ad7233cb4a2913a0107803f758cae2200");
    let mut device = DeviceDecoder::new();
    let out: Vec<_> = device.feed(&v1_info).collect();
    assert_eq!(out, vec![Err(WireError::WrongVersion { found: 1 })]);
    assert_eq!(device.stats().version_errors, 1);
    assert_eq!(device.stats().foreign_version, Some(1));
    // the same message re-framed as version 1 by the reference encoder is
    // those very bytes: only the version byte (and CRC) tell them apart
    let mut buf = [0u8; 64];
    let mut v1 = realistic_info();
    v1.protocol_version = 1;
    let payload = postcard::to_slice(&DeviceMessage::Info(v1), &mut buf).unwrap();
    // a v1 payload is the v3 one without the 16 bytes of `timing` and
    // (protocol 3) the 2 of `sensor`, `sensors`
    let v1_payload = &payload[..payload.len() - 18];
    assert_eq!(ref_frame(1, v1_payload), v1_info);
}

/// The version-2 payload of a version-3 message: the protocol-3 fields
/// taken out (a sample's `sensor`, right after the variant tag; a status's
/// `sensor` and an info's `sensor`, `sensors`, at the end); every other
/// message is unchanged.
fn v2_payload(g: &Golden) -> Vec<u8> {
    let mut buf = [0u8; 64];
    let mut p = match g {
        Golden::Device(m) => postcard::to_slice(m, &mut buf),
        Golden::Host(m) => postcard::to_slice(m, &mut buf),
    }
    .expect("postcard")
    .to_vec();
    match g {
        Golden::Device(DeviceMessage::Sample(_)) => {
            p.remove(1);
        }
        Golden::Device(DeviceMessage::Status(_)) => {
            p.pop();
        }
        Golden::Device(DeviceMessage::Info(_)) => {
            p.truncate(p.len() - 2);
            p[4] = 2; // the protocol_version field
        }
        _ => {}
    }
    p
}

/// Mixed versions: the golden frames of protocol 2 (checked in before the
/// step to 3) are refused by this decoder by their version byte, which it
/// keeps, so the host names the mismatch (robimu-record's
/// `ClientError::ProtocolVersion`); and they are exactly the version-3
/// messages without the protocol-3 fields, framed as version 2, which pins
/// what the step changed. (The other direction, a version-2 host meeting a
/// version-3 board, is the version-2 decoder's own test
/// `wrong_version_carries_the_version_seen`, which refuses version 3 by
/// its version.)
#[test]
fn version_2_frames_are_refused_by_their_version_and_differ_only_by_the_sensor_fields() {
    let v2 = read_golden(&golden_v2_path());
    assert_eq!(v2.len(), 19, "the version-2 file as checked in");
    let v3: std::collections::BTreeMap<_, _> = golden_messages().into_iter().collect();
    let mut device = DeviceDecoder::new();
    let mut host = HostDecoder::new();
    for (name, bytes) in &v2 {
        let out: Vec<Result<Golden, WireError>> = if name.starts_with("device/") {
            device.feed(bytes).map(|r| r.map(Golden::Device)).collect()
        } else {
            host.feed(bytes).map(|r| r.map(Golden::Host)).collect()
        };
        assert_eq!(
            out,
            vec![Err(WireError::WrongVersion { found: 2 })],
            "{name}"
        );
        let g = v3
            .get(name.as_str())
            .expect("every v2 frame has a v3 successor");
        assert_eq!(&ref_frame(2, &v2_payload(g)), bytes, "{name}");
    }
    assert_eq!(device.stats().foreign_version, Some(2));
    assert_eq!(
        device.stats().version_errors + host.stats().version_errors,
        19
    );
    assert_eq!(device.stats().frames_ok + host.stats().frames_ok, 0);
}
