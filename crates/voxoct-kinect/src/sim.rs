//! The simulated Kinect v1: ray casting a model on a turntable, with the sensor's noise.

use std::time::{Duration, Instant};

use glam::{Affine3A, Vec3};
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::TriMesh;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use voxoct_depth::noise::KINECT_V1_FOCAL_BASELINE_PX_M;
use voxoct_depth::{DepthFrame, Intrinsics, Rig};

use crate::{DepthSource, Model, SourceError};

/// Kinect v1 depth noise and artefacts, after Khoshelham & Elberink (2012), "Accuracy and
/// resolution of Kinect depth data for indoor mapping applications", Sensors 12(2).
///
/// The sensor measures a disparity `d = f·b / z` (pixels) between the projected speckle
/// pattern and its reference; the disparity carries Gaussian noise and is quantised to
/// 1/8 px, so the depth error grows as `σ_z = z² · σ_d / (f·b)`. The default `σ_d` is the
/// one of [`voxoct_depth::noise`] (the model the filters and the carving margin use):
/// σ_z ≈ 0.7 mm at 0.7 m, 2.4 mm at 1.3 m, before quantisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// `f · b`: focal length (px) times the projector–camera baseline (m). Kinect v1:
    /// 580 px × 0.075 m = 43.5 px·m.
    pub focal_baseline_px_m: f32,
    /// Standard deviation of the disparity noise, pixels (Kinect v1: ≈ 1/16 px,
    /// [`voxoct_depth::noise::kinect_v1_disparity_sigma_px`]; 0 = none).
    pub disparity_sigma_px: f32,
    /// Disparity quantisation step, pixels (1/8 px; 0 = none).
    pub disparity_step_px: f32,
    /// No reading nearer than this, metres (0.4 m).
    pub min_range_m: f32,
    /// No reading farther than this, metres (4.0 m).
    pub max_range_m: f32,
    /// Position of the IR projector along the camera's x axis, metres: a surface point that
    /// the projector cannot see has no reading (its shadow). The default, −0.075 m, puts the
    /// projector 7.5 cm to the camera's left, as in the project's reference scan; `None`
    /// switches the shadow off.
    pub projector_offset_x_m: Option<f32>,
    /// Incidence angle (between the ray and the surface normal), degrees, where drop-outs
    /// start; the probability of a drop-out rises quadratically to 1 at
    /// [`NoiseModel::grazing_end_deg`].
    pub grazing_start_deg: f32,
    /// Incidence angle, degrees, from which a pixel never has a reading.
    pub grazing_end_deg: f32,
    /// A pixel whose neighbour (within [`NoiseModel::edge_radius_px`]) is farther or nearer by
    /// more than this, metres, or has no return, sits on a depth edge.
    pub edge_jump_m: f32,
    /// Neighbourhood radius for depth edges, pixels (square window).
    pub edge_radius_px: u32,
    /// Probability that an edge pixel has no reading in a given frame (flicker).
    pub edge_flicker_prob: f32,
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self::KINECT_V1
    }
}

impl NoiseModel {
    /// The Kinect v1 figures used throughout the project. (The dev scans of `../shared/data`
    /// were rendered with twice this disparity noise, `disparity_sigma_px: 0.125`.)
    pub const KINECT_V1: Self = Self {
        focal_baseline_px_m: KINECT_V1_FOCAL_BASELINE_PX_M,
        disparity_sigma_px: voxoct_depth::noise::kinect_v1_disparity_sigma_px(),
        disparity_step_px: 0.125,
        min_range_m: 0.4,
        max_range_m: 4.0,
        projector_offset_x_m: Some(-0.075),
        grazing_start_deg: 70.0,
        grazing_end_deg: 88.0,
        edge_jump_m: 0.02,
        edge_radius_px: 1,
        edge_flicker_prob: 0.4,
    };

    /// The model's standard deviation of depth at `z` metres, from disparity noise alone:
    /// `z² · σ_d / (f·b)`.
    #[inline]
    #[must_use]
    pub fn depth_sigma_m(&self, z: f32) -> f32 {
        z * z * self.disparity_sigma_px / self.focal_baseline_px_m
    }
}

