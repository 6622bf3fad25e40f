//! The message table: every frame the device and the host exchange.
//!
//! Plain structs and enums with fixed-width integers; names carry their units
//! (`t_us`, `accel_raw`). Settings are enums so that an impossible setting
//! cannot be expressed. Postcard encodes enums by variant index, so **variants
//! are only ever appended**, never reordered: reordering is a protocol version
//! bump ([`crate::PROTOCOL_VERSION`]).

use serde::{Deserialize, Serialize};

/// Accelerometer full-scale range (BNO055 ACC_Config bits 1:0, page 1 reg 0x08).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AccelRange {
    /// ±2 g
    G2,
    /// ±4 g (the BNO055 reset default)
    G4,
    /// ±8 g
    G8,
    /// ±16 g
    G16,
}

/// Accelerometer low-pass bandwidth (ACC_Config bits 4:2).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AccelBandwidth {
    /// 7.81 Hz
    Hz7_81,
    /// 15.63 Hz
    Hz15_63,
    /// 31.25 Hz
    Hz31_25,
    /// 62.5 Hz (the BNO055 reset default)
    Hz62_5,
    /// 125 Hz
    Hz125,
    /// 250 Hz
    Hz250,
    /// 500 Hz
    Hz500,
    /// 1000 Hz
    Hz1000,
}

/// Gyroscope full-scale range (GYR_Config_0 bits 2:0, page 1 reg 0x0A).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GyroRange {
    /// ±2000 °/s (the BNO055 reset default)
    Dps2000,
    /// ±1000 °/s
    Dps1000,
    /// ±500 °/s
    Dps500,
    /// ±250 °/s
    Dps250,
    /// ±125 °/s
    Dps125,
}

/// Gyroscope low-pass bandwidth (GYR_Config_0 bits 5:3).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GyroBandwidth {
    /// 523 Hz
    Hz523,
    /// 230 Hz
    Hz230,
    /// 116 Hz
    Hz116,
    /// 47 Hz
    Hz47,
    /// 23 Hz
    Hz23,
    /// 12 Hz
    Hz12,
    /// 64 Hz
    Hz64,
    /// 32 Hz (the BNO055 reset default)
    Hz32,
}

impl AccelBandwidth {
    /// The low-pass bandwidth, Hz.
    pub fn hz(self) -> f32 {
        match self {
            Self::Hz7_81 => 7.8125,
            Self::Hz15_63 => 15.625,
            Self::Hz31_25 => 31.25,
            Self::Hz62_5 => 62.5,
            Self::Hz125 => 125.0,
            Self::Hz250 => 250.0,
            Self::Hz500 => 500.0,
            Self::Hz1000 => 1000.0,
        }
    }

    /// The accelerometer's internal output data rate at this bandwidth:
    /// twice the bandwidth (BNO055 table 3-8; its BMA280-class accelerometer), Hz.
    pub fn odr_hz(self) -> f32 {
        2.0 * self.hz()
    }
}

impl GyroBandwidth {
    /// The low-pass bandwidth, Hz.
    pub fn hz(self) -> f32 {
        match self {
            Self::Hz523 => 523.0,
            Self::Hz230 => 230.0,
            Self::Hz116 => 116.0,
            Self::Hz47 => 47.0,
            Self::Hz23 => 23.0,
            Self::Hz12 => 12.0,
            Self::Hz64 => 64.0,
            Self::Hz32 => 32.0,
        }
    }

    /// The gyroscope's internal output data rate at this bandwidth (BNO055
    /// table 3-9; its BMG160-class gyroscope), Hz.
    pub fn odr_hz(self) -> f32 {
        match self {
            Self::Hz523 | Self::Hz230 => 2000.0,
            Self::Hz116 => 1000.0,
            Self::Hz47 => 400.0,
            Self::Hz23 | Self::Hz64 => 200.0,
            Self::Hz12 | Self::Hz32 => 100.0,
        }
    }
}

/// What the chip does between the board's reads: each sensor low-pass
/// filters at its bandwidth and updates its data registers at its internal
/// output data rate (ODR), on its own clock. The board reads asynchronously
/// at [`SensorConfig::sample_rate_hz`]: a reading is the last internal
/// update, whose age is spread over [0, 1/ODR) ([`SensorTiming::alias_lines`]:
/// which rates make that age vary slowly).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct SensorTiming {
    /// Accelerometer low-pass bandwidth, Hz.
    pub accel_bandwidth_hz: f32,
    /// Accelerometer internal output data rate, Hz.
    pub accel_odr_hz: f32,
    /// Gyroscope low-pass bandwidth, Hz.
    pub gyro_bandwidth_hz: f32,
    /// Gyroscope internal output data rate, Hz.
    pub gyro_odr_hz: f32,
}

