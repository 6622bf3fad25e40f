//! Universal Robots driver: RTDE for joint readings, URScript for motion.
//!
//! RTDE (port [`RTDE_PORT`]) is a stream of big-endian packages, each
//! `uint16 size` (including this 3-byte header), `uint8 type`, payload:
//!
//! | type | client sends | controller replies |
//! | --- | --- | --- |
//! | `V` request protocol version | `uint16 version` | `uint8 accepted` |
//! | `O` setup outputs | `double frequency`, names `a,b,…` | `uint8 recipe id`, types `DOUBLE,VECTOR6D,…` (`NOT_FOUND` for an unknown name) |
//! | `S` start | — | `uint8 accepted` |
//! | `P` pause | — | `uint8 accepted` |
//! | `U` data package | — | `uint8 recipe id`, the values in recipe order |
//! | `M` text message | — | `uint8 length`, message, `uint8 length`, source, `uint8 warning level` |
//!
//! After `S` the controller sends a `U` package per control cycle divided
//! down to the requested frequency (125 Hz at most on CB-series, 500 Hz on
//! e-Series). [`UrClient`] reads `timestamp` (DOUBLE, s since the
//! controller started) and `actual_q` (VECTOR6D, rad) into joint samples
//! carrying both the controller's timestamp and the host's receive time;
//! [`UrPoller`] does so in a thread. Motion is a URScript program sent to
//! the secondary interface ([`SCRIPT_PORT`]): [`plan_script`] turns a plan
//! of `(t, q)` rows into `movej` to the first row and one `servoj` per
//! later row, with `t` the row's interval.

use std::io::Write;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use robimu_controller_wire::rtde::{self, BadSize, PackageParser, TooLong};

use super::poller::{Poller, Source};
use super::{read_some, JointSample, Joints, ReadFailure};

/// RTDE's TCP port.
pub const RTDE_PORT: u16 = 30004;
/// The secondary client interface, which runs URScript programs sent to it.
pub const SCRIPT_PORT: u16 = 30002;
/// The RTDE protocol version this client speaks.
pub const PROTOCOL_VERSION: u16 = 2;
/// The outputs a joint sample needs.
pub const SAMPLE_OUTPUTS: [&str; 2] = ["timestamp", "actual_q"];

/// RTDE package types.
pub use robimu_controller_wire::rtde::package;

/// Why a UR call failed.
#[derive(Debug, thiserror::Error)]
pub enum UrError {
    /// No TCP connection could be made.
    #[error("cannot connect to the UR controller at {addr}: {source}")]
    Connect {
        /// The address tried.
        addr: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The controller does not speak this protocol version.
    #[error("the UR controller refused RTDE protocol version {version}")]
    VersionRefused {
        /// The version asked for.
        version: u16,
    },
    /// An output name the controller does not know (`NOT_FOUND`), or a type
    /// this client cannot read.
    #[error("the UR controller cannot send {names:?}: types {types:?}")]
    BadRecipe {
        /// The names that failed.
        names: Vec<String>,
        /// The controller's type list.
        types: String,
    },
    /// A control request was not accepted.
    #[error("the UR controller refused {what}")]
    Refused {
        /// The request.
        what: String,
    },
    /// The connection closed or broke.
    #[error("connection to the UR controller lost during {during}: {detail}")]
    Disconnected {
        /// What was in progress.
        during: String,
        /// What the socket said.
        detail: String,
    },
    /// No reply in time.
    #[error("no reply to {during} within {timeout:?}")]
    Timeout {
        /// What was waited for.
        during: String,
        /// The time waited.
        timeout: Duration,
    },
    /// Bytes that do not fit the protocol.
    #[error("RTDE protocol error during {during}: {detail}")]
    Protocol {
        /// What was in progress.
        during: String,
        /// What was wrong.
        detail: String,
    },
    /// A plan that cannot be turned into a program.
    #[error("cannot run the plan: {0}")]
    Plan(String),
}

/// An RTDE field type and its size on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    /// f64.
    Double,
    /// 3 × f64.
    Vector3D,
    /// 6 × f64.
    Vector6D,
    /// 6 × i32.
    Vector6Int32,
    /// 6 × u32.
    Vector6Uint32,
    /// i32.
    Int32,
    /// u32.
    Uint32,
    /// u64.
    Uint64,
    /// u8 (0 or 1).
    Bool,
    /// u8.
    Uint8,
}

