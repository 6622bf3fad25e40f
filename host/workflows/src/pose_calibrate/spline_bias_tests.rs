//! Experiments (ignored): the pose spline's approximation of the motion
//! and τ's error with noise-free data.

use super::*;
use robimu_model::geom::{mul_mtv, sub};
use robimu_model::effects::ImuContext;
use robimu_model::PoseSpline;
use robimu_model::pose_measurement::{imu_indices, TAU};

fn env_f(k: &str, d: f64) -> f64 {
    std::env::var(k).ok().and_then(|s| s.parse().ok()).unwrap_or(d)
}
fn env_list(k: &str, d: &str) -> Vec<f64> {
    std::env::var(k)
        .unwrap_or(d.to_string())
        .split(',')
        .map(|s| s.parse().unwrap())
        .collect()
}

/// RMS of the body-rate error of `s` against `motion` over [t0, t1] (rad/s).
fn omega_rms(s: &PoseSpline, motion: &PoseSpline, t0: f64, t1: f64) -> (f64, f64) {
    let (mut sw, mut sa, mut n) = (0.0, 0.0, 0.0);
    let mut t = t0 + 0.2;
    while t < t1 - 0.2 {
        let (a, b) = (s.evaluate(t).unwrap(), motion.evaluate(t).unwrap());
        let e = sub(a.omega_n, b.omega_n);
        sw += e.iter().map(|v| v * v).sum::<f64>();
        let ea = sub(mul_mtv(&a.r, a.a), mul_mtv(&b.r, b.a));
        sa += ea.iter().map(|v| v * v).sum::<f64>();
        n += 1.0;
        t += 0.0037;
    }
    ((sw / n / 3.0).sqrt(), (sa / n / 3.0).sqrt())
}

/// S/(K − 1) of the score test of τ constant over `segs` segments of
/// IMU `imu`.
fn scatter(fit: &PoseFit, imu: usize, segs: usize) -> f64 {
    let n = fit.problem.selected_of(imu).len();
    let sums = fit
        .problem
        .extra_sums(&fit.theta, imu, segs - 1, |i, sample, cols| {
            if let Some(k) = (1..segs).rev().find(|&k| i >= n * k / segs) {
                cols[k - 1] = sample.dz_dt();
            }
        })
        .unwrap();
    let t = super::score::score_test(&sums, &vec![0.0; segs - 1], &fit.factor).unwrap();
    t.statistic / (segs - 1) as f64
}

/// [`random_pose_motion`] with its knots over a span `shift` s wider at
/// each end (so they do not nest with the fit's).
fn motion(duration: f64, seed: u64, shift: f64) -> PoseSpline {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use robimu_model::geom::{exp_so3, mul_mm, M3, V3};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let pad = super::simulate::MOTION_PAD;
    let knots = robimu_model::Knots::uniform(-pad - shift, duration + pad + shift, 0.5, 3).unwrap();
    let m = knots.num_coeffs();
    let mut nrm = |s: f64| Normal::new(0.0, s).unwrap().sample(&mut rng);
    let pos: Vec<V3> = (0..m).map(|_| std::array::from_fn(|_| nrm(0.15))).collect();
    let mut r = super::simulate::uniform_rotation(&mut rand::rngs::StdRng::seed_from_u64(seed + 7));
    let rot: Vec<M3> = (0..m)
        .map(|_| {
            let mut d: V3 = std::array::from_fn(|_| nrm(0.8));
            let n = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            if n > 2.0 {
                d = d.map(|v| v * 2.0 / n);
            }
            r = mul_mm(&r, &exp_so3(d));
            r
        })
        .collect();
    PoseSpline::new(knots, &pos, &rot).unwrap()
}

