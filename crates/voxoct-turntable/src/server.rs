//! The turntable server: the program on the Pi serves one [`Turntable`]
//! over TCP with the `VOXOCT-TT/1` protocol.

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::protocol::{
    LineEvent, LineReader, MAX_LINE_LEN, PROTOCOL, PROTOCOL_PREFIX, Reply, Request,
    close_gracefully, constant_time_eq, validate_token, write_line,
};
use crate::{ErrorCode, Turntable, TurntableError};

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
    pub fn shutdown(mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(h) = self.accept.take() {
            let _ = h.join();
        }
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
/// `ERR BUSY` (it may retry later). See the crate docs for the protocol.
///
/// # Errors
/// [`TurntableError::Config`] for an invalid token or zero
/// `max_connections`, [`TurntableError::Io`] when the listener cannot be
/// set up.
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
        .spawn(move || accept_loop(&listener, &for_loop))
        .map_err(|e| TurntableError::io("spawning the accept thread", e))?;
    Ok(ServerHandle {
        addr,
        shared,
        accept: Some(accept),
    })
}

fn accept_loop(listener: &TcpListener, shared: &Arc<Shared>) {
    let mut workers: Vec<JoinHandle<()>> = Vec::new();
    let mut next_id: u64 = 0;
    while !shared.stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, peer)) => {
                workers.retain(|w| !w.is_finished());
                if shared.connections.load(Ordering::SeqCst) >= shared.config.max_connections
                    && !evict_one_pending(shared)
                {
                    shared.log(peer, "refused: too many connections");
                    refuse_now(stream);
                    continue;
                }
                next_id += 1;
                let id = next_id;
                if let Ok(handle) = stream.try_clone() {
                    lock(&shared.pending).push((id, peer, handle));
                }
                // Released when the thread ends, however it ends (also by a panic).
                let slot = Slot {
                    shared: Arc::clone(shared),
                    id,
                };
                shared.connections.fetch_add(1, Ordering::SeqCst);
                let spawned = std::thread::Builder::new()
                    .name("voxoct-tt-conn".into())
                    .spawn(move || {
                        handle_connection(stream, peer, &slot.shared, id);
                        drop(slot);
                    });
                if let Ok(h) = spawned {
                    workers.push(h);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(ACCEPT_TICK);
            }
            // Transient accept errors (aborted connection, out of file
            // descriptors): back off and keep serving.
            Err(_) => std::thread::sleep(ACCEPT_TICK * 5),
        }
    }
    for w in workers {
        let _ = w.join();
    }
}

/// A connection's place in the count, given back on drop.
struct Slot {
    shared: Arc<Shared>,
    id: u64,
}

impl Drop for Slot {
    fn drop(&mut self) {
        lock(&self.shared.pending).retain(|(id, _, _)| *id != self.id);
        self.shared.connections.fetch_sub(1, Ordering::SeqCst);
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Closes the oldest connection still in its handshake, from the address
/// with the most such connections; `false` when there is none.
fn evict_one_pending(shared: &Shared) -> bool {
    let mut pending = lock(&shared.pending);
    let count = |ip: std::net::IpAddr| pending.iter().filter(|(_, p, _)| p.ip() == ip).count();
    let Some(ip) = pending
        .iter()
        .map(|(_, p, _)| p.ip())
        .max_by_key(|&ip| count(ip))
    else {
        return false;
    };
    let Some(i) = pending.iter().position(|(_, p, _)| p.ip() == ip) else {
        return false;
    };
    let (_, peer, stream) = pending.remove(i);
    shared.log(peer, "evicted: still no handshake and the server is full");
    let _ = stream.shutdown(std::net::Shutdown::Both);
    true
}

fn refuse_now(mut stream: TcpStream) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_write_timeout(Some(Duration::from_millis(100)));
    let reply = Reply::Err {
        code: ErrorCode::Busy,
        message: "too many connections; try again later".into(),
    };
    let _ = write_line(&mut stream, &reply.to_line());
    close_gracefully(&mut stream, Duration::from_millis(20));
}

/// Clears the session flag when the session ends, however it ends.
struct SessionGuard<'a>(&'a AtomicBool);

