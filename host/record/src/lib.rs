//! Recording a session from an IMU board and a robot (`robimu record`).
//!
//! The board ([`client`]) streams in one thread ([`imu`]), the robot's joint positions
//! are polled in another ([`crate::controller::aubo::JointPoller`]), the plan
//! runs in a third ([`motion`]); this module's loop writes what arrives into
//! the session directory (docs/model.md §7) and flushes it every second, so a
//! crash or a kill loses at most the last second. Session time is the host's
//! monotonic clock from the start of the recording; IMU samples are placed
//! on it by a robust fit of the board's clock against ping echoes
//! ([`clock_fit`]), refined while recording and made final at the end
//! ([`repair::remap_imu_times`], which `robimu repair` also runs).
//!
//! Files besides those of docs/model.md §7: `imu.csv` has the extra columns `t_device`
//! (s, the board's clock), `segment` (clock segment: a board reboot starts
//! a new one), `seq` and `temp_c` (the sensor's temperature, °C, read back
//! by [`robimu_session::Session`]); `pings.csv` logs every echo. From a
//! controller with a clock (UR), `joints.csv` has the extra columns
//! `t_robot` (s, the controller's timestamp) and `t_arrival` (s, session
//! time of arrival); at the end `t` is recomputed from `t_robot`
//! ([`robot_clock`], [`repair::remap_joint_times`]).
//!
//! **Several IMUs** (docs/model.md §9): a board may read two sensors
//! (protocol 3), and more boards may be given
//! ([`RecordOptions::extra_imu_ports`]). IMUs are numbered board by board,
//! each board's sensors in order: IMU 0 is `imu.csv`, IMU j ≥ 1 is
//! `imu<j>.csv` with an `[imu<j>]` table (its port, `board`, `sensor` and
//! `pings`, the ping log of its board). Each board has its own streaming
//! thread, ping log (`pings.csv`, `pings1.csv`, …) and clock fit; its
//! sensors share them. A board that fails ends the recording with its
//! error, keeping every board's data, as for one.
//!
//! **Watchdogs**: a board that goes silent without an I/O error (nothing
//! for 1 s, or no sample for max(2 s, 20 sample periods): [`imu`],
//! [`client::ClientError::Silent`]) and a robot controller whose connection
//! stays open but sends no joint sample for max(1 s, 20 sample periods)
//! ([`arm::ArmError::Silent`]) each end the recording with that error,
//! keeping what was recorded.
//!
//! Main types: [`RecordOptions`] (the board's port, the robot controller
//! ([`controller::RobotSpec`]), the plan ([`motion::Plan`]), the session
//! directory), [`record`] itself, [`RecordSummary`] (what was recorded, the
//! link's error counters, the clock fits) and [`RecordError`] (an aborted
//! recording keeps what it wrote).
//!
//! # Example
//!
//! A minute at rest from an AUBO arm and a board on a USB serial port (needs
//! the hardware; `robimu_hil::rig` simulates both for tests):
//!
//! ```no_run
//! use robimu_model::Robot;
//! use robimu_protocol::SensorConfig;
//! use robimu_record::controller::RobotSpec;
//! use robimu_record::{record, RecordOptions};
//!
//! let opts = RecordOptions {
//!     imu_port: "/dev/ttyACM0".into(),
//!     extra_imu_ports: Vec::new(),
//!     baud: 921_600,
//!     robot_spec: RobotSpec::parse("aubo:192.168.1.10")?,
//!     robot: Robot::aubo_i5(),
//!     robot_name: "aubo_i5".into(),
//!     plan: None, // record without moving the arm …
//!     duration: 60.0, // … for a minute
//!     out: "session".into(),
//!     joint_rate: 125.0,
//!     rest: 1.0,
//!     sensor: SensorConfig::default(),
//!     interrupt: None,
//! };
//! let summary = record(&opts, &mut |p| {
//!     eprint!("\r{:.0} of {:.0} s, {} IMU samples", p.elapsed, p.total, p.imu_samples)
//! })?;
//! println!("{:.1} s recorded into {}", summary.duration, summary.dir.display());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]

pub mod arm;
pub mod client;
pub mod clock_fit;
pub mod controller;
pub mod imu;
pub mod link;
pub mod motion;
pub mod repair;
pub mod robot_clock;

pub use crate::client::ImuClient;
pub use crate::controller::ur::Recipe;
pub use crate::controller::ur::UrSample;
pub use crate::controller::RobotSpecError;
pub use crate::motion::MotionPlanError;
pub use crate::robot_clock::Remapped;
pub use crate::robot_clock::RobotClockFit;

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::time::{Duration, Instant};

use robimu_protocol::{DecoderStats, DeviceInfo, SensorConfig};

use self::arm::Arm;
pub use self::arm::{ArmError, ArmRun};
use self::client::ClientError;
use self::clock_fit::{ClockFit, Echo};
use self::imu::{ImuEvent, ImuStream};
use self::motion::Plan;
use crate::controller::{JointSample, RobotSpec};
use robimu_model::Robot;
use robimu_session::{ImuTiming, SessionError, SessionMeta, SessionWriter};

