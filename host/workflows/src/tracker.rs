//! Tracker data and registration (paper §9): static poses measured by an
//! external tracker, the flange pose the model predicts for them, and the
//! two constant transforms (tracker←base, flange←marker) that relate the two.
//! Shared by the validation ([`crate::validate`]), the classical baselines
//! ([`crate::baseline`]), the tracker clock offset ([`crate::tracker_offset`])
//! and the simulator.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use robimu_model::geom::{
    self, add, matrix_from_quat, mul_mm, mul_mv, nearest_rotation, quat_from_matrix, sub, Iso, V3,
};
use robimu_model::geom::{exp_so3, log_so3};
use robimu_model::kinematics::forward_kinematics;
use robimu_model::{ParamLayout, Robot};
use robimu_session::Table;
use robimu_solver::{dense, LmOptions};

/// Why a validation could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValidateError {
    /// The inputs do not fit together or are too few.
    #[error("{0}")]
    Input(String),
}

fn input(m: impl Into<String>) -> ValidateError {
    ValidateError::Input(m.into())
}

/// σ of the tracker's position (m) and rotation (rad) used to weight pose
/// residuals: 0.1 mm and 0.05°.
pub(crate) const TRACKER_SIGMA: (f64, f64) = (1e-4, 0.05 * std::f64::consts::PI / 180.0);

fn too_little_rotation() -> ValidateError {
    input("the poses do not determine the tracker and marker rotations (too little rotation between poses)")
}

// ---------------------------------------------------------------- poses

/// A static pose measured by the tracker, with the joint angles there.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedPose {
    /// Session time, s.
    pub t: f64,
    /// Marker body pose in the tracker frame.
    pub marker: Iso,
    /// Joint angles, rad.
    pub q: Vec<f64>,
}

/// The pose of one tracker row `[px, py, pz, qw, qx, qy, qz]`.
pub(crate) fn pose_from_row(row: &[f64]) -> Result<Iso, ValidateError> {
    let q = [row[3], row[4], row[5], row[6]];
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n > 0.5 && n < 1.5) {
        return Err(input(format!(
            "quaternion ({}, {}, {}, {}) is not a unit quaternion (norm {n})",
            q[0], q[1], q[2], q[3]
        )));
    }
    Ok(Iso {
        r: matrix_from_quat(q),
        p: [row[0], row[1], row[2]],
    })
}

/// `[px, py, pz, qw, qx, qy, qz]` of a pose.
pub fn row_from_pose(t: &Iso) -> [f64; 7] {
    let q = quat_from_matrix(&t.r);
    [t.p[0], t.p[1], t.p[2], q[0], q[1], q[2], q[3]]
}

/// Static poses from a tracker table (docs/model.md §7 columns). The joint angles
/// come from its extra columns `q1..qn` when the file has them (`extra`:
/// those values, row-major), otherwise from `joints` linearly interpolated
/// at each pose's time.
pub(crate) fn tracked_poses(
    tracker: &Table,
    extra: Option<&[f64]>,
    joints: Option<&Table>,
    n: usize,
) -> Result<Vec<TrackedPose>, ValidateError> {
    if tracker.width() != 7 {
        return Err(input(format!(
            "a tracker table has 7 value columns (px, py, pz, qw, qx, qy, qz), not {}",
            tracker.width()
        )));
    }
    if extra.is_some_and(|v| v.len() != tracker.len() * n) {
        return Err(input(format!(
            "expected {n} joint angles for each of the {} poses",
            tracker.len()
        )));
    }
    let mut out = Vec::with_capacity(tracker.len());
    for i in 0..tracker.len() {
        let t = tracker.t[i];
        let marker = pose_from_row(tracker.row(i))
            .map_err(|e| input(format!("pose {} (t = {t} s): {e}", i + 1)))?;
        let q = match (extra, joints) {
            (Some(v), _) => v[i * n..(i + 1) * n].to_vec(),
            (None, Some(j)) => interpolate(j, t).ok_or_else(|| {
                input(format!(
                    "pose {} (t = {t} s) is outside the joint samples' time span",
                    i + 1
                ))
            })?,
            (None, None) => return Err(input(
                "the poses have no q1..qn columns and there are no joint samples to take them from",
            )),
        };
        out.push(TrackedPose { t, marker, q });
    }
    Ok(out)
}

