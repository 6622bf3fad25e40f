//! The IMU board side of a recording: a board identified and configured
//! through its [`ImuClient`] is started and streamed in a thread that also
//! pings it ten times a second for the clock mapping ([`super::clock_fit`]).
//!
//! A board that reboots mid-stream (it announces itself with `DeviceInfo`
//! and stops streaming) is configured and started again; samples after the
//! restart belong to a new clock *segment*, mapped by its own fit.
//!
//! A board of several sensors (protocol 3) is one stream: its samples name
//! their sensor, and all share the board's clock, pings and segments.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use robimu_protocol::{
    CommandKind, DecoderStats, DeviceInfo, DeviceMessage, HostMessage, ImuSample, SensorConfig,
    Status,
};

use super::clock_fit::Echo;
use crate::client::{ClientError, ImuClient};
use crate::link::DeviceClock;

/// What the streaming thread reports.
#[derive(Debug)]
pub enum ImuEvent {
    /// One sample in SI units.
    Sample {
        /// Which of the board's sensors ([`ImuSample::sensor`]).
        sensor: u8,
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
    /// A health report (one per sensor, [`Status::sensor`]).
    Status(Status),
    /// The board rebooted and was started again; a new segment begins.
    Restarted {
        /// The new segment.
        segment: u32,
    },
    /// Streaming failed; nothing follows.
    Failed(ClientError),
}

/// A streaming board: events arrive on [`ImuStream::events`].
pub(crate) struct ImuStream {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    rx: Receiver<ImuEvent>,
    stats: Arc<Mutex<DecoderStats>>,
}

impl ImuStream {
    /// Starts streaming on an identified, configured board whose sensors
    /// `infos` describes (sensor 0 first); host times are seconds since `epoch`.
    pub fn start<R, W>(
        mut link: ImuClient<R, W>,
        infos: Vec<DeviceInfo>,
        config: SensorConfig,
        epoch: Instant,
    ) -> Result<ImuStream, ClientError>
    where
        R: Read + Send + 'static,
        W: Write + Send + 'static,
    {
        link.start()?;
        let (tx, rx) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stats = Arc::new(Mutex::new(*link.stats()));
        let (flag, shared_stats) = (Arc::clone(&stop), Arc::clone(&stats));
        let thread = thread::Builder::new()
            .name("robimu-imu".into())
            .spawn(move || stream(link, infos, config, epoch, &tx, &flag, &shared_stats))
            .map_err(|source| ClientError::Thread {
                path: String::new(),
                source,
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
pub(crate) fn decimal(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// A sample frame in SI units with the board's scales (`info`), at
/// unwrapped device time `t_us`, as [`ImuEvent::Sample`].
pub fn sample_event(info: &DeviceInfo, segment: u32, t_us: u64, s: &ImuSample) -> ImuEvent {
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
        sensor: s.sensor,
        segment,
        device: t_us as f64 * 1e-6,
        seq: s.seq,
        z,
        temp: f64::from(s.temp_raw) * decimal(info.temp_scale_c_per_lsb),
    }
}

/// Seconds between pings.
pub const PING_PERIOD: Duration = Duration::from_millis(100);

/// The streaming watchdog's limits for a board sampling at `rate_hz`:
/// (nothing at all from the board, no sample from it). A streaming board
/// sends a sample every period and answers every ping ([`PING_PERIOD`]),
/// so 1 s of nothing is ten unanswered pings; a board that answers but
/// sends no sample is given max(2 s, 20 sample periods), counted after a
/// reboot from the request to start it again. Either ends the recording
/// with [`ClientError::Silent`], keeping what was recorded.
pub(crate) fn silence_limits(rate_hz: f64) -> (Duration, Duration) {
    let period = if rate_hz > 0.0 { 1.0 / rate_hz } else { 1.0 };
    (
        Duration::from_secs(1),
        Duration::from_secs_f64((20.0 * period).max(2.0)),
    )
}

/// The board's watchdog ([`silence_limits`]): when it last sent anything,
/// and when a sample.
struct Watchdog {
    quiet: Duration,
    no_sample: Duration,
    heard: Instant,
    /// Also reset when samples are due again (a restart was requested).
    sampled: Instant,
}

impl Watchdog {
    fn new(rate_hz: f64) -> Self {
        let (quiet, no_sample) = silence_limits(rate_hz);
        let now = Instant::now();
        Self {
            quiet,
            no_sample,
            heard: now,
            sampled: now,
        }
    }

    /// A message arrived at `at` (`sample`: a sample).
    fn heard(&mut self, at: Instant, sample: bool) {
        self.heard = at;
        if sample {
            self.sampled = at;
        }
    }

    /// What the board has been silent about at `now` beyond its limit:
    /// (what, how long, the limit).
    fn silent(&self, now: Instant) -> Option<(&'static str, Duration, Duration)> {
        if now.duration_since(self.heard) > self.quiet {
            Some(("message", now.duration_since(self.heard), self.quiet))
        } else if now.duration_since(self.sampled) > self.no_sample {
            Some(("sample", now.duration_since(self.sampled), self.no_sample))
        } else {
            None
        }
    }
}

fn stream<R: Read, W: Write>(
    mut link: ImuClient<R, W>,
    mut infos: Vec<DeviceInfo>,
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
    let mut watchdog = Watchdog::new(f64::from(config.sample_rate_hz));
    while !stop.load(Ordering::SeqCst) {
        let now = Instant::now();
        if let Some((what, waited, limit)) = watchdog.silent(now) {
            let path = link.path().to_string();
            let e = ClientError::Silent {
                path,
                what,
                waited,
                limit,
            };
            let _ = tx.send(ImuEvent::Failed(e));
            return;
        }
        if now >= next_ping {
            next_ping = now + PING_PERIOD;
            nonce = nonce.wrapping_add(1);
            if let Err(e) = link.send(&HostMessage::Ping { nonce }) {
                let _ = tx.send(ImuEvent::Failed(e));
                return;
            }
            pending.insert(nonce, Instant::now());
            pending.retain(|_, sent| now.duration_since(*sent) < Duration::from_secs(2));
            *stats.lock().unwrap_or_else(|e| e.into_inner()) = *link.stats();
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
        watchdog.heard(received, matches!(msg, DeviceMessage::Sample(_)));
        let t_us = clock.observe(&msg);
        let event = match msg {
            DeviceMessage::Sample(s) => match infos.get(usize::from(s.sensor)) {
                Some(info) => sample_event(info, segment, t_us.unwrap_or_default(), &s),
                // a sensor the board did not announce at the start
                None => continue,
            },
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
                    // its samples are due again from this request on
                    watchdog.sampled = received;
                    let _ = link.send(&HostMessage::Configure(config));
                    let _ = link.send(&HostMessage::Start);
                }
                ImuEvent::Status(s)
            }
            DeviceMessage::Info(i) => {
                if let Some(info) = infos.get_mut(usize::from(i.sensor)) {
                    *info = i;
                }
                // A board announces itself after boot: find out whether it
                // is still streaming.
                let _ = link.send(&HostMessage::GetStatus);
                continue;
            }
            DeviceMessage::CommandResult(r) => {
                if r.command == CommandKind::Start && r.result.is_ok() && restarting.is_some() {
                    restarting = None;
                    watchdog.sampled = received;
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
    final_status(&mut link, infos.len(), tx);
    *stats.lock().unwrap_or_else(|e| e.into_inner()) = *link.stats();
}

/// How long a stopped board's last health reports are waited for.
const FINAL_STATUS_WAIT: Duration = Duration::from_millis(300);

/// After Stop: ask for the board's health reports once more and pass one
/// per sensor on, so that the drop counters of the recording's summary
/// cover its last second too (the periodic reports come about once a
/// second). Samples still in flight are not kept; a board that does not
/// answer within [`FINAL_STATUS_WAIT`] leaves its last periodic counts.
fn final_status<R: Read, W: Write>(
    link: &mut ImuClient<R, W>,
    sensors: usize,
    tx: &Sender<ImuEvent>,
) {
    if link.send(&HostMessage::GetStatus).is_err() {
        return;
    }
    let deadline = Instant::now() + FINAL_STATUS_WAIT;
    let mut seen = vec![false; sensors];
    while seen.iter().any(|s| !s) && Instant::now() < deadline {
        match link.poll() {
            Ok(Some(DeviceMessage::Status(s))) => {
                if let Some(k) = seen.get_mut(usize::from(s.sensor)) {
                    *k = true;
                    let _ = tx.send(ImuEvent::Status(s));
                }
            }
            Ok(_) => {}
            Err(_) => return,
        }
    }
}