impl SensorTiming {
    /// The timing the BNO055 has with `config`'s bandwidths.
    pub fn of(config: &SensorConfig) -> Self {
        Self {
            accel_bandwidth_hz: config.accel_bandwidth.hz(),
            accel_odr_hz: config.accel_bandwidth.odr_hz(),
            gyro_bandwidth_hz: config.gyro_bandwidth.hz(),
            gyro_odr_hz: config.gyro_bandwidth.odr_hz(),
        }
    }
}

/// The firmware's default read rate, Hz: the choice of the read-rate rule
/// ([`SensorTiming::alias_free_rate`]) for the default bandwidths (62.5 Hz
/// accelerometer, ODR 125 Hz; 116 Hz gyroscope, ODR 1000 Hz); a test
/// checks the two agree.
pub const DEFAULT_SAMPLE_RATE_HZ: u16 = 150;

/// Acquisition settings, sent by the host in [`HostMessage::Configure`] and
/// reported back in [`DeviceInfo::config`].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SensorConfig {
    /// Accelerometer full-scale range.
    pub accel_range: AccelRange,
    /// Accelerometer low-pass bandwidth.
    pub accel_bandwidth: AccelBandwidth,
    /// Gyroscope full-scale range.
    pub gyro_range: GyroRange,
    /// Gyroscope low-pass bandwidth.
    pub gyro_bandwidth: GyroBandwidth,
    /// Sample rate in Hz (1..=1000; the BNO055 AMG data rate limits what is useful).
    pub sample_rate_hz: u16,
}

impl Default for SensorConfig {
    /// The paper's rig's ranges and bandwidths: ±4 g, 62.5 Hz accel;
    /// ±2000 °/s, 116 Hz gyro; sampled at [`DEFAULT_SAMPLE_RATE_HZ`]
    /// (150 Hz), the rate [`SensorTiming::alias_free_rate`] chooses for
    /// them (the paper's rig read at 120 Hz, whose age beats at 5 Hz).
    fn default() -> Self {
        Self {
            accel_range: AccelRange::G4,
            accel_bandwidth: AccelBandwidth::Hz62_5,
            gyro_range: GyroRange::Dps2000,
            gyro_bandwidth: GyroBandwidth::Hz116,
            sample_rate_hz: DEFAULT_SAMPLE_RATE_HZ,
        }
    }
}

/// Who the device is and how to turn its raw counts into SI units.
/// Sent after boot, after every sensor (re)initialisation and on [`HostMessage::GetInfo`].
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub struct DeviceInfo {
    /// Firmware version, `[major, minor, patch]`.
    pub firmware_version: [u8; 3],
    /// The device's [`crate::PROTOCOL_VERSION`].
    pub protocol_version: u8,
    /// BNO055 CHIP_ID (0xA0 for a genuine part).
    pub chip_id: u8,
    /// Accelerometer chip id (0xFB).
    pub accel_id: u8,
    /// Magnetometer chip id (0x32).
    pub mag_id: u8,
    /// Gyroscope chip id (0x0F).
    pub gyro_id: u8,
    /// BNO055 software revision (SW_REV_ID_MSB << 8 | LSB).
    pub sw_revision: u16,
    /// BNO055 bootloader revision.
    pub bootloader_revision: u8,
    /// The acquisition settings in force.
    pub config: SensorConfig,
    /// m/s² per accelerometer count (0.01 with UNIT_SEL in m/s²).
    pub accel_scale_mps2_per_lsb: f32,
    /// rad/s per gyroscope count (1/900 with UNIT_SEL in rad/s).
    pub gyro_scale_rads_per_lsb: f32,
    /// °C per temperature count (1.0).
    pub temp_scale_c_per_lsb: f32,
    /// The sensors' bandwidths and internal output data rates (protocol 2).
    pub timing: SensorTiming,
    /// Which of the board's sensors this is, `0..sensors` (protocol 3).
    pub sensor: u8,
    /// How many sensors the board reads (protocol 3; 1 or 2 BNO055 on one
    /// I²C bus). A board sends one `Info` per sensor.
    pub sensors: u8,
}

/// The most sensors one board reads: the BNO055 has two I²C addresses
/// (0x28, 0x29), so two share a bus.
pub const MAX_SENSORS: u8 = 2;

