//! Tests of the noise identification against independent references.

use super::*;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// An exact sample of the stationary AR process `ar` (n samples): draw
/// e_t ~ N(0, 1) and invert the whitening, u_t = Σ a_k u_{t−k} + e_t/scale.
fn sample(ar: &ArNoise, n: usize, seed: u64) -> Vec<f64> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(n);
    for t in 0..n {
        let (a, scale) = ar.whitening(t);
        let e: f64 = StandardNormal.sample(&mut rng);
        let pred: f64 = a.iter().enumerate().map(|(k, ak)| ak * u[t - k - 1]).sum();
        u.push(pred + e / scale);
    }
    u
}

fn times(n: usize, dt: f64) -> Vec<f64> {
    (0..n).map(|i| i as f64 * dt).collect()
}

/// Yule–Walker from the sample autocovariances (solved by Gaussian elimination).
fn yule_walker(u: &[f64], p: usize) -> Vec<f64> {
    let n = u.len();
    let m = u.iter().sum::<f64>() / n as f64;
    let g: Vec<f64> = (0..=p)
        .map(|k| (k..n).map(|i| (u[i] - m) * (u[i - k] - m)).sum::<f64>() / n as f64)
        .collect();
    let mut a: Vec<Vec<f64>> = (0..p)
        .map(|i| {
            let mut row: Vec<f64> = (0..p).map(|j| g[i.abs_diff(j)]).collect();
            row.push(g[i + 1]);
            row
        })
        .collect();
    for c in 0..p {
        for r in c + 1..p {
            let f = a[r][c] / a[c][c];
            for k in c..=p {
                a[r][k] -= f * a[c][k];
            }
        }
    }
    let mut x = vec![0.0; p];
    for r in (0..p).rev() {
        let s: f64 = (r + 1..p).map(|k| a[r][k] * x[k]).sum();
        x[r] = (a[r][p] - s) / a[r][r];
    }
    x
}

#[test]
fn burg_recovers_ar1_and_bic_picks_order_one() {
    let phi = 0.8;
    let n = 4000;
    let ar = ArNoise::new(vec![phi], 0.3).unwrap();
    let se = ((1.0 - phi * phi) / n as f64).sqrt();
    let (mut right, mut worst) = (0, 0.0_f64);
    for seed in 0..24 {
        let u = sample(&ar, n, seed);
        let id = identify_channel("ax", &times(n, 0.01), &u, None, &IdOptions::default()).unwrap();
        if id.order == 1 {
            right += 1;
            let z = (id.phi[0] - phi) / se;
            worst = worst.max(z.abs());
            assert!(z.abs() < 4.0, "seed {seed}: φ̂ = {} (z = {z})", id.phi[0]);
            assert!((id.phi_std_error[0] / se - 1.0).abs() < 0.1);
        }
        assert!(
            (id.sigma / 0.3 - 1.0).abs() < 0.15,
            "seed {seed}: σ = {}",
            id.sigma
        );
        assert!(id.ljung_box_p < 1e-6 && id.ljung_box_whitened_p > 1e-4);
    }
    eprintln!("AR(1): order 1 in {right}/24 seeds, worst |z| = {worst:.2}");
    assert!(right >= 20, "order 1 in {right}/24 seeds");
}

#[test]
fn burg_recovers_ar2_and_bic_picks_order_two() {
    let phi = [1.2, -0.5];
    let n = 4000;
    let ar = ArNoise::new(phi.to_vec(), 0.02).unwrap();
    let se = phi_std_errors(&ar, n);
    let mut right = 0;
    let mut worst = 0.0_f64;
    for seed in 100..124 {
        let u = sample(&ar, n, seed);
        let id = identify_channel("gz", &times(n, 0.01), &u, None, &IdOptions::default()).unwrap();
        if id.order == 2 {
            right += 1;
            for k in 0..2 {
                let z = (id.phi[k] - phi[k]) / se[k];
                worst = worst.max(z.abs());
                assert!(z.abs() < 4.0, "seed {seed}: φ̂ = {:?}", id.phi);
            }
        }
    }
    eprintln!("AR(2): order 2 in {right}/24 seeds, worst |z| = {worst:.2}");
    assert!(right >= 20, "order 2 in {right}/24 seeds");
    // the asymptotic standard errors of AR(2): Var φ̂_1 = Var φ̂_2 = (1 − φ_2²)/N
    let want = ((1.0 - phi[1] * phi[1]) / n as f64).sqrt();
    assert!(
        (se[0] - want).abs() < 1e-9 && (se[1] - want).abs() < 1e-9,
        "{se:?}"
    );
}

