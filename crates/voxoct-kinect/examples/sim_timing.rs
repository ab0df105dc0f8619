//! Times the simulated Kinect: a full turntable scan of a built-in model, 8 snapshots ×
//! 10 frames, reporting the first frame at each angle (ray casting + noise) and the others
//! (noise only).
//!
//! `cargo run -p voxoct-kinect --example sim_timing --profile test [-- MODEL [FIRST.pgm]]`
//! (the optional second argument saves the first frame as a standard 16-bit PGM, in mm).

use std::time::{Duration, Instant};

use voxoct_kinect::{DepthSource, SimConfig, SimulatedKinect, SourceError};

fn main() -> Result<(), SourceError> {
    let name = std::env::args().nth(1).unwrap_or_else(|| "figurine".into());
    let dump = std::env::args().nth(2);
    let mut sim = SimulatedKinect::builtin(&name, SimConfig::default())?;
    let (mut first, mut further, mut n_further) = (Duration::ZERO, Duration::ZERO, 0u32);
    let start = Instant::now();
    let mut valid = 0usize;
    for k in 0..8 {
        sim.set_turntable_angle_deg(45.0 * k as f32);
        for f in 0..10 {
            let t = Instant::now();
            let frame = sim.grab(Duration::from_secs(1))?;
            let dt = t.elapsed();
            if f == 0 {
                first += dt;
            } else {
                further += dt;
                n_further += 1;
            }
            if let (Some(path), 0, 0) = (&dump, k, f) {
                let mut bytes = format!("P5 {} {} 65535\n", frame.width, frame.height).into_bytes();
                bytes.extend(frame.data.iter().flat_map(|d| d.to_be_bytes()));
                std::fs::write(path, bytes).map_err(|source| SourceError::Io {
                    path: path.into(),
                    source,
                })?;
            }
            valid += frame.data.iter().filter(|&&d| d != 0).count();
        }
    }
    println!(
        "{name}: 8 snapshots x 10 frames in {:.2} s; first frame per angle {:.1} ms, \
         further frames {:.2} ms; {:.0} valid pixels per frame",
        start.elapsed().as_secs_f64(),
        first.as_secs_f64() * 1e3 / 8.0,
        further.as_secs_f64() * 1e3 / f64::from(n_further),
        valid as f64 / 80.0
    );
    Ok(())
}
