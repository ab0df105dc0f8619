//! `turntable_server`: the program the Raspberry Pi runs. It serves one
//! turntable over TCP with the `VOXOCT-TT/1` protocol (see
//! `voxoct_turntable::protocol`); the scanning host connects with
//! `RemoteTurntable`.
//!
//! ```sh
//! # On any machine: a simulated table on loopback (for trying the protocol).
//! cargo run --example turntable_server
//! # On the Pi: real pins, reachable from the LAN, with a shared secret.
//! VOXOCT_TURNTABLE_TOKEN=s3cret cargo run --release --features gpio --example turntable_server -- \
//!     --gpio --listen 0.0.0.0:7878 --microstep quarter --max-speed 30 --accel 60
//! ```
//!
//! Stop it with Ctrl-C or `SIGTERM`: a turn in progress finishes (with its
//! deceleration ramp) and gets its reply, clients are told the server is
//! shutting down, and the program exits with status 0. Without a token anyone
//! who can reach the port can turn the table: the library refuses to listen
//! beyond loopback without one unless `--insecure` is given.

use std::net::TcpListener;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use voxoct_turntable::{
    GpioPins, Microstep, ServerConfig, SimulatedTurntable, StepperConfig, Turntable, serve,
    token_from_env,
};

/// Serve a turntable (A4988 stepper on GPIO, or simulated) over TCP.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Address to listen on, HOST:PORT. Use 0.0.0.0:7878 to accept the LAN.
    #[arg(long, default_value = "127.0.0.1:7878")]
    listen: String,
    /// Shared secret clients must present (printable ASCII, no spaces).
    /// Default: the VOXOCT_TURNTABLE_TOKEN environment variable, if set.
    #[arg(long)]
    token: Option<String>,
    /// Listen beyond loopback without a token.
    #[arg(long)]
    insecure: bool,
    /// Drive the real stepper on GPIO (needs a build with `--features gpio`).
    #[arg(long)]
    gpio: bool,
    /// GPIO character device.
    #[arg(long, default_value = "/dev/gpiochip0")]
    gpio_chip: PathBuf,
    /// GPIO line (BCM number) of STEP.
    #[arg(long, default_value_t = 23)]
    step_pin: u32,
    /// GPIO line (BCM number) of DIR.
    #[arg(long, default_value_t = 24)]
    dir_pin: u32,
    /// GPIO line (BCM number) of ENABLE, or `none` when tied to GND.
    #[arg(long, default_value = "25")]
    enable_pin: String,
    /// GPIO lines of MS1,MS2,MS3 (e.g. `17,27,22`), or `none` when
    /// hard-wired to match --microstep.
    #[arg(long, default_value = "17,27,22")]
    ms_pins: String,
    /// Full steps per motor revolution.
    #[arg(long, default_value_t = 200)]
    steps_per_rev: u32,
    /// Microstep mode: full, half, quarter, eighth, sixteenth.
    #[arg(long, default_value = "quarter")]
    microstep: Microstep,
    /// Gear ratio TABLE_TEETH:MOTOR_TEETH (1:1 for direct drive).
    #[arg(long, default_value = "1:1")]
    gear: String,
    /// Top speed of the table, degrees per second.
    #[arg(long, default_value_t = 30.0)]
    max_speed: f64,
    /// Acceleration of the table, degrees per second².
    #[arg(long, default_value_t = 60.0)]
    accel: f64,
    /// Swap the direction of rotation.
    #[arg(long)]
    invert: bool,
    /// Release the motor (ENABLE high) between turns.
    #[arg(long)]
    disable_when_idle: bool,
    /// Simulated table only: speed in degrees per second (default: instant).
    #[arg(long)]
    sim_speed: Option<f64>,
    /// Print connection events.
    #[arg(long, short)]
    verbose: bool,
}

/// GPIO line numbers, comma-separated (`17,27,22`), or `none`.
fn parse_lines<const N: usize>(s: &str, flag: &str) -> Result<Option<[u32; N]>, String> {
    if s.trim().eq_ignore_ascii_case("none") {
        return Ok(None);
    }
    let err =
        || format!("--{flag}: {s:?} must be {N} GPIO line number(s) like 17,27,22, or `none`");
    let lines: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse())
        .collect::<Result<_, _>>()
        .map_err(|_| err())?;
    lines.try_into().map(Some).map_err(|_| err())
}

fn parse_gear(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("--gear: {s:?} must be TABLE_TEETH:MOTOR_TEETH, e.g. 60:20");
    let (a, b) = s.split_once(':').ok_or_else(err)?;
    Ok((
        a.trim().parse().map_err(|_| err())?,
        b.trim().parse().map_err(|_| err())?,
    ))
}