/// Everything the simulator needs besides the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// The depth camera (frame size comes from here).
    pub intrinsics: Intrinsics,
    /// Where the sensor sits (SCAN_FORMAT.md conventions).
    pub rig: Rig,
    /// Seed of the noise: the same seed, model, configuration and sequence of calls give the
    /// same frames.
    pub seed: u64,
    /// Noise-free frames: exact depths (rounded to [`SimConfig::unit_m`]), no disparity noise
    /// or quantisation, no drop-outs, no flicker. Geometry stays: range limits and the
    /// projector's shadow.
    pub exact: bool,
    /// The sensor model.
    pub noise: NoiseModel,
    /// Radius of the turntable disk, metres (its top face is at y = 0).
    pub turntable_radius_m: f32,
    /// Thickness of the turntable disk, metres.
    pub turntable_thickness_m: f32,
    /// The floor (an infinite horizontal plane) lies this far below the platform's top, metres.
    pub floor_drop_m: f32,
    /// Metres per stored depth unit of the frames (0.001: millimetres, rounded to nearest).
    pub unit_m: f32,
}

impl Default for SimConfig {
    /// The rig of the project's reference bunny scan: Kinect v1 intrinsics (f = 580 px,
    /// 640×480), sensor 0.30 m above the platform and 0.70 m from the axis, pitched down
    /// 17.82°; turntable radius 0.16 m, floor 9 cm below; millimetre units.
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::KINECT_V1,
            rig: Rig {
                tilt_deg: 17.82,
                sensor_position_m: Vec3::new(0.0, 0.30, 0.70),
            },
            seed: 0x5EED,
            exact: false,
            noise: NoiseModel::KINECT_V1,
            turntable_radius_m: 0.16,
            turntable_thickness_m: 0.02,
            floor_drop_m: 0.09,
            unit_m: 0.001,
        }
    }
}

impl SimConfig {
    /// Checks every field's range.
    ///
    /// # Errors
    /// [`SourceError::Config`] naming the first field out of range.
    pub fn validate(&self) -> Result<(), SourceError> {
        let bad = |field: &'static str, message: &str| {
            Err(SourceError::Config {
                field,
                message: message.to_owned(),
            })
        };
        let pos = |x: f32| x.is_finite() && x > 0.0;
        let nonneg = |x: f32| x.is_finite() && x >= 0.0;
        let prob = |x: f32| (0.0..=1.0).contains(&x);
        let i = &self.intrinsics;
        let n = &self.noise;
        if i.width == 0 || i.height == 0 || i.width > 8192 || i.height > 8192 {
            return bad("intrinsics", "width and height must be within 1..=8192");
        }
        if !(pos(i.fx) && pos(i.fy) && i.cx.is_finite() && i.cy.is_finite()) {
            return bad("intrinsics", "focal lengths must be positive and finite");
        }
        if !(self.rig.tilt_deg.is_finite() && self.rig.sensor_position_m.is_finite()) {
            return bad("rig", "tilt and position must be finite");
        }
        if !pos(self.unit_m) || self.unit_m * 65535.0 < n.max_range_m {
            return bad(
                "unit_m",
                "must be positive and let 65535 units reach max_range_m",
            );
        }
        if !pos(n.focal_baseline_px_m) {
            return bad("noise.focal_baseline_px_m", "must be positive");
        }
        if !nonneg(n.disparity_sigma_px) || !nonneg(n.disparity_step_px) {
            return bad("noise.disparity_sigma_px", "sigma and step must be >= 0");
        }
        if !(nonneg(n.min_range_m) && pos(n.max_range_m) && n.min_range_m < n.max_range_m) {
            return bad("noise.min_range_m", "need 0 <= min_range_m < max_range_m");
        }
        if !n.projector_offset_x_m.is_none_or(f32::is_finite) {
            return bad("noise.projector_offset_x_m", "must be finite");
        }
        if !(nonneg(n.grazing_start_deg)
            && n.grazing_start_deg < n.grazing_end_deg
            && n.grazing_end_deg <= 90.0)
        {
            return bad(
                "noise.grazing_start_deg",
                "need 0 <= grazing_start_deg < grazing_end_deg <= 90",
            );
        }
        if !pos(n.edge_jump_m) {
            return bad("noise.edge_jump_m", "must be positive");
        }
        if !prob(n.edge_flicker_prob) {
            return bad("noise.edge_flicker_prob", "must be within 0..=1");
        }
        if !pos(self.turntable_radius_m) || !pos(self.turntable_thickness_m) {
            return bad(
                "turntable_radius_m",
                "radius and thickness must be positive",
            );
        }
        if !(pos(self.floor_drop_m) && self.floor_drop_m >= self.turntable_thickness_m) {
            return bad("floor_drop_m", "must be at least the turntable's thickness");
        }
        Ok(())
    }
}

