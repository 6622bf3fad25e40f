//! The reference `r(t)`: queued segments played one after another, each
//! from where the one before ended; where the last ended once they have run.

use std::collections::VecDeque;

use super::segment::Segment;
use super::{Joints, JOINTS};

/// The queue of motions the reference plays.
#[derive(Debug)]
pub(crate) struct Reference {
    /// The queued segments with their execution ids, the running one first.
    pub(crate) queue: VecDeque<(i64, Segment)>,
    /// When the running segment started, s.
    pub(crate) front_start: f64,
    /// The reference when no segment runs.
    pub(crate) hold: Joints,
}

impl Reference {
    /// Holding `initial` from time `t`.
    pub(crate) fn new(t: f64, initial: Joints) -> Self {
        Reference {
            queue: VecDeque::new(),
            front_start: t,
            hold: initial,
        }
    }

    /// The reference at time `t` (retires finished segments).
    pub(crate) fn at(&mut self, t: f64) -> Joints {
        self.derivatives(t)[0]
    }

    /// The reference and its first two time derivatives at time `t`
    /// (retires finished segments).
    pub(crate) fn derivatives(&mut self, t: f64) -> [Joints; 3] {
        while let Some((_, seg)) = self.queue.front() {
            let tau = t - self.front_start;
            let duration = seg.duration();
            if tau >= duration {
                self.hold = seg.end();
                self.front_start += duration;
                self.queue.pop_front();
                continue;
            }
            return seg.eval_derivatives(tau);
        }
        [self.hold, [0.0; JOINTS], [0.0; JOINTS]]
    }

    /// Whether no segment is queued (as of the last query).
    pub(crate) fn is_idle(&self) -> bool {
        self.queue.is_empty()
    }
}
