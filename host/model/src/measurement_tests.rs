//! Tests of the measurement model against independent references: the
//! eq. (4)-recursion implementation (f64 and forward-mode jets), central finite
//! differences with Richardson extrapolation, and finite differences of the pose
//! along a spline.

use super::*;
use crate::geom::{mul_mm, transpose};
use crate::jet::Jet;
use crate::kinematics::forward_kinematics;
use crate::spline::{Knots, Spline};

/// Deterministic pseudo-random numbers in [−1, 1].
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A parameter vector drawn around the prior (within ~1σ).
fn perturbed_x(layout: &ParamLayout, rng: &mut Lcg) -> Vec<f64> {
    layout
        .specs()
        .iter()
        .map(|s| s.nominal + s.sigma * rng.next())
        .collect()
}

fn random_state(rng: &mut Lcg) -> JointState {
    let mut js = JointState::default();
    for j in 0..6 {
        js.q[j] = 1.5 * rng.next();
        js.qd[j] = 0.8 * rng.next();
        js.qdd[j] = 2.0 * rng.next();
        js.qddd[j] = 5.0 * rng.next();
    }
    js
}

/// Richardson-extrapolated central difference of a 6-vector function:
/// (4 D(h/2) − D(h)) / 3, error O(h⁴).
fn richardson(f: impl Fn(f64) -> [f64; 6], h: f64) -> [f64; 6] {
    let d = |h: f64| {
        let (p, m) = (f(h), f(-h));
        let mut r = [0.0; 6];
        for i in 0..6 {
            r[i] = (p[i] - m[i]) / (2.0 * h);
        }
        r
    };
    let (d1, d2) = (d(h), d(h / 2.0));
    let mut r = [0.0; 6];
    for i in 0..6 {
        r[i] = (4.0 * d2[i] - d1[i]) / 3.0;
    }
    r
}

fn inf_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// ‖a − b‖∞ ≤ rel·‖a‖∞ + abs.
fn assert_col_close(a: &[f64; 6], b: &[f64; 6], rel: f64, abs: f64, what: &str) {
    let diff: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let err = inf_norm(&diff);
    assert!(
        err <= rel * inf_norm(a) + abs,
        "{what}: analytic {a:?} vs reference {b:?} (err {err:e})"
    );
}

fn setup() -> (Robot, ParamLayout) {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    (robot, layout)
}

#[test]
fn value_matches_the_eq4_recursion_implementation() {
    let (robot, layout) = setup();
    let mut rng = Lcg(7);
    for _ in 0..20 {
        let x = perturbed_x(&layout, &mut rng);
        let js = random_state(&mut rng);
        let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
        let z = model.predict(&js);
        let p = layout.unpack(&x).unwrap();
        let zr = predict_generic(
            robot.links(),
            robot.gravity(),
            &p,
            &js.q[..6],
            &js.qd[..6],
            &js.qdd[..6],
        )
        .unwrap();
        assert_col_close(&z, &zr, 1e-13, 1e-13, "z");
        let mut jac = MeasurementJacobians::new(layout.len());
        model.jacobians(&js, &mut jac);
        assert_eq!(jac.z, z);
    }
}

const NJ: usize = 48 + 18;

#[test]
fn jacobians_match_forward_mode_jets() {
    let (robot, layout) = setup();
    let mut rng = Lcg(11);
    for _ in 0..10 {
        let x = perturbed_x(&layout, &mut rng);
        let js = random_state(&mut rng);
        let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
        let mut jac = MeasurementJacobians::new(layout.len());
        model.jacobians(&js, &mut jac);
        let xj: Vec<Jet<NJ>> = x
            .iter()
            .enumerate()
            .map(|(i, &v)| Jet::variable(v, i))
            .collect();
        let var = |off: usize, v: &[f64]| -> Vec<Jet<NJ>> {
            (0..6).map(|j| Jet::variable(v[j], off + j)).collect()
        };
        let p = layout.unpack(&xj).unwrap();
        let z = predict_generic(
            robot.links(),
            robot.gravity(),
            &p,
            &var(48, &js.q),
            &var(54, &js.qd),
            &var(60, &js.qdd),
        )
        .unwrap();
        let col = |k: usize| -> [f64; 6] { core::array::from_fn(|r| z[r].d[k]) };
        let tau = layout.offsets().tau;
        for c in 0..48 {
            if c == tau {
                // τ does not enter predict_generic; checked against the spline below.
                assert_eq!(col(c), [0.0; 6]);
                continue;
            }
            assert_col_close(
                &jac.dz_dx[c],
                &col(c),
                1e-11,
                1e-13,
                &layout.specs()[c].name,
            );
        }
        for j in 0..6 {
            assert_col_close(&jac.dz_dq[j], &col(48 + j), 1e-11, 1e-13, "dz/dq");
            assert_col_close(&jac.dz_dqd[j], &col(54 + j), 1e-11, 1e-13, "dz/dqd");
            assert_col_close(&jac.dz_dqdd[j], &col(60 + j), 1e-11, 1e-13, "dz/dqdd");
        }
    }
}

