//! Exporting a calibration result for other tools (`robimu export`): the
//! corrected robot (URDF or robot TOML) or the IMU intrinsics (Kalibr
//! imu.yaml or a correction file), one file per IMU where the format needs
//! it (docs/model.md §9).
//!
//! [`robot_spec`] names the robot a result was computed for; [`export`]
//! builds the files from the result and the resolved robot and writes them,
//! telling its caller what it wrote and what it noted ([`Notice`]). A pose
//! session's result (docs/model.md §7.9: no robot) exports its IMU through
//! [`export_poses`]: the same Kalibr and correction files, through the same
//! code (`export_imus`, one IMU or several); the robot formats are refused
//! naming why.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::urdf::{robot_to_urdf, UrdfOptions};
use robimu_model::{ModelParams, Robot};
use robimu_session::export::imu::{
    kalibr_imu_input_yaml, kalibr_imu_list_yaml, kalibr_imu_yaml, Correction, KalibrImu,
    KalibrOptions, KalibrPlacement, DEFAULT_RANDOM_WALK, FLANGE_AXES, POSED_BODY_AXES,
};
use robimu_session::export::robot::{corrected_toml, corrected_urdf};
use robimu_session::export::ros2_control::ros2_control_offsets;
use robimu_session::export::ur::calibrated_ur_yaml;
use robimu_session::export::{calibrated_params, imu_effects};
use robimu_session::result::CalibrationResult;
use robimu_session::{PoseSession, Session, SOURCE_POSES};

use crate::joint_offsets::joint_offsets;
use crate::pipeline::{is_urdf, ChainLinks};

/// What [`export`] writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// The calibrated robot as a URDF: the robot's own URDF corrected, or
    /// (a built-in or TOML robot) its plain URDF corrected.
    Urdf,
    /// The calibrated robot as robot TOML.
    Toml,
    /// The IMU as a Kalibr imu.yaml (several IMUs: Kalibr's IMU list and
    /// one file per IMU beside it).
    Kalibr,
    /// The IMU correction (per sensor M, M⁻¹ and b of z = M·v + b; TOML).
    Correction,
    /// The calibrated robot as Universal Robots' kinematics YAML (the UR
    /// ROS 2 description's `kinematics_params`; needs a robot of UR's
    /// structure).
    UrKinematics,
    /// Joint zero offsets for ros2_control (a `SimpleTransmission` per
    /// joint; [`crate::joint_offsets`]): the part of the calibration that
    /// offsets of the joint readings carry.
    Ros2Control,
}

/// The `hash` of a UR kinematics export whose robot names no factory
/// calibration.
const UNKNOWN_UR_HASH: &str = "robimu_no_factory_calibration";

/// What [`export`] tells its caller as it goes.
#[derive(Debug, Clone, PartialEq)]
pub enum Notice {
    /// A remark for the user (`note: …`).
    Note(String),
    /// A file was written.
    Wrote(PathBuf),
}

/// An export of the result in `calibration` (`robimu export`'s flags).
#[derive(Debug, Clone)]
pub struct ExportRequest {
    /// The result file (result.json), named in messages.
    pub calibration: PathBuf,
    /// What to write.
    pub format: ExportFormat,
    /// The robot as named ([`robot_spec`]): a built-in name or a file.
    pub spec: String,
    /// The directory a relative `spec` is relative to.
    pub spec_base: Option<PathBuf>,
    /// A URDF robot's base and tip links.
    pub links: ChainLinks,
    /// Kalibr: the IMU sample rate, Hz [default: the session's imu.csv].
    pub rate: Option<f64>,
    /// Kalibr: the `rostopic` keys, one per IMU [default: `/imu<j>`].
    pub rostopic: Vec<String>,
    /// Export IMU J alone.
    pub imu: Option<usize>,
    /// Kalibr: accelerometer and gyroscope random walks (two numbers).
    pub random_walk: Vec<f64>,
    /// Kalibr: an allan.csv of `robimu allan` or a noise.toml of `robimu noise`.
    pub noise: Option<PathBuf>,
    /// The file to write.
    pub out: PathBuf,
}

