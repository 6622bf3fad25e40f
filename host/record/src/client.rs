//! The IMU board as a typed client: open the port, then `identify`,
//! `configure`, `start`, `stop`, `ping`, `get_info`, `get_status`, each
//! answered by the board's own message or a [`ClientError`] that keeps the
//! board's [`CommandError`] typed.
//!
//! The streaming side of a recording ([`crate::imu::ImuStream`]) takes the
//! client over once the board is configured.

use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use robimu_protocol::{
    CommandError, CommandKind, DecoderStats, DeviceInfo, DeviceMessage, HostMessage, Pong,
    SensorConfig, Status,
};

use crate::link::{LinkError, LinkReader, LinkWriter};

/// How long a command (`Configure`, `Start`, `Stop`) may take to be answered.
pub(crate) const COMMAND_TIMEOUT: Duration = Duration::from_secs(3);

/// How long a configured board may take to report its new `DeviceInfo`.
const INFO_AFTER_CONFIGURE: Duration = Duration::from_millis(500);

/// Why the IMU board could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
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
    /// The board speaks another protocol version: its frames are intact but
    /// cannot be read by this host.
    #[error("the IMU board on {path} speaks robimu protocol version {found}, this robimu speaks version {expected}: flash the firmware that comes with this robimu (or use the robimu release of the board's firmware)")]
    ProtocolVersion {
        /// The port path.
        path: String,
        /// The board's version.
        found: u8,
        /// This host's version.
        expected: u8,
    },
    /// The board refused a command, for the reason it gave.
    #[error("the IMU board on {path} refused {command:?}: {error:?}")]
    Refused {
        /// The port path.
        path: String,
        /// The command.
        command: CommandKind,
        /// The board's reason.
        error: CommandError,
    },
    /// The board did not answer a command within [`COMMAND_TIMEOUT`].
    #[error("the IMU board on {path} did not answer {command:?} within 3 s")]
    NoAnswer {
        /// The port path.
        path: String,
        /// The command.
        command: CommandKind,
    },
    /// A board of several sensors did not describe one of them.
    #[error("the IMU board on {path} reads {sensors} sensors but sent no DeviceInfo for sensor {sensor}")]
    MissingSensor {
        /// The port path.
        path: String,
        /// The sensor without a `DeviceInfo`.
        sensor: usize,
        /// How many the board announced.
        sensors: usize,
    },
    /// The board did not answer a request for a report (`Status`, `Pong`).
    #[error("the IMU board on {path} sent no {what} within {waited:?}")]
    NoReport {
        /// The port path.
        path: String,
        /// What was asked for.
        what: &'static str,
        /// How long we waited.
        waited: Duration,
    },
    /// The streaming thread could not be started.
    #[error("the IMU board on {path} cannot start the streaming thread: {source}")]
    Thread {
        /// The port path (empty: the thread is the host's).
        path: String,
        /// What the system said.
        source: std::io::Error,
    },
    /// The port failed (unplugged, closed).
    #[error("the serial port {path} failed while streaming (unplugged?): {detail}")]
    Vanished {
        /// The port path.
        path: String,
        /// What the system said.
        detail: String,
    },
    /// The board went silent while streaming, with no I/O error: nothing
    /// from it (`what` = "message") or no sample while it answers (`what`
    /// = "sample") for longer than the watchdog allows
    /// (`imu::silence_limits`: 1 s of nothing, or max(2 s, 20 sample periods) without a sample).
    #[error("the IMU board on {path} went silent while streaming: no {what} for {waited:.1?} (the limit is {limit:?}) and no I/O error: it hung, lost power or its sensor stopped (check the cable and the board's LED, then record again)")]
    Silent {
        /// The port path.
        path: String,
        /// "message" or "sample".
        what: &'static str,
        /// How long nothing came.
        waited: Duration,
        /// The watchdog's limit.
        limit: Duration,
    },
}

/// A serial port, as the client reads and writes it.
pub(crate) type Port = Box<dyn serialport::SerialPort>;

/// The host side of the link to one IMU board.
pub struct ImuClient<R = Port, W = Port> {
    path: String,
    reader: LinkReader<R>,
    writer: LinkWriter<W>,
    /// The last `DeviceInfo` the board sent for each of its sensors
    /// (protocol 3: one per sensor), by sensor.
    infos: Vec<Option<DeviceInfo>>,
}

