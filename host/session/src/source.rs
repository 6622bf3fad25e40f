//! What a session's samples of the motion are: joint angles (`joints.csv`,
//! docs/model.md §7) or tool poses (`poses.csv`, `source = "poses"`,
//! docs/model.md §7.9). `session.toml` says which; a reader of one kind refuses
//! the other with a message naming it.

use std::path::Path;

use super::error::toml_error;
use super::SessionError;

/// The `source` value of a session with tool poses.
pub const SOURCE_POSES: &str = "poses";
/// The `source` value of a session with joint angles (the default: joint
/// sessions need not say it).
pub const SOURCE_JOINTS: &str = "joints";

/// Which samples of the motion a session has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SessionSource {
    /// Joint angles, `joints.csv`, a `robot` (docs/model.md §7).
    Joints,
    /// Tool poses, `poses.csv`, no robot (docs/model.md §7.9).
    Poses,
}

impl SessionSource {
    /// The source named by a parsed `session.toml`: its `source` key
    /// ([`SOURCE_POSES`], [`SOURCE_JOINTS`]; absent: joints). `path` names
    /// the file in the error of any other value.
    pub fn of_table(doc: &toml::Table, path: &Path) -> Result<Self, SessionError> {
        match doc.get("source") {
            None => Ok(Self::Joints),
            Some(toml::Value::String(s)) if s == SOURCE_POSES => Ok(Self::Poses),
            Some(toml::Value::String(s)) if s == SOURCE_JOINTS => Ok(Self::Joints),
            Some(other) => Err(SessionError::file(
                path,
                format!(
                    "source = {other} is not a session source: `\"{SOURCE_POSES}\"` (tool poses, \
                     poses.csv, docs/model.md §7.9) or `\"{SOURCE_JOINTS}\"` (joint angles, \
                     joints.csv; the default)"
                ),
            )),
        }
    }

    /// The source of the TOML text of a `session.toml`; `path` only names
    /// the file in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SessionError> {
        let doc: toml::Table = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        Self::of_table(&doc, path)
    }

    /// The source of the session in `dir`, from its `session.toml`.
    pub fn of_dir(dir: &Path) -> Result<Self, SessionError> {
        if !dir.is_dir() {
            return Err(SessionError::file(
                dir,
                "not a session directory (it does not exist or is not a directory)",
            ));
        }
        let path = dir.join(crate::files::META);
        let text = crate::text::read(&path)?;
        Self::parse(&text, &path)
    }
}

/// The error of a joint-session reader given a pose session (`path` is its
/// `session.toml`).
pub(crate) fn not_joints(path: &Path) -> SessionError {
    SessionError::file(
        path,
        "this is a pose session (source = \"poses\": tool poses in poses.csv, no robot; \
         docs/model.md §7.9), not a joint session: this command reads joint sessions \
         (joints.csv and a robot); `robimu check` checks both",
    )
}

/// The error of a pose-session reader given a joint session (`path` is its
/// `session.toml`).
pub(crate) fn not_poses(path: &Path) -> SessionError {
    SessionError::file(
        path,
        "this is a joint session (joints.csv and a robot; no source = \"poses\"), not a pose \
         session: a session with tool poses says source = \"poses\" and has poses.csv \
         (docs/model.md §7.9)",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_source_key_names_the_kind() {
        let p = Path::new("s.toml");
        let parse = |t: &str| SessionSource::parse(t, p);
        assert_eq!(parse("robot = \"x\"\n").unwrap(), SessionSource::Joints);
        assert_eq!(parse("source = \"poses\"\n").unwrap(), SessionSource::Poses);
        assert_eq!(
            parse("source = \"joints\"\n").unwrap(),
            SessionSource::Joints
        );
        let e = parse("source = \"mocap\"\n").unwrap_err().to_string();
        assert!(e.contains("s.toml") && e.contains("\"mocap\""), "{e}");
        let e = parse("source = 3\n").unwrap_err().to_string();
        assert!(e.contains("source = 3"), "{e}");
        let e = parse("source = \n").unwrap_err().to_string();
        assert!(e.starts_with("s.toml:1"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let e = SessionSource::of_dir(&dir.path().join("nope")).unwrap_err();
        assert!(e.to_string().contains("not a session directory"), "{e}");
    }
}
