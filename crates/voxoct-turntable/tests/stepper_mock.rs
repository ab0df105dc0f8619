//! The stepper logic driven with mock pins and a mock (virtual-time) timer:
//! the recorded edges must show the A4988 getting what it needs.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use proptest::prelude::*;
use voxoct_turntable::embedded_hal_02::digital::v2::OutputPin;
use voxoct_turntable::fugit_timer::{self, TimerDurationU32, TimerInstantU32};
use voxoct_turntable::{
    A4988, Microstep, StepperConfig, StepperPins, StepperTurntable, TIMER_HZ, Turntable,
    TurntableError,
};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Name {
    Step,
    Dir,
    Enable,
    Ms1,
    Ms2,
    Ms3,
}

#[derive(Debug, Clone, Copy)]
struct Edge {
    pin: Name,
    high: bool,
    /// Virtual nanoseconds.
    t: u64,
}

#[derive(Clone, Default)]
struct Rig {
    clock: Arc<AtomicU64>,
    log: Arc<Mutex<Vec<Edge>>>,
}

#[derive(Debug)]
struct PinFailed;

struct MockPin {
    name: Name,
    rig: Rig,
    fail_after: Option<usize>,
    writes: usize,
}

impl OutputPin for MockPin {
    type Error = PinFailed;
    fn set_low(&mut self) -> Result<(), PinFailed> {
        self.set(false)
    }
    fn set_high(&mut self) -> Result<(), PinFailed> {
        self.set(true)
    }
}

impl MockPin {
    fn set(&mut self, high: bool) -> Result<(), PinFailed> {
        self.writes += 1;
        if self.fail_after.is_some_and(|n| self.writes > n) {
            return Err(PinFailed);
        }
        let t = self.rig.clock.load(Ordering::SeqCst);
        self.rig.log.lock().unwrap().push(Edge {
            pin: self.name,
            high,
            t,
        });
        Ok(())
    }
}

/// Advances virtual time to the deadline on `wait`; optionally also sleeps
/// for real, to make a move overrun its wall-clock timeout.
struct MockTimer {
    rig: Rig,
    deadline: Option<u64>,
    real_sleep: Duration,
}

impl fugit_timer::Timer<TIMER_HZ> for MockTimer {
    type Error = std::convert::Infallible;
    fn now(&mut self) -> TimerInstantU32<TIMER_HZ> {
        TimerInstantU32::from_ticks(self.rig.clock.load(Ordering::SeqCst) as u32)
    }
    fn start(&mut self, d: TimerDurationU32<TIMER_HZ>) -> Result<(), Self::Error> {
        self.deadline = Some(self.rig.clock.load(Ordering::SeqCst) + u64::from(d.ticks()));
        Ok(())
    }
    fn cancel(&mut self) -> Result<(), Self::Error> {
        self.deadline = None;
        Ok(())
    }
    fn wait(&mut self) -> nb::Result<(), Self::Error> {
        if let Some(d) = self.deadline.take() {
            if !self.real_sleep.is_zero() {
                std::thread::sleep(self.real_sleep);
            }
            self.rig.clock.fetch_max(d, Ordering::SeqCst);
        }
        Ok(())
    }
}

impl Rig {
    fn pin(&self, name: Name) -> MockPin {
        MockPin {
            name,
            rig: self.clone(),
            fail_after: None,
            writes: 0,
        }
    }

    fn table(&self, config: StepperConfig) -> StepperTurntable<MockPin, MockTimer> {
        self.table_with(config, Duration::ZERO, None)
    }

    fn table_with(
        &self,
        config: StepperConfig,
        real_sleep: Duration,
        step_fails_after: Option<usize>,
    ) -> StepperTurntable<MockPin, MockTimer> {
        let mut step = self.pin(Name::Step);
        step.fail_after = step_fails_after;
        let pins = StepperPins {
            step,
            dir: self.pin(Name::Dir),
            enable: Some(self.pin(Name::Enable)),
            microstep: Some([
                self.pin(Name::Ms1),
                self.pin(Name::Ms2),
                self.pin(Name::Ms3),
            ]),
        };
        let timer = MockTimer {
            rig: self.clone(),
            deadline: None,
            real_sleep,
        };
        StepperTurntable::new(pins, timer, config).unwrap()
    }

    fn take(&self) -> Vec<Edge> {
        std::mem::take(&mut *self.log.lock().unwrap())
    }
}

