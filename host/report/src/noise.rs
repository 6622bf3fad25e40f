//! `robimu noise`'s table: the estimated σ of every IMU and joint channel,
//! with the σ a calibration would otherwise assume.

use std::fmt;

use robimu_session::IMU_COLUMNS;
use robimu_workflows::noise::{ChannelNoise, NoiseEstimate};

/// The σ assumed without the estimate: `(Σ_z, Σ_q)`.
pub type AssumedNoise = ([f64; 6], Vec<f64>);

/// The noise estimate as a table, one row a channel.
pub struct NoiseTable<'a> {
    /// The estimate.
    pub estimate: &'a NoiseEstimate,
    /// The σ a calibration would otherwise assume (the session's or the
    /// robot's), when known.
    pub assumed: Option<&'a AssumedNoise>,
}

fn row(
    f: &mut fmt::Formatter<'_>,
    name: &str,
    c: &ChannelNoise,
    unit: &str,
    given: Option<f64>,
) -> fmt::Result {
    writeln!(
        f,
        "{:<8} {:>12.4e} {:>10.2e} {:>8} {:>10}{}{}",
        name,
        c.sigma,
        c.std_error,
        unit,
        c.spacing,
        given.map_or(String::new(), |g| format!(" {g:>10.4e}")),
        if c.resolved {
            ""
        } else {
            "  (motion not resolved: upper bound)"
        }
    )
}

impl fmt::Display for NoiseTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:<8} {:>12} {:>10} {:>8} {:>10}{}",
            "channel",
            "sigma",
            "std.err",
            "unit",
            "knots [s]",
            if self.assumed.is_some() {
                "    assumed"
            } else {
                ""
            }
        )?;
        for (k, c) in self.estimate.sigma_z.iter().enumerate() {
            let unit = if k < 3 { "m/s^2" } else { "rad/s" };
            let given = self.assumed.map(|(z, _)| z[k]);
            row(f, IMU_COLUMNS[k], c, unit, given)?;
        }
        for (j, c) in self.estimate.sigma_q.iter().enumerate() {
            let given = self.assumed.and_then(|(_, q)| q.get(j).copied());
            row(f, &format!("q{}", j + 1), c, "rad", given)?;
        }
        Ok(())
    }
}
