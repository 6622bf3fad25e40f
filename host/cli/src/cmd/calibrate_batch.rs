//! `robimu calibrate-batch`: production batches — many sessions calibrated
//! in parallel as `robimu calibrate` does, one summary CSV, pass/fail
//! against a limits file (docs/guide/calibrating.md "Production batches").

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use robimu_workflows::batch::limits::Limits;
use robimu_workflows::batch::summary::Summary;
use robimu_workflows::batch::{run_queue, session_entries, Outcome};
use robimu_workflows::pipeline::{self, calibrate_job};

use crate::args::CalibrateFlags;
use crate::input::output_path;

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
    /// (docs/guide/calibrating.md "Production batches").
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

impl CalibrateBatchCmd {
    /// Calibrate every session, write the summary, fail when a unit fails.
    pub fn run(self) -> anyhow::Result<()> {
        let limits = match &self.limits {
            Some(p) => Limits::from_file(p)?,
            None => Limits::default(),
        };
        let file = self.fit.noise_file()?;
        let settings = self.fit.settings()?;
        self.fit.resonance.mode()?;
        let summary_path = output_path(Some(&self.out), self.out.clone())?;
        let jobs = match self.jobs {
            Some(0) => bail!("--jobs must be at least 1"),
            Some(n) => n,
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        };
        let queue = pipeline::jobs(
            session_entries(&self.dirs),
            self.results.as_deref(),
            self.force,
        )?;

        let bar = progress_bar(queue.len());
        let started = Instant::now();
        let done = run_queue(&queue, jobs, |job| {
            let t = Instant::now();
            let outcome = calibrate_job(job, &settings, file.as_ref(), |w| {
                bar.suspend(|| eprintln!("warning: {w}"))
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
