//! The IMU board side of a recording: open the port, identify the board,
//! configure and start it, then stream in a thread that also pings the
//! board ten times a second for the clock mapping ([`super::clock_fit`]).
//!
//! A board that reboots mid-stream (it announces itself with `DeviceInfo`
//! and stops streaming) is configured and started again; samples after the
//! restart belong to a new clock *segment*, mapped by its own fit.

use std::collections::HashMap;
use std::io::ErrorKind;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use robimu_protocol::{
    CommandKind, DecoderStats, DeviceInfo, DeviceMessage, HostMessage, SensorConfig, Status,
};

use super::clock_fit::Echo;
use crate::link::{DeviceClock, LinkError, LinkReader, LinkWriter};

/// Why the IMU board could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ImuError {
    /// The port does not exist.
    #[error("no serial port {path}: is the IMU board plugged in? (check `ls /dev/ttyUSB* /dev/ttyACM*`)")]
    NotFound {
        /// The port path.
        path: String,
    },
    /// Another program holds the port.
    #[error("the serial port {path} is busy: another program has it open ({detail})")]
    Busy {
        /// The port path.
        path: String,
        /// What the system said.
        detail: String,
    },
    /// The port could not be opened for another reason.
    #[error("cannot open the serial port {path}: {detail}")]
    Open {
        /// The port path.
        path: String,
        /// What the system said.
        detail: String,
    },
    /// Nothing on the port speaks the robimu protocol.
    #[error("{path} is not a robimu IMU board: no DeviceInfo within {waited:?} ({bytes} bytes received, {frames} valid frames, {bad} bad frames)")]
    NotRobimu {
        /// The port path.
        path: String,
        /// How long we waited.
        waited: Duration,
        /// Bytes received meanwhile.
        bytes: u64,
        /// Valid frames decoded.
        frames: u64,
        /// Frames rejected.
        bad: u64,
    },
    /// The board refused or did not answer a command.
    #[error("the IMU board on {path} {what}")]
    Command {
        /// The port path.
        path: String,
        /// What happened.
        what: String,
    },
    /// The port failed while streaming (unplugged, closed).
    #[error("the serial port {path} failed while streaming (unplugged?): {detail}")]
    Vanished {
        /// The port path.
        path: String,
        /// What the system said.
        detail: String,
    },
}

/// What the streaming thread reports.
#[derive(Debug)]
pub enum ImuEvent {
    /// One sample in SI units.
    Sample {
        /// Clock segment (0 until the first restart).
        segment: u32,
        /// Device time, s (unwrapped, since the segment's boot).
        device: f64,
        /// Sequence number.
        seq: u32,
        /// `[ax, ay, az, gx, gy, gz]`, m/s² and rad/s.
        z: [f64; 6],
        /// Sensor temperature, °C (`temp_raw` × `temp_scale_c_per_lsb`).
        temp: f64,
    },
    /// One ping echo.
    Echo {
        /// Clock segment.
        segment: u32,
        /// The exchange.
        echo: Echo,
    },
    /// A health report.
    Status(Status),
    /// The board rebooted and was started again; a new segment begins.
    Restarted {
        /// The new segment.
        segment: u32,
    },
    /// Streaming failed; nothing follows.
    Failed(ImuError),
}

type Port = Box<dyn serialport::SerialPort>;

/// Host side of the link during set-up.
pub struct Link {
    path: String,
    reader: LinkReader<Port>,
    writer: LinkWriter<Port>,
}