fn stepper_config(args: &Args) -> Result<StepperConfig, String> {
    let (table_teeth, motor_teeth) = parse_gear(&args.gear)?;
    let config = StepperConfig {
        full_steps_per_rev: args.steps_per_rev,
        microstep: args.microstep,
        gear_table_teeth: table_teeth,
        gear_motor_teeth: motor_teeth,
        max_speed_deg_s: args.max_speed,
        accel_deg_s2: args.accel,
        invert_direction: args.invert,
        disable_when_idle: args.disable_when_idle,
    };
    config.step_rates().map_err(|e| e.to_string())?;
    Ok(config)
}

fn gpio_pins(args: &Args) -> Result<GpioPins, String> {
    Ok(GpioPins {
        chip: args.gpio_chip.clone(),
        step: args.step_pin,
        dir: args.dir_pin,
        enable: parse_lines::<1>(&args.enable_pin, "enable-pin")?.map(|[n]| n),
        microstep: parse_lines::<3>(&args.ms_pins, "ms-pins")?,
    })
}

#[cfg(feature = "gpio")]
fn open_gpio(pins: &GpioPins, config: StepperConfig) -> Result<Box<dyn Turntable + Send>, String> {
    let table = voxoct_turntable::GpioTurntable::open(pins, config).map_err(|e| e.to_string())?;
    Ok(Box::new(table))
}

#[cfg(not(feature = "gpio"))]
fn open_gpio(
    _pins: &GpioPins,
    _config: StepperConfig,
) -> Result<Box<dyn Turntable + Send>, String> {
    Err(
        "--gpio: this build has no GPIO support. How to fix: build with \
         `cargo run --release --features gpio --example turntable_server -- --gpio ...` \
         on the Raspberry Pi"
            .into(),
    )
}

fn run(args: Args) -> Result<(), String> {
    // Read even when --token is given, so that a stale old variable is reported.
    let env_token = token_from_env().map_err(|e| e.to_string())?;
    let token = args.token.clone().or(env_token);
    let config = stepper_config(&args)?;
    let table: Box<dyn Turntable + Send> = if args.gpio {
        let pins = gpio_pins(&args)?;
        let table = open_gpio(&pins, config.clone())?;
        eprintln!(
            "turntable_server: A4988 on {} (STEP {}, DIR {}, ENABLE {:?}, MS {:?}), {} stepping",
            pins.chip.display(),
            pins.step,
            pins.dir,
            pins.enable,
            pins.microstep,
            config.microstep
        );
        table
    } else {
        let scale = config.scale().map_err(|e| e.to_string())?;
        let mut sim = SimulatedTurntable::with_scale(scale);
        if let Some(speed) = args.sim_speed {
            sim = sim
                .with_speed(speed)
                .map_err(|e| format!("--sim-speed: {e}"))?;
        }
        eprintln!(
            "turntable_server: simulated table, {} microsteps per revolution ({}° each)",
            scale.microsteps_per_rev(),
            scale.step_deg()
        );
        Box::new(sim)
    };

    let listener = TcpListener::bind(&args.listen)
        .map_err(|e| format!("--listen {}: cannot bind HOST:PORT ({e})", args.listen))?;
    let has_token = token.is_some();
    let server_config = ServerConfig {
        token,
        allow_network_without_token: args.insecure,
        verbose: args.verbose,
        ..ServerConfig::default()
    };
    let handle = serve(listener, table, server_config).map_err(|e| e.to_string())?;
    let local = handle.local_addr();
    eprintln!(
        "turntable_server: listening on {local} ({}); Ctrl-C to stop",
        if has_token {
            "token required"
        } else {
            "no token"
        }
    );
    // SIGINT/SIGTERM: stop accepting, let a turn in progress finish and get its reply,
    // tell clients the server is shutting down, then exit 0.
    let stop = handle.stop_signal();
    let mut signals = signal_hook::iterator::Signals::new([
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
    ])
    .map_err(|e| format!("installing the signal handlers: {e}"))?;
    let signal_thread = signals.handle();
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            eprintln!("turntable_server: signal {sig}: finishing the current turn, then stopping");
            stop.stop();
        }
    });
    handle.join();
    signal_thread.close();
    eprintln!("turntable_server: stopped");
    Ok(())
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(msg) => {
            eprintln!("turntable_server: error: {msg}");
            ExitCode::from(2)
        }
    }
}
