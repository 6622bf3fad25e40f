//! The pre-flight check of a recording (`robimu check`, run at the start of
//! `calibrate`): what in a session would make its calibration wrong or
//! useless, found before the fit. Each [`Finding`] has a severity, the
//! number behind it and what to do; one finding kind per module:
//!
//! * [`streams`] — sample rates and gaps per stream, repeated timestamps,
//!   timestamps in ms, clock jumps, the overlap of the two streams;
//! * [`channels`] — stuck (constant) and all-zero channels, saturation
//!   against the device's range (session.toml `[imu]`, docs/model.md §7.2);
//! * [`units`] — the accelerometer and gyroscope units: |s̃| at rest
//!   against g₀ within the gains' prior, |ω̃| during motion against the
//!   nominal kinematics' prediction from q̇ (§1.5, [`predicted_rate`]),
//!   swapped columns;
//! * [`motion`] — a motionless recording, and the excitation: the posterior
//!   σ the recorded motion gives under the prior (paper eq. (26), the
//!   information of [`crate::plan::information`]) — the parameters this
//!   recording cannot determine.
//!
//! A session with tool poses (`source = "poses"`, docs/model.md §7.9) is
//! checked by [`poses::check_pose_session`]: the streams as above, the
//! timing jitter and a start-up burst of late-stamped IMU samples
//! ([`timing`]), saturation found in the samples ([`clipping`]), and the
//! poses' quaternions and units ([`poses`]).
//!
//! Times in files that the reader refuses (NaN, time going backwards) are
//! one fatal finding naming the file and line ([`CheckReport::unreadable`]).

pub mod channels;
pub mod clipping;
pub mod motion;
pub mod poses;
pub(crate) mod predicted_rate;
pub mod streams;
pub mod timing;
pub mod units;

pub use poses::check_pose_session;

use std::fmt;

use predicted_rate::PredictedRate;
use robimu_model::Robot;
use robimu_session::Session;
use serde::Serialize;

/// How bad a finding is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// For the record.
    Info,
    /// The calibration runs but may suffer.
    Warning,
    /// The calibration would be wrong or cannot run: `calibrate` stops.
    Fatal,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(match self {
            Severity::Info => "info",
            Severity::Warning => "warning",
            Severity::Fatal => "fatal",
        })
    }
}

/// One thing the check found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// The kind, snake_case (`gyro_units`, `gap`, …).
    pub kind: &'static str,
    /// How bad it is.
    pub severity: Severity,
    /// The stream or channel it is about (`imu.csv`, `gx`, …).
    pub subject: String,
    /// The number behind it (its unit in `message`).
    pub value: f64,
    /// What was found, with the number.
    pub message: String,
    /// What to do.
    pub action: String,
}

impl Finding {
    /// A finding.
    pub fn new(
        kind: &'static str,
        severity: Severity,
        subject: impl Into<String>,
        value: f64,
        message: impl Into<String>,
        action: impl Into<String>,
    ) -> Self {
        Self {
            kind,
            severity,
            subject: subject.into(),
            value,
            message: message.into(),
            action: action.into(),
        }
    }
}

/// What to check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CheckOptions {
    /// Also the excitation ([`motion::excitation`]): the posterior σ of
    /// every parameter under the recorded motion (a few ms to a second).
    pub excitation: bool,
}

impl Default for CheckOptions {
    fn default() -> Self {
        Self { excitation: true }
    }
}

/// All findings of one session, in the order checked.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CheckReport {
    /// The findings.
    pub findings: Vec<Finding>,
}

impl CheckReport {
    /// The report of a session the reader refuses (`error` names the file
    /// and line: a NaN, time going backwards, a missing column, …).
    pub fn unreadable(error: &robimu_session::SessionError) -> Self {
        Self {
            findings: vec![Finding::new(
                "unreadable",
                Severity::Fatal,
                "session",
                f64::NAN,
                error.to_string(),
                "fix what the message names (the session format, docs/model.md §7: every value a finite number, time never decreasing)",
            )],
        }
    }

    /// The first fatal finding.
    pub fn fatal(&self) -> Option<&Finding> {
        self.findings.iter().find(|f| f.severity == Severity::Fatal)
    }

    /// The findings of `severity`.
    pub fn of(&self, severity: Severity) -> impl Iterator<Item = &Finding> {
        self.findings.iter().filter(move |f| f.severity == severity)
    }

    /// The first finding of `kind`.
    pub fn find(&self, kind: &str) -> Option<&Finding> {
        self.findings.iter().find(|f| f.kind == kind)
    }
}

/// Check `session`, recorded with `robot`.
///
/// The excitation is assessed only when nothing else is fatal (a
/// recording in the wrong units or on a broken clock says nothing about it).
///
/// The gyroscope's predicted rate ([`predicted_rate`], the longest part) is
/// computed on a second thread from the start; this one checks everything
/// else, then helps with what is left of it.
pub fn check_session(session: &Session, robot: &Robot, opts: &CheckOptions) -> CheckReport {
    let rate = PredictedRate::new(session, robot);
    let (mut findings, ()) = robimu_model::pair::join(
        || {
            let predicted = || {
                rate.work();
                rate.wait();
                rate.rms()
            };
            let mut findings = Vec::new();
            findings.extend(streams::check(session));
            findings.extend(channels::check(session));
            let moving = motion::motionless(session);
            let still = moving.iter().any(|f| f.severity == Severity::Fatal);
            findings.extend(moving);
            findings.extend(units::check(session, robot, still, predicted));
            // not asked for (a fatal finding first): the rest is not computed
            rate.stop();
            findings
        },
        || rate.work(),
    );
    let fatal = findings.iter().any(|f| f.severity == Severity::Fatal);
    if opts.excitation && !fatal {
        findings.extend(motion::excitation(session, robot));
    }
    CheckReport { findings }
}

/// The median of `v` (NaN when empty); `v` is reordered.
pub(crate) fn median_of(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let k = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    *m
}
