//! [`Problem::window_gradients`]: the windows' gradients add up to the
//! assembled gradient of every row (the priors left out), white and GLS.

use robimu_model::effects::EffectSet;

use crate::LeastSquares;

use super::gls_tests::{build, linearized, noise_model, options, setup};

#[test]
fn window_gradients_add_up_to_the_gradient_without_the_priors() {
    let s = setup();
    for noise in [None, Some(noise_model())] {
        let mut opts = options(&s, noise, [0.05; 6]);
        opts.use_prior = false;
        let mut p = build(&s, &opts, EffectSet::none());
        let theta = p.theta(&s.spline, &s.x);
        p.begin_iteration(&theta).unwrap();
        let (_, g, _) = linearized(&p, &theta);
        // windows cutting through knot spans and the gap, beyond both ends
        let edges = [-1.0, 0.31, 0.5, 0.557, 0.8, 2.0];
        let mut sum = vec![0.0; g.len()];
        let mut count = 0;
        p.window_gradients(&theta, &edges, |w, gw| {
            assert_eq!(w, count);
            count += 1;
            assert!(gw.iter().any(|v| *v != 0.0), "window {w} is empty");
            for (a, b) in sum.iter_mut().zip(gw) {
                *a += b;
            }
        })
        .unwrap();
        assert_eq!(count, edges.len() - 1);
        let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (k, (a, b)) in sum.iter().zip(&g).enumerate() {
            assert!((a - b).abs() <= 1e-9 * scale, "{k}: {a} vs {b}");
        }
    }
}
