//! A simulated AUBO arm controller on loopback TCP.
//!
//! [`SimAubo::spawn`] listens where [`SimAuboConfig::bind`] says and speaks
//! the JSON-RPC 2.0 interface of AUBO's ARCS controller (real port 30004):
//! requests and replies are bare JSON objects, concatenated with no
//! delimiter, so each connection parses its byte stream incrementally
//! ([`StreamParser`]); whitespace between objects is tolerated.
//!
//! Methods (names and parameter shapes as in the ARCS SDK headers'
//! JSON-RPC examples; `rob1` is the robot name):
//!
//! | method | params | result |
//! | --- | --- | --- |
//! | `rob1.RobotState.getJointPositions` | `[]` | six joint angles, rad |
//! | `rob1.MotionControl.moveJoint` | `[q, a, v, blend_radius, duration]` | status |
//! | `rob1.MotionControl.setServoMode` | `[enable]` | status |
//! | `rob1.MotionControl.isServoModeEnabled` | `[]` | bool |
//! | `rob1.MotionControl.servoJoint` | `[q, a, v, t, lookahead_time, gain]` | status |
//! | `rob1.MotionControl.pathBufferAlloc` | `[name, type, size]` | status |
//! | `rob1.MotionControl.pathBufferAppend` | `[name, [q, …]]` | status |
//! | `rob1.MotionControl.pathBufferEval` | `[name, a[6], v[6], t]` | status |
//! | `rob1.MotionControl.movePathBuffer` | `[name]` | status |
//! | `rob1.MotionControl.pathBufferFree` | `[name]` | status |
//! | `rob1.MotionControl.getExecId` | `[]` | id of the running motion, −1 idle |
//! | `rob1.MotionControl.stopJoint` | `[acc]` | status |
//!
//! As on the real controller, a refused motion is not a JSON-RPC error: the
//! result is a status code (0 success; negative an error, positive a
//! warning such as busy): −1 `AUBO_BAD_STATE`, −5 `AUBO_INVL_ARGUMENT`
//! (out of the velocity/acceleration limits, unknown buffer), −13
//! `AUBO_REQUEST_IGNORE` (`servoJoint` outside servo mode), −18
//! `AUBO_POS_BOUND_ERR` (a target beyond the position limits), 3
//! `AUBO_BUSY`. Protocol faults are JSON-RPC errors: −32700 parse error,
//! −32600 invalid request, −32601 unknown method, −32602 bad params.
//!
//! Motion model. Commands feed a reference `r(t)`: `moveJoint` queues a
//! synchronised trapezoidal move (speed and acceleration `v`, `a` clamped to
//! the joints' limits; `blend_radius` and `duration` ignored);
//! `movePathBuffer` queues a path buffer of type 2 (the SDK's
//! "cubic_spline, recorded trajectory"), whose waypoints are `t` seconds
//! apart, `t` being the sampling interval given to `pathBufferEval` (the
//! SDK: "type 2: t is the sampling interval"); the buffer must hold at least
//! `size` points and be evaluated before it moves, and its first point must
//! be where the previous motion ends (within 0.01 rad). Waypoints are joined
//! by cubic Hermite segments with central-difference tangents. In servo
//! mode `servoJoint(q, …, t, …)` ramps the reference linearly to `q` over
//! `t` seconds. The true joint angles follow `r(t)` through a first-order
//! lag of time constant [`SimAuboConfig::tracking_lag_s`], integrated in
//! steps of at most 2 ms by a 500 Hz simulation thread and, exactly at the
//! request time, by each `getJointPositions`, whose reply adds Gaussian
//! encoder noise. Every integration step is logged with its time (seconds
//! since [`SimAuboConfig::epoch`]): [`SimAubo::true_trajectory`].

// Joint loops index several joint vectors in step.
#![allow(clippy::needless_range_loop)]

use std::collections::{HashMap, VecDeque};
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use crate::server::{self, lock, Server};

/// Number of joints of the simulated arm.
pub const JOINTS: usize = 6;

/// A joint vector, rad.
pub type Joints = [f64; JOINTS];

/// Largest integration step of the simulation, s.
const MAX_STEP_S: f64 = 0.002;
/// How far a path buffer's first point may be from the planned position, rad.
const PATH_START_TOLERANCE: f64 = 0.01;

/// ARCS status codes the simulator returns.
pub mod status {
    /// Success.
    pub const OK: i64 = 0;
    /// The previous command is still executing (warning: not accepted).
    pub const BUSY: i64 = 3;
    /// The robot is not in a state that accepts the command.
    pub const BAD_STATE: i64 = -1;
    /// An argument is out of range (velocity, acceleration, buffer, …).
    pub const INVL_ARGUMENT: i64 = -5;
    /// The command is ignored (servo command outside servo mode).
    pub const REQUEST_IGNORE: i64 = -13;
    /// A joint target is beyond the position limits.
    pub const POS_BOUND_ERR: i64 = -18;
}

/// Per-joint limits of the simulated arm.
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimits {
    /// Lower position limits, rad.
    pub position_min: Joints,
    /// Upper position limits, rad.
    pub position_max: Joints,
    /// Speed limits, rad/s.
    pub velocity: Joints,
    /// Acceleration limits, rad/s².
    pub acceleration: Joints,
}

impl JointLimits {
    /// The same limits on every joint.
    pub fn uniform(position: f64, velocity: f64, acceleration: f64) -> Self {
        JointLimits {
            position_min: [-position; JOINTS],
            position_max: [position; JOINTS],
            velocity: [velocity; JOINTS],
            acceleration: [acceleration; JOINTS],
        }
    }

    fn within_position(&self, q: &Joints) -> bool {
        (0..JOINTS).all(|i| q[i] >= self.position_min[i] && q[i] <= self.position_max[i])
    }
}

impl Default for JointLimits {
    /// About an AUBO i5: ±175° joints (exactly: no less than its
    /// description's, so that a plan at the limit is accepted), 180°/s,
    /// 1000°/s².
    fn default() -> Self {
        JointLimits::uniform(175f64.to_radians(), std::f64::consts::PI, 17.4)
    }
}

