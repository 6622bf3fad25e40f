//! A simulated Universal Robots controller on loopback TCP: RTDE for
//! readings, a URScript port for motion.
//!
//! [`SimUr::spawn`] opens two ports on [`SimUrConfig::bind`]:
//!
//! * RTDE (real port 30004): big-endian packages `uint16 size`, `uint8
//!   type`, payload. `V` (protocol version; 1 ..=
//!   [`SimUrConfig::max_protocol_version`] accepted), `O` (setup outputs:
//!   `double frequency` in version 2, then comma-separated names; the reply
//!   is a recipe id and the types, `NOT_FOUND` for an unknown name, recipe
//!   id 0 for a frequency outside `(0, control rate]`), `S` (start; refused
//!   without a recipe), `P` (pause). After `V` the controller sends one `M`
//!   text message, which clients must skip. Outputs: `timestamp` (DOUBLE,
//!   s since the controller started: [`SimUrConfig::uptime_at_epoch_s`] +
//!   seconds since the epoch), `actual_q` (VECTOR6D, the true angles plus
//!   Gaussian encoder noise), `target_q` (VECTOR6D, the reference),
//!   `runtime_state` (UINT32: 2 playing, 1 stopped), `robot_mode` (INT32:
//!   7 running). Once started, a `U` package goes out at every control
//!   cycle of the requested period (cycles are multiples of 1/frequency
//!   since the epoch); a connection that falls behind skips to the latest
//!   cycle, as the real controller does.
//! * Script (real port 30002, the secondary interface): a connection sends
//!   one program and closes its write side. The program must be
//!   `def NAME():`, lines of `movej([6], a=A, v=V)`, `servoj([6], t=T,
//!   lookahead_time=L, gain=G)`, `stopj(A)`, then `end` and optionally
//!   `NAME()`; anything else is refused (the reason is kept:
//!   [`SimUr::script_errors`]) and the robot does not move. A program
//!   replaces the one running.
//!
//! Motion model. The reference `r(t)` ramps linearly: `movej` to its
//! target at speed `v` (the largest joint step over `v`), each `servoj` to
//! its target over `t` seconds. The true angles follow `r(t)` through a
//! first-order lag of time constant [`SimUrConfig::tracking_lag_s`],
//! integrated exactly for the piecewise-linear reference in steps of at
//! most 2 ms by a 500 Hz simulation thread; each step is logged
//! ([`SimUr::true_trajectory`]; times in seconds since the epoch), and a
//! data package's `actual_q` is the logged trajectory at its cycle time.

// Joint loops index several joint vectors in step.
#![allow(clippy::needless_range_loop)]

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use crate::aubo::{
    lag_step, lagged_state, Joints, Noise, TrueMotion, TrueSample, TrueState, JOINTS,
};
use crate::server::{self, lock, Server};

/// Largest integration step of the simulation, s.
const MAX_STEP_S: f64 = 0.002;

/// Faults the simulator can inject; changeable while it runs
/// ([`SimUr::set_faults`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultSwitches {
    /// Wait before every reply to a control package (`V`, `O`, `S`, `P`).
    pub reply_delay: Duration,
    /// Close each RTDE connection after sending this many data packages.
    pub drop_connection_after: Option<usize>,
    /// Send every package in two writes 1 ms apart, cut at a varying point.
    pub split_writes: bool,
    /// Hold each data package back before sending it by a delay drawn
    /// uniformly from `[0, jitter_max]` (seeded by [`SimUrConfig::seed`]):
    /// network and scheduling jitter. Below the control period every cycle
    /// is still sent; its `timestamp` stays the cycle's time.
    pub jitter_max: Duration,
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimUrConfig {
    /// Where to listen; both ports are chosen freely on its address when its
    /// port is 0.
    pub bind: SocketAddr,
    /// The clock's zero: trajectory times are seconds since this instant.
    pub epoch: Instant,
    /// The controller's `timestamp` at the epoch, s (its uptime).
    pub uptime_at_epoch_s: f64,
    /// Control rate, Hz: 125 (CB-series) or 500 (e-Series); the largest
    /// output frequency.
    pub control_rate_hz: f64,
    /// Highest RTDE protocol version accepted.
    pub max_protocol_version: u16,
    /// Initial joint angles, rad.
    pub initial: Joints,
    /// Time constant of the first-order tracking lag, s (0: none).
    pub tracking_lag_s: f64,
    /// Standard deviation of the encoder noise on `actual_q`, rad.
    pub encoder_noise_rad: f64,
    /// Seed of the encoder noise.
    pub seed: u64,
    /// Injected faults.
    pub faults: FaultSwitches,
}

