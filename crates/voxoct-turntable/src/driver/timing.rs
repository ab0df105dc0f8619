//! The A4988's datasheet timing, and the timing this crate drives it with.

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

#[cfg(test)]
mod tests {
    use std::convert::Infallible;

    use embedded_hal_02::digital::v2::OutputPin;

    use super::A4988;
    use crate::driver::TIMER_HZ;
    use crate::driver::stepper_turntable::Drv;

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
}
