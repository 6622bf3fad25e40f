//! Start-up of a pose calibration without a mount prior (MODEL.md §10, §6:
//! find τ and the sensor rotations from the data before linearising).
//!
//! * τ: the normalised cross-correlation of the measured angular speed |ω̃|
//!   with the pose spline's |ω_B(t + τ)| (the magnitude does not depend on
//!   the unknown rotation), on a 5 ms grid, refined by a parabola.
//! * Gyroscope: the affine regression ω̃_i = A ω_B(t_i + τ) + b (Wahba's
//!   problem with the §3 model's scale, misalignment and bias included),
//!   then A = K Γ R split by an LQ decomposition (Γ unit lower triangular,
//!   K > 0, R a rotation): R is the least-squares rotation when K Γ = I.
//! * Accelerometer: the same with s_i = R_iᵀ(p̈_i − g) + (\[α_i\]× + \[ω_i\]×²) p_I
//!   (g at g_xy = 0), alternated a few times with the linear solve for the
//!   IMU position p_I given A and b.
//! * The rotations become §3's Z–Y–X Euler angles (r_z, r_y, r_x).

use robimu_model::geom::{cross, dot, mul_mtv, sub, M3, V3};
use robimu_model::pose_measurement::G0;
use robimu_model::{ImuIntrinsics, PoseSpline};

use super::PoseCalibrationError;

/// Grid step of the τ search (s).
const TAU_STEP: f64 = 0.005;
/// Alternations of the accelerometer regression and the p_I solve.
const ACCEL_ROUNDS: usize = 4;

/// What the start-up found.
#[derive(Clone, Debug, PartialEq)]
pub struct Startup {
    /// τ (s).
    pub tau: f64,
    /// Peak normalised correlation of the angular speeds.
    pub correlation: f64,
    /// Accelerometer intrinsics from the regression.
    pub accel: ImuIntrinsics,
    /// Gyroscope intrinsics from the regression.
    pub gyro: ImuIntrinsics,
    /// IMU position p_I on B (m).
    pub p_imu: V3,
}

/// a > b, false when either is NaN.
pub(super) fn greater(a: f64, b: f64) -> bool {
    matches!(a.partial_cmp(&b), Some(std::cmp::Ordering::Greater))
}

fn norm(v: V3) -> f64 {
    dot(v, v).sqrt()
}

fn err(msg: impl Into<String>) -> PoseCalibrationError {
    PoseCalibrationError::Startup(msg.into())
}

