//! `robimu calibrate`: the MAP calibration of one session, its table and its
//! result file (docs/model.md §8).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use robimu_model::effects::EffectSet;
use robimu_model::observations::Measurements;
use robimu_model::{ParamLayout, Robot};
use robimu_report::convergence::{convergence_path, ConvergenceLog};
use robimu_report::figures::NoiseBand;
use robimu_report::fit_summary::{
    EffectEstimates, FitReport, RepeatabilityGroups, WeakDirectionsWarning,
};
use robimu_report::html::{calibration_report_imus, Convergence};
use robimu_report::noise::NoiseSummary;
use robimu_report::verdict::{trust_line, VerdictText};
use robimu_report::ParameterTable;
use robimu_session::result::CalibrationResult;
use robimu_session::Session;
use robimu_solver::IterationRecord;
use robimu_workflows::calibrate::fit::{fit, Fit, FitSpec, Start};
use robimu_workflows::calibrate::noise_choice::{
    calibrate_with_noise_settle, NoiseChoice, NoiseOutcome, Settle, MAX_REFITS,
};
use robimu_workflows::calibrate::noise_choice::{
    other_imu_identifications, residual_identification,
};
use robimu_workflows::calibrate::{check_measurements, CalibrateOptions, Calibration};
use robimu_workflows::check::{check_session, CheckOptions, Severity};
use robimu_workflows::diagnose::{effect_set, fit_json, setup_with};
use robimu_workflows::noise_id::{IdOptions, Identification};
use robimu_workflows::repeatability::{self, check_windows, Repeatability, Window};
use robimu_workflows::verdict::{self, VerdictInput};

use super::input::{load_session, output_path, Progress};
use super::noise_spec::{noise_choice, NoiseFileArg};

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
    /// The calibration's settings (shared with `robimu calibrate-batch`).
    #[command(flatten)]
    pub fit: CalibrateFlags,
}

/// The flags that set how a session is calibrated (`robimu calibrate`,
/// `robimu calibrate-batch`).
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateFlags {
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
    /// by `robimu noise`) replaces the session's key by key: `sigma_z`,
    /// `sigma_q` replace the session's and the robot's σ, and `ar_z`,
    /// `motion_z` (when given) the session's noise model, which
    /// `--noise-model auto` then fits as given (docs/model.md §4.6, §7.2).
    #[arg(long, value_name = "FILE")]
    pub noise: Option<PathBuf>,
    /// Also fit these catalogue effects with the baseline (comma-separated:
    /// g_sensitivity, size_effect, clock_drift, sensor_delay, bias_drift,
    /// joint_elasticity, encoder_scale, resonance, temperature_bias where imu.csv
    /// has a varying temp_c); prints their estimates and writes
    /// effects.json (the augmented model's parameters) next to the result file.
    /// With several IMUs a per-sensor effect of IMU j ≥ 1 is `imu<j>/NAME`
    /// (docs/model.md §9). `bias_drift:M` sets its spline's M segments over the session (default
    /// 1, a linear drift; `robimu diagnose` chooses M and prints the spec).
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    #[command(flatten)]
    pub resonance: super::input::ResonanceMode,
    /// The IMU noise model: `auto` (white unless the residuals fail the
    /// whiteness test; then identified from them and refitted by
    /// generalised least squares; a `[noise]` table — the session's or
    /// `--noise`'s — that gives `ar_z`/`motion_z` is fitted with that
    /// model), `white` (the paper's model), or a noise FILE: the same as
    /// `--noise FILE`, with the resulting model (the file's keys over the
    /// session's) fitted as given even when it is white (docs/model.md
    /// §4.6, §7.2).
    #[arg(long, value_name = "white|auto|FILE", default_value = "auto")]
    pub noise_model: String,
    /// `--noise-model auto`: the most GLS refits while the identified model
    /// settles (at least 1).
    #[arg(long, value_name = "N", default_value_t = MAX_REFITS)]
    pub noise_refits: usize,
    /// `--noise-model auto`: the identified model has settled when, from one
    /// refit to the next, no AR coefficient moves by TOL or more and no σ or
    /// motion gain by TOL relative (0 never settles: the white result is
    /// kept with a warning) [default: 0.02].
    #[arg(long, value_name = "TOL")]
    pub noise_settle: Option<f64>,
    /// Calibrate IMU J of a multi-IMU session alone (docs/model.md §9; 0 is
    /// imu.csv, J ≥ 1 imu<J>.csv) as a one-IMU session: the result uses the
    /// one-IMU names (`tau`, `k_a_x`, … for IMU J's own parameters, without
    /// the `imu<J>/` prefix) and the truth is compared by those names.
    /// Without it every IMU of the session is calibrated jointly.
    #[arg(long, value_name = "J")]
    pub imu: Option<usize>,
}