#[test]
fn burg_agrees_with_yule_walker_on_long_sequences() {
    for (phi, seed) in [
        (vec![0.8], 1),
        (vec![1.2, -0.5], 2),
        (vec![0.5, 0.2, -0.3], 3),
    ] {
        let ar = ArNoise::new(phi.clone(), 1.0).unwrap();
        let u = sample(&ar, 100_000, seed);
        let b = burg(&[&u], phi.len());
        let got = b.phi(phi.len());
        let yw = yule_walker(&u, phi.len());
        for k in 0..phi.len() {
            assert!(
                (got[k] - yw[k]).abs() < 1e-2,
                "{phi:?}: Burg {got:?} vs Yule–Walker {yw:?}"
            );
        }
    }
}

#[test]
fn white_noise_is_order_zero_with_uniform_ljung_box() {
    let ar = ArNoise::white(0.5).unwrap();
    let n = 3000;
    let (mut zero, mut small) = (0, 0);
    let mut ps = Vec::new();
    for seed in 200..250 {
        let u = sample(&ar, n, seed);
        let id = identify_channel("gx", &times(n, 0.01), &u, None, &IdOptions::default()).unwrap();
        zero += usize::from(id.order == 0);
        small += usize::from(id.ljung_box_p < 0.01);
        ps.push(id.ljung_box_p);
        if id.order == 0 {
            assert_eq!(id.correlation_time_s, 0.0);
            assert_eq!(id.sigma_understatement, 1.0);
            assert!(id.noise.is_white());
        }
    }
    let below_half = ps.iter().filter(|&&p| p < 0.5).count();
    eprintln!("white: order 0 in {zero}/50, LB p < 0.01 in {small}/50, p < 0.5 in {below_half}/50");
    assert!(zero >= 45, "order 0 in {zero}/50");
    assert!(small <= 2, "p < 0.01 in {small}/50");
    assert!(
        (15..=35).contains(&below_half),
        "p < 0.5 in {below_half}/50"
    );
}

#[test]
fn motion_gain_is_found_only_where_present() {
    let n = 20_000;
    let t = times(n, 0.01);
    // ‖q̈‖² swinging between 0 and 4 (rad/s²)²
    let x: Vec<f64> = t.iter().map(|&t| 4.0 * (0.3 * t).sin().powi(2)).collect();
    let sigma = 0.05_f64;
    let c = 2.0 * sigma * sigma / 4.0; // σ² doubles at the peak
    let ar = ArNoise::new(vec![0.6], sigma).unwrap();
    let noise = ChannelNoise::new(ar.clone(), c).unwrap();
    let mut worst = 0.0_f64;
    for seed in 300..305 {
        let u = sample(&ar, n, seed);
        let r: Vec<f64> = u.iter().zip(&x).map(|(u, &x)| u * noise.level(x)).collect();
        let id = identify_channel("az", &t, &r, Some(&x), &IdOptions::default()).unwrap();
        let rel = id.motion / c - 1.0;
        worst = worst.max(rel.abs());
        assert!(
            rel.abs() < 0.2,
            "seed {seed}: c = {} vs {c} (t = {})",
            id.motion,
            id.motion_t
        );
        assert!((id.sigma / sigma - 1.0).abs() < 0.05, "σ = {}", id.sigma);
        assert_eq!(id.order, 1);
        assert!((id.phi[0] - 0.6).abs() < 0.03);
        // without a motion-dependent level, c = 0
        let id = identify_channel("az", &t, &u, Some(&x), &IdOptions::default()).unwrap();
        assert_eq!(id.motion, 0.0, "t = {}", id.motion_t);
    }
    eprintln!("motion: worst relative error of c {:.1} %", 100.0 * worst);
}

