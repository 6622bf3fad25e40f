//! A calibration as the program shows it (`robimu calibrate`, `robimu
//! demo`): the library's pipeline ([`robimu_workflows::Prepared`]) with a
//! progress line, the verdict, the parameter table, the files it wrote, and
//! the HTML report, the effects and the time windows when asked for.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use robimu_model::{ParamLayout, Robot};
use robimu_report::convergence::ConvergenceLog;
use robimu_report::figures::NoiseBand;
use robimu_report::fit_summary::{FitReport, RepeatabilityGroups, WeakDirectionsWarning};
use robimu_report::html::{calibration_report_with, Convergence, ModelEvidence};
use robimu_report::model_summary::{ModelSummary, PoseAccuracyText};
use robimu_report::noise::NoiseSummary;
use robimu_report::verdict::{trust_line, VerdictText};
use robimu_report::ParameterTable;
use robimu_session::Session;
use robimu_solver::IterationRecord;
use robimu_workflows::calibrate::CalibrateOptions;
use robimu_workflows::diagnose::Diagnosis;
use robimu_workflows::repeatability::{self, Window};
use robimu_workflows::{load_session, FitEvent, Fitted, Prepared, Settings};

use crate::args::CalibrateFlags;
use crate::input::{output_path, Progress};

/// What to calibrate and what to write besides the result file.
pub struct CalibrateRun<'a> {
    /// The session directory.
    pub session: &'a Path,
    /// The result file [default: result.json in the session directory].
    pub out: Option<&'a Path>,
    /// Time windows of a repeatability study.
    pub windows: Option<usize>,
    /// Directory of the HTML report.
    pub report: Option<&'a Path>,
    /// The calibration's settings.
    pub flags: &'a CalibrateFlags,
}

impl CalibrateRun<'_> {
    /// Calibrate, print the table and write the result file (and what else
    /// was asked for); returns the calibration written (before a
    /// repeatability study's verdict).
    pub fn run(&self) -> anyhow::Result<Fitted> {
        let dir = self.session;
        let (session, robot) = load_session(dir)?;
        let file = self.flags.noise_file()?;
        let path = output_path(self.out, dir.join("result.json"))?;
        let settings = self.flags.settings()?;
        let p = Prepared::new(session, robot, &settings, file.as_ref(), |w| {
            eprintln!("warning: {w}")
        })?;
        let windows = self.windows.map(|k| p.windows(k)).transpose()?;
        let mut out = std::io::stdout().lock();
        write_header(&mut out, dir, &p.session, &p.layout, &p.opts)?;
        let fitted = fit_with_progress(&p)?;
        self.print_fit(&mut out, &p, &fitted)?;
        let history = fitted.write(&path)?;
        writeln!(out, "wrote {}", path.display())?;
        writeln!(out, "wrote {}", history.display())?;
        if let Some(report_dir) = self.report {
            let html = html_report(report_dir, &p, &fitted)?;
            writeln!(out, "wrote {}", html.display())?;
        }
        if let Some(epath) = p.write_effects(&fitted, &path)? {
            writeln!(out, "wrote {}", epath.display())?;
        }
        match windows {
            Some(windows) => repeatability_study(&mut out, &p, fitted, windows, &path),
            None => Ok(fitted),
        }
    }

    /// The verdict, the fit's summary, the noise model and the parameter
    /// table (warnings on stderr).
    fn print_fit(&self, out: &mut impl Write, p: &Prepared, fitted: &Fitted) -> anyhow::Result<()> {
        let Fitted {
            cal, noise, result, ..
        } = fitted;
        let chosen = self.flags.knot_spacing.is_none();
        write!(out, "{}", fit_summary(p, fitted, chosen))?;
        if let Some(w) = &noise.warning {
            eprintln!("warning: {w}");
        }
        writeln!(out)?;
        write!(
            out,
            "{}",
            ParameterTable::new(result, p.session.truth.as_ref())
        )?;
        out.flush()?;
        eprint!(
            "{}",
            WeakDirectionsWarning::new(&cal.weak_directions, &p.layout)
        );
        Ok(())
    }
}

/// The verdict, the fit's summary, the pose accuracy and the noise model
/// as `robimu calibrate` prints them above the parameter table
/// (`knot_chosen`: the knot spacing was chosen from the data).
pub fn fit_summary(p: &Prepared, fitted: &Fitted, knot_chosen: bool) -> String {
    let Fitted {
        cal, noise, result, ..
    } = fitted;
    let mut text = String::new();
    if let Some(v) = &result.verdict {
        text += &VerdictText(v).to_string();
    }
    text += &ModelSummary {
        result,
        fit: &fitted.fit,
    }
    .to_string();
    if let Some(pose) = &result.pose_accuracy {
        text += &PoseAccuracyText(pose).to_string();
    }
    text += &FitReport::brief(cal, knot_chosen).to_string();
    text += &NoiseSummary::new(&p.choice, noise, &cal.noise_model)
        .with_imus(&cal.extra_noise_models)
        .to_string();
    text
}

