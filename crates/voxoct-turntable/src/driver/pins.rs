//! Which pins the A4988 is wired to: GPIO line numbers on the Pi
//! ([`GpioPins`]) and the opened pins themselves ([`StepperPins`]).

use std::path::PathBuf;

/// Where the A4988 is wired on the Pi: the GPIO character device and its
/// line numbers (on a Raspberry Pi, line = BCM GPIO number on
/// `/dev/gpiochip0`; on a Pi 5 the header is on the RP1 chip, often
/// `/dev/gpiochip4` on older kernels).
///
/// The default wiring, all on the left of the 40-pin header near pin 11:
///
/// | A4988 pin | Pi GPIO (BCM) | header pin | notes |
/// |---|---|---|---|
/// | MS1 | GPIO17 | 11 | microstep select (table on [`Microstep`](super::Microstep)) |
/// | MS2 | GPIO27 | 13 | |
/// | MS3 | GPIO22 | 15 | |
/// | STEP | GPIO23 | 16 | one rising edge per microstep |
/// | DIR | GPIO24 | 18 | high = positive angles (unless inverted) |
/// | ENABLE | GPIO25 | 22 | active low; may be tied to GND instead |
/// | RESET, SLEEP | — | — | tie together (SLEEP pulled high) |
/// | VDD, GND | 3V3, GND | 1, 6 | logic supply at the Pi's 3.3 V |
/// | VMOT, GND | motor supply | — | 8–35 V, 100 µF across it; never unplug the motor while powered |
///
/// Set the A4988's current limit with its potentiometer before the first
/// turn.
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
    /// the configured [`Microstep`](super::Microstep) must match the wiring).
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