impl FieldType {
    /// The type named in a setup reply.
    pub fn parse(name: &str) -> Option<FieldType> {
        Some(match name {
            "DOUBLE" => FieldType::Double,
            "VECTOR3D" => FieldType::Vector3D,
            "VECTOR6D" => FieldType::Vector6D,
            "VECTOR6INT32" => FieldType::Vector6Int32,
            "VECTOR6UINT32" => FieldType::Vector6Uint32,
            "INT32" => FieldType::Int32,
            "UINT32" => FieldType::Uint32,
            "UINT64" => FieldType::Uint64,
            "BOOL" => FieldType::Bool,
            "UINT8" => FieldType::Uint8,
            _ => return None,
        })
    }

    /// Bytes on the wire.
    pub fn size(self) -> usize {
        match self {
            FieldType::Double | FieldType::Uint64 => 8,
            FieldType::Vector3D => 24,
            FieldType::Vector6D => 48,
            FieldType::Vector6Int32 | FieldType::Vector6Uint32 => 24,
            FieldType::Int32 | FieldType::Uint32 => 4,
            FieldType::Bool | FieldType::Uint8 => 1,
        }
    }

    /// The value's numbers (one for scalars).
    fn decode(self, b: &[u8]) -> Vec<f64> {
        let f = |i: usize| f64::from_be_bytes(b[8 * i..8 * i + 8].try_into().expect("8 bytes"));
        let u = |i: usize| u32::from_be_bytes(b[4 * i..4 * i + 4].try_into().expect("4 bytes"));
        match self {
            FieldType::Double => vec![f(0)],
            FieldType::Vector3D => (0..3).map(f).collect(),
            FieldType::Vector6D => (0..6).map(f).collect(),
            FieldType::Vector6Int32 => (0..6).map(|i| u(i) as i32 as f64).collect(),
            FieldType::Vector6Uint32 => (0..6).map(|i| u(i) as f64).collect(),
            FieldType::Int32 => vec![u(0) as i32 as f64],
            FieldType::Uint32 => vec![u(0) as f64],
            FieldType::Uint64 => {
                vec![u64::from_be_bytes(b[..8].try_into().expect("8 bytes")) as f64]
            }
            FieldType::Bool | FieldType::Uint8 => vec![b[0] as f64],
        }
    }
}

/// An output recipe the controller accepted.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    /// The id data packages carry.
    pub id: u8,
    /// The output names, in order.
    pub names: Vec<String>,
    /// Their types.
    pub types: Vec<FieldType>,
}

impl Recipe {
    /// Bytes of a data package's values.
    pub fn size(&self) -> usize {
        self.types.iter().map(|t| t.size()).sum()
    }

    fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }
}

/// One joint reading from a data package.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UrSample {
    /// The controller's `timestamp`, s since it started.
    pub robot_t: f64,
    /// Host time when the package was complete, s since the caller's epoch.
    pub host_t: f64,
    /// `actual_q`, rad.
    pub q: Joints,
}

impl UrSample {
    /// As a [`JointSample`] on the host clock.
    pub fn joint_sample(&self) -> JointSample {
        JointSample {
            t: self.host_t,
            q: self.q,
            robot_t: Some(self.robot_t),
        }
    }
}

/// An RTDE connection.
#[derive(Debug)]
pub struct UrClient {
    stream: TcpStream,
    peer: SocketAddr,
    packages: PackageParser,
    timeout: Duration,
    recipe: Option<Recipe>,
}

/// Connects to the first address of `addr` that answers.
fn connect_any(
    addr: impl ToSocketAddrs,
    timeout: Duration,
) -> Result<(TcpStream, SocketAddr), UrError> {
    super::connect_any(addr, timeout).map_err(|f| UrError::Connect {
        addr: f.addr,
        source: f.source,
    })
}

