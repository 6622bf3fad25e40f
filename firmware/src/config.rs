//! Settings of the acquisition core.

use robimu_protocol::SensorConfig;

/// The BNO055's two I²C addresses (COM3 pin low / high). Adafruit-style
/// boards use 0x28; the `bno055` crate's default is 0x29.
pub const BNO055_ADDRESSES: [u8; 2] = [0x28, 0x29];

/// Highest accepted sample rate, Hz (the BNO055 AMG data rate limits what is useful).
pub(crate) const MAX_SAMPLE_RATE_HZ: u16 = 1000;

/// How the acquisition core runs. `Default` is the paper's rig on an
/// Adafruit-style board; change fields with struct update syntax:
///
/// ```
/// let config = robimu_firmware::Config { i2c_address: 0x29, ..Default::default() };
/// assert_eq!(config.sensor.sample_rate_hz, robimu_protocol::DEFAULT_SAMPLE_RATE_HZ);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// BNO055 7-bit address, 0x28 or 0x29 ([`BNO055_ADDRESSES`]): sensor 0.
    pub i2c_address: u8,
    /// The address of a second BNO055 on the same bus (sensor 1; the other
    /// of [`BNO055_ADDRESSES`]), or `None` for a one-sensor board. Both are
    /// read on the same tick, each with its own counters and re-initialisation.
    pub second_address: Option<u8>,
    /// Ranges, bandwidths and the sample rate (1..=1000 Hz).
    pub sensor: SensorConfig,
    /// Period of the `Status` frames sent while streaming, ms; 0 disables
    /// them. Each one is preceded by a check that the chip is still in AMG
    /// mode (a chip that reset itself is re-initialised).
    pub status_period_ms: u32,
    /// Start streaming right after boot, without waiting for `Start`.
    pub autostart: bool,
    /// How long [`start`](crate::Acquisition::start) keeps retrying while the
    /// chip does not answer after power-up (it needs about 650 ms), ms.
    pub boot_timeout_ms: u32,
    /// Attempts at each sample read before the sample is given up (at least 1).
    pub read_attempts: u8,
    /// Consecutive failed samples after which the sensor is re-initialised.
    pub reinit_after_failures: u8,
    /// Wait between re-initialisation attempts while the sensor is down, ms.
    pub reinit_backoff_ms: u32,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            i2c_address: 0x28,
            second_address: None,
            sensor: SensorConfig::default(),
            status_period_ms: 1000,
            autostart: false,
            boot_timeout_ms: 1000,
            read_attempts: 3,
            reinit_after_failures: 3,
            reinit_backoff_ms: 1000,
        }
    }
}

impl Config {
    /// The sensors' addresses, sensor 0 first.
    pub fn addresses(&self) -> impl Iterator<Item = u8> {
        core::iter::once(self.i2c_address).chain(self.second_address)
    }
}

/// Whether `sensor` can be applied (the enums are always valid; the rate must
/// be 1..=[`MAX_SAMPLE_RATE_HZ`]).
pub(crate) fn sensor_config_valid(sensor: &SensorConfig) -> bool {
    (1..=MAX_SAMPLE_RATE_HZ).contains(&sensor.sample_rate_hz)
}