fn interpolate(j: &Table, t: f64) -> Option<Vec<f64>> {
    let (a, b) = j.span()?;
    if t < a || t > b {
        return None;
    }
    let k =
        j.t.partition_point(|&x| x <= t)
            .clamp(1, j.len().max(2) - 1);
    if j.len() == 1 {
        return Some(j.row(0).to_vec());
    }
    let (t0, t1) = (j.t[k - 1], j.t[k]);
    let w = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
    Some(
        j.row(k - 1)
            .iter()
            .zip(j.row(k))
            .map(|(x, y)| x + w * (y - x))
            .collect(),
    )
}

/// The generalized errors of `x` with the last link's (the IMU mount) zeroed:
/// the flange, to which the marker body is attached.
pub(crate) fn flange_eps(layout: &ParamLayout, x: &[f64]) -> Result<Vec<[f64; 6]>, ValidateError> {
    let mut eps = layout.unpack(x).map_err(|e| input(e.to_string()))?.eps;
    if let Some(last) = eps.last_mut() {
        *last = [0.0; 6];
    }
    Ok(eps)
}

/// Flange pose F(q; ε) in the base frame (eq. (3)), over the robot's whole
/// chain: each joint's DH part and its fixed transform C_i (the catalogue's
/// arms are described by their makers' joint origins, with no DH part).
pub(crate) fn flange_pose(robot: &Robot, eps: &[[f64; 6]], q: &[f64]) -> Iso {
    forward_kinematics(robot.chain(), eps, q)
}

/// The constant transforms between tracker, base, flange and marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// T_tb: the robot base frame in the tracker frame.
    pub tracker_base: Iso,
    /// T_fm: the marker body in the flange frame.
    pub flange_marker: Iso,
}

impl Registration {
    /// Predicted marker pose T_tb · F · T_fm.
    pub fn predict(&self, flange: &Iso) -> Iso {
        self.tracker_base
            .compose(flange)
            .compose(&self.flange_marker)
    }

    /// The registration moved by `d` = [w_tb, δp_tb, w_fm, δp_fm]:
    /// R_tb ← exp(w_tb) R_tb, R_fm ← R_fm exp(w_fm).
    pub(crate) fn perturbed(&self, d: &[f64]) -> Self {
        let (x, y) = (&self.tracker_base, &self.flange_marker);
        Self {
            tracker_base: Iso {
                r: mul_mm(&exp_so3([d[0], d[1], d[2]]), &x.r),
                p: add(x.p, [d[3], d[4], d[5]]),
            },
            flange_marker: Iso {
                r: mul_mm(&y.r, &exp_so3([d[6], d[7], d[8]])),
                p: add(y.p, [d[9], d[10], d[11]]),
            },
        }
    }

    /// The pose of the IMU (at `p_imu` in the flange frame, flange
    /// orientation) in the base frame, from a marker pose.
    pub fn imu_in_base(&self, marker: &Iso, p_imu: V3) -> Iso {
        self.tracker_base
            .inverse()
            .compose(marker)
            .compose(&self.flange_marker.inverse())
            .compose(&Iso::translation(p_imu))
    }
}

/// Weighted pose residual `[(p_meas − p_pred)/σ_p; log(R_measᵀ R_pred)/σ_R]`.
pub(crate) fn pose_residual(meas: &Iso, pred: &Iso, sp: f64, sr: f64) -> [f64; 6] {
    let dp = sub(meas.p, pred.p);
    let dr = log_so3(&geom::mul_mm(&geom::transpose(&meas.r), &pred.r));
    [
        dp[0] / sp,
        dp[1] / sp,
        dp[2] / sp,
        dr[0] / sr,
        dr[1] / sr,
        dr[2] / sr,
    ]
}

