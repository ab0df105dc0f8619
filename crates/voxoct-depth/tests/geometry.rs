//! The transform matches SCAN_FORMAT.md: an analytic sphere rendered through a known rig
//! (with the format's formulas written out here, independently of the crate), written as
//! a recorded scan, read back and back-projected, lands on the sphere; and the bunny scan
//! of `../shared/data` lands on its ground-truth mesh.

use std::path::Path;

use proptest::prelude::*;
use voxoct_depth::filter::FilterChain;
use voxoct_depth::glam::{Affine3A, Vec3};
use voxoct_depth::scan::{RecordedScan, ScanWriter};
use voxoct_depth::snapshot::{HOLE, Snapshot};
use voxoct_depth::triangulate::{DEFAULT_MAX_EDGE_SQ, triangulate_vec};
use voxoct_depth::{ClipBox, DepthFrame, Intrinsics, Rig, ScannerConfig, SensorConfig};

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

fn apply(a: &M3, p: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|k| a[i][k] * p[k]).sum())
}

fn transpose(a: &M3) -> M3 {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| a[j][i]))
}

/// `R_x(a)` and `R_y(a)` exactly as SCAN_FORMAT.md writes them.
fn rx(a: f64) -> M3 {
    let (s, c) = a.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}
fn ry(a: f64) -> M3 {
    let (s, c) = a.sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

/// Camera → object rotation and translation per SCAN_FORMAT.md, in f64:
/// `p_obj = R_y(-angle) · (R_x(-tilt) · diag(1,-1,-1) · p_cam + sensor)`.
fn camera_to_object(rig: &Rig, angle_deg: f64) -> (M3, [f64; 3]) {
    let flip = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let r_rig = mul(&rx(-f64::from(rig.tilt_deg).to_radians()), &flip);
    let ry = ry(-angle_deg.to_radians());
    let s = rig.sensor_position_m.to_array().map(f64::from);
    (mul(&ry, &r_rig), apply(&ry, s))
}

const CENTRE: [f64; 3] = [0.03, 0.08, -0.02];
const RADIUS: f64 = 0.06;

/// Renders the sphere: per pixel, the first ray–sphere intersection, depth rounded to
/// whole units.
fn render_sphere(intr: &Intrinsics, rig: &Rig, angle_deg: f64, unit: f64) -> DepthFrame {
    let (r, t) = camera_to_object(rig, angle_deg);
    // Sphere centre in the camera frame: p_cam = Rᵀ (p_obj − t).
    let c = apply(&transpose(&r), [0, 1, 2].map(|i| CENTRE[i] - t[i]));
    let mut f = DepthFrame::empty(intr.width, intr.height, unit as f32);
    for v in 0..intr.height {
        for u in 0..intr.width {
            // Ray with unit z component: the parameter is the depth.
            let d = [
                (f64::from(u) - f64::from(intr.cx)) / f64::from(intr.fx),
                (f64::from(v) - f64::from(intr.cy)) / f64::from(intr.fy),
                1.0,
            ];
            let a: f64 = d.iter().map(|x| x * x).sum();
            let b: f64 = -2.0 * (0..3).map(|i| d[i] * c[i]).sum::<f64>();
            let cc: f64 = c.iter().map(|x| x * x).sum::<f64>() - RADIUS * RADIUS;
            let disc = b * b - 4.0 * a * cc;
            if disc >= 0.0 {
                let z = (-b - disc.sqrt()) / (2.0 * a);
                if z > 0.0 {
                    f.data[(v * intr.width + u) as usize] = (z / unit).round() as u16;
                }
            }
        }
    }
    f
}

fn rig() -> Rig {
    Rig {
        tilt_deg: 19.65,
        sensor_position_m: Vec3::new(0.0, 0.30, 0.7),
    }
}

#[test]
fn rendered_sphere_back_projects_onto_the_sphere() {
    let intr = Intrinsics::KINECT_V1;
    let unit = 0.001;
    let config = ScannerConfig {
        sensor: SensorConfig {
            intrinsics: intr,
            depth_unit_m: unit as f32,
        },
        rig: rig(),
        clip: ClipBox {
            min: Vec3::splat(-0.5),
            max: Vec3::splat(0.5),
        },
    };
    let angles = [0.0, 45.0, 90.0, 200.0, -30.0];
    let dir = tempfile::tempdir().unwrap();
    let mut w = ScanWriter::create(dir.path(), config).unwrap();
    for &a in &angles {
        let f = render_sphere(&intr, &config.rig, a, unit);
        w.add_snapshot(a as f32, &[f.clone(), f]).unwrap();
    }
    w.finish().unwrap();

    let scan = RecordedScan::open(dir.path()).unwrap();
    let m = &scan.manifest;
    let chain = FilterChain::parse("average").unwrap();
    for (k, frames) in scan.frames.iter().enumerate() {
        let angle = m.snapshots[k].angle_deg;
        let frame = chain.apply(frames).unwrap();
        let s = Snapshot::from_frame(&frame, &m.sensor.intrinsics, &m.rig, angle, &m.clip).unwrap();
        let rendered = frame.data.iter().filter(|&&d| d != 0).count();
        assert!(rendered > 3_000, "the sphere is in view: {rendered}");
        assert_eq!(s.valid_count(), rendered, "the clip box holds the sphere");
        let mut worst = 0.0f64;
        for (i, p) in s.points.iter().enumerate() {
            if p.x.is_nan() {
                continue;
            }
            let (u, v) = (
                (i as u32 % intr.width) as f64,
                (i as u32 / intr.width) as f64,
            );
            // The depth rounding moves a point along its ray by at most half a unit in z.
            let ray = (((u - 319.5) / 580.0).powi(2) + ((v - 239.5) / 580.0).powi(2) + 1.0).sqrt();
            let bound = 0.5 * unit * ray + 2e-6;
            let q = p.to_array().map(f64::from);
            let dist = ((0..3)
                .map(|j| (q[j] - CENTRE[j]).powi(2))
                .sum::<f64>()
                .sqrt()
                - RADIUS)
                .abs();
            assert!(
                dist <= bound,
                "snapshot {k} pixel {i}: {dist} m off the sphere > {bound}"
            );
            worst = worst.max(dist);
        }
        println!(
            "sphere at {angle}°: {rendered} points, worst {:.3} mm",
            worst * 1e3
        );

        // Triangles: every one faces the sensor and points out of the sphere.
        let tris = triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ);
        assert!(
            tris.len() > rendered,
            "{} triangles for {rendered} points",
            tris.len()
        );
        let sensor = s.sensor_position();
        for t in &tris {
            let n = t.scaled_normal();
            let centroid = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
            assert!(
                n.dot(sensor - centroid) > 0.0,
                "{t:?} faces away from the sensor"
            );
            let c = Vec3::new(CENTRE[0] as f32, CENTRE[1] as f32, CENTRE[2] as f32);
            assert!(n.dot(centroid - c) > 0.0, "{t:?} points into the sphere");
            assert!(t.v.iter().all(|v| !v.is_nan()));
        }
    }
}

