//! `robimu robots`: the built-in robot catalogue.

use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_model::catalogue::builtin_file;
use robimu_model::urdf::robot_to_urdf;
use robimu_model::{Robot, BUILTIN_ROBOTS};

/// The built-in robots: list them, print one, or write one as URDF.
///
/// Without a subcommand, lists every built-in robot (name, joints, source).
/// Every command that takes `--robot` accepts these names.
#[derive(Debug, Clone, clap::Args)]
pub struct RobotsCmd {
    #[command(subcommand)]
    pub action: Option<RobotsAction>,
}

/// What `robimu robots` does.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum RobotsAction {
    /// Print a built-in robot's description (the robot TOML format: save it
    /// to a file, edit it and pass the file as `--robot`).
    Show {
        /// The built-in robot's name (`robimu robots` lists them).
        name: String,
        /// Instead, write its nominal kinematics as a plain URDF (links and
        /// joints only) to this file.
        #[arg(long, value_name = "FILE")]
        urdf: Option<PathBuf>,
    },
}

fn builtin(name: &str) -> anyhow::Result<Robot> {
    match Robot::builtin(name) {
        Some(r) => Ok(r),
        None => bail!(
            "unknown robot `{name}`: the built-in robots are {}",
            BUILTIN_ROBOTS.join(", ")
        ),
    }
}

impl RobotsCmd {
    /// Run the command.
    pub fn run(self) -> anyhow::Result<()> {
        match self.action {
            None => {
                println!("{:<8} {:>6}  source", "name", "joints");
                for name in BUILTIN_ROBOTS {
                    let r = builtin(name)?;
                    let source = r
                        .description()
                        .source
                        .clone()
                        .unwrap_or_else(|| "docs/model.md §6 (the paper's AUBO i5, §8)".into());
                    println!("{name:<8} {:>6}  {source}", r.dof());
                }
                Ok(())
            }
            Some(RobotsAction::Show { name, urdf: None }) => {
                let r = builtin(&name)?;
                match builtin_file(&name) {
                    Some(file) => print!("{file}"),
                    None => print!("{}", toml::to_string(r.description())?),
                }
                Ok(())
            }
            Some(RobotsAction::Show {
                name,
                urdf: Some(path),
            }) => {
                let r = builtin(&name)?;
                std::fs::write(&path, robot_to_urdf(&r))
                    .with_context(|| format!("cannot write {}", path.display()))?;
                eprintln!("wrote {} ({name}, {} joints)", path.display(), r.dof());
                Ok(())
            }
        }
    }
}