/// What to record.
#[derive(Clone, Debug)]
pub struct RecordOptions {
    /// The IMU board's serial port.
    pub imu_port: String,
    /// More IMU boards' serial ports (docs/model.md §9: their sensors are
    /// the IMUs after those of `imu_port`'s board, in this order).
    pub extra_imu_ports: Vec<String>,
    /// Its baud rate.
    pub baud: u32,
    /// The robot controller.
    pub robot_spec: RobotSpec,
    /// The robot's description (limits, joint count).
    pub robot: Robot,
    /// `robot = …` in session.toml (a built-in name or a path).
    pub robot_name: String,
    /// The plan to execute; `None` records without moving the arm.
    pub plan: Option<Plan>,
    /// Without a plan: how long to record, s.
    pub duration: f64,
    /// The session directory.
    pub out: PathBuf,
    /// Joint polling rate, Hz.
    pub joint_rate: f64,
    /// Rest recorded before and after the motion, s.
    pub rest: f64,
    /// The IMU settings.
    pub sensor: SensorConfig,
    /// Set (e.g. by a Ctrl-C handler) to stop the recording early: the plan
    /// is halted and everything recorded is finished as at a normal end.
    pub interrupt: Option<Arc<AtomicBool>>,
}

/// Live figures for a progress display.
#[derive(Clone, Debug, Default)]
pub struct RecordProgress {
    /// Seconds since the recording started.
    pub elapsed: f64,
    /// Expected length, s.
    pub total: f64,
    /// IMU samples written.
    pub imu_samples: u64,
    /// Joint samples written.
    pub joint_samples: u64,
    /// IMU samples per second over the last second.
    pub imu_rate: f64,
    /// Samples missing by sequence number.
    pub seq_gaps: u64,
    /// Frames that failed their CRC.
    pub crc_errors: u64,
    /// Other rejected frames.
    pub bad_frames: u64,
    /// Board reboots recovered.
    pub restarts: u32,
    /// Samples the board reports it dropped (all sensors of all boards).
    pub device_dropped: u32,
    /// The same figures per IMU (docs/model.md §9), IMU 0 first.
    pub imus: Vec<ImuProgress>,
}

/// One IMU's live figures: one progress line each.
#[derive(Clone, Debug, Default)]
pub struct ImuProgress {
    /// Its board's serial port.
    pub port: String,
    /// Which of the board's sensors.
    pub sensor: u8,
    /// Samples written.
    pub samples: u64,
    /// Samples per second over the last second.
    pub rate: f64,
    /// Samples missing by sequence number.
    pub seq_gaps: u64,
    /// Samples the board reports it dropped for this sensor.
    pub device_dropped: u32,
}

impl RecordProgress {
    /// Takes the error counters of every board's link, summed.
    fn set_links(&mut self, stats: &[DecoderStats]) {
        self.crc_errors = stats.iter().map(|s| s.crc_errors).sum();
        self.bad_frames = stats.iter().map(|s| s.errors() - s.crc_errors).sum();
    }
}

/// What a recording produced.
#[derive(Clone, Debug)]
pub struct RecordSummary {
    /// The session directory.
    pub dir: PathBuf,
    /// Length, s.
    pub duration: f64,
    /// The final counters.
    pub progress: RecordProgress,
    /// Link decoder counters.
    pub link: DecoderStats,
    /// The board.
    pub device: DeviceInfo,
    /// Final clock fit per segment.
    pub clock: Vec<(u32, ClockFit)>,
    /// Every board (the first is the one of `device`, `link` and `clock`).
    pub boards: Vec<BoardSummary>,
    /// The joint times' mapping from the controller's clock (UR); `None`
    /// for a controller without one (AUBO: arrival times).
    pub joint_clock: Option<repair::JointClock>,
    /// The host instant of the session's time 0 (streaming starts).
    pub epoch: Instant,
}

/// One board of a recording.
#[derive(Clone, Debug)]
pub struct BoardSummary {
    /// Its serial port.
    pub port: String,
    /// Its sensors, sensor 0 first.
    pub devices: Vec<DeviceInfo>,
    /// The IMU number of its sensor 0 (docs/model.md §9).
    pub first_imu: usize,
    /// Its link's decoder counters.
    pub link: DecoderStats,
    /// Its final clock fit per segment.
    pub clock: Vec<(u32, ClockFit)>,
}

