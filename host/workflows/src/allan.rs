//! Allan deviation of a static IMU recording (IEEE Std 952-1997, annex C).
//!
//! The overlapping Allan variance at cluster time τ = m·τ0 (τ0 the sample
//! period) is σ²(τ) = ½ ⟨(ȳ_{k+m} − ȳ_k)²⟩ over every k, ȳ_k the mean of the
//! m samples from k on; τ runs over octaves m = 1, 2, 4, … up to a ninth of
//! the record (longer clusters have too few independent pairs).
//!
//! Read off from the curve: the noise density N (white noise, angle/velocity
//! random walk) as σ at τ = 1 s on the line of slope −½ fitted to the region
//! where the curve falls as τ^−½ (σ(τ) = N/√τ there), and the bias
//! instability B = min σ(τ) / 0.664 (flicker floor, σ = 0.664·B).

use robimu_session::IMU_COLUMNS;

/// One point of an Allan deviation curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanPoint {
    /// Cluster time τ, s.
    pub tau: f64,
    /// Cluster size m (samples).
    pub m: usize,
    /// Allan deviation σ(τ), the channel's unit.
    pub adev: f64,
}

/// Noise terms read off one curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseTerms {
    /// Noise density N, unit·√s (= unit/√Hz); σ of one sample is N/√τ0.
    pub density: f64,
    /// Points of the −½ region the density was fitted to (0: none found,
    /// the density is read from the shortest τ alone).
    pub density_points: usize,
    /// Bias instability B = min σ / 0.664, the channel's unit.
    pub bias_instability: f64,
    /// τ of the minimum, s.
    pub tau_min: f64,
}

/// One IMU channel's curve and its noise terms.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelAllan {
    /// Channel name (`ax` … `gz`).
    pub name: String,
    /// The curve, increasing τ.
    pub curve: Vec<AllanPoint>,
    /// Read off the curve.
    pub terms: NoiseTerms,
}

/// Why an Allan deviation could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AllanError {
    /// Fewer samples than two octaves need.
    #[error("{count} samples are too few for an Allan deviation (need at least {need})")]
    TooFewSamples {
        /// Samples present.
        count: usize,
        /// Samples needed.
        need: usize,
    },
    /// The sample period is not a positive finite number.
    #[error("sample period {0} s is not a positive number (are the sample times increasing?)")]
    BadPeriod(f64),
    /// A sample is NaN or infinite.
    #[error("sample {0} is not finite")]
    NotFinite(usize),
}

/// Fewest samples accepted: clusters m = 1 and 2 with a ninth of the record.
pub const MIN_SAMPLES: usize = 18;

/// The overlapping Allan deviation of `y` sampled every `tau0` s, at
/// octave-spaced τ up to a ninth of the record.
pub(crate) fn allan_deviation(y: &[f64], tau0: f64) -> Result<Vec<AllanPoint>, AllanError> {
    if !(tau0.is_finite() && tau0 > 0.0) {
        return Err(AllanError::BadPeriod(tau0));
    }
    let n = y.len();
    if n < MIN_SAMPLES {
        return Err(AllanError::TooFewSamples {
            count: n,
            need: MIN_SAMPLES,
        });
    }
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(AllanError::NotFinite(i + 1));
    }
    // cumulative sums about the mean (keeps the differences well conditioned)
    let mean = y.iter().sum::<f64>() / n as f64;
    let mut theta = Vec::with_capacity(n + 1);
    theta.push(0.0);
    let mut acc = 0.0;
    for v in y {
        acc += v - mean;
        theta.push(acc);
    }
    let mut out = Vec::new();
    let mut m = 1;
    while 9 * m <= n {
        let mut sum = 0.0;
        let count = n - 2 * m + 1;
        for k in 0..count {
            let d = theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k];
            sum += d * d;
        }
        let mf = m as f64;
        let avar = sum / (2.0 * mf * mf * count as f64);
        out.push(AllanPoint {
            tau: mf * tau0,
            m,
            adev: avar.sqrt(),
        });
        m *= 2;
    }
    Ok(out)
}

