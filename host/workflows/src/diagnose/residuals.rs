//! Residual statistics of a fit (step 2 of the diagnosis, see the module
//! doc of [`super`]): whitened RMS and χ² per channel, Ljung–Box
//! whiteness, the Welch spectrum and its largest peak, the worst time
//! window and the regressor the residuals follow most.

use serde::Serialize;

use crate::calibrate::fit::Fit;
use crate::stats::{chi2_sf, ljung_box, LJUNG_BOX_LAGS};
use robimu_model::effects::CatalogueSetup;
use robimu_model::observations::Measurements;
use robimu_model::{JointState, MeasurementModel, ParamLayout, PerChannel, Robot};

/// Residual statistics of one fit (whitened residuals; see the module doc).
#[derive(Debug, Clone, Default, Serialize)]
pub struct ResidualStats {
    /// IMU samples.
    pub samples: usize,
    /// RMS per channel (1 = at the noise model).
    pub rms: PerChannel<f64>,
    /// Σ r² per channel.
    pub chi2: PerChannel<f64>,
    /// Σ r² over all channels, and its degrees of freedom (6 × samples).
    pub chi2_total: (f64, usize),
    /// Ljung–Box statistic (20 lags) and its p-value per channel.
    pub ljung_box: PerChannel<(f64, f64)>,
    /// Largest Welch-periodogram peak per channel: (frequency Hz, power
    /// relative to the channel's median).
    #[serde(serialize_with = "PerChannel::serialize_present")]
    pub spectral_peak: PerChannel<Option<(f64, f64)>>,
    /// P-value of that peak under a flat spectrum ([`peak_p_value`]).
    #[serde(serialize_with = "PerChannel::serialize_present")]
    pub spectral_peak_p: PerChannel<Option<f64>>,
    /// Per channel: the tenth of the session with the largest RMS (start s,
    /// RMS relative to the channel's).
    pub worst_window: PerChannel<(f64, f64)>,
    /// Per channel: the regressor with the largest |correlation| (name, r, z = r√N).
    pub top_regressor: PerChannel<(String, f64, f64)>,
    /// How many regressors were searched (the Bonferroni factor of
    /// [`regressor_p_value`]).
    pub regressors: usize,
    /// The motion's band, Hz: the frequency below which
    /// [`MOTION_BAND_SHARE`] of the power of the angular rate ω at the IMU
    /// lies ([`motion_band`]). The model's regressors carry their power
    /// there, so a discrepancy inside it can move the parameters and one
    /// far above it (a sensor's sampling artefact) cannot.
    pub motion_band_hz: Option<f64>,
}

/// Share of the angular rate's power below [`ResidualStats::motion_band_hz`].
pub const MOTION_BAND_SHARE: f64 = 0.999;

/// The frequency below which [`MOTION_BAND_SHARE`] of the summed Welch
/// power of `series` (sampled at `rate` Hz, each centred) lies; `None`
/// when they are too short or carry no power.
pub fn motion_band(series: &[&[f64]], rate: f64) -> Option<f64> {
    let mut total: Vec<(f64, f64)> = Vec::new();
    for x in series {
        let n = x.len().max(1) as f64;
        let mean = x.iter().sum::<f64>() / n;
        let centred: Vec<f64> = x.iter().map(|v| v - mean).collect();
        let spec = welch(&centred, rate);
        if total.is_empty() {
            total = spec;
        } else {
            total.iter_mut().zip(spec).for_each(|(a, b)| a.1 += b.1);
        }
    }
    let sum: f64 = total.iter().map(|p| p.1).sum();
    if sum.is_nan() || sum <= 0.0 {
        return None;
    }
    let mut acc = 0.0;
    total.iter().find_map(|&(f, p)| {
        acc += p;
        (acc >= MOTION_BAND_SHARE * sum).then_some(f)
    })
}

/// P-value of the largest |z| = |r|√N among `regressors` correlations of
/// white residuals with fixed series: each z ~ N(0, 1) under H0, so
/// P(|z| > z₀) = P(χ²₁ > z₀²), Bonferroni over the regressors.
pub fn regressor_p_value(z: f64, regressors: usize) -> f64 {
    if !z.is_finite() {
        return 1.0;
    }
    (regressors.max(1) as f64 * chi2_sf(z * z, 1.0)).min(1.0)
}

