//! Repeatability: calibrate each of k equal time windows of a session (the
//! paper used five 1-minute windows) and compare each with the calibration
//! of the whole session.
//!
//! A window holds the joint samples in its span and the IMU samples in the
//! same span of the session clock; τ is re-estimated per window, so IMU
//! samples whose u = t + τ falls just outside the span are dropped by the
//! estimator ([`robimu_solver::problem::Problem`]). For nested data sets the window's
//! estimate has the larger σ, so |window − full| / σ_window stays of order 1
//! when the reported uncertainty is right.

use super::calibrate::{calibrate, CalibrateError, CalibrateOptions, Calibration};
use robimu_model::observations::Measurements;
use robimu_model::units::DisplayUnit;
use robimu_model::{ParamLayout, Robot};
use robimu_solver::IterationRecord;

/// Shortest window that is calibrated, s.
pub(crate) const MIN_WINDOW: f64 = 10.0;

/// One window of a session.
#[derive(Debug, Clone)]
pub struct Window {
    /// Start of the span on the session clock, s.
    pub t0: f64,
    /// End of the span, s.
    pub t1: f64,
    /// The samples in the span.
    pub data: Measurements,
}

/// Split `data` into `k` equal spans of its joint time range. Each window
/// gets the joint and IMU samples with t in [t0, t1) (the last one also
/// those at t1). Empty when `k` is 0 or there are no joint samples.
pub(crate) fn split_windows(data: &Measurements, k: usize) -> Vec<Window> {
    let (Some(&a), Some(&b)) = (data.joint_t.first(), data.joint_t.last()) else {
        return Vec::new();
    };
    let n = data.joint_q.len() / data.joint_t.len();
    (0..k)
        .map(|w| {
            let t0 = a + (b - a) * w as f64 / k as f64;
            let t1 = if w + 1 == k {
                b
            } else {
                a + (b - a) * (w + 1) as f64 / k as f64
            };
            let last = w + 1 == k;
            let inside = |t: f64| t >= t0 && (t < t1 || (last && t <= t1));
            let mut m = Measurements::default();
            for (s, &t) in data.joint_t.iter().enumerate() {
                if inside(t) {
                    m.joint_t.push(t);
                    m.joint_q
                        .extend_from_slice(&data.joint_q[s * n..(s + 1) * n]);
                }
            }
            for (&t, z) in data.imu_t.iter().zip(&data.imu_z) {
                if inside(t) {
                    m.imu_t.push(t);
                    m.imu_z.push(*z);
                }
            }
            Window { t0, t1, data: m }
        })
        .collect()
}

/// Why a repeatability study failed.
#[derive(Debug, thiserror::Error)]
pub enum RepeatabilityError {
    /// Fewer than two windows asked for.
    #[error("the repeatability study needs at least 2 windows (got {0})")]
    TooFewWindows(usize),
    /// The session has no joint samples to split.
    #[error("the session has no joint samples to split into windows")]
    NoSamples,
    /// The windows are too short to calibrate.
    #[error("window {window} of {count} ({t0:.1}..{t1:.1} s) lasts {:.1} s; each window needs at least {MIN_WINDOW} s (use fewer windows or a longer session)", t1 - t0)]
    WindowTooShort {
        /// 1-based window number.
        window: usize,
        /// Number of windows.
        count: usize,
        /// Start, s.
        t0: f64,
        /// End, s.
        t1: f64,
    },
    /// The calibration of the whole session failed.
    #[error("the calibration of the whole session failed: {0}")]
    Full(#[source] CalibrateError),
    /// The calibration of one window failed.
    #[error("the calibration of window {window} of {count} ({t0:.1}..{t1:.1} s) failed: {source}")]
    Window {
        /// 1-based window number.
        window: usize,
        /// Number of windows.
        count: usize,
        /// Start, s.
        t0: f64,
        /// End, s.
        t1: f64,
        /// The cause.
        #[source]
        source: CalibrateError,
    },
}

/// One window's calibration compared with the full one.
#[derive(Debug, Clone)]
pub struct WindowResult {
    /// Start of the span, s.
    pub t0: f64,
    /// End of the span, s.
    pub t1: f64,
    /// The window's calibration.
    pub calibration: Calibration,
    /// window − full per parameter of x, SI (angles wrapped to ±π).
    pub difference: Vec<f64>,
}

/// One parameter's largest difference over the windows.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterSpread {
    /// Index into x.
    pub index: usize,
    /// Largest |window − full|, SI.
    pub max_difference: f64,
    /// The window it occurs in (0-based).
    pub window: usize,
    /// That difference over the full calibration's σ.
    pub relative_to_full: f64,
    /// That difference over that window's σ.
    pub relative_to_window: f64,
}

