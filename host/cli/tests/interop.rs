//! Working with other tools (issue 5, items 1–2): robots from URDF, the
//! calibrated robot as URDF and robot TOML, the IMU correction and
//! `robimu correct`.

#![allow(clippy::needless_range_loop)]

use std::path::{Path, PathBuf};

use nalgebra::{Matrix4, Rotation3, Translation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use robimu_model::geom::Iso;
use robimu_model::kinematics::{forward_kinematics, JointState};
use robimu_model::measurement::predict_generic;
use robimu_model::urdf::{parse_joints, robot_from_urdf_str, UrdfOptions};
use robimu_model::{ImuIntrinsics, MeasurementJacobians, MeasurementModel, ParamLayout, Robot};
use robimu_session::export::imu::{correct_rows, inverse, Correction};
use robimu_session::export::robot::{corrected_toml, corrected_urdf};
use robimu_workflows::simulate::{random_session, SimulateOptions};

mod common;
use common::{robimu, robimu_ok};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn read(name: &str) -> String {
    std::fs::read_to_string(fixture(name)).unwrap()
}

/// x drawn from the priors (every parameter perturbed).
fn random_x(layout: &ParamLayout, rng: &mut impl Rng) -> Vec<f64> {
    layout
        .specs()
        .iter()
        .map(|s| s.nominal + s.sigma * rng.random_range(-2.0..2.0))
        .collect()
}

fn random_state(robot: &Robot, rng: &mut impl Rng) -> JointState {
    let n = robot.dof();
    let mut v = |a: f64| (0..n).map(|_| rng.random_range(-a..a)).collect::<Vec<_>>();
    let (q, qd, qdd, qddd) = (v(2.5), v(1.0), v(3.0), v(5.0));
    JointState::from_slices(&q, &qd, &qdd, &qddd)
}

fn urdf_aubo() -> Robot {
    let (robot, chain) =
        robot_from_urdf_str(&read("aubo_i5.urdf"), &UrdfOptions::default()).unwrap();
    assert_eq!(
        (chain.base.as_str(), chain.tip.as_str()),
        ("base_link", "flange")
    );
    robot
        .with_estimated_errors(Robot::aubo_i5().estimated_errors().to_vec())
        .unwrap()
}

#[test]
fn urdf_aubo_predicts_the_same_imu_signals_as_the_builtin_dh_model() {
    let dh = Robot::aubo_i5();
    let urdf = urdf_aubo();
    assert_eq!(urdf.dof(), 6);
    // Limits carried over from the URDF; acceleration: the documented default.
    for (a, b) in dh.limits().iter().zip(urdf.limits()) {
        assert!((a.q_min - b.q_min).abs() < 1e-15 && (a.q_max - b.q_max).abs() < 1e-15);
        assert!((a.qd_max - b.qd_max).abs() < 1e-15);
        assert!((b.qdd_max - 100f64.to_radians()).abs() < 1e-15);
    }
    // Every joint goes through the general (non-DH) path.
    assert!(urdf.chain().iter().all(|l| l.fixed.is_some()));
    let layout_dh = ParamLayout::new(&dh);
    let layout_urdf = ParamLayout::new(&urdf);
    assert_eq!(layout_dh.specs(), layout_urdf.specs());
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut worst: f64 = 0.0;
    for _ in 0..20 {
        let x = random_x(&layout_dh, &mut rng);
        let m_dh = MeasurementModel::new(&dh, &layout_dh, &x).unwrap();
        let m_urdf = MeasurementModel::new(&urdf, &layout_urdf, &x).unwrap();
        for _ in 0..25 {
            let js = random_state(&dh, &mut rng);
            let (a, b) = (m_dh.predict(&js), m_urdf.predict(&js));
            for c in 0..6 {
                worst = worst.max((a[c] - b[c]).abs());
            }
        }
    }
    println!("URDF vs DH AUBO i5: max |Δz| = {worst:.2e}");
    assert!(worst < 1e-9, "max |Δz| = {worst:e}");
}

#[test]
fn jacobians_of_a_urdf_robot_match_finite_differences() {
    let (robot, _) = robot_from_urdf_str(
        &read("axes_3r.urdf"),
        &UrdfOptions {
            tip: Some("tool0".into()),
            ..UrdfOptions::default()
        },
    )
    .unwrap();
    // Every generalized error estimated except the fixed IMU rotation.
    let all: Vec<_> = (1..=3)
        .flat_map(|l| (1..=6).map(move |k| [l, k]))
        .filter(|&[l, k]| !(l == 3 && k >= 4))
        .map(robimu_model::ErrorIndex::from)
        .collect();
    let robot = robot.with_estimated_errors(all).unwrap();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let x = random_x(&layout, &mut rng);
    let js = random_state(&robot, &mut rng);
    let model = MeasurementModel::new(&robot, &layout, &x).unwrap();
    let mut jac = MeasurementJacobians::new(model.n_params());
    model.jacobians(&js, &mut jac);
    // The eq. (4) recursion over the same chain agrees with the fast model.
    let generic = predict_generic(
        robot.chain(),
        robot.gravity(),
        &layout.unpack(&x).unwrap(),
        &js.q[..3],
        &js.qd[..3],
        &js.qdd[..3],
    )
    .unwrap();
    for c in 0..6 {
        assert!(
            (generic[c] - jac.z[c]).abs() < 1e-12,
            "{generic:?} vs {:?}",
            jac.z
        );
    }
    let h = 1e-6;
    let tau = layout.offsets().tau;
    for k in 0..x.len() {
        if k == tau {
            continue; // ∂z/∂τ is the chain rule through q(t): not an x-only derivative
        }
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[k] += h;
        xm[k] -= h;
        let zp = MeasurementModel::new(&robot, &layout, &xp)
            .unwrap()
            .predict(&js);
        let zm = MeasurementModel::new(&robot, &layout, &xm)
            .unwrap()
            .predict(&js);
        for c in 0..6 {
            let fd = (zp[c] - zm[c]) / (2.0 * h);
            let an = jac.dz_dx[k][c];
            assert!(
                (fd - an).abs() < 1e-5 * (1.0 + an.abs()),
                "{} channel {c}: analytic {an} vs FD {fd}",
                layout.specs()[k].name
            );
        }
    }
}

/// URDF forward kinematics written independently with nalgebra: the product
/// of joint origins and axis–angle rotations from the base link to `tip`.
fn urdf_fk_nalgebra(text: &str, base: &str, tip: &str, q: &[f64]) -> Matrix4<f64> {
    let (_, joints) = parse_joints(text).unwrap();
    let mut chain = Vec::new();
    let mut cur = tip.to_string();
    while cur != base {
        let j = joints.iter().find(|j| j.child == cur).unwrap();
        chain.push(j.clone());
        cur = j.parent.clone();
    }
    chain.reverse();
    let mut m = Matrix4::identity();
    let mut qi = q.iter();
    for j in &chain {
        let o = &j.origin;
        let rot = Rotation3::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]);
        m = m
            * Translation3::new(o.xyz[0], o.xyz[1], o.xyz[2]).to_homogeneous()
            * rot.to_homogeneous();
        if j.kind != "fixed" {
            let axis = Unit::new_normalize(Vector3::new(j.axis[0], j.axis[1], j.axis[2]));
            m *= Rotation3::from_axis_angle(&axis, *qi.next().unwrap()).to_homogeneous();
        }
    }
    m
}