impl Default for SimUrConfig {
    fn default() -> Self {
        SimUrConfig {
            bind: SocketAddr::from(([127, 0, 0, 1], 0)),
            epoch: Instant::now(),
            uptime_at_epoch_s: 1234.5,
            control_rate_hz: 500.0,
            max_protocol_version: 2,
            initial: [0.0; JOINTS],
            tracking_lag_s: 0.02,
            encoder_noise_rad: 1e-4,
            seed: 1,
            faults: FaultSwitches::default(),
        }
    }
}

/// Why the simulated controller could not be started.
#[derive(Debug, thiserror::Error)]
pub enum SimUrError {
    /// A listening socket could not be opened.
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

/// A running simulated UR controller; stops when dropped.
pub struct SimUr {
    rtde: SocketAddr,
    script: SocketAddr,
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

struct Shared {
    epoch: Instant,
    config: SimUrConfig,
    stop: AtomicBool,
    faults: Mutex<FaultSwitches>,
    robot: Mutex<Robot>,
    script_errors: Mutex<Vec<String>>,
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

fn listen(addr: SocketAddr) -> Result<(TcpListener, SocketAddr), SimUrError> {
    let bind = |source| SimUrError::Bind { addr, source };
    let l = TcpListener::bind(addr).map_err(bind)?;
    let local = l.local_addr().map_err(bind)?;
    l.set_nonblocking(true).map_err(bind)?;
    Ok((l, local))
}

impl SimUr {
    /// Opens the two ports and starts the simulation and accept threads.
    pub fn spawn(config: SimUrConfig) -> Result<SimUr, SimUrError> {
        let (rtde_l, rtde) = listen(config.bind)?;
        let mut script_bind = config.bind;
        if script_bind.port() != 0 {
            script_bind.set_port(script_bind.port().wrapping_add(1));
        }
        let (script_l, script) = listen(script_bind)?;
        let shared = Arc::new(Shared {
            epoch: config.epoch,
            stop: AtomicBool::new(false),
            faults: Mutex::new(config.faults.clone()),
            robot: Mutex::new(Robot::new(&config)),
            script_errors: Mutex::new(Vec::new()),
            connections: Mutex::new(Vec::new()),
            config,
        });
        let mut sim = SimUr {
            rtde,
            script,
            shared,
            threads: Vec::new(),
        };
        let s = Arc::clone(&sim.shared);
        sim.start_thread("sim-ur-motion", move || simulation_loop(&s))?;
        let s = Arc::clone(&sim.shared);
        sim.start_thread("sim-ur-rtde", move || {
            server::accept_loop(&rtde_l, &s, "sim-ur-conn", serve_rtde)
        })?;
        let s = Arc::clone(&sim.shared);
        sim.start_thread("sim-ur-script", move || {
            server::accept_loop(&script_l, &s, "sim-ur-conn", serve_script)
        })?;
        Ok(sim)
    }

    fn start_thread(
        &mut self,
        name: &str,
        f: impl FnOnce() + Send + 'static,
    ) -> Result<(), SimUrError> {
        let handle = thread::Builder::new()
            .name(name.into())
            .spawn(f)
            .map_err(SimUrError::Thread)?;
        self.threads.push(handle);
        Ok(())
    }

    /// A handle that reads the true joint state (angles, velocities,
    /// accelerations) from any thread.
    pub fn state_probe(&self) -> UrStateProbe {
        UrStateProbe {
            shared: Arc::clone(&self.shared),
        }
    }

    /// The RTDE address.
    pub fn rtde_addr(&self) -> SocketAddr {
        self.rtde
    }

    /// The URScript address.
    pub fn script_addr(&self) -> SocketAddr {
        self.script
    }