impl Default for CalibrateFlags {
    /// `robimu calibrate`'s defaults.
    fn default() -> Self {
        Self {
            freeze: Vec::new(),
            no_prior: false,
            knot_spacing: None,
            noise: None,
            effects: Vec::new(),
            resonance: Default::default(),
            noise_model: "auto".into(),
            noise_refits: MAX_REFITS,
            noise_settle: None,
            imu: None,
        }
    }
}

impl CalibrateCmd {
    /// Calibrate, print the table and write the result file.
    pub fn run(self) -> anyhow::Result<()> {
        let dir = &self.session;
        let (session, robot) = load_session(dir)?;
        let file = self.fit.noise_file()?;
        let path = output_path(self.out.as_deref(), dir.join("result.json"))?;
        let p = self.fit.prepare(dir, session, robot, file.as_ref())?;
        let (session, robot, layout, opts, data) =
            (&p.session, &p.robot, &p.layout, &p.opts, &p.data);
        let windows = match self.windows {
            Some(k) => Some(
                check_windows(data, k)
                    .with_context(|| format!("--windows {k}: cannot split {}", dir.display()))?,
            ),
            None => None,
        };
        let mut out = std::io::stdout().lock();
        write_header(&mut out, dir, session, layout, opts)?;

        let progress = Progress::start("fitting the trajectory and finding the time offset tau");
        progress.println(IterationRecord::HEADER);
        let fitted = self.fit.fit_prepared(&p, dir, |r| {
            progress.println(r.to_string());
            progress.set_message(format!(
                "iteration {}: cost {:.6e}, lambda {:.1e}",
                r.iteration, r.cost, r.lambda
            ));
        });
        progress.finish();
        let Fitted {
            cal,
            noise,
            mut result,
            whiteness,
            other_imus,
        } = fitted?;
        let choice = &p.choice;
        let effects = &p.effects;
        if let Some(v) = &result.verdict {
            write!(out, "{}", VerdictText(v))?;
        }
        write!(
            out,
            "{}",
            FitReport::brief(&cal, self.fit.knot_spacing.is_none())
        )?;
        write!(
            out,
            "{}",
            NoiseSummary::new(choice, &noise, &cal.noise_model)
        )?;
        if let Some(w) = &noise.warning {
            eprintln!("warning: {w}");
        }
        writeln!(out)?;
        write!(
            out,
            "{}",
            ParameterTable::new(&result, session.truth.as_ref())
        )?;
        out.flush()?;
        eprint!(
            "{}",
            WeakDirectionsWarning::new(&cal.weak_directions, layout)
        );
        let hpath = write_result(&result, &cal, &path)?;
        writeln!(out, "wrote {}", path.display())?;
        writeln!(out, "wrote {}", hpath.display())?;
        if let Some(report_dir) = &self.report {
            let html = html_report(report_dir, robot, data, opts, &cal, &result, session)?;
            writeln!(out, "wrote {}", html.display())?;
        }
        if let Some(set) = effects {
            fit_effects(&mut out, robot, data, opts, set, &cal, &path)?;
        }
        if let Some(windows) = windows {
            let study = calibrate_windows(robot, opts, windows, cal, dir)?;
            writeln!(out)?;
            write!(out, "{}", RepeatabilityGroups(&study))?;
            let csv = path.with_file_name("repeatability.csv");
            write_windows_csv(&csv, layout, &study)
                .with_context(|| format!("cannot write {}", csv.display()))?;
            writeln!(out, "wrote {}", csv.display())?;
            let verdict = verdict::verdict(&VerdictInput {
                robot,
                calibration: &study.full,
                noise: Some(&noise),
                whiteness: whiteness.as_ref(),
                repeatability: Some(&study),
                other_imus: &other_imus,
            });
            if let Some(c) = verdict.checks.iter().find(|c| c.topic == "repeatability") {
                let mark = if c.ok { "ok" } else { "FAIL" };
                writeln!(
                    out,
                    "verdict with the windows:\n  {mark:<4} {:<13} {}",
                    c.topic, c.text
                )?;
            }
            writeln!(out, "{}", trust_line(&verdict))?;
            result.verdict = Some(verdict);
            result.write(&path)?;
            writeln!(
                out,
                "wrote {} (its verdict with the windows)",
                path.display()
            )?;
        }
        Ok(())
    }
}

