use super::*;
use rand::{Rng, SeedableRng};
use robimu_model::params::draw_truth;
use robimu_model::robot::default_estimated_errors;
use robimu_model::{JointState, MeasurementModel};

fn fixture(name: &str) -> String {
    format!(
        "{}/../cli/tests/fixtures/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// The AUBO i5 (plain DH), the UR5 (DH, other signs and offsets) and the
/// AUBO i5 from its URDF (fixed transforms C_i, all errors estimated).
fn robots() -> Vec<Robot> {
    let ur5 = Robot::from_toml_file(fixture("ur5.toml")).unwrap();
    let (urdf, _) = robimu_model::urdf::robot_from_urdf_file(
        fixture("aubo_i5.urdf"),
        &robimu_model::urdf::UrdfOptions::default(),
    )
    .unwrap();
    let urdf = urdf
        .with_estimated_errors(default_estimated_errors(urdf.dof()))
        .unwrap();
    vec![Robot::aubo_i5(), ur5, urdf]
}

fn random_state(robot: &Robot, rng: &mut rand::rngs::StdRng) -> [Vec<f64>; 3] {
    let n = robot.dof();
    let q = robot
        .limits()
        .iter()
        .map(|l| rng.random_range(l.q_min..l.q_max))
        .collect();
    let qd = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    let qdd = (0..n).map(|_| rng.random_range(-3.0..3.0)).collect();
    [q, qd, qdd]
}

fn max_abs(v: impl IntoIterator<Item = f64>) -> f64 {
    v.into_iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Item 3's check: with the hidden effects off, the URDF chain's
/// Newton–Euler pass gives the model's ω, s and z (MeasurementModel's
/// spatial-twist walk) to 1e-9 relative, at the nominal x and at drawn
/// truths, on random joint states.
#[test]
fn the_urdf_chain_matches_the_model_to_1e_9() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(15);
    for robot in robots() {
        let layout = ParamLayout::new(&robot);
        let xs = [
            layout.nominal(),
            draw_truth(&layout, &mut rng),
            draw_truth(&layout, &mut rng),
        ];
        for x in &xs {
            let model = MeasurementModel::new(&robot, &layout, x).unwrap();
            let arm = UrdfArm::from_model(&robot, &layout, x).unwrap();
            let mut physics = ArmPhysics::new(arm.clone(), ArmEffects::default(), 9.81).unwrap();
            for i in 0..40 {
                let [q, qd, qdd] = random_state(&robot, &mut rng);
                let js = JointState::from_slices(&q, &qd, &qdd, &vec![0.0; q.len()]);
                let (pose, omega, s) = model.inertial(&js);
                let k = arm.kinematics(&q, &qd, &qdd);
                let scale = max_abs(s.into_iter().chain(omega));
                let err = max_abs((0..3).flat_map(|c| [k.s[c] - s[c], k.omega[c] - omega[c]]));
                assert!(err <= 1e-9 * scale, "{} ω, s off by {err:e}", robot.name());
                let err_r = max_abs((0..9).map(|c| k.r[(c / 3, c % 3)] - pose.r[c / 3][c % 3]));
                assert!(err_r < 1e-12, "{} R off by {err_r:e}", robot.name());
                let z = model.predict(&js);
                let zz = physics.signal(i as f64 * 0.01, &q, &qd, &qdd);
                let err = max_abs((0..6).map(|c| zz[c] - z[c]));
                assert!(
                    err <= 1e-9 * max_abs(z),
                    "{} z off by {err:e}",
                    robot.name()
                );
            }
        }
    }
}

/// A URDF may put each link's frame anywhere about its joint: rotating
/// child frame j by B_j (O'_j = B_{j−1}ᵀ O_j B_j, axis'_j = B_jᵀ e_z,
/// O'_tip = B_nᵀ O_tip) leaves the IMU signal unchanged, so the pass
/// handles general axes.
#[test]
fn general_axes_and_rotated_link_frames_give_the_same_signal() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let arm = UrdfArm::from_model(&robot, &layout, &draw_truth(&layout, &mut rng)).unwrap();
    let b: Vec<Isometry3<f64>> = (0..arm.dof())
        .map(|_| {
            let v = Vector3::from_fn(|_, _| rng.random_range(-2.0..2.0));
            Isometry3::rotation(v)
        })
        .collect();
    let mut other = arm.clone();
    let mut prev = Isometry3::identity();
    for (j, joint) in other.joints.iter_mut().enumerate() {
        let o = prev.inverse() * joint.origin.isometry() * b[j];
        joint.origin = UrdfOrigin::from_isometry(&o);
        joint.axis = (b[j].rotation.inverse() * Vector3::z()).into();
        prev = b[j];
    }
    other.tip = UrdfOrigin::from_isometry(&(prev.inverse() * arm.tip.isometry()));
    assert!(other.joints.iter().any(|j| j.axis[2].abs() < 0.9));
    for _ in 0..20 {
        let [q, qd, qdd] = random_state(&robot, &mut rng);
        let (a, c) = (
            arm.kinematics(&q, &qd, &qdd),
            other.kinematics(&q, &qd, &qdd),
        );
        let err = max_abs((0..3).flat_map(|i| [a.s[i] - c.s[i], a.omega[i] - c.omega[i]]));
        assert!(err < 1e-10, "{err:e}");
    }
}

/// Elastic joints: the signal is the model's at the deflected trajectory
/// q_a(t) = q(t) + c∘τ_g(q(t)), with q̇_a, q̈_a from central differences of
/// q_a along the exact curve (step 1e-4 s, not the source's 1 ms Taylor
/// step); and the deflection is what c·τ_g says.
#[test]
fn elastic_joints_read_as_the_model_at_the_deflected_trajectory() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let x = layout.nominal();
    let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
    let mass = MassModel::for_robot(&robot);
    let compliance = vec![2e-5, 5e-5, 4e-5, 1e-5, 1e-5, 0.0];
    let effects = ArmEffects {
        elasticity: Some(Elasticity {
            mass: mass.clone(),
            compliance: compliance.clone(),
        }),
        mode: None,
    };
    let arm = UrdfArm::from_model(&robot, &layout, &x).unwrap();
    let mut physics = ArmPhysics::new(arm, effects, 9.81).unwrap();
    let curve = |t: f64| -> [Vec<f64>; 3] {
        let f = |j: usize| 0.7 + 0.3 * j as f64;
        let q = (0..6).map(|j| 0.3 + 0.5 * (f(j) * t).sin()).collect();
        let qd = (0..6).map(|j| 0.5 * f(j) * (f(j) * t).cos()).collect();
        let qdd = (0..6)
            .map(|j| -0.5 * f(j) * f(j) * (f(j) * t).sin())
            .collect();
        [q, qd, qdd]
    };
    let deflected = |t: f64| -> Vec<f64> {
        let q = &curve(t)[0];
        let tau = mass.gravity_torques(q, 9.81);
        (0..6).map(|j| q[j] + compliance[j] * tau[j]).collect()
    };
    let mut biggest = 0.0f64;
    for i in 0..30 {
        let t = 0.37 * i as f64;
        let [q, qd, qdd] = curve(t);
        let h = 1e-4;
        let (qa, qp, qm) = (deflected(t), deflected(t + h), deflected(t - h));
        let qda: Vec<f64> = (0..6).map(|j| (qp[j] - qm[j]) / (2.0 * h)).collect();
        let qdda: Vec<f64> = (0..6)
            .map(|j| (qp[j] - 2.0 * qa[j] + qm[j]) / (h * h))
            .collect();
        let z = model.predict(&JointState::from_slices(&qa, &qda, &qdda, &[0.0; 6]));
        let rigid = model.predict(&JointState::from_slices(&q, &qd, &qdd, &[0.0; 6]));
        let zz = physics.signal(t, &q, &qd, &qdd);
        let err = max_abs((0..6).map(|c| zz[c] - z[c]));
        let effect = max_abs((0..6).map(|c| rigid[c] - z[c]));
        biggest = biggest.max(effect);
        assert!(
            err < 1e-5 + 1e-3 * effect,
            "t {t}: {err:e} (effect {effect:e})"
        );
    }
    // the deflection is far above the check's tolerance
    assert!(biggest > 1e-3, "elasticity changes z by only {biggest:e}");
}

