//! The Linux GPIO path (feature `gpio`): opening a chip that is missing or
//! not a GPIO chip fails with an error naming it instead of panicking, and a
//! bad configuration is refused before any chip is touched.
#![cfg(feature = "gpio")]

use voxoct_turntable::{GpioPins, GpioTurntable, StepperConfig, TurntableError};

#[test]
fn opening_a_missing_gpio_chip_is_a_clear_error() {
    let pins = GpioPins {
        chip: "/dev/gpiochip-voxoct-does-not-exist".into(),
        ..GpioPins::default()
    };
    let err = GpioTurntable::open(&pins, StepperConfig::default()).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, TurntableError::Hardware(_)), "{msg}");
    assert!(msg.contains("/dev/gpiochip-voxoct-does-not-exist"), "{msg}");
    assert!(msg.contains("How to fix"), "{msg}");
}

#[test]
fn a_file_that_is_not_a_gpio_chip_is_a_clear_error() {
    // /dev/null opens, but answers no GPIO ioctl.
    let pins = GpioPins {
        chip: "/dev/null".into(),
        ..GpioPins::default()
    };
    let err = GpioTurntable::open(&pins, StepperConfig::default()).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, TurntableError::Hardware(_)), "{msg}");
    assert!(msg.contains("GPIO chip /dev/null"), "{msg}");
    assert!(msg.contains("How to fix"), "{msg}");
}

#[test]
fn a_bad_config_is_refused_before_touching_the_chip() {
    let cfg = StepperConfig {
        max_speed_deg_s: 0.0,
        ..StepperConfig::default()
    };
    let err = GpioTurntable::open(&GpioPins::default(), cfg).unwrap_err();
    assert!(matches!(err, TurntableError::Config(_)), "{err}");
}
