//! Recordings of other tools written as session directories (`robimu
//! import`): the streams the readers of [`robimu_session::import`] return,
//! checked against the robot they were recorded on.

use std::path::Path;

use anyhow::{bail, Context};
use robimu_session::import::{Imported, Streams};
use robimu_session::SessionMeta;

use crate::pipeline::{resolve_robot, ChainLinks};

/// Write `streams`, read from `source` (named in the notes and messages),
/// as the session `out` of the robot `robot` names (a built-in name or a
/// robot file), whose joint count they must have.
pub fn write_imported(
    streams: Streams,
    out: &Path,
    robot: &str,
    source: &str,
) -> anyhow::Result<Imported> {
    let spec = robot;
    let (robot, kind) = resolve_robot(spec, None, &ChainLinks::default())?;
    let width = streams.joints.first().map_or(0, |(_, q)| q.len());
    if width != robot.dof() {
        bail!(
            "{source}: {width} joints imported ({}), but robot `{}` has {} (ros2: choose them with --joint-names)",
            streams.joint_names.join(", "),
            robot.name(),
            robot.dof()
        );
    }
    let mut meta = SessionMeta::new(kind.session_field(spec));
    meta.notes = Some(format!("imported from {source}"));
    streams
        .write_session(out, &meta)
        .with_context(|| format!("cannot write the session {}", out.display()))
}
