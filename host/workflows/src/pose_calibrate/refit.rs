//! The refit of a pose calibration with extra parameters θ_E appended to x
//! (docs/model.md §7.9, *diagnosis*): the IMU-side effects' columns C(i)
//! stacked ([`Stacked`]), z_i = ẑ_i(x, spline) + C(i) θ_E.
//!
//! Solved by block Newton steps: with θ_E held, the IMU samples corrected
//! to z_i − C(i) θ_E (C at the previous fit) and the pose calibration
//! solved again (every other unknown at its MAP given θ_E); then θ_E moves
//! by the score test's one-step −V_E⁻¹ u_E ([`Information`], the other
//! unknowns projected out, u_E with θ_E's prior gradient); until the step
//! is below [`STEP_TOL`] of its σ. The cross-derivatives ∂C/∂x are
//! neglected as in the joint path's effects (the columns are taken at the
//! previous fit).

use robimu_model::pose_measurement::inertial::{dz_dt_of, PoseImuSample};
use robimu_model::pose_measurement::rows::{prediction_rows, RowContext, SegmentCache};
use robimu_model::PoseMeasurements;

use super::score::Information;
use super::{fit_poses, PoseCalibration, PoseCalibrationError, PoseCalibrationOptions, PoseFit};

/// The refit ends when every step of θ_E is below this fraction of its σ.
pub(crate) const STEP_TOL: f64 = 0.02;

/// Most block Newton steps.
pub(crate) const MAX_STEPS: usize = 8;

/// The stacked columns C(i) of every candidate and their prior information.
pub(crate) struct Stacked<'a> {
    /// Writes all k columns of a sample (zeroed before).
    pub columns: &'a dyn Fn(&PoseImuSample<'_>, &mut [[f64; 6]]),
    /// 1/σ² of each parameter's zero-mean prior.
    pub prior: Vec<f64>,
}

/// A fit with θ_E: the calibration of the corrected samples, its problem,
/// the candidates' information there and θ_E (zero outside E).
pub(crate) struct EffectFit {
    /// The calibration (x, σ, residual RMS) of the corrected samples.
    pub cal: PoseCalibration,
    /// Its solved problem.
    pub fit: PoseFit,
    /// Every candidate's u (with θ_E's prior gradient) and V at the fit.
    pub info: Information,
    /// θ_E over all stacked columns.
    pub theta_e: Vec<f64>,
    /// The MAP cost with θ_E's prior, J = ½‖r‖² + ½ Σ θ_e²/σ_e².
    pub cost: f64,
}

impl Stacked<'_> {
    /// Number of columns.
    pub fn len(&self) -> usize {
        self.prior.len()
    }

    /// The fit of `data` corrected by `theta_e` (columns at `at`; none
    /// for the baseline).
    pub fn fit(
        &self,
        data: &PoseMeasurements,
        opts: &PoseCalibrationOptions,
        theta_e: Vec<f64>,
        at: Option<&EffectFit>,
    ) -> Result<EffectFit, PoseCalibrationError> {
        let corrected = match at {
            Some(a) => self.corrected(data, a, &theta_e)?,
            None => data.clone(),
        };
        let (cal, fit) = fit_poses(&corrected, &[], opts, |_| {}, |_| {})?;
        let k = self.len();
        let sums = fit
            .problem
            .extra_sums(&fit.theta, 0, k, |_, s, cols| (self.columns)(s, cols))?;
        let mut info = Information::new(&sums, &self.prior, &fit.factor);
        let mut cost = cal.cost;
        for j in 0..k {
            info.u[j] += self.prior[j] * theta_e[j];
            cost += 0.5 * self.prior[j] * theta_e[j] * theta_e[j];
        }
        Ok(EffectFit {
            cal,
            fit,
            info,
            theta_e,
            cost,
        })
    }

    /// `data`'s IMU samples less C(i) θ_E, C at the fit `at` (samples
    /// off its spline unchanged: they are not in the fit).
    fn corrected(
        &self,
        data: &PoseMeasurements,
        at: &EffectFit,
        theta_e: &[f64],
    ) -> Result<PoseMeasurements, PoseCalibrationError> {
        let p = &at.fit.problem;
        let sp = p.spline(&at.fit.theta)?;
        let x = p.x(&at.fit.theta);
        let ctx = RowContext::new(x).map_err(robimu_solver::PoseProblemError::from)?;
        let mut out = data.clone();
        let mut cols = vec![[0.0; 6]; self.len()];
        let mut cache = SegmentCache::default();
        for (t, z) in out.imu_t.iter().zip(out.imu_z.iter_mut()) {
            let Ok(rows) = prediction_rows(&sp, *t, &ctx, &mut cache) else {
                continue;
            };
            let sample = PoseImuSample::new(&sp, *t, x, dz_dt_of(&rows));
            cols.iter_mut().for_each(|c| *c = [0.0; 6]);
            (self.columns)(&sample, &mut cols);
            for (col, th) in cols.iter().zip(theta_e).filter(|(_, th)| **th != 0.0) {
                for c in 0..6 {
                    z[c] -= col[c] * th;
                }
            }
        }
        Ok(out)
    }

    /// The refit with the parameters `set` (stacked column indices) from
    /// the fit `start` (module doc).
    pub fn refit(
        &self,
        data: &PoseMeasurements,
        opts: &PoseCalibrationOptions,
        set: &[usize],
        start: &EffectFit,
    ) -> Result<EffectFit, PoseCalibrationError> {
        let singular =
            || PoseCalibrationError::Solver("the effects' information is singular".to_string());
        let step = |at: &EffectFit| -> Result<(EffectFit, bool), PoseCalibrationError> {
            let t = at.info.test(set).ok_or_else(singular)?;
            let mut theta_e = at.theta_e.clone();
            for (j, &c) in set.iter().enumerate() {
                theta_e[c] += t.step[j];
            }
            let small = (t.step.iter().zip(&t.step_sigma)).all(|(s, sg)| s.abs() <= STEP_TOL * sg);
            Ok((self.fit(data, opts, theta_e, Some(at))?, small))
        };
        let (mut cur, mut done) = step(start)?;
        for _ in 1..MAX_STEPS {
            if done {
                break;
            }
            (cur, done) = step(&cur)?;
        }
        Ok(cur)
    }
}
