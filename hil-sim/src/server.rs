//! What the simulated controllers ([`crate::aubo`], [`crate::ur`]) share as
//! TCP servers: a stop flag, one thread per accepted connection, and
//! shutting down by joining every thread.

use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::{self, JoinHandle};
use std::time::Duration;

/// Locks a mutex, recovering the data if a thread panicked holding it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A simulator's shared state, as a server.
pub(crate) trait Server: Send + Sync + 'static {
    /// Set to stop every thread.
    fn stop_flag(&self) -> &AtomicBool;
    /// The threads serving accepted connections.
    fn connections(&self) -> &Mutex<Vec<JoinHandle<()>>>;
}

/// Accepts connections on the non-blocking `listener` until the stop flag is
/// set, serving each with `serve` on a thread named `name`.
pub(crate) fn accept_loop<S: Server>(
    listener: &TcpListener,
    shared: &Arc<S>,
    name: &str,
    serve: fn(TcpStream, &S),
) {
    while !shared.stop_flag().load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, _)) => {
                let conn = Arc::clone(shared);
                let spawned = thread::Builder::new()
                    .name(name.into())
                    .spawn(move || serve(stream, &conn));
                if let Ok(handle) = spawned {
                    lock(shared.connections()).push(handle);
                }
            }
            Err(_) => thread::sleep(Duration::from_millis(5)),
        }
    }
}

/// Sets the stop flag and joins `threads`, then every connection's thread.
pub(crate) fn shutdown<S: Server>(shared: &S, threads: &mut Vec<JoinHandle<()>>) {
    shared.stop_flag().store(true, Ordering::SeqCst);
    for t in threads.drain(..) {
        let _ = t.join();
    }
    let connections = std::mem::take(&mut *lock(shared.connections()));
    for c in connections {
        let _ = c.join();
    }
}
