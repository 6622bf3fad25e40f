//! Tests of the pose-session measurement: names and priors, the jerk and ω̈
//! of the spline, every Jacobian against central finite differences.

use super::*;
use crate::geom::{exp_so3, mul_mm};
use crate::spline::Knots;
use rand::{Rng, SeedableRng};

/// A random pose spline over [0, 3] s with rotations ~1 rad apart.
fn random_spline(seed: u64) -> PoseSpline {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let knots = Knots::uniform(0.0, 3.0, 0.3, 3).unwrap();
    let m = knots.num_coeffs();
    let pos: Vec<V3> = (0..m)
        .map(|_| std::array::from_fn(|_| rng.random_range(-0.3..0.3)))
        .collect();
    let mut r = exp_so3([0.3, -1.0, 2.0]);
    let rot: Vec<M3> = (0..m)
        .map(|_| {
            r = mul_mm(
                &r,
                &exp_so3(std::array::from_fn(|_| rng.random_range(-0.7..0.7))),
            );
            r
        })
        .collect();
    PoseSpline::new(knots, &pos, &rot).unwrap()
}

/// A parameter vector with every entry away from its nominal.
fn test_x() -> Vec<f64> {
    let mut x: Vec<f64> = pose_param_specs([2.5, -0.4, 1.0], [-2.0, 0.3, -0.8])
        .iter()
        .map(|s| s.nominal)
        .collect();
    let off = [0.05, -0.12, 0.08, 0.3, -0.2, 0.1];
    x[..6].copy_from_slice(&off);
    for (k, v) in x[ACCEL..].iter_mut().enumerate() {
        *v += 0.01 * (k as f64 + 1.0).sin();
    }
    x
}

#[test]
fn names_units_and_priors_follow_section_10() {
    let n = pose_param_names();
    assert_eq!(
        &n[..6],
        &["p_imu_x", "p_imu_y", "p_imu_z", "g_x", "g_y", "tau"]
    );
    assert_eq!(n[ACCEL], "gamma_a_yz");
    assert_eq!(n[ACCEL + ROT], "r_a_z");
    assert_eq!(n[GYRO + ROT + 2], "r_w_x");
    assert_eq!(n[29], "b_w_z");
    let s = pose_param_specs([1.0, 2.0, 3.0], [0.0; 3]);
    assert_eq!(s.len(), POSE_PARAMS);
    assert_eq!((s[0].unit, s[0].sigma), ("m", 0.2));
    assert_eq!((s[TAU].unit, s[TAU].sigma), ("s", 1.0));
    assert_eq!(s[ACCEL + ROT + 1].nominal, 2.0);
    assert!(s[ACCEL + ROT].sigma > 3.0);
    assert_eq!((s[29].unit, s[29].sigma), ("rad/s", 5.0f64.to_radians()));
    assert_eq!((s[ACCEL + 6].unit, s[ACCEL + 6].nominal), ("1", 1.0));
}

#[test]
fn jerk_and_omega_ddot_match_finite_differences() {
    let sp = random_spline(3);
    let h = 1e-5;
    for &t in &[0.05, 0.71, 1.45, 2.33, 2.95] {
        let (j, wdd) = sp.jerk_and_omega_ddot(t).unwrap();
        let (a, b) = (sp.evaluate(t + h).unwrap(), sp.evaluate(t - h).unwrap());
        for c in 0..3 {
            let fd_j = (a.a[c] - b.a[c]) / (2.0 * h);
            let fd_w = (a.alpha[c] - b.alpha[c]) / (2.0 * h);
            assert!(
                (j[c] - fd_j).abs() < 1e-5 * (1.0 + fd_j.abs()),
                "jerk {c} at {t}: {} vs {fd_j}",
                j[c]
            );
            assert!(
                (wdd[c] - fd_w).abs() < 1e-5 * (1.0 + fd_w.abs()),
                "ω̈ {c} at {t}: {} vs {fd_w}",
                wdd[c]
            );
        }
    }
}

#[test]
fn prediction_matches_its_jacobian_value_and_physics_at_rest() {
    let sp = random_spline(4);
    let x = test_x();
    for &t in &[0.3, 1.2, 2.0] {
        let p = predict(&sp, t, &x).unwrap();
        let j = predict_jacobians(&sp, t, &x).unwrap();
        for c in 0..6 {
            assert!((p[c] - j.z[c]).abs() < 1e-12);
        }
    }
    assert!(matches!(
        predict(&sp, 0.0, &x[..29]),
        Err(PoseMeasurementError::Length { found: 29 })
    ));
    assert!(predict(&sp, 2.95, &x).is_err(), "t + τ past the end");
}

