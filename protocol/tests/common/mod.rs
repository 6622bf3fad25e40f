//! Shared test helpers: independent reference implementations of the wire
//! format (bitwise CRC-32C, textbook COBS, LEB128/zigzag varints) and
//! proptest strategies for every message type.
#![allow(dead_code)]

use proptest::prelude::*;
use proptest::sample::select;
use robimu_protocol::*;

/// Bit-by-bit CRC-32C (reflected polynomial 0x82F63B78, init/xorout all ones),
/// written from the definition, independent of the `crc` crate's tables.
pub fn ref_crc32c(data: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &byte in data {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Textbook COBS encoding (Cheshire & Baker 1999), without the delimiter.
pub fn ref_cobs(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_at = 0;
    let mut code = 1u8;
    for &b in data {
        if b == 0 {
            out[code_at] = code;
            code_at = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_at] = code;
    out
}

/// Reference frame: COBS(version ++ payload ++ CRC-32C LE) ++ 0x00.
pub fn ref_frame(version: u8, payload: &[u8]) -> Vec<u8> {
    let mut body = vec![version];
    body.extend_from_slice(payload);
    let crc = ref_crc32c(&body);
    body.extend_from_slice(&crc.to_le_bytes());
    let mut frame = ref_cobs(&body);
    frame.push(0);
    frame
}

/// Unsigned LEB128, as postcard writes integers.
pub fn leb(mut v: u64) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let low = (v & 0x7F) as u8;
        v >>= 7;
        if v == 0 {
            out.push(low);
            return out;
        }
        out.push(low | 0x80);
    }
}

/// Zigzag + LEB128, as postcard writes signed integers.
pub fn zz(v: i64) -> Vec<u8> {
    leb(((v << 1) ^ (v >> 63)) as u64)
}

/// Encodes with the crate under test into a fresh `Vec`.
pub fn frame_of<M: serde::Serialize>(msg: &M) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    encode(msg, &mut buf)
        .expect("every message fits MAX_FRAME_LEN")
        .to_vec()
}

/// Exhaustive variant names (a new variant fails to compile here until the
/// golden vectors and strategies cover it).
pub fn device_variant(m: &DeviceMessage) -> &'static str {
    match m {
        DeviceMessage::Info(_) => "Info",
        DeviceMessage::Sample(_) => "Sample",
        DeviceMessage::Status(_) => "Status",
        DeviceMessage::Pong(_) => "Pong",
        DeviceMessage::CommandResult(_) => "CommandResult",
    }
}

/// See [`device_variant`].
pub fn host_variant(m: &HostMessage) -> &'static str {
    match m {
        HostMessage::Configure(_) => "Configure",
        HostMessage::Start => "Start",
        HostMessage::Stop => "Stop",
        HostMessage::Ping { .. } => "Ping",
        HostMessage::GetInfo => "GetInfo",
        HostMessage::GetStatus => "GetStatus",
    }
}

/// Worst-case frame length per variant, from the table in `frame.rs` docs.
pub fn device_variant_max_frame(m: &DeviceMessage) -> usize {
    match m {
        DeviceMessage::Info(_) => 57,
        DeviceMessage::Sample(_) => 38,
        DeviceMessage::Status(_) => 45,
        DeviceMessage::Pong(_) => 18,
        DeviceMessage::CommandResult(_) => 11,
    }
}

/// See [`device_variant_max_frame`].
pub fn host_variant_max_frame(m: &HostMessage) -> usize {
    match m {
        HostMessage::Configure(_) => 15,
        HostMessage::Ping { .. } => 13,
        HostMessage::Start | HostMessage::Stop | HostMessage::GetInfo | HostMessage::GetStatus => 8,
    }
}

// ---- proptest strategies --------------------------------------------------

pub fn accel_range() -> impl Strategy<Value = AccelRange> {
    use AccelRange::*;
    select(vec![G2, G4, G8, G16])
}

pub fn accel_bandwidth() -> impl Strategy<Value = AccelBandwidth> {
    use AccelBandwidth::*;
    select(vec![
        Hz7_81, Hz15_63, Hz31_25, Hz62_5, Hz125, Hz250, Hz500, Hz1000,
    ])
}

pub fn gyro_range() -> impl Strategy<Value = GyroRange> {
    use GyroRange::*;
    select(vec![Dps2000, Dps1000, Dps500, Dps250, Dps125])
}

pub fn gyro_bandwidth() -> impl Strategy<Value = GyroBandwidth> {
    use GyroBandwidth::*;
    select(vec![Hz523, Hz230, Hz116, Hz47, Hz23, Hz12, Hz64, Hz32])
}

