//! The simulated chip: register file, mode rules and the I²C transaction model.

use embedded_hal::i2c::{ErrorType, I2c, Operation, SevenBitAddress};

use crate::regs::*;
use crate::timing::{self, Pipeline, Sensor, Timing};
use crate::{RawReading, SampleSource, SimError};

/// Registers per page.
const PAGE_LEN: usize = 0x80;
/// First and last page-0 register refreshed from the source (`ACC_DATA_X_LSB`..=`TEMP`).
const DATA_FIRST: u8 = ACC_DATA;
const DATA_LAST: u8 = TEMP;
/// `SYS_STATUS` values (datasheet table 4-2).
const SYS_STATUS_IDLE: u8 = 0;
const SYS_STATUS_FUSION: u8 = 5;
const SYS_STATUS_NO_FUSION: u8 = 6;

/// How the data registers get their values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum ChipModel {
    /// A fresh reading from [`SampleSource::sample`] at every data read: no
    /// filter, no internal clock (the default).
    #[default]
    Ideal,
    /// The datasheet's AMG behaviour ([`crate::timing`]): each sensor
    /// filters [`SampleSource::stimulus`] at its configured bandwidth and
    /// updates its registers at its output data rate; reads between updates
    /// return the previous update; range and `UNIT_SEL` saturate and scale.
    /// A source without stimuli is served as by the ideal chip.
    Datasheet,
}

/// A register-level simulated BNO055 on one 7-bit address.
///
/// Implements [`I2c`]: a write's first byte sets the register pointer, further
/// bytes are written with auto-increment; reads auto-increment from the pointer.
/// A transaction that fails (wrong address, busy, injected fault) has no effect.
#[derive(Debug, Clone)]
pub struct Bno055Sim<Src> {
    address: u8,
    source: Src,
    model: ChipModel,
    /// The internal clocks' rate error, ppm.
    clock_error_ppm: f64,
    accel: Option<Pipeline>,
    gyro: Option<Pipeline>,
    pages: [[u8; PAGE_LEN]; 2],
    pointer: u8,
    busy_remaining: u32,
    fail_remaining: u32,
    reset_busy: u32,
    transactions: u32,
    failed_transactions: u32,
    resets: u32,
    ignored_writes: u32,
    samples_latched: u32,
}

impl<Src: SampleSource> Bno055Sim<Src> {
    /// A chip at `address` (0x28 or 0x29 on real boards), powered up and ready,
    /// in CONFIG mode with the datasheet reset values.
    pub fn new(address: u8, source: Src) -> Self {
        let mut sim = Self {
            address,
            source,
            model: ChipModel::Ideal,
            clock_error_ppm: 0.0,
            accel: None,
            gyro: None,
            pages: [[0; PAGE_LEN]; 2],
            pointer: 0,
            busy_remaining: 0,
            fail_remaining: 0,
            reset_busy: 0,
            transactions: 0,
            failed_transactions: 0,
            resets: 0,
            ignored_writes: 0,
            samples_latched: 0,
        };
        sim.load_reset_values();
        sim
    }

    /// The chip in `model` (default [`ChipModel::Ideal`]).
    pub fn with_model(mut self, model: ChipModel) -> Self {
        self.model = model;
        self
    }

    /// The chip model.
    pub fn model(&self) -> ChipModel {
        self.model
    }

    /// Datasheet mode: the chip's internal clock runs `ppm`·10⁻⁶ fast
    /// against the source's (default 0): each sensor updates at
    /// ODR·(1 + ε) ([`crate::timing`]). A value that is not finite or not
    /// above −10⁶ ppm is taken as 0.
    pub fn with_clock_error_ppm(mut self, ppm: f64) -> Self {
        self.clock_error_ppm = if ppm.is_finite() && ppm > -1e6 {
            ppm
        } else {
            0.0
        };
        self
    }

    /// The internal clocks' rate error, ppm.
    pub fn clock_error_ppm(&self) -> f64 {
        self.clock_error_ppm
    }

    /// Runs the internal clocks (datasheet mode) up to the source's next
    /// [`Stimulus`](crate::Stimulus): every internal update in between is
    /// written to the data registers. Call it often (at several times the
    /// highest output data rate) so the filters see the signal finely; a
    /// data read runs the clocks too. Nothing in the ideal model.
    pub fn advance(&mut self) {
        if self.model == ChipModel::Datasheet {
            self.run_clocks();
        }
    }