/// Time spent by the simulator on its last frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SimTimings {
    /// Ray casting for the current turntable angle (zero when the cache was reused).
    pub cast: Duration,
    /// Making the frame's noise from the cache.
    pub noise: Duration,
}

/// Per-angle cache: each pixel's ray is cast once per turntable angle.
#[derive(Debug, Clone)]
struct RayCache {
    angle_deg: f32,
    /// Exact depth along the optical axis, metres; 0 = no return (miss or shadow).
    z: Vec<f32>,
    /// |cos| of the angle between the ray and the surface normal.
    cos: Vec<f32>,
    /// On a depth edge.
    edge: Vec<bool>,
}

/// A simulated Kinect v1 looking at a model on a turntable.
///
/// The scene, in the platform frame: the model (which turns with the turntable by `+angle`
/// about +Y), the turntable disk (top face at y = 0) and the floor. Each pixel's ray is cast
/// once per turntable angle (parry3d `TriMesh` BVH, rows in parallel with rayon) — exact
/// depth, incidence, projector shadow and depth edges are cached — and each frame's noise is
/// drawn from that cache, so further frames at the same angle are cheap.
///
/// Frames back-project through [`Rig::camera_to_object`]`(angle)` onto the unrotated model.
#[derive(Debug, Clone)]
pub struct SimulatedKinect {
    config: SimConfig,
    /// The model and the turntable disk in the object frame.
    scene: TriMesh,
    angle_deg: f32,
    cache: Option<RayCache>,
    frames: u64,
    timings: SimTimings,
}

impl SimulatedKinect {
    /// A simulator of `model` (platform frame, standing on y = 0) with `config`.
    ///
    /// # Errors
    /// [`SourceError::Config`] for a configuration out of range, [`SourceError::BadModel`]
    /// for a model without triangles or with non-finite coordinates.
    pub fn new(model: &Model, config: SimConfig) -> Result<Self, SourceError> {
        config.validate()?;
        model.validate("for the simulator")?;
        let mut scene = model.clone();
        scene.append(&turntable_disk(
            config.turntable_radius_m,
            config.turntable_thickness_m,
        ));
        Ok(Self {
            scene: scene.to_trimesh()?,
            config,
            angle_deg: 0.0,
            cache: None,
            frames: 0,
            timings: SimTimings::default(),
        })
    }

    /// A simulator of a built-in model ([`Model::BUILTIN_NAMES`]).
    ///
    /// # Errors
    /// [`SourceError::BadModel`] for an unknown name; as [`SimulatedKinect::new`].
    pub fn builtin(name: &str, config: SimConfig) -> Result<Self, SourceError> {
        let model = Model::builtin(name).ok_or_else(|| SourceError::BadModel {
            what: name.to_owned(),
            message: format!(
                "no built-in model of that name (known: {})",
                Model::BUILTIN_NAMES.join(", ")
            ),
        })?;
        Self::new(&model, config)
    }

    /// Turns the simulated turntable to `deg` degrees (the object turns by `+deg` about +Y).
    pub fn set_turntable_angle_deg(&mut self, deg: f32) {
        self.angle_deg = deg;
    }

