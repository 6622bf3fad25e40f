//! AUBO arm driver: a blocking JSON-RPC 2.0 client of the ARCS controller.
//!
//! The controller (port [`DEFAULT_PORT`]) takes requests
//! `{"jsonrpc":"2.0","method":"rob1.…","params":[…],"id":N}` and answers
//! `{"jsonrpc":"2.0","id":N,"result":…}` or `{…,"error":{"code","message"}}`,
//! as bare JSON objects with no delimiter: replies are parsed as a stream
//! and matched to requests by id (late replies to timed-out requests are
//! skipped). Method names and parameter shapes follow the JSON-RPC examples
//! of the ARCS SDK headers (`MotionControl`, `RobotState`). Motion methods
//! return a status code, not a JSON-RPC error, when the robot refuses them;
//! a non-zero status becomes [`AuboError::Refused`] with the code's name
//! ([`status_message`]). The code meanings are from the SDK's comments;
//! what the controller's own message would say is not known.
//!
//! [`JointPoller`] polls `getJointPositions` at a fixed rate in a thread.

use std::io::Write;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::thread;
use std::time::{Duration, Instant};

use robimu_controller_wire::{Pacer, StreamParser};
use serde_json::{json, Value};

use super::poller::{Poller, Source};
use super::{connect_any, read_some, ReadFailure};

/// The ARCS controller's JSON-RPC port.
pub(crate) const DEFAULT_PORT: u16 = 30004;

pub use super::{JointSample, Joints};

/// Why a robot call failed.
#[derive(Debug, thiserror::Error)]
pub enum AuboError {
    /// No TCP connection could be made.
    #[error("cannot connect to the AUBO controller at {addr}: {source}")]
    Connect {
        /// The address tried.
        addr: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The robot answered with an error or a non-zero status.
    #[error("the robot refused {method}: code {code}: {message}")]
    Refused {
        /// The JSON-RPC method.
        method: String,
        /// The JSON-RPC error code or ARCS status code.
        code: i64,
        /// The robot's message, or the status code's meaning.
        message: String,
    },
    /// The connection closed or broke.
    #[error("connection to the robot lost during {method}: {detail}")]
    Disconnected {
        /// The JSON-RPC method in flight.
        method: String,
        /// What the socket said.
        detail: String,
    },
    /// No reply in time.
    #[error("no reply to {method} within {timeout:?}")]
    Timeout {
        /// The JSON-RPC method.
        method: String,
        /// The time waited.
        timeout: Duration,
    },
    /// A reply that does not fit the protocol.
    #[error("protocol error in {method}: {detail}")]
    Protocol {
        /// The JSON-RPC method.
        method: String,
        /// What was wrong.
        detail: String,
    },
}

/// The meaning of an ARCS status code (from the SDK's comments).
pub(crate) fn status_message(code: i64) -> &'static str {
    match code {
        1 => "AUBO_BAD_STATE: safety mode is not Normal, Reduced or Recovery",
        2 => "AUBO_QUEUE_FULL: the trajectory queue is full",
        3 => "AUBO_BUSY: the previous command is still executing",
        -1 => "AUBO_BAD_STATE: the robot is not in a state that accepts this command",
        -4 => "AUBO_TIMEOUT: the controller timed out",
        -5 => "AUBO_INVL_ARGUMENT: argument out of range (limits, speed, buffer)",
        -13 => "AUBO_REQUEST_IGNORE: ignored (servo command while not in servo mode)",
        -18 => "AUBO_POS_BOUND_ERR: joint position beyond the robot's limits",
        -22 => "AUBO_TRAJ_SELF_COLLISION: the trajectory risks self-collision",
        -30 => "AUBO_ALGORITHM_PLAN_FAILED: trajectory planning failed",
        c if c > 0 => "warning: command not accepted",
        _ => "error",
    }
}

/// A connection to an AUBO ARCS controller.
#[derive(Debug)]
pub struct AuboClient {
    stream: TcpStream,
    peer: SocketAddr,
    replies: StreamParser,
    next_id: u64,
    timeout: Duration,
}

impl AuboClient {
    /// Connects; every call then waits at most `timeout` for its reply.
    pub fn connect(addr: impl ToSocketAddrs, timeout: Duration) -> Result<AuboClient, AuboError> {
        let (stream, peer) = connect_any(addr, timeout).map_err(|f| AuboError::Connect {
            addr: f.addr,
            source: f.source,
        })?;
        Ok(AuboClient {
            stream,
            peer,
            replies: StreamParser::default(),
            next_id: 1,
            timeout,
        })
    }

    /// The controller's address.
    pub fn peer(&self) -> SocketAddr {
        self.peer
    }

