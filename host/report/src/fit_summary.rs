//! Text reports of a fit, in the manner of Ceres' `Summary`: a brief one
//! (termination, iterations, cost, the trajectory spline, τ, whitened
//! residual RMS per channel) and a full one (the iteration log before it and
//! the weak directions after), plus the pieces the commands print on their
//! own: the iteration log's lines, the weak-direction warning, fitted effect
//! parameters and the repeatability table.

use std::fmt;

use robimu_model::effects::EffectParam;
use robimu_model::ParamLayout;
use robimu_workflows::calibrate::fit::Fit;
use robimu_workflows::calibrate::{Calibration, WeakDirection};
use robimu_workflows::repeatability::Repeatability;

/// Whitened residual RMS per IMU channel: `ax 1.00 ay 0.99 … gz 1.01`.
pub struct ResidualRms(pub [f64; 6]);

impl fmt::Display for ResidualRms {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.0;
        write!(
            f,
            "ax {:.2} ay {:.2} az {:.2} gx {:.2} gy {:.2} gz {:.2}",
            r[0], r[1], r[2], r[3], r[4], r[5]
        )
    }
}

/// The report of a calibration's fit (see the module doc).
pub struct FitReport<'a> {
    calibration: &'a Calibration,
    knots_chosen: bool,
    full: bool,
}

impl<'a> FitReport<'a> {
    /// The brief report; `knots_chosen` when the knot spacing was chosen
    /// from the data (not given).
    pub fn brief(calibration: &'a Calibration, knots_chosen: bool) -> Self {
        Self {
            calibration,
            knots_chosen,
            full: false,
        }
    }

    /// The full report: the iteration log, the brief report, the weak directions.
    pub fn full(calibration: &'a Calibration, knots_chosen: bool) -> Self {
        Self {
            full: true,
            ..Self::brief(calibration, knots_chosen)
        }
    }
}

impl fmt::Display for FitReport<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let cal = self.calibration;
        let summary = &cal.summary;
        if self.full {
            writeln!(f, "{summary}")?;
        }
        writeln!(
            f,
            "{} after {} iterations: cost {:.6e} -> {:.6e}",
            summary.termination,
            summary.iterations.len(),
            summary.initial_cost,
            summary.final_cost
        )?;
        writeln!(
            f,
            "trajectory spline: knots every {} s{}",
            cal.knot_spacing,
            if self.knots_chosen {
                " (chosen from the joint samples)"
            } else {
                ""
            }
        )?;
        if let Some(t) = &cal.tau_initial {
            writeln!(
                f,
                "time offset found from the data before the fit: tau = {:.4} s",
                t.tau
            )?;
        }
        writeln!(
            f,
            "{} IMU samples used; whitened residual rms (1 = as modelled): {}",
            cal.imu_samples_used,
            ResidualRms(cal.residual_rms)
        )?;
        if self.full {
            for w in &cal.weak_directions {
                writeln!(f, "weak direction: {}", Direction(w))?;
            }
        }
        Ok(())
    }
}

/// A weak direction's parameters with their share, and its information.
struct Direction<'a>(&'a WeakDirection);

impl fmt::Display for Direction<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .0
            .parameters
            .iter()
            .map(|(name, share)| format!("{name} {:.0} %", 100.0 * share))
            .collect();
        write!(
            f,
            "{}  (data information {:.1e} of the prior's)",
            parts.join(", "),
            self.0.relative_information
        )
    }
}

/// The warning about directions the data barely determines (nothing when
/// there are none), for stderr.
pub struct WeakDirectionsWarning<'a> {
    weak: &'a [WeakDirection],
    only_robot_lengths: bool,
}

impl<'a> WeakDirectionsWarning<'a> {
    /// The warning for `calibration`'s weak directions.
    pub fn new(calibration: &'a Calibration, layout: &ParamLayout) -> Self {
        let weak = &calibration.weak_directions[..];
        Self {
            weak,
            only_robot_lengths: weak.iter().all(|w| w.only_robot_lengths(layout)),
        }
    }
}

impl fmt::Display for WeakDirectionsWarning<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.weak.is_empty() {
            return Ok(());
        }
        writeln!(
            f,
            "warning: the data barely determines {} parameter combination(s); their estimates rest on the priors:",
            self.weak.len()
        )?;
        for w in self.weak {
            writeln!(f, "  {}", Direction(w))?;
        }
        if self.only_robot_lengths {
            writeln!(f, "  (all are robot length errors: the motion is too slow to observe them; `--freeze lengths` holds them at nominal)")?;
        }
        Ok(())
    }
}

/// One fitted effect parameter in its display unit:
/// `name                               +0.1234 ± 0.0100 ppm`.
pub struct EffectValue<'a> {
    /// Parameter name.
    pub name: &'a str,
    /// Value, SI.
    pub value: f64,
    /// σ, SI.
    pub sigma: f64,
    /// Display unit and the factor from SI to it.
    pub display: (&'a str, f64),
}

impl<'a> EffectValue<'a> {
    /// Parameter `e` of `fit`'s θ_E.
    pub fn of(fit: &'a Fit, e: usize) -> Self {
        let p: &EffectParam = &fit.effect_params[e];
        Self {
            name: &p.name,
            value: fit.theta_e[e],
            sigma: fit.sigma_e[e],
            display: p.display,
        }
    }
}

impl fmt::Display for EffectValue<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (unit, scale) = self.display;
        write!(
            f,
            "{:<34} {:+.4} ± {:.4} {unit}",
            self.name,
            self.value * scale,
            self.sigma * scale
        )
    }
}

/// The effects fitted with the baseline and the residual RMS with them.
pub struct EffectEstimates<'a>(pub &'a Fit);

impl fmt::Display for EffectEstimates<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let fit = self.0;
        writeln!(f, "effects (fitted with the baseline):")?;
        for e in 0..fit.effect_params.len() {
            writeln!(f, "  {}", EffectValue::of(fit, e))?;
        }
        writeln!(
            f,
            "whitened residual rms with the effects: {}",
            ResidualRms(fit.residual_rms())
        )
    }
}

/// Each parameter group's largest difference from the full calibration.
pub struct RepeatabilityGroups<'a>(pub &'a Repeatability);

impl fmt::Display for RepeatabilityGroups<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let study = self.0;
        let (first, last) = (study.windows.first(), study.windows.last());
        writeln!(
            f,
            "repeatability: {} windows of {:.1} s ({:.1}..{:.1} s), largest difference from the full calibration per parameter group",
            study.windows.len(),
            first.map_or(0.0, |w| w.t1 - w.t0),
            first.map_or(0.0, |w| w.t0),
            last.map_or(0.0, |w| w.t1),
        )?;
        writeln!(
            f,
            "{:<16} {:<12} {:>12} {:<6} {:>14}",
            "group", "parameter", "difference", "unit", "diff/sigma_win"
        )?;
        for g in &study.groups {
            writeln!(
                f,
                "{:<16} {:<12} {:>12.4} {:<6} {:>14.2}",
                g.group,
                g.name,
                g.difference,
                g.unit.symbol(),
                g.relative_to_window
            )?;
        }
        Ok(())
    }
}