#[test]
fn crate_transform_equals_the_format_formula() {
    for angle in [0.0f64, 17.0, 90.0, 181.5, -720.0] {
        let (r, t) = camera_to_object(&rig(), angle);
        let a = rig().camera_to_object(angle as f32);
        for p in [[0.0, 0.0, 0.0], [0.1, -0.2, 0.7], [-0.3, 0.25, 1.9]] {
            let want = apply(&r, p);
            let got = a.transform_point3(Vec3::from_array(p.map(|x| x as f32)));
            for i in 0..3 {
                assert!(
                    (f64::from(got[i]) - (want[i] + t[i])).abs() < 1e-6,
                    "{angle}: {got}"
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// On any depth image, every triangle faces the sensor and has no edge above the
    /// threshold, and a snapshot file round-trips.
    #[test]
    fn triangles_face_the_sensor(
        data in prop::collection::vec(prop_oneof![1 => Just(0u16), 6 => 600u16..640], 12 * 9),
        angle in -360.0f32..360.0,
        tilt in -30.0f32..40.0,
    ) {
        let intr = Intrinsics { width: 12, height: 9, fx: 580.0, fy: 580.0, cx: 5.5, cy: 4.0 };
        let frame = DepthFrame { width: 12, height: 9, unit_m: 0.001, data };
        let rig = Rig { tilt_deg: tilt, sensor_position_m: Vec3::new(0.0, 0.3, 0.7) };
        let clip = ClipBox { min: Vec3::splat(-2.0), max: Vec3::splat(2.0) };
        let s = Snapshot::from_frame(&frame, &intr, &rig, angle, &clip).unwrap();
        prop_assert_eq!(s.points.len(), 108);
        for (p, &d) in s.points.iter().zip(&frame.data) {
            prop_assert_eq!(p.x.is_nan(), d == 0);
        }
        let sensor = s.sensor_position();
        for t in triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ) {
            let n = t.scaled_normal();
            prop_assert!(n.dot(sensor - (t.v[0] + t.v[1] + t.v[2]) / 3.0) > 0.0);
            for (a, b) in [(0, 1), (1, 2), (2, 0)] {
                prop_assert!(t.v[a].distance_squared(t.v[b]) <= DEFAULT_MAX_EDGE_SQ);
            }
        }
        prop_assert!(s.points.iter().zip(&frame.data).all(|(p, &d)| (d == 0) == p.x.is_nan() && (d == 0) == p.is_nan() && (!p.is_nan() || p.x.to_bits() == HOLE.x.to_bits())));
        let _ = (HOLE, Affine3A::IDENTITY);
    }
}

// ---- the bunny scan of ../shared/data ----

/// Reads a binary little-endian PLY with `double x, y, z` vertices (other vertex
/// properties skipped if they are doubles or floats) and `list uchar uint|int` faces.
fn read_ply(path: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .ok_or("no end_header")?;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|e| e.to_string())?;
    let mut body = &bytes[end + 11..];
    let (mut nv, mut nf) = (0usize, 0usize);
    let mut element = "";
    let mut vprops: Vec<(String, usize)> = Vec::new();
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["format", f, _] if *f != "binary_little_endian" => return Err(format!("format {f}")),
            ["element", e, n] => {
                element = if *e == "vertex" {
                    "vertex"
                } else if *e == "face" {
                    "face"
                } else {
                    "other"
                };
                let n: usize = n.parse().map_err(|_| "bad count")?;
                if element == "vertex" {
                    nv = n
                } else if element == "face" {
                    nf = n
                }
            }
            ["property", "list", c, i, _]
                if element == "face" && (*c != "uchar" || !(*i == "uint" || *i == "int")) =>
            {
                return Err(format!("face list {c} {i}"));
            }
            ["property", t, name] if element == "vertex" => {
                let size = match *t {
                    "double" | "float64" => 8,
                    "float" | "float32" => 4,
                    t => return Err(format!("vertex type {t}")),
                };
                vprops.push((name.to_string(), size));
            }
            _ => {}
        }
    }
    let stride: usize = vprops.iter().map(|p| p.1).sum();
    let mut verts = Vec::with_capacity(nv);
    for _ in 0..nv {
        let mut xyz = [0f32; 3];
        let mut off = 0;
        for (name, size) in &vprops {
            let b = &body[off..off + size];
            let x = if *size == 8 {
                f64::from_le_bytes(b.try_into().unwrap()) as f32
            } else {
                f32::from_le_bytes(b.try_into().unwrap())
            };
            match name.as_str() {
                "x" => xyz[0] = x,
                "y" => xyz[1] = x,
                "z" => xyz[2] = x,
                _ => {}
            }
            off += size;
        }
        verts.push(Vec3::from_array(xyz));
        body = &body[stride..];
    }
    let mut faces = Vec::with_capacity(nf);
    for _ in 0..nf {
        if body[0] != 3 {
            return Err("non-triangle face".into());
        }
        let idx = |k: usize| u32::from_le_bytes(body[1 + 4 * k..5 + 4 * k].try_into().unwrap());
        faces.push([idx(0), idx(1), idx(2)]);
        body = &body[13..];
    }
    Ok((verts, faces))
}