/// The robot `result` (read from `calibration`) was computed for: `given`
/// (`--robot`) as is, else the result's robot relative to its session
/// directory (or to the result file's directory).
pub fn robot_spec(
    result: &CalibrationResult,
    calibration: &Path,
    given: Option<&str>,
) -> anyhow::Result<(String, Option<PathBuf>)> {
    let session_dir = result.session.as_ref().map(PathBuf::from);
    let result_dir = calibration.parent().map(Path::to_path_buf);
    Ok(match (given, &result.robot) {
        (Some(r), _) => (r.to_string(), None),
        (None, Some(r)) => (r.clone(), session_dir.or(result_dir)),
        (None, None) => bail!("{} names no robot: give --robot", calibration.display()),
    })
}

/// Build the export `req` asks for from `result` and `robot` (the robot
/// `req.spec` names) and write it, with [`Notice`]s to `notify`.
pub fn export(
    req: &ExportRequest,
    result: &CalibrationResult,
    robot: &Robot,
    notify: &mut dyn FnMut(Notice),
) -> anyhow::Result<()> {
    let ex = Exporter { req, result, robot };
    let format = match req.format {
        ExportFormat::Urdf => "a URDF",
        ExportFormat::Toml => "a robot TOML",
        ExportFormat::Kalibr => "Kalibr's imu.yaml",
        ExportFormat::Correction => "the correction file",
        ExportFormat::UrKinematics => "UR's kinematics YAML",
        ExportFormat::Ros2Control => "ros2_control's joint offsets",
    };
    if let Some(note) = result.effects_not_carried(format) {
        notify(Notice::Note(note));
    }
    if matches!(req.format, ExportFormat::Kalibr | ExportFormat::Correction) {
        let session = match req.format {
            ExportFormat::Kalibr => result
                .session
                .as_deref()
                .and_then(|d| Session::load(Path::new(d)).ok()),
            _ => None,
        };
        let imus = JointImus {
            ex,
            session: session.as_ref(),
        };
        return export_imus(req, result.imu_count(), &imus, notify);
    }
    let k = result.imu_count();
    let j = req.imu.unwrap_or(0);
    if k > 1 && req.imu.is_none() {
        notify(Notice::Note(format!(
            "the result has {k} IMUs: the robot carries IMU 0's position (--imu J for another)"
        )));
    }
    let (_, params) = ex.imu_params(j)?;
    let text = ex.robot_file(req.format, &params, notify)?;
    write_file(&req.out, &text, notify)
}

/// The ros2_control offsets of `params` for `robot`, with what they carry
/// in the file's comment and in a note.
fn ros2_control(
    robot: &Robot,
    params: &ModelParams,
    notify: &mut dyn FnMut(Notice),
) -> anyhow::Result<String> {
    let fit = joint_offsets(robot, params).context("--format ros2-control")?;
    let d = robot.description();
    let names: Vec<String> = (0..robot.dof())
        .map(|i| {
            d.joint_names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("joint{}", i + 1))
        })
        .collect();
    if d.joint_names.is_empty() {
        notify(Notice::Note(format!(
            "robot `{}` names no joints: the transmissions name them joint1…joint{} (rename them to your description's)",
            robot.name(),
            robot.dof()
        )));
    }
    let (a, b) = (&fit.nominal, &fit.with_offsets);
    let carried = format!(
        "flange error against the calibrated model over {} configurations within the joint limits: nominal {:.3} mm, {:.4}° mean ({:.3} mm, {:.4}° 95th percentile); with these offsets {:.3} mm, {:.4}° mean ({:.3} mm, {:.4}° 95th percentile)",
        crate::pose_accuracy::CONFIGURATIONS,
        a.position_mean_mm, a.rotation_mean_deg, a.position_p95_mm, a.rotation_p95_deg,
        b.position_mean_mm, b.rotation_mean_deg, b.position_p95_mm, b.rotation_p95_deg,
    );
    notify(Notice::Note(format!(
        "ros2_control's offsets carry the joint zeros only: {carried}; the rest (link lengths and axis tilts, the IMU, effects such as joint elasticity) needs the corrected URDF (--format urdf)"
    )));
    let comment = vec![
        format!(
            "robimu: joint zero offsets of a calibration of `{}` for ros2_control.",
            robot.name()
        ),
        "Each is a transmission_interface/SimpleTransmission: joint position =".into(),
        "actuator position / mechanical_reduction + offset (rad), so the nominal".into(),
        "description sees the reading plus the offset. Copy the <transmission>".into(),
        "elements into your robot's <ros2_control> tag.".into(),
        format!("What they carry: {carried}."),
        "What they cannot: link lengths and axis tilts (the corrected URDF: robimu export, format urdf),".into(),
        "the IMU, and effects such as joint elasticity.".into(),
    ];
    Ok(ros2_control_offsets(
        robot.name(),
        &names,
        &fit.offsets,
        &comment,
    ))
}

