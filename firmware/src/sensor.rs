//! The BNO055 in AMG mode: boot and configuration through the `bno055`
//! crate, sample reads as one direct burst.
//!
//! # Why both the crate and direct transactions
//!
//! `bno055` 0.4 does the chip-id check, soft reset, power mode, accelerometer
//! configuration and mode switches ([`Sensor::init`], [`Sensor::configure`]),
//! but it has no gyroscope range/bandwidth or `UNIT_SEL` API, does not check
//! that the chip is in CONFIG mode before configuration writes, and re-writes
//! `PAGE_ID` before every read (4 transactions for accelerometer + gyroscope).
//! So the core
//!
//! * writes `GYR_Config_0/1` (page 1) and `UNIT_SEL` itself, in CONFIG mode,
//!   and reads every configuration register back ([`Error::NotApplied`]);
//! * leaves page 0 selected and reads a sample as **one** `write_read` of
//!   the 18 data bytes 0x08..=0x19 (accelerometer, magnetometer, gyroscope),
//!   plus one 1-byte read of `TEMP` about once a second (the BNO055 updates
//!   its temperature at 1 Hz).
//!
//! The driver is built on demand over `&mut I2C` (embedded-hal implements
//! `I2c` for `&mut T`), with its cached mode set to the chip's known mode, so
//! the core keeps the bus for its own transactions.

use bno055::{AccConfig, BNO055OperationMode, Bno055};
use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{Error as _, ErrorKind, I2c};

use crate::regs;
use crate::Error;
use robimu_protocol::SensorConfig;

/// Identity registers read at initialisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Identity {
    /// `CHIP_ID` (0xA0).
    pub chip_id: u8,
    /// `ACC_ID` (0xFB).
    pub accel_id: u8,
    /// `MAG_ID` (0x32).
    pub mag_id: u8,
    /// `GYR_ID` (0x0F).
    pub gyro_id: u8,
    /// `SW_REV_ID_MSB << 8 | SW_REV_ID_LSB`.
    pub sw_revision: u16,
    /// `BL_REV_ID`.
    pub bootloader_revision: u8,
}

/// Raw accelerometer and gyroscope counts of one burst read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AmgReading {
    /// Accelerometer x, y, z counts.
    pub accel: [i16; 3],
    /// Gyroscope x, y, z counts.
    pub gyro: [i16; 3],
}

/// The BNO055 on its bus.
#[derive(Debug)]
pub struct Sensor<I2C> {
    i2c: I2C,
    address: u8,
}

impl<I2C: I2c> Sensor<I2C> {
    /// The chip at `address` (checked at [`init`](Self::init)).
    pub fn new(i2c: I2C, address: u8) -> Self {
        Self { i2c, address }
    }

    /// Gives the bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }

    /// The bus.
    pub fn bus_mut(&mut self) -> &mut I2C {
        &mut self.i2c
    }

    /// A driver over the borrowed bus that believes the chip is in `mode`.
    fn driver(&mut self, mode: BNO055OperationMode) -> Result<Bno055<&mut I2C>, Error> {
        let driver = Bno055::new(&mut self.i2c);
        let mut driver = match self.address {
            0x29 => driver,
            0x28 => driver.with_alternative_address(),
            other => return Err(Error::InvalidAddress(other)),
        };
        driver.mode = mode;
        Ok(driver)
    }

    /// Checks `CHIP_ID`, soft-resets the chip (waiting the 650 ms of table
    /// 1-2), selects CONFIG mode and normal power, and reads the identity.
    /// One attempt: the caller retries while the chip is booting.
    pub fn init(&mut self, delay: &mut dyn DelayNs) -> Result<Identity, Error> {
        let mut driver = self.driver(BNO055OperationMode::CONFIG_MODE)?;
        driver.init(delay)?;
        let revision = driver.get_revision()?;
        Ok(Identity {
            chip_id: bno055::BNO055_ID,
            accel_id: revision.accelerometer,
            mag_id: revision.magnetometer,
            gyro_id: revision.gyroscope,
            sw_revision: revision.software,
            bootloader_revision: revision.bootloader,
        })
    }