    /// The simulated turntable's angle, degrees.
    #[must_use]
    pub fn turntable_angle_deg(&self) -> f32 {
        self.angle_deg
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Time spent on the last frame.
    #[must_use]
    pub fn last_timings(&self) -> SimTimings {
        self.timings
    }

    /// The model together with the turntable disk, in the object frame (the floor, the plane
    /// `y = -floor_drop_m`, is not part of it).
    #[must_use]
    pub fn scene_mesh(&self) -> &TriMesh {
        &self.scene
    }

    /// Distance from a point of the object frame to the nearest surface of the scene: model,
    /// turntable or floor.
    #[must_use]
    pub fn distance_to_scene(&self, p: Vec3) -> f32 {
        let mesh = self.scene.distance_to_local_point(p, false);
        mesh.min((p.y + self.config.floor_drop_m).abs())
    }

    /// The exact depth of every pixel (metres, 0 = no return) at the current angle, before
    /// noise and rounding.
    pub fn exact_depth_m(&mut self) -> &[f32] {
        self.ensure_cache();
        match &self.cache {
            Some(c) => &c.z,
            None => &[],
        }
    }

    /// Renders the next frame at the current turntable angle.
    pub fn render(&mut self) -> DepthFrame {
        self.ensure_cache();
        let t = Instant::now();
        let (w, h) = (self.config.intrinsics.width, self.config.intrinsics.height);
        let mut frame = DepthFrame::empty(w, h, self.config.unit_m);
        if let Some(cache) = &self.cache {
            let cfg = &self.config;
            let frame_no = self.frames;
            let cos_start = cfg.noise.grazing_start_deg.to_radians().cos();
            frame
                .data
                .par_chunks_mut(w as usize)
                .enumerate()
                .for_each(|(v, row)| {
                    let start = v * w as usize;
                    let mut rng = Pcg64Mcg::seed_from_u64(mix(cfg.seed, frame_no, v as u64));
                    for (u, out) in row.iter_mut().enumerate() {
                        let i = start + u;
                        *out = pixel(
                            cfg,
                            &mut rng,
                            cache.z[i],
                            cache.cos[i],
                            cache.edge[i],
                            cos_start,
                        );
                    }
                });
        }
        self.frames += 1;
        self.timings.noise = t.elapsed();
        frame
    }

    fn ensure_cache(&mut self) {
        if self
            .cache
            .as_ref()
            .is_some_and(|c| c.angle_deg.to_bits() == self.angle_deg.to_bits())
        {
            self.timings.cast = Duration::ZERO;
            return;
        }
        let t = Instant::now();
        self.cache = Some(self.cast());
        self.timings.cast = t.elapsed();
    }

    /// Casts every pixel's ray at the current angle.
    fn cast(&self) -> RayCache {
        let cfg = &self.config;
        let k = &cfg.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let cam_to_obj: Affine3A = cfg.rig.camera_to_object(self.angle_deg);
        let origin = Vec3::from(cam_to_obj.translation);
        let projector = cfg
            .noise
            .projector_offset_x_m
            .map(|x| cam_to_obj.transform_point3(Vec3::new(x, 0.0, 0.0)));
        let floor_y = -cfg.floor_drop_m;
        // Rays are cast a little beyond the range so that range limits apply to exact depths.
        let max_t = cfg.noise.max_range_m * 1.01;
        let mut z = vec![0.0f32; w * h];
        let mut cos = vec![0.0f32; w * h];
        z.par_chunks_mut(w)
            .zip(cos.par_chunks_mut(w))
            .enumerate()
            .for_each(|(v, (zrow, crow))| {
                for u in 0..w {
                    // Camera-frame direction with z = 1, so the time of impact is the depth.
                    let d_cam = Vec3::new((u as f32 - k.cx) / k.fx, (v as f32 - k.cy) / k.fy, 1.0);
                    let dir = cam_to_obj.transform_vector3(d_cam);
                    let ray = Ray::new(origin, dir);
                    let mut best: Option<(f32, Vec3)> = self
                        .scene
                        .cast_local_ray_and_get_normal(&ray, max_t, true)
                        .map(|hit| (hit.time_of_impact, hit.normal));
                    if dir.y < 0.0 {
                        let t = (floor_y - origin.y) / dir.y;
                        if t > 0.0 && t < max_t && best.is_none_or(|(b, _)| t < b) {
                            best = Some((t, Vec3::Y));
                        }
                    }
                    let Some((t, n)) = best else { continue };
                    let p = origin + dir * t;
                    if let Some(q) = projector {
                        let to_p = p - q;
                        let len = to_p.length();
                        // Stop 1 mm short of the point so that its own surface does not count.
                        let reach = 1.0 - 1e-3 / len.max(1e-3);
                        if self.scene.intersects_local_ray(&Ray::new(q, to_p), reach) {
                            continue;
                        }
                    }
                    zrow[u] = t;
                    crow[u] = n.normalize_or_zero().dot(dir.normalize()).abs();
                }
            });
        let edge = depth_edges(
            &z,
            w,
            h,
            cfg.noise.edge_radius_px as usize,
            cfg.noise.edge_jump_m,
        );
        RayCache {
            angle_deg: self.angle_deg,
            z,
            cos,
            edge,
        }
    }
}

/// Marks pixels with a return whose neighbourhood holds a pixel without one or a depth jump.
fn depth_edges(z: &[f32], w: usize, h: usize, r: usize, jump: f32) -> Vec<bool> {
    let mut edge = vec![false; w * h];
    edge.par_chunks_mut(w).enumerate().for_each(|(v, row)| {
        for (u, e) in row.iter_mut().enumerate() {
            let zc = z[v * w + u];
            if zc == 0.0 {
                continue;
            }
            'win: for vv in v.saturating_sub(r)..=(v + r).min(h - 1) {
                for uu in u.saturating_sub(r)..=(u + r).min(w - 1) {
                    let zn = z[vv * w + uu];
                    if zn == 0.0 || (zn - zc).abs() > jump {
                        *e = true;
                        break 'win;
                    }
                }
            }
        }
    });
    edge
}

