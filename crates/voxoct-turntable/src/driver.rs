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

use std::convert::Infallible;
use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::task::Poll;
use std::time::{Duration, Instant};

use embedded_hal_02::digital::v2::OutputPin;
use stepper::compat::Pin;
use stepper::drivers::drv8825::DRV8825;
use stepper::motion_control::{DelayToTicks, SoftwareMotionControl};
use stepper::ramp_maker::trapezoidal::DefaultNum;
use stepper::ramp_maker::{MotionProfile, Trapezoidal};
use stepper::traits::MotionControl;
use stepper::{Direction, Stepper};

use crate::{StepScale, Turntable, TurntableError};

/// Tick rate of the timer the stepper logic runs on: nanoseconds, so the
/// DRV8825 timings (650 ns, 1.9 µs) convert without rounding. Step delays
/// are at most about one second, well within the 32-bit tick range.
pub const TIMER_HZ: u32 = 1_000_000_000;

/// Datasheet timing of the Allegro A4988 and of the signals this crate
/// produces for it.
///
/// The figures come from the A4988 datasheet (Allegro MicroSystems,
/// "A4988 DMOS Microstepping Driver with Translator and Overcurrent
/// Protection", Figure 1 and its table "Timing Requirements") and the TI
/// DRV8825 datasheet (SLVSA73, section 7.6 "Timing Requirements"), whose
/// values the `stepper` crate's DRV8825 driver uses.
#[derive(Debug, Clone, Copy)]
pub struct A4988;

impl A4988 {
    /// A4988: minimum STEP high time, 1 µs (datasheet, timing table, A).
    pub const MIN_STEP_HIGH_NS: u32 = 1_000;
    /// A4988: minimum STEP low time, 1 µs (timing table, B).
    pub const MIN_STEP_LOW_NS: u32 = 1_000;
    /// A4988: minimum setup time of DIR and MSx before the STEP rising edge,
    /// 200 ns (timing table, C).
    pub const MIN_SETUP_NS: u32 = 200;
    /// A4988: minimum hold time of DIR and MSx after the STEP rising edge,
    /// 200 ns (timing table, D).
    pub const MIN_HOLD_NS: u32 = 200;
    /// What this crate drives (stepper's DRV8825 driver, TI DRV8825
    /// datasheet 7.6 `tSU(DIR)`): DIR setup before the first STEP, 650 ns.
    pub const SETUP_NS: u32 = 650;
    /// What this crate drives (DRV8825 datasheet 7.6 `tWH(STEP)`): STEP high
    /// time, 1.9 µs.
    pub const PULSE_NS: u32 = 1_900;
    /// Settling time this crate waits after setting MS1–MS3 or ENABLE,
    /// before the first step: 1 ms, far above the 200 ns setup minimum and
    /// equal to the datasheet's wake-up time from sleep.
    pub const SETTLE_NS: u32 = 1_000_000;
}

// The DRV8825 timing must satisfy the A4988 minimums; checked at compile time.
const _: () = assert!(A4988::PULSE_NS >= A4988::MIN_STEP_HIGH_NS);
const _: () = assert!(A4988::SETUP_NS >= A4988::MIN_SETUP_NS);
const _: () = assert!(A4988::SETUP_NS >= A4988::MIN_HOLD_NS);

/// A4988 microstep mode, selected with the MS1, MS2, MS3 pins.
///
/// | mode | MS1 | MS2 | MS3 | microsteps per full step |
/// |---|---|---|---|---|
/// | full | L | L | L | 1 |
/// | half | H | L | L | 2 |
/// | quarter | L | H | L | 4 |
/// | eighth | H | H | L | 8 |
/// | sixteenth | H | H | H | 16 |
///
/// (A4988 datasheet, Table 1 "Microstepping Resolution Truth Table".) A
/// 1.8° motor at quarter stepping turns 0.45° per microstep, the thesis's
/// setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Microstep {
    /// Full steps.
    Full,
    /// Half steps.
    Half,
    /// Quarter steps (the default).
    #[default]
    Quarter,
    /// Eighth steps.
    Eighth,
    /// Sixteenth steps.
    Sixteenth,
}