    /// The configured timing of `sensor` (from `ACC_Config` / `GYR_Config_0`).
    pub fn timing(&self, sensor: Sensor) -> Timing {
        match sensor {
            Sensor::Accel => Timing::accel(self.pages[1][usize::from(ACC_CONFIG)]),
            Sensor::Gyro => Timing::gyro(self.pages[1][usize::from(GYR_CONFIG_0)]),
        }
    }

    /// Register updates of `sensor` since it last started (datasheet mode:
    /// leaving CONFIG mode starts the sensors).
    pub fn updates(&self, sensor: Sensor) -> u64 {
        let pipe = match sensor {
            Sensor::Accel => &self.accel,
            Sensor::Gyro => &self.gyro,
        };
        pipe.as_ref().map_or(0, Pipeline::updates)
    }

    /// Models the power-up time: the next `transactions` transactions are not
    /// acknowledged (the real chip needs about 650 ms, datasheet table 1-2).
    pub fn booting_for(mut self, transactions: u32) -> Self {
        self.busy_remaining = transactions;
        self
    }

    /// Makes the chip busy now: the next `transactions` transactions are not acknowledged.
    pub fn set_busy(&mut self, transactions: u32) {
        self.busy_remaining = transactions;
    }

    /// How many transactions the chip stays busy after a `SYS_TRIGGER` reset
    /// (default 0: callers are expected to wait the 650 ms themselves, and
    /// the simulator has no clock).
    pub fn set_reset_busy(&mut self, transactions: u32) {
        self.reset_busy = transactions;
    }

    /// Fails the next `transactions` transactions with [`SimError::Injected`].
    pub fn fail_next(&mut self, transactions: u32) {
        self.fail_remaining = transactions;
    }

    /// Register `reg` of `page` (0 or 1), read without side effects.
    pub fn register(&self, page: u8, reg: u8) -> u8 {
        self.pages[usize::from(page & 1)][usize::from(reg) % PAGE_LEN]
    }

    /// The selected page (0 or 1).
    pub fn page(&self) -> u8 {
        self.pages[0][usize::from(PAGE_ID)] & 1
    }

    /// The operation mode (`OPR_MODE` bits 3:0).
    pub fn operation_mode(&self) -> u8 {
        self.pages[0][usize::from(OPR_MODE)] & 0x0F
    }

    /// The chip's 7-bit address.
    pub fn address(&self) -> u8 {
        self.address
    }

    /// Transactions addressed to the chip so far (including failed ones).
    pub fn transaction_count(&self) -> u32 {
        self.transactions
    }

    /// Transactions that failed (busy or injected fault).
    pub fn failed_transaction_count(&self) -> u32 {
        self.failed_transactions
    }

    /// `SYS_TRIGGER` resets so far.
    pub fn reset_count(&self) -> u32 {
        self.resets
    }

    /// Register writes ignored (read-only register, or config register outside CONFIG mode).
    pub fn ignored_write_count(&self) -> u32 {
        self.ignored_writes
    }

    /// Readings taken from the source so far.
    pub fn samples_latched(&self) -> u32 {
        self.samples_latched
    }

    /// The source.
    pub fn source_mut(&mut self) -> &mut Src {
        &mut self.source
    }

    /// Gives the source back.
    pub fn into_source(self) -> Src {
        self.source
    }

    fn load_reset_values(&mut self) {
        self.pages = [[0; PAGE_LEN]; 2];
        for &(reg, value) in PAGE0_RESET {
            self.pages[0][usize::from(reg)] = value;
        }
        for &(reg, value) in PAGE1_RESET {
            self.pages[1][usize::from(reg)] = value;
        }
        self.pointer = 0;
    }

    fn in_config_mode(&self) -> bool {
        self.operation_mode() == MODE_CONFIG
    }

    /// Reads register `reg` of the selected page, latching a new reading first
    /// when a burst (`burst_start`) starts at a page-0 data register.
    fn read_register(&mut self, reg: u8, burst_start: bool) -> u8 {
        let page = usize::from(self.page());
        if burst_start && page == 0 && (DATA_FIRST..=DATA_LAST).contains(&reg) {
            let clocked = self.model == ChipModel::Datasheet && self.run_clocks();
            if !clocked {
                self.latch_reading();
            }
        }
        self.pages[page][usize::from(reg) % PAGE_LEN]
    }

