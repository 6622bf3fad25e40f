//! The last pose-spline fit and τ search of this thread, kept for the next
//! call with the same input: `robimu calibrate` on a pose session checks
//! it first (the rotation convention, [`crate::check`], fits the spline and
//! finds τ) and then calibrates it, which fits and searches the same again.
//! A call with any other input computes afresh (and is kept instead);
//! failures are not kept.

use std::cell::RefCell;

use robimu_model::{PoseSpline, PoseSplineError};

/// What a fit was made from: times, positions, quaternions, knot spacing.
type FitKey = (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 4]>, u64);
/// What a τ search was made from: the spline, IMU times and samples, range.
type TauKey = (PoseSpline, Vec<f64>, Vec<[f64; 6]>, u64);

thread_local! {
    static FIT: RefCell<Option<(FitKey, PoseSpline)>> = const { RefCell::new(None) };
    static TAU: RefCell<Option<(TauKey, (f64, f64))>> = const { RefCell::new(None) };
}

/// [`PoseSpline::fit`], the last result again for the same input.
pub(crate) fn fit(
    t: &[f64],
    p: &[[f64; 3]],
    q: &[[f64; 4]],
    spacing: f64,
) -> Result<PoseSpline, PoseSplineError> {
    let same = |k: &FitKey| k.0 == t && k.1 == p && k.2 == q && k.3 == spacing.to_bits();
    if let Some(s) =
        FIT.with_borrow(|m| m.as_ref().filter(|(k, _)| same(k)).map(|(_, s)| s.clone()))
    {
        return Ok(s);
    }
    let s = PoseSpline::fit(t, p, q, spacing)?;
    let key = (t.to_vec(), p.to_vec(), q.to_vec(), spacing.to_bits());
    FIT.with_borrow_mut(|m| *m = Some((key, s.clone())));
    Ok(s)
}

/// The τ search `search` (the start-up's, [`super::startup::find_tau`]) on
/// this input, the last result again for the same input.
pub(crate) fn find_tau<E>(
    spline: &PoseSpline,
    imu_t: &[f64],
    imu_z: &[[f64; 6]],
    tau_max: f64,
    search: impl FnOnce() -> Result<(f64, f64), E>,
) -> Result<(f64, f64), E> {
    let same =
        |k: &TauKey| k.3 == tau_max.to_bits() && k.1 == imu_t && k.2 == imu_z && k.0 == *spline;
    if let Some(r) = TAU.with_borrow(|m| m.as_ref().filter(|(k, _)| same(k)).map(|(_, r)| *r)) {
        return Ok(r);
    }
    let r = search()?;
    let key = (
        spline.clone(),
        imu_t.to_vec(),
        imu_z.to_vec(),
        tau_max.to_bits(),
    );
    TAU.with_borrow_mut(|m| *m = Some((key, r)));
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn poses(n: usize) -> (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 4]>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.05).collect();
        let p = t.iter().map(|s| [s.sin(), s.cos(), 0.1 * s]).collect();
        let q = t
            .iter()
            .map(|s| [(0.3 * s).cos(), 0.0, 0.0, (0.3 * s).sin()])
            .collect();
        (t, p, q)
    }

    /// The same input gives the same spline and τ without searching again;
    /// another input is computed afresh.
    #[test]
    fn same_input_is_kept_other_input_is_computed() {
        let (t, p, q) = poses(60);
        let a = fit(&t, &p, &q, 0.2).unwrap();
        assert_eq!(a, PoseSpline::fit(&t, &p, &q, 0.2).unwrap());
        assert_eq!(fit(&t, &p, &q, 0.2).unwrap(), a);
        let b = fit(&t, &p, &q, 0.25).unwrap();
        assert_ne!(a, b);
        assert_eq!(b, PoseSpline::fit(&t, &p, &q, 0.25).unwrap());
        let (imu_t, imu_z) = (vec![0.0, 1.0], vec![[0.0; 6]; 2]);
        let calls = std::cell::Cell::new(0);
        let search = |v: f64| {
            calls.set(calls.get() + 1);
            Ok::<_, ()>((v, 0.5))
        };
        let r1 = find_tau(&b, &imu_t, &imu_z, 1.0, || search(0.1)).unwrap();
        let r2 = find_tau(&b, &imu_t, &imu_z, 1.0, || search(0.2)).unwrap();
        assert_eq!((r1, r2, calls.get()), ((0.1, 0.5), (0.1, 0.5), 1));
        let r3 = find_tau(&b, &imu_t, &imu_z, 2.0, || search(0.3)).unwrap();
        let r4 = find_tau(&a, &imu_t, &imu_z, 2.0, || search(0.4)).unwrap();
        assert_eq!((r3.0, r4.0, calls.get()), (0.3, 0.4, 3));
        // failures are not kept
        assert!(find_tau(&a, &imu_t, &imu_z, 3.0, || Err(())).is_err());
        let r5 = find_tau(&a, &imu_t, &imu_z, 3.0, || search(0.5)).unwrap();
        assert_eq!(r5.0, 0.5);
    }
}
