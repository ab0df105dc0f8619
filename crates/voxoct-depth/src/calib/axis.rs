//! The turntable axis: the sensor's `x` and `z` (and optionally the tilt) that make the
//! snapshots agree, and the whole calibration.

use glam::{Affine3A, Vec3};

use super::optimise::{NelderMeadOptions, nelder_mead};
use super::plane::{PlatformFit, PlatformOptions, calibrate_platform, camera_points};
use super::{CalibError, CalibSnapshot};
use crate::{ClipBox, FrameError, Intrinsics, Rig, ScannerConfig};

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
pub(super) fn grid_normals(points: &[Vec3], w: usize, h: usize) -> Vec<Vec3> {
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
) -> Result<View, FrameError> {
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
            let [u, v, _] = intr.project_any(q);
            let (u, v) = (u.round() as i64, v.round() as i64);
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
    let bad = |name, reason: String| Err(CalibError::InvalidArgument { name, reason });
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

/// Options of [`calibrate`]: the platform plane's and the axis's.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CalibOptions {
    /// The platform plane ([`calibrate_platform`]).
    pub platform: PlatformOptions,
    /// The turntable axis ([`calibrate_axis`]).
    pub axis: AxisOptions,
}

/// The whole calibration of `config`'s rig (the starting point) from `snapshots`, the
/// filtered frames of one scan over a full turn: the platform plane — the turntable disk
/// around the object — gives the tilt and height, then [`calibrate_axis`] the sensor's `x`
/// and `z`. When no plane is found, the tilt is minimised with the axis instead and the
/// height stays as in `config`. The residuals compare the starting rig with the result.
pub fn calibrate(
    config: &ScannerConfig,
    snapshots: &[CalibSnapshot],
    opts: &CalibOptions,
) -> Result<Calibration, CalibError> {
    let intr = &config.sensor.intrinsics;
    let fit = calibrate_platform(snapshots, intr, &config.rig, &opts.platform).ok();
    finish(config, snapshots, fit, opts)
}

/// [`calibrate`] with the tilt and height from `platform`, a scan of the empty platform
/// (the best plane there is); a plane not found there is an error.
pub fn calibrate_with_platform(
    config: &ScannerConfig,
    snapshots: &[CalibSnapshot],
    platform: &[CalibSnapshot],
    opts: &CalibOptions,
) -> Result<Calibration, CalibError> {
    let intr = &config.sensor.intrinsics;
    let fit = calibrate_platform(platform, intr, &config.rig, &opts.platform)?;
    finish(config, snapshots, Some(fit), opts)
}

/// The axis step of [`calibrate`] after the plane step's `fit`.
fn finish(
    config: &ScannerConfig,
    snapshots: &[CalibSnapshot],
    fit: Option<PlatformFit>,
    opts: &CalibOptions,
) -> Result<Calibration, CalibError> {
    let (intr, start, clip) = (&config.sensor.intrinsics, config.rig, &config.clip);
    let axis_opts = &opts.axis;
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
