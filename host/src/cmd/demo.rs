//! `robimu demo`: the main job on simulated hardware. First the IMU board:
//! the real firmware core over a simulated BNO055 on a pseudo-terminal,
//! opened like a USB serial adapter, configured, streamed and pinged through
//! [`robimu::link`]. Then a simulated AUBO i5 session calibrated against its
//! hidden truth.

use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use robimu::link::{DeviceClock, LinkError, LinkReader, LinkWriter};
use robimu_hil_sim::device::{SimDevice, SimDeviceConfig};
use robimu_protocol::{
    CommandKind, DeviceInfo, DeviceMessage, HostMessage, ImuSample, SensorConfig, Status,
};

use super::calibrate::CalibrateCmd;
use super::simulate::SimulateCmd;

/// Run the main job on simulated hardware, no robot or IMU needed.
///
/// Streams from a simulated IMU board over a serial link (pseudo-terminal),
/// then simulates an AUBO i5 session and calibrates it, showing the
/// estimates against the hidden truth.
#[derive(Debug, Clone, clap::Args)]
pub struct DemoCmd {
    /// Directory for the simulated session and its result [default: a new
    /// directory under the system's temporary directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// How long to stream from the simulated IMU board, s.
    #[arg(long, default_value_t = 3.0)]
    pub stream: f64,
    /// Length of the simulated robot session, s.
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Seed of the simulated session.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Skip the IMU board part.
    #[arg(long)]
    pub no_device: bool,
}

impl DemoCmd {
    /// Run both parts.
    pub fn run(self) -> anyhow::Result<()> {
        let start = Instant::now();
        let mut out = std::io::stdout();
        if !self.no_device {
            writeln!(out, "== 1. the IMU board (simulated) ==")?;
            if !(self.stream.is_finite() && self.stream > 0.0 && self.stream <= 3600.0) {
                bail!(
                    "--stream must be a number of seconds in (0, 3600] (got {})",
                    self.stream
                );
            }
            stream_device(self.stream, &mut out)
                .context("the simulated IMU board part failed (--no-device skips it)")?;
            writeln!(out)?;
        }
        writeln!(out, "== 2. calibration of a simulated AUBO i5 session ==")?;
        let dir = self.out.clone().unwrap_or_else(|| {
            std::env::temp_dir().join(format!("robimu-demo-{}", std::process::id()))
        });
        let sim = SimulateCmd {
            robot: "aubo_i5".into(),
            duration: self.duration,
            rate: 120.0,
            joint_rate: None,
            seed: self.seed,
            out: dir.clone(),
            noise_free: false,
            truth: None,
            trajectory: None,
            effect: Vec::new(),
        };
        let t0 = Instant::now();
        let s = sim.write()?;
        writeln!(
            out,
            "simulated {} s of random motion with the paper's noise: {} joint and {} IMU samples at 120 Hz ({:.1} s)",
            self.duration,
            s.joint_samples,
            s.imu_samples,
            t0.elapsed().as_secs_f64()
        )?;
        let t0 = Instant::now();
        CalibrateCmd {
            session: dir.clone(),
            out: None,
            freeze: Vec::new(),
            no_prior: false,
            knot_spacing: None,
            noise: None,
            windows: None,
            effects: Vec::new(),
        }
        .run()?;
        writeln!(out, "calibration took {:.1} s", t0.elapsed().as_secs_f64())?;
        writeln!(
            out,
            "\nfiles in {}: session.toml, joints.csv, imu.csv, truth.toml (the hidden truth), result.json",
            dir.display()
        )?;
        writeln!(
            out,
            "next: robimu calibrate {} --freeze lengths   (demo took {:.1} s)",
            dir.display(),
            start.elapsed().as_secs_f64()
        )?;
        Ok(())
    }
}

/// Host side of the link to the simulated board.
struct Link {
    reader: LinkReader<Box<dyn serialport::SerialPort>>,
    writer: LinkWriter<Box<dyn serialport::SerialPort>>,
}

