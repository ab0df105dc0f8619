//! Which pins the A4988 is wired to: GPIO line numbers on the Pi
//! ([`GpioPins`]) and the opened pins themselves ([`StepperPins`]).

use std::path::PathBuf;

/// Where the A4988 is wired on the Pi: the GPIO character device and its
/// line numbers (on a Raspberry Pi, line = BCM GPIO number on
/// `/dev/gpiochip0`; on a Pi 5 the header is on the RP1 chip, often
/// `/dev/gpiochip4` on older kernels).
///
/// The defaults, all on the left of the 40-pin header near pin 11: MS1 =
/// GPIO17 (pin 11), MS2 = GPIO27 (pin 13), MS3 = GPIO22 (pin 15), STEP =
/// GPIO23 (pin 16), DIR = GPIO24 (pin 18), ENABLE = GPIO25 (pin 22).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GpioPins {
    /// The GPIO character device.
    pub chip: PathBuf,
    /// Line driving STEP.
    pub step: u32,
    /// Line driving DIR.
    pub dir: u32,
    /// Line driving ENABLE (active low), or `None` when ENABLE is tied low.
    pub enable: Option<u32>,
    /// Lines driving MS1, MS2, MS3, or `None` when they are hard-wired (then
    /// the configured [`Microstep`] must match the wiring).
    pub microstep: Option<[u32; 3]>,
}

impl Default for GpioPins {
    fn default() -> Self {
        Self {
            chip: PathBuf::from("/dev/gpiochip0"),
            step: 23,
            dir: 24,
            enable: Some(25),
            microstep: Some([17, 27, 22]),
        }
    }
}

/// The pins of one A4988, all of one `OutputPin` type `P` (as on Linux,
/// where every line is a `CdevPin`).
#[derive(Debug)]
pub struct StepperPins<P> {
    /// STEP: one rising edge per microstep.
    pub step: P,
    /// DIR: high = forward (positive angles, unless inverted).
    pub dir: P,
    /// ENABLE (active low), if wired.
    pub enable: Option<P>,
    /// MS1, MS2, MS3, if wired.
    pub microstep: Option<[P; 3]>,
}