    /// Replaces the injected faults (effective from the next package).
    pub fn set_faults(&self, faults: FaultSwitches) {
        *lock(&self.shared.faults) = faults;
    }

    /// The true joint trajectory so far (every integration step, ≥ 500 Hz).
    pub fn true_trajectory(&self) -> Vec<TrueSample> {
        lock(&self.shared.robot).log.clone()
    }

    /// The true joint angles now.
    pub fn true_joints(&self) -> Joints {
        let now = self.shared.now();
        let mut robot = lock(&self.shared.robot);
        robot.advance_to(now);
        robot.q
    }

    /// Why programs sent to the script port were refused, oldest first.
    pub fn script_errors(&self) -> Vec<String> {
        lock(&self.shared.script_errors).clone()
    }

    /// Whether a program is running.
    pub fn program_running(&self) -> bool {
        let now = self.shared.now();
        let mut robot = lock(&self.shared.robot);
        robot.advance_to(now);
        !robot.queue.is_empty()
    }

    /// Stops every thread and closes every connection.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        server::shutdown(&*self.shared, &mut self.threads);
    }
}

impl Drop for SimUr {
    fn drop(&mut self) {
        self.shutdown();
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

/// One RTDE connection's state.
struct Rtde {
    version: u16,
    recipe: Option<(u8, Vec<String>, f64)>,
    next_recipe_id: u8,
    streaming: bool,
    /// Next control cycle to send (index of multiples of the period).
    next_cycle: u64,
    sent: usize,
    writes: usize,
    /// Draws the jitter delays.
    jitter: Noise,
}

fn package(kind: u8, payload: &[u8]) -> Vec<u8> {
    let mut p = ((payload.len() + 3) as u16).to_be_bytes().to_vec();
    p.push(kind);
    p.extend_from_slice(payload);
    p
}

fn write_package(
    stream: &mut TcpStream,
    bytes: &[u8],
    faults: &FaultSwitches,
    writes: &mut usize,
) -> std::io::Result<()> {
    *writes += 1;
    if faults.split_writes && bytes.len() > 1 {
        let cut = 1 + *writes % (bytes.len() - 1);
        stream.write_all(&bytes[..cut])?;
        stream.flush()?;
        thread::sleep(Duration::from_millis(1));
        stream.write_all(&bytes[cut..])
    } else {
        stream.write_all(bytes)
    }
}

/// Output names the simulator knows and their types.
fn output_type(name: &str) -> &'static str {
    match name {
        "timestamp" => "DOUBLE",
        "actual_q" | "target_q" => "VECTOR6D",
        "runtime_state" => "UINT32",
        "robot_mode" => "INT32",
        _ => "NOT_FOUND",
    }
}

fn serve_rtde(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_nodelay(true);
    // Socket timeouts are rounded to scheduler ticks (several ms), too
    // coarse for 500 Hz: data packages go out from their own thread, which
    // sleeps precisely; requests are read here with a coarse timeout.
    let Ok(writer) = stream.try_clone() else {
        return;
    };
    let writer = Mutex::new(writer);
    let state = Mutex::new(Rtde {
        version: 0,
        recipe: None,
        next_recipe_id: 1,
        streaming: false,
        next_cycle: 0,
        sent: 0,
        writes: 0,
        jitter: Noise {
            state: shared.config.seed ^ 0x7177_E12A,
        },
    });
    let closed = AtomicBool::new(false);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(20)));
    thread::scope(|scope| {
        scope.spawn(|| send_data(&writer, &state, &closed, shared));
        let mut buf = Vec::new();
        let mut chunk = [0u8; 4096];
        'read: while !shared.stop.load(Ordering::SeqCst) && !closed.load(Ordering::SeqCst) {
            match stream.read(&mut chunk) {
                Ok(0) => break,
                Ok(n) => buf.extend_from_slice(&chunk[..n]),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(_) => break,
            }
            while buf.len() >= 3 {
                let size = u16::from_be_bytes([buf[0], buf[1]]) as usize;
                if size < 3 {
                    break 'read; // cannot resynchronise
                }
                if buf.len() < size {
                    break;
                }
                let kind = buf[2];
                let payload = buf[3..size].to_vec();
                buf.drain(..size);
                let faults = lock(&shared.faults).clone();
                thread::sleep(faults.reply_delay);
                let mut c = lock(&state);
                let replies = handle_request(&mut c, kind, &payload, shared);
                let mut w = lock(&writer);
                for r in replies {
                    if write_package(&mut w, &r, &faults, &mut c.writes).is_err() {
                        break 'read;
                    }
                }
            }
        }
        closed.store(true, Ordering::SeqCst);
    });
}

