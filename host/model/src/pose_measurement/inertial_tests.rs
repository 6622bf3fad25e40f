//! The pose sample's IMU quantities against independent references (ω and
//! s read back through the sensor model of [`super::super::predict`], ω̇ and
//! dz/dt by central differences in time), and the IMU-side effects'
//! columns on a pose sample against finite differences of their exact
//! forms or an independent lever-arm construction.

use super::*;
use crate::effects::{self, CatalogueSetup, ImuExactContext, MassModel, SessionSpan};
use crate::geom::{exp_so3, inverse3, mul_mm, mul_mv};
use crate::pose_measurement::{pose_param_specs, predict, ACCEL, GYRO};
use crate::spline::Knots;

fn spline() -> PoseSpline {
    let knots = Knots::uniform(0.0, 4.0, 0.3, 3).unwrap();
    let m = knots.num_coeffs();
    let pos: Vec<V3> = (0..m)
        .map(|k| {
            let a = k as f64;
            [0.3 * (0.7 * a).sin(), 0.2 * (1.1 * a).cos(), 0.1 * a.sin()]
        })
        .collect();
    let mut r = exp_so3([0.3, -1.0, 2.0]);
    let rot: Vec<M3> = (0..m)
        .map(|k| {
            let a = k as f64;
            r = mul_mm(&r, &exp_so3([0.5 * a.sin(), 0.4 * (2.0 * a).cos(), -0.3]));
            r
        })
        .collect();
    PoseSpline::new(knots, &pos, &rot).unwrap()
}

