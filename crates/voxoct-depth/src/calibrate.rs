//! Rig calibration from recorded scans: the platform plane and the turntable axis.
//!
//! The rig ([`Rig`]) has four numbers: the tilt and the sensor position `(x, y, z)` in the
//! platform frame. Two measurements recover them:
//!
//! 1. **The platform plane** ([`calibrate_platform`]): the platform's top is the plane
//!    `y = 0` of the platform frame. Its points (picked near `y = 0` under the starting
//!    rig, so the floor and the object's upper part stay out) are fitted by RANSAC, then by
//!    least squares on the inliers ([`fit_plane_ransac`]). The plane's normal in the camera
//!    frame is the tilt (and the roll, which the rig model takes as 0 and is only
//!    reported); its distance to the optical centre is the sensor height `y`. An empty
//!    platform is best, but the turntable disk around an object works too.
//! 2. **The turntable axis** ([`calibrate_axis`]): with a wrong `x` or `z` the snapshots,
//!    turned into the common frame, disagree. The disagreement is measured between every
//!    pair of snapshots at most [`AxisOptions::max_pair_angle_deg`] apart: each sampled
//!    point of one snapshot is taken into the other's camera frame, projected to a pixel
//!    (projective association), and its distance to the plane of that pixel (normal from
//!    the pixel grid) goes through the robust Geman–McClure loss. A [`nelder_mead`]
//!    minimiser runs on it from coarse to fine (the loss's scale shrinks from 6 to 1 mm).
//!
//! What is observable: `x` and `z` from the disagreement; the tilt from the plane and
//! (weakly, through the axis's inclination) from the disagreement — [`AxisOptions::free_tilt`]
//! adds it to the minimisation; `y` **only** from the plane, since a shift along the axis
//! changes no snapshot's agreement with another. The roll is assumed 0.
//!
//! The sensor's `z` is the weakest of the three: between snapshots 45° apart a shift of the
//! axis along the line of sight moves the object mostly sideways, which only surfaces seen
//! obliquely and the object's outline reveal. Points within three pixels of a depth edge
//! are left out all the same (flying pixels there sit behind the surface, a bias `z` would
//! absorb), so the object should cover a good part of the frame.
//!
//! Measured (`tests/calibration.rs` at the workspace root, simulated Kinect v1 scans of 8
//! snapshots × 3 frames, start off by up to ±10 mm and ±2°): sensor position within 0.3 mm,
//! tilt within 0.03°; on the bunny scan (8 × 10 frames), within 0.2 mm and 0.02°, in about
//! 3 s on one core.
//!
//! Keep the clip box generous while calibrating: a wrong rig moves the object, so the
//! axis step widens the scan's clip box by [`AxisOptions::margin_m`] and adds the platform
//! top, whose disagreement under a wrong tilt also helps.

use glam::{Affine3A, Vec3};

use crate::error::DepthError;
use crate::filter::FilterChain;
use crate::scan::RecordedScan;
use crate::types::{ClipBox, DepthFrame, Intrinsics, Rig};

/// What can go wrong while calibrating.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibError {
    /// Reading or filtering the frames failed.
    #[error(transparent)]
    Depth(#[from] DepthError),

    /// Too few points to fit.
    ///
    /// How to fix: check that the starting rig is within a few centimetres and degrees, and
    /// that the scan shows the platform (for the plane) or an object (for the axis).
    #[error("{what}: {found} usable points, at least {needed} needed")]
    TooFewPoints {
        /// What was being fitted.
        what: &'static str,
        /// Points found.
        found: usize,
        /// Points needed.
        needed: usize,
    },

    /// RANSAC found no plane with enough inliers.
    ///
    /// How to fix: scan the empty platform, or raise [`RansacOptions::threshold_m`] for a
    /// noisy sensor.
    #[error("no plane found: the best candidate has {inliers} inliers of {points} points")]
    NoPlane {
        /// Inliers of the best candidate.
        inliers: usize,
        /// Points tried.
        points: usize,
    },

    /// The axis needs snapshots at two or more angles, with overlapping views.
    ///
    /// How to fix: calibrate on a scan over a full turn with at most 90° between snapshots.
    #[error("axis calibration: {reason}")]
    Snapshots {
        /// What is missing.
        reason: String,
    },

    /// An option out of range.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// The option.
        name: &'static str,
        /// Why it is refused.
        reason: String,
    },
}