/// The structural mode integrated sample by sample (jittered 100 Hz
/// steps, forcing a sinusoid at and below resonance, as the motion is
/// slow) settles to the analytic
/// steady state of ẍ + 2ζω₀ẋ + ω₀²x = −β A sin ωt: amplitude
/// βA/√((ω₀² − ω²)² + (2ζω₀ω)²).
#[test]
fn the_structural_mode_has_the_oscillators_frequency_response() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let arm = UrdfArm::from_model(&robot, &layout, &layout.nominal()).unwrap();
    let mode = StructuralMode {
        frequency_hz: 12.0,
        damping_ratio: 0.02,
        translation_gain: 0.5,
        rotation_gain: 2.0,
    };
    let effects = ArmEffects {
        elasticity: None,
        mode: Some(mode),
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    for ratio in [0.5, 0.9, 1.0] {
        let mut physics = ArmPhysics::new(arm.clone(), effects.clone(), 9.81).unwrap();
        let w0 = 2.0 * std::f64::consts::PI * mode.frequency_hz;
        let w = ratio * w0;
        let amp = 0.3;
        let mut t = 0.0;
        let (mut peak_t, mut peak_r) = (0.0f64, 0.0f64);
        while t < 12.0 {
            let f = amp * (w * t).sin();
            physics.advance_mode(&mode, t, [f, 0.0, 0.0, 0.0, 0.0, f]);
            if t > 10.0 {
                let d = physics.mode_displacement();
                peak_t = peak_t.max(d[0].abs());
                peak_r = peak_r.max(d[5].abs());
                assert!(d[1] == 0.0 && d[3] == 0.0);
            }
            t += 0.01 * rng.random_range(0.7..1.3);
        }
        let h = 1.0 / ((w0 * w0 - w * w).powi(2) + (2.0 * 0.02 * w0 * w).powi(2)).sqrt();
        // sampled peaks lie within cos(ω·Δt/2) of the true amplitude
        let low = (w * 0.013 / 2.0).cos().min(0.98);
        for (peak, beta) in [(peak_t, 0.5), (peak_r, 2.0)] {
            let want = beta * amp * h;
            assert!(
                peak <= 1.02 * want && peak >= low * want,
                "ω/ω₀ {ratio}: peak {peak:e}, analytic {want:e}"
            );
        }
    }
}

