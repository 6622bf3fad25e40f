//! A simulated IMU board on a pseudo-terminal.
//!
//! [`SimDevice::spawn`] runs the firmware's acquisition core in a thread:
//! its bus is a [`Bno055Bus`] with one [`Bno055Sim`] fed by a
//! [`SampleSource`], or two (0x28 and 0x29, [`SimDeviceConfig::second`],
//! each with its own source and chip clock), its delay is
//! `thread::sleep`, its clock is [`DriftingClock`] (host monotonic time with
//! an offset and a rate error), and its serial port is the master side of a
//! pseudo-terminal pair. The slave side's path ([`SimDevice::port_path`]) is
//! what a host opens, exactly as it would open a USB serial adapter.
//!
//! The master is non-blocking: when no host reads, the pty buffer (about
//! 20 KiB on Linux) fills and the core sees a backed-up link, dropping and
//! counting samples, as on the real board.

use std::os::unix::io::{AsRawFd, RawFd};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use embedded_hal::delay::DelayNs;
use nix::errno::Errno;
use nix::fcntl::{fcntl, FcntlArg, FdFlag, OFlag};
use nix::poll::{poll, PollFd, PollFlags};
use robimu_bno055_sim::{Bno055Bus, Bno055Sim, ChipModel, SampleSource, SineSource};
use robimu_firmware::{Acquisition, Clock, Config};
use robimu_protocol::Status;
use serialport::{SerialPort, TTYPort};

