//! A turntable that exists only in memory, for the simulated sensor and the
//! tests.

use std::time::Duration;

use crate::{StepScale, Turntable, TurntableError};

/// A simulated table: exact microstep bookkeeping, optionally a finite speed
/// so that turns take real time (and timeouts can be tested).
///
/// With a speed set, a turn whose duration `|angle| / speed` exceeds the
/// timeout is refused before moving, like the stepper driver refuses a turn
/// its motion profile cannot finish in time.
#[derive(Debug, Clone)]
pub struct SimulatedTurntable {
    scale: StepScale,
    position: i64,
    speed_deg_s: Option<f64>,
    turns: u64,
}

impl Default for SimulatedTurntable {
    /// 800 microsteps per revolution (a 1.8° motor at quarter stepping,
    /// 0.45° per step, the thesis's setting), instantaneous turns.
    fn default() -> Self {
        Self {
            scale: StepScale::QUARTER_200,
            position: 0,
            speed_deg_s: None,
            turns: 0,
        }
    }
}

impl SimulatedTurntable {
    /// A table with `microsteps_per_rev` microsteps per revolution and
    /// instantaneous turns.
    ///
    /// # Errors
    /// [`TurntableError::Config`] when `microsteps_per_rev` is 0 or above 2⁴⁰.
    pub fn new(microsteps_per_rev: u64) -> Result<Self, TurntableError> {
        Ok(Self::with_scale(StepScale::new(microsteps_per_rev)?))
    }

    /// A table with the given microstep scale (e.g. that of a
    /// [`StepperConfig`](crate::StepperConfig)) and instantaneous turns.
    #[must_use]
    pub fn with_scale(scale: StepScale) -> Self {
        Self {
            scale,
            ..Self::default()
        }
    }

    /// The speeds [`SimulatedTurntable::with_speed`] accepts, degrees per second.
    pub const SPEED_RANGE_DEG_S: (f64, f64) = (0.01, 1e6);

    /// Makes turns take `|angle| / deg_per_s` seconds of real time.
    ///
    /// # Errors
    /// [`TurntableError::Config`] unless `deg_per_s` is within
    /// [`SimulatedTurntable::SPEED_RANGE_DEG_S`].
    pub fn with_speed(mut self, deg_per_s: f64) -> Result<Self, TurntableError> {
        let (lo, hi) = Self::SPEED_RANGE_DEG_S;
        if !(deg_per_s.is_finite() && (lo..=hi).contains(&deg_per_s)) {
            return Err(TurntableError::Config(format!(
                "simulated speed {deg_per_s} deg/s: must be between {lo} (a turn in 10 hours) \
                 and {hi} deg/s"
            )));
        }
        self.speed_deg_s = Some(deg_per_s);
        Ok(self)
    }

    /// The position in microsteps from home (signed, not wrapped).
    #[must_use]
    pub fn position_microsteps(&self) -> i64 {
        self.position
    }

    /// The microstep scale.
    #[must_use]
    pub fn scale(&self) -> StepScale {
        self.scale
    }

    /// How many turns (calls of `rotate_by` that moved) were made.
    #[must_use]
    pub fn turns(&self) -> u64 {
        self.turns
    }
}

impl Turntable for SimulatedTurntable {
    fn rotate_by(&mut self, degrees: f64, timeout: Duration) -> Result<f64, TurntableError> {
        let steps = self.scale.degrees_to_microsteps(degrees)?;
        let real = self.scale.microsteps_to_degrees(steps);
        if let Some(speed) = self.speed_deg_s {
            let took = Duration::try_from_secs_f64(real.abs() / speed).unwrap_or(Duration::MAX);
            if took > timeout {
                return Err(TurntableError::TooSlow {
                    operation: format!("rotate by {real} deg"),
                    needs: took,
                    timeout,
                });
            }
            std::thread::sleep(took);
        }
        self.position += steps;
        if steps != 0 {
            self.turns += 1;
        }
        Ok(real)
    }