/// The mode moves the reading while the arm moves, and not at rest.
#[test]
fn the_structural_mode_shows_in_the_signal_only_with_motion() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let arm = UrdfArm::from_model(&robot, &layout, &layout.nominal()).unwrap();
    let effects = ArmEffects {
        elasticity: None,
        mode: Some(StructuralMode::default()),
    };
    let mut with = ArmPhysics::new(arm.clone(), effects, 9.81).unwrap();
    let mut without = ArmPhysics::new(arm, ArmEffects::default(), 9.81).unwrap();
    let q = [0.1, 0.2, 1.0, 0.3, 0.4, 0.5];
    let mut diff_rest = 0.0f64;
    let mut diff_moving = 0.0f64;
    for i in 0..300 {
        let t = i as f64 * 0.01;
        let moving = i >= 100;
        // a joint-2 acceleration step at t = 1 s
        let qdd = [0.0, if moving { 1.0 } else { 0.0 }, 0.0, 0.0, 0.0, 0.0];
        let qd = [0.0, if moving { t - 1.0 } else { 0.0 }, 0.0, 0.0, 0.0, 0.0];
        let (a, b) = (
            with.signal(t, &q, &qd, &qdd),
            without.signal(t, &q, &qd, &qdd),
        );
        let d = max_abs((0..6).map(|c| a[c] - b[c]));
        if moving {
            diff_moving = diff_moving.max(d);
        } else {
            diff_rest = diff_rest.max(d);
        }
    }
    assert!(diff_rest < 1e-12, "{diff_rest:e}");
    assert!(diff_moving > 1e-2, "{diff_moving:e}");
}

#[test]
fn bad_effects_are_named() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let arm = UrdfArm::from_model(&robot, &layout, &layout.nominal()).unwrap();
    let e = ArmPhysics::new(
        arm.clone(),
        ArmEffects {
            elasticity: Some(Elasticity {
                mass: MassModel::for_robot(&robot),
                compliance: vec![1e-5; 3],
            }),
            mode: None,
        },
        9.81,
    )
    .unwrap_err();
    assert!(e.to_string().contains("3 given"), "{e}");
    let e = ArmPhysics::new(
        arm,
        ArmEffects {
            elasticity: None,
            mode: Some(StructuralMode {
                damping_ratio: 0.0,
                ..StructuralMode::default()
            }),
        },
        9.81,
    )
    .unwrap_err();
    assert!(e.to_string().contains("damping"), "{e}");
    let e = UrdfArm::from_model(&robot, &layout, &[0.0; 3]).unwrap_err();
    assert!(
        e.to_string().contains("length") || e.to_string().contains("entries"),
        "{e}"
    );
}