#[test]
fn jacobian_in_x_matches_finite_differences() {
    let sp = random_spline(5);
    let x = test_x();
    for &t in &[0.23, 1.13, 2.4] {
        let j = predict_jacobians(&sp, t, &x).unwrap();
        for k in 0..POSE_PARAMS {
            let h = 1e-6;
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[k] += h;
            xm[k] -= h;
            let (zp, zm) = (predict(&sp, t, &xp).unwrap(), predict(&sp, t, &xm).unwrap());
            for r in 0..6 {
                let fd = (zp[r] - zm[r]) / (2.0 * h);
                let tol = 1e-6 * (1.0 + fd.abs().max(j.dx[r][k].abs()));
                assert!(
                    (j.dx[r][k] - fd).abs() < tol,
                    "∂z{r}/∂x{k} at {t}: {} vs {fd}",
                    j.dx[r][k]
                );
            }
        }
    }
}

#[test]
fn jacobian_in_control_points_matches_finite_differences() {
    let sp = random_spline(6);
    let x = test_x();
    for &t in &[0.25, 1.4, 2.2] {
        let j = predict_jacobians(&sp, t, &x).unwrap();
        for col in 0..CTRL {
            let (cp, part, c) = (j.first + col / 6, (col % 6) / 3, col % 3);
            let h = 1e-6;
            let z = |s: f64| {
                let mut e = [0.0; 3];
                e[c] = s * h;
                let mut q = sp.clone();
                if part == 0 {
                    q.perturb(cp, e, [0.0; 3]);
                } else {
                    q.perturb(cp, [0.0; 3], e);
                }
                predict(&q, t, &x).unwrap()
            };
            let (zp, zm) = (z(1.0), z(-1.0));
            for r in 0..6 {
                let fd = (zp[r] - zm[r]) / (2.0 * h);
                let tol = 1e-6 * (1.0 + fd.abs().max(j.dc[r][col].abs()));
                assert!(
                    (j.dc[r][col] - fd).abs() < tol,
                    "∂z{r}/∂c{col} at {t}: {} vs {fd}",
                    j.dc[r][col]
                );
            }
        }
    }
}

/// The compact rows (13-variable rotation jets, closed-form rest) equal the
/// 30-variable reference [`predict_jacobians`] in every column, and are
/// zero where they have no column, to 1e-10 relative.
#[test]
fn compact_rows_equal_the_30_variable_reference() {
    use rows::{prediction_rows, RowContext, ACCEL_COLS, GYRO_LOCAL};
    for seed in 0..4 {
        let sp = random_spline(seed);
        let x = test_x();
        let ctx = RowContext::new(&x).unwrap();
        let mut seeds = rows::SegmentCache::default();
        for k in 0..40 {
            let t = 0.05 + 2.7 * k as f64 / 40.0;
            let p = predict_jacobians(&sp, t, &x).unwrap();
            let rw = prediction_rows(&sp, t, &ctx, &mut seeds).unwrap();
            assert_eq!(p.first, rw.first);
            let full = |r: usize, col: usize| {
                if col < CTRL {
                    p.dc[r][col]
                } else {
                    p.dx[r][col - CTRL]
                }
            };
            let scale = (0..6)
                .flat_map(|r| (0..CTRL + POSE_PARAMS).map(move |c| (r, c)))
                .map(|(r, c)| full(r, c).abs())
                .fold(1.0f64, f64::max);
            let close = |a: f64, b: f64, what: &str| {
                assert!(
                    (a - b).abs() <= 1e-10 * scale,
                    "{what}: {a} vs {b} (seed {seed}, t {t})"
                )
            };
            for r in 0..3 {
                close(rw.z[r], p.z[r], "z_a");
                close(rw.z[3 + r], p.z[3 + r], "z_w");
                for col in 0..CTRL + POSE_PARAMS {
                    let a = if col < ACCEL_COLS {
                        rw.accel[r][col]
                    } else {
                        0.0
                    };
                    close(a, full(r, col), &format!("accel row {r} col {col}"));
                    let g = GYRO_LOCAL
                        .iter()
                        .position(|&l| l == col)
                        .map_or(0.0, |i| rw.gyro[r][i]);
                    close(g, full(3 + r, col), &format!("gyro row {r} col {col}"));
                }
            }
        }
    }
}
