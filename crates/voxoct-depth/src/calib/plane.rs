//! The platform plane: RANSAC and least squares on the points near `y = 0`.

use glam::Vec3;

use super::axis::grid_normals;
use super::{CalibError, CalibSnapshot};
use crate::{DepthFrame, FrameError, Intrinsics, Rig};

// ---- small helpers -------------------------------------------------------------------------

/// SplitMix64: a tiny deterministic generator for RANSAC's samples.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Camera-frame points of every pixel of `frame` (NaN where there is no reading).
pub(crate) fn camera_points(
    frame: &DepthFrame,
    intr: &Intrinsics,
) -> Result<Vec<Vec3>, FrameError> {
    crate::filter::check_frame_size(0, frame, intr.width, intr.height)?;
    let w = frame.width as usize;
    Ok(frame
        .data
        .iter()
        .enumerate()
        .map(|(i, &d)| {
            if d == 0 {
                Vec3::NAN
            } else {
                let (u, v) = ((i % w) as f32, (i / w) as f32);
                intr.unproject(u, v, f32::from(d) * frame.unit_m)
            }
        })
        .collect())
}

// ---- planes --------------------------------------------------------------------------------

/// Options of the RANSAC plane fit of [`calibrate_platform`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacOptions {
    /// Random three-point candidates tried.
    pub iterations: u32,
    /// A point within this distance of a plane is its inlier, metres.
    pub threshold_m: f32,
    /// Fewest inliers to accept a plane.
    pub min_inliers: usize,
    /// Seed of the sampling (the same seed gives the same fit).
    pub seed: u64,
    /// When set, only planes whose normal is within `max_angle_deg` of this direction are
    /// considered, and the normal returned points along it.
    pub normal_hint: Option<Vec3>,
    /// See `normal_hint`, degrees.
    pub max_angle_deg: f32,
}

impl Default for RansacOptions {
    fn default() -> Self {
        Self {
            iterations: 400,
            threshold_m: 0.004,
            min_inliers: 50,
            seed: 1,
            normal_hint: None,
            max_angle_deg: 20.0,
        }
    }
}

/// A fitted plane: the points `p` with `normal · p = offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneFit {
    /// Unit normal.
    pub normal: Vec3,
    /// `normal · p` for points of the plane, metres.
    pub offset: f32,
    /// Inliers of the final fit.
    pub inliers: usize,
    /// Root mean square distance of the inliers to the plane, metres.
    pub rms_m: f32,
}

impl PlaneFit {
    /// Signed distance of `p` to the plane (positive on the normal's side), metres.
    #[inline]
    #[must_use]
    pub fn distance(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }
}

/// Total-least-squares plane through `pts`: the centroid and the covariance's weakest
/// direction (inverse power iteration from `guess`, in f64).
fn least_squares_plane(pts: &[Vec3], guess: Vec3) -> Option<(Vec3, f32)> {
    use glam::{DMat3, DVec3};
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let c = pts.iter().fold(DVec3::ZERO, |a, p| a + p.as_dvec3()) / n;
    let mut cov = DMat3::ZERO;
    for p in pts {
        let d = p.as_dvec3() - c;
        cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    // Regularise by a hair so that an exactly flat cloud stays invertible.
    let scale = (cov.x_axis.x + cov.y_axis.y + cov.z_axis.z).max(1e-30);
    let inv = (cov + DMat3::from_diagonal(DVec3::splat(scale * 1e-12))).inverse();
    if !inv.is_finite() {
        return None;
    }
    let mut v = guess.as_dvec3().normalize_or(DVec3::Y);
    for _ in 0..30 {
        v = (inv * v).normalize_or_zero();
        if v == DVec3::ZERO {
            return None;
        }
    }
    let normal = v.as_vec3();
    Some((normal, v.dot(c) as f32))
}

/// Fits the dominant plane of `points` (non-finite points are ignored): RANSAC over random
/// three-point candidates, then least squares on the inliers, twice.
///
/// Errors: [`CalibError::TooFewPoints`] under `min_inliers` finite points,
/// [`CalibError::NoPlane`] when no candidate reaches `min_inliers`.
pub(crate) fn fit_plane_ransac(
    points: &[Vec3],
    opts: &RansacOptions,
) -> Result<PlaneFit, CalibError> {
    if !(opts.threshold_m.is_finite() && opts.threshold_m > 0.0) {
        return Err(CalibError::InvalidArgument {
            name: "threshold_m",
            reason: format!("{} is not a positive distance", opts.threshold_m),
        });
    }
    let pts: Vec<Vec3> = points.iter().copied().filter(|p| p.is_finite()).collect();
    let needed = opts.min_inliers.max(3);
    if pts.len() < needed {
        return Err(CalibError::TooFewPoints {
            what: "plane",
            found: pts.len(),
            needed,
        });
    }
    let hint = opts.normal_hint.map(Vec3::normalize_or_zero);
    let cos_max = opts.max_angle_deg.to_radians().cos();
    let mut rng = SplitMix(opts.seed);
    let mut best: Option<(usize, Vec3, f32)> = None;
    for _ in 0..opts.iterations.max(1) {
        let (a, b, c) = (
            pts[rng.below(pts.len())],
            pts[rng.below(pts.len())],
            pts[rng.below(pts.len())],
        );
        let mut n = (b - a).cross(c - a);
        if n.length_squared() < 1e-12 {
            continue;
        }
        n = n.normalize();
        if let Some(h) = hint {
            if n.dot(h) < 0.0 {
                n = -n;
            }
            if n.dot(h) < cos_max {
                continue;
            }
        }
        let d = n.dot(a);
        let count = pts
            .iter()
            .filter(|p| (n.dot(**p) - d).abs() < opts.threshold_m)
            .count();
        if best.is_none_or(|(bc, _, _)| count > bc) {
            best = Some((count, n, d));
        }
    }
    let (count, mut n, mut d) = best.unwrap_or((0, Vec3::Y, 0.0));
    if count < needed {
        return Err(CalibError::NoPlane {
            inliers: count,
            points: pts.len(),
        });
    }
    let mut inliers: Vec<Vec3> = Vec::new();
    for _ in 0..3 {
        inliers.clear();
        inliers.extend(
            pts.iter()
                .copied()
                .filter(|p| (n.dot(*p) - d).abs() < opts.threshold_m),
        );
        if let Some((n2, d2)) = least_squares_plane(&inliers, n) {
            (n, d) = (n2, d2);
        }
    }
    let orient = hint.unwrap_or(n);
    if n.dot(orient) < 0.0 {
        (n, d) = (-n, -d);
    }
    let ss: f64 = inliers
        .iter()
        .map(|p| f64::from(n.dot(*p) - d).powi(2))
        .sum();
    let rms_m = (ss / inliers.len().max(1) as f64).sqrt() as f32;
    Ok(PlaneFit {
        normal: n,
        offset: d,
        inliers: inliers.len(),
        rms_m,
    })
}

/// Options of [`calibrate_platform`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformOptions {
    /// Candidate points lie within this height of `y = 0` under the starting rig, metres.
    pub band_m: f32,
    /// ... and within this distance of the axis, metres.
    pub radius_m: f32,
    /// Every `step`-th pixel along rows and columns is used.
    pub step: u32,
    /// The plane fit.
    pub ransac: RansacOptions,
}

