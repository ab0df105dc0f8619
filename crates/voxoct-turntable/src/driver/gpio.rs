//! [`GpioTurntable`]: the stepper turntable on Linux GPIO character-device
//! pins (feature `gpio`).

use std::fmt;

use super::{GpioPins, InstantTimer, StepperConfig, StepperPins, StepperTurntable};
use crate::TurntableError;

/// The stepper turntable on Linux GPIO character-device pins (feature
/// `gpio`).
pub type GpioTurntable = StepperTurntable<linux_embedded_hal::CdevPin, InstantTimer>;

impl StepperTurntable<linux_embedded_hal::CdevPin, InstantTimer> {
    /// Opens the GPIO lines of `pins` as outputs (consumer label `voxoct`)
    /// and sets the driver up as [`StepperTurntable::new`] does.
    ///
    /// # Errors
    /// [`TurntableError::Hardware`] naming the chip or line that could not be
    /// opened (no such chip on this machine, line busy, permission denied),
    /// [`TurntableError::Config`] for an invalid configuration.
    pub fn open(pins: &GpioPins, config: StepperConfig) -> Result<Self, TurntableError> {
        use linux_embedded_hal::gpio_cdev::{Chip, LineRequestFlags};
        config.step_rates()?;
        let chip_name = pins.chip.display().to_string();
        let mut chip = Chip::new(&pins.chip).map_err(|e| {
            TurntableError::Hardware(format!(
                "cannot open GPIO chip {chip_name}: {e}. How to fix: run on the Raspberry Pi, \
                 pass the right chip with --gpio-chip, and make sure this user may open it \
                 (group gpio)"
            ))
        })?;
        let mut line =
            |n: u32, what: &str| -> Result<linux_embedded_hal::CdevPin, TurntableError> {
                let err = |e: &dyn fmt::Display| {
                    TurntableError::Hardware(format!("GPIO line {n} ({what}) on {chip_name}: {e}"))
                };
                let handle = chip
                    .get_line(n)
                    .map_err(|e| err(&e))?
                    .request(LineRequestFlags::OUTPUT, 0, "voxoct")
                    .map_err(|e| err(&e))?;
                linux_embedded_hal::CdevPin::new(handle).map_err(|e| err(&e))
            };
        let step = line(pins.step, "STEP")?;
        let dir = line(pins.dir, "DIR")?;
        let enable = pins.enable.map(|n| line(n, "ENABLE")).transpose()?;
        let microstep = match pins.microstep {
            Some([a, b, c]) => Some([line(a, "MS1")?, line(b, "MS2")?, line(c, "MS3")?]),
            None => None,
        };
        Self::new(
            StepperPins {
                step,
                dir,
                enable,
                microstep,
            },
            InstantTimer::new(),
            config,
        )
    }
}
