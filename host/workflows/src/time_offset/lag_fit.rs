//! The regression of the measured gyroscope on the predicted body rate at
//! one lag L (docs/model.md §6.5): g ≈ M ω(t + L) + b over the samples whose
//! t + L lies in the trajectory's span, its mean squared residual and R².
//!
//! The samples are sorted by time, so those inside the span at a lag are
//! one run of them (found by bisection), and the normal equations' sums —
//! Σ a aᵀ and Σ a gᵀ with a = [ω; 1], Σ g², Σ g — are accumulated over that
//! run alone: the upper triangle of the symmetric Σ a aᵀ, its constant row
//! as Σ ω and the count, Σ 1·g as Σ g. These are the terms, in the order, of
//! the plain sum over every sample (which [`tests`] keeps as the reference).

use super::rate_grid::RateGrid;
use robimu_model::lanes::F64x4;

/// The samples of the search, sorted by time.
pub struct Samples {
    t: Vec<f64>,
    g: Vec<[f64; 3]>,
}

impl Samples {
    /// Times and gyroscope vectors (sorted by time here when they are not).
    pub fn new(t: Vec<f64>, g: Vec<[f64; 3]>) -> Self {
        if t.windows(2).all(|w| w[0] <= w[1]) {
            return Self { t, g };
        }
        let mut order: Vec<usize> = (0..t.len()).collect();
        order.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
        Self {
            t: order.iter().map(|&i| t[i]).collect(),
            g: order.iter().map(|&i| g[i]).collect(),
        }
    }

    /// Every `stride`-th sample.
    pub fn every(&self, stride: usize) -> Self {
        let s = stride.max(1);
        Self {
            t: self.t.iter().step_by(s).copied().collect(),
            g: self.g.iter().step_by(s).copied().collect(),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }
}

/// The fit at one lag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LagFit {
    /// The lag L, s.
    pub lag: f64,
    /// Mean squared residual.
    pub msr: f64,
    /// Fraction of the gyroscope's variance explained.
    pub r_squared: f64,
    /// Samples inside the span.
    pub count: usize,
}

/// Fewest samples a lag is fitted with.
const MIN_COUNT: usize = 50;

impl LagFit {
    /// The regression at `lag` of `samples` on the rate of `grid` (`None`
    /// with fewer than 50 samples inside the span or a singular Σ a aᵀ):
    /// one lane of [`Self::at_x4`]'s sums (the search fits four lags at a
    /// time; this is the one-lag reference its tests compare with).
    #[cfg(test)]
    pub fn at(lag: f64, samples: &Samples, grid: &RateGrid) -> Option<Self> {
        let (lo, hi) = run(lag, samples, grid);
        let mut sums = Sums4::default();
        for i in lo..hi {
            sums.add_lane(0, grid.at_inside(samples.t[i] + lag), &samples.g[i]);
        }
        sums.fit(0, lag, hi - lo)
    }
}

/// The samples inside the span of `grid` at `lag`: t + lag is monotone in
/// t, so they are one run lo..hi.
fn run(lag: f64, samples: &Samples, grid: &RateGrid) -> (usize, usize) {
    let (t0, t1) = grid.span();
    let t = &samples.t;
    let lo = t.partition_point(|&ti| ti + lag < t0);
    (lo, lo + t[lo..].partition_point(|&ti| ti + lag <= t1))
}

impl LagFit {
    /// The regressions at four lags, each lane the bits of a fit of its lag
    /// alone ([`Self::at`]): every lag's sums run over its samples in order, the samples inside all
    /// four spans in the lanes of [`F64x4`] (the same operations lane by
    /// lane), the few at the ends of one lag's span alone. Compiled for
    /// AVX2 where the CPU has it.
    pub fn at_x4(lags: [f64; 4], samples: &Samples, grid: &RateGrid) -> [Option<Self>; 4] {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx,avx2")]
            fn avx2(lags: [f64; 4], samples: &Samples, grid: &RateGrid) -> [Option<LagFit>; 4] {
                LagFit::at_lanes(lags, samples, grid)
            }
            if robimu_model::lanes::has_avx2() {
                // SAFETY: the CPU has AVX and AVX2 (checked just above).
                return unsafe { avx2(lags, samples, grid) };
            }
        }
        Self::at_lanes(lags, samples, grid)
    }

    #[inline(always)]
    fn at_lanes(lags: [f64; 4], samples: &Samples, grid: &RateGrid) -> [Option<Self>; 4] {
        let (t, g) = (&samples.t, &samples.g);
        // each lag's samples inside the span
        let runs = lags.map(|lag| run(lag, samples, grid));
        let common_lo = runs.iter().map(|r| r.0).max().unwrap_or(0);
        let common_hi = runs.iter().map(|r| r.1).min().unwrap_or(0).max(common_lo);
        let mut sums = Sums4::default();
        for (l, &(lo, hi)) in runs.iter().enumerate() {
            for i in lo..hi.min(common_lo) {
                sums.add_lane(l, grid.at_inside(t[i] + lags[l]), &g[i]);
            }
        }
        let lag4 = F64x4(lags);
        for i in common_lo..common_hi {
            let u = F64x4::splat(t[i]) + lag4;
            let w: [[f64; 3]; 4] = std::array::from_fn(|l| grid.at_inside(u.0[l]));
            sums.add(std::array::from_fn(|a| F64x4(w.map(|wl| wl[a]))), &g[i]);
        }
        for (l, &(lo, hi)) in runs.iter().enumerate() {
            for i in common_hi.max(lo)..hi {
                sums.add_lane(l, grid.at_inside(t[i] + lags[l]), &g[i]);
            }
        }
        std::array::from_fn(|l| sums.fit(l, lags[l], runs[l].1 - runs[l].0))
    }
}

