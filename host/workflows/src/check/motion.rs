//! Whether the recording moves, and whether its motion excites the
//! parameters: the posterior σ of x under the prior and the information of
//! the recorded trajectory (paper eq. (26); [`Information`] at the nominal
//! x, the session's IMU noise model and rate, the midpoint rule at
//! [`QUADRATURE`] points per second — the planner's and `robimu
//! identifiability`'s measure). A parameter whose σ stays above
//! [`UNDETERMINED`] of its prior σ is one this recording cannot determine.

use robimu_model::{Knots, Robot, Spline};
use robimu_session::{files, Session};

use super::{Finding, Severity};
use crate::plan::information::{posterior_sigma, robot_lengths, Information, Sampling};

/// The largest joint range (rad) of a recording that does not move.
pub(crate) const MOTIONLESS: f64 = 0.01;
/// σ / prior σ above which a parameter is not determined.
pub(crate) const UNDETERMINED: f64 = 0.9;
/// Midpoint-rule points per second of the excitation measure.
pub(crate) const QUADRATURE: f64 = 20.0;

/// A fatal finding when no joint moves by more than [`MOTIONLESS`].
pub fn motionless(session: &Session) -> Vec<Finding> {
    let j = &session.joints;
    let n = j.width();
    // every joint's extremes in one pass over the rows
    let mut lo = vec![f64::INFINITY; n];
    let mut hi = vec![f64::NEG_INFINITY; n];
    for row in j.values.chunks(n.max(1)) {
        for ((v, a), b) in row.iter().zip(&mut lo).zip(&mut hi) {
            (*a, *b) = (a.min(*v), b.max(*v));
        }
    }
    let (mut range, mut joint) = (0.0f64, 0usize);
    for c in 0..n {
        if hi[c] - lo[c] > range {
            (range, joint) = (hi[c] - lo[c], c);
        }
    }
    if range >= MOTIONLESS {
        return Vec::new();
    }
    vec![Finding::new(
        "motionless",
        Severity::Fatal,
        files::JOINTS,
        range,
        format!(
            "the robot does not move (largest joint range {range:.4} rad, q{}): a static recording determines neither the robot nor most IMU parameters",
            joint + 1
        ),
        "record an excitation trajectory (robimu plan, then robimu record); a static recording is for robimu noise / allan",
    )]
}

/// The excitation finding: the parameters the recorded motion cannot
/// determine (robot lengths alone are info: they need speed, paper §8.4).
pub fn excitation(session: &Session, robot: &Robot) -> Vec<Finding> {
    match sigma_ratios(session, robot) {
        Ok(list) => vec![excitation_finding(robot, &list)],
        Err(e) => vec![Finding::new(
            "excitation",
            Severity::Info,
            "motion",
            f64::NAN,
            format!("excitation not assessed: {e}"),
            "",
        )],
    }
}

/// Each parameter's name and σ / prior σ under the recorded motion.
pub(crate) fn sigma_ratios(session: &Session, robot: &Robot) -> Result<Vec<(String, f64)>, String> {
    let noise = session.noise_model(robot).map_err(|e| e.to_string())?;
    let rate = session
        .imu
        .median_rate()
        .ok_or("imu.csv has no sample interval")?;
    let info = Information::with_noise(robot, noise, rate).map_err(|e| e.to_string())?;
    let j = &session.joints;
    let (a, b) = j.span().ok_or("joints.csv is empty")?;
    let knots = Knots::uniform(a, b, 1.0, 3).map_err(|e| e.to_string())?;
    let spline = Spline::fit(knots, j.width(), &j.t, &j.values).map_err(|e| e.to_string())?;
    let total = info.total(&spline, 1.0, Sampling::Quadrature(QUADRATURE));
    let sigma = posterior_sigma(&total).ok_or("the information is not positive definite")?;
    Ok(info
        .layout()
        .specs()
        .iter()
        .zip(sigma)
        .map(|(s, v)| (s.name.clone(), v / s.sigma))
        .collect())
}

fn excitation_finding(robot: &Robot, ratios: &[(String, f64)]) -> Finding {
    let layout = robimu_model::ParamLayout::new(robot);
    let lengths = robot_lengths(&layout);
    let weak: Vec<(usize, &(String, f64))> = ratios
        .iter()
        .enumerate()
        .filter(|(_, (_, r))| *r > UNDETERMINED)
        .collect();
    let others: Vec<&str> = weak
        .iter()
        .filter(|(k, _)| !lengths.contains(k))
        .map(|(_, (n, _))| n.as_str())
        .collect();
    let names = |v: &[&str]| v.join(", ");
    let worst = weak.iter().map(|(_, (_, r))| *r).fold(0.0f64, f64::max);
    if weak.is_empty() {
        let (name, best) = ratios
            .iter()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(("", 0.0), |(n, r)| (n.as_str(), *r));
        return Finding::new(
            "excitation",
            Severity::Info,
            "motion",
            best,
            format!(
                "the motion determines every parameter (largest σ/prior σ = {best:.2}, {name})"
            ),
            "",
        );
    }
    let length_names: Vec<&str> = weak
        .iter()
        .filter(|(k, _)| lengths.contains(k))
        .map(|(_, (n, _))| n.as_str())
        .collect();
    if others.is_empty() {
        return Finding::new(
            "excitation",
            Severity::Info,
            "motion",
            length_names.len() as f64,
            format!(
                "this recording cannot determine {} robot length parameter(s) (σ > {UNDETERMINED} prior σ: {}): expected below high speeds (paper §8.4)",
                length_names.len(),
                names(&length_names)
            ),
            "they stay at the prior; faster motion (robimu plan) or a tracker determines them",
        );
    }
    Finding::new(
        "excitation",
        Severity::Warning,
        "motion",
        others.len() as f64,
        format!(
            "this recording cannot determine {} parameter(s) beyond the robot lengths (σ > {UNDETERMINED} prior σ, up to {worst:.2}): {}{}",
            others.len(),
            names(&others),
            if length_names.is_empty() {
                String::new()
            } else {
                format!("; and {} robot length(s)", length_names.len())
            }
        ),
        "excite more (robimu plan: an optimised trajectory), or --freeze them",
    )
}