impl UrClient {
    /// Connects; every request then waits at most `timeout` for its reply.
    pub fn connect(addr: impl ToSocketAddrs, timeout: Duration) -> Result<UrClient, UrError> {
        let (stream, peer) = connect_any(addr, timeout)?;
        Ok(UrClient {
            stream,
            peer,
            packages: PackageParser::default(),
            timeout,
            recipe: None,
        })
    }

    /// Connects, negotiates [`PROTOCOL_VERSION`], sets up
    /// [`SAMPLE_OUTPUTS`] at `frequency_hz` and starts the data stream.
    pub fn open_stream(
        addr: impl ToSocketAddrs,
        frequency_hz: f64,
        timeout: Duration,
    ) -> Result<UrClient, UrError> {
        let mut c = UrClient::connect(addr, timeout)?;
        c.negotiate_version(PROTOCOL_VERSION)?;
        c.setup_outputs(frequency_hz, &SAMPLE_OUTPUTS)?;
        c.start()?;
        Ok(c)
    }

    /// The controller's address.
    pub fn peer(&self) -> SocketAddr {
        self.peer
    }

    /// The accepted output recipe.
    pub fn recipe(&self) -> Option<&Recipe> {
        self.recipe.as_ref()
    }

    fn send(&mut self, kind: u8, payload: &[u8], during: &str) -> Result<(), UrError> {
        let out = rtde::encode(kind, payload).map_err(|TooLong(size)| UrError::Protocol {
            during: during.into(),
            detail: format!("package of {size} bytes is too long"),
        })?;
        self.stream
            .write_all(&out)
            .map_err(|e| UrError::Disconnected {
                during: during.into(),
                detail: e.to_string(),
            })
    }

    /// The next package of a type in `kinds` (text messages and, unless
    /// asked for, data packages are skipped), waiting until `deadline`.
    fn receive(
        &mut self,
        kinds: &[u8],
        during: &str,
        deadline: Instant,
    ) -> Result<(u8, Vec<u8>), UrError> {
        loop {
            let next = self
                .packages
                .next_package()
                .map_err(|BadSize(size)| UrError::Protocol {
                    during: during.into(),
                    detail: format!("package size {size} is less than its header"),
                })?;
            if let Some((kind, payload)) = next {
                if kinds.contains(&kind) {
                    return Ok((kind, payload));
                }
                // Text messages and packages of other requests: skipped.
                continue;
            }
            let packages = &mut self.packages;
            read_some(&mut self.stream, deadline, |b| packages.push(b)).map_err(|f| match f {
                ReadFailure::Deadline => UrError::Timeout {
                    during: during.into(),
                    timeout: self.timeout,
                },
                ReadFailure::Lost(detail) => UrError::Disconnected {
                    during: during.into(),
                    detail,
                },
            })?;
        }
    }

    /// Sends a request and waits for the reply of the same type.
    fn request(&mut self, kind: u8, payload: &[u8], during: &str) -> Result<Vec<u8>, UrError> {
        self.send(kind, payload, during)?;
        let deadline = Instant::now() + self.timeout;
        Ok(self.receive(&[kind], during, deadline)?.1)
    }

    fn accepted(&mut self, kind: u8, payload: &[u8], during: &str) -> Result<bool, UrError> {
        let reply = self.request(kind, payload, during)?;
        match reply.as_slice() {
            [a] => Ok(*a != 0),
            _ => Err(UrError::Protocol {
                during: during.into(),
                detail: format!("expected a 1-byte accepted flag, got {} bytes", reply.len()),
            }),
        }
    }

    /// `V`: asks for protocol `version`.
    pub fn negotiate_version(&mut self, version: u16) -> Result<(), UrError> {
        let during = format!("the protocol version request ({version})");
        if self.accepted(
            package::REQUEST_PROTOCOL_VERSION,
            &version.to_be_bytes(),
            &during,
        )? {
            Ok(())
        } else {
            Err(UrError::VersionRefused { version })
        }
    }