impl ImuClient {
    /// Opens `path` at `baud`, mapping the system's errors to [`ClientError`].
    pub fn open(path: &str, baud: u32) -> Result<Self, ClientError> {
        if !std::path::Path::new(path).exists() {
            return Err(ClientError::NotFound { path: path.into() });
        }
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(20))
            .open()
            .map_err(|e| open_error(path, e))?;
        let writer = port.try_clone().map_err(|e| open_error(path, e))?;
        Ok(Self::from_parts(path, port, writer))
    }
}

impl<R: Read, W: Write> ImuClient<R, W> {
    /// A client over any reader and writer (`path` names them in errors). A
    /// read that times out (`ErrorKind::TimedOut`) or ends means "nothing yet".
    pub fn from_parts(path: &str, reader: R, writer: W) -> Self {
        Self {
            path: path.into(),
            reader: LinkReader::new(reader),
            writer: LinkWriter::new(writer),
            infos: Vec::new(),
        }
    }

    /// The port path.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The link's decoder counters (bytes, frames, CRC errors, …).
    pub fn stats(&self) -> &DecoderStats {
        self.reader.stats()
    }

    fn vanished(&self, e: &LinkError) -> ClientError {
        ClientError::Vanished {
            path: self.path.clone(),
            detail: e.to_string(),
        }
    }

    /// The next message, if one arrived within the port's read timeout.
    pub fn poll(&mut self) -> Result<Option<DeviceMessage>, ClientError> {
        match self.reader.next_message() {
            Ok(m) => Ok(m),
            Err(LinkError::Read(e)) if e.kind() == ErrorKind::TimedOut => Ok(None),
            Err(e) => Err(self.vanished(&e)),
        }
    }

    /// Sends one message without waiting for an answer.
    pub fn send(&mut self, msg: &HostMessage) -> Result<(), ClientError> {
        self.writer.send(msg).map_err(|e| self.vanished(&e))
    }

    fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pick: impl FnMut(&DeviceMessage) -> Option<T>,
    ) -> Result<Option<T>, ClientError> {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if let Some(m) = self.poll()? {
                if let DeviceMessage::Info(i) = m {
                    self.remember(i);
                }
                if let Some(t) = pick(&m) {
                    return Ok(Some(t));
                }
            }
        }
        Ok(None)
    }

    fn remember(&mut self, info: DeviceInfo) {
        let k = usize::from(info.sensor);
        if k < usize::from(robimu_protocol::MAX_SENSORS) {
            if self.infos.len() <= k {
                self.infos.resize(k + 1, None);
            }
            self.infos[k] = Some(info);
        }
    }

    /// How many sensors the board reads (its last `DeviceInfo`'s `sensors`;
    /// 1 before one came).
    pub fn sensors(&self) -> usize {
        self.infos
            .iter()
            .flatten()
            .next()
            .map_or(1, |i| usize::from(i.sensors).max(1))
    }

    /// Sends a command and waits for its `CommandResult`.
    fn command(&mut self, msg: HostMessage, command: CommandKind) -> Result<(), ClientError> {
        self.send(&msg)?;
        let result = self.wait_for(COMMAND_TIMEOUT, |m| match m {
            DeviceMessage::CommandResult(r) if r.command == command => Some(r.result),
            _ => None,
        })?;
        match result {
            Some(Ok(())) => Ok(()),
            Some(Err(error)) => Err(ClientError::Refused {
                path: self.path.clone(),
                command,
                error,
            }),
            None => Err(ClientError::NoAnswer {
                path: self.path.clone(),
                command,
            }),
        }
    }

    /// Ends any partial frame the board holds, stops a streaming board and
    /// asks for its `DeviceInfo` ([`ClientError::NotRobimu`] when none comes
    /// within `timeout`).
    pub fn identify(&mut self, timeout: Duration) -> Result<DeviceInfo, ClientError> {
        self.writer.resync().map_err(|e| self.vanished(&e))?;
        self.send(&HostMessage::Stop)?;
        self.get_info(timeout)
    }

    /// Asks for the board's `DeviceInfo`.
    pub fn get_info(&mut self, timeout: Duration) -> Result<DeviceInfo, ClientError> {
        self.send(&HostMessage::GetInfo)?;
        let info = self.wait_for(timeout, |m| match m {
            DeviceMessage::Info(i) => Some(*i),
            _ => None,
        })?;
        info.ok_or_else(|| {
            let s = self.reader.stats();
            if let Some(found) = s.foreign_version {
                return ClientError::ProtocolVersion {
                    path: self.path.clone(),
                    found,
                    expected: robimu_protocol::PROTOCOL_VERSION,
                };
            }
            ClientError::NotRobimu {
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

    /// Configures the sensor; the `DeviceInfo` the board reports after it
    /// (the last one it sent when no fresh one comes within 0.5 s); sensor
    /// 0's on a board of several ([`Self::configure_sensors`]).
    pub fn configure(&mut self, config: &SensorConfig) -> Result<DeviceInfo, ClientError> {
        let infos = self.configure_sensors(config)?;
        infos.into_iter().next().ok_or_else(|| self.no_info())
    }

    /// Configures every sensor of the board (protocol 3: one `Configure`
    /// applies to all); the `DeviceInfo` of each, sensor 0 first (a fresh
    /// one, or the last one it sent when none comes within 0.5 s).
    ///
    /// # Errors
    ///
    /// As [`Self::configure`]; [`ClientError::MissingSensor`] if a sensor
    /// the board announces never describes itself.
    pub fn configure_sensors(
        &mut self,
        config: &SensorConfig,
    ) -> Result<Vec<DeviceInfo>, ClientError> {
        self.command(HostMessage::Configure(*config), CommandKind::Configure)?;
        let mut fresh: Vec<Option<DeviceInfo>> = Vec::new();
        let end = Instant::now() + INFO_AFTER_CONFIGURE;
        while Instant::now() < end {
            let n = self.sensors();
            if fresh.len() >= n && fresh.iter().take(n).all(Option::is_some) {
                break;
            }
            let got =
                self.wait_for(end.saturating_duration_since(Instant::now()), |m| match m {
                    DeviceMessage::Info(i) => Some(*i),
                    _ => None,
                })?;
            let Some(i) = got else { break };
            let k = usize::from(i.sensor);
            if k < usize::from(robimu_protocol::MAX_SENSORS) {
                if fresh.len() <= k {
                    fresh.resize(k + 1, None);
                }
                fresh[k] = Some(i);
            }
        }
        if self.infos.iter().all(Option::is_none) && fresh.iter().all(Option::is_none) {
            let first = self.get_info(INFO_AFTER_CONFIGURE)?;
            self.remember(first);
        }
        let n = self.sensors();
        (0..n)
            .map(|k| {
                fresh
                    .get(k)
                    .copied()
                    .flatten()
                    .or_else(|| self.infos.get(k).copied().flatten())
                    .ok_or_else(|| ClientError::MissingSensor {
                        path: self.path.clone(),
                        sensor: k,
                        sensors: n,
                    })
            })
            .collect()
    }

    fn no_info(&self) -> ClientError {
        ClientError::MissingSensor {
            path: self.path.clone(),
            sensor: 0,
            sensors: self.sensors(),
        }
    }

    /// Starts streaming.
    pub fn start(&mut self) -> Result<(), ClientError> {
        self.command(HostMessage::Start, CommandKind::Start)
    }

    /// Stops streaming.
    pub fn stop(&mut self) -> Result<(), ClientError> {
        self.command(HostMessage::Stop, CommandKind::Stop)
    }

    /// Asks for a health report.
    pub fn get_status(&mut self, timeout: Duration) -> Result<Status, ClientError> {
        self.request(HostMessage::GetStatus, "Status", timeout, |m| match m {
            DeviceMessage::Status(s) => Some(*s),
            _ => None,
        })
    }

    /// Pings the board and waits for its echo.
    pub fn ping(&mut self, nonce: u32, timeout: Duration) -> Result<Pong, ClientError> {
        self.request(HostMessage::Ping { nonce }, "Pong", timeout, |m| match m {
            DeviceMessage::Pong(p) if p.nonce == nonce => Some(*p),
            _ => None,
        })
    }

    /// Sends `msg` and waits for the report `pick` takes.
    fn request<T>(
        &mut self,
        msg: HostMessage,
        what: &'static str,
        timeout: Duration,
        pick: impl FnMut(&DeviceMessage) -> Option<T>,
    ) -> Result<T, ClientError> {
        self.send(&msg)?;
        self.wait_for(timeout, pick)?
            .ok_or_else(|| ClientError::NoReport {
                path: self.path.clone(),
                what,
                waited: timeout,
            })
    }
}

fn open_error(path: &str, e: serialport::Error) -> ClientError {
    let detail = e.to_string();
    let lower = detail.to_lowercase();
    if lower.contains("busy") || lower.contains("exclusive") || lower.contains("locked") {
        ClientError::Busy {
            path: path.into(),
            detail,
        }
    } else if matches!(e.kind(), serialport::ErrorKind::NoDevice) || lower.contains("no such file")
    {
        ClientError::NotFound { path: path.into() }
    } else {
        ClientError::Open {
            path: path.into(),
            detail,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_protocol::{encode_to_vec, CommandResult};

    fn info() -> DeviceInfo {
        DeviceInfo {
            firmware_version: [1, 2, 3],
            protocol_version: robimu_protocol::PROTOCOL_VERSION,
            chip_id: 0xA0,
            accel_id: 0xFB,
            mag_id: 0x32,
            gyro_id: 0x0F,
            sw_revision: 0x0311,
            bootloader_revision: 0x15,
            config: SensorConfig::default(),
            accel_scale_mps2_per_lsb: 0.01,
            gyro_scale_rads_per_lsb: 1.0 / 900.0,
            temp_scale_c_per_lsb: 1.0,
            timing: robimu_protocol::SensorTiming::of(&SensorConfig::default()),
            sensor: 0,
            sensors: 1,
        }
    }

    /// A client whose board has already sent `replies`.
    fn client(replies: &[DeviceMessage]) -> ImuClient<std::io::Cursor<Vec<u8>>, Vec<u8>> {
        let mut bytes = Vec::new();
        for m in replies {
            bytes.extend(encode_to_vec(m).unwrap());
        }
        ImuClient::from_parts("/dev/test", std::io::Cursor::new(bytes), Vec::new())
    }

    fn result(command: CommandKind, result: Result<(), CommandError>) -> DeviceMessage {
        DeviceMessage::CommandResult(CommandResult { command, result })
    }

    #[test]
    fn a_refusal_keeps_the_boards_reason() {
        let mut c = client(&[result(CommandKind::Configure, Err(CommandError::Busy))]);
        let err = c.configure(&SensorConfig::default()).unwrap_err();
        assert!(matches!(
            err,
            ClientError::Refused {
                command: CommandKind::Configure,
                error: CommandError::Busy,
                ..
            }
        ));
        assert_eq!(
            err.to_string(),
            "the IMU board on /dev/test refused Configure: Busy"
        );
    }

    #[test]
    fn configure_returns_the_fresh_info_or_the_last_one() {
        let mut fresh = info();
        fresh.config.sample_rate_hz = 200;
        let mut c = client(&[
            DeviceMessage::Info(info()),
            result(CommandKind::Configure, Ok(())),
            DeviceMessage::Info(fresh),
        ]);
        assert_eq!(c.identify(Duration::from_millis(50)).unwrap(), info());
        assert_eq!(c.configure(&fresh.config).unwrap(), fresh);

        let mut c = client(&[
            DeviceMessage::Info(info()),
            result(CommandKind::Configure, Ok(())),
        ]);
        c.identify(Duration::from_millis(50)).unwrap();
        assert_eq!(c.configure(&SensorConfig::default()).unwrap(), info());
    }

    #[test]
    fn a_board_of_another_protocol_version_is_named() {
        // A version-1 board's DeviceInfo (protocol/tests/golden.rs): intact
        // frames of the old version, sent twice.
        let v1 = "02010102010b01a0fb320f91061501030b02780ad7233cb4a2913a0107803f758cae2200";
        let frame: Vec<u8> = (0..v1.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&v1[i..i + 2], 16).unwrap())
            .collect();
        let bytes = [frame.clone(), frame].concat();
        let mut c = ImuClient::from_parts("/dev/test", std::io::Cursor::new(bytes), Vec::new());
        let err = c.identify(Duration::from_millis(20)).unwrap_err();
        assert!(
            matches!(
                err,
                ClientError::ProtocolVersion {
                    found: 1,
                    expected: 3,
                    ..
                }
            ),
            "{err:?}"
        );
        let text = err.to_string();
        assert!(
            text.contains("protocol version 1") && text.contains("version 3"),
            "{text}"
        );
    }

    #[test]
    fn silence_is_typed() {
        let mut c = client(&[]);
        let err = c.start().unwrap_err();
        assert!(matches!(
            err,
            ClientError::NoAnswer {
                command: CommandKind::Start,
                ..
            }
        ));
        assert_eq!(
            err.to_string(),
            "the IMU board on /dev/test did not answer Start within 3 s"
        );
        assert!(matches!(
            c.get_info(Duration::from_millis(10)),
            Err(ClientError::NotRobimu { bytes: 0, .. })
        ));
        assert!(matches!(
            c.get_status(Duration::from_millis(10)),
            Err(ClientError::NoReport { what: "Status", .. })
        ));
    }

    #[test]
    fn reports_are_answered() {
        let status = Status {
            streaming: true,
            ..Status::default()
        };
        let mut c = client(&[
            DeviceMessage::Pong(Pong { nonce: 6, t_us: 1 }),
            DeviceMessage::Pong(Pong { nonce: 7, t_us: 2 }),
            DeviceMessage::Status(status),
            result(CommandKind::Stop, Ok(())),
        ]);
        assert_eq!(c.ping(7, Duration::from_millis(50)).unwrap().t_us, 2);
        assert_eq!(c.get_status(Duration::from_millis(50)).unwrap(), status);
        c.stop().unwrap();
        let sent = c.writer.into_inner();
        let mut reader = LinkReader::<_, HostMessage>::for_messages(&sent[..]);
        let sent: Vec<_> = reader.by_ref().map(Result::unwrap).collect();
        assert_eq!(
            sent,
            [
                HostMessage::Ping { nonce: 7 },
                HostMessage::GetStatus,
                HostMessage::Stop
            ]
        );
    }

    /// A two-sensor board (protocol 3): one `Configure`, a fresh
    /// `DeviceInfo` per sensor, returned in sensor order; a sensor the
    /// board announces but never describes is named.
    #[test]
    fn configure_sensors_returns_every_sensors_info() {
        let two = |k: u8, rate: u16| {
            let mut i = info();
            i.sensor = k;
            i.sensors = 2;
            i.sw_revision = 0x0300 + u16::from(k);
            i.config.sample_rate_hz = rate;
            i
        };
        let mut c = client(&[
            DeviceMessage::Info(two(0, 150)),
            DeviceMessage::Info(two(1, 150)),
            result(CommandKind::Configure, Ok(())),
            DeviceMessage::Info(two(0, 200)),
            DeviceMessage::Info(two(1, 200)),
        ]);
        assert_eq!(c.identify(Duration::from_millis(50)).unwrap(), two(0, 150));
        let infos = c.configure_sensors(&two(0, 200).config).unwrap();
        assert_eq!(infos, vec![two(0, 200), two(1, 200)]);
        assert_eq!(c.sensors(), 2);

        let mut c = client(&[
            DeviceMessage::Info(two(0, 150)),
            result(CommandKind::Configure, Ok(())),
        ]);
        c.identify(Duration::from_millis(50)).unwrap();
        let err = c.configure_sensors(&SensorConfig::default()).unwrap_err();
        assert!(matches!(
            err,
            ClientError::MissingSensor {
                sensor: 1,
                sensors: 2,
                ..
            }
        ));
        assert_eq!(
            err.to_string(),
            "the IMU board on /dev/test reads 2 sensors but sent no DeviceInfo for sensor 1"
        );
    }

    /// Mixed versions: a board of protocol 2 (its `DeviceInfo` frame as
    /// checked in, protocol/tests/golden/frames_v2.txt) is refused by name,
    /// with both versions.
    #[test]
    fn a_protocol_2_board_is_refused_by_name() {
        let v2_info: Vec<u8> = (0..GOLDEN_V2_INFO.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&GOLDEN_V2_INFO[i..i + 2], 16).unwrap())
            .collect();
        let mut c = ImuClient::from_parts("/dev/test", std::io::Cursor::new(v2_info), Vec::new());
        let err = c.identify(Duration::from_millis(50)).unwrap_err();
        assert!(
            matches!(
                err,
                ClientError::ProtocolVersion {
                    found: 2,
                    expected: 3,
                    ..
                }
            ),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "the IMU board on /dev/test speaks robimu protocol version 2, this robimu speaks \
             version 3: flash the firmware that comes with this robimu (or use the robimu \
             release of the board's firmware)"
        );
    }

    /// `device/info` of protocol/tests/golden/frames_v2.txt.
    const GOLDEN_V2_INFO: &str = "02020102010b02a0fb320f91061501030b02780ad7233cb4a2913a0103803f01037a420103fa420103e84201077a4494c10f4c00";
}