/// Welch segment length (samples).
const SEGMENT: usize = 512;

/// Residual statistics of `fit` on `data` (`rate` the IMU rate, Hz, for
/// the spectrum; τ from the fit).
///
/// The candidate regressors, evaluated at each IMU sample on the fitted
/// trajectory (at t + τ) with the fitted x:
///
/// ```text
/// time                    t, s
/// q1.. qd1.. qdd1..       joint angles, rates, accelerations (rad, rad/s, rad/s²)
/// wx wy wz, sx sy sz      angular rate ω and specific force s at the IMU (sensor frame)
/// tg1..tgN                gravity torque per joint, N·m (setup's mass model and g0)
/// temp                    sensor temperature, °C (only when the session recorded it)
/// ```
pub fn residual_stats(
    robot: &Robot,
    data: &Measurements,
    setup: &CatalogueSetup,
    fit: &Fit,
) -> ResidualStats {
    // IMU 0's residuals, at its own vector of x (docs/model.md §9)
    let layout = ParamLayout::new(robot);
    let x0 = ParamLayout::with_imus(robot, fit.n_imus).imu_x(0, &fit.x);
    let res = &fit.residuals;
    let ts: Vec<f64> = res.iter().map(|(i, _)| data.imu_t[*i]).collect();
    let rate = if ts.len() > 1 {
        (ts.len() - 1) as f64 / (ts[ts.len() - 1] - ts[0]).max(1e-9)
    } else {
        1.0
    };
    let tau = x0[layout.offsets().tau];
    let model = MeasurementModel::new(robot, &layout, &x0).ok();
    // regressors at each sample
    let dof = robot.dof();
    let mut reg_names: Vec<String> = vec!["time".into()];
    for j in 1..=dof {
        for k in ["q", "qd", "qdd"] {
            reg_names.push(format!("{k}{j}"));
        }
    }
    for k in ["wx", "wy", "wz", "sx", "sy", "sz"] {
        reg_names.push(k.into());
    }
    let gravity = setup.mass.dof() == dof;
    if gravity {
        reg_names.extend((1..=dof).map(|j| format!("tg{j}")));
    }
    let temp = data
        .imu_temp
        .as_deref()
        .filter(|c| c.len() == data.imu_t.len());
    if temp.is_some() {
        reg_names.push("temp".into());
    }
    // the regressors as columns, one value per sample; the two halves of
    // the samples on two threads
    let columns = |part: &[(usize, [f64; 6])]| -> Vec<Vec<f64>> {
        let mut regs: Vec<Vec<f64>> = (0..reg_names.len())
            .map(|_| Vec::with_capacity(part.len()))
            .collect();
        let mut js = JointState::default();
        for (i, _) in part {
            let t = data.imu_t[*i];
            fit.trajectory.evaluate_clamped(t + tau, &mut js);
            let mut cols = regs.iter_mut();
            let mut put = |v: f64| cols.next().expect("one column per regressor").push(v);
            put(t);
            for j in 0..dof {
                put(js.q[j]);
                put(js.qd[j]);
                put(js.qdd[j]);
            }
            let (w, s) = match &model {
                Some(m) => {
                    let (_, w, s) = m.inertial(&js);
                    (w, s)
                }
                None => ([0.0; 3], [0.0; 3]),
            };
            w.into_iter().chain(s).for_each(&mut put);
            if gravity {
                let tg = setup.mass.gravity_torques_array(&js.q[..dof], setup.g0);
                tg[..dof].iter().for_each(|&v| put(v));
            }
            if let Some(c) = temp {
                put(c[*i]);
            }
        }
        regs
    };
    let (first, second) = res.split_at(res.len() / 2);
    let (mut regs, rest) = robimu_model::pair::join(|| columns(first), || columns(second));
    for (col, more) in regs.iter_mut().zip(rest) {
        col.extend(more);
    }
    let w0 = 1 + 3 * dof;
    let motion_band_hz = motion_band(&[&regs[w0][..], &regs[w0 + 1][..], &regs[w0 + 2][..]], rate);
    let regs: Vec<Centred> = regs.iter().map(|x| Centred::new(x)).collect();
    // the channels' statistics, three per thread, gathered in channel order
    let channel = |c: usize| channel_stats(res, c, &ts, rate, &regs, &reg_names);
    let (mut per_channel, rest) = robimu_model::pair::join(
        || (0..3).map(channel).collect::<Vec<ChannelStats>>(),
        || (3..6).map(channel).collect::<Vec<_>>(),
    );
    per_channel.extend(rest);
    let st: [ChannelStats; 6] = match per_channel.try_into() {
        Ok(st) => st,
        Err(_) => unreachable!("six channels"),
    };
    let mut chi2_total = 0.0;
    for c in &st {
        chi2_total += c.ss;
    }
    ResidualStats {
        samples: res.len(),
        rms: PerChannel(std::array::from_fn(|k| st[k].rms)),
        chi2: PerChannel(std::array::from_fn(|k| st[k].ss)),
        chi2_total: (chi2_total, 6 * res.len()),
        ljung_box: PerChannel(std::array::from_fn(|k| st[k].ljung_box)),
        spectral_peak: PerChannel(std::array::from_fn(|k| st[k].peak.map(|(peak, _)| peak))),
        spectral_peak_p: PerChannel(std::array::from_fn(|k| st[k].peak.map(|(_, p)| p))),
        worst_window: PerChannel(std::array::from_fn(|k| st[k].worst_window)),
        top_regressor: PerChannel(std::array::from_fn(|k| st[k].top_regressor.clone())),
        regressors: reg_names.len(),
        motion_band_hz,
    }
}

