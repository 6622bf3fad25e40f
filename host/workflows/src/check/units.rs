//! The units of the IMU columns (docs/model.md §7.4: m/s², rad/s).
//!
//! * **Accelerometer**: at rest |s̃| = |K Γ R s + b| ≈ k·g₀; the median
//!   |s̃| over the static stretches (all samples when there are none: the
//!   arm's accelerations are small against g₀) must lie within
//!   g₀·(1 ± 3σ_k) of the gains' prior. ≈ 1 is g, ≈ 1000 mg.
//! * **Gyroscope**: the RMS of |ω̃ − b̂| during the recording against the
//!   RMS of |ω| the nominal kinematics predict from the joint samples
//!   (q, q̇ by central differences; §1.5, |R ω| = |ω|): a ratio near
//!   180/π = 57.3 is deg/s. RMS over the whole span needs no time
//!   alignment (τ is unknown before the fit). b̂ is the median gyro vector
//!   at rest, when the recording has static stretches; |ω̃| at rest beyond
//!   the bias prior (3σ_b per axis) is a warning.
//! * **Swapped columns**: |gyro columns| ≈ g₀ at rest (or over all
//!   samples) with |accel columns| ≪ g₀.

use robimu_model::{ParamLayout, Robot};
use robimu_session::{files, Session, Table};

use super::{median_of, Finding, Severity};
use crate::calibrate::joint_outside_limits;

/// A joint row is static when every |q̇| is below this, rad/s.
pub(crate) const STATIC_SPEED: f64 = 0.01;
/// A static stretch lasts at least this long, s.
pub(crate) const STATIC_MIN: f64 = 2.0;
/// IMU samples this close to either end of a static stretch are left out
/// (the clocks differ by τ), s.
pub(crate) const STATIC_MARGIN: f64 = 0.5;
/// RMS |ω| (rad/s) the joints must predict for the gyroscope's scale to
/// be checked (finite differences of joint noise alone give a few 0.01).
pub(crate) const MOVING: f64 = 0.05;
/// Plausible ratios of the gyroscope's RMS to the prediction.
pub(crate) const GYRO_RATIO: (f64, f64) = (0.6, 1.6);

/// q̇ at every joint row by central differences (one-sided at the ends,
/// 0 across repeated times).
pub(crate) fn joint_speeds(session: &Session) -> Vec<f64> {
    let n = session.joint_count();
    let mut qd = vec![0.0; session.joints.len() * n];
    for (i, row) in qd.chunks_exact_mut(n.max(1)).enumerate() {
        speeds_at(&session.joints, i, row);
    }
    qd
}

/// q̇ at joint row `i` of `joints` into `out` (one per column), as
/// [`joint_speeds`].
pub(super) fn speeds_at(joints: &Table, i: usize, out: &mut [f64]) {
    let (t, rows) = (&joints.t, joints.len());
    out.fill(0.0);
    if rows < 2 {
        return;
    }
    let (a, b) = (i.saturating_sub(1), (i + 1).min(rows - 1));
    let dt = t[b] - t[a];
    if dt > 0.0 {
        let (qa, qb) = (joints.row(a), joints.row(b));
        for j in 0..out.len() {
            out[j] = (qb[j] - qa[j]) / dt;
        }
    }
}

/// The static stretches of the joints, `(t0, t1)` of at least
/// [`STATIC_MIN`] s with every |q̇| < [`STATIC_SPEED`].
pub(crate) fn static_stretches(session: &Session, qd: &[f64]) -> Vec<(f64, f64)> {
    let n = session.joint_count();
    let t = &session.joints.t;
    let mut out = Vec::new();
    let mut start: Option<usize> = None;
    for i in 0..=t.len() {
        let still = i < t.len()
            && qd[i * n..(i + 1) * n]
                .iter()
                .all(|v| v.abs() < STATIC_SPEED);
        match (still, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                if t[i - 1] - t[s] >= STATIC_MIN {
                    out.push((t[s], t[i - 1]));
                }
                start = None;
            }
            _ => {}
        }
    }
    out
}

