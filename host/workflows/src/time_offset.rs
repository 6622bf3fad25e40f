//! Finding the time offset τ from the data before linearising (docs/model.md §6).
//!
//! Truths drawn from the priors put τ seconds away from 0, far outside the
//! basin of the local solver. For each candidate lag L the measured gyroscope
//! vectors are regressed on the body rate predicted by the nominal model at
//! t + L, with a free 3×3 matrix and an offset (which absorbs unknown gains,
//! misalignment, sensor rotation and bias): the lag with the smallest mean
//! squared residual wins. This stays sharp when the gyro bias is as large as
//! the rate, where correlating the norms of the two rates goes flat.
//!
//! The predicted rate is evaluated once on a 10 ms grid and interpolated
//! linearly (`rate_grid`; the motion's bandwidth is a few Hz, so the
//! interpolation error is ~1e-3 of the rate). A coarse scan over the whole
//! range (`lag_fit` at each lag, the lags split over two threads) runs on
//! at most [`TauSearch::coarse_samples`] of the samples; its best local
//! minima and their neighbours are fitted again with all samples, and the
//! best of those is refined by a fine scan with all samples around it and a
//! parabola through the best three lags. The local solver then refines τ
//! further.

mod lag_fit;
mod rate_grid;

use crate::body_rate::BodyRate;
use lag_fit::{LagFit, Samples};
use rate_grid::RateGrid;
use robimu_model::lanes::quads;
use robimu_model::Spline;

/// Search settings.
#[derive(Debug, Clone, Copy)]
pub struct TauSearch {
    /// Lags from −range to +range are tried, s.
    pub range: f64,
    /// Coarse step, s.
    pub coarse_step: f64,
    /// Fine step, s.
    pub fine_step: f64,
    /// At most this many IMU samples are used.
    pub max_samples: usize,
    /// At most this many of them scan the coarse lags; the coarse scan's
    /// best local minima are then fitted again with all (the fine scan
    /// always uses all).
    pub coarse_samples: usize,
}

impl Default for TauSearch {
    fn default() -> Self {
        Self {
            range: 5.0,
            coarse_step: 0.02,
            fine_step: 0.001,
            max_samples: 4000,
            coarse_samples: 500,
        }
    }
}

/// Result of the search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TauEstimate {
    /// The lag with the best fit, s.
    pub tau: f64,
    /// Fraction of the gyro variance explained at that lag (1 = perfect).
    pub r_squared: f64,
    /// Samples used at that lag.
    pub samples: usize,
}

/// Why τ could not be found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TauError {
    /// Too few IMU samples overlap the joint data at every lag.
    #[error("too few IMU samples overlap the joint samples at any time offset within ±{range} s")]
    NoOverlap {
        /// The search range.
        range: f64,
    },
    /// The robot barely rotates, so the gyroscope cannot fix the time offset.
    #[error("the gyroscope signal does not follow the robot's rotation at any time offset (best R² = {r_squared:.2}); does the robot move, and is imu.csv from the same run?")]
    NoMatch {
        /// Best fraction of variance explained.
        r_squared: f64,
    },
}

/// Fit every lag of `lags` (in order, `None` where a lag has too few
/// samples), the two halves on two threads.
fn scan(lags: &[f64], samples: &Samples, grid: &RateGrid) -> Vec<Option<LagFit>> {
    // four lags at a time (LagFit::at_x4; a short last quad repeats a lag)
    let run = |part: &[f64]| -> Vec<Option<LagFit>> {
        let mut fits = Vec::with_capacity(part.len());
        for (quad, len) in quads(0..part.len()) {
            let four = LagFit::at_x4(quad.map(|k| part[k]), samples, grid);
            fits.extend(four.into_iter().take(len));
        }
        fits
    };
    let half = lags.len() / 2;
    let (mut a, b) = robimu_model::pair::join(|| run(&lags[..half]), || run(&lags[half..]));
    a.extend(b);
    a
}

/// The fit of least mean squared residual (the first of equals).
fn best(fits: impl IntoIterator<Item = Option<LagFit>>) -> Option<LagFit> {
    fits.into_iter()
        .flatten()
        .min_by(|a, b| a.msr.total_cmp(&b.msr))
}