/// One channel's part of [`ResidualStats`].
struct ChannelStats {
    ss: f64,
    rms: f64,
    ljung_box: (f64, f64),
    /// ((frequency, peak over median), its p-value).
    peak: Option<((f64, f64), f64)>,
    worst_window: (f64, f64),
    top_regressor: (String, f64, f64),
}

/// The statistics of channel `c` of the residuals `res` (sample times
/// `ts`, `rate` Hz) against the regressors `regs` named `names`.
fn channel_stats(
    res: &[(usize, [f64; 6])],
    c: usize,
    ts: &[f64],
    rate: f64,
    regs: &[Centred],
    names: &[String],
) -> ChannelStats {
    let n = res.len().max(1);
    let r: Vec<f64> = res.iter().map(|(_, v)| v[c]).collect();
    let ss: f64 = r.iter().map(|v| v * v).sum();
    let rms = (ss / n as f64).sqrt();
    let spec = welch(&r, rate);
    let mut powers: Vec<f64> = spec.iter().map(|p| p.1).collect();
    powers.sort_by(f64::total_cmp);
    let median = powers
        .get(powers.len() / 2)
        .copied()
        .unwrap_or(1.0)
        .max(1e-300);
    let peak = spec
        .iter()
        .skip(1)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|&(f, p)| {
            let pv = peak_p_value(p / median, welch_segments(r.len()), spec.len() - 1);
            ((f, p / median), pv)
        });
    let w = (r.len() / 10).max(1);
    let mut worst = (0.0, 0.0);
    for (k, chunk) in r.chunks(w).enumerate() {
        let wr = (chunk.iter().map(|v| v * v).sum::<f64>() / chunk.len() as f64).sqrt();
        if wr > worst.1 {
            worst = (ts[k * w], wr);
        }
    }
    let mut best = (String::new(), 0.0f64);
    let centred = Centred::new(&r);
    for (x, gname) in regs.iter().zip(names) {
        let corr = x.correlation(&centred);
        if corr.abs() > best.1.abs() {
            best = (gname.clone(), corr);
        }
    }
    ChannelStats {
        ss,
        rms,
        ljung_box: ljung_box(&r, LJUNG_BOX_LAGS),
        peak,
        worst_window: (worst.0, worst.1 / rms.max(1e-300)),
        top_regressor: (best.0, best.1, best.1 * (n as f64).sqrt()),
    }
}