/// Why a recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The IMU board could not be set up (nothing recorded).
    #[error(transparent)]
    Imu(#[from] ClientError),
    /// The robot could not be set up (nothing recorded).
    #[error(transparent)]
    Robot(#[from] ArmError),
    /// The session could not be written.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The recording stopped early; what was recorded is on disk.
    #[error("recording stopped after {:.1} s: {cause}; the {} IMU and {} joint samples recorded are kept in {}", summary.duration, summary.progress.imu_samples, summary.progress.joint_samples, summary.dir.display())]
    Aborted {
        /// What stopped it.
        cause: String,
        /// What was kept.
        summary: Box<RecordSummary>,
    },
}

/// Records a session. `progress` is called about five times a second.
pub fn record(
    opts: &RecordOptions,
    progress: &mut dyn FnMut(&RecordProgress),
) -> Result<RecordSummary, RecordError> {
    // Set-up: everything that can fail before a file is written.
    let ports: Vec<&str> = std::iter::once(opts.imu_port.as_str())
        .chain(opts.extra_imu_ports.iter().map(String::as_str))
        .collect();
    let (boards, arm) = connect(opts, &ports)?;
    let (state, summaries) = create_session(opts, &ports, &boards)?;
    let mut recording = Recording::start(opts, &ports, boards, arm, state)?;
    let mut cause = recording.run(progress)?;
    // Stopping early: halt the plan first.
    if let Some(c) = cause.as_mut().filter(|_| recording.arm.moving()) {
        match recording.arm.halt() {
            Ok(()) => c.push_str("; the robot was stopped"),
            Err(e) => c.push_str(&format!(
                "; COULD NOT STOP THE ROBOT ({e}): stop it at the controller"
            )),
        }
    }
    recording.wind_down(summaries, cause, progress)
}

/// An opened board, its sensors configured (their infos, sensor 0 first).
type Board = (ImuClient, Vec<DeviceInfo>);

/// Opens, identifies and configures every board (its sensors' infos beside
/// it), connects to the robot and prepares the plan.
fn connect(opts: &RecordOptions, ports: &[&str]) -> Result<(Vec<Board>, Arm), RecordError> {
    let mut boards = Vec::with_capacity(ports.len());
    for port in ports {
        let mut board = ImuClient::open(port, opts.baud)?;
        board.identify(Duration::from_secs(3))?;
        let infos = board.configure_sensors(&opts.sensor)?;
        boards.push((board, infos));
    }
    let mut arm = Arm::connect(&opts.robot_spec)?;
    if let Some(plan) = &opts.plan {
        arm.prepare(&opts.robot, plan)?;
    }
    Ok((boards, arm))
}

/// Creates the session directory and every board's summary (its IMUs'
/// progress lines named by port and sensor).
fn create_session(
    opts: &RecordOptions,
    ports: &[&str],
    boards: &[Board],
) -> Result<(SessionSink, Vec<BoardSummary>), RecordError> {
    let sensors: Vec<usize> = boards.iter().map(|(_, i)| i.len()).collect();
    let meta = session_meta(opts, ports, boards);
    let n = opts.robot.dof();
    let controller_clock = matches!(opts.robot_spec, RobotSpec::Ur { .. });
    let mut state = SessionSink::create_boards(&opts.out, &meta, n, controller_clock, &sensors)?;
    let mut summaries = Vec::with_capacity(boards.len());
    for (b, (_, infos)) in boards.iter().enumerate() {
        let first_imu = sensors[..b].iter().sum::<usize>();
        for (k, _) in infos.iter().enumerate() {
            let p = &mut state.progress.imus[first_imu + k];
            p.port = ports[b].to_string();
            p.sensor = k as u8;
        }
        summaries.push(BoardSummary {
            port: ports[b].to_string(),
            devices: infos.clone(),
            first_imu,
            link: DecoderStats::default(),
            clock: Vec::new(),
        });
    }
    Ok((state, summaries))
}

/// A recording under way: the streams, the robot, the session being
/// written and the loop's clocks.
struct Recording<'a> {
    opts: &'a RecordOptions,
    ports: &'a [&'a str],
    /// Every board's streaming thread.
    streams: Vec<ImuStream>,
    /// The joint poller and the plan.
    arm: ArmRun,
    /// The session being written.
    state: SessionSink,
    /// The host instant of session time 0.
    epoch: Instant,
    /// When the recording ends: set at the start without a plan, `rest`
    /// after the motion with one.
    stop_at: Option<Instant>,
    /// When the files are flushed next.
    next_flush: Instant,
    /// When `progress` is called next.
    next_show: Instant,
    /// The start of the sample-rate window and every IMU's count then.
    rate_window: (Instant, Vec<u64>),
}

