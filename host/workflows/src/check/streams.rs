//! Sample rates, gaps and clocks of `joints.csv` and `imu.csv`
//! (docs/model.md §7.1): per stream the median rate, the gaps longer than
//! [`GAP_FACTOR`] median periods (count and largest), repeated timestamps,
//! timestamps in ms (or µs, ns: the rate 10³ᵏ× off the nominal), and the
//! overlap of the two streams.

use super::{median_of, Finding, Severity};
use robimu_session::{files, Session, Table};

/// A gap is an interval longer than this many median periods.
pub const GAP_FACTOR: f64 = 3.0;
/// A gap at least this long (s) is a dropout or a clock jump.
pub const JUMP: f64 = 1.0;
/// Plausible sample rates of a recording, Hz.
pub const RATES: (f64, f64) = (5.0, 10_000.0);
/// The IMU samples may lie outside the joint span by this much (s): the time
/// offset τ between the clocks (as `calibrate`'s input check allows).
pub const CLOCK_SLACK: f64 = 10.0;

/// The stream findings of `session`.
pub fn check(session: &Session) -> Vec<Finding> {
    let nominal = nominal_rate(session);
    let mut out = Vec::new();
    out.extend(stream(files::JOINTS, &session.joints, None));
    out.extend(stream(files::IMU, &session.imu, nominal));
    out.extend(overlap(&session.joints, &session.imu));
    out
}

/// `[imu] sample_rate_hz` of session.toml, when recorded.
pub fn nominal_rate(session: &Session) -> Option<f64> {
    let v = session.meta.imu.as_ref()?.get("sample_rate_hz")?;
    v.as_float()
        .or_else(|| v.as_integer().map(|i| i as f64))
        .filter(|r| *r > 0.0)
}

/// Rate, gaps, repeated times and the time unit of one stream.
fn stream(name: &str, table: &Table, nominal: Option<f64>) -> Vec<Finding> {
    let mut out = Vec::new();
    let t = &table.t;
    let (Some(&t0), Some(&t1)) = (t.first(), t.last()) else {
        return out;
    };
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let repeated = dt.iter().filter(|d| **d <= 0.0).count();
    let mut positive: Vec<f64> = dt.iter().copied().filter(|d| *d > 0.0).collect();
    let period = median_of(&mut positive);
    if period.is_nan() || period <= 0.0 {
        out.push(Finding::new(
            "rate",
            Severity::Fatal,
            name,
            t.len() as f64,
            format!(
                "{name}: {} rows, all at t = {t0} s: no sample rate",
                t.len()
            ),
            "record more than one instant",
        ));
        return out;
    }
    let rate = 1.0 / period;
    let duration = t1 - t0;
    out.push(Finding::new(
        "rate",
        Severity::Info,
        name,
        rate,
        format!(
            "{name}: {} rows over {duration:.1} s, {rate:.3} Hz (median period {:.3} ms)",
            t.len(),
            period * 1e3
        ),
        "",
    ));
    if let Some(f) = time_unit(name, rate, duration, nominal) {
        out.push(f);
        return out;
    }
    if let Some(nom) = nominal {
        if (rate / nom - 1.0).abs() > 0.05 {
            out.push(Finding::new(
                "rate",
                Severity::Warning,
                name,
                rate,
                format!("{name}: {rate:.3} Hz, but session.toml [imu] sample_rate_hz = {nom}"),
                "check the device's configuration and the recorder's read rate (samples dropped or repeated?)",
            ));
        }
    }
    if repeated > 0 {
        out.push(Finding::new(
            "repeated_time",
            Severity::Warning,
            name,
            repeated as f64,
            format!(
                "{name}: {repeated} rows repeat the time of the row before ({:.2} % of the rows)",
                100.0 * repeated as f64 / t.len() as f64
            ),
            "check the recorder's time stamps (a coarse clock, or rows written twice)",
        ));
    }
    let gaps: Vec<usize> = (0..dt.len())
        .filter(|&i| dt[i] > GAP_FACTOR * period)
        .collect();
    if let Some(&worst) = gaps.iter().max_by(|&&a, &&b| dt[a].total_cmp(&dt[b])) {
        let largest = dt[worst];
        let severity = if largest >= JUMP || gaps.len() * 100 > t.len() {
            Severity::Warning
        } else {
            Severity::Info
        };
        let what = if largest >= JUMP {
            "a dropout or clock jump"
        } else {
            "samples lost"
        };
        out.push(Finding::new(
            "gap",
            severity,
            name,
            largest,
            format!(
                "{name}: largest gap {largest:.3} s at t = {:.3} s ({what}); {} gap(s) > {GAP_FACTOR}× the median period",
                t[worst],
                gaps.len()
            ),
            if largest >= JUMP {
                "check the recording around that time; calibrate the parts on either side separately if the clock jumped"
            } else {
                "none needed for a few lost samples; many: lower the sample rate or check the link"
            },
        ));
    }
    dt.clear();
    out
}

/// Timestamps in ms, µs or ns: the rate 10³ᵏ× below the nominal (or
/// below [`RATES`] with 10³ᵏ× inside).
fn time_unit(name: &str, rate: f64, duration: f64, nominal: Option<f64>) -> Option<Finding> {
    let plausible = |r: f64| match nominal {
        Some(nom) => (r / nom - 1.0).abs() < 0.2,
        None => (RATES.0..=RATES.1).contains(&r),
    };
    if plausible(rate) {
        return None;
    }
    for (factor, unit) in [(1e3, "ms"), (1e6, "µs"), (1e9, "ns")] {
        if plausible(rate * factor) {
            return Some(Finding::new(
                "time_unit",
                Severity::Fatal,
                name,
                rate,
                format!(
                    "{name}: timestamps in {unit}? (rate {rate:.6} Hz, {factor:.0e}× that would be {:.1} Hz; duration {duration:.0} s)",
                    rate * factor
                ),
                format!("divide the t column by {factor:.0e} (docs/model.md §7: seconds)"),
            ));
        }
    }
    if rate < RATES.0 {
        return Some(Finding::new(
            "rate",
            Severity::Warning,
            name,
            rate,
            format!(
                "{name}: {rate:.3} Hz is too slow for a calibration (duration {duration:.1} s)"
            ),
            "check the t column's unit (seconds) and the recorder's rate",
        ));
    }
    None
}

/// The overlap of the joint and IMU spans.
fn overlap(joints: &Table, imu: &Table) -> Option<Finding> {
    let (a, b) = joints.span()?;
    let (c, d) = imu.span()?;
    let common = (b.min(d) - a.max(c)).max(0.0);
    let shorter = (b - a).min(d - c).max(f64::MIN_POSITIVE);
    let share = common / shorter;
    let spans = format!("joints.csv {a:.3}..{b:.3} s, imu.csv {c:.3}..{d:.3} s");
    if d < a - CLOCK_SLACK || c > b + CLOCK_SLACK {
        return Some(Finding::new(
            "overlap",
            Severity::Fatal,
            "streams",
            share,
            format!("the streams do not overlap ({spans}): two clocks?"),
            "put both files on the same session clock (the recorder's, or subtract each stream's start)",
        ));
    }
    let severity = if share < 0.9 {
        Severity::Warning
    } else {
        Severity::Info
    };
    Some(Finding::new(
        "overlap",
        severity,
        "streams",
        share,
        format!(
            "the streams overlap over {:.1} % of the shorter one ({spans})",
            100.0 * share
        ),
        if share < 0.9 {
            "only the common span calibrates; check both streams' clocks"
        } else {
            ""
        },
    ))
}