/// Slope of the −½ region's bounds: a segment counts as white noise when its
/// log-log slope is within ±0.2 of −½.
const SLOPE_TOLERANCE: f64 = 0.2;

/// N and B from a curve (see the module doc). The −½ region is the run of
/// points from the shortest τ whose segments keep a slope within ±0.2 of −½;
/// log N is the mean of log σ + ½ log τ over it, weighted by 1/m (the number
/// of independent clusters, so long τ with few clusters counts little).
pub(crate) fn noise_terms(curve: &[AllanPoint]) -> NoiseTerms {
    let mut region = 0;
    if curve.len() >= 2 {
        for w in curve.windows(2) {
            let slope = (w[1].adev.ln() - w[0].adev.ln()) / (w[1].tau.ln() - w[0].tau.ln());
            if (slope + 0.5).abs() <= SLOPE_TOLERANCE {
                region = if region == 0 { 2 } else { region + 1 };
            } else {
                break;
            }
        }
    }
    let used = &curve[..region.max(1).min(curve.len())];
    let (mut num, mut den) = (0.0, 0.0);
    for p in used {
        let w = 1.0 / p.m as f64;
        num += w * (p.adev.ln() + 0.5 * p.tau.ln());
        den += w;
    }
    let density = if den > 0.0 {
        (num / den).exp()
    } else {
        f64::NAN
    };
    let min = curve
        .iter()
        .copied()
        .min_by(|a, b| a.adev.total_cmp(&b.adev));
    NoiseTerms {
        density,
        density_points: region,
        bias_instability: min.map_or(f64::NAN, |p| p.adev / 0.664),
        tau_min: min.map_or(f64::NAN, |p| p.tau),
    }
}

/// The rate random walk K (the bias random walk Kalibr calls
/// `…_random_walk`, unit/s·√s) from the rising part of a curve, where
/// σ²(τ) = N²/τ + K²·τ/3 (IEEE Std 952, annex C; N the noise `density`):
/// the points after the minimum whose segments keep a slope within ±0.2 of
/// +½, K the mean of log √(3·(σ² − N²/τ)/τ) over them weighted by 1/m.
/// `None` when the curve does not rise so (a recording too short to show
/// the bias wander).
pub(crate) fn rate_random_walk(curve: &[AllanPoint], density: f64) -> Option<f64> {
    let start = curve
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.adev.total_cmp(&b.1.adev))?
        .0;
    let mut used: Vec<AllanPoint> = Vec::new();
    for w in curve[start..].windows(2) {
        let slope = (w[1].adev.ln() - w[0].adev.ln()) / (w[1].tau.ln() - w[0].tau.ln());
        if (slope - 0.5).abs() <= SLOPE_TOLERANCE {
            if used.is_empty() {
                used.push(w[0]);
            }
            used.push(w[1]);
        } else if !used.is_empty() {
            break;
        }
    }
    if used.is_empty() {
        return None;
    }
    let (mut num, mut den) = (0.0, 0.0);
    for p in &used {
        let k2 = 3.0 * (p.adev * p.adev - density * density / p.tau) / p.tau;
        if k2 > 0.0 {
            let w = 1.0 / p.m as f64;
            num += w * 0.5 * k2.ln();
            den += w;
        }
    }
    (den > 0.0).then(|| (num / den).exp())
}

