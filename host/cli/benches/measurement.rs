//! Per-sample cost of the measurement model (release: `cargo bench -p robimu --bench measurement`).
//!
//! AUBO i5, x of 48, 36 000 IMU samples (120 Hz × 300 s) along a cubic spline
//! with 1 s knots. Reports ns per sample for: spline evaluation (q..q⃛),
//! z only, z + all Jacobians (analytic), the same four samples at a time
//! (F64x4 lanes, the assembly's path), and z + Jacobians by forward-mode jets.

use std::hint::black_box;
use std::time::Instant;

use robimu_model::jet::Jet;
use robimu_model::measurement::predict_generic;
use robimu_model::{
    F64x4, JointState, Knots, MeasurementJacobians, MeasurementModel, ParamLayout, Robot, Spline,
};

fn main() {
    let robot = Robot::aubo_i5();
    let layout = ParamLayout::new(&robot);
    let x: Vec<f64> = layout
        .specs()
        .iter()
        .enumerate()
        .map(|(i, s)| s.nominal + 0.5 * s.sigma * ((i as f64) * 0.7).sin())
        .collect();
    let model = MeasurementModel::new(&robot, &layout, &x).expect("valid x");
    let knots = Knots::uniform(0.0, 300.0, 1.0, 3).expect("valid knots");
    let m = knots.num_coeffs();
    let coeffs: Vec<f64> = (0..m * 6)
        .map(|k| 0.8 * ((k as f64) * 1.37).sin())
        .collect();
    let spline = Spline::new(knots, 6, coeffs).expect("valid spline");
    let n = 36_000;
    let times: Vec<f64> = (0..n).map(|i| i as f64 / 120.0).collect();

    // Timed in short chunks; the minimum over chunks is robust to preemption on
    // a shared machine, the median shows the typical figure.
    let time = |label: &str, samples: usize, f: &mut dyn FnMut(usize, usize)| {
        let chunk = 250.min(samples);
        f(0, chunk); // warm-up
        let mut per: Vec<f64> = Vec::new();
        for _ in 0..4 {
            for start in (0..samples - chunk + 1).step_by(chunk) {
                let t0 = Instant::now();
                f(start, start + chunk);
                per.push(t0.elapsed().as_secs_f64() * 1e9 / chunk as f64);
            }
        }
        per.sort_by(f64::total_cmp);
        println!(
            "{label:<46} min {:>8.1} ns/sample, median {:>8.1}",
            per[0],
            per[per.len() / 2]
        );
    };

    let mut states = vec![JointState::default(); n];
    time("spline evaluate (q, qd, qdd, qddd)", n, &mut |a, b| {
        for (s, &t) in states[a..b].iter_mut().zip(&times[a..b]) {
            spline.evaluate(black_box(t), s).expect("in range");
        }
    });
    time("z only (predict)", n, &mut |a, b| {
        let mut acc = 0.0;
        for s in &states[a..b] {
            acc += model.predict(black_box(s))[0];
        }
        black_box(acc);
    });
    let mut jac = MeasurementJacobians::new(layout.len());
    time(
        "z + dz/dx (48) + dz/dq,dq',dq'' (analytic)",
        n,
        &mut |a, b| {
            for s in &states[a..b] {
                model.jacobians(black_box(s), &mut jac);
                black_box(&jac);
            }
        },
    );
    // four samples in the lanes of F64x4 (the assembly's path), per sample
    let quads: Vec<JointState<F64x4>> = states
        .chunks_exact(4)
        .map(|c| {
            let mut q = JointState::<F64x4>::default();
            for (l, s) in c.iter().enumerate() {
                for j in 0..6 {
                    q.q[j].0[l] = s.q[j];
                    q.qd[j].0[l] = s.qd[j];
                    q.qdd[j].0[l] = s.qdd[j];
                    q.qddd[j].0[l] = s.qddd[j];
                }
            }
            q
        })
        .collect();
    time("z only, four lanes (predict_x4)", n, &mut |a, b| {
        let mut acc = 0.0;
        for q in &quads[a / 4..b / 4] {
            acc += model.predict_x4(black_box(q))[0].lane(0);
        }
        black_box(acc);
    });
    let mut jac4 = MeasurementJacobians::<F64x4>::zeros(layout.len());
    time(
        "z + all Jacobians, four lanes (jacobians_x4)",
        n,
        &mut |a, b| {
            for q in &quads[a / 4..b / 4] {
                model.jacobians_x4(black_box(q), &mut jac4);
                black_box(&jac4);
            }
        },
    );
    let pj = layout
        .unpack(
            &x.iter()
                .enumerate()
                .map(|(i, &v)| Jet::<66>::variable(v, i))
                .collect::<Vec<_>>(),
        )
        .expect("valid x");
    let nj = 2_000;
    time("z + Jacobians by Jet<66> (reference)", nj, &mut |a, b| {
        for s in &states[a..b] {
            let v = |o: usize, a: &[f64]| -> [Jet<66>; 6] {
                core::array::from_fn(|j| Jet::variable(a[j], o + j))
            };
            let z = predict_generic(
                robot.links(),
                robot.gravity(),
                &pj,
                &v(48, &s.q),
                &v(54, &s.qd),
                &v(60, &s.qdd),
            )
            .expect("valid gravity");
            black_box(z);
        }
    });
}
