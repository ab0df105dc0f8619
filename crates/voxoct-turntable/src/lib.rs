//! voxoct-turntable: the turntable that turns the object between depth
//! frames — a stepper motor on a Raspberry Pi, the TCP link that tells it
//! how far to turn, and a simulated table for tests and the simulated
//! sensor.
//!
//! Everything implements one object-safe trait, [`Turntable`]:
//!
//! * [`SimulatedTurntable`]: in memory, optionally at a finite speed;
//! * [`StepperTurntable`]: an Allegro A4988 on STEP/DIR (and MS1–MS3,
//!   ENABLE) pins, generic over the embedded-hal pin and timer traits so it
//!   runs against mock pins anywhere; `GpioTurntable` (feature `gpio`) opens
//!   the pins of a Linux GPIO chip, wired as in [`GpioPins`];
//! * [`RemoteTurntable`]: a table served over TCP by [`serve`] (what the
//!   program `examples/turntable_server.rs` runs on the Pi), with the
//!   line-based protocol `VOXOCT-TT/1` specified in [`protocol`]. The
//!   shared-secret token's environment variable, for the server and the
//!   scanner alike, is [`TOKEN_ENV`] (read it with [`token_from_env`]).
//!
//! The scan pipeline cannot tell them apart. Positions are whole
//! **microsteps** (`i64`) counted from home, and angles (`f64` degrees) are
//! derived from them, so turns never drift: a request that is not a whole
//! number of microsteps is rounded to the nearest one and the angle really
//! turned is returned.
//!
//! A simulated table served on loopback, turned by a client, as a scanning
//! host turns the Pi's table:
//!
//! ```
//! use std::net::TcpListener;
//! use std::time::Duration;
//! use voxoct_turntable::{
//!     ClientTimeouts, RemoteTurntable, ServerConfig, SimulatedTurntable, Turntable,
//!     TurntableError, serve,
//! };
//!
//! // The Pi's side (there: a GpioTurntable). A 1.8° motor at quarter
//! // stepping: 800 microsteps, 0.45° each.
//! let config = ServerConfig {
//!     token: Some("s3cret".into()),
//!     ..ServerConfig::default()
//! };
//! let server = serve(TcpListener::bind("127.0.0.1:0")?, SimulatedTurntable::new(800)?, config)?;
//!
//! // The scanning host's side: the token is checked in the handshake.
//! let addr = server.local_addr();
//! let refused = RemoteTurntable::connect(addr, None, ClientTimeouts::default());
//! assert!(matches!(refused, Err(TurntableError::Unauthorised)));
//! let mut table = RemoteTurntable::connect(addr, Some("s3cret"), ClientTimeouts::default())?;
//! let timeout = Duration::from_secs(10);
//! for _ in 0..8 {
//!     assert_eq!(table.rotate_by(45.0, timeout)?, 45.0);
//! }
//! assert_eq!(table.angle_deg()?, 0.0); // exactly one revolution, no drift
//! // 1° is not a whole number of 0.45° steps: two steps are made.
//! assert_eq!(table.rotate_by(1.0, timeout)?, 0.9);
//! table.close()?;
//! server.shutdown();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The design (why microsteps, the A4988 timing, the server's limits and
//! the single session) is in `ARCHITECTURE.md`.

mod client;
mod driver;
mod error;
pub mod protocol;
mod scale;
pub mod server;
mod sim;
mod token;

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
pub use token::{TOKEN_ENV, token_from_env};

/// The crates whose traits appear in [`StepperTurntable`]'s bounds:
/// implement `embedded_hal_02::digital::v2::OutputPin` for your pins and
/// `fugit_timer::Timer<TIMER_HZ>` for your timer.
pub use {embedded_hal_02, fugit_timer};

/// A turntable: turn by an angle, read the angle, set home.
///
/// Object-safe, so a pipeline can hold a `Box<dyn Turntable>` and not know
/// whether the table is simulated, on local pins or across the network.
///
/// Angles are `f64` degrees, unlike the `f32` of the geometry crates, on
/// purpose: they are computed from whole microsteps with one rounding
/// ([`StepScale`] keeps products up to 2⁴⁹ exact, which `f32`'s 24-bit
/// mantissa cannot), and they travel as decimal text whose shortest `f64`
/// form is what the table really did (`0.9`, `45.9`). Convert to `f32` once,
/// where the sensor pose is built.
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
