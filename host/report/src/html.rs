//! Self-contained HTML reports: one page with inline CSS and every figure as
//! inline SVG (no scripts, no external URLs), written next to the figures'
//! PNG and SVG files.
//!
//! * [`calibration_report`] — the verdict, the pose accuracy before and
//!   after, the model and the evidence for its effects
//!   ([`calibration_report_with`]), parameter table (paper Table II),
//!   posterior σ against the prior σ, convergence, and, when the session is
//!   at hand, the joint trajectory and the IMU residuals over time;
//! * [`validation_report_with`] — robot accuracy (Fig. 10), IMU accuracy
//!   (Fig. 11) and the calibrated against the classical parameters.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{DisplayUnit, ParameterTable};
use crate::diagnosis_figures::{residuals_plot, spectra_plot};
use crate::figures::{residual_figure, sigma_reduction_figure, NoiseBand};
use crate::plot::{histogram_grid, line_panels, HistogramPanel, LinePanel, PlotError};
use robimu_model::observations::Measurements;
use robimu_model::{JointState, MeasurementModel, ParamLayout, Robot, Spline};
use robimu_session::result::{ActualPoseErrors, PoseErrorStats};
use robimu_session::CalibrationResult;
use robimu_session::Truth;
use robimu_workflows::diagnose::Diagnosis;
use robimu_workflows::tracker_offset::TrackerAlignment;
use robimu_workflows::validate::{ImuAccuracy, RobotAccuracy};

