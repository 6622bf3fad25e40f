//! Two-way fork–join: [`join`] runs one closure on the calling thread and
//! the other on a helper thread that waits *actively* for its next job.
//!
//! The calibration alternates short serial steps (a factorisation, a
//! set-up: 1–3 ms) with two-way parallel ones (a linearisation's two
//! halves). A thread spawned — or a parked one woken — after such a step
//! finds the other core halted, and on a virtual machine waking a halted
//! core is the hypervisor's business: on the project's 2-core machine a
//! thread spawned after a 2–4 ms serial step started 1.2–2.9 ms later, as
//! long as the step itself (issue 18, docs/performance.md). The helper
//! here keeps its core awake instead: after a job it polls for the next
//! one for [`SPIN`] before it parks (what OpenMP runtimes do between
//! parallel regions), so a `join` made shortly after the last one starts
//! at once. The poll is a plain load loop (a loop of `pause` makes KVM's
//! pause-loop exiting take the core away) that yields to any other thread
//! ready on its core between rounds.
//!
//! One helper serves the process; a `join` while it is busy (a `join`
//! from another thread, or nested in one) runs its second closure on a
//! scoped thread of its own instead, as does every `join` when the helper
//! cannot be started. A panic in either closure is re-raised in the caller
//! after both have finished.

use std::cell::UnsafeCell;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicPtr, Ordering};
use std::sync::OnceLock;
use std::thread::{self, Thread};
use std::time::{Duration, Instant};

/// How long the helper polls for a next job before it parks.
pub(crate) const SPIN: Duration = Duration::from_millis(4);

/// `(a(), b())`, `b` on the helper thread (module doc).
pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA,
    B: FnOnce() -> RB + Send,
    RB: Send,
{
    let helper = match Helper::get() {
        Some(h)
            if h.busy
                .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
                .is_ok() =>
        {
            h
        }
        _ => {
            return thread::scope(|s| {
                let h = s.spawn(b);
                let ra = a();
                (ra, h.join().unwrap_or_else(|p| resume_unwind(p)))
            })
        }
    };
    let job = StackJob {
        f: UnsafeCell::new(Some(b)),
        result: UnsafeCell::new(None),
        done: AtomicBool::new(false),
        caller: thread::current(),
    };
    let raw = RawJob {
        data: &job as *const StackJob<B, RB> as *const (),
        run: StackJob::<B, RB>::run,
    };
    helper.post(raw);
    let ra = catch_unwind(AssertUnwindSafe(a));
    // `job` lives on this stack: wait for the helper before anything else
    job.wait();
    helper.busy.store(false, Ordering::Release);
    // SAFETY: `done` (acquire) says the helper wrote the result and no
    // longer touches `job`.
    let rb = unsafe { (*job.result.get()).take() }.expect("the helper ran the job");
    match (ra, rb) {
        (Ok(ra), Ok(rb)) => (ra, rb),
        (Err(p), _) | (_, Err(p)) => resume_unwind(p),
    }
}

/// A job on the caller's stack: the closure, then its result.
struct StackJob<B, RB> {
    f: UnsafeCell<Option<B>>,
    result: UnsafeCell<Option<thread::Result<RB>>>,
    done: AtomicBool,
    caller: Thread,
}

impl<B: FnOnce() -> RB, RB> StackJob<B, RB> {
    /// Run the job behind `data` (a `StackJob<B, RB>`), on the helper.
    ///
    /// # Safety
    /// `data` points to a live `StackJob<B, RB>` whose caller waits for
    /// `done`, and this is called once.
    unsafe fn run(data: *const ()) {
        // SAFETY: the caller's contract.
        let job = unsafe { &*(data as *const Self) };
        // SAFETY: only this call touches `f` and `result` until `done`.
        let f = unsafe { (*job.f.get()).take() }.expect("a job runs once");
        let r = catch_unwind(AssertUnwindSafe(f));
        unsafe { *job.result.get() = Some(r) };
        let caller = job.caller.clone();
        // after this store the caller may free `job`
        job.done.store(true, Ordering::Release);
        caller.unpark();
    }

    /// Wait until the helper has run the job: poll, then park.
    fn wait(&self) {
        wait_for(|| self.done.load(Ordering::Acquire));
    }
}

