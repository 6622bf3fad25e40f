//! `robimu noise`'s table: the estimated σ of every IMU and joint channel,
//! with the σ a calibration would otherwise assume.

use std::fmt;

use robimu_model::IMU_CHANNELS;
use robimu_workflows::noise::{ChannelNoise, NoiseEstimate};

/// The σ assumed without the estimate: `(Σ_z, Σ_q)`.
pub(crate) type AssumedNoise = ([f64; 6], Vec<f64>);

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
            row(f, IMU_CHANNELS[k], c, unit, given)?;
        }
        for (j, c) in self.estimate.sigma_q.iter().enumerate() {
            let given = self.assumed.and_then(|(_, q)| q.get(j).copied());
            row(f, &format!("q{}", j + 1), c, "rad", given)?;
        }
        Ok(())
    }
}

/// The identified correlation and motion level of each IMU channel's noise
/// (`robimu noise`, after the σ table), one row a channel.
pub struct NoiseCorrelationTable<'a> {
    /// The identification.
    pub id: &'a robimu_workflows::noise_id::Identification,
    /// The spline fits whose residuals it used.
    pub estimate: &'a NoiseEstimate,
}

impl fmt::Display for NoiseCorrelationTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "noise correlation (AR by BIC on the spline residuals; white: Ljung-Box, Bonferroni over 6 at {}):",
            robimu_workflows::noise_id::WHITENESS_ALPHA
        )?;
        writeln!(
            f,
            "{:<8} {:>5} {:>9} {:>9} {:>8} {:>10} {:>10} {:>6}  phi",
            "channel", "order", "corr [ms]", "N_eff/N", "x sigma", "motion c", "LB p", "white"
        )?;
        for ((c, w), fit) in self
            .id
            .channels
            .iter()
            .zip(self.id.white)
            .zip(&self.estimate.sigma_z)
        {
            let phi: Vec<String> = c.phi.iter().map(|v| format!("{v:.3}")).collect();
            writeln!(
                f,
                "{:<8} {:>5} {:>9.2} {:>9.3} {:>8.2} {:>10} {:>10.2e} {:>6}  [{}]{}",
                c.channel,
                c.order,
                1e3 * c.correlation_time_s,
                c.n_eff_fraction,
                c.sigma_understatement,
                if c.motion > 0.0 {
                    format!("{:.3e}", c.motion)
                } else {
                    "-".to_string()
                },
                c.ljung_box_p,
                if w { "yes" } else { "no" },
                phi.join(", "),
                if fit.resolved || w {
                    ""
                } else {
                    "  (knot search unresolved: the spline absorbed slow noise; time, N_eff, factor and sigma understated)"
                }
            )?;
        }
        writeln!(
            f,
            "(x sigma: how much a white model understates the sigma of a slowly determined parameter; \
             spline residuals flag correlation reliably but understate its time when it is not short against the knot spacing)"
        )
    }
}

/// One line per IMU channel of a noise model: `white`, or its AR order and
/// coefficients, N_eff/N, the factor a white model understates slow
/// parameters' σ by, and the motion gain (docs/model.md §4.6).
pub struct NoiseChannels<'a>(pub &'a robimu_model::noise::NoiseModel);

impl fmt::Display for NoiseChannels<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (name, c) in IMU_CHANNELS.iter().zip(&self.0.imu) {
            if c.is_white() {
                writeln!(f, "  {name}: white")?;
                continue;
            }
            let phi: Vec<String> = c.ar.phi().iter().map(|v| format!("{v:.3}")).collect();
            write!(
                f,
                "  {name}: AR({}) phi [{}], N_eff/N {:.3}, a white model understates slow parameters' sigma x{:.2}",
                c.ar.order(),
                phi.join(", "),
                c.ar.effective_fraction(),
                c.ar.low_frequency_ratio().sqrt()
            )?;
            if c.motion > 0.0 {
                write!(f, ", motion gain {:.3e}", c.motion)?;
            }
            writeln!(f)?;
        }
        Ok(())
    }
}

/// The noise model a calibration used, and why (`calibrate --noise-model`).
pub struct NoiseSummary<'a> {
    choice: &'a robimu_workflows::calibrate::noise_choice::NoiseChoice,
    outcome: &'a robimu_workflows::calibrate::noise_choice::NoiseOutcome,
    used: &'a robimu_model::noise::NoiseModel,
    /// The models used for IMUs j ≥ 1 (`others[j - 1]`).
    others: &'a [robimu_model::noise::NoiseModel],
}

impl<'a> NoiseSummary<'a> {
    /// The same, with the models the fit used for IMUs j ≥ 1 of a
    /// multi-IMU session (`others[j - 1]`; docs/model.md §9), each printed
    /// after IMU 0's.
    pub fn with_imus(mut self, others: &'a [robimu_model::noise::NoiseModel]) -> Self {
        self.others = others;
        self
    }

    /// The summary of `outcome` under `choice`, the fit having used `used`.
    pub fn new(
        choice: &'a robimu_workflows::calibrate::noise_choice::NoiseChoice,
        outcome: &'a robimu_workflows::calibrate::noise_choice::NoiseOutcome,
        used: &'a robimu_model::noise::NoiseModel,
    ) -> Self {
        Self {
            choice,
            outcome,
            used,
            others: &[],
        }
    }
}

impl fmt::Display for NoiseSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.imu0(f)?;
        for (k, m) in self.others.iter().enumerate() {
            if m.is_white() {
                writeln!(f, "IMU {} noise model: white", k + 1)?;
            } else {
                writeln!(
                    f,
                    "IMU {} noise model: its own, generalised least squares:",
                    k + 1
                )?;
                write!(f, "{}", NoiseChannels(m))?;
            }
        }
        Ok(())
    }
}

impl NoiseSummary<'_> {
    /// IMU 0's model and why (the one-IMU summary).
    fn imu0(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use robimu_workflows::calibrate::noise_choice::NoiseChoice;
        let channels = |f: &mut fmt::Formatter<'_>| write!(f, "{}", NoiseChannels(self.used));
        match self.choice {
            NoiseChoice::White => writeln!(f, "noise model: white (--noise-model white)"),
            NoiseChoice::Given(_) => {
                writeln!(f, "noise model: given (generalised least squares):")?;
                channels(f)
            }
            NoiseChoice::Auto => {
                let p = |id: &robimu_workflows::noise_id::Identification| -> String {
                    IMU_CHANNELS
                        .iter()
                        .zip(&id.channels)
                        .map(|(n, c)| format!("{n} {:.2e}", c.ljung_box_p))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                match (&self.outcome.white_test, &self.outcome.identified) {
                    (Some(t), None) if self.outcome.warning.is_none() => {
                        if t.white.iter().all(|&w| w) {
                            writeln!(
                                f,
                                "noise model: white (the residuals pass the Ljung-Box whiteness test; p: {})",
                                p(t)
                            )
                        } else {
                            writeln!(
                                f,
                                "noise model: white (Ljung-Box p: {}; no AR order or motion level is supported by the data)",
                                p(t)
                            )
                        }
                    }
                    (Some(t), Some(_)) => {
                        writeln!(
                            f,
                            "noise model: identified from the residuals, which are not white (Ljung-Box p: {}); refitted by generalised least squares ({} refits):",
                            p(t),
                            self.outcome.refits
                        )?;
                        channels(f)
                    }
                    _ => writeln!(f, "noise model: white (kept; see the warning)"),
                }
            }
        }
    }
}
