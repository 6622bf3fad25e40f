//! `robimu calibrate-batch`: production batches — many sessions calibrated
//! in parallel as `robimu calibrate` does, one summary CSV, pass/fail
//! against a limits file (README "Production batches").

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_workflows::batch::limits::Limits;
use robimu_workflows::batch::summary::{imu_parameter_names, SessionOutcome, Summary};
use robimu_workflows::batch::{run_queue, session_entries, Entry, Outcome};

use super::calibrate::{effects_fit, write_result, CalibrateFlags, Fitted};
use super::input::{load_session, output_path};
use super::noise_spec::NoiseFileArg;

/// Calibrate many sessions in parallel (production batches).
///
/// Each session is calibrated exactly as `robimu calibrate` does with the
/// same flags, its result.json (and NAME.convergence.csv, effects.json)
/// written into its directory or under `--results`; one summary CSV row per
/// session and IMU: status (ok, failed, unreadable, with the error), the
/// IMU's parameters with their σ, the residual RMS, the solver's
/// termination and pass/fail against `--limits`. A failed or unreadable
/// session is reported and does not stop the batch; the exit status is
/// non-zero when any unit fails or any session is unreadable.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateBatchCmd {
    /// Session directories, or directories whose subdirectories are
    /// sessions (a shell glob's expansion is fine).
    #[arg(required = true, value_name = "DIR")]
    pub dirs: Vec<PathBuf>,
    /// Limits every unit must meet: a TOML file with one `[limits]` table
    /// (README "Production batches").
    #[arg(long, value_name = "FILE")]
    pub limits: Option<PathBuf>,
    /// The summary CSV to write.
    #[arg(long, value_name = "FILE", default_value = "summary.csv")]
    pub out: PathBuf,
    /// Sessions calibrated at once [default: the available cores].
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Write each session's result files into DIR/NAME/ (NAME: the session
    /// directory's name) instead of the session directory.
    #[arg(long, value_name = "DIR")]
    pub results: Option<PathBuf>,
    /// Overwrite existing result files (refused otherwise, before any
    /// session is calibrated).
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub fit: CalibrateFlags,
}

/// A session with the result file it is to get.
struct Job {
    entry: Entry,
    result: PathBuf,
}

