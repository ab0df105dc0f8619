//! [`StepperTurntable`]: the [`Turntable`] on an A4988, generic over the
//! pins and the timer.

use std::fmt;
use std::task::Poll;
use std::time::{Duration, Instant};

use embedded_hal_02::digital::v2::OutputPin;
use stepper::compat::Pin;
use stepper::drivers::drv8825::DRV8825;
use stepper::motion_control::SoftwareMotionControl;
use stepper::ramp_maker::MotionProfile;
use stepper::ramp_maker::trapezoidal::DefaultNum;
use stepper::traits::MotionControl;
use stepper::{Direction, Stepper};

use super::ramp::{ExactTrapezoid, SecondsToTicks};
use super::timer::wait_ns;
use super::{A4988, StepperConfig, StepperPins, TIMER_HZ, hw};
use crate::{StepScale, Turntable, TurntableError};

pub(super) type Drv<P> = DRV8825<(), (), (), (), (), (), (), Pin<P>, Pin<P>>;
type Motion<P, T> = SoftwareMotionControl<Drv<P>, T, ExactTrapezoid, SecondsToTicks, TIMER_HZ>;

/// A turntable driven by an A4988 through STEP/DIR (and optionally ENABLE
/// and MS1–MS3), with trapezoidal speed ramps.
///
/// Generic over the pin type `P` (embedded-hal 0.2 `OutputPin`) and the
/// timer `T` (`fugit_timer::Timer` at [`TIMER_HZ`]); on a Pi use
/// `GpioTurntable` (feature `gpio`), elsewhere mock pins.
///
/// `rotate_by` first plans the move: if the ramped profile needs longer
/// than the timeout it returns [`TurntableError::Timeout`] without moving.
/// While moving it checks the wall clock; on overrun it stops at once (no
/// deceleration ramp) and keeps the steps really made in the position.
pub struct StepperTurntable<P, T>
where
    P: OutputPin,
    P::Error: fmt::Debug,
    T: fugit_timer::Timer<TIMER_HZ>,
{
    stepper: Stepper<Motion<P, T>>,
    enable: Option<P>,
    microstep: Option<[P; 3]>,
    config: StepperConfig,
    scale: StepScale,
    max_speed: DefaultNum,
    accel: DefaultNum,
    position: i64,
}

impl<P, T> fmt::Debug for StepperTurntable<P, T>
where
    P: OutputPin,
    P::Error: fmt::Debug,
    T: fugit_timer::Timer<TIMER_HZ>,
{
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("StepperTurntable")
            .field("config", &self.config)
            .field("position", &self.position)
            .finish_non_exhaustive()
    }
}

