//! `robimu export`: a calibration result in the formats other tools read.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::urdf::UrdfOptions;
use robimu_session::export::imu::{
    kalibr_imu_yaml, Correction, KalibrOptions, DEFAULT_RANDOM_WALK,
};
use robimu_session::export::robot::{corrected_toml, corrected_urdf};
use robimu_session::export::{calibrated_params, imu_effects};
use robimu_session::result::CalibrationResult;
use robimu_session::Session;

use super::input::{is_urdf, output_path, resolve_robot_with, UrdfLinks};

/// What `robimu export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// The calibrated robot as a URDF: the robot's own URDF with corrected
    /// joint origins and an `imu_link` (needs a URDF robot).
    Urdf,
    /// The calibrated robot as robot TOML (`--robot FILE.toml` reads it).
    Toml,
    /// The IMU as a Kalibr imu.yaml (noise densities, scale-misalignment intrinsics).
    Kalibr,
    /// The IMU correction for firmware or drivers: per sensor the matrix M,
    /// M⁻¹ and bias b of z = M·v + b (TOML); apply v = M⁻¹·(z − b).
    Correction,
}

/// Export a calibration for other tools: the corrected robot (URDF or
/// robot TOML) or the IMU intrinsics (Kalibr imu.yaml or a correction file).
///
/// The robot is the one the result names (relative to its session
/// directory) unless --robot is given; it must be the robot the calibration
/// was computed for.
#[derive(Debug, Clone, clap::Args)]
pub struct ExportCmd {
    /// The calibration result (result.json from `robimu calibrate`).
    #[arg(long)]
    pub calibration: PathBuf,
    /// What to write.
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// The robot (built-in name, robot TOML or URDF) [default: the result's].
    #[arg(long)]
    pub robot: Option<String>,
    #[command(flatten)]
    pub links: UrdfLinks,
    /// Kalibr: IMU sample rate, Hz [default: from the result's session imu.csv].
    #[arg(long)]
    pub rate: Option<f64>,
    /// Kalibr: the `rostopic` key.
    #[arg(long, default_value = "/imu0")]
    pub rostopic: String,
    /// Kalibr: accelerometer and gyroscope random walks, m/s^3/sqrt(Hz) and
    /// rad/s^2/sqrt(Hz) (robimu's biases are constant, so these are not
    /// estimated; Kalibr needs them positive) [default: 1e-3,1e-4, of the
    /// order of consumer MEMS IMUs].
    #[arg(long, value_delimiter = ',', value_name = "ACCEL,GYRO")]
    pub random_walk: Vec<f64>,
    /// Kalibr: the noise measured by `robimu allan` (its allan.csv: noise
    /// densities N and, where the curve rises as √τ, the random walks K) or
    /// by `robimu noise` (its noise.toml: σ per sample, densities σ/√rate)
    /// [default: the σ of the result's session; random walks placeholders].
    #[arg(long, value_name = "allan.csv|noise.toml")]
    pub noise: Option<PathBuf>,
    /// File to write.
    #[arg(long)]
    pub out: PathBuf,
}

impl ExportCmd {
    /// Read the result, build the export, write it.
    pub fn run(self) -> anyhow::Result<()> {
        let out = output_path(Some(&self.out), self.out.clone())?;
        let result = CalibrationResult::read(&self.calibration)?;
        let session_dir = result.session.as_ref().map(PathBuf::from);
        let result_dir = self.calibration.parent().map(Path::to_path_buf);
        let (spec, spec_base) = match (&self.robot, &result.robot) {
            (Some(r), _) => (r.clone(), None),
            (None, Some(r)) => (r.clone(), session_dir.clone().or(result_dir)),
            (None, None) => bail!(
                "{} names no robot: give --robot",
                self.calibration.display()
            ),
        };
        let (robot, _) = resolve_robot_with(&spec, spec_base.as_deref(), &self.links)?;
        let params = calibrated_params(&robot, &result).with_context(|| {
            format!("{} does not fit robot `{spec}`", self.calibration.display())
        })?;
        let text = match self.format {
            ExportFormat::Toml => corrected_toml(&robot, &params)?,
            ExportFormat::Correction => Correction::new(&params)?.to_toml()?,
            ExportFormat::Urdf => {
                let path = match &spec_base {
                    Some(b) if Path::new(&spec).is_relative() => b.join(&spec),
                    _ => PathBuf::from(&spec),
                };
                if !is_urdf(&path) {
                    bail!("--format urdf needs a URDF robot; the robot is `{spec}` (use --format toml, or --robot FILE.urdf)");
                }
                let urdf = std::fs::read_to_string(&path)
                    .with_context(|| format!("cannot read {}", path.display()))?;
                let opts = UrdfOptions {
                    base: self.links.base.clone(),
                    tip: self.links.tip.clone(),
                    ..UrdfOptions::default()
                };
                corrected_urdf(&urdf, &opts, &params)?
            }
            ExportFormat::Kalibr => {
                self.kalibr(&result, &robot, &params, session_dir.as_deref())?
            }
        };
        std::fs::write(&out, text).with_context(|| format!("cannot write {}", out.display()))?;
        println!("wrote {}", out.display());
        Ok(())
    }