/// A report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file could not be written or read back.
    #[error("cannot write {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A figure could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The session does not fit the result.
    #[error("{0}")]
    Session(String),
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ReportError + '_ {
    move |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// `s` with `& < > " '` escaped for HTML text and attributes.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const CSS: &str = "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}\
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}\
table{border-collapse:collapse;font-size:.85em;margin:.5em 0}\
th,td{border:1px solid #ddd;padding:.2em .5em;text-align:right}\
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}\
.bar{display:inline-block;height:.7em;background:#4a7fd0;vertical-align:middle}\
figure{margin:1em 0}figure svg{max-width:100%;height:auto}figcaption{font-size:.85em;color:#555}\
.note{color:#555;font-size:.9em}";

/// One HTML page built section by section.
#[derive(Debug, Clone)]
pub(crate) struct HtmlPage {
    title: String,
    body: String,
}

impl HtmlPage {
    /// An empty page with this title (also its first heading).
    pub fn new(title: &str) -> Self {
        Self {
            title: title.to_string(),
            body: format!("<h1>{}</h1>\n", escape(title)),
        }
    }

    /// A section heading.
    pub fn heading(&mut self, text: &str) {
        let _ = writeln!(self.body, "<h2>{}</h2>", escape(text));
    }

    /// A paragraph of plain text.
    pub fn paragraph(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
    }

    /// A table with an `id`; cells are plain text except where a cell starts
    /// with `<span class="bar"` (a bar drawn by [`bar`]).
    pub fn table(&mut self, id: &str, headers: &[&str], rows: &[Vec<String>]) {
        self.grouped_table(id, headers, &[(String::new(), rows.to_vec())]);
    }

    /// A table whose rows come in groups, each under a full-width heading
    /// row (`<tr class="group">`; none for an empty title); cells as in
    /// [`Self::table`].
    pub fn grouped_table(
        &mut self,
        id: &str,
        headers: &[&str],
        groups: &[(String, Vec<Vec<String>>)],
    ) {
        let _ = write!(self.body, "<table id=\"{}\"><thead><tr>", escape(id));
        for h in headers {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr></thead><tbody>\n");
        for (title, rows) in groups {
            if !title.is_empty() {
                let _ = writeln!(
                    self.body,
                    "<tr class=\"group\"><th colspan=\"{}\" style=\"text-align:left\">{}</th></tr>",
                    headers.len(),
                    escape(title)
                );
            }
            for row in rows {
                self.body.push_str("<tr>");
                for cell in row {
                    if cell.starts_with("<span class=\"bar\"") {
                        let _ = write!(self.body, "<td>{cell}</td>");
                    } else {
                        let _ = write!(self.body, "<td>{}</td>", escape(cell));
                    }
                }
                self.body.push_str("</tr>\n");
            }
        }
        self.body.push_str("</tbody></table>\n");
    }

    /// A figure: the SVG file inlined, with a caption.
    pub fn figure(&mut self, svg: &Path, caption: &str) -> Result<(), ReportError> {
        let text = std::fs::read_to_string(svg).map_err(io(svg))?;
        let start = text.find("<svg").unwrap_or(0);
        let _ = writeln!(
            self.body,
            "<figure>{}<figcaption>{}</figcaption></figure>",
            &text[start..],
            escape(caption)
        );
        Ok(())
    }

    /// The complete document.
    pub fn render(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
             <title>{}</title><style>{CSS}</style></head><body>\n{}</body></html>\n",
            escape(&self.title),
            self.body
        )
    }

    /// Write the document to `path`.
    pub fn write(&self, path: &Path) -> Result<(), ReportError> {
        std::fs::write(path, self.render()).map_err(io(path))
    }
}

/// A horizontal bar of `fraction` (0..1) of 8 em, as a table cell.
pub fn bar(fraction: f64) -> String {
    let w = (fraction.clamp(0.0, 1.0) * 8.0 * 100.0).round() / 100.0;
    format!("<span class=\"bar\" style=\"width:{w}em\"></span>")
}

/// Time series of a session under a calibration: the joint trajectory and
/// the IMU residuals `z − ẑ(x)` (eq. (10)) with the noise model's σ.
#[derive(Debug, Clone, Default)]
pub struct SessionSeries {
    /// Joint angles: per joint, (t, q in degrees).
    pub joints: Vec<Vec<(f64, f64)>>,
    /// IMU residuals per channel `[ax, ay, az, gx, gy, gz]`: (t, residual in
    /// m/s² or °/s).
    pub residuals: Vec<Vec<(f64, f64)>>,
    /// The noise model's σ at the same samples (t, σ in m/s² or °/s).
    pub sigma: Vec<Vec<(f64, f64)>>,
    /// Where the σ come from (for the caption).
    pub noise_source: String,
    /// The time offset τ of `x`, s.
    pub tau: f64,
    /// The trajectory the residuals are along (for the caption).
    pub trajectory: String,
}

/// Keep at most `max` evenly spaced points.
fn decimate(v: Vec<(f64, f64)>, max: usize) -> Vec<(f64, f64)> {
    if v.len() <= max {
        return v;
    }
    let step = v.len().div_ceil(max);
    v.into_iter().step_by(step).collect()
}

impl SessionSeries {
    /// Checks that `data` and `x` belong to `robot`: enough joint samples
    /// with one value per joint, and one value per parameter of its layout.
    pub fn check(robot: &Robot, data: &Measurements, x: &[f64]) -> Result<(), ReportError> {
        let n = robot.dof();
        let layout_len = ParamLayout::new(robot).len();
        if data.joint_t.len() < 8 || data.joint_q.len() != data.joint_t.len() * n {
            return Err(ReportError::Session(format!(
                "the session's joint samples do not fit robot `{}`",
                robot.name()
            )));
        }
        if x.len() != layout_len {
            return Err(ReportError::Session(format!(
                "the result has {} parameters but robot `{}` has {layout_len}",
                x.len(),
                robot.name()
            )));
        }
        Ok(())
    }

    /// The series of `data` under parameters `x`: the joint samples, and the
    /// IMU residuals along `trajectory` (the joint trajectory fitted to the
    /// samples, e.g. with the calibration's knot spacing; IMU samples outside
    /// it are left out) with the σ of `noise` there.
    pub fn new(
        robot: &Robot,
        data: &Measurements,
        x: &[f64],
        trajectory: &Spline,
        noise: &NoiseBand,
    ) -> Result<Self, ReportError> {
        Self::check(robot, data, x)?;
        let n = robot.dof();
        let layout = ParamLayout::new(robot);
        let model = MeasurementModel::new(robot, &layout, x)
            .map_err(|e| ReportError::Session(e.to_string()))?;
        let tau = x[layout.offsets().tau];
        let mut joints = vec![Vec::new(); n];
        for (s, &t) in data.joint_t.iter().enumerate() {
            for (j, series) in joints.iter_mut().enumerate() {
                series.push((t, data.joint_q[s * n + j].to_degrees()));
            }
        }
        let (a, b) = (trajectory.knots().start(), trajectory.knots().end());
        let mut residuals = vec![Vec::new(); 6];
        let mut sigma = vec![Vec::new(); 6];
        let mut js = JointState::default();
        for (&t, z) in data.imu_t.iter().zip(&data.imu_z) {
            let tr = t + tau;
            if tr < a || tr > b || trajectory.evaluate(tr, &mut js).is_err() {
                continue;
            }
            let pred = model.predict(&js);
            let qdd2: f64 = js.qdd[..n].iter().map(|a| a * a).sum();
            for c in 0..6 {
                let shown = |v: f64| if c < 3 { v } else { v.to_degrees() };
                residuals[c].push((t, shown(z[c] - pred[c])));
                sigma[c].push((t, shown(noise.sigma_at(c, qdd2))));
            }
        }
        Ok(Self {
            joints: thin(joints),
            residuals: thin(residuals),
            sigma: thin(sigma),
            noise_source: noise.source.clone(),
            tau,
            trajectory: "the trajectory refitted to the joint samples".into(),
        })
    }

    /// The series of a pose calibration's IMU (docs/model.md §7.9) from
    /// its fit: `residuals` (t, measured minus predicted, m/s² and rad/s)
    /// along the fit's own pose spline, the white σ `sigma_z` of the fit
    /// (`noise_source` says which), τ; no joint samples.
    pub fn of_pose_fit(
        residuals: &[(f64, [f64; 6])],
        sigma_z: &[f64; 6],
        noise_source: &str,
        tau: f64,
    ) -> Self {
        let shown = |c: usize, v: f64| if c < 3 { v } else { v.to_degrees() };
        let per_channel = |of: fn(usize, &[f64; 6], &[f64; 6]) -> f64| {
            (0..6)
                .map(|c| {
                    (residuals
                        .iter()
                        .map(|(t, e)| (*t, shown(c, of(c, e, sigma_z)))))
                    .collect()
                })
                .collect()
        };
        Self {
            joints: Vec::new(),
            residuals: thin(per_channel(|c, e, _| e[c])),
            sigma: thin(per_channel(|c, _, s| s[c])),
            noise_source: noise_source.into(),
            tau,
            trajectory: "the pose spline of the fit".into(),
        }
    }
}

/// Each series down to at most 1500 evenly spaced points.
fn thin(v: Vec<Vec<(f64, f64)>>) -> Vec<Vec<(f64, f64)>> {
    v.into_iter().map(|s| decimate(s, 1500)).collect()
}

/// What the report knows of the solver's iterations.
#[derive(Debug, Clone, Copy)]
pub enum Convergence<'a> {
    /// The cost at the start and after each iteration.
    Costs(&'a [f64]),
    /// No iteration history: why (shown on the page instead of the figure).
    Unavailable(&'a str),
}

/// Write `dir/report.html` (and its figures, PNG + SVG) for a calibration
/// result: the parameter table (against `truth` when given), posterior σ
/// against prior σ, convergence (`costs`: the cost at each solver
/// iteration, when known) and the session's series when given.
pub fn calibration_report(
    dir: &Path,
    result: &CalibrationResult,
    truth: Option<&Truth>,
    costs: Option<&[f64]>,
    series: Option<&SessionSeries>,
) -> Result<PathBuf, ReportError> {
    let convergence = match costs {
        Some(c) => Convergence::Costs(c),
        None => Convergence::Unavailable("the solver's iteration history was not given"),
    };
    let series = series.map_or(&[][..], std::slice::from_ref);
    calibration_report_imus(dir, result, truth, convergence, series)
}

/// [`calibration_report`] with the convergence figure's data, or the reason
/// it is missing (stated on the page), for a result of one or several IMUs (docs/model.md
/// §9): `series[j]` is IMU j's (each under its own parameters,
/// [`CalibrationResult::imu`]), the trajectory drawn from the first; the
/// parameter table and the σ figure grouped by IMU. One series (or none)
/// gives the one-IMU page.
pub fn calibration_report_imus(
    dir: &Path,
    result: &CalibrationResult,
    truth: Option<&Truth>,
    convergence: Convergence<'_>,
    series: &[SessionSeries],
) -> Result<PathBuf, ReportError> {
    calibration_report_with(dir, result, truth, convergence, series, None)
}

/// Write `dir/report.html` for a pose session's result (docs/model.md
/// §7.9): the overview with the verdict, the parameters against their
/// priors (and `truth`), convergence, and each IMU's residuals along the
/// fit's pose spline when `series` has them (`robimu calibrate --report`,
/// [`SessionSeries::of_pose_fit`]; a result file alone does not: the
/// spline is not in it). No joint trajectory.
pub(crate) fn pose_calibration_report(
    dir: &Path,
    result: &CalibrationResult,
    truth: Option<&Truth>,
    convergence: Convergence<'_>,
    series: &[SessionSeries],
) -> Result<PathBuf, ReportError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut page = HtmlPage::new("robimu calibration report");
    overview_section(&mut page, result);
    parameters_section(&mut page, dir, result, truth)?;
    convergence_section(&mut page, dir, result, convergence)?;
    if series.is_empty() {
        page.heading("Residuals");
        page.paragraph(
            "No residual figure from the result file alone: a pose session's trajectory is \
             estimated together with the IMU's parameters and is not in the result, and a pose \
             spline refitted to the pose samples alone (a controller's or tracker's rate and \
             noise) does not resolve the motion's rates and accelerations to the IMU's noise. \
             `robimu calibrate --report DIR` draws them from the fit. The calibration's residual \
             RMS per IMU channel over σ_z, and of the poses over σ_p and σ_r, are the verdict's \
             residuals check above.",
        );
    } else {
        residual_sections(&mut page, dir, series)?;
    }
    let path = dir.join("report.html");
    page.write(&path)?;
    Ok(path)
}

/// The search that gave a calibration's model its effects, for the
/// report's evidence: the session's samples and the diagnosis.
pub struct ModelEvidence<'a> {
    /// The session's measurements.
    pub data: &'a Measurements,
    /// The search (its baseline and final fits).
    pub diagnosis: &'a Diagnosis,
    /// Show every candidate's score in every round (`diagnose --report`).
    pub every_candidate: bool,
}

/// [`calibration_report_imus`] with the evidence for the effects the model
/// gained (docs/model.md §8.6): the residuals' RMS over time and their
/// spectra before and after, beside each effect's test and parameters.
pub fn calibration_report_with(
    dir: &Path,
    result: &CalibrationResult,
    truth: Option<&Truth>,
    convergence: Convergence<'_>,
    series: &[SessionSeries],
    evidence: Option<&ModelEvidence<'_>>,
) -> Result<PathBuf, ReportError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut page = HtmlPage::new("robimu calibration report");
    overview_section(&mut page, result);
    pose_accuracy_section(&mut page, result);
    model_section(&mut page, dir, result, evidence)?;
    parameters_section(&mut page, dir, result, truth)?;
    convergence_section(&mut page, dir, result, convergence)?;
    series_sections(&mut page, dir, series)?;
    let path = dir.join("report.html");
    page.write(&path)?;
    Ok(path)
}

/// The page's opening: what was calibrated, and the verdict.
fn overview_section(page: &mut HtmlPage, result: &CalibrationResult) {
    let mut facts = Vec::new();
    if let Some(r) = &result.robot {
        facts.push(format!("robot {r}"));
    }
    if let Some(s) = &result.session {
        facts.push(format!("session {s}"));
    }
    let active = result.parameters.iter().filter(|p| !p.frozen).count();
    facts.push(format!(
        "{active} of {} parameters estimated",
        result.parameters.len()
    ));
    let k = result.imu_count();
    if k > 1 {
        facts.push(format!("{k} IMUs (docs/model.md §9)"));
    }
    page.paragraph(&facts.join("; "));
    verdict_block(page, result);
}

/// The parameter table (grouped by section, against `truth` when given)
/// and the figure of posterior σ against prior σ.
fn parameters_section(
    page: &mut HtmlPage,
    dir: &Path,
    result: &CalibrationResult,
    truth: Option<&Truth>,
) -> Result<(), ReportError> {
    page.heading("Parameters");
    let table = ParameterTable::new(result, truth);
    let mut headers = vec![
        "parameter",
        "unit",
        "nominal",
        "prior σ",
        "estimate",
        "posterior σ",
        "σ / prior σ",
        "",
    ];
    if truth.is_some() {
        headers.extend(["error", "error / σ"]);
    }
    let rows: Vec<Vec<String>> = table
        .rows
        .iter()
        .map(|r| {
            let ratio = r.sigma.map(|s| s / r.prior_sigma);
            let mut row = vec![
                r.name.clone(),
                r.unit.symbol().to_string(),
                format!("{:.4}", r.nominal),
                format!("{:.4}", r.prior_sigma),
                format!("{:.4}", r.estimate),
                r.sigma.map_or("frozen".into(), |s| format!("{s:.4}")),
                ratio.map_or(String::new(), |v| format!("{v:.3}")),
                ratio.map_or(String::new(), bar),
            ];
            if truth.is_some() {
                row.push(r.error.map_or(String::new(), |e| format!("{e:.4}")));
                row.push(
                    r.normalized_error
                        .map_or(String::new(), |z| format!("{z:.2}")),
                );
            }
            row
        })
        .collect();
    if table.sections.is_empty() {
        page.table("parameters", &headers, &rows);
    } else {
        let groups: Vec<(String, Vec<Vec<String>>)> = table
            .sections
            .iter()
            .map(|s| {
                (
                    s.title.clone(),
                    s.rows.iter().map(|&i| rows[i].clone()).collect(),
                )
            })
            .collect();
        page.grouped_table("parameters", &headers, &groups);
    }
    if let Some(t) = &table.truth {
        page.paragraph(&format!(
            "Against the truth: largest |error|/σ = {:.2} ({}){}.",
            t.max_abs_normalized_error,
            t.worst,
            t.nees.map_or(String::new(), |v| format!(
                ", NEES {v:.1} over {} dof",
                t.dof
            ))
        ));
        let per = table.worst_per_section();
        if !per.is_empty() {
            let parts: Vec<String> = per
                .iter()
                .map(|(title, z, name)| format!("{title} {z:.2} ({name})"))
                .collect();
            page.paragraph(&format!(
                "Largest |error|/σ by section: {}.",
                parts.join("; ")
            ));
        }
    }
    let files = sigma_reduction_figure(&dir.join("posterior_sigma"), result)?;
    page.figure(
        &files[1],
        "How much the data reduced each parameter's uncertainty: each bar runs from 1 (the prior σ, not reduced) to posterior σ / prior σ, on a log scale (one decade = ten times smaller).",
    )?;
    Ok(())
}

/// The solver's run (iterations, costs, termination, residual RMS) and
/// the convergence figure, or why it is missing.
fn convergence_section(
    page: &mut HtmlPage,
    dir: &Path,
    result: &CalibrationResult,
    convergence: Convergence<'_>,
) -> Result<(), ReportError> {
    page.heading("Convergence");
    let mut text = String::new();
    if let (Some(i), Some(c0), Some(c1)) =
        (result.iterations, result.initial_cost, result.final_cost)
    {
        text = format!("{i} iterations: cost {c0:.6e} → {c1:.6e}");
        if let Some(t) = &result.termination {
            text.push_str(&format!(" ({t})"));
        }
        text.push('.');
    }
    if let Some(rms) = result.residual_rms {
        text.push_str(&format!(
            " Whitened residual RMS (1 = as modelled): ax {:.2}, ay {:.2}, az {:.2}, gx {:.2}, gy {:.2}, gz {:.2}.",
            rms[0], rms[1], rms[2], rms[3], rms[4], rms[5]
        ));
    }
    if !text.is_empty() {
        page.paragraph(text.trim());
    }
    let costs = match convergence {
        Convergence::Costs(c) if !c.is_empty() => Some(c),
        Convergence::Costs(_) => {
            page.paragraph("No convergence figure: the iteration history is empty.");
            None
        }
        Convergence::Unavailable(why) => {
            page.paragraph(&format!("No convergence figure: {why}."));
            None
        }
    };
    if let Some(costs) = costs {
        let pts: Vec<(f64, f64)> = costs
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0.0)
            .map(|(k, c)| (k as f64, c.log10()))
            .collect();
        let files = line_panels(
            &dir.join("convergence"),
            "Convergence",
            &[LinePanel {
                title: "MAP cost J per iteration".into(),
                x_label: "iteration".into(),
                y_label: "log10 J".into(),
                series: vec![("J".into(), pts)],
            }],
            1,
        )?;
        page.figure(&files[1], "The solver's cost at each iteration.")?;
    }
    Ok(())
}

