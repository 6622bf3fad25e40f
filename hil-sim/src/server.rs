//! What the simulated controllers ([`crate::aubo`], [`crate::ur`]) share as
//! TCP servers: the clock, a stop flag, the simulation thread, one thread
//! per accepted connection, and shutting down by joining every thread.

use std::io::{ErrorKind, Read};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use robimu_controller_wire::Pacer;

use crate::arm::MAX_STEP_S;

/// Locks a mutex, recovering the data if a thread panicked holding it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The state every simulated controller's threads share.
pub(crate) struct Core {
    /// The clock's zero.
    pub(crate) epoch: Instant,
    /// Set to stop every thread.
    stop: AtomicBool,
    /// The threads serving accepted connections.
    connections: Mutex<Vec<JoinHandle<()>>>,
}

impl Core {
    /// Running, with its clock's zero at `epoch`.
    pub(crate) fn new(epoch: Instant) -> Self {
        Core {
            epoch,
            stop: AtomicBool::new(false),
            connections: Mutex::new(Vec::new()),
        }
    }

    /// Seconds since the epoch.
    pub(crate) fn now(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    /// Whether the simulator is stopping.
    pub(crate) fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}

/// A simulator's shared state, as a server.
pub(crate) trait Server: Send + Sync + 'static {
    /// Its clock, stop flag and connections.
    fn core(&self) -> &Core;
}

/// Binds a non-blocking listener on `addr`; the address it got.
pub(crate) fn listen(addr: SocketAddr) -> std::io::Result<(TcpListener, SocketAddr)> {
    let l = TcpListener::bind(addr)?;
    let local = l.local_addr()?;
    l.set_nonblocking(true)?;
    Ok((l, local))
}

/// A started simulator's shared state and threads; dropping it stops
/// every thread and closes every connection.
pub(crate) struct Running<S: Server> {
    pub(crate) shared: Arc<S>,
    threads: Vec<JoinHandle<()>>,
}

impl<S: Server> Running<S> {
    /// No thread started yet.
    pub(crate) fn new(shared: S) -> Self {
        Running {
            shared: Arc::new(shared),
            threads: Vec::new(),
        }
    }

    /// Starts a thread named `name` running `f` on the shared state.
    pub(crate) fn start(
        &mut self,
        name: &str,
        f: impl FnOnce(&Arc<S>) + Send + 'static,
    ) -> std::io::Result<()> {
        let shared = Arc::clone(&self.shared);
        let handle = thread::Builder::new()
            .name(name.into())
            .spawn(move || f(&shared))?;
        self.threads.push(handle);
        Ok(())
    }
}

impl<S: Server> Drop for Running<S> {
    fn drop(&mut self) {
        shutdown(&*self.shared, &mut self.threads);
    }
}

/// The simulation thread: every [`MAX_STEP_S`] until the stop flag is set,
/// `advance(t)` with `t` the time since the epoch.
pub(crate) fn simulation_loop(core: &Core, mut advance: impl FnMut(f64)) {
    let mut pacer = Pacer::new(Duration::from_secs_f64(MAX_STEP_S));
    while !core.stopped() {
        pacer.wait();
        advance(core.now());
    }
}

/// What one read from a connection with a read timeout gave.
pub(crate) enum Received {
    /// This many bytes, at the start of the read buffer.
    Bytes(usize),
    /// Nothing yet (timeout or interrupted): check the stop flag, read again.
    Nothing,
    /// The peer closed its side (end of stream).
    Closed,
    /// The connection broke.
    Broken,
}

/// Reads once from `stream` into `chunk`.
pub(crate) fn receive(stream: &mut TcpStream, chunk: &mut [u8]) -> Received {
    match stream.read(chunk) {
        Ok(0) => Received::Closed,
        Ok(n) => Received::Bytes(n),
        Err(e)
            if matches!(
                e.kind(),
                ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
            ) =>
        {
            Received::Nothing
        }
        Err(_) => Received::Broken,
    }
}

/// Accepts connections on the non-blocking `listener` until the stop flag is
/// set, serving each with `serve` on a thread named `name`.
pub(crate) fn accept_loop<S: Server>(
    listener: &TcpListener,
    shared: &Arc<S>,
    name: &str,
    serve: fn(TcpStream, &S),
) {
    while !shared.core().stopped() {
        match listener.accept() {
            Ok((stream, _)) => {
                let conn = Arc::clone(shared);
                let spawned = thread::Builder::new()
                    .name(name.into())
                    .spawn(move || serve(stream, &conn));
                if let Ok(handle) = spawned {
                    lock(&shared.core().connections).push(handle);
                }
            }
            Err(_) => thread::sleep(Duration::from_millis(5)),
        }
    }
}

/// Sets the stop flag and joins `threads`, then every connection's thread.
fn shutdown<S: Server>(shared: &S, threads: &mut Vec<JoinHandle<()>>) {
    let core = shared.core();
    core.stop.store(true, Ordering::SeqCst);
    for t in threads.drain(..) {
        let _ = t.join();
    }
    let connections = std::mem::take(&mut *lock(&core.connections));
    for c in connections {
        let _ = c.join();
    }
}