#[test]
fn jacobians_match_central_finite_differences() {
    let (robot, layout) = setup();
    let mut rng = Lcg(23);
    let tau = layout.offsets().tau;
    for _ in 0..5 {
        let x = perturbed_x(&layout, &mut rng);
        let js = random_state(&mut rng);
        let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
        let mut jac = MeasurementJacobians::new(layout.len());
        model.jacobians(&js, &mut jac);
        for c in 0..layout.len() {
            if c == tau {
                continue; // see jacobian_tau_matches_spline_time_shift
            }
            let h = 1e-3 * layout.specs()[c].sigma.max(1e-3);
            let fd = richardson(
                |d| {
                    let mut xp = x.clone();
                    xp[c] += d;
                    MeasurementModel::new(&robot, &layout, &xp)
                        .unwrap()
                        .predict(&js)
                },
                h,
            );
            assert_col_close(&jac.dz_dx[c], &fd, 1e-6, 1e-9, &layout.specs()[c].name);
        }
        for j in 0..6 {
            for (which, analytic) in [(0, jac.dz_dq[j]), (1, jac.dz_dqd[j]), (2, jac.dz_dqdd[j])] {
                let fd = richardson(
                    |d| {
                        let mut s = js;
                        [&mut s.q, &mut s.qd, &mut s.qdd][which][j] += d;
                        model.predict(&s)
                    },
                    1e-3,
                );
                assert_col_close(
                    &analytic,
                    &fd,
                    1e-6,
                    1e-9,
                    &format!("d z/d q^({which})_{j}"),
                );
            }
        }
    }
}

fn test_spline(degree: usize) -> Spline {
    let knots = Knots::uniform(0.0, 12.0, 1.0, degree).unwrap();
    let m = knots.num_coeffs();
    let mut rng = Lcg(99 + degree as u64);
    let coeffs: Vec<f64> = (0..m * 6).map(|_| 1.2 * rng.next()).collect();
    Spline::new(knots, 6, coeffs).unwrap()
}

#[test]
fn jacobian_tau_matches_spline_time_shift() {
    let (robot, layout) = setup();
    let mut rng = Lcg(5);
    let x = perturbed_x(&layout, &mut rng);
    let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
    let tau = layout.offsets().tau;
    let mut jac = MeasurementJacobians::new(layout.len());
    for degree in [3, 5] {
        let spline = test_spline(degree);
        for &t in &[1.37, 4.61, 8.22, 10.5] {
            let mut js = JointState::default();
            spline.evaluate(t, &mut js).unwrap();
            model.jacobians(&js, &mut jac);
            // z(τ) = h(q(t_i + τ)): differentiate through the spline itself.
            let fd = richardson(
                |d| {
                    let mut s = JointState::default();
                    spline.evaluate(t + d, &mut s).unwrap();
                    model.predict(&s)
                },
                1e-3,
            );
            assert_col_close(&jac.dz_dx[tau], &fd, 1e-6, 1e-9, "tau");
        }
    }
}

fn vee_of_skew(m: &M3) -> V3 {
    [
        0.5 * (m[2][1] - m[1][2]),
        0.5 * (m[0][2] - m[2][0]),
        0.5 * (m[1][0] - m[0][1]),
    ]
}

