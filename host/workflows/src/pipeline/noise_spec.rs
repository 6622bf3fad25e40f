//! `--noise-model SPEC` of `robimu simulate` and `robimu montecarlo` (the
//! IMU noise the simulated sessions get) and of `robimu plan` and `robimu
//! identifiability` (the noise a plan is made for); and `--noise-model
//! white|auto|FILE` of `robimu calibrate` and `robimu diagnose`
//! ([`noise_choice`]): the noise model they fit with (docs/model.md §4.6).
//!
//! SPEC is `white` (the paper's model, the default), or
//! `ar1:accel=TAU_MS[,gyro=TAU_MS][,motion=C]` (AR(1) of correlation time
//! TAU ms, φ = exp(−dt/TAU) with dt the IMU sample period, on the
//! accelerometer and/or gyroscope channels, same marginal σ; `motion=C`
//! adds C‖q̈‖² to every channel's variance, channel unit² per (rad/s²)²),
//! or a TOML file whose `[noise]` table has session.toml's keys (`ar_z`,
//! `motion_z`, and optionally `sigma_z`).

use std::path::{Path, PathBuf};

use crate::calibrate::noise_choice::NoiseChoice;
use crate::noise::NoiseFile;
use anyhow::{bail, Context};
use robimu_model::noise::NoiseModel;
use robimu_session::{check_ar_order_for_data, NoiseShape, Session};

/// What SPEC accepts, for error messages.
const EXPECTED: &str =
    "expected `white`, `ar1:accel=TAU_MS[,gyro=TAU_MS][,motion=C]` or a TOML file with a [noise] table";

/// The noise model of `spec` at the robot's standard deviations `sigma_z`
/// (a file's `sigma_z` replaces them) and the IMU sample rate `imu_rate` Hz.
pub fn parse_noise_model(
    spec: &str,
    sigma_z: [f64; 6],
    imu_rate: f64,
) -> anyhow::Result<NoiseModel> {
    let spec = spec.trim();
    let what = || format!("--noise-model {spec}");
    if spec == "white" {
        return NoiseModel::white(sigma_z).with_context(what);
    }
    if let Some(keys) = spec.strip_prefix("ar1:") {
        let dt = 1.0 / imu_rate;
        let (mut accel, mut gyro, mut motion) = (None, None, 0.0);
        for item in keys.split(',').map(str::trim).filter(|k| !k.is_empty()) {
            let Some((key, value)) = item.split_once('=') else {
                bail!("{}: `{item}` is not KEY=VALUE ({EXPECTED})", what());
            };
            let v: f64 = value
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .with_context(|| format!("{}: `{item}`: the value must be a number", what()))?;
            match key.trim() {
                "accel" | "gyro" => {
                    if v <= 0.0 {
                        bail!(
                            "{}: `{item}`: the correlation time must be a positive number of ms",
                            what()
                        );
                    }
                    let phi = (-dt / (v * 1e-3)).exp();
                    if key.trim() == "accel" {
                        accel = Some(phi);
                    } else {
                        gyro = Some(phi);
                    }
                }
                "motion" => {
                    if v < 0.0 {
                        bail!(
                            "{}: `{item}`: the motion gain must be a number >= 0",
                            what()
                        );
                    }
                    motion = v;
                }
                other => bail!(
                    "{}: unknown key `{other}` (the keys are accel, gyro and motion)",
                    what()
                ),
            }
        }
        if accel.is_none() && gyro.is_none() {
            bail!("{}: give accel=TAU_MS and/or gyro=TAU_MS", what());
        }
        return NoiseModel::ar1(sigma_z, [accel, gyro], [motion; 2]).with_context(what);
    }
    let path = Path::new(spec);
    if !path.is_file() {
        bail!("{}: {EXPECTED} (no such file)", what());
    }
    let (table, shape) = NoiseFile::read_with_shape(path).with_context(what)?;
    let sigma_z = table.noise.sigma_z.unwrap_or(sigma_z);
    shape
        .unwrap_or_default()
        .noise_model(sigma_z)
        .map_err(|e| anyhow::anyhow!("{}: {}: [noise]: {e}", what(), path.display()))
}

/// A noise file given on the command line (`--noise FILE` or `--noise-model
/// FILE`), read once: its flag, path, σ and model keys.
pub struct NoiseFileArg {
    /// `--noise` or `--noise-model`.
    pub flag: &'static str,
    /// The file.
    pub path: PathBuf,
    /// Its σ.
    pub file: NoiseFile,
    /// Its `ar_z`/`motion_z`, if any.
    pub shape: Option<NoiseShape>,
}

