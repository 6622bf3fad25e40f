//! The acquisition core: sensor, schedule, link and commands.
//!
//! # Loop
//!
//! The board calls [`Acquisition::start`] once and then
//! [`Acquisition::poll`] as often as it can (a busy loop, or on timer and
//! UART interrupts). Each poll
//!
//! 1. reads the host bytes already received and answers complete commands;
//! 2. retries a down sensor when its back-off has elapsed;
//! 3. if the next sample deadline ([`crate::schedule`]) has passed, reads one
//!    sample (one I²C burst), timestamps it with the clock read just before
//!    the burst, and queues an `ImuSample` frame;
//! 4. when due, checks that the chip is still in AMG mode and queues a `Status`;
//! 5. writes queued bytes only while the port reports `WriteReady`.
//!
//! # Two sensors on one bus
//!
//! With [`Config::second_address`] the core reads a second BNO055 on the
//! same bus (protocol 3: every frame names its sensor). Both are read on
//! the same tick, sensor 0 first, each timestamped just before its own
//! burst, and share the slot's `seq`; each has its own identity,
//! temperature, I²C error and re-initialisation counters, and its own
//! `DeviceInfo` and `Status` frames. A sensor that fails is re-initialised
//! on its own while the other keeps streaming.
//!
//! Nothing waits on the link or the bus beyond one transaction; the exceptions
//! are configuration (`Configure`, about 40 ms of mode-switch delays) and
//! re-initialisation (the chip's 650 ms reset time).
//!
//! # Sampling and the chip's internal rates
//!
//! In AMG mode the BNO055's accelerometer and gyroscope each filter at
//! their configured bandwidth and update their data registers at their own
//! internal output data rate (ODR: 2 × bandwidth for the accelerometer,
//! 100–2000 Hz by bandwidth for the gyroscope; datasheet tables 3-8 and
//! 3-9), on clocks the board cannot see (the chip has no data-ready signal
//! in AMG mode). Of the two ways to keep reads from aliasing the internal
//! updates — read at the chip's own rate from its timing, or read
//! asynchronously at a rate chosen so that they do not alias — the core
//! takes the second: without a data-ready signal the first would have to
//! track a clock it cannot observe, and a board rate locked to a nominal ODR
//! drifts against the chip's by the oscillator's tolerance. It reads
//! **asynchronously** at its own `sample_rate_hz` on the board's clock, and
//! reports the bandwidths and ODRs in `DeviceInfo::timing`. A reading is the
//! last internal update: each sensor's value is delayed by its filter's
//! group delay plus an age spread over [0, 1/ODR) (mean 1/(2·ODR)), a
//! sawtooth whose harmonics alias to f·‖kF/f‖. The default rate is the
//! protocol's rule ([`robimu_protocol::alias`],
//! [`SensorTiming::alias_free_rate`]): 150 Hz for the default 125 Hz /
//! 1000 Hz ODRs, where the slowest line is at 25 Hz (22.5 Hz for a chip
//! clock 2 % off), above the motion's band; at the paper's 120 Hz the age
//! beats at 5 Hz. A `Configure` with any rate of 1..=1000 Hz is applied as
//! asked (the host warns when its margin is short); above an ODR some reads
//! repeat the previous update. The host records both rates (session.toml
//! `[imu]`).
//!
//! # Sequence numbers and drops
//!
//! `seq` numbers sample *slots* (deadlines): it advances by one per deadline,
//! whether the reading was sent, dropped for lack of queue space, missed
//! because the loop was late, or lost to a failed read. Each of those
//! failures adds one to that sensor's `samples_dropped`, so on a lossless
//! link the gaps in each sensor's `seq` add up to exactly its `samples_dropped`.
//!
//! # I²C errors
//!
//! A failed sample read is retried at once, up to `read_attempts` times;
//! every failed transaction counts in `i2c_errors`. After
//! `reinit_after_failures` consecutive lost samples, or when the periodic
//! check finds the chip out of AMG mode (it reset itself), the sensor is
//! re-initialised (soft reset and configuration), `sensor_reinits` counts
//! it, and a fresh `DeviceInfo` is sent. While the sensor is down, slots are
//! dropped and re-initialisation is retried every `reinit_backoff_ms`.
//! Errors while waiting for the chip to boot in [`Acquisition::start`] are
//! expected (it does not answer for about 650 ms) and not counted.

