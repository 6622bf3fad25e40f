//! `robimu allan`: Allan deviation of a static IMU recording.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_report::allan::{write_allan_csv, write_allan_figure, AllanTable};
use robimu_session::{files, read_table, Columns, IMU_COLUMNS};
use robimu_workflows::allan::imu_allan;

/// Allan deviation of each IMU channel of a static recording.
///
/// Computes the overlapping Allan deviation at octave-spaced cluster times
/// and reads off the noise density N (σ at τ = 1 s on the fitted τ^-1/2
/// line) and the bias instability B (minimum σ / 0.664). Prints them per
/// channel and writes allan.csv and allan.png/allan.svg (log-log).
#[derive(Debug, Clone, clap::Args)]
pub struct AllanCmd {
    /// An imu.csv (t,ax,ay,az,gx,gy,gz) or a session directory holding one,
    /// recorded with the IMU at rest.
    pub input: PathBuf,
    /// Directory to write allan.csv and the plot into [default: the
    /// session directory, or the CSV's directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

impl AllanCmd {
    /// Compute, print and write.
    pub fn run(self) -> anyhow::Result<()> {
        let (csv, default_dir) = if self.input.is_dir() {
            (self.input.join(files::IMU), self.input.clone())
        } else {
            let parent = self
                .input
                .parent()
                .filter(|p| !p.as_os_str().is_empty())
                .map_or_else(|| PathBuf::from("."), |p| p.to_path_buf());
            (self.input.clone(), parent)
        };
        let out_dir = self.out.clone().unwrap_or(default_dir);
        if !out_dir.is_dir() {
            bail!("--out {}: not a directory", out_dir.display());
        }
        let table = read_table(&csv, Columns::Fixed(&IMU_COLUMNS))
            .with_context(|| format!("cannot read the IMU samples {}", csv.display()))?;
        let z: Vec<[f64; 6]> = table
            .values
            .chunks_exact(6)
            .map(|v| std::array::from_fn(|c| v[c]))
            .collect();
        let (tau0, channels) = imu_allan(&table.t, &z)
            .with_context(|| format!("cannot compute the Allan deviation of {}", csv.display()))?;
        let mut out = std::io::stdout().lock();
        writeln!(
            out,
            "{}: {} samples every {:.4} s ({:.1} Hz), {:.1} s",
            csv.display(),
            table.len(),
            tau0,
            1.0 / tau0,
            table.len() as f64 * tau0
        )?;
        let channels = &channels;
        write!(out, "{}", AllanTable { tau0, channels })?;
        let csv_out = write_allan_csv(&out_dir, channels)?;
        writeln!(out, "wrote {}", csv_out.display())?;
        for path in write_allan_figure(&out_dir, channels)? {
            writeln!(out, "wrote {}", path.display())?;
        }
        Ok(())
    }
}
