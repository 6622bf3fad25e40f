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
//! linearly (the motion's bandwidth is a few Hz, so the interpolation error
//! is ~1e-3 of the rate); a coarse scan over the whole range (split over two
//! threads) is refined by a fine scan around its optimum and a parabola
//! through the best three lags. The local solver then refines τ further.

use robimu_model::{JointState, MeasurementModel, Spline};

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
}

impl Default for TauSearch {
    fn default() -> Self {
        Self {
            range: 5.0,
            coarse_step: 0.02,
            fine_step: 0.001,
            max_samples: 4000,
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

/// Mean squared residual and R² of the regression g ≈ M ω + b over the
/// samples whose t + lag is inside the span.
fn fit_at(
    lag: f64,
    imu_t: &[f64],
    gyro: &[[f64; 3]],
    rate_at: &mut impl FnMut(f64) -> Option<[f64; 3]>,
) -> Option<(f64, f64, usize)> {
    let mut m = [[0.0f64; 4]; 4];
    let mut c = [[0.0f64; 3]; 4];
    let mut gg = [0.0f64; 3];
    let mut gs = [0.0f64; 3];
    let mut count = 0usize;
    for (t, g) in imu_t.iter().zip(gyro) {
        let Some(w) = rate_at(t + lag) else { continue };
        let a = [w[0], w[1], w[2], 1.0];
        for i in 0..4 {
            for j in 0..4 {
                m[i][j] += a[i] * a[j];
            }
            for k in 0..3 {
                c[i][k] += a[i] * g[k];
            }
        }
        for k in 0..3 {
            gg[k] += g[k] * g[k];
            gs[k] += g[k];
        }
        count += 1;
    }
    if count < 50 {
        return None;
    }
    // RSS = Σ‖g‖² − tr(Cᵀ M⁻¹ C), via Cholesky of the 4×4 M (with a tiny ridge).
    let ridge = 1e-12 * (m[0][0] + m[1][1] + m[2][2] + m[3][3]);
    for (i, row) in m.iter_mut().enumerate() {
        row[i] += ridge;
    }
    let mut l = [[0.0f64; 4]; 4];
    for i in 0..4 {
        for j in 0..=i {
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut explained = 0.0;
    for k in 0..3 {
        // y = L⁻¹ c_k; explained += ‖y‖²
        let mut y = [0.0f64; 4];
        for i in 0..4 {
            let mut s = c[i][k];
            for j in 0..i {
                s -= l[i][j] * y[j];
            }
            y[i] = s / l[i][i];
        }
        explained += y.iter().map(|v| v * v).sum::<f64>();
    }
    let total: f64 = gg.iter().sum();
    let centred: f64 = (0..3).map(|k| gg[k] - gs[k] * gs[k] / count as f64).sum();
    let rss = (total - explained).max(0.0);
    let r2 = if centred > 0.0 {
        1.0 - rss / centred
    } else {
        0.0
    };
    Some((rss / count as f64, r2, count))
}

/// Find τ: see the module doc. `model` is the nominal model, `trajectory`
/// the spline fitted to the joint samples.
pub fn find_tau(
    model: &MeasurementModel,
    trajectory: &Spline,
    imu_t: &[f64],
    imu_gyro: &[[f64; 3]],
    search: &TauSearch,
) -> Result<TauEstimate, TauError> {
    let (t0, t1) = (trajectory.knots().start(), trajectory.knots().end());
    let stride = imu_t.len().div_ceil(search.max_samples.max(1)).max(1);
    let ts: Vec<f64> = imu_t.iter().step_by(stride).copied().collect();
    let gs: Vec<[f64; 3]> = imu_gyro.iter().step_by(stride).copied().collect();
    let exact = |u: f64, js: &mut JointState| -> Option<[f64; 3]> {
        if u < t0 || u > t1 {
            return None;
        }
        trajectory.evaluate(u, js).ok()?;
        Some(model.inertial(js).1)
    };
    // body-rate grid, its two halves on two threads
    let h = (search.coarse_step / 2.0).min(0.01);
    let steps = ((t1 - t0) / h).ceil() as usize;
    let nodes = |ks: std::ops::Range<usize>| -> Vec<[f64; 3]> {
        let mut js = JointState::default();
        ks.map(|k| exact((t0 + k as f64 * h).min(t1), &mut js).unwrap_or([0.0; 3]))
            .collect()
    };
    let mid = steps.div_ceil(2);
    let grid: Vec<[f64; 3]> = std::thread::scope(|s| {
        let second = s.spawn(|| nodes(mid..steps + 1));
        let mut g = nodes(0..mid);
        g.extend(second.join().expect("grid thread panicked"));
        g
    });
    let interp = |u: f64| -> Option<[f64; 3]> {
        if u < t0 || u > t1 {
            return None;
        }
        let f = (u - t0) / h;
        let k = (f.floor() as usize).min(steps.saturating_sub(1));
        let a = f - k as f64;
        let (p, q) = (grid[k], grid[(k + 1).min(steps)]);
        Some(std::array::from_fn(|i| p[i] + a * (q[i] - p[i])))
    };
    // scan `lags`, best (lag, msr, r2, count) first
    let scan = |lags: &[f64]| -> Vec<(f64, f64, f64, usize)> {
        let half = lags.len() / 2;
        let run = |part: &[f64]| -> Vec<(f64, f64, f64, usize)> {
            let mut f = interp;
            part.iter()
                .filter_map(|&lag| fit_at(lag, &ts, &gs, &mut f).map(|(m, r2, c)| (lag, m, r2, c)))
                .collect()
        };
        let (a, b) = std::thread::scope(|s| {
            let h = s.spawn(|| run(&lags[half..]));
            (run(&lags[..half]), h.join().expect("scan thread panicked"))
        });
        a.into_iter().chain(b).collect()
    };
    let n_coarse = (search.range / search.coarse_step).round() as i64;
    let coarse_lags: Vec<f64> = (-n_coarse..=n_coarse)
        .map(|k| k as f64 * search.coarse_step)
        .collect();
    let coarse = scan(&coarse_lags);
    let Some(best) = coarse.iter().min_by(|a, b| a.1.total_cmp(&b.1)) else {
        return Err(TauError::NoOverlap {
            range: search.range,
        });
    };
    let n_fine = (2.0 * search.coarse_step / search.fine_step).round() as i64;
    let fine_lags: Vec<f64> = (-n_fine..=n_fine)
        .map(|k| best.0 + k as f64 * search.fine_step)
        .collect();
    let fine = scan(&fine_lags);
    let Some(ib) = (0..fine.len()).min_by(|&a, &b| fine[a].1.total_cmp(&fine[b].1)) else {
        return Err(TauError::NoOverlap {
            range: search.range,
        });
    };
    let (lag, _, r2, count) = fine[ib];
    if r2 < 0.5 {
        return Err(TauError::NoMatch { r_squared: r2 });
    }
    let mut tau = lag;
    if ib > 0 && ib + 1 < fine.len() {
        tau += parabola_vertex(fine[ib - 1].1, fine[ib].1, fine[ib + 1].1, search.fine_step);
    }
    Ok(TauEstimate {
        tau,
        r_squared: r2,
        samples: count,
    })
}

/// Where the parabola through (−h, y_m), (0, y_0), (h, y_p) has its minimum,
/// relative to the middle point; 0 when it opens downwards (no refinement).
pub fn parabola_vertex(ym: f64, y0: f64, yp: f64, h: f64) -> f64 {
    let denom = ym - 2.0 * y0 + yp;
    if denom > 0.0 {
        0.5 * h * (ym - yp) / denom
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::parabola_vertex;

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
