//! Tests of the pose spline: every derivative and Jacobian against central
//! finite differences, physical motions (constant-rate spin, circle, IMU
//! lever arm), fits (self-recovery, quaternion sign flips) and bad input.

use super::*;
use crate::geom::{exp_so3, identity, quat_from_matrix};

/// Largest absolute entry.
fn max_abs(j: &Jac3x12) -> f64 {
    j.iter().flatten().fold(0.0, |a, v| a.max(v.abs()))
}

/// max |J − J_fd| / max |J| (absolute when J is zero).
fn rel_err(j: &Jac3x12, fd: &Jac3x12) -> f64 {
    let d = (0..3)
        .flat_map(|r| (0..LOCAL).map(move |k| (r, k)))
        .map(|(r, k)| (j[r][k] - fd[r][k]).abs())
        .fold(0.0, f64::max);
    let s = max_abs(j);
    if s > 0.0 {
        d / s
    } else {
        d
    }
}

fn rel3(a: V3, b: V3, scale: f64) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max) / scale
}

fn norm(v: V3) -> f64 {
    dot3(v, v).sqrt()
}

fn dot3(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A spline with well-curved rotation (differences up to ~1 rad), one
/// stationary pair of rotation control points (d = 0: the small-angle
/// branches) and a wiggly position.
fn test_spline() -> PoseSpline {
    let knots = Knots::uniform(0.0, 2.0, 0.25, DEGREE).unwrap();
    let m = knots.num_coeffs();
    let positions: Vec<V3> = (0..m)
        .map(|k| {
            let x = k as f64;
            [
                (0.7 * x).sin(),
                0.3 * x - 0.02 * x * x,
                (1.3 * x).cos() * 0.4,
            ]
        })
        .collect();
    let mut rotations: Vec<M3> = (0..m)
        .map(|k| {
            let x = k as f64;
            exp_so3([0.9 * (0.5 * x).sin(), 0.4 * x - 1.0, 0.6 * (0.8 * x).cos()])
        })
        .collect();
    rotations[6] = rotations[5];
    PoseSpline::new(knots, &positions, &rotations).unwrap()
}

/// An output of a (perturbed) spline, for finite differences.
type Probe = Box<dyn Fn(&PoseSpline) -> V3>;
/// A vector of a [`PoseState`].
type StateField = fn(&PoseState) -> V3;

const TIMES: [f64; 7] = [0.0, 0.13, 0.5, 0.77, 1.25, 1.61, 2.0];

/// Central differences of `f` over the 12 local parameters of the control
/// points from `first` (rotation δ or position c).
fn fd_jac(sp: &PoseSpline, first: usize, rotation: bool, f: impl Fn(&PoseSpline) -> V3) -> Jac3x12 {
    let h = 1e-6;
    let mut jac = [[0.0; LOCAL]; 3];
    for k in 0..LOCAL {
        let mut e = [0.0; 3];
        e[k % 3] = h;
        let (mut sp_p, mut sp_m) = (sp.clone(), sp.clone());
        let em = e.map(|v| -v);
        if rotation {
            sp_p.perturb(first + k / 3, [0.0; 3], e);
            sp_m.perturb(first + k / 3, [0.0; 3], em);
        } else {
            sp_p.perturb(first + k / 3, e, [0.0; 3]);
            sp_m.perturb(first + k / 3, em, [0.0; 3]);
        }
        let (fp, fm) = (f(&sp_p), f(&sp_m));
        for r in 0..3 {
            jac[r][k] = (fp[r] - fm[r]) / (2.0 * h);
        }
    }
    jac
}

/// Log(R0ᵀ R(t)) of a perturbed spline: its central difference is the
/// body-frame rotation Jacobian.
fn rot_probe(r0: M3, t: f64) -> impl Fn(&PoseSpline) -> V3 {
    move |s| log_so3(&mul_mm(&transpose(&r0), &s.rotation(t).unwrap()))
}

/// [`test_spline`] with rotation control points 2.6–2.9 rad apart (large
/// differences d_j, towards Log's and J_r⁻¹'s range end at π).
fn fast_spline() -> PoseSpline {
    let sp = test_spline();
    let mut r = identity();
    let rotations: Vec<M3> = (0..sp.num_control_points())
        .map(|k| {
            let x = k as f64;
            let axis = [(0.9 * x).cos(), (0.9 * x).sin(), 0.5];
            let step = (2.6 + 0.3 * (x * 1.7).sin().abs()) / norm(axis);
            r = mul_mm(&r, &exp_so3(axis.map(|v| v * step)));
            r
        })
        .collect();
    let positions: Vec<V3> = (0..sp.num_control_points())
        .map(|k| sp.position_control_point(k))
        .collect();
    let fast = PoseSpline::new(sp.knots().clone(), &positions, &rotations).unwrap();
    for k in 0..fast.num_control_points() - DEGREE {
        assert!(fast.differences(k).iter().all(|&d| norm(d) > 2.5));
    }
    fast
}

#[test]
fn pose_jacobians_match_finite_differences() {
    for sp in [test_spline(), fast_spline()] {
        pose_jacobians_of(&sp);
    }
}

fn pose_jacobians_of(sp: &PoseSpline) {
    let sp = sp.clone();
    let mut worst = 0.0f64;
    for t in TIMES {
        let (s, j) = sp.jacobians(t).unwrap();
        let s2 = sp.evaluate(t).unwrap();
        for (a, b) in [(s.omega_n, s2.omega_n), (s.alpha, s2.alpha), (s.p, s2.p)] {
            assert!(
                rel3(a, b, 1.0) < 1e-12,
                "jet and f64 values differ at t = {t}"
            );
        }
        let ev = |f: fn(&PoseState) -> V3| move |x: &PoseSpline| f(&x.evaluate(t).unwrap());
        let rot: [(&Jac3x12, Probe); 5] = [
            (&j.r, Box::new(rot_probe(s.r, t))),
            (&j.omega_n, Box::new(ev(|s| s.omega_n))),
            (&j.omega, Box::new(ev(|s| s.omega))),
            (&j.alpha_n, Box::new(ev(|s| s.alpha_n))),
            (&j.alpha, Box::new(ev(|s| s.alpha))),
        ];
        for (jac, f) in rot {
            worst = worst.max(rel_err(jac, &fd_jac(&sp, j.first, true, f)));
        }
        let pos: [(&Jac3x12, StateField); 3] = [(&j.p, |s| s.p), (&j.v, |s| s.v), (&j.a, |s| s.a)];
        for (jac, f) in pos {
            worst = worst.max(rel_err(jac, &fd_jac(&sp, j.first, false, ev(f))));
            // position outputs do not depend on the rotation
            assert_eq!(max_abs(&fd_jac(&sp, j.first, true, ev(f))), 0.0);
        }
    }
    eprintln!("pose Jacobians: worst relative error {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn imu_point_jacobians_match_finite_differences() {
    let sp = test_spline();
    let p_imu = [0.12, -0.3, 0.07];
    let mut worst = 0.0f64;
    for t in TIMES {
        let (s, j) = sp.imu_point_jacobians(t, p_imu).unwrap();
        let s2 = sp.imu_point(t, p_imu).unwrap();
        assert!(rel3(s.a_n, s2.a_n, 1.0) < 1e-12 && rel3(s.v, s2.v, 1.0) < 1e-12);
        let ev =
            |f: fn(&ImuPointState) -> V3| move |x: &PoseSpline| f(&x.imu_point(t, p_imu).unwrap());
        let cases: [(&Jac3x12, bool, Probe); 9] = [
            (&j.r, true, Box::new(rot_probe(s.r, t))),
            (&j.p_rotation, true, Box::new(ev(|s| s.p))),
            (&j.v_rotation, true, Box::new(ev(|s| s.v))),
            (&j.a_n_rotation, true, Box::new(ev(|s| s.a_n))),
            (&j.omega_n, true, Box::new(ev(|s| s.omega_n))),
            (&j.omega, true, Box::new(ev(|s| s.omega))),
            (&j.p_position, false, Box::new(ev(|s| s.p))),
            (&j.v_position, false, Box::new(ev(|s| s.v))),
            (&j.a_n_position, false, Box::new(ev(|s| s.a_n))),
        ];
        for (jac, rotation, f) in cases {
            worst = worst.max(rel_err(jac, &fd_jac(&sp, j.first, rotation, f)));
        }
    }
    eprintln!("IMU point Jacobians: worst relative error {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn pose_residual_jacobians_match_finite_differences() {
    let sp = test_spline();
    let mut worst = 0.0f64;
    for (k, t) in TIMES.into_iter().enumerate() {
        let s = sp.evaluate(t).unwrap();
        // a measurement a little off the spline, given with either quaternion sign
        let r_meas = mul_mm(&s.r, &exp_so3([0.02, -0.05, 0.03 * k as f64]));
        let mut q = quat_from_matrix(&r_meas);
        if k % 2 == 1 {
            q = q.map(|v| -v);
        }
        let p_meas = add(s.p, [0.01, -0.02, 0.005]);
        let res = sp.pose_residual(t, p_meas, q).unwrap();
        assert!(rel3(res.e_p, [-0.01, 0.02, -0.005], 1.0) < 1e-12);
        let n_r = [0.02, -0.05, 0.03 * k as f64];
        assert!(rel3(res.e_r, n_r.map(|v| -v), 1.0) < 1e-12, "{:?}", res.e_r);
        let e_r = |x: &PoseSpline| x.pose_residual(t, p_meas, q).unwrap().e_r;
        let e_p = |x: &PoseSpline| x.pose_residual(t, p_meas, q).unwrap().e_p;
        worst = worst.max(rel_err(
            &res.e_r_rotation,
            &fd_jac(&sp, res.first, true, e_r),
        ));
        worst = worst.max(rel_err(
            &res.e_p_position,
            &fd_jac(&sp, res.first, false, e_p),
        ));
    }
    eprintln!("pose residual Jacobians: worst relative error {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn time_derivatives_match_finite_differences() {
    let sp = test_spline();
    let p_imu = [0.12, -0.3, 0.07];
    let h = 1e-5;
    let mut worst = 0.0f64;
    // off the knots (multiples of 0.25): there the third derivatives jump and
    // central differences of α and a are only first-order accurate
    for t in [0.13, 0.61, 0.77, 1.11, 1.37, 1.61, 1.9] {
        let (s, sp_, sm) = (
            sp.evaluate(t).unwrap(),
            sp.evaluate(t + h).unwrap(),
            sp.evaluate(t - h).unwrap(),
        );
        let d = |a: V3, b: V3| [0, 1, 2].map(|k| (a[k] - b[k]) / (2.0 * h));
        // Ṙ Rᵀ = [ω_n]×, Rᵀ Ṙ = [ω]×
        let w_n = log_so3(&mul_mm(&sp_.r, &transpose(&sm.r))).map(|v| v / (2.0 * h));
        let w_b = log_so3(&mul_mm(&transpose(&sm.r), &sp_.r)).map(|v| v / (2.0 * h));
        let scale_w = norm(s.omega).max(1.0);
        let scale_a = norm(s.alpha).max(1.0);
        worst = worst.max(rel3(s.omega_n, w_n, scale_w));
        worst = worst.max(rel3(s.omega, w_b, scale_w));
        worst = worst.max(rel3(s.omega, mul_mtv(&s.r, s.omega_n), scale_w));
        worst = worst.max(rel3(s.alpha_n, d(sp_.omega_n, sm.omega_n), scale_a));
        worst = worst.max(rel3(s.alpha, d(sp_.omega, sm.omega), scale_a));
        worst = worst.max(rel3(s.v, d(sp_.p, sm.p), norm(s.v).max(1.0)));
        worst = worst.max(rel3(s.a, d(sp_.v, sm.v), norm(s.a).max(1.0)));
        let (i, ip, im) = (
            sp.imu_point(t, p_imu).unwrap(),
            sp.imu_point(t + h, p_imu).unwrap(),
            sp.imu_point(t - h, p_imu).unwrap(),
        );
        worst = worst.max(rel3(i.v, d(ip.p, im.p), norm(i.v).max(1.0)));
        worst = worst.max(rel3(i.a_n, d(ip.v, im.v), norm(i.a_n).max(1.0)));
    }
    eprintln!("time derivatives: worst relative error {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn ends_interpolate_the_end_control_points() {
    let sp = test_spline();
    let m = sp.num_control_points();
    let r0 = sp.rotation(0.0).unwrap();
    let r1 = sp.rotation(2.0).unwrap();
    let e0 = log_so3(&mul_mm(&transpose(&sp.rotation_control_points()[0]), &r0));
    let e1 = log_so3(&mul_mm(
        &transpose(&sp.rotation_control_points()[m - 1]),
        &r1,
    ));
    assert!(norm(e0) < 1e-14 && norm(e1) < 1e-14, "{e0:?} {e1:?}");
    assert!(sp.evaluate(2.0 + 1e-9).is_err());
}

/// Pose samples of a rotation R(t) and position p(t) at `rate` Hz over [0, t1].
fn samples(
    t1: f64,
    rate: f64,
    pose: impl Fn(f64) -> (V3, M3),
) -> (Vec<f64>, Vec<V3>, Vec<[f64; 4]>) {
    let n = (t1 * rate).round() as usize;
    let times: Vec<f64> = (0..=n).map(|k| t1 * k as f64 / n as f64).collect();
    let (ps, qs) = times
        .iter()
        .map(|&t| {
            let (p, r) = pose(t);
            (p, quat_from_matrix(&r))
        })
        .unzip();
    (times, ps, qs)
}

fn spin_axis() -> V3 {
    let a = [1.0, 2.0, -0.5];
    a.map(|v| v / norm(a))
}

#[test]
fn constant_rate_spin_is_recovered() {
    let (w0, axis) = (1.3, spin_axis());
    let (times, ps, qs) = samples(4.0, 100.0, |t| {
        ([0.0; 3], exp_so3(axis.map(|v| v * w0 * t)))
    });
    let (sp, rep) = PoseSpline::fit_report(&times, &ps, &qs, 0.1).unwrap();
    let mut worst = [0.0f64; 2];
    for k in 0..=360 {
        let t = 0.2 + 0.01 * k as f64;
        let s = sp.evaluate(t).unwrap();
        let want = axis.map(|v| v * w0);
        worst[0] = worst[0]
            .max(rel3(s.omega, want, 1.0))
            .max(rel3(s.omega_n, want, 1.0));
        worst[1] = worst[1].max(norm(s.alpha_n));
    }
    eprintln!(
        "spin: |ω − ω0| ≤ {:.2e} rad/s, |α| ≤ {:.2e} rad/s², fit {rep:?}",
        worst[0], worst[1]
    );
    assert!(rep.converged && rep.rms_rotation < 1e-9, "{rep:?}");
    assert!(worst[0] < 1e-6 && worst[1] < 1e-5, "{worst:?}");
}

#[test]
fn imu_on_a_spinning_body_feels_the_centripetal_acceleration() {
    let w0 = 2.0;
    let (times, ps, qs) = samples(3.0, 100.0, |t| ([0.0; 3], exp_so3([0.0, 0.0, w0 * t])));
    let sp = PoseSpline::fit(&times, &ps, &qs, 0.1).unwrap();
    let p_imu = [0.3, 0.0, 0.1];
    let mut worst = 0.0f64;
    for k in 0..=200 {
        let t = 0.5 + 0.01 * k as f64;
        let s = sp.imu_point(t, p_imu).unwrap();
        let rp = mul_mv(&s.r, p_imu);
        let want = [-w0 * w0 * rp[0], -w0 * w0 * rp[1], 0.0];
        worst = worst.max(rel3(s.a_n, want, w0 * w0 * 0.3));
        assert!(rel3(s.omega, [0.0, 0.0, w0], 1.0) < 1e-6);
    }
    eprintln!("lever arm: |a_n − (−ω²r)|/(ω²r) ≤ {worst:.2e}");
    assert!(worst < 1e-6, "{worst:e}");
}

#[test]
fn circle_acceleration_points_to_the_centre() {
    let (r, w, c) = (0.5, 2.0, [0.2, -0.1, 0.7]);
    let (times, ps, qs) = samples(5.0, 200.0, |t| {
        (
            [c[0] + r * (w * t).cos(), c[1] + r * (w * t).sin(), c[2]],
            identity(),
        )
    });
    let sp = PoseSpline::fit(&times, &ps, &qs, 0.05).unwrap();
    let mut worst = 0.0f64;
    for k in 0..=400 {
        let t = 0.5 + 0.01 * k as f64;
        let s = sp.evaluate(t).unwrap();
        let want = sub(c, s.p).map(|v| v * w * w);
        worst = worst.max(rel3(s.a, want, r * w * w));
        assert!(norm(s.omega_n) < 1e-12);
    }
    eprintln!("circle: |a_n − (−rω²)|/(rω²) ≤ {worst:.2e}");
    assert!(worst < 1e-3, "{worst:e}");
}

#[test]
fn fit_recovers_a_spline_on_its_own_knots() {
    let truth = test_spline();
    let (times, ps, qs) = samples(2.0, 200.0, |t| {
        let s = truth.evaluate(t).unwrap();
        (s.p, s.r)
    });
    let (sp, rep) = PoseSpline::fit_report(&times, &ps, &qs, 0.25).unwrap();
    assert_eq!(sp.knots(), truth.knots());
    let mut worst = [0.0f64; 2];
    for k in 0..sp.num_control_points() {
        let (a, b) = (
            &sp.rotation_control_points()[k],
            &truth.rotation_control_points()[k],
        );
        worst[0] = worst[0].max(norm(log_so3(&mul_mm(&transpose(a), b))));
        let d = sub(
            sp.position_control_point(k),
            truth.position_control_point(k),
        );
        worst[1] = worst[1].max(norm(d));
    }
    eprintln!(
        "self-fit: control points within {:.2e} rad, {:.2e} m, {rep:?}",
        worst[0], worst[1]
    );
    assert!(
        rep.converged && worst[0] < 1e-9 && worst[1] < 1e-9,
        "{worst:?} {rep:?}"
    );
}

#[test]
fn quaternion_sign_flips_do_not_change_the_fit() {
    let truth = test_spline();
    let (times, ps, qs) = samples(2.0, 50.0, |t| {
        let s = truth.evaluate(t).unwrap();
        (s.p, s.r)
    });
    let flipped: Vec<[f64; 4]> = qs
        .iter()
        .enumerate()
        .map(|(k, q)| if (k * 7) % 3 == 1 { q.map(|v| -v) } else { *q })
        .collect();
    assert!(flipped.iter().zip(&qs).any(|(a, b)| a != b));
    let a = PoseSpline::fit(&times, &ps, &qs, 0.3).unwrap();
    let b = PoseSpline::fit(&times, &ps, &flipped, 0.3).unwrap();
    assert_eq!(a, b);
}

#[test]
fn bad_samples_are_rejected() {
    let (times, ps, qs) = samples(1.0, 20.0, |t| ([t, 0.0, 0.0], exp_so3([0.0, t, 0.0])));
    let err = PoseSpline::fit(&times, &ps[1..], &qs, 0.2).unwrap_err();
    assert!(
        matches!(err, PoseSplineError::LengthMismatch { .. }),
        "{err}"
    );
    let mut q0 = qs.clone();
    q0[3] = [0.0; 4];
    let err = PoseSpline::fit(&times, &ps, &q0, 0.2).unwrap_err();
    assert_eq!(
        err,
        PoseSplineError::BadSample {
            index: 3,
            what: "quaternion"
        }
    );
    let mut t0 = times.clone();
    t0[2] = f64::NAN;
    let err = PoseSpline::fit(&t0, &ps, &qs, 0.2).unwrap_err();
    assert_eq!(
        err,
        PoseSplineError::BadSample {
            index: 2,
            what: "time"
        }
    );
    let err = PoseSpline::fit(&times, &ps, &qs, 0.0).unwrap_err();
    assert_eq!(err, PoseSplineError::Spline(SplineError::BadSpacing(0.0)));
    // a gap of 0.5 s with knots every 0.1 s
    let keep: Vec<usize> = (0..times.len())
        .filter(|&k| !(5..15).contains(&k))
        .collect();
    let pick = |v: &[V3]| keep.iter().map(|&k| v[k]).collect::<Vec<_>>();
    let tg: Vec<f64> = keep.iter().map(|&k| times[k]).collect();
    let qg: Vec<[f64; 4]> = keep.iter().map(|&k| qs[k]).collect();
    let err = PoseSpline::fit(&tg, &pick(&ps), &qg, 0.1).unwrap_err();
    assert!(
        matches!(err, PoseSplineError::Spline(SplineError::Singular { .. })),
        "{err}"
    );
    // the rotation refinement alone bridges the gap (damping holds the
    // unconstrained control points)
    let mut sp = PoseSpline::fit(&times, &ps, &qs, 0.1).unwrap();
    let rg: Vec<M3> = qg.iter().map(|&q| matrix_from_quat(q)).collect();
    assert!(sp.refine_rotation(&tg, &rg, 20).unwrap().1);
    let knots = Knots::uniform(0.0, 1.0, 0.2, 2).unwrap();
    let err = PoseSpline::new(knots, &[], &[]).unwrap_err();
    assert_eq!(err, PoseSplineError::Spline(SplineError::BadDegree(2)));
}

#[test]
fn noisy_samples_in_any_order_fit_close_to_the_truth() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let truth = test_spline();
    let (sigma_p, sigma_r) = (1e-3, 2e-3);
    let mut rng = rand::rngs::StdRng::seed_from_u64(39);
    let mut noise = |s: f64| -> V3 {
        std::array::from_fn(|_| {
            let z: f64 = StandardNormal.sample(&mut rng);
            s * z
        })
    };
    let (times, mut ps, mut qs) = samples(2.0, 200.0, |t| {
        let s = truth.evaluate(t).unwrap();
        (s.p, s.r)
    });
    for (p, q) in ps.iter_mut().zip(qs.iter_mut()) {
        // MODEL.md §10: p̃ = p + n_p, R̃ = R·Exp(n_r)
        *p = add(*p, noise(sigma_p));
        *q = quat_from_matrix(&mul_mm(&matrix_from_quat(*q), &exp_so3(noise(sigma_r))));
    }
    let (sp, rep) = PoseSpline::fit_report(&times, &ps, &qs, 0.25).unwrap();
    // residual RMS ≈ σ·√3 (less the 3·11 fitted degrees of freedom of 3·401)
    let (ep, er) = (
        rep.rms_position / (sigma_p * 3f64.sqrt()),
        rep.rms_rotation / (sigma_r * 3f64.sqrt()),
    );
    eprintln!("noisy fit: RMS/σ√3 = {ep:.3} (p), {er:.3} (R), {rep:?}");
    assert!(rep.converged && (0.9..1.05).contains(&ep) && (0.9..1.05).contains(&er));
    let mut worst = 0.0f64;
    // away from the ends, where the clamped end control points rest on few samples
    for k in 5..=95 {
        let t = 0.02 * k as f64;
        let (a, b) = (sp.rotation(t).unwrap(), truth.rotation(t).unwrap());
        let e = norm(log_so3(&mul_mm(&transpose(&a), &b)));
        worst = worst.max(e);
    }
    eprintln!("noisy fit: rotation error ≤ {worst:.2e} rad (σ_r = {sigma_r})");
    assert!(worst < 0.5 * sigma_r, "rotation error {worst:e} rad");
    // the same samples in reverse order: the same spline to rounding
    let rev = |v: &[[f64; 4]]| v.iter().rev().copied().collect::<Vec<_>>();
    let times_r: Vec<f64> = times.iter().rev().copied().collect();
    let ps_r: Vec<V3> = ps.iter().rev().copied().collect();
    let sp_r = PoseSpline::fit(&times_r, &ps_r, &rev(&qs), 0.25).unwrap();
    for k in 0..sp.num_control_points() {
        let (a, b) = (
            &sp.rotation_control_points()[k],
            &sp_r.rotation_control_points()[k],
        );
        assert!(norm(log_so3(&mul_mm(&transpose(a), b))) < 1e-10);
        let d = sub(sp.position_control_point(k), sp_r.position_control_point(k));
        assert!(norm(d) < 1e-10);
    }
}

#[test]
#[ignore = "a timing: a 10-minute session at 100 Hz (run with --release)"]
fn long_session_fit_time() {
    let (times, ps, qs) = samples(600.0, 100.0, |t| {
        let w = [0.7 * (0.3 * t).sin(), 0.5 * (0.21 * t).cos(), 0.4 * t];
        (
            [(0.5 * t).sin(), (0.4 * t).cos(), 0.1 * (0.9 * t).sin()],
            exp_so3(w),
        )
    });
    let start = std::time::Instant::now();
    let (sp, rep) = PoseSpline::fit_report(&times, &ps, &qs, 0.05).unwrap();
    let fit = start.elapsed();
    let start = std::time::Instant::now();
    for &t in &times {
        std::hint::black_box(sp.imu_point_jacobians(t, [0.1, 0.0, 0.05]).unwrap());
    }
    eprintln!(
        "{} samples, {} control points: fit {fit:?} ({rep:?}); IMU-point Jacobians {:?} per sample",
        times.len(),
        sp.num_control_points(),
        start.elapsed() / times.len() as u32
    );
}

/// The value-only pose error equals the residual of `pose_residual_r`
/// (computed through the jets).
#[test]
fn pose_error_equals_the_residual_with_jacobians() {
    let sp = {
        let times: Vec<f64> = (0..=200).map(|k| k as f64 * 0.01).collect();
        let pos: Vec<[f64; 3]> = times.iter().map(|t| [t.sin(), 0.3 * t, t * t]).collect();
        let q: Vec<[f64; 4]> = times
            .iter()
            .map(|t| {
                let (a, b) = (0.7 * t, 0.4 * t * t);
                let n = (1.0 + a * a + b * b).sqrt();
                [1.0 / n, a / n, b / n, 0.2 / n]
            })
            .collect();
        PoseSpline::fit(&times, &pos, &q, 0.1).unwrap()
    };
    let r_meas = crate::geom::exp_so3([0.1, -0.2, 0.3]);
    for k in 0..50 {
        let t = 0.013 + 1.95 * k as f64 / 50.0;
        let full = sp.pose_residual_r(t, [0.1, 0.2, 0.3], &r_meas).unwrap();
        let (e_p, e_r) = sp.pose_error_r(t, [0.1, 0.2, 0.3], &r_meas).unwrap();
        for c in 0..3 {
            assert!((e_p[c] - full.e_p[c]).abs() < 1e-14, "e_p {c} at {t}");
            assert!((e_r[c] - full.e_r[c]).abs() < 1e-12, "e_r {c} at {t}");
        }
    }
}

/// The jet-free rotation Jacobian of the pose residual equals the one
/// through the 12-variable jets (`jacobians`' r) to 1e-12.
#[test]
fn rotation_jacobian_without_jets_equals_the_jets() {
    let times: Vec<f64> = (0..=200).map(|k| k as f64 * 0.01).collect();
    let pos = vec![[0.0; 3]; times.len()];
    let q: Vec<[f64; 4]> = times
        .iter()
        .map(|t| {
            let (a, b) = (1.7 * t, 0.9 * t * t);
            let n = (1.0 + a * a + b * b + 0.04).sqrt();
            [1.0 / n, a / n, b / n, 0.2 / n]
        })
        .collect();
    let sp = PoseSpline::fit(&times, &pos, &q, 0.1).unwrap();
    for k in 0..60 {
        let t = 0.007 + 1.98 * k as f64 / 60.0;
        let loc = sp.local(t).unwrap();
        let (r, j) = sp.rotation_and_jacobian(&loc);
        let (state, jac) = sp.jacobians(t).unwrap();
        for a in 0..3 {
            for b in 0..3 {
                assert!((r[a][b] - state.r[a][b]).abs() < 1e-12);
            }
            for c in 0..LOCAL {
                assert!((j[a][c] - jac.r[a][c]).abs() < 1e-12, "J[{a}][{c}] at {t}");
            }
        }
    }
}