    /// The Kalibr imu.yaml of `params`, the sample rate and noise from
    /// --rate or the result's session.
    fn kalibr(
        &self,
        result: &CalibrationResult,
        robot: &robimu_model::Robot,
        params: &robimu_model::ModelParams,
        session_dir: Option<&Path>,
    ) -> anyhow::Result<String> {
        let session = session_dir.and_then(|d| Session::load(d).ok());
        let rate = match (self.rate, &session) {
            (Some(r), _) => r,
            (None, Some(s)) => s
                .imu
                .median_rate()
                .context("the session's imu.csv has no sample interval: give --rate")?,
            (None, None) => bail!(
                "the IMU sample rate is unknown (the result's session is not readable): give --rate"
            ),
        };
        if !(rate.is_finite() && rate > 0.0) {
            bail!("--rate {rate}: must be a positive number of Hz");
        }
        let (mut sigma_z, mut noise_source) = match &session {
            Some(s) => (
                s.noise(robot)?.0,
                "largest per-sample σ of the session's noise / √rate".to_string(),
            ),
            None => (
                robot.sigma_z(),
                "largest per-sample σ of the robot's noise / √rate".to_string(),
            ),
        };
        let mut noise_density = None;
        let mut random_walk = DEFAULT_RANDOM_WALK;
        let mut random_walk_source = None;
        if let Some(path) = &self.noise {
            let shown = path.display();
            let is_csv = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
            if is_csv {
                let text = std::fs::read_to_string(path)
                    .with_context(|| format!("cannot read --noise {shown}"))?;
                let curves = robimu_workflows::allan::curves_from_csv(&text).map_err(|e| {
                    anyhow::anyhow!("--noise {shown}: not an allan.csv of `robimu allan`: {e}")
                })?;
                let largest = |r: std::ops::Range<usize>, f: &dyn Fn(usize) -> Option<f64>| {
                    r.map(f).try_fold(0.0f64, |m, v| v.map(|v| m.max(v)))
                };
                let density = |c: usize| Some(curves[c].terms.density).filter(|d| d.is_finite());
                let walk = |c: usize| {
                    robimu_workflows::allan::rate_random_walk(
                        &curves[c].curve,
                        curves[c].terms.density,
                    )
                };
                let (Some(na), Some(ng)) = (largest(0..3, &density), largest(3..6, &density))
                else {
                    bail!("--noise {shown}: no noise density on every channel");
                };
                noise_density = Some([na, ng]);
                noise_source =
                    format!("the Allan deviation's N (largest of each sensor's axes) in {shown}");
                match (largest(0..3, &walk), largest(3..6, &walk)) {
                    (Some(a), Some(g)) => {
                        random_walk = [a, g];
                        random_walk_source = Some(format!(
                            "the Allan deviation's rate random walk K (σ = K·√(τ/3), largest of each sensor's axes) in {shown}"
                        ));
                    }
                    _ => eprintln!(
                        "note: {shown}: the Allan curves do not rise as √τ on every axis (record longer at rest): the random walks stay placeholders"
                    ),
                }
            } else {
                let file = robimu_workflows::noise::NoiseFile::read(path)
                    .with_context(|| format!("--noise {shown}"))?;
                let Some(s) = file.noise.sigma_z else {
                    bail!("--noise {shown}: its [noise] table has no sigma_z");
                };
                sigma_z = s;
                noise_source = format!("largest per-sample σ of {shown} / √rate");
            }
        }
        match self.random_walk.as_slice() {
            [] => {}
            &[a, g] if [a, g].iter().all(|v| v.is_finite() && *v > 0.0) => {
                random_walk = [a, g];
                random_walk_source = Some("given with --random-walk".into());
            }
            other => bail!(
                "--random-walk {other:?}: give two positive numbers, ACCEL,GYRO (Kalibr divides by them)"
            ),
        }
        if random_walk_source.is_none() {
            eprintln!(
                "note: the random walks in the imu.yaml are placeholders ({}, {}): give --noise allan.csv of a long static recording, or --random-walk",
                random_walk[0], random_walk[1]
            );
        }
        let (g_sensitivity, size_effect) = imu_effects(result)?;
        Ok(kalibr_imu_yaml(
            params,
            &KalibrOptions {
                rate,
                sigma_z,
                noise_density,
                noise_source,
                rostopic: self.rostopic.clone(),
                random_walk,
                random_walk_source,
                g_sensitivity,
                size_effect,
            },
        ))
    }
}
