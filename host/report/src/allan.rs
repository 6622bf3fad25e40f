//! `robimu allan`'s output: the noise terms of each IMU channel as a
//! table, allan.csv and the log-log figure.

use std::fmt;
use std::path::{Path, PathBuf};

use robimu_workflows::allan::ChannelAllan;

use crate::html::ReportError;
use crate::plot::{loglog_panels, LogLogPanel};

/// The noise density N, bias instability B and σ per sample of each
/// channel, sampled every `tau0` s.
pub struct AllanTable<'a> {
    /// The sample interval, s.
    pub tau0: f64,
    /// The channels, `ax` … `gz`.
    pub channels: &'a [ChannelAllan],
}

impl fmt::Display for AllanTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:<8} {:>14} {:>14} {:>10} {:>10} {:>16}",
            "channel", "N [u/sqrt(Hz)]", "B [u]", "tau_B [s]", "N points", "sigma/sample [u]"
        )?;
        for (k, c) in self.channels.iter().enumerate() {
            let unit = if k < 3 { "m/s^2" } else { "rad/s" };
            let t = &c.terms;
            writeln!(
                f,
                "{:<8} {:>14.4e} {:>14.4e} {:>10.3} {:>10} {:>16.4e}  u = {unit}{}",
                c.name,
                t.density,
                t.bias_instability,
                t.tau_min,
                t.density_points,
                t.density / self.tau0.sqrt(),
                if t.density_points == 0 {
                    "  (no tau^-1/2 region: N from the shortest tau)"
                } else {
                    ""
                }
            )?;
        }
        Ok(())
    }
}

/// `dir/allan.csv`: τ and every channel's Allan deviation; returns its path.
pub fn write_allan_csv(dir: &Path, channels: &[ChannelAllan]) -> Result<PathBuf, ReportError> {
    use std::fmt::Write as _;
    let mut text = String::from("tau,ax,ay,az,gx,gy,gz\n");
    if let Some(first) = channels.first() {
        for (i, p) in first.curve.iter().enumerate() {
            let _ = write!(text, "{}", p.tau);
            for c in channels {
                let _ = write!(text, ",{}", c.curve[i].adev);
            }
            text.push('\n');
        }
    }
    let path = dir.join("allan.csv");
    std::fs::write(&path, text).map_err(|source| ReportError::Io {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// `dir/allan.png` and `dir/allan.svg`: the accelerometer and gyroscope
/// curves (log-log); returns the paths written.
pub fn write_allan_figure(
    dir: &Path,
    channels: &[ChannelAllan],
) -> Result<Vec<PathBuf>, ReportError> {
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
    Ok(loglog_panels(
        &dir.join("allan"),
        "Allan deviation",
        &panels,
    )?)
}