fn rising_steps(edges: &[Edge]) -> Vec<u64> {
    edges
        .iter()
        .filter(|e| e.pin == Name::Step && e.high)
        .map(|e| e.t)
        .collect()
}

fn last_level(edges: &[Edge], pin: Name) -> Option<bool> {
    edges.iter().rev().find(|e| e.pin == pin).map(|e| e.high)
}

/// A fast configuration so the mock runs take few virtual steps of ramp.
fn fast() -> StepperConfig {
    StepperConfig {
        max_speed_deg_s: 180.0,
        accel_deg_s2: 720.0,
        ..StepperConfig::default()
    }
}

const T: Duration = Duration::from_secs(30);

#[test]
fn mode_pins_follow_the_datasheet_table() {
    for mode in Microstep::ALL {
        let rig = Rig::default();
        let _table = rig.table(StepperConfig {
            microstep: mode,
            ..fast()
        });
        let edges = rig.take();
        let got = [Name::Ms1, Name::Ms2, Name::Ms3].map(|p| last_level(&edges, p).unwrap());
        assert_eq!(got, mode.pin_levels(), "{mode}");
        // The driver is enabled (ENABLE is active low).
        assert_eq!(last_level(&edges, Name::Enable), Some(false));
        // MS pins are set before DIR and well before any step.
        let ms_done = edges
            .iter()
            .filter(|e| e.pin == Name::Ms3)
            .map(|e| e.t)
            .max()
            .unwrap();
        let dir_first = edges.iter().find(|e| e.pin == Name::Dir).unwrap().t;
        assert!(dir_first >= ms_done + u64::from(A4988::SETTLE_NS));
    }
    // Quarter stepping: L H L.
    assert_eq!(Microstep::Quarter.pin_levels(), [false, true, false]);
}

#[test]
fn forward_turn_sets_dir_first_and_steps_exactly() {
    let rig = Rig::default();
    let mut table = rig.table(fast());
    rig.take();
    assert_eq!(table.rotate_by(45.0, T).unwrap(), 45.0);
    let edges = rig.take();
    let steps = rising_steps(&edges);
    assert_eq!(steps.len(), 100, "45° at 0.45° per microstep");
    // DIR is set high (forward) before the first STEP edge, with setup time.
    let first_step_idx = edges.iter().position(|e| e.pin == Name::Step).unwrap();
    let dir = edges[..first_step_idx]
        .iter()
        .rev()
        .find(|e| e.pin == Name::Dir)
        .expect("DIR set before the first step");
    assert!(dir.high);
    assert!(steps[0] - dir.t >= u64::from(A4988::MIN_SETUP_NS));
    assert!(steps[0] - dir.t >= u64::from(A4988::SETUP_NS));
    // DIR never changes during the move.
    assert!(edges[first_step_idx..].iter().all(|e| e.pin != Name::Dir));
    // Every pulse is at least the A4988's minimum high time, and STEP ends low.
    let step_edges: Vec<&Edge> = edges.iter().filter(|e| e.pin == Name::Step).collect();
    assert_eq!(step_edges.len(), 200);
    for pair in step_edges.chunks(2) {
        assert!(pair[0].high && !pair[1].high);
        assert!(pair[1].t - pair[0].t >= u64::from(A4988::MIN_STEP_HIGH_NS));
    }
    assert_eq!(table.position_microsteps(), 100);
    assert_eq!(table.angle_deg().unwrap(), 45.0);
}

#[test]
fn the_speed_ramps_up_and_down() {
    let rig = Rig::default();
    let mut table = rig.table(StepperConfig::default()); // 30°/s, 60°/s²
    rig.take();
    table.rotate_by(90.0, T).unwrap();
    let steps = rising_steps(&rig.take());
    assert_eq!(steps.len(), 200);
    let gaps: Vec<u64> = steps.windows(2).map(|w| w[1] - w[0]).collect();
    let min_gap = *gaps.iter().min().unwrap();
    // Top speed 30°/s = 66.7 microsteps/s: no gap much shorter than 15 ms.
    assert!(
        min_gap as f64 >= 0.95e9 / (30.0 / 0.45),
        "min gap {min_gap} ns"
    );
    // Starts and ends slowly.
    assert!(gaps[0] > 2 * min_gap, "first gap {} vs {min_gap}", gaps[0]);
    assert!(gaps[gaps.len() - 1] > 2 * min_gap);
    // And the whole turn takes about the planned time (virtual clock).
    let took = steps[steps.len() - 1] - steps[0];
    let planned = table.planned_duration(200).as_nanos() as u64;
    assert!(
        took <= planned && took * 10 >= planned * 9,
        "{took} vs {planned}"
    );
}