/// τ by cross-correlating |ω̃| with |ω_B(t + τ)| over |τ| ≤ `tau_max`.
pub(crate) fn find_tau(
    spline: &PoseSpline,
    imu_t: &[f64],
    imu_z: &[[f64; 6]],
    tau_max: f64,
) -> Result<(f64, f64), PoseCalibrationError> {
    let (t0, t1) = (spline.knots().start(), spline.knots().end());
    let np = ((t1 - t0) / TAU_STEP) as usize + 1;
    let pose: Vec<f64> = (0..np)
        .map(|k| {
            spline
                .evaluate(t0 + k as f64 * TAU_STEP)
                .map(|s| norm(s.omega))
        })
        .collect::<Result<_, _>>()
        .map_err(|e| err(e.to_string()))?;
    let (s0, s1) = (imu_t[0], imu_t[imu_t.len() - 1]);
    let nq = ((s1 - s0) / TAU_STEP) as usize + 1;
    let mut imu = Vec::with_capacity(nq);
    let mut i = 0;
    for m in 0..nq {
        let t = s0 + m as f64 * TAU_STEP;
        while i + 2 < imu_t.len() && imu_t[i + 1] < t {
            i += 1;
        }
        let (ta, tb) = (imu_t[i], imu_t[i + 1]);
        let u = if tb > ta {
            ((t - ta) / (tb - ta)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (
            norm([imu_z[i][3], imu_z[i][4], imu_z[i][5]]),
            norm([imu_z[i + 1][3], imu_z[i + 1][4], imu_z[i + 1][5]]),
        );
        imu.push(a + u * (b - a));
    }
    // τ = (t0 − s0) + L·step: imu[m] pairs with pose[m + L].
    let base = t0 - s0;
    let l_lo = ((-tau_max - base) / TAU_STEP).ceil() as i64;
    let l_hi = ((tau_max - base) / TAU_STEP).floor() as i64;
    let min_overlap = (np.min(nq) / 4).max(20);
    let (pa, paa) = (prefix(&imu, |v| v), prefix(&imu, |v| v * v));
    let (pb, pbb) = (prefix(&pose, |v| v), prefix(&pose, |v| v * v));
    let corr = |l: i64| -> Option<f64> {
        let m_lo = (-l).max(0) as usize;
        let m_hi = (nq as i64).min(np as i64 - l);
        if m_hi <= m_lo as i64 || ((m_hi as usize) - m_lo) < min_overlap {
            return None;
        }
        let (m_hi, k_lo) = (m_hi as usize, (m_lo as i64 + l) as usize);
        let k_hi = k_lo + (m_hi - m_lo);
        let n = (m_hi - m_lo) as f64;
        let (sa, saa) = (pa[m_hi] - pa[m_lo], paa[m_hi] - paa[m_lo]);
        let (sb, sbb) = (pb[k_hi] - pb[k_lo], pbb[k_hi] - pbb[k_lo]);
        let sab = dot_lanes(&imu[m_lo..m_hi], &pose[k_lo..k_hi]);
        let (va, vb) = (saa - sa * sa / n, sbb - sb * sb / n);
        (va > 0.0 && vb > 0.0).then(|| (sab - sa * sb / n) / (va * vb).sqrt())
    };
    let scores: Vec<(i64, f64)> = (l_lo..=l_hi)
        .filter_map(|l| corr(l).map(|c| (l, c)))
        .collect();
    let &(lb, cb) = scores
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .ok_or_else(|| err("the IMU and pose streams do not overlap within the τ search range"))?;
    let (cm, cp) = (corr(lb - 1), corr(lb + 1));
    let frac = match (cm, cp) {
        (Some(m), Some(p)) if m - 2.0 * cb + p < 0.0 => 0.5 * (m - p) / (m - 2.0 * cb + p),
        _ => 0.0,
    };
    Ok((base + (lb as f64 + frac) * TAU_STEP, cb))
}

/// Prefix sums of f(v): `out[k]` = Σ_{i<k} f(v_i) (the correlation's
/// window sums in O(1) per lag).
fn prefix(v: &[f64], f: impl Fn(f64) -> f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(v.len() + 1);
    let mut acc = 0.0;
    out.push(acc);
    for &x in v {
        acc += f(x);
        out.push(acc);
    }
    out
}

/// Σ a_i b_i in 8 interleaved partial sums (vectorised).
fn dot_lanes(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// Least squares y_i ≈ A u_i + b: (A, b).
fn affine_fit(u: &[V3], y: &[V3]) -> Result<(M3, V3), PoseCalibrationError> {
    let mut n = [[0.0; 4]; 4];
    let mut rhs = [[0.0; 4]; 3];
    for (ui, yi) in u.iter().zip(y) {
        let v = [ui[0], ui[1], ui[2], 1.0];
        for p in 0..4 {
            for q in 0..4 {
                n[p][q] += v[p] * v[q];
            }
            for r in 0..3 {
                rhs[r][p] += yi[r] * v[p];
            }
        }
    }
    let mut a = [[0.0; 3]; 3];
    let mut b = [0.0; 3];
    for r in 0..3 {
        let sol = solve4(n, rhs[r])
            .ok_or_else(|| err("too little motion to align the IMU with the poses"))?;
        a[r] = [sol[0], sol[1], sol[2]];
        b[r] = sol[3];
    }
    Ok((a, b))
}

/// Gaussian elimination with partial pivoting of a small system.
fn solve_n<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    for c in 0..N {
        let p = (c..N).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if !greater(a[p][c].abs(), 1e-12 * scale) {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..N {
            let f = a[r][c] / a[c][c];
            for k in c..N {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0; N];
    for r in (0..N).rev() {
        let s: f64 = (r + 1..N).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

fn solve4(a: [[f64; 4]; 4], b: [f64; 4]) -> Option<[f64; 4]> {
    solve_n(a, b)
}

/// A = K Γ R (LQ decomposition by Gram–Schmidt on A's rows): the §3
/// intrinsics with zero bias, or None if A is singular or a reflection.
pub(crate) fn split_sensor_matrix(a: &M3) -> Option<ImuIntrinsics> {
    let mut q = [[0.0; 3]; 3];
    let mut l = [[0.0; 3]; 3];
    for i in 0..3 {
        let mut v = a[i];
        for j in 0..i {
            l[i][j] = dot(a[i], q[j]);
            v = sub(v, q[j].map(|x| x * l[i][j]));
        }
        l[i][i] = norm(v);
        if !greater(l[i][i], 1e-12) {
            return None;
        }
        q[i] = v.map(|x| x / l[i][i]);
    }
    if dot(cross(q[0], q[1]), q[2]) < 0.0 {
        return None;
    }
    let k = [l[0][0], l[1][1], l[2][2]];
    Some(ImuIntrinsics {
        gamma: [l[1][0] / k[1], -l[2][0] / k[2], l[2][1] / k[2]],
        r: euler_zyx(&q),
        k,
        b: [0.0; 3],
    })
}

/// The Z–Y–X Euler angles (r_z, r_y, r_x) of R = Rz·Ry·Rx (§3).
pub(crate) fn euler_zyx(r: &M3) -> [f64; 3] {
    let ry = (-r[2][0]).clamp(-1.0, 1.0).asin();
    [r[1][0].atan2(r[0][0]), ry, r[2][1].atan2(r[2][2])]
}

/// The start-up (module doc) for IMU samples at `imu_t`, τ within ±`tau_max`.
pub(crate) fn startup(
    spline: &PoseSpline,
    imu_t: &[f64],
    imu_z: &[[f64; 6]],
    tau_max: f64,
) -> Result<Startup, PoseCalibrationError> {
    let (tau, correlation) = super::memo::find_tau(spline, imu_t, imu_z, tau_max, || {
        find_tau(spline, imu_t, imu_z, tau_max)
    })?;
    let used: Vec<usize> = (0..imu_t.len())
        .filter(|&i| spline.knots().contains(imu_t[i] + tau))
        .collect();
    let states = used
        .iter()
        .map(|&i| spline.evaluate(imu_t[i] + tau))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| err(e.to_string()))?;
    let meas = |off: usize| -> Vec<V3> {
        used.iter()
            .map(|&i| [imu_z[i][off], imu_z[i][off + 1], imu_z[i][off + 2]])
            .collect()
    };
    let (w_meas, s_meas) = (meas(3), meas(0));
    let omega: Vec<V3> = states.iter().map(|s| s.omega).collect();
    let (aw, bw) = affine_fit(&omega, &w_meas)?;
    let mut gyro =
        split_sensor_matrix(&aw).ok_or_else(|| err("the gyroscope alignment is singular"))?;
    gyro.b = bw;
    let g = [0.0, 0.0, -G0];
    let base: Vec<V3> = states.iter().map(|s| mul_mtv(&s.r, sub(s.a, g))).collect();
    // s_i = base_i + M_i p_I with M_i p = α × p + ω × (ω × p)
    let lever = |i: usize, p: V3| -> V3 {
        let (w, al) = (states[i].omega, states[i].alpha);
        robimu_model::geom::add(cross(al, p), cross(w, cross(w, p)))
    };
    let mut p_imu = [0.0; 3];
    let (mut aa, mut ba) = ([[0.0; 3]; 3], [0.0; 3]);
    for _ in 0..ACCEL_ROUNDS {
        let s: Vec<V3> = (0..states.len())
            .map(|i| robimu_model::geom::add(base[i], lever(i, p_imu)))
            .collect();
        (aa, ba) = affine_fit(&s, &s_meas)?;
        p_imu = solve_lever(&aa, &ba, &s_meas, &base, &lever)?;
    }
    let mut accel =
        split_sensor_matrix(&aa).ok_or_else(|| err("the accelerometer alignment is singular"))?;
    accel.b = ba;
    Ok(Startup {
        tau,
        correlation,
        accel,
        gyro,
        p_imu,
    })
}

/// RMS (rad/s) of the gyroscope's affine alignment (the start-up's
/// regression ω̃ ≈ A u + b) at `tau` with two rates of the poses: their
/// body rates ω (u = ω, the §10 convention R = R_WB) and their world-frame
/// rates ω_n. If the quaternions hold the inverse rotation, the body's
/// true rate is −ω_n: a constant A maps it onto the gyroscope's axes, and
/// ω only when the body turns about a fixed axis (the check of the
/// convention, `check::poses`).
pub(crate) fn gyro_alignment_rms(
    spline: &PoseSpline,
    imu_t: &[f64],
    imu_z: &[[f64; 6]],
    tau: f64,
) -> Result<(f64, f64), PoseCalibrationError> {
    let (mut body, mut world, mut meas) = (Vec::new(), Vec::new(), Vec::new());
    for (t, z) in imu_t.iter().zip(imu_z) {
        if spline.knots().contains(t + tau) {
            let s = spline.evaluate(t + tau).map_err(|e| err(e.to_string()))?;
            body.push(s.omega);
            world.push(s.omega_n);
            meas.push([z[3], z[4], z[5]]);
        }
    }
    let rms = |u: &[V3]| -> Result<f64, PoseCalibrationError> {
        let (a, b) = affine_fit(u, &meas)?;
        let ss: f64 = u
            .iter()
            .zip(&meas)
            .map(|(ui, yi)| {
                let e = sub(
                    robimu_model::geom::add(robimu_model::geom::mul_mv(&a, *ui), b),
                    *yi,
                );
                dot(e, e)
            })
            .sum();
        Ok((ss / (3 * meas.len().max(1)) as f64).sqrt())
    };
    Ok((rms(&body)?, rms(&world)?))
}

/// p_I minimising Σ |A (base_i + M_i p) + b − s̃_i|².
fn solve_lever(
    a: &M3,
    b: &V3,
    s_meas: &[V3],
    base: &[V3],
    lever: &dyn Fn(usize, V3) -> V3,
) -> Result<V3, PoseCalibrationError> {
    let mut n = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    let am = |v: V3| robimu_model::geom::mul_mv(a, v);
    for i in 0..base.len() {
        let cols: [V3; 3] = std::array::from_fn(|c| {
            let mut e = [0.0; 3];
            e[c] = 1.0;
            am(lever(i, e))
        });
        let y = sub(sub(s_meas[i], *b), am(base[i]));
        for p in 0..3 {
            for q in 0..3 {
                n[p][q] += dot(cols[p], cols[q]);
            }
            rhs[p] += dot(cols[p], y);
        }
    }
    solve_n(n, rhs).ok_or_else(|| err("too little rotation to locate the IMU on the posed body"))
}
