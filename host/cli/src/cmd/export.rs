//! `robimu export`: a calibration result in the formats other tools read.

use std::path::PathBuf;

use robimu_session::result::CalibrationResult;
use robimu_workflows::export::{
    export, export_poses, is_pose_result, robot_spec, ExportFormat as Format, ExportRequest, Notice,
};
use robimu_workflows::pipeline::ChainLinks;

use crate::args::UrdfLinks;
use crate::input::{output_path, resolve_robot_with};

/// What `robimu export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// The calibrated robot as a URDF: the robot's own URDF with corrected
    /// joint origins and an `imu_link` (a built-in or TOML robot: its plain
    /// URDF, as `robots show --urdf` writes it, corrected).
    Urdf,
    /// The calibrated robot as robot TOML (`--robot FILE.toml` reads it).
    Toml,
    /// The IMU as a Kalibr imu.yaml (noise densities, scale-misalignment intrinsics).
    Kalibr,
    /// The IMU correction for firmware or drivers: per sensor the matrix M,
    /// M⁻¹ and bias b of z = M·v + b (TOML); apply v = M⁻¹·(z − b).
    Correction,
    /// The calibrated robot as Universal Robots' kinematics YAML: pass it
    /// to the UR ROS 2 description as `kinematics_params` (needs a UR robot:
    /// a built-in `ur*`, or one read with `robots show --ur-kinematics`).
    UrKinematics,
    /// Joint zero offsets for ros2_control: a `SimpleTransmission` per joint
    /// (joint = actuator + offset) to merge into the robot's
    /// `<ros2_control>` tag; the offsets that bring the nominal flange pose
    /// closest to the calibrated one over the workspace, with what they
    /// leave (the rest needs the corrected URDF).
    Ros2Control,
}

/// Export a calibration for other tools: the corrected robot (URDF or
/// robot TOML) or the IMU intrinsics (Kalibr imu.yaml or a correction file).
///
/// The robot is the one the result names (relative to its session
/// directory) unless --robot is given; it must be the robot the calibration
/// was computed for. A pose session's result (docs/model.md §7.9) has no
/// robot: it exports its IMU (kalibr, correction) only.
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
    /// The chain of a URDF robot.
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
        self.export(&mut |notice| match notice {
            Notice::Note(text) => eprintln!("note: {text}"),
            Notice::Wrote(path) => println!("wrote {}", path.display()),
        })
    }

    /// Export, telling `notice` each note and each file written.
    pub fn export(self, notice: &mut dyn FnMut(Notice)) -> anyhow::Result<()> {
        let out = output_path(Some(&self.out), self.out.clone())?;
        let result = CalibrationResult::read(&self.calibration)?;
        let poses = is_pose_result(&result);
        if poses && self.robot.is_some() {
            anyhow::bail!(
                "--robot: a pose session has no robot ({} is a pose session's result, source = \"poses\")",
                self.calibration.display()
            );
        }
        let (spec, spec_base) = if poses {
            (String::new(), None)
        } else {
            robot_spec(&result, &self.calibration, self.robot.as_deref())?
        };
        let request = ExportRequest {
            calibration: self.calibration,
            format: match self.format {
                ExportFormat::Urdf => Format::Urdf,
                ExportFormat::Toml => Format::Toml,
                ExportFormat::Kalibr => Format::Kalibr,
                ExportFormat::Correction => Format::Correction,
                ExportFormat::UrKinematics => Format::UrKinematics,
                ExportFormat::Ros2Control => Format::Ros2Control,
            },
            spec,
            spec_base,
            links: ChainLinks {
                base: self.links.base.clone(),
                tip: self.links.tip.clone(),
            },
            rate: self.rate,
            rostopic: self.rostopic,
            imu: self.imu,
            random_walk: self.random_walk,
            noise: self.noise,
            out,
        };
        if poses {
            return export_poses(&request, &result, notice);
        }
        let (robot, _) =
            resolve_robot_with(&request.spec, request.spec_base.as_deref(), &self.links)?;
        export(&request, &result, &robot, notice)
    }
}
