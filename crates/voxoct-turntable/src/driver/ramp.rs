//! The speed ramp: RampMaker's trapezoidal profile, made exact, and the
//! conversion of its delays to timer ticks.

use std::convert::Infallible;

use stepper::motion_control::DelayToTicks;
use stepper::ramp_maker::trapezoidal::DefaultNum;
use stepper::ramp_maker::{MotionProfile, Trapezoidal};

use super::{A4988, TIMER_HZ};

/// RampMaker's trapezoidal profile, made exact: a fresh ramp for every move
/// (no speed carried over from an interrupted one) and exactly the commanded
/// number of steps, never one more.
pub(super) struct ExactTrapezoid {
    accel: DefaultNum,
    inner: Trapezoidal<DefaultNum>,
    left: u32,
}

impl ExactTrapezoid {
    pub(super) fn new(accel: DefaultNum) -> Self {
        Self {
            accel,
            inner: Trapezoidal::new(accel),
            left: 0,
        }
    }

    pub(super) fn stop(&mut self) {
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
pub(super) struct SecondsToTicks;

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

#[cfg(test)]
mod tests {
    use stepper::ramp_maker::MotionProfile;
    use stepper::ramp_maker::trapezoidal::DefaultNum;

    use super::ExactTrapezoid;

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
