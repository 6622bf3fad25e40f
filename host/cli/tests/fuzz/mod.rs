//! The mutation harness: seeded inputs through [`mutate`](mutate::mutate)
//! into each reader of [`targets`], in-process, every call timed and its
//! panic caught.
//!
//! An input is a directory written under `CARGO_TARGET_TMPDIR/fuzz-work`;
//! if the process dies on one (a stack overflow or an abort cannot be
//! caught), it is still there. Panics and slow calls are copied with a
//! `finding.txt` (target, seed, mutations, message) to
//! `CARGO_TARGET_TMPDIR/fuzz-findings`. A call still running after
//! [`Budget::abort_after`] ends the process with its input named.

pub mod mutate;
pub mod targets;

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use targets::Target;

/// A call slower than this is reported as a hang.
pub const SLOW: Duration = Duration::from_secs(2);

/// How long and how much to fuzz.
#[derive(Debug, Clone)]
pub struct Budget {
    /// The RNG seed of the campaign.
    pub seed: u64,
    /// Stop after this long…
    pub time: Duration,
    /// …or after this many inputs.
    pub inputs: usize,
    /// A call running this long ends the process (a hang).
    pub abort_after: Duration,
    /// Only the targets whose name contains this.
    pub only: Option<String>,
    /// The process-level mode: run this `robimu` program on each input
    /// (the targets that have a command), instead of calling the reader.
    /// A run still going after [`Self::abort_after`] is killed and
    /// counted as a hang; one killed by a signal or that printed a panic
    /// is a panic; a non-zero exit must come with an `error: ` line.
    pub process: Option<PathBuf>,
}

/// How one input ended.
enum Outcome {
    /// Read (exit 0).
    Ok,
    /// Refused with this message (the error line of the program).
    Refused(String),
    /// Panicked, or the program was killed by a signal.
    Panic(String),
    /// The program was still running after the limit and was killed.
    Hung,
}

/// Runs `bin` with `args`, killed after `limit`.
fn run_command(bin: &Path, args: &[String], limit: Duration) -> Outcome {
    use std::process::{Command, Stdio};
    let err_path = std::env::temp_dir().join(format!("robimu-fuzz-{}.err", std::process::id()));
    let err = std::fs::File::create(&err_path).unwrap();
    let mut child = Command::new(bin)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(err)
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = std::fs::read(&err_path).unwrap_or_default();
    let stderr = String::from_utf8_lossy(&stderr);
    let Some(status) = status else {
        return Outcome::Hung;
    };
    if let Some(line) = stderr.lines().find(|l| l.contains("panicked at")) {
        return Outcome::Panic(line.to_string());
    }
    if status.success() {
        return Outcome::Ok;
    }
    if status.code().is_none() {
        return Outcome::Panic(format!("killed by a signal ({status})"));
    }
    match stderr.find("error: ") {
        Some(k) => Outcome::Refused(stderr[k..].trim().to_string()),
        None => Outcome::Refused(String::new()),
    }
}

/// What happened to one target's inputs.
#[derive(Debug, Clone, Default)]
pub struct Counts {
    /// Inputs fed.
    pub inputs: usize,
    /// Read without error.
    pub ok: usize,
    /// Refused with a message.
    pub errors: usize,
    /// Refused with an empty message.
    pub silent_errors: usize,
    /// Panicked.
    pub panics: usize,
    /// Accepted, but what they produced is refused by the project's own
    /// reader (a silently invalid result).
    pub accepted_invalid: usize,
    /// Took longer than [`SLOW`].
    pub slow: usize,
    /// The longest call.
    pub longest: Duration,
    /// Distinct refusal messages (their first 160 characters on one line,
    /// the input's directory left out), up to 1000.
    pub messages: std::collections::BTreeSet<String>,
}

impl Counts {
    /// Findings: panics, slow calls, silent or invalid acceptances.
    pub fn findings(&self) -> usize {
        self.panics + self.slow + self.silent_errors + self.accepted_invalid
    }

    fn add(&mut self, o: &Counts) {
        self.inputs += o.inputs;
        self.ok += o.ok;
        self.errors += o.errors;
        self.silent_errors += o.silent_errors;
        self.panics += o.panics;
        self.accepted_invalid += o.accepted_invalid;
        self.slow += o.slow;
        self.longest = self.longest.max(o.longest);
    }
}

