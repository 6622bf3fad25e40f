//! The body rate the nominal model predicts, on a uniform time grid, and its
//! linear interpolation (the τ search's ω(t), docs/model.md §6.5).
//!
//! The nodes are evaluated once, by the trajectory's span polynomials
//! ([`SpanPolynomials`]: a few Horner steps per node instead of the
//! Cox–de Boor table) and the chain's rotations alone ([`BodyRate`]: ω of
//! docs/model.md §1.5 from q and q̇, bit for bit the ω of
//! `MeasurementModel::inertial`), the two halves on two threads.

use crate::body_rate::BodyRate;
use robimu_model::lanes::{quads, F64x4};
use robimu_model::{SpanPolynomials, Spline, MAX_JOINTS};

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
        let dim = trajectory.dim();
        // four nodes at a time, one per lane of BodyRate::imu_x4 (the bits
        // of four BodyRate::imu calls)
        // (ω of node first + i into out[i][..3])
        let nodes = |first: usize, out: &mut [[f64; 6]]| {
            // q and q̇ (ω needs no q̈)
            let mut rows = [[F64x4::splat(0.0); MAX_JOINTS]; 2];
            let mut hint = 0;
            for (quad, len) in quads(first..first + out.len()) {
                let u = F64x4(quad.map(|k| (t0 + k as f64 * h).min(t1)));
                let inside = trajectory.rows_x4(&spans, u, [0, 1], &mut hint, &mut rows);
                let w = rate.imu_x4(&rows[0][..dim], &rows[1][..dim]);
                for l in 0..len {
                    let at = quad[l] - first;
                    out[at][..3].copy_from_slice(if inside[l] { &w[l] } else { &[0.0; 3] });
                }
            }
        };
        // the two halves on two threads, each writing its part in place
        let mut grid = vec![[0.0; 6]; steps + 1];
        let mid = steps.div_ceil(2);
        let (first, second) = grid.split_at_mut(mid);
        robimu_model::pair::join(|| nodes(0, first), || nodes(mid, second));
        Self::with_differences(t0, t1, h, grid)
    }

    /// The grid of the values `nodes` at t0 + k·h (the last at t1), k =
    /// 0..=steps with steps = ⌈(t1 − t0)/h⌉.
    ///
    /// # Panics
    /// If there are not steps + 1 nodes.
    #[cfg(test)]
    #[track_caller]
    pub fn from_nodes(t0: f64, t1: f64, h: f64, nodes: Vec<[f64; 3]>) -> Self {
        let nodes = nodes
            .iter()
            .map(|p| [p[0], p[1], p[2], 0.0, 0.0, 0.0])
            .collect();
        Self::with_differences(t0, t1, h, nodes)
    }

    /// The grid of the values `nodes[k][..3]` at t0 + k·h (the last at t1),
    /// their differences to the next node written into `nodes[k][3..]`.
    #[track_caller]
    fn with_differences(t0: f64, t1: f64, h: f64, mut nodes: Vec<[f64; 6]>) -> Self {
        let steps = ((t1 - t0) / h).ceil() as usize;
        assert_eq!(nodes.len(), steps + 1, "one node per grid point");
        for k in 0..=steps {
            let q = nodes[(k + 1).min(steps)];
            let p = &mut nodes[k];
            for a in 0..3 {
                p[3 + a] = q[a] - p[a];
            }
        }
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