/// One pixel's stored value from its cached ray; `cos_start` is the cosine of
/// `grazing_start_deg` (drop-outs only below it).
#[inline]
fn pixel(cfg: &SimConfig, rng: &mut Pcg64Mcg, z: f32, cos: f32, edge: bool, cos_start: f32) -> u16 {
    if z <= 0.0 {
        return 0;
    }
    let n = &cfg.noise;
    let z = if cfg.exact {
        z
    } else {
        if edge && rng.random::<f32>() < n.edge_flicker_prob {
            return 0;
        }
        if cos < cos_start {
            let incidence = cos.clamp(0.0, 1.0).acos().to_degrees();
            let p_drop = ((incidence - n.grazing_start_deg)
                / (n.grazing_end_deg - n.grazing_start_deg))
                .clamp(0.0, 1.0);
            if rng.random::<f32>() < p_drop * p_drop {
                return 0;
            }
        }
        let mut d = n.focal_baseline_px_m / z;
        if n.disparity_sigma_px > 0.0 {
            d += n.disparity_sigma_px * rng.sample::<f32, _>(StandardNormal);
        }
        if n.disparity_step_px > 0.0 {
            d = (d / n.disparity_step_px).round() * n.disparity_step_px;
        }
        if d <= 0.0 {
            return 0;
        }
        n.focal_baseline_px_m / d
    };
    if !(n.min_range_m..=n.max_range_m).contains(&z) {
        return 0;
    }
    let q = (z / cfg.unit_m).round();
    if (1.0..=65535.0).contains(&q) {
        q as u16
    } else {
        0
    }
}