#[test]
fn gaps_split_segments_and_agree_with_one_segment() {
    let ar = ArNoise::new(vec![0.9], 1.0).unwrap();
    let n = 20_000;
    let dt = 0.01;
    // one long segment …
    let u = sample(&ar, n, 7);
    let one = identify_channel("ax", &times(n, dt), &u, None, &IdOptions::default()).unwrap();
    // … and two independent halves of the same process with a gap between
    let a = sample(&ar, n / 2, 8);
    let b = sample(&ar, n / 2, 9);
    let mut t = times(n / 2, dt);
    t.extend(times(n / 2, dt).iter().map(|v| v + 150.0));
    let r: Vec<f64> = a.iter().chain(&b).copied().collect();
    let two = identify_channel("ax", &t, &r, None, &IdOptions::default()).unwrap();
    assert_eq!((one.segments, two.segments), (1, 2));
    assert_eq!(two.order, 1);
    let se = ((1.0 - 0.81) / n as f64).sqrt();
    assert!(
        (one.phi[0] - two.phi[0]).abs() < 4.0 * se,
        "{} vs {}",
        one.phi[0],
        two.phi[0]
    );
    assert!((two.phi[0] - 0.9).abs() < 3.0 * se);
    assert!((two.dt - dt).abs() < 1e-12);
    assert_eq!(segments(&[0.0, 1.0, 2.0, 5.0, 6.0], 1.5), vec![0..3, 3..5]);
}

#[test]
fn too_short_and_bad_input_are_refused() {
    let o = IdOptions::default();
    let e = identify_channel("gy", &times(19, 0.01), &[0.1; 19], None, &o).unwrap_err();
    assert!(matches!(e, NoiseIdError::TooShort { count: 19, .. }), "{e}");
    assert!(e.to_string().contains("gy: 19 residuals"), "{e}");
    let mut r = vec![0.1; 40];
    r[3] = f64::NAN;
    let e = identify_channel("gy", &times(40, 0.01), &r, None, &o).unwrap_err();
    assert!(e.to_string().contains("sample 4"), "{e}");
    let e = identify_channel("gy", &times(40, 0.01), &[1.0; 40], None, &o).unwrap_err();
    assert!(e.to_string().contains("zero"), "{e}");
    let e = identify_channel("gy", &times(40, 0.01), &[1.0; 39], None, &o).unwrap_err();
    assert!(e.to_string().contains("40 times"), "{e}");
}

#[test]
fn six_channels_and_the_bonferroni_rule() {
    let n = 3000;
    let t = times(n, 0.01);
    let models = [
        ArNoise::new(vec![0.7], 0.1).unwrap(),
        ArNoise::white(0.1).unwrap(),
        ArNoise::white(0.1).unwrap(),
        ArNoise::white(0.01).unwrap(),
        ArNoise::new(vec![0.5, 0.2], 0.01).unwrap(),
        ArNoise::white(0.01).unwrap(),
    ];
    let cols: Vec<Vec<f64>> = models
        .iter()
        .enumerate()
        .map(|(c, m)| sample(m, n, 400 + c as u64))
        .collect();
    let r: Vec<[f64; 6]> = (0..n)
        .map(|i| std::array::from_fn(|c| cols[c][i]))
        .collect();
    let id = identify(&t, &r, None, &IdOptions::default()).unwrap();
    assert_eq!(id.white, [false, true, true, true, false, true]);
    assert_eq!(id.model.imu[0].ar.order(), 1);
    assert_eq!(id.channels[4].order, 2);
    assert!(id.model.imu[1].is_white());
    assert_eq!(
        white_by_bonferroni(&[0.004, 0.0016, 0.5], 0.01),
        vec![true, false, true]
    );
}