/// The `rostopic` of each of `k` IMUs: the request's (one per IMU, or one
/// with `imu`), else `/imu<j>`.
fn rostopics(req: &ExportRequest, k: usize) -> anyhow::Result<Vec<String>> {
    match req.rostopic.len() {
        0 => Ok((0..k).map(|j| format!("/imu{j}")).collect()),
        n if n == k => Ok(req.rostopic.clone()),
        1 if req.imu.is_some() => Ok(vec![req.rostopic[0].clone(); k]),
        n => bail!(
            "--rostopic: {n} topics for {k} IMUs (give one per IMU, comma-separated{})",
            if k > 1 { ", or one with --imu J" } else { "" }
        ),
    }
}

/// One export's inputs.
struct Exporter<'a> {
    req: &'a ExportRequest,
    result: &'a CalibrationResult,
    robot: &'a Robot,
}

impl Exporter<'_> {
    /// IMU `j`'s one-IMU view of the result (docs/model.md §9).
    fn view(&self, j: usize) -> anyhow::Result<CalibrationResult> {
        self.result
            .imu(j)
            .map_err(|e| anyhow::anyhow!("{}: {e}", self.req.calibration.display()))
    }

    /// IMU `j`'s parameters, with its one-IMU view.
    fn imu_params(&self, j: usize) -> anyhow::Result<(CalibrationResult, ModelParams)> {
        let view = self.view(j)?;
        let params = calibrated_params(self.robot, &view).with_context(|| {
            format!(
                "{} does not fit robot `{}`",
                self.req.calibration.display(),
                self.req.spec
            )
        })?;
        Ok((view, params))
    }

    /// The calibrated robot in a robot `format` with one IMU's `params`.
    fn robot_file(
        &self,
        format: ExportFormat,
        params: &ModelParams,
        notify: &mut dyn FnMut(Notice),
    ) -> anyhow::Result<String> {
        let (req, spec) = (self.req, self.req.spec.as_str());
        Ok(match format {
            ExportFormat::Toml => corrected_toml(self.robot, params)?,
            ExportFormat::UrKinematics => {
                let text = calibrated_ur_yaml(self.robot, params, UNKNOWN_UR_HASH)
                    .with_context(|| format!("--format ur-kinematics: robot `{spec}`"))?;
                notify(Notice::Note(
                    "the UR kinematics YAML carries the joint geometry only (base to tool0): not the IMU's mount and intrinsics, the time offset, nor effects such as joint elasticity".into(),
                ));
                if self.robot.description().calibration_hash.is_none() {
                    notify(Notice::Note(format!(
                        "the robot names no factory calibration: hash `{UNKNOWN_UR_HASH}` (read the robot's calibration as the nominal with `robimu robots show MODEL --ur-kinematics FILE`)"
                    )));
                }
                text
            }
            ExportFormat::Ros2Control => ros2_control(self.robot, params, notify)?,
            ExportFormat::Urdf => {
                let path = match &req.spec_base {
                    Some(b) if Path::new(spec).is_relative() => b.join(spec),
                    _ => PathBuf::from(spec),
                };
                if is_urdf(&path) {
                    let urdf = robimu_model::text::read_to_string(&path)
                        .with_context(|| format!("cannot read {}", path.display()))?;
                    let opts = UrdfOptions {
                        base: req.links.base.clone(),
                        tip: req.links.tip.clone(),
                        ..UrdfOptions::default()
                    };
                    corrected_urdf(&urdf, &opts, params)?
                } else {
                    // a built-in or TOML robot: its plain URDF (`robots show
                    // --urdf`: the maker's base and flange links and joint
                    // names), corrected
                    notify(Notice::Note(format!(
                        "`{spec}` is not a URDF: the corrected URDF is its plain description (links and joints, as `robimu robots show --urdf` writes it; no meshes, inertias or ros2_control tags)"
                    )));
                    corrected_urdf(&robot_to_urdf(self.robot), &UrdfOptions::default(), params)?
                }
            }
            ExportFormat::Kalibr | ExportFormat::Correction => {
                bail!("not a robot format: the IMU formats are export_imus'")
            }
        })
    }
}