impl<'a> Recording<'a> {
    /// Starts the session clock, every board's stream and the robot's
    /// poller (and, after the rest, the plan).
    fn start(
        opts: &'a RecordOptions,
        ports: &'a [&'a str],
        boards: Vec<Board>,
        arm: Arm,
        mut state: SessionSink,
    ) -> Result<Self, RecordError> {
        let epoch = Instant::now();
        let mut streams = Vec::with_capacity(boards.len());
        for (board, infos) in boards {
            streams.push(ImuStream::start(board, infos, opts.sensor, epoch)?);
        }
        let motion = opts.plan.as_ref().map(|p| p.duration());
        let arm = arm.start(
            &opts.robot,
            opts.plan.clone(),
            opts.joint_rate,
            epoch,
            opts.rest,
            &opts.robot_spec,
        )?;
        let total = motion.map_or(opts.duration, |d| d + 2.0 * opts.rest);

        state.progress.total = total;
        let stop_at = if motion.is_none() {
            Some(epoch + Duration::from_secs_f64(opts.duration))
        } else {
            None
        };
        let next_flush = Instant::now() + Duration::from_secs(1);
        let next_show = Instant::now();
        let rate_window = (Instant::now(), vec![0u64; state.progress.imus.len()]);
        Ok(Self {
            opts,
            ports,
            streams,
            arm,
            state,
            epoch,
            stop_at,
            next_flush,
            next_show,
            rate_window,
        })
    }

    /// The loop: writes what arrives until the end, an interrupt or a
    /// failure (its cause).
    fn run(
        &mut self,
        progress: &mut dyn FnMut(&RecordProgress),
    ) -> Result<Option<String>, RecordError> {
        let mut cause: Option<String> = None;
        while cause.is_none() {
            let now = Instant::now();
            if self.stop_at.is_some_and(|t| now >= t) {
                break;
            }
            if self
                .opts
                .interrupt
                .as_ref()
                .is_some_and(|f| f.load(Ordering::Relaxed))
            {
                cause = Some("interrupted (Ctrl-C)".into());
                break;
            }
            self.take_imu_events(&mut cause);
            self.take_joint_samples(&mut cause)?;
            if self.stop_at.is_none() {
                match self.arm.motion_done() {
                    Ok(true) => {
                        self.stop_at =
                            Some(Instant::now() + Duration::from_secs_f64(self.opts.rest))
                    }
                    Ok(false) => {}
                    Err(e) => cause = Some(e),
                }
            }
            if now >= self.next_flush {
                self.next_flush = now + Duration::from_secs(1);
                self.state.flush()?;
            }
            if now >= self.next_show {
                self.next_show = now + Duration::from_millis(200);
                self.show_progress(now, progress);
            }
        }
        Ok(cause)
    }

    /// Waits on the first board, then takes what every board has.
    fn take_imu_events(&mut self, cause: &mut Option<String>) {
        match self.streams[0]
            .events()
            .recv_timeout(Duration::from_millis(10))
        {
            Ok(ev) => {
                if let Err(c) = self.state.handle_from(0, ev) {
                    *cause = Some(c);
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                *cause = Some(format!(
                    "the IMU streaming thread of {} ended",
                    self.ports[0]
                ));
            }
        }
        for (b, stream) in self.streams.iter().enumerate() {
            while cause.is_none() {
                match stream.events().try_recv() {
                    Ok(ev) => {
                        if let Err(c) = self.state.handle_from(b, ev) {
                            *cause = Some(c);
                        }
                    }
                    Err(std::sync::mpsc::TryRecvError::Empty) => break,
                    Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                        *cause = Some(format!(
                            "the IMU streaming thread of {} ended",
                            self.ports[b]
                        ));
                    }
                }
            }
        }
    }

    /// Writes the joint samples polled so far.
    fn take_joint_samples(&mut self, cause: &mut Option<String>) -> Result<(), RecordError> {
        while let Some(sample) = self.arm.try_sample() {
            match sample {
                Ok(s) => self.state.joint_sample(&s, self.opts.robot.dof())?,
                Err(e) => {
                    *cause = Some(format!("the robot connection failed: {e}"));
                    break;
                }
            }
        }
        if cause.is_none() {
            *cause = self.arm.silence().map(|e| e.to_string());
        }
        Ok(())
    }

    /// Updates the live figures (elapsed time, link counters, sample rates
    /// over the last second) and shows them.
    fn show_progress(&mut self, now: Instant, progress: &mut dyn FnMut(&RecordProgress)) {
        let state = &mut self.state;
        state.progress.elapsed = self.epoch.elapsed().as_secs_f64();
        let stats: Vec<DecoderStats> = self.streams.iter().map(ImuStream::stats).collect();
        state.progress.set_links(&stats);
        let dt = self.rate_window.0.elapsed().as_secs_f64();
        if dt >= 1.0 {
            let counts: Vec<u64> = state.progress.imus.iter().map(|p| p.samples).collect();
            for ((p, now_n), then_n) in state
                .progress
                .imus
                .iter_mut()
                .zip(&counts)
                .zip(&self.rate_window.1)
            {
                p.rate = (now_n - then_n) as f64 / dt;
            }
            state.progress.imu_rate = state.progress.imus.iter().map(|p| p.rate).sum();
            self.rate_window = (now, counts);
        }
        progress(&state.progress);
    }

    /// Wind down: stops the boards and the poller, keeps what they still
    /// hold, closes the session and maps its times (the final clock fits);
    /// the summary, or the summary in an error when `cause` stopped it.
    fn wind_down(
        self,
        mut summaries: Vec<BoardSummary>,
        mut cause: Option<String>,
        progress: &mut dyn FnMut(&RecordProgress),
    ) -> Result<RecordSummary, RecordError> {
        let Self {
            opts,
            streams,
            arm,
            mut state,
            epoch,
            ..
        } = self;
        let n = opts.robot.dof();
        let info = summaries[0].devices[0];
        let duration = epoch.elapsed().as_secs_f64();
        let mut links = Vec::with_capacity(streams.len());
        for (b, stream) in streams.into_iter().enumerate() {
            let (rest_events, link_stats) = stream.stop();
            for ev in rest_events.try_iter() {
                if let Err(c) = state.handle_from(b, ev) {
                    cause.get_or_insert(c);
                }
            }
            links.push(link_stats);
        }
        for s in arm.stop() {
            state.joint_sample(&s, n)?;
        }
        state.drain_waiting(true)?;
        state.progress.elapsed = duration;
        state.progress.set_links(&links);
        progress(&state.progress);
        let counters = state.progress.clone();
        let dir = state.finish()?;
        for (j, fits, _) in repair::remap_all_imu_times(&dir)? {
            if let Some(board) = summaries.iter_mut().find(|b| b.first_imu == j) {
                board.clock = fits.clone();
            }
            write_clock_notes_of(&dir, j, &fits)?;
        }
        for (board, link) in summaries.iter_mut().zip(&links) {
            board.link = *link;
        }
        let clock = summaries[0].clock.clone();
        let link_stats = summaries[0].link;
        let joint_clock = repair::remap_joint_times(&dir)?;
        if let Some(c) = &joint_clock {
            repair::write_controller_clock(&dir, c)?;
        }
        let summary = RecordSummary {
            dir,
            duration,
            progress: counters,
            link: link_stats,
            device: info,
            clock,
            boards: summaries,
            joint_clock,
            epoch,
        };
        match cause {
            None => Ok(summary),
            Some(cause) => Err(RecordError::Aborted {
                cause,
                summary: Box::new(summary),
            }),
        }
    }
}