impl Microstep {
    /// Every mode, coarsest first.
    pub const ALL: [Self; 5] = [
        Self::Full,
        Self::Half,
        Self::Quarter,
        Self::Eighth,
        Self::Sixteenth,
    ];

    /// Microsteps per full step (1, 2, 4, 8, 16).
    #[must_use]
    pub fn divisor(self) -> u32 {
        match self {
            Self::Full => 1,
            Self::Half => 2,
            Self::Quarter => 4,
            Self::Eighth => 8,
            Self::Sixteenth => 16,
        }
    }

    /// The mode with `divisor` microsteps per full step.
    #[must_use]
    pub fn from_divisor(divisor: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.divisor() == divisor)
    }

    /// Levels of `[MS1, MS2, MS3]` (`true` = high) per the datasheet table.
    #[must_use]
    pub fn pin_levels(self) -> [bool; 3] {
        match self {
            Self::Full => [false, false, false],
            Self::Half => [true, false, false],
            Self::Quarter => [false, true, false],
            Self::Eighth => [true, true, false],
            Self::Sixteenth => [true, true, true],
        }
    }
}

impl FromStr for Microstep {
    type Err = TurntableError;

    /// Accepts `full`, `half`, `quarter`, `eighth`, `sixteenth` or the
    /// divisor `1`, `2`, `4`, `8`, `16`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let m = match s.trim().to_ascii_lowercase().as_str() {
            "full" | "1" => Self::Full,
            "half" | "2" => Self::Half,
            "quarter" | "4" => Self::Quarter,
            "eighth" | "8" => Self::Eighth,
            "sixteenth" | "16" => Self::Sixteenth,
            _ => {
                return Err(TurntableError::Config(format!(
                    "microstep mode {s:?}: expected full, half, quarter, eighth, sixteenth \
                     (or 1, 2, 4, 8, 16)"
                )));
            }
        };
        Ok(m)
    }
}

impl fmt::Display for Microstep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Full => "full",
            Self::Half => "half",
            Self::Quarter => "quarter",
            Self::Eighth => "eighth",
            Self::Sixteenth => "sixteenth",
        })
    }
}

/// Mechanics and motion limits of a stepper turntable.
#[derive(Debug, Clone, PartialEq)]
pub struct StepperConfig {
    /// Full steps per motor revolution (200 for a 1.8° motor).
    pub full_steps_per_rev: u32,
    /// Microstep mode set on MS1–MS3.
    pub microstep: Microstep,
    /// Teeth (or pulley diameter) on the table side of the gearing; the
    /// motor turns `gear_table_teeth / gear_motor_teeth` times per table
    /// revolution. 1 for direct drive.
    pub gear_table_teeth: u32,
    /// Teeth on the motor side of the gearing. 1 for direct drive.
    pub gear_motor_teeth: u32,
    /// Top speed of the table, degrees per second.
    pub max_speed_deg_s: f64,
    /// Acceleration (and deceleration) of the table, degrees per second².
    pub accel_deg_s2: f64,
    /// Swap the meaning of DIR, so positive angles turn the other way.
    pub invert_direction: bool,
    /// Pull ENABLE high (motor free, no holding torque, cooler) between
    /// turns. Off by default: the table holds still while the camera
    /// captures.
    pub disable_when_idle: bool,
}

impl Default for StepperConfig {
    /// 200-step motor, quarter stepping, direct drive, 30°/s, 60°/s².
    fn default() -> Self {
        Self {
            full_steps_per_rev: 200,
            microstep: Microstep::Quarter,
            gear_table_teeth: 1,
            gear_motor_teeth: 1,
            max_speed_deg_s: 30.0,
            accel_deg_s2: 60.0,
            invert_direction: false,
            disable_when_idle: false,
        }
    }
}

/// Highest step rate accepted, microsteps per second: keeps every step delay
/// far above the 1.9 µs pulse.
const MAX_STEP_RATE: f64 = 20_000.0;
/// Lowest acceleration accepted, microsteps per second²: keeps the first
/// step delay (1/√(2a)) under one second.
const MIN_STEP_ACCEL: f64 = 1.0;
/// Highest acceleration accepted, microsteps per second².
const MAX_STEP_ACCEL: f64 = 1_000_000.0;