impl Drop for SessionGuard<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::SeqCst);
    }
}

fn handle_connection(mut stream: TcpStream, peer: SocketAddr, shared: &Shared, id: u64) {
    let cfg = &shared.config;
    if stream.set_nonblocking(false).is_err()
        || stream.set_write_timeout(Some(cfg.write_timeout)).is_err()
    {
        return;
    }
    let _ = stream.set_nodelay(true);
    let mut reader = LineReader::default();

    // --- handshake ---
    let deadline = Instant::now() + cfg.handshake_timeout;
    let event = match reader.read_line(&mut stream, deadline, Some(&shared.stop)) {
        Ok(e) => e,
        Err(_) => return,
    };
    let line = match event {
        LineEvent::Line(l) => l,
        LineEvent::TooLong => {
            return fail(&mut stream, ErrorCode::TooLong, &too_long_msg());
        }
        LineEvent::NotUtf8 => {
            return fail(&mut stream, ErrorCode::BadRequest, "handshake is not UTF-8");
        }
        LineEvent::TimedOut => {
            shared.log(peer, "no handshake in time");
            let msg = format!("no handshake within {:?}", cfg.handshake_timeout);
            return fail(&mut stream, ErrorCode::Timeout, &msg);
        }
        LineEvent::Eof | LineEvent::Stopped => return,
    };
    // Past the handshake line: no longer evictable.
    lock(&shared.pending).retain(|(i, _, _)| *i != id);
    if let Err((code, msg)) = check_handshake(&line, cfg.token.as_deref()) {
        shared.log(peer, &format!("handshake refused: {code}"));
        if code == ErrorCode::Unauthorised {
            std::thread::sleep(UNAUTHORISED_DELAY);
        }
        return fail(&mut stream, code, &msg);
    }
    if shared
        .session_active
        .compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst)
        .is_err()
    {
        shared.log(peer, "refused: another session is open");
        return fail(
            &mut stream,
            ErrorCode::Busy,
            "another client is using the turntable; try again when it disconnects",
        );
    }
    // Dropped before any final reply and linger, so the table is free again
    // at once.
    let session = SessionGuard(&shared.session_active);
    if write_line(&mut stream, &Reply::Ok(PROTOCOL.into()).to_line()).is_err() {
        return;
    }
    shared.log(peer, "session opened");

    // --- requests ---
    loop {
        let deadline = Instant::now() + cfg.idle_timeout;
        let event = match reader.read_line(&mut stream, deadline, Some(&shared.stop)) {
            Ok(e) => e,
            Err(_) => break,
        };
        let reply = match event {
            LineEvent::Line(line) => match Request::parse(&line) {
                Err(msg) => Reply::Err {
                    code: ErrorCode::BadRequest,
                    message: msg,
                },
                Ok(Request::Quit) => {
                    drop(session);
                    let _ = write_line(&mut stream, &Reply::Ok("BYE".into()).to_line());
                    close_gracefully(&mut stream, LINGER);
                    break;
                }
                Ok(req) => {
                    // A failing turntable (even a panicking one) gets an ERR reply.
                    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(shared, req)))
                        .unwrap_or_else(|panic| {
                            let what = panic
                                .downcast_ref::<&str>()
                                .map(|s| (*s).to_string())
                                .or_else(|| panic.downcast_ref::<String>().cloned())
                                .unwrap_or_else(|| "unknown failure".into());
                            shared.log(peer, &format!("request failed: {what}"));
                            Reply::Err {
                                code: ErrorCode::Internal,
                                message: format!("the turntable failed: {what}"),
                            }
                        })
                }
            },
            LineEvent::NotUtf8 => Reply::Err {
                code: ErrorCode::BadRequest,
                message: "request is not UTF-8".into(),
            },
            LineEvent::TooLong => {
                shared.log(peer, "line too long; closing");
                drop(session);
                fail(&mut stream, ErrorCode::TooLong, &too_long_msg());
                break;
            }
            LineEvent::TimedOut => {
                let msg = format!("idle for {:?}; closing", cfg.idle_timeout);
                drop(session);
                fail(&mut stream, ErrorCode::Timeout, &msg);
                break;
            }
            LineEvent::Stopped => {
                drop(session);
                fail(&mut stream, ErrorCode::Internal, "server shutting down");
                break;
            }
            LineEvent::Eof => break,
        };
        if write_line(&mut stream, &reply.to_line()).is_err() {
            shared.log(peer, "client gone before the reply");
            break;
        }
    }
    shared.log(peer, "session closed");
}