/// An IMU sample waiting for its segment's clock fit.
struct Waiting {
    /// Which IMU (docs/model.md §9).
    imu: usize,
    /// Device time, s.
    device: f64,
    seq: u32,
    z: [f64; 6],
    /// Temperature, °C.
    temp: f64,
}

/// One board's side of a [`SessionSink`]: its ping log, clock fits and
/// waiting samples.
struct BoardSink {
    pings: std::io::BufWriter<std::fs::File>,
    pings_path: PathBuf,
    echoes: BTreeMap<u32, Vec<Echo>>,
    fits: BTreeMap<u32, ClockFit>,
    /// Samples of segments without a clock fit yet.
    waiting: BTreeMap<u32, Vec<Waiting>>,
    /// The last `seq` by segment and sensor.
    last_seq: BTreeMap<(u32, u8), u32>,
    /// The IMU number of its sensor 0.
    first_imu: usize,
    sensors: usize,
}

/// The writing side of a recording: takes IMU events and joint samples,
/// maps device time to session time, writes the session's files.
pub struct SessionSink {
    writer: SessionWriter,
    boards: Vec<BoardSink>,
    /// Whether `joints.csv` has the controller clock's columns.
    controller_clock: bool,
    /// Per IMU, the last session time written: the provisional mapping
    /// moves as the clock fit is refined (by tens of ms while it is young
    /// or when the host is loaded), and rows are written non-decreasing so
    /// that what is on disk stays a readable session should the recording
    /// be killed; the final mapping ([`repair::remap_imu_times`]) places
    /// every row again from `t_device`.
    last_written: Vec<f64>,
    /// The counters so far.
    pub progress: RecordProgress,
}

impl SessionSink {
    /// Creates the session directory `dir` (session.toml, CSV headers,
    /// `pings.csv`).
    pub fn create(dir: &Path, meta: &SessionMeta, joints: usize) -> Result<Self, SessionError> {
        Self::create_with_clock(dir, meta, joints, false)
    }

    /// [`Self::create`]; with `controller_clock`, `joints.csv` gets the
    /// columns [`repair::JOINT_CLOCK_COLUMNS`] (a controller that stamps its
    /// samples, UR).
    pub fn create_with_clock(
        dir: &Path,
        meta: &SessionMeta,
        joints: usize,
        controller_clock: bool,
    ) -> Result<Self, SessionError> {
        Self::create_boards(dir, meta, joints, controller_clock, &[1])
    }

    /// [`Self::create_with_clock`] for boards of `sensors[b]` sensors each
    /// (docs/model.md §9: IMUs numbered board by board); board b's ping log
    /// is [`repair::pings_file`]`(b)`.
    pub fn create_boards(
        dir: &Path,
        meta: &SessionMeta,
        joints: usize,
        controller_clock: bool,
        sensors: &[usize],
    ) -> Result<Self, SessionError> {
        let joint_extra: &[&str] = if controller_clock {
            &repair::JOINT_CLOCK_COLUMNS
        } else {
            &[]
        };
        let writer = SessionWriter::create_with_extra(
            dir,
            meta,
            joints,
            joint_extra,
            &[
                "t_device",
                "segment",
                "seq",
                robimu_session::IMU_TEMP_COLUMN,
            ],
        )?;
        let mut boards = Vec::with_capacity(sensors.len());
        let mut first_imu = 0;
        for (b, &n) in sensors.iter().enumerate() {
            let pings_path = dir.join(repair::pings_file(b));
            let mut pings = std::io::BufWriter::new(
                std::fs::File::create(&pings_path).map_err(|e| SessionError::io(&pings_path, e))?,
            );
            writeln!(pings, "{}", repair::PINGS_HEADER)
                .map_err(|e| SessionError::io(&pings_path, e))?;
            boards.push(BoardSink {
                pings,
                pings_path,
                echoes: BTreeMap::new(),
                fits: BTreeMap::new(),
                waiting: BTreeMap::new(),
                last_seq: BTreeMap::new(),
                first_imu,
                sensors: n.max(1),
            });
            first_imu += n.max(1);
        }
        let progress = RecordProgress {
            imus: vec![ImuProgress::default(); first_imu],
            ..RecordProgress::default()
        };
        Ok(SessionSink {
            writer,
            boards,
            controller_clock,
            last_written: vec![f64::NEG_INFINITY; first_imu],
            progress,
        })
    }

    /// Writes one joint sample.
    pub fn joint(&mut self, t: f64, q: &[f64]) -> Result<(), SessionError> {
        self.writer.joint(t, q)?;
        self.progress.joint_samples += 1;
        Ok(())
    }

    /// Writes the first `joints` angles of a driver's sample, with the
    /// controller's timestamp when the session has its column (a missing
    /// one is written as NaN; [`repair::remap_joint_times`] then keeps the
    /// arrival times).
    pub fn joint_sample(&mut self, s: &JointSample, joints: usize) -> Result<(), SessionError> {
        if !self.controller_clock {
            return self.joint(s.t, &s.q[..joints]);
        }
        let robot_t = s.robot_t.unwrap_or(f64::NAN);
        self.writer
            .joint_extra(s.t, &s.q[..joints], &[robot_t, s.t])?;
        self.progress.joint_samples += 1;
        Ok(())
    }

