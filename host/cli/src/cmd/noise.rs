//! `robimu noise`: Σ_z and Σ_q of a recording by spline fitting (paper §8.1).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Context;
use robimu_report::noise::{NoiseCorrelationTable, NoiseTable};
use robimu_session::Session;
use robimu_workflows::noise::{estimate_noise, identify_imu_noise, NoiseFile, NoiseOptions};
use robimu_workflows::noise_id::IdOptions;

use crate::input::{output_path, session_robot};

/// Estimate the measurement noise of a session from its own samples.
///
/// Fits every joint and IMU channel with a least-squares cubic spline over
/// time, the knot spacing halved while that still explains significantly
/// more of the signal, and takes the residual σ (corrected for the fit's
/// degrees of freedom). Prints the table (with the σ a calibration would
/// otherwise assume: the session's `[noise]` or the robot's), then each IMU
/// channel's identified noise correlation (AR order and coefficients,
/// correlation time, N_eff/N, the factor a white model understates σ by,
/// motion gain, Ljung–Box whiteness), and writes a TOML file with a
/// `[noise]` table in session.toml's format (plus `ar_z` and `motion_z`),
/// for `robimu calibrate --noise`.
#[derive(Debug, Clone, clap::Args)]
pub struct NoiseCmd {
    /// Session directory (session.toml, joints.csv, imu.csv), recorded while
    /// the robot moves.
    pub session: PathBuf,
    /// Noise file to write [default: noise.toml in the session directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

impl NoiseCmd {
    /// Estimate, print and write.
    pub fn run(self) -> anyhow::Result<()> {
        let dir = &self.session;
        let session = Session::load(dir)
            .with_context(|| format!("cannot load the session {}", dir.display()))?;
        robimu_workflows::pipeline::check_times(&session)?;
        let path = output_path(self.out.as_deref(), dir.join("noise.toml"))?;
        let data = session.measurements();
        let opts = NoiseOptions::default();
        let est = estimate_noise(&data, session.joint_count(), &opts)
            .with_context(|| format!("cannot estimate the noise of {}", dir.display()))?;
        // the σ a calibration would otherwise assume, for comparison
        let assumed = session_robot(&session)
            .ok()
            .and_then(|robot| session.noise(&robot).ok());
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "session {}: {} joint samples, {} IMU samples",
            dir.display(),
            session.joints.len(),
            session.imu.len()
        )?;
        let assumed = assumed.as_ref();
        write!(
            out,
            "{}",
            NoiseTable {
                estimate: &est,
                assumed
            }
        )?;
        let id = identify_imu_noise(
            &data,
            session.joint_count(),
            &est,
            &opts,
            &IdOptions::default(),
        )
        .with_context(|| format!("cannot identify the noise of {}", dir.display()))?;
        write!(
            out,
            "{}",
            NoiseCorrelationTable {
                id: &id,
                estimate: &est
            }
        )?;
        let file = NoiseFile {
            noise: est.to_override(),
        };
        std::fs::write(&path, file.to_toml_with_model(&id.model))
            .with_context(|| format!("cannot write {}", path.display()))?;
        writeln!(out, "wrote {}", path.display())?;
        Ok(())
    }
}