impl<P, T> StepperTurntable<P, T>
where
    P: OutputPin,
    P::Error: fmt::Debug,
    T: fugit_timer::Timer<TIMER_HZ>,
{
    /// Takes the pins, sets MS1–MS3 for the configured mode and ENABLE low
    /// (driver on), sets DIR, and waits [`A4988::SETTLE_NS`]. The position
    /// starts at 0 (home).
    ///
    /// # Errors
    /// [`TurntableError::Config`] for an invalid configuration,
    /// [`TurntableError::Hardware`] when a pin or the timer fails.
    pub fn new(
        pins: StepperPins<P>,
        mut timer: T,
        config: StepperConfig,
    ) -> Result<Self, TurntableError> {
        let scale = config.scale()?;
        let (speed, accel) = config.step_rates()?;
        let max_speed = DefaultNum::checked_from_num(speed)
            .ok_or_else(|| TurntableError::Config(format!("speed {speed} out of range")))?;
        let accel_n = DefaultNum::checked_from_num(accel)
            .ok_or_else(|| TurntableError::Config(format!("acceleration {accel} out of range")))?;
        let StepperPins {
            step,
            dir,
            mut enable,
            mut microstep,
        } = pins;
        if let Some(ms) = microstep.as_mut() {
            for (pin, high) in ms.iter_mut().zip(config.microstep.pin_levels()) {
                (if high { pin.set_high() } else { pin.set_low() }).map_err(hw("MS pin"))?;
            }
        }
        if let Some(en) = enable.as_mut() {
            en.set_low().map_err(hw("ENABLE pin"))?;
        }
        wait_ns(&mut timer, A4988::SETTLE_NS)?;
        let stepper = Stepper::from_driver(DRV8825::new())
            .enable_direction_control(Pin(dir), Direction::Forward, &mut timer)
            .map_err(hw("DIR pin"))?
            .enable_step_control(Pin(step))
            .enable_motion_control((timer, ExactTrapezoid::new(accel_n), SecondsToTicks));
        let mut table = Self {
            stepper,
            enable,
            microstep,
            config,
            scale,
            max_speed,
            accel: accel_n,
            position: 0,
        };
        if table.config.disable_when_idle {
            table.set_enabled(false)?;
        }
        Ok(table)
    }

    /// The configuration in use.
    #[must_use]
    pub fn config(&self) -> &StepperConfig {
        &self.config
    }

    /// The microstep scale of the table.
    #[must_use]
    pub fn scale(&self) -> StepScale {
        self.scale
    }

    /// The position in microsteps from home (signed, not wrapped).
    #[must_use]
    pub fn position_microsteps(&self) -> i64 {
        self.position
    }

    /// Whether MS1–MS3 are driven by this crate.
    #[must_use]
    pub fn drives_mode_pins(&self) -> bool {
        self.microstep.is_some()
    }

    /// How long a turn of `microsteps` takes with the configured ramp
    /// (sum of the planned step delays).
    #[must_use]
    pub fn planned_duration(&self, microsteps: u32) -> Duration {
        let mut p = ExactTrapezoid::new(self.accel);
        p.enter_position_mode(self.max_speed, microsteps);
        let mut secs = 0.0;
        while let Some(d) = p.next_delay() {
            secs += d.to_num::<f64>();
        }
        Duration::try_from_secs_f64(secs).unwrap_or(Duration::MAX)
    }

    fn set_enabled(&mut self, on: bool) -> Result<(), TurntableError> {
        let Some(en) = self.enable.as_mut() else {
            return Ok(());
        };
        // ENABLE is active low.
        (if on { en.set_low() } else { en.set_high() }).map_err(hw("ENABLE pin"))?;
        if on {
            let timer = self
                .stepper
                .driver_mut()
                .timer_mut()
                .ok_or_else(|| TurntableError::Hardware("timer busy while idle".into()))?;
            wait_ns(timer, A4988::SETTLE_NS)?;
        }
        Ok(())
    }

    /// Plans a turn before anything moves: `None` for a turn of zero
    /// microsteps, else the number of microsteps and the signed motor target
    /// (direction inversion applied).
    ///
    /// # Errors
    /// [`TurntableError::BadAngle`] for an angle the scale refuses or one
    /// move cannot make, [`TurntableError::TooSlow`] when the ramp needs
    /// longer than `timeout`.
    fn plan(&self, degrees: f64, timeout: Duration) -> Result<Option<(u32, i32)>, TurntableError> {
        let steps = self.scale.degrees_to_microsteps(degrees)?;
        if steps == 0 {
            return Ok(None);
        }
        let n = u32::try_from(steps.unsigned_abs())
            .ok()
            .filter(|&n| n <= i32::MAX as u32)
            .ok_or_else(|| TurntableError::BadAngle {
                degrees,
                reason: format!("{steps} microsteps is more than one move can make"),
            })?;
        let planned = self.planned_duration(n);
        if planned > timeout {
            return Err(TurntableError::TooSlow {
                operation: format!("rotate by {degrees} deg"),
                needs: planned,
                timeout,
            });
        }
        let signed = n as i32 * steps.signum() as i32;
        let motor_target = if self.config.invert_direction {
            -signed
        } else {
            signed
        };
        Ok(Some((n, motor_target)))
    }

    /// Steps to `motor_target` (from a position reset to 0), watching the
    /// wall clock; on overrun or a stepping error the motor stops at once.
    /// Returns the first error and whether the move overran `timeout`.
    fn step_to(
        &mut self,
        motor_target: i32,
        timeout: Duration,
    ) -> (Result<(), TurntableError>, bool) {
        let start = Instant::now();
        let mut outcome: Result<(), TurntableError> = Ok(());
        let mut overran = false;
        {
            let mut fut = self.stepper.move_to_position(self.max_speed, motor_target);
            loop {
                match fut.poll() {
                    Poll::Ready(Ok(())) => break,
                    Poll::Ready(Err(e)) => {
                        outcome = Err(hw("stepping")(e));
                        break;
                    }
                    Poll::Pending => {}
                }
                if start.elapsed() > timeout {
                    overran = true;
                    break;
                }
            }
        }
        if overran || outcome.is_err() {
            // Keep the first error; a failing stop is reported only alone.
            let stopped = self.stop_now();
            if outcome.is_ok() {
                outcome = stopped;
            }
        }
        (outcome, overran)
    }

    /// Stops an interrupted move: no further steps, finish the pulse in
    /// flight, return to idle (bounded by the longest step delay).
    fn stop_now(&mut self) -> Result<(), TurntableError> {
        let motion = self.stepper.driver_mut();
        motion.profile_mut().stop();
        let give_up = Instant::now() + Duration::from_secs(3);
        loop {
            match motion.update() {
                Ok(false) => return Ok(()),
                Ok(true) if Instant::now() > give_up => {
                    return Err(TurntableError::Hardware("could not stop the motor".into()));
                }
                Ok(true) => {}
                Err(e) => return Err(hw("stopping")(e)),
            }
        }
    }
}

impl<P, T> Turntable for StepperTurntable<P, T>
where
    P: OutputPin,
    P::Error: fmt::Debug,
    T: fugit_timer::Timer<TIMER_HZ>,
{
    fn rotate_by(&mut self, degrees: f64, timeout: Duration) -> Result<f64, TurntableError> {
        let Some((n, motor_target)) = self.plan(degrees, timeout)? else {
            return Ok(0.0);
        };
        if self.config.disable_when_idle {
            self.set_enabled(true)?;
        }
        self.stepper
            .reset_position(0)
            .map_err(hw("reset position"))?;
        let (mut outcome, overran) = self.step_to(motor_target, timeout);
        let made = self.stepper.driver().current_step();
        let made = if self.config.invert_direction {
            -made
        } else {
            made
        };
        self.position += i64::from(made);
        if self.config.disable_when_idle {
            let off = self.set_enabled(false);
            if outcome.is_ok() {
                outcome = off;
            }
        }
        outcome?;
        if overran {
            return Err(TurntableError::Timeout {
                operation: format!(
                    "rotate by {degrees} deg (stopped after {} of {n} microsteps)",
                    made.unsigned_abs()
                ),
                after: timeout,
            });
        }
        Ok(self.scale.microsteps_to_degrees(i64::from(made)))
    }

    fn angle_deg(&mut self) -> Result<f64, TurntableError> {
        Ok(self.scale.angle_deg(self.position))
    }

    fn home(&mut self) -> Result<(), TurntableError> {
        self.position = 0;
        Ok(())
    }
}
