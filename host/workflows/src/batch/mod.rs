//! Production batches (`robimu calibrate-batch`, issue 16): many sessions,
//! each calibrated as `robimu calibrate` does, on a work queue over several
//! threads; one [`summary`] row per session and IMU, checked against the
//! user's [`limits`].

pub mod limits;
pub mod summary;

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use robimu_session::result::CalibrationResult;

/// The files whose presence makes a directory a session directory.
pub(crate) const SESSION_FILES: [&str; 3] = ["session.toml", "joints.csv", "imu.csv"];

/// One session of a batch as the command line names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// The session directory.
    pub dir: PathBuf,
    /// Why it is not a session directory (reported as unreadable).
    pub problem: Option<String>,
}

/// How one session of a batch ended.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// Calibrated: the result file's contents.
    Calibrated(Box<CalibrationResult>),
    /// Read, but the calibration failed (the error's text).
    Failed(String),
    /// The session could not be read (the error's text).
    Unreadable(String),
}

/// Whether `dir` holds any of the [`SESSION_FILES`].
fn is_session_dir(dir: &Path) -> bool {
    SESSION_FILES.iter().any(|f| dir.join(f).is_file())
}

/// The sessions that `args` name, in order, each once: a directory holding
/// a session file ([`SESSION_FILES`]) is a session; a directory without one
/// is a parent, whose subdirectories holding a session file are its
/// sessions (by name); a parent without any, or a path that is no
/// directory, is an entry with its problem.
pub fn session_entries(args: &[PathBuf]) -> Vec<Entry> {
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    let mut push = |dir: PathBuf, problem: Option<String>| {
        let key = std::fs::canonicalize(&dir).unwrap_or_else(|_| dir.clone());
        if seen.insert(key) {
            out.push(Entry { dir, problem });
        }
    };
    for arg in args {
        if !arg.exists() {
            push(arg.clone(), Some("no such directory".into()));
        } else if !arg.is_dir() {
            push(arg.clone(), Some("not a directory".into()));
        } else if is_session_dir(arg) {
            push(arg.clone(), None);
        } else {
            let mut subs: Vec<PathBuf> = match std::fs::read_dir(arg) {
                Ok(rd) => rd
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.is_dir() && is_session_dir(p))
                    .collect(),
                Err(e) => {
                    push(arg.clone(), Some(format!("cannot list the directory: {e}")));
                    continue;
                }
            };
            if subs.is_empty() {
                push(
                    arg.clone(),
                    Some(format!(
                        "not a session directory: no {} in it or in its subdirectories",
                        SESSION_FILES.join(", ")
                    )),
                );
            }
            subs.sort();
            for s in subs {
                push(s, None);
            }
        }
    }
    out
}

/// `work` applied to every item by `jobs` threads (at least 1, at most one
/// per item), each taking the next item from a shared queue until none is
/// left; the results in the items' order.
///
/// # Panics
/// When `work` panics.
pub fn run_queue<T: Sync, R: Send>(
    items: &[T],
    jobs: usize,
    work: impl Fn(&T) -> R + Sync,
) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<R>>> = items.iter().map(|_| Mutex::new(None)).collect();
    let jobs = jobs.clamp(1, items.len().max(1));
    std::thread::scope(|s| {
        for _ in 0..jobs {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                let r = work(item);
                *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
            });
        }
    });
    slots
        .into_iter()
        .map(|m| {
            m.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every item ran")
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;
    use std::time::Duration;

    #[test]
    fn queue_runs_every_item_once_in_order_on_several_threads() {
        let items: Vec<usize> = (0..40).collect();
        let threads = Mutex::new(HashMap::new());
        let out = run_queue(&items, 3, |&i| {
            std::thread::sleep(Duration::from_millis(2));
            *threads
                .lock()
                .unwrap()
                .entry(std::thread::current().id())
                .or_insert(0) += 1;
            i * i
        });
        assert_eq!(out, items.iter().map(|i| i * i).collect::<Vec<_>>());
        let threads = threads.into_inner().unwrap();
        assert_eq!(threads.len(), 3, "{threads:?}");
        assert_eq!(threads.values().sum::<usize>(), 40);
        // more jobs than items, and no items
        assert_eq!(run_queue(&[7], 8, |&i: &i32| i + 1), vec![8]);
        assert!(run_queue(&[] as &[i32], 0, |&i| i).is_empty());
    }

    #[test]
    fn entries_are_sessions_parents_children_or_problems() {
        let root = tempfile::tempdir().unwrap();
        let mk = |p: &str, file: Option<&str>| {
            let d = root.path().join(p);
            std::fs::create_dir_all(&d).unwrap();
            if let Some(f) = file {
                std::fs::write(d.join(f), "").unwrap();
            }
            d
        };
        let s1 = mk("lot/s1", Some("session.toml"));
        let s2 = mk("lot/s2", Some("imu.csv"));
        mk("lot/figures", None);
        let alone = mk("alone", Some("session.toml"));
        let empty = mk("empty", None);
        let file = root.path().join("lot/notes.txt");
        std::fs::write(&file, "").unwrap();
        let lot = root.path().join("lot");
        let missing = root.path().join("missing");
        let got = session_entries(&[
            lot.clone(),
            alone.clone(),
            s1.clone(),
            empty.clone(),
            file.clone(),
            missing.clone(),
        ]);
        let dirs: Vec<&Path> = got.iter().map(|e| e.dir.as_path()).collect();
        assert_eq!(dirs, [&s1, &s2, &alone, &empty, &file, &missing]);
        let problems: Vec<Option<&str>> = got.iter().map(|e| e.problem.as_deref()).collect();
        assert_eq!(problems[..3], [None, None, None]);
        assert!(problems[3].unwrap().contains("not a session directory"));
        assert_eq!(problems[4], Some("not a directory"));
        assert_eq!(problems[5], Some("no such directory"));
    }
}
