//! Robot arm drivers for `robimu record --robot KIND:HOST[:PORT]`.
//!
//! * [`aubo`]: AUBO arms over the ARCS controller's JSON-RPC (port 30004).
//! * [`ur`]: Universal Robots arms: RTDE (port 30004) for joint readings,
//!   URScript on the secondary interface (port 30002) for motion.

pub mod aubo;
mod poller;
pub mod ur;

use std::fmt;
use std::io::{ErrorKind, Read};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

/// A joint vector of a six-joint arm, rad.
pub type Joints = [f64; 6];

/// One joint reading from a robot driver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointSample {
    /// Host time, s since the poller's epoch: the midpoint between request
    /// and reply (AUBO), or when the data package arrived (UR).
    pub t: f64,
    /// Joint angles, rad.
    pub q: Joints,
    /// The controller's own timestamp, s (UR RTDE `timestamp`, seconds since
    /// the controller started); `None` when the controller sends none.
    pub robot_t: Option<f64>,
}

/// Which robot to drive, as given on the command line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RobotSpec {
    /// An AUBO arm's ARCS controller at `host:port`.
    Aubo {
        /// Host name or address.
        host: String,
        /// TCP port (default [`aubo::DEFAULT_PORT`]).
        port: u16,
    },
    /// A Universal Robots controller at `host`.
    Ur {
        /// Host name or address.
        host: String,
        /// RTDE port (default [`ur::RTDE_PORT`]).
        rtde_port: u16,
        /// URScript port (default [`ur::SCRIPT_PORT`]).
        script_port: u16,
    },
}

/// The accepted forms, for error messages.
const FORMS: &str = "aubo:HOST[:PORT] or ur:HOST[:RTDE_PORT[:SCRIPT_PORT]]";

/// Why a robot specification could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RobotSpecError {
    /// The kind before the first `:` is not a known robot.
    #[error("unknown robot kind {kind:?} in {spec:?} (expected {FORMS})")]
    UnknownKind {
        /// The whole specification.
        spec: String,
        /// The kind given.
        kind: String,
    },
    /// No host after the kind.
    #[error("no host in robot {spec:?} (expected {FORMS})")]
    NoHost {
        /// The whole specification.
        spec: String,
    },
    /// The port is not a number in 1..=65535.
    #[error("bad port {port:?} in robot {spec:?}")]
    BadPort {
        /// The whole specification.
        spec: String,
        /// The port text.
        port: String,
    },
}

impl RobotSpec {
    /// Reads `aubo:HOST[:PORT]` or `ur:HOST[:RTDE_PORT[:SCRIPT_PORT]]` (an
    /// IPv6 host in brackets: `aubo:[::1]:30004`).
    pub fn parse(spec: &str) -> Result<RobotSpec, RobotSpecError> {
        let (kind, rest) = spec.split_once(':').unwrap_or((spec, ""));
        if kind.eq_ignore_ascii_case("ur") {
            return Self::parse_ur(spec, rest);
        }
        if !kind.eq_ignore_ascii_case("aubo") {
            return Err(RobotSpecError::UnknownKind {
                spec: spec.to_string(),
                kind: kind.to_string(),
            });
        }
        let (host, port) = split_host(rest, true);
        if host.is_empty() {
            return Err(no_host(spec));
        }
        let port = match port {
            None => aubo::DEFAULT_PORT,
            Some(p) => parse_port(spec, p)?,
        };
        Ok(RobotSpec::Aubo {
            host: host.to_string(),
            port,
        })
    }

    /// `HOST[:RTDE_PORT[:SCRIPT_PORT]]` after `ur:`.
    fn parse_ur(spec: &str, rest: &str) -> Result<RobotSpec, RobotSpecError> {
        let (host, ports) = split_host(rest, false);
        if host.is_empty() {
            return Err(no_host(spec));
        }
        let (rtde_port, script_port) = match ports.map(|p| p.split_once(':').unwrap_or((p, ""))) {
            None => (ur::RTDE_PORT, ur::SCRIPT_PORT),
            Some((r, "")) => (parse_port(spec, r)?, ur::SCRIPT_PORT),
            Some((r, s)) => (parse_port(spec, r)?, parse_port(spec, s)?),
        };
        Ok(RobotSpec::Ur {
            host: host.to_string(),
            rtde_port,
            script_port,
        })
    }
}

/// `HOST[:PORTS]` (an IPv6 host in brackets): the host and what follows
/// its `:`, at the last `:` of a bare host if `last`, else at its first.
fn split_host(rest: &str, last: bool) -> (&str, Option<&str>) {
    if let Some(bracketed) = rest.strip_prefix('[') {
        return match bracketed.split_once(']') {
            Some((h, tail)) => (h, tail.strip_prefix(':')),
            None => (bracketed, None),
        };
    }
    let split = if last {
        rest.rsplit_once(':')
    } else {
        rest.split_once(':')
    };
    match split {
        Some((h, p)) => (h, Some(p)),
        None => (rest, None),
    }
}

fn no_host(spec: &str) -> RobotSpecError {
    RobotSpecError::NoHost {
        spec: spec.to_string(),
    }
}

/// A port in 1..=65535.
fn parse_port(spec: &str, p: &str) -> Result<u16, RobotSpecError> {
    match p.parse::<u16>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(RobotSpecError::BadPort {
            spec: spec.to_string(),
            port: p.to_string(),
        }),
    }
}

impl fmt::Display for RobotSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RobotSpec::Aubo { host, port } if host.contains(':') => {
                write!(f, "aubo:[{host}]:{port}")
            }
            RobotSpec::Aubo { host, port } => write!(f, "aubo:{host}:{port}"),
            RobotSpec::Ur {
                host,
                rtde_port,
                script_port,
            } if host.contains(':') => write!(f, "ur:[{host}]:{rtde_port}:{script_port}"),
            RobotSpec::Ur {
                host,
                rtde_port,
                script_port,
            } => write!(f, "ur:{host}:{rtde_port}:{script_port}"),
        }
    }
}

