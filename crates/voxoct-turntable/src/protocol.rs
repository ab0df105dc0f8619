//! The `VOXOCT-TT/1` wire protocol: its specification, constants, request
//! and reply lines (and, inside the crate, a bounded line reader).
//!
//! The Pi runs the server ([`serve`](crate::serve)); the scanning host
//! connects as the client ([`RemoteTurntable`](crate::RemoteTurntable)).
//! (The thesis used Lidgren over UDP; this is TCP.) The protocol is
//! line-based text, so it can be spoken from any language, or typed into
//! `nc`:
//!
//! * **Transport**: one TCP connection; default port 7878. Every message is
//!   one line of UTF-8 text ending in `\n` (a `\r` before it is ignored), at
//!   most [`MAX_LINE_LEN`] = 256 bytes including the `\n`. Words
//!   are separated by single spaces (the server accepts any ASCII
//!   whitespace). Numbers are decimal (`-45`, `0.45`, `1e2`), in degrees;
//!   timeouts are whole milliseconds.
//! * **Handshake**: the client's first line is `VOXOCT-TT/1` or
//!   `VOXOCT-TT/1 <token>` (the token: 1–128 printable ASCII bytes without
//!   spaces). The server answers `OK VOXOCT-TT/1` and the session starts, or
//!   answers an error and closes the connection: `ERR VERSION ...` when the
//!   client names another version `VOXOCT-TT/<n>`, `ERR UNAUTHORISED ...`
//!   when the server has a token and the client's is missing or wrong
//!   (compared in constant time, answered after a 100 ms delay),
//!   `ERR BUSY ...` when another client's session is open, `ERR BAD_REQUEST
//!   ...` for anything else, `ERR TIMEOUT ...` after 3 s without a
//!   handshake.
//! * **Requests** (one at a time; the client waits for each reply):
//!
//!   | request | reply | meaning |
//!   |---|---|---|
//!   | `ROTATE <degrees> [<timeout_ms>]` | `OK <degrees turned>` | turn by a signed angle (positive = forward), at most 3600° in magnitude; blocks until the turn is done; the reply is the angle really turned (whole microsteps). `timeout_ms` in 1..=3600000, default 60000, capped by the server (600000) |
//!   | `ANGLE` | `OK <degrees>` | current angle in `[0, 360)` |
//!   | `HOME` | `OK 0` | declare the current position to be 0° (no motion) |
//!   | `PING` | `OK PONG` | liveness check |
//!   | `QUIT` | `OK BYE` | end the session; the server closes |
//!
//! * **Errors**: `ERR <code> <message>`, the message free text to the end
//!   of the line. Codes ([`ErrorCode`]): `BAD_REQUEST` (malformed line,
//!   unknown command, bad argument, not UTF-8 — the connection stays open),
//!   `TOO_LONG` (a line over 256 bytes; the server then closes the
//!   connection), `BAD_ANGLE` (non-finite or over 3600°), `TIMEOUT` (the
//!   turn cannot finish within its timeout: refused before moving when the
//!   planned ramp is too long; stopped where it is when it overruns — ask
//!   `ANGLE`), `HARDWARE`, `BUSY`, `UNAUTHORISED`, `VERSION`, `INTERNAL`
//!   (also sent when the server shuts down; it then closes).
//! * **Time limits** (the defaults of [`ServerConfig`](crate::ServerConfig)):
//!   the server closes a session idle for 600 s and a connection silent for
//!   3 s before its handshake; it gives up writing a reply after 5 s.
//!   [`RemoteTurntable`](crate::RemoteTurntable) waits at most 5 s for a
//!   reply, or the turn's timeout plus 5 s for `ROTATE`
//!   ([`ClientTimeouts`](crate::ClientTimeouts)). When the server closes a
//!   session on its own (idle timeout, shutdown) it first sends one
//!   unsolicited `ERR` line; a client should therefore treat any line or EOF
//!   that arrives while it is idle as the end of the session (nothing it
//!   sends later would be executed). `RemoteTurntable` checks for this
//!   before each request and reconnects transparently.
//! * **One client at a time**: a second client is *refused* with `ERR BUSY`
//!   while a session is open (two scanning hosts turning one table would
//!   ruin both scans); it may retry once the first disconnects. At most 8
//!   connections are handled at once; when all are taken, a connection
//!   still silent in its handshake is closed to make room, and only when
//!   there is none does the newcomer get `ERR BUSY` at once.
//! * **Client gone mid-turn**: the turn completes (stopping a loaded table
//!   abruptly could make it skip), then the session ends and the table is
//!   free. **Server gone mid-turn**: the client sees the closed connection
//!   ([`TurntableError::Disconnected`]) or, if the Pi vanished silently,
//!   [`TurntableError::Timeout`] after the turn's timeout plus the margin —
//!   never a hang.
//!
//! A session, as typed into `nc pi.local 7878` (`>` client, `<` server):
//!
//! ```text
//! > VOXOCT-TT/1 s3cret
//! < OK VOXOCT-TT/1
//! > ROTATE 45 10000
//! < OK 45
//! > ROTATE 1
//! < OK 0.9
//! > ANGLE
//! < OK 45.9
//! > ROTATE x
//! < ERR BAD_REQUEST ROTATE: "x" is not a decimal number of degrees
//! > QUIT
//! < OK BYE
//! ```