fn iso_to_na(t: &Iso) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    for i in 0..3 {
        for j in 0..3 {
            m[(i, j)] = t.r[i][j];
        }
        m[(i, 3)] = t.p[i];
    }
    m
}

fn max_diff(a: &Matrix4<f64>, b: &Matrix4<f64>) -> f64 {
    (a - b).abs().max()
}

#[test]
fn urdf_import_reproduces_urdf_forward_kinematics_for_general_axes() {
    let text = read("axes_3r.urdf");
    // Two leaves (tool0, finger): the tip must be named.
    let e = robot_from_urdf_str(&text, &UrdfOptions::default()).unwrap_err();
    assert!(e.to_string().contains("--tip"), "{e}");
    let opts = UrdfOptions {
        base: Some("world".into()),
        tip: Some("tool0".into()),
        ..UrdfOptions::default()
    };
    let (robot, _) = robot_from_urdf_str(&text, &opts).unwrap();
    assert_eq!(robot.dof(), 3);
    // continuous joint: ±π
    assert!((robot.limits()[1].q_max - std::f64::consts::PI).abs() < 1e-15);
    // The model's base is joint 1's frame: model pose = B⁻¹·URDF pose with
    // B = URDF pose of that frame, found at q = 0 from the two.
    let zero = [[0.0; 6]; 3];
    let b = urdf_fk_nalgebra(&text, "world", "tool0", &[0.0; 3])
        * iso_to_na(&forward_kinematics(robot.chain(), &zero, &[0.0; 3]))
            .try_inverse()
            .unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    for _ in 0..50 {
        let q: Vec<f64> = (0..3).map(|_| rng.random_range(-2.0..2.0)).collect();
        let model = b * iso_to_na(&forward_kinematics(robot.chain(), &zero, &q));
        let urdf = urdf_fk_nalgebra(&text, "world", "tool0", &q);
        assert!(max_diff(&model, &urdf) < 1e-12, "q {q:?}\n{model}\n{urdf}");
    }
}