    /// Applies `config` and enters AMG mode. `from_amg` tells whether the chip
    /// is in AMG mode now (reconfiguration) or in CONFIG mode (after
    /// [`init`](Self::init)). Leaves page 0 selected for [`read`](Self::read).
    pub fn configure(
        &mut self,
        config: &SensorConfig,
        from_amg: bool,
        delay: &mut dyn DelayNs,
    ) -> Result<(), Error> {
        let acc = regs::acc_config(config);
        let gyr0 = regs::gyr_config_0(config);
        {
            let current = if from_amg {
                BNO055OperationMode::AMG
            } else {
                BNO055OperationMode::CONFIG_MODE
            };
            let mut driver = self.driver(current)?;
            driver.set_mode(BNO055OperationMode::CONFIG_MODE, delay)?;
            let acc_config = AccConfig::try_from_bits(acc).map_err(|_| Error::Driver)?;
            // Selects page 1.
            driver.set_acc_config(&acc_config)?;
        }
        self.write(regs::GYR_CONFIG_0, gyr0)?;
        self.write(regs::GYR_CONFIG_1, regs::GYR_CONFIG_1_NORMAL)?;
        let mut page1 = [0u8; 4]; // ACC_Config, MAG_Config, GYR_Config_0, GYR_Config_1
        self.read_into(regs::ACC_CONFIG, &mut page1)?;
        let [acc_read, _mag, gyr0_read, gyr1_read] = page1;
        check(1, regs::ACC_CONFIG, acc, acc_read)?;
        check(1, regs::GYR_CONFIG_0, gyr0, gyr0_read)?;
        check(1, regs::GYR_CONFIG_1, regs::GYR_CONFIG_1_NORMAL, gyr1_read)?;

        self.write(regs::PAGE_ID, 0)?;
        self.write(regs::UNIT_SEL, regs::UNIT_SEL_MPS2_RADS_CELSIUS)?;
        let mut unit_sel = [0u8; 1];
        self.read_into(regs::UNIT_SEL, &mut unit_sel)?;
        let [unit_sel] = unit_sel;
        check(
            0,
            regs::UNIT_SEL,
            regs::UNIT_SEL_MPS2_RADS_CELSIUS,
            unit_sel,
        )?;

        self.driver(BNO055OperationMode::CONFIG_MODE)?
            .set_mode(BNO055OperationMode::AMG, delay)?;
        self.check_amg()
    }

    /// Reads `OPR_MODE` (page 0 must be selected) and checks that it is AMG.
    pub fn check_amg(&mut self) -> Result<(), Error> {
        let mut mode = [0u8; 1];
        self.read_into(regs::OPR_MODE, &mut mode)?;
        let [mode] = mode;
        let found = mode & 0x0F;
        if found == regs::MODE_AMG {
            Ok(())
        } else {
            Err(Error::ModeNotEntered { found })
        }
    }

    /// One burst read of the 18 AMG data bytes (page 0 selected by
    /// [`configure`](Self::configure)): one bus transaction.
    pub fn read(&mut self) -> Result<AmgReading, ErrorKind> {
        let mut buf = [0u8; regs::AMG_DATA_LEN];
        self.i2c
            .write_read(self.address, &[regs::ACC_DATA_X_LSB], &mut buf)
            .map_err(|e| e.kind())?;
        let (accel, rest) = buf.split_at(6);
        let gyro = rest.get(regs::GYR_OFFSET_IN_BURST - 6..).unwrap_or(&[]);
        Ok(AmgReading {
            accel: vector(accel),
            gyro: vector(gyro),
        })
    }

    /// Reads `TEMP` (°C, signed): one bus transaction.
    pub fn read_temperature(&mut self) -> Result<i8, ErrorKind> {
        let mut buf = [0u8; 1];
        self.i2c
            .write_read(self.address, &[regs::TEMP], &mut buf)
            .map_err(|e| e.kind())?;
        Ok(i8::from_le_bytes(buf))
    }

    fn write(&mut self, register: u8, value: u8) -> Result<(), Error> {
        self.i2c
            .write(self.address, &[register, value])
            .map_err(|e| Error::Bus(e.kind()))
    }

    fn read_into(&mut self, register: u8, buf: &mut [u8]) -> Result<(), Error> {
        self.i2c
            .write_read(self.address, &[register], buf)
            .map_err(|e| Error::Bus(e.kind()))
    }
}

/// Little-endian x, y, z from the first 6 bytes of `bytes` (zeros if short).
fn vector(bytes: &[u8]) -> [i16; 3] {
    let mut v = [0i16; 3];
    for (axis, pair) in v.iter_mut().zip(bytes.chunks_exact(2)) {
        if let [lo, hi] = *pair {
            *axis = i16::from_le_bytes([lo, hi]);
        }
    }
    v
}

fn check(page: u8, register: u8, wrote: u8, read: u8) -> Result<(), Error> {
    if wrote == read {
        Ok(())
    } else {
        Err(Error::NotApplied {
            page,
            register,
            wrote,
            read,
        })
    }
}