use std::io::{self, Read, Write};
use std::net::{Shutdown, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::{ErrorCode, TurntableError};

/// The handshake word of this protocol version.
pub const PROTOCOL: &str = "VOXOCT-TT/1";
/// What every version's handshake word starts with.
pub const PROTOCOL_PREFIX: &str = "VOXOCT-TT/";
/// The longest line either side sends or accepts, in bytes, counting the
/// final `\n`.
pub const MAX_LINE_LEN: usize = 256;
/// The longest token, in bytes.
pub const MAX_TOKEN_LEN: usize = 128;
/// The default TCP port.
pub const DEFAULT_PORT: u16 = 7878;
/// The largest `timeout_ms` of a `ROTATE` request (one hour).
pub const MAX_TIMEOUT_MS: u64 = 3_600_000;

/// Checks that a token can travel in the handshake: 1 to
/// [`MAX_TOKEN_LEN`] bytes of printable ASCII without spaces.
///
/// # Errors
/// [`TurntableError::Config`] saying what is wrong (never echoing the token).
pub(crate) fn validate_token(token: &str) -> Result<(), TurntableError> {
    if token.is_empty() || token.len() > MAX_TOKEN_LEN {
        return Err(TurntableError::Config(format!(
            "token: must be 1 to {MAX_TOKEN_LEN} bytes long (it is {})",
            token.len()
        )));
    }
    if !token.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(TurntableError::Config(
            "token: only printable ASCII without spaces is allowed".into(),
        ));
    }
    Ok(())
}

/// Compares two byte strings in time that depends only on their lengths,
/// not on where they differ.
#[must_use]
pub(crate) fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    let mut diff = a.len() ^ b.len();
    for i in 0..a.len().max(b.len()) {
        let x = a.get(i).copied().unwrap_or(0);
        let y = b.get(i).copied().unwrap_or(0);
        diff |= usize::from(x ^ y);
    }
    std::hint::black_box(diff) == 0
}

/// A request from client to server, after the handshake.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// `ROTATE <degrees> [<timeout_ms>]`.
    Rotate {
        /// Signed angle, degrees (positive = forward).
        degrees: f64,
        /// How long the server may take, if given.
        timeout: Option<Duration>,
    },
    /// `ANGLE`.
    Angle,
    /// `HOME`.
    Home,
    /// `PING`.
    Ping,
    /// `QUIT`.
    Quit,
}

