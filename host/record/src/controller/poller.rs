//! Joint samples read in a thread: the loop, the channel and the stop that
//! the AUBO and UR pollers share ([`super::aubo::JointPoller`],
//! [`super::ur::UrPoller`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::thread::{self, JoinHandle};

use super::JointSample;

/// One controller's side of a [`Poller`].
pub(crate) trait Source: Send + 'static {
    /// What the poller hands back when stopped.
    type Client: Send + 'static;
    /// Why reading failed.
    type Error: Send + 'static;
    /// Reads the next sample (blocking).
    fn read(&mut self) -> Result<JointSample, Self::Error>;
    /// Runs after each sample is handed on (a fixed-rate poller waits).
    fn after_sample(&mut self) {}
    /// Once stopped (not after an error): the client, if still usable.
    fn finish(self) -> Option<Self::Client>;
}

/// Reads joint samples in a thread; samples, then at most one error (after
/// which reading stops), arrive on [`Poller::samples`].
pub struct Poller<C, E> {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Option<C>>>,
    rx: Receiver<Result<JointSample, E>>,
}

impl<C: Send + 'static, E: Send + 'static> Poller<C, E> {
    /// Starts reading from `source` on a thread named `name`.
    pub(crate) fn start<S>(name: &str, mut source: S) -> std::io::Result<Self>
    where
        S: Source<Client = C, Error = E>,
    {
        let (tx, rx) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = thread::Builder::new().name(name.into()).spawn(move || {
            while !flag.load(Ordering::SeqCst) {
                match source.read() {
                    Ok(s) => {
                        if tx.send(Ok(s)).is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        let _ = tx.send(Err(e));
                        return None;
                    }
                }
                source.after_sample();
            }
            source.finish()
        })?;
        Ok(Poller {
            stop,
            thread: Some(thread),
            rx,
        })
    }
}

impl<C, E> Poller<C, E> {
    /// The samples (and a final error, if reading failed).
    pub fn samples(&self) -> &Receiver<Result<JointSample, E>> {
        &self.rx
    }

    /// Stops reading; returns the client (unless reading failed, or the
    /// controller's own stopping step did) and the channel, which still
    /// holds the samples not yet received.
    #[allow(clippy::type_complexity)]
    pub fn stop(mut self) -> (Option<C>, Receiver<Result<JointSample, E>>) {
        self.stop.store(true, Ordering::SeqCst);
        let client = self.thread.take().and_then(|t| t.join().ok()).flatten();
        let (_, empty) = mpsc::channel();
        (client, std::mem::replace(&mut self.rx, empty))
    }

    /// Stops reading without waiting for the thread, which may be blocked
    /// on a controller that no longer answers (it ends by itself once its
    /// read times out); returns the channel, which still holds the samples
    /// not yet received.
    pub fn abandon(mut self) -> Receiver<Result<JointSample, E>> {
        self.stop.store(true, Ordering::SeqCst);
        drop(self.thread.take());
        let (_, empty) = mpsc::channel();
        std::mem::replace(&mut self.rx, empty)
    }
}

impl<C, E> Drop for Poller<C, E> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
