//! The client: a [`Turntable`] on the other end of a TCP connection.

use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use crate::protocol::{
    LineEvent, LineReader, MAX_TIMEOUT_MS, PROTOCOL, PROTOCOL_PREFIX, Reply, Request,
    validate_token, write_line,
};
use crate::{ErrorCode, MAX_ROTATION_DEG, Turntable, TurntableError};

/// Client-side time limits. No call of a [`RemoteTurntable`] waits longer
/// than these (plus the turn's own timeout for `rotate_by`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClientTimeouts {
    /// Limit for establishing the TCP connection, per resolved address.
    pub connect: Duration,
    /// Limit for the handshake reply and for the reply to `ANGLE`, `HOME`,
    /// `PING`; also the write timeout of every request.
    pub reply: Duration,
    /// Extra time allowed for the reply to `ROTATE`, on top of the turn's
    /// own timeout (network delay, planning).
    pub rotate_margin: Duration,
}

impl Default for ClientTimeouts {
    /// 5 s to connect, 5 s per reply, 5 s margin on turns.
    fn default() -> Self {
        Self {
            connect: Duration::from_secs(5),
            reply: Duration::from_secs(5),
            rotate_margin: Duration::from_secs(5),
        }
    }
}

/// A turntable served by [`serve`](crate::server::serve) on another machine
/// (the Pi), reached over TCP.
///
/// It implements [`Turntable`], so a pipeline cannot tell it from a local
/// table. Errors reported by the server come back as the same variants
/// ([`TurntableError::Timeout`], [`TurntableError::BadAngle`], ...). After a
/// network failure or a timeout the connection's state is unknown, so it is
/// dropped: later calls fail with [`TurntableError::Disconnected`] until
/// [`RemoteTurntable::reconnect`] succeeds. A session the server closed
/// while the client was idle (its idle timeout, a restart) is detected
/// before the next request is sent and reconnected transparently. The
/// server's angle is not affected by reconnecting.
#[derive(Debug)]
pub struct RemoteTurntable {
    stream: Option<TcpStream>,
    reader: LineReader,
    addr: SocketAddr,
    token: Option<String>,
    timeouts: ClientTimeouts,
    /// Set during the handshake: no idle-close check (and so no recursion).
    handshaking: bool,
}