/// Why a request line was refused; sent as the message of a
/// `BAD_REQUEST` reply (the connection stays open).
///
/// How to fix: send one of the requests listed in the module docs, spelled
/// as shown there.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum RequestError {
    /// The line holds no word.
    #[error("empty request; expected ROTATE, ANGLE, HOME, PING or QUIT")]
    Empty,
    /// The first word is not a command (its first 32 characters).
    #[error("unknown command {0:?}; expected ROTATE, ANGLE, HOME, PING or QUIT")]
    UnknownCommand(String),
    /// `ROTATE` without an angle.
    #[error("ROTATE needs an angle: ROTATE <degrees> [<timeout_ms>]")]
    MissingAngle,
    /// The angle of `ROTATE` is not a decimal number.
    #[error("ROTATE: {0:?} is not a decimal number of degrees")]
    NotAnAngle(String),
    /// The timeout of `ROTATE` is not a whole number of milliseconds in
    /// `1..=`[`MAX_TIMEOUT_MS`].
    #[error(
        "ROTATE: timeout {0:?} must be a whole number of milliseconds in 1..={max}",
        max = MAX_TIMEOUT_MS
    )]
    BadTimeout(String),
    /// More words than the command takes (the command is named).
    #[error("too many arguments for {0}")]
    TooManyArguments(String),
}

impl Request {
    /// Parses one request line (without its `\n`).
    ///
    /// # Errors
    /// [`RequestError`] naming what is wrong; its text is the message of the
    /// `BAD_REQUEST` reply.
    pub fn parse(line: &str) -> Result<Self, RequestError> {
        let mut words = line.split_ascii_whitespace();
        let Some(cmd) = words.next() else {
            return Err(RequestError::Empty);
        };
        let req = match cmd {
            "ROTATE" => {
                let Some(deg) = words.next() else {
                    return Err(RequestError::MissingAngle);
                };
                let degrees: f64 = deg
                    .parse()
                    .map_err(|_| RequestError::NotAnAngle(deg.to_string()))?;
                let timeout = match words.next() {
                    None => None,
                    Some(ms) => {
                        let ms: u64 = ms
                            .parse()
                            .ok()
                            .filter(|ms| (1..=MAX_TIMEOUT_MS).contains(ms))
                            .ok_or_else(|| RequestError::BadTimeout(ms.to_string()))?;
                        Some(Duration::from_millis(ms))
                    }
                };
                Self::Rotate { degrees, timeout }
            }
            "ANGLE" => Self::Angle,
            "HOME" => Self::Home,
            "PING" => Self::Ping,
            "QUIT" => Self::Quit,
            other => {
                return Err(RequestError::UnknownCommand(
                    other.chars().take(32).collect(),
                ));
            }
        };
        if words.next().is_some() {
            return Err(RequestError::TooManyArguments(cmd.to_string()));
        }
        Ok(req)
    }

    /// The request as a line, with its `\n`.
    #[must_use]
    pub fn to_line(&self) -> String {
        match self {
            Self::Rotate {
                degrees,
                timeout: None,
            } => format!("ROTATE {degrees}\n"),
            Self::Rotate {
                degrees,
                timeout: Some(t),
            } => format!("ROTATE {degrees} {}\n", t.as_millis()),
            Self::Angle => "ANGLE\n".into(),
            Self::Home => "HOME\n".into(),
            Self::Ping => "PING\n".into(),
            Self::Quit => "QUIT\n".into(),
        }
    }
}

/// A reply line: `OK <value>` or `ERR <code> <message>`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// Success, with its value.
    Ok(String),
    /// Failure.
    Err {
        /// The error code.
        code: ErrorCode,
        /// A human-readable explanation.
        message: String,
    },
}

impl Reply {
    /// An `ERR` reply for a local error.
    #[must_use]
    pub fn error(err: &TurntableError) -> Self {
        Self::Err {
            code: err.code(),
            message: err.to_string(),
        }
    }

    /// Parses one reply line (without its `\n`).
    ///
    /// # Errors
    /// [`TurntableError::Protocol`] for anything but a well-formed reply.
    pub fn parse(line: &str) -> Result<Self, TurntableError> {
        if let Some(value) = line.strip_prefix("OK ") {
            if value.is_empty() || value.contains(char::is_whitespace) {
                return Err(TurntableError::Protocol(format!(
                    "OK reply must carry one value: {line:?}"
                )));
            }
            return Ok(Self::Ok(value.to_string()));
        }
        if let Some(rest) = line.strip_prefix("ERR ") {
            let (code, message) = rest.split_once(' ').unwrap_or((rest, ""));
            let code = ErrorCode::parse(code).ok_or_else(|| {
                TurntableError::Protocol(format!("unknown error code in {line:?}"))
            })?;
            return Ok(Self::Err {
                code,
                message: message.to_string(),
            });
        }
        Err(TurntableError::Protocol(format!(
            "expected 'OK <value>' or 'ERR <code> <message>', got {:?}",
            line.chars().take(64).collect::<String>()
        )))
    }

