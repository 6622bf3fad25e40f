//! The rig's session without real time: [`record_offline`] records a plan
//! from the same simulated hardware as [`crate::rig::SimRig`] on a virtual
//! clock, as fast as the computer goes (docs/model.md §4.8).
//!
//! Shared with the real-time rig and `robimu record`: the IMU physics
//! ([`crate::physics::ModelSource`] with the config's noise, warm-up and
//! arm physics), the register-level BNO055 ([`Bno055Sim`], ideal or
//! datasheet chip), the firmware's acquisition core ([`Acquisition`]: its
//! schedule, sample reads, time stamps, `Status` and `Pong` frames), the
//! link's framing and decoding ([`LinkReader`], [`LinkWriter`]), the
//! controller's motion model ([`VirtualAubo`]: path buffer, tracking lag,
//! encoder noise), and the session writer with its clock fit
//! ([`SessionSink`], [`robimu_record::repair::remap_imu_times`]).
//!
//! Not shared: the threads, the pseudo-terminal and the TCP link (here a
//! byte buffer without latency or faults), the JSON-RPC driver (the plan
//! goes to the motion model as the driver would send it), and the timing
//! jitter of a real computer: the core is polled every
//! [`TwinOptions::poll_interval_s`] exactly, joints are read every
//! 1/[`TwinOptions::joint_rate`] exactly and stamped at that instant, and
//! pings are answered at the next poll. The board boots at virtual time 0
//! (the warm-up's power-up), the session's time 0 is when streaming starts.

use std::collections::{HashMap, VecDeque};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use embedded_hal::delay::DelayNs;
use robimu_bno055_sim::Bno055Sim;
use robimu_firmware::{Acquisition, Clock, Config};
use robimu_hil_sim::aubo::{TrueMotion, TrueState, VirtualAubo};
use robimu_protocol::{CommandKind, DeviceInfo, DeviceMessage, HostMessage, SensorConfig};
use robimu_record::clock_fit::Echo;
use robimu_record::imu::{sample_event, ImuEvent};
use robimu_record::link::{DeviceClock, LinkReader, LinkWriter};
use robimu_record::motion::Plan;
use robimu_record::{repair, SessionSink};
use robimu_session::{SessionError, SessionMeta, Truth};

use crate::physics::ModelSource;
use crate::rig::{aubo_config, check_joints, imu_source, RigError, SimRigConfig};

/// Why a virtual-time recording failed.
#[derive(Debug, thiserror::Error)]
pub enum TwinError {
    /// The simulated hardware is not valid.
    #[error(transparent)]
    Rig(#[from] RigError),
    /// The session could not be written.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The simulated controller refused the plan (an ARCS status code).
    #[error("the simulated controller refused the plan (status {0}); is it within the robot's limits and does it start at the initial pose?")]
    Refused(i64),
    /// The simulated board did not start streaming.
    #[error("the simulated IMU board did not start streaming: {0}")]
    Board(String),
    /// Bad options.
    #[error("bad twin options: {0}")]
    Options(String),
    /// The session writer refused a sample or an echo.
    #[error("cannot write the session: {0}")]
    Sink(String),
}

/// How to record, as `robimu record`'s options say it.
#[derive(Clone, Debug)]
pub struct TwinOptions {
    /// `robot = …` in session.toml.
    pub robot_name: String,
    /// Rest recorded before and after the motion, s.
    pub rest: f64,
    /// Joint polling rate, Hz.
    pub joint_rate: f64,
    /// The IMU settings sent to the board.
    pub sensor: SensorConfig,
    /// Virtual time between two polls of the firmware core, s (the
    /// real-time device thread sleeps 200 µs between polls).
    pub poll_interval_s: f64,
}

impl Default for TwinOptions {
    /// `aubo_i5`, 1 s rest, 125 Hz joints, the default sensor settings,
    /// polls every 200 µs.
    fn default() -> Self {
        Self {
            robot_name: "aubo_i5".into(),
            rest: 1.0,
            joint_rate: 125.0,
            sensor: SensorConfig::default(),
            poll_interval_s: 200e-6,
        }
    }
}

/// What a virtual-time recording produced.
#[derive(Clone, Debug)]
pub struct TwinSummary {
    /// The session directory.
    pub dir: PathBuf,
    /// Length, s.
    pub duration: f64,
    /// IMU samples written.
    pub imu_samples: u64,
    /// Joint samples written.
    pub joint_samples: u64,
    /// The board as it described itself.
    pub device: DeviceInfo,
    /// The hidden truth (τ = 0), as `truth.toml` lists it.
    pub truth: Truth,
    /// The board's power-up (the warm-up's time zero) before the session's
    /// time zero, s.
    pub powered_for_s: f64,
    /// The IMU samples' true session times minus the times the session
    /// gives them (its clock fit from the pings), at the session's middle,
    /// s: the clock mapping's own error, which τ absorbs (docs/model.md
    /// §4.8). A ping is answered at the next poll and its echo read there,
    /// so the echo's midpoint is half a poll interval early.
    pub imu_time_error_s: f64,
}

/// Virtual time, ns, shared by the board's clock, its delays and the arm.
#[derive(Clone, Default)]
struct VirtualTime(Arc<AtomicU64>);

impl VirtualTime {
    fn seconds(&self) -> f64 {
        self.0.load(Ordering::Relaxed) as f64 * 1e-9
    }

