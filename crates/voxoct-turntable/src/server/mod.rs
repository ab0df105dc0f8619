//! The turntable server: the program on the Pi serves one [`Turntable`]
//! over TCP with the `VOXOCT-TT/1` protocol.
//!
//! | file | what |
//! |---|---|
//! | `mod.rs` | [`ServerConfig`], [`serve`], [`ServerHandle`], [`StopSignal`] |
//! | `accept.rs` | the accept loop: connection limit, eviction of silent connections |
//! | `session.rs` | one connection: the handshake phase, then the request phase |

mod accept;
mod session;

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::protocol::validate_token;
use crate::{TOKEN_ENV, Turntable, TurntableError};

/// Server settings. Every wait has a limit, so no client can hold a thread
/// forever.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// Shared secret the client must present in the handshake; `None`
    /// accepts any client (only sensible on loopback).
    pub token: Option<String>,
    /// How long a new connection may take to send its handshake line.
    pub handshake_timeout: Duration,
    /// A session idle this long (no request) is closed.
    pub idle_timeout: Duration,
    /// Timeout of a `ROTATE` that gives none.
    pub default_rotate_timeout: Duration,
    /// Cap on the timeout a client may ask for.
    pub max_rotate_timeout: Duration,
    /// How long a reply may take to write before the client counts as gone.
    pub write_timeout: Duration,
    /// Most connections handled at once (the session plus clients still in
    /// their handshake). When they are all taken, a new connection evicts the
    /// oldest connection still in its handshake, taken from the address with
    /// the most of them (so idle or flooding clients cannot lock out a client
    /// with the token); only when none is in its handshake is it refused.
    pub max_connections: usize,
    /// Accept clients beyond loopback although there is no token. Off by
    /// default: [`serve`] refuses a listener on a non-loopback address
    /// without a token, since anyone who can reach the port could then turn
    /// the table.
    pub allow_network_without_token: bool,
    /// Print one line per connection event to stderr.
    pub verbose: bool,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            token: None,
            handshake_timeout: Duration::from_secs(3),
            idle_timeout: Duration::from_secs(600),
            default_rotate_timeout: Duration::from_secs(60),
            max_rotate_timeout: Duration::from_secs(600),
            write_timeout: Duration::from_secs(5),
            max_connections: 8,
            allow_network_without_token: false,
            verbose: false,
        }
    }
}

/// Delay before answering a wrong token, to slow down guessing.
const UNAUTHORISED_DELAY: Duration = Duration::from_millis(100);
/// How long to drain a closing connection.
const LINGER: Duration = Duration::from_millis(200);
/// Accept-loop polling interval.
const ACCEPT_TICK: Duration = Duration::from_millis(10);

struct Shared {
    table: Mutex<Box<dyn Turntable + Send>>,
    session_active: AtomicBool,
    connections: AtomicUsize,
    /// Connections still in their handshake: id, peer, a handle to close it.
    pending: Mutex<Vec<(u64, SocketAddr, TcpStream)>>,
    stop: AtomicBool,
    config: ServerConfig,
}

impl Shared {
    fn log(&self, peer: SocketAddr, msg: &str) {
        if self.config.verbose {
            eprintln!("voxoct-turntable: {peer}: {msg}");
        }
    }
}

/// A running server; [`ServerHandle::shutdown`] (or dropping the handle)
/// stops it.
pub struct ServerHandle {
    addr: SocketAddr,
    shared: Arc<Shared>,
    accept: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for ServerHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ServerHandle")
            .field("addr", &self.addr)
            .field("stopping", &self.shared.stop.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

/// A cloneable way to ask a server to stop from another thread (for
/// instance a signal handler thread), while the main thread is in
/// [`ServerHandle::join`].
#[derive(Clone)]
pub struct StopSignal(Arc<Shared>);

impl std::fmt::Debug for StopSignal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StopSignal").finish_non_exhaustive()
    }
}

impl StopSignal {
    /// Asks the server to stop; returns at once.
    pub fn stop(&self) {
        self.0.stop.store(true, Ordering::SeqCst);
    }
}

