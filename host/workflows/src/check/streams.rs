//! Sample rates, gaps and clocks of `joints.csv` and `imu.csv`
//! (docs/model.md §7.1): per stream the median rate, the gaps longer than
//! [`GAP_FACTOR`] median periods (count and largest), repeated timestamps,
//! time stamps off their neighbours' midpoint (irregular, [`STAMP_OFF`]),
//! timestamps in ms (or µs, ns: the rate 10³ᵏ× off the nominal), and the
//! overlap of the two streams.

use super::{median_of, Finding, Severity};
use robimu_session::{files, Session, Table};

/// A gap is an interval longer than this many median periods.
pub(crate) const GAP_FACTOR: f64 = 3.0;
/// A gap at least this long (s) is a dropout or a clock jump.
pub(crate) const JUMP: f64 = 1.0;
/// A row's time stamp is off when it lies more than this part of the median
/// period from the midpoint of its neighbours' (the two periods around it
/// summing to two periods within half of one: no row lost or added).
pub(crate) const STAMP_OFF: f64 = 0.125;
/// Plausible sample rates of a recording, Hz.
pub(crate) const RATES: (f64, f64) = (5.0, 10_000.0);
/// The IMU samples may lie outside the joint span by this much (s): the time
/// offset τ between the clocks (as `calibrate`'s input check allows).
pub(crate) const CLOCK_SLACK: f64 = 10.0;

/// The stream findings of `session`.
pub fn check(session: &Session) -> Vec<Finding> {
    let nominal = nominal_rate(session.meta.imu.as_ref());
    let mut out = Vec::new();
    out.extend(stream(files::JOINTS, &session.joints, None));
    out.extend(stream(files::IMU, &session.imu, nominal));
    out.extend(overlap(
        (files::JOINTS, &session.joints),
        (files::IMU, &session.imu),
    ));
    out
}

/// `[imu] sample_rate_hz` of session.toml (the `[imu]` table), when recorded.
pub(crate) fn nominal_rate(imu: Option<&toml::Table>) -> Option<f64> {
    let v = imu?.get("sample_rate_hz")?;
    v.as_float()
        .or_else(|| v.as_integer().map(|i| i as f64))
        .filter(|r| *r > 0.0)
}

/// Rate, gaps, repeated times and the time unit of one stream.
pub(crate) fn stream(name: &str, table: &Table, nominal: Option<f64>) -> Vec<Finding> {
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
    out.extend(stamps_off(name, t, period));
    dt.clear();
    out
}

/// The rows whose time stamp lies more than [`STAMP_OFF`] periods from the
/// midpoint of its neighbours' (information). Harmless when the stamps are
/// the instants the values were sampled at, however irregular; when they are
/// a poll's round trip (the AUBO driver stamps a joint reply at the
/// midpoint of its request and reply) a stalled host puts errors into them,
/// the trajectory spline follows them and the knot choice takes finer knots
/// (docs/guide/recording.md: the real-time demo's sessions, where dropping these
/// rows restored the 125 ms knots).
fn stamps_off(name: &str, t: &[f64], period: f64) -> Option<Finding> {
    let (mut off, mut count, mut worst) = (0usize, 0usize, (0.0f64, 0usize));
    for i in 1..t.len().saturating_sub(1) {
        let (a, b) = (t[i] - t[i - 1], t[i + 1] - t[i]);
        if a <= 0.0 || b <= 0.0 || (a + b - 2.0 * period).abs() > 0.5 * period {
            continue;
        }
        count += 1;
        let r = 0.5 * (a - b);
        if r.abs() > STAMP_OFF * period {
            off += 1;
            if r.abs() > worst.0 {
                worst = (r.abs(), i);
            }
        }
    }
    if off == 0 {
        return None;
    }
    let fraction = off as f64 / count as f64;
    Some(Finding::new(
        "stamps_off",
        Severity::Info,
        name,
        fraction,
        format!(
            "{name}: {off} of {count} rows ({:.1} %) are stamped more than {:.2} ms ({STAMP_OFF} of the period) off the midpoint of their neighbours' stamps (worst {:.2} ms at t = {:.3} s): sampled or stamped irregularly",
            100.0 * fraction,
            STAMP_OFF * period * 1e3,
            worst.0 * 1e3,
            t[worst.1]
        ),
        "none if these are the true sample instants; if they are a poll's round trip, their errors make the trajectory's knots finer: record on a host that is not busy, or from a controller that stamps its own samples",
    ))
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

/// The overlap of the spans of the motion's stream (`joints.csv`,
/// `poses.csv`) and the IMU's, each given with its file name.
pub(crate) fn overlap(motion: (&str, &Table), imu: (&str, &Table)) -> Option<Finding> {
    let (a, b) = motion.1.span()?;
    let (c, d) = imu.1.span()?;
    let common = (b.min(d) - a.max(c)).max(0.0);
    let shorter = (b - a).min(d - c).max(f64::MIN_POSITIVE);
    let share = common / shorter;
    let spans = format!("{} {a:.3}..{b:.3} s, {} {c:.3}..{d:.3} s", motion.0, imu.0);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// 125 Hz stamps as a recorder writes them (1e-9 s rounding).
    fn regular(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| (i as f64 * 0.008 * 1e9).round() / 1e9)
            .collect()
    }

    #[test]
    fn regular_stamps_and_lost_rows_are_not_off() {
        let t = regular(2000);
        assert!(stamps_off("joints.csv", &t, 0.008).is_none());
        // rows lost (one, then three in a row): gaps, not late stamps
        let lost: Vec<f64> = t
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != 500 && !(900..903).contains(&i))
            .map(|(_, &v)| v)
            .collect();
        assert!(stamps_off("joints.csv", &lost, 0.008).is_none());
        // jitter within 1/10 of the period (the midpoint moves by less)
        let small: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, &v)| v + 0.0008 * ((i * 7919 % 13) as f64 / 12.0 - 0.5))
            .collect();
        assert!(stamps_off("joints.csv", &small, 0.008).is_none());
    }

    /// Every 50th row stamped 3 ms late: it and its two neighbours lie off
    /// the midpoints (by 3 and 1.5 ms), 3 of every 50 rows, and the worst
    /// is named; one late row in 2 000 is counted with its neighbours.
    #[test]
    fn late_stamps_are_counted_and_the_worst_named() {
        let mut t = regular(2000);
        for i in (25..2000).step_by(50) {
            t[i] += 0.003;
        }
        let f = stamps_off("joints.csv", &t, 0.008).expect("late stamps found");
        assert_eq!(f.kind, "stamps_off");
        assert_eq!(f.severity, Severity::Info);
        assert!((f.value - 3.0 / 50.0).abs() < 2e-3, "{}", f.value);
        // the worst is a late row (t = 0.203 + 0.4 k s), off by 3 ms
        let at: f64 = f
            .message
            .split("worst 3.00 ms at t = ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{}", f.message));
        assert!(
            ((at - 0.203) / 0.4 - ((at - 0.203) / 0.4).round()).abs() < 1e-6,
            "{at}"
        );
        let mut one = regular(2000);
        one[1000] += 0.003;
        let f = stamps_off("joints.csv", &one, 0.008).expect("one late stamp");
        assert!((f.value - 3.0 / 1998.0).abs() < 1e-9, "{}", f.value);
    }
}