/// The panic message a reader wrapper raises when a reader accepted what
/// the project's own reader then refuses.
pub const ACCEPTED_INVALID: &str = "accepted what the session reader refuses";

/// The input being read, for the watchdog.
struct Current {
    since: Instant,
    what: String,
}

/// Runs the campaign: round-robin over the targets, each input a random
/// seed of the target with one to three mutations. Returns each target's
/// counts and the findings' directories.
pub fn campaign(budget: &Budget) -> (Vec<(&'static str, Counts)>, Vec<PathBuf>) {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let work = tmp.join("fuzz-work");
    let found = tmp.join("fuzz-findings").join(budget.seed.to_string());
    let _ = std::fs::remove_dir_all(&work);
    let targets: Vec<Target> = targets::all()
        .into_iter()
        .filter(|t| {
            budget
                .only
                .as_ref()
                .is_none_or(|o| t.name.contains(o.as_str()))
        })
        .filter(|t| budget.process.is_none() || t.command.is_some())
        .collect();
    assert!(!targets.is_empty(), "no target matches {:?}", budget.only);
    // each seed written once; an input rewrites only its mutated file
    for (ti, t) in targets.iter().enumerate() {
        for (si, s) in t.seeds.iter().enumerate() {
            write_seed(&input_dir(&work, ti, si), s, None);
        }
    }
    let current: Arc<Mutex<Option<Current>>> = Arc::new(Mutex::new(None));
    {
        let current = Arc::clone(&current);
        let limit = budget.abort_after;
        std::thread::spawn(move || loop {
            std::thread::sleep(Duration::from_millis(250));
            if let Some(c) = current.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
                if c.since.elapsed() > limit {
                    eprintln!("HANG: a call has run {limit:?}: {}", c.what);
                    std::process::exit(3);
                }
            }
        });
    }
    let panic_message: Arc<Mutex<Option<String>>> = Arc::new(Mutex::new(None));
    let hook = std::panic::take_hook();
    {
        let slot = Arc::clone(&panic_message);
        std::panic::set_hook(Box::new(move |info| {
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let at = info.location().map(|l| l.to_string()).unwrap_or_default();
            *slot.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!("{msg} at {at}"));
        }));
    }
    let mut rng = StdRng::seed_from_u64(budget.seed);
    let mut counts: Vec<Counts> = vec![Counts::default(); targets.len()];
    let mut findings = Vec::new();
    let start = Instant::now();
    let mut n = 0;
    while n < budget.inputs && start.elapsed() < budget.time {
        let ti = n % targets.len();
        n += 1;
        let t = &targets[ti];
        let si = rng.random_range(0..t.seeds.len());
        let seed = &t.seeds[si];
        let fi = seed.mutable[rng.random_range(0..seed.mutable.len())];
        let mut bytes = seed.files[fi].1.clone();
        let how = mutate::mutate(&mut rng, &mut bytes);
        let dir = input_dir(&work, ti, si);
        if t.rewrites {
            write_seed(&dir, seed, Some((fi, &bytes)));
        } else {
            std::fs::write(dir.join(&seed.files[fi].0), &bytes).unwrap();
        }
        let what = format!(
            "{} on seed {} with {} of {} ({})",
            t.name,
            seed.label,
            how.join(" + "),
            seed.files[fi].0,
            dir.display()
        );
        let t0 = Instant::now();
        let outcome = match (&budget.process, t.command) {
            (Some(bin), Some(command)) => {
                let out = dir.with_extension("out");
                let o = run_command(bin, &command(&dir, &out), budget.abort_after);
                let _ = std::fs::remove_dir_all(&out);
                o
            }
            _ => {
                *panic_message.lock().unwrap() = None;
                *current.lock().unwrap() = Some(Current {
                    since: Instant::now(),
                    what: what.clone(),
                });
                let r = std::panic::catch_unwind(AssertUnwindSafe(|| (t.read)(&dir)));
                *current.lock().unwrap() = None;
                let caught = panic_message.lock().unwrap().take();
                match (r, caught) {
                    (Err(_), msg) => Outcome::Panic(msg.unwrap_or_default()),
                    // a panic the library caught itself (a thread joined, a
                    // third-party reader isolated): still a panic on stderr
                    (Ok(_), Some(msg)) => {
                        Outcome::Panic(format!("caught inside the reader: {msg}"))
                    }
                    (Ok(Ok(())), None) => Outcome::Ok,
                    (Ok(Err(e)), None) => Outcome::Refused(e),
                }
            }
        };
        let took = t0.elapsed();
        let c = &mut counts[ti];
        c.inputs += 1;
        c.longest = c.longest.max(took);
        let finding = match outcome {
            Outcome::Ok => {
                c.ok += 1;
                None
            }
            Outcome::Refused(e) if e.trim().is_empty() => {
                c.silent_errors += 1;
                Some("refused with an empty message".to_string())
            }
            Outcome::Refused(e) => {
                c.errors += 1;
                if c.messages.len() < 1000 {
                    // the message without the input's directory
                    let e = e
                        .replace(&format!("{}/", dir.display()), "")
                        .replace('\n', " | ");
                    c.messages.insert(e.chars().take(160).collect());
                }
                None
            }
            Outcome::Panic(msg) => {
                if msg.contains(ACCEPTED_INVALID) {
                    c.accepted_invalid += 1;
                } else {
                    c.panics += 1;
                }
                Some(format!("panic: {msg}"))
            }
            Outcome::Hung => {
                c.slow += 1;
                Some(format!(
                    "still running after {:?}: killed",
                    budget.abort_after
                ))
            }
        };
        let finding = finding.or_else(|| {
            (budget.process.is_none() && took > SLOW).then(|| {
                c.slow += 1;
                format!("took {took:?}")
            })
        });
        if let Some(why) = finding {
            let keep = found.join(format!("{}-{}", ti, n));
            write_seed(&keep, seed, Some((fi, &bytes)));
            std::fs::write(keep.join("finding.txt"), format!("{what}\n{why}\n")).unwrap();
            eprintln!("FINDING: {what}: {why}");
            findings.push(keep);
        }
        // the next input of this seed starts from the seed's file
        if !t.rewrites {
            std::fs::write(dir.join(&seed.files[fi].0), &seed.files[fi].1).unwrap();
        }
    }
    std::panic::set_hook(hook);
    (
        targets.iter().map(|t| t.name).zip(counts).collect(),
        findings,
    )
}