/// The trajectory (from the first series) and each IMU's residuals with
/// the noise model's band; nothing without a series.
fn series_sections(
    page: &mut HtmlPage,
    dir: &Path,
    series: &[SessionSeries],
) -> Result<(), ReportError> {
    if let Some(s) = series.first() {
        page.heading("Trajectory");
        let panels: Vec<LinePanel> = s
            .joints
            .iter()
            .enumerate()
            .map(|(j, pts)| LinePanel {
                title: format!("q{}", j + 1),
                x_label: "t [s]".into(),
                y_label: "deg".into(),
                series: vec![(format!("q{}", j + 1), pts.clone())],
            })
            .collect();
        let files = line_panels(&dir.join("trajectory"), "Joint trajectory", &panels, 3)?;
        page.figure(&files[1], "The joint samples of the session.")?;
        residual_sections(page, dir, series)?;
    }
    Ok(())
}

/// Each IMU's residuals over time with the noise model's band.
fn residual_sections(
    page: &mut HtmlPage,
    dir: &Path,
    series: &[SessionSeries],
) -> Result<(), ReportError> {
    page.heading("Residuals");
    for (j, s) in series.iter().enumerate() {
        let (stem, who) = if series.len() == 1 {
            ("residuals".to_string(), String::new())
        } else {
            (format!("residuals_imu{j}"), format!("IMU {j}: "))
        };
        let files = residual_figure(&dir.join(stem), &s.residuals, &s.sigma, s.tau)?;
        page.figure(
            &files[1],
            &format!(
                "{who}Measured minus predicted IMU output over time ({}, τ = {:.2} ms), with the ±1σ band of {}: residuals that fit the noise model stay mostly inside it.",
                s.trajectory,
                1e3 * s.tau,
                s.noise_source
            ),
        )?;
    }
    Ok(())
}

