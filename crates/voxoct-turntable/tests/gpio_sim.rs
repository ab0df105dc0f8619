//! The real GPIO path (feature `gpio`: `GpioTurntable` on linux-embedded-hal's `CdevPin`s)
//! against the kernel's GPIO simulator, `gpio-sim`, where the machine offers it.
//!
//! gpio-sim (Linux ≥ 5.17, `CONFIG_GPIO_SIM`) makes simulated chips through configfs
//! (`/sys/kernel/config/gpio-sim`): a chip appears as `/dev/gpiochipN`, opened through the same
//! character-device API as the Raspberry Pi's, and sysfs shows each line's level
//! (`/sys/devices/platform/<dev_name>/<chip_name>/sim_gpio<L>/value`). The test skips, saying
//! why, when configfs, the module or the permission to use them is missing — as on a
//! container or a VM kernel without modules.
#![cfg(feature = "gpio")]

use std::path::{Path, PathBuf};
use std::time::Duration;

use voxoct_turntable::{GpioPins, GpioTurntable, Microstep, StepperConfig, Turntable};

const CONFIGFS: &str = "/sys/kernel/config/gpio-sim";

/// A live simulated chip, torn down on drop.
struct SimChip {
    device: PathBuf,
    /// `/dev/gpiochipN`.
    dev: PathBuf,
    /// `/sys/devices/platform/<dev_name>/<chip_name>`.
    sysfs: PathBuf,
}

impl SimChip {
    /// Makes a chip of `lines` lines, or says why it cannot.
    fn create(lines: u32) -> Result<Self, String> {
        if !Path::new(CONFIGFS).is_dir() {
            // Try to load the module (root, a kernel with modules); ignore failures.
            let _ = std::process::Command::new("modprobe")
                .arg("gpio-sim")
                .status();
        }
        if !Path::new(CONFIGFS).is_dir() {
            return Err(format!(
                "{CONFIGFS} is absent (no configfs mount or no gpio-sim in this kernel)"
            ));
        }
        let device = Path::new(CONFIGFS).join(format!("voxoct-test-{}", std::process::id()));
        std::fs::create_dir(&device).map_err(|e| format!("mkdir {}: {e}", device.display()))?;
        let mut chip = Self {
            device,
            dev: PathBuf::new(),
            sysfs: PathBuf::new(),
        };
        let bank = chip.device.join("gpio-bank0");
        let io = |r: std::io::Result<()>, what: &str| r.map_err(|e| format!("{what}: {e}"));
        io(std::fs::create_dir(&bank), "mkdir gpio-bank0")?;
        io(
            std::fs::write(bank.join("num_lines"), lines.to_string()),
            "num_lines",
        )?;
        io(std::fs::write(chip.device.join("live"), "1"), "live")?;
        let read = |p: PathBuf| {
            std::fs::read_to_string(&p)
                .map(|s| s.trim().to_owned())
                .map_err(|e| format!("{}: {e}", p.display()))
        };
        let chip_name = read(bank.join("chip_name"))?;
        let dev_name = read(chip.device.join("dev_name"))?;
        chip.dev = Path::new("/dev").join(&chip_name);
        chip.sysfs = Path::new("/sys/devices/platform")
            .join(dev_name)
            .join(chip_name);
        Ok(chip)
    }

    /// The level the chip's user drives on `line`.
    fn level(&self, line: u32) -> bool {
        let p = self.sysfs.join(format!("sim_gpio{line}/value"));
        let v = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        v.trim() == "1"
    }
}

impl Drop for SimChip {
    fn drop(&mut self) {
        let _ = std::fs::write(self.device.join("live"), "0");
        let _ = std::fs::remove_dir(self.device.join("gpio-bank0"));
        let _ = std::fs::remove_dir(&self.device);
    }
}

#[test]
fn the_stepper_drives_simulated_gpio_lines() {
    let chip = match SimChip::create(32) {
        Ok(c) => c,
        Err(why) => {
            println!("skipped: no gpio-sim here: {why}");
            return;
        }
    };
    let pins = GpioPins {
        chip: chip.dev.clone(),
        ..GpioPins::default()
    };
    let [ms1, ms2, ms3] = pins.microstep.expect("default pins drive MS1..3");
    let enable = pins.enable.expect("default pins drive ENABLE");
    let config = StepperConfig {
        microstep: Microstep::Quarter,
        max_speed_deg_s: 360.0,
        accel_deg_s2: 3600.0,
        disable_when_idle: true,
        ..StepperConfig::default()
    };
    let mut table = GpioTurntable::open(&pins, config).expect("open the simulated chip");
    // Quarter stepping is MS1 L, MS2 H, MS3 L (A4988 datasheet); idle means ENABLE high.
    assert_eq!(
        [chip.level(ms1), chip.level(ms2), chip.level(ms3)],
        [false, true, false]
    );
    assert!(chip.level(enable), "the driver is released while idle");

    let t = Duration::from_secs(10);
    assert_eq!(table.rotate_by(9.0, t).unwrap(), 9.0);
    assert_eq!(table.angle_deg().unwrap(), 9.0);
    let forward = chip.level(pins.dir);
    assert!(chip.level(enable), "released again after the turn");
    assert_eq!(table.rotate_by(-4.5, t).unwrap(), -4.5);
    assert_eq!(table.angle_deg().unwrap(), 4.5);
    assert_ne!(
        chip.level(pins.dir),
        forward,
        "DIR flips for a reverse turn"
    );
    assert!(!chip.level(pins.step), "STEP rests low");
    drop(table);
}
