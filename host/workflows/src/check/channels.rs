//! Stuck channels and saturation: an IMU channel that never changes (all
//! zero: not connected or not enabled; another constant: frozen), a
//! channel that repeats one value for a long run of rows, and samples at
//! the device's range (session.toml `[imu]` `accel_range` `G2…G16`,
//! `gyro_range` `Dps125…Dps2000`, as `robimu record` writes them).

use super::{Finding, Severity};
use robimu_session::{files, Session, Table, IMU_COLUMNS};

/// A run of identical values over at least this share of the rows is a
/// stuck channel (fatal); over [`STUCK_RUN_S`] a warning.
pub(crate) const STUCK_SHARE: f64 = 0.5;
/// Seconds of identical consecutive values that make a warning.
pub(crate) const STUCK_RUN_S: f64 = 1.0;
/// A sample within this fraction of the range is saturated.
pub(crate) const SATURATION: f64 = 0.98;
/// Standard gravity, m/s² (the BNO055's g).
pub(crate) const G_STANDARD: f64 = 9.80665;

/// The channel findings of `session`.
pub fn check(session: &Session) -> Vec<Finding> {
    let mut out = imu_channels(files::IMU, &session.imu);
    for (j, name) in session.joints.columns.iter().enumerate() {
        out.extend(stuck(files::JOINTS, &session.joints, j, name, false));
    }
    out.extend(saturation(session));
    out
}

/// The stuck channels of the IMU table `imu` read from `file` (`imu.csv`,
/// `imu<j>.csv`; a joint or a pose session's): all six 0, or one channel
/// constant or repeating a value.
pub(crate) fn imu_channels(file: &str, imu: &Table) -> Vec<Finding> {
    let all_zero = (0..6).all(|c| column(imu, c).all(|v| v == 0.0));
    if !all_zero {
        let channels = IMU_COLUMNS.iter().enumerate();
        return channels
            .filter_map(|(c, name)| stuck(file, imu, c, name, true))
            .collect();
    }
    vec![Finding::new(
        "stuck",
        Severity::Fatal,
        file,
        imu.len() as f64,
        format!("{file}: all six channels are 0 in all {} rows", imu.len()),
        "the sensor was not read (not connected, not enabled, or the topic held no data): record again",
    )]
}

fn column(t: &Table, c: usize) -> impl Iterator<Item = f64> + '_ {
    t.values.iter().skip(c).step_by(t.width()).copied()
}

/// The longest run of identical values of column `c` of `t` (read from
/// `file`): constant, or stuck. A joint that does not move is a warning
/// (its parameters stay at the prior: the excitation finding names them),
/// an IMU channel fatal.
fn stuck(file: &str, t: &Table, c: usize, name: &str, imu: bool) -> Option<Finding> {
    let (w, len) = (t.width(), t.len());
    let v = |i: usize| t.values[i * w + c];
    let (mut best, mut start, mut run_start) = (1usize, 0usize, 0usize);
    // the column's values side by side, row by row
    let pairs = (t.values.chunks_exact(w)).zip(t.values.get(w..).unwrap_or(&[]).chunks_exact(w));
    for (i, (before, row)) in (1..).zip(pairs) {
        if row[c] != before[c] {
            run_start = i;
        } else if i + 1 - run_start > best {
            best = i + 1 - run_start;
            start = run_start;
        }
    }
    let end = start + best - 1;
    let seconds = t.t[end] - t.t[start];
    if best == len && len > 1 {
        let severity = if imu {
            Severity::Fatal
        } else {
            Severity::Warning
        };
        return Some(Finding::new(
            "stuck",
            severity,
            name,
            v(0),
            format!("{file}: {name} is constant ({} in all {len} rows)", v(0)),
            if imu {
                "a stuck or disconnected channel: check the sensor and record again"
            } else {
                "this joint never moves: its parameters stay at the prior (move it, or accept that)"
            },
        ));
    }
    let share = best as f64 / len as f64;
    if best > 2 && (share >= STUCK_SHARE || seconds >= STUCK_RUN_S) {
        let severity = if imu && share >= STUCK_SHARE {
            Severity::Fatal
        } else {
            Severity::Warning
        };
        return Some(Finding::new(
            "stuck",
            severity,
            name,
            seconds,
            format!(
                "{file}: {name} repeats {} for {seconds:.2} s ({best} rows from t = {:.3} s, {:.1} % of the rows)",
                v(start),
                t.t[start],
                100.0 * share
            ),
            "a frozen channel or a stalled recorder: check that stretch, cut it out or record again",
        ));
    }
    None
}

/// The range of a sensor from `[imu]`: (accelerometer m/s², gyroscope rad/s).
pub fn ranges(session: &Session) -> (Option<f64>, Option<f64>) {
    ranges_of(session.meta.imu.as_ref())
}

/// [`ranges`] of an `[imu]` table (of a joint or a pose session).
pub(crate) fn ranges_of(imu: Option<&toml::Table>) -> (Option<f64>, Option<f64>) {
    let Some(imu) = imu else {
        return (None, None);
    };
    let text = |k: &str| imu.get(k).and_then(|v| v.as_str()).map(str::to_string);
    let accel = text("accel_range")
        .and_then(|s| s.strip_prefix('G').and_then(|g| g.parse::<f64>().ok()))
        .map(|g| g * G_STANDARD);
    let gyro = text("gyro_range")
        .and_then(|s| s.strip_prefix("Dps").and_then(|d| d.parse::<f64>().ok()))
        .map(f64::to_radians);
    (accel, gyro)
}

/// Fatal above this share of saturated rows (the fit cannot use them), a
/// warning below.
const SATURATED_SHARE_FATAL: f64 = 0.01;

/// The severity of saturation in `share` of the rows, whether found at a
/// recorded range or by clipping runs ([`super::clipping`]).
pub(crate) fn saturation_severity(share: f64) -> Severity {
    if share > SATURATED_SHARE_FATAL {
        Severity::Fatal
    } else {
        Severity::Warning
    }
}

/// Samples at the device's range, per sensor.
fn saturation(session: &Session) -> Vec<Finding> {
    let (accel, gyro) = ranges(session);
    saturation_of(files::IMU, &session.imu, accel, gyro)
}

/// The rows of the IMU table `imu` (read from `file`) at the range `accel`
/// (m/s²) or `gyro` (rad/s), per sensor (a sensor without a range is not
/// checked).
pub(crate) fn saturation_of(
    file: &str,
    imu: &Table,
    accel: Option<f64>,
    gyro: Option<f64>,
) -> Vec<Finding> {
    let mut out = Vec::new();
    for (range, cols, sensor, unit) in [
        (accel, 0..3, "accelerometer", "m/s²"),
        (gyro, 3..6, "gyroscope", "rad/s"),
    ] {
        let Some(range) = range else { continue };
        let n = imu.len();
        let count = (0..n)
            .filter(|&i| {
                let row = imu.row(i);
                cols.clone().any(|c| row[c].abs() >= SATURATION * range)
            })
            .count();
        if count == 0 {
            continue;
        }
        let share = count as f64 / n as f64;
        let severity = saturation_severity(share);
        out.push(Finding::new(
            "saturation",
            severity,
            sensor,
            count as f64,
            format!(
                "{file}: {sensor}: {count} rows ({:.2} %) at its range ±{range:.3} {unit}",
                100.0 * share
            ),
            "choose a larger range, or a slower motion (robimu plan's limits)",
        ));
    }
    out
}
