//! STL writing throughput (MB/s) into memory and into a file.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use voxoct_stl::glam::Vec3;
use voxoct_stl::{StlFormat, write_ascii, write_binary, write_file};

/// A UV sphere with about `n` triangles.
fn sphere(n: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let rings = ((n / 2) as f32).sqrt() as u32;
    let (nu, nv) = (rings.max(3), rings.max(3));
    let mut v = Vec::new();
    for i in 0..=nv {
        for j in 0..nu {
            let th = std::f32::consts::PI * i as f32 / nv as f32;
            let ph = std::f32::consts::TAU * j as f32 / nu as f32;
            v.push(Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * 0.07);
        }
    }
    let mut t = Vec::new();
    for i in 0..nv {
        for j in 0..nu {
            let a = i * nu + j;
            let b = i * nu + (j + 1) % nu;
            t.push([a, b, a + nu]);
            t.push([b, b + nu, a + nu]);
        }
    }
    (v, t)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("stl_write");
    for n in [100_000usize, 1_000_000] {
        let (v, t) = sphere(n);
        let bin_bytes = 84 + 50 * t.len();
        let mut buf = Vec::with_capacity(bin_bytes);
        g.throughput(Throughput::Bytes(bin_bytes as u64));
        g.bench_with_input(BenchmarkId::new("binary_vec", t.len()), &n, |b, _| {
            b.iter(|| {
                buf.clear();
                write_binary(&mut buf, &v, &t, 1000.0).unwrap();
                black_box(buf.len())
            })
        });
        let dir = std::env::temp_dir().join(format!("voxoct-stl-bench-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bench.stl");
        g.bench_with_input(BenchmarkId::new("binary_file", t.len()), &n, |b, _| {
            b.iter(|| write_file(&path, &v, &t, StlFormat::Binary, 1000.0).unwrap())
        });
        let mut abuf = Vec::new();
        write_ascii(&mut abuf, &v, &t, 1000.0).unwrap();
        g.throughput(Throughput::Bytes(abuf.len() as u64));
        g.bench_with_input(BenchmarkId::new("ascii_vec", t.len()), &n, |b, _| {
            b.iter(|| {
                abuf.clear();
                write_ascii(&mut abuf, &v, &t, 1000.0).unwrap();
                black_box(abuf.len())
            })
        });
        let _ = std::fs::remove_dir_all(&dir);
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
