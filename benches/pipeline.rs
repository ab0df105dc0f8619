//! End-to-end: a recorded scan held in memory → filtered, triangulated, inserted, meshed and
//! written as binary STL into memory.
//!
//! Uses the bunny scan of `../shared/data` when it is there (8 snapshots × 10 frames, the
//! figures quoted in the README), otherwise a simulated scan of the built-in figurine.

use std::hint::black_box;
use std::path::Path;

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use voxoct::depth::ScannerConfig;
use voxoct::depth::scan::RecordedScan;
use voxoct::kinect::{SimConfig, SimulatedKinect};
use voxoct::pipeline::{Params, SnapshotFrames, reconstruct, recorded_snapshots, simulate_scan};

fn load() -> (String, ScannerConfig, Vec<SnapshotFrames>) {
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/bunny-scan");
    if let Ok(scan) = RecordedScan::open(&bunny) {
        let (config, snapshots) = recorded_snapshots(scan);
        return ("bunny".into(), config, snapshots);
    }
    let mut kinect = SimulatedKinect::builtin("figurine", SimConfig::default()).expect("figurine");
    let (config, snapshots) = simulate_scan(&mut kinect, 8, 10).expect("simulated scan");
    ("figurine".into(), config, snapshots)
}

fn bench_pipeline(c: &mut Criterion) {
    let (name, config, snapshots) = load();
    let mut group = c.benchmark_group("pipeline");
    group.sample_size(10);
    for leaf in [0.001_f32, 0.0005] {
        let params = Params {
            leaf_m: leaf,
            ..Params::default()
        };
        let id = BenchmarkId::new(format!("{name}/to_stl"), format!("{}mm", leaf * 1000.0));
        let mut stl = Vec::with_capacity(64 << 20);
        group.bench_function(id, |b| {
            // Cloning the frames (the input) is setup, not measured.
            b.iter_batched(
                || snapshots.clone(),
                |input| {
                    let r = reconstruct(&config, input, &params, |_| {}).expect("reconstruct");
                    stl.clear();
                    voxoct::stl::write_binary(
                        &mut stl,
                        &r.mesh.vertices,
                        &r.mesh.triangles,
                        1000.0,
                    )
                    .expect("stl");
                    black_box(stl.len())
                },
                BatchSize::LargeInput,
            );
        });
    }
    group.finish();
}

criterion_group!(benches, bench_pipeline);
criterion_main!(benches);