/// The IMUs of a result as the IMU formats (Kalibr, correction) take them:
/// a joint session's through its robot ([`JointImus`]), a pose session's
/// without one ([`PoseImus`]).
trait ImuSource {
    /// IMU `j`'s one-IMU view of the result (docs/model.md §9) and its
    /// parameters.
    fn imu_params(&self, j: usize) -> anyhow::Result<(CalibrationResult, ModelParams)>;

    /// The Kalibr options of IMU `j` (its one-IMU view `view`): the sample
    /// rate from the request or the session's `imu.csv` / `imu<j>.csv`, the
    /// noise from the request's noise file or the session, the fitted effects.
    fn kalibr_options(
        &self,
        view: &CalibrationResult,
        j: usize,
        rostopic: &str,
        notify: &mut dyn FnMut(Notice),
    ) -> anyhow::Result<KalibrOptions>;
}

/// A joint session's IMUs: parameters through the robot, rate and noise
/// from the session (when readable) or the robot.
struct JointImus<'a> {
    ex: Exporter<'a>,
    session: Option<&'a Session>,
}

impl ImuSource for JointImus<'_> {
    fn imu_params(&self, j: usize) -> anyhow::Result<(CalibrationResult, ModelParams)> {
        self.ex.imu_params(j)
    }

    fn kalibr_options(
        &self,
        view: &CalibrationResult,
        j: usize,
        rostopic: &str,
        notify: &mut dyn FnMut(Notice),
    ) -> anyhow::Result<KalibrOptions> {
        let (req, robot) = (self.ex.req, self.ex.robot);
        let imu_table = self.session.map(|s| {
            if j == 0 {
                Some(&s.imu)
            } else {
                s.extra_imus.get(j - 1).map(|t| &t.samples)
            }
        });
        let rate = sample_rate(req.rate, imu_table, j)?;
        let (sigma_z, noise_source) = match self.session {
            Some(s) => (s.noise(robot)?.0, "session's noise"),
            None => (robot.sigma_z(), "robot's noise"),
        };
        let noise_source = format!("largest per-sample σ of the {noise_source} / √rate");
        kalibr_options(req, view, rate, (sigma_z, noise_source), rostopic, notify)
    }
}

/// A pose session's IMUs (docs/model.md §7.9): parameters without a robot
/// ([`pose_params`]), rate and noise from the pose session (when readable)
/// or the pose calibration's defaults.
struct PoseImus<'a> {
    req: &'a ExportRequest,
    result: &'a CalibrationResult,
    session: Option<PoseSession>,
}

impl ImuSource for PoseImus<'_> {
    fn imu_params(&self, j: usize) -> anyhow::Result<(CalibrationResult, ModelParams)> {
        let shown = self.req.calibration.display();
        let view = self
            .result
            .imu(j)
            .map_err(|e| anyhow::anyhow!("{shown}: {e}"))?;
        let params = pose_params(&view).with_context(|| format!("{shown}: not a pose result"))?;
        Ok((view, params))
    }

    fn kalibr_options(
        &self,
        view: &CalibrationResult,
        j: usize,
        rostopic: &str,
        notify: &mut dyn FnMut(Notice),
    ) -> anyhow::Result<KalibrOptions> {
        let session = self.session.as_ref();
        let imu_table = session.map(|s| s.imus.get(j).map(|t| &t.samples));
        let rate = sample_rate(self.req.rate, imu_table, j)?;
        let (sigma_z, source) = match session {
            Some(s) => (
                crate::pipeline::poses::pose_options(&s.meta, |_| {}).sigma_z,
                "largest per-sample σ of the session's noise / √rate",
            ),
            None => (
                crate::pose_calibrate::PoseCalibrationOptions::default().sigma_z,
                "largest per-sample σ of the pose calibration's default noise / √rate",
            ),
        };
        kalibr_options(
            self.req,
            view,
            rate,
            (sigma_z, source.into()),
            rostopic,
            notify,
        )
    }
}

