//! BNO055 register addresses and reset values (datasheet section 4.2, table 4-2).

/// `PAGE_ID`, present on both pages.
pub const PAGE_ID: u8 = 0x07;

/// Page 0: `CHIP_ID`.
pub const CHIP_ID: u8 = 0x00;
/// Page 0: `ACC_ID`.
pub const ACC_ID: u8 = 0x01;
/// Page 0: `MAG_ID`.
pub const MAG_ID: u8 = 0x02;
/// Page 0: `GYR_ID`.
pub const GYR_ID: u8 = 0x03;
/// Page 0: `SW_REV_ID_LSB`.
pub const SW_REV_ID_LSB: u8 = 0x04;
/// Page 0: `SW_REV_ID_MSB`.
pub const SW_REV_ID_MSB: u8 = 0x05;
/// Page 0: `BL_REV_ID`.
pub const BL_REV_ID: u8 = 0x06;
/// Page 0: `ACC_DATA_X_LSB`, first of 6 accelerometer bytes (x, y, z little-endian i16).
pub(crate) const ACC_DATA: u8 = 0x08;
/// Page 0: `MAG_DATA_X_LSB`, first of 6 magnetometer bytes.
pub(crate) const MAG_DATA: u8 = 0x0E;
/// Page 0: `GYR_DATA_X_LSB`, first of 6 gyroscope bytes.
pub(crate) const GYR_DATA: u8 = 0x14;
/// Page 0: `TEMP` (signed byte).
pub const TEMP: u8 = 0x34;
/// Page 0: `SYS_STATUS`.
pub(crate) const SYS_STATUS: u8 = 0x39;
/// Page 0: `UNIT_SEL`.
pub const UNIT_SEL: u8 = 0x3B;
/// Page 0: `OPR_MODE`.
pub const OPR_MODE: u8 = 0x3D;
/// Page 0: `PWR_MODE`.
pub const PWR_MODE: u8 = 0x3E;
/// Page 0: `SYS_TRIGGER`.
pub const SYS_TRIGGER: u8 = 0x3F;
/// `SYS_TRIGGER` bit 5: system reset.
pub(crate) const SYS_TRIGGER_RST_SYS: u8 = 0x20;
/// Page 0: `AXIS_MAP_CONFIG`.
pub(crate) const AXIS_MAP_CONFIG: u8 = 0x41;

/// Page 1: `ACC_Config` (range bits 1:0, bandwidth bits 4:2, power mode bits 7:5).
pub const ACC_CONFIG: u8 = 0x08;
/// Page 1: `MAG_Config`.
pub(crate) const MAG_CONFIG: u8 = 0x09;
/// Page 1: `GYR_Config_0` (range bits 2:0, bandwidth bits 5:3).
pub const GYR_CONFIG_0: u8 = 0x0A;
/// Page 1: `GYR_Config_1` (power mode bits 2:0).
pub const GYR_CONFIG_1: u8 = 0x0B;
/// Page 1: `INT_MSK`.
pub(crate) const INT_MSK: u8 = 0x0F;
/// Page 1: `INT_EN`.
pub(crate) const INT_EN: u8 = 0x10;

/// `OPR_MODE` value of CONFIG mode.
pub(crate) const MODE_CONFIG: u8 = 0x00;
/// `OPR_MODE` value of AMG mode (accelerometer, magnetometer, gyroscope; no fusion).
pub const MODE_AMG: u8 = 0x07;

/// Datasheet identity values.
pub(crate) const CHIP_ID_VALUE: u8 = 0xA0;
/// Accelerometer id.
pub(crate) const ACC_ID_VALUE: u8 = 0xFB;
/// Magnetometer id.
pub(crate) const MAG_ID_VALUE: u8 = 0x32;
/// Gyroscope id.
pub(crate) const GYR_ID_VALUE: u8 = 0x0F;
/// Software revision simulated (3.11, i.e. `SW_REV_ID` = 0x0311).
pub(crate) const SW_REV_VALUE: u16 = 0x0311;
/// Bootloader revision simulated.
pub(crate) const BL_REV_VALUE: u8 = 0x15;

/// Page 0 reset values that are not zero (register, value).
pub(crate) const PAGE0_RESET: &[(u8, u8)] = &[
    (CHIP_ID, CHIP_ID_VALUE),
    (ACC_ID, ACC_ID_VALUE),
    (MAG_ID, MAG_ID_VALUE),
    (GYR_ID, GYR_ID_VALUE),
    (SW_REV_ID_LSB, SW_REV_VALUE.to_le_bytes()[0]),
    (SW_REV_ID_MSB, SW_REV_VALUE.to_le_bytes()[1]),
    (BL_REV_ID, BL_REV_VALUE),
    (UNIT_SEL, 0x80),
    (AXIS_MAP_CONFIG, 0x24),
];

/// Page 1 reset values that are not zero (register, value).
pub(crate) const PAGE1_RESET: &[(u8, u8)] = &[
    (PAGE_ID, 0x01),
    (ACC_CONFIG, 0x0D),
    (MAG_CONFIG, 0x6D),
    (GYR_CONFIG_0, 0x38),
    (0x11, 0x14), // ACC_AM_THRES
    (0x12, 0x03), // ACC_INT_Settings
    (0x13, 0x0F), // ACC_HG_DURATION
    (0x14, 0xC0), // ACC_HG_THRES
    (0x15, 0x0A), // ACC_NM_THRES
    (0x16, 0x0B), // ACC_NM_SET
    (0x18, 0x01), // GYR_HR_X_SET
    (0x19, 0x19), // GYR_DUR_X
    (0x1A, 0x01), // GYR_HR_Y_SET
    (0x1B, 0x19), // GYR_DUR_Y
    (0x1C, 0x01), // GYR_HR_Z_SET
    (0x1D, 0x19), // GYR_DUR_Z
    (0x1E, 0x04), // GYR_AM_THRES
    (0x1F, 0x0A), // GYR_AM_SET
];