/// Pearson correlation (0 when either series is constant: tested exactly,
/// since the rounded mean of a constant series such as a recorded 24.7 °C
/// leaves deviations of one ulp that would otherwise give a spurious r).
#[cfg(test)]
pub(super) fn correlation(x: &[f64], y: &[f64]) -> f64 {
    Centred::new(x).correlation(&Centred::new(y))
}

/// A series prepared for [`Centred::correlation`] with many others: its
/// deviations from the mean and their sum of squares, computed once (the
/// residual statistics correlate every channel with every regressor).
struct Centred {
    /// x_i − x̄ (empty for a constant series).
    dev: Vec<f64>,
    /// Σ (x_i − x̄)².
    ss: f64,
    /// Every value equal.
    constant: bool,
}

impl Centred {
    fn new(x: &[f64]) -> Self {
        if x.windows(2).all(|w| w[0] == w[1]) {
            return Self {
                dev: Vec::new(),
                ss: 0.0,
                constant: true,
            };
        }
        let n = x.len().max(1) as f64;
        let mean = x.iter().sum::<f64>() / n;
        let dev: Vec<f64> = x.iter().map(|a| a - mean).collect();
        let mut ss = 0.0;
        for d in &dev {
            ss += d * d;
        }
        Self {
            dev,
            ss,
            constant: false,
        }
    }

    /// Pearson correlation with `other` (same length): 0 when either is
    /// constant (see [`correlation`]).
    fn correlation(&self, other: &Centred) -> f64 {
        if self.constant || other.constant {
            return 0.0;
        }
        let mut sxy = 0.0;
        for (a, b) in self.dev.iter().zip(&other.dev) {
            sxy += a * b;
        }
        if self.ss <= 0.0 || other.ss <= 0.0 {
            0.0
        } else {
            sxy / (self.ss * other.ss).sqrt()
        }
    }
}

/// RMS of `r` over consecutive windows of about `window` seconds (the
/// residual plot of `robimu diagnose`): the span of `t` (non-decreasing, each
/// sample's time) is cut into round(span / window) equal windows, so the
/// last one is not a stub; one (mean sample time, RMS) per window that holds
/// samples.
pub fn windowed_rms(t: &[f64], r: &[f64], window: f64) -> Vec<(f64, f64)> {
    let (Some(&t0), Some(&t1)) = (t.first(), t.last()) else {
        return Vec::new();
    };
    let span = t1 - t0;
    let count = if window > 0.0 && span > 0.0 {
        (span / window).round().max(1.0)
    } else {
        1.0
    };
    let width = if span > 0.0 { span / count } else { 1.0 };
    let mut out = Vec::new();
    let (mut key, mut st, mut ss, mut n) = (0.0, 0.0, 0.0, 0usize);
    for (&ti, &ri) in t.iter().zip(r) {
        let k = ((ti - t0) / width).floor().min(count - 1.0);
        if k != key && n > 0 {
            out.push((st / n as f64, (ss / n as f64).sqrt()));
            (st, ss, n) = (0.0, 0.0, 0);
        }
        key = k;
        st += ti;
        ss += ri * ri;
        n += 1;
    }
    if n > 0 {
        out.push((st / n as f64, (ss / n as f64).sqrt()));
    }
    out
}

/// Segments of [`welch`] for `n` samples (0 when too short).
pub fn welch_segments(n: usize) -> usize {
    let seg = SEGMENT.min(n);
    if seg < 8 {
        return 0;
    }
    (n - seg) / (seg / 2) + 1
}

/// P-value of a Welch peak `ratio` times the channel's median power when
/// the spectrum is flat (white residuals), Bonferroni over the `bins`
/// searched: each bin of `segments` Hann segments at 50 % overlap is
/// S·χ²_ν/ν with ν = 2K/1.056 (Welch 1967: adjacent segments correlate by
/// 1/6 in amplitude), the median S·m_ν (Wilson–Hilferty), so the peak bin
/// exceeds ν·ratio·m_ν in χ²_ν.
pub fn peak_p_value(ratio: f64, segments: usize, bins: usize) -> f64 {
    if segments == 0 || !ratio.is_finite() {
        return 1.0;
    }
    let nu = 2.0 * segments as f64 / 1.056;
    let median = (1.0 - 2.0 / (9.0 * nu)).powi(3);
    (bins.max(1) as f64 * chi2_sf(nu * ratio * median, nu)).min(1.0)
}