impl Link {
    /// Opens `path` at `baud`, mapping the system's errors to [`ImuError`].
    pub fn open(path: &str, baud: u32) -> Result<Link, ImuError> {
        if !std::path::Path::new(path).exists() {
            return Err(ImuError::NotFound { path: path.into() });
        }
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(20))
            .open()
            .map_err(|e| open_error(path, e))?;
        let writer = port.try_clone().map_err(|e| open_error(path, e))?;
        Ok(Link {
            path: path.into(),
            reader: LinkReader::new(port),
            writer: LinkWriter::new(writer),
        })
    }

    fn poll(&mut self) -> Result<Option<DeviceMessage>, ImuError> {
        match self.reader.next_message() {
            Ok(m) => Ok(m),
            Err(LinkError::Read(e)) if e.kind() == ErrorKind::TimedOut => Ok(None),
            Err(e) => Err(ImuError::Vanished {
                path: self.path.clone(),
                detail: e.to_string(),
            }),
        }
    }

    fn send(&mut self, msg: &HostMessage) -> Result<(), ImuError> {
        self.writer.send(msg).map_err(|e| ImuError::Vanished {
            path: self.path.clone(),
            detail: e.to_string(),
        })
    }

    fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pick: impl FnMut(&DeviceMessage) -> Option<T>,
    ) -> Result<Option<T>, ImuError> {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if let Some(m) = self.poll()? {
                if let Some(t) = pick(&m) {
                    return Ok(Some(t));
                }
            }
        }
        Ok(None)
    }

    fn command(&mut self, msg: HostMessage, kind: CommandKind) -> Result<(), ImuError> {
        self.send(&msg)?;
        let result = self.wait_for(Duration::from_secs(3), |m| match m {
            DeviceMessage::CommandResult(r) if r.command == kind => Some(r.result),
            _ => None,
        })?;
        match result {
            Some(Ok(())) => Ok(()),
            Some(Err(e)) => Err(ImuError::Command {
                path: self.path.clone(),
                what: format!("refused {kind:?}: {e:?}"),
            }),
            None => Err(ImuError::Command {
                path: self.path.clone(),
                what: format!("did not answer {kind:?} within 3 s"),
            }),
        }
    }

    /// Asks for `DeviceInfo` (a board that is streaming is stopped first).
    pub fn identify(&mut self, timeout: Duration) -> Result<DeviceInfo, ImuError> {
        self.writer.resync().map_err(|e| ImuError::Vanished {
            path: self.path.clone(),
            detail: e.to_string(),
        })?;
        self.send(&HostMessage::Stop)?;
        self.send(&HostMessage::GetInfo)?;
        let info = self.wait_for(timeout, |m| match m {
            DeviceMessage::Info(i) => Some(*i),
            _ => None,
        })?;
        info.ok_or_else(|| {
            let s = self.reader.stats();
            ImuError::NotRobimu {
                path: self.path.clone(),
                waited: timeout,
                bytes: s.bytes_received,
                frames: s.frames_ok,
                bad: s.crc_errors
                    + s.cobs_errors
                    + s.version_errors
                    + s.too_long
                    + s.too_short
                    + s.deserialize_errors,
            }
        })
    }

    /// Configures the sensor; returns the `DeviceInfo` it reports after.
    pub fn configure(&mut self, config: SensorConfig) -> Result<Option<DeviceInfo>, ImuError> {
        self.command(HostMessage::Configure(config), CommandKind::Configure)?;
        self.wait_for(Duration::from_millis(500), |m| match m {
            DeviceMessage::Info(i) => Some(*i),
            _ => None,
        })
    }
}

fn open_error(path: &str, e: serialport::Error) -> ImuError {
    let detail = e.to_string();
    let lower = detail.to_lowercase();
    if lower.contains("busy") || lower.contains("exclusive") || lower.contains("locked") {
        ImuError::Busy {
            path: path.into(),
            detail,
        }
    } else if matches!(e.kind(), serialport::ErrorKind::NoDevice) || lower.contains("no such file")
    {
        ImuError::NotFound { path: path.into() }
    } else {
        ImuError::Open {
            path: path.into(),
            detail,
        }
    }
}

/// A streaming board: events arrive on [`ImuStream::events`].
pub struct ImuStream {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    rx: Receiver<ImuEvent>,
    stats: Arc<Mutex<DecoderStats>>,
}