    /// Takes one IMU event of the first board; `Err(cause)` ends the recording.
    pub fn handle(&mut self, ev: ImuEvent) -> Result<(), String> {
        self.handle_from(0, ev)
    }

    /// Takes one IMU event of board `board`; `Err(cause)` ends the recording.
    pub fn handle_from(&mut self, board: usize, ev: ImuEvent) -> Result<(), String> {
        let Some(bs) = self.boards.get_mut(board) else {
            return Err(format!(
                "an event of board {board}, which the session does not have"
            ));
        };
        match ev {
            ImuEvent::Sample {
                sensor,
                segment,
                device,
                seq,
                z,
                temp,
            } => {
                if usize::from(sensor) >= bs.sensors {
                    // a sensor the board did not announce: not an IMU of the session
                    return Ok(());
                }
                let imu = bs.first_imu + usize::from(sensor);
                if let Some(prev) = bs.last_seq.insert((segment, sensor), seq) {
                    let gaps = u64::from(seq.wrapping_sub(prev).saturating_sub(1).min(1 << 20));
                    self.progress.seq_gaps += gaps;
                    self.progress.imus[imu].seq_gaps += gaps;
                }
                bs.waiting.entry(segment).or_default().push(Waiting {
                    imu,
                    device,
                    seq,
                    z,
                    temp,
                });
                self.drain_waiting(false).map_err(|e| e.to_string())?;
            }
            ImuEvent::Echo { segment, echo } => {
                writeln!(
                    bs.pings,
                    "{:?},{:?},{:?},{segment}",
                    echo.host_send, echo.host_recv, echo.device
                )
                .map_err(|e| SessionError::io(&bs.pings_path, e).to_string())?;
                let list = bs.echoes.entry(segment).or_default();
                list.push(echo);
                // Refit often while the fit is young, then once a second over
                // the last minute of echoes (the final fit uses them all).
                if list.len() >= 3 && (list.len() < 20 || list.len() % 10 == 0) {
                    let recent = &list[list.len().saturating_sub(600)..];
                    if let Some(fit) = ClockFit::fit(recent) {
                        bs.fits.insert(segment, fit);
                    }
                }
            }
            ImuEvent::Status(s) => {
                if usize::from(s.sensor) < bs.sensors {
                    let imu = bs.first_imu + usize::from(s.sensor);
                    self.progress.imus[imu].device_dropped = s.samples_dropped;
                    self.progress.device_dropped = self
                        .progress
                        .imus
                        .iter()
                        .fold(0u32, |a, p| a.wrapping_add(p.device_dropped));
                }
            }
            ImuEvent::Restarted { .. } => self.progress.restarts += 1,
            ImuEvent::Failed(e) => return Err(e.to_string()),
        }
        Ok(())
    }

    /// Writes waiting samples whose segment has a fit (all of them, with
    /// the best mapping available, when `all`).
    pub fn drain_waiting(&mut self, all: bool) -> Result<(), SessionError> {
        for bs in &mut self.boards {
            let segments: Vec<u32> = bs.waiting.keys().copied().collect();
            for segment in segments {
                let fit = match bs.fits.get(&segment) {
                    Some(f) => *f,
                    None if all => match bs.echoes.get(&segment).and_then(|e| e.first()) {
                        Some(e) => ClockFit::offset_only(e),
                        None => continue,
                    },
                    None => continue,
                };
                for w in bs.waiting.remove(&segment).unwrap_or_default() {
                    let t = fit.to_session(w.device).max(self.last_written[w.imu]);
                    self.last_written[w.imu] = t;
                    self.writer.imu_extra_of(
                        w.imu,
                        t,
                        &w.z,
                        &[w.device, f64::from(segment), f64::from(w.seq), w.temp],
                    )?;
                    self.progress.imu_samples += 1;
                    self.progress.imus[w.imu].samples += 1;
                }
            }
        }
        Ok(())
    }

    /// Pushes every buffered row to the operating system.
    pub fn flush(&mut self) -> Result<(), SessionError> {
        self.writer.flush()?;
        for bs in &mut self.boards {
            bs.pings
                .flush()
                .map_err(|e| SessionError::io(&bs.pings_path, e))?;
        }
        Ok(())
    }

    /// Writes what waits, flushes and closes.
    pub fn finish(mut self) -> Result<PathBuf, SessionError> {
        self.drain_waiting(true)?;
        self.flush()?;
        self.writer.finish()
    }
}

/// session.toml of a recording from `boards` (on `ports`): `[imu]` for
/// IMU 0, `[imu<j>]` for the others (docs/model.md §9), each naming its
/// port, board, sensor and ping log when there are several.
fn session_meta<B>(
    opts: &RecordOptions,
    ports: &[&str],
    boards: &[(B, Vec<DeviceInfo>)],
) -> SessionMeta {
    let mut meta = SessionMeta::new(opts.robot_name.clone());
    let several = boards.iter().map(|(_, i)| i.len()).sum::<usize>() > 1;
    let mut j = 0;
    for (b, (_, infos)) in boards.iter().enumerate() {
        for (k, info) in infos.iter().enumerate() {
            let mut t = device_table(info, ports[b]);
            if several {
                t.insert("board".into(), (b as i64).into());
                t.insert("sensor".into(), (k as i64).into());
                t.insert("pings".into(), repair::pings_file(b).into());
            }
            if j == 0 {
                meta.imu = Some(t);
            } else {
                meta.imu_tables.insert(j, t);
            }
            j += 1;
        }
    }
    meta.notes = Some(format!(
        "recorded by robimu {} from {} and {}",
        env!("CARGO_PKG_VERSION"),
        ports.join(", "),
        describe(&opts.robot_spec)
    ));
    meta
}