impl StepperConfig {
    /// The microstep scale of the table.
    ///
    /// # Errors
    /// [`TurntableError::Config`] for zero steps or teeth.
    pub fn scale(&self) -> Result<StepScale, TurntableError> {
        if self.full_steps_per_rev == 0 || self.gear_motor_teeth == 0 || self.gear_table_teeth == 0
        {
            return Err(TurntableError::Config(format!(
                "full_steps_per_rev {}, gear teeth {}:{}: all must be at least 1",
                self.full_steps_per_rev, self.gear_table_teeth, self.gear_motor_teeth
            )));
        }
        let num = u64::from(self.full_steps_per_rev)
            * u64::from(self.microstep.divisor())
            * u64::from(self.gear_table_teeth);
        StepScale::from_ratio(num, u64::from(self.gear_motor_teeth))
    }

    /// Speed and acceleration in microsteps per second (and per second²),
    /// after checking them.
    ///
    /// # Errors
    /// [`TurntableError::Config`] naming the field and its valid range.
    pub fn step_rates(&self) -> Result<(f64, f64), TurntableError> {
        let per_deg = self.scale()?.microsteps_per_rev() / 360.0;
        let speed = self.max_speed_deg_s * per_deg;
        let accel = self.accel_deg_s2 * per_deg;
        if !(speed.is_finite() && speed > 0.0 && speed <= MAX_STEP_RATE) {
            return Err(TurntableError::Config(format!(
                "max_speed_deg_s {}: gives {speed} microsteps/s, must be > 0 and at most {}",
                self.max_speed_deg_s, MAX_STEP_RATE
            )));
        }
        if !(accel.is_finite() && (MIN_STEP_ACCEL..=MAX_STEP_ACCEL).contains(&accel)) {
            return Err(TurntableError::Config(format!(
                "accel_deg_s2 {}: gives {accel} microsteps/s², must be in {MIN_STEP_ACCEL}..={MAX_STEP_ACCEL}",
                self.accel_deg_s2
            )));
        }
        Ok((speed, accel))
    }
}

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

/// A `fugit_timer::Timer` on `std::time::Instant`, for Linux, which has no
/// hardware timer API that stepper could use.
///
/// `start` records a deadline; `wait` returns `WouldBlock` until it has
/// passed. To spare the Pi's CPU, `wait` sleeps through all but the last
/// [`InstantTimer::SPIN`] of a wait and spins for the rest. Jitter: a
/// non-real-time Linux kernel wakes a sleeping thread typically 50–100 µs
/// late, occasionally milliseconds late under load; the spin hides the
/// former for delays longer than `SPIN`. A late wake only stretches one step
/// delay (the motor briefly slows, which never makes it skip); pulses and
/// setup times only ever get longer, never shorter, than asked. The chosen
/// alternative, a busy loop throughout, burns a core for the whole turn.
#[derive(Debug, Clone)]
pub struct InstantTimer {
    epoch: Instant,
    deadline: Option<Instant>,
}

impl InstantTimer {
    /// The final part of every wait that is spun rather than slept.
    pub const SPIN: Duration = Duration::from_micros(200);

    /// A new, idle timer.
    #[must_use]
    pub fn new() -> Self {
        Self {
            epoch: Instant::now(),
            deadline: None,
        }
    }
}

impl Default for InstantTimer {
    fn default() -> Self {
        Self::new()
    }
}

impl fugit_timer::Timer<TIMER_HZ> for InstantTimer {
    type Error = Infallible;

    /// Nanoseconds since the timer was created, wrapping every ~4.29 s (the
    /// 32-bit tick type; stepper only uses durations).
    fn now(&mut self) -> fugit_timer::TimerInstantU32<TIMER_HZ> {
        let ns = self.epoch.elapsed().as_nanos();
        fugit_timer::TimerInstantU32::from_ticks((ns % (1u128 << 32)) as u32)
    }