/// Solve T_tb and T_fm from flange poses F_k and marker poses M_k
/// (M_k ≈ T_tb F_k T_fm): closed-form start (rotation axes of relative
/// motions, then linear translations), refined by nonlinear least squares
/// ([`robimu_solver::dense`]).
pub fn register(flanges: &[Iso], markers: &[Iso]) -> Result<Registration, ValidateError> {
    let n = flanges.len();
    if n != markers.len() || n < 3 {
        return Err(input(format!(
            "the tracker and marker transforms need at least 3 poses (got {})",
            n.min(markers.len())
        )));
    }
    // log(M_iᵀ M_j) = R_fmᵀ log(F_iᵀ F_j): R_fm = argmax Σ a_Fᵀ R a_M.
    let mut h = [[0.0; 3]; 3];
    let rel = |v: &[Iso], i: usize, j: usize| log_so3(&mul_mm(&geom::transpose(&v[i].r), &v[j].r));
    for i in 0..n {
        for j in [(i + 1) % n, (i + n / 2) % n] {
            if i == j {
                continue;
            }
            let (af, am) = (rel(flanges, i, j), rel(markers, i, j));
            for a in 0..3 {
                for b in 0..3 {
                    h[a][b] += af[a] * am[b];
                }
            }
        }
    }
    let r_fm = nearest_rotation(&h).ok_or_else(too_little_rotation)?;
    let mut hx = [[0.0; 3]; 3];
    for (f, m) in flanges.iter().zip(markers) {
        let fr = mul_mm(&f.r, &r_fm);
        let p = mul_mm(&m.r, &geom::transpose(&fr));
        for a in 0..3 {
            for b in 0..3 {
                hx[a][b] += p[a][b];
            }
        }
    }
    let r_tb = nearest_rotation(&hx).ok_or_else(too_little_rotation)?;
    // M.p − R_tb F.p = R_tb F.R p_fm + p_tb: linear in (p_fm, p_tb), solved
    // by the normal equations (Cholesky).
    let mut ata = Mat::<f64>::zeros(6, 6);
    let mut atb = Mat::<f64>::zeros(6, 1);
    for (f, m) in flanges.iter().zip(markers) {
        let a = mul_mm(&r_tb, &f.r);
        let b = sub(m.p, mul_mv(&r_tb, f.p));
        for row in 0..3 {
            let mut reg = [a[row][0], a[row][1], a[row][2], 0.0, 0.0, 0.0];
            reg[3 + row] = 1.0;
            for u in 0..6 {
                atb[(u, 0)] += reg[u] * b[row];
                for v in 0..6 {
                    ata[(u, v)] += reg[u] * reg[v];
                }
            }
        }
    }
    let sol = ata
        .llt(Side::Lower)
        .map_err(|_| input("the poses do not determine the tracker and marker positions"))?
        .solve(atb);
    let sol: Vec<f64> = (0..6).map(|i| sol[(i, 0)]).collect();
    let start = Registration {
        tracker_base: Iso {
            r: r_tb,
            p: [sol[3], sol[4], sol[5]],
        },
        flange_marker: Iso {
            r: r_fm,
            p: [sol[0], sol[1], sol[2]],
        },
    };
    let (sp, sr) = TRACKER_SIGMA;
    let f = |d: &[f64]| -> Vec<f64> {
        let reg = start.perturbed(d);
        flanges
            .iter()
            .zip(markers)
            .flat_map(|(fl, m)| pose_residual(m, &reg.predict(fl), sp, sr))
            .collect()
    };
    let opts = LmOptions {
        max_iterations: 50,
        ..LmOptions::default()
    };
    let sol = dense::solve(f, vec![0.0; 12], &opts).map_err(|e| {
        input(format!(
            "the poses do not determine the tracker and marker transforms: {e}"
        ))
    })?;
    Ok(start.perturbed(&sol.theta))
}