    /// `O`: asks for `names` at `frequency_hz`; the accepted recipe.
    pub fn setup_outputs(&mut self, frequency_hz: f64, names: &[&str]) -> Result<Recipe, UrError> {
        let during = "the output setup";
        let mut payload = frequency_hz.to_be_bytes().to_vec();
        payload.extend_from_slice(names.join(",").as_bytes());
        let reply = self.request(package::SETUP_OUTPUTS, &payload, during)?;
        let Some((&id, types)) = reply.split_first() else {
            return Err(UrError::Protocol {
                during: during.into(),
                detail: "empty reply".into(),
            });
        };
        let types = String::from_utf8_lossy(types).into_owned();
        let list: Vec<&str> = types.split(',').collect();
        if list.len() != names.len() {
            return Err(UrError::Protocol {
                during: during.into(),
                detail: format!(
                    "{} types for {} outputs: {types:?}",
                    list.len(),
                    names.len()
                ),
            });
        }
        let parsed: Vec<Option<FieldType>> = list.iter().map(|t| FieldType::parse(t)).collect();
        let bad: Vec<String> = names
            .iter()
            .zip(&parsed)
            .filter(|(_, t)| t.is_none())
            .map(|(n, _)| n.to_string())
            .collect();
        if !bad.is_empty() {
            return Err(UrError::BadRecipe { names: bad, types });
        }
        if id == 0 {
            return Err(UrError::Refused {
                what: format!(
                    "the output setup at {frequency_hz} Hz (recipe id 0: is the frequency above the controller's rate?)"
                ),
            });
        }
        let recipe = Recipe {
            id,
            names: names.iter().map(|n| n.to_string()).collect(),
            types: parsed.into_iter().flatten().collect(),
        };
        self.recipe = Some(recipe.clone());
        Ok(recipe)
    }

    /// `S`: starts the data stream.
    pub fn start(&mut self) -> Result<(), UrError> {
        if self.accepted(package::START, &[], "start")? {
            Ok(())
        } else {
            Err(UrError::Refused {
                what: "start (no output recipe set up?)".into(),
            })
        }
    }

    /// `P`: pauses the data stream (data packages still in flight are
    /// skipped).
    pub fn pause(&mut self) -> Result<(), UrError> {
        if self.accepted(package::PAUSE, &[], "pause")? {
            Ok(())
        } else {
            Err(UrError::Refused {
                what: "pause".into(),
            })
        }
    }

    /// The next data package's values, one `Vec` per recipe output.
    pub fn read_data(&mut self) -> Result<Vec<Vec<f64>>, UrError> {
        let during = "reading data packages";
        let deadline = Instant::now() + self.timeout;
        let (_, payload) = self.receive(&[package::DATA_PACKAGE], during, deadline)?;
        let recipe = self.recipe.as_ref().ok_or_else(|| UrError::Protocol {
            during: during.into(),
            detail: "a data package before any output setup".into(),
        })?;
        let expected = recipe.size() + 1;
        if payload.len() != expected || payload[0] != recipe.id {
            return Err(UrError::Protocol {
                during: during.into(),
                detail: format!(
                    "data package of {} bytes for recipe {} (expected {expected} bytes for recipe {})",
                    payload.len(),
                    payload.first().copied().unwrap_or(0),
                    recipe.id
                ),
            });
        }
        let mut at = 1;
        Ok(recipe
            .types
            .iter()
            .map(|t| {
                let v = t.decode(&payload[at..at + t.size()]);
                at += t.size();
                v
            })
            .collect())
    }

    /// The next data package as a joint sample (the recipe must hold
    /// `timestamp` and `actual_q`); `host_t` is seconds since `epoch`.
    pub fn read_sample(&mut self, epoch: Instant) -> Result<UrSample, UrError> {
        let values = self.read_data()?;
        let host_t = epoch.elapsed().as_secs_f64();
        let recipe = self.recipe.as_ref().expect("read_data checked the recipe");
        let (Some(ti), Some(qi)) = (recipe.index("timestamp"), recipe.index("actual_q")) else {
            return Err(UrError::Protocol {
                during: "reading joint samples".into(),
                detail: format!("the recipe {:?} lacks timestamp or actual_q", recipe.names),
            });
        };
        let q: Joints = values[qi]
            .as_slice()
            .try_into()
            .map_err(|_| UrError::Protocol {
                during: "reading joint samples".into(),
                detail: "actual_q is not a VECTOR6D".into(),
            })?;
        Ok(UrSample {
            robot_t: values[ti][0],
            host_t,
            q,
        })
    }
}