impl CalibrateBatchCmd {
    /// Calibrate every session, write the summary, fail when a unit fails.
    pub fn run(self) -> anyhow::Result<()> {
        let limits = match &self.limits {
            Some(p) => Limits::from_file(p)?,
            None => Limits::default(),
        };
        let file = self.fit.noise_file()?;
        self.fit.settle()?;
        self.fit.resonance.mode()?;
        let summary_path = output_path(Some(&self.out), self.out.clone())?;
        let jobs = match self.jobs {
            Some(0) => bail!("--jobs must be at least 1"),
            Some(n) => n,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        let queue = self.jobs_of(session_entries(&self.dirs))?;

        let bar = progress_bar(queue.len());
        let started = Instant::now();
        let done = run_queue(&queue, jobs, |job| {
            let t = Instant::now();
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                self.calibrate_one(job, file.as_ref())
            }))
            .unwrap_or_else(|p| {
                let why = p
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| p.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                failed(&job.entry.dir, format!("internal error (panic): {why}"))
            });
            let status = match &outcome.outcome {
                Outcome::Calibrated(_) => "ok",
                Outcome::Failed(_) => "failed",
                Outcome::Unreadable(_) => "unreadable",
            };
            let line = format!(
                "{status:<10} {} ({:.1} s)",
                job.entry.dir.display(),
                t.elapsed().as_secs_f64()
            );
            bar.suspend(|| println!("{line}"));
            bar.inc(1);
            outcome
        });
        bar.finish_and_clear();
        let elapsed = started.elapsed().as_secs_f64();

        let summary = Summary::new(&done, &limits);
        summary
            .write_csv(&summary_path)
            .with_context(|| format!("cannot write {}", summary_path.display()))?;
        let (over, failed, unreadable) = summary.counts();
        let rows = summary.rows.len();
        println!(
            "{} of {rows} units pass; {over} outside the limits, {failed} failed to calibrate, {unreadable} unreadable ({} sessions in {elapsed:.1} s on {} jobs)",
            rows - over - failed - unreadable,
            queue.len(),
            jobs.min(queue.len().max(1))
        );
        println!("wrote {}", summary_path.display());
        if over + failed + unreadable > 0 {
            bail!(
                "{} of {rows} units did not pass (see {})",
                over + failed + unreadable,
                summary_path.display()
            );
        }
        Ok(())
    }

    /// Each session with its result file; refused when two sessions would
    /// share one, or a result file exists and `--force` is not given.
    fn jobs_of(&self, entries: Vec<Entry>) -> anyhow::Result<Vec<Job>> {
        if let Some(dir) = &self.results {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("--results: cannot create {}", dir.display()))?;
        }
        let mut jobs: Vec<Job> = Vec::new();
        for entry in entries {
            let result = match &self.results {
                None => entry.dir.join("result.json"),
                Some(dir) => {
                    let name = std::path::absolute(&entry.dir)
                        .ok()
                        .and_then(|p| p.file_name().map(|n| n.to_owned()))
                        .unwrap_or_else(|| "session".into());
                    dir.join(name).join("result.json")
                }
            };
            if entry.problem.is_none() {
                if let Some(other) = jobs
                    .iter()
                    .find(|j| j.entry.problem.is_none() && j.result == result)
                {
                    bail!(
                        "--results: the sessions {} and {} would both write {}",
                        other.entry.dir.display(),
                        entry.dir.display(),
                        result.display()
                    );
                }
            }
            jobs.push(Job { entry, result });
        }
        let existing: Vec<&Job> = jobs
            .iter()
            .filter(|j| j.entry.problem.is_none() && j.result.exists())
            .collect();
        if !self.force && !existing.is_empty() {
            bail!(
                "{} of the sessions already have a result file (first: {}): pass --force to overwrite them, or --results DIR to write elsewhere",
                existing.len(),
                existing[0].result.display()
            );
        }
        Ok(jobs)
    }

    /// One session: read, calibrated as `robimu calibrate` does, its
    /// result files written.
    fn calibrate_one(&self, job: &Job, file: Option<&NoiseFileArg>) -> SessionOutcome {
        let dir = &job.entry.dir;
        let unreadable = |e: String| SessionOutcome {
            dir: dir.clone(),
            outcome: Outcome::Unreadable(e),
            imu_parameters: Vec::new(),
        };
        if let Some(problem) = &job.entry.problem {
            return unreadable(problem.clone());
        }
        let (session, robot) = match load_session(dir) {
            Ok(s) => s,
            Err(e) => return unreadable(format!("{e:#}")),
        };
        let p = match self.fit.prepare(dir, session, robot, file) {
            Ok(p) => p,
            Err(e) => return failed(dir, format!("{e:#}")),
        };
        let imu_parameters = imu_parameter_names(&p.layout);
        let outcome = (|| -> anyhow::Result<Outcome> {
            let Fitted { cal, result, .. } = self.fit.fit_prepared(&p, dir, |_| {})?;
            if let Some(parent) = job.result.parent() {
                std::fs::create_dir_all(parent)
                    .with_context(|| format!("cannot create {}", parent.display()))?;
            }
            write_result(&result, &cal, &job.result)?;
            if let Some(set) = &p.effects {
                effects_fit(&p.robot, &p.data, &p.opts, set, &cal, &job.result)?;
            }
            Ok(Outcome::Calibrated(Box::new(result)))
        })()
        .unwrap_or_else(|e| Outcome::Failed(format!("{e:#}")));
        SessionOutcome {
            dir: dir.clone(),
            outcome,
            imu_parameters,
        }
    }
}

/// A session that failed to calibrate.
fn failed(dir: &Path, why: String) -> SessionOutcome {
    SessionOutcome {
        dir: dir.to_path_buf(),
        outcome: Outcome::Failed(why),
        imu_parameters: Vec::new(),
    }
}

/// The bar over the sessions (hidden when stderr is no terminal).
fn progress_bar(n: usize) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(n as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} sessions  {elapsed} elapsed, {eta} left",
        )
        .expect("valid template"),
    );
    bar
}