/// One filtered snapshot to calibrate on: the turntable angle and the filtered frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibSnapshot {
    /// Turntable angle, degrees.
    pub angle_deg: f32,
    /// The snapshot's frames filtered into one (use [`DepthFrame::unit_m`]).
    pub frame: DepthFrame,
}

impl CalibSnapshot {
    /// Every snapshot of a recorded scan, filtered by `chain`.
    pub fn from_scan(scan: &RecordedScan, chain: &FilterChain) -> Result<Vec<Self>, DepthError> {
        scan.manifest
            .snapshots
            .iter()
            .zip(&scan.frames)
            .map(|(s, frames)| {
                Ok(Self {
                    angle_deg: s.angle_deg,
                    frame: chain.apply(frames)?,
                })
            })
            .collect()
    }
}

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
fn camera_points(frame: &DepthFrame, intr: &Intrinsics) -> Result<Vec<Vec3>, DepthError> {
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

/// Options of [`fit_plane_ransac`].
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
pub fn fit_plane_ransac(points: &[Vec3], opts: &RansacOptions) -> Result<PlaneFit, CalibError> {
    if !(opts.threshold_m.is_finite() && opts.threshold_m > 0.0) {
        return Err(CalibError::InvalidOption {
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

// ---- Nelder–Mead ---------------------------------------------------------------------------

/// Options of [`nelder_mead`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NelderMeadOptions {
    /// Most iterations (one reflection and what follows it).
    pub max_iterations: u32,
    /// Stop when the simplex's values span less than this.
    pub f_tol: f64,
    /// ... and its vertices lie within this distance of the best one (∞-norm).
    pub x_tol: f64,
}

impl Default for NelderMeadOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            f_tol: 1e-9,
            x_tol: 1e-4,
        }
    }
}

/// The result of [`nelder_mead`].
#[derive(Debug, Clone, PartialEq)]
pub struct Minimum {
    /// The best point found.
    pub x: Vec<f64>,
    /// The function's value there.
    pub value: f64,
    /// Iterations run.
    pub iterations: u32,
    /// Function evaluations.
    pub evaluations: u32,
}

/// Minimises `f` by the Nelder–Mead simplex method (standard coefficients: reflection 1,
/// expansion 2, contraction ½, shrink ½), from `x0` with an initial simplex of `x0` and
/// `x0 + step[i]·eᵢ`. Derivative-free, so it copes with the robust, piecewise-smooth
/// alignment cost. Non-finite values count as +∞.
///
/// # Panics
/// When `x0` and `step` differ in length or are empty.
///
/// ```
/// use voxoct_depth::{nelder_mead, NelderMeadOptions};
/// let m = nelder_mead(
///     |x| (x[0] - 1.0).powi(2) + 10.0 * (x[1] + 2.0).powi(2),
///     &[0.0, 0.0],
///     &[0.5, 0.5],
///     &NelderMeadOptions::default(),
/// );
/// assert!((m.x[0] - 1.0).abs() < 1e-3 && (m.x[1] + 2.0).abs() < 1e-3);
/// ```
pub fn nelder_mead(
    mut f: impl FnMut(&[f64]) -> f64,
    x0: &[f64],
    step: &[f64],
    opts: &NelderMeadOptions,
) -> Minimum {
    assert!(
        !x0.is_empty() && x0.len() == step.len(),
        "x0 and step must be non-empty and of one length"
    );
    let n = x0.len();
    let mut evals = 0u32;
    let mut eval = |x: &[f64]| {
        evals += 1;
        let v = f(x);
        if v.is_finite() { v } else { f64::INFINITY }
    };
    let mut simplex: Vec<(Vec<f64>, f64)> = Vec::with_capacity(n + 1);
    simplex.push((x0.to_vec(), eval(x0)));
    for i in 0..n {
        let mut x = x0.to_vec();
        x[i] += step[i];
        let v = eval(&x);
        simplex.push((x, v));
    }
    let mut iterations = 0;
    let lerp = |a: &[f64], b: &[f64], t: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(a, b)| a + t * (b - a)).collect()
    };
    while iterations < opts.max_iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let spread = simplex[n].1 - simplex[0].1;
        let size = simplex[1..]
            .iter()
            .flat_map(|(x, _)| x.iter().zip(&simplex[0].0).map(|(a, b)| (a - b).abs()))
            .fold(0.0, f64::max);
        if spread.abs() <= opts.f_tol && size <= opts.x_tol {
            break;
        }
        iterations += 1;
        let mut centroid = vec![0.0; n];
        for (x, _) in &simplex[..n] {
            for (c, xi) in centroid.iter_mut().zip(x) {
                *c += xi / n as f64;
            }
        }
        let worst = simplex[n].clone();
        let xr = lerp(&centroid, &worst.0, -1.0);
        let fr = eval(&xr);
        if fr < simplex[0].1 {
            let xe = lerp(&centroid, &worst.0, -2.0);
            let fe = eval(&xe);
            simplex[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (xr, fr);
        } else {
            let (xc, fc) = if fr < worst.1 {
                let xc = lerp(&centroid, &xr, 0.5);
                let fc = eval(&xc);
                (xc, fc)
            } else {
                let xc = lerp(&centroid, &worst.0, 0.5);
                let fc = eval(&xc);
                (xc, fc)
            };
            if fc < worst.1.min(fr) {
                simplex[n] = (xc, fc);
            } else {
                let best = simplex[0].0.clone();
                for v in simplex.iter_mut().skip(1) {
                    v.0 = lerp(&best, &v.0, 0.5);
                    v.1 = eval(&v.0);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (x, value) = simplex.swap_remove(0);
    Minimum {
        x,
        value,
        iterations,
        evaluations: evals,
    }
}

// ---- the axis --------------------------------------------------------------------------------

/// Options of [`calibrate_axis`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisOptions {
    /// Also minimise over the tilt (otherwise it stays as given, e.g. from the plane).
    pub free_tilt: bool,
    /// Pairs of snapshots at most this far apart in angle are compared, degrees.
    pub max_pair_angle_deg: f32,
    /// The scan's clip box is widened by this on every side while calibrating, metres.
    pub margin_m: f32,
    /// Include the platform's top (down to `y = −margin_m`) in the comparison.
    pub include_platform: bool,
    /// Most sampled points per snapshot (sources of the comparison).
    pub max_points: usize,
    /// Scales of the robust loss, coarse to fine, metres (one minimisation per scale).
    pub scales_m: [f32; 3],
    /// Iterations of each minimisation.
    pub max_iterations: u32,
    /// A pair farther apart than this (point to point) counts as a mismatch, in multiples
    /// of the current scale.
    pub gate: f32,
}

impl Default for AxisOptions {
    fn default() -> Self {
        Self {
            free_tilt: false,
            max_pair_angle_deg: 90.0,
            margin_m: 0.03,
            include_platform: true,
            max_points: 6000,
            scales_m: [0.006, 0.0025, 0.001],
            max_iterations: 150,
            gate: 5.0,
        }
    }
}

/// The result of a calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// The calibrated rig.
    pub rig: Rig,
    /// The platform fit used for the tilt and height, if any.
    pub platform: Option<PlatformFit>,
    /// Disagreement between the snapshots under the starting rig, metres: the mean
    /// point-to-plane distance between overlapping snapshots, each capped at
    /// [`RESIDUAL_CAP_M`] (a point with no counterpart counts as the cap).
    pub residual_before_m: f32,
    /// The same under the calibrated rig.
    pub residual_after_m: f32,
    /// Nelder–Mead iterations, all levels.
    pub iterations: u32,
    /// Point pairs compared under the calibrated rig.
    pub pairs: usize,
}

/// The cap of one point's disagreement in [`Calibration::residual_before_m`], metres.
pub const RESIDUAL_CAP_M: f32 = 0.01;

/// One snapshot prepared for the comparison.
struct View {
    angle_rad: f32,
    /// Camera-frame points, NaN outside the generous clip or without a reading.
    points: Vec<Vec3>,
    /// Camera-frame unit normals facing the sensor, NaN where unknown.
    normals: Vec<Vec3>,
    /// Sampled (point, normal) pairs, camera frame.
    sources: Vec<(Vec3, Vec3)>,
}

/// Half-width of the normal's stencil, pixels.
const NORMAL_R: usize = 3;

/// Unit normals of a camera-frame point grid, facing the sensor, from the points
/// [`NORMAL_R`] pixels left, right, up and down; NaN where one of them is missing or the
/// depth bends by more than 4 mm between them (a depth jump).
fn grid_normals(points: &[Vec3], w: usize, h: usize) -> Vec<Vec3> {
    let mut normals = vec![Vec3::NAN; points.len()];
    let r = NORMAL_R;
    // Second differences of depth: zero on any plane however oblique, large across a jump.
    let max_bend = 0.004;
    for v in r..h.saturating_sub(r) {
        for u in r..w.saturating_sub(r) {
            let i = v * w + u;
            let c = points[i];
            if !c.is_finite() {
                continue;
            }
            let (l, rt, up, dn) = (
                points[i - r],
                points[i + r],
                points[i - r * w],
                points[i + r * w],
            );
            if ![l, rt, up, dn].iter().all(|q| q.is_finite())
                || ((l.z + rt.z) * 0.5 - c.z).abs() > max_bend
                || ((up.z + dn.z) * 0.5 - c.z).abs() > max_bend
            {
                continue;
            }
            let n = (rt - l).cross(dn - up).normalize_or_zero();
            if n != Vec3::ZERO {
                normals[i] = if n.dot(c) > 0.0 { -n } else { n };
            }
        }
    }
    normals
}

/// Pixels within this many of a hole or a depth jump are left out of the comparison.
const EDGE_R: usize = 3;
/// Surfaces seen more obliquely than this (cosine of the angle of incidence) are left out.
const MIN_INCIDENCE_COS: f32 = 0.1;

/// Pixels within `r` (along rows and columns) of a missing point or of a depth jump between
/// neighbours (more than 1 cm plus four pixel footprints, so that oblique planes pass).
fn near_edges(points: &[Vec3], w: usize, h: usize, fx: f32, r: usize) -> Vec<bool> {
    let mut bad: Vec<bool> = points.iter().map(|p| !p.is_finite()).collect();
    for v in 0..h {
        for u in 0..w {
            let i = v * w + u;
            let z = points[i].z;
            let jump = |j: usize| (z - points[j].z).abs() > 0.01 + 4.0 * z / fx;
            if (u + 1 < w && jump(i + 1)) || (v + 1 < h && jump(i + w)) {
                bad[i] = true;
            }
        }
    }
    // Dilate by r: rows, then columns (running counts).
    let dilate = |src: &[bool], len: usize, stride: usize, lines: usize, line_stride: usize| {
        let mut out = vec![false; src.len()];
        for l in 0..lines {
            let base = l * line_stride;
            let mut count = 0usize;
            for k in 0..len.min(r) {
                count += usize::from(src[base + k * stride]);
            }
            for k in 0..len {
                if k + r < len {
                    count += usize::from(src[base + (k + r) * stride]);
                }
                if k > r {
                    count -= usize::from(src[base + (k - r - 1) * stride]);
                }
                out[base + k * stride] = count > 0;
            }
        }
        out
    };
    let rows = dilate(&bad, w, 1, h, w);
    dilate(&rows, h, w, w, 1)
}

fn prepare_view(
    s: &CalibSnapshot,
    intr: &Intrinsics,
    start: &Rig,
    clip: &ClipBox,
    max_points: usize,
) -> Result<View, DepthError> {
    let mut points = camera_points(&s.frame, intr)?;
    let to_obj = start.camera_to_object(s.angle_deg);
    for p in &mut points {
        if p.is_finite() && !clip.contains(to_obj.transform_point3(*p)) {
            *p = Vec3::NAN;
        }
    }
    let (w, h) = (intr.width as usize, intr.height as usize);
    let mut normals = grid_normals(&points, w, h);
    // Depth edges carry the sensor's worst errors (flying pixels pulled towards the
    // background, all away from the sensor: a bias the sensor's z would absorb), and so do
    // grazing surfaces: neither takes part.
    let edge = near_edges(&points, w, h, intr.fx, EDGE_R);
    for ((n, p), e) in normals.iter_mut().zip(&points).zip(&edge) {
        if *e || n.dot(-p.normalize_or_zero()) < MIN_INCIDENCE_COS {
            *n = Vec3::NAN;
        }
    }
    let valid = normals.iter().filter(|n| n.is_finite()).count();
    let stride = (valid / max_points.max(1)).max(1);
    let sources = points
        .iter()
        .zip(&normals)
        .filter(|(_, n)| n.is_finite())
        .step_by(stride)
        .map(|(p, n)| (*p, *n))
        .collect();
    Ok(View {
        angle_rad: s.angle_deg.to_radians(),
        points,
        normals,
        sources,
    })
}

/// The comparison's tallies at one rig.
struct Agreement {
    /// Mean robust loss (0 = perfect, 1 = all mismatched).
    cost: f64,
    /// Mean capped absolute point-to-plane distance, metres.
    residual: f64,
    pairs: usize,
}

fn agreement(
    views: &[View],
    pairs: &[(usize, usize)],
    intr: &Intrinsics,
    rig: &Rig,
    scale: f32,
    gate: f32,
) -> Agreement {
    let c = rig.camera_to_rig();
    let cinv = c.inverse();
    let (w, h) = (intr.width as i64, intr.height as i64);
    let s2 = f64::from(scale) * f64::from(scale);
    let gate2 = (gate * scale).powi(2);
    let cap = f64::from(RESIDUAL_CAP_M);
    let (mut cost, mut resid, mut count) = (0f64, 0f64, 0usize);
    for &(k, j) in pairs {
        let (vk, vj) = (&views[k], &views[j]);
        let m: Affine3A = cinv * Affine3A::from_rotation_y(vj.angle_rad - vk.angle_rad) * c;
        for &(p, n) in &vk.sources {
            let q = m.transform_point3(p);
            let nq = m.transform_vector3(n);
            if q.z <= 0.0 || nq.dot(q) >= 0.0 {
                continue; // behind the sensor, or facing away from it: not visible in j
            }
            let u = (q.x * intr.fx / q.z + intr.cx).round() as i64;
            let v = (q.y * intr.fy / q.z + intr.cy).round() as i64;
            if u < 0 || v < 0 || u >= w || v >= h {
                continue;
            }
            let idx = (v * w + u) as usize;
            let t = vj.points[idx];
            let nt = vj.normals[idx];
            if !t.is_finite() || !nt.is_finite() {
                continue;
            }
            count += 1;
            let d = q - t;
            let r = f64::from(nt.dot(d));
            if d.length_squared() > gate2 || nq.dot(nt) < 0.5 {
                cost += 1.0;
            } else {
                cost += r * r / (r * r + s2);
            }
            resid += if d.length() > RESIDUAL_CAP_M {
                cap
            } else {
                r.abs().min(cap)
            };
        }
    }
    let nf = count.max(1) as f64;
    Agreement {
        cost: if count == 0 { 1.0 } else { cost / nf },
        residual: if count == 0 { cap } else { resid / nf },
        pairs: count,
    }
}

fn check_axis_options(opts: &AxisOptions) -> Result<(), CalibError> {
    let bad = |name, reason: String| Err(CalibError::InvalidOption { name, reason });
    if !(opts.margin_m.is_finite() && opts.margin_m >= 0.0) {
        return bad(
            "margin_m",
            format!("{} is not a distance ≥ 0", opts.margin_m),
        );
    }
    if opts.scales_m.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return bad(
            "scales_m",
            format!("{:?} must all be positive", opts.scales_m),
        );
    }
    if !(opts.gate.is_finite() && opts.gate >= 1.0) {
        return bad("gate", format!("{} must be at least 1", opts.gate));
    }
    if !(opts.max_pair_angle_deg > 0.0 && opts.max_pair_angle_deg <= 180.0) {
        return bad(
            "max_pair_angle_deg",
            format!("{} is not in (0, 180]", opts.max_pair_angle_deg),
        );
    }
    Ok(())
}