/// Burg's recursion as plain index loops over every segment (the former
/// code, kept as the reference): the slice loops give the same numbers,
/// bit for bit, with segments shorter than the order among them.
#[test]
fn burg_equals_the_plain_recursion() {
    fn plain(segments: &[&[f64]], max_order: usize) -> Burg {
        let samples: usize = segments.iter().map(|s| s.len()).sum();
        let mut f: Vec<Vec<f64>> = segments.iter().map(|s| s.to_vec()).collect();
        let mut b = f.clone();
        let ss: f64 = f.iter().flatten().map(|v| v * v).sum();
        let mut v = vec![ss / samples.max(1) as f64];
        let mut reflection = Vec::new();
        for m in 1..=max_order {
            let (mut num, mut den) = (0.0, 0.0);
            for (fs, bs) in f.iter().zip(&b) {
                for t in m..fs.len() {
                    num += fs[t] * bs[t - 1];
                    den += fs[t] * fs[t] + bs[t - 1] * bs[t - 1];
                }
            }
            let k = if den > 0.0 { 2.0 * num / den } else { 0.0 };
            for (fs, bs) in f.iter_mut().zip(b.iter_mut()) {
                for t in (m..fs.len()).rev() {
                    let (ft, bt) = (fs[t], bs[t - 1]);
                    fs[t] = ft - k * bt;
                    bs[t] = bt - k * ft;
                }
            }
            reflection.push(k);
            v.push(v[m - 1] * (1.0 - k * k));
        }
        Burg {
            reflection,
            error_variance: v,
            samples,
        }
    }
    let ar = ArNoise::new(vec![0.6, -0.2], 1.0).unwrap();
    let u = sample(&ar, 3000, 5);
    let parts: Vec<&[f64]> = vec![&u[..1200], &u[1200..1203], &u[1203..1204], &u[1204..]];
    for max_order in [0, 1, 3, 8] {
        assert_eq!(burg(&parts, max_order), plain(&parts, max_order));
        assert_eq!(burg(&parts[..1], max_order), plain(&parts[..1], max_order));
    }
}

/// The whitening with the full-order predictor hoisted equals the
/// per-sample [`ArNoise::whitening`] formula, bit for bit, on segments
/// shorter and longer than the order.
#[test]
fn whiten_equals_the_per_sample_formula() {
    for phi in [vec![], vec![0.7], vec![0.5, 0.2, -0.1]] {
        let ar = ArNoise::new(phi, 2.0).unwrap();
        let u = sample(&ar, 500, 9);
        let segs = [0..2, 2..3, 3..300, 300..500];
        let mut want = Vec::new();
        for s in &segs {
            let v = &u[s.clone()];
            for t in 0..v.len() {
                let (a, scale) = ar.whitening(t);
                let pred: f64 = a.iter().enumerate().map(|(k, ak)| ak * v[t - k - 1]).sum();
                want.push(scale * (v[t] - pred));
            }
        }
        assert_eq!(whiten(&ar, &u, &segs), want);
    }
}

/// The Ljung–Box statistic from the series centred once, four lags per
/// pass, equals the textbook sum with the mean subtracted in every term,
/// bit for bit (whole and partial blocks of lags, a series barely longer
/// than its lags).
#[test]
fn ljung_box_equals_the_direct_sum() {
    let ar = ArNoise::new(vec![0.3], 1.0).unwrap();
    let r: Vec<f64> = sample(&ar, 2000, 11).iter().map(|v| v + 0.4).collect();
    for (r, lags) in [
        (&r[..], LJUNG_BOX_LAGS),
        (&r[..], 7),
        (&r[..], 1),
        (&r[..9], 6),
    ] {
        let n = r.len();
        let m = r.iter().sum::<f64>() / n as f64;
        let c0: f64 = r.iter().map(|v| (v - m) * (v - m)).sum();
        let mut q = 0.0;
        for k in 1..=lags {
            let ck: f64 = (k..n).map(|i| (r[i] - m) * (r[i - k] - m)).sum();
            let rho = ck / c0;
            q += rho * rho / (n - k) as f64;
        }
        q *= n as f64 * (n as f64 + 2.0);
        assert_eq!(
            ljung_box(r, lags),
            (q, chi2_sf(q, lags as f64)),
            "{lags} lags"
        );
    }
}