impl CalibrateFlags {
    /// A loaded session made ready to calibrate with these flags: the
    /// settings, the checked measurements, the `--effects` set and the
    /// noise choice (`file`: [`Self::noise_file`], read once by the caller).
    pub(crate) fn prepare(
        &self,
        dir: &Path,
        mut session: Session,
        robot: Robot,
        file: Option<&NoiseFileArg>,
    ) -> anyhow::Result<Prepared> {
        preflight(&session, &robot)?;
        let mut robot = robot;
        if let Some(j) = self.imu {
            let k = session.n_imus();
            session = session.only_imu(j).with_context(|| {
                format!(
                    "--imu {j}: the session {} has {k} IMU{} (0..{})",
                    dir.display(),
                    if k == 1 { "" } else { "s" },
                    k - 1
                )
            })?;
            // IMU j alone: its own mount prior is the one-IMU robot's
            robot = robot.with_mount(0, *robot.mount_of(j))?;
        }
        let data = session.measurements();
        let layout = ParamLayout::with_imus(&robot, data.n_imus());
        let opts = self.options(&session, &robot, &layout, file)?;
        check_measurements(&robot, &data)
            .with_context(|| format!("cannot calibrate the session {}", dir.display()))?;
        let effects = self.effect_set(&robot, &data)?;
        let choice = self.noise_choice(&session, &opts, data.imu_t.len(), file)?;
        let settle = self.settle()?;
        Ok(Prepared {
            session,
            robot,
            layout,
            opts,
            data,
            effects,
            choice,
            settle,
        })
    }

    /// The calibration of a prepared session with the noise choice
    /// (docs/model.md §4.6) and its result file's contents (not written).
    pub(crate) fn fit_prepared(
        &self,
        p: &Prepared,
        dir: &Path,
        report: impl FnMut(&IterationRecord),
    ) -> anyhow::Result<Fitted> {
        let (cal, noise) =
            calibrate_with_noise_settle(&p.robot, &p.data, &p.opts, &p.choice, &p.settle, report)
                .with_context(|| format!("cannot calibrate the session {}", dir.display()))?;
        let whiteness = (p.choice != NoiseChoice::Auto)
            .then(|| residual_identification(&p.robot, &p.data, &cal, &IdOptions::default()).ok())
            .flatten();
        let other_imus: Vec<(usize, Identification)> =
            other_imu_identifications(&p.robot, &p.data, &cal, &IdOptions::default())
                .into_iter()
                .filter_map(|(j, id)| id.ok().map(|id| (j, id)))
                .collect();
        let verdict = verdict::verdict(&VerdictInput {
            robot: &p.robot,
            calibration: &cal,
            noise: Some(&noise),
            whiteness: whiteness.as_ref(),
            repeatability: None,
            other_imus: &other_imus,
        });
        let mut result = result_file(&cal, &p.layout, &p.session, dir, p.opts.use_prior);
        result.noise_warning = noise.warning.clone();
        result.verdict = Some(verdict);
        Ok(Fitted {
            cal,
            noise,
            result,
            whiteness,
            other_imus,
        })
    }

    /// The noise file of `--noise FILE` or `--noise-model FILE`, read once:
    /// its flag, path, σ and model keys. Two different files are refused.
    pub(crate) fn noise_file(&self) -> anyhow::Result<Option<NoiseFileArg>> {
        NoiseFileArg::from_flags(self.noise.as_deref(), &self.noise_model)
    }