/// The coarse optimum: the scan of `lags` over `all` samples, or, with a
/// thinned `coarse` set, its scan's local minima (the best
/// [`COARSE_CANDIDATES`]) and their neighbours fitted again with all samples.
fn coarse_best(lags: &[f64], all: &Samples, coarse: &Samples, grid: &RateGrid) -> Option<LagFit> {
    if coarse.len() == all.len() {
        return best(scan(lags, all, grid));
    }
    let thin = scan(lags, coarse, grid);
    let msr = |k: usize| thin[k].map_or(f64::INFINITY, |f| f.msr);
    let mut minima: Vec<usize> = (0..lags.len())
        .filter(|&k| {
            thin[k].is_some()
                && (k == 0 || msr(k) <= msr(k - 1))
                && (k + 1 == lags.len() || msr(k) <= msr(k + 1))
        })
        .collect();
    minima.sort_by(|&a, &b| msr(a).total_cmp(&msr(b)));
    minima.truncate(COARSE_CANDIDATES);
    let mut near: Vec<usize> = minima
        .iter()
        .flat_map(|&k| k.saturating_sub(1)..(k + 2).min(lags.len()))
        .collect();
    near.sort_unstable();
    near.dedup();
    let again: Vec<f64> = near.iter().map(|&k| lags[k]).collect();
    best(scan(&again, all, grid))
}

/// Local minima of the thinned coarse scan fitted again with all samples.
pub(crate) const COARSE_CANDIDATES: usize = 8;

/// Find τ: see the module doc. `rate` is the nominal model's body rate
/// ([`BodyRate`]), `trajectory` the spline fitted to the joint samples.
pub(crate) fn find_tau(
    rate: &BodyRate,
    trajectory: &Spline,
    imu_t: &[f64],
    imu_gyro: &[[f64; 3]],
    search: &TauSearch,
) -> Result<TauEstimate, TauError> {
    let stride = imu_t.len().div_ceil(search.max_samples.max(1)).max(1);
    let all = Samples::new(
        imu_t.iter().step_by(stride).copied().collect(),
        imu_gyro.iter().step_by(stride).copied().collect(),
    );
    let coarse = all.every(all.len().div_ceil(search.coarse_samples.max(1)));
    let grid = RateGrid::new(rate, trajectory, (search.coarse_step / 2.0).min(0.01));
    let n_coarse = (search.range / search.coarse_step).round() as i64;
    let coarse_lags: Vec<f64> = (-n_coarse..=n_coarse)
        .map(|k| k as f64 * search.coarse_step)
        .collect();
    let Some(best) = coarse_best(&coarse_lags, &all, &coarse, &grid) else {
        return Err(TauError::NoOverlap {
            range: search.range,
        });
    };
    let n_fine = (2.0 * search.coarse_step / search.fine_step).round() as i64;
    let fine_lags: Vec<f64> = (-n_fine..=n_fine)
        .map(|k| best.lag + k as f64 * search.fine_step)
        .collect();
    let fine: Vec<LagFit> = scan(&fine_lags, &all, &grid)
        .into_iter()
        .flatten()
        .collect();
    let Some(ib) = (0..fine.len()).min_by(|&a, &b| fine[a].msr.total_cmp(&fine[b].msr)) else {
        return Err(TauError::NoOverlap {
            range: search.range,
        });
    };
    let LagFit {
        lag,
        r_squared: r2,
        count,
        ..
    } = fine[ib];
    if r2 < 0.5 {
        return Err(TauError::NoMatch { r_squared: r2 });
    }
    let mut tau = lag;
    if ib > 0 && ib + 1 < fine.len() {
        tau += parabola_vertex(
            fine[ib - 1].msr,
            fine[ib].msr,
            fine[ib + 1].msr,
            search.fine_step,
        );
    }
    Ok(TauEstimate {
        tau,
        r_squared: r2,
        samples: count,
    })
}

/// Where the parabola through (−h, y_m), (0, y_0), (h, y_p) has its minimum,
/// relative to the middle point; 0 when it opens downwards (no refinement).
pub(crate) fn parabola_vertex(ym: f64, y0: f64, yp: f64, h: f64) -> f64 {
    let denom = ym - 2.0 * y0 + yp;
    if denom > 0.0 {
        0.5 * h * (ym - yp) / denom
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parabola_vertex_of_a_sampled_parabola() {
        let f = |x: f64| 2.0 * (x - 0.013) * (x - 0.013) + 5.0;
        let h = 0.01;
        let v = parabola_vertex(f(-h), f(0.0), f(h), h);
        assert!((v - 0.013).abs() < 1e-12, "{v}");
        // opening downwards: no refinement
        assert_eq!(parabola_vertex(1.0, 2.0, 1.5, h), 0.0);
    }
}
