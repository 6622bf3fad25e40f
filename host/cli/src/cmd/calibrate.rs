//! `robimu calibrate`: the MAP calibration of one session, its table and its
//! result file (docs/model.md §8).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use robimu_model::{ParamLayout, Robot};
use robimu_report::convergence::{convergence_path, ConvergenceLog};
use robimu_report::ParameterTable;
use robimu_workflows::calibrate::{calibrate, check_measurements, CalibrateOptions};
use robimu_workflows::noise::NoiseFile;
use robimu_workflows::repeatability::{self, check_windows, Repeatability};

use super::input::{load_session, output_path, Progress};

/// Calibrate the robot and the IMU together from a session.
///
/// Estimates every parameter with its posterior uncertainty, prints the
/// parameter table (against the truth when the session has a truth.toml)
/// and writes the result file (JSON, docs/model.md §8) and, next to it, the
/// solver's iteration history (NAME.convergence.csv for NAME.json).
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateCmd {
    /// Session directory (session.toml, joints.csv, imu.csv).
    pub session: PathBuf,
    /// Result file to write [default: result.json in the session directory].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Parameters to hold at their prior mean, comma-separated: `lengths`
    /// (the robot's length errors eps_i_1..3 of links i < n, not the IMU
    /// position) and/or parameter names (eps_2_4, tau, b_w_z, …).
    #[arg(long, value_delimiter = ',')]
    pub freeze: Vec<String>,
    /// Fit without the priors (fails when the data leaves some parameter
    /// combination undetermined).
    #[arg(long)]
    pub no_prior: bool,
    /// Knot spacing of the estimated trajectory spline, s [default: chosen
    /// from the data: halved from 1 s while the spline cannot follow the
    /// joint samples within their noise].
    #[arg(long)]
    pub knot_spacing: Option<f64>,
    /// Noise file whose `[noise]` table (session.toml's format, e.g. written
    /// by `robimu noise`) replaces the session's and the robot's σ.
    #[arg(long, value_name = "FILE")]
    pub noise: Option<PathBuf>,
    /// Repeatability: also calibrate each of N equal time windows (N >= 2;
    /// the paper used five 1-minute windows), print each parameter group's
    /// largest difference from the full calibration and write
    /// repeatability.csv next to the result file.
    #[arg(long, value_name = "N")]
    pub windows: Option<usize>,
    /// Also write a self-contained HTML report (report.html and its figures)
    /// into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Also fit these catalogue effects with the baseline (comma-separated:
    /// g_sensitivity, size_effect, clock_drift, bias_drift,
    /// joint_elasticity, encoder_scale, resonance); prints their estimates and writes
    /// effects.json (the augmented model's parameters) next to the result file.
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    #[command(flatten)]
    pub resonance: super::input::ResonanceMode,
}

/// Indices into x of the `--freeze` items.
pub fn frozen_indices(
    robot: &Robot,
    layout: &ParamLayout,
    items: &[String],
) -> anyhow::Result<Vec<usize>> {
    parameter_indices(robot, layout, items, "--freeze")
}