    /// The calibration settings: the session's σ (replaced by the noise
    /// file's), `--freeze`, `--no-prior`, `--knot-spacing`.
    fn options(
        &self,
        session: &Session,
        robot: &Robot,
        layout: &ParamLayout,
        file: Option<&NoiseFileArg>,
    ) -> anyhow::Result<CalibrateOptions> {
        let mut opts = CalibrateOptions::new(robot);
        (opts.sigma_z, opts.sigma_q) = session.noise(robot)?;
        if let Some(f) = file {
            if let Some(z) = f.file.noise.sigma_z {
                opts.sigma_z = z;
            }
            if let Some(q) = &f.file.noise.sigma_q {
                if q.len() != robot.dof() {
                    bail!(
                        "{} {}: [noise] sigma_q has {} values but robot `{}` has {} joints",
                        f.flag,
                        f.path.display(),
                        q.len(),
                        robot.name(),
                        robot.dof()
                    );
                }
                opts.sigma_q = q.clone();
            }
        }
        opts.frozen = layout
            .select(&self.freeze)
            .map_err(|e| anyhow::anyhow!("--freeze: {e}"))?;
        opts.use_prior = !self.no_prior;
        if let Some(h) = self.knot_spacing {
            if !(h.is_finite() && h > 0.0) {
                bail!("--knot-spacing must be a positive number of seconds (got {h})");
            }
        }
        opts.knot_spacing = self.knot_spacing;
        Ok(opts)
    }

    /// `--noise-refits` and `--noise-settle`.
    pub(crate) fn settle(&self) -> anyhow::Result<Settle> {
        if self.noise_refits == 0 {
            bail!("--noise-refits must be at least 1");
        }
        let mut settle = Settle {
            max_refits: self.noise_refits,
            ..Settle::default()
        };
        if let Some(tol) = self.noise_settle {
            if !(tol.is_finite() && tol >= 0.0) {
                bail!("--noise-settle must be a number >= 0 (got {tol})");
            }
            (settle.phi, settle.sigma) = (tol, tol);
        }
        Ok(settle)
    }

    /// The `--noise-model` choice: `white`; `auto` (the noise table's AR
    /// model — the noise file's keys, else the session's — as given, else
    /// identified when needed); a FILE's model as given. The σ are `opts`'
    /// (the noise file's over the session's); an AR order beyond the data is
    /// refused.
    fn noise_choice(
        &self,
        session: &Session,
        opts: &CalibrateOptions,
        samples: usize,
        file: Option<&NoiseFileArg>,
    ) -> anyhow::Result<NoiseChoice> {
        noise_choice(&self.noise_model, session, opts.sigma_z, samples, file)
    }

    /// The `--effects` set (`None` without effects: then the catalogue, and
    /// its resonance response to the joint trajectory, is never set up).
    fn effect_set(&self, robot: &Robot, data: &Measurements) -> anyhow::Result<Option<EffectSet>> {
        let mode = self.resonance.mode()?;
        let specs: Vec<&str> = self
            .effects
            .iter()
            .map(|s| s.trim())
            .filter(|s| !s.is_empty())
            .collect();
        if specs.is_empty() {
            return Ok(None);
        }
        let mut setup = setup_with(robot, data, None, mode);
        let names = specs
            .iter()
            .map(|s| setup.apply_spec(s))
            .collect::<Result<Vec<_>, _>>()
            .context("--effects")?;
        Ok(Some(effect_set(&setup, &names).context("--effects")?))
    }
}

/// A session ready to calibrate ([`CalibrateFlags::prepare`]).
pub(crate) struct Prepared {
    pub session: Session,
    pub robot: Robot,
    pub layout: ParamLayout,
    pub opts: CalibrateOptions,
    pub data: Measurements,
    /// The `--effects` set, when given.
    pub effects: Option<EffectSet>,
    pub choice: NoiseChoice,
    pub settle: Settle,
}

/// A finished calibration ([`CalibrateFlags::fit_prepared`]).
pub(crate) struct Fitted {
    pub cal: Calibration,
    pub noise: NoiseOutcome,
    /// The result file's contents (with the verdict, docs/model.md §8.5).
    pub result: CalibrationResult,
    /// The whiteness test of the final residuals when the noise choice is
    /// not `auto` (which has its own), for the verdict.
    pub whiteness: Option<Identification>,
    /// A multi-IMU fit's IMUs j ≥ 1: the identification from each one's residuals.
    pub other_imus: Vec<(usize, Identification)>,
}

/// Write the result file at `path` and the solver's iteration history next
/// to it; returns the history's path.
pub(crate) fn write_result(
    result: &CalibrationResult,
    cal: &Calibration,
    path: &Path,
) -> anyhow::Result<PathBuf> {
    result.write(path)?;
    let hpath = convergence_path(path);
    ConvergenceLog::from_summary(&cal.summary).write(&hpath)?;
    Ok(hpath)
}