/// The prepared views and the pairs `(source, target)` to compare.
type Prepared = (Vec<View>, Vec<(usize, usize)>);

/// The prepared views and the pairs to compare.
fn prepare(
    snapshots: &[CalibSnapshot],
    intr: &Intrinsics,
    start: &Rig,
    clip: &ClipBox,
    opts: &AxisOptions,
) -> Result<Prepared, CalibError> {
    check_axis_options(opts)?;
    let m = Vec3::splat(opts.margin_m);
    let mut wide = ClipBox {
        min: clip.min - m,
        max: clip.max + m,
    };
    if opts.include_platform {
        wide.min.y = wide.min.y.min(-opts.margin_m);
    }
    let views = snapshots
        .iter()
        .map(|s| prepare_view(s, intr, start, &wide, opts.max_points))
        .collect::<Result<Vec<_>, _>>()?;
    let mut pairs = Vec::new();
    for k in 0..views.len() {
        for j in 0..views.len() {
            let d = (views[j].angle_rad - views[k].angle_rad)
                .to_degrees()
                .rem_euclid(360.0);
            let d = d.min(360.0 - d);
            if k != j && d > 0.5 && d <= opts.max_pair_angle_deg {
                pairs.push((k, j));
            }
        }
    }
    if pairs.is_empty() {
        return Err(CalibError::Snapshots {
            reason: format!(
                "{} snapshots, no two of them at different angles within {}°",
                views.len(),
                opts.max_pair_angle_deg
            ),
        });
    }
    let sources: usize = views.iter().map(|v| v.sources.len()).sum();
    if sources < 100 {
        return Err(CalibError::TooFewPoints {
            what: "axis",
            found: sources,
            needed: 100,
        });
    }
    Ok((views, pairs))
}