fn input_dir(work: &Path, target: usize, seed: usize) -> PathBuf {
    work.join(format!("t{target}")).join(format!("s{seed}"))
}

/// Writes `seed`'s files into `dir` (emptied first), file `fi` as `bytes`
/// when given.
fn write_seed(dir: &Path, seed: &targets::Seed, replace: Option<(usize, &[u8])>) {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).unwrap();
    for (i, (name, bytes)) in seed.files.iter().enumerate() {
        let b = match replace {
            Some((fi, m)) if fi == i => m,
            _ => bytes,
        };
        std::fs::write(dir.join(name), b).unwrap();
    }
}

/// The campaign's table: one row per target and the total.
pub fn table(counts: &[(&'static str, Counts)], elapsed: Duration, seed: u64) -> String {
    let mut out = format!(
        "fuzz campaign seed {seed}, {:.1} s\n{:<36} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>9} {:>8}\n",
        elapsed.as_secs_f64(),
        "target",
        "inputs",
        "ok",
        "errors",
        "panics",
        "silent",
        ">2 s",
        "longest",
        "messages"
    );
    let mut total = Counts::default();
    let row = |name: &str, c: &Counts, distinct: String| {
        format!(
            "{:<36} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>7.0}ms {:>8}\n",
            name,
            c.inputs,
            c.ok,
            c.errors,
            c.panics,
            c.silent_errors + c.accepted_invalid,
            c.slow,
            c.longest.as_secs_f64() * 1e3,
            distinct
        )
    };
    for (name, c) in counts {
        out.push_str(&row(name, c, c.messages.len().to_string()));
        total.add(c);
    }
    out.push_str(&row("total", &total, String::new()));
    out
}