impl ImuStream {
    /// Starts streaming on an identified, configured link; host times are
    /// seconds since `epoch`.
    pub fn start(
        mut link: Link,
        info: DeviceInfo,
        config: SensorConfig,
        epoch: Instant,
    ) -> Result<ImuStream, ImuError> {
        link.command(HostMessage::Start, CommandKind::Start)?;
        let (tx, rx) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(*link.reader.stats()));
        let (flag, shared_stats) = (Arc::clone(&stop), Arc::clone(&stats));
        let thread = thread::Builder::new()
            .name("robimu-imu".into())
            .spawn(move || stream(link, info, config, epoch, &tx, &flag, &shared_stats))
            .map_err(|e| ImuError::Command {
                path: String::new(),
                what: format!("cannot start the streaming thread: {e}"),
            })?;
        Ok(ImuStream {
            stop,
            thread: Some(thread),
            rx,
            stats,
        })
    }

    /// The events.
    pub fn events(&self) -> &Receiver<ImuEvent> {
        &self.rx
    }

    /// The link's decoder counters (bytes, frames, CRC errors, …).
    pub fn stats(&self) -> DecoderStats {
        *self.stats.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Stops the board and the thread; returns the events not yet read and
    /// the link's final decoder counters.
    pub fn stop(mut self) -> (Receiver<ImuEvent>, DecoderStats) {
        self.halt();
        let (_, empty) = mpsc::channel();
        (std::mem::replace(&mut self.rx, empty), self.stats())
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for ImuStream {
    fn drop(&mut self) {
        self.halt();
    }
}

/// The f64 an f32 scale stands for: its shortest decimal form (0.01f32
/// is 0.009999999776 as an f64; the board means 0.01).
fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// Seconds between pings.
const PING_PERIOD: Duration = Duration::from_millis(100);

fn stream(
    mut link: Link,
    mut info: DeviceInfo,
    config: SensorConfig,
    epoch: Instant,
    tx: &Sender<ImuEvent>,
    stop: &AtomicBool,
    stats: &Mutex<DecoderStats>,
) {
    let secs = |i: Instant| i.duration_since(epoch).as_secs_f64();
    let mut clock = DeviceClock::new();
    let mut segment = 0u32;
    let mut pending: HashMap<u32, Instant> = HashMap::new();
    let mut nonce = 0u32;
    let mut next_ping = Instant::now();
    // After a reboot: when we last asked the board to start again.
    let mut restarting: Option<Instant> = None;
    while !stop.load(Ordering::SeqCst) {
        let now = Instant::now();
        if now >= next_ping {
            next_ping = now + PING_PERIOD;
            nonce = nonce.wrapping_add(1);
            if let Err(e) = link.send(&HostMessage::Ping { nonce }) {
                let _ = tx.send(ImuEvent::Failed(e));
                return;
            }
            pending.insert(nonce, Instant::now());
            pending.retain(|_, sent| now.duration_since(*sent) < Duration::from_secs(2));
            *stats.lock().unwrap_or_else(|e| e.into_inner()) = *link.reader.stats();
        }
        let msg = match link.poll() {
            Ok(Some(m)) => m,
            Ok(None) => continue,
            Err(e) => {
                let _ = tx.send(ImuEvent::Failed(e));
                return;
            }
        };
        let received = Instant::now();
        let t_us = clock.observe(&msg);
        let event = match msg {
            DeviceMessage::Sample(s) => {
                let (a, g) = (
                    decimal(info.accel_scale_mps2_per_lsb),
                    decimal(info.gyro_scale_rads_per_lsb),
                );
                let z = [
                    f64::from(s.accel_raw[0]) * a,
                    f64::from(s.accel_raw[1]) * a,
                    f64::from(s.accel_raw[2]) * a,
                    f64::from(s.gyro_raw[0]) * g,
                    f64::from(s.gyro_raw[1]) * g,
                    f64::from(s.gyro_raw[2]) * g,
                ];
                ImuEvent::Sample {
                    segment,
                    device: t_us.unwrap_or_default() as f64 * 1e-6,
                    seq: s.seq,
                    z,
                    temp: f64::from(s.temp_raw) * decimal(info.temp_scale_c_per_lsb),
                }
            }
            DeviceMessage::Pong(p) => match pending.remove(&p.nonce) {
                Some(sent) => ImuEvent::Echo {
                    segment,
                    echo: Echo {
                        host_send: secs(sent),
                        host_recv: secs(received),
                        device: t_us.unwrap_or_default() as f64 * 1e-6,
                    },
                },
                None => continue,
            },
            DeviceMessage::Status(s) => {
                if !s.streaming && restarting.is_none_or(|t| t.elapsed() > Duration::from_secs(1)) {
                    // Rebooted (or stopped by someone else): start it again.
                    restarting = Some(Instant::now());
                    let _ = link.send(&HostMessage::Configure(config));
                    let _ = link.send(&HostMessage::Start);
                }
                ImuEvent::Status(s)
            }
            DeviceMessage::Info(i) => {
                info = i;
                // A board announces itself after boot: find out whether it
                // is still streaming.
                let _ = link.send(&HostMessage::GetStatus);
                continue;
            }
            DeviceMessage::CommandResult(r) => {
                if r.command == CommandKind::Start && r.result.is_ok() && restarting.is_some() {
                    restarting = None;
                    segment += 1;
                    clock.reset();
                    pending.clear();
                    ImuEvent::Restarted { segment }
                } else {
                    continue;
                }
            }
        };
        if tx.send(event).is_err() {
            break;
        }
    }
    let _ = link.send(&HostMessage::Stop);
    *stats.lock().unwrap_or_else(|e| e.into_inner()) = *link.reader.stats();
}