/// Sends a data package at every due cycle of a started stream.
fn send_data(writer: &Mutex<TcpStream>, state: &Mutex<Rtde>, closed: &AtomicBool, shared: &Shared) {
    while !shared.stop.load(Ordering::SeqCst) && !closed.load(Ordering::SeqCst) {
        let mut c = lock(state);
        let Some((id, names, f)) = c.recipe.clone().filter(|_| c.streaming) else {
            drop(c);
            thread::sleep(Duration::from_millis(1));
            continue;
        };
        let now = shared.now();
        let due = c.next_cycle as f64 / f;
        if now < due {
            drop(c);
            thread::sleep(Duration::from_secs_f64((due - now).min(0.005)));
            continue;
        }
        // Behind by more than a cycle: skip to the latest one.
        let cycle = c.next_cycle.max((now * f).floor() as u64);
        let faults = lock(&shared.faults).clone();
        if !faults.jitter_max.is_zero() {
            thread::sleep(faults.jitter_max.mul_f64(c.jitter.uniform()));
        }
        let mut w = lock(writer);
        if faults.drop_connection_after.is_some_and(|n| c.sent >= n) {
            let _ = w.shutdown(std::net::Shutdown::Both);
            closed.store(true, Ordering::SeqCst);
            return;
        }
        let data = data_package(id, &names, cycle as f64 / f, shared);
        if write_package(&mut w, &data, &faults, &mut c.writes).is_err() {
            closed.store(true, Ordering::SeqCst);
            return;
        }
        c.sent += 1;
        c.next_cycle = cycle + 1;
    }
}

fn handle_request(c: &mut Rtde, kind: u8, payload: &[u8], shared: &Shared) -> Vec<Vec<u8>> {
    match kind {
        b'V' => {
            let v = match payload {
                [a, b] => u16::from_be_bytes([*a, *b]),
                _ => 0,
            };
            let ok = v >= 1 && v <= shared.config.max_protocol_version;
            if ok {
                c.version = v;
            }
            let mut out = vec![package(b'V', &[ok as u8])];
            if ok {
                // A text message, as controllers send on their own.
                let (msg, source) = (b"RTDE client connected", b"sim-ur");
                let mut m = vec![msg.len() as u8];
                m.extend_from_slice(msg);
                m.push(source.len() as u8);
                m.extend_from_slice(source);
                m.push(3); // info
                out.push(package(b'M', &m));
            }
            out
        }
        b'O' => {
            let rate = shared.config.control_rate_hz;
            let (f, names) = if c.version >= 2 && payload.len() >= 8 {
                let f = f64::from_be_bytes(payload[..8].try_into().expect("8 bytes"));
                (f, &payload[8..])
            } else {
                (rate, payload)
            };
            let names: Vec<String> = String::from_utf8_lossy(names)
                .split(',')
                .map(str::to_string)
                .collect();
            let types: Vec<&str> = names.iter().map(|n| output_type(n)).collect();
            let valid_f = f > 0.0 && f <= rate;
            let id = if valid_f && !types.contains(&"NOT_FOUND") {
                let id = c.next_recipe_id;
                c.next_recipe_id = c.next_recipe_id.wrapping_add(1).max(1);
                c.recipe = Some((id, names, f));
                id
            } else {
                0
            };
            let mut reply = vec![id];
            reply.extend_from_slice(types.join(",").as_bytes());
            vec![package(b'O', &reply)]
        }
        b'S' => {
            let ok = c.recipe.is_some();
            if ok && !c.streaming {
                c.streaming = true;
                let f = c.recipe.as_ref().map_or(1.0, |r| r.2);
                c.next_cycle = (shared.now() * f).ceil() as u64;
            }
            vec![package(b'S', &[ok as u8])]
        }
        b'P' => {
            c.streaming = false;
            vec![package(b'P', &[1])]
        }
        _ => Vec::new(), // unknown packages are ignored
    }
}