/// Write `dir/validation.html` (and the Fig. 10 / Fig. 11 histograms, PNG +
/// SVG): robot accuracy, IMU accuracy when given, and the calibrated
/// against the classical robot parameters, stating the tracker/robot time
/// offset δ applied to the tracked motion (`alignment`, with the IMU
/// accuracy).
pub fn validation_report_with(
    dir: &Path,
    layout: &ParamLayout,
    result: &CalibrationResult,
    robot: &RobotAccuracy,
    imu: Option<&ImuAccuracy>,
    alignment: Option<&TrackerAlignment>,
) -> Result<PathBuf, ReportError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut page = HtmlPage::new("robimu validation against an external tracker");
    robot_accuracy_section(&mut page, dir, robot)?;
    robot_parameters_section(&mut page, layout, result, robot);
    if let Some(imu) = imu {
        imu_accuracy_section(&mut page, dir, imu, alignment)?;
    }
    let path = dir.join("validation.html");
    page.write(&path)?;
    Ok(path)
}

/// The robot's accuracy on held-out poses with nominal, calibrated and
/// classical parameters: table and histograms.
fn robot_accuracy_section(
    page: &mut HtmlPage,
    dir: &Path,
    robot: &RobotAccuracy,
) -> Result<(), ReportError> {
    page.heading("Robot accuracy");
    page.paragraph(&format!(
        "{} poses solve the tracker and marker transforms (and the classical calibration); {} held-out poses give the errors.",
        robot.train, robot.test
    ));
    let methods = [
        ("nominal", &robot.nominal),
        ("calibrated (this method)", &robot.calibrated),
        ("classical (tracker)", &robot.classical),
    ];
    let rows: Vec<Vec<String>> = methods
        .iter()
        .map(|(name, e)| {
            vec![
                name.to_string(),
                format!("{:.3}", 1e3 * e.mean_position()),
                format!("{:.3}", 1e3 * e.max_position()),
                format!("{:.4}", e.mean_rotation().to_degrees()),
                format!("{:.4}", e.max_rotation().to_degrees()),
            ]
        })
        .collect();
    page.table(
        "robot-accuracy",
        &[
            "parameters",
            "mean position error [mm]",
            "max [mm]",
            "mean rotation error [°]",
            "max [°]",
        ],
        &rows,
    );
    let mut panels = Vec::new();
    for (name, e) in methods {
        panels.push(HistogramPanel {
            title: format!("{name}: position [mm]"),
            values: e.position.iter().map(|v| 1e3 * v).collect(),
            normal: None,
        });
        panels.push(HistogramPanel {
            title: format!("{name}: rotation [deg]"),
            values: e.rotation.iter().map(|v| v.to_degrees()).collect(),
            normal: None,
        });
    }
    let files = histogram_grid(
        &dir.join("robot_accuracy"),
        "Robot accuracy on held-out poses",
        &panels,
        2,
    )?;
    page.figure(
        &files[1],
        "Position and rotation errors before calibration (top), after this calibration (middle) and after the classical calibration (bottom).",
    )?;
    Ok(())
}

