//! The IMU sample selection follows τ ([`Problem::reselect`]), and stops
//! alternating when τ steps back and forth across a sample's edge.

use super::gls_tests::{problem, setup};
use super::multi_tests::SZ;
use crate::LeastSquares;

/// A constructed 2-cycle: τ moves by one sample period and back. The
/// selection follows the first step, and on the way back (a return to the
/// selection before the last change) it keeps the samples both selections
/// hold, from then on, whatever τ does within the margin.
#[test]
fn a_selection_that_would_cycle_back_keeps_the_samples_both_hold() {
    let s = setup();
    let mut p = problem(&s, None, SZ);
    let tau_at = s.layout.offsets().tau;
    let dt = s.data.imu_t[1] - s.data.imu_t[0];
    let tau0 = s.x[tau_at];
    let [at0, at1, at2] = [0.0, 1.01, 2.01].map(|k| {
        let mut x = s.x.clone();
        x[tau_at] = tau0 + k * dt;
        p.theta(&s.spline, &x)
    });
    p.begin_iteration(&at0).unwrap();
    let r0 = p.imu_range();
    p.begin_iteration(&at1).unwrap();
    let r1 = p.imu_range();
    assert_ne!(r0, r1, "a step of one sample period moves the selection");
    // the selection at τ + dt is the one at τ shifted by a sample
    assert_eq!(r1.start, r0.start - 1, "{r0:?} → {r1:?}");
    p.begin_iteration(&at0).unwrap();
    let both = r0.start.max(r1.start)..r0.end.min(r1.end);
    assert_eq!(p.imu_range(), both, "back at τ: the intersection");
    // (here the data end before the span does: only the start moves, and
    // the intersection is the selection at τ; frozen, τ + dt keeps it)
    for theta in [&at1, &at0, &at1] {
        p.begin_iteration(theta).unwrap();
        assert_eq!(p.imu_range(), both, "frozen from then on");
    }
    // without the return, a second forward step is followed
    let mut q = problem(&s, None, SZ);
    q.begin_iteration(&at0).unwrap();
    q.begin_iteration(&at1).unwrap();
    q.begin_iteration(&at2).unwrap();
    assert_eq!(q.imu_range().start, r0.start - 2);
}