/// Generalized errors on every link (the IMU mount: translation only).
fn random_params(robot: &Robot, rng: &mut impl Rng) -> robimu_model::ModelParams {
    let layout = ParamLayout::new(robot);
    let mut p = layout.unpack(&random_x(&layout, rng)).unwrap();
    let n = robot.dof();
    for (i, e) in p.eps.iter_mut().enumerate() {
        for (k, v) in e.iter_mut().enumerate() {
            if i + 1 == n {
                if k < 3 {
                    *v = [0.03, -0.07, 0.02][k] + rng.random_range(-0.01..0.01);
                }
            } else {
                *v = rng.random_range(-0.02..0.02);
            }
        }
    }
    p
}

#[test]
fn corrected_urdf_and_toml_reimport_to_the_calibrated_kinematics() {
    for (file, tip) in [("aubo_i5.urdf", None), ("axes_3r.urdf", Some("tool0"))] {
        let text = read(file);
        let opts = UrdfOptions {
            tip: tip.map(str::to_string),
            ..UrdfOptions::default()
        };
        let (robot, _) = robot_from_urdf_str(&text, &opts).unwrap();
        let n = robot.dof();
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let params = random_params(&robot, &mut rng);
        let corrected = corrected_urdf(&text, &opts, &params).unwrap();
        // Same names, one new link and joint.
        let (_, before) = parse_joints(&text).unwrap();
        let (_, after) = parse_joints(&corrected).unwrap();
        assert_eq!(after.len(), before.len() + 1);
        for (a, b) in before.iter().zip(&after) {
            assert_eq!(
                (&a.name, &a.parent, &a.child),
                (&b.name, &b.parent, &b.child)
            );
        }
        let (urdf_again, _) = robot_from_urdf_str(
            &corrected,
            &UrdfOptions {
                tip: Some("imu_link".into()),
                ..UrdfOptions::default()
            },
        )
        .unwrap();
        let toml_again = Robot::from_toml_str(&corrected_toml(&robot, &params).unwrap()).unwrap();
        let mut mount = vec![[0.0; 6]; n];
        mount[n - 1][..3].copy_from_slice(&toml_again.mount().position);
        let mut worst: f64 = 0.0;
        for _ in 0..50 {
            let q: Vec<f64> = (0..n).map(|_| rng.random_range(-2.5..2.5)).collect();
            let cal = iso_to_na(&forward_kinematics(robot.chain(), &params.eps, &q));
            let u = iso_to_na(&forward_kinematics(
                urdf_again.chain(),
                &vec![[0.0; 6]; n],
                &q,
            ));
            let t = iso_to_na(&forward_kinematics(toml_again.chain(), &mount, &q));
            worst = worst.max(max_diff(&cal, &u)).max(max_diff(&cal, &t));
        }
        println!("{file}: corrected URDF/TOML vs calibrated FK: max diff {worst:.2e}");
        assert!(worst < 1e-9, "{file}: {worst:e}");
    }
}