/// Indices in x of `items` (`lengths` and/or parameter names), the errors
/// naming `flag`.
pub fn parameter_indices(
    robot: &Robot,
    layout: &ParamLayout,
    items: &[String],
    flag: &str,
) -> anyhow::Result<Vec<usize>> {
    let n = robot.dof();
    let mut out = Vec::new();
    for item in items.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        if item == "lengths" {
            out.extend(
                layout
                    .estimated_errors()
                    .iter()
                    .filter(|e| e.link < n && e.k <= 3)
                    .filter_map(|e| layout.eps_index(e.link, e.k)),
            );
        } else if let Some(k) = layout.index_of(item) {
            out.push(k);
        } else {
            let names: Vec<&str> = layout.specs().iter().map(|s| s.name.as_str()).collect();
            bail!(
                "{flag}: unknown parameter `{item}`; valid: lengths, {}",
                names.join(", ")
            );
        }
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

impl CalibrateCmd {
    /// Calibrate, print the table and write the result file.
    pub fn run(self) -> anyhow::Result<()> {
        let dir = &self.session;
        let (session, robot) = load_session(dir)?;
        let layout = ParamLayout::new(&robot);
        let mut opts = CalibrateOptions::new(&robot);
        (opts.sigma_z, opts.sigma_q) = session.noise(&robot)?;
        if let Some(path) = &self.noise {
            let file = NoiseFile::read(path).context("--noise")?;
            if let Some(z) = file.noise.sigma_z {
                opts.sigma_z = z;
            }
            if let Some(q) = file.noise.sigma_q {
                if q.len() != robot.dof() {
                    bail!(
                        "--noise {}: [noise] sigma_q has {} values but robot `{}` has {} joints",
                        path.display(),
                        q.len(),
                        robot.name(),
                        robot.dof()
                    );
                }
                opts.sigma_q = q;
            }
        }
        opts.frozen = frozen_indices(&robot, &layout, &self.freeze)?;
        opts.use_prior = !self.no_prior;
        if let Some(h) = self.knot_spacing {
            if !(h.is_finite() && h > 0.0) {
                bail!("--knot-spacing must be a positive number of seconds (got {h})");
            }
        }
        opts.knot_spacing = self.knot_spacing;
        let path = output_path(self.out.as_deref(), dir.join("result.json"))?;
        let data = session.measurements();
        check_measurements(&robot, &data)
            .with_context(|| format!("cannot calibrate the session {}", dir.display()))?;
        let effect_setup =
            robimu_workflows::diagnose::setup_with(&robot, &data, None, self.resonance.mode()?);
        let effect_names: Vec<String> = self
            .effects
            .iter()
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect();
        for name in &effect_names {
            robimu_model::effects::by_name(&effect_setup, name).context("--effects")?;
        }
        let windows = match self.windows {
            Some(k) => Some(
                check_windows(&data, k)
                    .with_context(|| format!("--windows {k}: cannot split {}", dir.display()))?,
            ),
            None => None,
        };
        let mut out = std::io::stdout().lock();
        let (ta, tb) = session.joints.span().unwrap_or_default();
        writeln!(
            out,
            "session {}: robot {}, {} joint samples, {} IMU samples, {:.1} s; estimating {} of {} parameters{}",
            dir.display(),
            session.meta.robot,
            session.joints.len(),
            session.imu.len(),
            tb - ta,
            layout.len() - opts.frozen.len(),
            layout.len(),
            if opts.use_prior { "" } else { " without priors" }
        )?;
        out.flush()?;

        let progress = Progress::start("fitting the trajectory and finding the time offset tau");
        progress.println(format!(
            "{:>4} {:>14} {:>10} {:>9} {:>10}",
            "iter", "cost", "step", "lambda", "gradient"
        ));
        let cal = calibrate(&robot, &data, &opts, |r| {
            progress.println(format!(
                "{:>4} {:>14.6e} {:>10.3e} {:>9.1e} {:>10.3e}",
                r.iteration, r.cost, r.step_norm, r.lambda, r.gradient_norm
            ));
            progress.set_message(format!(
                "iteration {}: cost {:.6e}, lambda {:.1e}",
                r.iteration, r.cost, r.lambda
            ));
        });
        progress.finish();
        let cal = cal.with_context(|| format!("cannot calibrate the session {}", dir.display()))?;

        let summary = &cal.summary;
        writeln!(
            out,
            "{} after {} iterations: cost {:.6e} -> {:.6e}",
            summary.termination,
            summary.iterations.len(),
            summary.initial_cost,
            summary.final_cost
        )?;
        writeln!(
            out,
            "trajectory spline: knots every {} s{}",
            cal.knot_spacing,
            if self.knot_spacing.is_none() {
                " (chosen from the joint samples)"
            } else {
                ""
            }
        )?;
        if let Some(t) = &cal.tau_initial {
            writeln!(
                out,
                "time offset found from the data before the fit: tau = {:.4} s",
                t.tau
            )?;
        }
        let rms = cal.residual_rms;
        writeln!(
            out,
            "{} IMU samples used; whitened residual rms (1 = as modelled): ax {:.2} ay {:.2} az {:.2} gx {:.2} gy {:.2} gz {:.2}",
            cal.imu_samples_used, rms[0], rms[1], rms[2], rms[3], rms[4], rms[5]
        )?;
        let mut result = cal.to_result(&layout);
        result.robot = Some(session.meta.robot.clone());
        result.session = Some(
            std::path::absolute(dir)
                .unwrap_or_else(|_| dir.clone())
                .display()
                .to_string(),
        );
        result.priors_used = Some(opts.use_prior);
        writeln!(out)?;
        write!(
            out,
            "{}",
            ParameterTable::new(&result, session.truth.as_ref())
        )?;
        out.flush()?;
        if !cal.weak_directions.is_empty() {
            eprintln!(
                "warning: the data barely determines {} parameter combination(s); their estimates rest on the priors:",
                cal.weak_directions.len()
            );
            for w in &cal.weak_directions {
                let parts: Vec<String> = w
                    .parameters
                    .iter()
                    .map(|(name, share)| format!("{name} {:.0} %", 100.0 * share))
                    .collect();
                eprintln!(
                    "  {}  (data information {:.1e} of the prior's)",
                    parts.join(", "),
                    w.relative_information
                );
            }
            let n = robot.dof();
            let only_lengths = cal.weak_directions.iter().all(|w| {
                w.parameters.iter().all(|(name, _)| {
                    layout.index_of(name).is_some_and(|k| {
                        layout
                            .estimated_errors()
                            .get(k)
                            .is_some_and(|e| e.link < n && e.k <= 3)
                    })
                })
            });
            if only_lengths {
                eprintln!("  (all are robot length errors: the motion is too slow to observe them; `--freeze lengths` holds them at nominal)");
            }
        }
        result.write(&path)?;
        writeln!(out, "wrote {}", path.display())?;
        let history = ConvergenceLog::from_summary(&cal.summary);
        let hpath = convergence_path(&path);
        history.write(&hpath)?;
        writeln!(out, "wrote {}", hpath.display())?;
        if let Some(report_dir) = &self.report {
            let costs = history.costs();
            let series = super::report::session_series(
                &robot,
                &data,
                &cal.x,
                &opts.sigma_q,
                Some(cal.knot_spacing),
            )?;
            let html = robimu_report::html::calibration_report(
                report_dir,
                &result,
                session.truth.as_ref(),
                Some(&costs),
                Some(&series),
            )?;
            writeln!(out, "wrote {}", html.display())?;
        }
        if !effect_names.is_empty() {
            let progress = Progress::start(format!("fitting with {}", effect_names.join(", ")));
            let fit = robimu_workflows::diagnose::fit(
                &robot,
                &data,
                &opts,
                &effect_setup,
                &effect_names,
                None,
                Some(&cal.x),
            );
            progress.finish();
            let fit =
                fit.with_context(|| format!("--effects: cannot fit {}", effect_names.join(", ")))?;
            writeln!(out, "\neffects (fitted with the baseline):")?;
            for (e, p) in fit.effect_params.iter().enumerate() {
                let (unit, scale) = p.display;
                writeln!(
                    out,
                    "  {:<34} {:+.4} ± {:.4} {unit}",
                    p.name,
                    fit.theta_e[e] * scale,
                    fit.sigma_e[e] * scale
                )?;
            }
            let rms = fit.residual_rms();
            writeln!(
                out,
                "whitened residual rms with the effects: ax {:.2} ay {:.2} az {:.2} gx {:.2} gy {:.2} gz {:.2}",
                rms[0], rms[1], rms[2], rms[3], rms[4], rms[5]
            )?;
            let epath = path.with_file_name("effects.json");
            let json = robimu_workflows::diagnose::fit_json(&layout, &fit);
            std::fs::write(&epath, serde_json::to_string_pretty(&json)?)
                .with_context(|| format!("cannot write {}", epath.display()))?;
            writeln!(out, "wrote {}", epath.display())?;
        }
        if let Some(windows) = windows {
            let count = windows.len();
            let progress = Progress::start(format!("calibrating {count} windows"));
            let results = repeatability::calibrate_windows(&robot, windows, &opts, |w, r| {
                progress.set_message(format!(
                    "window {} of {count}: iteration {}, cost {:.6e}",
                    w + 1,
                    r.iteration,
                    r.cost
                ));
            });
            progress.finish();
            let results =
                results.with_context(|| format!("--windows {count}: {}", dir.display()))?;
            let study = repeatability::compare(&layout, cal, results);
            writeln!(out)?;
            write_groups(&mut out, &study)?;
            let csv = path.with_file_name("repeatability.csv");
            write_windows_csv(&csv, &layout, &study)
                .with_context(|| format!("cannot write {}", csv.display()))?;
            writeln!(out, "wrote {}", csv.display())?;
        }
        Ok(())
    }
}

/// The table of each parameter group's largest difference from the full
/// calibration.
fn write_groups(out: &mut impl Write, study: &Repeatability) -> std::io::Result<()> {
    let (first, last) = (study.windows.first(), study.windows.last());
    writeln!(
        out,
        "repeatability: {} windows of {:.1} s ({:.1}..{:.1} s), largest difference from the full calibration per parameter group",
        study.windows.len(),
        first.map_or(0.0, |w| w.t1 - w.t0),
        first.map_or(0.0, |w| w.t0),
        last.map_or(0.0, |w| w.t1),
    )?;
    writeln!(
        out,
        "{:<16} {:<12} {:>12} {:<6} {:>14}",
        "group", "parameter", "difference", "unit", "diff/sigma_win"
    )?;
    for g in &study.groups {
        writeln!(
            out,
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

/// repeatability.csv: per window and parameter (x order), SI units.
fn write_windows_csv(
    path: &std::path::Path,
    layout: &ParamLayout,
    study: &Repeatability,
) -> anyhow::Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    w.write_record([
        "window",
        "t0",
        "t1",
        "name",
        "unit",
        "value",
        "sigma",
        "difference",
    ])?;
    for (k, win) in study.windows.iter().enumerate() {
        for (i, spec) in layout.specs().iter().enumerate() {
            w.write_record([
                (k + 1).to_string(),
                win.t0.to_string(),
                win.t1.to_string(),
                spec.name.clone(),
                spec.unit.to_string(),
                win.calibration.x[i].to_string(),
                win.calibration.sigma[i].to_string(),
                win.difference[i].to_string(),
            ])?;
        }
    }
    w.flush()?;
    Ok(())
}