/// Faults the simulator can inject; changeable while it runs
/// ([`SimAubo::set_faults`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultSwitches {
    /// Wait before every reply.
    pub reply_delay: Duration,
    /// Close each connection, without a reply, when it sends a request after
    /// this many answered requests.
    pub drop_connection_after: Option<usize>,
    /// Refuse every motion command with `AUBO_BAD_STATE` (as a robot in
    /// protective stop does).
    pub refuse_motion: bool,
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimAuboConfig {
    /// Where to listen (`127.0.0.1:0`: any free loopback port).
    pub bind: SocketAddr,
    /// The clock's zero: trajectory times are seconds since this instant.
    pub epoch: Instant,
    /// Initial joint angles, rad.
    pub initial: Joints,
    /// Joint limits.
    pub limits: JointLimits,
    /// Time constant of the first-order tracking lag, s (0: none).
    pub tracking_lag_s: f64,
    /// Standard deviation of the encoder noise on reported angles, rad.
    pub encoder_noise_rad: f64,
    /// Per-joint encoder noise standard deviations, rad (overrides
    /// `encoder_noise_rad` when set).
    pub encoder_noise_per_joint: Option<Joints>,
    /// Seed of the encoder noise.
    pub seed: u64,
    /// Injected faults.
    pub faults: FaultSwitches,
}

impl Default for SimAuboConfig {
    fn default() -> Self {
        SimAuboConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            epoch: Instant::now(),
            initial: [0.0; JOINTS],
            limits: JointLimits::default(),
            tracking_lag_s: 0.02,
            encoder_noise_rad: 1e-4,
            encoder_noise_per_joint: None,
            seed: 1,
            faults: FaultSwitches::default(),
        }
    }
}

/// Why the simulated controller could not be started.
#[derive(Debug, thiserror::Error)]
pub enum SimAuboError {
    /// The listening socket could not be opened.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The requested address.
        addr: SocketAddr,
        /// The cause.
        source: std::io::Error,
    },
    /// A thread could not be started.
    #[error("cannot start a simulator thread: {0}")]
    Thread(#[source] std::io::Error),
}

/// One time-stamped sample of the true joint angles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueSample {
    /// Seconds since the configured epoch.
    pub t: f64,
    /// True joint angles, rad.
    pub q: Joints,
}

/// The true joint state at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrueState {
    /// Seconds since the configured epoch.
    pub t: f64,
    /// Joint angles, rad.
    pub q: Joints,
    /// Joint velocities, rad/s.
    pub qd: Joints,
    /// Joint accelerations, rad/s².
    pub qdd: Joints,
}

/// Where a simulated IMU on the flange gets the arm's true motion: any
/// simulated controller's state probe.
pub trait TrueMotion: Send {
    /// The true state now.
    fn now(&self) -> TrueState;
}

impl TrueMotion for StateProbe {
    fn now(&self) -> TrueState {
        StateProbe::now(self)
    }
}

/// Reads the simulated arm's true state from another thread (a simulated
/// IMU on the flange uses it as its physics). Cloneable; keeps the
/// simulation's state alive but not its threads.
#[derive(Clone)]
pub struct StateProbe {
    shared: Arc<Shared>,
}

impl StateProbe {
    /// The true state now.
    pub fn now(&self) -> TrueState {
        let t = self.shared.now();
        lock(&self.shared.robot).state_at(t)
    }

    /// The simulation's epoch (time zero of [`TrueState::t`]).
    pub fn epoch(&self) -> Instant {
        self.shared.epoch
    }
}

/// A running simulated controller; stops when dropped.
pub struct SimAubo {
    addr: SocketAddr,
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

impl SimAubo {
    /// Opens the socket and starts the simulation and accept threads.
    pub fn spawn(config: SimAuboConfig) -> Result<SimAubo, SimAuboError> {
        let listener = TcpListener::bind(config.bind).map_err(|source| SimAuboError::Bind {
            addr: config.bind,
            source,
        })?;
        let addr = listener.local_addr().map_err(|source| SimAuboError::Bind {
            addr: config.bind,
            source,
        })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| SimAuboError::Bind {
                addr: config.bind,
                source,
            })?;
        let shared = Arc::new(Shared {
            epoch: config.epoch,
            stop: AtomicBool::new(false),
            faults: Mutex::new(config.faults.clone()),
            robot: Mutex::new(Robot::new(&config)),
            connections: Mutex::new(Vec::new()),
        });
        let mut threads = Vec::new();
        let sim = Arc::clone(&shared);
        threads.push(
            thread::Builder::new()
                .name("sim-aubo-motion".into())
                .spawn(move || simulation_loop(&sim))
                .map_err(SimAuboError::Thread)?,
        );
        let acc = Arc::clone(&shared);
        let accept = thread::Builder::new()
            .name("sim-aubo-accept".into())
            .spawn(move || server::accept_loop(&listener, &acc, "sim-aubo-conn", serve_connection));
        match accept {
            Ok(handle) => threads.push(handle),
            Err(e) => {
                shared.stop.store(true, Ordering::SeqCst);
                for t in threads {
                    let _ = t.join();
                }
                return Err(SimAuboError::Thread(e));
            }
        }
        Ok(SimAubo {
            addr,
            shared,
            threads,
        })
    }

    /// The address clients connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Replaces the injected faults (effective from the next request).
    pub fn set_faults(&self, faults: FaultSwitches) {
        *lock(&self.shared.faults) = faults;
    }

    /// The true joint trajectory so far (every integration step, ≥ 500 Hz).
    pub fn true_trajectory(&self) -> Vec<TrueSample> {
        lock(&self.shared.robot).log.clone()
    }

    /// Removes and returns the true trajectory logged so far.
    pub fn take_true_trajectory(&self) -> Vec<TrueSample> {
        std::mem::take(&mut lock(&self.shared.robot).log)
    }