/// A parameter group's largest difference, in display units.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupSpread {
    /// Group name (`robot lengths`, `accelerometer`, …).
    pub group: &'static str,
    /// The display unit the group's members share (a group whose members
    /// have different units is reported once per unit).
    pub unit: DisplayUnit,
    /// The parameter with the largest difference (index into x).
    pub index: usize,
    /// Its name.
    pub name: String,
    /// Its largest |window − full|, display units.
    pub difference: f64,
    /// That difference over the window's σ.
    pub relative_to_window: f64,
}

/// The outcome of a repeatability study.
#[derive(Debug, Clone)]
pub struct Repeatability {
    /// The calibration of the whole session.
    pub full: Calibration,
    /// Each window, in time order.
    pub windows: Vec<WindowResult>,
    /// Per estimated parameter (frozen ones left out), in x order.
    pub parameters: Vec<ParameterSpread>,
    /// Per parameter group (and unit), in x order of the groups.
    pub groups: Vec<GroupSpread>,
}

/// The group of parameter `k` (robot lengths ε_i1..3 and angles ε_i4..6 for
/// i < n, IMU position ε_n1..3, gravity, τ, accelerometer, gyroscope).
pub(crate) fn group_of(layout: &ParamLayout, k: usize) -> &'static str {
    let o = layout.offsets();
    if let Some(e) = layout.estimated_errors().get(k) {
        return match (e.link == layout.n_links(), e.is_translation()) {
            (true, true) => "IMU position",
            (true, false) => "IMU orientation",
            (false, true) => "robot lengths",
            (false, false) => "robot angles",
        };
    }
    match k {
        _ if k < o.tau => "gravity",
        _ if k == o.tau => "time offset",
        _ if k < o.gamma_w => "accelerometer",
        _ => "gyroscope",
    }
}

/// Check that `k` windows of `data` are long enough, before any calibration.
pub(crate) fn check_windows(
    data: &Measurements,
    k: usize,
) -> Result<Vec<Window>, RepeatabilityError> {
    if k < 2 {
        return Err(RepeatabilityError::TooFewWindows(k));
    }
    let windows = split_windows(data, k);
    if windows.is_empty() {
        return Err(RepeatabilityError::NoSamples);
    }
    if let Some((w, win)) = windows
        .iter()
        .enumerate()
        .find(|(_, w)| w.t1 - w.t0 < MIN_WINDOW)
    {
        return Err(RepeatabilityError::WindowTooShort {
            window: w + 1,
            count: k,
            t0: win.t0,
            t1: win.t1,
        });
    }
    Ok(windows)
}

/// Calibrate the whole session and each of `k` windows, and compare.
pub fn repeatability(
    robot: &Robot,
    data: &Measurements,
    k: usize,
    opts: &CalibrateOptions,
) -> Result<Repeatability, RepeatabilityError> {
    let windows = check_windows(data, k)?;
    let full = calibrate(robot, data, opts, |_| {}).map_err(RepeatabilityError::Full)?;
    let results = calibrate_windows(robot, windows, opts, |_, _| {})?;
    Ok(compare(&ParamLayout::new(robot), full, results))
}

/// Calibrate each window; `report` sees (0-based window, solver iteration).
pub(crate) fn calibrate_windows(
    robot: &Robot,
    windows: Vec<Window>,
    opts: &CalibrateOptions,
    mut report: impl FnMut(usize, &IterationRecord),
) -> Result<Vec<WindowResult>, RepeatabilityError> {
    let count = windows.len();
    let mut results = Vec::with_capacity(count);
    for (w, win) in windows.into_iter().enumerate() {
        let cal = calibrate(robot, &win.data, opts, |r| report(w, r)).map_err(|source| {
            RepeatabilityError::Window {
                window: w + 1,
                count,
                t0: win.t0,
                t1: win.t1,
                source,
            }
        })?;
        results.push(WindowResult {
            t0: win.t0,
            t1: win.t1,
            calibration: cal,
            difference: Vec::new(),
        });
    }
    Ok(results)
}