#[test]
fn reverse_turns_set_dir_low_and_come_back() {
    let rig = Rig::default();
    let mut table = rig.table(fast());
    table.rotate_by(90.0, T).unwrap();
    rig.take();
    assert_eq!(table.rotate_by(-135.0, T).unwrap(), -135.0);
    let edges = rig.take();
    assert_eq!(rising_steps(&edges).len(), 300);
    let first_step_idx = edges.iter().position(|e| e.pin == Name::Step).unwrap();
    assert_eq!(last_level(&edges[..first_step_idx], Name::Dir), Some(false));
    assert_eq!(table.angle_deg().unwrap(), 315.0);
    assert_eq!(table.position_microsteps(), -100);
}

#[test]
fn inverted_direction_swaps_dir_only() {
    let rig = Rig::default();
    let mut table = rig.table(StepperConfig {
        invert_direction: true,
        ..fast()
    });
    rig.take();
    assert_eq!(table.rotate_by(45.0, T).unwrap(), 45.0);
    let edges = rig.take();
    let first_step_idx = edges.iter().position(|e| e.pin == Name::Step).unwrap();
    assert_eq!(last_level(&edges[..first_step_idx], Name::Dir), Some(false));
    assert_eq!(table.angle_deg().unwrap(), 45.0);
}

#[test]
fn eight_45s_return_to_exactly_zero() {
    let rig = Rig::default();
    let mut table = rig.table(fast());
    rig.take();
    for _ in 0..8 {
        assert_eq!(table.rotate_by(45.0, T).unwrap(), 45.0);
    }
    assert_eq!(rising_steps(&rig.take()).len(), 800);
    assert_eq!(table.angle_deg().unwrap(), 0.0);
    assert_eq!(table.position_microsteps(), 800);
    table.home().unwrap();
    assert_eq!(table.position_microsteps(), 0);
}

#[test]
fn sixteenth_stepping_with_gearing() {
    let rig = Rig::default();
    let mut table = rig.table(StepperConfig {
        microstep: Microstep::Sixteenth,
        gear_table_teeth: 60,
        gear_motor_teeth: 20,
        max_speed_deg_s: 60.0,
        accel_deg_s2: 240.0,
        ..StepperConfig::default()
    });
    rig.take();
    // 200 × 16 × 3 = 9600 microsteps per table revolution: 45° = 1200.
    assert_eq!(table.rotate_by(45.0, T).unwrap(), 45.0);
    assert_eq!(rising_steps(&rig.take()).len(), 1200);
}

#[test]
fn too_long_a_turn_is_refused_before_moving() {
    let rig = Rig::default();
    let mut table = rig.table(StepperConfig::default()); // 30°/s
    rig.take();
    let err = table.rotate_by(180.0, Duration::from_secs(2)).unwrap_err();
    assert!(matches!(err, TurntableError::TooSlow { .. }), "{err}");
    assert!(err.to_string().contains("refused before moving"), "{err}");
    assert!(rising_steps(&rig.take()).is_empty());
    assert_eq!(table.position_microsteps(), 0);
}

#[test]
fn an_overrunning_turn_stops_and_keeps_the_steps_made() {
    let rig = Rig::default();
    // Each timer wait really sleeps 5 ms (two waits per step): 100 steps
    // need about 1 s of wall time, but the plan says about 0.5 s, so a
    // timeout of plan + 50 ms passes planning and then overruns.
    let mut table = rig.table_with(fast(), Duration::from_millis(5), None);
    rig.take();
    let timeout = table.planned_duration(100) + Duration::from_millis(50);
    assert!(timeout < Duration::from_millis(800), "{timeout:?}");
    let err = table.rotate_by(45.0, timeout).unwrap_err();
    assert!(matches!(err, TurntableError::Timeout { .. }), "{err}");
    let edges = rig.take();
    let made = rising_steps(&edges).len() as i64;
    assert!(made > 0 && made < 100, "made {made}");
    assert_eq!(
        table.position_microsteps(),
        made,
        "position = steps really made"
    );
    assert_eq!(last_level(&edges, Name::Step), Some(false), "STEP left low");
    // The table still works afterwards, from a standstill.
    let mut quick = rig.table(fast());
    assert_eq!(quick.rotate_by(45.0, T).unwrap(), 45.0);
}

