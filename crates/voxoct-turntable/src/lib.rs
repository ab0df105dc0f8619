//! voxoct-turntable: the turntable that turns the object between depth
//! frames — a stepper motor on a Raspberry Pi, the TCP link that tells it
//! how far to turn, and a simulated table for tests and the simulated
//! sensor.
//!
//! Everything implements one object-safe trait, [`Turntable`]:
//! [`SimulatedTurntable`] (in memory), [`StepperTurntable`] (an A4988 on
//! GPIO pins; `GpioTurntable` with feature `gpio`) and [`RemoteTurntable`]
//! (a table served over TCP by [`server::serve`], the program
//! `examples/turntable_server.rs` runs on the Pi). The scan pipeline cannot
//! tell them apart.
//!
//! Positions are whole **microsteps** (`i64`) counted from home, and angles
//! are derived from them, so turns never drift: a request that is not a
//! whole number of microsteps is rounded to the nearest one and the angle
//! really turned is returned.
//!
//! ```
//! use std::time::Duration;
//! use voxoct_turntable::{SimulatedTurntable, Turntable};
//!
//! // A 1.8° motor at quarter stepping: 800 microsteps, 0.45° each.
//! let mut table = SimulatedTurntable::new(800)?;
//! for _ in 0..8 {
//!     assert_eq!(table.rotate_by(45.0, Duration::from_secs(1))?, 45.0);
//! }
//! assert_eq!(table.angle_deg()?, 0.0); // exactly one revolution, no drift
//! // 1° is not a whole number of 0.45° steps: two steps are made.
//! assert_eq!(table.rotate_by(1.0, Duration::from_secs(1))?, 0.9);
//! # Ok::<(), voxoct_turntable::TurntableError>(())
//! ```
//!
//! # The stepper and its wiring
//!
//! [`StepperTurntable`] drives an Allegro A4988 through the `stepper` crate
//! (DRV8825 STEP/DIR timing, which exceeds the A4988's minimums, see
//! [`A4988`]; trapezoidal acceleration ramps from RampMaker) and sets the
//! A4988's MS1–MS3 pins itself from [`Microstep`]. Default wiring
//! ([`GpioPins::default`], BCM numbers = lines of `/dev/gpiochip0`):
//!
//! | A4988 pin | Pi GPIO (BCM) | header pin | notes |
//! |---|---|---|---|
//! | MS1 | GPIO17 | 11 | microstep select (table on [`Microstep`]) |
//! | MS2 | GPIO27 | 13 | |
//! | MS3 | GPIO22 | 15 | |
//! | STEP | GPIO23 | 16 | one rising edge per microstep |
//! | DIR | GPIO24 | 18 | high = positive angles (unless inverted) |
//! | ENABLE | GPIO25 | 22 | active low; may be tied to GND instead |
//! | RESET, SLEEP | — | — | tie together (SLEEP pulled high) |
//! | VDD, GND | 3V3, GND | 1, 6 | logic supply at the Pi's 3.3 V |
//! | VMOT, GND | motor supply | — | 8–35 V, 100 µF across it; never unplug the motor while powered |
//!
//! Set the A4988's current limit with its potentiometer before the first
//! turn.
//!
//! # The network protocol, `VOXOCT-TT/1`
//!
//! The Pi runs the server; the scanning host connects as the client. (The
//! thesis used Lidgren over UDP; this is TCP.) The protocol is line-based
//! text, so it can be spoken from any language, or typed into `nc`:
//!
//! * **Transport**: one TCP connection; default port 7878. Every message is
//!   one line of UTF-8 text ending in `\n` (a `\r` before it is ignored), at
//!   most [`protocol::MAX_LINE_LEN`] = 256 bytes including the `\n`. Words
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
//!   ...` for anything else, `ERR TIMEOUT ...` after 5 s without a
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
//! * **Time limits**: the server closes a session idle for 600 s and a
//!   connection silent for 5 s before its handshake; it gives up writing a
//!   reply after 5 s. [`RemoteTurntable`] waits at most 5 s for a reply, or
//!   the turn's timeout plus 5 s for `ROTATE` ([`ClientTimeouts`]). When
//!   the server closes a session on its own (idle timeout, shutdown) it
//!   first sends one unsolicited `ERR` line; a client should therefore
//!   treat any line or EOF that arrives while it is idle as the end of the
//!   session (nothing it sends later would be executed).
//!   [`RemoteTurntable`] checks for this before each request and reconnects
//!   transparently.
//! * **One client at a time**: a second client is *refused* with `ERR BUSY`
//!   while a session is open (two scanning hosts turning one table would
//!   ruin both scans); it may retry once the first disconnects. At most 8
//!   connections are handled at once (extra ones get `ERR BUSY` at once).
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