/// The unit findings; `motionless`: the recording does not move (the
/// gyroscope's scale then cannot be checked); `predicted`: the RMS |ω̃|
/// the nominal kinematics predict over the joint rows
/// ([`super::predicted_rate`]), asked for only when the scale is checked.
pub fn check(
    session: &Session,
    robot: &Robot,
    motionless: bool,
    predicted: impl FnOnce() -> Option<f64>,
) -> Vec<Finding> {
    let mut out = Vec::new();
    if let Some(f) = joint_units(session, robot) {
        out.push(f);
        return out;
    }
    let layout = ParamLayout::new(robot);
    let sigma = |name: &str| {
        layout
            .index_of(name)
            .map_or(0.1, |k| layout.specs()[k].sigma)
    };
    let levels = Levels::of(session);
    let g0 = robot.gravity();
    if let Some(f) = swapped_columns(&levels, g0) {
        out.push(f);
        return out;
    }
    out.push(accel_units(
        session,
        &levels,
        g0,
        3.0 * sigma("k_a_x"),
        3.0 * sigma("b_a_x") * 3f64.sqrt(),
    ));
    // the gyroscope at rest: its bias only
    let b_w = 3.0 * sigma("b_w_x") * 3f64.sqrt();
    let mut bias = [0.0; 3];
    if levels.at_rest.len() >= 10 {
        bias = levels.gyro_bias(session);
        if levels.gyro > b_w {
            out.push(Finding::new(
                "gyro_at_rest",
                Severity::Warning,
                "gyroscope",
                levels.gyro,
                format!(
                    "|ω| at rest = {:.4}, beyond the bias prior ({b_w:.4} rad/s, 3σ per axis)",
                    levels.gyro
                ),
                "check the gyroscope's unit (rad/s) and that the arm was still",
            ));
        }
    }
    if motionless {
        return out;
    }
    if let Some(f) = gyro_scale(session, predicted, bias) {
        out.push(f);
    }
    out
}

/// Joints in degrees (a joint outside its limits), fatal: the gyroscope's
/// comparison with the joint speeds would then blame the gyroscope.
fn joint_units(session: &Session, robot: &Robot) -> Option<Finding> {
    if session.joint_count() != robot.dof() {
        return None;
    }
    let v = joint_outside_limits(robot, &session.joints.values)?;
    Some(Finding::new(
        "joint_units",
        Severity::Fatal,
        files::JOINTS,
        v.q,
        v.to_string(),
        "give joints.csv's q1..qn in rad: multiply degrees by π/180 = 0.017453",
    ))
}

/// The IMU's levels: the median |accelerometer| and |gyroscope| at rest
/// (over all samples without static stretches).
struct Levels {
    /// The IMU rows inside the static stretches (margins left out).
    at_rest: Vec<usize>,
    /// Where the medians come from, for the messages.
    where_: &'static str,
    /// Median |ax, ay, az| and |gx, gy, gz|.
    accel: f64,
    gyro: f64,
}

impl Levels {
    fn of(session: &Session) -> Self {
        let qd = joint_speeds(session);
        let stretches = static_stretches(session, &qd);
        let imu = &session.imu;
        let at_rest: Vec<usize> = (0..imu.len())
            .filter(|&i| {
                let t = imu.t[i];
                stretches
                    .iter()
                    .any(|&(a, b)| t >= a + STATIC_MARGIN && t <= b - STATIC_MARGIN)
            })
            .collect();
        let (rows, where_) = if at_rest.len() >= 10 {
            (at_rest.clone(), "at rest")
        } else {
            (
                (0..imu.len()).collect(),
                "over all samples (no static stretch)",
            )
        };
        let norm = |i: usize, c: usize| {
            let r = imu.row(i);
            (r[c] * r[c] + r[c + 1] * r[c + 1] + r[c + 2] * r[c + 2]).sqrt()
        };
        let accel = median_of(&mut rows.iter().map(|&i| norm(i, 0)).collect::<Vec<_>>());
        let gyro = median_of(&mut rows.iter().map(|&i| norm(i, 3)).collect::<Vec<_>>());
        Self {
            at_rest,
            where_,
            accel,
            gyro,
        }
    }

    /// The median gyroscope vector at rest.
    fn gyro_bias(&self, session: &Session) -> [f64; 3] {
        let mut bias = [0.0; 3];
        for (c, b) in bias.iter_mut().enumerate() {
            *b = median_of(
                &mut self
                    .at_rest
                    .iter()
                    .map(|&i| session.imu.row(i)[3 + c])
                    .collect::<Vec<_>>(),
            );
        }
        bias
    }
}