/// Why one bounded read from a controller's socket gave nothing.
pub(crate) enum ReadFailure {
    /// The deadline had passed: nothing was read.
    Deadline,
    /// The connection closed or broke: what the socket said.
    Lost(String),
}

/// Reads once from `stream`, handing what arrived to `received`, waiting
/// at most until `deadline`. `Ok` also when the wait ended early with
/// nothing: look at what was received, then read again. The drivers'
/// receive loops share it.
pub(crate) fn read_some(
    stream: &mut TcpStream,
    deadline: Instant,
    received: impl FnOnce(&[u8]),
) -> Result<(), ReadFailure> {
    let now = Instant::now();
    if now >= deadline {
        return Err(ReadFailure::Deadline);
    }
    let lost = |e: std::io::Error| ReadFailure::Lost(e.to_string());
    stream
        .set_read_timeout(Some(deadline - now))
        .map_err(lost)?;
    let mut chunk = [0u8; 4096];
    match stream.read(&mut chunk) {
        Ok(0) => Err(ReadFailure::Lost(
            "the controller closed the connection".into(),
        )),
        Ok(n) => {
            received(&chunk[..n]);
            Ok(())
        }
        Err(e)
            if matches!(
                e.kind(),
                ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
            ) =>
        {
            Ok(())
        }
        Err(e) => Err(lost(e)),
    }
}

/// Why [`connect_any`] failed: the addresses tried (`(unresolved)` if the
/// name did not resolve) and the last cause.
pub(crate) struct ConnectFailure {
    pub(crate) addr: String,
    pub(crate) source: std::io::Error,
}

/// Connects (no Nagle delay) to the first address of `addr` that answers
/// within `timeout`.
pub(crate) fn connect_any(
    addr: impl ToSocketAddrs,
    timeout: Duration,
) -> Result<(TcpStream, SocketAddr), ConnectFailure> {
    let addrs: Vec<SocketAddr> = addr
        .to_socket_addrs()
        .map_err(|source| ConnectFailure {
            addr: "(unresolved)".into(),
            source,
        })?
        .collect();
    let mut last = std::io::Error::new(ErrorKind::NotFound, "no address");
    for a in &addrs {
        match TcpStream::connect_timeout(a, timeout) {
            Ok(stream) => {
                let _ = stream.set_nodelay(true);
                return Ok((stream, *a));
            }
            Err(e) => last = e,
        }
    }
    Err(ConnectFailure {
        addr: addrs
            .iter()
            .map(|a| a.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        source: last,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_host_port_and_default_port() {
        let aubo = |h: &str, p| RobotSpec::Aubo {
            host: h.into(),
            port: p,
        };
        assert_eq!(
            RobotSpec::parse("aubo:10.0.0.5"),
            Ok(aubo("10.0.0.5", 30004))
        );
        assert_eq!(
            RobotSpec::parse("aubo:arm.lab:4000"),
            Ok(aubo("arm.lab", 4000))
        );
        assert_eq!(RobotSpec::parse("aubo:[::1]:31"), Ok(aubo("::1", 31)));
        assert_eq!(RobotSpec::parse("aubo:[::1]"), Ok(aubo("::1", 30004)));
        for s in ["aubo:10.0.0.5", "aubo:arm.lab:4000", "aubo:[::1]:31"] {
            let p = RobotSpec::parse(s).unwrap();
            assert_eq!(RobotSpec::parse(&p.to_string()), Ok(p));
        }
    }

    #[test]
    fn parses_ur_with_default_and_given_ports() {
        let ur = |h: &str, r, s| RobotSpec::Ur {
            host: h.into(),
            rtde_port: r,
            script_port: s,
        };
        assert_eq!(
            RobotSpec::parse("ur:10.0.0.7"),
            Ok(ur("10.0.0.7", 30004, 30002))
        );
        assert_eq!(RobotSpec::parse("UR:arm:4000"), Ok(ur("arm", 4000, 30002)));
        assert_eq!(
            RobotSpec::parse("ur:arm:4000:4001"),
            Ok(ur("arm", 4000, 4001))
        );
        assert_eq!(RobotSpec::parse("ur:[::1]:5:6"), Ok(ur("::1", 5, 6)));
        for s in ["ur:10.0.0.7", "ur:arm:4000:4001", "ur:[::1]:5:6"] {
            let p = RobotSpec::parse(s).unwrap();
            assert_eq!(RobotSpec::parse(&p.to_string()), Ok(p));
        }
        assert!(matches!(
            RobotSpec::parse("ur:arm:4000:x"),
            Err(RobotSpecError::BadPort { port, .. }) if port == "x"
        ));
        assert!(matches!(
            RobotSpec::parse("ur:"),
            Err(RobotSpecError::NoHost { .. })
        ));
    }

    #[test]
    fn rejects_bad_specs_naming_the_cause() {
        assert!(matches!(
            RobotSpec::parse("kuka:1.2.3.4"),
            Err(RobotSpecError::UnknownKind { kind, .. }) if kind == "kuka"
        ));
        assert!(matches!(
            RobotSpec::parse("aubo:"),
            Err(RobotSpecError::NoHost { .. })
        ));
        assert!(matches!(
            RobotSpec::parse("aubo:h:99999"),
            Err(RobotSpecError::BadPort { port, .. }) if port == "99999"
        ));
        assert!(matches!(
            RobotSpec::parse("aubo:h:0"),
            Err(RobotSpecError::BadPort { .. })
        ));
    }
}