/// Noise scale EXP_NOISE (0: noise-free data, σ given, not identified),
/// knot spacings EXP_KNOTS, EXP_RUNS seeds from 100; 1 and 2 IMUs.
#[test]
#[ignore = "experiment"]
fn experiment_tau_bias() {
    let runs = env_f("EXP_RUNS", 20.0) as u64;
    let ns = env_f("EXP_NOISE", 0.0);
    let knots = env_list("EXP_KNOTS", "0.1");
    let imus = env_list("EXP_IMUS", "1,2");
    let segs = env_f("EXP_SEGS", 16.0) as usize;
    let mut noise = PoseNoise::default();
    noise.sigma_p *= ns;
    noise.sigma_r *= ns;
    noise.sigma_z = noise.sigma_z.map(|v| v * ns);
    for &h in &knots {
        for &k in &imus {
            let k = k as usize;
            let mut zs: Vec<Vec<f64>> = vec![Vec::new(); k];
            let mut om = Vec::new();
            let mut phis: Vec<Vec<f64>> = vec![Vec::new(); k];
            let (mut ms, mut sig) = (Vec::new(), Vec::new());
            for s in 100..100 + runs {
                let truth = draw_pose_imus_truth(1000 + s, 2);
                let motion = motion(60.0, 2000 + s, env_f("EXP_SHIFT", 0.0));
                let (data, more) =
                    simulate_pose_imus(&truth, 2, &motion, (15.0, 0.003), 100.0, &noise, 3000 + s)
                        .unwrap();
                let opts = PoseCalibrationOptions {
                    knot_spacing: Some(h),
                    identify_noise: ns > 0.0,
                    ..Default::default()
                };
                let (cal, fit) = match fit_poses(&data, &more[..k - 1], &opts, |_| {}, |_| {}) {
                    Ok(r) => r,
                    Err(e) => {
                        println!("  seed {s}: {e}");
                        continue;
                    }
                };
                for j in 0..k {
                    let t = imu_indices(j)[TAU];
                    zs[j].push((cal.x[t] - truth[t]) / cal.sigma[t]);
                    if j == 0 {
                        ms.push((cal.x[t] - truth[t]) * 1e3);
                        sig.push(cal.sigma[t] * 1e3);
                    }
                }
                for j in 0..k {
                    phis[j].push(scatter(&fit, j, segs));
                }
                let sp = fit.problem.spline(&fit.theta).unwrap();
                om.push(omega_rms(&sp, &motion, 0.0, 60.0));
            }
            let rms = |v: &[f64]| (v.iter().map(|a| a * a).sum::<f64>() / v.len() as f64).sqrt();
            let m = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let w: Vec<f64> = om.iter().map(|a| a.0).collect();
            let a: Vec<f64> = om.iter().map(|a| a.1).collect();
            let pl: Vec<String> = phis.iter().map(|v| format!("{:.2}", m(v))).collect();
            println!("  tau error (ms) rms {:.4} mean {:+.4}, sigma mean {:.4} ms", rms(&ms), m(&ms), m(&sig));
            println!("  mean S/(K-1) over {segs} segments: {}", pl.join(" "));
            let zl: Vec<String> = zs.iter().map(|v| format!("rms {:.2} mean {:+.2}", rms(v), m(v))).collect();
            let corr = if k == 2 {
                let c = zs[0].iter().zip(&zs[1]).map(|(a, b)| a * b).sum::<f64>()
                    / (zs[0].len() as f64 * rms(&zs[0]) * rms(&zs[1]));
                format!(" corr {c:.2}")
            } else {
                String::new()
            };
            println!(
                "h {h:.4} imus {k} noise {ns}: z_tau {}{corr}; fitted spline vs truth: omega rms {:.4} deg/s, s rms {:.4} m/s2",
                zl.join(" | "),
                m(&w).to_degrees(),
                m(&a)
            );
        }
    }
}

/// The best approximation of the motion by a pose spline with knots every
/// h: fitted to the noise-free poses at EXP_RATE Hz.
#[test]
#[ignore = "experiment"]
fn experiment_best_approximation() {
    let knots = env_list("EXP_KNOTS", "0.1,0.08,0.0667,0.05");
    let rate = env_f("EXP_RATE", 200.0);
    for &h in &knots {
        let mut om = Vec::new();
        for s in 100..105 {
            let motion = random_pose_motion(60.0, 2000 + s).unwrap();
            let n = (60.0 * rate) as usize;
            let t: Vec<f64> = (0..=n).map(|i| i as f64 / rate).collect();
            let st: Vec<_> = t.iter().map(|&u| motion.evaluate(u).unwrap()).collect();
            let p: Vec<[f64; 3]> = st.iter().map(|x| x.p).collect();
            let q: Vec<[f64; 4]> = st
                .iter()
                .map(|x| robimu_model::geom::quat_from_matrix(&x.r))
                .collect();
            let sp = PoseSpline::fit(&t, &p, &q, h).unwrap();
            om.push(omega_rms(&sp, &motion, 0.0, 60.0));
        }
        let m = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let w: Vec<f64> = om.iter().map(|a| a.0.to_degrees()).collect();
        let a: Vec<f64> = om.iter().map(|a| a.1).collect();
        println!("h {h:.4}: best approx omega rms {:.4} deg/s, s rms {:.4} m/s2", m(&w), m(&a));
    }
}