    /// A handle that reads the true joint state (angles, velocities,
    /// accelerations) from any thread.
    pub fn state_probe(&self) -> StateProbe {
        StateProbe {
            shared: Arc::clone(&self.shared),
        }
    }

    /// The true joint angles now.
    pub fn true_joints(&self) -> Joints {
        let now = self.shared.now();
        let mut robot = lock(&self.shared.robot);
        robot.advance_to(now);
        robot.q
    }

    /// Stops every thread and closes every connection.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        server::shutdown(&*self.shared, &mut self.threads);
    }
}

impl Drop for SimAubo {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The simulated controller's motion model on a virtual clock: the same
/// reference, tracking lag and encoder noise as [`SimAubo`], without the
/// server or threads, for twins recorded in virtual time
/// (`robimu_hil::twin`). Time is seconds from zero, set by the caller.
#[derive(Debug)]
pub struct VirtualAubo {
    robot: Robot,
}

impl VirtualAubo {
    /// The arm of `config` (its initial pose, limits, lag, encoder noise and
    /// seed; `bind`, `epoch` and `faults` are not used) at time zero.
    pub fn new(config: &SimAuboConfig) -> Self {
        let mut robot = Robot::new(config);
        robot.t = 0.0;
        robot.front_start = 0.0;
        robot.log.clear();
        Self { robot }
    }

    /// Queues a path buffer of `points` `h` seconds apart, as
    /// `robimu record`'s AUBO driver sends it (alloc, append, eval with
    /// limits `a`, `v`, move) at time `t`; `Err` is the controller's
    /// refusing status code.
    pub fn play_path(
        &mut self,
        t: f64,
        points: &[Joints],
        h: f64,
        a: Joints,
        v: Joints,
    ) -> Result<(), i64> {
        let name = "virtual";
        self.robot.advance_to(t);
        let check = |code: i64| {
            if code == status::OK {
                Ok(())
            } else {
                Err(code)
            }
        };
        check(self.robot.path_alloc(name, 2.0, points.len() as f64))?;
        check(self.robot.path_append(name, points.to_vec()))?;
        check(self.robot.path_eval(name, a, v, h))?;
        check(self.robot.move_path(name))?;
        self.robot.buffers.clear();
        Ok(())
    }

    /// The true state at `t` (not before the last query's time).
    pub fn state_at(&mut self, t: f64) -> TrueState {
        self.robot.state_at(t)
    }

    /// What `getJointPositions` answers at `t`: the true angles plus
    /// encoder noise.
    pub fn joint_positions(&mut self, t: f64) -> Joints {
        self.robot.advance_to(t);
        self.robot.measured()
    }

    /// Whether no motion runs at `t` (`getExecId` is −1).
    pub fn idle_at(&mut self, t: f64) -> bool {
        self.robot.advance_to(t);
        let _ = self.robot.reference(t);
        self.robot.exec_id() == -1
    }
}

/// State shared by the simulator's threads.
struct Shared {
    epoch: Instant,
    stop: AtomicBool,
    faults: Mutex<FaultSwitches>,
    robot: Mutex<Robot>,
    connections: Mutex<Vec<JoinHandle<()>>>,
}

impl Shared {
    fn now(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }
}

impl Server for Shared {
    fn stop_flag(&self) -> &AtomicBool {
        &self.stop
    }
    fn connections(&self) -> &Mutex<Vec<JoinHandle<()>>> {
        &self.connections
    }
}

fn simulation_loop(shared: &Shared) {
    let period = Duration::from_secs_f64(MAX_STEP_S);
    let mut next = Instant::now();
    while !shared.stop.load(Ordering::SeqCst) {
        next += period;
        let now = Instant::now();
        if next > now {
            thread::sleep(next - now);
        } else {
            next = now;
        }
        let t = shared.now();
        lock(&shared.robot).advance_to(t);
    }
}

fn serve_connection(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_nodelay(true);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(20)));
    let mut parser = StreamParser::default();
    let mut answered = 0usize;
    let mut chunk = [0u8; 4096];
    while !shared.stop.load(Ordering::SeqCst) {
        let n = match stream.read(&mut chunk) {
            Ok(0) => return,
            Ok(n) => n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => continue,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(_) => return,
        };
        parser.push(&chunk[..n]);
        loop {
            let message = match parser.next_value() {
                Ok(Some(v)) => v,
                Ok(None) => break,
                Err(e) => {
                    let reply = error_reply(Value::Null, -32700, &format!("parse error: {e}"));
                    if send(&mut stream, &reply).is_err() {
                        return;
                    }
                    break;
                }
            };
            let faults = lock(&shared.faults).clone();
            if faults.drop_connection_after.is_some_and(|n| answered >= n) {
                let _ = stream.shutdown(std::net::Shutdown::Both);
                return;
            }
            let reply = handle_message(&message, shared, &faults);
            if !faults.reply_delay.is_zero() {
                thread::sleep(faults.reply_delay);
            }
            if let Some(reply) = reply {
                if send(&mut stream, &reply).is_err() {
                    return;
                }
            }
            answered += 1;
        }
    }
}

fn send(stream: &mut TcpStream, reply: &Value) -> std::io::Result<()> {
    stream.write_all(reply.to_string().as_bytes())
}

/// Incremental parser of concatenated JSON values in a byte stream.
#[derive(Debug, Default)]
pub struct StreamParser {
    buf: Vec<u8>,
}

impl StreamParser {
    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next complete value, `None` if more bytes are needed. On a syntax
    /// error the buffered bytes are discarded (the stream cannot be
    /// resynchronised) and the error returned.
    pub fn next_value(&mut self) -> Result<Option<Value>, serde_json::Error> {
        let mut it = serde_json::Deserializer::from_slice(&self.buf).into_iter::<Value>();
        match it.next() {
            None => {
                self.buf.clear();
                Ok(None)
            }
            Some(Ok(v)) => {
                let used = it.byte_offset();
                self.buf.drain(..used);
                Ok(Some(v))
            }
            Some(Err(e)) if e.is_eof() => Ok(None),
            Some(Err(e)) => {
                self.buf.clear();
                Err(e)
            }
        }
    }
}