impl ServerHandle {
    /// The address the server listens on (useful after binding port 0).
    #[must_use]
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// A handle that can stop the server from elsewhere.
    #[must_use]
    pub fn stop_signal(&self) -> StopSignal {
        StopSignal(Arc::clone(&self.shared))
    }

    /// Stops accepting, closes idle sessions within ~250 ms, lets a turn in
    /// progress finish (bounded by its timeout), and waits for every thread.
    pub fn shutdown(self) {
        drop(self); // `Drop` stops the server and joins its threads.
    }

    /// Blocks until the server stops through a [`StopSignal`] (for a
    /// foreground program without one: forever).
    pub fn join(mut self) {
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
    }
}

/// Serves `table` on `listener` in background threads until the returned
/// handle is shut down or dropped.
///
/// One client at a time owns the table (a *session*): a second client that
/// completes the handshake while a session is open is refused with
/// `ERR BUSY` (it may retry later). See [`protocol`](crate::protocol) for
/// the protocol.
///
/// # Errors
/// [`TurntableError::Config`] for an invalid token, zero
/// `max_connections`, or a listener beyond loopback without a token (unless
/// [`ServerConfig::allow_network_without_token`]); [`TurntableError::Io`]
/// when the listener cannot be set up.
pub fn serve<T>(
    listener: TcpListener,
    table: T,
    config: ServerConfig,
) -> Result<ServerHandle, TurntableError>
where
    T: Turntable + Send + 'static,
{
    if let Some(t) = &config.token {
        validate_token(t)?;
    }
    if config.max_connections == 0 {
        return Err(TurntableError::Config(
            "max_connections: must be at least 1".into(),
        ));
    }
    let addr = listener
        .local_addr()
        .map_err(|e| TurntableError::io("reading the listening address", e))?;
    if !addr.ip().is_loopback() && config.token.is_none() && !config.allow_network_without_token {
        return Err(TurntableError::Config(format!(
            "listening on {addr} without a token would let anyone who reaches the port turn \
             the table. How to fix: set a token (turntable_server: --token or {TOKEN_ENV}), \
             or allow it explicitly (ServerConfig::allow_network_without_token; \
             turntable_server: --insecure)"
        )));
    }
    listener
        .set_nonblocking(true)
        .map_err(|e| TurntableError::io("setting the listener non-blocking", e))?;
    let shared = Arc::new(Shared {
        table: Mutex::new(Box::new(table)),
        session_active: AtomicBool::new(false),
        connections: AtomicUsize::new(0),
        pending: Mutex::new(Vec::new()),
        stop: AtomicBool::new(false),
        config,
    });
    let for_loop = Arc::clone(&shared);
    let accept = std::thread::Builder::new()
        .name("voxoct-tt-accept".into())
        .spawn(move || accept::accept_loop(&listener, &for_loop))
        .map_err(|e| TurntableError::io("spawning the accept thread", e))?;
    Ok(ServerHandle {
        addr,
        shared,
        accept: Some(accept),
    })
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_config_is_refused() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let cfg = ServerConfig {
            token: Some("has space".into()),
            ..ServerConfig::default()
        };
        let r = serve(l, crate::SimulatedTurntable::default(), cfg);
        assert!(matches!(r, Err(TurntableError::Config(_))));
    }

    #[test]
    fn the_network_without_a_token_is_refused_unless_allowed() {
        let l = TcpListener::bind("0.0.0.0:0").unwrap();
        let err = serve(
            l,
            crate::SimulatedTurntable::default(),
            ServerConfig::default(),
        )
        .unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, TurntableError::Config(_)), "{msg}");
        assert!(
            msg.contains("0.0.0.0:") && msg.contains("without a token"),
            "{msg}"
        );
        for cfg in [
            ServerConfig {
                token: Some("s3cret".into()),
                ..ServerConfig::default()
            },
            ServerConfig {
                allow_network_without_token: true,
                ..ServerConfig::default()
            },
        ] {
            let l = TcpListener::bind("0.0.0.0:0").unwrap();
            let handle = serve(l, crate::SimulatedTurntable::default(), cfg).unwrap();
            handle.shutdown();
        }
        // Loopback needs no token.
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        serve(
            l,
            crate::SimulatedTurntable::default(),
            ServerConfig::default(),
        )
        .unwrap()
        .shutdown();
    }
}