/// Welch periodogram (Hann window, 50 % overlap, segments of 512): (frequency
/// Hz, power density) for frequencies 0..rate/2. Each segment's DFT
/// X_k = Σ_i x_i e^{−2πi·ki/L} is an iterative radix-2 FFT when L is a power
/// of two (always, but for series shorter than 512), else the direct sum.
pub fn welch(r: &[f64], rate: f64) -> Vec<(f64, f64)> {
    let seg = SEGMENT.min(r.len());
    if seg < 8 {
        return Vec::new();
    }
    let bins = seg / 2 + 1;
    let win: Vec<f64> = (0..seg)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / seg as f64).cos())
        .collect();
    let wss: f64 = win.iter().map(|w| w * w).sum();
    let mut p = vec![0.0; bins];
    let mut count = 0;
    let mut start = 0;
    let dft = Dft::new(seg);
    let mut x = vec![(0.0, 0.0); seg];
    while start + seg <= r.len() {
        for (i, xi) in x.iter_mut().enumerate() {
            *xi = (r[start + i] * win[i], 0.0);
        }
        dft.transform(&mut x);
        for (pk, &(re, im)) in p.iter_mut().zip(&x) {
            *pk += (re * re + im * im) / (wss * rate);
        }
        count += 1;
        start += seg / 2;
    }
    p.iter()
        .enumerate()
        .map(|(k, v)| (k as f64 * rate / seg as f64, v / count.max(1) as f64))
        .collect()
}

/// The DFT of length L, X_k = Σ_i x_i e^{−2πi·ki/L}, with its twiddles
/// (cos, sin of 2π i/L) computed once.
struct Dft {
    len: usize,
    twiddle: Vec<(f64, f64)>,
}