/// Reads data packages in a thread; samples, then at most one error (after
/// which reading stops), arrive on [`Poller::samples`]. The same poller as
/// [`super::aubo::JointPoller`]; each sample carries the controller's
/// timestamp in [`JointSample::robot_t`]. [`Poller::stop`] pauses the
/// stream and returns the client unless reading or pausing failed.
pub(crate) type UrPoller = Poller<UrClient, UrError>;

impl UrPoller {
    /// Starts reading from a client whose data stream is started (see
    /// [`UrClient::open_stream`]); host times are seconds since `epoch`.
    pub fn spawn(client: UrClient, epoch: Instant) -> Result<UrPoller, UrError> {
        Poller::start("ur-rtde", Streaming { client, epoch }).map_err(|e| UrError::Disconnected {
            during: "starting the RTDE reader".into(),
            detail: format!("cannot start the thread: {e}"),
        })
    }
}

/// The UR side of a [`UrPoller`].
struct Streaming {
    client: UrClient,
    epoch: Instant,
}

impl Source for Streaming {
    type Client = UrClient;
    type Error = UrError;

    fn read(&mut self) -> Result<JointSample, UrError> {
        self.client
            .read_sample(self.epoch)
            .map(|s| s.joint_sample())
    }

    /// Pauses the stream.
    fn finish(mut self) -> Option<UrClient> {
        self.client.pause().ok().map(|_| self.client)
    }
}