/// The robot parameters this calibration and the classical one estimate,
/// side by side, and the classical fit's residual.
fn robot_parameters_section(
    page: &mut HtmlPage,
    layout: &ParamLayout,
    result: &CalibrationResult,
    robot: &RobotAccuracy,
) {
    page.heading("Robot parameters: calibrated and classical");
    let rows: Vec<Vec<String>> = robot
        .baseline
        .estimated
        .iter()
        .map(|(ix, name, v)| {
            let spec = &layout.specs()[*ix];
            let unit = DisplayUnit::for_si(spec.unit);
            let ours = result.parameter(name).map(|p| p.value);
            vec![
                name.clone(),
                unit.symbol().to_string(),
                format!("{:.4}", unit.show(spec.nominal)),
                ours.map_or(String::new(), |o| format!("{:.4}", unit.show(o))),
                format!("{:.4}", unit.show(*v)),
            ]
        })
        .collect();
    page.table(
        "robot-parameters",
        &["parameter", "unit", "nominal", "calibrated", "classical"],
        &rows,
    );
    page.paragraph(&format!(
        "Classical calibration: weighted pose residual RMS {:.2} (1 = tracker noise of 0.1 mm / 0.05°).",
        robot.baseline.residual_rms
    ));
}

/// The IMU's accuracy against the tracked ground truth (with the tracker's
/// time offset when given): table and histograms.
fn imu_accuracy_section(
    page: &mut HtmlPage,
    dir: &Path,
    imu: &ImuAccuracy,
    alignment: Option<&TrackerAlignment>,
) -> Result<(), ReportError> {
    page.heading("IMU accuracy");
    page.paragraph(&format!(
        "Ground truth from degree-5 splines fitted to the tracked IMU pose; {} IMU samples fit the classical IMU calibration, {} held-out samples give the errors.",
        imu.train, imu.test
    ));
    if let Some(a) = alignment {
        page.paragraph(&tracker_alignment_text(a));
    }
    let methods = [
        ("nominal", &imu.nominal),
        ("calibrated (this method)", &imu.calibrated),
        ("classical (tracker)", &imu.classical),
    ];
    let rows: Vec<Vec<String>> = methods
        .iter()
        .map(|(name, e)| {
            vec![
                name.to_string(),
                format!("{:.3}", e.rms_gyro().to_degrees()),
                format!("{:.3}", e.rms_accel()),
            ]
        })
        .collect();
    page.table(
        "imu-accuracy",
        &[
            "intrinsics",
            "RMS angular-rate error [°/s]",
            "RMS specific-force error [m/s²]",
        ],
        &rows,
    );
    let mut panels = Vec::new();
    for (name, e) in methods {
        panels.push(HistogramPanel {
            title: format!("{name}: |Δω| [deg/s]"),
            values: e.gyro.iter().map(|v| v.to_degrees()).collect(),
            normal: None,
        });
        panels.push(HistogramPanel {
            title: format!("{name}: |Δs| [m/s^2]"),
            values: e.accel.clone(),
            normal: None,
        });
    }
    let files = histogram_grid(
        &dir.join("imu_accuracy"),
        "IMU accuracy against the tracked ground truth",
        &panels,
        2,
    )?;
    page.figure(
        &files[1],
        "Angular-rate and specific-force errors with nominal, calibrated and classical intrinsics.",
    )?;
    Ok(())
}