/// Why the simulated device could not be started.
#[derive(Debug, thiserror::Error)]
pub enum SimDeviceError {
    /// The pseudo-terminal pair could not be created.
    #[error("cannot create a pseudo-terminal pair: {0}")]
    Pty(#[from] serialport::Error),
    /// The pseudo-terminal has no slave path.
    #[error("the pseudo-terminal slave has no path")]
    NoPath,
    /// The master could not be made non-blocking.
    #[error("cannot make the pseudo-terminal master non-blocking: {0}")]
    NonBlocking(#[source] Errno),
    /// The master could not be kept from child processes.
    #[error("cannot set close-on-exec on the pseudo-terminal master: {0}")]
    CloseOnExec(#[source] Errno),
    /// The device thread could not be started.
    #[error("cannot start the device thread: {0}")]
    Thread(#[source] std::io::Error),
}

/// What to simulate.
pub struct SimDeviceConfig {
    /// The readings the simulated BNO055 serves.
    pub source: Box<dyn SampleSource + Send>,
    /// The firmware settings (address, rate, status period, autostart, …).
    pub config: Config,
    /// How the simulated chip fills its data registers; in
    /// [`ChipModel::Datasheet`] the device thread runs the chip's clocks
    /// before every poll of the core (every `poll_interval`).
    pub chip_model: ChipModel,
    /// The chip's internal clock rate error against the source's time, ppm
    /// ([`Bno055Sim::with_clock_error_ppm`]; datasheet mode).
    pub chip_clock_error_ppm: f64,
    /// Device clock at spawn time, µs.
    pub clock_offset_us: u64,
    /// Device clock rate error, ppm (positive: the device clock runs fast).
    pub clock_drift_ppm: f64,
    /// Transactions the simulated chip refuses after power-up (the real chip
    /// needs about 650 ms; the core retries every 10 ms).
    pub boot_busy_transactions: u32,
    /// Sleep between two polls of the core.
    pub poll_interval: Duration,
    /// Seed of the injected serial faults ([`SimDevice::set_serial_faults`]).
    pub fault_seed: u64,
    /// A second BNO055 on the bus (sensor 1, at `config.second_address`,
    /// or the other address than `config.i2c_address` when that is `None`).
    pub second: Option<SecondSensor>,
}

/// The second simulated BNO055 of a two-sensor board: its own readings
/// (its own mounting, noise and biases) and its own chip clock.
pub struct SecondSensor {
    /// The readings it serves.
    pub source: Box<dyn SampleSource + Send>,
    /// Its internal clock rate error, ppm (datasheet mode).
    pub chip_clock_error_ppm: f64,
}

impl SimDeviceConfig {
    /// `source` with the default firmware settings, a clock without offset
    /// or drift, a chip that answers at once, and polls every 200 µs.
    pub fn new(source: Box<dyn SampleSource + Send>) -> Self {
        Self {
            source,
            config: Config::default(),
            chip_model: ChipModel::Ideal,
            chip_clock_error_ppm: 0.0,
            clock_offset_us: 0,
            clock_drift_ppm: 0.0,
            boot_busy_transactions: 0,
            poll_interval: Duration::from_micros(200),
            fault_seed: 1,
            second: None,
        }
    }
}

impl Default for SimDeviceConfig {
    /// [`SineSource`] readings with [`SimDeviceConfig::new`]'s settings.
    fn default() -> Self {
        Self::new(Box::new(SineSource::default()))
    }
}

/// Host monotonic time as a device clock: `offset + (1 + drift·10⁻⁶)·elapsed`,
/// wrapping at 2³² µs.
#[derive(Debug, Clone, Copy)]
pub struct DriftingClock {
    start: Instant,
    offset_us: u64,
    drift_ppm: f64,
}

impl DriftingClock {
    /// A clock reading `offset_us` now and running `drift_ppm` fast.
    pub fn new(offset_us: u64, drift_ppm: f64) -> Self {
        Self {
            start: Instant::now(),
            offset_us,
            drift_ppm,
        }
    }

    /// Unwrapped device time at `instant`, µs, unrounded (what
    /// [`Self::now_us_u64`] reads then, before its rounding down).
    pub fn device_us_at(&self, instant: Instant) -> f64 {
        let elapsed_us = if instant >= self.start {
            (instant - self.start).as_secs_f64() * 1e6
        } else {
            -(self.start - instant).as_secs_f64() * 1e6
        };
        self.offset_us as f64 + elapsed_us * (1.0 + self.drift_ppm * 1e-6)
    }

    /// Unwrapped device time, µs.
    pub fn now_us_u64(&self) -> u64 {
        let elapsed_us = self.start.elapsed().as_nanos() as f64 / 1000.0;
        self.offset_us + (elapsed_us * (1.0 + self.drift_ppm * 1e-6)) as u64
    }
}

impl Clock for DriftingClock {
    fn now_us(&mut self) -> u32 {
        self.now_us_u64() as u32
    }
}

/// `DelayNs` by sleeping the thread.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SleepDelay;

impl DelayNs for SleepDelay {
    fn delay_ns(&mut self, ns: u32) {
        thread::sleep(Duration::from_nanos(u64::from(ns)));
    }
}

/// Serial-link faults the simulated board injects into what it sends;
/// changeable while it runs ([`SimDevice::set_serial_faults`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SerialFaults {
    /// Probability that an outgoing byte has one random bit flipped.
    pub corrupt_probability: f64,
    /// Probability that an outgoing byte is lost.
    pub drop_probability: f64,
}

/// Commands to the running device thread.
#[derive(Default)]
struct Control {
    stop: AtomicBool,
    /// Pending resets (power cycles).
    resets: AtomicU32,
    /// Close the pseudo-terminal and end the thread (the board unplugged).
    vanish: AtomicBool,
    faults: Mutex<SerialFaults>,
}

/// SplitMix64: a small deterministic generator for the injected faults.
#[derive(Debug, Clone, Copy)]
struct SplitMix(u64);

impl SplitMix {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A failed read or write on the pseudo-terminal master.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PtyError(pub Errno);

impl embedded_io::Error for PtyError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

/// The device side of the link: the pty master, non-blocking, as an
/// embedded-io port.
///
/// With no host attached the master cannot be read (`EIO`): that reads as
/// "no data". Writes go to the pty buffer until it is full (`EAGAIN`: not
/// ready), like a USB serial adapter nobody reads.
pub(crate) struct PtySerial {
    master: TTYPort,
    control: Arc<Control>,
    rng: SplitMix,
}

impl PtySerial {
    fn fd(&self) -> RawFd {
        self.master.as_raw_fd()
    }

    /// Whether `poll` reports any of `events` now (no waiting).
    fn ready(&self, events: PollFlags) -> Result<bool, PtyError> {
        let mut fds = [PollFd::new(self.fd(), events)];
        match poll(&mut fds, 0) {
            Ok(0) | Err(Errno::EINTR) => Ok(false),
            Ok(_) => Ok(fds[0].revents().is_some_and(|r| r.intersects(events))),
            Err(e) => Err(PtyError(e)),
        }
    }
}

impl embedded_io::ErrorType for PtySerial {
    type Error = PtyError;
}

impl embedded_io::ReadReady for PtySerial {
    fn read_ready(&mut self) -> Result<bool, PtyError> {
        self.ready(PollFlags::POLLIN)
    }
}

impl embedded_io::Read for PtySerial {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, PtyError> {
        match nix::unistd::read(self.fd(), buf) {
            Ok(n) => Ok(n),
            // No data yet, or no host attached.
            Err(Errno::EAGAIN | Errno::EIO | Errno::EINTR) => Ok(0),
            Err(e) => Err(PtyError(e)),
        }
    }
}

impl embedded_io::WriteReady for PtySerial {
    fn write_ready(&mut self) -> Result<bool, PtyError> {
        self.ready(PollFlags::POLLOUT)
    }
}

impl embedded_io::Write for PtySerial {
    fn write(&mut self, buf: &[u8]) -> Result<usize, PtyError> {
        let faults = *self
            .control
            .faults
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        if faults == SerialFaults::default() {
            return match nix::unistd::write(self.fd(), buf) {
                Ok(n) => Ok(n),
                Err(Errno::EAGAIN | Errno::EINTR) => Ok(0),
                Err(e) => Err(PtyError(e)),
            };
        }
        // Faulty line: decide each byte's fate, remembering which input
        // byte each sent byte came from so a partial write reports how much
        // of `buf` was consumed.
        let mut out = Vec::with_capacity(buf.len());
        let mut origin = Vec::with_capacity(buf.len());
        for (i, &b) in buf.iter().enumerate() {
            if self.rng.uniform() < faults.drop_probability {
                continue;
            }
            let b = if self.rng.uniform() < faults.corrupt_probability {
                b ^ (1 << (self.rng.next_u64() % 8))
            } else {
                b
            };
            out.push(b);
            origin.push(i);
        }
        if out.is_empty() {
            return Ok(buf.len());
        }
        match nix::unistd::write(self.fd(), &out) {
            Ok(n) if n == out.len() => Ok(buf.len()),
            Ok(0) => Ok(0),
            Ok(n) => Ok(origin[n]),
            Err(Errno::EAGAIN | Errno::EINTR) => Ok(0),
            Err(e) => Err(PtyError(e)),
        }
    }

    fn flush(&mut self) -> Result<(), PtyError> {
        Ok(())
    }
}

/// The simulated chips' bus.
pub(crate) type SimBus = Bno055Bus<Box<dyn SampleSource + Send>>;

/// The acquisition core as the simulated device runs it.
pub(crate) type SimCore = Acquisition<SimBus, SleepDelay, PtySerial, DriftingClock>;

/// A running simulated device; stopped on [`stop`](Self::stop) or drop.
pub struct SimDevice {
    port_path: String,
    control: Arc<Control>,
    thread: Option<JoinHandle<Status>>,
    clock: DriftingClock,
}

impl SimDevice {
    /// Creates the pseudo-terminal and starts the device thread, which boots
    /// the core ([`Acquisition::start`]) and then polls it.
    ///
    /// # Errors
    ///
    /// [`SimDeviceError`] if the pty or the thread cannot be created.
    pub fn spawn(config: SimDeviceConfig) -> Result<Self, SimDeviceError> {
        let (master, slave) = TTYPort::pair()?;
        let port_path = slave.name().ok_or(SimDeviceError::NoPath)?;
        // The host opens the slave by path; the raw mode `pair` set persists.
        drop(slave);
        fcntl(master.as_raw_fd(), FcntlArg::F_SETFL(OFlag::O_NONBLOCK))
            .map_err(SimDeviceError::NonBlocking)?;
        // Not inherited by a `robimu record` the test starts: a child holding
        // the master would keep the port alive after `vanish`.
        fcntl(master.as_raw_fd(), FcntlArg::F_SETFD(FdFlag::FD_CLOEXEC))
            .map_err(SimDeviceError::CloseOnExec)?;
        let control = Arc::new(Control::default());
        let serial = PtySerial {
            master,
            control: Arc::clone(&control),
            rng: SplitMix(config.fault_seed),
        };
        let thread_control = Arc::clone(&control);
        let clock = DriftingClock::new(config.clock_offset_us, config.clock_drift_ppm);
        let thread = thread::Builder::new()
            .name("robimu-sim-device".into())
            .spawn(move || run(config, serial, clock, &thread_control))
            .map_err(SimDeviceError::Thread)?;
        Ok(Self {
            port_path,
            control,
            thread: Some(thread),
            clock,
        })
    }

    /// The board's clock until its first [`Self::reset`] (which restarts it).
    pub fn clock(&self) -> DriftingClock {
        self.clock
    }

    /// Replaces the injected serial faults (effective from the next write).
    pub fn set_serial_faults(&self, faults: SerialFaults) {
        *self
            .control
            .faults
            .lock()
            .unwrap_or_else(|e| e.into_inner()) = faults;
    }

    /// Power-cycles the board mid-stream: the core restarts (boots, sends
    /// `DeviceInfo`, waits for `Start` unless autostart is set) with its
    /// clock restarting from zero; the sensor's physics source carries on.
    pub fn reset(&self) {
        self.control.resets.fetch_add(1, Ordering::SeqCst);
    }

    /// Unplugs the board: the device thread ends and the pseudo-terminal
    /// closes, so the host's port reads fail and the path disappears.
    pub fn vanish(&self) {
        self.control.vanish.store(true, Ordering::SeqCst);
    }

    /// Whether the device thread is still running.
    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Path of the serial port to open (e.g. `/dev/pts/7`).
    pub fn port_path(&self) -> &str {
        &self.port_path
    }

    /// Stops the device and returns its final health counters.
    ///
    /// # Panics
    ///
    /// Re-raises a panic of the device thread (a firmware bug).
    pub fn stop(mut self) -> Status {
        self.halt().unwrap_or_default()
    }

    fn halt(&mut self) -> Option<Status> {
        self.control.stop.store(true, Ordering::Relaxed);
        let thread = self.thread.take()?;
        match thread.join() {
            Ok(status) => Some(status),
            Err(panic) => std::panic::resume_unwind(panic),
        }
    }
}

impl Drop for SimDevice {
    fn drop(&mut self) {
        if !thread::panicking() {
            self.halt();
        } else {
            self.control.stop.store(true, Ordering::Relaxed);
        }
    }
}

/// The chips, powered up with their sources (`[first, second]`).
fn chips(
    config: &SimDeviceConfig,
    firmware: &Config,
    sources: [Option<Box<dyn SampleSource + Send>>; 2],
    clock_error_ppm: [f64; 2],
) -> SimBus {
    let addresses = [firmware.i2c_address, firmware.second_address.unwrap_or(0)];
    let mut made =
        sources
            .into_iter()
            .zip(addresses)
            .zip(clock_error_ppm)
            .map(|((source, address), ppm)| {
                source.map(|s| {
                    Bno055Sim::new(address, s)
                        .with_model(config.chip_model)
                        .with_clock_error_ppm(ppm)
                        .booting_for(config.boot_busy_transactions)
                })
            });
    match (made.next().flatten(), made.next().flatten()) {
        (Some(first), Some(second)) => Bno055Bus::two(first, second),
        (Some(first), None) => Bno055Bus::one(first),
        // unreachable: the first source is always given
        (None, _) => Bno055Bus::one(Bno055Sim::new(
            firmware.i2c_address,
            Box::new(SineSource::default()),
        )),
    }
}

fn run(
    mut config: SimDeviceConfig,
    serial: PtySerial,
    clock: DriftingClock,
    control: &Control,
) -> Status {
    let mut firmware = config.config;
    let second = config.second.take();
    if second.is_some() && firmware.second_address.is_none() {
        let [a, b] = robimu_firmware::config::BNO055_ADDRESSES;
        firmware.second_address = Some(if firmware.i2c_address == a { b } else { a });
    }
    let ppm = [
        config.chip_clock_error_ppm,
        second.as_ref().map_or(0.0, |s| s.chip_clock_error_ppm),
    ];
    let source = std::mem::replace(&mut config.source, Box::new(SineSource::default()));
    let bus = chips(
        &config,
        &firmware,
        [Some(source), second.map(|s| s.source)],
        ppm,
    );
    let mut core: SimCore = Acquisition::new(bus, SleepDelay, serial, clock, firmware);
    // A boot failure leaves the core answering the host and retrying.
    let _ = core.start();
    while !control.stop.load(Ordering::Relaxed) {
        if control.vanish.load(Ordering::SeqCst) {
            // Dropping the core closes the pty master.
            return core.status();
        }
        if control.resets.load(Ordering::SeqCst) > 0 {
            control.resets.fetch_sub(1, Ordering::SeqCst);
            let (bus, delay, serial, _) = core.release();
            let sources = bus.into_chips().map(|c| c.map(Bno055Sim::into_source));
            let bus = chips(&config, &firmware, sources, ppm);
            let clock = DriftingClock::new(0, config.clock_drift_ppm);
            core = Acquisition::new(bus, delay, serial, clock, firmware);
            let _ = core.start();
        }
        core.bus_mut().advance();
        core.poll();
        thread::sleep(config.poll_interval);
    }
    core.status()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `device_us_at` is the clock's reading at an instant: its offset and
    /// rate over a second, and `now_us_u64` (which rounds down) now.
    #[test]
    fn device_us_at_is_the_clocks_reading_then() {
        let clock = DriftingClock::new(1_234_000, 48.7);
        let t0 = clock.device_us_at(clock.start);
        assert_eq!(t0, 1_234_000.0);
        let t1 = clock.device_us_at(clock.start + Duration::from_secs(1));
        assert!(
            (t1 - t0 - 1e6 * (1.0 + 48.7e-6)).abs() < 1e-6,
            "{}",
            t1 - t0
        );
        let before = clock.device_us_at(clock.start - Duration::from_millis(2));
        assert!((t0 - before - 2e3 * (1.0 + 48.7e-6)).abs() < 1e-6);
        let (a, read, b) = (Instant::now(), clock.now_us_u64(), Instant::now());
        let (lo, hi) = (clock.device_us_at(a), clock.device_us_at(b));
        assert!(
            lo - 1.0 <= read as f64 && read as f64 <= hi,
            "{lo} {read} {hi}"
        );
    }
}