/// Return once `ready()`: poll it for up to [`SPIN`], then park between
/// looks (whoever makes it true unparks this thread).
fn wait_for(ready: impl Fn() -> bool) {
    let start = Instant::now();
    while !ready() {
        if !poll(&ready, start) {
            thread::park();
        }
    }
}

/// Poll `ready` until [`SPIN`] after `start`: whether it became true.
fn poll(ready: &impl Fn() -> bool, start: Instant) -> bool {
    loop {
        for _ in 0..4096 {
            if ready() {
                return true;
            }
        }
        if start.elapsed() > SPIN {
            return ready();
        }
        // let another thread of this core run (a scoped thread of a
        // `join` made while the helper is busy, another process)
        thread::yield_now();
    }
}

/// A type-erased [`StackJob`].
struct RawJob {
    data: *const (),
    run: unsafe fn(*const ()),
}

/// The helper thread and its mailbox.
struct Helper {
    /// Held by the one `join` the helper serves.
    busy: AtomicBool,
    /// The posted job (null: none); a `Box<RawJob>`.
    job: AtomicPtr<RawJob>,
    thread: Thread,
}

impl Helper {
    /// The process's helper, started at the first call (`None` when no
    /// thread can be started).
    fn get() -> Option<&'static Helper> {
        static HELPER: OnceLock<Option<&'static Helper>> = OnceLock::new();
        *HELPER.get_or_init(|| {
            let (tx, rx) = std::sync::mpsc::channel::<&'static Helper>();
            let handle = thread::Builder::new()
                .name("robimu-pair".into())
                .spawn(move || {
                    if let Ok(helper) = rx.recv() {
                        helper.serve();
                    }
                })
                .ok()?;
            let helper: &'static Helper = Box::leak(Box::new(Helper {
                busy: AtomicBool::new(false),
                job: AtomicPtr::new(std::ptr::null_mut()),
                thread: handle.thread().clone(),
            }));
            tx.send(helper).ok()?;
            Some(helper)
        })
    }

    fn post(&self, job: RawJob) {
        let old = self
            .job
            .swap(Box::into_raw(Box::new(job)), Ordering::AcqRel);
        debug_assert!(old.is_null(), "one job at a time");
        self.thread.unpark();
    }

    fn serve(&self) -> ! {
        loop {
            wait_for(|| !self.job.load(Ordering::Acquire).is_null());
            // only this thread takes jobs: the one seen is still there
            let job = self.job.swap(std::ptr::null_mut(), Ordering::AcqRel);
            // SAFETY: posted by `join`, which waits for the job to finish.
            let job = unsafe { Box::from_raw(job) };
            unsafe { (job.run)(job.data) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_closures_run_with_their_borrows() {
        let v: Vec<u64> = (0..1000).collect();
        let (lo, hi) = v.split_at(500);
        for _ in 0..200 {
            let (a, b) = join(|| lo.iter().sum::<u64>(), || hi.iter().sum::<u64>());
            assert_eq!(a + b, 499_500);
        }
    }

    #[test]
    fn nested_and_concurrent_joins_fall_back_to_a_thread() {
        let (a, b) = join(|| join(|| 1, || 2), || join(|| 3, || 4));
        assert_eq!((a, b), ((1, 2), (3, 4)));
        let results: Vec<(u32, u32)> = thread::scope(|s| {
            let hs: Vec<_> = (0..4u32)
                .map(|k| s.spawn(move || join(|| k, || k * 10)))
                .collect();
            hs.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert_eq!(results, [(0, 0), (1, 10), (2, 20), (3, 30)]);
    }

    #[test]
    fn a_panic_in_the_helpers_closure_reaches_the_caller() {
        let r = catch_unwind(|| join(|| 1, || -> u32 { panic!("boom") }));
        assert!(r.is_err());
        // the helper still serves
        assert_eq!(join(|| 5, || 6), (5, 6));
    }

    #[test]
    fn a_join_after_the_helper_parked_still_runs() {
        assert_eq!(join(|| 1, || 2), (1, 2));
        thread::sleep(SPIN * 3);
        assert_eq!(join(|| 3, || 4), (3, 4));
    }
}
