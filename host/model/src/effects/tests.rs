//! Each effect's Jacobian ∂z/∂θ_e against central differences of its exact
//! (simulator) form.

use rand::SeedableRng;

use super::*;
use crate::trajectory::random_walk;
use crate::{MeasurementJacobians, MeasurementModel, ParamLayout, Robot};

#[test]
fn effect_jacobians_match_finite_differences_of_the_exact_form() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let mut x = layout.nominal();
    for (k, s) in layout.specs().iter().enumerate() {
        x[k] += 0.3 * s.sigma * ((k as f64) * 1.7).sin();
    }
    x[layout.offsets().tau] = 0.02;
    let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let spline = random_walk(&robot, 20.0, 1.0, &mut rng).unwrap();
    let traj = trajectory_fn(&spline);
    let mut setup = CatalogueSetup::new(
        SessionSpan { t0: 0.0, t1: 20.0 },
        MassModel::for_robot(&robot),
        robot.gravity(),
        Some(&spline),
    );
    // bias_drift's spline with 4 segments of 5 s: the times below fall in
    // segments 0, 1 and 3
    setup.set_resolution("bias_drift", 4).unwrap();
    assert_eq!(by_name(&setup, "bias_drift").unwrap().params().len(), 24);
    // a warm-up read in whole degrees at 100 Hz
    let ts: Vec<f64> = (0..2001).map(|i| i as f64 * 0.01).collect();
    let temp: Vec<f64> = ts
        .iter()
        .map(|t| (30.0 - 6.0 * (-t / 8.0).exp()).round())
        .collect();
    setup.set_temperature(&ts, &temp);
    assert_eq!(catalogue(&setup).len(), NAMES.len());
    let names: Vec<_> = catalogue(&setup).iter().map(|e| e.name()).collect();
    assert_eq!(names, NAMES);
    let mut jac = MeasurementJacobians::new(layout.len());
    let mut checked = 0;
    for effect in catalogue(&setup) {
        let params = effect.params();
        let k = params.len();
        assert!(k > 0, "{}", effect.name());
        for t in [2.3, 7.7, 15.1] {
            let js = traj(t + x[layout.offsets().tau]);
            model.jacobians(&js, &mut jac);
            let ctx = SampleContext::new(t, &js, &model, &jac, &layout);
            let mut cols = vec![[0.0; 6]; k];
            effect.columns(&ctx, &mut cols);
            let ex = ExactContext {
                t,
                tau: x[layout.offsets().tau],
                model: &model,
                trajectory: &traj,
            };
            let zero = vec![0.0; k];
            let z0 = effect.exact(&ex, &zero, &layout);
            let base = ex.baseline();
            for c in 0..6 {
                assert!(
                    (z0[c] - base[c]).abs() < 1e-12,
                    "{} not zero at θ = 0",
                    effect.name()
                );
            }
            for (e, p) in params.iter().enumerate() {
                let h = 1e-4 * p.prior_sigma;
                let mut th = zero.clone();
                th[e] = h;
                let zp = effect.exact(&ex, &th, &layout);
                th[e] = -h;
                let zm = effect.exact(&ex, &th, &layout);
                let norm = cols[e].iter().map(|v| v * v).sum::<f64>().sqrt();
                for c in 0..6 {
                    let fd = (zp[c] - zm[c]) / (2.0 * h);
                    assert!(
                        (fd - cols[e][c]).abs() <= 1e-5 * norm.max(1.0),
                        "{} {} channel {c} t {t}: fd {fd} vs {}",
                        effect.name(),
                        p.name,
                        cols[e][c]
                    );
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 40);
}

#[test]
fn gravity_torque_matches_finite_differences_of_potential_energy() {
    // τ_j = −∂V/∂q_j with V = Σ m_l g0 z_l (independent formula)
    let robot = Robot::aubo_i5();
    let mass = MassModel::for_robot(&robot);
    let q = [0.3, -0.7, 1.1, 0.4, -0.9, 0.2];
    let g0 = 9.81;
    let tau = mass.gravity_torques(&q, g0);
    let energy = |q: &[f64]| -> f64 { mass.potential_energy(q, g0) };
    for j in 0..6 {
        let h = 1e-6;
        let mut qp = q;
        qp[j] += h;
        let mut qm = q;
        qm[j] -= h;
        let fd = -(energy(&qp) - energy(&qm)) / (2.0 * h);
        assert!(
            (fd - tau[j]).abs() < 1e-6 * (1.0 + fd.abs()),
            "joint {j}: {fd} vs {}",
            tau[j]
        );
    }
    assert!(
        tau[1].abs() > 1.0,
        "shoulder carries a gravity torque: {tau:?}"
    );
}

/// The allocation-free gravity torques (twist sines once per model) are
/// bit-identical to the former form: frames by [`link_transform`] in a
/// vector, then the same sums.
#[test]
fn gravity_torque_array_is_the_former_computation() {
    use crate::geom::{add, cross, dot, mul_mv, sub, Iso};
    use crate::kinematics::link_transform;
    let robot = Robot::aubo_i5();
    let mass = MassModel::for_robot(&robot);
    let coms = [[0.1, -0.02, 0.3]; 6];
    let masses = [1.0, 2.0, 3.0, 0.5, 0.25, 4.0];
    let other = MassModel::new(&robot, masses.to_vec(), coms.to_vec()).unwrap();
    for (m, com, model) in [
        (vec![5.0, 6.5, 3.0, 1.5, 1.5, 0.5], None, &mass),
        (masses.to_vec(), Some(coms), &other),
    ] {
        for k in 0..50 {
            let q: Vec<f64> = (0..6)
                .map(|j| 2.0 * ((k * 7 + j * 3) as f64 * 0.91).sin())
                .collect();
            let g0 = 9.80665;
            // the former computation
            let n = robot.dof();
            let mut frames = vec![Iso::identity()];
            for (dh, &qi) in robot.links().iter().zip(&q) {
                let f = frames[frames.len() - 1].compose(&link_transform(dh, qi));
                frames.push(f);
            }
            let com_l = |l: usize| match com {
                Some(c) => c[l],
                None => [
                    [0.0, 0.0, 0.02],
                    [-0.204, 0.0, 0.06],
                    [-0.188, 0.0, 0.01],
                    [0.0; 3],
                    [0.0; 3],
                    [0.0, 0.0, -0.02],
                ][l],
            };
            let centres: Vec<[f64; 3]> = (0..n)
                .map(|l| add(frames[l + 1].p, mul_mv(&frames[l + 1].r, com_l(l))))
                .collect();
            let want: Vec<f64> = (0..n)
                .map(|j| {
                    let axis = [frames[j].r[0][2], frames[j].r[1][2], frames[j].r[2][2]];
                    (j..n)
                        .map(|l| {
                            dot(
                                axis,
                                cross(sub(centres[l], frames[j].p), [0.0, 0.0, -g0 * m[l]]),
                            )
                        })
                        .sum()
                })
                .collect();
            let got = model.gravity_torques_array(&q, g0);
            assert_eq!(&got[..n], &want[..], "q {q:?}");
            assert!(got[n..].iter().all(|&v| v == 0.0));
            assert_eq!(model.gravity_torques(&q, g0), want);
        }
    }
}

/// Effect specs: `NAME` and `NAME:M`, M only for an effect with a
/// resolution, in range, a whole number; `spec` reads back.
#[test]
fn effect_specs_set_the_resolution_or_say_why_not() {
    let robot = Robot::aubo_i5();
    let mut setup = CatalogueSetup::new(
        SessionSpan { t0: 0.0, t1: 20.0 },
        MassModel::for_robot(&robot),
        robot.gravity(),
        None,
    );
    assert_eq!(setup.spec("bias_drift"), "bias_drift:1");
    assert_eq!(setup.apply_spec("clock_drift").unwrap(), "clock_drift");
    assert_eq!(setup.apply_spec(" bias_drift:8 ").unwrap(), "bias_drift");
    assert_eq!(setup.bias_drift_segments, 8);
    assert_eq!(setup.spec("bias_drift"), "bias_drift:8");
    assert_eq!(setup.spec("clock_drift"), "clock_drift");
    for (bad, says) in [
        ("bias_drift:0", "from 1 to"),
        ("bias_drift:x", "not a whole number"),
        ("bias_drift:1000", "from 1 to"),
        ("clock_drift:4", "has no resolution"),
        ("no_such:4", "unknown effect"),
    ] {
        let e = setup.apply_spec(bad).unwrap_err().to_string();
        assert!(e.contains(says), "{bad}: {e}");
    }
    assert_eq!(setup.bias_drift_segments, 8, "a bad spec changes nothing");
}

/// An effect a session cannot have is refused with what it needs, not as
/// unknown; a misspelt name lists the catalogue.
#[test]
fn unavailable_effects_say_what_they_need() {
    let robot = Robot::aubo_i5();
    let setup = CatalogueSetup::new(
        SessionSpan { t0: 0.0, t1: 20.0 },
        MassModel::for_robot(&robot),
        robot.gravity(),
        None,
    );
    let names: Vec<_> = catalogue(&setup).iter().map(|e| e.name()).collect();
    assert!(!names.contains(&"temperature_bias") && !names.contains(&"resonance"));
    let msg = by_name(&setup, "temperature_bias")
        .err()
        .unwrap()
        .to_string();
    assert!(
        msg.contains("not available") && msg.contains("temperature column"),
        "{msg}"
    );
    let msg = by_name(&setup, "resonance").err().unwrap().to_string();
    assert!(msg.contains("joint trajectory"), "{msg}");
    let msg = by_name(&setup, "temprature_bias")
        .err()
        .unwrap()
        .to_string();
    assert!(
        msg.contains("unknown effect") && msg.contains("g_sensitivity"),
        "{msg}"
    );
}

/// Effects with several IMUs (docs/model.md §9): labels, the candidates of
/// a two-IMU session, the owner of each, the names in an effect set, and
/// the refusals with their reason.
#[test]
fn per_sensor_effects_are_labelled_per_imu_and_shared_ones_once() {
    let robot = Robot::aubo_i5();
    let mut setup = CatalogueSetup::new(
        SessionSpan { t0: 0.0, t1: 20.0 },
        MassModel::for_robot(&robot),
        robot.gravity(),
        None,
    );
    assert_eq!(
        split_label("imu2/bias_drift"),
        Some((Some(2), "bias_drift"))
    );
    assert_eq!(split_label("bias_drift"), Some((None, "bias_drift")));
    for bad in [
        "imu0/bias_drift",
        "imu01/bias_drift",
        "imu+1/bias_drift",
        "imux/bias_drift",
    ] {
        assert_eq!(split_label(bad), None, "{bad}");
    }
    // one IMU: the catalogue itself
    let one: Vec<String> = catalogue(&setup).iter().map(|e| e.name().into()).collect();
    assert_eq!(setup.candidates(), one);
    setup.n_imus = 2;
    // IMU 1 records a warm-up, IMU 0 nothing: only IMU 1 has temperature_bias
    let ts: Vec<f64> = (0..2001).map(|i| i as f64 * 0.01).collect();
    let temp: Vec<f64> = ts
        .iter()
        .map(|t| (30.0 - 6.0 * (-t / 8.0).exp()).round())
        .collect();
    setup.set_imu_temperature(1, &ts, &temp);
    let c = setup.candidates();
    let per_imu1: Vec<&str> = c.iter().filter_map(|n| n.strip_prefix("imu1/")).collect();
    assert_eq!(
        per_imu1,
        [
            "g_sensitivity",
            "size_effect",
            "clock_drift",
            "sensor_delay",
            "bias_drift",
            "temperature_bias"
        ]
    );
    assert_eq!(c.len(), one.len() + 6);
    assert!(!c.iter().any(|n| n == "temperature_bias"));
    let (e, owner) = by_label(&setup, "imu1/temperature_bias").unwrap();
    assert_eq!((e.name(), owner), ("temperature_bias", Some(1)));
    assert_eq!(by_label(&setup, "g_sensitivity").unwrap().1, Some(0));
    assert_eq!(by_label(&setup, "encoder_scale").unwrap().1, None);
    for (bad, says) in [
        ("imu1/encoder_scale", "shared by every IMU"),
        ("imu2/g_sensitivity", "no IMU 2"),
        ("imu0/g_sensitivity", "IMU j ≥ 1"),
        ("temperature_bias", "temperature column"),
        ("imu1/g_sensitivty", "unknown effect"),
    ] {
        let msg = by_name(&setup, bad).err().unwrap().to_string();
        assert!(msg.contains(says), "{bad}: {msg}");
    }
    assert_eq!(
        setup.apply_spec("imu1/bias_drift:4").unwrap(),
        "imu1/bias_drift"
    );
    assert_eq!(setup.spec("imu1/bias_drift"), "imu1/bias_drift:4");
    // the set: labels, prefixed parameter and constant names, per-IMU maps
    let mut set = EffectSet::new();
    set.push_on(by_name(&setup, "imu1/bias_drift").unwrap(), Some(1));
    set.push(by_name(&setup, "encoder_scale").unwrap());
    set.push_on(by_name(&setup, "clock_drift").unwrap(), Some(0));
    assert_eq!(
        set.names(),
        ["imu1/bias_drift", "encoder_scale", "clock_drift"]
    );
    assert!(set.params()[..24]
        .iter()
        .all(|p| p.name.starts_with("imu1/bias_drift.")));
    assert_eq!(set.params()[24].name, "encoder_scale.kappa_1");
    assert_eq!(set.params()[30].name, "clock_drift.kappa");
    let consts: Vec<String> = set.constants().into_iter().map(|c| c.name).collect();
    assert!(
        consts.contains(&"imu1/bias_drift.t_start".to_string()),
        "{consts:?}"
    );
    assert!(
        consts.contains(&"clock_drift.t_ref".to_string()),
        "{consts:?}"
    );
    assert_eq!(set.imu_map(0), (24..31).collect::<Vec<_>>());
    assert_eq!(set.imu_map(1), (0..30).collect::<Vec<_>>());
}

/// The catalogue's arms are described by their makers' joint origins (C_i,
/// no DH part): the mass model takes the whole chain (regression: it once
/// took the DH part alone, which put every link at the base and gave a
/// UR5e no gravity torque). τ = −∂V/∂q on each, and a stretched-out UR5e
/// (q = 0: the upper arm and forearm horizontal, 0.425 + 0.3922 m) with the
/// uniform 2 kg per link carries at its shoulder the moment of the links'
/// weights about the shoulder axis: 2 kg · g0 · (0.425 + 4 · 0.8172) m.
#[test]
fn gravity_torques_of_the_catalogues_chains() {
    let g0 = 9.81;
    for name in ["ur5e", "fr3", "iiwa14"] {
        let robot = Robot::builtin(name).unwrap();
        let mass = MassModel::for_robot(&robot);
        let n = robot.dof();
        let q: Vec<f64> = (0..n).map(|j| 0.3 - 0.17 * j as f64).collect();
        let tau = mass.gravity_torques(&q, g0);
        for j in 0..n {
            let h = 1e-6;
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[j] += h;
            qm[j] -= h;
            let fd = -(mass.potential_energy(&qp, g0) - mass.potential_energy(&qm, g0)) / (2.0 * h);
            assert!(
                (fd - tau[j]).abs() < 1e-6 * (1.0 + fd.abs()),
                "{name} joint {j}: {fd} vs {}",
                tau[j]
            );
        }
        assert!(tau.iter().any(|t| t.abs() > 1.0), "{name}: {tau:?}");
    }
    let ur = MassModel::for_robot(&Robot::builtin("ur5e").unwrap());
    let tau = ur.gravity_torques(&[0.0; 6], g0);
    let expected = 2.0 * g0 * (0.425 + 4.0 * (0.425 + 0.3922));
    assert!(
        (tau[1].abs() - expected).abs() < 1e-3 * expected,
        "{} vs {expected}",
        tau[1]
    );
}
