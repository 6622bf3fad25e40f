//! The robot side of a recording, one interface over the drivers: connect,
//! move to the plan's start, poll joints, run the plan, tell when it ended.
//!
//! * AUBO: a joint move to the start before recording, the plan as one path
//!   buffer from a motion thread ([`super::motion`]); it has ended when the
//!   controller reports no motion.
//! * UR: one URScript program (`movej` to the start, a `servoj` per row)
//!   sent when recording starts; it has ended when the plan's duration has
//!   passed and the arm stands within 2 mrad of the plan's last pose.
//!
//! A recording that stops early halts a running plan ([`ArmRun::halt`]) on a
//! connection of its own: AUBO `stopJoint`, UR a `stopj` program.

use std::sync::mpsc::TryRecvError;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use super::motion::{self, Plan};
use crate::controller::aubo::{AuboClient, AuboError, JointPoller};
use crate::controller::ur::{UrError, UrPoller, UrPorts, UrRobot};
use crate::controller::{JointSample, RobotSpec};
use robimu_model::Robot;

/// Why the robot could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ArmError {
    /// AUBO.
    #[error(transparent)]
    Aubo(#[from] AuboError),
    /// Universal Robots.
    #[error(transparent)]
    Ur(#[from] UrError),
    /// The controller went silent while recording: its connection is open
    /// (no I/O error) but no joint sample came within the watchdog's limit
    /// (`silence_limit`: max(1 s, 20 sample periods)).
    #[error("the robot controller {robot} went silent while recording: no joint sample for {waited:.1?} (the limit is {limit:?}: max(1 s, 20 sample periods)) and no I/O error: it hung, or its network stopped with the connection open (check the controller and the cable, then record again)")]
    Silent {
        /// The controller (`aubo:HOST:PORT`, `ur:HOST:RTDE:SCRIPT`).
        robot: String,
        /// How long no sample came.
        waited: Duration,
        /// The watchdog's limit.
        limit: Duration,
    },
}

/// The robot connection's watchdog limit for joints sampled at `rate_hz`:
/// no joint sample for max(1 s, 20 sample periods) ends the recording with
/// [`ArmError::Silent`], keeping what was recorded (as the IMU board's
/// watchdog does, `crate::imu`). A polled controller (AUBO) answers each
/// poll within a period, a streaming one (UR RTDE) sends a package every
/// period: a second of nothing is tens of missed samples.
pub(crate) fn silence_limit(rate_hz: f64) -> Duration {
    let period = if rate_hz > 0.0 { 1.0 / rate_hz } else { 1.0 };
    Duration::from_secs_f64((20.0 * period).max(1.0))
}

/// A connected robot, before recording.
pub enum Arm {
    /// AUBO: one connection for motion, one for polling.
    Aubo {
        /// Motion commands.
        motion: AuboClient,
        /// Joint polling.
        polling: AuboClient,
    },
    /// Universal Robots.
    Ur(UrRobot),
}

/// A robot while recording.
pub struct ArmRun {
    poller: Poller,
    motion: Motion,
    spec: RobotSpec,
    /// When the last joint sample was received.
    heard: Instant,
    /// The watchdog's limit (`silence_limit`).
    limit: Duration,
    /// Set once the watchdog fired: the poller is not waited for.
    silent: bool,
}

/// Deceleration of a halt, rad/s² (the paper's joint acceleration limit).
const HALT_ACCELERATION: f64 = 1.745;

enum Poller {
    Aubo(JointPoller),
    Ur(UrPoller),
}

enum Motion {
    None,
    Aubo(Option<JoinHandle<Result<(), AuboError>>>),
    Ur {
        sent: Instant,
        duration: f64,
        end: [f64; 6],
        last: Option<[f64; 6]>,
    },
    Done,
}

impl Arm {
    /// Connects to the controller `spec` names.
    pub fn connect(spec: &RobotSpec) -> Result<Arm, ArmError> {
        let timeout = Duration::from_secs(2);
        Ok(match spec {
            RobotSpec::Aubo { host, port } => Arm::Aubo {
                motion: AuboClient::connect((host.as_str(), *port), timeout)?,
                polling: AuboClient::connect((host.as_str(), *port), timeout)?,
            },
            RobotSpec::Ur {
                host,
                rtde_port,
                script_port,
            } => Arm::Ur(UrRobot::connect(
                host,
                UrPorts {
                    rtde: *rtde_port,
                    script: *script_port,
                },
                timeout,
            )?),
        })
    }

    /// Before recording: brings the arm to the plan's start where the
    /// driver does that separately (AUBO).
    pub fn prepare(&mut self, robot: &Robot, plan: &Plan) -> Result<(), ArmError> {
        if let Arm::Aubo { motion, .. } = self {
            motion::move_to_start(motion, robot, plan)?;
        }
        Ok(())
    }

    /// Starts polling at `rate_hz` (times since `epoch`) and, after `rest`
    /// seconds, the plan.
    pub fn start(
        self,
        robot: &Robot,
        plan: Option<Plan>,
        rate_hz: f64,
        epoch: Instant,
        rest: f64,
        spec: &RobotSpec,
    ) -> Result<ArmRun, ArmError> {
        let spec = spec.clone();
        Ok(match self {
            Arm::Aubo {
                mut motion,
                polling,
            } => {
                let poller = Poller::Aubo(JointPoller::spawn(polling, rate_hz, epoch)?);
                let motion = match plan {
                    None => Motion::None,
                    Some(plan) => {
                        let robot = robot.clone();
                        Motion::Aubo(Some(thread::spawn(move || {
                            thread::sleep(Duration::from_secs_f64(rest));
                            motion::execute(&mut motion, &robot, &plan)
                        })))
                    }
                };
                ArmRun {
                    poller,
                    motion,
                    spec,
                    heard: Instant::now(),
                    limit: silence_limit(rate_hz),
                    silent: false,
                }
            }
            Arm::Ur(ur) => {
                let poller = Poller::Ur(ur.spawn_poller(rate_hz, epoch)?);
                let motion = match plan {
                    None => Motion::None,
                    Some(plan) => {
                        thread::sleep(Duration::from_secs_f64(rest));
                        let rows: Vec<(f64, Vec<f64>)> = plan
                            .q
                            .iter()
                            .enumerate()
                            .map(|(k, q)| (k as f64 * plan.dt, q.to_vec()))
                            .collect();
                        let duration = ur.execute_plan(&rows)?;
                        Motion::Ur {
                            sent: Instant::now(),
                            duration,
                            end: *plan.q.last().unwrap_or(&[0.0; 6]),
                            last: None,
                        }
                    }
                };
                ArmRun {
                    poller,
                    motion,
                    spec,
                    heard: Instant::now(),
                    limit: silence_limit(rate_hz),
                    silent: false,
                }
            }
        })
    }
}

impl ArmRun {
    /// The next joint sample, if one is waiting; `Err` ends the recording.
    pub fn try_sample(&mut self) -> Option<Result<JointSample, String>> {
        let next = match &self.poller {
            Poller::Aubo(p) => match p.samples().try_recv() {
                Ok(r) => Some(r.map_err(|e| e.to_string())),
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => Some(Err("the joint poller ended".into())),
            },
            Poller::Ur(p) => match p.samples().try_recv() {
                Ok(r) => Some(r.map_err(|e| e.to_string())),
                Err(TryRecvError::Empty) => None,
                Err(TryRecvError::Disconnected) => Some(Err("the RTDE reader ended".into())),
            },
        };
        if let (Some(Ok(s)), Motion::Ur { last, .. }) = (&next, &mut self.motion) {
            *last = Some(s.q);
        }
        if let Some(Ok(_)) = &next {
            self.heard = Instant::now();
        }
        next
    }

    /// The watchdog: [`ArmError::Silent`] when no joint sample has come
    /// for longer than `silence_limit` (the poller is then abandoned, not
    /// waited for, by [`Self::stop`]).
    pub fn silence(&mut self) -> Option<ArmError> {
        let waited = self.heard.elapsed();
        if waited <= self.limit {
            return None;
        }
        self.silent = true;
        Some(ArmError::Silent {
            robot: self.spec.to_string(),
            waited,
            limit: self.limit,
        })
    }

    /// Whether the plan has ended (`Ok(true)`; always with no plan: the
    /// caller's duration decides), or failed.
    pub fn motion_done(&mut self) -> Result<bool, String> {
        let done = match &mut self.motion {
            Motion::None => return Ok(false),
            Motion::Done => return Ok(true),
            Motion::Aubo(handle) => {
                if !handle.as_ref().is_some_and(|h| h.is_finished()) {
                    return Ok(false);
                }
                match handle.take().map(|h| h.join()) {
                    Some(Ok(Ok(()))) => true,
                    Some(Ok(Err(e))) => return Err(format!("the plan failed on the robot: {e}")),
                    _ => return Err("the motion thread failed".into()),
                }
            }
            Motion::Ur {
                sent,
                duration,
                end,
                last,
            } => {
                let elapsed = sent.elapsed().as_secs_f64();
                if elapsed < *duration {
                    return Ok(false);
                }
                let arrived = last.is_some_and(|q| (0..6).all(|j| (q[j] - end[j]).abs() < 2e-3));
                if !arrived && elapsed > *duration + 120.0 {
                    return Err("the UR arm did not reach the plan's last pose within 2 minutes of its end (is the program running? check the pendant)".into());
                }
                arrived
            }
        };
        if done {
            self.motion = Motion::Done;
        }
        Ok(done)
    }

    /// Whether a plan was started and has not been seen to end.
    pub fn moving(&self) -> bool {
        match &self.motion {
            Motion::None | Motion::Done => false,
            Motion::Aubo(h) => h.as_ref().is_some_and(|h| !h.is_finished()),
            Motion::Ur { .. } => true,
        }
    }

    /// Halts a running plan (see the module doc); `Ok` when the stop command
    /// was accepted.
    pub fn halt(&mut self) -> Result<(), String> {
        let timeout = Duration::from_secs(2);
        let r = match &self.spec {
            RobotSpec::Aubo { host, port } => AuboClient::connect((host.as_str(), *port), timeout)
                .and_then(|mut c| c.stop_joint(HALT_ACCELERATION))
                .map_err(|e| e.to_string()),
            RobotSpec::Ur {
                host,
                rtde_port,
                script_port,
            } => UrRobot::connect(
                host,
                UrPorts {
                    rtde: *rtde_port,
                    script: *script_port,
                },
                timeout,
            )
            .and_then(|ur| ur.stop(HALT_ACCELERATION))
            .map_err(|e| e.to_string()),
        };
        if r.is_ok() {
            self.motion = Motion::Done;
        }
        r
    }

    /// Stops polling; returns the samples still queued.
    pub fn stop(self) -> Vec<JointSample> {
        match (self.poller, self.silent) {
            (Poller::Aubo(p), false) => p.stop().1.try_iter().flatten().collect(),
            (Poller::Ur(p), false) => p.stop().1.try_iter().flatten().collect(),
            // a silent controller: its poller may be blocked on a read
            (Poller::Aubo(p), true) => p.abandon().try_iter().flatten().collect(),
            (Poller::Ur(p), true) => p.abandon().try_iter().flatten().collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_watchdog_allows_a_second_or_twenty_periods() {
        // AUBO polled and UR streamed at 125 Hz: 20 periods are 0.16 s
        assert_eq!(silence_limit(125.0), Duration::from_secs(1));
        // a slow controller: 20 periods of 10 Hz
        assert_eq!(silence_limit(10.0), Duration::from_secs(2));
        // no rate stated: as 1 Hz
        assert_eq!(silence_limit(0.0), Duration::from_secs(20));
        let e = ArmError::Silent {
            robot: "ur:10.0.0.2:30004:30002".into(),
            waited: Duration::from_millis(1010),
            limit: silence_limit(125.0),
        };
        assert!(e.to_string().starts_with(
            "the robot controller ur:10.0.0.2:30004:30002 went silent while recording: no joint sample for 1.0s (the limit is 1s"
        ));
    }
}