fn error_reply(id: Value, code: i64, message: &str) -> Value {
    json!({"jsonrpc": "2.0", "id": id, "error": {"code": code, "message": message}})
}

/// Answers one request; `None` for a notification (no `id`).
fn handle_message(message: &Value, shared: &Shared, faults: &FaultSwitches) -> Option<Value> {
    let Some(obj) = message.as_object() else {
        return Some(error_reply(
            Value::Null,
            -32600,
            "invalid request: not a JSON object",
        ));
    };
    let id = obj.get("id").cloned();
    let Some(method) = obj.get("method").and_then(Value::as_str) else {
        return Some(error_reply(
            id.unwrap_or(Value::Null),
            -32600,
            "invalid request: no method",
        ));
    };
    let params = match obj.get("params") {
        None => Vec::new(),
        Some(Value::Array(a)) => a.clone(),
        Some(_) => {
            return id.map(|id| error_reply(id, -32602, "invalid params: params must be an array"))
        }
    };
    let outcome = dispatch(method, &params, shared, faults);
    let id = id?;
    Some(match outcome {
        Ok(result) => json!({"jsonrpc": "2.0", "id": id, "result": result}),
        Err(RpcError { code, message }) => error_reply(id, code, &message),
    })
}

/// A JSON-RPC error object.
struct RpcError {
    code: i64,
    message: String,
}

fn bad_params(method: &str, what: &str) -> RpcError {
    RpcError {
        code: -32602,
        message: format!("invalid params for {method}: {what}"),
    }
}

fn param_f64(method: &str, params: &[Value], i: usize, name: &str) -> Result<f64, RpcError> {
    params
        .get(i)
        .and_then(Value::as_f64)
        .filter(|x| x.is_finite())
        .ok_or_else(|| bad_params(method, &format!("parameter {i} ({name}) must be a number")))
}

fn param_joints(method: &str, params: &[Value], i: usize, name: &str) -> Result<Joints, RpcError> {
    params.get(i).and_then(joints_of).ok_or_else(|| {
        bad_params(
            method,
            &format!("parameter {i} ({name}) must be {JOINTS} joint angles"),
        )
    })
}

fn joints_of(v: &Value) -> Option<Joints> {
    let a = v.as_array()?;
    if a.len() != JOINTS {
        return None;
    }
    let mut q = [0.0; JOINTS];
    for (qi, x) in q.iter_mut().zip(a) {
        *qi = x.as_f64().filter(|x| x.is_finite())?;
    }
    Some(q)
}

fn param_str<'a>(
    method: &str,
    params: &'a [Value],
    i: usize,
    name: &str,
) -> Result<&'a str, RpcError> {
    params
        .get(i)
        .and_then(Value::as_str)
        .ok_or_else(|| bad_params(method, &format!("parameter {i} ({name}) must be a string")))
}

fn dispatch(
    method: &str,
    p: &[Value],
    shared: &Shared,
    faults: &FaultSwitches,
) -> Result<Value, RpcError> {
    let Some(name) = method.strip_prefix("rob1.") else {
        return Err(unknown(method));
    };
    let motion = name.starts_with("MotionControl.move")
        || matches!(
            name,
            "MotionControl.servoJoint" | "MotionControl.setServoMode"
        );
    let now = shared.now();
    let mut robot = lock(&shared.robot);
    robot.advance_to(now);
    if motion && faults.refuse_motion {
        // A robot in protective stop refuses before looking at parameters.
        return Ok(json!(status::BAD_STATE));
    }
    let code = match name {
        "RobotState.getJointPositions" => {
            let q = robot.measured();
            return Ok(json!(q.to_vec()));
        }
        "MotionControl.isServoModeEnabled" => return Ok(json!(robot.servo_mode)),
        "MotionControl.getExecId" => return Ok(json!(robot.exec_id())),
        "MotionControl.moveJoint" => {
            let q = param_joints(method, p, 0, "q")?;
            let a = param_f64(method, p, 1, "a")?;
            let v = param_f64(method, p, 2, "v")?;
            robot.move_joint(q, a, v)
        }
        "MotionControl.setServoMode" => {
            let enable = p
                .first()
                .and_then(Value::as_bool)
                .ok_or_else(|| bad_params(method, "parameter 0 (enable) must be a boolean"))?;
            robot.set_servo_mode(enable, now)
        }
        "MotionControl.servoJoint" => {
            let q = param_joints(method, p, 0, "q")?;
            let t = param_f64(method, p, 3, "t")?;
            robot.servo_joint(q, t, now)
        }
        "MotionControl.pathBufferAlloc" => {
            let name = param_str(method, p, 0, "name")?;
            let kind = param_f64(method, p, 1, "type")?;
            let size = param_f64(method, p, 2, "size")?;
            robot.path_alloc(name, kind, size)
        }
        "MotionControl.pathBufferAppend" => {
            let name = param_str(method, p, 0, "name")?;
            let points = p
                .get(1)
                .and_then(Value::as_array)
                .and_then(|a| a.iter().map(joints_of).collect::<Option<Vec<_>>>())
                .ok_or_else(|| {
                    bad_params(
                        method,
                        &format!(
                            "parameter 1 (waypoints) must be a list of {JOINTS}-joint vectors"
                        ),
                    )
                })?;
            robot.path_append(name, points)
        }
        "MotionControl.pathBufferEval" => {
            let name = param_str(method, p, 0, "name")?;
            let a = param_joints(method, p, 1, "a")?;
            let v = param_joints(method, p, 2, "v")?;
            let t = param_f64(method, p, 3, "t")?;
            robot.path_eval(name, a, v, t)
        }
        "MotionControl.movePathBuffer" => {
            let name = param_str(method, p, 0, "name")?;
            robot.move_path(name)
        }
        "MotionControl.pathBufferFree" => {
            let name = param_str(method, p, 0, "name")?;
            if robot.buffers.remove(name).is_some() {
                status::OK
            } else {
                status::INVL_ARGUMENT
            }
        }
        "MotionControl.stopJoint" => {
            param_f64(method, p, 0, "acc")?;
            robot.stop_motion(now);
            status::OK
        }
        _ => return Err(unknown(method)),
    };
    Ok(json!(code))
}