/// The check of the recording before the fit (`robimu check` without the
/// excitation measure, which the calibration's own σ replace): warnings on
/// stderr, a fatal finding stops the calibration with its message.
fn preflight(session: &Session, robot: &Robot) -> anyhow::Result<()> {
    let report = check_session(session, robot, &CheckOptions { excitation: false });
    for f in report.of(Severity::Warning) {
        eprintln!("warning: {} ({})", f.message, f.action);
    }
    super::check::fatal(&report, &session.dir).map_err(|e| {
        anyhow::anyhow!(
            "{e}; `robimu check {}` lists every finding",
            session.dir.display()
        )
    })
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

/// The result file of `cal`, with the session's robot and path.
fn result_file(
    cal: &Calibration,
    layout: &ParamLayout,
    session: &Session,
    dir: &Path,
    use_prior: bool,
) -> CalibrationResult {
    let mut result = cal.to_result(layout);
    result.robot = Some(session.meta.robot.clone());
    result.session = Some(
        std::path::absolute(dir)
            .unwrap_or_else(|_| dir.to_path_buf())
            .display()
            .to_string(),
    );
    result.priors_used = Some(use_prior);
    result
}

/// `--report`: the HTML report of the calibration.
fn html_report(
    report_dir: &Path,
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    cal: &Calibration,
    result: &CalibrationResult,
    session: &Session,
) -> anyhow::Result<PathBuf> {
    let noise = NoiseBand::of_fit(result.noise_model.as_ref(), &opts.sigma_z);
    // one series per IMU, each under its own parameters (docs/model.md §9)
    let layout = cal.layout(robot);
    let k = layout.n_imus();
    let series = (0..k)
        .map(|j| {
            super::report::session_series(
                robot,
                &data.only_imu(j),
                &layout.imu_x(j, &cal.x),
                &opts.sigma_q,
                Some(cal.knot_spacing),
                &noise,
            )
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let costs = ConvergenceLog::from_summary(&cal.summary).costs();
    Ok(calibration_report_imus(
        report_dir,
        result,
        session.truth.as_ref(),
        Convergence::Costs(&costs),
        &series,
    )?)
}

/// `--effects`: the baseline plus the effects from the calibration's x,
/// printed and written to effects.json next to the result file.
fn fit_effects(
    out: &mut impl Write,
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    set: &EffectSet,
    cal: &Calibration,
    path: &Path,
) -> anyhow::Result<()> {
    let progress = Progress::start(format!("fitting with {}", set.names().join(", ")));
    let f = effects_fit(robot, data, opts, set, cal, path);
    progress.finish();
    let (f, epath) = f?;
    writeln!(out)?;
    write!(out, "{}", EffectEstimates(&f))?;
    writeln!(out, "wrote {}", epath.display())?;
    Ok(())
}

/// The fit of `--effects` from the calibration's x, written to effects.json
/// next to the result file `path`; returns the fit and effects.json's path.
pub(crate) fn effects_fit(
    robot: &Robot,
    data: &Measurements,
    opts: &CalibrateOptions,
    set: &EffectSet,
    cal: &Calibration,
    path: &Path,
) -> anyhow::Result<(Fit, PathBuf)> {
    let spec = FitSpec {
        robot,
        data,
        effects: set,
        start: Start::At(&cal.x),
    };
    let f = fit(&spec, opts, |_| {})
        .with_context(|| format!("--effects: cannot fit {}", set.names().join(", ")))?;
    let epath = path.with_file_name("effects.json");
    let json = fit_json(&ParamLayout::with_imus(robot, f.n_imus), &f);
    std::fs::write(&epath, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("cannot write {}", epath.display()))?;
    Ok((f, epath))
}

/// `--windows`: calibrate each window and compare with the full calibration.
fn calibrate_windows(
    robot: &Robot,
    opts: &CalibrateOptions,
    windows: Vec<Window>,
    full: Calibration,
    dir: &Path,
) -> anyhow::Result<Repeatability> {
    let count = windows.len();
    let progress = Progress::start(format!("calibrating {count} windows"));
    let results = repeatability::calibrate_windows(robot, windows, opts, |w, r| {
        progress.set_message(format!(
            "window {} of {count}: iteration {}, cost {:.6e}",
            w + 1,
            r.iteration,
            r.cost
        ));
    });
    progress.finish();
    let results = results.with_context(|| format!("--windows {count}: {}", dir.display()))?;
    Ok(repeatability::compare(
        &ParamLayout::new(robot),
        full,
        results,
    ))
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