impl Dft {
    fn new(len: usize) -> Self {
        let twiddle = (0..len)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / len as f64;
                (a.cos(), a.sin())
            })
            .collect();
        Self { len, twiddle }
    }

    /// Replace `x` (length L, (re, im)) by its DFT.
    fn transform(&self, x: &mut [(f64, f64)]) {
        let n = self.len;
        debug_assert_eq!(x.len(), n);
        let w = |i: usize| self.twiddle[i % n];
        if !n.is_power_of_two() {
            let y: Vec<(f64, f64)> = (0..n)
                .map(|k| {
                    x.iter()
                        .enumerate()
                        .fold((0.0, 0.0), |(re, im), (i, &(a, b))| {
                            let (c, s) = w(k * i);
                            (re + a * c + b * s, im + b * c - a * s)
                        })
                })
                .collect();
            x.copy_from_slice(&y);
            return;
        }
        let bits = n.trailing_zeros();
        for i in 0..n {
            let j = i.reverse_bits() >> (usize::BITS - bits);
            if j > i {
                x.swap(i, j);
            }
        }
        let mut half = 1;
        while half < n {
            let stride = n / (2 * half);
            for block in x.chunks_exact_mut(2 * half) {
                let (lo, hi) = block.split_at_mut(half);
                for (k, (u, v)) in lo.iter_mut().zip(hi.iter_mut()).enumerate() {
                    let (c, s) = w(k * stride);
                    // v·e^{−iα} with (c, s) = (cos α, sin α)
                    let t = (v.0 * c + v.1 * s, v.1 * c - v.0 * s);
                    *v = (u.0 - t.0, u.1 - t.1);
                    *u = (u.0 + t.0, u.1 + t.1);
                }
            }
            half *= 2;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Dft;

    /// The motion's band of angular rates made of sines whose powers are
    /// known (a sine of amplitude A carries A²/2): 99.9 % of the power lies
    /// below the highest motion sine when a weak fast one carries less than
    /// 0.1 % (so the band ends at the motion's edge, not at 5 Hz), and
    /// above it when the fast one carries 1 %.
    #[test]
    fn the_motion_band_ends_where_the_rates_power_does() {
        let rate = 150.0;
        let t: Vec<f64> = (0..45_000).map(|i| i as f64 / rate).collect();
        let sine = |a: f64, f: f64| -> Vec<f64> {
            t.iter()
                .map(|t| a * (2.0 * std::f64::consts::PI * f * t).sin())
                .collect()
        };
        let add = |a: Vec<f64>, b: Vec<f64>| -> Vec<f64> {
            a.iter().zip(&b).map(|(x, y)| x + y).collect()
        };
        // motion at 0.3, 0.6 and 1.0 Hz (power 0.5 + 0.125 + 0.02); a 5 Hz
        // artefact of power 0.5·0.01² = 5e-5 (< 0.1 % of 0.645)
        let motion = || add(add(sine(1.0, 0.3), sine(0.5, 0.6)), sine(0.2, 1.0));
        let wx = add(motion(), sine(0.01, 5.0));
        let zero = vec![0.0; t.len()];
        let band = super::motion_band(&[&wx, &zero, &zero], rate).unwrap();
        // the Welch bins are rate/512 = 0.29 Hz apart, and the Hann window
        // spreads each sine over its neighbours
        assert!((1.0..1.7).contains(&band), "band {band} Hz");
        // the fast sine at 1 % of the power moves the band's edge to it
        let wx = add(motion(), sine(0.114, 5.0));
        let band = super::motion_band(&[&zero, &wx, &zero], rate).unwrap();
        assert!((4.7..5.6).contains(&band), "band {band} Hz");
        // no motion, no band
        assert_eq!(super::motion_band(&[&zero], rate), None);
    }

    /// The correlation through [`super::Centred`] (deviations and sums of
    /// squares computed once per series) is bit-identical to the former
    /// one-pass form, constant series included.
    #[test]
    fn centred_correlation_is_the_former_one() {
        fn former(x: &[f64], y: &[f64]) -> f64 {
            let constant = |s: &[f64]| s.windows(2).all(|w| w[0] == w[1]);
            if constant(x) || constant(y) {
                return 0.0;
            }
            let n = x.len().max(1) as f64;
            let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
            let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
            for (a, b) in x.iter().zip(y) {
                sxy += (a - mx) * (b - my);
                sxx += (a - mx) * (a - mx);
                syy += (b - my) * (b - my);
            }
            if sxx <= 0.0 || syy <= 0.0 {
                0.0
            } else {
                sxy / (sxx * syy).sqrt()
            }
        }
        let series = |k: usize| -> Vec<f64> {
            (0..997)
                .map(|i| ((i * (3 + k)) as f64 * 0.731).sin() * (1.0 + k as f64) + 0.1 * k as f64)
                .collect()
        };
        let mut all: Vec<Vec<f64>> = (0..6).map(series).collect();
        all.push(vec![24.7; 997]);
        for x in &all {
            for y in &all {
                assert_eq!(super::correlation(x, y).to_bits(), former(x, y).to_bits());
            }
        }
    }

    /// The FFT of [`Dft`] equals the direct sum Σ_i x_i e^{−2πi·ki/L}
    /// (evaluated here independently, with sin/cos per term) for powers of
    /// two and, through its direct branch, for other lengths.
    #[test]
    fn dft_matches_the_direct_sum() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        for len in [512, 64, 8, 12, 100] {
            let x: Vec<(f64, f64)> = (0..len)
                .map(|_| (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
                .collect();
            let mut y = x.clone();
            Dft::new(len).transform(&mut y);
            for (k, yk) in y.iter().enumerate() {
                let (mut re, mut im) = (0.0, 0.0);
                for (i, &(a, b)) in x.iter().enumerate() {
                    let ang = -2.0 * std::f64::consts::PI * (k * i) as f64 / len as f64;
                    re += a * ang.cos() - b * ang.sin();
                    im += a * ang.sin() + b * ang.cos();
                }
                let err = (yk.0 - re).hypot(yk.1 - im);
                assert!(
                    err < 1e-11,
                    "len {len}, bin {k}: {yk:?} against ({re}, {im})"
                );
            }
        }
    }
}
