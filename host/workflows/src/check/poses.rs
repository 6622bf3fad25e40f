//! The check of a session with tool poses (docs/model.md §7.9): the
//! streams as for a joint session ([`super::streams`]: rates,
//! gaps with their time and length, repeated stamps, time units, the
//! overlap of `poses.csv` and each IMU's span), the timing jitter of each
//! stream and a start-up burst of late-stamped IMU samples
//! ([`super::timing`]), stuck IMU channels ([`super::channels`]: all six
//! 0, or one constant or repeating a value), saturated IMU channels
//! ([`super::clipping`], or against the `[imu]` / `[imu<j>]` range when
//! recorded) — each IMU's (`imu.csv`, `imu<j>.csv`), each finding naming
//! its file — and the poses themselves:
//!
//! * quaternion sign flips (q·q' < 0 between consecutive rows: q and −q
//!   are the same rotation; information);
//! * quaternions that are not unit (|q| off 1 by more than `NON_UNIT`:
//!   count and worst; a warning, fatal when the median is off by
//!   `NOT_QUATERNION`: the columns are not a quaternion w first);
//! * positions in mm (a range over `MM_RANGE` m on an axis, the 90th
//!   percentile of the speed over `MM_SPEED` m/s, or a distance from the
//!   origin over `MM_DISTANCE` m: fatal);
//! * the inverse rotation convention ([`convention`]: the gyroscope
//!   follows the rates of the quaternions' inverse; fatal).

use super::streams::{nominal_rate, overlap, stream};
use super::{clipping, median_of, timing, CheckReport, Finding, Severity};
use robimu_session::{files, PoseSession, Table};

/// A quaternion whose norm is off 1 by more than this is named.
pub(crate) const NON_UNIT: f64 = 1e-3;
/// When the median norm is off 1 by more than this the columns are no
/// unit quaternion at all (fatal).
pub(crate) const NOT_QUATERNION: f64 = 0.1;
/// A position range (m) on one axis beyond which poses are taken for mm.
pub(crate) const MM_RANGE: f64 = 10.0;
/// A 90th-percentile speed (m/s) beyond which poses are taken for mm: no
/// tool or tracked body moves this fast for a tenth of a recording.
pub(crate) const MM_SPEED: f64 = 10.0;
/// A distance (m) from the world origin beyond which poses are taken for
/// mm: a robot's base or a motion-capture room is not this large (a small
/// motion in mm has neither the range nor the speed of `MM_RANGE`,
/// `MM_SPEED`, but is far from its origin).
pub(crate) const MM_DISTANCE: f64 = 100.0;

/// Check the pose session `session`; the findings in the order checked.
pub fn check_pose_session(session: &PoseSession) -> CheckReport {
    let mut findings = Vec::new();
    findings.extend(stream(files::POSES, &session.poses, None));
    findings.extend(timing::jitter(files::POSES, &session.poses.t));
    findings.extend(sign_flips(session));
    findings.extend(non_unit(session));
    findings.extend(millimetres(&session.poses));
    findings.extend(convention::inverse_rotation(session));
    for (j, imu) in session.imus.iter().enumerate() {
        let name = files::imu_csv(j);
        let table = if j == 0 {
            session.meta.imu.as_ref()
        } else {
            session.meta.imu_tables.get(&j)
        };
        findings.extend(stream(&name, &imu.samples, nominal_rate(table)));
        findings.extend(timing::jitter(&name, &imu.samples.t));
        findings.extend(timing::startup_burst(&name, &imu.samples.t));
        findings.extend(super::channels::imu_channels(&name, &imu.samples));
        findings.extend(saturation(&name, &imu.samples, table));
        findings.extend(overlap(
            (files::POSES, &session.poses),
            (&name, &imu.samples),
        ));
    }
    CheckReport { findings }
}

/// Saturation against the `[imu]` range when recorded (as in a joint
/// session), else found in the samples ([`clipping`]).
fn saturation(name: &str, imu: &Table, table: Option<&toml::Table>) -> Vec<Finding> {
    let (accel, gyro) = super::channels::ranges_of(table);
    if accel.is_none() && gyro.is_none() {
        return clipping::check(name, imu);
    }
    super::channels::saturation_of(name, imu, accel, gyro)
}