/// The fit with a spinner and the solver's iterations on stderr.
fn fit_with_progress(p: &Prepared) -> anyhow::Result<Fitted> {
    let progress = Progress::start("fitting the trajectory and finding the time offset tau");
    progress.println(IterationRecord::HEADER);
    let fitted = p.fit(|e| match e {
        FitEvent::Iteration(r) => {
            progress.println(r.to_string());
            progress.set_message(format!(
                "iteration {}: cost {:.6e}, lambda {:.1e}",
                r.iteration, r.cost, r.lambda
            ));
        }
        FitEvent::Stage(s) => {
            progress.println(format!("-- {s}"));
            progress.set_message(s.to_string())
        }
    });
    progress.finish();
    Ok(fitted?)
}

/// `--windows`: each window calibrated and compared with the full
/// calibration, repeatability.csv, and the result file again with the
/// verdict that includes the windows; returns the calibration with it.
fn repeatability_study(
    out: &mut impl Write,
    p: &Prepared,
    mut fitted: Fitted,
    windows: Vec<Window>,
    path: &Path,
) -> anyhow::Result<Fitted> {
    let count = windows.len();
    let progress = Progress::start(format!("calibrating {count} windows"));
    let study = p.repeatability(&fitted, windows, |w, r| {
        progress.set_message(format!(
            "window {} of {count}: iteration {}, cost {:.6e}",
            w + 1,
            r.iteration,
            r.cost
        ));
    });
    progress.finish();
    let (study, result) = study?;
    writeln!(out)?;
    write!(out, "{}", RepeatabilityGroups(&study))?;
    let csv = path.with_file_name("repeatability.csv");
    repeatability::write_csv(&csv, &p.layout, &study)
        .with_context(|| format!("cannot write {}", csv.display()))?;
    writeln!(out, "wrote {}", csv.display())?;
    if let Some(verdict) = &result.verdict {
        if let Some(c) = verdict.checks.iter().find(|c| c.topic == "repeatability") {
            let mark = if c.ok { "ok" } else { "FAIL" };
            writeln!(
                out,
                "verdict with the windows:\n  {mark:<4} {:<13} {}",
                c.topic, c.text
            )?;
        }
        writeln!(out, "{}", trust_line(verdict))?;
    }
    result.write(path)?;
    writeln!(
        out,
        "wrote {} (its verdict with the windows)",
        path.display()
    )?;
    fitted.result = result;
    Ok(fitted)
}

/// The first line: the session, its samples and what is estimated.
fn write_header(
    out: &mut impl Write,
    dir: &Path,
    session: &Session,
    layout: &ParamLayout,
    opts: &CalibrateOptions,
) -> std::io::Result<()> {
    let (ta, tb) = session.joints.span().unwrap_or_default();
    writeln!(
        out,
        "session {}: robot {}, {} joint samples, {} IMU samples{}, {:.1} s; estimating {} of {} parameters{}",
        dir.display(),
        session.meta.robot,
        session.joints.len(),
        session.imu.len(),
        match layout.n_imus() {
            1 => String::new(),
            k => format!(" (IMU 0; {k} IMUs fitted jointly)"),
        },
        tb - ta,
        layout.len() - opts.frozen.len(),
        layout.len(),
        if opts.use_prior { "" } else { " without priors" }
    )?;
    out.flush()
}

/// `diagnose --report DIR`: the calibration page of diagnose's final model
/// `d` (its verdict, pose accuracy, evidence), with every candidate's score.
pub fn diagnosis_report(session: &Path, dir: &Path, d: Diagnosis) -> anyhow::Result<PathBuf> {
    let (s, robot) = load_session(session)?;
    let p = Prepared::new(s, robot, &Settings::default(), None, |_| {})?;
    let fitted = p.fitted_from(d)?;
    html_report_with(dir, &p, &fitted, true)
}

/// `--report`: the HTML report of the calibration, one series per IMU, each
/// under its own parameters (docs/model.md §9).
fn html_report(report_dir: &Path, p: &Prepared, fitted: &Fitted) -> anyhow::Result<PathBuf> {
    html_report_with(report_dir, p, fitted, false)
}

/// [`html_report`], with every candidate's score in every round of the
/// search when `every_candidate`.
fn html_report_with(
    report_dir: &Path,
    p: &Prepared,
    fitted: &Fitted,
    every_candidate: bool,
) -> anyhow::Result<PathBuf> {
    let (robot, opts, cal, result): (&Robot, _, _, _) =
        (&p.robot, &p.opts, &fitted.cal, &fitted.result);
    let layout = cal.layout(robot);
    let series = (0..layout.n_imus())
        .map(|j| {
            robimu_report::result_report::session_series(
                robot,
                &p.data.only_imu(j),
                &layout.imu_x(j, &cal.x),
                &opts.sigma_q,
                Some(cal.knot_spacing),
                &NoiseBand::of_fit(result.noise_model_of(j), &opts.sigma_z),
            )
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let costs = ConvergenceLog::from_summary(&cal.summary).costs();
    let evidence = fitted.selection.as_ref().map(|d| ModelEvidence {
        data: &p.data,
        diagnosis: d,
        every_candidate,
    });
    Ok(calibration_report_with(
        report_dir,
        result,
        p.session.truth.as_ref(),
        Convergence::Costs(&costs),
        &series,
        evidence.as_ref(),
    )?)
}