fn data_package(id: u8, names: &[String], t: f64, shared: &Shared) -> Vec<u8> {
    let mut guard = lock(&shared.robot);
    let robot = &mut *guard;
    let (q, reference) = robot.state_at(t);
    let mut p = vec![id];
    for n in names {
        match n.as_str() {
            "timestamp" => {
                p.extend_from_slice(&(shared.config.uptime_at_epoch_s + t).to_be_bytes())
            }
            "actual_q" => {
                for x in q {
                    let noisy = x + robot.noise_rad * robot.noise.gaussian();
                    p.extend_from_slice(&noisy.to_be_bytes());
                }
            }
            "target_q" => {
                for x in reference {
                    p.extend_from_slice(&x.to_be_bytes());
                }
            }
            "runtime_state" => {
                let state: u32 = if robot.queue.is_empty() { 1 } else { 2 };
                p.extend_from_slice(&state.to_be_bytes());
            }
            "robot_mode" => p.extend_from_slice(&7i32.to_be_bytes()),
            _ => {}
        }
    }
    package(b'U', &p)
}

fn serve_script(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_read_timeout(Some(Duration::from_millis(20)));
    let mut text = Vec::new();
    let mut chunk = [0u8; 8192];
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        if shared.stop.load(Ordering::SeqCst) || Instant::now() > deadline {
            return;
        }
        match stream.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => text.extend_from_slice(&chunk[..n]),
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(_) => return,
        }
    }
    let program = String::from_utf8(text)
        .map_err(|_| "the program is not UTF-8".to_string())
        .and_then(|t| parse_program(&t));
    match program {
        Ok(cmds) => {
            let now = shared.now();
            let mut robot = lock(&shared.robot);
            robot.advance_to(now);
            robot.run(cmds, now);
        }
        Err(e) => lock(&shared.script_errors).push(e),
    }
}

/// One statement of the accepted URScript form.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `movej(q, a=…, v=…)`: to `q` at speed `v`, rad/s.
    MoveJ {
        /// Target, rad.
        q: Joints,
        /// Speed, rad/s.
        v: f64,
    },
    /// `servoj(q, t=…, lookahead_time=…, gain=…)`: to `q` in `t` s.
    ServoJ {
        /// Target, rad.
        q: Joints,
        /// Time, s.
        t: f64,
    },
    /// `stopj(a)`.
    StopJ,
}

/// Parses the accepted program form (see the module documentation).
pub fn parse_program(text: &str) -> Result<Vec<Command>, String> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (n, first) = lines.next().ok_or("empty program")?;
    let name = first
        .strip_prefix("def ")
        .and_then(|r| r.strip_suffix("():"))
        .ok_or_else(|| format!("line {n}: expected `def NAME():`, got {first:?}"))?;
    let mut cmds = Vec::new();
    let mut ended = false;
    for (n, line) in lines.by_ref() {
        if line == "end" {
            ended = true;
            break;
        }
        cmds.push(parse_statement(line).map_err(|e| format!("line {n}: {e}: {line:?}"))?);
    }
    if !ended {
        return Err("no `end` closing the program".into());
    }
    for (n, line) in lines {
        if line != format!("{name}()") {
            return Err(format!(
                "line {n}: after `end` only `{name}()` is accepted: {line:?}"
            ));
        }
    }
    Ok(cmds)
}