    /// The reply as one line of at most [`MAX_LINE_LEN`] bytes, with its
    /// `\n`; line breaks in the message become spaces, and a long message is
    /// cut at a character boundary.
    #[must_use]
    pub fn to_line(&self) -> String {
        let mut s = match self {
            Self::Ok(v) => format!("OK {v}"),
            Self::Err { code, message } => format!("ERR {code} {message}"),
        };
        s = s.replace(['\r', '\n'], " ");
        if s.len() > MAX_LINE_LEN - 1 {
            let mut cut = MAX_LINE_LEN - 1;
            while !s.is_char_boundary(cut) {
                cut -= 1;
            }
            s.truncate(cut);
        }
        s.push('\n');
        s
    }
}

/// What one [`LineReader::read_line`] produced.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum LineEvent {
    /// A complete line, without `\n` (and without a trailing `\r`).
    Line(String),
    /// More than [`MAX_LINE_LEN`] bytes without a line end.
    TooLong,
    /// A complete line that is not UTF-8.
    NotUtf8,
    /// The peer closed its side.
    Eof,
    /// The deadline passed.
    TimedOut,
    /// The stop flag was raised.
    Stopped,
}

/// Reads `\n`-terminated lines from a socket with a deadline, never
/// buffering more than a few kilobytes.
#[derive(Debug, Default)]
pub(crate) struct LineReader {
    buf: Vec<u8>,
}

/// How often a blocked read wakes up to look at the stop flag.
const TICK: Duration = Duration::from_millis(50);

impl LineReader {
    /// Whether no bytes are buffered.
    pub(crate) fn is_empty(&self) -> bool {
        self.buf.is_empty()
    }

    pub(crate) fn read_line(
        &mut self,
        stream: &mut TcpStream,
        deadline: Instant,
        stop: Option<&AtomicBool>,
    ) -> io::Result<LineEvent> {
        let mut chunk = [0u8; 512];
        loop {
            if let Some(i) = self.buf.iter().position(|&b| b == b'\n') {
                if i + 1 > MAX_LINE_LEN {
                    self.buf.clear();
                    return Ok(LineEvent::TooLong);
                }
                let mut line: Vec<u8> = self.buf.drain(..=i).collect();
                line.pop();
                if line.last() == Some(&b'\r') {
                    line.pop();
                }
                return Ok(match String::from_utf8(line) {
                    Ok(s) => LineEvent::Line(s),
                    Err(_) => LineEvent::NotUtf8,
                });
            }
            if self.buf.len() >= MAX_LINE_LEN {
                self.buf.clear();
                return Ok(LineEvent::TooLong);
            }
            if stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
                return Ok(LineEvent::Stopped);
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(LineEvent::TimedOut);
            }
            let wait = (deadline - now).min(TICK).max(Duration::from_millis(1));
            stream.set_read_timeout(Some(wait))?;
            match stream.read(&mut chunk) {
                Ok(0) => return Ok(LineEvent::Eof),
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock
                            | io::ErrorKind::TimedOut
                            | io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(e),
            }
        }
    }
}

/// Writes one line and flushes it.
pub(crate) fn write_line(stream: &mut TcpStream, line: &str) -> io::Result<()> {
    stream.write_all(line.as_bytes())?;
    stream.flush()
}

