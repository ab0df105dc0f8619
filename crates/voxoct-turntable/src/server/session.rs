//! One connection: the handshake phase, which claims the session, then the
//! request phase.

use std::net::{SocketAddr, TcpStream};
use std::sync::PoisonError;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use super::{LINGER, Shared, UNAUTHORISED_DELAY, lock};
use crate::ErrorCode;
use crate::protocol::{
    LineEvent, LineReader, MAX_LINE_LEN, PROTOCOL, PROTOCOL_PREFIX, Reply, Request,
    close_gracefully, constant_time_eq, write_line,
};

/// Clears the session flag when the session ends, however it ends.
struct SessionGuard<'a>(&'a AtomicBool);

impl Drop for SessionGuard<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::SeqCst);
    }
}

/// Serves one connection in its phases: set the socket up, the handshake
/// (which claims the session), then requests until the session ends.
pub(super) fn handle_connection(mut stream: TcpStream, peer: SocketAddr, shared: &Shared, id: u64) {
    if stream.set_nonblocking(false).is_err()
        || stream
            .set_write_timeout(Some(shared.config.write_timeout))
            .is_err()
    {
        return;
    }
    let _ = stream.set_nodelay(true);
    let mut reader = LineReader::default();
    if let Some(session) = handshake(&mut stream, &mut reader, peer, shared, id) {
        serve_requests(&mut stream, &mut reader, peer, shared, session);
    }
}

/// The handshake phase: reads the first line within
/// [`ServerConfig::handshake_timeout`](super::ServerConfig::handshake_timeout),
/// checks version and token, claims the session and answers
/// `OK VOXOCT-TT/1`. `None` (after an `ERR` reply where one is due) when the
/// connection does not get a session.
fn handshake<'a>(
    stream: &mut TcpStream,
    reader: &mut LineReader,
    peer: SocketAddr,
    shared: &'a Shared,
    id: u64,
) -> Option<SessionGuard<'a>> {
    let cfg = &shared.config;
    let deadline = Instant::now() + cfg.handshake_timeout;
    let line = match reader
        .read_line(stream, deadline, Some(&shared.stop))
        .ok()?
    {
        LineEvent::Line(l) => l,
        LineEvent::TooLong => {
            fail(stream, ErrorCode::TooLong, &too_long_msg());
            return None;
        }
        LineEvent::NotUtf8 => {
            fail(stream, ErrorCode::BadRequest, "handshake is not UTF-8");
            return None;
        }
        LineEvent::TimedOut => {
            shared.log(peer, "no handshake in time");
            let msg = format!("no handshake within {:?}", cfg.handshake_timeout);
            fail(stream, ErrorCode::Timeout, &msg);
            return None;
        }
        LineEvent::Eof | LineEvent::Stopped => return None,
    };
    // Past the handshake line: no longer evictable.
    lock(&shared.pending).retain(|(i, _, _)| *i != id);
    if let Err((code, msg)) = check_handshake(&line, cfg.token.as_deref()) {
        shared.log(peer, &format!("handshake refused: {code}"));
        if code == ErrorCode::Unauthorised {
            std::thread::sleep(UNAUTHORISED_DELAY);
        }
        fail(stream, code, &msg);
        return None;
    }
    if shared
        .session_active
        .compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst)
        .is_err()
    {
        shared.log(peer, "refused: another session is open");
        fail(
            stream,
            ErrorCode::Busy,
            "another client is using the turntable; try again when it disconnects",
        );
        return None;
    }
    // Dropped before any final reply and linger, so the table is free again
    // at once.
    let session = SessionGuard(&shared.session_active);
    write_line(stream, &Reply::Ok(PROTOCOL.into()).to_line()).ok()?;
    shared.log(peer, "session opened");
    Some(session)
}

/// The request phase: one request, one reply, until `QUIT`, the idle
/// timeout, a line too long, shutdown or the client leaving. The session
/// (`session`) is released before the last reply is lingered over.
fn serve_requests(
    stream: &mut TcpStream,
    reader: &mut LineReader,
    peer: SocketAddr,
    shared: &Shared,
    session: SessionGuard<'_>,
) {
    let cfg = &shared.config;
    loop {
        let deadline = Instant::now() + cfg.idle_timeout;
        let Ok(event) = reader.read_line(stream, deadline, Some(&shared.stop)) else {
            break;
        };
        let reply = match event {
            LineEvent::Line(line) => match Request::parse(&line) {
                Err(e) => Reply::Err {
                    code: ErrorCode::BadRequest,
                    message: e.to_string(),
                },
                Ok(Request::Quit) => {
                    drop(session);
                    let _ = write_line(stream, &Reply::Ok("BYE".into()).to_line());
                    close_gracefully(stream, LINGER);
                    break;
                }
                Ok(req) => execute_caught(shared, peer, req),
            },
            LineEvent::NotUtf8 => Reply::Err {
                code: ErrorCode::BadRequest,
                message: "request is not UTF-8".into(),
            },
            LineEvent::TooLong => {
                shared.log(peer, "line too long; closing");
                drop(session);
                fail(stream, ErrorCode::TooLong, &too_long_msg());
                break;
            }
            LineEvent::TimedOut => {
                let msg = format!("idle for {:?}; closing", cfg.idle_timeout);
                drop(session);
                fail(stream, ErrorCode::Timeout, &msg);
                break;
            }
            LineEvent::Stopped => {
                drop(session);
                fail(stream, ErrorCode::Internal, "server shutting down");
                break;
            }
            LineEvent::Eof => break,
        };
        if write_line(stream, &reply.to_line()).is_err() {
            shared.log(peer, "client gone before the reply");
            break;
        }
    }
    shared.log(peer, "session closed");
}

/// Executes a request; a failing turntable (even a panicking one) gets an
/// `ERR INTERNAL` reply.
fn execute_caught(shared: &Shared, peer: SocketAddr, req: Request) -> Reply {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| execute(shared, req))).unwrap_or_else(
        |panic| {
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
        },
    )
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
}
