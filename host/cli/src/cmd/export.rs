//! `robimu export`: a calibration result in the formats other tools read.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::urdf::UrdfOptions;
use robimu_model::{ModelParams, Robot};
use robimu_session::export::imu::{
    kalibr_imu_input_yaml, kalibr_imu_list_yaml, kalibr_imu_yaml, Correction, KalibrImu,
    KalibrOptions, KalibrPlacement, DEFAULT_RANDOM_WALK,
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
///
/// A result of several IMUs (docs/model.md §9): `--format kalibr` writes
/// Kalibr's IMU list (`imu0:`, `imu1:`, … each with its T_i_b relative to
/// IMU 0 and its time offset) to --out and, beside it, one file per IMU in
/// the form Kalibr's `--imu` reads (`imu.yaml` → `imu0.yaml`, `imu1.yaml`,
/// …: OUT's name with the IMU's number after its stem); `--format
/// correction` one file per IMU named so. `--imu J` writes IMU J's file
/// alone to --out; the robot formats take IMU 0's position unless --imu
/// is given.
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
    /// Kalibr: the `rostopic` key, one per IMU (comma-separated) [default:
    /// /imu0, /imu1, …].
    #[arg(long, value_delimiter = ',', value_name = "TOPIC")]
    pub rostopic: Vec<String>,
    /// A result of several IMUs: export IMU J alone (0 is `imu.csv`'s,
    /// J ≥ 1 `imu<J>.csv`'s; docs/model.md §9).
    #[arg(long, value_name = "J")]
    pub imu: Option<usize>,
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
        let k = result.imu_count();
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
        // IMU j's parameters (docs/model.md §9), each as a one-IMU result
        let imu_params = |j: usize| -> anyhow::Result<(CalibrationResult, ModelParams)> {
            let view = result
                .imu(j)
                .map_err(|e| anyhow::anyhow!("{}: {e}", self.calibration.display()))?;
            let params = calibrated_params(&robot, &view).with_context(|| {
                format!("{} does not fit robot `{spec}`", self.calibration.display())
            })?;
            Ok((view, params))
        };
        if let Some(j) = self.imu {
            result
                .imu(j)
                .map_err(|e| anyhow::anyhow!("{}: {e}", self.calibration.display()))?;
        }
        let chosen: Vec<usize> = match self.imu {
            Some(j) => vec![j],
            None => (0..k).collect(),
        };
        let rostopics = self.rostopics(k)?;
        let session = match self.format {
            ExportFormat::Kalibr => session_dir.as_deref().and_then(|d| Session::load(d).ok()),
            _ => None,
        };
        let text = match self.format {
            ExportFormat::Kalibr if k > 1 => {
                let mut views = Vec::new();
                for (j, topic) in rostopics.iter().enumerate() {
                    let (view, params) = imu_params(j)?;
                    let opts = self.kalibr_options(&view, &robot, session.as_ref(), j, topic)?;
                    views.push((params, opts));
                }
                let imus: Vec<KalibrImu<'_>> = views
                    .iter()
                    .map(|(p, o)| KalibrImu {
                        params: p,
                        opts: o,
                        placement: KalibrPlacement::relative(&views[0].0, p),
                    })
                    .collect();
                if let Some(j) = self.imu {
                    kalibr_imu_input_yaml(j, &imus)
                } else {
                    for j in 0..k {
                        write_file(&per_imu_path(&out, j), &kalibr_imu_input_yaml(j, &imus))?;
                    }
                    kalibr_imu_list_yaml(&imus)
                }
            }
            ExportFormat::Correction if chosen.len() > 1 => {
                for &j in &chosen {
                    let (_, params) = imu_params(j)?;
                    let text = Correction::new(&params)
                        .with_context(|| format!("IMU {j}"))?
                        .to_toml()?;
                    write_file(&per_imu_path(&out, j), &text)?;
                }
                return Ok(());
            }
            format => {
                let j = self.imu.unwrap_or(0);
                if k > 1 && self.imu.is_none() {
                    eprintln!(
                        "note: the result has {k} IMUs: the robot carries IMU 0's position (--imu J for another)"
                    );
                }
                let (view, params) = imu_params(j)?;
                self.one(
                    format,
                    &view,
                    &robot,
                    &spec,
                    spec_base.as_deref(),
                    &params,
                    session.as_ref(),
                    &rostopics[j],
                )?
            }
        };
        write_file(&out, &text)
    }

    /// The `rostopic` of each of `k` IMUs: --rostopic (one per IMU), else
    /// `/imu<j>`.
    fn rostopics(&self, k: usize) -> anyhow::Result<Vec<String>> {
        match self.rostopic.len() {
            0 => Ok((0..k).map(|j| format!("/imu{j}")).collect()),
            n if n == k => Ok(self.rostopic.clone()),
            1 if self.imu.is_some() => Ok(vec![self.rostopic[0].clone(); k]),
            n => bail!(
                "--rostopic: {n} topics for {k} IMUs (give one per IMU, comma-separated{})",
                if k > 1 { ", or one with --imu J" } else { "" }
            ),
        }
    }

    /// The export of one IMU's parameters (`view`, `params`).
    #[allow(clippy::too_many_arguments)]
    fn one(
        &self,
        format: ExportFormat,
        view: &CalibrationResult,
        robot: &Robot,
        spec: &str,
        spec_base: Option<&Path>,
        params: &ModelParams,
        session: Option<&Session>,
        rostopic: &str,
    ) -> anyhow::Result<String> {
        Ok(match format {
            ExportFormat::Toml => corrected_toml(robot, params)?,
            ExportFormat::Correction => Correction::new(params)?.to_toml()?,
            ExportFormat::Urdf => {
                let path = match spec_base {
                    Some(b) if Path::new(spec).is_relative() => b.join(spec),
                    _ => PathBuf::from(spec),
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
                corrected_urdf(&urdf, &opts, params)?
            }
            ExportFormat::Kalibr => {
                let j = self.imu.unwrap_or(0);
                kalibr_imu_yaml(
                    params,
                    &self.kalibr_options(view, robot, session, j, rostopic)?,
                )
            }
        })
    }

    /// The Kalibr options of IMU `j` (its one-IMU view `result`): the
    /// sample rate from --rate or the session's `imu.csv` / `imu<j>.csv`,
    /// the noise from --noise or the session, the fitted effects.
    fn kalibr_options(
        &self,
        result: &CalibrationResult,
        robot: &Robot,
        session: Option<&Session>,
        j: usize,
        rostopic: &str,
    ) -> anyhow::Result<KalibrOptions> {
        let file = if j == 0 {
            "imu.csv".to_string()
        } else {
            format!("imu{j}.csv")
        };
        let imu_table = session.and_then(|s| {
            if j == 0 {
                Some(&s.imu)
            } else {
                s.extra_imus.get(j - 1).map(|t| &t.samples)
            }
        });
        let rate = match (self.rate, imu_table) {
            (Some(r), _) => r,
            (None, Some(t)) => t.median_rate().with_context(|| {
                format!("the session's {file} has no sample interval: give --rate")
            })?,
            (None, None) if session.is_some() => {
                bail!("the result's session has no {file}: give --rate")
            }
            (None, None) => bail!(
                "the IMU sample rate is unknown (the result's session is not readable): give --rate"
            ),
        };
        if !(rate.is_finite() && rate > 0.0) {
            bail!("--rate {rate}: must be a positive number of Hz");
        }
        let (mut sigma_z, mut noise_source) = match session {
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
        Ok(KalibrOptions {
            rate,
            sigma_z,
            noise_density,
            noise_source,
            rostopic: rostopic.to_string(),
            random_walk,
            random_walk_source,
            g_sensitivity,
            size_effect,
        })
    }
}

/// IMU `j`'s file beside `out`: its stem followed by j (`imu.yaml` →
/// `imu1.yaml`; `_` between a stem ending in a digit and j).
pub fn per_imu_path(out: &Path, j: usize) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let sep = if stem.ends_with(|c: char| c.is_ascii_digit()) {
        "_"
    } else {
        ""
    };
    let name = match out.extension() {
        Some(e) => format!("{stem}{sep}{j}.{}", e.to_string_lossy()),
        None => format!("{stem}{sep}{j}"),
    };
    out.with_file_name(name)
}

/// Write `text` to `path` and say so.
fn write_file(path: &Path, text: &str) -> anyhow::Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