/// docs/model.md §1.5: forward kinematics and the predicted ω, s along a
/// spline agree with finite differences of the pose along the spline:
/// ω_n from (R(t+h) − R(t−h))/2h · Rᵀ, a_n from the central second difference
/// of p, both Richardson-extrapolated.
#[test]
fn predicted_omega_and_s_match_pose_finite_differences_along_a_spline() {
    let (robot, layout) = setup();
    let mut rng = Lcg(31);
    let x = perturbed_x(&layout, &mut rng);
    let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
    let params = layout.unpack(&x).unwrap();
    let g = model.gravity();
    for degree in [3, 5] {
        let spline = test_spline(degree);
        let pose = |t: f64| {
            let mut s = JointState::default();
            spline.evaluate(t, &mut s).unwrap();
            forward_kinematics(robot.links(), &params.eps, &s.q[..6])
        };
        // Away from knots (integers) so the h-window sees one polynomial piece.
        for &t in &[0.31, 2.5, 5.77, 9.43, 11.6] {
            let mut js = JointState::default();
            spline.evaluate(t, &mut js).unwrap();
            let (iso, omega, s) = model.inertial(&js);
            let f0 = pose(t);
            // FK itself: the model's pose equals the independent FK.
            for i in 0..3 {
                assert!((iso.p[i] - f0.p[i]).abs() < 1e-14);
                for j in 0..3 {
                    assert!((iso.r[i][j] - f0.r[i][j]).abs() < 1e-14);
                }
            }
            let omega_fd = |h: f64| {
                let (rp, rm) = (pose(t + h).r, pose(t - h).r);
                let mut dr = [[0.0; 3]; 3];
                for i in 0..3 {
                    for j in 0..3 {
                        dr[i][j] = (rp[i][j] - rm[i][j]) / (2.0 * h);
                    }
                }
                vee_of_skew(&mul_mm(&dr, &transpose(&f0.r)))
            };
            let acc_fd = |h: f64| {
                let (pp, pm) = (pose(t + h).p, pose(t - h).p);
                core::array::from_fn::<f64, 3, _>(|i| (pp[i] - 2.0 * f0.p[i] + pm[i]) / (h * h))
            };
            let h = 2e-3;
            let rich = |a: V3, b: V3| -> V3 { core::array::from_fn(|i| (4.0 * b[i] - a[i]) / 3.0) };
            let omega_n = rich(omega_fd(h), omega_fd(h / 2.0));
            let a_n = rich(acc_fd(h), acc_fd(h / 2.0));
            let omega_ref = geom::mul_mtv(&f0.r, omega_n);
            let s_ref = geom::mul_mtv(&f0.r, sub(a_n, g));
            let rel = |a: V3, b: V3| {
                let d = sub(a, b);
                inf_norm(&d) / inf_norm(&b)
            };
            assert!(
                rel(omega, omega_ref) < 1e-6,
                "ω {omega:?} vs {omega_ref:?} (deg {degree}, t {t})"
            );
            assert!(
                rel(s, s_ref) < 1e-6,
                "s {s:?} vs {s_ref:?} (deg {degree}, t {t})"
            );
            // The linear acceleration alone (without g) too.
            let a_model = sub(geom::mul_mv(&iso.r, s), geom::scale(g, -1.0));
            assert!(
                rel(a_model, a_n) < 1e-6,
                "a_n {a_model:?} vs {a_n:?} (deg {degree}, t {t})"
            );
            // And z through the sensor model.
            let z = model.predict(&js);
            let zr = imu::sensor_output(&params.accel, &params.gyro, omega_ref, s_ref);
            assert_col_close(&z, &zr, 1e-6, 0.0, "z along spline");
        }
    }
}

#[test]
fn bad_inputs_are_typed_errors() {
    let (robot, layout) = setup();
    let mut x = layout.nominal();
    assert!(matches!(
        MeasurementModel::new(&robot, &layout, &x[..10]),
        Err(ModelError::ParamLength(_))
    ));
    x[layout.offsets().g_xy] = 9.0;
    x[layout.offsets().g_xy + 1] = 9.0;
    assert!(matches!(
        MeasurementModel::new(&robot, &layout, &x),
        Err(ModelError::Imu(ImuError::GravityOutOfRange { .. }))
    ));
}

/// Four samples in the lanes of [`F64x4`] give, lane by lane, exactly the
/// bits of four scalar evaluations (prediction and every Jacobian), on the
/// AVX2 copy where the CPU has it and on the baseline copy.
#[test]
fn four_lanes_are_four_scalar_evaluations_bit_for_bit() {
    let (robot, layout) = setup();
    let mut rng = Lcg(0x5eed_1a7e);
    for _ in 0..5 {
        let x = perturbed_x(&layout, &mut rng);
        let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
        let states: [JointState; 4] = std::array::from_fn(|_| random_state(&mut rng));
        let mut js4 = JointState::<F64x4>::default();
        for (l, js) in states.iter().enumerate() {
            for j in 0..MAX_JOINTS {
                js4.q[j].0[l] = js.q[j];
                js4.qd[j].0[l] = js.qd[j];
                js4.qdd[j].0[l] = js.qdd[j];
                js4.qddd[j].0[l] = js.qddd[j];
            }
        }
        let mut jac4 = MeasurementJacobians::<F64x4>::zeros(layout.len());
        model.jacobians_x4(&js4, &mut jac4);
        let mut base4 = MeasurementJacobians::<F64x4>::zeros(layout.len());
        model.jacobians_lanes(&js4, &mut base4);
        assert_eq!(jac4, base4, "the AVX2 copy and the baseline copy differ");
        let z4 = model.predict_x4(&js4);
        let (mut one, mut lane) = (
            MeasurementJacobians::new(layout.len()),
            MeasurementJacobians::new(layout.len()),
        );
        for (l, js) in states.iter().enumerate() {
            model.jacobians(js, &mut one);
            jac4.lane_into(l, &mut lane);
            assert_eq!(one, lane, "lane {l}");
            let z = model.predict(js);
            assert_eq!(z, z4.map(|v| v.lane(l)), "prediction, lane {l}");
            assert_eq!(z, one.z);
        }
    }
}