    fn angle_deg(&mut self) -> Result<f64, TurntableError> {
        Ok(self.scale.angle_deg(self.position))
    }

    fn home(&mut self) -> Result<(), TurntableError> {
        self.position = 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const T: Duration = Duration::from_secs(1);

    #[test]
    fn eight_45s_come_back_to_zero() {
        let mut t = SimulatedTurntable::default();
        for i in 1..=8 {
            assert_eq!(t.rotate_by(45.0, T).unwrap(), 45.0);
            assert_eq!(t.angle_deg().unwrap(), (45 * (i % 8)) as f64);
        }
        assert_eq!(t.position_microsteps(), 800);
        assert_eq!(t.angle_deg().unwrap(), 0.0);
    }

    #[test]
    fn reports_the_angle_really_turned() {
        let mut t = SimulatedTurntable::default();
        assert_eq!(t.rotate_by(1.0, T).unwrap(), 0.9);
        assert_eq!(t.rotate_by(-1.0, T).unwrap(), -0.9);
        assert_eq!(t.angle_deg().unwrap(), 0.0);
        assert_eq!(t.rotate_by(-90.0, T).unwrap(), -90.0);
        assert_eq!(t.angle_deg().unwrap(), 270.0);
        t.home().unwrap();
        assert_eq!(t.angle_deg().unwrap(), 0.0);
    }

    #[test]
    fn slow_table_times_out_without_moving() {
        let mut t = SimulatedTurntable::default().with_speed(1000.0).unwrap();
        let err = t.rotate_by(90.0, Duration::from_millis(10)).unwrap_err();
        assert!(matches!(err, TurntableError::TooSlow { .. }), "{err}");
        assert!(SimulatedTurntable::default().with_speed(1e-20).is_err());
        assert_eq!(t.position_microsteps(), 0);
        let start = std::time::Instant::now();
        assert_eq!(t.rotate_by(45.0, T).unwrap(), 45.0);
        assert!(start.elapsed() >= Duration::from_millis(45));
        assert!(SimulatedTurntable::default().with_speed(0.0).is_err());
    }

    #[test]
    fn boxed_and_borrowed_tables_forward_every_call() {
        let mut sim = SimulatedTurntable::default();
        {
            // Box<dyn> around &mut around &mut dyn: all three forwarding impls.
            let mut by_ref: &mut dyn Turntable = &mut sim;
            let mut table: Box<dyn Turntable + '_> = Box::new(&mut by_ref);
            assert_eq!(table.rotate_by(90.0, T).unwrap(), 90.0);
            assert_eq!(table.rotate_by(-1.0, T).unwrap(), -0.9);
            assert_eq!(table.angle_deg().unwrap(), 89.1);
            let err = table.rotate_by(f64::NAN, T).unwrap_err();
            assert!(matches!(err, TurntableError::BadAngle { .. }), "{err}");
            table.home().unwrap();
            assert_eq!(table.angle_deg().unwrap(), 0.0);
        }
        // The calls reached the simulated table itself.
        assert_eq!(sim.turns(), 2);
        assert_eq!(sim.position_microsteps(), 0);
        assert_eq!(sim.rotate_by(45.0, T).unwrap(), 45.0);
        assert_eq!(sim.position_microsteps(), 100);
    }

    proptest! {
        #[test]
        fn angle_matches_sum_of_reported_turns(turns in proptest::collection::vec(-400.0f64..400.0, 0..20)) {
            let mut t = SimulatedTurntable::default();
            let mut total = 0.0;
            for d in turns {
                total += t.rotate_by(d, T).unwrap();
            }
            let expect = total.rem_euclid(360.0);
            let got = t.angle_deg().unwrap();
            let diff = (got - expect).abs();
            prop_assert!(diff < 1e-6 || (360.0 - diff) < 1e-6, "{got} vs {expect}");
        }
    }
}