fn describe(spec: &RobotSpec) -> String {
    match spec {
        RobotSpec::Aubo { host, port } => format!("AUBO controller {host}:{port}"),
        RobotSpec::Ur {
            host, rtde_port, ..
        } => format!("UR controller {host}:{rtde_port}"),
    }
}

/// The `[imu]` table of session.toml: who the board is and how it was set.
pub fn device_table(info: &DeviceInfo, port: &str) -> toml::Table {
    let mut t = toml::Table::new();
    let v = info.firmware_version;
    t.insert("port".into(), port.into());
    t.insert(
        "firmware".into(),
        format!("{}.{}.{}", v[0], v[1], v[2]).into(),
    );
    t.insert("protocol".into(), i64::from(info.protocol_version).into());
    t.insert("chip_id".into(), i64::from(info.chip_id).into());
    t.insert(
        "sample_rate_hz".into(),
        i64::from(info.config.sample_rate_hz).into(),
    );
    t.insert(
        "accel_range".into(),
        format!("{:?}", info.config.accel_range).into(),
    );
    t.insert(
        "accel_bandwidth".into(),
        format!("{:?}", info.config.accel_bandwidth).into(),
    );
    t.insert(
        "gyro_range".into(),
        format!("{:?}", info.config.gyro_range).into(),
    );
    t.insert(
        "gyro_bandwidth".into(),
        format!("{:?}", info.config.gyro_bandwidth).into(),
    );
    let timing = info.timing;
    let decimal = imu::decimal;
    ImuTiming {
        accel_bandwidth_hz: decimal(timing.accel_bandwidth_hz),
        accel_odr_hz: decimal(timing.accel_odr_hz),
        gyro_bandwidth_hz: decimal(timing.gyro_bandwidth_hz),
        gyro_odr_hz: decimal(timing.gyro_odr_hz),
    }
    .insert_into(&mut t);
    let margin = timing.alias_margin_hz(f64::from(info.config.sample_rate_hz));
    if margin.is_finite() {
        t.insert(
            "alias_margin_hz".into(),
            ((margin * 100.0).round() / 100.0).into(),
        );
    }
    t
}

/// The warning `robimu record` prints for `config`'s read rate when its
/// alias margin is below [`robimu_protocol::ALIAS_MARGIN_HZ`]
/// ([`robimu_protocol::alias`]): which sensor's updates beat at which
/// frequency, the margin, and the nearest alias-free rate. `None` when the
/// rate is alias-free.
pub fn alias_warning(config: &SensorConfig) -> Option<String> {
    use robimu_protocol::{AliasSensor, SensorTiming, ALIAS_CLOCK_TOLERANCE, ALIAS_MARGIN_HZ};
    let timing = SensorTiming::of(config);
    let rate = config.sample_rate_hz;
    let line = timing.worst_alias(f64::from(rate))?;
    if line.margin_hz >= ALIAS_MARGIN_HZ {
        return None;
    }
    let sensor = match line.sensor {
        AliasSensor::Accel => "accelerometer",
        AliasSensor::Gyro => "gyroscope",
    };
    let harmonic = match line.harmonic {
        1 => String::new(),
        k => format!(" (harmonic {k} of the data age)"),
    };
    let spread = f64::from(line.harmonic) * line.odr_hz * ALIAS_CLOCK_TOLERANCE;
    let nearest = match timing.nearest_alias_free_rate(rate) {
        Some(r) => format!("the nearest alias-free rate is {r} Hz (--rate {r})"),
        None => "no rate of 100–1000 Hz is alias-free for these bandwidths".to_string(),
    };
    Some(format!(
        "reading at {rate} Hz, the {sensor}'s {} Hz updates beat at {:.1} Hz{harmonic}, \
         ±{spread:.1} Hz for a chip clock within ±{:.0} %: alias margin {:.1} Hz, below {:.0} Hz, \
         so the data age varies slowly, like a changing delay no model effect has \
         (docs/model.md §4.8); {nearest}",
        line.odr_hz,
        line.frequency_hz,
        100.0 * ALIAS_CLOCK_TOLERANCE,
        line.margin_hz,
        ALIAS_MARGIN_HZ,
    ))
}

/// Adds the clock fits to session.toml's `[imu]` table.
pub fn write_clock_notes(dir: &Path, clock: &[(u32, ClockFit)]) -> Result<(), SessionError> {
    write_clock_notes_of(dir, 0, clock)
}

