//! The gyroscope reading the nominal kinematics predict at every joint row
//! (the RMS |ω| of the gyroscope's unit check, docs/model.md §7.8): q from
//! the row, q̇ by central differences ([`super::units::joint_speeds`]),
//! ω̃ = K Γ R ω + b of [`BodyRate`] at the nominal x.
//!
//! The longest part of the check (the chain's rotations, six sines and
//! cosines per row): the rows are cut into chunks that any thread may take
//! ([`PredictedRate::work`]), so that a second thread computes them while
//! the first checks everything else and then helps. Each row's |ω̃|² is
//! kept, and the mean square sums them in row order: the sum of one pass.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;

use robimu_model::lanes::{quads, F64x4};
use robimu_model::{MeasurementModel, ParamLayout, Robot, MAX_JOINTS};
use robimu_session::Session;

use super::units::speeds_at;
use crate::body_rate::BodyRate;

/// Rows per chunk.
const CHUNK: usize = 2048;

/// The predicted |ω̃|² of every joint row, chunk by chunk.
pub(crate) struct PredictedRate<'s> {
    session: &'s Session,
    /// The nominal model's rotations (`None` when the model cannot be built).
    rate: Option<BodyRate>,
    /// The next chunk not yet taken.
    next: AtomicUsize,
    /// Each chunk's rows' |ω̃|², once computed.
    chunks: Vec<OnceLock<Vec<f64>>>,
    /// A thread panicked computing a chunk (it will never be set).
    failed: AtomicBool,
}

/// Marks [`PredictedRate::failed`] when dropped by a panic.
struct FailOnPanic<'a>(&'a AtomicBool);

impl Drop for FailOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Release);
        }
    }
}

impl<'s> PredictedRate<'s> {
    /// The prediction for `session`'s joint rows with `robot` (nothing
    /// computed yet).
    pub fn new(session: &'s Session, robot: &Robot) -> Self {
        let layout = ParamLayout::new(robot);
        let rate = MeasurementModel::new(robot, &layout, &layout.nominal())
            .ok()
            .map(|model| BodyRate::new(robot, &model));
        let count = match rate {
            Some(_) => session.joints.len().div_ceil(CHUNK),
            None => 0,
        };
        Self {
            session,
            rate,
            next: AtomicUsize::new(0),
            chunks: (0..count).map(|_| OnceLock::new()).collect(),
            failed: AtomicBool::new(false),
        }
    }

    /// Compute the chunks no thread has taken yet, until none is left.
    pub fn work(&self) {
        let Some(rate) = &self.rate else { return };
        let _guard = FailOnPanic(&self.failed);
        loop {
            let c = self.next.fetch_add(1, Ordering::Relaxed);
            let Some(slot) = self.chunks.get(c) else {
                return;
            };
            let rows = c * CHUNK..((c + 1) * CHUNK).min(self.session.joints.len());
            let _ = slot.set(self.squares(rate, rows));
        }
    }

    /// Wait until every chunk taken by another thread is computed.
    ///
    /// # Panics
    /// When a thread panicked computing one (it would never be computed).
    pub fn wait(&self) {
        while self.chunks.iter().any(|c| c.get().is_none()) {
            assert!(
                !self.failed.load(Ordering::Acquire),
                "gyroscope prediction thread panicked"
            );
            std::thread::yield_now();
        }
    }

    /// Leave the chunks not yet taken (the prediction is not needed).
    pub fn stop(&self) {
        self.next.fetch_max(self.chunks.len(), Ordering::Relaxed);
    }

    /// RMS |ω̃| over the joint rows (NaN without rows); `None` when the
    /// nominal model cannot be built.
    ///
    /// # Panics
    /// Unless every chunk has been computed ([`Self::work`] returned on
    /// every thread that called it).
    pub fn rms(&self) -> Option<f64> {
        self.rate.as_ref()?;
        let mut sum = 0.0;
        for chunk in &self.chunks {
            for w2 in chunk.get().expect("every chunk computed") {
                sum += w2;
            }
        }
        Some((sum / self.session.joints.len() as f64).sqrt())
    }

    /// |ω̃|² at the joint rows `rows`.
    fn squares(&self, rate: &BodyRate, rows: std::ops::Range<usize>) -> Vec<f64> {
        let joints = &self.session.joints;
        let n = self.session.joint_count();
        // as a JointState: the joints the session lacks at 0; four rows at a
        // time, one per lane of BodyRate::gyro_x4 (the bits of four
        // BodyRate::gyro calls)
        let zero = F64x4::splat(0.0);
        let (mut q, mut v) = ([zero; MAX_JOINTS], [zero; MAX_JOINTS]);
        let mut speeds = [0.0; MAX_JOINTS];
        let mut out = Vec::with_capacity(rows.len());
        for (quad, len) in quads(rows) {
            for (l, &i) in quad.iter().enumerate() {
                speeds_at(joints, i, &mut speeds[..n]);
                for (j, &qj) in joints.row(i).iter().enumerate() {
                    q[j].0[l] = qj;
                    v[j].0[l] = speeds[j];
                }
            }
            let w = rate.gyro_x4(&q, &v);
            out.extend(
                w.iter()
                    .take(len)
                    .map(|w| w[0] * w[0] + w[1] * w[1] + w[2] * w[2]),
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A thread that panics while computing chunks marks the prediction
    /// failed (so [`PredictedRate::wait`] stops instead of waiting for a
    /// chunk that will never come); one that returns does not.
    #[test]
    fn a_panic_while_computing_marks_the_prediction_failed() {
        let failed = AtomicBool::new(false);
        let r = std::panic::catch_unwind(|| {
            let _guard = FailOnPanic(&failed);
            panic!("a chunk's computation failed");
        });
        assert!(r.is_err());
        assert!(failed.load(Ordering::Acquire));
        let fine = AtomicBool::new(false);
        drop(FailOnPanic(&fine));
        assert!(!fine.load(Ordering::Acquire));
    }
}