/// The IMU formats of a result of `k` IMUs (docs/model.md §9), a joint or a
/// pose session's alike: `--imu J` writes IMU J's file to `req.out`; else
/// one IMU writes its file, several write Kalibr's IMU list to `req.out`
/// and one file per IMU beside it ([`per_imu_path`]; the correction: the
/// per-IMU files alone).
fn export_imus(
    req: &ExportRequest,
    k: usize,
    imus: &dyn ImuSource,
    notify: &mut dyn FnMut(Notice),
) -> anyhow::Result<()> {
    let rostopics = rostopics(req, k)?;
    if let Some(j) = req.imu {
        imus.imu_params(j)?;
    }
    let text = match req.format {
        ExportFormat::Kalibr if k > 1 => {
            let mut views = Vec::new();
            for (j, topic) in rostopics.iter().enumerate() {
                let (view, params) = imus.imu_params(j)?;
                let opts = imus.kalibr_options(&view, j, topic, notify)?;
                views.push((params, opts));
            }
            let list: Vec<KalibrImu<'_>> = views
                .iter()
                .map(|(p, o)| KalibrImu {
                    params: p,
                    opts: o,
                    placement: KalibrPlacement::relative(&views[0].0, p),
                })
                .collect();
            if let Some(j) = req.imu {
                kalibr_imu_input_yaml(j, &list)
            } else {
                for j in 0..k {
                    let path = per_imu_path(&req.out, j);
                    write_file(&path, &kalibr_imu_input_yaml(j, &list), notify)?;
                }
                kalibr_imu_list_yaml(&list)
            }
        }
        ExportFormat::Correction if k > 1 && req.imu.is_none() => {
            for j in 0..k {
                let (_, params) = imus.imu_params(j)?;
                let text = Correction::new(&params)
                    .with_context(|| format!("IMU {j}"))?
                    .to_toml()?;
                write_file(&per_imu_path(&req.out, j), &text, notify)?;
            }
            return Ok(());
        }
        format => {
            let j = req.imu.unwrap_or(0);
            let (view, params) = imus.imu_params(j)?;
            match format {
                ExportFormat::Kalibr => {
                    let opts = imus.kalibr_options(&view, j, &rostopics[j], notify)?;
                    kalibr_imu_yaml(&params, &opts)
                }
                ExportFormat::Correction => Correction::new(&params)?.to_toml()?,
                _ => bail!("not an IMU format: the robot formats need a robot"),
            }
        }
    };
    write_file(&req.out, &text, notify)
}

/// The Kalibr options of one IMU (its one-IMU view `view`) sampled at
/// `rate` with per-sample σ `sigma_z` (and where they come from): the noise
/// from the request's noise file where given, the fitted effects.
fn kalibr_options(
    req: &ExportRequest,
    view: &CalibrationResult,
    rate: f64,
    (sigma_z, noise_source): ([f64; 6], String),
    rostopic: &str,
    notify: &mut dyn FnMut(Notice),
) -> anyhow::Result<KalibrOptions> {
    let mut noise = KalibrNoise {
        sigma_z,
        noise_source,
        noise_density: None,
        random_walk: DEFAULT_RANDOM_WALK,
        random_walk_source: None,
    };
    if let Some(path) = &req.noise {
        noise.read(path, notify)?;
    }
    match req.random_walk.as_slice() {
        [] => {}
        &[a, g] if [a, g].iter().all(|v| v.is_finite() && *v > 0.0) => {
            noise.random_walk = [a, g];
            noise.random_walk_source = Some("given with --random-walk".into());
        }
        other => bail!(
            "--random-walk {other:?}: give two positive numbers, ACCEL,GYRO (Kalibr divides by them)"
        ),
    }
    if noise.random_walk_source.is_none() {
        notify(Notice::Note(format!(
            "the random walks in the imu.yaml are placeholders ({}, {}): give --noise allan.csv of a long static recording, or --random-walk",
            noise.random_walk[0], noise.random_walk[1]
        )));
    }
    let (g_sensitivity, size_effect) = imu_effects(view)?;
    Ok(KalibrOptions {
        rate,
        sigma_z: noise.sigma_z,
        noise_density: noise.noise_density,
        noise_source: noise.noise_source,
        rostopic: rostopic.to_string(),
        body_axes: if is_pose_result(view) {
            POSED_BODY_AXES
        } else {
            FLANGE_AXES
        },
        random_walk: noise.random_walk,
        random_walk_source: noise.random_walk_source,
        g_sensitivity,
        size_effect,
    })
}