fn parse_statement(line: &str) -> Result<Command, String> {
    let (func, rest) = line.split_once('(').ok_or("not a call")?;
    let args = rest.strip_suffix(')').ok_or("no closing parenthesis")?;
    if func == "stopj" {
        args.trim().parse::<f64>().map_err(|_| "bad deceleration")?;
        return Ok(Command::StopJ);
    }
    let open = args
        .strip_prefix('[')
        .ok_or("the first argument must be a joint list")?;
    let (list, named) = open.split_once(']').ok_or("unclosed joint list")?;
    let values: Vec<f64> = list
        .split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| format!("bad joint value {x:?}"))
        })
        .collect::<Result<_, _>>()?;
    let q: Joints = values
        .try_into()
        .map_err(|v: Vec<f64>| format!("{} joint values, expected {JOINTS}", v.len()))?;
    let mut kw = std::collections::HashMap::new();
    for part in named.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| format!("bad argument {part:?}"))?;
        let v: f64 = v
            .trim()
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .ok_or_else(|| format!("bad value of {}", k.trim()))?;
        kw.insert(k.trim().to_string(), v);
    }
    let get = |k: &str| {
        kw.get(k)
            .copied()
            .ok_or_else(|| format!("{func} needs {k}="))
    };
    match func {
        "movej" => {
            let v = get("v")?;
            if v <= 0.0 {
                return Err("v must be positive".into());
            }
            Ok(Command::MoveJ { q, v })
        }
        "servoj" => {
            let t = get("t")?;
            get("lookahead_time")?;
            get("gain")?;
            if t <= 0.0 {
                return Err("t must be positive".into());
            }
            Ok(Command::ServoJ { q, t })
        }
        other => Err(format!("unsupported function {other}")),
    }
}

/// Reads the simulated UR arm's true state from another thread.
#[derive(Clone)]
pub struct UrStateProbe {
    shared: Arc<Shared>,
}

impl TrueMotion for UrStateProbe {
    fn now(&self) -> TrueState {
        let t = self.shared.now();
        lock(&self.shared.robot).true_state(t)
    }
}

/// A linear ramp of the reference.
#[derive(Clone, Copy, Debug)]
struct Ramp {
    from: Joints,
    to: Joints,
    duration: f64,
}

/// The simulated arm.
struct Robot {
    lag_s: f64,
    noise_rad: f64,
    noise: Noise,
    q: Joints,
    t: f64,
    r_prev: Joints,
    hold: Joints,
    queue: VecDeque<Ramp>,
    front_start: f64,
    log: Vec<TrueSample>,
    /// The reference at each logged step.
    ref_log: Vec<Joints>,
}

impl Robot {
    fn new(config: &SimUrConfig) -> Robot {
        let t = config.epoch.elapsed().as_secs_f64();
        Robot {
            lag_s: config.tracking_lag_s.max(0.0),
            noise_rad: config.encoder_noise_rad.max(0.0),
            noise: Noise { state: config.seed },
            q: config.initial,
            t,
            r_prev: config.initial,
            hold: config.initial,
            queue: VecDeque::new(),
            front_start: t,
            log: vec![TrueSample {
                t,
                q: config.initial,
            }],
            ref_log: vec![config.initial],
        }
    }

    /// Replaces the running program by `cmds`, starting at `now`.
    fn run(&mut self, cmds: Vec<Command>, now: f64) {
        let mut from = self.reference(now);
        self.queue.clear();
        self.hold = from;
        self.front_start = now;
        for c in cmds {
            let ramp = match c {
                Command::MoveJ { q, v } => {
                    let d = (0..JOINTS).fold(0.0_f64, |m, i| m.max((q[i] - from[i]).abs()));
                    Ramp {
                        from,
                        to: q,
                        duration: d / v,
                    }
                }
                Command::ServoJ { q, t } => Ramp {
                    from,
                    to: q,
                    duration: t,
                },
                Command::StopJ => continue,
            };
            from = ramp.to;
            self.queue.push_back(ramp);
        }
    }

    /// The reference at `t` (retires finished ramps).
    fn reference(&mut self, t: f64) -> Joints {
        self.reference_and_rate(t).0
    }

    /// The reference and its rate at `t` (retires finished ramps).
    fn reference_and_rate(&mut self, t: f64) -> (Joints, Joints) {
        while let Some(r) = self.queue.front() {
            let tau = t - self.front_start;
            if tau >= r.duration {
                self.hold = r.to;
                self.front_start += r.duration;
                self.queue.pop_front();
                continue;
            }
            let u = (tau / r.duration).max(0.0);
            let mut q = r.from;
            let mut rate = [0.0; JOINTS];
            for i in 0..JOINTS {
                q[i] += (r.to[i] - r.from[i]) * u;
                rate[i] = (r.to[i] - r.from[i]) / r.duration;
            }
            return (q, rate);
        }
        (self.hold, [0.0; JOINTS])
    }

