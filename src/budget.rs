//! The memory a run will need, estimated from its inputs and settings before any frame is
//! read, and the memory it took.
//!
//! ```
//! use voxoct::budget::{check_memory, parse_bytes};
//! use voxoct::depth::ScannerConfig;
//! use voxoct::pipeline::Params;
//!
//! assert_eq!(parse_bytes("512M"), Ok(512 << 20));
//! let config = ScannerConfig::default();
//! // 8 snapshots of 4 frames at 1 mm fit in 8 GiB; at 0.05 mm they do not.
//! assert!(check_memory(&config, &Params::default(), 8, 32, 8 << 30).is_ok());
//! let fine = Params { leaf_m: 0.000_05, ..Params::default() };
//! assert!(check_memory(&config, &fine, 8, 32, 8 << 30).unwrap_err().contains("--leaf"));
//! ```

use voxoct_core::glam::Vec3;
use voxoct_depth::ScannerConfig;

use crate::pipeline::Params;

/// Peak bytes per occupied leaf (octree, field, mesh and its smoothing): an estimate taken
/// from runs of the built-in figurine at 0.5–2 mm leaves, used only to refuse runs that
/// cannot fit (the `peak MiB` column of BENCHMARKS.md's pipeline table shows real runs).
pub const BYTES_PER_LEAF: f64 = 700.0;
/// Scratch bytes per pixel of a snapshot being filtered, back-projected and triangulated.
pub const BYTES_PER_SNAPSHOT_PIXEL: f64 = 32.0;

/// What a run is estimated to hold at its peak, bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryEstimate {
    /// The depth frames, all held at once (2 bytes per pixel).
    pub frames: f64,
    /// Per-snapshot scratch of filtering, back-projection and triangulation.
    pub scratch: f64,
    /// The octree and the mesh: the clip box's surface (within the root cube) in leaf
    /// squares, a quarter of it occupied, [`BYTES_PER_LEAF`] each.
    pub mesh: f64,
}

impl MemoryEstimate {
    /// The estimate for `frames` depth frames in `snapshots` snapshots of the sensor in
    /// `config`, meshed with the root and leaf of `params`.
    #[must_use]
    pub fn new(config: &ScannerConfig, params: &Params, snapshots: u64, frames: u64) -> Self {
        let i = config.sensor.intrinsics;
        let pixels = f64::from(i.width) * f64::from(i.height);
        let c = config.clip;
        let e = (c.max - c.min).min(Vec3::splat(params.root_m));
        let area = 2.0 * f64::from(e.x * e.y + e.y * e.z + e.z * e.x);
        let leaf = f64::from(params.leaf_m);
        let leaves = area / (leaf * leaf) / 4.0;
        Self {
            frames: frames as f64 * pixels * 2.0,
            scratch: snapshots as f64 * pixels * BYTES_PER_SNAPSHOT_PIXEL,
            mesh: leaves * BYTES_PER_LEAF,
        }
    }

    /// The total, bytes.
    #[must_use]
    pub fn total(&self) -> f64 {
        self.frames + self.scratch + self.mesh
    }
}

/// Refuses a run whose [`MemoryEstimate`] exceeds `limit` bytes, saying what dominates it
/// and what to change.
///
/// # Errors
/// The message, naming `--leaf` or the frames, and `--max-memory`.
pub fn check_memory(
    config: &ScannerConfig,
    params: &Params,
    snapshots: u64,
    frames: u64,
    limit: u64,
) -> Result<(), String> {
    let est = MemoryEstimate::new(config, params, snapshots, frames);
    let need = est.total();
    if need <= limit as f64 {
        return Ok(());
    }
    let i = config.sensor.intrinsics;
    let biggest = if est.mesh >= est.frames + est.scratch {
        format!(
            "at --leaf {} m; use a larger leaf or a smaller clip box",
            params.leaf_m
        )
    } else {
        format!(
            "for {frames} frames of {}x{}; use fewer snapshots or frames",
            i.width, i.height
        )
    };
    Err(format!(
        "this run needs about {} {biggest} (the limit is {}; raise it with --max-memory)",
        human(need),
        human(limit as f64)
    ))
}

/// Parses a size: bytes, or a number with K, M, G or T (powers of 1024), e.g. `8G`.
///
/// # Errors
/// A message quoting `s` when it is not a positive size (at most 10¹⁸ bytes).
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&t[..t.len() - 1], 1u64 << 10),
        Some('M') => (&t[..t.len() - 1], 1 << 20),
        Some('G') => (&t[..t.len() - 1], 1 << 30),
        Some('T') => (&t[..t.len() - 1], 1 << 40),
        _ => (t, 1),
    };
    let x: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a size such as 4G, 512M or 1000000"))?;
    if !(x.is_finite() && x > 0.0) || x * mult as f64 > 1e18 {
        return Err(format!("{s:?} is not a positive size"));
    }
    Ok((x * mult as f64) as u64)
}

/// A size for people: MB, GB or TB (powers of 1000).
fn human(bytes: f64) -> String {
    if bytes >= 1e12 {
        format!("{:.1} TB", bytes / 1e12)
    } else if bytes >= 1e9 {
        format!("{:.1} GB", bytes / 1e9)
    } else {
        format!("{:.0} MB", bytes / 1e6)
    }
}

/// Peak resident set size of this process (Linux `VmHWM`), 0 where unknown.
#[must_use]
pub fn peak_rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes_and_refuse_nonsense() {
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert_eq!(parse_bytes("4k"), Ok(4096));
        assert_eq!(parse_bytes(" 1.5G "), Ok(3 << 29));
        assert_eq!(parse_bytes("2T"), Ok(2 << 40));
        for bad in ["", "G", "-1M", "0", "x", "1e30", "NaNK"] {
            assert!(parse_bytes(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn the_estimate_grows_with_frames_and_with_finer_leaves() {
        let config = ScannerConfig::default();
        let p = Params::default();
        let a = MemoryEstimate::new(&config, &p, 8, 32);
        let b = MemoryEstimate::new(&config, &p, 8, 64);
        assert!((b.frames - 2.0 * a.frames).abs() < 1.0);
        let half = Params {
            leaf_m: p.leaf_m / 2.0,
            ..p.clone()
        };
        let c = MemoryEstimate::new(&config, &half, 8, 32);
        assert!((c.mesh / a.mesh - 4.0).abs() < 1e-6);
        // The message names what dominates.
        let many = check_memory(&config, &p, 8, 100_000, 1 << 30).unwrap_err();
        assert!(many.contains("frames"), "{many}");
    }

    #[test]
    fn peak_memory_is_read_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(peak_rss_bytes() > 0);
        }
    }
}
