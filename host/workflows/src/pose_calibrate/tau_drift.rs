//! Is τ constant over the recording? A Rao score test at the MAP estimate
//! (docs/model.md §7.9, *time offset*).
//!
//! The alternative: the IMU samples of segment k (the used samples cut
//! into [`SEGMENTS`] runs of equal count) read at t_i + τ + δ_k, δ_0 = 0.
//! Their residuals' Jacobian is ∂r_i/∂δ_k = ∂r_i/∂τ on segment k, so the
//! score and information blocks are those of τ restricted to the segment:
//! linearising the problem with only segment k's IMU samples (and no pose
//! samples, which do not depend on τ) gives its score g_k (the gradient's
//! τ entry) and c_k (the τ column of its Gauss–Newton matrix), each less
//! τ's prior: three quarters of one linearisation's IMU work. The efficient
//! information V = diag(d_k) − Cᵀ A⁻¹ C projects out every parameter of the
//! fit (spline, p_I, g, τ and the 24 sensor parameters) with the fit's own
//! Gauss–Newton matrix A; at the MAP estimate the full gradient is zero, so
//! S = gᵀ V⁻¹ g ~ χ²_{K−1} when τ is constant. A lag that wanders (a drifting
//! clock, arrival stamps) makes it large even where the other parameters
//! absorb most of the drift, which refitting τ alone per half misses.

use robimu_model::pose_measurement::{imu_indices, n_pose_params, TAU};
use robimu_model::PoseSpline;
use robimu_solver::{
    ArrowFactor, LeastSquares, PoseData, PoseImuData, PoseProblem, PoseProblemError,
};

use crate::stats::chi2_sf;
use faer::linalg::solvers::DenseSolveCore;

/// Number of segments K.
pub(crate) const SEGMENTS: usize = 4;

/// The test's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct TauDrift {
    /// S (χ²_{K−1} under a constant τ).
    pub statistic: f64,
    /// Degrees of freedom, K − 1.
    pub dof: usize,
    /// P(χ²_{K−1} > S).
    pub p_value: f64,
    /// One-step estimates of δ_1 … δ_{K−1} (s): τ in segment k less τ in
    /// the first, V⁻¹ g.
    pub delta: Vec<f64>,
    /// Their standard deviations (s), √diag(V⁻¹).
    pub delta_sigma: Vec<f64>,
}

/// The score test of IMU `imu`'s τ (its `selected` samples) at the
/// solution θ of the problem of the full data `data` (its spline `base`)
/// and `more` (IMU j ≥ 1), with `factor` the undamped Gauss–Newton matrix
/// at θ. `None` when there are too few IMU samples to cut or V is singular.
pub(crate) fn tau_drift(
    (base, data): (&PoseSpline, &PoseData),
    more: &[PoseImuData],
    imu: usize,
    selected: &[usize],
    theta: &[f64],
    factor: &ArrowFactor,
) -> Result<Option<TauDrift>, PoseProblemError> {
    let m = SEGMENTS - 1;
    if selected.len() < 10 * SEGMENTS {
        return Ok(None);
    }
    let n = theta.len();
    let tau = imu_indices(imu)[TAU];
    // τ's index in θ (after the band)
    let i_tau = n - n_pose_params(1 + more.len()) + tau;
    let (w_tau, e_tau) = (
        data.prior_sigma[tau].powi(-2),
        theta[i_tau] - data.prior_mean[tau],
    );
    // segment k's τ column of the information and gradient entry; the
    // segments are independent, each on its own thread
    let segment = |k: usize| -> Result<(f64, Vec<f64>), PoseProblemError> {
        let range = selected.len() * k / SEGMENTS..selected.len() * (k + 1) / SEGMENTS;
        let (seg, seg_more) = segment_data(data, more, imu, &selected[range]);
        let mut p = PoseProblem::with_imus(base.clone(), seg, seg_more)?;
        p.begin_iteration(theta)?;
        let mut a = p.new_matrix();
        let mut gk = vec![0.0; n];
        p.linearize(theta, &mut a, &mut gk)?;
        let mut c: Vec<f64> = (0..n).map(|i| a.get(i, i_tau)).collect();
        c[i_tau] -= w_tau;
        Ok((gk[i_tau] - w_tau * e_tau, c))
    };
    let parts: Vec<Result<(f64, Vec<f64>), PoseProblemError>> = std::thread::scope(|s| {
        let handles: Vec<_> = (2..SEGMENTS).map(|k| s.spawn(move || segment(k))).collect();
        let first = segment(1);
        std::iter::once(first)
            .chain(
                handles
                    .into_iter()
                    .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e))),
            )
            .collect()
    });
    let mut g = Vec::with_capacity(m);
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(m);
    for part in parts {
        let (gk, c) = part?;
        g.push(gk);
        cols.push(c);
    }
    let d: Vec<f64> = cols.iter().map(|c| c[i_tau]).collect();
    // V = diag(d) − Cᵀ A⁻¹ C
    let solved: Vec<Vec<f64>> = cols
        .iter()
        .map(|c| {
            let mut s = c.clone();
            factor.solve_in_place(&mut s);
            s
        })
        .collect();
    let v = faer::Mat::from_fn(m, m, |a, b| {
        let cross: f64 = cols[a].iter().zip(&solved[b]).map(|(x, y)| x * y).sum();
        if a == b {
            d[a] - cross
        } else {
            -cross
        }
    });
    let Ok(llt) = v.llt(faer::Side::Lower) else {
        return Ok(None);
    };
    let v_inv = llt.inverse();
    let delta: Vec<f64> = (0..m)
        .map(|a| -(0..m).map(|b| v_inv[(a, b)] * g[b]).sum::<f64>())
        .collect();
    let statistic: f64 = (0..m)
        .map(|a| g[a] * (0..m).map(|b| v_inv[(a, b)] * g[b]).sum::<f64>())
        .sum();
    Ok(Some(TauDrift {
        statistic,
        dof: m,
        p_value: chi2_sf(statistic, m as f64),
        delta,
        delta_sigma: (0..m).map(|a| v_inv[(a, a)].max(0.0).sqrt()).collect(),
    }))
}