    fn advance_ns(&self, ns: u64) {
        self.0.fetch_add(ns, Ordering::Relaxed);
    }
}

/// The board's clock on virtual time: `offset + (1 + drift·10⁻⁶)·t`, µs.
struct VirtualClock {
    time: VirtualTime,
    offset_us: u64,
    drift_ppm: f64,
}

impl Clock for VirtualClock {
    fn now_us(&mut self) -> u32 {
        let t_us = self.time.seconds() * 1e6 * (1.0 + self.drift_ppm * 1e-6);
        (self.offset_us + t_us as u64) as u32
    }
}

/// `DelayNs` that advances virtual time.
struct VirtualDelay(VirtualTime);

impl DelayNs for VirtualDelay {
    fn delay_ns(&mut self, ns: u32) {
        self.0.advance_ns(u64::from(ns));
    }
}

/// The two directions of the link.
#[derive(Default)]
struct Pipe {
    to_device: VecDeque<u8>,
    to_host: VecDeque<u8>,
}

/// One end of the in-memory link.
#[derive(Clone, Default)]
struct End(Arc<Mutex<Pipe>>);

impl End {
    fn lock(&self) -> MutexGuard<'_, Pipe> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

fn drain(from: &mut VecDeque<u8>, buf: &mut [u8]) -> usize {
    let n = buf.len().min(from.len());
    for (b, v) in buf.iter_mut().zip(from.drain(..n)) {
        *b = v;
    }
    n
}

impl embedded_io::ErrorType for End {
    type Error = core::convert::Infallible;
}

impl embedded_io::Read for End {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        Ok(drain(&mut self.lock().to_device, buf))
    }
}

impl embedded_io::ReadReady for End {
    fn read_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(!self.lock().to_device.is_empty())
    }
}