/// One sentence on the tracker/robot time offset δ.
pub fn tracker_alignment_text(a: &TrackerAlignment) -> String {
    match &a.estimate {
        Some(e) => format!(
            "Tracker time offset δ = t_tracker − t_session = {:.1} ms, estimated by matching the tracked and the robot's angular speed (R² = {:.4}, RMS difference {:.3} °/s over {:.1} s); tracker/IMU offset τ + δ.",
            1e3 * a.delta,
            e.r_squared,
            e.rms.to_degrees(),
            e.overlap
        ),
        None => format!(
            "Tracker time offset δ = t_tracker − t_session = {:.1} ms (given); tracker/IMU offset τ + δ.",
            1e3 * a.delta
        ),
    }
}

/// The flange pose accuracy before and after (docs/model.md §8.7).
fn pose_accuracy_section(page: &mut HtmlPage, result: &CalibrationResult) {
    let Some(a) = &result.pose_accuracy else {
        return;
    };
    page.heading("Pose accuracy");
    page.paragraph(&format!(
        "The flange's position and orientation error over {} random configurations within the joint limits: predicted before calibration (the prior: the nominal model) and after (the posterior); the undetermined row is what the parameters the data left at their prior contribute. Where the truth is known (simulation), the actual errors beside.",
        a.configurations
    ));
    let row = |label: &str, s: &PoseErrorStats, band: String| {
        vec![
            label.to_string(),
            format!("{:.3}", s.position_mean_mm),
            format!("{:.3}", s.position_p95_mm),
            format!("{:.4}", s.rotation_mean_deg),
            format!("{:.4}", s.rotation_p95_deg),
            band,
        ]
    };
    let band = |e: &ActualPoseErrors| {
        format!(
            "{:.0} % / {:.0} %",
            100.0 * e.position_inside_band,
            100.0 * e.rotation_inside_band
        )
    };
    let mut rows = vec![
        row("before calibration (predicted)", &a.before, String::new()),
        row("after calibration (predicted)", &a.after, String::new()),
        row(
            "  of which undetermined",
            &a.after_undetermined,
            String::new(),
        ),
    ];
    if let Some(e) = &a.actual_before {
        rows.push(row("before, actual (truth)", &e.stats, band(e)));
    }
    if let Some(e) = &a.actual_after {
        rows.push(row("after, actual (truth)", &e.stats, band(e)));
    }
    page.table(
        "pose-accuracy",
        &[
            "",
            "position mean [mm]",
            "position p95 [mm]",
            "rotation mean [deg]",
            "rotation p95 [deg]",
            "inside the predicted 95 % band",
        ],
        &rows,
    );
}