/// The URScript program that runs a plan of `(t, q)` rows (s, rad):
/// `movej` to the first row, then one `servoj` per later row with
/// `t` = that row's interval.
///
/// ```text
/// def robimu_plan():
///   movej([q0], a=1.0, v=0.5)
///   servoj([q1], t=Δt1, lookahead_time=0.1, gain=300)
///   …
///   stopj(2.0)
/// end
/// robimu_plan()
/// ```
pub(crate) fn plan_script(plan: &[(f64, Vec<f64>)]) -> Result<String, UrError> {
    if plan.len() < 2 {
        return Err(UrError::Plan(format!(
            "{} rows; a plan needs at least 2",
            plan.len()
        )));
    }
    let mut s = String::from("def robimu_plan():\n");
    let vector = |q: &[f64]| {
        q.iter()
            .map(|x| format!("{x:.9}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for (k, (t, q)) in plan.iter().enumerate() {
        if q.len() != 6 {
            return Err(UrError::Plan(format!(
                "row {k}: {} joints, a UR arm has 6",
                q.len()
            )));
        }
        if !t.is_finite() || q.iter().any(|x| !x.is_finite()) {
            return Err(UrError::Plan(format!("row {k}: not a finite number")));
        }
        if k == 0 {
            s.push_str(&format!("  movej([{}], a=1.0, v=0.5)\n", vector(q)));
            continue;
        }
        let dt = t - plan[k - 1].0;
        if dt <= 0.0 {
            return Err(UrError::Plan(format!(
                "row {k}: time {t} s does not increase (previous {} s)",
                plan[k - 1].0
            )));
        }
        s.push_str(&format!(
            "  servoj([{}], t={dt:.6}, lookahead_time=0.1, gain=300)\n",
            vector(q)
        ));
    }
    s.push_str("  stopj(2.0)\nend\nrobimu_plan()\n");
    Ok(s)
}

/// Ports of a UR controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UrPorts {
    /// RTDE.
    pub rtde: u16,
    /// The secondary interface (URScript).
    pub script: u16,
}

impl Default for UrPorts {
    fn default() -> Self {
        UrPorts {
            rtde: RTDE_PORT,
            script: SCRIPT_PORT,
        }
    }
}

/// A UR arm: where it is and how long to wait for it. Each call opens its
/// own connection.
#[derive(Debug, Clone)]
pub struct UrRobot {
    host: String,
    ports: UrPorts,
    timeout: Duration,
}

impl UrRobot {
    /// Checks that the controller answers RTDE (protocol version 2).
    pub fn connect(host: &str, ports: UrPorts, timeout: Duration) -> Result<UrRobot, UrError> {
        let mut c = UrClient::connect((host, ports.rtde), timeout)?;
        c.negotiate_version(PROTOCOL_VERSION)?;
        Ok(UrRobot {
            host: host.to_string(),
            ports,
            timeout,
        })
    }

    /// Starts reading joint samples at `rate_hz` (125 or 500 Hz are the
    /// controllers' own rates) on a new RTDE connection; host times are
    /// seconds since `epoch`.
    pub fn spawn_poller(&self, rate_hz: f64, epoch: Instant) -> Result<UrPoller, UrError> {
        let client =
            UrClient::open_stream((self.host.as_str(), self.ports.rtde), rate_hz, self.timeout)?;
        UrPoller::spawn(client, epoch)
    }

    /// Stops the arm: a program of one `stopj(a)` (`a` rad/s²) replaces the
    /// one running.
    pub fn stop(&self, a: f64) -> Result<(), UrError> {
        self.send_program(&format!("def robimu_stop():\n  stopj({a:.3})\nend\n"))
    }

    fn send_program(&self, script: &str) -> Result<(), UrError> {
        let (mut stream, _) = connect_any((self.host.as_str(), self.ports.script), self.timeout)?;
        let lost = |e: std::io::Error| UrError::Disconnected {
            during: "sending the program".into(),
            detail: e.to_string(),
        };
        stream.set_write_timeout(Some(self.timeout)).map_err(lost)?;
        stream.write_all(script.as_bytes()).map_err(lost)?;
        stream.shutdown(std::net::Shutdown::Write).map_err(lost)?;
        Ok(())
    }

    /// Sends the plan's program ([`plan_script`]) to the script port; the
    /// robot starts it at once. Returns the plan's duration, s (the move to
    /// the first row comes before it).
    pub fn execute_plan(&self, plan: &[(f64, Vec<f64>)]) -> Result<f64, UrError> {
        self.send_program(&plan_script(plan)?)?;
        Ok(plan[plan.len() - 1].0 - plan[0].0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_types_decode_big_endian() {
        let mut b = Vec::new();
        for x in [1.5f64, -2.0, 0.0, 3.25, 1e-9, -7.0] {
            b.extend_from_slice(&x.to_be_bytes());
        }
        assert_eq!(
            FieldType::Vector6D.decode(&b),
            vec![1.5, -2.0, 0.0, 3.25, 1e-9, -7.0]
        );
        assert_eq!(FieldType::Int32.decode(&(-5i32).to_be_bytes()), vec![-5.0]);
        assert_eq!(FieldType::Uint32.decode(&[0, 0, 1, 0]), vec![256.0]);
        assert_eq!(FieldType::parse("NOT_FOUND"), None);
        assert_eq!(FieldType::parse("VECTOR6D").unwrap().size(), 48);
    }

    #[test]
    fn plan_script_has_one_servoj_per_row_and_rejects_bad_plans() {
        let plan: Vec<(f64, Vec<f64>)> = (0..4)
            .map(|k| (0.5 + 0.01 * k as f64, vec![0.1 * k as f64; 6]))
            .collect();
        let s = plan_script(&plan).unwrap();
        assert!(
            s.starts_with("def robimu_plan():\n  movej([0.000000000, "),
            "{s}"
        );
        assert_eq!(s.matches("servoj(").count(), 3);
        assert!(s.contains("servoj([0.300000000, 0.300000000, 0.300000000, 0.300000000, 0.300000000, 0.300000000], t=0.010000, lookahead_time=0.1, gain=300)"), "{s}");
        assert!(s.ends_with("end\nrobimu_plan()\n"));
        let mut back = plan.clone();
        back[2].0 = 0.5;
        assert!(plan_script(&back)
            .unwrap_err()
            .to_string()
            .contains("row 2"));
        let mut five = plan.clone();
        five[1].1.pop();
        assert!(plan_script(&five).unwrap_err().to_string().contains("6"));
        assert!(plan_script(&plan[..1]).is_err());
    }
}