impl RemoteTurntable {
    /// Connects to `addr` and performs the handshake with `token` (which
    /// must match the server's, if it has one).
    ///
    /// # Errors
    /// [`TurntableError::Io`] when no address accepts the connection,
    /// [`TurntableError::Unauthorised`] for a wrong or missing token,
    /// [`TurntableError::Version`] when the server speaks another version,
    /// [`TurntableError::Busy`] when another client holds the table,
    /// [`TurntableError::Timeout`] when the server does not answer in time,
    /// [`TurntableError::Config`] for a token that cannot be sent.
    pub fn connect(
        addr: impl ToSocketAddrs,
        token: Option<&str>,
        timeouts: ClientTimeouts,
    ) -> Result<Self, TurntableError> {
        if let Some(t) = token {
            validate_token(t)?;
        }
        let addrs: Vec<SocketAddr> = addr
            .to_socket_addrs()
            .map_err(|e| TurntableError::io("resolving the server address", e))?
            .collect();
        let mut last_err = None;
        for a in addrs {
            let mut client = Self {
                stream: None,
                reader: LineReader::default(),
                addr: a,
                token: token.map(str::to_string),
                timeouts,
                handshaking: false,
            };
            match client.reconnect() {
                Ok(()) => return Ok(client),
                // A refused or unreachable address: try the next one.
                Err(e @ TurntableError::Io { .. }) => last_err = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last_err.unwrap_or_else(|| {
            TurntableError::io(
                "resolving the server address",
                std::io::Error::new(std::io::ErrorKind::NotFound, "no address"),
            )
        }))
    }

    /// Drops the current connection, if any, and connects again to the same
    /// address with the same token.
    ///
    /// # Errors
    /// As [`RemoteTurntable::connect`].
    pub fn reconnect(&mut self) -> Result<(), TurntableError> {
        self.stream = None;
        self.reader = LineReader::default();
        let stream = TcpStream::connect_timeout(&self.addr, self.timeouts.connect)
            .map_err(|e| TurntableError::io(format!("connecting to {}", self.addr), e))?;
        let _ = stream.set_nodelay(true);
        stream
            .set_write_timeout(Some(self.timeouts.reply))
            .map_err(|e| TurntableError::io("setting the write timeout", e))?;
        self.stream = Some(stream);
        let hello = match &self.token {
            Some(t) => format!("{PROTOCOL} {t}\n"),
            None => format!("{PROTOCOL}\n"),
        };
        self.handshaking = true;
        let value = self.exchange(&hello, "handshake", self.timeouts.reply, None);
        self.handshaking = false;
        let value = value?;
        if value != PROTOCOL {
            self.stream = None;
            if value.starts_with(PROTOCOL_PREFIX) {
                return Err(TurntableError::Version(format!(
                    "the server speaks {value}, this client {PROTOCOL}"
                )));
            }
            return Err(TurntableError::Protocol(format!(
                "handshake answered with {value:?}, expected {PROTOCOL}"
            )));
        }
        Ok(())
    }

    /// The server's address.
    #[must_use]
    pub fn peer_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Whether a connection is open (it may still have died silently).
    #[must_use]
    pub fn is_connected(&self) -> bool {
        self.stream.is_some()
    }

    /// Sends `PING` and returns the round-trip time.
    ///
    /// # Errors
    /// As any request: [`TurntableError::Disconnected`],
    /// [`TurntableError::Timeout`], [`TurntableError::Protocol`].
    pub fn ping(&mut self) -> Result<Duration, TurntableError> {
        let start = Instant::now();
        let v = self.exchange(&Request::Ping.to_line(), "PING", self.timeouts.reply, None)?;
        if v != "PONG" {
            return Err(TurntableError::Protocol(format!("PING answered {v:?}")));
        }
        Ok(start.elapsed())
    }

    /// Ends the session politely (`QUIT`), so the table is free for another
    /// client at once.
    ///
    /// # Errors
    /// As any request.
    pub fn close(mut self) -> Result<(), TurntableError> {
        self.exchange(&Request::Quit.to_line(), "QUIT", self.timeouts.reply, None)?;
        self.stream = None;
        Ok(())
    }

    /// Sends one line and waits up to `wait` for its reply; returns the `OK`
    /// value. Drops the connection on any failure that leaves it in an
    /// unknown state.
    fn exchange(
        &mut self,
        line: &str,
        what: &str,
        wait: Duration,
        degrees: Option<f64>,
    ) -> Result<String, TurntableError> {
        let result = self.exchange_inner(line, what, wait);
        match result {
            Ok(Reply::Ok(v)) => Ok(v),
            Ok(Reply::Err { code, message }) => {
                if matches!(
                    code,
                    ErrorCode::TooLong
                        | ErrorCode::Version
                        | ErrorCode::Unauthorised
                        | ErrorCode::Busy
                ) {
                    // The server closes the connection after these.
                    self.stream = None;
                }
                Err(remote_error(code, message, wait, degrees))
            }
            Err(e) => {
                self.stream = None;
                Err(e)
            }
        }
    }

    fn exchange_inner(
        &mut self,
        line: &str,
        what: &str,
        wait: Duration,
    ) -> Result<Reply, TurntableError> {
        if self.stream.is_some() && !self.reader.is_empty() {
            // Left-over bytes mean the stream is out of step: start afresh.
            self.stream = None;
        }
        if !self.handshaking && self.stream.as_mut().is_some_and(|s| !peer_still_there(s)) {
            // The server closed the session while we were idle (idle
            // timeout, restart). Nothing of this request has been sent yet,
            // so reconnecting is safe for every request, ROTATE included.
            self.reconnect()?;
        }
        let Some(stream) = self.stream.as_mut() else {
            return Err(TurntableError::Disconnected(
                "not connected (an earlier error closed the connection); call reconnect()".into(),
            ));
        };
        write_line(stream, line).map_err(|e| {
            TurntableError::Disconnected(format!("sending {what} to {} failed: {e}", self.addr))
        })?;
        let deadline = Instant::now() + wait;
        let event = self.reader.read_line(stream, deadline, None).map_err(|e| {
            TurntableError::Disconnected(format!(
                "connection to {} broke while waiting for the reply to {what}: {e}",
                self.addr
            ))
        })?;
        match event {
            LineEvent::Line(l) => Reply::parse(&l),
            LineEvent::Eof => Err(TurntableError::Disconnected(format!(
                "the server at {} closed the connection before answering {what}",
                self.addr
            ))),
            LineEvent::TimedOut | LineEvent::Stopped => Err(TurntableError::Timeout {
                operation: format!("waiting for the reply to {what} from {}", self.addr),
                after: wait,
            }),
            LineEvent::TooLong => Err(TurntableError::Protocol(
                "the server sent an over-long line".into(),
            )),
            LineEvent::NotUtf8 => Err(TurntableError::Protocol(
                "the server sent a line that is not UTF-8".into(),
            )),
        }
    }
}

/// Whether an idle connection is still open with nothing unsolicited
/// waiting: a server closing a session sends at most one `ERR` line and then
/// EOF, which a non-blocking peek sees.
fn peer_still_there(stream: &TcpStream) -> bool {
    if stream.set_nonblocking(true).is_err() {
        return false;
    }
    let mut byte = [0u8; 1];
    let alive = matches!(
        stream.peek(&mut byte),
        Err(ref e) if e.kind() == std::io::ErrorKind::WouldBlock
    );
    stream.set_nonblocking(false).is_ok() && alive
}

fn remote_error(
    code: ErrorCode,
    message: String,
    wait: Duration,
    degrees: Option<f64>,
) -> TurntableError {
    match code {
        ErrorCode::Busy => TurntableError::Busy(message),
        ErrorCode::Unauthorised => TurntableError::Unauthorised,
        ErrorCode::Version => TurntableError::Version(message),
        // Refused before moving: nothing timed out, the server says why.
        ErrorCode::Timeout if message.contains(crate::error::REFUSED_BEFORE_MOVING) => {
            TurntableError::Remote { code, message }
        }
        ErrorCode::Timeout => TurntableError::Timeout {
            operation: format!("server: {message}"),
            after: wait,
        },
        ErrorCode::BadAngle => TurntableError::BadAngle {
            degrees: degrees.unwrap_or(f64::NAN),
            reason: format!("server: {message}"),
        },
        _ => TurntableError::Remote { code, message },
    }
}

fn parse_number(v: &str, what: &str) -> Result<f64, TurntableError> {
    v.parse::<f64>()
        .ok()
        .filter(|d| d.is_finite())
        .ok_or_else(|| TurntableError::Protocol(format!("{what} answered {v:?}, not a number")))
}

impl Turntable for RemoteTurntable {
    fn rotate_by(&mut self, degrees: f64, timeout: Duration) -> Result<f64, TurntableError> {
        if !degrees.is_finite() || degrees.abs() > MAX_ROTATION_DEG {
            return Err(TurntableError::BadAngle {
                degrees,
                reason: format!("must be finite and at most {MAX_ROTATION_DEG} degrees"),
            });
        }
        let ms = timeout.as_millis().clamp(1, u128::from(MAX_TIMEOUT_MS)) as u64;
        let req = Request::Rotate {
            degrees,
            timeout: Some(Duration::from_millis(ms)),
        };
        let wait = timeout + self.timeouts.rotate_margin;
        let v = self.exchange(&req.to_line(), "ROTATE", wait, Some(degrees))?;
        let turned = parse_number(&v, "ROTATE")?;
        Ok(turned)
    }

    fn angle_deg(&mut self) -> Result<f64, TurntableError> {
        let v = self.exchange(
            &Request::Angle.to_line(),
            "ANGLE",
            self.timeouts.reply,
            None,
        )?;
        let a = parse_number(&v, "ANGLE")?;
        if !(0.0..360.0).contains(&a) {
            return Err(TurntableError::Protocol(format!(
                "ANGLE answered {a}, outside [0, 360)"
            )));
        }
        Ok(a)
    }

    fn home(&mut self) -> Result<(), TurntableError> {
        self.exchange(&Request::Home.to_line(), "HOME", self.timeouts.reply, None)?;
        Ok(())
    }
}