use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;
use embedded_io::{Read, ReadReady, Write, WriteReady};
use robimu_protocol::{
    encode_device, CommandError, CommandKind, CommandResult, DeviceInfo, DeviceMessage,
    HostDecoder, HostMessage, ImuSample, Pong, SensorConfig, SensorTiming, Status, DELIMITER,
    DEVICE_MAX_FRAME_LEN, MAX_SENSORS, PROTOCOL_VERSION,
};

use crate::config::sensor_config_valid;
use crate::schedule::Schedule;
use crate::sensor::{AmgReading, Identity, Sensor};
use crate::tx_queue::TxQueue;
use crate::{regs, Clock, Config, Error, FIRMWARE_VERSION};

/// Transmit queue size, bytes: six of the longest device frames.
pub const TX_QUEUE_LEN: usize = 6 * DEVICE_MAX_FRAME_LEN;
/// Queue bytes that sample frames may not use, kept for replies and status.
pub const TX_RESERVE: usize = 2 * DEVICE_MAX_FRAME_LEN;
/// Host bytes read per chunk.
const RX_CHUNK_LEN: usize = 32;
/// Chunks read per poll at most (bounds the time spent on input).
const RX_CHUNKS_PER_POLL: usize = 4;
/// Wait between attempts while the chip boots, ms.
const BOOT_RETRY_MS: u32 = 10;
/// Longest status period honoured, ms (wrapping comparisons need < 2³¹ µs).
const MAX_STATUS_PERIOD_MS: u32 = 30 * 60 * 1000;

/// Whether wrapping time `now` has reached `t` (within ±35 minutes).
fn reached(now: u32, t: u32) -> bool {
    now.wrapping_sub(t) <= i32::MAX as u32
}

/// One BNO055 on the bus and its own state.
#[derive(Debug, Clone, Copy, Default)]
struct Slot {
    address: u8,
    identity: Identity,
    ready: bool,
    temperature: i8,
    /// Samples until the next temperature read (0: read with the next sample).
    temp_countdown: u16,
    /// Consecutive samples lost to read failures.
    failed_samples: u32,
    next_reinit_us: u32,
    /// Its sample and I²C counters (the board's in [`Acquisition::counters`]).
    counters: Status,
}

/// The acquisition core over a BNO055 bus `I2C`, a delay `D`, a serial port
/// `S` and a microsecond clock `C`.
pub struct Acquisition<I2C, D, S, C> {
    i2c: I2C,
    slots: [Slot; MAX_SENSORS as usize],
    /// How many of `slots` are in use (1 or 2).
    sensors: usize,
    delay: D,
    serial: S,
    clock: C,
    config: Config,
    streaming: bool,
    schedule: Schedule,
    next_seq: u32,
    next_status_us: u32,
    /// The board's counters (`t_us`, `frames_sent`, `rx_errors`).
    counters: Status,
    control_dropped: u32,
    /// Lone delimiters queued for resynchronisation, not counted as frames.
    uncounted_delimiters: u32,
    tx: TxQueue<TX_QUEUE_LEN>,
    rx: HostDecoder,
}

