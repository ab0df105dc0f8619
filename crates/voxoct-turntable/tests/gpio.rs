//! The Linux GPIO path (feature `gpio`): it compiles, and opening pins on a
//! machine without the chip fails with a clear error instead of panicking.
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
fn opening_the_default_chip_here_errors_or_works() {
    let pins = GpioPins::default();
    if pins.chip.exists() {
        println!(
            "note: {} exists; not touching real pins in a test",
            pins.chip.display()
        );
        return;
    }
    let err = GpioTurntable::open(&pins, StepperConfig::default()).unwrap_err();
    assert!(matches!(err, TurntableError::Hardware(_)), "{err}");
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
