//! The identification from a fit's own residuals against the former one
//! from residuals predicted anew.

use super::*;
use crate::noise_id::ChannelIdentification;
use crate::simulate::{random_session, SimulateOptions};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// The identification from residuals z − h predicted at every sample with
/// [`Spline::evaluate`] and [`MeasurementModel::predict`] (the former
/// computation, kept as the reference).
fn predicted_anew(robot: &Robot, data: &Measurements, f: &Fit) -> Identification {
    let layout = ParamLayout::new(robot);
    let x = &f.x[..layout.len()];
    let model = MeasurementModel::new(robot, &layout, x).unwrap();
    let tau = x[layout.offsets().tau];
    let (mut t, mut r, mut qdd2) = (Vec::new(), Vec::new(), Vec::new());
    let mut js = JointState::default();
    for (&ti, z) in data.imu_t.iter().zip(&data.imu_z) {
        if f.trajectory.evaluate(ti + tau, &mut js).is_err() {
            continue;
        }
        let pred = model.predict(&js);
        t.push(ti);
        r.push(std::array::from_fn::<f64, 6, _>(|c| z[c] - pred[c]));
        qdd2.push(js.qdd[..robot.dof()].iter().map(|a| a * a).sum::<f64>());
    }
    identify(&t, &r, Some(&qdd2), &IdOptions::default()).unwrap()
}

fn assert_close(what: &str, a: f64, b: f64) {
    assert!(
        (a - b).abs() <= 1e-9 * a.abs().max(b.abs()),
        "{what}: {a} vs {b}"
    );
}

fn assert_same(got: &Identification, want: &Identification) {
    assert_eq!(got.white, want.white);
    for (g, w) in got.channels.iter().zip(&want.channels) {
        let c: &ChannelIdentification = w;
        let name = &c.channel;
        assert_eq!(
            (g.order, g.samples, g.segments),
            (c.order, c.samples, c.segments),
            "{name}"
        );
        for (a, b) in g.phi.iter().zip(&c.phi) {
            assert_close(name, *a, *b);
        }
        for (what, a, b) in [
            ("sigma", g.sigma, c.sigma),
            ("motion", g.motion, c.motion),
            ("motion t", g.motion_t, c.motion_t),
            ("Ljung-Box p", g.ljung_box_p, c.ljung_box_p),
            ("whitened p", g.ljung_box_whitened_p, c.ljung_box_whitened_p),
            ("dt", g.dt, c.dt),
        ] {
            assert_close(&format!("{name} {what}"), a, b);
        }
    }
}

/// A white fit's whitened residuals times σ_z, with the samples of its end
/// margins predicted again, give the identification of residuals predicted
/// anew at every sample to 1e-9 relative (AR coefficients, σ, motion gain
/// and t, p-values) and the same orders and decisions; so does the
/// identification of its calibration (predicted by span polynomials).
/// With AR(1) noise on ax, so that an order is chosen and ax is not white.
#[test]
fn fit_residuals_give_the_identification_of_predicted_ones() {
    let robot = Robot::aubo_i5();
    let sim = SimulateOptions::paper(&robot);
    let mut s = random_session(&robot, 30.0, 1.0, &sim, 4242).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut u = 0.0;
    for z in &mut s.data.imu_z {
        let e: f64 = StandardNormal.sample(&mut rng);
        u = 0.9 * u + 0.05 * e;
        z[0] += u;
    }
    let opts = CalibrateOptions::new(&robot);
    let f = fit(&FitSpec::baseline(&robot, &s.data), &opts, |_| {}).unwrap();
    assert!(f.noise.is_white() && f.residuals.len() < s.data.imu_t.len());
    let want = predicted_anew(&robot, &s.data, &f);
    assert!(
        !want.white[0] && want.channels[0].order >= 1,
        "ax correlated"
    );
    let got = fit_identifications(&robot, &s.data, &f, &IdOptions::default()).unwrap()[0].clone();
    assert_same(&got, &want);
    let cal = calibration_of(&robot, &opts, &f).unwrap();
    let again = residual_identification(&robot, &s.data, &cal, &IdOptions::default()).unwrap();
    assert_same(&again, &want);
}

/// Two IMUs whose noise differs (docs/model.md §9): IMU 0 white at σ_z,
/// IMU 1's accelerometer AR(1) φ = 0.9 at 1.5 σ_z and its gyroscope white
/// at 0.7 σ_z. `Auto` identifies each IMU's noise from its own residuals
/// and whitens each by its own: IMU 0 keeps the white model of σ_z (its
/// residuals pass the test; the σ identified from them are the truth's
/// within 10 %), IMU 1 gets AR(1) with φ within 0.05 of 0.9 on the
/// accelerometer, white on the gyroscope, every σ within 15 % of the
/// truth's; IMU 1's whitened residual RMS is about 1.
#[test]
fn each_imu_gets_its_own_identified_noise() {
    let robot = Robot::aubo_i5();
    let sz = robot.sigma_z();
    let sz1: [f64; 6] = std::array::from_fn(|c| sz[c] * if c < 3 { 1.5 } else { 0.7 });
    let truth1 = NoiseModel::ar1(sz1, [Some(0.9), None], [0.0; 2]).unwrap();
    let mut sim = SimulateOptions::paper(&robot);
    sim.imu_noise = vec![NoiseModel::white(sz).unwrap(), truth1.clone()];
    let s = crate::simulate::random_session_imus(&robot, 2, 60.0, 1.0, &sim, 4100).unwrap();
    let opts = CalibrateOptions::new(&robot);
    let (cal, outcome) =
        calibrate_with_noise(&robot, &s.data, &opts, &NoiseChoice::Auto, |_| {}).unwrap();
    assert!(outcome.warning.is_none(), "{:?}", outcome.warning);
    assert!(outcome.refits >= 1);
    // IMU 0: white, its own test passed, σ identified near the truth
    assert!(cal.noise_model.is_white());
    assert_eq!(cal.noise_model.sigma_z(), sz);
    let id0 = outcome.white_test.as_ref().unwrap();
    assert!(id0.white.iter().all(|&w| w), "{:?}", id0.white);
    for c in 0..6 {
        let r = id0.model.imu[c].ar.sigma() / sz[c];
        assert!((r - 1.0).abs() < 0.1, "IMU 0 channel {c}: σ ratio {r:.3}");
    }
    // IMU 1: its own model, identified from its own residuals
    assert_eq!(cal.extra_noise_models.len(), 1);
    let m1 = &cal.extra_noise_models[0];
    assert_eq!(outcome.extra_white_tests.len(), 1);
    assert!(!outcome.extra_white_tests[0].white[..3].iter().any(|&w| w));
    for c in 0..6 {
        let ch = &m1.imu[c];
        let r = ch.ar.sigma() / sz1[c];
        eprintln!("IMU 1 channel {c}: φ {:?}, σ/truth {r:.3}", ch.ar.phi());
        assert!((r - 1.0).abs() < 0.15, "IMU 1 channel {c}: σ ratio {r:.3}");
        assert_eq!(ch.motion, 0.0);
        if c < 3 {
            assert_eq!(ch.ar.order(), 1, "channel {c}");
            assert!((ch.ar.phi()[0] - 0.9).abs() < 0.05, "channel {c}");
        } else {
            assert!(ch.ar.is_white(), "channel {c}: {:?}", ch.ar.phi());
        }
    }
    // the fit whitened IMU 1 by it: RMS about 1 over both IMUs
    for (c, r) in cal.residual_rms.iter().enumerate() {
        assert!((r - 1.0).abs() < 0.1, "channel {c}: whitened RMS {r:.3}");
    }
}