/// The disagreement between `snapshots` under `rig` (see
/// [`Calibration::residual_before_m`]), metres, and the number of point pairs compared.
pub fn alignment_residual(
    snapshots: &[CalibSnapshot],
    intr: &Intrinsics,
    rig: &Rig,
    clip: &ClipBox,
    opts: &AxisOptions,
) -> Result<(f32, usize), CalibError> {
    let (views, pairs) = prepare(snapshots, intr, rig, clip, opts)?;
    let a = agreement(&views, &pairs, intr, rig, opts.scales_m[2], opts.gate);
    Ok((a.residual as f32, a.pairs))
}

/// Calibrates the turntable axis: minimises the disagreement between `snapshots` (filtered
/// frames of one scan over a full turn) over the sensor position's `x` and `z` (and the tilt
/// with [`AxisOptions::free_tilt`]), starting from `start`, whose `y` is kept. `clip` is
/// the scan's clip box (widened by [`AxisOptions::margin_m`]).
///
/// Use [`calibrate`] to fit the platform plane first (tilt and height).
pub fn calibrate_axis(
    snapshots: &[CalibSnapshot],
    intr: &Intrinsics,
    start: Rig,
    clip: &ClipBox,
    opts: &AxisOptions,
) -> Result<Calibration, CalibError> {
    let (views, pairs) = prepare(snapshots, intr, &start, clip, opts)?;
    let fine = opts.scales_m[2];
    let before = agreement(&views, &pairs, intr, &start, fine, opts.gate);
    // Parameters in millimetres and tenths of a degree: comparable effects.
    let rig_of = |x: &[f64]| {
        let mut r = start;
        r.sensor_position_m.x = start.sensor_position_m.x + (x[0] * 1e-3) as f32;
        r.sensor_position_m.z = start.sensor_position_m.z + (x[1] * 1e-3) as f32;
        if let Some(t) = x.get(2) {
            r.tilt_deg = start.tilt_deg + (t * 0.1) as f32;
        }
        r
    };
    let dims = if opts.free_tilt { 3 } else { 2 };
    let mut x = vec![0.0; dims];
    let mut iterations = 0;
    for &scale in &opts.scales_m {
        let step_mm = f64::from(scale) * 1e3;
        let step = vec![step_mm; dims];
        let m = nelder_mead(
            |x| agreement(&views, &pairs, intr, &rig_of(x), scale, opts.gate).cost,
            &x,
            &step,
            &NelderMeadOptions {
                max_iterations: opts.max_iterations,
                f_tol: 1e-7,
                x_tol: 0.02,
            },
        );
        x = m.x;
        iterations += m.iterations;
    }
    let rig = rig_of(&x);
    let after = agreement(&views, &pairs, intr, &rig, fine, opts.gate);
    Ok(Calibration {
        rig,
        platform: None,
        residual_before_m: before.residual as f32,
        residual_after_m: after.residual as f32,
        iterations,
        pairs: after.pairs,
    })
}

