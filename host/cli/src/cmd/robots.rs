//! `robimu robots`: the built-in robot catalogue.

use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_model::catalogue::builtin_file;
use robimu_model::urdf::robot_to_urdf;
use robimu_model::{Robot, BUILTIN_ROBOTS};
use robimu_session::export::ur::UrKinematics;
use robimu_session::export::ur_conf::UrCalibrationConf;

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
        /// A Universal Robots arm's own factory calibration as its nominal
        /// kinematics: the kinematics YAML that `ur_calibration` extracts
        /// from the controller (the UR ROS 2 description's
        /// `kinematics_params`), over the built-in NAME's joint names,
        /// limits and noise. Save the printed description and pass it as
        /// `--robot`; `export --format ur-kinematics` writes the
        /// calibrated file back.
        #[arg(long, value_name = "FILE", conflicts_with = "ur_calibration_conf")]
        ur_kinematics: Option<PathBuf>,
        /// A Universal Robots arm's factory calibration as the controller
        /// keeps it (`/root/.urcontrol/calibration.conf`: the corrections
        /// `delta_theta`, `delta_a`, `delta_d`, `delta_alpha` of UR's DH
        /// table), read as its nominal kinematics like --ur-kinematics.
        #[arg(long, value_name = "FILE")]
        ur_calibration_conf: Option<PathBuf>,
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
        let Some(RobotsAction::Show {
            name,
            ur_kinematics,
            ur_calibration_conf,
            urdf,
        }) = self.action
        else {
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
            return Ok(());
        };
        let mut robot = builtin(&name)?;
        if let Some(file) = &ur_kinematics {
            let k = UrKinematics::from_yaml_file(file)?;
            robot = k
                .nominal_robot(&robot, &file.display().to_string())
                .with_context(|| format!("--ur-kinematics {}", file.display()))?;
        }
        if let Some(file) = &ur_calibration_conf {
            let conf = UrCalibrationConf::from_file(file)?;
            robot = UrKinematics::from_calibration_conf(&name, &conf)
                .and_then(|k| k.nominal_robot(&robot, &file.display().to_string()))
                .with_context(|| format!("--ur-calibration-conf {}", file.display()))?;
        }
        let given = ur_kinematics.as_ref().or(ur_calibration_conf.as_ref());
        match (urdf, given) {
            (Some(path), _) => {
                std::fs::write(&path, robot_to_urdf(&robot))
                    .with_context(|| format!("cannot write {}", path.display()))?;
                eprintln!("wrote {} ({name}, {} joints)", path.display(), robot.dof());
            }
            (None, Some(file)) => print!(
                "# Robot `{name}` with the kinematics of {} (robimu robots show {name} --ur-kinematics or --ur-calibration-conf).\n{}",
                file.display(),
                toml::to_string(robot.description())?
            ),
            (None, None) => match builtin_file(&name) {
                Some(file) => print!("{file}"),
                None => print!("{}", toml::to_string(robot.description())?),
            },
        }
        Ok(())
    }
}