/// The curves of an `allan.csv` (`tau,ax,ay,az,gx,gy,gz`, as `robimu allan`
/// writes it), with their noise terms; m is τ over the first τ.
pub(crate) fn curves_from_csv(text: &str) -> Result<Vec<ChannelAllan>, String> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .ok_or("empty file")?
        .split(',')
        .map(str::trim)
        .collect();
    let want: Vec<&str> = std::iter::once("tau").chain(IMU_COLUMNS).collect();
    if header != want {
        return Err(format!("header {header:?}, expected {want:?}"));
    }
    let mut out: Vec<ChannelAllan> = IMU_COLUMNS
        .iter()
        .map(|n| ChannelAllan {
            name: n.to_string(),
            curve: Vec::new(),
            terms: noise_terms(&[]),
        })
        .collect();
    let mut tau0 = None;
    for (k, line) in lines.enumerate() {
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("line {}: {e}", k + 2))?;
        if v.len() != 7 || !v.iter().all(|x| x.is_finite() && *x > 0.0) {
            return Err(format!(
                "line {}: expected 7 positive numbers, got {line:?}",
                k + 2
            ));
        }
        let tau0 = *tau0.get_or_insert(v[0]);
        let m = (v[0] / tau0).round().max(1.0) as usize;
        for (c, ch) in out.iter_mut().enumerate() {
            ch.curve.push(AllanPoint {
                tau: v[0],
                m,
                adev: v[c + 1],
            });
        }
    }
    if out[0].curve.is_empty() {
        return Err("no curve points".into());
    }
    for ch in &mut out {
        ch.terms = noise_terms(&ch.curve);
    }
    Ok(out)
}

/// The sample period of `t`: the median interval.
pub(crate) fn sample_period(t: &[f64]) -> Result<f64, AllanError> {
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if dt.is_empty() {
        return Err(AllanError::TooFewSamples {
            count: t.len(),
            need: MIN_SAMPLES,
        });
    }
    dt.sort_by(f64::total_cmp);
    let tau0 = dt[dt.len() / 2];
    if !(tau0.is_finite() && tau0 > 0.0) {
        return Err(AllanError::BadPeriod(tau0));
    }
    Ok(tau0)
}

