//! Mechanics and motion limits of a stepper turntable, checked.

use super::Microstep;
use crate::{StepScale, TurntableError};

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

#[cfg(test)]
mod tests {
    use super::StepperConfig;
    use crate::TurntableError;

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
}