/// One accelerometer + gyroscope reading.
///
/// `t_us` is the device clock in microseconds, **wrapping** modulo 2³²
/// (every 71.6 minutes). Readers unwrap it by accumulating the wrapping
/// difference between consecutive samples (`t_us.wrapping_sub(prev)`), which is
/// exact while consecutive samples are less than 2³¹ µs (35 minutes) apart.
/// `seq` also wraps modulo 2³² and increments by one per *sampled* reading, so
/// a gap in `seq` counts samples lost on the device or on the link.
///
/// `sensor` (protocol 3) tells which of the board's sensors read it; every
/// sensor of a board is read on the same tick and numbered by the same
/// `seq`, so each sensor's own gaps count its own losses.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ImuSample {
    /// Which of the board's sensors ([`DeviceInfo::sensor`]).
    pub sensor: u8,
    /// Sample sequence number (wrapping).
    pub seq: u32,
    /// Device time of the reading, µs (wrapping, see above).
    pub t_us: u32,
    /// Raw accelerometer counts, sensor axes x, y, z.
    pub accel_raw: [i16; 3],
    /// Raw gyroscope counts, sensor axes x, y, z.
    pub gyro_raw: [i16; 3],
    /// Raw temperature count (°C with the default scale).
    pub temp_raw: i8,
}

/// Health counters, sent periodically (about once a second) while streaming
/// and on [`HostMessage::GetStatus`], one per sensor of the board (protocol
/// 3): the sample and I²C counters are that sensor's, `frames_sent` and
/// `rx_errors` the board's (the same in every sensor's report). All counters wrap.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Status {
    /// Device time of the report, µs (wrapping).
    pub t_us: u32,
    /// Whether the device is streaming samples.
    pub streaming: bool,
    /// Samples read from the sensor and queued for sending.
    pub samples_sent: u32,
    /// Samples dropped because the serial link was backed up, or a deadline was missed.
    pub samples_dropped: u32,
    /// Failed I²C transactions (each retry counts).
    pub i2c_errors: u32,
    /// Times the sensor was re-initialised after repeated failures.
    pub sensor_reinits: u32,
    /// Frames written to the serial link (all kinds).
    pub frames_sent: u32,
    /// Host frames the device could not decode.
    pub rx_errors: u32,
    /// Which of the board's sensors the sample and I²C counters are (protocol 3).
    pub sensor: u8,
}

/// Answer to [`HostMessage::Ping`]: the nonce back, with the device clock
/// at the moment the ping was handled, so that the host can map device time
/// to host time.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Pong {
    /// The host's nonce, echoed.
    pub nonce: u32,
    /// Device time when the ping was handled, µs (wrapping).
    pub t_us: u32,
}

/// Why a command failed.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CommandError {
    /// A setting is out of range (e.g. a sample rate of 0 or above 1000 Hz).
    InvalidConfig,
    /// The sensor did not answer or rejected the configuration.
    SensorFault,
    /// The command is not allowed now (e.g. `Configure` while streaming).
    Busy,
}

/// Which command a [`CommandResult`] answers.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CommandKind {
    /// [`HostMessage::Configure`]
    Configure,
    /// [`HostMessage::Start`]
    Start,
    /// [`HostMessage::Stop`]
    Stop,
}

/// The typed outcome of a command that changes device state.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CommandResult {
    /// The command answered.
    pub command: CommandKind,
    /// `Ok(())`, or why it failed.
    pub result: Result<(), CommandError>,
}

/// Frames from the device to the host.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq)]
pub enum DeviceMessage {
    /// Identity and scales.
    Info(DeviceInfo),
    /// One reading.
    Sample(ImuSample),
    /// Health counters.
    Status(Status),
    /// Answer to a ping.
    Pong(Pong),
    /// Outcome of `Configure`, `Start` or `Stop`.
    CommandResult(CommandResult),
}

/// Frames from the host to the device.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HostMessage {
    /// Apply new settings (only while stopped); answered by a `CommandResult`
    /// and, on success, a fresh `Info`.
    Configure(SensorConfig),
    /// Start streaming samples; answered by a `CommandResult`.
    Start,
    /// Stop streaming; answered by a `CommandResult`.
    Stop,
    /// Echo `nonce` with the device clock in a `Pong`.
    Ping {
        /// Chosen by the host to match the answer.
        nonce: u32,
    },
    /// Ask for a `DeviceInfo`.
    GetInfo,
    /// Ask for a `Status`.
    GetStatus,
}
