//! One snapshot's depth work at Kinect v1 size: filters over 10 frames of 640×480,
//! back-projection + transform + clip, triangulation, and all of it together.
//!
//! Uses snapshot 0 of `../shared/data/bunny-scan` when present, else a synthetic sphere
//! on a turntable with noise and drop-outs.

use std::hint::black_box;
use std::path::Path;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use voxoct_depth::filter::FilterChain;
use voxoct_depth::glam::Vec3;
use voxoct_depth::scan::RecordedScan;
use voxoct_depth::snapshot::Snapshot;
use voxoct_depth::triangulate::{DEFAULT_MAX_EDGE_SQ, triangulate};
use voxoct_depth::{ClipBox, DepthFrame, Intrinsics, Rig, ScannerConfig};

struct Data {
    frames: Vec<DepthFrame>,
    intr: Intrinsics,
    rig: Rig,
    clip: ClipBox,
    angle: f32,
    source: &'static str,
}

fn data() -> Data {
    let dir = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/bunny-scan"
    ));
    if dir.join("scan.toml").exists()
        && let Ok(mut scan) = RecordedScan::open(dir)
    {
        let m = &scan.manifest;
        return Data {
            intr: m.sensor.intrinsics,
            rig: m.rig,
            clip: m.clip,
            angle: m.snapshots[0].angle_deg,
            frames: scan.frames.swap_remove(0),
            source: "bunny",
        };
    }
    synthetic()
}

/// A 0.1 m sphere on a turntable disk, ±2 mm noise, 2 % drop-outs.
fn synthetic() -> Data {
    let c = ScannerConfig::default();
    let intr = c.sensor.intrinsics;
    let to_obj = c.rig.camera_to_object(0.0);
    let centre = Vec3::new(0.0, 0.1, 0.0);
    let r = 0.1f32;
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as u32
    };
    let frames = (0..10)
        .map(|_| {
            let mut f = DepthFrame::empty(intr.width, intr.height, 0.001);
            for v in 0..intr.height {
                for u in 0..intr.width {
                    let dir = to_obj.transform_vector3(intr.unproject(u as f32, v as f32, 1.0));
                    let o = Vec3::from(to_obj.translation);
                    // Sphere, then the plane y = 0.
                    let oc = o - centre;
                    let b = oc.dot(dir);
                    let a = dir.length_squared();
                    let disc = b * b - a * (oc.length_squared() - r * r);
                    let z = if disc >= 0.0 {
                        (-b - disc.sqrt()) / a
                    } else if dir.y < 0.0 {
                        -o.y / dir.y
                    } else {
                        0.0
                    };
                    let noise = (rnd() % 5) as f32 - 2.0;
                    if z > 0.0 && rnd() % 50 != 0 {
                        f.data[(v * intr.width + u) as usize] = (z * 1000.0 + noise) as u16;
                    }
                }
            }
            f
        })
        .collect();
    Data {
        frames,
        intr,
        rig: c.rig,
        clip: c.clip,
        angle: 0.0,
        source: "synthetic-sphere",
    }
}

fn bench(c: &mut Criterion) {
    let d = data();
    let size = format!(
        "{}x{}x{}-{}",
        d.frames.len(),
        d.intr.width,
        d.intr.height,
        d.source
    );
    println!("depth bench data: {size}");

    let mut g = c.benchmark_group("filter");
    for name in [
        "basic",
        "average",
        "average-discard",
        "median",
        "basic+outlier",
        "average+outlier",
        "median+outlier",
    ] {
        let chain = FilterChain::parse(name).unwrap();
        g.bench_with_input(BenchmarkId::new(name, &size), &d.frames, |b, fr| {
            b.iter(|| chain.apply(black_box(fr)).unwrap())
        });
    }
    g.finish();

    let frame = FilterChain::default().apply(&d.frames).unwrap();
    let mut snap = Snapshot::from_frame(&frame, &d.intr, &d.rig, d.angle, &d.clip).unwrap();
    let mut tris = Vec::new();
    triangulate(&snap, DEFAULT_MAX_EDGE_SQ, &mut tris);
    println!(
        "default chain: {} valid points, {} triangles",
        snap.valid_count(),
        tris.len()
    );

    let mut g = c.benchmark_group("geometry");
    g.bench_function(
        BenchmarkId::new("back-project+transform+clip", &size),
        |b| {
            b.iter(|| {
                snap.fill_from_frame(black_box(&frame), &d.intr, &d.rig, d.angle, &d.clip)
                    .unwrap()
            })
        },
    );
    g.bench_function(BenchmarkId::new("triangulate", &size), |b| {
        b.iter(|| {
            tris.clear();
            triangulate(black_box(&snap), DEFAULT_MAX_EDGE_SQ, &mut tris);
        })
    });
    g.finish();

    let mut g = c.benchmark_group("snapshot-total");
    for name in ["average", "average+outlier", "median+outlier"] {
        let chain = FilterChain::parse(name).unwrap();
        g.bench_function(BenchmarkId::new(name, &size), |b| {
            b.iter(|| {
                let f = chain.apply(black_box(&d.frames)).unwrap();
                snap.fill_from_frame(&f, &d.intr, &d.rig, d.angle, &d.clip)
                    .unwrap();
                tris.clear();
                triangulate(&snap, DEFAULT_MAX_EDGE_SQ, &mut tris);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
