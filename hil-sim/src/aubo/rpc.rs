//! The simulated controller's JSON-RPC 2.0 server: one thread per
//! connection parses the request stream and answers each request from the
//! simulated arm.

use std::io::Write;
use std::net::TcpStream;
use std::thread;
use std::time::Duration;

use serde_json::{json, Value};

use super::{status, FaultSwitches, Shared, StreamParser};
use crate::arm::{Joints, JOINTS};
use crate::server::{self, lock, Received};

pub(super) fn serve_connection(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_nodelay(true);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(20)));
    let mut parser = StreamParser::default();
    let mut answered = 0usize;
    let mut chunk = [0u8; 4096];
    while !shared.core.stopped() {
        let n = match server::receive(&mut stream, &mut chunk) {
            Received::Bytes(n) => n,
            Received::Nothing => continue,
            Received::Closed | Received::Broken => return,
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
            if faults.silent {
                continue;
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

/// A request's parameters, read by position; a missing or mistyped one is
/// a JSON-RPC "invalid params" error naming it.
struct Params<'a> {
    method: &'a str,
    p: &'a [Value],
}

impl<'a> Params<'a> {
    fn bad(&self, what: &str) -> RpcError {
        RpcError {
            code: -32602,
            message: format!("invalid params for {}: {what}", self.method),
        }
    }

    /// Parameter `i`, called `name`, read by `read`, else an error saying it
    /// `must be` so.
    fn get<T>(
        &self,
        i: usize,
        name: &str,
        must_be: &str,
        read: impl FnOnce(&'a Value) -> Option<T>,
    ) -> Result<T, RpcError> {
        self.p
            .get(i)
            .and_then(read)
            .ok_or_else(|| self.bad(&format!("parameter {i} ({name}) must be {must_be}")))
    }

    fn f64(&self, i: usize, name: &str) -> Result<f64, RpcError> {
        self.get(i, name, "a number", |v| {
            v.as_f64().filter(|x| x.is_finite())
        })
    }

    fn joints(&self, i: usize, name: &str) -> Result<Joints, RpcError> {
        self.get(i, name, &format!("{JOINTS} joint angles"), joints_of)
    }

    fn str(&self, i: usize, name: &str) -> Result<&'a str, RpcError> {
        self.get(i, name, "a string", Value::as_str)
    }

    fn bool(&self, i: usize, name: &str) -> Result<bool, RpcError> {
        self.get(i, name, "a boolean", Value::as_bool)
    }

    fn waypoints(&self, i: usize, name: &str) -> Result<Vec<Joints>, RpcError> {
        let must_be = format!("a list of {JOINTS}-joint vectors");
        self.get(i, name, &must_be, |v| {
            v.as_array()?.iter().map(joints_of).collect()
        })
    }
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
    let now = shared.core.now();
    let mut robot = lock(&shared.robot);
    robot.advance_to(now);
    if motion && faults.refuse_motion {
        // A robot in protective stop refuses before looking at parameters.
        return Ok(json!(status::BAD_STATE));
    }
    let p = Params { method, p };
    let code = match name {
        "RobotState.getJointPositions" => return Ok(json!(robot.measured().to_vec())),
        "MotionControl.isServoModeEnabled" => return Ok(json!(robot.servo_mode)),
        "MotionControl.getExecId" => return Ok(json!(robot.exec_id())),
        "MotionControl.moveJoint" => {
            robot.move_joint(p.joints(0, "q")?, p.f64(1, "a")?, p.f64(2, "v")?)
        }
        "MotionControl.setServoMode" => robot.set_servo_mode(p.bool(0, "enable")?, now),
        "MotionControl.servoJoint" => robot.servo_joint(p.joints(0, "q")?, p.f64(3, "t")?, now),
        "MotionControl.pathBufferAlloc" => {
            robot.path_alloc(p.str(0, "name")?, p.f64(1, "type")?, p.f64(2, "size")?)
        }
        "MotionControl.pathBufferAppend" => {
            robot.path_append(p.str(0, "name")?, p.waypoints(1, "waypoints")?)
        }
        "MotionControl.pathBufferEval" => robot.path_eval(
            p.str(0, "name")?,
            p.joints(1, "a")?,
            p.joints(2, "v")?,
            p.f64(3, "t")?,
        ),
        "MotionControl.movePathBuffer" => robot.move_path(p.str(0, "name")?),
        "MotionControl.pathBufferFree" => match robot.buffers.remove(p.str(0, "name")?) {
            Some(_) => status::OK,
            None => status::INVL_ARGUMENT,
        },
        "MotionControl.stopJoint" => {
            p.f64(0, "acc")?;
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