/// Whether `result` is a pose session's (docs/model.md §7.9: `"source":
/// "poses"`, no robot).
pub fn is_pose_result(result: &CalibrationResult) -> bool {
    result.source.as_deref() == Some(SOURCE_POSES)
}

/// [`export`] of a pose session's result (docs/model.md §7.9): the IMU's
/// intrinsics as Kalibr's imu.yaml or the correction file, from the same
/// 24 sensor parameters as a joint session's; the robot formats are
/// refused (a pose session has no robot). The sample rate and noise come
/// from the request or the result's pose session. A result of several
/// IMUs is exported as a joint session's is ([`export_imus`]: Kalibr's IMU
/// list and one file per IMU, or the one `--imu J` names).
pub fn export_poses(
    req: &ExportRequest,
    result: &CalibrationResult,
    notify: &mut dyn FnMut(Notice),
) -> anyhow::Result<()> {
    let robot_format = match req.format {
        ExportFormat::Kalibr | ExportFormat::Correction => None,
        ExportFormat::Urdf => Some("urdf"),
        ExportFormat::Toml => Some("toml"),
        ExportFormat::UrKinematics => Some("ur-kinematics"),
        ExportFormat::Ros2Control => Some("ros2-control"),
    };
    if let Some(f) = robot_format {
        bail!(
            "{}: a pose session has no robot: --format {f} writes a calibrated robot, and this \
             result (source = \"poses\", docs/model.md §7.9) has the IMU's parameters only; \
             --format kalibr or --format correction export them",
            req.calibration.display()
        );
    }
    if let Some(note) = result.effects_not_carried(match req.format {
        ExportFormat::Kalibr => "Kalibr's imu.yaml",
        _ => "the correction file",
    }) {
        notify(Notice::Note(note));
    }
    let imus = PoseImus {
        req,
        result,
        session: match req.format {
            ExportFormat::Kalibr => result
                .session
                .as_deref()
                .and_then(|d| PoseSession::read(Path::new(d)).ok()),
            _ => None,
        },
    };
    export_imus(req, result.imu_count(), &imus, notify)
}

/// A pose result's IMU parameters as [`ModelParams`] of no robot: the 24
/// sensor parameters, g, τ, and the IMU's position p_imu on the posed body
/// as the last (here: only) link's ε_1..3.
fn pose_params(view: &CalibrationResult) -> anyhow::Result<ModelParams> {
    let (accel, gyro) = robimu_session::export::calibrated_intrinsics(view)?;
    let get = |n: &str| {
        view.parameter(n)
            .map(|p| p.value)
            .with_context(|| format!("no parameter {n}"))
    };
    Ok(ModelParams {
        eps: vec![[
            get("p_imu_x")?,
            get("p_imu_y")?,
            get("p_imu_z")?,
            0.0,
            0.0,
            0.0,
        ]],
        g_xy: [get("g_x")?, get("g_y")?],
        tau: get("tau")?,
        accel,
        gyro,
    })
}