/// The problem data of one segment: IMU `imu`'s samples `picked` alone
/// (no pose samples: they do not touch τ's column or gradient entry; nor
/// the other IMUs' samples), the full prior.
fn segment_data(
    data: &PoseData,
    more: &[PoseImuData],
    imu: usize,
    picked: &[usize],
) -> (PoseData, Vec<PoseImuData>) {
    let mut seg = PoseData {
        pose_t: Vec::new(),
        pose_p: Vec::new(),
        pose_r: Vec::new(),
        imu_t: Vec::new(),
        imu_z: Vec::new(),
        prior_mean: data.prior_mean.clone(),
        prior_sigma: data.prior_sigma.clone(),
        ..*data
    };
    let mut seg_more: Vec<PoseImuData> = more
        .iter()
        .map(|m| PoseImuData {
            imu_t: Vec::new(),
            imu_z: Vec::new(),
            ..*m
        })
        .collect();
    let (src_t, src_z) = match imu {
        0 => (&data.imu_t, &data.imu_z),
        j => (&more[j - 1].imu_t, &more[j - 1].imu_z),
    };
    let (t, z) = match imu {
        0 => (&mut seg.imu_t, &mut seg.imu_z),
        j => {
            let m = &mut seg_more[j - 1];
            (&mut m.imu_t, &mut m.imu_z)
        }
    };
    t.extend(picked.iter().map(|&i| src_t[i]));
    z.extend(picked.iter().map(|&i| src_z[i]));
    (seg, seg_more)
}

/// Below this p-value the verdict doubts a constant τ.
pub(crate) const P_DOUBT: f64 = 0.01;

/// The verdict's *time offset* check: τ constant over the recording
/// (p ≥ [`P_DOUBT`]); when doubted, τ per segment relative to the first.
pub(crate) fn verdict_check(drift: Option<&TauDrift>) -> robimu_session::result::VerdictCheck {
    let (ok, text) = match drift {
        None => (
            true,
            "not tested (too few IMU samples to cut the recording)".to_string(),
        ),
        Some(d) => {
            let per = d
                .delta
                .iter()
                .zip(&d.delta_sigma)
                .map(|(v, s)| format!("{:+.1} ± {:.1} ms", v * 1e3, s * 1e3))
                .collect::<Vec<_>>()
                .join(", ");
            let ok = d.p_value >= P_DOUBT;
            let head = if ok {
                "τ constant over the recording"
            } else {
                "τ changes over the recording (a lag that wanders or a drifting clock: the \
                 estimates and σ do not hold)"
            };
            (
                ok,
                format!(
                    "{head}: score test over {} segments χ²_{} = {:.1}, p = {:.2e}; τ of \
                     segments 2–{} less the first's: {per}",
                    d.dof + 1,
                    d.dof,
                    d.statistic,
                    d.p_value,
                    d.dof + 1
                ),
            )
        }
    };
    robimu_session::result::VerdictCheck {
        topic: "time offset".into(),
        ok,
        text,
    }
}

#[cfg(test)]
#[path = "tau_drift_tests.rs"]
mod tests;
