//! Robot arm drivers for `robimu record --robot KIND:HOST[:PORT]`.
//!
//! * [`aubo`]: AUBO arms over the ARCS controller's JSON-RPC (port 30004).

pub mod aubo;

use std::fmt;

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
}

/// Why a robot specification could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RobotSpecError {
    /// The kind before the first `:` is not a known robot.
    #[error("unknown robot kind {kind:?} in {spec:?} (expected aubo:HOST[:PORT])")]
    UnknownKind {
        /// The whole specification.
        spec: String,
        /// The kind given.
        kind: String,
    },
    /// No host after the kind.
    #[error("no host in robot {spec:?} (expected aubo:HOST[:PORT])")]
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
    /// Reads `aubo:HOST[:PORT]` (an IPv6 host in brackets: `aubo:[::1]:30004`).
    pub fn parse(spec: &str) -> Result<RobotSpec, RobotSpecError> {
        let (kind, rest) = spec.split_once(':').unwrap_or((spec, ""));
        if !kind.eq_ignore_ascii_case("aubo") {
            return Err(RobotSpecError::UnknownKind {
                spec: spec.to_string(),
                kind: kind.to_string(),
            });
        }
        let (host, port) = if let Some(bracketed) = rest.strip_prefix('[') {
            match bracketed.split_once(']') {
                Some((h, tail)) => (h, tail.strip_prefix(':')),
                None => (bracketed, None),
            }
        } else {
            match rest.rsplit_once(':') {
                Some((h, p)) => (h, Some(p)),
                None => (rest, None),
            }
        };
        if host.is_empty() {
            return Err(RobotSpecError::NoHost {
                spec: spec.to_string(),
            });
        }
        let port = match port {
            None => aubo::DEFAULT_PORT,
            Some(p) => match p.parse::<u16>() {
                Ok(n) if n > 0 => n,
                _ => {
                    return Err(RobotSpecError::BadPort {
                        spec: spec.to_string(),
                        port: p.to_string(),
                    })
                }
            },
        };
        Ok(RobotSpec::Aubo {
            host: host.to_string(),
            port,
        })
    }
}

impl fmt::Display for RobotSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RobotSpec::Aubo { host, port } if host.contains(':') => {
                write!(f, "aubo:[{host}]:{port}")
            }
            RobotSpec::Aubo { host, port } => write!(f, "aubo:{host}:{port}"),
        }
    }
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
    fn rejects_bad_specs_naming_the_cause() {
        assert!(matches!(
            RobotSpec::parse("ur:1.2.3.4"),
            Err(RobotSpecError::UnknownKind { kind, .. }) if kind == "ur"
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