/// Consecutive quaternions of opposite sign (q·q' < 0): counted, the first
/// named (information: the same rotations, but a reader that interpolates
/// the components naively goes the long way round).
fn sign_flips(session: &PoseSession) -> Option<Finding> {
    let q = session.quaternions();
    let t = &session.poses.t;
    let flips: Vec<usize> = (1..q.len())
        .filter(|&i| (0..4).map(|k| q[i][k] * q[i - 1][k]).sum::<f64>() < 0.0)
        .collect();
    let first = *flips.first()?;
    Some(Finding::new(
        "quaternion_sign",
        Severity::Info,
        files::POSES,
        flips.len() as f64,
        format!(
            "poses.csv: {} quaternion sign flips (q·q' < 0 between consecutive rows, the first at \
             t = {:.3} s): harmless, q and −q are the same rotation",
            flips.len(),
            t[first]
        ),
        "none needed: q and −q are one rotation (a tool that interpolates the components must align their signs first)",
    ))
}

/// Quaternions whose norm is off 1 by more than `NON_UNIT`: the count
/// and the worst.
fn non_unit(session: &PoseSession) -> Option<Finding> {
    let mut norms: Vec<f64> = session
        .quaternions()
        .iter()
        .map(|q| q.iter().map(|v| v * v).sum::<f64>().sqrt())
        .collect();
    let off: Vec<usize> = (0..norms.len())
        .filter(|&i| (norms[i] - 1.0).abs() > NON_UNIT)
        .collect();
    let worst = *off
        .iter()
        .max_by(|&&a, &&b| (norms[a] - 1.0).abs().total_cmp(&(norms[b] - 1.0).abs()))?;
    let (worst_norm, worst_t) = (norms[worst], session.poses.t[worst]);
    let median = median_of(&mut norms);
    let fatal = (median - 1.0).abs() > NOT_QUATERNION;
    let n = session.poses.len();
    Some(Finding::new(
        "quaternion_norm",
        if fatal {
            Severity::Fatal
        } else {
            Severity::Warning
        },
        files::POSES,
        off.len() as f64,
        format!(
            "poses.csv: {} of {n} quaternions are not unit (|q| off 1 by more than {NON_UNIT}; the \
             worst |q| = {worst_norm:.6} at t = {worst_t:.3} s; median |q| = {median:.6})",
            off.len()
        ),
        if fatal {
            "the columns qw,qx,qy,qz are not a unit quaternion, w first: check the export's columns and convention (docs/model.md §7.9)"
        } else {
            "normalise them (q/|q|); many or far off: check the source's precision, or rows where the tracker lost the body"
        },
    ))
}

/// Positions that look like millimetres: a range over `MM_RANGE` m on an
/// axis, the 90th percentile of the speed between rows over `MM_SPEED`
/// m/s, or a distance from the origin over `MM_DISTANCE` m (fatal).
fn millimetres(poses: &Table) -> Option<Finding> {
    let p: Vec<&[f64]> = poses.values.chunks_exact(7).collect();
    let range = (0..3)
        .map(|c| {
            let (lo, hi) = p
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
                    (l.min(r[c]), h.max(r[c]))
                });
            hi - lo
        })
        .fold(0.0f64, f64::max);
    let norm = |r: &[f64]| (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    let distance = p.iter().map(|r| norm(r)).fold(0.0f64, f64::max);
    let mut speeds: Vec<f64> = (1..p.len())
        .filter_map(|i| {
            let dt = poses.t[i] - poses.t[i - 1];
            let d = [0, 1, 2].map(|c| p[i][c] - p[i - 1][c]);
            (dt > 0.0).then(|| norm(&d) / dt)
        })
        .collect();
    speeds.sort_by(f64::total_cmp);
    let p90 = speeds.get(speeds.len() * 9 / 10).copied().unwrap_or(0.0);
    if range <= MM_RANGE && p90 <= MM_SPEED && distance <= MM_DISTANCE {
        return None;
    }
    Some(Finding::new(
        "pose_units",
        Severity::Fatal,
        files::POSES,
        range,
        format!(
            "poses.csv: poses in mm? the positions span {range:.3} \"m\" on one axis (in mm: {:.3} m), \
             reach {distance:.3} \"m\" from the origin (in mm: {:.3} m), and 10 % of the speeds \
             exceed {p90:.3} \"m/s\" (in mm: {:.3} m/s); no tool moves over more than {MM_RANGE} m, \
             {MM_DISTANCE} m from its origin or faster than {MM_SPEED} m/s",
            range * 1e-3,
            distance * 1e-3,
            p90 * 1e-3
        ),
        "pass --units mm (to the import), or divide px, py, pz by 1000: poses.csv holds metres (docs/model.md §7.9)",
    ))
}

mod convention;
#[cfg(test)]
mod tests;