/// The regression sums of four lags, one per lane.
#[derive(Default)]
struct Sums4 {
    m: [[F64x4; 4]; 3],
    c: [[F64x4; 3]; 3],
    gg: [F64x4; 3],
    gs: [F64x4; 3],
}

impl Sums4 {
    /// One sample in every lane: ω `w` (per axis, per lane) and g.
    #[inline(always)]
    fn add(&mut self, w: [F64x4; 3], g: &[f64; 3]) {
        for i in 0..3 {
            for j in i..3 {
                self.m[i][j] += w[i] * w[j];
            }
            self.m[i][3] += w[i];
            for k in 0..3 {
                self.c[i][k] += w[i] * g[k];
            }
        }
        for k in 0..3 {
            self.gg[k] += F64x4::splat(g[k] * g[k]);
            self.gs[k] += F64x4::splat(g[k]);
        }
    }

    /// One sample in lane `l` alone.
    #[inline(always)]
    fn add_lane(&mut self, l: usize, w: [f64; 3], g: &[f64; 3]) {
        for i in 0..3 {
            for j in i..3 {
                self.m[i][j].0[l] += w[i] * w[j];
            }
            self.m[i][3].0[l] += w[i];
            for k in 0..3 {
                self.c[i][k].0[l] += w[i] * g[k];
            }
        }
        for k in 0..3 {
            self.gg[k].0[l] += g[k] * g[k];
            self.gs[k].0[l] += g[k];
        }
    }

    /// Lane `l`'s fit from its sums over `count` samples.
    fn fit(&self, l: usize, lag: f64, count: usize) -> Option<LagFit> {
        if count < MIN_COUNT {
            return None;
        }
        let mut m = [[0.0f64; 4]; 4];
        for i in 0..3 {
            for j in i..4 {
                m[i][j] = self.m[i][j].0[l];
            }
        }
        m[3][3] = count as f64;
        for i in 0..4 {
            for j in 0..i {
                m[i][j] = m[j][i];
            }
        }
        let lane3 = |v: &[F64x4; 3]| v.map(|x| x.0[l]);
        let gs = lane3(&self.gs);
        let c = [lane3(&self.c[0]), lane3(&self.c[1]), lane3(&self.c[2]), gs];
        let (msr, r_squared) = solve(m, &c, lane3(&self.gg), gs, count)?;
        Some(LagFit {
            lag,
            msr,
            r_squared,
            count,
        })
    }
}