    /// The true state at `t`: `q̇ = (r − q)/T`, `q̈ = (ṙ − q̇)/T` with the
    /// ramps' own rates (without a lag, the reference's; q̈ = 0 within a
    /// ramp).
    fn true_state(&mut self, t: f64) -> TrueState {
        self.advance_to(t);
        let (r, rd) = self.reference_and_rate(t.max(self.t));
        lagged_state(self.t, self.q, [r, rd, [0.0; JOINTS]], self.lag_s)
    }

    /// Integrates the lag up to `t`, exactly for a reference linear within
    /// each step (as the AUBO simulator does).
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
            self.ref_log.push(r);
        }
    }

    /// The true angles and the reference at `t`: integrated forward, or
    /// interpolated in the log (steps ≤ 2 ms) when the simulation is
    /// already past `t`.
    fn state_at(&mut self, t: f64) -> (Joints, Joints) {
        if t >= self.t {
            self.advance_to(t);
            return (self.q, self.r_prev);
        }
        let log = &self.log;
        let k = log.partition_point(|s| s.t < t).clamp(1, log.len() - 1);
        let (a, b) = (&log[k - 1], &log[k]);
        let u = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
        let (mut q, mut r) = (a.q, self.ref_log[k - 1]);
        for i in 0..JOINTS {
            q[i] += u * (b.q[i] - a.q[i]);
            r[i] += u * (self.ref_log[k][i] - r[i]);
        }
        (q, r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_servoj_program_form_and_refuses_others() {
        let p = "def robimu_plan():\n  movej([0, 0, 0, 0, 0, 0.5], a=1.0, v=0.5)\n  servoj([0.1, 0, 0, 0, 0, 0.5], t=0.008000, lookahead_time=0.1, gain=300)\n  stopj(2.0)\nend\nrobimu_plan()\n";
        let cmds = parse_program(p).unwrap();
        assert_eq!(
            cmds,
            vec![
                Command::MoveJ {
                    q: [0.0, 0.0, 0.0, 0.0, 0.0, 0.5],
                    v: 0.5
                },
                Command::ServoJ {
                    q: [0.1, 0.0, 0.0, 0.0, 0.0, 0.5],
                    t: 0.008
                },
                Command::StopJ
            ]
        );
        let e = parse_program(&p.replace("servoj", "speedj")).unwrap_err();
        assert!(e.contains("line 3") && e.contains("speedj"), "{e}");
        let e = parse_program(&p.replace("0.5], a", "0.5, 1], a")).unwrap_err();
        assert!(e.contains("7 joint values"), "{e}");
        assert!(parse_program(&p.replace("end\n", "")).is_err());
        assert!(parse_program(&p.replace("t=0.008000, ", ""))
            .unwrap_err()
            .contains("t="));
    }

    #[test]
    fn program_ramps_the_reference_through_the_lag() {
        let config = SimUrConfig {
            tracking_lag_s: 0.0,
            ..SimUrConfig::default()
        };
        let mut r = Robot::new(&config);
        let t0 = r.t;
        r.run(
            vec![
                Command::MoveJ {
                    q: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                    v: 2.0,
                },
                Command::ServoJ {
                    q: [1.0, 0.2, 0.0, 0.0, 0.0, 0.0],
                    t: 0.1,
                },
            ],
            t0,
        );
        // movej: 1 rad at 2 rad/s = 0.5 s, then servoj 0.1 s.
        assert!((r.state_at(t0 + 0.25).0[0] - 0.5).abs() < 1e-9);
        assert!((r.state_at(t0 + 0.55).0[1] - 0.1).abs() < 1e-9);
        assert_eq!(r.state_at(t0 + 1.0).0, [1.0, 0.2, 0.0, 0.0, 0.0, 0.0]);
        // In the past: interpolated from the log.
        let (q, reference) = r.state_at(t0 + 0.251);
        assert!((q[0] - 0.502).abs() < 1e-9 && (reference[0] - 0.502).abs() < 1e-9);
    }
}