impl NoiseFileArg {
    /// The file of `--noise FILE` (`noise`) or `--noise-model FILE` (`spec`
    /// when it is neither `white` nor `auto`), read once; two different
    /// files are refused.
    pub fn from_flags(noise: Option<&Path>, spec: &str) -> anyhow::Result<Option<Self>> {
        let model_file = match spec.trim() {
            "white" | "auto" => None,
            file => {
                let path = Path::new(file);
                if !path.is_file() {
                    bail!("--noise-model `{file}`: not `white`, `auto` or a readable TOML file");
                }
                Some(path.to_path_buf())
            }
        };
        let (flag, path) = match (noise, model_file) {
            (Some(a), Some(b)) if a != b => bail!(
                "--noise {} and --noise-model {}: give the noise file once",
                a.display(),
                b.display()
            ),
            (Some(a), _) => ("--noise", a.to_path_buf()),
            (None, Some(b)) => ("--noise-model", b),
            (None, None) => return Ok(None),
        };
        let (file, shape) = NoiseFile::read_with_shape(&path).context(flag)?;
        Ok(Some(Self {
            flag,
            path,
            file,
            shape,
        }))
    }
}

/// The `--noise-model white|auto|FILE` choice of calibrate and diagnose:
/// `white`; `auto` (the noise table's AR model — the noise file's keys,
/// else the session's — as given, else identified when needed); a FILE's
/// model as given. The σ are `sigma_z` (the noise file's over the
/// session's); an AR order beyond the `samples` is refused.
pub fn noise_choice(
    spec: &str,
    session: &Session,
    sigma_z: [f64; 6],
    samples: usize,
    file: Option<&NoiseFileArg>,
) -> anyhow::Result<NoiseChoice> {
    let mode = spec.trim();
    if mode == "white" {
        return Ok(NoiseChoice::White);
    }
    let from_file = file.and_then(|f| f.shape.clone().map(|s| (s, f)));
    let (shape, origin) = match &from_file {
        Some((s, f)) => (s.clone(), format!("{} {}", f.flag, f.path.display())),
        None => (
            session.meta.noise_shape.clone().unwrap_or_default(),
            session.dir.join("session.toml").display().to_string(),
        ),
    };
    let given = shape
        .noise_model(sigma_z)
        .map_err(|e| anyhow::anyhow!("{origin}: [noise]: {e}"))?;
    if mode == "auto" && given.is_white() {
        return Ok(NoiseChoice::Auto);
    }
    check_ar_order_for_data(given.max_order(), samples)
        .map_err(|e| anyhow::anyhow!("--noise-model: {e}"))?;
    Ok(NoiseChoice::Given(Box::new(given)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SZ: [f64; 6] = [0.38, 0.21, 0.19, 0.0056, 0.0082, 0.0099];

    #[test]
    fn ar1_spec_gives_the_correlation_time() {
        let m = parse_noise_model("ar1:accel=50,gyro=20,motion=1e-4", SZ, 120.0).unwrap();
        let dt = 1.0 / 120.0;
        assert_eq!(m.imu[0].ar.phi(), &[(-dt / 0.05_f64).exp()]);
        assert_eq!(m.imu[5].ar.phi(), &[(-dt / 0.02_f64).exp()]);
        assert_eq!(m.sigma_z(), SZ);
        assert!(m.imu.iter().all(|c| c.motion == 1e-4));
        let exact = dt / ((dt / 0.05_f64).exp() - 1.0);
        assert!((m.imu[0].ar.correlation_time(dt) - exact).abs() < 1e-12);
        let a = parse_noise_model("ar1:accel=10", SZ, 120.0).unwrap();
        assert!(!a.imu[0].ar.is_white() && a.imu[3].ar.is_white());
        assert!(parse_noise_model("white", SZ, 120.0).unwrap().is_white());
    }

    #[test]
    fn bad_specs_say_why() {
        let e = |s: &str| format!("{:#}", parse_noise_model(s, SZ, 120.0).unwrap_err());
        assert!(e("pink").contains("expected `white`"), "{}", e("pink"));
        assert!(
            e("ar1:").contains("accel=TAU_MS and/or gyro"),
            "{}",
            e("ar1:")
        );
        assert!(e("ar1:accel=-5").contains("positive number of ms"));
        assert!(e("ar1:accel=abc").contains("must be a number"));
        assert!(e("ar1:accel=5,motion=-1").contains(">= 0"));
        assert!(e("ar1:accel=5,jerk=1").contains("unknown key `jerk`"));
        assert!(e("ar1:accel").contains("not KEY=VALUE"));
    }
}