/// A well-mixed 64-bit seed from the user's seed, the frame number and the row (SplitMix64
/// finaliser), so that rows can be drawn in parallel and still reproduce.
fn mix(seed: u64, frame: u64, row: u64) -> u64 {
    let mut x =
        seed ^ frame.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ row.wrapping_mul(0xD1B5_4A32_D192_ED03);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The turntable: a closed disk of `radius`, top face at y = 0, `thickness` thick.
fn turntable_disk(radius: f32, thickness: f32) -> Model {
    crate::model::cylinder(radius, thickness, 128).translated(Vec3::new(0.0, -thickness, 0.0))
}

impl DepthSource for SimulatedKinect {
    fn intrinsics(&self) -> Intrinsics {
        self.config.intrinsics
    }

    /// Renders a frame; never waits, so `timeout` is ignored.
    fn grab(&mut self, _timeout: Duration) -> Result<DepthFrame, SourceError> {
        Ok(self.render())
    }

    /// The rig's tilt (pitch down, degrees).
    fn tilt_deg(&mut self) -> Option<f32> {
        Some(self.config.rig.tilt_deg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rate(cfg: &SimConfig, z: f32, cos: f32, edge: bool) -> f32 {
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let n = 20_000;
        let cos_start = cfg.noise.grazing_start_deg.to_radians().cos();
        let valid = (0..n)
            .filter(|_| pixel(cfg, &mut rng, z, cos, edge, cos_start) != 0)
            .count();
        valid as f32 / n as f32
    }

    #[test]
    fn grazing_incidence_drops_readings() {
        let cfg = SimConfig::default();
        assert_eq!(rate(&cfg, 0.7, 1.0, false), 1.0);
        assert_eq!(rate(&cfg, 0.7, 60f32.to_radians().cos(), false), 1.0);
        let mid = rate(&cfg, 0.7, 80f32.to_radians().cos(), false);
        // p_drop = ((80 - 70) / 18)² ≈ 0.31.
        assert!((mid - 0.69).abs() < 0.03, "{mid}");
        assert_eq!(rate(&cfg, 0.7, 89.5f32.to_radians().cos(), false), 0.0);
    }

    #[test]
    fn edges_flicker_with_the_configured_probability() {
        let cfg = SimConfig::default();
        let r = rate(&cfg, 0.7, 1.0, true);
        assert!((r - 0.6).abs() < 0.02, "{r}");
        let exact = SimConfig { exact: true, ..cfg };
        assert_eq!(rate(&exact, 0.7, 0.01, true), 1.0);
    }

    #[test]
    fn range_limits_apply_even_when_exact() {
        let cfg = SimConfig {
            exact: true,
            ..SimConfig::default()
        };
        let mut rng = Pcg64Mcg::seed_from_u64(1);
        assert_eq!(pixel(&cfg, &mut rng, 0.39, 1.0, false, 0.3), 0);
        assert_eq!(pixel(&cfg, &mut rng, 4.01, 1.0, false, 0.3), 0);
        assert_eq!(pixel(&cfg, &mut rng, 0.7004, 1.0, false, 0.3), 700);
        assert_eq!(pixel(&cfg, &mut rng, 0.7006, 1.0, false, 0.3), 701);
    }

    #[test]
    fn noisy_depths_come_from_quantised_disparities() {
        // Without the millimetre rounding (fine units), every depth is f·b / (k / 8).
        let cfg = SimConfig {
            unit_m: 1e-5,
            noise: NoiseModel {
                max_range_m: 0.6,
                ..NoiseModel::KINECT_V1
            },
            ..SimConfig::default()
        };
        let mut rng = Pcg64Mcg::seed_from_u64(3);
        for _ in 0..200 {
            let q = pixel(&cfg, &mut rng, 0.5, 1.0, false, 0.3);
            let d = 43.5 / (f32::from(q) * 1e-5);
            let k = d * 8.0;
            assert!((k - k.round()).abs() < 0.02, "{q} -> disparity {d}");
        }
    }

    #[test]
    fn too_near_gives_no_reading() {
        let cfg = SimConfig {
            rig: Rig {
                tilt_deg: 0.0,
                sensor_position_m: Vec3::new(0.0, 0.06, 0.35),
            },
            exact: true,
            ..SimConfig::default()
        };
        let mut sim = SimulatedKinect::builtin("sphere", cfg).unwrap();
        assert!((sim.exact_depth_m()[240 * 640 + 320] - 0.29).abs() < 1e-3);
        assert_eq!(sim.render().get(320, 240), 0);
    }

    #[test]
    fn bad_configuration_names_the_field() {
        let cfg = SimConfig {
            noise: NoiseModel {
                edge_flicker_prob: 1.5,
                ..NoiseModel::KINECT_V1
            },
            ..SimConfig::default()
        };
        match SimulatedKinect::builtin("sphere", cfg) {
            Err(SourceError::Config { field, .. }) => assert_eq!(field, "noise.edge_flicker_prob"),
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            SimulatedKinect::builtin("teapot", SimConfig::default()),
            Err(SourceError::BadModel { .. })
        ));
    }
}
