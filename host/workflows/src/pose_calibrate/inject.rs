//! IMU-side catalogue effects injected into a simulated pose session
//! (`simulate --source poses --effect NAME=M`, docs/model.md §7.9): each
//! IMU sample gets its effect's exact form ([`Effect::imu_exact`]: the
//! warped clock of clock_drift, the delayed accelerometer of sensor_delay,
//! the additive terms of the others at the true motion) less the baseline,
//! at θ_e = [`Effect::injection`]`(M)`; several effects superpose.

use robimu_model::effects::{
    self, CatalogueSetup, Effect, ImuExactContext, MassModel, SessionSpan,
};
use robimu_model::pose_measurement::inertial::PoseImuSample;
use robimu_model::pose_measurement::{self as pm, G0, TAU};
use robimu_model::{PoseMeasurements, PoseSpline};

use super::PoseCalibrationError;

/// Parse `NAME=MAGNITUDE` of an IMU-side effect.
pub(crate) fn parse_pose_effect(spec: &str) -> Result<(String, f64), PoseCalibrationError> {
    let bad = |m: String| Err(PoseCalibrationError::Input(m));
    let Some((name, m)) = spec.split_once('=') else {
        return bad(format!("--effect `{spec}`: expected NAME=MAGNITUDE"));
    };
    let Ok(m) = m.trim().parse::<f64>() else {
        return bad(format!("--effect `{spec}`: `{m}` is not a number"));
    };
    if !m.is_finite() {
        return bad(format!("--effect `{spec}`: the magnitude must be finite"));
    }
    Ok((name.trim().to_string(), m))
}

/// Add the effects `injected` (name, magnitude in the effect's
/// [`Effect::magnitude_unit`]) to `data`'s IMU samples, simulated from
/// `truth` on `motion` (before any change of their stamps).
pub(crate) fn inject_pose_effects(
    data: &mut PoseMeasurements,
    truth: &[f64],
    motion: &PoseSpline,
    injected: &[(String, f64)],
) -> Result<(), PoseCalibrationError> {
    let (Some(&t0), Some(&t1)) = (data.imu_t.first(), data.imu_t.last()) else {
        return Ok(());
    };
    let setup = CatalogueSetup::new(SessionSpan { t0, t1 }, MassModel::none(), G0, None);
    let input = |m: String| PoseCalibrationError::Input(m);
    let mut chosen: Vec<(Box<dyn Effect>, Vec<f64>)> = Vec::new();
    for (name, m) in injected {
        let e = effects::by_name(&setup, name).map_err(|e| input(e.to_string()))?;
        chosen.push((e, Vec::new()));
        let (e, theta) = chosen.last_mut().expect("pushed");
        *theta = e.injection(*m);
    }
    let z_at = |s: f64| pm::predict(motion, s - truth[TAU], truth).unwrap_or([f64::NAN; 6]);
    for (t, z) in data.imu_t.iter().zip(data.imu_z.iter_mut()) {
        let sample = PoseImuSample::at(motion, *t, truth).map_err(|e| input(e.to_string()))?;
        let ctx = ImuExactContext {
            t: *t,
            tau: truth[TAU],
            z_at: &z_at,
            imu: &sample,
        };
        let base = z_at(t + truth[TAU]);
        for (e, theta) in &chosen {
            let Some(exact) = e.imu_exact(&ctx, theta) else {
                return Err(input(format!(
                    "effect `{}` does not apply to a pose session (it acts through joint angles \
                     or links)",
                    e.name()
                )));
            };
            for c in 0..6 {
                z[c] += exact[c] - base[c];
            }
        }
    }
    Ok(())
}