impl Default for PlatformOptions {
    fn default() -> Self {
        Self {
            band_m: 0.04,
            radius_m: 0.2,
            step: 2,
            ransac: RansacOptions::default(),
        }
    }
}

/// The platform plane seen by the sensor, as rig values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformFit {
    /// Sensor pitch down, degrees (the rig's `tilt_deg`).
    pub tilt_deg: f32,
    /// Sensor roll about its optical axis, degrees (the rig model assumes 0; a large value
    /// means the sensor is mounted crooked).
    pub roll_deg: f32,
    /// Height of the optical centre above the platform, metres (the rig's
    /// `sensor_position_m.y`).
    pub height_m: f32,
    /// The plane in the camera frame, its normal pointing up.
    pub plane: PlaneFit,
}

impl PlatformFit {
    /// `rig` with the tilt and height of this fit.
    #[must_use]
    pub fn apply(&self, rig: Rig) -> Rig {
        let mut r = rig;
        r.tilt_deg = self.tilt_deg;
        r.sensor_position_m.y = self.height_m;
        r
    }
}

/// The platform's up direction (+Y) in the camera frame of `rig`.
fn up_in_camera(rig: &Rig) -> Vec3 {
    Vec3::from(rig.camera_to_rig().matrix3.transpose() * glam::Vec3A::Y)
}

/// Fits the platform's top plane in `snapshots` (all angles pooled: the plane does not turn)
/// and reads the sensor's tilt, roll and height off it. `start` only selects the candidate
/// points (within [`PlatformOptions::band_m`] of `y = 0`, with a local normal within
/// [`RansacOptions::max_angle_deg`] of up — which keeps out the disk's rim and the object's
/// sides), so it may be off by centimetres and a few degrees.
pub fn calibrate_platform(
    snapshots: &[CalibSnapshot],
    intr: &Intrinsics,
    start: &Rig,
    opts: &PlatformOptions,
) -> Result<PlatformFit, CalibError> {
    let step = opts.step.max(1) as usize;
    let to_rig = start.camera_to_rig();
    let up = up_in_camera(start);
    let cos_max = opts.ransac.max_angle_deg.to_radians().cos();
    let (w, h) = (intr.width as usize, intr.height as usize);
    let mut cands = Vec::new();
    for s in snapshots {
        let pts = camera_points(&s.frame, intr)?;
        let normals = grid_normals(&pts, w, h);
        for (i, (p, n)) in pts.iter().zip(&normals).enumerate() {
            if (i % w) % step != 0 || (i / w) % step != 0 || !n.is_finite() || n.dot(up) < cos_max {
                continue;
            }
            let q = to_rig.transform_point3(*p);
            if q.y.abs() < opts.band_m && q.x.hypot(q.z) < opts.radius_m {
                cands.push(*p);
            }
        }
    }
    let ransac = RansacOptions {
        normal_hint: Some(up),
        ..opts.ransac
    };
    let plane = fit_plane_ransac(&cands, &ransac)?;
    let n = plane.normal;
    // Up in the camera frame is (sin roll, −cos tilt·cos roll, −sin tilt·cos roll).
    let tilt_deg = (-n.z).atan2(-n.y).to_degrees();
    let roll_deg = n.x.clamp(-1.0, 1.0).asin().to_degrees();
    Ok(PlatformFit {
        tilt_deg,
        roll_deg,
        height_m: -plane.offset,
        plane,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
}
