//! The simulated controller's URScript port: a connection sends one
//! program, which replaces the one running; the program form it accepts.

use std::collections::HashMap;
use std::net::TcpStream;
use std::time::{Duration, Instant};

use super::Shared;
use crate::arm::{Joints, JOINTS};
use crate::server::{self, lock, Received};

/// Reads one program until the client closes its write side (at most 5 s)
/// and runs it, or keeps why it was refused.
pub(super) fn serve_script(mut stream: TcpStream, shared: &Shared) {
    let _ = stream.set_read_timeout(Some(Duration::from_millis(20)));
    let mut text = Vec::new();
    let mut chunk = [0u8; 8192];
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        if shared.core.stopped() || Instant::now() > deadline {
            return;
        }
        match server::receive(&mut stream, &mut chunk) {
            Received::Bytes(n) => text.extend_from_slice(&chunk[..n]),
            Received::Nothing => {}
            Received::Closed => break,
            Received::Broken => return,
        }
    }
    let program = String::from_utf8(text)
        .map_err(|_| "the program is not UTF-8".to_string())
        .and_then(|t| parse_program(&t));
    match program {
        Ok(cmds) => {
            let now = shared.core.now();
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
    let mut kw = HashMap::new();
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
}
