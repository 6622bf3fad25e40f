//! Test doubles shared by the firmware tests: a clock advanced by hand (and by
//! the delay), an in-memory serial link that can back up, a shared handle on
//! the simulated bus, and a host that decodes what the device sent.
#![allow(dead_code)]

use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::convert::Infallible;
use std::rc::Rc;

use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::{ErrorType, I2c, Operation};
use robimu_bno055_sim::{Bno055Bus, Bno055Sim, RawReading, SampleSource};
use robimu_firmware::{Acquisition, Clock, Config};
use robimu_protocol::{
    encode_host, DeviceDecoder, DeviceMessage, HostMessage, ImuSample, MAX_FRAME_LEN,
};

/// Simulated time in µs, shared by the clock, the delay and the sources.
#[derive(Clone, Default)]
pub struct SimTime(pub Rc<Cell<u64>>);

impl SimTime {
    pub fn starting_at(t_us: u64) -> Self {
        Self(Rc::new(Cell::new(t_us)))
    }
    pub fn now(&self) -> u64 {
        self.0.get()
    }
    pub fn advance(&self, dt_us: u64) {
        self.0.set(self.0.get() + dt_us);
    }
}

impl Clock for SimTime {
    fn now_us(&mut self) -> u32 {
        self.0.get() as u32 // wrapping, like a hardware timer
    }
}

/// A delay that advances simulated time instead of sleeping.
pub struct SimDelay {
    pub time: SimTime,
    pub total_ns: Rc<Cell<u64>>,
}

impl DelayNs for SimDelay {
    fn delay_ns(&mut self, ns: u32) {
        let total = self.total_ns.get() + u64::from(ns);
        // Advance whole microseconds as they accumulate.
        let before = self.total_ns.get() / 1000;
        self.total_ns.set(total);
        self.time.advance(total / 1000 - before);
    }
}

/// Readings that encode the simulated time at which they were latched:
/// `accel = [t & 0x7fff, (t >> 15) & 0x7fff, (t >> 30) & 0x7fff]`
/// (µs, wrapping at 2³²), `gyro = [-1, 2, -3]`, `temp = 21`.
pub struct TimeSource(pub SimTime);

pub fn encode_time(t_us: u32) -> [i16; 3] {
    [
        (t_us & 0x7fff) as i16,
        ((t_us >> 15) & 0x7fff) as i16,
        (t_us >> 30) as i16,
    ]
}

impl SampleSource for TimeSource {
    fn sample(&mut self) -> RawReading {
        RawReading {
            accel: encode_time(self.0.now() as u32),
            gyro: [-1, 2, -3],
            mag: [5, 6, 7],
            temp: 21,
        }
    }
}

/// The simulated BNO055, shared between the core and the test.
pub type Sim = Bno055Sim<TimeSource>;

/// Two simulated BNO055 on one bus (0x28 and 0x29).
pub type TwoSims = Bno055Bus<TimeSource>;

/// A bus (one chip, or a [`Bno055Bus`]) shared between the core and the test.
pub struct SharedBus<B = Sim>(pub Rc<RefCell<B>>);

impl<B> Clone for SharedBus<B> {
    fn clone(&self) -> Self {
        Self(self.0.clone())
    }
}

impl<B> ErrorType for SharedBus<B> {
    type Error = robimu_bno055_sim::SimError;
}

impl<B: I2c<Error = robimu_bno055_sim::SimError>> I2c for SharedBus<B> {
    fn transaction(
        &mut self,
        address: u8,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        self.0.borrow_mut().transaction(address, operations)
    }
}

/// The serial link, seen from the device. `writable = false` models a
/// backed-up link: the device must not write then (the double panics).
#[derive(Default)]
pub struct LinkState {
    pub to_device: VecDeque<u8>,
    pub from_device: Vec<u8>,
    pub writable: bool,
    /// Bytes accepted per `write` call.
    pub max_write: usize,
}

#[derive(Clone)]
pub struct Link(pub Rc<RefCell<LinkState>>);

impl Link {
    pub fn new() -> Self {
        Self(Rc::new(RefCell::new(LinkState {
            writable: true,
            max_write: 16,
            ..LinkState::default()
        })))
    }
    pub fn set_writable(&self, writable: bool) {
        self.0.borrow_mut().writable = writable;
    }
    pub fn send(&self, message: &HostMessage) {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = encode_host(message, &mut buf).unwrap();
        self.0.borrow_mut().to_device.extend(frame.iter().copied());
    }
    pub fn send_bytes(&self, bytes: &[u8]) {
        self.0.borrow_mut().to_device.extend(bytes.iter().copied());
    }
    pub fn take_sent(&self) -> Vec<u8> {
        std::mem::take(&mut self.0.borrow_mut().from_device)
    }
}