fn unknown(method: &str) -> RpcError {
    RpcError {
        code: -32601,
        message: format!("method not found: {method}"),
    }
}

/// A queued motion of the reference.
#[derive(Clone, Debug)]
enum Segment {
    /// Synchronised trapezoidal move: `q0 + dq·s(τ)/d`.
    Trapezoid {
        q0: Joints,
        dq: Joints,
        d: f64,
        a: f64,
        t_acc: f64,
        duration: f64,
    },
    /// Cubic Hermite path through `points`, `h` seconds apart.
    Spline { points: Vec<Joints>, h: f64 },
}

impl Segment {
    fn trapezoid(q0: Joints, q1: Joints, v: f64, a: f64) -> Segment {
        let mut dq = [0.0; JOINTS];
        for i in 0..JOINTS {
            dq[i] = q1[i] - q0[i];
        }
        let d = dq.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let (t_acc, duration) = if d * a < v * v {
            let t = (d / a).sqrt();
            (t, 2.0 * t)
        } else {
            (v / a, d / v + v / a)
        };
        Segment::Trapezoid {
            q0,
            dq,
            d,
            a,
            t_acc,
            duration,
        }
    }

    fn duration(&self) -> f64 {
        match self {
            Segment::Trapezoid { duration, .. } => *duration,
            Segment::Spline { points, h } => (points.len() - 1) as f64 * h,
        }
    }

    fn eval(&self, tau: f64) -> Joints {
        match self {
            Segment::Trapezoid {
                q0,
                dq,
                d,
                a,
                t_acc,
                duration,
            } => {
                if *d == 0.0 {
                    return *q0;
                }
                let tau = tau.clamp(0.0, *duration);
                let v_peak = a * t_acc;
                let s = if tau < *t_acc {
                    0.5 * a * tau * tau
                } else if tau <= duration - t_acc {
                    0.5 * a * t_acc * t_acc + v_peak * (tau - t_acc)
                } else {
                    let r = duration - tau;
                    d - 0.5 * a * r * r
                };
                let mut q = *q0;
                for i in 0..JOINTS {
                    q[i] += dq[i] * s / d;
                }
                q
            }
            Segment::Spline { points, h } => spline_eval(points, *h, tau),
        }
    }

    fn end(&self) -> Joints {
        self.eval(self.duration())
    }

    /// The reference and its first two time derivatives at `tau`.
    fn eval_derivatives(&self, tau: f64) -> [Joints; 3] {
        match self {
            Segment::Trapezoid {
                dq,
                d,
                a,
                t_acc,
                duration,
                ..
            } => {
                let mut out = [self.eval(tau), [0.0; JOINTS], [0.0; JOINTS]];
                if *d == 0.0 || tau <= 0.0 || tau >= *duration {
                    return out;
                }
                let (v, acc) = if tau < *t_acc {
                    (a * tau, *a)
                } else if tau <= duration - t_acc {
                    (a * t_acc, 0.0)
                } else {
                    (a * (duration - tau), -a)
                };
                for i in 0..JOINTS {
                    out[1][i] = dq[i] * v / d;
                    out[2][i] = dq[i] * acc / d;
                }
                out
            }
            Segment::Spline { points, h } => spline_derivatives(points, *h, tau),
        }
    }
}

/// [`spline_eval`] and its first two derivatives with respect to time.
fn spline_derivatives(points: &[Joints], h: f64, tau: f64) -> [Joints; 3] {
    let n = points.len();
    let mut out = [spline_eval(points, h, tau), [0.0; JOINTS], [0.0; JOINTS]];
    if n == 1 || tau < 0.0 || tau > (n - 1) as f64 * h {
        return out;
    }
    let x = (tau / h).clamp(0.0, (n - 1) as f64);
    let k = (x.floor() as usize).min(n - 2);
    let u = x - k as f64;
    let tangent = |j: usize, i: usize| -> f64 {
        let lo = j.saturating_sub(1);
        let hi = (j + 1).min(n - 1);
        (points[hi][i] - points[lo][i]) / (hi - lo) as f64
    };
    let d1 = [
        6.0 * u * u - 6.0 * u,
        3.0 * u * u - 4.0 * u + 1.0,
        -6.0 * u * u + 6.0 * u,
        3.0 * u * u - 2.0 * u,
    ];
    let d2 = [
        12.0 * u - 6.0,
        6.0 * u - 4.0,
        -12.0 * u + 6.0,
        6.0 * u - 2.0,
    ];
    for i in 0..JOINTS {
        let c = [
            points[k][i],
            tangent(k, i),
            points[k + 1][i],
            tangent(k + 1, i),
        ];
        out[1][i] = (0..4).map(|j| d1[j] * c[j]).sum::<f64>() / h;
        out[2][i] = (0..4).map(|j| d2[j] * c[j]).sum::<f64>() / (h * h);
    }
    out
}

/// One step of the first-order tracking lag `dq/dt = (r − q)/T` over `h`
/// seconds, exact for a reference linear from `r_prev` to `r` within the
/// step: with `r = r₀ + s·t`, `q − r + sT` decays as `e^(−t/T)`. `T = 0`
/// tracks the reference exactly.
pub(crate) fn lag_step(q: &mut Joints, r_prev: &Joints, r: &Joints, h: f64, lag_s: f64) {
    let decay = if lag_s > 0.0 { (-h / lag_s).exp() } else { 0.0 };
    for i in 0..JOINTS {
        let s = (r[i] - r_prev[i]) / h;
        let tail = s * lag_s;
        q[i] = r[i] - tail + (q[i] - r_prev[i] + tail) * decay;
    }
}