impl<I2C, D, S, C> Acquisition<I2C, D, S, C>
where
    I2C: I2c,
    D: DelayNs,
    S: Read + ReadReady + Write + WriteReady,
    C: Clock,
{
    /// A core that has not touched the bus or the port yet; call
    /// [`start`](Self::start) next.
    pub fn new(i2c: I2C, delay: D, serial: S, clock: C, config: Config) -> Self {
        let mut slots = [Slot::default(); MAX_SENSORS as usize];
        let mut sensors = 0;
        for (slot, address) in slots.iter_mut().zip(config.addresses()) {
            slot.address = address;
            slot.counters.sensor = sensors as u8;
            sensors += 1;
        }
        Self {
            i2c,
            slots,
            sensors,
            delay,
            serial,
            clock,
            config,
            streaming: false,
            schedule: Schedule::new(config.sensor.sample_rate_hz, 0),
            next_seq: 0,
            next_status_us: 0,
            counters: Status::default(),
            control_dropped: 0,
            uncounted_delimiters: 0,
            tx: TxQueue::new(),
            rx: HostDecoder::new(),
        }
    }

    /// Boots the sensors and announces the device (one `DeviceInfo` per sensor).
    ///
    /// Retries for up to `boot_timeout_ms` while the chip does not answer (or
    /// answers with a wrong `CHIP_ID`) after power-up, then soft-resets it
    /// (650 ms), configures AMG mode, the ranges and bandwidths of
    /// `config.sensor` and the units (m/s², rad/s, °C). Then queues a lone
    /// delimiter (so the host drops any partial frame) and a `DeviceInfo`,
    /// starts streaming if `autostart`, and writes what the port accepts.
    ///
    /// # Errors
    ///
    /// Why a sensor is not ready (the first one's). The core stays usable either way: it
    /// answers the host, and retries the sensor every `reinit_backoff_ms`
    /// and on `Start`. [`Error::InvalidSampleRate`] if the configured rate is
    /// outside 1..=1000 Hz (the sensor is up, but streaming waits for a valid
    /// `Configure`).
    pub fn start(&mut self) -> Result<(), Error> {
        self.queue_delimiter();
        let mut result = Ok(());
        for k in 0..self.sensors {
            let booted = self.boot(k);
            result = result.and(booted);
        }
        self.queue_info();
        let rate_valid = sensor_config_valid(&self.config.sensor);
        if self.config.autostart && rate_valid {
            self.begin_streaming();
        }
        self.flush();
        match result {
            Ok(()) if !rate_valid => {
                Err(Error::InvalidSampleRate(self.config.sensor.sample_rate_hz))
            }
            other => other,
        }
    }

    /// One turn of the loop (see the [module documentation](self)).
    pub fn poll(&mut self) {
        self.receive();
        let now = self.clock.now_us();
        self.counters.t_us = now;
        for k in 0..self.sensors {
            if !self.slot(k).ready && reached(now, self.slot(k).next_reinit_us) {
                self.reinitialise(k);
            }
        }
        if self.streaming {
            self.sample_if_due();
        }
        self.status_if_due();
        self.flush();
    }

    /// The health counters of sensor 0 (`t_us` is the time of the last poll).
    pub fn status(&self) -> Status {
        self.status_of(0)
    }

    /// The health counters of sensor `k` (the board's `t_us`,
    /// `frames_sent` and `rx_errors`; sensor 0's for a `k` out of range).
    pub fn status_of(&self, k: usize) -> Status {
        let own = self.slot(k).counters;
        Status {
            streaming: self.streaming,
            samples_sent: own.samples_sent,
            samples_dropped: own.samples_dropped,
            i2c_errors: own.i2c_errors,
            sensor_reinits: own.sensor_reinits,
            sensor: own.sensor,
            ..self.counters
        }
    }

    /// How many sensors the board reads (1, or 2 with [`Config::second_address`]).
    pub fn sensors(&self) -> usize {
        self.sensors
    }

    /// Replies and status frames that did not fit the transmit queue (not
    /// in [`Status`]; normally 0).
    pub fn control_frames_dropped(&self) -> u32 {
        self.control_dropped
    }

    /// Whether samples are being streamed.
    pub fn is_streaming(&self) -> bool {
        self.streaming
    }

    /// Whether every sensor is initialised and configured.
    pub fn sensor_ready(&self) -> bool {
        (0..self.sensors).all(|k| self.slot(k).ready)
    }

    /// Whether sensor `k` is initialised and configured.
    pub fn sensor_ready_of(&self, k: usize) -> bool {
        k < self.sensors && self.slot(k).ready
    }

    /// The settings in force.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Sensor 0's identity read at the last (re-)initialisation (zeros before one succeeded).
    pub fn identity(&self) -> Identity {
        self.slot(0).identity
    }

    /// Sensor `k`'s identity (sensor 0's for a `k` out of range).
    pub fn identity_of(&self, k: usize) -> Identity {
        self.slot(k).identity
    }

    /// The next sample deadline on the device clock, µs (wrapping), while
    /// streaming: a board may sleep until then or until a UART interrupt.
    pub fn next_deadline_us(&self) -> Option<u32> {
        self.streaming.then(|| self.schedule.next_deadline_us())
    }

    /// Bytes waiting in the transmit queue.
    pub fn tx_queued(&self) -> usize {
        self.tx.len()
    }

    /// The `DeviceInfo` the core sends for sensor 0: identity, settings and the scales of
    /// the raw counts (0.01 m/s², 1/900 rad/s and 1 °C per count, from
    /// `UNIT_SEL`; the BNO055 scales its output registers independently of
    /// the range).
    pub fn device_info(&self) -> DeviceInfo {
        self.device_info_of(0)
    }

    /// The `DeviceInfo` of sensor `k` (sensor 0's for a `k` out of range).
    pub fn device_info_of(&self, k: usize) -> DeviceInfo {
        let slot = self.slot(k);
        let identity = slot.identity;
        DeviceInfo {
            firmware_version: FIRMWARE_VERSION,
            protocol_version: PROTOCOL_VERSION,
            chip_id: identity.chip_id,
            accel_id: identity.accel_id,
            mag_id: identity.mag_id,
            gyro_id: identity.gyro_id,
            sw_revision: identity.sw_revision,
            bootloader_revision: identity.bootloader_revision,
            config: self.config.sensor,
            accel_scale_mps2_per_lsb: regs::ACCEL_SCALE_MPS2_PER_LSB,
            gyro_scale_rads_per_lsb: regs::GYRO_SCALE_RADS_PER_LSB,
            temp_scale_c_per_lsb: regs::TEMP_SCALE_C_PER_LSB,
            timing: SensorTiming::of(&self.config.sensor),
            sensor: slot.counters.sensor,
            sensors: self.sensors as u8,
        }
    }

    /// The bus (a simulator runs the simulated chips' clocks through it).
    pub fn bus_mut(&mut self) -> &mut I2C {
        &mut self.i2c
    }

    /// Gives back the bus, delay, port and clock.
    pub fn release(self) -> (I2C, D, S, C) {
        (self.i2c, self.delay, self.serial, self.clock)
    }

    // ----- sensor -------------------------------------------------------

    /// Sensor `k`'s state (sensor 0's for a `k` out of range).
    fn slot(&self, k: usize) -> &Slot {
        let [first, ..] = &self.slots;
        if k < self.sensors {
            self.slots.get(k).unwrap_or(first)
        } else {
            first
        }
    }

    fn slot_mut(&mut self, k: usize) -> &mut Slot {
        let k = if k < self.sensors { k } else { 0 };
        let [first, rest @ ..] = &mut self.slots;
        match k.checked_sub(1) {
            None => first,
            Some(i) => match rest.get_mut(i) {
                Some(slot) => slot,
                None => first,
            },
        }
    }

    /// The driver of sensor `k` over the shared bus.
    fn sensor(&mut self, k: usize) -> Sensor<&mut I2C> {
        let address = self.slot(k).address;
        Sensor::new(&mut self.i2c, address)
    }

    /// Retries [`bring_up`](Self::bring_up) while the chip boots.
    fn boot(&mut self, k: usize) -> Result<(), Error> {
        let mut waited_ms = 0u32;
        loop {
            match self.bring_up(k) {
                Ok(()) => return Ok(()),
                Err(Error::Bus(_) | Error::WrongChipId(_))
                    if waited_ms < self.config.boot_timeout_ms =>
                {
                    self.delay.delay_ms(BOOT_RETRY_MS);
                    waited_ms = waited_ms.saturating_add(BOOT_RETRY_MS);
                }
                Err(e) => {
                    self.sensor_down(k);
                    return Err(e);
                }
            }
        }
    }

    /// One attempt at initialising and configuring sensor `k`.
    fn bring_up(&mut self, k: usize) -> Result<(), Error> {
        self.slot_mut(k).ready = false;
        let address = self.slot(k).address;
        if k > 0 && address == self.slot(0).address {
            return Err(Error::InvalidAddress(address));
        }
        let config = self.config.sensor;
        let mut sensor = Sensor::new(&mut self.i2c, address);
        let identity = sensor.init(&mut self.delay)?;
        self.slot_mut(k).identity = identity;
        let mut sensor = Sensor::new(&mut self.i2c, address);
        sensor.configure(&config, false, &mut self.delay)?;
        let slot = self.slot_mut(k);
        slot.ready = true;
        slot.failed_samples = 0;
        Ok(())
    }

    /// Re-initialises sensor `k` after failures; counts it and announces it.
    fn reinitialise(&mut self, k: usize) {
        match self.bring_up(k) {
            Ok(()) => {
                let c = &mut self.slot_mut(k).counters;
                c.sensor_reinits = c.sensor_reinits.wrapping_add(1);
                self.queue_info_of(k);
            }
            Err(e) => {
                self.count_error(k, &e);
                self.sensor_down(k);
            }
        }
    }

    fn sensor_down(&mut self, k: usize) {
        let backoff_us = self
            .config
            .reinit_backoff_ms
            .min(MAX_STATUS_PERIOD_MS)
            .saturating_mul(1000);
        let next = self.clock.now_us().wrapping_add(backoff_us);
        let slot = self.slot_mut(k);
        slot.ready = false;
        slot.next_reinit_us = next;
    }

    fn count_error(&mut self, k: usize, e: &Error) {
        if e.is_bus() {
            self.count_i2c_error(k);
        }
    }

    fn count_i2c_error(&mut self, k: usize) {
        let c = &mut self.slot_mut(k).counters;
        c.i2c_errors = c.i2c_errors.wrapping_add(1);
    }

    // ----- sampling -----------------------------------------------------

    fn begin_streaming(&mut self) {
        let now = self.clock.now_us();
        self.streaming = true;
        self.schedule = Schedule::new(self.config.sensor.sample_rate_hz, now);
        for slot in self.slots.iter_mut() {
            slot.temp_countdown = 0;
            slot.failed_samples = 0;
        }
        self.next_status_us = now.wrapping_add(self.status_period_us());
    }

    fn sample_if_due(&mut self) {
        let now = self.clock.now_us();
        let Some(missed) = self.schedule.poll(now) else {
            return;
        };
        self.next_seq = self.next_seq.wrapping_add(missed);
        for k in 0..self.sensors {
            self.count_dropped(k, missed);
            self.sample_sensor(k);
        }
        self.next_seq = self.next_seq.wrapping_add(1);
    }

    /// Reads sensor `k` for the current slot and queues its sample.
    fn sample_sensor(&mut self, k: usize) {
        if !self.slot(k).ready {
            self.count_dropped(k, 1);
            return;
        }
        let Some((t_us, reading)) = self.read_with_retries(k) else {
            self.count_dropped(k, 1);
            let limit = u32::from(self.config.reinit_after_failures.max(1));
            let slot = self.slot_mut(k);
            slot.failed_samples = slot.failed_samples.saturating_add(1);
            if slot.failed_samples >= limit {
                self.reinitialise(k);
            }
            return;
        };
        self.slot_mut(k).failed_samples = 0;
        self.read_temperature_if_due(k);
        let slot = self.slot(k);
        let sample = ImuSample {
            sensor: slot.counters.sensor,
            seq: self.next_seq,
            t_us,
            accel_raw: reading.accel,
            gyro_raw: reading.gyro,
            temp_raw: slot.temperature,
        };
        let mut buf = [0u8; DEVICE_MAX_FRAME_LEN];
        let queued = match encode_device(&DeviceMessage::Sample(sample), &mut buf) {
            Ok(frame) => self.tx.push_with_reserve(frame, TX_RESERVE),
            Err(_) => false,
        };
        let c = &mut self.slot_mut(k).counters;
        if queued {
            c.samples_sent = c.samples_sent.wrapping_add(1);
        } else {
            c.samples_dropped = c.samples_dropped.wrapping_add(1);
        }
    }

    /// Counts `n` of sensor `k`'s slots as dropped (their sequence numbers are used up).
    fn count_dropped(&mut self, k: usize, n: u32) {
        let c = &mut self.slot_mut(k).counters;
        c.samples_dropped = c.samples_dropped.wrapping_add(n);
    }

    /// Sensor `k`'s burst read, retried; returns the clock just before the successful burst.
    fn read_with_retries(&mut self, k: usize) -> Option<(u32, AmgReading)> {
        for _ in 0..self.config.read_attempts.max(1) {
            let t_us = self.clock.now_us();
            match self.sensor(k).read() {
                Ok(reading) => return Some((t_us, reading)),
                Err(_) => self.count_i2c_error(k),
            }
        }
        None
    }

    /// Reads sensor `k`'s `TEMP` about once a second (the BNO055 updates it at 1 Hz);
    /// on failure keeps the last value and tries again with the next sample.
    fn read_temperature_if_due(&mut self, k: usize) {
        if self.slot(k).temp_countdown > 0 {
            self.slot_mut(k).temp_countdown -= 1;
            return;
        }
        let countdown = self.config.sensor.sample_rate_hz.saturating_sub(1);
        match self.sensor(k).read_temperature() {
            Ok(t) => {
                let slot = self.slot_mut(k);
                slot.temperature = t;
                slot.temp_countdown = countdown;
            }
            Err(_) => self.count_i2c_error(k),
        }
    }

    // ----- status -------------------------------------------------------

    fn status_period_us(&self) -> u32 {
        self.config.status_period_ms.min(MAX_STATUS_PERIOD_MS) * 1000
    }

    fn status_if_due(&mut self) {
        let period = self.status_period_us();
        if !self.streaming || period == 0 {
            return;
        }
        let now = self.clock.now_us();
        if !reached(now, self.next_status_us) {
            return;
        }
        self.next_status_us = self.next_status_us.wrapping_add(period);
        if reached(now, self.next_status_us) {
            // More than a period late: restart the cadence from now.
            self.next_status_us = now.wrapping_add(period);
        }
        for k in 0..self.sensors {
            if self.slot(k).ready {
                match self.sensor(k).check_amg() {
                    Ok(()) => {}
                    Err(e @ Error::Bus(_)) => self.count_error(k, &e),
                    // Out of AMG mode: the chip reset itself.
                    Err(_) => self.reinitialise(k),
                }
            }
        }
        self.queue_status();
    }

    // ----- commands -----------------------------------------------------

    fn receive(&mut self) {
        let mut chunk = [0u8; RX_CHUNK_LEN];
        for _ in 0..RX_CHUNKS_PER_POLL {
            if !matches!(self.serial.read_ready(), Ok(true)) {
                return;
            }
            let n = match self.serial.read(&mut chunk) {
                Ok(n) if n > 0 => n,
                _ => return,
            };
            let mut rest = chunk.get(..n).unwrap_or(&[]);
            while !rest.is_empty() {
                let (outcome, tail) = self.rx.push(rest);
                rest = tail;
                match outcome {
                    Some(Ok(message)) => self.handle(message),
                    Some(Err(_)) => {
                        self.counters.rx_errors = self.counters.rx_errors.wrapping_add(1);
                    }
                    None => {}
                }
            }
        }
    }

    fn handle(&mut self, message: HostMessage) {
        match message {
            HostMessage::Configure(sensor) => {
                let result = self.configure(sensor);
                self.queue_result(CommandKind::Configure, result);
                if result.is_ok() {
                    self.queue_info();
                }
            }
            HostMessage::Start => {
                let result = self.start_streaming();
                self.queue_result(CommandKind::Start, result);
            }
            HostMessage::Stop => {
                self.streaming = false;
                self.queue_result(CommandKind::Stop, Ok(()));
            }
            HostMessage::Ping { nonce } => {
                let t_us = self.clock.now_us();
                self.queue_control(&DeviceMessage::Pong(Pong { nonce, t_us }));
            }
            HostMessage::GetInfo => self.queue_info(),
            HostMessage::GetStatus => {
                self.counters.t_us = self.clock.now_us();
                self.queue_status();
            }
        }
    }

    fn configure(&mut self, sensor: SensorConfig) -> Result<(), CommandError> {
        if self.streaming {
            return Err(CommandError::Busy);
        }
        if !sensor_config_valid(&sensor) {
            return Err(CommandError::InvalidConfig);
        }
        let previous = self.config.sensor;
        self.config.sensor = sensor;
        let mut failed = false;
        for k in 0..self.sensors {
            if let Err(e) = self.apply(k, &sensor) {
                self.count_error(k, &e);
                self.sensor_down(k);
                failed = true;
            }
        }
        if !failed {
            return Ok(());
        }
        // Back to the settings in force: a sensor that took the new ones
        // is set back (one that fails that is re-initialised later).
        self.config.sensor = previous;
        for k in 0..self.sensors {
            if self.slot(k).ready {
                if let Err(e) = self.apply(k, &previous) {
                    self.count_error(k, &e);
                    self.sensor_down(k);
                }
            }
        }
        Err(CommandError::SensorFault)
    }

    /// Configures sensor `k` with `sensor` (brings it up if it is down).
    fn apply(&mut self, k: usize, sensor: &SensorConfig) -> Result<(), Error> {
        if self.slot(k).ready {
            let address = self.slot(k).address;
            Sensor::new(&mut self.i2c, address).configure(sensor, true, &mut self.delay)
        } else {
            self.bring_up(k)
        }
    }

    fn start_streaming(&mut self) -> Result<(), CommandError> {
        if self.streaming {
            return Ok(());
        }
        if !sensor_config_valid(&self.config.sensor) {
            return Err(CommandError::InvalidConfig);
        }
        for k in 0..self.sensors {
            if !self.slot(k).ready {
                self.reinitialise(k);
                if !self.slot(k).ready {
                    return Err(CommandError::SensorFault);
                }
            }
        }
        self.begin_streaming();
        Ok(())
    }

    // ----- link ---------------------------------------------------------

    fn queue_delimiter(&mut self) {
        if self.tx.push(&[DELIMITER]) {
            self.uncounted_delimiters = self.uncounted_delimiters.wrapping_add(1);
        }
    }

    /// Queues every sensor's `DeviceInfo`.
    fn queue_info(&mut self) {
        for k in 0..self.sensors {
            self.queue_info_of(k);
        }
    }

    fn queue_info_of(&mut self, k: usize) {
        self.queue_control(&DeviceMessage::Info(self.device_info_of(k)));
    }

    /// Queues every sensor's `Status`.
    fn queue_status(&mut self) {
        for k in 0..self.sensors {
            self.queue_control(&DeviceMessage::Status(self.status_of(k)));
        }
    }

    fn queue_result(&mut self, command: CommandKind, result: Result<(), CommandError>) {
        self.queue_control(&DeviceMessage::CommandResult(CommandResult {
            command,
            result,
        }));
    }

    /// Queues a reply or status frame; it may use the reserve.
    fn queue_control(&mut self, message: &DeviceMessage) {
        let mut buf = [0u8; DEVICE_MAX_FRAME_LEN];
        let queued = match encode_device(message, &mut buf) {
            Ok(frame) => self.tx.push(frame),
            Err(_) => false,
        };
        if !queued {
            self.control_dropped = self.control_dropped.wrapping_add(1);
        }
    }

    /// Writes queued bytes while the port is ready; counts completed frames
    /// by their delimiters. Never calls the port's blocking `flush`.
    fn flush(&mut self) {
        while !self.tx.is_empty() {
            if !matches!(self.serial.write_ready(), Ok(true)) {
                return;
            }
            let front = self.tx.front();
            let written = match self.serial.write(front) {
                Ok(n) if n > 0 => n.min(front.len()),
                _ => return,
            };
            let delimiters = front
                .get(..written)
                .unwrap_or(&[])
                .iter()
                .filter(|&&b| b == DELIMITER)
                .count() as u32;
            let resync = delimiters.min(self.uncounted_delimiters);
            self.uncounted_delimiters -= resync;
            self.counters.frames_sent = self.counters.frames_sent.wrapping_add(delimiters - resync);
            self.tx.consume(written);
        }
    }
}