#[test]
fn corrected_toml_of_the_builtin_dh_robot_reproduces_its_calibrated_kinematics() {
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let params = random_params(&robot, &mut rng);
    let again = Robot::from_toml_str(&corrected_toml(&robot, &params).unwrap()).unwrap();
    assert_eq!(again.estimated_errors(), robot.estimated_errors());
    let mut mount = [[0.0; 6]; 6];
    mount[5][..3].copy_from_slice(&again.mount().position);
    for _ in 0..50 {
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-2.5..2.5)).collect();
        let cal = iso_to_na(&forward_kinematics(robot.chain(), &params.eps, &q));
        let t = iso_to_na(&forward_kinematics(again.chain(), &mount, &q));
        assert!(max_diff(&cal, &t) < 1e-9);
    }
}

fn random_intrinsics(rng: &mut impl Rng, bias: f64) -> ImuIntrinsics {
    let mut u = |a: f64| rng.random_range(-a..a);
    ImuIntrinsics {
        gamma: [u(0.03), u(0.03), u(0.03)],
        r: [std::f64::consts::PI + u(0.1), u(0.1), u(0.1)],
        k: [1.0 + u(0.1), 1.0 + u(0.1), 1.0 + u(0.1)],
        b: [u(bias), u(bias), u(bias)],
    }
}

#[test]
fn forward_sensor_model_then_correction_is_the_identity() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let (a, g) = (
        random_intrinsics(&mut rng, 2.0),
        random_intrinsics(&mut rng, 0.1),
    );
    let truth: Vec<[f64; 6]> = (0..1000)
        .map(|_| {
            std::array::from_fn(|c| rng.random_range(-1.0..1.0) * if c < 3 { 20.0 } else { 3.0 })
        })
        .collect();
    let raw: Vec<[f64; 6]> = truth
        .iter()
        .map(|v| {
            let (za, zw) = (a.apply([v[0], v[1], v[2]]), g.apply([v[3], v[4], v[5]]));
            [za[0], za[1], za[2], zw[0], zw[1], zw[2]]
        })
        .collect();
    let back = correct_rows(&a, &g, &raw).unwrap();
    let file = Correction::from_intrinsics(&a, &g).unwrap();
    let parsed: Correction = toml::from_str(&file.to_toml().unwrap()).unwrap();
    let mut worst: f64 = 0.0;
    for ((t, b), z) in truth.iter().zip(&back).zip(&raw) {
        let c = parsed.apply(z);
        for k in 0..6 {
            worst = worst.max((t[k] - b[k]).abs()).max((t[k] - c[k]).abs());
        }
    }
    println!("forward then inverse: max error {worst:.2e}");
    assert!(worst < 1e-12, "{worst:e}");
    assert!(inverse(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]).is_none());
}

