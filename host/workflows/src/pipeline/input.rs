//! A session directory and its robot as the pipeline reads them: the robot a
//! session names (built-in, TOML description or URDF), the session's own
//! gravity and IMU mounts over it, and the check that both agree.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::error_selection::{identifiable_errors, IdentifiableOptions};
use robimu_model::urdf::{robot_from_urdf_file, UrdfOptions};
use robimu_model::Robot;
use robimu_session::Session;

use crate::check::{CheckReport, Severity};

/// Robots built into the program (`--robot NAME`, `robot = "NAME"`): the
/// catalogue of `robimu_model::catalogue`.
pub use robimu_model::BUILTIN_ROBOTS;

/// Where a robot description comes from.
pub enum RobotSource {
    /// A built-in robot.
    Builtin,
    /// A TOML robot description at this path.
    File(PathBuf),
}

impl RobotSource {
    /// `robot = …` in the session.toml of a session made for the robot
    /// `spec` names: the built-in name, or the file's absolute path (the
    /// session must find it from its own directory).
    pub fn session_field(self, spec: &str) -> String {
        match self {
            RobotSource::Builtin => spec.to_string(),
            RobotSource::File(path) => std::path::absolute(&path)
                .unwrap_or(path)
                .display()
                .to_string(),
        }
    }
}

/// Base and tip link of a URDF robot's chain; `None`: the URDF's root link,
/// and its only leaf link.
#[derive(Debug, Clone, Default)]
pub struct ChainLinks {
    /// The base link of the chain.
    pub base: Option<String>,
    /// The tip (flange) link of the chain.
    pub tip: Option<String>,
}

/// Whether `path` names a URDF file (by its extension).
pub fn is_urdf(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("urdf"))
}

/// The robot `spec` names: a built-in name, or a path to a TOML robot
/// description or a URDF (relative paths are taken relative to `base` when
/// given), a URDF's chain chosen by `links`.
pub fn resolve_robot(
    spec: &str,
    base: Option<&Path>,
    links: &ChainLinks,
) -> anyhow::Result<(Robot, RobotSource)> {
    if let Some(robot) = Robot::builtin(spec) {
        return Ok((robot, RobotSource::Builtin));
    }
    let path = match base {
        Some(base) if Path::new(spec).is_relative() => base.join(spec),
        _ => PathBuf::from(spec),
    };
    if !path.is_file() {
        bail!(
            "unknown robot `{spec}`: not a built-in robot ({}) and no robot description file {}",
            BUILTIN_ROBOTS.join(", "),
            path.display()
        );
    }
    let robot = if is_urdf(&path) {
        let opts = UrdfOptions {
            base: links.base.clone(),
            tip: links.tip.clone(),
            ..UrdfOptions::default()
        };
        robot_from_urdf_file(&path, &opts)
            .with_context(|| format!("cannot use the URDF {}", path.display()))?
            .0
    } else {
        Robot::from_toml_file(&path)
            .with_context(|| format!("cannot use the robot description {}", path.display()))?
    };
    // docs/model.md §1: without an explicit `[errors]` table the estimated
    // generalized errors are found numerically, never hand-listed.
    let robot = if robot.description().errors.is_none() {
        let set = identifiable_errors(&robot, &IdentifiableOptions::default()).with_context(|| {
            format!(
                "{}: cannot determine which generalized errors are identifiable (list them in an [errors] table)",
                path.display()
            )
        })?;
        robot.with_estimated_errors(set.errors)?
    } else {
        robot
    };
    Ok((robot, RobotSource::File(path)))
}

/// The session's robot, with the session's gravity magnitude when it sets one
/// and each IMU's mount prior from its `[imu.mount]` / `[imu<j>.mount]`
/// table (docs/model.md §9: IMU 0's missing keys keep the robot's
/// `[imu_mount]`, IMU j ≥ 1's keep IMU 0's).
pub fn session_robot(session: &Session) -> anyhow::Result<Robot> {
    let toml = session.dir.join("session.toml");
    let (mut robot, _) = resolve_robot(
        &session.meta.robot,
        Some(&session.dir),
        &ChainLinks::default(),
    )
    .with_context(|| format!("{}: `robot`", toml.display()))?;
    if let Some(g0) = session.meta.gravity {
        robot = robot
            .with_gravity(g0)
            .context("session.toml: `gravity` is not usable")?;
    }
    for (&j, m) in &session.meta.mounts {
        // in order: IMU 0 first, so that IMU j ≥ 1 builds on IMU 0's prior
        let base = *robot.mount();
        let name = if j == 0 {
            "imu".into()
        } else {
            format!("imu{j}")
        };
        robot = robot
            .with_mount(j, m.over(&base))
            .with_context(|| format!("{}: [{name}.mount] is not usable", toml.display()))?;
    }
    Ok(robot)
}

/// Loads the session at `dir` with its robot, checking that they have the
/// same joint count and that the streams' times pass the check's fatal
/// tests (a time unit off by 10³ᵏ, no rate, no overlap) before any command
/// lays a spline over them.
pub fn load_session(dir: &Path) -> anyhow::Result<(Session, Robot)> {
    let session =
        Session::load(dir).with_context(|| format!("cannot load the session {}", dir.display()))?;
    check_times(&session)?;
    let robot = session_robot(&session)?;
    if session.joint_count() != robot.dof() {
        bail!(
            "{}: {} joint columns (q1..q{}), but robot `{}` has {} joints",
            dir.join("joints.csv").display(),
            session.joint_count(),
            session.joint_count(),
            robot.name(),
            robot.dof()
        );
    }
    Ok((session, robot))
}

/// An error when `session`'s times fail the check's fatal stream tests (a
/// time unit off by 10³ᵏ, no rate, streams that do not overlap): before a
/// spline is laid over them.
pub fn check_times(session: &Session) -> anyhow::Result<()> {
    let report = CheckReport {
        findings: crate::check::streams::check(session),
    };
    fatal_findings(&report, &session.dir).map_err(|e| {
        anyhow::anyhow!(
            "{e}; `robimu check {}` lists every finding",
            session.dir.display()
        )
    })
}

/// An error naming the check's fatal findings for the session in `dir`, if any.
pub fn fatal_findings(report: &CheckReport, dir: &Path) -> anyhow::Result<()> {
    let fatal: Vec<String> = report
        .of(Severity::Fatal)
        .map(|f| format!("{} (what to do: {})", f.message, f.action))
        .collect();
    if fatal.is_empty() {
        return Ok(());
    }
    bail!(
        "the session {} failed the check: {}",
        dir.display(),
        fatal.join("; ")
    )
}
