//! A production batch as `robimu calibrate-batch` runs it: each session
//! with the result file it is to get ([`jobs`]), each calibrated as
//! `robimu calibrate` does ([`calibrate_job`]), on [`crate::batch::run_queue`].

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

use super::calibration::{Fitted, Prepared, Settings};
use super::input::load_session;
use super::noise_spec::NoiseFileArg;
use crate::batch::summary::{imu_parameter_names, SessionOutcome};
use crate::batch::{Entry, Outcome};

/// A session of a batch with the result file it is to get.
#[derive(Debug, Clone)]
pub struct Job {
    /// The session as the command line named it.
    pub entry: Entry,
    /// Its result.json.
    pub result: PathBuf,
}

/// Each session with its result file: in its directory, or under
/// `results/NAME/` (created); refused when two sessions would share one,
/// or a result file exists and `force` is not set.
pub fn jobs(entries: Vec<Entry>, results: Option<&Path>, force: bool) -> anyhow::Result<Vec<Job>> {
    if let Some(dir) = results {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--results: cannot create {}", dir.display()))?;
    }
    let mut jobs: Vec<Job> = Vec::new();
    for entry in entries {
        let result = match results {
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
    if !force && !existing.is_empty() {
        bail!(
            "{} of the sessions already have a result file (first: {}): pass --force to overwrite them, or --results DIR to write elsewhere",
            existing.len(),
            existing[0].result.display()
        );
    }
    Ok(jobs)
}

/// One session of a batch: read, calibrated as `robimu calibrate` does, its
/// result files written; the pre-flight check's warnings go to `warn`; a
/// panic is caught and reported as a failure.
pub fn calibrate_job(
    job: &Job,
    settings: &Settings,
    file: Option<&NoiseFileArg>,
    warn: impl Fn(String),
) -> SessionOutcome {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        calibrate_one(job, settings, file, warn)
    }))
    .unwrap_or_else(|p| {
        let why = p
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        failed(&job.entry.dir, format!("internal error (panic): {why}"))
    })
}

fn calibrate_one(
    job: &Job,
    settings: &Settings,
    file: Option<&NoiseFileArg>,
    warn: impl Fn(String),
) -> SessionOutcome {
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
    let p = match Prepared::new(session, robot, settings, file, warn) {
        Ok(p) => p,
        Err(e) => return failed(dir, format!("{:#}", anyhow::Error::from(e))),
    };
    let imu_parameters = imu_parameter_names(&p.layout);
    let outcome = (|| -> anyhow::Result<Outcome> {
        let fitted: Fitted = p.fit(|_| {})?;
        if let Some(parent) = job.result.parent() {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("cannot create {}", parent.display()))?;
        }
        fitted.write(&job.result)?;
        p.write_effects(&fitted, &job.result)?;
        Ok(Outcome::Calibrated(Box::new(fitted.result)))
    })()
    .unwrap_or_else(|e| Outcome::Failed(format!("{e:#}")));
    SessionOutcome {
        dir: dir.clone(),
        outcome,
        imu_parameters,
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