#[test]
fn correcting_a_simulated_raw_stream_gives_the_true_signal_to_noise_level() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let opts = SimulateOptions::paper(&robot);
    let sim = random_session(&robot, 30.0, 1.0, &opts, 4).unwrap();
    let model = MeasurementModel::new(&robot, &layout, &sim.truth).unwrap();
    let p = layout.unpack(&sim.truth).unwrap();
    let tau = p.tau;
    let corrected = correct_rows(&p.accel, &p.gyro, &sim.data.imu_z).unwrap();
    // Expected σ of the corrected channels: √Σ_k (M⁻¹)_ck² σ_k².
    let sz = opts.sigma_z;
    let expect = |m: &robimu_model::geom::M3, off: usize| -> [f64; 3] {
        let mi = inverse(m).unwrap();
        std::array::from_fn(|c| {
            (0..3)
                .map(|k| (mi[c][k] * sz[off + k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
    };
    let (ea, ew) = (expect(&p.accel.matrix(), 0), expect(&p.gyro.matrix(), 3));
    let mut sum2 = [0.0; 6];
    let mut count = 0usize;
    let mut js = JointState::default();
    let (t0, t1) = (sim.trajectory.knots().start(), sim.trajectory.knots().end());
    for (t, v) in sim.data.imu_t.iter().zip(&corrected) {
        if t + tau < t0 || t + tau > t1 {
            continue;
        }
        sim.trajectory.state_at(t + tau, &mut js);
        let (_, omega, s) = model.inertial(&js);
        let truth = [s[0], s[1], s[2], omega[0], omega[1], omega[2]];
        for c in 0..6 {
            sum2[c] += (v[c] - truth[c]).powi(2);
        }
        count += 1;
    }
    assert!(count > 2000, "{count} samples in the trajectory span");
    for c in 0..6 {
        let rms = (sum2[c] / count as f64).sqrt();
        let sigma = if c < 3 { ea[c] } else { ew[c - 3] };
        println!("channel {c}: corrected − true RMS {rms:.4e}, noise σ {sigma:.4e}");
        assert!(
            (0.9..1.1).contains(&(rms / sigma)),
            "channel {c}: {rms} vs σ {sigma}"
        );
    }
}

fn m3_from(m: &robimu_model::geom::M3) -> nalgebra::Matrix3<f64> {
    nalgebra::Matrix3::from_fn(|i, j| m[i][j])
}

/// A result.json holding `x` for `robot` (the docs/model.md §8 shape).
fn write_result(dir: &Path, robot_spec: &str, layout: &ParamLayout, x: &[f64]) -> PathBuf {
    let path = dir.join("result.json");
    let mut values = x.iter();
    common::write_result_json(&path, robot_spec, layout, |_| *values.next().unwrap());
    path
}

#[test]
fn cli_export_and_correct() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = fixture("aubo_i5.urdf");
    let robot = urdf_aubo();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let x = random_x(&layout, &mut rng);
    let result = write_result(dir.path(), urdf.to_str().unwrap(), &layout, &x);
    let res = result.to_str().unwrap();
    for (format, file) in [
        ("urdf", "robot.urdf"),
        ("toml", "robot.toml"),
        ("kalibr", "imu.yaml"),
        ("correction", "correction.toml"),
    ] {
        let out = dir.path().join(file);
        let mut args = vec!["export", "--calibration", res, "--format", format];
        args.extend(["--out", out.to_str().unwrap()]);
        if format == "kalibr" {
            args.extend(["--rate", "200"]);
        }
        let run = robimu(&args);
        assert!(run.success(), "{format}: {}", run.stderr);
    }
    // The exported URDF and TOML are usable robots.
    let again = Robot::from_toml_file(dir.path().join("robot.toml")).unwrap();
    assert_eq!(again.dof(), 6);
    let text = std::fs::read_to_string(dir.path().join("robot.urdf")).unwrap();
    assert!(text.contains("imu_link") && text.contains("wrist3_joint"));
    let yaml = std::fs::read_to_string(dir.path().join("imu.yaml")).unwrap();
    for key in [
        "accelerometer_noise_density",
        "accelerometer_random_walk",
        "gyroscope_noise_density",
        "gyroscope_random_walk",
        "rostopic: /imu0",
        "update_rate: 200",
        "C_gyro_i:",
        "model: scale-misalignment",
    ] {
        assert!(yaml.contains(key), "imu.yaml lacks {key}:\n{yaml}");
    }
    // Kalibr weighs its bias motion by 1/random_walk²: never 0.
    assert!(yaml.contains("accelerometer_random_walk: 0.001"), "{yaml}");
    assert!(yaml.contains("gyroscope_random_walk: 0.0001"), "{yaml}");
    let given = dir.path().join("imu2.yaml");
    let export_kalibr = |random_walk: &str| {
        robimu(&[
            "export",
            "--calibration",
            res,
            "--format",
            "kalibr",
            "--rate",
            "200",
            "--random-walk",
            random_walk,
            "--out",
            given.to_str().unwrap(),
        ])
    };
    let run = export_kalibr("0.002,3e-5");
    assert!(run.success(), "{}", run.stderr);
    let yaml2 = std::fs::read_to_string(&given).unwrap();
    assert!(
        yaml2.contains("accelerometer_random_walk: 0.002"),
        "{yaml2}"
    );
    assert!(yaml2.contains("gyroscope_random_walk: 3e-5"), "{yaml2}");
    let run = export_kalibr("0,1e-4");
    assert!(!run.success());
    assert!(run.stderr.contains("two positive numbers"));
    // σ_ax / √200 as the accelerometer noise density (the largest σ is ax).
    let nd = 0.38 / 200f64.sqrt();
    assert!(
        yaml.contains(&format!("accelerometer_noise_density: {nd:?}")),
        "{yaml}"
    );

    // Kalibr's model a_m = M_a·a_i, ω_m = M_g·C_gyro_i·ω_i with a_i = R(T_i_b)·v
    // must reproduce robimu's K·Γ·R for both sensors.
    let p = layout.unpack(&x).unwrap();
    let rows = |indent: &str| -> Vec<Vec<f64>> {
        yaml.lines()
            .filter_map(|l| l.strip_prefix(indent)?.strip_prefix("- ["))
            .map(|l| {
                l.split(']')
                    .next()
                    .unwrap()
                    .split(',')
                    .map(|v| v.trim().parse().unwrap())
                    .collect()
            })
            .collect()
    };
    let (t_i_b, mats) = (rows("  "), rows("    "));
    assert_eq!((t_i_b.len(), mats.len()), (4, 12));
    let m3 = |r: &[Vec<f64>]| nalgebra::Matrix3::from_fn(|i, j| r[i][j]);
    let rot = m3(&t_i_b[..3]);
    let (ma, cg, mg) = (m3(&mats[0..3]), m3(&mats[6..9]), m3(&mats[9..12]));
    let (ka, kw) = (m3_from(&p.accel.matrix()), m3_from(&p.gyro.matrix()));
    assert!((ma * rot - ka).abs().max() < 1e-12, "{ma} {ka}");
    assert!((mg * cg * rot - kw).abs().max() < 1e-12, "{mg} {kw}");
    assert!(ma[(0, 1)] == 0.0 && ma[(0, 2)] == 0.0 && ma[(1, 2)] == 0.0);

    // correct: raw = forward model of known vectors; corrected = those vectors.
    let mut csv = String::from("t,ax,ay,az,gx,gy,gz,temp\n");
    let mut truth = Vec::new();
    for i in 0..50 {
        let v: [f64; 6] = std::array::from_fn(|c| ((i * 6 + c) as f64 * 0.37).sin() * 9.0);
        let (za, zw) = (
            p.accel.apply([v[0], v[1], v[2]]),
            p.gyro.apply([v[3], v[4], v[5]]),
        );
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},25\n",
            i as f64 * 0.01,
            za[0],
            za[1],
            za[2],
            zw[0],
            zw[1],
            zw[2]
        ));
        truth.push(v);
    }
    let raw = dir.path().join("raw.csv");
    std::fs::write(&raw, csv).unwrap();
    robimu_ok(&["correct", "--calibration", res, raw.to_str().unwrap()]);
    let table = robimu_session::read_table(
        &dir.path().join("raw_corrected.csv"),
        robimu_session::Columns::Fixed(&robimu_session::IMU_COLUMNS),
    )
    .unwrap();
    assert_eq!(table.len(), 50);
    for (i, v) in truth.iter().enumerate() {
        for c in 0..6 {
            assert!(
                (table.row(i)[c] - v[c]).abs() < 1e-12,
                "row {i} channel {c}"
            );
        }
    }
    // Bad input: a clear message, non-zero exit, no panic.
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "t,ax,ay\n0,1,2\n").unwrap();
    let run = robimu(&["correct", "--calibration", res, bad.to_str().unwrap()]);
    assert!(!run.success());
    let err = &run.stderr;
    assert!(
        err.contains("bad.csv") && !err.contains("panicked"),
        "{err}"
    );
    // a built-in robot exports its plain URDF, corrected
    let plain = dir.path().join("x.urdf");
    let run = robimu(&[
        "export",
        "--calibration",
        res,
        "--format",
        "urdf",
        "--robot",
        "aubo_i5",
        "--out",
        plain.to_str().unwrap(),
    ]);
    assert!(run.success(), "{}", run.stderr);
    assert!(run.stderr.contains("is not a URDF"), "{}", run.stderr);
    assert!(std::fs::read_to_string(&plain)
        .unwrap()
        .contains("imu_link"));
}