/// The model written and why: each effect added with its score test, the
/// refit's likelihood ratio, the residual RMS before and after and its
/// parameters; the figures of the residuals before and after when the
/// evidence is given.
fn model_section(
    page: &mut HtmlPage,
    dir: &Path,
    result: &CalibrationResult,
    evidence: Option<&ModelEvidence<'_>>,
) -> Result<(), ReportError> {
    let Some(tests) = &result.model_tests else {
        return Ok(());
    };
    page.heading("Model");
    let effects = result.effects.as_deref().unwrap_or_default();
    let names: Vec<&str> = effects.iter().map(|e| e.name.as_str()).collect();
    page.paragraph(&format!(
        "{} ({}; score tests of {} catalogue effects at family-wise α = {}, docs/model.md §8.6).",
        match names.is_empty() {
            true => "The paper's model".to_string(),
            false => format!("The paper's model + {}", names.join(", ")),
        },
        match tests.selection.as_str() {
            "paper" => "asked for with --model paper",
            "given" => "the effects given with --effects",
            _ => "chosen by the tests",
        },
        tests.candidates,
        tests.alpha
    ));
    let mut rows = Vec::new();
    for e in effects {
        let ev = e.evidence.as_ref();
        let rms = |v: Option<&[f64; 6]>| {
            v.map_or(String::new(), |v| {
                v.iter()
                    .map(|x| format!("{x:.3}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
        };
        rows.push(vec![
            e.name.clone(),
            ev.map_or("given".into(), |v| {
                format!("{:.1} ({} dof), p = {:.2e}", v.statistic, v.dof, v.p_value)
            }),
            ev.map_or(String::new(), |v| {
                format!("{:.1}, p = {:.2e}", v.lr_statistic, v.lr_p_value)
            }),
            rms(ev.map(|v| &v.rms_before)),
            rms(ev.map(|v| &v.rms_after)),
        ]);
    }
    if !rows.is_empty() {
        page.table(
            "effects",
            &[
                "effect",
                "score test",
                "refit's likelihood ratio",
                "whitened RMS before (ax…gz)",
                "after",
            ],
            &rows,
        );
        let params: Vec<Vec<String>> = effects
            .iter()
            .flat_map(|e| &e.parameters)
            .map(|p| {
                vec![
                    p.name.clone(),
                    p.unit.clone(),
                    format!("{:.6e}", p.value),
                    format!("{:.3e}", p.sigma),
                ]
            })
            .collect();
        page.table(
            "effect-parameters",
            &["parameter", "unit (SI)", "estimate", "σ"],
            &params,
        );
    }
    if let Some(ev) = evidence.filter(|e| e.every_candidate) {
        candidates_table(page, ev.diagnosis);
    }
    if let Some(ev) = evidence.filter(|_| !effects.is_empty()) {
        let rms = residuals_plot(&dir.join("model_residuals"), ev.data, ev.diagnosis)
            .map_err(ReportError::from)?;
        page.figure(
            &rms[1],
            "Whitened residuals' RMS over time before (the paper's model) and after the effects: the gap the effects close (1 = the noise model's level).",
        )?;
        let spectra = spectra_plot(&dir.join("model_spectra"), ev.data, ev.diagnosis)
            .map_err(ReportError::from)?;
        page.figure(
            &spectra[1],
            "Whitened residual spectra before and after the effects: a peak or slope the effects take away was structure the paper's model lacked.",
        )?;
    }
    Ok(())
}

/// Every candidate's score test in every round of the search, and the
/// candidates rejected.
fn candidates_table(page: &mut HtmlPage, d: &Diagnosis) {
    let mut rows = Vec::new();
    let rounds = d
        .found
        .iter()
        .map(|f| (format!("added {}", f.name), &f.scores))
        .chain(std::iter::once(("last".to_string(), &d.last_scores)));
    for (k, (what, scores)) in rounds.enumerate() {
        for s in scores {
            rows.push(vec![
                format!("{} ({what})", k + 1),
                s.name.clone(),
                format!("{:.1}", s.statistic),
                s.dof.to_string(),
                format!("{:.2e}", s.p_value),
                if s.p_value < d.threshold {
                    "significant"
                } else {
                    ""
                }
                .into(),
            ]);
        }
    }
    page.paragraph(&format!(
        "Every candidate's Rao score in every round (Bonferroni threshold {:.1e}); rejected: {}.",
        d.threshold,
        match d.rejected.is_empty() {
            true => "none".to_string(),
            false => d
                .rejected
                .iter()
                .map(|r| format!("{} ({})", r.name, r.reason))
                .collect::<Vec<_>>()
                .join("; "),
        }
    ));
    page.table(
        "candidates",
        &["round", "candidate", "score", "dof", "p", ""],
        &rows,
    );
}

/// The verdict of result.json (when it has one): the trust line, then
/// one row per check (`robimu_workflows::verdict`).
fn verdict_block(page: &mut HtmlPage, result: &CalibrationResult) {
    let Some(v) = &result.verdict else { return };
    page.heading("Verdict");
    let _ = writeln!(
        page.body,
        "<p id=\"trust\" class=\"trust-{}\"><b>{}</b></p>",
        v.trust,
        escape(&crate::verdict::trust_line(v))
    );
    let rows: Vec<Vec<String>> = v
        .checks
        .iter()
        .map(|c| {
            vec![
                c.topic.clone(),
                if c.ok { "ok" } else { "FAIL" }.to_string(),
                c.text.clone(),
            ]
        })
        .collect();
    page.table("verdict", &["check", "", "finding"], &rows);
    if !v.next_steps.is_empty() {
        let items: Vec<Vec<String>> = v.next_steps.iter().map(|s| vec![s.clone()]).collect();
        page.table("next-steps", &["what to do next"], &items);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup() {
        assert_eq!(
            escape("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
        let mut p = HtmlPage::new("t<1>");
        p.table("x", &["a"], &[vec!["<b>".into()], vec![bar(0.5)]]);
        let html = p.render();
        assert!(html.contains("<title>t&lt;1&gt;</title>"));
        assert!(html.contains("<td>&lt;b&gt;</td>"));
        assert!(html.contains("<td><span class=\"bar\" style=\"width:4em\"></span></td>"));
        assert!(!html.contains("http://") && !html.contains("https://"));
    }
}

#[cfg(test)]
mod band_tests {
    use super::*;
    use crate::figures::NoiseBand;

    /// The band is the noise's ±1σ: on a simulated session whose
    /// accelerometer noise grows with the joint acceleration (AR(1), motion
    /// gain c), the true parameters' residuals fall inside it 68 % of the
    /// time in every channel, where the band at rest holds far fewer.
    #[test]
    fn residual_band_holds_68_percent_of_simulated_noise() {
        use robimu_model::noise::NoiseModel;
        use robimu_workflows::calibrate::noise_model_record;
        use robimu_workflows::simulate::{random_session, SimulateOptions};
        let robot = Robot::aubo_i5();
        let mut opts = SimulateOptions::paper(&robot);
        let model = NoiseModel::ar1(opts.sigma_z, [Some(0.6), None], [0.3, 0.0]).unwrap();
        opts.noise_model = Some(model.clone());
        let s = random_session(&robot, 30.0, 1.0, &opts, 5).unwrap();
        let inside = |band: &NoiseBand| {
            let series =
                SessionSeries::new(&robot, &s.data, &s.truth, &s.trajectory, band).unwrap();
            (0..6)
                .map(|c| {
                    let (r, sd) = (&series.residuals[c], &series.sigma[c]);
                    assert_eq!(r.len(), sd.len());
                    let k = r.iter().zip(sd).filter(|(r, s)| r.1.abs() <= s.1).count();
                    k as f64 / r.len() as f64
                })
                .collect::<Vec<f64>>()
        };
        let record = noise_model_record(&model);
        let fit = inside(&NoiseBand::of_fit(Some(&record), &opts.sigma_z));
        for (c, f) in fit.iter().enumerate() {
            assert!(
                (f - 0.6827).abs() < 0.05,
                "channel {c}: {f:.3} inside ±1σ ({fit:?})"
            );
        }
        let at_rest = inside(&NoiseBand::of_fit(None, &opts.sigma_z));
        for c in 0..3 {
            assert!(
                at_rest[c] < fit[c] - 0.1,
                "channel {c}: {at_rest:?} vs {fit:?}"
            );
        }
    }
}