    /// Sends one request and waits for its result.
    pub fn call(&mut self, method: &str, params: Value) -> Result<Value, AuboError> {
        let id = self.next_id;
        self.next_id += 1;
        let request = json!({"jsonrpc": "2.0", "method": method, "params": params, "id": id});
        let lost = |e: std::io::Error| AuboError::Disconnected {
            method: method.to_string(),
            detail: e.to_string(),
        };
        self.stream
            .write_all(request.to_string().as_bytes())
            .map_err(lost)?;
        let deadline = Instant::now() + self.timeout;
        loop {
            while let Some(reply) = self.next_value(method)? {
                if reply.get("id").and_then(Value::as_u64) == Some(id) {
                    return reply_result(method, reply);
                }
                // A late reply to an earlier, timed-out request: skip.
            }
            let replies = &mut self.replies;
            read_some(&mut self.stream, deadline, |b| replies.push(b)).map_err(|f| match f {
                ReadFailure::Deadline => AuboError::Timeout {
                    method: method.to_string(),
                    timeout: self.timeout,
                },
                ReadFailure::Lost(detail) => AuboError::Disconnected {
                    method: method.to_string(),
                    detail,
                },
            })?;
        }
    }

    /// The next complete JSON value received.
    fn next_value(&mut self, method: &str) -> Result<Option<Value>, AuboError> {
        self.replies.next_value().map_err(|e| AuboError::Protocol {
            method: method.to_string(),
            detail: format!("reply is not JSON: {e}"),
        })
    }

    /// Calls a method that returns an ARCS status code; non-zero is refused.
    fn call_status(&mut self, method: &str, params: Value) -> Result<(), AuboError> {
        let result = self.call(method, params)?;
        match result.as_i64() {
            Some(0) => Ok(()),
            Some(code) => Err(AuboError::Refused {
                method: method.to_string(),
                code,
                message: status_message(code).to_string(),
            }),
            None => Err(AuboError::Protocol {
                method: method.to_string(),
                detail: format!("expected a status code, got {result}"),
            }),
        }
    }

    /// `RobotState.getJointPositions`: the joint angles, rad.
    pub fn joint_positions(&mut self) -> Result<Joints, AuboError> {
        let method = "rob1.RobotState.getJointPositions";
        let result = self.call(method, json!([]))?;
        joints_of(&result).ok_or_else(|| AuboError::Protocol {
            method: method.to_string(),
            detail: format!("expected 6 joint angles, got {result}"),
        })
    }

    /// `MotionControl.moveJoint(q, a, v, blend_radius = 0, duration = 0)`:
    /// queues a joint move (`a` rad/s², `v` rad/s).
    pub fn move_joint(&mut self, q: &Joints, a: f64, v: f64) -> Result<(), AuboError> {
        self.call_status("rob1.MotionControl.moveJoint", json!([q, a, v, 0.0, 0.0]))
    }

    /// `MotionControl.stopJoint(acc)`: stops any motion, decelerating at
    /// `acc` rad/s².
    pub fn stop_joint(&mut self, acc: f64) -> Result<(), AuboError> {
        self.call_status("rob1.MotionControl.stopJoint", json!([acc]))
    }

    /// `MotionControl.setServoMode(enable)`.
    pub fn set_servo_mode(&mut self, enable: bool) -> Result<(), AuboError> {
        self.call_status("rob1.MotionControl.setServoMode", json!([enable]))
    }

    /// `MotionControl.servoJoint(q, a = 0, v = 0, t, lookahead_time = 0.1,
    /// gain = 200)`: reach `q` in `t` seconds (servo mode only).
    pub fn servo_joint(&mut self, q: &Joints, t: f64) -> Result<(), AuboError> {
        self.call_status(
            "rob1.MotionControl.servoJoint",
            json!([q, 0.0, 0.0, t, 0.1, 200.0]),
        )
    }

    /// `MotionControl.pathBufferAlloc(name, type, size)`; type 2 is a
    /// recorded trajectory sampled at a fixed interval.
    pub fn path_buffer_alloc(
        &mut self,
        name: &str,
        kind: i64,
        size: usize,
    ) -> Result<(), AuboError> {
        self.call_status(
            "rob1.MotionControl.pathBufferAlloc",
            json!([name, kind, size]),
        )
    }

    /// `MotionControl.pathBufferAppend(name, waypoints)`.
    pub fn path_buffer_append(
        &mut self,
        name: &str,
        waypoints: &[Joints],
    ) -> Result<(), AuboError> {
        self.call_status(
            "rob1.MotionControl.pathBufferAppend",
            json!([name, waypoints]),
        )
    }