fn percentile(sorted: &[f32], p: f64) -> f32 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

#[test]
#[ignore = "needs ../shared/data"]
fn bunny_scan_lands_on_the_ground_truth() {
    use parry3d::query::PointQuery;
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data");
    let scan_dir = Path::new(root).join("bunny-scan");
    let gt = Path::new(root).join("bunny-scan.gt.ply");
    assert!(
        scan_dir.join("scan.toml").exists() && gt.exists(),
        "{} or its ground truth is absent",
        scan_dir.display()
    );
    let (verts, faces) = read_ply(&gt).unwrap();
    let mesh = parry3d::shape::TriMesh::new(verts, faces).unwrap();
    let scan = RecordedScan::open(&scan_dir).unwrap();
    let m = &scan.manifest;
    for (name, max_median_mm, max_p95_mm) in [
        ("basic", 2.0, 6.0),
        ("average", 2.0, 6.0),
        ("median+outlier", 2.0, 6.0),
    ] {
        let chain = FilterChain::parse(name).unwrap();
        let frame = chain.apply(&scan.frames[0]).unwrap();
        let s = Snapshot::from_frame(
            &frame,
            &m.sensor.intrinsics,
            &m.rig,
            m.snapshots[0].angle_deg,
            &m.clip,
        )
        .unwrap();
        let mut d: Vec<f32> = s
            .valid_points()
            .map(|p| mesh.distance_to_local_point(p, false))
            .collect();
        assert!(d.len() > 5_000, "{} points", d.len());
        d.sort_by(f32::total_cmp);
        let (med, p95, max) = (
            percentile(&d, 0.5) * 1e3,
            percentile(&d, 0.95) * 1e3,
            d[d.len() - 1] * 1e3,
        );
        println!(
            "bunny snapshot 0, {name}: {} points, distance to ground truth median {med:.3} mm, p95 {p95:.3} mm, max {max:.1} mm",
            d.len()
        );
        assert!(
            med < max_median_mm && p95 < max_p95_mm,
            "{name}: median {med} mm, p95 {p95} mm"
        );
    }
    // Every snapshot, through the turntable rotation, with the default chain: this checks
    // the sign of the angle too.
    let chain = FilterChain::default();
    for (k, frames) in scan.frames.iter().enumerate() {
        let angle = m.snapshots[k].angle_deg;
        let frame = chain.apply(frames).unwrap();
        let s = Snapshot::from_frame(&frame, &m.sensor.intrinsics, &m.rig, angle, &m.clip).unwrap();
        let mut d: Vec<f32> = s
            .valid_points()
            .map(|p| mesh.distance_to_local_point(p, false))
            .collect();
        d.sort_by(f32::total_cmp);
        let (med, p95) = (percentile(&d, 0.5) * 1e3, percentile(&d, 0.95) * 1e3);
        println!(
            "bunny snapshot {k} ({angle}°), {chain}: {} points, median {med:.3} mm, p95 {p95:.3} mm",
            d.len()
        );
        assert!(
            d.len() > 5_000 && med < 1.0 && p95 < 3.0,
            "snapshot {k}: {med} / {p95} mm"
        );
    }
}