/// The true state of a joint vector following `reference = [r, ṙ, r̈]`
/// through the first-order lag `T` ([`lag_step`]), at angles `q`:
/// `q̇ = (r − q)/T`, `q̈ = (ṙ − q̇)/T` (the lag's own equation); without a
/// lag the reference's own derivatives.
pub(crate) fn lagged_state(t: f64, q: Joints, reference: [Joints; 3], lag_s: f64) -> TrueState {
    let [r, rd, rdd] = reference;
    let mut state = TrueState {
        t,
        q,
        qd: rd,
        qdd: rdd,
    };
    if lag_s > 0.0 {
        for i in 0..JOINTS {
            state.qd[i] = (r[i] - q[i]) / lag_s;
            state.qdd[i] = (rd[i] - state.qd[i]) / lag_s;
        }
    }
    state
}

/// Cubic Hermite interpolation with central-difference tangents (one-sided
/// at the ends).
fn spline_eval(points: &[Joints], h: f64, tau: f64) -> Joints {
    let n = points.len();
    if n == 1 {
        return points[0];
    }
    let x = (tau / h).clamp(0.0, (n - 1) as f64);
    let k = (x.floor() as usize).min(n - 2);
    let u = x - k as f64;
    let tangent = |j: usize, i: usize| -> f64 {
        let lo = j.saturating_sub(1);
        let hi = (j + 1).min(n - 1);
        (points[hi][i] - points[lo][i]) / (hi - lo) as f64
    };
    let (h00, h10, h01, h11) = (
        2.0 * u * u * u - 3.0 * u * u + 1.0,
        u * u * u - 2.0 * u * u + u,
        -2.0 * u * u * u + 3.0 * u * u,
        u * u * u - u * u,
    );
    let mut q = [0.0; JOINTS];
    for i in 0..JOINTS {
        q[i] = h00 * points[k][i]
            + h10 * tangent(k, i)
            + h01 * points[k + 1][i]
            + h11 * tangent(k + 1, i);
    }
    q
}

/// A path buffer being filled.
#[derive(Debug)]
struct PathBuffer {
    size: usize,
    points: Vec<Joints>,
    interval: Option<f64>,
}

/// Small deterministic Gaussian generator (SplitMix64 + Box–Muller).
#[derive(Debug)]
pub(crate) struct Noise {
    pub(crate) state: u64,
}