/// `export --format kalibr` of a result with g_sensitivity and size_effect
/// fitted writes Kalibr's size-effect model with A = G·R_ωᵀ and the lever
/// arms R_a·r; `--noise allan.csv` gives the noise densities N and random
/// walks K of the Allan curve σ² = N²/τ + K²τ/3 instead of placeholders.
#[test]
fn cli_kalibr_export_takes_the_fitted_effects_and_the_allan_noise() {
    let dir = tempfile::tempdir().unwrap();
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let mut rng = rand::rngs::StdRng::seed_from_u64(4);
    let x = random_x(&layout, &mut rng);
    let result = write_result(dir.path(), "aubo_i5", &layout, &x);
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    let g: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| 1e-3 * (r as f64 - c as f64 + 0.3)));
    let lever = [[8e-4, -5e-4, 3e-4], [-4e-4, 7e-4, 6e-4]];
    let axes = ['x', 'y', 'z'];
    let extra = json["parameters"].as_array_mut().unwrap();
    let mut push = |name: String, v: f64| {
        extra.push(
            serde_json::json!({"name": name, "unit": "1", "value": v, "prior": 0.0,
            "prior_sigma": 1.0, "sigma": 0.0, "frozen": true}),
        )
    };
    for r in 0..3 {
        for c in 0..3 {
            push(format!("g_sensitivity.g{}_s{}", axes[r], axes[c]), g[r][c]);
        }
    }
    for (a, arm) in ['y', 'z'].iter().zip(&lever) {
        for c in 0..3 {
            push(format!("size_effect.r{a}_{}", axes[c]), arm[c]);
        }
    }
    std::fs::write(&result, json.to_string()).unwrap();
    // An Allan curve with known N and K per sensor (accelerometer, gyro).
    let (n, k) = ([2e-3, 1e-4], [4e-4, 2e-5]);
    let mut csv = String::from("tau,ax,ay,az,gx,gy,gz\n");
    for e in 0..18 {
        let tau = 0.01 * 2f64.powi(e);
        csv.push_str(&tau.to_string());
        for c in 0..6 {
            let (n, k) = (n[c / 3] * (1.0 - 0.1 * (c % 3) as f64), k[c / 3]);
            csv.push_str(&format!(",{}", (n * n / tau + k * k * tau / 3.0).sqrt()));
        }
        csv.push('\n');
    }
    let allan = dir.path().join("allan.csv");
    std::fs::write(&allan, csv).unwrap();
    let out = dir.path().join("imu.yaml");
    let run = robimu_ok(&[
        "export",
        "--calibration",
        result.to_str().unwrap(),
        "--format",
        "kalibr",
        "--rate",
        "100",
        "--noise",
        allan.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!run.stderr.contains("placeholders"), "{}", run.stderr);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(!text.contains("PLACEHOLDERS"), "{text}");
    let y: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
    let imu = &y["imu0"];
    assert_eq!(
        imu["model"].as_str(),
        Some("scale-misalignment-size-effect")
    );
    let close = |key: &str, want: f64, tol: f64| {
        let got = imu[key].as_f64().unwrap();
        assert!((got / want - 1.0).abs() < tol, "{key}: {got} vs {want}");
    };
    close("accelerometer_noise_density", n[0], 0.03);
    close("gyroscope_noise_density", n[1], 0.03);
    close("accelerometer_random_walk", k[0], 0.05);
    close("gyroscope_random_walk", k[1], 0.05);
    let p = layout.unpack(&x).unwrap();
    let m = |v: &serde_yaml::Value| -> nalgebra::Matrix3<f64> {
        let rows: Vec<Vec<f64>> = serde_yaml::from_value(v.clone()).unwrap();
        nalgebra::Matrix3::from_fn(|i, j| rows[i][j])
    };
    let (rw, ra) = (m3_from(&p.gyro.rotation()), m3_from(&p.accel.rotation()));
    let a = m(&imu["gyroscopes"]["A"]);
    assert!((a * rw - m3_from(&g)).abs().max() < 1e-15, "{a}");
    let ry: Vec<f64> = serde_yaml::from_value(imu["accelerometers"]["ry_i"].clone()).unwrap();
    let want = ra * Vector3::from(lever[0]);
    assert!((Vector3::from_vec(ry) - want).abs().max() < 1e-15);
    // Without --noise: placeholders, said on stderr and in the file.
    let run = robimu_ok(&[
        "export",
        "--calibration",
        result.to_str().unwrap(),
        "--format",
        "kalibr",
        "--rate",
        "100",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(run.stderr.contains("placeholders"), "{}", run.stderr);
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .contains("PLACEHOLDERS"));
}