/// Adds the clock fits of IMU `j`'s board to its table (`[imu]` for j = 0,
/// `[imu<j>]` else; docs/model.md §9).
pub fn write_clock_notes_of(
    dir: &Path,
    j: usize,
    clock: &[(u32, ClockFit)],
) -> Result<(), SessionError> {
    let fits: Vec<toml::Value> = clock
        .iter()
        .map(|(segment, f)| {
            repair::clock_row(
                *segment,
                f.offset,
                f.drift_ppm(),
                [
                    ("residual_us", (f.residual_rms * 1e6).into()),
                    ("echoes_used", (f.used as i64).into()),
                ],
            )
        })
        .collect();
    repair::update_meta(dir, |meta| {
        let table = if j == 0 {
            meta.imu.get_or_insert_with(toml::Table::new)
        } else {
            meta.imu_tables.entry(j).or_default()
        };
        table.insert("clock".into(), fits.into());
    })
}

#[cfg(test)]
mod alias_tests {
    use super::*;
    use robimu_protocol::{SensorTiming, PROTOCOL_VERSION};

    fn config(rate: u16) -> SensorConfig {
        SensorConfig {
            sample_rate_hz: rate,
            ..SensorConfig::default()
        }
    }

    /// 120 Hz against the default 125 Hz accelerometer: its updates beat
    /// at 125 − 120 = 5 Hz (±2.5 Hz), margin 2.5 Hz; 100 Hz: the 4th
    /// harmonic at 500 − 5·100 = 0 Hz; both name 150 Hz as the nearest
    /// alias-free rate; the default rate has no warning.
    #[test]
    fn aliasing_rates_are_warned_about_with_the_beat_and_the_nearest_rate() {
        let w = alias_warning(&config(120)).unwrap();
        for part in [
            "120 Hz",
            "accelerometer's 125 Hz",
            "beat at 5.0 Hz",
            "±2.5 Hz",
            "margin 2.5 Hz",
            "--rate 150",
        ] {
            assert!(w.contains(part), "{part}: {w}");
        }
        let w = alias_warning(&config(100)).unwrap();
        for part in [
            "beat at 0.0 Hz (harmonic 4",
            "margin -10.0 Hz",
            "--rate 150",
        ] {
            assert!(w.contains(part), "{part}: {w}");
        }
        assert_eq!(alias_warning(&SensorConfig::default()), None);
    }

    /// session.toml's `[imu]` gets the rate's margin, rounded to 0.01 Hz.
    #[test]
    fn the_device_table_has_the_alias_margin() {
        let cfg = config(120);
        let info = DeviceInfo {
            firmware_version: [0, 1, 0],
            protocol_version: PROTOCOL_VERSION,
            chip_id: 0xA0,
            accel_id: 0xFB,
            mag_id: 0x32,
            gyro_id: 0x0F,
            sw_revision: 0x0311,
            bootloader_revision: 0x15,
            config: cfg,
            accel_scale_mps2_per_lsb: 0.01,
            gyro_scale_rads_per_lsb: 1.0 / 900.0,
            temp_scale_c_per_lsb: 1.0,
            timing: SensorTiming::of(&cfg),
            sensor: 0,
            sensors: 1,
        };
        let t = device_table(&info, "virtual");
        assert_eq!(t["alias_margin_hz"].as_float(), Some(2.5));
        assert_eq!(t["sample_rate_hz"].as_integer(), Some(120));
    }
}

#[cfg(test)]
mod sink_tests {
    use super::*;
    use robimu_session::Session;

    fn sample(device: f64, seq: u32) -> ImuEvent {
        ImuEvent::Sample {
            sensor: 0,
            segment: 0,
            device,
            seq,
            z: [0.0, 0.0, 9.81, 0.0, 0.0, 0.0],
            temp: 25.0,
        }
    }

    fn echo(host_send: f64, rtt: f64, device: f64) -> ImuEvent {
        ImuEvent::Echo {
            segment: 0,
            echo: clock_fit::Echo {
                host_send,
                host_recv: host_send + rtt,
                device,
            },
        }
    }

    /// A young clock fit that moves back (a loaded host's late echoes, then
    /// prompt ones) would map later samples before earlier ones: the rows on
    /// disk stay non-decreasing, so a recording killed then is a session
    /// that loads (regression: `time goes backwards` after SIGKILL under
    /// load).
    #[test]
    fn provisional_times_never_go_backwards() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("s");
        let mut sink = SessionSink::create(&out, &SessionMeta::new("aubo_i5"), 6).unwrap();
        // device = host time + 0.1 s, but the first echoes came back 80 ms
        // late (a fit that maps 40 ms late), the later ones promptly
        for k in 0..3 {
            let t = 0.1 * f64::from(k);
            sink.handle(echo(t, 0.08, t + 0.1)).unwrap();
        }
        let mut seq = 0;
        let mut next = |sink: &mut SessionSink, from: f64, to: f64| {
            let mut d = from;
            while d < to {
                sink.handle(sample(d, seq)).unwrap();
                seq += 1;
                d += 1.0 / 120.0;
            }
        };
        next(&mut sink, 0.35, 0.6);
        for k in 3..12 {
            let t = 0.1 * f64::from(k);
            sink.handle(echo(t, 0.001, t + 0.1)).unwrap();
        }
        next(&mut sink, 0.6, 1.0);
        for j in 0..6 {
            sink.joint(0.05 * f64::from(j), &[0.0; 6]).unwrap();
        }
        sink.flush().unwrap();
        // read as a killed recording leaves it (no final remap)
        let s = Session::load(&out).unwrap();
        let t = &s.measurements().imu_t;
        assert!(t.len() > 50 && t.windows(2).all(|w| w[1] >= w[0]), "{t:?}");
    }
}