impl Noise {
    pub(crate) fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    pub(crate) fn gaussian(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Servo-mode ramp of the reference.
#[derive(Clone, Copy, Debug)]
struct Ramp {
    t0: f64,
    from: Joints,
    to: Joints,
    duration: f64,
}

/// The simulated arm: reference, true angles, queued motions.
#[derive(Debug)]
struct Robot {
    limits: JointLimits,
    lag_s: f64,
    noise_rad: Joints,
    noise: Noise,
    /// True joint angles at `t`.
    q: Joints,
    t: f64,
    /// The reference at `t`.
    r_prev: Joints,
    /// Reference when no motion runs.
    hold: Joints,
    queue: VecDeque<(i64, Segment)>,
    front_start: f64,
    plan_end: Joints,
    next_exec_id: i64,
    servo_mode: bool,
    servo: Option<Ramp>,
    buffers: HashMap<String, PathBuffer>,
    log: Vec<TrueSample>,
}

impl Robot {
    fn new(config: &SimAuboConfig) -> Robot {
        let t = config.epoch.elapsed().as_secs_f64();
        Robot {
            limits: config.limits.clone(),
            lag_s: config.tracking_lag_s.max(0.0),
            noise_rad: config
                .encoder_noise_per_joint
                .unwrap_or([config.encoder_noise_rad; JOINTS])
                .map(|s| s.max(0.0)),
            noise: Noise { state: config.seed },
            q: config.initial,
            t,
            r_prev: config.initial,
            hold: config.initial,
            queue: VecDeque::new(),
            front_start: t,
            plan_end: config.initial,
            next_exec_id: 1,
            servo_mode: false,
            servo: None,
            buffers: HashMap::new(),
            log: vec![TrueSample {
                t,
                q: config.initial,
            }],
        }
    }

    /// The reference at time `t` (retires finished motions).
    fn reference(&mut self, t: f64) -> Joints {
        self.reference_derivatives(t)[0]
    }

    /// The reference and its first two time derivatives at time `t`
    /// (retires finished motions).
    fn reference_derivatives(&mut self, t: f64) -> [Joints; 3] {
        if let Some(r) = self.servo {
            let inside = r.duration > 0.0 && t > r.t0 && t < r.t0 + r.duration;
            let u = if r.duration > 0.0 {
                ((t - r.t0) / r.duration).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let mut out = [r.from, [0.0; JOINTS], [0.0; JOINTS]];
            for i in 0..JOINTS {
                out[0][i] += (r.to[i] - r.from[i]) * u;
                if inside {
                    out[1][i] = (r.to[i] - r.from[i]) / r.duration;
                }
            }
            return out;
        }
        while let Some((_, seg)) = self.queue.front() {
            let tau = t - self.front_start;
            let duration = seg.duration();
            if tau >= duration {
                self.hold = seg.end();
                self.front_start += duration;
                self.queue.pop_front();
                continue;
            }
            return seg.eval_derivatives(tau);
        }
        [self.hold, [0.0; JOINTS], [0.0; JOINTS]]
    }

    /// The true joint angles and their first two derivatives at `t` (≥ the
    /// last integration time). With a lag `T`, `q̇ = (r − q)/T` and
    /// `q̈ = (ṙ − q̇)/T` (the lag's own equation, with the exact reference);
    /// without one the reference's own derivatives.
    fn state_at(&mut self, t: f64) -> TrueState {
        self.advance_to(t);
        let reference = self.reference_derivatives(t.max(self.t));
        lagged_state(self.t, self.q, reference, self.lag_s)
    }

    /// Integrates the tracking lag up to time `t`: exactly for a reference
    /// linear within each step, so the result does not depend on how the
    /// interval is cut into steps.
    fn advance_to(&mut self, t: f64) {
        while self.t < t {
            let h = (t - self.t).min(MAX_STEP_S);
            let t_next = self.t + h;
            let r = self.reference(t_next);
            lag_step(&mut self.q, &self.r_prev, &r, h, self.lag_s);
            self.r_prev = r;
            self.t = t_next;
            self.log.push(TrueSample {
                t: self.t,
                q: self.q,
            });
        }
    }

    fn measured(&mut self) -> Joints {
        let mut q = self.q;
        for (qi, s) in q.iter_mut().zip(self.noise_rad) {
            *qi += s * self.noise.gaussian();
        }
        q
    }

    fn exec_id(&self) -> i64 {
        if self.servo_mode {
            return if self.servo.is_some() { 0 } else { -1 };
        }
        self.queue.front().map_or(-1, |(id, _)| *id)
    }

    fn enqueue(&mut self, seg: Segment) {
        if self.queue.is_empty() {
            self.front_start = self.t;
        }
        self.plan_end = seg.end();
        let id = self.next_exec_id;
        self.next_exec_id += 1;
        self.queue.push_back((id, seg));
    }

    fn move_joint(&mut self, q: Joints, a: f64, v: f64) -> i64 {
        if self.servo_mode {
            return status::BAD_STATE;
        }
        if !self.limits.within_position(&q) {
            return status::POS_BOUND_ERR;
        }
        if a <= 0.0 || v <= 0.0 {
            return status::INVL_ARGUMENT;
        }
        let v = self.limits.velocity.iter().fold(v, |m, &x| m.min(x));
        let a = self.limits.acceleration.iter().fold(a, |m, &x| m.min(x));
        let seg = Segment::trapezoid(self.plan_end, q, v, a);
        self.enqueue(seg);
        status::OK
    }

    fn set_servo_mode(&mut self, enable: bool, now: f64) -> i64 {
        if enable == self.servo_mode {
            return status::OK;
        }
        if enable {
            if !self.queue.is_empty() {
                return status::BUSY;
            }
            self.servo_mode = true;
            self.servo = None;
        } else {
            let r = self.reference(now);
            self.servo_mode = false;
            self.servo = None;
            self.hold = r;
            self.plan_end = r;
        }
        status::OK
    }

    fn servo_joint(&mut self, q: Joints, t: f64, now: f64) -> i64 {
        if !self.servo_mode {
            return status::REQUEST_IGNORE;
        }
        if !self.limits.within_position(&q) {
            return status::POS_BOUND_ERR;
        }
        if t <= 0.0 {
            return status::INVL_ARGUMENT;
        }
        let from = self.reference(now);
        if (0..JOINTS).any(|i| (q[i] - from[i]).abs() / t > self.limits.velocity[i]) {
            return status::INVL_ARGUMENT;
        }
        self.servo = Some(Ramp {
            t0: now,
            from,
            to: q,
            duration: t,
        });
        status::OK
    }

    fn path_alloc(&mut self, name: &str, kind: f64, size: f64) -> i64 {
        if kind != 2.0 || size < 2.0 || size.fract() != 0.0 {
            return status::INVL_ARGUMENT;
        }
        self.buffers.insert(
            name.to_string(),
            PathBuffer {
                size: size as usize,
                points: Vec::new(),
                interval: None,
            },
        );
        status::OK
    }

    fn path_append(&mut self, name: &str, points: Vec<Joints>) -> i64 {
        let limits = &self.limits;
        let Some(buf) = self.buffers.get_mut(name) else {
            return status::INVL_ARGUMENT;
        };
        if !points.iter().all(|q| limits.within_position(q)) {
            return status::POS_BOUND_ERR;
        }
        buf.points.extend(points);
        buf.interval = None;
        status::OK
    }

    fn path_eval(&mut self, name: &str, a: Joints, v: Joints, t: f64) -> i64 {
        let limits = &self.limits;
        let Some(buf) = self.buffers.get_mut(name) else {
            return status::INVL_ARGUMENT;
        };
        if buf.points.len() < buf.size || buf.points.len() < 2 || t <= 0.0 {
            return status::INVL_ARGUMENT;
        }
        for i in 0..JOINTS {
            let v_max = v[i].min(limits.velocity[i]);
            let a_max = a[i].min(limits.acceleration[i]);
            let p = &buf.points;
            let too_fast = p.windows(2).any(|w| (w[1][i] - w[0][i]).abs() / t > v_max);
            let too_sharp = p
                .windows(3)
                .any(|w| (w[2][i] - 2.0 * w[1][i] + w[0][i]).abs() / (t * t) > a_max);
            if too_fast || too_sharp {
                return status::INVL_ARGUMENT;
            }
        }
        buf.interval = Some(t);
        status::OK
    }

    fn move_path(&mut self, name: &str) -> i64 {
        if self.servo_mode {
            return status::BAD_STATE;
        }
        let Some(buf) = self.buffers.get(name) else {
            return status::INVL_ARGUMENT;
        };
        let Some(h) = buf.interval else {
            return status::BAD_STATE;
        };
        let start = buf.points[0];
        if (0..JOINTS).any(|i| (start[i] - self.plan_end[i]).abs() > PATH_START_TOLERANCE) {
            return status::INVL_ARGUMENT;
        }
        let seg = Segment::Spline {
            points: buf.points.clone(),
            h,
        };
        self.enqueue(seg);
        status::OK
    }

    /// Stops at once: the reference holds where it is now.
    fn stop_motion(&mut self, now: f64) {
        let r = self.reference(now);
        self.queue.clear();
        self.servo = None;
        self.hold = r;
        self.plan_end = r;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `state_at`'s velocities and accelerations against central differences
    /// of its angles and velocities along a path-buffer motion with lag.
    #[test]
    fn true_state_derivatives_match_finite_differences() {
        for lag in [0.02, 0.0] {
            let config = SimAuboConfig {
                tracking_lag_s: lag,
                ..SimAuboConfig::default()
            };
            let mut robot = Robot::new(&config);
            let t0 = robot.t;
            let points: Vec<Joints> = (0..400)
                .map(|k| {
                    let s = k as f64 * 0.004;
                    core::array::from_fn(|i| 0.3 * (s * (1.0 + i as f64 * 0.3)).sin())
                })
                .collect();
            robot.enqueue(Segment::Spline { points, h: 0.004 });
            let h = 1e-4;
            let states: Vec<TrueState> = (0..12000)
                .map(|k| robot.state_at(t0 + 0.2 + k as f64 * h))
                .collect();
            let mut worst = [0.0f64; 2];
            for k in (1000..11000).step_by(97) {
                for i in 0..JOINTS {
                    let qd = (states[k + 1].q[i] - states[k - 1].q[i]) / (2.0 * h);
                    let qdd = (states[k + 1].qd[i] - states[k - 1].qd[i]) / (2.0 * h);
                    worst[0] = worst[0].max((qd - states[k].qd[i]).abs());
                    worst[1] = worst[1].max((qdd - states[k].qdd[i]).abs());
                }
            }
            // Speeds up to ~0.8 rad/s, accelerations up to ~1.5 rad/s². Without
            // a lag the Hermite reference's q̈ jumps at waypoints (4 ms apart),
            // which central differences straddle.
            let tol = if lag > 0.0 {
                [1e-6, 1e-3]
            } else {
                [1e-5, 3e-2]
            };
            assert!(worst[0] < tol[0], "lag {lag}: velocity error {}", worst[0]);
            assert!(
                worst[1] < tol[1],
                "lag {lag}: acceleration error {}",
                worst[1]
            );
        }
    }

    #[test]
    fn parser_splits_concatenated_objects_at_any_boundary() {
        let text = br#"{"id":1,"m":"a"}  {"id":2,"p":[1,2,{"x":"}"}]}
{"id":3}"#;
        for cut in 0..text.len() {
            let mut p = StreamParser::default();
            let mut ids = Vec::new();
            for part in [&text[..cut], &text[cut..]] {
                p.push(part);
                while let Some(v) = p.next_value().unwrap() {
                    ids.push(v["id"].as_i64().unwrap());
                }
            }
            assert_eq!(ids, vec![1, 2, 3], "cut at {cut}");
        }
    }

    #[test]
    fn parser_reports_garbage_and_recovers() {
        let mut p = StreamParser::default();
        p.push(b"{\"id\":1]");
        assert!(p.next_value().is_err());
        p.push(b"{\"id\":4}");
        assert_eq!(p.next_value().unwrap().unwrap()["id"], 4);
    }

    #[test]
    fn trapezoid_matches_closed_form() {
        // 1 rad at v = 0.5, a = 1: t_acc 0.5 s, total 1/0.5 + 0.5 = 2.5 s.
        let q1 = [1.0, -0.5, 0.0, 0.0, 0.0, 0.25];
        let seg = Segment::trapezoid([0.0; JOINTS], q1, 0.5, 1.0);
        assert!((seg.duration() - 2.5).abs() < 1e-12);
        // Halfway in time is halfway in distance (symmetry).
        let mid = seg.eval(1.25);
        assert!((mid[0] - 0.5).abs() < 1e-12 && (mid[1] + 0.25).abs() < 1e-12);
        // End of acceleration: a t²/2 = 0.125.
        assert!((seg.eval(0.5)[0] - 0.125).abs() < 1e-12);
        assert_eq!(seg.end(), q1);
    }

    #[test]
    fn spline_interpolates_waypoints_and_a_line_exactly() {
        let points: Vec<Joints> = (0..5).map(|k| [0.1 * k as f64; JOINTS]).collect();
        for k in 0..5 {
            assert!(
                (spline_eval(&points, 0.01, 0.01 * k as f64)[0] - 0.1 * k as f64).abs() < 1e-12
            );
        }
        // A line stays a line between points.
        assert!((spline_eval(&points, 0.01, 0.025)[3] - 0.25).abs() < 1e-12);
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let mut n = Noise { state: 7 };
        let xs: Vec<f64> = (0..20000).map(|_| n.gaussian()).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }

    /// The virtual-time arm plays a path buffer as the server does: it
    /// refuses one that does not start where the arm stands (status −5),
    /// follows the waypoints through the lag (at the end within the lag's
    /// tail of the last point), and is idle once the path has run.
    #[test]
    fn the_virtual_arm_plays_a_path_buffer_through_its_lag() {
        let config = SimAuboConfig {
            tracking_lag_s: 0.02,
            encoder_noise_rad: 0.0,
            ..SimAuboConfig::default()
        };
        let h = 0.004;
        let points: Vec<Joints> = (0..500)
            .map(|k| {
                core::array::from_fn(|i| {
                    0.2 * (1.0 - (k as f64 * h * (1.0 + i as f64 * 0.2)).cos())
                })
            })
            .collect();
        let (a, v) = ([100.0; JOINTS], [10.0; JOINTS]);
        let mut arm = VirtualAubo::new(&config);
        let mut shifted = points.clone();
        shifted[0][0] += 0.1;
        assert_eq!(
            arm.play_path(0.5, &shifted, h, a, v),
            Err(status::INVL_ARGUMENT)
        );
        assert!(arm.idle_at(0.5));
        arm.play_path(1.0, &points, h, a, v).unwrap();
        assert!(!arm.idle_at(1.5));
        let end = 1.0 + (points.len() - 1) as f64 * h;
        assert!(!arm.idle_at(end - 0.01));
        assert!(arm.idle_at(end + 1e-6));
        // five lag constants after the end the arm stands at the last point
        let q = arm.joint_positions(end + 0.1);
        let last = points[points.len() - 1];
        for i in 0..JOINTS {
            assert!(
                (q[i] - last[i]).abs() < 1e-3 * last[i].abs().max(1e-2),
                "{q:?} vs {last:?}"
            );
        }
        // and at rest: q̇ = (r − q)/T vanishes
        let s = arm.state_at(end + 0.2);
        assert!(s.qd.iter().all(|v| v.abs() < 1e-3), "{s:?}");
    }
}
