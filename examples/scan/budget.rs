//! Flag ranges, flags that do not apply to the chosen source, and the memory a run will
//! need, estimated from its inputs and flags before any frame is read.

use clap::ArgMatches;
use clap::parser::ValueSource;

use voxoct::depth::ScannerConfig;

use crate::Args;

/// Most Taubin smoothing iterations (each is a pass over the mesh).
pub const MAX_SMOOTH: u32 = 1000;
/// Most triangle hits a leaf can be asked for.
pub const MAX_MIN_HITS: u32 = 1 << 16;
/// Peak bytes per occupied leaf (octree, field, mesh and its smoothing), measured on the
/// built-in figurine at 0.5–2 mm leaves (about 700).
const BYTES_PER_LEAF: f64 = 700.0;
/// Scratch bytes per pixel of a snapshot being filtered, back-projected and triangulated.
const BYTES_PER_SNAPSHOT_PIXEL: f64 = 32.0;

/// Whether `id` was given on the command line (not a default).
fn given(m: &ArgMatches, id: &str) -> bool {
    m.value_source(id) == Some(ValueSource::CommandLine)
}

/// The octree depth for a root edge and a leaf size: the first depth whose node edge is at
/// most the leaf size.
#[must_use]
pub fn octree_depth(root: f32, leaf: f32) -> u32 {
    let mut d = 0;
    while d < 64 && f64::from(root) / 2f64.powi(d as i32) > f64::from(leaf) {
        d += 1;
    }
    d
}

/// Range checks and source/flag combinations, before anything is read.
pub fn check_flags(args: &Args, m: &ArgMatches) -> Result<(), String> {
    if let Some(n) = args.smooth
        && n > MAX_SMOOTH
    {
        return Err(format!(
            "--smooth must be between 0 and {MAX_SMOOTH} iterations, got {n}"
        ));
    }
    if let Some(n) = args.min_hits
        && n > MAX_MIN_HITS
    {
        return Err(format!(
            "--min-hits must be between 0 and {MAX_MIN_HITS}, got {n} (no leaf is hit that often: \
             the mesh would be empty)"
        ));
    }
    let depth = octree_depth(args.root, args.leaf);
    if args.lod > depth {
        return Err(format!(
            "--lod {}: the level of detail cannot exceed the octree's {depth} levels (--root {} m \
             with --leaf {} m)",
            args.lod, args.root, args.leaf
        ));
    }
    if let Some(c) = args.min_component {
        let leaves_per_side = 1u64 << depth.min(21);
        if c as u64
            > leaves_per_side
                .saturating_mul(leaves_per_side)
                .saturating_mul(6)
        {
            return Err(format!(
                "--min-component {c} is more leaves than any surface in this octree has; every \
                 piece would be removed"
            ));
        }
    }
    if args.leaf > 0.05 {
        return Err(format!(
            "--leaf {} m is larger than the objects a turntable scanner takes; --leaf is in metres \
             (0.001 = 1 mm)",
            args.leaf
        ));
    }
    // Flags that only mean something for some sources.
    let source = if args.input.is_some() {
        "--input"
    } else if args.fakenect.is_some() {
        "--fakenect"
    } else if args.kinect {
        "--kinect"
    } else if args.model.is_some() {
        "--model"
    } else {
        "--builtin"
    };
    let simulated = matches!(source, "--model" | "--builtin");
    let captured = simulated || source == "--kinect";
    let rules: [(&str, &str, bool); 7] = [
        (
            "degrees_per_snapshot",
            "--degrees-per-snapshot",
            source == "--fakenect",
        ),
        ("snapshots", "--snapshots", captured),
        ("frames", "--frames", captured || source == "--fakenect"),
        ("seed", "--seed", simulated),
        ("exact", "--exact", simulated),
        ("builtin", "--builtin", source == "--builtin"),
        ("token", "--token", args.turntable.is_some()),
    ];
    for (id, flag, applies) in rules {
        if !applies && given(m, id) {
            return Err(format!("{flag} does not apply to {source}: remove it"));
        }
    }
    Ok(())
}

