//! The body rate the nominal model predicts, on a uniform time grid, and its
//! linear interpolation (the τ search's ω(t), docs/model.md §6.5).
//!
//! The nodes are evaluated once, by the trajectory's span polynomials
//! ([`SpanPolynomials`]: a few Horner steps per node instead of the
//! Cox–de Boor table) and the chain's rotations alone ([`BodyRate`]: ω of
//! docs/model.md §1.5 from q and q̇, bit for bit the ω of
//! `MeasurementModel::inertial`), the two halves on two threads.

use crate::body_rate::BodyRate;
use robimu_model::{Basis, SpanPolynomials, Spline, MAX_JOINTS};

/// ω at t0 + k·h, k = 0..=steps (the last node clamped to t1).
pub struct RateGrid {
    t0: f64,
    t1: f64,
    h: f64,
    /// The last node's index less one, ≥ 0.
    last: i64,
    /// ω at node k, then ω at node k + 1 minus ω at node k (the last one's 0).
    nodes: Vec<[f64; 6]>,
}

impl RateGrid {
    /// The grid of step `h` over the span of `trajectory`, ω from `rate`.
    pub fn new(rate: &BodyRate, trajectory: &Spline, h: f64) -> Self {
        let knots = trajectory.knots();
        let (t0, t1) = (knots.start(), knots.end());
        let steps = ((t1 - t0) / h).ceil() as usize;
        let spans = SpanPolynomials::new(knots);
        let (coeffs, dim) = (trajectory.coeffs(), trajectory.dim());
        // four nodes at a time, one per lane of BodyRate::imu_x4 (the bits
        // of four BodyRate::imu calls)
        let nodes = |ks: std::ops::Range<usize>| -> Vec<[f64; 3]> {
            let (mut q, mut qd) = ([[0.0; 4]; MAX_JOINTS], [[0.0; 4]; MAX_JOINTS]);
            let mut b = Basis::default();
            let mut out = Vec::with_capacity(ks.len());
            let ks: Vec<usize> = ks.collect();
            for quad in ks.chunks(4) {
                let mut inside = [false; 4];
                for l in 0..4 {
                    // a short last quad repeats its last node
                    let k = quad[l.min(quad.len() - 1)];
                    let u = (t0 + k as f64 * h).min(t1);
                    inside[l] = spans.basis(u, &mut b).is_ok();
                    // q and q̇ as Spline::evaluate_basis forms them (ω needs no q̈)
                    for (d, rows) in [&mut q, &mut qd].into_iter().enumerate() {
                        for row in rows.iter_mut().take(dim) {
                            row[l] = 0.0;
                        }
                        if !inside[l] {
                            continue;
                        }
                        for a in 0..b.count {
                            let w = b.d[d][a];
                            let c = &coeffs[(b.first + a) * dim..(b.first + a + 1) * dim];
                            for j in 0..dim {
                                rows[j][l] += w * c[j];
                            }
                        }
                    }
                }
                let w = rate.imu_x4(&q, &qd);
                for l in 0..quad.len() {
                    out.push(if inside[l] { w[l] } else { [0.0; 3] });
                }
            }
            out
        };
        let mid = steps.div_ceil(2);
        let nodes: Vec<[f64; 3]> = std::thread::scope(|s| {
            let second = s.spawn(|| nodes(mid..steps + 1));
            let mut g = nodes(0..mid);
            g.extend(second.join().expect("grid thread panicked"));
            g
        });
        Self::from_nodes(t0, t1, h, nodes)
    }

    /// The grid of the values `nodes` at t0 + k·h (the last at t1), k =
    /// 0..=steps with steps = ⌈(t1 − t0)/h⌉.
    ///
    /// # Panics
    /// If there are not steps + 1 nodes.
    #[track_caller]
    pub fn from_nodes(t0: f64, t1: f64, h: f64, nodes: Vec<[f64; 3]>) -> Self {
        let steps = ((t1 - t0) / h).ceil() as usize;
        assert_eq!(nodes.len(), steps + 1, "one node per grid point");
        let nodes = (0..nodes.len())
            .map(|k| {
                let (p, q) = (nodes[k], nodes[(k + 1).min(steps)]);
                [p[0], p[1], p[2], q[0] - p[0], q[1] - p[1], q[2] - p[2]]
            })
            .collect();
        Self {
            t0,
            t1,
            h,
            last: steps.saturating_sub(1) as i64,
            nodes,
        }
    }

    /// The span [t0, t1] the grid covers.
    pub fn span(&self) -> (f64, f64) {
        (self.t0, self.t1)
    }

    /// ω at `u` (t0 ≤ u ≤ t1, not checked) by linear interpolation.
    #[inline(always)]
    pub fn at_inside(&self, u: f64) -> [f64; 3] {
        let f = (u - self.t0) / self.h;
        // f ≥ 0: truncation is the floor
        let k = (f as i64).min(self.last);
        let a = f - k as f64;
        let p = &self.nodes[k as usize];
        [p[0] + a * p[3], p[1] + a * p[4], p[2] + a * p[5]]
    }
}
