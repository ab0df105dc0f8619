//! The error of every turntable operation, shared by local and remote
//! tables, and the wire codes it is reported under. (Parsing a request line
//! has its own error, [`RequestError`](crate::protocol::RequestError).)

use std::time::Duration;

/// The words that end a [`TurntableError::TooSlow`] message (a test checks it): the client
/// recognises a turn the server refused before moving by them (the wire code is `TIMEOUT`).
pub(crate) const REFUSED_BEFORE_MOVING: &str = "refused before moving";

/// Everything that can go wrong while driving a turntable, locally or over
/// the network.
///
/// A [`RemoteTurntable`](crate::RemoteTurntable) returns the same variants as
/// the local table behind the server wherever the wire has a code for them
/// ([`ErrorCode`]), so the pipeline can handle both alike.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TurntableError {
    /// The operation did not finish within its timeout.
    ///
    /// A turn whose planned duration (from the speed and acceleration)
    /// exceeds the timeout is refused before it starts, without moving; a
    /// turn that overruns while moving is stopped where it is and the
    /// position keeps the steps really made.
    ///
    /// How to fix: give a longer timeout, or a higher speed.
    #[error("{operation} timed out after {after:?}")]
    Timeout {
        /// What was being done (`"rotate"`, `"reply from server"`, ...).
        operation: String,
        /// The timeout that ran out.
        after: Duration,
    },

    /// A turn refused before moving: it would take longer than its timeout allows.
    ///
    /// How to fix: give a longer timeout, or a higher speed.
    #[error(
        "{operation} would take {needs:?}, longer than its timeout of {timeout:?}; refused before moving"
    )]
    TooSlow {
        /// What was asked (`"rotate by 90 deg"`).
        operation: String,
        /// How long it would take.
        needs: Duration,
        /// The timeout it had.
        timeout: Duration,
    },

    /// The peer closed the connection, or it broke.
    ///
    /// How to fix: check that the server still runs and the network is up,
    /// then reconnect ([`RemoteTurntable::reconnect`](crate::RemoteTurntable::reconnect)).
    #[error("disconnected: {0}")]
    Disconnected(String),

    /// An I/O error on the network (connect, bind, read, write).
    #[error("network I/O failed while {context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// The peer sent something that does not follow the protocol.
    ///
    /// How to fix: make sure both ends speak `VOXOCT-TT/1` as described in
    /// [`protocol`](crate::protocol).
    #[error("protocol error: {0}")]
    Protocol(String),

    /// The peer speaks another version of the protocol.
    ///
    /// How to fix: run the same voxoct version on the scanning host and the
    /// Pi.
    #[error("protocol version mismatch: {0}")]
    Version(String),

    /// The server refused the shared-secret token (missing or wrong).
    ///
    /// How to fix: pass the client the server's token (`turntable_server
    /// --token`, or [`TOKEN_ENV`](crate::TOKEN_ENV)).
    #[error("unauthorised: the server refused the token")]
    Unauthorised,

    /// The table is in use by another client, or the server is at its
    /// connection limit.
    ///
    /// How to fix: stop the other client, or wait and connect again.
    #[error("busy: {0}")]
    Busy(String),

    /// The remote table reported an error that has no local variant (for
    /// instance a hardware error on the Pi).
    #[error("the turntable server reported {code}: {message}")]
    Remote {
        /// The wire error code.
        code: ErrorCode,
        /// The server's explanation.
        message: String,
    },

    /// A GPIO pin or the timer failed.
    ///
    /// How to fix: check the wiring, the pin numbers, and that this process
    /// may use `/dev/gpiochip*` (group `gpio` on Raspberry Pi OS).
    #[error("hardware error: {0}")]
    Hardware(String),

    /// The requested angle is not finite or larger than
    /// [`MAX_ROTATION_DEG`](crate::MAX_ROTATION_DEG) in magnitude.
    ///
    /// How to fix: pass a finite angle in degrees; turn in several calls if
    /// you really need more.
    #[error("bad angle {degrees}: {reason}")]
    BadAngle {
        /// The angle asked for, in degrees.
        degrees: f64,
        /// Why it was refused.
        reason: String,
    },

    /// A configuration value is out of range.
    ///
    /// How to fix: the message names the field and its valid range.
    #[error("bad configuration: {0}")]
    Config(String),
}

impl TurntableError {
    /// The wire code this error is reported under by the server.
    #[must_use]
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::Timeout { .. } | Self::TooSlow { .. } => ErrorCode::Timeout,
            Self::BadAngle { .. } => ErrorCode::BadAngle,
            Self::Busy(_) => ErrorCode::Busy,
            Self::Unauthorised => ErrorCode::Unauthorised,
            Self::Version(_) => ErrorCode::Version,
            Self::Hardware(_) => ErrorCode::Hardware,
            Self::Protocol(_) => ErrorCode::BadRequest,
            Self::Remote { code, .. } => *code,
            Self::Disconnected(_) | Self::Io { .. } | Self::Config(_) => ErrorCode::Internal,
        }
    }

    pub(crate) fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Self::Io {
            context: context.into(),
            source,
        }
    }
}

/// The error codes of `ERR <code> <message>` replies (see
/// [`protocol`](crate::protocol)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorCode {
    /// `BAD_REQUEST`: malformed line, unknown command, bad argument.
    BadRequest,
    /// `TOO_LONG`: a line longer than [`MAX_LINE_LEN`](crate::protocol::MAX_LINE_LEN); the
    /// server closes the connection after this reply.
    TooLong,
    /// `VERSION`: the handshake named another protocol version.
    Version,
    /// `UNAUTHORISED`: missing or wrong token.
    Unauthorised,
    /// `BUSY`: another client holds the table, or too many connections.
    Busy,
    /// `BAD_ANGLE`: non-finite or too large an angle.
    BadAngle,
    /// `TIMEOUT`: the turn could not finish within its timeout.
    Timeout,
    /// `HARDWARE`: a pin or timer failed on the server.
    Hardware,
    /// `INTERNAL`: anything else.
    Internal,
}

impl ErrorCode {
    /// All codes, for documentation and tests.
    pub const ALL: [Self; 9] = [
        Self::BadRequest,
        Self::TooLong,
        Self::Version,
        Self::Unauthorised,
        Self::Busy,
        Self::BadAngle,
        Self::Timeout,
        Self::Hardware,
        Self::Internal,
    ];

    /// The code as written on the wire.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::BadRequest => "BAD_REQUEST",
            Self::TooLong => "TOO_LONG",
            Self::Version => "VERSION",
            Self::Unauthorised => "UNAUTHORISED",
            Self::Busy => "BUSY",
            Self::BadAngle => "BAD_ANGLE",
            Self::Timeout => "TIMEOUT",
            Self::Hardware => "HARDWARE",
            Self::Internal => "INTERNAL",
        }
    }

    /// Parses a wire code; `None` for an unknown one.
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == s)
    }
}

impl std::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refused_turn_says_the_words_the_client_looks_for() {
        let e = TurntableError::TooSlow {
            operation: "rotate by 90 deg".into(),
            needs: Duration::from_secs(1),
            timeout: Duration::from_millis(100),
        };
        assert!(e.to_string().ends_with(REFUSED_BEFORE_MOVING), "{e}");
    }
}
