//! The calibration's building blocks on synthetic data: RANSAC plane fits with outliers,
//! the Nelder–Mead minimiser, the platform's tilt and height from a rendered plane, and the
//! inspection images.

use proptest::prelude::*;
use voxoct_depth::glam::Vec3;
use voxoct_depth::{
    AxisOptions, CalibError, CalibSnapshot, ClipBox, DepthFrame, Intrinsics, NelderMeadOptions,
    PlatformOptions, RansacOptions, Rig, Snapshot, calibrate_axis, calibrate_platform, depth_image,
    fit_plane_ransac, nelder_mead, views_image, write_png,
};

/// A deterministic pseudo-random number in [0, 1).
fn rnd(state: &mut u64) -> f32 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    (*state >> 40) as f32 / (1u64 << 24) as f32
}

/// `n` points on the plane `normal · p = offset` with uniform noise of ±`noise`, plus
/// `outliers` points anywhere in a 1 m cube.
fn plane_cloud(
    normal: Vec3,
    offset: f32,
    n: usize,
    noise: f32,
    outliers: usize,
    seed: u64,
) -> Vec<Vec3> {
    let mut s = seed | 1;
    let normal = normal.normalize();
    let a = normal.any_orthonormal_vector();
    let b = normal.cross(a);
    let mut pts: Vec<Vec3> = (0..n)
        .map(|_| {
            let (u, v, e) = (
                rnd(&mut s) - 0.5,
                rnd(&mut s) - 0.5,
                (rnd(&mut s) - 0.5) * 2.0 * noise,
            );
            normal * (offset + e) + a * u * 0.4 + b * v * 0.4
        })
        .collect();
    pts.extend((0..outliers).map(|_| Vec3::new(rnd(&mut s), rnd(&mut s), rnd(&mut s)) - 0.5));
    pts
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// RANSAC finds the plane among 40 % outliers within a fraction of the noise.
    #[test]
    fn ransac_finds_a_plane_among_outliers(
        nx in -1.0f32..1.0, ny in 0.2f32..1.0, nz in -1.0f32..1.0,
        offset in -0.3f32..0.3, seed in 1u64..1000,
    ) {
        let normal = Vec3::new(nx, ny, nz).normalize();
        let pts = plane_cloud(normal, offset, 600, 0.001, 400, seed);
        let opts = RansacOptions { threshold_m: 0.003, seed, ..RansacOptions::default() };
        let fit = fit_plane_ransac(&pts, &opts).unwrap();
        let n = if fit.normal.dot(normal) < 0.0 { -fit.normal } else { fit.normal };
        let off = if fit.normal.dot(normal) < 0.0 { -fit.offset } else { fit.offset };
        prop_assert!(n.angle_between(normal).to_degrees() < 0.5, "normal {n} vs {normal}");
        prop_assert!((off - offset).abs() < 5e-4, "offset {off} vs {offset}");
        prop_assert!(fit.inliers >= 590 && fit.inliers < 700, "inliers {}", fit.inliers);
        prop_assert!(fit.rms_m < 0.001);
    }
}

