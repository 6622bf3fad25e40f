//! The rotation convention of `poses.csv` (MODEL.md §10: q is R_WB, the
//! body's axes in W). A stream of the inverse rotation (R_BW, a "world in
//! tool" pose, or JPL's quaternion convention for Hamilton's) has the same
//! angular speed, so τ is found, but the body's true rate is then −ω_n of
//! the given rotations, not their ω: the gyroscope's alignment
//! ([`gyro_alignment_rms`]) fits the world-frame rates far better than the
//! body rates. Named, fatal, when its RMS is under `INVERSE_RATIO` of the
//! body rates'.

use robimu_session::{files, PoseSession};

use crate::check::{Finding, Severity};
use crate::pose_calibrate::memo;
use crate::pose_calibrate::startup::{find_tau, gyro_alignment_rms};
use crate::pose_calibrate::{fit_spline, PoseCalibrationOptions};

/// The world-frame rates' alignment RMS under this part of the body
/// rates' names the inverse convention. The body rates of a body turning
/// about varying axes leave an RMS of the order of the rates themselves
/// in the wrong convention, against the gyroscope's noise in the right one.
pub(crate) const INVERSE_RATIO: f64 = 0.5;

/// The finding of an inverse rotation convention (module doc); None when
/// the convention fits or the alignment cannot be computed (the other
/// checks name why: too few samples, no overlap, no quaternions).
pub(crate) fn inverse_rotation(session: &PoseSession) -> Option<Finding> {
    let data = session.measurements();
    if data.pose_t.len() < 8 || data.imu_t.len() < 20 {
        return None;
    }
    // the calibration's spline (its default knots and fallback), so that
    // it reuses this fit; τ searched as its start-up does
    let opts = PoseCalibrationOptions::default();
    let (spline, _) = fit_spline(&data, &opts, session.n_imus(), &mut |_| {}).ok()?;
    let search = opts.tau_search;
    let (tau, _) = memo::find_tau(&spline, &data.imu_t, &data.imu_z, search, || {
        find_tau(&spline, &data.imu_t, &data.imu_z, search)
    })
    .ok()?;
    let (body, world) = gyro_alignment_rms(&spline, &data.imu_t, &data.imu_z, tau).ok()?;
    // NaN fits name nothing
    if world.partial_cmp(&(INVERSE_RATIO * body)) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    Some(Finding::new(
        "rotation_convention",
        Severity::Fatal,
        files::POSES,
        world / body,
        format!(
            "poses.csv: the quaternions look like the inverse rotation (R_BW instead of R_WB, or \
             JPL's convention): the gyroscope follows the rates of their inverse, rms \
             {world:.4} rad/s after the alignment, against {body:.4} rad/s for the rotations as \
             given (τ = {tau:.3} s)"
        ),
        "import the poses again with --conjugate (each rotation inverted, the position kept; or \
         --inverse when the file gives the world's frame in the body, position too), or conjugate \
         the quaternions in poses.csv (qx, qy, qz → −qx, −qy, −qz): it holds R_WB, the body's axes \
         in the world (docs/model.md §7.9)",
    ))
}
