//! Benchmarks of voxoct-core: the overlap test, and insertion of a realistic snapshot
//! (1 mm leaves, 1 m root), serial and parallel.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use voxoct_core::glam::UVec3;
use voxoct_core::{Aabb, Octree, Triangle, intersection_test_aabb_triangle};

#[path = "../tests/support/snapshot.rs"]
mod snapshot;

fn overlap(c: &mut Criterion) {
    let tris = snapshot::triangles();
    let tree = Octree::new(snapshot::root_min(), 1.0, 0.001).unwrap();
    let grid = tree.leaf_grid();
    // Each triangle against the leaves of its bounding box: the octree's workload,
    // a mix of overlapping and separated pairs.
    let mut pairs: Vec<(Aabb, Triangle)> = Vec::new();
    for t in tris.iter().step_by(7) {
        let bb = t.aabb();
        let lo = ((bb.min - grid.origin) / grid.cell).floor().as_uvec3();
        let hi = ((bb.max - grid.origin) / grid.cell).floor().as_uvec3();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    pairs.push((grid.cell_aabb(UVec3::new(x, y, z)), *t));
                }
            }
        }
    }
    let hits = pairs
        .iter()
        .filter(|(b, t)| intersection_test_aabb_triangle(b, t))
        .count();
    eprintln!("overlap bench: {} pairs, {} overlapping", pairs.len(), hits);
    if let Some(ns) = cpu_ns_per_item(50, pairs.len(), || {
        black_box(
            pairs
                .iter()
                .filter(|(bx, t)| intersection_test_aabb_triangle(black_box(bx), black_box(t)))
                .count(),
        );
    }) {
        eprintln!("overlap test: {ns:.1} CPU ns per call");
    }
    let mut g = c.benchmark_group("overlap");
    g.throughput(Throughput::Elements(pairs.len() as u64));
    g.bench_function(BenchmarkId::new("aabb_triangle", pairs.len()), |b| {
        b.iter(|| {
            pairs
                .iter()
                .filter(|(bx, t)| intersection_test_aabb_triangle(black_box(bx), black_box(t)))
                .count()
        })
    });
    g.finish();
}

/// CPU time of the calling thread, ns (Linux; `None` elsewhere). The machine may be
/// shared: this figure, unlike wall-clock time, is not inflated by other processes.
fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// CPU ns per item of `f` run `reps` times over `items` items.
fn cpu_ns_per_item(reps: usize, items: usize, mut f: impl FnMut()) -> Option<f64> {
    f();
    let t0 = thread_cpu_ns()?;
    for _ in 0..reps {
        f();
    }
    Some((thread_cpu_ns()? - t0) as f64 / (reps * items) as f64)
}

/// CPU ns of every thread of the process, by thread id (Linux; empty elsewhere).
fn threads_cpu_ns() -> Vec<(u64, u64)> {
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return Vec::new();
    };
    dir.filter_map(|e| {
        let e = e.ok()?;
        let tid: u64 = e.file_name().to_str()?.parse().ok()?;
        let s = std::fs::read_to_string(e.path().join("schedstat")).ok()?;
        Some((tid, s.split_whitespace().next()?.parse().ok()?))
    })
    .collect()
}

/// Runs `f` `reps` times and returns the CPU ns per item of the busiest thread and of
/// all threads together: a load-independent view of parallel scaling (the busiest
/// thread is the critical path when every thread has a core of its own).
fn busiest_and_total_cpu_ns(reps: usize, items: usize, mut f: impl FnMut()) -> Option<(f64, f64)> {
    f();
    let before = threads_cpu_ns();
    for _ in 0..reps {
        f();
    }
    let after = threads_cpu_ns();
    if after.is_empty() {
        return None;
    }
    let deltas: Vec<u64> = after
        .iter()
        .map(|&(tid, t)| {
            let t0 = before.iter().find(|b| b.0 == tid).map_or(0, |b| b.1);
            t.saturating_sub(t0)
        })
        .collect();
    let per = (reps * items) as f64;
    let max = deltas.iter().copied().max()? as f64 / per;
    let sum = deltas.iter().sum::<u64>() as f64 / per;
    Some((max, sum))
}

fn insert(c: &mut Criterion) {
    let tris = snapshot::triangles();
    let min = snapshot::root_min();
    let mut tree = Octree::new(min, 1.0, 0.001).unwrap();
    tree.insert_all(&tris);
    let leaves = tree.leaf_count();
    eprintln!(
        "snapshot: {} triangles, depth {}, leaf edge {:.4} mm, {} leaves, {} nodes, {} bytes = {:.2} bytes/leaf",
        tris.len(),
        tree.depth(),
        tree.leaf_edge() * 1000.0,
        leaves,
        tree.node_count(),
        tree.memory_bytes(),
        tree.memory_bytes() as f64 / leaves as f64
    );
    if let Some(ns) = cpu_ns_per_item(20, tris.len(), || {
        let mut t = Octree::new(min, 1.0, 0.001).unwrap();
        t.insert_all(black_box(&tris));
        black_box(t.leaf_count());
    }) {
        eprintln!("serial insertion: {ns:.1} CPU ns per triangle (tree construction included)");
    }
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        if let Some((max, sum)) = busiest_and_total_cpu_ns(10, tris.len(), || {
            pool.install(|| {
                let mut t = Octree::new(min, 1.0, 0.001).unwrap();
                t.par_insert(black_box(&tris));
                black_box(t.leaf_count());
            })
        }) {
            eprintln!(
                "par_insert, {threads} thread(s): busiest thread {max:.1} CPU ns per triangle, all threads {sum:.1}"
            );
        }
    }
    let mut g = c.benchmark_group("insert");
    g.throughput(Throughput::Elements(tris.len() as u64));
    g.bench_function(BenchmarkId::new("serial", tris.len()), |b| {
        b.iter(|| {
            let mut t = Octree::new(min, 1.0, 0.001).unwrap();
            t.insert_all(black_box(&tris));
            t.leaf_count()
        })
    });
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        g.bench_function(BenchmarkId::new("par_insert_threads", threads), |b| {
            b.iter(|| {
                pool.install(|| {
                    let mut t = Octree::new(min, 1.0, 0.001).unwrap();
                    t.par_insert(black_box(&tris));
                    t.leaf_count()
                })
            })
        });
    }
    g.bench_function(BenchmarkId::new("reference", tris.len()), |b| {
        b.iter(|| {
            let mut t = Octree::new(min, 1.0, 0.001).unwrap();
            for tri in black_box(&tris) {
                t.insert_reference(tri);
            }
            t.leaf_count()
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = overlap, insert
}
criterion_main!(benches);