impl Link {
    /// The next message, `None` when none arrived within the port's timeout.
    fn poll(&mut self) -> anyhow::Result<Option<DeviceMessage>> {
        match self.reader.next_message() {
            Ok(m) => Ok(m),
            Err(LinkError::Read(e)) if e.kind() == std::io::ErrorKind::TimedOut => Ok(None),
            Err(e) => Err(e).context("the serial link failed"),
        }
    }

    /// Waits up to `timeout` for the first message `pick` accepts; the
    /// messages before it are dropped.
    fn wait_for<T>(
        &mut self,
        timeout: Duration,
        mut pick: impl FnMut(&DeviceMessage) -> Option<T>,
    ) -> anyhow::Result<Option<T>> {
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

    /// Sends a state-changing command and waits for its `CommandResult`.
    fn command(&mut self, msg: HostMessage, kind: CommandKind) -> anyhow::Result<()> {
        self.writer.send(&msg)?;
        let result = self.wait_for(Duration::from_secs(3), |m| match m {
            DeviceMessage::CommandResult(r) if r.command == kind => Some(r.result),
            _ => None,
        })?;
        match result {
            Some(Ok(())) => Ok(()),
            Some(Err(e)) => bail!("the device refused {kind:?}: {e:?}"),
            None => bail!("the device did not answer {kind:?} within 3 s"),
        }
    }
}

fn si(info: &DeviceInfo, s: &ImuSample) -> ([f64; 3], [f64; 3], f64) {
    let a = f64::from(info.accel_scale_mps2_per_lsb);
    let g = f64::from(info.gyro_scale_rads_per_lsb);
    (
        s.accel_raw.map(|v| f64::from(v) * a),
        s.gyro_raw.map(|v| f64::from(v) * g),
        f64::from(s.temp_raw) * f64::from(info.temp_scale_c_per_lsb),
    )
}

fn sample_line(info: &DeviceInfo, s: &ImuSample, t_s: f64) -> String {
    let (a, w, temp) = si(info, s);
    format!(
        "t {t_s:8.3} s  seq {:6}  accel [{:7.3} {:7.3} {:7.3}] m/s^2  gyro [{:7.4} {:7.4} {:7.4}] rad/s  {temp:4.0} C",
        s.seq, a[0], a[1], a[2], w[0], w[1], w[2]
    )
}

/// Starts the simulated board, streams from it for `seconds` and prints what
/// a user checks on a real one.
fn stream_device(seconds: f64, out: &mut impl Write) -> anyhow::Result<()> {
    let device = SimDevice::spawn(SimDeviceConfig::default())
        .context("cannot start the simulated IMU board")?;
    let path = device.port_path().to_string();
    writeln!(
        out,
        "simulated board on {path} (the real firmware core over a register-level BNO055)"
    )?;
    let port = serialport::new(&path, 921_600)
        .timeout(Duration::from_millis(20))
        .open()
        .with_context(|| format!("cannot open the serial port {path}"))?;
    let writer = port
        .try_clone()
        .with_context(|| format!("cannot open the serial port {path} for writing"))?;
    let mut link = Link {
        reader: LinkReader::new(port),
        writer: LinkWriter::new(writer),
    };
    link.writer.resync()?;
    link.writer.send(&HostMessage::GetInfo)?;
    let mut info = link
        .wait_for(Duration::from_secs(5), |m| match m {
            DeviceMessage::Info(i) => Some(*i),
            _ => None,
        })?
        .context("the board sent no DeviceInfo within 5 s")?;
    let v = info.firmware_version;
    writeln!(
        out,
        "device: firmware {}.{}.{}, protocol {}, BNO055 chip id {:#04x} (accel {:#04x}, mag {:#04x}, gyro {:#04x}), software revision {:#06x}",
        v[0], v[1], v[2], info.protocol_version, info.chip_id, info.accel_id, info.mag_id, info.gyro_id, info.sw_revision
    )?;

    let config = SensorConfig::default();
    link.command(HostMessage::Configure(config), CommandKind::Configure)?;
    if let Some(i) = link.wait_for(Duration::from_secs(1), |m| match m {
        DeviceMessage::Info(i) => Some(*i),
        _ => None,
    })? {
        info = i;
    }
    let c = info.config;
    writeln!(
        out,
        "configured: accel {:?} / {:?}, gyro {:?} / {:?}, {} Hz; scales {} m/s^2 and {:.6} rad/s per count",
        c.accel_range,
        c.accel_bandwidth,
        c.gyro_range,
        c.gyro_bandwidth,
        c.sample_rate_hz,
        info.accel_scale_mps2_per_lsb,
        info.gyro_scale_rads_per_lsb
    )?;

    link.command(HostMessage::Start, CommandKind::Start)?;
    let live = std::io::stdout().is_terminal();
    let started = Instant::now();
    let end = started + Duration::from_secs_f64(seconds);
    let mut clock = DeviceClock::new();
    let (mut count, mut gaps, mut first, mut last) = (0u64, 0u64, None, None::<(u64, ImuSample)>);
    let mut status: Option<Status> = None;
    let mut ping_sent: Option<Instant> = None;
    let mut rtt: Option<Duration> = None;
    let mut next_show = started;
    const NONCE: u32 = 0x5EED_1234;
    while Instant::now() < end {
        if ping_sent.is_none() && started.elapsed() > Duration::from_secs_f64(seconds / 2.0) {
            link.writer.send(&HostMessage::Ping { nonce: NONCE })?;
            ping_sent = Some(Instant::now());
        }
        let Some(m) = link.poll()? else { continue };
        let t_us = clock.observe(&m);
        match m {
            DeviceMessage::Sample(s) => {
                let t = t_us.unwrap_or_default();
                if let Some((_, prev)) = &last {
                    gaps += u64::from(s.seq.wrapping_sub(prev.seq).saturating_sub(1));
                }
                first.get_or_insert(t);
                last = Some((t, s));
                count += 1;
                if Instant::now() >= next_show {
                    let line = sample_line(&info, &s, t as f64 * 1e-6);
                    if live {
                        write!(out, "\r{line}\x1b[K")?;
                    } else {
                        writeln!(out, "{line}")?;
                    }
                    out.flush()?;
                    next_show += if live {
                        Duration::from_millis(100)
                    } else {
                        Duration::from_secs(1)
                    };
                }
            }
            DeviceMessage::Status(s) => status = Some(s),
            DeviceMessage::Pong(p) if p.nonce == NONCE => {
                rtt = ping_sent.map(|t| t.elapsed());
            }
            DeviceMessage::Info(i) => info = i,
            _ => {}
        }
    }
    if live {
        writeln!(out)?;
    }
    let host_s = started.elapsed().as_secs_f64();
    link.command(HostMessage::Stop, CommandKind::Stop)?;
    let final_status = device.stop();
    let rate = match (first, &last) {
        (Some(a), Some((b, _))) if *b > a && count > 1 => {
            (count - 1) as f64 / ((b - a) as f64 * 1e-6)
        }
        _ => 0.0,
    };
    let stats = *link.reader.stats();
    writeln!(
        out,
        "streamed {count} samples in {host_s:.1} s: {rate:.1} Hz by the device clock ({} Hz configured)",
        c.sample_rate_hz
    )?;
    writeln!(
        out,
        "losses: {gaps} sequence gaps; device dropped {} samples in total (last status during streaming: {}); link: {} CRC errors, {} other bad frames, {} bytes discarded",
        final_status.samples_dropped,
        status.map_or_else(|| "none".into(), |s| format!("{} sent, {} dropped", s.samples_sent, s.samples_dropped)),
        stats.crc_errors,
        stats.cobs_errors + stats.version_errors + stats.too_long + stats.too_short + stats.deserialize_errors,
        stats.bytes_discarded
    )?;
    match rtt {
        Some(d) => writeln!(out, "ping round trip: {:.2} ms", d.as_secs_f64() * 1e3)?,
        None => writeln!(out, "ping: no answer while streaming")?,
    }
    if count == 0 {
        bail!("the simulated board streamed no samples");
    }
    Ok(())
}
