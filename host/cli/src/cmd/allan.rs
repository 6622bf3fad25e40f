//! `robimu allan`: Allan deviation of a static IMU recording.

use std::fmt::Write as _;
use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_report::plot::{loglog_panels, LogLogPanel};
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
        writeln!(
            out,
            "{:<8} {:>14} {:>14} {:>10} {:>10} {:>16}",
            "channel", "N [u/sqrt(Hz)]", "B [u]", "tau_B [s]", "N points", "sigma/sample [u]"
        )?;
        for (k, c) in channels.iter().enumerate() {
            let unit = if k < 3 { "m/s^2" } else { "rad/s" };
            let t = &c.terms;
            writeln!(
                out,
                "{:<8} {:>14.4e} {:>14.4e} {:>10.3} {:>10} {:>16.4e}  u = {unit}{}",
                c.name,
                t.density,
                t.bias_instability,
                t.tau_min,
                t.density_points,
                t.density / tau0.sqrt(),
                if t.density_points == 0 {
                    "  (no tau^-1/2 region: N from the shortest tau)"
                } else {
                    ""
                }
            )?;
        }
        let mut text = String::from("tau,ax,ay,az,gx,gy,gz\n");
        for (i, p) in channels[0].curve.iter().enumerate() {
            write!(text, "{}", p.tau)?;
            for c in &channels {
                write!(text, ",{}", c.curve[i].adev)?;
            }
            text.push('\n');
        }
        let csv_out = out_dir.join("allan.csv");
        std::fs::write(&csv_out, text)
            .with_context(|| format!("cannot write {}", csv_out.display()))?;
        writeln!(out, "wrote {}", csv_out.display())?;
        let panel = |title: &str, unit: &str, range: std::ops::Range<usize>| LogLogPanel {
            title: title.into(),
            x_label: "tau [s]".into(),
            y_label: format!("Allan deviation [{unit}]"),
            series: channels[range]
                .iter()
                .map(|c| {
                    let points = c.curve.iter().map(|p| (p.tau, p.adev)).collect();
                    (c.name.clone(), points)
                })
                .collect(),
        };
        let panels = [
            panel("accelerometer", "m/s^2", 0..3),
            panel("gyroscope", "rad/s", 3..6),
        ];
        for path in loglog_panels(&out_dir.join("allan"), "Allan deviation", &panels)? {
            writeln!(out, "wrote {}", path.display())?;
        }
        Ok(())
    }
}