    fn start(
        &mut self,
        duration: fugit_timer::TimerDurationU32<TIMER_HZ>,
    ) -> Result<(), Infallible> {
        self.deadline = Some(Instant::now() + Duration::from_nanos(u64::from(duration.ticks())));
        Ok(())
    }

    fn cancel(&mut self) -> Result<(), Infallible> {
        self.deadline = None;
        Ok(())
    }

    fn wait(&mut self) -> nb::Result<(), Infallible> {
        let Some(deadline) = self.deadline else {
            return Ok(());
        };
        let now = Instant::now();
        if now >= deadline {
            self.deadline = None;
            return Ok(());
        }
        let left = deadline - now;
        if left > Self::SPIN {
            std::thread::sleep(left - Self::SPIN);
        } else {
            std::hint::spin_loop();
        }
        Err(nb::Error::WouldBlock)
    }
}

/// RampMaker's trapezoidal profile, made exact: a fresh ramp for every move
/// (no speed carried over from an interrupted one) and exactly the commanded
/// number of steps, never one more.
struct ExactTrapezoid {
    accel: DefaultNum,
    inner: Trapezoidal<DefaultNum>,
    left: u32,
}

impl ExactTrapezoid {
    fn new(accel: DefaultNum) -> Self {
        Self {
            accel,
            inner: Trapezoidal::new(accel),
            left: 0,
        }
    }

    fn stop(&mut self) {
        self.left = 0;
    }
}

impl MotionProfile for ExactTrapezoid {
    type Velocity = DefaultNum;
    type Delay = DefaultNum;

    fn enter_position_mode(&mut self, max_velocity: DefaultNum, num_steps: u32) {
        self.inner = Trapezoidal::new(self.accel);
        self.inner.enter_position_mode(max_velocity, num_steps);
        self.left = num_steps;
    }

    fn next_delay(&mut self) -> Option<DefaultNum> {
        if self.left == 0 {
            return None;
        }
        let d = self.inner.next_delay()?;
        self.left -= 1;
        Some(d)
    }
}

/// Converts RampMaker delays (seconds, fixed point) to nanosecond ticks.
struct SecondsToTicks;

impl DelayToTicks<DefaultNum, TIMER_HZ> for SecondsToTicks {
    type Error = Infallible;

    fn delay_to_ticks(
        &self,
        delay: DefaultNum,
    ) -> Result<fugit_timer::TimerDurationU32<TIMER_HZ>, Infallible> {
        let ns = (delay.to_num::<f64>() * f64::from(TIMER_HZ)).round();
        // Never below twice the pulse (stepper subtracts the pulse length).
        let ns = ns.clamp(f64::from(2 * A4988::PULSE_NS), f64::from(u32::MAX)) as u32;
        Ok(fugit_timer::TimerDurationU32::from_ticks(ns))
    }
}

type Drv<P> = DRV8825<(), (), (), (), (), (), (), Pin<P>, Pin<P>>;
type Motion<P, T> = SoftwareMotionControl<Drv<P>, T, ExactTrapezoid, SecondsToTicks, TIMER_HZ>;

fn hw<E: fmt::Debug>(what: &str) -> impl FnOnce(E) -> TurntableError + '_ {
    move |e| TurntableError::Hardware(format!("{what}: {e:?}"))
}

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