/// The memory limit: `--max-memory`, or half the machine's memory (and no more than three
/// quarters of this process's address-space limit).
pub fn limit_bytes(args: &Args) -> u64 {
    if let Some(b) = args.max_memory {
        return b;
    }
    voxoct::depth::scan::default_memory_limit()
}

/// Parses `--max-memory`: bytes, or a number with K, M, G or T (powers of 1024).
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

/// A size for people.
fn human(bytes: f64) -> String {
    if bytes >= 1e12 {
        format!("{:.1} TB", bytes / 1e12)
    } else if bytes >= 1e9 {
        format!("{:.1} GB", bytes / 1e9)
    } else {
        format!("{:.0} MB", bytes / 1e6)
    }
}

/// Refuses a run whose estimate exceeds the limit: `frames` depth frames of the sensor's
/// size held at once, and the octree and mesh for the clip box at `--leaf`.
pub fn check_memory(
    args: &Args,
    config: &ScannerConfig,
    snapshots: u64,
    frames: u64,
) -> Result<(), String> {
    let i = config.sensor.intrinsics;
    let pixels = f64::from(i.width) * f64::from(i.height);
    let frame_bytes = frames as f64 * pixels * 2.0;
    let scratch = snapshots as f64 * pixels * BYTES_PER_SNAPSHOT_PIXEL;
    // Occupied leaves: at most the clip box's surface (within the root cube) in leaf
    // squares; an object fills about a quarter of it.
    let c = config.clip;
    let e = (c.max - c.min).min(voxoct::core::glam::Vec3::splat(args.root));
    let area = 2.0 * f64::from(e.x * e.y + e.y * e.z + e.z * e.x);
    let leaf = f64::from(args.leaf);
    let leaves = area / (leaf * leaf) / 4.0;
    let mesh = leaves * BYTES_PER_LEAF;
    let need = frame_bytes + scratch + mesh;
    let limit = limit_bytes(args);
    if need > limit as f64 {
        let biggest = if mesh >= frame_bytes + scratch {
            format!(
                "at --leaf {} m; use a larger leaf or a smaller clip box",
                args.leaf
            )
        } else {
            format!(
                "for {frames} frames of {}x{}; use fewer snapshots or frames",
                i.width, i.height
            )
        };
        return Err(format!(
            "this run needs about {} {biggest} (the limit is {}; raise it with --max-memory)",
            human(need),
            human(limit as f64)
        ));
    }
    Ok(())
}

/// Why the mesh came out empty, from what the run saw.
pub fn explain_empty(args: &Args, triangles_in: usize, leaves: usize) -> String {
    if triangles_in == 0 {
        return "the scan produced an empty mesh: no frame had a valid depth pixel inside the \
                clip box (all-zero or out-of-range frames, or the object outside [clip]; check \
                [clip], [rig] and the frames)"
            .into();
    }
    if leaves == 0 {
        return format!(
            "the scan produced an empty mesh: {triangles_in} triangles were triangulated but none \
             fell inside the octree (--root {} m centred on the clip box)",
            args.root
        );
    }
    if let Some(h) = args.min_hits
        && h > 1
    {
        return format!(
            "the scan produced an empty mesh: every one of the {leaves} leaves was hit by fewer \
             than --min-hits {h} triangles"
        );
    }
    if let Some(c) = args.min_component {
        return format!(
            "the scan produced an empty mesh: every piece has fewer than --min-component {c} leaves"
        );
    }
    if args.lod > 0 {
        return format!(
            "the scan produced an empty mesh: at --lod {} the {leaves} leaves merge into cells \
             too coarse to enclose anything; use a smaller --lod",
            args.lod
        );
    }
    format!(
        "the scan produced an empty mesh: {leaves} leaves of {} m enclose no volume (too few \
         views of the object, or a leaf too coarse for it)",
        args.leaf
    )
}
