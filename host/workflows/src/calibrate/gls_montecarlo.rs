//! Monte Carlo: accelerometer noise AR(1) with a correlation time of 30 ms.
//! The GLS fit given the true noise model is consistent (average NEES in
//! its 95 % χ² interval); the white fit on the same data is not.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use robimu_model::noise::{ArNoise, NoiseModel};
use robimu_model::Robot;

use super::fit::{fit, FitSpec};
use super::CalibrateOptions;
use crate::simulate::{random_session, SimulateOptions};

/// A stationary AR sample path of `len` samples, exactly: e_t ~ N(0, 1)
/// through the inverse of the whitening, u_t = Σ a_k u_{t−k} + e_t / scale.
fn ar_path(ar: &ArNoise, len: usize, rng: &mut rand::rngs::StdRng) -> Vec<f64> {
    let mut u = Vec::with_capacity(len);
    for t in 0..len {
        let (a, scale) = ar.whitening(t);
        let e: f64 = StandardNormal.sample(rng);
        let mut v = e / scale;
        for (k, ak) in a.iter().enumerate() {
            v += ak * u[t - k - 1];
        }
        u.push(v);
    }
    u
}

/// (average NEES of the GLS fits, of the white fits, number of parameters,
/// per fit kind the range of std(error/σ) over the parameters).
fn run(runs: u64) -> (f64, f64, usize, [(f64, f64); 2]) {
    let robot = Robot::aubo_i5();
    let sz = robot.sigma_z();
    let rate: f64 = 120.0;
    let phi = (-1.0 / (rate * 0.030)).exp();
    let model = NoiseModel::ar1(sz, [Some(phi), None], [0.0; 2]).unwrap();
    let mut sim = SimulateOptions::paper(&robot);
    // the simulator's white accelerometer noise off (negligible), the AR
    // noise added below; gyroscope and joint noise as usual
    for s in &mut sim.sigma_z[..3] {
        *s *= 1e-6;
    }
    let white_opts = CalibrateOptions::new(&robot);
    let mut gls_opts = white_opts.clone();
    gls_opts.noise = Some(model.clone());
    let (mut nees_gls, mut nees_white, mut dim) = (0.0, 0.0, 0);
    let mut z2: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for seed in 0..runs {
        let mut s = random_session(&robot, 60.0, 1.0, &sim, 9000 + seed).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(77 + seed);
        for c in 0..3 {
            let u = ar_path(&model.imu[c].ar, s.data.imu_z.len(), &mut rng);
            for (z, v) in s.data.imu_z.iter_mut().zip(u) {
                z[c] += v;
            }
        }
        let spec = FitSpec::baseline(&robot, &s.data);
        for (kind, (opts, acc)) in [(&gls_opts, &mut nees_gls), (&white_opts, &mut nees_white)]
            .into_iter()
            .enumerate()
        {
            let f = fit(&spec, opts, |_| {}).unwrap();
            let e: Vec<f64> = f.active.iter().map(|&k| f.x[k] - s.truth[k]).collect();
            z2[kind].resize(e.len(), 0.0);
            for (a, &k) in f.active.iter().enumerate() {
                z2[kind][a] += (e[a] / f.sigma_x[k]).powi(2) / runs as f64;
            }
            let info = &f.information;
            let mut q = 0.0;
            for i in 0..e.len() {
                for j in 0..e.len() {
                    q += e[i] * info[(i, j)] * e[j];
                }
            }
            *acc += q / runs as f64;
            dim = e.len();
        }
    }
    let range = |v: &[f64]| {
        v.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &m| {
            (lo.min(m.sqrt()), hi.max(m.sqrt()))
        })
    };
    (nees_gls, nees_white, dim, [range(&z2[0]), range(&z2[1])])
}

#[test]
fn calibrate_gls_is_consistent_under_ar1_accelerometer_noise() {
    let runs = std::env::var("GLS_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30);
    let (gls, white, dim, spread) = run(runs);
    // average NEES ~ χ²(runs·dim)/runs: 95 % interval dim ± 1.96·sqrt(2·dim/runs)
    let half = 1.96 * (2.0 * dim as f64 / runs as f64).sqrt();
    eprintln!("NEES over {runs} runs, {dim} parameters: GLS {gls:.2}, white {white:.2}, interval {:.2}..{:.2}; rms(error/σ) per parameter: GLS {:.2?}, white {:.2?}", dim as f64 - half, dim as f64 + half, spread[0], spread[1]);
    assert!(
        (gls - dim as f64).abs() <= half,
        "GLS NEES {gls} vs {dim} ± {half}"
    );
    assert!(
        white > dim as f64 + 3.0 * half,
        "white NEES {white} should be well above {dim} + {half}"
    );
}