/// The differences of the windows from the full calibration (fills each
/// window's `difference`).
pub fn compare(
    layout: &ParamLayout,
    full: Calibration,
    mut windows: Vec<WindowResult>,
) -> Repeatability {
    let specs = layout.specs();
    for w in &mut windows {
        w.difference = (0..layout.len())
            .map(|i| {
                let d = w.calibration.x[i] - full.x[i];
                if DisplayUnit::for_si(specs[i].unit).is_angle() {
                    wrap(d)
                } else {
                    d
                }
            })
            .collect();
    }
    let mut parameters = Vec::new();
    for &i in &full.active {
        let (window, d) = windows
            .iter()
            .enumerate()
            .map(|(w, r)| (w, r.difference[i].abs()))
            .fold((0, -1.0), |best, c| if c.1 > best.1 { c } else { best });
        parameters.push(ParameterSpread {
            index: i,
            max_difference: d,
            window,
            relative_to_full: d / full.sigma[i],
            relative_to_window: d / windows[window].calibration.sigma[i],
        });
    }
    let mut groups: Vec<GroupSpread> = Vec::new();
    for p in &parameters {
        let spec = &specs[p.index];
        let (group, unit) = (group_of(layout, p.index), DisplayUnit::for_si(spec.unit));
        let shown = unit.show(p.max_difference);
        let candidate = GroupSpread {
            group,
            unit: unit.clone(),
            index: p.index,
            name: spec.name.clone(),
            difference: shown,
            relative_to_window: p.relative_to_window,
        };
        match groups
            .iter_mut()
            .find(|g| g.group == group && g.unit == unit)
        {
            Some(g) if shown > g.difference => *g = candidate,
            Some(_) => {}
            None => groups.push(candidate),
        }
    }
    Repeatability {
        full,
        windows,
        parameters,
        groups,
    }
}

/// An angle difference in (−π, π].
fn wrap(d: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let r = d - TAU * (d / TAU).round();
    if r <= -PI {
        r + TAU
    } else {
        r
    }
}