/// Swapped columns, fatal: the gyroscope's carry gravity (and the
/// accelerometer's do not).
fn swapped_columns(levels: &Levels, g0: f64) -> Option<Finding> {
    let (gyro, accel, where_) = (levels.gyro, levels.accel, levels.where_);
    if !((0.5 * g0..=2.5 * g0).contains(&gyro) && accel < 0.3 * g0) {
        return None;
    }
    Some(Finding::new(
        "swapped_columns",
        Severity::Fatal,
        files::IMU,
        gyro,
        format!(
            "accelerometer and gyroscope columns swapped? (|gx,gy,gz| {where_} = {gyro:.2} ≈ g0 = {g0:.2}, |ax,ay,az| = {accel:.3})"
        ),
        "imu.csv's columns are t,ax,ay,az,gx,gy,gz: put the accelerometer first",
    ))
}

/// The accelerometer's scale: the radius of a sphere fitted to the
/// samples (or the median |a|, the range widened by the bias prior `b_a`)
/// against g₀ within the gains' prior (±`k_a`); fatal outside, with a hint
/// for g and mg.
fn accel_units(session: &Session, levels: &Levels, g0: f64, k_a: f64, b_a: f64) -> Finding {
    let (lo, hi) = (g0 * (1.0 - k_a), g0 * (1.0 + k_a));
    let sphere = sphere_radius(&session.imu);
    let (radius, what, lo, hi) = match sphere {
        Some(r) => (
            r,
            "|a - b| (a sphere fitted to the samples, the bias b its centre)".to_string(),
            lo,
            hi,
        ),
        None => (
            levels.accel,
            format!(
                "|a| {} (too few orientations for a sphere fit: range widened by the bias prior)",
                levels.where_
            ),
            (lo - b_a).max(0.0),
            hi + b_a,
        ),
    };
    if (lo..=hi).contains(&radius) {
        return Finding::new(
            "accel_units",
            Severity::Info,
            "accelerometer",
            radius,
            format!(
                "{what} = {radius:.3} m/s² (expected {g0:.2} within the gains' prior, {lo:.2}..{hi:.2})"
            ),
            "",
        );
    }
    let hint = if (0.7..=1.3).contains(&radius) {
        format!(" — in g: multiply ax, ay, az by {g0}")
    } else if (700.0..=1300.0).contains(&radius) {
        format!(" — in mg: multiply ax, ay, az by {}", g0 / 1000.0)
    } else {
        String::new()
    };
    Finding::new(
        "accel_units",
        Severity::Fatal,
        "accelerometer",
        radius,
        format!(
            "accelerometer not in m/s²? ({what} = {radius:.2}, expected {g0:.2}, {lo:.2}..{hi:.2}){hint}"
        ),
        "give imu.csv's ax, ay, az in m/s² (docs/model.md §7.4)",
    )
}

/// The gyroscope's RMS |ω̃ − b| against the RMS |ω̃| the nominal
/// kinematics predict (`predicted`).
fn gyro_scale(
    session: &Session,
    predicted: impl FnOnce() -> Option<f64>,
    bias: [f64; 3],
) -> Option<Finding> {
    let predicted = predicted()?;
    let joints = &session.joints;
    let (a, b) = joints.span()?;
    let imu = &session.imu;
    let (mut measured, mut count) = (0.0, 0usize);
    for i in 0..imu.len() {
        if imu.t[i] < a || imu.t[i] > b {
            continue;
        }
        let r = imu.row(i);
        measured += (0..3).map(|c| (r[3 + c] - bias[c]).powi(2)).sum::<f64>();
        count += 1;
    }
    if count == 0 || predicted.is_nan() || predicted <= MOVING {
        return None;
    }
    let measured = (measured / count as f64).sqrt();
    let ratio = measured / predicted;
    let deg = 180.0 / std::f64::consts::PI;
    let numbers = format!(
        "RMS |ω| = {measured:.4} against {predicted:.4} rad/s predicted from the joint speeds: ratio {ratio:.2}"
    );
    let (severity, message, action) = if (GYRO_RATIO.0 * deg..=GYRO_RATIO.1 * deg).contains(&ratio)
    {
        (
            Severity::Fatal,
            format!("gyroscope in deg/s? ({numbers}, 180/π = 57.3)"),
            "give imu.csv's gx, gy, gz in rad/s: multiply by π/180 = 0.017453",
        )
    } else if (GYRO_RATIO.0..=GYRO_RATIO.1).contains(&ratio) {
        (Severity::Info, format!("gyroscope scale: {numbers}"), "")
    } else {
        (
            Severity::Fatal,
            format!("gyroscope scale off ({numbers}, expected 1 within the gains' prior)"),
            "check the gyroscope's unit (rad/s), that imu.csv and joints.csv are the same recording, and the robot model",
        )
    };
    Some(Finding::new(
        "gyro_units",
        severity,
        "gyroscope",
        ratio,
        message,
        action,
    ))
}