impl embedded_io::Write for End {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        self.lock().to_host.extend(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

impl embedded_io::WriteReady for End {
    fn write_ready(&mut self) -> Result<bool, Self::Error> {
        Ok(true)
    }
}

/// The host's side of the link: reads what the board sent, writes to it.
struct HostEnd(End);

impl io::Read for HostEnd {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        Ok(drain(&mut self.0.lock().to_host, buf))
    }
}

impl io::Write for HostEnd {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.lock().to_device.extend(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// The arm's true motion at the current virtual time.
struct VirtualMotion {
    arm: Arc<Mutex<VirtualAubo>>,
    time: VirtualTime,
}

impl VirtualMotion {
    fn arm(&self) -> MutexGuard<'_, VirtualAubo> {
        self.arm.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl TrueMotion for VirtualMotion {
    fn now(&self) -> TrueState {
        let t = self.time.seconds();
        self.arm().state_at(t)
    }
}

type Core = Acquisition<Bno055Sim<ModelSource>, VirtualDelay, End, VirtualClock>;

/// The simulated board and the host's link to it.
struct Board {
    core: Core,
    reader: LinkReader<HostEnd>,
    writer: LinkWriter<HostEnd>,
    clock: DeviceClock,
    time: VirtualTime,
    poll_ns: u64,
}

impl Board {
    /// One poll interval: runs the chip's clocks and the core.
    fn step(&mut self) {
        self.time.advance_ns(self.poll_ns);
        self.core.bus_mut().advance();
        self.core.poll();
    }

    fn send(&mut self, msg: &HostMessage) {
        // The in-memory link does not fail.
        let _ = self.writer.send(msg);
    }

    fn next_message(&mut self) -> Option<DeviceMessage> {
        self.reader.next_message().ok().flatten()
    }

    /// Sends the commands `robimu record` sends (stop, info, configure,
    /// start) and polls until streaming starts; returns the board's last
    /// `DeviceInfo`.
    fn start(&mut self, sensor: SensorConfig) -> Result<DeviceInfo, TwinError> {
        let _ = self.writer.resync();
        self.send(&HostMessage::Stop);
        self.send(&HostMessage::GetInfo);
        self.send(&HostMessage::Configure(sensor));
        self.send(&HostMessage::Start);
        let mut info = None;
        // Configuring takes about 40 ms of the chip's mode switches.
        for _ in 0..100_000 {
            self.step();
            while let Some(msg) = self.next_message() {
                match msg {
                    DeviceMessage::Info(i) => info = Some(i),
                    DeviceMessage::CommandResult(r) if r.command == CommandKind::Start => {
                        r.result
                            .map_err(|e| TwinError::Board(format!("Start refused: {e:?}")))?;
                        return info.ok_or_else(|| {
                            TwinError::Board("no DeviceInfo before streaming".into())
                        });
                    }
                    DeviceMessage::CommandResult(r) if r.result.is_err() => {
                        return Err(TwinError::Board(format!(
                            "{:?} refused: {:?}",
                            r.command, r.result
                        )));
                    }
                    _ => {}
                }
            }
        }
        Err(TwinError::Board("no answer to Start".into()))
    }
}

/// Records `plan` from the rig `config` describes (AUBO controller, IMU
/// board; the arm starts at `config.initial`, which should be the plan's
/// first pose) into the session directory `dir` on a virtual clock, and
/// writes the hidden truth beside it (`truth.toml`).
///
/// # Errors
///
/// [`TwinError`]: a rig that cannot be built, a plan the controller
/// refuses, a session that cannot be written.
pub fn record_offline(
    config: &SimRigConfig,
    plan: &Plan,
    dir: &Path,
    opts: &TwinOptions,
) -> Result<TwinSummary, TwinError> {
    check_joints(&config.robot)?;
    check_options(opts)?;
    let time = VirtualTime::default();
    let arm = Arc::new(Mutex::new(VirtualAubo::new(&aubo_config(config))));
    let (mut board, truth) = boot_board(config, opts, &time, &arm)?;
    let info = board.start(opts.sensor)?;

    let mut meta = SessionMeta::new(opts.robot_name.clone());
    meta.imu = Some(robimu_record::device_table(&info, "virtual"));
    meta.notes = Some(format!(
        "recorded in virtual time by robimu {} from the simulated rig (robimu_hil::twin)",
        env!("CARGO_PKG_VERSION")
    ));
    let sink = SessionSink::create(dir, &meta, config.robot.dof())?;

    // Session time 0: streaming starts.
    let epoch = time.seconds();
    let mut run = OfflineRun {
        config,
        opts,
        info,
        time,
        epoch,
        sink,
        pending: HashMap::new(),
        nonce: 0,
        imu_samples: 0,
    };
    run.play(&mut board, &arm, plan)?;
    board.send(&HostMessage::Stop);
    run.finish(truth)
}

/// Checks the poll interval, the joint rate and the rest.
fn check_options(opts: &TwinOptions) -> Result<(), TwinError> {
    if !(opts.poll_interval_s > 0.0 && opts.poll_interval_s <= 0.01) {
        return Err(TwinError::Options(format!(
            "poll interval {} s is not in (0, 0.01]",
            opts.poll_interval_s
        )));
    }
    if !(opts.joint_rate > 0.0 && opts.joint_rate.is_finite() && opts.rest >= 0.0) {
        return Err(TwinError::Options(format!(
            "joint rate {} Hz and rest {} s must be positive",
            opts.joint_rate, opts.rest
        )));
    }
    Ok(())
}

/// Builds the board on the virtual clock `time` (its chip sensing the
/// motion of `arm` and the hidden truth, returned) and boots it.
fn boot_board(
    config: &SimRigConfig,
    opts: &TwinOptions,
    time: &VirtualTime,
    arm: &Arc<Mutex<VirtualAubo>>,
) -> Result<(Board, Truth), TwinError> {
    let motion = VirtualMotion {
        arm: Arc::clone(arm),
        time: time.clone(),
    };
    let (source, truth) = imu_source(config, Box::new(motion))?;
    let firmware = Config::default();
    let chip = Bno055Sim::new(firmware.i2c_address, source)
        .with_model(config.chip)
        .with_clock_error_ppm(config.chip_clock_error_ppm);
    let end = End::default();
    let clock = VirtualClock {
        time: time.clone(),
        offset_us: config.clock_offset_us,
        drift_ppm: config.clock_drift_ppm,
    };
    let core = Acquisition::new(
        chip,
        VirtualDelay(time.clone()),
        end.clone(),
        clock,
        firmware,
    );
    let mut board = Board {
        core,
        reader: LinkReader::new(HostEnd(end.clone())),
        writer: LinkWriter::new(HostEnd(end)),
        clock: DeviceClock::new(),
        time: time.clone(),
        poll_ns: (opts.poll_interval_s * 1e9).round() as u64,
    };
    board
        .core
        .start()
        .map_err(|e| TwinError::Board(format!("boot failed: {e:?}")))?;
    Ok((board, truth))
}

/// A recording in virtual time: the session being written and the pings
/// in flight.
struct OfflineRun<'a> {
    config: &'a SimRigConfig,
    opts: &'a TwinOptions,
    /// The board's sensor.
    info: DeviceInfo,
    time: VirtualTime,
    /// The virtual time (s) of session time 0.
    epoch: f64,
    sink: SessionSink,
    /// Session time each ping in flight was sent at.
    pending: HashMap<u32, f64>,
    nonce: u32,
    imu_samples: u64,
}

impl OfflineRun<'_> {
    /// Session time now.
    fn session_t(&self) -> f64 {
        self.time.seconds() - self.epoch
    }

    /// The loop: pings, board steps, IMU messages and joint samples until
    /// `rest` after the plan (sent after `rest`) ends.
    fn play(
        &mut self,
        board: &mut Board,
        arm: &Mutex<VirtualAubo>,
        plan: &Plan,
    ) -> Result<(), TwinError> {
        let (opts, robot) = (self.opts, &self.config.robot);
        let joint_period = 1.0 / opts.joint_rate;
        let ping_period = robimu_record::imu::PING_PERIOD.as_secs_f64();
        let (mut next_joint, mut next_ping) = (0.0, 0.0);
        let mut plan_sent = false;
        let mut stop_at: Option<f64> = None;
        let limit = plan.duration() + 2.0 * opts.rest + 60.0;
        let (a, v) = robimu_record::motion::path_limits(robot);
        loop {
            let t = self.session_t();
            if stop_at.is_some_and(|s| t >= s) {
                return Ok(());
            }
            if t > limit {
                return Err(TwinError::Board(format!(
                    "the plan did not end within {limit:.0} s"
                )));
            }
            if t >= next_ping {
                next_ping += ping_period;
                self.nonce = self.nonce.wrapping_add(1);
                board.send(&HostMessage::Ping { nonce: self.nonce });
                self.pending.insert(self.nonce, t);
            }
            board.step();
            let t = self.session_t();
            self.take_messages(board, t)?;
            let now = self.time.seconds();
            let mut arm = arm.lock().unwrap_or_else(|e| e.into_inner());
            while next_joint <= t {
                let q = arm.joint_positions(now);
                self.sink.joint(t, &q[..robot.dof()])?;
                next_joint += joint_period;
            }
            if !plan_sent && t >= opts.rest {
                plan_sent = true;
                arm.play_path(now, &plan.q, plan.dt, a, v)
                    .map_err(TwinError::Refused)?;
            } else if plan_sent && stop_at.is_none() && arm.idle_at(now) {
                stop_at = Some(t + opts.rest);
            }
        }
    }

    /// Writes what the board sent (samples, ping echoes received at
    /// session time `t`, status).
    fn take_messages(&mut self, board: &mut Board, t: f64) -> Result<(), TwinError> {
        while let Some(msg) = board.next_message() {
            let t_us = board.clock.observe(&msg);
            match msg {
                DeviceMessage::Sample(s) => {
                    self.imu_samples += 1;
                    let ev = sample_event(&self.info, 0, t_us.unwrap_or_default(), &s);
                    self.sink.handle(ev).map_err(TwinError::Sink)?;
                }
                DeviceMessage::Pong(p) => {
                    if let Some(sent) = self.pending.remove(&p.nonce) {
                        let echo = Echo {
                            host_send: sent,
                            host_recv: t,
                            device: t_us.unwrap_or_default() as f64 * 1e-6,
                        };
                        self.sink
                            .handle(ImuEvent::Echo { segment: 0, echo })
                            .map_err(TwinError::Sink)?;
                    }
                }
                DeviceMessage::Status(s) => {
                    self.sink
                        .handle(ImuEvent::Status(s))
                        .map_err(TwinError::Sink)?;
                }
                DeviceMessage::Info(_) | DeviceMessage::CommandResult(_) => {}
            }
        }
        Ok(())
    }

    /// Closes the session, maps its IMU times by the final clock fit and
    /// writes the hidden `truth` beside it.
    fn finish(self, truth: Truth) -> Result<TwinSummary, TwinError> {
        let (config, epoch) = (self.config, self.epoch);
        let duration = self.session_t();
        let joint_samples = self.sink.progress.joint_samples;
        let dir = self.sink.finish()?;
        let (clock, _) = repair::remap_imu_times(&dir)?;
        robimu_record::write_clock_notes(&dir, &clock)?;
        // the board's clock at the session's middle, and the time the fit gives it
        let middle = epoch + duration / 2.0;
        let device =
            config.clock_offset_us as f64 * 1e-6 + middle * (1.0 + config.clock_drift_ppm * 1e-6);
        let imu_time_error_s = crate::truth::clock_mapping_error(&clock, duration / 2.0, device);
        let truth_path = dir.join(robimu_session::files::TRUTH);
        std::fs::write(&truth_path, truth.to_toml())
            .map_err(|e| SessionError::io(&truth_path, e))?;
        Ok(TwinSummary {
            dir,
            duration,
            imu_samples: self.imu_samples,
            joint_samples,
            device: self.info,
            truth,
            powered_for_s: epoch,
            imu_time_error_s,
        })
    }
}