/// repeatability.csv: per window and parameter (x order), SI units.
pub fn write_csv(
    path: &std::path::Path,
    layout: &ParamLayout,
    study: &Repeatability,
) -> Result<(), csv::Error> {
    let mut w = csv::Writer::from_path(path)?;
    w.write_record([
        "window",
        "t0",
        "t1",
        "name",
        "unit",
        "value",
        "sigma",
        "difference",
    ])?;
    for (k, win) in study.windows.iter().enumerate() {
        for (i, spec) in layout.specs().iter().enumerate() {
            w.write_record([
                (k + 1).to_string(),
                win.t0.to_string(),
                win.t1.to_string(),
                spec.name.clone(),
                spec.unit.to_string(),
                win.calibration.x[i].to_string(),
                win.calibration.sigma[i].to_string(),
                win.difference[i].to_string(),
            ])?;
        }
    }
    w.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{random_session, SimulateOptions};

    #[test]
    fn windows_partition_the_samples() {
        let robot = Robot::aubo_i5();
        let s = random_session(&robot, 30.0, 1.0, &SimulateOptions::paper(&robot), 2).unwrap();
        let d = &s.data;
        let w = split_windows(d, 3);
        assert_eq!(w.len(), 3);
        let joints: usize = w.iter().map(|w| w.data.joint_t.len()).sum();
        let imu: usize = w.iter().map(|w| w.data.imu_t.len()).sum();
        assert_eq!(joints, d.joint_t.len());
        assert_eq!(imu, d.imu_t.len());
        assert_eq!(w[0].t0, d.joint_t[0]);
        assert_eq!(w[2].t1, *d.joint_t.last().unwrap());
        for (a, b) in w.iter().zip(&w[1..]) {
            assert_eq!(a.t1, b.t0);
            assert!(a.data.joint_t.last().unwrap() < &b.data.joint_t[0]);
        }
        for win in &w {
            assert!((win.t1 - win.t0 - 10.0).abs() < 0.1);
            assert_eq!(win.data.joint_q.len(), 6 * win.data.joint_t.len());
            assert!(win.data.joint_t.iter().all(|&t| t >= win.t0 && t <= win.t1));
            // joint rows are copied with their time stamp
            let s0 = d
                .joint_t
                .iter()
                .position(|&t| t == win.data.joint_t[0])
                .unwrap();
            assert_eq!(win.data.joint_q[..6], d.joint_q[s0 * 6..s0 * 6 + 6]);
        }
        assert!((wrap(2.0 * std::f64::consts::PI - 0.1) + 0.1).abs() < 1e-12);
        assert_eq!(wrap(-0.2), -0.2);
    }

    #[test]
    fn too_short_windows_are_named_before_any_calibration() {
        let robot = Robot::aubo_i5();
        let s = random_session(&robot, 30.0, 1.0, &SimulateOptions::paper(&robot), 3).unwrap();
        let opts = CalibrateOptions::new(&robot);
        let e = repeatability(&robot, &s.data, 4, &opts).unwrap_err();
        assert!(matches!(
            e,
            RepeatabilityError::WindowTooShort {
                window: 1,
                count: 4,
                ..
            }
        ));
        let text = e.to_string();
        assert!(
            text.contains("window 1 of 4") && text.contains("at least 10 s"),
            "{text}"
        );
        let e = repeatability(&robot, &s.data, 1, &opts).unwrap_err();
        assert!(e.to_string().contains("at least 2 windows"), "{e}");
    }

    /// The paper's study on a simulated 300 s session: five 1-minute windows.
    #[test]
    fn five_windows_agree_with_the_full_calibration_within_their_sigma() {
        let robot = Robot::aubo_i5();
        let s = random_session(&robot, 300.0, 1.0, &SimulateOptions::paper(&robot), 21).unwrap();
        let opts = CalibrateOptions::new(&robot);
        let r = repeatability(&robot, &s.data, 5, &opts).unwrap();
        let layout = ParamLayout::new(&robot);
        assert_eq!(r.windows.len(), 5);
        assert_eq!(r.parameters.len(), layout.len());
        for (w, win) in r.windows.iter().enumerate() {
            assert!(
                win.calibration.summary.termination.converged(),
                "window {w}"
            );
            assert!((win.t1 - win.t0 - 60.0).abs() < 0.1);
            for c in win.calibration.residual_rms {
                assert!((c - 1.0).abs() < 0.1, "window {w}: residual rms {c}");
            }
        }
        for g in &r.groups {
            eprintln!(
                "{:>16} {:>8} {:>12}: {:.4} ({:.2} sigma_window)",
                g.group,
                g.unit.symbol(),
                g.name,
                g.difference,
                g.relative_to_window
            );
        }
        for p in &r.parameters {
            let name = &layout.specs()[p.index].name;
            // independent recomputation from the two calibrations
            let w = &r.windows[p.window].calibration;
            let d = (w.x[p.index] - r.full.x[p.index]).abs();
            assert!((d - p.max_difference).abs() < 1e-12, "{name}");
            for win in &r.windows {
                assert!((win.calibration.x[p.index] - r.full.x[p.index]).abs() <= d + 1e-15);
                // the window's σ is the larger (it has a fifth of the data)
                assert!(
                    win.calibration.sigma[p.index] > r.full.sigma[p.index],
                    "{name}"
                );
            }
            assert!(
                p.relative_to_window < 5.0,
                "{name}: |window - full| = {:.2} sigma_window",
                p.relative_to_window
            );
            // the windows truly disagree somewhere (not copies of the full fit)
            assert!(p.max_difference > 0.0, "{name}");
        }
        let names: Vec<&str> = r.groups.iter().map(|g| g.group).collect();
        for want in [
            "robot lengths",
            "robot angles",
            "IMU position",
            "gravity",
            "time offset",
            "accelerometer",
            "gyroscope",
        ] {
            assert!(names.contains(&want), "{names:?}");
        }
        // each group reports its member with the largest difference
        for g in &r.groups {
            let best = r
                .parameters
                .iter()
                .filter(|p| {
                    group_of(&layout, p.index) == g.group
                        && DisplayUnit::for_si(layout.specs()[p.index].unit) == g.unit
                })
                .map(|p| g.unit.show(p.max_difference))
                .fold(0.0, f64::max);
            assert_eq!(best, g.difference, "{}", g.group);
        }
    }
}