/// IMU `j`'s sample rate: `given`, else the median rate of its samples
/// (`imu_table`: `None` when the result's session is not readable, `Some(None)`
/// when it has no `imu.csv` / `imu<j>.csv`).
fn sample_rate(
    given: Option<f64>,
    imu_table: Option<Option<&robimu_session::Table>>,
    j: usize,
) -> anyhow::Result<f64> {
    let file = robimu_session::files::imu_csv(j);
    let rate = match (given, imu_table) {
        (Some(r), _) => r,
        (None, Some(Some(t))) => t
            .median_rate()
            .with_context(|| format!("the session's {file} has no sample interval: give --rate"))?,
        (None, Some(None)) => bail!("the result's session has no {file}: give --rate"),
        (None, None) => bail!(
            "the IMU sample rate is unknown (the result's session is not readable): give --rate"
        ),
    };
    if !(rate.is_finite() && rate > 0.0) {
        bail!("--rate {rate}: must be a positive number of Hz");
    }
    Ok(rate)
}

/// The noise parts of [`KalibrOptions`].
struct KalibrNoise {
    sigma_z: [f64; 6],
    noise_source: String,
    noise_density: Option<[f64; 2]>,
    random_walk: [f64; 2],
    random_walk_source: Option<String>,
}

impl KalibrNoise {
    /// The noise of `path`: an allan.csv (densities N and, where measurable,
    /// random walks K) or a noise.toml (its `sigma_z`).
    fn read(&mut self, path: &Path, notify: &mut dyn FnMut(Notice)) -> anyhow::Result<()> {
        let shown = path.display();
        let is_csv = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        if !is_csv {
            let file =
                crate::noise::NoiseFile::read(path).with_context(|| format!("--noise {shown}"))?;
            let Some(s) = file.noise.sigma_z else {
                bail!("--noise {shown}: its [noise] table has no sigma_z");
            };
            self.sigma_z = s;
            self.noise_source = format!("largest per-sample σ of {shown} / √rate");
            return Ok(());
        }
        let text = robimu_model::text::read_to_string(path)
            .with_context(|| format!("cannot read --noise {shown}"))?;
        let curves = crate::allan::curves_from_csv(&text).map_err(|e| {
            anyhow::anyhow!("--noise {shown}: not an allan.csv of `robimu allan`: {e}")
        })?;
        let largest = |r: std::ops::Range<usize>, f: &dyn Fn(usize) -> Option<f64>| {
            r.map(f).try_fold(0.0f64, |m, v| v.map(|v| m.max(v)))
        };
        let density = |c: usize| Some(curves[c].terms.density).filter(|d| d.is_finite());
        let walk =
            |c: usize| crate::allan::rate_random_walk(&curves[c].curve, curves[c].terms.density);
        let (Some(na), Some(ng)) = (largest(0..3, &density), largest(3..6, &density)) else {
            bail!("--noise {shown}: no noise density on every channel");
        };
        self.noise_density = Some([na, ng]);
        self.noise_source =
            format!("the Allan deviation's N (largest of each sensor's axes) in {shown}");
        match (largest(0..3, &walk), largest(3..6, &walk)) {
            (Some(a), Some(g)) => {
                self.random_walk = [a, g];
                self.random_walk_source = Some(format!(
                    "the Allan deviation's rate random walk K (σ = K·√(τ/3), largest of each sensor's axes) in {shown}"
                ));
            }
            _ => notify(Notice::Note(format!(
                "{shown}: the Allan curves do not rise as √τ on every axis (record longer at rest): the random walks stay placeholders"
            ))),
        }
        Ok(())
    }
}

/// IMU `j`'s file beside `out`: its stem followed by j (`imu.yaml` →
/// `imu1.yaml`; `_` between a stem ending in a digit and j).
pub(crate) fn per_imu_path(out: &Path, j: usize) -> PathBuf {
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
fn write_file(path: &Path, text: &str, notify: &mut dyn FnMut(Notice)) -> anyhow::Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    notify(Notice::Wrote(path.to_path_buf()));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_imu_paths() {
        let p = |s: &str, j| per_imu_path(Path::new(s), j);
        assert_eq!(p("out/imu.yaml", 1), Path::new("out/imu1.yaml"));
        assert_eq!(p("out/imu0.yaml", 2), Path::new("out/imu0_2.yaml"));
        assert_eq!(p("corr", 0), Path::new("corr0"));
    }
}