#[test]
fn a_failing_pin_is_a_hardware_error() {
    let rig = Rig::default();
    let mut table = rig.table_with(fast(), Duration::ZERO, Some(7));
    let err = table.rotate_by(45.0, T).unwrap_err();
    assert!(matches!(err, TurntableError::Hardware(_)), "{err}");
    assert!(err.to_string().contains("PinFailed"), "{err}");
}

#[test]
fn disable_when_idle_frees_the_motor_between_turns() {
    let rig = Rig::default();
    let mut table = rig.table(StepperConfig {
        disable_when_idle: true,
        ..fast()
    });
    assert_eq!(
        last_level(&rig.take(), Name::Enable),
        Some(true),
        "off at rest"
    );
    table.rotate_by(9.0, T).unwrap();
    let edges = rig.take();
    let first = edges.iter().position(|e| e.pin == Name::Step).unwrap();
    let last = edges.iter().rposition(|e| e.pin == Name::Step).unwrap();
    assert_eq!(last_level(&edges[..first], Name::Enable), Some(false));
    assert!(edges[first..last].iter().all(|e| e.pin != Name::Enable));
    assert_eq!(last_level(&edges, Name::Enable), Some(true));
}

#[test]
fn bad_configs_and_angles_are_refused() {
    let rig = Rig::default();
    let pins = || StepperPins {
        step: rig.pin(Name::Step),
        dir: rig.pin(Name::Dir),
        enable: None,
        microstep: None,
    };
    let timer = || MockTimer {
        rig: rig.clone(),
        deadline: None,
        real_sleep: Duration::ZERO,
    };
    for bad in [
        StepperConfig {
            full_steps_per_rev: 0,
            ..fast()
        },
        StepperConfig {
            max_speed_deg_s: -1.0,
            ..fast()
        },
        StepperConfig {
            max_speed_deg_s: 1e9,
            ..fast()
        },
        StepperConfig {
            accel_deg_s2: f64::INFINITY,
            ..fast()
        },
    ] {
        let r = StepperTurntable::new(pins(), timer(), bad);
        assert!(matches!(r, Err(TurntableError::Config(_))));
    }
    let mut table = StepperTurntable::new(pins(), timer(), fast()).unwrap();
    assert!(!table.drives_mode_pins());
    for d in [f64::NAN, 1e6] {
        assert!(matches!(
            table.rotate_by(d, T),
            Err(TurntableError::BadAngle { .. })
        ));
    }
    assert_eq!(table.rotate_by(0.1, T).unwrap(), 0.0, "rounds to no step");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn step_count_matches_commanded_microsteps(turns in proptest::collection::vec(-200.0f64..200.0, 1..5)) {
        let rig = Rig::default();
        let mut table = rig.table(fast());
        rig.take();
        let mut expected_edges = 0u64;
        let mut expected_pos = 0i64;
        for d in turns {
            let turned = table.rotate_by(d, T).unwrap();
            let n = (turned / 0.45).round() as i64;
            prop_assert!((turned - d).abs() <= 0.225 + 1e-9);
            expected_edges += n.unsigned_abs();
            expected_pos += n;
        }
        prop_assert_eq!(rising_steps(&rig.take()).len() as u64, expected_edges);
        prop_assert_eq!(table.position_microsteps(), expected_pos);
        let a = table.angle_deg().unwrap();
        prop_assert!((0.0..360.0).contains(&a));
    }
}

#[test]
fn the_instant_timer_drives_a_real_time_turn() {
    use voxoct_turntable::InstantTimer;
    let rig = Rig::default();
    let pins = StepperPins {
        step: rig.pin(Name::Step),
        dir: rig.pin(Name::Dir),
        enable: None,
        microstep: None,
    };
    let mut table = StepperTurntable::new(pins, InstantTimer::new(), fast()).unwrap();
    rig.take();
    let planned = table.planned_duration(20);
    let start = std::time::Instant::now();
    assert_eq!(table.rotate_by(9.0, T).unwrap(), 9.0);
    let took = start.elapsed();
    assert_eq!(rising_steps(&rig.take()).len(), 20);
    // Never faster than planned; late wake-ups only ever slow it down.
    assert!(took >= planned, "{took:?} < {planned:?}");
    assert!(
        took < planned * 3 + Duration::from_millis(100),
        "{took:?} vs {planned:?}"
    );
}
