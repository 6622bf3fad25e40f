//! `robimu simulate --source poses`: a simulated session with tool poses
//! (docs/model.md §7.9) written as a session directory: `session.toml`
//! (`source = "poses"`, the σ it was simulated with), `poses.csv`,
//! `imu.csv` and `truth.toml` with the 30 true parameters.
//!
//! Without a robot the truth is drawn from the priors with a uniformly
//! random mount rotation ([`draw_pose_truth`]), the motion is a random
//! hand-held-like one ([`random_pose_motion`]), and the samples are
//! [`simulate_pose_session`]'s, with the default noise of
//! [`PoseCalibrationOptions`](crate::PoseCalibrationOptions). With a robot
//! the body is its flange on the motion of `robimu simulate --robot`
//! (`pipeline/pose_flange.rs`). Either way the IMU stamps may then carry
//! arrival jitter and a drifting lag ([`ImuTiming`]). With `imus` K > 1
//! IMU j ≥ 1 is written to `imu<j>.csv` with its own truth and noise
//! (docs/model.md §9: hand-held, its own mount rotation,
//! [`simulate_pose_imus`]; on a robot's flange, the robot's IMU j as
//! `robimu simulate --imus K` places it) and the truth lists all 2 + 28·K
//! parameters.

use std::fmt;
use std::path::PathBuf;

use robimu_model::Robot;
use robimu_session::{
    pose_parameter_names, NoiseOverride, PoseNoise as PoseSigma, PoseSessionMeta,
    PoseSessionWriter, Truth,
};

use super::pose_flange::flange_session;
use super::simulate::check_rates;
use super::PipelineError;
use crate::pose_calibrate::inject::{inject_pose_effects, parse_pose_effect};
use crate::pose_calibrate::{
    draw_pose_imus_truth, random_pose_motion, simulate_pose_imus, ImuSamples, ImuTiming, PoseNoise,
};

/// What to simulate.
#[derive(Debug, Clone)]
pub struct PoseSessionSpec {
    /// Session directory to write (created if needed).
    pub out: PathBuf,
    /// Length, s.
    pub duration: f64,
    /// Seed of the truth, the motion and the noise.
    pub seed: u64,
    /// Pose sample rate, Hz.
    pub pose_rate: f64,
    /// Standard deviation of the pose sample times about the nominal grid, s
    /// (the poses are stamped with their true times).
    pub pose_jitter: f64,
    /// IMU sample rate, Hz.
    pub imu_rate: f64,
    /// The robot whose flange carries the IMU (`None`: a hand-held motion).
    pub robot: Option<Robot>,
    /// Arrival jitter and lag drift of the IMU stamps.
    pub imu_timing: ImuTiming,
    /// Number of IMUs K on the body (docs/model.md §9).
    pub imus: usize,
    /// IMU-side catalogue effects injected, `NAME=MAGNITUDE`
    /// ([`crate::pose_calibrate::inject`]; the hand-held motion only).
    pub effects: Vec<String>,
}

/// A written pose session.
#[derive(Debug, Clone)]
pub struct PoseSimulated {
    /// Its directory.
    pub dir: PathBuf,
    /// Rows of poses.csv.
    pub poses: usize,
    /// Rows of imu.csv.
    pub imu_samples: usize,
    /// Number of IMUs.
    pub imus: usize,
    /// Length, s.
    pub duration: f64,
    /// The true τ, s.
    pub tau: f64,
}

impl fmt::Display for PoseSimulated {
    /// `wrote DIR: … poses, … IMU samples … (true tau = …)`, the line
    /// `robimu simulate --source poses` prints.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {}: {} poses, {} IMU samples{} over {:.1} s (true tau = {:.4} s; truth in truth.toml)",
            self.dir.display(),
            self.poses,
            self.imu_samples,
            match self.imus {
                1 => String::new(),
                k => format!(" per IMU ({k} IMUs: imu.csv, imu1.csv, …)"),
            },
            self.duration,
            self.tau
        )
    }
}

/// The effects `spec` injects, `(name, magnitude)` (the hand-held motion only).
fn injected_effects(spec: &PoseSessionSpec) -> Result<Vec<(String, f64)>, PipelineError> {
    let injected = (spec.effects.iter())
        .map(|s| parse_pose_effect(s))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| PipelineError::input(e.into()))?;
    if spec.robot.is_some() && !injected.is_empty() {
        return Err(PipelineError::input(anyhow::anyhow!(
            "--effect with --robot: not available yet (effects are injected into the hand-held \
             motion's pose session)"
        )));
    }
    Ok(injected)
}

/// The flags of `spec` checked; the effects to inject.
fn checked_spec(spec: &PoseSessionSpec) -> Result<Vec<(String, f64)>, PipelineError> {
    check_rates(spec.duration, spec.imu_rate, None).map_err(PipelineError::input)?;
    check_rates(spec.duration, spec.pose_rate, None)
        .map_err(|e| PipelineError::input(anyhow::anyhow!("--pose-rate: {e}")))?;
    if !(spec.pose_jitter.is_finite()
        && spec.pose_jitter >= 0.0
        && spec.pose_jitter * spec.pose_rate < 0.5)
    {
        return Err(PipelineError::input(anyhow::anyhow!(
            "--pose-jitter must be ≥ 0 and below half the pose period (got {} s at {} Hz)",
            spec.pose_jitter,
            spec.pose_rate
        )));
    }
    let ImuTiming { jitter, drift } = spec.imu_timing;
    if !(jitter.is_finite() && jitter >= 0.0 && drift.is_finite()) {
        return Err(PipelineError::input(anyhow::anyhow!(
            "--imu-jitter must be ≥ 0 and --imu-drift finite (got {jitter} s and {drift} s)"
        )));
    }
    if !(1..=64).contains(&spec.imus) {
        return Err(PipelineError::input(anyhow::anyhow!(
            "--imus must be between 1 and 64 (got {})",
            spec.imus
        )));
    }
    let injected = injected_effects(spec)?;
    if spec.imus > 1 && !injected.is_empty() {
        return Err(PipelineError::input(anyhow::anyhow!(
            "--effect is for one IMU: it cannot be combined with --imus {}",
            spec.imus
        )));
    }
    Ok(injected)
}