#[test]
fn ransac_orients_by_the_hint_and_refuses_sparse_input() {
    let pts = plane_cloud(Vec3::Y, 0.1, 300, 0.0005, 100, 5);
    let fit = fit_plane_ransac(
        &pts,
        &RansacOptions {
            normal_hint: Some(-Vec3::Y),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        (fit.normal + Vec3::Y).length() < 1e-3 && (fit.offset + 0.1).abs() < 1e-3,
        "{fit:?}"
    );
    // A hint far from the only plane: nothing qualifies.
    let err = fit_plane_ransac(
        &pts,
        &RansacOptions {
            normal_hint: Some(Vec3::X),
            ..Default::default()
        },
    );
    assert!(matches!(err, Err(CalibError::NoPlane { .. })), "{err:?}");
    let err = fit_plane_ransac(&pts[..10], &RansacOptions::default());
    assert!(
        matches!(err, Err(CalibError::TooFewPoints { found: 10, .. })),
        "{err:?}"
    );
}

#[test]
fn nelder_mead_minimises_rosenbrock_and_a_robust_bowl() {
    let rosen = |x: &[f64]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
    let opts = NelderMeadOptions {
        max_iterations: 2000,
        f_tol: 1e-14,
        x_tol: 1e-8,
    };
    let m = nelder_mead(rosen, &[-1.2, 1.0], &[0.5, 0.5], &opts);
    assert!(
        (m.x[0] - 1.0).abs() < 1e-3 && (m.x[1] - 1.0).abs() < 1e-3,
        "{m:?}"
    );
    assert!(m.evaluations > m.iterations);
    // A saturating (Geman–McClure) bowl in three variables with a NaN region.
    let f = |x: &[f64]| {
        if x[2] > 50.0 {
            return f64::NAN;
        }
        let r2: f64 = x
            .iter()
            .zip([3.0, -2.0, 0.5])
            .map(|(a, b)| (a - b).powi(2))
            .sum();
        r2 / (r2 + 4.0)
    };
    let m = nelder_mead(f, &[0.0; 3], &[2.0; 3], &NelderMeadOptions::default());
    assert!(m.value < 1e-6, "{m:?}");
}

/// A frame of the platform plane `y = 0` seen from `rig` (exact depths in 0.1 mm units).
fn render_platform(rig: &Rig, intr: &Intrinsics) -> DepthFrame {
    let to_rig = rig.camera_to_rig();
    let mut f = DepthFrame::empty(intr.width, intr.height, 1e-4);
    for v in 0..intr.height {
        for u in 0..intr.width {
            // The ray through the pixel at depth 1, in the rig frame.
            let o = to_rig.transform_point3(Vec3::ZERO);
            let d = to_rig.transform_point3(intr.unproject(u as f32, v as f32, 1.0)) - o;
            if d.y < -1e-6 {
                let z = -o.y / d.y;
                let p = o + d * z;
                if p.x.hypot(p.z) < 0.16 {
                    f.data[(v * intr.width + u) as usize] = (z / 1e-4).round() as u16;
                }
            }
        }
    }
    f
}

/// A 160×120 sensor, enough for the platform-plane fits.
fn small_sensor() -> Intrinsics {
    Intrinsics {
        width: 160,
        height: 120,
        fx: 145.0,
        fy: 145.0,
        cx: 79.5,
        cy: 59.5,
    }
}

#[test]
fn platform_plane_gives_tilt_and_height() {
    let intr = small_sensor();
    let truth = Rig {
        tilt_deg: 21.5,
        sensor_position_m: Vec3::new(0.0, 0.32, 0.68),
    };
    let frame = render_platform(&truth, &intr);
    let snaps = [CalibSnapshot {
        angle_deg: 0.0,
        frame,
    }];
    // Start 2° and 1 cm off.
    let start = Rig {
        tilt_deg: 19.5,
        sensor_position_m: Vec3::new(0.01, 0.31, 0.69),
    };
    let fit = calibrate_platform(
        &snaps,
        &intr,
        &start,
        &PlatformOptions {
            step: 1,
            ..Default::default()
        },
    )
    .unwrap();
    assert!((fit.tilt_deg - 21.5).abs() < 0.02, "{fit:?}");
    assert!((fit.height_m - 0.32).abs() < 2e-4, "{fit:?}");
    assert!(fit.roll_deg.abs() < 0.02, "{fit:?}");
    let rig = fit.apply(start);
    assert_eq!(rig.sensor_position_m.x, 0.01);
}

#[test]
fn images_show_depth_and_views() {
    let intr = small_sensor();
    let rig = Rig {
        tilt_deg: 20.0,
        sensor_position_m: Vec3::new(0.0, 0.3, 0.7),
    };
    let frame = render_platform(&rig, &intr);
    let img = depth_image(&frame).unwrap();
    // The platform's near edge (bottom rows) is lighter than its far edge (top rows).
    let col = |y| {
        (0..160)
            .filter_map(|x| img.get(x, y))
            .map(|p| p[0])
            .max()
            .unwrap()
    };
    let rows: Vec<u32> = (0..120).filter(|&y| col(y) > 0).collect();
    assert!(
        col(*rows.last().unwrap()) > col(rows[0]),
        "nearer must be lighter"
    );
    let clip = ClipBox {
        min: Vec3::splat(-0.2),
        max: Vec3::splat(0.2),
    };
    let snaps: Vec<Snapshot> = [0.0, 90.0]
        .iter()
        .map(|&a| Snapshot::from_frame(&frame, &intr, &rig, a, &clip).unwrap())
        .collect();
    let views = views_image(&snaps, 64);
    assert_eq!((views.width, views.height), (132, 64));
    assert!(
        views
            .data
            .chunks_exact(3)
            .filter(|p| p.iter().any(|&c| c > 100))
            .count()
            > 200
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.png");
    write_png(&path, &views).unwrap();
    assert!(std::fs::metadata(&path).unwrap().len() > 100);
    let bad = voxoct_depth::RgbImage {
        width: 3,
        height: 3,
        data: vec![0; 5],
    };
    assert!(write_png(dir.path().join("b.png"), &bad).is_err());
}

/// Spheres standing off the axis on the turntable disk (radius 0.16 m, top at y = 0), in
/// the object frame: (centre, radius).
const SPHERES: [(Vec3, f32); 4] = [
    (Vec3::new(0.05, 0.05, 0.02), 0.05),
    (Vec3::new(-0.05, 0.04, -0.05), 0.04),
    (Vec3::new(-0.01, 0.13, -0.01), 0.04),
    (Vec3::new(0.02, 0.03, -0.09), 0.03),
];

/// A ray-cast frame of the spheres and the disk at turntable angle `angle_deg`, seen from
/// `rig`, in 0.1 mm units with ±0.5 mm of deterministic noise.
fn render_scene(rig: &Rig, intr: &Intrinsics, angle_deg: f32, seed: u64) -> DepthFrame {
    let to_rig = rig.camera_to_rig();
    let turn = voxoct_depth::glam::Mat3::from_rotation_y(angle_deg.to_radians());
    let spheres: Vec<(Vec3, f32)> = SPHERES.iter().map(|&(c, r)| (turn * c, r)).collect();
    let o = rig.sensor_position_m;
    let mut s = seed | 1;
    let mut f = DepthFrame::empty(intr.width, intr.height, 1e-4);
    for v in 0..intr.height {
        for u in 0..intr.width {
            // Point at camera depth t: o + t·d.
            let d = to_rig.transform_point3(intr.unproject(u as f32, v as f32, 1.0)) - o;
            let mut best = f32::INFINITY;
            if d.y < 0.0 {
                let t = -o.y / d.y;
                let p = o + d * t;
                if p.x.hypot(p.z) < 0.16 {
                    best = t;
                }
            }
            for &(c, r) in &spheres {
                let oc = o - c;
                let (a, b, cc) = (d.dot(d), 2.0 * d.dot(oc), oc.dot(oc) - r * r);
                let disc = b * b - 4.0 * a * cc;
                if disc >= 0.0 {
                    let t = (-b - disc.sqrt()) / (2.0 * a);
                    if t > 0.0 {
                        best = best.min(t);
                    }
                }
            }
            if best.is_finite() {
                let z = best + (rnd(&mut s) - 0.5) * 1e-3;
                f.data[(v * intr.width + u) as usize] = (z / 1e-4).round() as u16;
            }
        }
    }
    f
}

fn scene_scan(rig: &Rig, intr: &Intrinsics) -> Vec<CalibSnapshot> {
    (0..8)
        .map(|k| {
            let a = 45.0 * k as f32;
            CalibSnapshot {
                angle_deg: a,
                frame: render_scene(rig, intr, a, 100 + k),
            }
        })
        .collect()
}

#[test]
fn axis_is_recovered_from_a_synthetic_turn() {
    let intr = Intrinsics {
        width: 320,
        height: 240,
        fx: 290.0,
        fy: 290.0,
        cx: 159.5,
        cy: 119.5,
    };
    let truth = Rig {
        tilt_deg: 20.0,
        sensor_position_m: Vec3::new(0.004, 0.3, 0.68),
    };
    let snaps = scene_scan(&truth, &intr);
    let clip = ClipBox {
        min: Vec3::new(-0.15, 0.003, -0.15),
        max: Vec3::new(0.15, 0.3, 0.15),
    };
    let start = Rig {
        tilt_deg: 21.5,
        sensor_position_m: Vec3::new(-0.005, 0.31, 0.69),
    };
    let cal = voxoct_depth::calibrate(
        &snaps,
        None,
        &intr,
        start,
        &clip,
        &PlatformOptions::default(),
        &AxisOptions::default(),
    )
    .unwrap();
    let err = cal.rig.sensor_position_m - truth.sensor_position_m;
    println!(
        "synthetic: position error {err} m, tilt error {}°, residual {} → {} m",
        cal.rig.tilt_deg - truth.tilt_deg,
        cal.residual_before_m,
        cal.residual_after_m
    );
    assert!(err.abs().max_element() < 1e-3, "{cal:?}");
    assert!((cal.rig.tilt_deg - truth.tilt_deg).abs() < 0.1, "{cal:?}");
    assert!(
        cal.residual_after_m < 0.6 * cal.residual_before_m,
        "{cal:?}"
    );
    assert!(cal.platform.is_some());

    // Without the plane, the tilt comes from the snapshots' agreement alone (the height,
    // a shift along the axis, cannot: it stays as given).
    let start = Rig {
        tilt_deg: 21.0,
        sensor_position_m: Vec3::new(-0.005, 0.3, 0.69),
    };
    let opts = AxisOptions {
        free_tilt: true,
        ..AxisOptions::default()
    };
    let cal = calibrate_axis(&snaps, &intr, start, &clip, &opts).unwrap();
    let err = cal.rig.sensor_position_m - truth.sensor_position_m;
    println!(
        "synthetic, free tilt: position error {err} m, tilt error {}°",
        cal.rig.tilt_deg - truth.tilt_deg
    );
    assert!(err.abs().max_element() < 1e-3, "{cal:?}");
    assert!((cal.rig.tilt_deg - truth.tilt_deg).abs() < 0.1, "{cal:?}");
}

#[test]
fn axis_needs_two_angles() {
    let intr = Intrinsics {
        width: 320,
        height: 240,
        fx: 290.0,
        fy: 290.0,
        cx: 159.5,
        cy: 119.5,
    };
    let rig = Rig {
        tilt_deg: 20.0,
        sensor_position_m: Vec3::new(0.0, 0.3, 0.68),
    };
    let snaps = [CalibSnapshot {
        angle_deg: 0.0,
        frame: render_scene(&rig, &intr, 0.0, 1),
    }];
    let clip = ClipBox {
        min: Vec3::splat(-0.2),
        max: Vec3::splat(0.2),
    };
    let err = calibrate_axis(&snaps, &intr, rig, &clip, &AxisOptions::default());
    assert!(matches!(err, Err(CalibError::Snapshots { .. })), "{err:?}");
    let bad = AxisOptions {
        scales_m: [0.0, 0.001, 0.001],
        ..AxisOptions::default()
    };
    let err = calibrate_axis(&snaps, &intr, rig, &clip, &bad);
    assert!(
        matches!(
            err,
            Err(CalibError::InvalidOption {
                name: "scales_m",
                ..
            })
        ),
        "{err:?}"
    );
}
