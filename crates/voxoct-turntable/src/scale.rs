//! Exact conversion between degrees of the table and whole microsteps.

use crate::TurntableError;

/// The largest turn one call may ask for, in degrees (ten revolutions).
///
/// Larger or non-finite angles are refused with
/// [`TurntableError::BadAngle`]; a scan never needs more, and a typo
/// (`36000` for `360`) must not spin the table for minutes.
pub const MAX_ROTATION_DEG: f64 = 3600.0;

/// Microsteps per revolution of the *table*, kept as an exact fraction
/// `num / den` so that a gear ratio such as 60:16 loses nothing.
///
/// Positions are whole microsteps (`i64`) counted from home; angles are
/// derived from them, never accumulated, so repeated turns cannot drift:
/// 8 × 45° on an 800-microstep table is 8 × 100 microsteps = exactly one
/// revolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepScale {
    num: u64,
    den: u64,
}

/// Bound on the numerator so every product below fits in `i128` and every
/// quotient is exact in `f64`.
const MAX_NUM: u64 = 1 << 40;

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

impl StepScale {
    /// 800 microsteps per revolution: a 1.8° motor at quarter stepping.
    pub(crate) const QUARTER_200: Self = Self { num: 800, den: 1 };

    /// A table that turns once per `microsteps_per_rev` microsteps.
    ///
    /// # Errors
    /// [`TurntableError::Config`] when `microsteps_per_rev` is 0 or above 2⁴⁰.
    pub fn new(microsteps_per_rev: u64) -> Result<Self, TurntableError> {
        Self::from_ratio(microsteps_per_rev, 1)
    }

    /// A table that turns once per `num / den` microsteps (the fraction is
    /// reduced).
    ///
    /// # Errors
    /// [`TurntableError::Config`] when either part is 0 or the reduced
    /// numerator is above 2⁴⁰.
    pub fn from_ratio(num: u64, den: u64) -> Result<Self, TurntableError> {
        if num == 0 || den == 0 {
            return Err(TurntableError::Config(format!(
                "microsteps per revolution {num}/{den}: both parts must be at least 1"
            )));
        }
        let g = gcd(num, den);
        let (num, den) = (num / g, den / g);
        if num > MAX_NUM {
            return Err(TurntableError::Config(format!(
                "microsteps per revolution {num}/{den}: numerator must be at most 2^40"
            )));
        }
        Ok(Self { num, den })
    }

    /// Microsteps per table revolution (may be fractional with a gear
    /// ratio).
    #[must_use]
    pub fn microsteps_per_rev(&self) -> f64 {
        self.num as f64 / self.den as f64
    }

    /// Degrees of the table per microstep.
    #[must_use]
    pub fn step_deg(&self) -> f64 {
        360.0 * self.den as f64 / self.num as f64
    }

    /// The whole number of microsteps nearest to `degrees` (halves round
    /// away from zero).
    ///
    /// # Errors
    /// [`TurntableError::BadAngle`] for a non-finite angle or one larger in
    /// magnitude than [`MAX_ROTATION_DEG`].
    pub fn degrees_to_microsteps(&self, degrees: f64) -> Result<i64, TurntableError> {
        if !degrees.is_finite() {
            return Err(TurntableError::BadAngle {
                degrees,
                reason: "the angle must be a finite number of degrees".into(),
            });
        }
        if degrees.abs() > MAX_ROTATION_DEG {
            return Err(TurntableError::BadAngle {
                degrees,
                reason: format!("at most {MAX_ROTATION_DEG} degrees per turn"),
            });
        }
        // |degrees| ≤ 3600 and num ≤ 2^40: the product fits easily in i64.
        let steps = (degrees * self.num as f64 / (360.0 * self.den as f64)).round();
        Ok(steps as i64)
    }

    /// The angle of `steps` microsteps, in degrees (signed, not wrapped).
    #[must_use]
    pub fn microsteps_to_degrees(&self, steps: i64) -> f64 {
        // Exact integer product, one rounding at the division.
        (i128::from(steps) * 360 * i128::from(self.den)) as f64 / self.num as f64
    }

    /// The table angle of a position (microsteps from home), in `[0, 360)`.
    #[must_use]
    pub fn angle_deg(&self, position: i64) -> f64 {
        let r = (i128::from(position) * i128::from(self.den)).rem_euclid(i128::from(self.num));
        // r < num ≤ 2^40: r * 360 is exact in f64 and the quotient is < 360.
        let a = (r * 360) as f64 / self.num as f64;
        if a >= 360.0 { 0.0 } else { a }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn quarter_stepping_is_045_degrees() {
        let s = StepScale::new(800).unwrap();
        assert_eq!(s.step_deg(), 0.45);
        assert_eq!(s.degrees_to_microsteps(45.0).unwrap(), 100);
        assert_eq!(s.degrees_to_microsteps(-0.7).unwrap(), -2);
        assert_eq!(
            s.degrees_to_microsteps(0.225).unwrap(),
            1,
            "half rounds away"
        );
        assert_eq!(s.angle_deg(800), 0.0);
        assert_eq!(s.angle_deg(-100), 315.0);
    }

    #[test]
    fn bad_angles_are_refused() {
        let s = StepScale::new(800).unwrap();
        for d in [f64::NAN, f64::INFINITY, -f64::INFINITY, 3600.1, -1e300] {
            assert!(matches!(
                s.degrees_to_microsteps(d),
                Err(TurntableError::BadAngle { .. })
            ));
        }
        assert!(StepScale::new(0).is_err());
        assert!(StepScale::from_ratio(3, 0).is_err());
    }

    #[test]
    fn gear_ratio_is_exact() {
        // 200 steps × 4 microsteps × 60/16 teeth = 3000 microsteps per rev.
        let s = StepScale::from_ratio(800 * 60, 16).unwrap();
        assert_eq!(s.microsteps_per_rev(), 3000.0);
        assert_eq!(s.angle_deg(3000 * 7), 0.0);
        // 800 × 61/16 = 3050: 45° is 381.25 microsteps, not whole.
        let s = StepScale::from_ratio(800 * 61, 16).unwrap();
        assert_eq!(s.degrees_to_microsteps(45.0).unwrap(), 381);
        assert!((s.microsteps_to_degrees(381) - 44.970_491_803).abs() < 1e-6);
    }

    proptest! {
        #[test]
        fn angle_is_in_range_and_periodic(per_rev in 1u64..100_000, pos in -10_000_000i64..10_000_000) {
            let s = StepScale::new(per_rev).unwrap();
            let a = s.angle_deg(pos);
            prop_assert!((0.0..360.0).contains(&a));
            prop_assert_eq!(a, s.angle_deg(pos + per_rev as i64));
        }

        #[test]
        fn rounding_is_within_half_a_step(per_rev in 1u64..100_000, deg in -3600.0f64..3600.0) {
            let s = StepScale::new(per_rev).unwrap();
            let n = s.degrees_to_microsteps(deg).unwrap();
            let real = s.microsteps_to_degrees(n);
            prop_assert!((real - deg).abs() <= s.step_deg() / 2.0 + 1e-9);
        }
    }
}
