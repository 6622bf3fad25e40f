//! Monte Carlo of the sandwich the widened covariance comes from
//! ([`crate::calibrate::sandwich_fit`], [`super::covariance_kind`]) on 40 s sessions fitted by GLS
//! with their true noise (AR(1) accelerometer noise of 50 ms) and the
//! `sensor_delay` effect: with an adequate model the sandwich σ are the
//! model's A⁻¹ σ (a little below: never widened); with a misfit that follows the motion (a term in ω_y ω_z
//! added to gz and to ax, which no parameter of the model makes) A⁻¹'s σ
//! understate the spread of the estimates over the runs, the sandwich's
//! cover it.

use robimu_model::effects::resonance::Mode;
use robimu_model::{JointState, Robot};

use crate::calibrate::fit::{fit, FitSpec, Start};
use crate::calibrate::sandwich_fit::fit_sandwich;
use crate::calibrate::sandwich_montecarlo::{ar1_accel_noise, median, ratios};
use crate::calibrate::CalibrateOptions;
use crate::diagnose::{effect_set, setup_with};
use crate::simulate::{random_session, SimulateOptions};

/// Per run and active parameter: the error, the model's σ and the
/// sandwich σ.
struct Runs {
    err: Vec<Vec<f64>>,
    s_model: Vec<Vec<f64>>,
    s_sandwich: Vec<Vec<f64>>,
}

/// `runs` sessions, `misfit` the size of the added term in σ per (rad/s)²
/// (0: none).
fn run(runs: u64, misfit: f64) -> Runs {
    let robot = Robot::aubo_i5();
    let sz = robot.sigma_z();
    let model = ar1_accel_noise(&robot);
    let sim = SimulateOptions {
        noise_model: Some(model.clone()),
        ..SimulateOptions::paper(&robot)
    };
    let opts = CalibrateOptions {
        noise: Some(model),
        ..CalibrateOptions::new(&robot)
    };
    let mut out = Runs {
        err: Vec::new(),
        s_model: Vec::new(),
        s_sandwich: Vec::new(),
    };
    for seed in 0..runs {
        let mut s = random_session(&robot, 40.0, 1.0, &sim, 7300 + seed).unwrap();
        if misfit != 0.0 {
            // gz += m σ_gz ω_y ω_z /(1 rad/s)², ax += m σ_ax (the same)
            let mut js = JointState::default();
            for (t, z) in s.data.imu_t.iter().zip(s.data.imu_z.iter_mut()) {
                s.trajectory.evaluate_clamped(*t, &mut js);
                let w = js.qd[1] * js.qd[2];
                z[5] += misfit * sz[5] * w;
                z[0] += misfit * sz[0] * w;
            }
        }
        let setup = setup_with(&robot, &s.data, None, Mode::default());
        let set = effect_set(&setup, &["sensor_delay".to_string()]).unwrap();
        let spec = FitSpec {
            effects: &set,
            start: Start::Nominal,
            ..FitSpec::baseline(&robot, &s.data)
        };
        let f = fit(&spec, &opts, |_| {}).unwrap();
        let sw = fit_sandwich(&robot, &s.data, &opts, &set, &f, 2.0, 0).unwrap();
        let pick = |v: &[f64]| -> Vec<f64> { f.active.iter().map(|&k| v[k]).collect() };
        out.err
            .push(f.active.iter().map(|&k| f.x[k] - s.truth[k]).collect());
        out.s_model.push(pick(&f.sigma_x));
        out.s_sandwich.push(pick(&sw.sigma));
    }
    out
}

fn range(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)))
}

#[test]
fn with_an_adequate_model_the_sandwich_is_the_models_covariance() {
    let r = run(6, 0.0);
    // mean over the runs of sandwich σ / model σ, per parameter
    let dim = r.err[0].len();
    let q: Vec<f64> = (0..dim)
        .map(|k| {
            r.s_sandwich
                .iter()
                .zip(&r.s_model)
                .map(|(a, b)| a[k] / b[k])
                .sum::<f64>()
                / r.err.len() as f64
        })
        .collect();
    let (lo, hi) = range(&q);
    eprintln!(
        "sandwich σ / model σ: median {:.3}, range {lo:.3}..{hi:.3}",
        median(&q)
    );
    // the windows' scores at the estimate lose the leverage of each window
    // (20 of 2 s here): biased low by about that much, never high — the
    // widening max(1, ·) leaves an adequate model's σ within a few %
    assert!((0.75..=1.02).contains(&median(&q)), "median {}", median(&q));
    assert!(lo > 0.6 && hi < 1.1, "{lo}..{hi}");
}

#[test]
fn with_a_misfit_that_follows_the_motion_the_sandwich_covers_the_spread() {
    let r = run(16, 60.0);
    let (model, sw) = (ratios(&r.err, &r.s_model), ratios(&r.err, &r.s_sandwich));
    let dim = model.len();
    let worst = (0..dim)
        .max_by(|&a, &b| model[a].total_cmp(&model[b]))
        .unwrap();
    eprintln!(
        "rms(error)/mean(σ) over {} runs: model median {:.2} range {:.2?}, sandwich median {:.2} range {:.2?}; worst under the model: {:.2} → {:.2}",
        r.err.len(), median(&model), range(&model), median(&sw), range(&sw), model[worst], sw[worst]
    );
    assert!(
        model[worst] > 3.0,
        "the misfit is too small: {}",
        model[worst]
    );
    assert!(median(&model) > 1.3, "model median {}", median(&model));
    assert!(range(&sw).1 < 2.0, "sandwich {:?}", range(&sw));
    assert!(median(&sw) < 1.25, "sandwich median {}", median(&sw));
}
