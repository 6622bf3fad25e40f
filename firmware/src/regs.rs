//! BNO055 register addresses used directly, and the register encodings of
//! the protocol's settings (datasheet BST-BNO055-DS000, section 4.3).
//!
//! The `bno055` crate keeps its register constants private; the ones the core
//! writes or reads itself are named here.

use robimu_protocol::{AccelBandwidth, AccelRange, GyroBandwidth, GyroRange, SensorConfig};

/// `PAGE_ID` (both pages).
pub(crate) const PAGE_ID: u8 = 0x07;
/// Page 0: `ACC_DATA_X_LSB`; the 18 bytes from here are accelerometer,
/// magnetometer and gyroscope x, y, z as little-endian `i16`.
pub(crate) const ACC_DATA_X_LSB: u8 = 0x08;
/// Length of the accelerometer + magnetometer + gyroscope burst, bytes (0x08..=0x19).
pub(crate) const AMG_DATA_LEN: usize = 18;
/// Offset of the gyroscope x LSB within the burst (`GYR_DATA_X_LSB` = 0x14).
pub(crate) const GYR_OFFSET_IN_BURST: usize = 12;
/// Page 0: `TEMP`.
pub const TEMP: u8 = 0x34;
/// Page 0: `UNIT_SEL`.
pub const UNIT_SEL: u8 = 0x3B;
/// Page 0: `OPR_MODE`.
pub(crate) const OPR_MODE: u8 = 0x3D;
/// Page 1: `ACC_Config`.
pub(crate) const ACC_CONFIG: u8 = 0x08;
/// Page 1: `GYR_Config_0` (range bits 2:0, bandwidth bits 5:3).
pub(crate) const GYR_CONFIG_0: u8 = 0x0A;
/// Page 1: `GYR_Config_1` (power mode bits 2:0).
pub(crate) const GYR_CONFIG_1: u8 = 0x0B;

/// `OPR_MODE` operation mode AMG (accelerometer, magnetometer, gyroscope; no fusion).
pub(crate) const MODE_AMG: u8 = 0x07;

/// `UNIT_SEL`: acceleration in m/s² (bit 0 clear), angular rate in rad/s
/// (bit 1 set), Euler angles in degrees, temperature in °C, Windows
/// orientation (bit 7 clear).
pub(crate) const UNIT_SEL_MPS2_RADS_CELSIUS: u8 = 0b0000_0010;

/// `GYR_Config_1`: normal power mode.
pub(crate) const GYR_CONFIG_1_NORMAL: u8 = 0x00;

/// m/s² per accelerometer count with `UNIT_SEL` in m/s² (1 m/s² = 100 LSB,
/// datasheet table 3-17; independent of the range).
pub(crate) const ACCEL_SCALE_MPS2_PER_LSB: f32 = 0.01;
/// rad/s per gyroscope count with `UNIT_SEL` in rad/s (1 rad/s = 900 LSB,
/// datasheet table 3-22; independent of the range).
pub(crate) const GYRO_SCALE_RADS_PER_LSB: f32 = 1.0 / 900.0;
/// °C per temperature count (1 °C = 1 LSB, table 3-37).
pub(crate) const TEMP_SCALE_C_PER_LSB: f32 = 1.0;

/// `ACC_Config` for `config`: range bits 1:0, bandwidth bits 4:2, normal
/// power mode (bits 7:5 clear).
pub(crate) fn acc_config(config: &SensorConfig) -> u8 {
    let range = match config.accel_range {
        AccelRange::G2 => 0b00,
        AccelRange::G4 => 0b01,
        AccelRange::G8 => 0b10,
        AccelRange::G16 => 0b11,
    };
    let bandwidth = match config.accel_bandwidth {
        AccelBandwidth::Hz7_81 => 0b000,
        AccelBandwidth::Hz15_63 => 0b001,
        AccelBandwidth::Hz31_25 => 0b010,
        AccelBandwidth::Hz62_5 => 0b011,
        AccelBandwidth::Hz125 => 0b100,
        AccelBandwidth::Hz250 => 0b101,
        AccelBandwidth::Hz500 => 0b110,
        AccelBandwidth::Hz1000 => 0b111,
    };
    bandwidth << 2 | range
}

/// `GYR_Config_0` for `config`: range bits 2:0, bandwidth bits 5:3.
pub(crate) fn gyr_config_0(config: &SensorConfig) -> u8 {
    let range = match config.gyro_range {
        GyroRange::Dps2000 => 0b000,
        GyroRange::Dps1000 => 0b001,
        GyroRange::Dps500 => 0b010,
        GyroRange::Dps250 => 0b011,
        GyroRange::Dps125 => 0b100,
    };
    let bandwidth = match config.gyro_bandwidth {
        GyroBandwidth::Hz523 => 0b000,
        GyroBandwidth::Hz230 => 0b001,
        GyroBandwidth::Hz116 => 0b010,
        GyroBandwidth::Hz47 => 0b011,
        GyroBandwidth::Hz23 => 0b100,
        GyroBandwidth::Hz12 => 0b101,
        GyroBandwidth::Hz64 => 0b110,
        GyroBandwidth::Hz32 => 0b111,
    };
    bandwidth << 3 | range
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reset_defaults_encode_to_the_datasheet_reset_values() {
        // ACC_Config resets to 0x0D (±4 g, 62.5 Hz), GYR_Config_0 to 0x38
        // (±2000 °/s, 32 Hz): table 4-2.
        let config = SensorConfig {
            accel_range: AccelRange::G4,
            accel_bandwidth: AccelBandwidth::Hz62_5,
            gyro_range: GyroRange::Dps2000,
            gyro_bandwidth: GyroBandwidth::Hz32,
            sample_rate_hz: 100,
        };
        assert_eq!(acc_config(&config), 0x0D);
        assert_eq!(gyr_config_0(&config), 0x38);
    }

    #[test]
    fn extremes_encode_to_their_bit_fields() {
        let config = SensorConfig {
            accel_range: AccelRange::G16,
            accel_bandwidth: AccelBandwidth::Hz1000,
            gyro_range: GyroRange::Dps125,
            gyro_bandwidth: GyroBandwidth::Hz523,
            sample_rate_hz: 100,
        };
        assert_eq!(acc_config(&config), 0b0001_1111);
        assert_eq!(gyr_config_0(&config), 0b0000_0100);
        // The paper's rig: ±4 g 62.5 Hz; ±2000 °/s 116 Hz.
        let rig = SensorConfig::default();
        assert_eq!(acc_config(&rig), 0x0D);
        assert_eq!(gyr_config_0(&rig), 0b0001_0000);
    }
}