    /// `MotionControl.pathBufferEval(name, a, v, t)`: checks the buffer
    /// against per-joint limits `a`, `v`; for type 2 `t` is the sampling
    /// interval, s.
    pub fn path_buffer_eval(
        &mut self,
        name: &str,
        a: &Joints,
        v: &Joints,
        t: f64,
    ) -> Result<(), AuboError> {
        self.call_status("rob1.MotionControl.pathBufferEval", json!([name, a, v, t]))
    }

    /// `MotionControl.movePathBuffer(name)`: queues the evaluated buffer.
    pub fn path_buffer_move(&mut self, name: &str) -> Result<(), AuboError> {
        self.call_status("rob1.MotionControl.movePathBuffer", json!([name]))
    }

    /// `MotionControl.getExecId`: the running motion's id, `None` when idle.
    pub fn exec_id(&mut self) -> Result<Option<i64>, AuboError> {
        let method = "rob1.MotionControl.getExecId";
        let result = self.call(method, json!([]))?;
        match result.as_i64() {
            Some(-1) => Ok(None),
            Some(id) => Ok(Some(id)),
            None => Err(AuboError::Protocol {
                method: method.to_string(),
                detail: format!("expected an integer, got {result}"),
            }),
        }
    }

    /// Polls [`AuboClient::exec_id`] every 10 ms until no motion runs.
    pub fn wait_idle(&mut self, timeout: Duration) -> Result<(), AuboError> {
        let deadline = Instant::now() + timeout;
        while self.exec_id()?.is_some() {
            if Instant::now() >= deadline {
                return Err(AuboError::Timeout {
                    method: "rob1.MotionControl.getExecId (waiting for the motion to end)".into(),
                    timeout,
                });
            }
            thread::sleep(Duration::from_millis(10));
        }
        Ok(())
    }
}

fn joints_of(v: &Value) -> Option<Joints> {
    let a = v.as_array()?;
    if a.len() != 6 {
        return None;
    }
    let mut q = [0.0; 6];
    for (qi, x) in q.iter_mut().zip(a) {
        *qi = x.as_f64()?;
    }
    Some(q)
}

/// The result of a reply, or its error as [`AuboError::Refused`].
fn reply_result(method: &str, mut reply: Value) -> Result<Value, AuboError> {
    if let Some(error) = reply.get("error") {
        return Err(AuboError::Refused {
            method: method.to_string(),
            code: error.get("code").and_then(Value::as_i64).unwrap_or(0),
            message: error
                .get("message")
                .and_then(Value::as_str)
                .unwrap_or("(no message)")
                .to_string(),
        });
    }
    reply
        .get_mut("result")
        .map(Value::take)
        .ok_or_else(|| AuboError::Protocol {
            method: method.to_string(),
            detail: "reply has neither result nor error".into(),
        })
}

/// Polls `getJointPositions` at a fixed rate in a thread; samples, then at
/// most one error (after which polling stops), arrive on
/// [`Poller::samples`]; [`Poller::stop`] returns the client unless polling
/// had failed.
pub type JointPoller = Poller<AuboClient, AuboError>;

impl JointPoller {
    /// Starts polling at `rate_hz`; times are seconds since `epoch`.
    pub fn spawn(
        client: AuboClient,
        rate_hz: f64,
        epoch: Instant,
    ) -> Result<JointPoller, AuboError> {
        let source = Polling {
            client,
            epoch,
            pacer: Pacer::new(Duration::from_secs_f64(1.0 / rate_hz.max(1e-3))),
        };
        Poller::start("aubo-poller", source).map_err(|e| AuboError::Disconnected {
            method: "rob1.RobotState.getJointPositions".into(),
            detail: format!("cannot start the polling thread: {e}"),
        })
    }
}

/// The AUBO side of a [`JointPoller`].
struct Polling {
    client: AuboClient,
    epoch: Instant,
    pacer: Pacer,
}

impl Source for Polling {
    type Client = AuboClient;
    type Error = AuboError;

    /// One `getJointPositions`, timed at the midpoint of request and reply.
    fn read(&mut self) -> Result<JointSample, AuboError> {
        let sent = Instant::now();
        let reading = self.client.joint_positions();
        let received = Instant::now();
        let t = (sent.duration_since(self.epoch).as_secs_f64()
            + received.duration_since(self.epoch).as_secs_f64())
            / 2.0;
        reading.map(|q| JointSample {
            t,
            q,
            robot_t: None,
        })
    }

    fn after_sample(&mut self) {
        self.pacer.wait();
    }

    fn finish(self) -> Option<AuboClient> {
        Some(self.client)
    }
}