/// Curves and noise terms of the six IMU channels, sampled at `t` (assumed
/// evenly spaced; the median interval is taken as τ0).
pub fn imu_allan(t: &[f64], z: &[[f64; 6]]) -> Result<(f64, Vec<ChannelAllan>), AllanError> {
    let tau0 = sample_period(t)?;
    let mut out = Vec::with_capacity(6);
    for (c, name) in IMU_COLUMNS.iter().enumerate() {
        let y: Vec<f64> = z.iter().map(|v| v[c]).collect();
        let curve = allan_deviation(&y, tau0)?;
        out.push(ChannelAllan {
            name: name.to_string(),
            terms: noise_terms(&curve),
            curve,
        });
    }
    Ok((tau0, out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn normals(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    #[test]
    fn white_noise_follows_n_over_root_tau() {
        // density N = 0.02 unit/√Hz at 100 Hz: σ per sample N·√100
        let (rate, density): (f64, f64) = (100.0, 0.02);
        let y: Vec<f64> = normals(200_000, 1)
            .iter()
            .map(|z| 5.0 + density * rate.sqrt() * z)
            .collect();
        let curve = allan_deviation(&y, 1.0 / rate).unwrap();
        assert_eq!(curve[0].tau, 0.01);
        assert!(curve.last().unwrap().m * 9 <= y.len());
        for p in &curve {
            let expected = density / p.tau.sqrt();
            // relative standard error of the overlapping estimate ≈ 0.8/√(N/m)
            let tol = 4.0 * 0.8 / ((y.len() / p.m) as f64).sqrt();
            assert!(
                (p.adev / expected - 1.0).abs() < tol.max(0.01),
                "τ = {}: {} vs {}",
                p.tau,
                p.adev,
                expected
            );
        }
        let terms = noise_terms(&curve);
        eprintln!("white: {terms:?}, true N {density}");
        assert!(
            (terms.density / density - 1.0).abs() < 0.02,
            "{terms:?} vs {density}"
        );
        assert!(terms.density_points >= curve.len() - 3, "{terms:?}");
    }

    #[test]
    fn random_walk_gives_the_plus_half_slope_and_the_floor() {
        // σ²(τ) = N²/τ + K²τ/3 (IEEE 952 table C.1), minimum 2NK/√3 at τ = √3·N/K
        let (rate, density, k) = (50.0, 0.01, 0.002);
        let tau0: f64 = 1.0 / rate;
        let (w, v) = (normals(400_000, 2), normals(400_000, 3));
        let mut bias = 0.0;
        let y: Vec<f64> = w
            .iter()
            .zip(&v)
            .map(|(w, v)| {
                bias += k * tau0.sqrt() * v;
                density / tau0.sqrt() * w + bias
            })
            .collect();
        let curve = allan_deviation(&y, tau0).unwrap();
        for p in &curve {
            let expected = (density * density / p.tau + k * k * p.tau / 3.0).sqrt();
            let tol = 5.0 / ((y.len() / p.m) as f64).sqrt();
            assert!(
                (p.adev / expected - 1.0).abs() < tol.max(0.02),
                "τ = {}: {} vs {}",
                p.tau,
                p.adev,
                expected
            );
        }
        // the last octaves rise as √τ
        let n = curve.len();
        let (a, b) = (curve[n - 4], curve[n - 1]);
        let slope = (b.adev / a.adev).ln() / (b.tau / a.tau).ln();
        assert!((slope - 0.5).abs() < 0.12, "slope {slope}");
        let terms = noise_terms(&curve);
        let k_est = rate_random_walk(&curve, terms.density).expect("the curve rises");
        eprintln!(
            "white + random walk: {terms:?}, true N {density}, slope {slope}, K {k_est} (true {k})"
        );
        assert!((k_est / k - 1.0).abs() < 0.15, "K {k_est} vs {k}");
        // White noise alone: no rising part, no K.
        let white: Vec<f64> = w.iter().map(|w| density / tau0.sqrt() * w).collect();
        let flat = allan_deviation(&white, tau0).unwrap();
        assert_eq!(rate_random_walk(&flat, noise_terms(&flat).density), None);
        // The CSV robimu allan writes reads back to the same curve and terms.
        let mut csv = String::from("tau,ax,ay,az,gx,gy,gz\n");
        for p in &curve {
            csv.push_str(&format!("{}{}\n", p.tau, format!(",{}", p.adev).repeat(6)));
        }
        let back = curves_from_csv(&csv).unwrap();
        assert_eq!(back[5].curve, curve);
        assert_eq!(back[5].terms, terms);
        assert!(curves_from_csv("tau,ax\n1,2\n")
            .unwrap_err()
            .contains("header"));
        assert!(
            (terms.density / density - 1.0).abs() < 0.03,
            "{terms:?} vs {density}"
        );
        // the floor: octave sampling can miss the true minimum by a little
        let floor = (2.0 * density * k / 3f64.sqrt()).sqrt();
        let found = terms.bias_instability * 0.664;
        eprintln!("floor {found} vs {floor}");
        assert!(
            found >= floor * 0.97 && found < floor * 1.12,
            "{found} vs {floor}"
        );
    }

    #[test]
    fn bad_input_is_refused() {
        assert_eq!(
            allan_deviation(&[1.0; 10], 0.01).unwrap_err(),
            AllanError::TooFewSamples {
                count: 10,
                need: MIN_SAMPLES
            }
        );
        assert!(matches!(
            allan_deviation(&[1.0; 100], 0.0),
            Err(AllanError::BadPeriod(_))
        ));
        let mut y = vec![1.0; 100];
        y[4] = f64::INFINITY;
        assert_eq!(allan_deviation(&y, 0.01), Err(AllanError::NotFinite(5)));
        assert!(matches!(
            sample_period(&[1.0; 30]),
            Err(AllanError::BadPeriod(_))
        ));
    }
}