fn wait_ns<T: fugit_timer::Timer<TIMER_HZ>>(timer: &mut T, ns: u32) -> Result<(), TurntableError> {
    timer
        .start(fugit_timer::TimerDurationU32::from_ticks(ns))
        .map_err(hw("timer start"))?;
    // Bounded: the timer's own deadline, checked against the wall clock too.
    let give_up = Instant::now() + Duration::from_nanos(u64::from(ns)) + Duration::from_secs(1);
    loop {
        match timer.wait() {
            Ok(()) => return Ok(()),
            Err(nb::Error::Other(e)) => return Err(hw("timer wait")(e)),
            Err(nb::Error::WouldBlock) if Instant::now() > give_up => {
                return Err(TurntableError::Hardware("timer never expired".into()));
            }
            Err(nb::Error::WouldBlock) => {}
        }
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
        let steps = self.scale.degrees_to_microsteps(degrees)?;
        if steps == 0 {
            return Ok(0.0);
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

        if self.config.disable_when_idle {
            self.set_enabled(true)?;
        }
        self.stepper
            .reset_position(0)
            .map_err(hw("reset position"))?;
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

/// The stepper turntable on Linux GPIO character-device pins (feature
/// `gpio`).
#[cfg(feature = "gpio")]
pub type GpioTurntable = StepperTurntable<linux_embedded_hal::CdevPin, InstantTimer>;

#[cfg(feature = "gpio")]
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

#[cfg(test)]
mod tests {
    use super::*;
    use fugit_timer::Timer as _;

    struct NullPin;
    impl OutputPin for NullPin {
        type Error = Infallible;
        fn set_low(&mut self) -> Result<(), Infallible> {
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            Ok(())
        }
    }

    #[test]
    fn documented_timing_is_what_stepper_drives() {
        use stepper::traits::{SetDirection, Step};
        let pulse = <Drv<NullPin> as Step>::PULSE_LENGTH;
        let setup = <Drv<NullPin> as SetDirection>::SETUP_TIME;
        assert_eq!(pulse.ticks(), A4988::PULSE_NS);
        assert_eq!(setup.ticks(), A4988::SETUP_NS);
        // Both convert to the nanosecond timer without rounding.
        let p: fugit_timer::TimerDurationU32<TIMER_HZ> = pulse.convert();
        assert_eq!(p.ticks(), A4988::PULSE_NS);
    }

    #[test]
    fn microstep_table_matches_datasheet() {
        use Microstep::*;
        let table = [
            (Full, [false, false, false], 1),
            (Half, [true, false, false], 2),
            (Quarter, [false, true, false], 4),
            (Eighth, [true, true, false], 8),
            (Sixteenth, [true, true, true], 16),
        ];
        for (m, levels, div) in table {
            assert_eq!(m.pin_levels(), levels);
            assert_eq!(m.divisor(), div);
            assert_eq!(Microstep::from_divisor(div), Some(m));
            assert_eq!(m.to_string().parse::<Microstep>().unwrap(), m);
        }
        assert!("tenth".parse::<Microstep>().is_err());
    }

    #[test]
    fn default_config_is_045_degrees_per_step() {
        let c = StepperConfig::default();
        assert_eq!(c.scale().unwrap().step_deg(), 0.45);
        let geared = StepperConfig {
            gear_table_teeth: 60,
            gear_motor_teeth: 20,
            ..c.clone()
        };
        assert_eq!(geared.scale().unwrap().step_deg(), 0.15);
        let bad = StepperConfig {
            max_speed_deg_s: f64::NAN,
            ..c.clone()
        };
        assert!(matches!(bad.step_rates(), Err(TurntableError::Config(_))));
        let bad = StepperConfig {
            accel_deg_s2: 0.0,
            ..c
        };
        assert!(matches!(bad.step_rates(), Err(TurntableError::Config(_))));
    }

    #[test]
    fn instant_timer_waits_at_least_the_duration() {
        let mut t = InstantTimer::new();
        let start = Instant::now();
        t.start(fugit_timer::TimerDurationU32::from_ticks(2_000_000))
            .unwrap();
        let mut polls = 0u64;
        while t.wait().is_err() {
            polls += 1;
            assert!(polls < 10_000_000, "timer never expired");
        }
        assert!(start.elapsed() >= Duration::from_millis(2));
        assert!(t.wait().is_ok(), "an expired timer stays expired");
    }

    #[test]
    fn exact_trapezoid_gives_exactly_n_steps() {
        let accel = DefaultNum::from_num(1000.0);
        for n in [0u32, 1, 2, 3, 7, 100, 801, 5000] {
            let mut p = ExactTrapezoid::new(accel);
            p.enter_position_mode(DefaultNum::from_num(800.0), n);
            let mut count = 0u32;
            while p.next_delay().is_some() {
                count += 1;
                assert!(count <= n);
            }
            assert_eq!(count, n);
        }
    }
}