pub fn sensor_config() -> impl Strategy<Value = SensorConfig> {
    (
        accel_range(),
        accel_bandwidth(),
        gyro_range(),
        gyro_bandwidth(),
        any::<u16>(),
    )
        .prop_map(
            |(accel_range, accel_bandwidth, gyro_range, gyro_bandwidth, sample_rate_hz)| {
                SensorConfig {
                    accel_range,
                    accel_bandwidth,
                    gyro_range,
                    gyro_bandwidth,
                    sample_rate_hz,
                }
            },
        )
}

/// Any bit pattern, NaNs and infinities included.
pub fn any_f32_bits() -> impl Strategy<Value = f32> {
    any::<u32>().prop_map(f32::from_bits)
}

pub fn device_info() -> impl Strategy<Value = DeviceInfo> {
    (
        any::<[u8; 3]>(),
        any::<[u8; 5]>(),
        any::<u16>(),
        any::<u8>(),
        sensor_config(),
        [any_f32_bits(), any_f32_bits(), any_f32_bits()],
        any::<[u8; 2]>(),
        [
            any_f32_bits(),
            any_f32_bits(),
            any_f32_bits(),
            any_f32_bits(),
        ],
    )
        .prop_map(
            |(
                fw,
                ids,
                sw_revision,
                bootloader_revision,
                config,
                scales,
                [sensor, sensors],
                rates,
            )| {
                let [protocol_version, chip_id, accel_id, mag_id, gyro_id] = ids;
                let [accel_scale_mps2_per_lsb, gyro_scale_rads_per_lsb, temp_scale_c_per_lsb] =
                    scales;
                DeviceInfo {
                    firmware_version: fw,
                    protocol_version,
                    chip_id,
                    accel_id,
                    mag_id,
                    gyro_id,
                    sw_revision,
                    bootloader_revision,
                    config,
                    accel_scale_mps2_per_lsb,
                    gyro_scale_rads_per_lsb,
                    temp_scale_c_per_lsb,
                    timing: SensorTiming {
                        accel_bandwidth_hz: rates[0],
                        accel_odr_hz: rates[1],
                        gyro_bandwidth_hz: rates[2],
                        gyro_odr_hz: rates[3],
                    },
                    sensor,
                    sensors,
                }
            },
        )
}

pub fn imu_sample() -> impl Strategy<Value = ImuSample> {
    (
        any::<u32>(),
        any::<u32>(),
        any::<[i16; 3]>(),
        any::<[i16; 3]>(),
        any::<i8>(),
        any::<u8>(),
    )
        .prop_map(
            |(seq, t_us, accel_raw, gyro_raw, temp_raw, sensor)| ImuSample {
                sensor,
                seq,
                t_us,
                accel_raw,
                gyro_raw,
                temp_raw,
            },
        )
}

pub fn status() -> impl Strategy<Value = Status> {
    (any::<u32>(), any::<bool>(), any::<[u32; 6]>(), any::<u8>()).prop_map(
        |(t_us, streaming, c, sensor)| Status {
            t_us,
            streaming,
            samples_sent: c[0],
            samples_dropped: c[1],
            i2c_errors: c[2],
            sensor_reinits: c[3],
            frames_sent: c[4],
            rx_errors: c[5],
            sensor,
        },
    )
}

pub fn pong() -> impl Strategy<Value = Pong> {
    (any::<u32>(), any::<u32>()).prop_map(|(nonce, t_us)| Pong { nonce, t_us })
}

pub fn command_result() -> impl Strategy<Value = CommandResult> {
    use CommandError::*;
    use CommandKind::*;
    (
        select(vec![Configure, Start, Stop]),
        prop_oneof![
            Just(Ok(())),
            select(vec![InvalidConfig, SensorFault, Busy]).prop_map(Err)
        ],
    )
        .prop_map(|(command, result)| CommandResult { command, result })
}

pub fn device_message() -> impl Strategy<Value = DeviceMessage> {
    prop_oneof![
        1 => device_info().prop_map(DeviceMessage::Info),
        // Samples dominate real traffic.
        3 => imu_sample().prop_map(DeviceMessage::Sample),
        1 => status().prop_map(DeviceMessage::Status),
        1 => pong().prop_map(DeviceMessage::Pong),
        1 => command_result().prop_map(DeviceMessage::CommandResult),
    ]
}

pub fn host_message() -> impl Strategy<Value = HostMessage> {
    prop_oneof![
        sensor_config().prop_map(HostMessage::Configure),
        Just(HostMessage::Start),
        Just(HostMessage::Stop),
        any::<u32>().prop_map(|nonce| HostMessage::Ping { nonce }),
        Just(HostMessage::GetInfo),
        Just(HostMessage::GetStatus),
    ]
}
