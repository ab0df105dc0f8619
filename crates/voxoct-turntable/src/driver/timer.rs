//! The timer the stepper logic waits on: its tick rate, a `std` timer for
//! Linux, and a bounded wait.

use std::convert::Infallible;
use std::time::{Duration, Instant};

use super::hw;
use crate::TurntableError;

/// Tick rate of the timer the stepper logic runs on: nanoseconds, so the
/// DRV8825 timings (650 ns, 1.9 µs) convert without rounding. Step delays
/// are at most about one second, well within the 32-bit tick range.
pub const TIMER_HZ: u32 = 1_000_000_000;

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

/// Waits `ns` nanoseconds on `timer`, giving up (as a hardware error) when the
/// timer has not expired a second after the wall clock says it should have.
pub(super) fn wait_ns<T: fugit_timer::Timer<TIMER_HZ>>(
    timer: &mut T,
    ns: u32,
) -> Result<(), TurntableError> {
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

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use fugit_timer::Timer as _;

    use super::InstantTimer;

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
}
