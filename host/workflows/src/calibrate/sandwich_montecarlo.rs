//! Monte Carlo: accelerometer noise AR(1) of 50 ms, 60 s sessions. The
//! white fit's sandwich σ ([`super::sandwich`]) and the σ of `Auto` (the
//! GLS fit with the noise identified from the residuals) both match the
//! spread of their estimators over the runs; the GLS σ are the smaller
//! (the prewhitened estimate uses the information better); the white fit's
//! own σ are too small.

use robimu_model::noise::NoiseModel;
use robimu_model::{ParamLayout, Robot};

use super::fit::{fit, FitSpec};
use super::noise_choice::{calibrate_with_noise, residual_identification, NoiseChoice};
use super::sandwich::{bandwidth, sandwich};
use super::{calibration_of, CalibrateOptions};
use crate::noise_id::IdOptions;
use crate::simulate::{random_session, SimulateOptions};

/// Per run and active parameter: errors of the white and the auto fit, and
/// the white fit's own σ, its sandwich σ and the auto fit's σ.
struct Runs {
    e_white: Vec<Vec<f64>>,
    e_auto: Vec<Vec<f64>>,
    s_white: Vec<Vec<f64>>,
    s_sandwich: Vec<Vec<f64>>,
    s_auto: Vec<Vec<f64>>,
    refitted: usize,
    /// The active parameters (indices into x).
    active: Vec<usize>,
}

/// The sessions' IMU rate, Hz.
pub(crate) const RATE: f64 = 120.0;

/// The Monte Carlos' IMU noise: the accelerometer's AR(1) of 50 ms
/// correlation at [`RATE`], the gyroscope's white, σ `robot`'s.
pub(crate) fn ar1_accel_noise(robot: &Robot) -> NoiseModel {
    let phi = (-1.0f64 / (RATE * 0.050)).exp();
    NoiseModel::ar1(robot.sigma_z(), [Some(phi), None], [0.0; 2]).unwrap()
}

fn run(runs: u64) -> Runs {
    let robot = Robot::aubo_i5();
    let model = ar1_accel_noise(&robot);
    let sim = SimulateOptions {
        noise_model: Some(model),
        ..SimulateOptions::paper(&robot)
    };
    let opts = CalibrateOptions::new(&robot);
    let mut out = Runs {
        e_white: Vec::new(),
        e_auto: Vec::new(),
        s_white: Vec::new(),
        s_sandwich: Vec::new(),
        s_auto: Vec::new(),
        refitted: 0,
        active: Vec::new(),
    };
    for seed in 0..runs {
        let s = random_session(&robot, 60.0, 1.0, &sim, 5100 + seed).unwrap();
        let f = fit(&FitSpec::baseline(&robot, &s.data), &opts, |_| {}).unwrap();
        let white = calibration_of(&robot, &opts, &f).unwrap();
        let id = residual_identification(&robot, &s.data, &white, &IdOptions::default()).unwrap();
        let l = bandwidth(&id.model, 1.0 / RATE, f.residuals.len());
        let sw = sandwich(&robot, &s.data, &opts, &f, l).unwrap();
        let (auto, outcome) =
            calibrate_with_noise(&robot, &s.data, &opts, &NoiseChoice::Auto, |_| {}).unwrap();
        assert!(outcome.warning.is_none(), "{:?}", outcome.warning);
        out.refitted += usize::from(outcome.refits > 0);
        let pick = |v: &[f64]| -> Vec<f64> { f.active.iter().map(|&k| v[k]).collect() };
        let err = |x: &[f64]| -> Vec<f64> { f.active.iter().map(|&k| x[k] - s.truth[k]).collect() };
        out.e_white.push(err(&f.x));
        out.e_auto.push(err(&auto.x));
        out.s_white.push(pick(&f.sigma_x));
        out.s_sandwich.push(pick(&sw.sigma));
        out.s_auto.push(pick(&auto.sigma));
        out.active.clone_from(&f.active);
    }
    out
}

/// Per parameter: rms over the runs of the error over the mean predicted σ
/// (one row of `e` and of `s` a run).
pub(crate) fn ratios(e: &[Vec<f64>], s: &[Vec<f64>]) -> Vec<f64> {
    let n = e.len() as f64;
    (0..e[0].len())
        .map(|k| {
            let rms = (e.iter().map(|r| r[k] * r[k]).sum::<f64>() / n).sqrt();
            let mean = s.iter().map(|r| r[k]).sum::<f64>() / n;
            rms / mean
        })
        .collect()
}

/// The median (the upper one of an even count).
pub(crate) fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn sandwich_and_gls_sigma_match_the_spread_and_gls_is_more_efficient() {
    let runs = std::env::var("SANDWICH_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(24);
    let r = run(runs);
    assert_eq!(r.refitted, runs as usize, "auto refitted every run");
    let (sw, gls, naive) = (
        ratios(&r.e_white, &r.s_sandwich),
        ratios(&r.e_auto, &r.s_auto),
        ratios(&r.e_white, &r.s_white),
    );
    let range = |v: &[f64]| {
        v.iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)))
    };
    let dim = sw.len();
    // efficiency: mean GLS σ over mean sandwich σ, per parameter
    let eff: Vec<f64> = (0..dim)
        .map(|k| {
            let m = |s: &[Vec<f64>]| s.iter().map(|row| row[k]).sum::<f64>();
            m(&r.s_auto) / m(&r.s_sandwich)
        })
        .collect();
    let smaller = eff.iter().filter(|&&e| e < 1.0).count();
    eprintln!(
        "{runs} runs, {dim} parameters: rms(error)/mean(σ) median (range): sandwich {:.3} {:.2?}, GLS {:.3} {:.2?}, white's own σ {:.3} {:.2?}; GLS σ / sandwich σ median {:.3} {:.2?}, smaller for {smaller}",
        median(&sw), range(&sw), median(&gls), range(&gls), median(&naive), range(&naive),
        median(&eff), range(&eff)
    );
    for (name, v) in [("sandwich", &sw), ("GLS", &gls)] {
        let m = median(v);
        assert!((0.85..=1.15).contains(&m), "{name}: median ratio {m}");
        let (lo, hi) = range(v);
        assert!(lo > 0.55 && hi < 1.5, "{name}: ratios {lo}..{hi}");
    }
    assert!(median(&naive) > 1.3, "white σ ratio {}", median(&naive));
    // Efficiency: GLS σ below the sandwich σ for most parameters, far below
    // for those the accelerometer determines; the others (gyroscope-
    // determined, white noise there; prior-dominated lengths) are equal up
    // to the sandwich's own scatter.
    let layout = ParamLayout::new(&Robot::aubo_i5());
    let above: Vec<String> = (0..dim)
        .filter(|&k| eff[k] >= 1.0)
        .map(|k| format!("{} {:.3}", layout.specs()[r.active[k]].name, eff[k]))
        .collect();
    eprintln!("GLS σ ≥ sandwich σ: {above:?}");
    assert!(
        smaller * 4 >= dim * 3,
        "GLS σ smaller for {smaller} of {dim}"
    );
    let (lo, hi) = range(&eff);
    assert!(lo < 0.7 && hi < 1.15, "GLS / sandwich σ {lo}..{hi}");
    assert!(
        median(&eff) < 1.0,
        "GLS / sandwich σ median {}",
        median(&eff)
    );
}