    /// Copies a reading from the source into the data registers of the sensors
    /// that the operation mode enables; nothing in CONFIG mode (sensors off).
    fn latch_reading(&mut self) {
        let Some((acc, mag, gyr)) = enabled_sensors(self.operation_mode()) else {
            return;
        };
        let RawReading {
            accel,
            gyro,
            mag: magnetic,
            temp,
        } = self.source.sample();
        self.samples_latched = self.samples_latched.wrapping_add(1);
        if acc {
            self.store_vector(ACC_DATA, accel);
        }
        if mag {
            self.store_vector(MAG_DATA, magnetic);
        }
        if gyr {
            self.store_vector(GYR_DATA, gyro);
        }
        self.pages[0][usize::from(TEMP)] = temp.to_le_bytes()[0];
    }

    fn store_vector(&mut self, first: u8, v: [i16; 3]) {
        store_vector(&mut self.pages[0], first, v);
    }

    /// Datasheet mode: takes one stimulus and runs each enabled sensor's
    /// pipeline to its time (a sensor (re)starts settled at the stimulus,
    /// its registers written with it, when it was off or its timing
    /// changed). `false` if the source has no stimuli.
    fn run_clocks(&mut self) -> bool {
        let Some(st) = self.source.stimulus() else {
            return false;
        };
        let Some((acc, _, gyr)) = enabled_sensors(self.operation_mode()) else {
            self.accel = None;
            self.gyro = None;
            return true;
        };
        let unit_sel = self.pages[0][usize::from(UNIT_SEL)];
        let (acc_per_unit, gyr_per_unit) = timing::counts_per_unit(unit_sel);
        let acc_config = self.pages[1][usize::from(ACC_CONFIG)];
        let gyr_config = self.pages[1][usize::from(GYR_CONFIG_0)];
        let clock_error = self.clock_error_ppm * 1e-6;
        let channels = [
            (
                Sensor::Accel,
                acc,
                st.accel_mps2,
                ACC_DATA,
                acc_per_unit,
                timing::accel_full_scale_mps2(acc_config),
            ),
            (
                Sensor::Gyro,
                gyr,
                st.gyro_rads,
                GYR_DATA,
                gyr_per_unit,
                timing::gyro_full_scale_rads(gyr_config),
            ),
        ];
        for (sensor, enabled, x, first, per_unit, full_scale) in channels {
            let configured = self.timing(sensor);
            let slot = match sensor {
                Sensor::Accel => &mut self.accel,
                Sensor::Gyro => &mut self.gyro,
            };
            if !enabled {
                *slot = None;
                continue;
            }
            let (source, page0) = (&mut self.source, &mut self.pages[0]);
            let mut write = |y: [f64; 3]| {
                let n = source.output_noise(sensor);
                let counts =
                    core::array::from_fn(|i| timing::to_counts(y[i] + n[i], per_unit, full_scale));
                store_vector(page0, first, counts);
            };
            match slot {
                Some(pipe) if pipe.timing() == configured => pipe.run_to(st.t_s, x, write),
                _ => {
                    // A sensor starting has its first value ready at once
                    // (the mode switch takes 7 ms, datasheet table 3-6).
                    write(x);
                    *slot = Some(Pipeline::start(configured, clock_error, st.t_s, x));
                }
            }
        }
        self.pages[0][usize::from(TEMP)] =
            timing::temp_counts(unit_sel, st.temp_c).to_le_bytes()[0];
        true
    }

    /// Writes register `reg` of the selected page under the datasheet rules
    /// (section 3.3: only CONFIG mode may change configuration; `OPR_MODE`,
    /// `PAGE_ID`, `SYS_TRIGGER` and the interrupt registers in any mode).
    fn write_register(&mut self, reg: u8, value: u8) {
        let page = self.page();
        match (page, reg) {
            (_, PAGE_ID) => {
                if value <= 1 {
                    self.pages[0][usize::from(PAGE_ID)] = value;
                    self.pages[1][usize::from(PAGE_ID)] = value;
                } else {
                    self.ignored_writes += 1;
                }
            }
            (0, OPR_MODE) => self.set_mode(value & 0x0F),
            (0, SYS_TRIGGER) => {
                if value & SYS_TRIGGER_RST_SYS != 0 {
                    self.reset();
                } else {
                    // Self-test (bit 0) completes at once; the other bits are kept.
                    self.pages[0][usize::from(SYS_TRIGGER)] = value & 0xC0;
                }
            }
            (1, INT_MSK | INT_EN) => self.pages[1][usize::from(reg)] = value,
            (0, UNIT_SEL | PWR_MODE | 0x40..=0x42 | 0x55..=0x6A)
            | (1, 0x08..=0x0D | 0x11..=0x1F)
                if self.in_config_mode() =>
            {
                self.pages[usize::from(page)][usize::from(reg)] = value;
            }
            _ => self.ignored_writes += 1,
        }
    }