/// The whole calibration: the platform plane (from `platform` — a scan of the empty
/// platform — or, when `None`, from the turntable disk around the object in `snapshots`)
/// gives the tilt and height, then [`calibrate_axis`] the sensor's `x` and `z`. When no
/// plane is found in the object scan, the tilt is minimised with the axis instead and the
/// height stays as in `start`. The residuals compare `start` with the result.
pub fn calibrate(
    snapshots: &[CalibSnapshot],
    platform: Option<&[CalibSnapshot]>,
    intr: &Intrinsics,
    start: Rig,
    clip: &ClipBox,
    plane_opts: &PlatformOptions,
    axis_opts: &AxisOptions,
) -> Result<Calibration, CalibError> {
    let fit = match platform {
        Some(p) => Some(calibrate_platform(p, intr, &start, plane_opts)?),
        None => calibrate_platform(snapshots, intr, &start, plane_opts).ok(),
    };
    let (mid, opts) = match &fit {
        Some(f) => (f.apply(start), *axis_opts),
        None => (
            start,
            AxisOptions {
                free_tilt: true,
                ..*axis_opts
            },
        ),
    };
    let mut cal = calibrate_axis(snapshots, intr, mid, clip, &opts)?;
    cal.platform = fit;
    // Each residual with the clip box placed by its own rig.
    cal.residual_before_m = alignment_residual(snapshots, intr, &start, clip, axis_opts)?.0;
    (cal.residual_after_m, cal.pairs) =
        alignment_residual(snapshots, intr, &cal.rig, clip, axis_opts)?;
    Ok(cal)
}
