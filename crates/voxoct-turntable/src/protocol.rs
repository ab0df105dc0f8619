//! The `VOXOCT-TT/1` wire protocol: constants, request and reply lines, and
//! a bounded line reader. The protocol itself is specified on the crate's
//! front page.

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
pub fn validate_token(token: &str) -> Result<(), TurntableError> {
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
pub fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
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

impl Request {
    /// Parses one request line (without its `\n`).
    ///
    /// # Errors
    /// A message for the `BAD_REQUEST` reply.
    pub fn parse(line: &str) -> Result<Self, String> {
        let mut words = line.split_ascii_whitespace();
        let Some(cmd) = words.next() else {
            return Err("empty request; expected ROTATE, ANGLE, HOME, PING or QUIT".into());
        };
        let req = match cmd {
            "ROTATE" => {
                let Some(deg) = words.next() else {
                    return Err("ROTATE needs an angle: ROTATE <degrees> [<timeout_ms>]".into());
                };
                let degrees: f64 = deg
                    .parse()
                    .map_err(|_| format!("ROTATE: {deg:?} is not a decimal number of degrees"))?;
                let timeout = match words.next() {
                    None => None,
                    Some(ms) => {
                        let ms: u64 = ms
                            .parse()
                            .ok()
                            .filter(|ms| (1..=MAX_TIMEOUT_MS).contains(ms))
                            .ok_or_else(|| {
                                format!(
                                    "ROTATE: timeout {ms:?} must be a whole number of \
                                     milliseconds in 1..={MAX_TIMEOUT_MS}"
                                )
                            })?;
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
                let shown: String = other.chars().take(32).collect();
                return Err(format!(
                    "unknown command {shown:?}; expected ROTATE, ANGLE, HOME, PING or QUIT"
                ));
            }
        };
        if words.next().is_some() {
            return Err(format!("too many arguments for {cmd}"));
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
        for bad in [
            "",
            "ROTATE",
            "ROTATE x",
            "ROTATE 1 0",
            "ROTATE 1 -5",
            "ROTATE 1 99999999999",
            "PING now",
            "rotate 1",
            "FOO",
        ] {
            assert!(Request::parse(bad).is_err(), "{bad:?}");
        }
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
