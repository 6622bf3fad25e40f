//! Trajectory planning (paper §7) and identifiability (§8.2): the limits hold
//! at every 1 kHz sample of the exported plan, the information matches an
//! independent per-sample sum, and the plan beats random trajectories.

use faer::Mat;
use rand::SeedableRng;
use robimu_model::trajectory::from_samples;
use robimu_model::{JointState, MeasurementJacobians, MeasurementModel, ParamLayout, Robot};
use robimu_workflows::identifiability::{baseline, median, Baseline};
use robimu_workflows::plan::information::{lambda_max, Information, Sampling};
use robimu_workflows::plan::{check_limits, plan, PlanOptions, SplineFile};

mod common;
use common::{robimu, robimu_ok, s};

fn short(duration: f64) -> PlanOptions {
    PlanOptions {
        duration,
        evaluations: 120,
        ..PlanOptions::default()
    }
}

#[test]
fn exported_plan_respects_every_limit_at_1khz() {
    let dir = std::env::temp_dir().join(format!("robimu-plan-test-{}", std::process::id()));
    robimu_ok([
        "plan",
        "--duration",
        "40",
        "--evaluations",
        "60",
        "--out",
        s(&dir),
    ]);
    let robot = Robot::aubo_i5();
    // the spline as written
    let text = std::fs::read_to_string(dir.join("spline.toml")).unwrap();
    let file: SplineFile = toml::from_str(&text).unwrap();
    let spline = file.spline().unwrap();
    check_limits(&robot, &spline, 1000.0).unwrap();
    // plan.csv (250 Hz) as a robot would take it, refitted and sampled at 1 kHz
    let csv = std::fs::read_to_string(dir.join("plan.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "t,q1,q2,q3,q4,q5,q6");
    let (mut t, mut q) = (Vec::new(), Vec::new());
    for l in lines {
        let v: Vec<f64> = l.split(',').map(|s| s.parse().unwrap()).collect();
        t.push(v[0]);
        q.extend_from_slice(&v[1..]);
    }
    assert!((t[1] - t[0] - 0.004).abs() < 1e-9 && (t.last().unwrap() - 40.0).abs() < 1e-9);
    let refit = from_samples(6, &t, &q).unwrap();
    let mut js = JointState::default();
    let mut moved = [0.0f64; 6];
    for k in 0..=40_000 {
        let tk = k as f64 * 1e-3;
        refit.evaluate(tk, &mut js).unwrap();
        for (j, lim) in robot.limits().iter().enumerate() {
            assert!(js.q[j] >= lim.q_min && js.q[j] <= lim.q_max, "q{j} at {tk}");
            // the refit may ring by a hair; the plan itself is checked exactly above
            assert!(
                js.qd[j].abs() <= lim.qd_max * 1.001,
                "qd{j} {} at {tk}",
                js.qd[j]
            );
            assert!(
                js.qdd[j].abs() <= lim.qdd_max * 1.01,
                "qdd{j} {} at {tk}",
                js.qdd[j]
            );
            moved[j] = moved[j].max(js.qd[j].abs() / lim.qd_max);
        }
    }
    // at rest at both ends; and it uses the speed it is allowed
    for te in [0.0, 40.0] {
        spline.evaluate(te, &mut js).unwrap();
        assert!(js.qd[..6].iter().all(|v| v.abs() < 1e-12));
        assert!(js.qdd[..6].iter().all(|v| v.abs() < 1e-12));
    }
    assert!(moved.iter().all(|&m| m > 0.5), "{moved:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Λ from an independent per-sample loop over the measurement Jacobians.
fn direct_information(robot: &Robot, spline: &robimu_model::Spline, rate: f64) -> Mat<f64> {
    let layout = ParamLayout::new(robot);
    let model = MeasurementModel::new(robot, &layout, &layout.nominal()).unwrap();
    let np = layout.len();
    let s = layout.sigmas();
    let sz = robot.sigma_z();
    let mut lam = Mat::from_fn(
        np,
        np,
        |i, j| if i == j { 1.0 / (s[i] * s[i]) } else { 0.0 },
    );
    let mut js = JointState::default();
    let mut jac = MeasurementJacobians::new(np);
    let t1 = spline.knots().end();
    let count = (t1 * rate + 1e-9).floor() as usize;
    for k in 0..=count {
        spline.evaluate(k as f64 / rate, &mut js).unwrap();
        model.jacobians(&js, &mut jac);
        for a in 0..np {
            for b in 0..np {
                let mut v = 0.0;
                for (r, s) in sz.iter().enumerate() {
                    v += jac.dz_dx[a][r] * jac.dz_dx[b][r] / (s * s);
                }
                lam[(a, b)] += v;
            }
        }
    }
    lam
}

#[test]
fn information_matches_a_direct_sum_and_the_quadrature_is_close() {
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let s = baseline(&robot, Baseline::RandomWalk, 20.0, &mut rng).unwrap();
    let info = Information::new(&robot, robot.sigma_z(), 50.0).unwrap();
    let exact = info.total(&s, 1.0, Sampling::Exact);
    let direct = direct_information(&robot, &s, 50.0);
    let np = info.dim();
    for a in 0..np {
        for b in 0..np {
            let scale = (direct[(a, a)] * direct[(b, b)]).sqrt();
            assert!(
                (exact[(a, b)] - direct[(a, b)]).abs() <= 1e-9 * scale,
                "({a},{b})"
            );
        }
    }
    // split into blocks = whole (additivity, eq. (30))
    let mut split = info.prior();
    for (a, b, last) in [(0.0, 7.3, false), (7.3, 12.0, false), (12.0, 20.0, true)] {
        info.accumulate(&s, a, b, last, 1.0, Sampling::Exact, &mut split);
    }
    let all: Vec<usize> = (0..np).collect();
    let l = lambda_max(&exact, &all);
    assert!((lambda_max(&split, &all) / l - 1.0).abs() < 1e-9);
    // the planner's 20 per second quadrature gives the same measure within 3 %
    let quad = info.total(&s, 1.0, Sampling::Quadrature(20.0));
    assert!(
        (lambda_max(&quad, &all) / l - 1.0).abs() < 0.03,
        "{} vs {l}",
        lambda_max(&quad, &all)
    );
}

#[test]
fn time_scaling_matches_a_resampled_faster_trajectory() {
    // the speed study's q̇·s, q̈·s² against a spline that really is s times faster
    let robot = Robot::aubo_i5();
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    let s = baseline(&robot, Baseline::RandomWalk, 16.0, &mut rng).unwrap();
    let file = SplineFile::of(&s);
    let mut fast = file.clone();
    fast.knots.iter_mut().for_each(|y| *y /= 4.0);
    let fast = fast.spline().unwrap();
    let slow = Information::new(&robot, robot.sigma_z(), 30.0).unwrap();
    let quick = Information::new(&robot, robot.sigma_z(), 120.0).unwrap();
    let a = slow.total(&s, 4.0, Sampling::Exact);
    let b = quick.total(&fast, 1.0, Sampling::Exact);
    let all: Vec<usize> = (0..slow.dim()).collect();
    assert!((lambda_max(&a, &all) / lambda_max(&b, &all) - 1.0).abs() < 1e-6);
}

#[test]
fn a_plan_beats_both_random_baselines() {
    let robot = Robot::aubo_i5();
    let p = plan(&robot, &short(60.0), |_, _, _| {}).unwrap();
    check_limits(&robot, &p.spline, 1000.0).unwrap();
    // the measure decreases with time and matches a fresh evaluation
    assert!(p.lambda_max.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-9)));
    let info = Information::new(&robot, robot.sigma_z(), 120.0).unwrap();
    let all: Vec<usize> = (0..info.dim()).collect();
    let fresh = lambda_max(&info.total(&p.spline, 1.0, Sampling::Exact), &all);
    assert!((fresh / p.lambda_max.last().unwrap() - 1.0).abs() < 1e-9);
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let mut uni = Vec::new();
    let mut walk = Vec::new();
    for _ in 0..3 {
        let u = baseline(&robot, Baseline::Uniform, 60.0, &mut rng).unwrap();
        check_limits(&robot, &u, 200.0).unwrap();
        uni.push(lambda_max(&info.total(&u, 1.0, Sampling::Exact), &all));
        let w = baseline(&robot, Baseline::RandomWalk, 60.0, &mut rng).unwrap();
        walk.push(lambda_max(&info.total(&w, 1.0, Sampling::Exact), &all));
    }
    assert!(
        median(&uni) > 15.0 * fresh,
        "uniform {uni:?} vs plan {fresh}"
    );
    assert!(median(&walk) > 2.0 * fresh, "walk {walk:?} vs plan {fresh}");
}

#[test]
fn bad_options_are_refused_with_the_cause() {
    let robot = Robot::aubo_i5();
    let mut o = short(60.0);
    o.knot_spacing = 0.2;
    let e = plan(&robot, &o, |_, _, _| {}).unwrap_err().to_string();
    assert!(e.contains("knot spacing") && e.contains("joint 4"), "{e}");
    let e = plan(&robot, &short(2.0), |_, _, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("no free coefficients"), "{e}");
    let out = robimu(["identifiability", "--plan", "/nonexistent-plan-dir"]);
    assert!(!out.success());
    let err = &out.stderr;
    assert!(
        err.contains("no spline.toml or plan.csv") && !err.contains("panicked"),
        "{err}"
    );
}
