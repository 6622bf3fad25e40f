//! The simulated controller's RTDE server: protocol version, output
//! recipes, start and pause, and a data package per control cycle.

use std::io::Write;
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::thread;
use std::time::Duration;

use robimu_controller_wire::rtde::{self as wire, package, PackageParser};

use super::{FaultSwitches, Shared};
use crate::arm::noise::Noise;
use crate::server::{self, lock, Received};

/// A package of type `kind`; none (not sent) for a payload too long for
/// one, which only a client asking for thousands of outputs could cause.
fn encode(kind: u8, payload: &[u8]) -> Vec<u8> {
    wire::encode(kind, payload).unwrap_or_default()
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

pub(super) fn serve_rtde(mut stream: TcpStream, shared: &Shared) {
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
        let mut packages = PackageParser::default();
        let mut chunk = [0u8; 4096];
        'read: while !shared.core.stopped() && !closed.load(Ordering::SeqCst) {
            match server::receive(&mut stream, &mut chunk) {
                Received::Bytes(n) => packages.push(&chunk[..n]),
                Received::Nothing => {}
                Received::Closed | Received::Broken => break,
            }
            loop {
                let (kind, payload) = match packages.next_package() {
                    Ok(Some(p)) => p,
                    Ok(None) => break,
                    Err(_) => break 'read, // cannot resynchronise
                };
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
    while !shared.core.stopped() && !closed.load(Ordering::SeqCst) {
        let mut c = lock(state);
        let Some((id, names, f)) = c.recipe.clone().filter(|_| c.streaming) else {
            drop(c);
            thread::sleep(Duration::from_millis(1));
            continue;
        };
        let now = shared.core.now();
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
        if faults.stall_data {
            // the cycle passes unsent; the connection stays open
            c.next_cycle = cycle + 1;
            drop(w);
            drop(c);
            thread::sleep(Duration::from_millis(1));
            continue;
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
        package::REQUEST_PROTOCOL_VERSION => {
            let v = match payload {
                [a, b] => u16::from_be_bytes([*a, *b]),
                _ => 0,
            };
            let ok = v >= 1 && v <= shared.config.max_protocol_version;
            if ok {
                c.version = v;
            }
            let mut out = vec![encode(package::REQUEST_PROTOCOL_VERSION, &[ok as u8])];
            if ok {
                // A text message, as controllers send on their own.
                let (msg, source) = (b"RTDE client connected", b"sim-ur");
                let mut m = vec![msg.len() as u8];
                m.extend_from_slice(msg);
                m.push(source.len() as u8);
                m.extend_from_slice(source);
                m.push(3); // info
                out.push(encode(package::TEXT_MESSAGE, &m));
            }
            out
        }
        package::SETUP_OUTPUTS => {
            let rate = shared.config.control_rate_hz;
            let (f, names) = if c.version >= 2 && payload.len() >= 8 {
                let f = f64::from_be_bytes(payload[..8].try_into().expect("8 bytes"));
                (f, &payload[8..])
            } else {
                (rate, payload)
            };
            // a trailing comma (ur_rtde sends one) names nothing, as on the
            // real controller
            let names: Vec<String> = String::from_utf8_lossy(names)
                .split(',')
                .filter(|n| !n.is_empty())
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
            vec![encode(package::SETUP_OUTPUTS, &reply)]
        }
        package::START => {
            let ok = c.recipe.is_some();
            if ok && !c.streaming {
                c.streaming = true;
                let f = c.recipe.as_ref().map_or(1.0, |r| r.2);
                c.next_cycle = (shared.core.now() * f).ceil() as u64;
            }
            vec![encode(package::START, &[ok as u8])]
        }
        package::PAUSE => {
            c.streaming = false;
            vec![encode(package::PAUSE, &[1])]
        }
        package::GET_URCONTROL_VERSION => {
            // PolyScope 5.15 on an e-Series (500 Hz), 3.15 on a CB3
            let major = if shared.config.control_rate_hz > 125.0 {
                5
            } else {
                3
            };
            let reply: Vec<u8> = [major, 15u32, 0, 0]
                .iter()
                .flat_map(|v| v.to_be_bytes())
                .collect();
            vec![encode(package::GET_URCONTROL_VERSION, &reply)]
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
                for x in robot.measure(q) {
                    p.extend_from_slice(&x.to_be_bytes());
                }
            }
            "target_q" => {
                for x in reference {
                    p.extend_from_slice(&x.to_be_bytes());
                }
            }
            "runtime_state" => {
                let state: u32 = if robot.reference.is_idle() { 1 } else { 2 };
                p.extend_from_slice(&state.to_be_bytes());
            }
            "robot_mode" => p.extend_from_slice(&7i32.to_be_bytes()),
            _ => {}
        }
    }
    encode(package::DATA_PACKAGE, &p)
}