/// The radius of the sphere |a − c| = r through the accelerometer samples
/// (linear least squares in c and r² − |c|²: |a|² = 2 a·c + d), `None`
/// when the samples do not spread in every direction (the spread along the
/// narrowest axis below a tenth of the RMS |a|: a sensor at rest, or one
/// that turned about one axis only).
pub(crate) fn sphere_radius(imu: &robimu_session::Table) -> Option<f64> {
    let n = imu.len();
    if n < 10 {
        return None;
    }
    let mut ata = [[0.0f64; 4]; 4];
    let mut atb = [0.0; 4];
    let mut mean = [0.0; 3];
    let mut square = 0.0;
    for a in imu.values.chunks_exact(imu.width()) {
        let row = [2.0 * a[0], 2.0 * a[1], 2.0 * a[2], 1.0];
        let y = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        square += y / n as f64;
        for r in 0..4 {
            atb[r] += row[r] * y;
            // the upper triangle (the lower one sums the same products)
            for c in r..4 {
                ata[r][c] += row[r] * row[c];
            }
        }
        for c in 0..3 {
            mean[c] += a[c] / n as f64;
        }
    }
    for r in 1..4 {
        for c in 0..r {
            ata[r][c] = ata[c][r];
        }
    }
    let cov = faer::Mat::from_fn(3, 3, |r, c| {
        (ata[r][c] / 4.0 - n as f64 * mean[r] * mean[c]) / n as f64
    });
    let ata = faer::Mat::from_fn(4, 4, |r, c| ata[r][c]);
    let spread = cov
        .self_adjoint_eigenvalues(faer::Side::Lower)
        .ok()?
        .into_iter()
        .fold(f64::INFINITY, f64::min)
        .max(0.0)
        .sqrt();
    let llt = ata.llt(faer::Side::Lower).ok()?;
    let rhs = faer::Mat::from_fn(4, 1, |r, _| atb[r]);
    let x = faer::linalg::solvers::Solve::solve(&llt, &rhs);
    let c = [x[(0, 0)], x[(1, 0)], x[(2, 0)]];
    let r2 = x[(3, 0)] + c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    let r = r2.max(0.0).sqrt();
    (r > 0.0 && spread > 0.1 * square.sqrt()).then_some(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_session::Table;

    fn table(rows: &[[f64; 3]]) -> Table {
        Table {
            columns: robimu_model::IMU_CHANNELS
                .iter()
                .map(|c| c.to_string())
                .collect(),
            t: (0..rows.len()).map(|i| i as f64).collect(),
            values: rows
                .iter()
                .flat_map(|a| [a[0], a[1], a[2], 0.0, 0.0, 0.0])
                .collect(),
        }
    }

    /// Points on a sphere of radius 7 about (1, −2, 3): the radius back to
    /// rounding; points on one circle (a turn about one axis): no radius.
    #[test]
    fn sphere_radius_of_points_on_a_sphere() {
        let c = [1.0, -2.0, 3.0];
        let mut rows = Vec::new();
        for i in 0..40 {
            let (th, ph) = (0.37 * i as f64, 0.11 + 0.23 * i as f64);
            let u = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
            rows.push(std::array::from_fn(|k| c[k] + 7.0 * u[k]));
        }
        let r = sphere_radius(&table(&rows)).unwrap();
        assert!((r - 7.0).abs() < 1e-9, "{r}");
        let circle: Vec<[f64; 3]> = (0..40)
            .map(|i| {
                let a = 0.3 * i as f64;
                [c[0] + 7.0 * a.cos(), c[1] + 7.0 * a.sin(), c[2]]
            })
            .collect();
        assert_eq!(sphere_radius(&table(&circle)), None);
    }
}