/// session.toml's note on how the session was simulated.
fn notes(spec: &PoseSessionSpec) -> String {
    format!(
        "simulated by robimu simulate --source poses (seed {}, {}, poses at {} Hz with \
             jitter {} s, IMU at {} Hz, IMU stamps' arrival jitter {} s and lag drift {} s{})",
        spec.seed,
        spec.robot
            .as_ref()
            .map_or("a hand-held motion".to_string(), |r| format!(
                "the flange of {}",
                r.name()
            )),
        spec.pose_rate,
        spec.pose_jitter,
        spec.imu_rate,
        spec.imu_timing.jitter,
        spec.imu_timing.drift,
        if spec.effects.is_empty() {
            String::new()
        } else {
            format!(", effects injected: {}", spec.effects.join(", "))
        }
    )
}

/// Simulate the pose session `spec` describes and write it.
pub fn simulate_pose_dir(spec: &PoseSessionSpec) -> Result<PoseSimulated, PipelineError> {
    let injected = checked_spec(spec)?;
    let fit = |e: crate::PoseCalibrationError| PipelineError::fit(e.into());
    let mut noise = PoseNoise::default();
    let (truth, mut data, mut more) = match &spec.robot {
        None => {
            let truth = draw_pose_imus_truth(spec.seed, spec.imus);
            let motion =
                random_pose_motion(spec.duration, spec.seed.wrapping_add(1)).map_err(fit)?;
            let (mut data, more) = simulate_pose_imus(
                &truth,
                spec.imus,
                &motion,
                (spec.pose_rate, spec.pose_jitter),
                spec.imu_rate,
                &noise,
                spec.seed.wrapping_add(2),
            )
            .map_err(fit)?;
            if !injected.is_empty() {
                // one IMU (checked_spec): the truth is its 30
                inject_pose_effects(&mut data, &truth, &motion, &injected)
                    .map_err(|e| PipelineError::input(e.into()))?;
            }
            (truth, data, more)
        }
        Some(robot) => {
            let f = flange_session(
                robot.clone(),
                spec.imus,
                spec.duration,
                spec.imu_rate,
                spec.seed,
                spec.pose_rate,
                spec.pose_jitter,
                &noise,
            )
            .map_err(PipelineError::fit)?;
            noise.sigma_z = f.sigma_z;
            (f.truth, f.data, f.more)
        }
    };
    spec.imu_timing
        .apply(&mut data, spec.seed.wrapping_add(3))
        .map_err(|e| PipelineError::input(e.into()))?;
    for (j, m) in more.iter_mut().enumerate() {
        restamp(&spec.imu_timing, m, spec.seed.wrapping_add(4 + j as u64))?;
    }
    let meta = PoseSessionMeta {
        poses: Some(PoseSigma {
            sigma_p: Some(noise.sigma_p),
            sigma_r: Some(noise.sigma_r),
        }),
        noise: Some(NoiseOverride {
            sigma_z: Some(noise.sigma_z),
            sigma_q: None,
        }),
        notes: Some(notes(spec)),
        ..Default::default()
    };
    let write = |e: robimu_session::SessionError| PipelineError::write(e.into());
    let mut w = PoseSessionWriter::create(&spec.out, &meta).map_err(write)?;
    w.measurements(&data).map_err(write)?;
    for (j, m) in more.iter().enumerate() {
        for (t, z) in m.t.iter().zip(&m.z) {
            w.imu_of(j + 1, *t, z).map_err(write)?;
        }
    }
    w.truth(&Truth {
        values: pose_parameter_names(spec.imus)
            .into_iter()
            .zip(truth.clone())
            .collect(),
    })
    .map_err(write)?;
    let dir = w.finish().map_err(write)?;
    Ok(PoseSimulated {
        dir,
        poses: data.pose_t.len(),
        imu_samples: data.imu_t.len(),
        imus: spec.imus,
        duration: spec.duration,
        tau: truth[5],
    })
}

/// [`ImuTiming::apply`] to IMU j ≥ 1's samples `m`.
fn restamp(timing: &ImuTiming, m: &mut ImuSamples, seed: u64) -> Result<(), PipelineError> {
    let mut d = robimu_model::PoseMeasurements {
        imu_t: std::mem::take(&mut m.t),
        imu_z: std::mem::take(&mut m.z),
        ..Default::default()
    };
    timing
        .apply(&mut d, seed)
        .map_err(|e| PipelineError::input(e.into()))?;
    (m.t, m.z) = (d.imu_t, d.imu_z);
    Ok(())
}

#[cfg(test)]
#[path = "pose_simulate_tests.rs"]
mod tests;