/// Mean squared residual and R² from the sums: RSS = Σ‖g‖² − tr(Cᵀ M⁻¹ C),
/// by Cholesky of the 4×4 M (with a tiny ridge).
fn solve(
    mut m: [[f64; 4]; 4],
    c: &[[f64; 3]; 4],
    gg: [f64; 3],
    gs: [f64; 3],
    count: usize,
) -> Option<(f64, f64)> {
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
    Some((rss / count as f64, r2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The regression at `lag` as a plain sum over every sample, skipping
    /// those outside the span (the sums of the former scan, kept as the
    /// reference).
    fn direct(lag: f64, t: &[f64], g: &[[f64; 3]], grid: &RateGrid) -> Option<(f64, f64, usize)> {
        let (t0, t1) = grid.span();
        let mut m = [[0.0f64; 4]; 4];
        let mut c = [[0.0f64; 3]; 4];
        let (mut gg, mut gs) = ([0.0f64; 3], [0.0f64; 3]);
        let mut count = 0usize;
        for (&ti, g) in t.iter().zip(g) {
            let u = ti + lag;
            if u < t0 || u > t1 {
                continue;
            }
            let w = grid.at_inside(u);
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
        if count < MIN_COUNT {
            return None;
        }
        solve(m, &c, gg, gs, count).map(|(msr, r2)| (msr, r2, count))
    }

    /// On random rates and samples (a bias, gains and noise, some samples
    /// outside the span at every lag) the run's sums give the direct
    /// regression's mean squared residual and R² to 1e-12 relative, and the
    /// same sample count, at lags inside, across and beyond the span.
    #[test]
    fn run_sums_equal_the_direct_regression() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(18);
        let (t0, t1, h) = (2.0f64, 62.0, 0.01);
        let steps = ((t1 - t0) / h).ceil() as usize;
        let nodes: Vec<[f64; 3]> = (0..=steps)
            .map(|k| {
                let x = k as f64 * h;
                [
                    (1.3 * x).sin(),
                    (0.7 * x).cos() * 0.5,
                    (2.1 * x + 0.3).sin(),
                ]
            })
            .collect();
        let grid = RateGrid::from_nodes(t0, t1, h, nodes);
        let n = 3000;
        let mut t: Vec<f64> = (0..n).map(|_| rng.random_range(-3.0..68.0)).collect();
        t.sort_by(f64::total_cmp);
        let g: Vec<[f64; 3]> = t
            .iter()
            .map(|&ti| {
                let w = grid.at_inside((ti + 0.37).clamp(t0, t1));
                std::array::from_fn(|k| {
                    1.05 * w[k] + 0.1 * w[(k + 1) % 3] + 0.02 + 0.05 * rng.random_range(-1.0..1.0)
                })
            })
            .collect();
        let samples = Samples::new(t.clone(), g.clone());
        let mut fitted = 0;
        for lag in [-70.0, -5.0, -0.5, 0.0, 0.37, 0.3712, 1.0, 4.99, 50.0, 64.0] {
            let want = direct(lag, &t, &g, &grid);
            let got = LagFit::at(lag, &samples, &grid);
            match (want, got) {
                (None, None) => {}
                (Some((msr, r2, count)), Some(f)) => {
                    fitted += 1;
                    assert_eq!(f.count, count, "lag {lag}");
                    assert!(
                        (f.msr - msr).abs() <= 1e-12 * msr,
                        "lag {lag}: {} vs {msr}",
                        f.msr
                    );
                    assert!(
                        (f.r_squared - r2).abs() <= 1e-12,
                        "lag {lag}: {} vs {r2}",
                        f.r_squared
                    );
                }
                (w, g) => panic!("lag {lag}: {w:?} vs {g:?}"),
            }
        }
        assert!(fitted >= 7, "{fitted} lags fitted");
        // best at the true lag
        let at = |lag: f64| LagFit::at(lag, &samples, &grid).unwrap().msr;
        assert!(at(0.37) < at(0.35) && at(0.37) < at(0.39));
    }

    /// Four lags at once: each lane the bits of its own `at` call, for lags
    /// whose sample runs coincide, overlap, are disjoint, or are too short
    /// to fit (the ends of the span).
    #[test]
    fn four_lags_at_once_are_the_single_lag_fits() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (t0, t1, h) = (0.0f64, 30.0, 0.01);
        let steps = ((t1 - t0) / h).ceil() as usize;
        let nodes: Vec<[f64; 3]> = (0..=steps)
            .map(|k| {
                let x = k as f64 * h;
                [(0.9 * x).sin(), (1.7 * x).cos(), 0.2 * (0.4 * x).sin()]
            })
            .collect();
        let grid = RateGrid::from_nodes(t0, t1, h, nodes);
        let mut t: Vec<f64> = (0..2000).map(|_| rng.random_range(-2.0..33.0)).collect();
        t.sort_by(f64::total_cmp);
        let g: Vec<[f64; 3]> = t
            .iter()
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let samples = Samples::new(t, g);
        let quads = [
            [0.1, 0.1, 0.1, 0.1],
            [-1.0, -0.25, 0.5, 2.0],
            [-31.0, -10.0, 10.0, 31.0],
            [-32.9, -29.5, 29.5, 32.9],
            [0.0, 0.001, 0.002, 0.003],
        ];
        let mut fitted = 0;
        for lags in quads {
            let four = LagFit::at_x4(lags, &samples, &grid);
            for (l, &lag) in lags.iter().enumerate() {
                let one = LagFit::at(lag, &samples, &grid);
                assert_eq!(four[l], one, "lag {lag}");
                fitted += usize::from(one.is_some());
            }
        }
        assert!(fitted >= 14, "{fitted} of 20 lags fitted");
    }

    /// Samples out of time order are sorted: the same fit as sorted input.
    #[test]
    fn unsorted_samples_are_sorted() {
        let nodes: Vec<[f64; 3]> = (0..=1000)
            .map(|k| {
                let x = k as f64 * 0.01;
                [x.sin(), (2.0 * x).cos(), 0.3 * x]
            })
            .collect();
        let grid = RateGrid::from_nodes(0.0, 10.0, 0.01, nodes);
        let t: Vec<f64> = (0..400).map(|i| 0.025 * i as f64).collect();
        let g: Vec<[f64; 3]> = t
            .iter()
            .map(|&ti| grid.at_inside(ti))
            .map(|w| [w[1], w[0], w[2] + 0.1])
            .collect();
        let mut order: Vec<usize> = (0..t.len()).collect();
        order.reverse();
        order.swap(3, 200);
        let shuffled = Samples::new(
            order.iter().map(|&i| t[i]).collect(),
            order.iter().map(|&i| g[i]).collect(),
        );
        let sorted = Samples::new(t, g);
        assert_eq!(shuffled.t, sorted.t);
        assert_eq!(shuffled.g, sorted.g);
        assert_eq!(
            LagFit::at(0.2, &shuffled, &grid),
            LagFit::at(0.2, &sorted, &grid)
        );
    }
}