fn too_long_msg() -> String {
    format!("line longer than {MAX_LINE_LEN} bytes; closing the connection")
}

fn fail(stream: &mut TcpStream, code: ErrorCode, msg: &str) {
    let reply = Reply::Err {
        code,
        message: msg.to_string(),
    };
    let _ = write_line(stream, &reply.to_line());
    close_gracefully(stream, LINGER);
}

fn check_handshake(line: &str, token: Option<&str>) -> Result<(), (ErrorCode, String)> {
    let mut words = line.split_ascii_whitespace();
    let version = words.next().unwrap_or("");
    if !version.starts_with(PROTOCOL_PREFIX) {
        return Err((
            ErrorCode::BadRequest,
            format!("expected the handshake '{PROTOCOL} [<token>]'"),
        ));
    }
    if version != PROTOCOL {
        let shown: String = version.chars().take(32).collect();
        return Err((
            ErrorCode::Version,
            format!("this server speaks {PROTOCOL}, the client sent {shown}"),
        ));
    }
    let given = words.next();
    if words.next().is_some() {
        return Err((
            ErrorCode::BadRequest,
            format!("the handshake is '{PROTOCOL} [<token>]' (too many words)"),
        ));
    }
    if let Some(expected) = token {
        let ok = given.is_some_and(|g| constant_time_eq(g.as_bytes(), expected.as_bytes()));
        if !ok {
            return Err((
                ErrorCode::Unauthorised,
                "missing or wrong token".to_string(),
            ));
        }
    }
    Ok(())
}

fn execute(shared: &Shared, req: Request) -> Reply {
    let cfg = &shared.config;
    // A panic inside a turntable poisons the lock; the position is still the
    // best we know, so keep serving.
    let mut table = shared.table.lock().unwrap_or_else(PoisonError::into_inner);
    let result = match req {
        Request::Rotate { degrees, timeout } => {
            let timeout = timeout
                .unwrap_or(cfg.default_rotate_timeout)
                .min(cfg.max_rotate_timeout);
            table.rotate_by(degrees, timeout).map(|d| d.to_string())
        }
        Request::Angle => table.angle_deg().map(|d| d.to_string()),
        Request::Home => table.home().map(|()| "0".to_string()),
        Request::Ping => Ok("PONG".to_string()),
        Request::Quit => Ok("BYE".to_string()),
    };
    match result {
        Ok(v) => Reply::Ok(v),
        Err(e) => Reply::error(&e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handshake_rules() {
        assert!(check_handshake("VOXOCT-TT/1", None).is_ok());
        assert!(check_handshake("VOXOCT-TT/1 anything", None).is_ok());
        assert!(check_handshake("VOXOCT-TT/1 tok", Some("tok")).is_ok());
        let code = |l: &str, t: Option<&str>| check_handshake(l, t).unwrap_err().0;
        assert_eq!(code("VOXOCT-TT/1", Some("tok")), ErrorCode::Unauthorised);
        assert_eq!(
            code("VOXOCT-TT/1 tok2", Some("tok")),
            ErrorCode::Unauthorised
        );
        assert_eq!(code("VOXOCT-TT/2 tok", Some("tok")), ErrorCode::Version);
        assert_eq!(code("HELLO", None), ErrorCode::BadRequest);
        assert_eq!(code("VOXOCT-TT/1 a b", None), ErrorCode::BadRequest);
    }

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
}