    fn set_mode(&mut self, mode: u8) {
        if mode > 0x0C {
            self.ignored_writes += 1;
            return;
        }
        let was_config = self.in_config_mode();
        self.pages[0][usize::from(OPR_MODE)] = mode;
        if mode == MODE_CONFIG {
            // Sensors off: they restart when an operating mode is entered.
            self.accel = None;
            self.gyro = None;
        }
        if mode == MODE_CONFIG && !was_config {
            // "All output data is reset to zero" in CONFIG mode (section 3.3.1).
            for reg in DATA_FIRST..=DATA_LAST {
                self.pages[0][usize::from(reg)] = 0;
            }
        }
        self.pages[0][usize::from(SYS_STATUS)] = match mode {
            MODE_CONFIG => SYS_STATUS_IDLE,
            1..=7 => SYS_STATUS_NO_FUSION,
            _ => SYS_STATUS_FUSION,
        };
    }

    fn reset(&mut self) {
        self.load_reset_values();
        self.accel = None;
        self.gyro = None;
        self.resets = self.resets.wrapping_add(1);
        self.busy_remaining = self.reset_busy;
    }

    fn run(&mut self, operations: &mut [Operation<'_>]) {
        // A write after a read (or the first write) starts with the register address.
        let mut expect_address = true;
        for operation in operations {
            match operation {
                Operation::Write(bytes) => {
                    for &byte in bytes.iter() {
                        if expect_address {
                            self.pointer = byte & 0x7F;
                            expect_address = false;
                        } else {
                            self.write_register(self.pointer, byte);
                            self.pointer = (self.pointer + 1) & 0x7F;
                        }
                    }
                }
                Operation::Read(buffer) => {
                    expect_address = true;
                    for (i, byte) in buffer.iter_mut().enumerate() {
                        *byte = self.read_register(self.pointer, i == 0);
                        self.pointer = (self.pointer + 1) & 0x7F;
                    }
                }
            }
        }
    }
}

/// Writes `v` little-endian at `first` of page 0.
fn store_vector(page0: &mut [u8; PAGE_LEN], first: u8, v: [i16; 3]) {
    for (axis, value) in v.iter().enumerate() {
        let bytes = value.to_le_bytes();
        let at = usize::from(first) + 2 * axis;
        page0[at] = bytes[0];
        page0[at + 1] = bytes[1];
    }
}

/// (accelerometer, magnetometer, gyroscope) enabled in `mode`, `None` in CONFIG
/// mode (datasheet table 3-3).
fn enabled_sensors(mode: u8) -> Option<(bool, bool, bool)> {
    Some(match mode {
        0x01 => (true, false, false),
        0x02 => (false, true, false),
        0x03 => (false, false, true),
        0x04 | 0x09 | 0x0A => (true, true, false),
        0x05 | 0x08 => (true, false, true),
        0x06 => (false, true, true),
        0x07 | 0x0B | 0x0C => (true, true, true),
        _ => return None,
    })
}

impl<Src> ErrorType for Bno055Sim<Src> {
    type Error = SimError;
}

impl<Src: SampleSource> I2c<SevenBitAddress> for Bno055Sim<Src> {
    fn transaction(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        if address != self.address {
            return Err(SimError::NoAcknowledge);
        }
        self.transactions = self.transactions.wrapping_add(1);
        if self.busy_remaining > 0 {
            self.busy_remaining -= 1;
            self.failed_transactions = self.failed_transactions.wrapping_add(1);
            return Err(SimError::NoAcknowledge);
        }
        if self.fail_remaining > 0 {
            self.fail_remaining -= 1;
            self.failed_transactions = self.failed_transactions.wrapping_add(1);
            return Err(SimError::Injected);
        }
        self.run(operations);
        Ok(())
    }
}

#[cfg(test)]
mod datasheet_tests;
#[cfg(test)]
mod tests;
