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
pub(crate) struct ResidualRms(pub [f64; 6]);

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
                "time offset found from the data before the fit: tau = {:.1} ms",
                t.tau * 1e3
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
    /// The warning for the weak directions of a calibration with `layout`.
    pub fn new(weak: &'a [WeakDirection], layout: &ParamLayout) -> Self {
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
pub(crate) struct EffectValue<'a> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_model::Robot;
    use robimu_solver::IterationRecord;

    #[test]
    fn residual_rms_and_effect_values_have_fixed_columns() {
        let r = ResidualRms([1.0, 0.994, 1.006, 2.0, 0.5, 1.234]);
        assert_eq!(
            r.to_string(),
            "ax 1.00 ay 0.99 az 1.01 gx 2.00 gy 0.50 gz 1.23"
        );
        let v = EffectValue {
            name: "clock_drift.ppm",
            value: 2.5e-6,
            sigma: 1e-7,
            display: ("ppm", 1e6),
        };
        assert_eq!(
            v.to_string(),
            format!("{:<34} +2.5000 ± 0.1000 ppm", "clock_drift.ppm")
        );
    }

    /// A calibration with made-up numbers (only what the report shows).
    fn calibration() -> Calibration {
        use robimu_model::{Knots, Spline};
        use robimu_solver::{IterationRecord, LmSummary, Termination};
        let knots = Knots::uniform(0.0, 2.0, 1.0, 3).unwrap();
        let m = knots.num_coeffs();
        let record = |iteration, cost| IterationRecord {
            iteration,
            cost,
            step_norm: 0.5,
            lambda: 1e-4,
            gradient_norm: 1e-3,
            tries: 1,
        };
        Calibration {
            x: vec![0.0],
            sigma: vec![1.0],
            active: vec![0],
            covariance: vec![1.0],
            trajectory: Spline::new(knots, 1, vec![0.0; m]).unwrap(),
            tau_initial: Some(robimu_workflows::time_offset::TauEstimate {
                tau: 0.04999,
                r_squared: 0.99,
                samples: 100,
            }),
            knot_spacing: 0.5,
            joint_fit_rms: vec![1.0],
            summary: LmSummary {
                initial_cost: 2.0e5,
                final_cost: 1.5e4,
                iterations: vec![record(1, 2.0e4), record(2, 1.5e4)],
                termination: Termination::FunctionTolerance,
            },
            imu_samples_used: 1200,
            weak_directions: vec![WeakDirection {
                relative_information: 2e-3,
                parameters: vec![("tau".into(), 1.0)],
            }],
            residual_rms: [1.0; 6],
            noise_model: robimu_model::noise::NoiseModel::white([1.0; 6]).unwrap(),
            extra_noise_models: Vec::new(),
        }
    }

    #[test]
    fn brief_and_full_reports() {
        let cal = calibration();
        let brief = FitReport::brief(&cal, true).to_string();
        assert_eq!(
            brief,
            "converged (cost change below tolerance) after 2 iterations: cost 2.000000e5 -> 1.500000e4\n\
             trajectory spline: knots every 0.5 s (chosen from the joint samples)\n\
             time offset found from the data before the fit: tau = 50.0 ms\n\
             1200 IMU samples used; whitened residual rms (1 = as modelled): ax 1.00 ay 1.00 az 1.00 gx 1.00 gy 1.00 gz 1.00\n"
        );
        let given = FitReport::brief(&cal, false).to_string();
        assert!(given.contains("knots every 0.5 s\n"), "{given}");
        let full = FitReport::full(&cal, true).to_string();
        assert!(full.starts_with(IterationRecord::HEADER), "{full}");
        assert!(full.contains(&brief), "{full}");
        assert!(
            full.ends_with("weak direction: tau 100 %  (data information 2.0e-3 of the prior's)\n"),
            "{full}"
        );
    }

    #[test]
    fn weak_direction_warning_names_the_parameters_and_the_length_hint() {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        assert_eq!(WeakDirectionsWarning::new(&[], &layout).to_string(), "");
        let length = layout
            .estimated_errors()
            .iter()
            .find(|e| e.is_length(layout.n_links()))
            .and_then(|e| layout.eps_index(e.link, e.k))
            .unwrap();
        let name = layout.specs()[length].name.clone();
        let weak = [WeakDirection {
            relative_information: 3e-3,
            parameters: vec![(name.clone(), 0.9)],
        }];
        let text = WeakDirectionsWarning::new(&weak, &layout).to_string();
        assert!(text.starts_with("warning: the data barely determines 1 parameter combination(s)"));
        assert!(
            text.contains(&format!(
                "  {name} 90 %  (data information 3.0e-3 of the prior's)\n"
            )),
            "{text}"
        );
        assert!(text.contains("`--freeze lengths`"), "{text}");
        let tau = WeakDirection {
            relative_information: 1e-3,
            parameters: vec![("tau".into(), 1.0)],
        };
        let text = WeakDirectionsWarning::new(std::slice::from_ref(&tau), &layout).to_string();
        assert!(!text.contains("--freeze lengths"), "{text}");
    }
}