mod client;
mod driver;
mod error;
pub mod protocol;
mod scale;
pub mod server;
mod sim;

use std::time::Duration;

pub use client::{ClientTimeouts, RemoteTurntable};
#[cfg(feature = "gpio")]
pub use driver::GpioTurntable;
pub use driver::{
    A4988, GpioPins, InstantTimer, Microstep, StepperConfig, StepperPins, StepperTurntable,
    TIMER_HZ,
};
pub use error::{ErrorCode, TurntableError};
pub use scale::{MAX_ROTATION_DEG, StepScale};
pub use server::{ServerConfig, ServerHandle, serve};
pub use sim::SimulatedTurntable;

/// The crates whose traits appear in [`StepperTurntable`]'s bounds:
/// implement `embedded_hal_02::digital::v2::OutputPin` for your pins and
/// `fugit_timer::Timer<TIMER_HZ>` for your timer.
pub use {embedded_hal_02, fugit_timer};

/// A turntable: turn by an angle, read the angle, set home.
///
/// Object-safe, so a pipeline can hold a `Box<dyn Turntable>` and not know
/// whether the table is simulated, on local pins or across the network.
pub trait Turntable {
    /// Turns by `degrees` (positive = forward) and blocks until the turn is
    /// done; returns the angle really turned, which is `degrees` rounded to
    /// a whole number of microsteps.
    ///
    /// # Errors
    /// [`TurntableError::BadAngle`] for a non-finite angle or one over
    /// [`MAX_ROTATION_DEG`]; [`TurntableError::Timeout`] when the turn
    /// cannot finish within `timeout` (refused before moving when
    /// predictable; otherwise the table stops where it is and
    /// [`Turntable::angle_deg`] tells where); hardware and network errors.
    fn rotate_by(&mut self, degrees: f64, timeout: Duration) -> Result<f64, TurntableError>;

    /// The current angle, in degrees in `[0, 360)`, measured from home in
    /// the positive direction.
    ///
    /// # Errors
    /// Network errors for a remote table; local tables never fail.
    fn angle_deg(&mut self) -> Result<f64, TurntableError>;

    /// Declares the current position to be home (0°). Without a home switch
    /// nothing moves: place the object, then call this.
    ///
    /// # Errors
    /// Network errors for a remote table; local tables never fail.
    fn home(&mut self) -> Result<(), TurntableError>;
}

impl<T: Turntable + ?Sized> Turntable for Box<T> {
    fn rotate_by(&mut self, degrees: f64, timeout: Duration) -> Result<f64, TurntableError> {
        (**self).rotate_by(degrees, timeout)
    }

    fn angle_deg(&mut self) -> Result<f64, TurntableError> {
        (**self).angle_deg()
    }

    fn home(&mut self) -> Result<(), TurntableError> {
        (**self).home()
    }
}

impl<T: Turntable + ?Sized> Turntable for &mut T {
    fn rotate_by(&mut self, degrees: f64, timeout: Duration) -> Result<f64, TurntableError> {
        (**self).rotate_by(degrees, timeout)
    }

    fn angle_deg(&mut self) -> Result<f64, TurntableError> {
        (**self).angle_deg()
    }

    fn home(&mut self) -> Result<(), TurntableError> {
        (**self).home()
    }
}
