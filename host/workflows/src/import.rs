//! Recordings of other tools written as session directories (`robimu
//! import`): the streams the readers of [`robimu_session::import`] return,
//! checked against the robot they were recorded on.

use std::path::Path;

use anyhow::{bail, Context};
use robimu_model::Robot;
use robimu_session::import::{Imported, Streams};
use robimu_session::SessionMeta;

use crate::pipeline::{resolve_robot, ChainLinks, RobotSource};

/// The robot an import is for: the robot `spec` names (a built-in name or a
/// robot file) and what the session's `robot` field records of it.
pub struct ImportRobot {
    /// The robot.
    pub robot: Robot,
    spec: String,
    source: RobotSource,
}

/// The joints a ROS 2 import picks by name from each JointState, in chain
/// order ([`ImportRobot::joints_by_name`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JointsByName {
    /// The names, in chain order; `None`: the first message's, in its order.
    pub names: Option<Vec<String>>,
    /// Whether the user chose them (a message without names is then
    /// refused); else they are the robot's chain, and an unnamed message is
    /// taken to be in chain order.
    pub given: bool,
}

impl ImportRobot {
    /// The robot `spec` names (a built-in name, a robot TOML or a URDF).
    pub fn resolve(spec: &str) -> anyhow::Result<Self> {
        let (robot, source) = resolve_robot(spec, None, &ChainLinks::default())?;
        Ok(Self {
            robot,
            spec: spec.to_string(),
            source,
        })
    }

    /// The joints to pick by name: those `given` (`--joint-names`), else the
    /// robot's joint names in chain order (every built-in robot but
    /// `aubo_i5`, and every URDF robot, names its joints), so that a
    /// driver's own order and extra joints (a gripper's) do not matter.
    pub fn joints_by_name(&self, given: Option<Vec<String>>) -> JointsByName {
        match given {
            Some(names) => JointsByName {
                names: Some(names),
                given: true,
            },
            None => {
                let names = &self.robot.description().joint_names;
                JointsByName {
                    names: (!names.is_empty()).then(|| names.clone()),
                    given: false,
                }
            }
        }
    }
}

/// Write `streams`, read from `source` (named in the notes and messages),
/// as the session `out` of `robot`, whose joint count they must have.
pub fn write_imported(
    streams: Streams,
    out: &Path,
    robot: ImportRobot,
    source: &str,
) -> anyhow::Result<Imported> {
    let ImportRobot {
        robot,
        spec,
        source: kind,
    } = robot;
    let width = streams.joints.first().map_or(0, |(_, q)| q.len());
    if width != robot.dof() {
        bail!(
            "{source}: {width} joints imported ({}), but robot `{}` has {} (ros2: choose them with --joint-names)",
            streams.joint_names.join(", "),
            robot.name(),
            robot.dof()
        );
    }
    let mut meta = SessionMeta::new(kind.session_field(&spec));
    meta.notes = Some(format!("imported from {source}"));
    streams
        .write_session(out, &meta)
        .with_context(|| format!("cannot write the session {}", out.display()))
}