/// Closes a connection so that the last reply reaches the peer: shut down
/// our sending side, then read and discard what the peer still sends (at
/// most 64 KiB, at most `linger`), so that unread input does not turn the
/// close into a reset that could destroy the reply in flight.
pub(crate) fn close_gracefully(stream: &mut TcpStream, linger: Duration) {
    let _ = stream.shutdown(Shutdown::Write);
    let deadline = Instant::now() + linger;
    let mut chunk = [0u8; 1024];
    let mut total = 0usize;
    while total < 64 * 1024 {
        let now = Instant::now();
        if now >= deadline {
            break;
        }
        if stream.set_read_timeout(Some(deadline - now)).is_err() {
            break;
        }
        match stream.read(&mut chunk) {
            Ok(0) | Err(_) => break,
            Ok(n) => total += n,
        }
    }
    let _ = stream.shutdown(Shutdown::Both);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn requests_parse_and_print() {
        let r = Request::parse("ROTATE -45.5 2000").unwrap();
        assert_eq!(
            r,
            Request::Rotate {
                degrees: -45.5,
                timeout: Some(Duration::from_secs(2))
            }
        );
        assert_eq!(r.to_line(), "ROTATE -45.5 2000\n");
        assert_eq!(Request::parse("PING").unwrap(), Request::Ping);
        assert_eq!(Request::parse(" ANGLE ").unwrap(), Request::Angle);
        let timeout = |ms: &str| RequestError::BadTimeout(ms.into());
        for (bad, why) in [
            ("", RequestError::Empty),
            ("ROTATE", RequestError::MissingAngle),
            ("ROTATE x", RequestError::NotAnAngle("x".into())),
            ("ROTATE 1 0", timeout("0")),
            ("ROTATE 1 -5", timeout("-5")),
            ("ROTATE 1 99999999999", timeout("99999999999")),
            ("PING now", RequestError::TooManyArguments("PING".into())),
            ("rotate 1", RequestError::UnknownCommand("rotate".into())),
            ("FOO", RequestError::UnknownCommand("FOO".into())),
        ] {
            assert_eq!(Request::parse(bad), Err(why), "{bad:?}");
        }
        // The messages sent in BAD_REQUEST replies.
        assert_eq!(
            Request::parse("ROTATE x").unwrap_err().to_string(),
            r#"ROTATE: "x" is not a decimal number of degrees"#
        );
        assert_eq!(
            Request::parse("ROTATE 1 0").unwrap_err().to_string(),
            r#"ROTATE: timeout "0" must be a whole number of milliseconds in 1..=3600000"#
        );
        let long = "X".repeat(40);
        assert_eq!(
            Request::parse(&long).unwrap_err(),
            RequestError::UnknownCommand("X".repeat(32))
        );
    }

    #[test]
    fn replies_parse_and_print() {
        assert_eq!(Reply::parse("OK 45").unwrap(), Reply::Ok("45".into()));
        assert_eq!(
            Reply::parse("ERR BUSY someone else").unwrap(),
            Reply::Err {
                code: ErrorCode::Busy,
                message: "someone else".into()
            }
        );
        for bad in ["OK", "OK ", "OK 1 2", "ERR NOPE x", "HELLO", ""] {
            assert!(Reply::parse(bad).is_err(), "{bad:?}");
        }
        let long = Reply::Err {
            code: ErrorCode::Internal,
            message: "é\nx".repeat(200),
        }
        .to_line();
        assert!(long.len() <= MAX_LINE_LEN);
        assert_eq!(long.matches('\n').count(), 1);
        assert!(long.ends_with('\n'));
    }

    #[test]
    fn token_rules() {
        assert!(validate_token("s3cret-TOKEN_1").is_ok());
        assert!(validate_token("").is_err());
        assert!(validate_token("two words").is_err());
        assert!(validate_token(&"a".repeat(MAX_TOKEN_LEN + 1)).is_err());
        assert!(constant_time_eq(b"abc", b"abc"));
        assert!(!constant_time_eq(b"abc", b"abd"));
        assert!(!constant_time_eq(b"abc", b"abcd"));
        assert!(!constant_time_eq(b"", b"a"));
    }

    proptest! {
        #[test]
        fn rotate_round_trips(deg in -3600.0f64..3600.0, ms in 1u64..MAX_TIMEOUT_MS) {
            let r = Request::Rotate { degrees: deg, timeout: Some(Duration::from_millis(ms)) };
            let line = r.to_line();
            prop_assert!(line.len() <= MAX_LINE_LEN);
            prop_assert_eq!(Request::parse(line.trim_end()).unwrap(), r);
        }

        #[test]
        fn parse_never_panics(s in "\\PC{0,80}") {
            let _ = Request::parse(&s);
            let _ = Reply::parse(&s);
        }
    }
}
