//! The A4988 stepper driver, generic over the pins and the timer.
//!
//! Motion goes through the [`stepper`] crate (0.6.0): its DRV8825 driver
//! produces the STEP/DIR signals and its software motion control, with
//! RampMaker's trapezoidal profile, ramps the speed up and down so that a
//! heavy object does not make the motor skip steps. The A4988 is not one of
//! stepper's drivers; the DRV8825's STEP/DIR timing is a safe superset of the
//! A4988's (see [`A4988`]), but its mode pins do not match, so this module
//! sets MS1–MS3 itself from [`Microstep`].
//!
//! Everything here is generic over the embedded-hal 0.2 `OutputPin` (the
//! same type for every pin) and a `fugit_timer::Timer` at [`TIMER_HZ`], so
//! tests drive it with mock pins on any machine; the Linux pin types are
//! behind the `gpio` feature (`GpioTurntable`).
//!
//! One concept per file:
//!
//! | file | what |
//! |---|---|
//! | `timing.rs` | [`A4988`]: datasheet timing, checked at compile time |
//! | `microstep.rs` | [`Microstep`]: modes and their MS1–MS3 levels |
//! | `config.rs` | [`StepperConfig`]: mechanics, speed and acceleration limits |
//! | `pins.rs` | [`GpioPins`] (line numbers), [`StepperPins`] (opened pins) |
//! | `timer.rs` | [`TIMER_HZ`], [`InstantTimer`], the bounded wait |
//! | `ramp.rs` | the exact trapezoidal ramp and its delay-to-tick conversion |
//! | `stepper_turntable.rs` | [`StepperTurntable`]: planning, stepping, stopping |
//! | `gpio.rs` | `GpioTurntable`: the lines of a Linux GPIO chip (feature `gpio`) |

mod config;
#[cfg(feature = "gpio")]
mod gpio;
mod microstep;
mod pins;
mod ramp;
mod stepper_turntable;
mod timer;
mod timing;

pub use config::StepperConfig;
#[cfg(feature = "gpio")]
pub use gpio::GpioTurntable;
pub use microstep::Microstep;
pub use pins::{GpioPins, StepperPins};
pub use stepper_turntable::StepperTurntable;
pub use timer::{InstantTimer, TIMER_HZ};
pub use timing::A4988;

use crate::TurntableError;

/// Turns a pin or timer error into [`TurntableError::Hardware`] naming what
/// failed.
fn hw<E: std::fmt::Debug>(what: &str) -> impl FnOnce(E) -> TurntableError + '_ {
    move |e| TurntableError::Hardware(format!("{what}: {e:?}"))
}