fn x() -> Vec<f64> {
    let mut x: Vec<f64> = pose_param_specs([2.5, -0.4, 1.0], [-2.0, 0.3, -0.8])
        .iter()
        .map(|s| s.nominal)
        .collect();
    x[..6].copy_from_slice(&[0.05, -0.12, 0.08, 0.3, -0.2, 0.1]);
    for (k, v) in x[ACCEL..].iter_mut().enumerate() {
        *v += 0.01 * (k as f64 + 1.0).sin();
    }
    x
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

/// ω and s from z through the sensor model: v = M⁻¹ (z − b).
fn read_back(z: &[f64; 6], x: &[f64]) -> (V3, V3) {
    let (acc, gyr) = intrinsics(x);
    let un = |m: M3, b: V3, z: &[f64]| {
        mul_mv(
            &inverse3(&m).unwrap(),
            [z[0] - b[0], z[1] - b[1], z[2] - b[2]],
        )
    };
    (
        un(gyr.matrix(), gyr.b, &z[3..]),
        un(acc.matrix(), acc.b, &z[..3]),
    )
}

#[test]
fn the_pose_sample_gives_the_imus_own_quantities() {
    let (sp, x) = (spline(), x());
    for t in [0.8, 1.7, 2.9] {
        let s = PoseImuSample::at(&sp, t, &x).unwrap();
        let z = predict(&sp, t, &x).unwrap();
        let (w, f) = read_back(&z, &x);
        let i = s.inertial();
        let h = 1e-5;
        let (zp, zm) = (
            predict(&sp, t + h, &x).unwrap(),
            predict(&sp, t - h, &x).unwrap(),
        );
        let (wp, wm) = (read_back(&zp, &x).0, read_back(&zm, &x).0);
        for c in 0..3 {
            assert!(close(i.omega[c], w[c], 1e-9), "ω {c} at {t}");
            assert!(close(i.s[c], f[c], 1e-9), "s {c} at {t}");
            let wd = (wp[c] - wm[c]) / (2.0 * h);
            assert!(close(i.omega_dot[c], wd, 1e-5), "ω̇ {c} at {t}");
        }
        for c in 0..6 {
            let d = (zp[c] - zm[c]) / (2.0 * h);
            assert!(close(s.dz_dt()[c], d, 1e-5), "dz/dt {c} at {t}");
        }
        assert_eq!(s.accel_matrix(), intrinsics(&x).0.matrix());
    }
}

fn setup() -> CatalogueSetup {
    let span = SessionSpan { t0: 0.5, t1: 3.5 };
    CatalogueSetup::new(span, MassModel::none(), G0, None)
}

/// Columns of the IMU-side effects on a pose sample against central
/// differences of their exact forms in θ_e ([`Effect::imu_exact`], with
/// the pose session's baseline z): exact for the additive ones, the warped
/// clock and the delayed accelerometer for clock_drift and sensor_delay.
#[test]
fn imu_side_columns_match_their_exact_forms_on_a_pose_sample() {
    let (sp, x) = (spline(), x());
    let z_at = |s: f64| predict(&sp, s - x[TAU], &x).unwrap();
    for e in effects::catalogue(&setup()) {
        let k = e.params().len();
        let t = 2.1;
        let s = PoseImuSample::at(&sp, t, &x).unwrap();
        let mut cols = vec![[0.0; 6]; k];
        let imu_side = e.imu_columns(&s, &mut cols);
        let ctx = ImuExactContext {
            t,
            tau: x[TAU],
            z_at: &z_at,
            imu: &s,
        };
        if !imu_side {
            assert!(e.imu_exact(&ctx, &vec![0.0; k]).is_none(), "{}", e.name());
            continue;
        }
        for j in 0..k {
            let h = 1e-3 * e.params()[j].prior_sigma;
            let mut th = vec![0.0; k];
            th[j] = h;
            let zp = e.imu_exact(&ctx, &th).unwrap();
            th[j] = -h;
            let zm = e.imu_exact(&ctx, &th).unwrap();
            for c in 0..6 {
                let d = (zp[c] - zm[c]) / (2.0 * h);
                assert!(
                    (cols[j][c] - d).abs() <= 1e-5 * (1.0 + d.abs()),
                    "{} θ {j} channel {c}: {} vs {d}",
                    e.name(),
                    cols[j][c]
                );
            }
        }
    }
}

/// The joint-side effects do not apply to a pose sample; the IMU-side ones do.
#[test]
fn the_imu_side_effects_are_the_per_sensor_ones_without_the_joints() {
    let (sp, x) = (spline(), x());
    let s = PoseImuSample::at(&sp, 1.0, &x).unwrap();
    let applies: Vec<&str> = effects::catalogue(&setup())
        .iter()
        .filter(|e| e.imu_columns(&s, &mut vec![[0.0; 6]; e.params().len()]))
        .map(|e| e.name())
        .collect();
    assert_eq!(
        applies,
        [
            "g_sensitivity",
            "size_effect",
            "clock_drift",
            "sensor_delay",
            "bias_drift"
        ]
    );
}

/// size_effect's columns against the lever arm built independently: the
/// specific force of the point p_I + r read through the model (p_I moved
/// by r), less that of p_I, through M_a.
#[test]
fn size_effect_columns_are_the_lever_arms_specific_force() {
    let (sp, x) = (spline(), x());
    let e = effects::by_name(&setup(), "size_effect").unwrap();
    let t = 1.3;
    let s = PoseImuSample::at(&sp, t, &x).unwrap();
    let mut cols = vec![[0.0; 6]; 6];
    assert!(e.imu_columns(&s, &mut cols));
    let f0 = read_back(&predict(&sp, t, &x).unwrap(), &x).1;
    let ma = intrinsics(&x).0.matrix();
    for (a, row) in [1usize, 2].into_iter().enumerate() {
        for c in 0..3 {
            let mut xr = x.clone();
            xr[P_IMU + c] += 1.0;
            let f1 = read_back(&predict(&sp, t, &xr).unwrap(), &x).1;
            let d = mul_mv(&ma, sub(f1, f0));
            assert!(close(cols[3 * a + c][row], d[row], 1e-9), "r_{row} {c}");
        }
    }
    let _ = GYRO;
}
