//! The calibration on synthetic data (RANSAC and Nelder–Mead are tested in their modules): the platform's tilt and height from a rendered plane, and the
//! inspection images.

use voxoct_depth::calib::{
    AxisOptions, CalibError, CalibOptions, CalibSnapshot, PlatformOptions, calibrate_axis,
    calibrate_platform,
};
use voxoct_depth::glam::Vec3;
use voxoct_depth::image::{depth_image, views_image, write_png};
use voxoct_depth::snapshot::Snapshot;
use voxoct_depth::{ClipBox, DepthFrame, Intrinsics, Rig, ScannerConfig, SensorConfig};

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

/// A deterministic pseudo-random number in [0, 1).
fn rnd(state: &mut u64) -> f32 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    (*state >> 40) as f32 / (1u64 << 24) as f32
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
    let bad = voxoct_depth::image::RgbImage {
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
    let config = ScannerConfig {
        sensor: SensorConfig {
            intrinsics: intr,
            depth_unit_m: 0.001,
        },
        rig: start,
        clip,
    };
    let cal = voxoct_depth::calib::calibrate(&config, &snaps, &CalibOptions::default()).unwrap();
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
            Err(CalibError::InvalidArgument {
                name: "scales_m",
                ..
            })
        ),
        "{err:?}"
    );
}
