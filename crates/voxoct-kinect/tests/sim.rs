//! The simulated Kinect against its own geometry and noise model.

use std::time::Duration;

use parry3d::query::PointQuery;
use voxoct_kinect::glam::Vec3;
use voxoct_kinect::{DepthFrame, DepthSource, Model, NoiseModel, SimConfig, SimulatedKinect};

const T: Duration = Duration::from_secs(1);

/// Back-projects a pixel into the object frame at turntable angle `angle`.
fn object_point(cfg: &SimConfig, angle: f32, frame: &DepthFrame, u: u32, v: u32) -> Option<Vec3> {
    let z = frame.depth_m(u, v)?;
    let p = cfg.intrinsics.unproject(u as f32, v as f32, z);
    Some(cfg.rig.camera_to_object(angle).transform_point3(p))
}

#[test]
fn exact_frames_back_project_onto_the_scene_within_rounding() {
    let cfg = SimConfig {
        exact: true,
        ..SimConfig::default()
    };
    // The mug is not symmetric about the axis (handle), so a wrong turn would show.
    let model = Model::builtin("mug").unwrap();
    let model_mesh = model.to_trimesh().unwrap();
    let mut sim = SimulatedKinect::new(&model, cfg).unwrap();
    let k = cfg.intrinsics;
    for angle in [0.0f32, 215.0, 270.0] {
        sim.set_turntable_angle_deg(angle);
        let frame = sim.grab(T).unwrap();
        let (mut valid, mut on_model, mut on_handle) = (0, 0, 0);
        for v in 0..k.height {
            for u in 0..k.width {
                let Some(p) = object_point(&cfg, angle, &frame, u, v) else {
                    continue;
                };
                valid += 1;
                // Rounding to 1 mm moves the point along its ray by at most 0.5 mm in z,
                // i.e. 0.5 mm × |ray direction with z = 1|; the surface is no farther.
                let ray = Vec3::new((u as f32 - k.cx) / k.fx, (v as f32 - k.cy) / k.fy, 1.0);
                let bound = 0.5e-3 * ray.length() * 1.001 + 2e-5;
                let d = sim.distance_to_scene(p);
                assert!(
                    d <= bound,
                    "angle {angle}: pixel ({u}, {v}) -> {p} is {d} m off"
                );
                if p.y > 0.003 && model_mesh.distance_to_local_point(p, false) <= bound {
                    on_model += 1;
                    if p.x > 0.05 {
                        on_handle += 1;
                    }
                }
            }
        }
        assert!(valid > 100_000, "angle {angle}: {valid} valid pixels");
        assert!(
            on_model > 5_000,
            "angle {angle}: {on_model} pixels on the mug"
        );
        // The handle (+X of the object frame) is turned to the camera's right at 0°, towards
        // it at 215° and 270° (R_y(270°)·X = +Z): some of it is seen, where the model has it.
        assert!(
            on_handle > 20,
            "angle {angle}: {on_handle} pixels on the handle"
        );
    }
}

#[test]
fn depth_noise_matches_the_disparity_model() {
    let model = Model::builtin("box").unwrap();
    let exact_cfg = SimConfig {
        exact: true,
        ..SimConfig::default()
    };
    let mut exact = SimulatedKinect::new(&model, exact_cfg).unwrap();
    let z_true = exact.exact_depth_m().to_vec();
    let noise = NoiseModel::KINECT_V1;
    let mut noisy = SimulatedKinect::new(&model, SimConfig::default()).unwrap();
    let (mut n, mut sum, mut sum2) = (0usize, 0.0f64, 0.0f64);
    for _ in 0..4 {
        let frame = noisy.grab(T).unwrap();
        for (&q, &z) in frame.data.iter().zip(&z_true) {
            if q == 0 || !(0.6..=0.85).contains(&z) {
                continue;
            }
            let e = (f64::from(q) * 1e-3 - f64::from(z)) / f64::from(noise.depth_sigma_m(z));
            n += 1;
            sum += e;
            sum2 += e * e;
        }
    }
    let mean = sum / n as f64;
    let sd = (sum2 / n as f64 - mean * mean).sqrt();
    // σ_z = z²·σ_d/(f·b) ≈ 1.3–2.1 mm here; quantisation to 1/8 px and to 1 mm add a little.
    assert!(n > 50_000, "{n}");
    assert!(mean.abs() < 0.1, "mean error {mean} σ");
    println!("{n} pixels: mean {mean:.3} σ, spread {sd:.3} σ");
    assert!((0.85..1.35).contains(&sd), "spread {sd} σ");
}

fn exact_sim(projector: Option<f32>) -> SimulatedKinect {
    let cfg = SimConfig {
        exact: true,
        noise: NoiseModel {
            projector_offset_x_m: projector,
            ..NoiseModel::KINECT_V1
        },
        ..SimConfig::default()
    };
    SimulatedKinect::builtin("figurine", cfg).unwrap()
}

/// Mean column of the pixels that the projector's shadow removes, and of the figurine.
fn shadow_and_object_columns(projector: f32) -> (f64, f64, usize) {
    let cfg = SimConfig::default();
    let lit = exact_sim(None).grab(T).unwrap();
    let shadowed = exact_sim(Some(projector)).grab(T).unwrap();
    let (mut su, mut sn, mut ou, mut on) = (0.0, 0usize, 0.0, 0usize);
    for v in 0..lit.height {
        for u in 0..lit.width {
            let Some(p) = object_point(&cfg, 0.0, &lit, u, v) else {
                continue;
            };
            match shadowed.depth_m(u, v) {
                None => {
                    su += f64::from(u);
                    sn += 1;
                }
                Some(_) if p.y > 0.003 && p.x.abs() < 0.15 && p.z.abs() < 0.15 => {
                    ou += f64::from(u);
                    on += 1;
                }
                Some(_) => {}
            }
        }
    }
    (su / sn as f64, ou / on as f64, sn)
}

#[test]
fn projector_shadow_falls_beside_the_object_away_from_the_projector() {
    // Projector on the camera's left (−x): the shadow is on the object's right in the image.
    let (shadow_u, object_u, n) = shadow_and_object_columns(-0.075);
    assert!(n > 300, "{n} shadow pixels");
    assert!(
        shadow_u > object_u + 10.0,
        "shadow at u={shadow_u}, object at u={object_u}"
    );
    let (shadow_u, object_u, n) = shadow_and_object_columns(0.075);
    assert!(n > 300, "{n} shadow pixels");
    assert!(
        shadow_u < object_u - 10.0,
        "shadow at u={shadow_u}, object at u={object_u}"
    );
}

#[test]
fn same_seed_same_frames_other_seed_other_frames() {
    let run = |seed: u64| {
        let cfg = SimConfig {
            seed,
            ..SimConfig::default()
        };
        let mut sim = SimulatedKinect::builtin("torus", cfg).unwrap();
        let a = sim.grab(T).unwrap();
        sim.set_turntable_angle_deg(45.0);
        let b = sim.grab(T).unwrap();
        let c = sim.grab(T).unwrap();
        (a, b, c)
    };
    let (a1, b1, c1) = run(1);
    let (a2, b2, c2) = run(1);
    assert!(a1 == a2 && b1 == b2 && c1 == c2);
    // Consecutive frames at one angle differ (noise, flicker), and so does another seed.
    assert_ne!(b1, c1);
    let (a3, ..) = run(2);
    assert_ne!(a1, a3);
    let differing = a1.data.iter().zip(&a3.data).filter(|(x, y)| x != y).count();
    assert!(differing > 10_000, "{differing}");
}