impl embedded_io::ErrorType for Link {
    type Error = Infallible;
}

impl embedded_io::Read for Link {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let mut state = self.0.borrow_mut();
        let n = buf.len().min(state.to_device.len());
        for slot in buf.iter_mut().take(n) {
            *slot = state.to_device.pop_front().unwrap();
        }
        Ok(n)
    }
}

impl embedded_io::ReadReady for Link {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.borrow().to_device.is_empty())
    }
}

impl embedded_io::Write for Link {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let mut state = self.0.borrow_mut();
        assert!(
            state.writable,
            "the core wrote to a port that was not ready (would block)"
        );
        let n = buf.len().min(state.max_write);
        state.from_device.extend_from_slice(&buf[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> Result<(), Infallible> {
        panic!("the core must never call the blocking flush");
    }
}

impl embedded_io::WriteReady for Link {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.0.borrow().writable)
    }
}

/// A core over two simulated BNO055 (0x28, 0x29) on one bus.
pub type TwoRig = Rig<TwoSims>;

impl Rig<TwoSims> {
    /// `config` with the second sensor at 0x29.
    pub fn two(config: Config, t0_us: u64) -> Self {
        let time = SimTime::starting_at(t0_us);
        let bus = Bno055Bus::two(
            Bno055Sim::new(0x28, TimeSource(time.clone())),
            Bno055Sim::new(0x29, TimeSource(time.clone())),
        );
        let config = Config {
            second_address: Some(0x29),
            ..config
        };
        Self::over(bus, time, config)
    }
}

/// A core over a simulated bus (default: one BNO055 at 0x28), with its handles.
pub struct Rig<B = Sim> {
    pub core: Acquisition<SharedBus<B>, SimDelay, Link, SimTime>,
    pub time: SimTime,
    pub bus: Rc<RefCell<B>>,
    pub link: Link,
    pub host: Host,
}

impl Rig {
    pub fn new(config: Config, t0_us: u64, boot_busy: u32) -> Self {
        let time = SimTime::starting_at(t0_us);
        let sim = Bno055Sim::new(0x28, TimeSource(time.clone())).booting_for(boot_busy);
        Self::over(sim, time, config)
    }
}

impl<B: I2c<Error = robimu_bno055_sim::SimError>> Rig<B> {
    /// The core over `bus` at simulated time `time`.
    fn over(bus: B, time: SimTime, config: Config) -> Self {
        let bus = Rc::new(RefCell::new(bus));
        let link = Link::new();
        let delay = SimDelay {
            time: time.clone(),
            total_ns: Rc::new(Cell::new(0)),
        };
        let core = Acquisition::new(
            SharedBus(bus.clone()),
            delay,
            link.clone(),
            time.clone(),
            config,
        );
        Self {
            core,
            time,
            bus,
            link,
            host: Host::default(),
        }
    }

    /// Polls every `step_us` until `duration_us` of simulated time has passed,
    /// decoding the output as it goes.
    pub fn run(&mut self, duration_us: u64, step_us: u64) {
        let end = self.time.now() + duration_us;
        while self.time.now() < end {
            self.core.poll();
            self.host.receive(&self.link.take_sent());
            self.time.advance(step_us);
        }
    }

    pub fn poll(&mut self) {
        self.core.poll();
        self.host.receive(&self.link.take_sent());
    }
}

/// The host end: decodes every device frame.
#[derive(Default)]
pub struct Host {
    pub decoder: DeviceDecoder,
    pub messages: Vec<DeviceMessage>,
    pub raw: Vec<u8>,
}

impl Host {
    pub fn receive(&mut self, bytes: &[u8]) {
        self.raw.extend_from_slice(bytes);
        for outcome in self.decoder.feed(bytes) {
            self.messages.push(outcome.expect("device frames decode"));
        }
    }

    pub fn samples(&self) -> Vec<ImuSample> {
        self.messages
            .iter()
            .filter_map(|m| match m {
                DeviceMessage::Sample(s) => Some(*s),
                _ => None,
            })
            .collect()
    }

    pub fn take(&mut self) -> Vec<DeviceMessage> {
        std::mem::take(&mut self.messages)
    }
}
