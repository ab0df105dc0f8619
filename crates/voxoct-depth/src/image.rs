//! Pictures of depth data for people: frames, filter differences and the aligned point views.
//!
//! Everything returns an [`RgbImage`] (8-bit RGB, row-major); [`write_png`] stores one.
//!
//! - [`depth_image`] / [`snapshot_image`]: depth as grey, nearer lighter (the thesis's
//!   Figure 3.1); pixels without a reading in some of the snapshot's frames in red, the
//!   brighter the more frames missed them (its Figure 3.2).
//! - [`difference_image`]: two filters' outputs on one snapshot, signed (its Figures
//!   4.8–4.10): red where the first is farther, blue where it is nearer.
//! - [`views_image`]: every snapshot's clipped points in the common frame, seen from above
//!   (left) and from the side (right), one colour per snapshot. A wrong rig shows at once as
//!   doubled contours.

#[cfg(feature = "png")]
use std::path::Path;

use glam::Vec3;

use crate::DepthFrame;
use crate::error::FrameError;
use crate::filter::{check_frame, check_frame_size, check_frames};
use crate::snapshot::Snapshot;

/// An 8-bit RGB image, row-major from the top-left pixel, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `width * height * 3` bytes: R, G, B of each pixel.
    pub data: Vec<u8>,
}

impl RgbImage {
    /// A black image.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            data: vec![0; width as usize * height as usize * 3],
        }
    }

    /// The colour of pixel `(x, y)`; `None` outside the image.
    #[must_use]
    pub fn get(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        (x < self.width && y < self.height).then(|| {
            let i = (y as usize * self.width as usize + x as usize) * 3;
            [self.data[i], self.data[i + 1], self.data[i + 2]]
        })
    }

    /// Sets pixel `(x, y)`; does nothing outside the image.
    pub fn put(&mut self, x: u32, y: u32, rgb: [u8; 3]) {
        if x < self.width && y < self.height {
            let i = (y as usize * self.width as usize + x as usize) * 3;
            self.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
}

/// Why [`write_png`] failed.
#[cfg(feature = "png")]
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ImageError {
    /// Writing the file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The image's data does not match its size, or the image is empty.
    #[error("RGB image: {reason}")]
    BadImage {
        /// What is wrong.
        reason: String,
    },
}

/// Writes `img` as an 8-bit RGB PNG, atomically (a temporary file renamed over `path`).
/// Feature `png` (on by default).
#[cfg(feature = "png")]
pub fn write_png(path: impl AsRef<Path>, img: &RgbImage) -> Result<(), ImageError> {
    let path = path.as_ref();
    let mut bytes = Vec::new();
    write_png_to(&mut bytes, img).map_err(|e| ImageError::BadImage {
        reason: e.to_string(),
    })?;
    crate::atomic::write_atomic(path, &bytes).map_err(|source| ImageError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Writes `img` as an 8-bit RGB PNG to `w` (a file, standard output, memory); the caller
/// names the destination in its error. Feature `png` (on by default).
///
/// # Errors
/// An invalid image or a failing writer, as [`std::io::Error`].
#[cfg(feature = "png")]
pub fn write_png_to<W: std::io::Write>(w: W, img: &RgbImage) -> std::io::Result<()> {
    let expected = img.width as usize * img.height as usize * 3;
    if img.data.len() != expected || img.width == 0 || img.height == 0 {
        return Err(std::io::Error::other(format!(
            "{} bytes for a {}x{} RGB image (expected {expected}, non-empty)",
            img.data.len(),
            img.width,
            img.height
        )));
    }
    let mut enc = png::Encoder::new(std::io::BufWriter::new(w), img.width, img.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(std::io::Error::other)?;
    w.write_image_data(&img.data)
        .map_err(std::io::Error::other)?;
    w.finish().map_err(std::io::Error::other)
}

/// For each pixel, how many of `frames` have no reading there.
///
/// Errors when a frame is malformed or the frames differ in size or unit.
pub fn invalid_counts(frames: &[DepthFrame]) -> Result<Vec<u16>, FrameError> {
    check_frames(frames)?;
    let mut counts = vec![0u16; frames[0].len()];
    for f in frames {
        for (c, &d) in counts.iter_mut().zip(&f.data) {
            *c = c.saturating_add(u16::from(d == 0));
        }
    }
    Ok(counts)
}

/// The nearest and farthest depth of a frame's readings, metres.
fn depth_range(frame: &DepthFrame) -> Option<(f32, f32)> {
    let mut lo = u16::MAX;
    let mut hi = 0u16;
    for &d in frame.data.iter().filter(|&&d| d != 0) {
        lo = lo.min(d);
        hi = hi.max(d);
    }
    (hi != 0).then(|| (f32::from(lo) * frame.unit_m, f32::from(hi) * frame.unit_m))
}

/// Grey level of depth `z` in `[near, far]`: 255 at the nearest, 48 at the farthest,
/// linear in inverse depth (like the sensor's disparity), which gives the near object more
/// of the grey levels than a far floor.
fn grey(z: f32, near: f32, far: f32) -> u8 {
    let t = if far > near && near > 0.0 {
        ((1.0 / near - 1.0 / z) / (1.0 / near - 1.0 / far)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (255.0 - 207.0 * t).round() as u8
}

/// A depth frame as a picture: nearer is lighter (the frame's own depth range spans the
/// grey levels 255 to 48, linear in inverse depth), no reading is black.
///
/// Errors when the frame's data does not match its size.
pub fn depth_image(frame: &DepthFrame) -> Result<RgbImage, FrameError> {
    check_frame(0, frame)?;
    let mut img = RgbImage::new(frame.width, frame.height);
    if let Some((near, far)) = depth_range(frame) {
        for (px, &d) in img.data.chunks_exact_mut(3).zip(&frame.data) {
            if d != 0 {
                let g = grey(f32::from(d) * frame.unit_m, near, far);
                px.copy_from_slice(&[g, g, g]);
            }
        }
    }
    Ok(img)
}

/// A snapshot as a picture: `filtered` (the output of a filter chain on `frames`) in grey as
/// [`depth_image`], and every pixel that had no reading in at least one of `frames` in red,
/// from dark red (one frame missed it) to bright red (all of them did).
///
/// ```
/// use voxoct_depth::DepthFrame;
/// use voxoct_depth::filter::FilterChain;
/// use voxoct_depth::image::snapshot_image;
/// let mut a = DepthFrame::empty(2, 1, 0.001);
/// a.data = vec![500, 600];
/// let mut b = a.clone();
/// b.data[1] = 0;
/// let img = snapshot_image(&[a.clone(), b.clone()], &FilterChain::parse("average")?.apply(&[a, b])?)?;
/// assert_eq!(img.get(0, 0), Some([255, 255, 255])); // the nearest reading
/// let [r, g, _] = img.get(1, 0).unwrap();
/// assert!(r > 100 && g == 0); // missed by one frame of two
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn snapshot_image(
    frames: &[DepthFrame],
    filtered: &DepthFrame,
) -> Result<RgbImage, FrameError> {
    let counts = invalid_counts(frames)?;
    check_frame_size(0, filtered, frames[0].width, frames[0].height)?;
    let mut img = depth_image(filtered)?;
    let n = frames.len() as f32;
    for (px, &c) in img.data.chunks_exact_mut(3).zip(&counts) {
        if c > 0 {
            let r = (100.0 + 155.0 * f32::from(c) / n).round().min(255.0) as u8;
            px.copy_from_slice(&[r, 0, 0]);
        }
    }
    Ok(img)
}

/// What [`difference_image`] measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffStats {
    /// Pixels with a reading in both frames.
    pub both: usize,
    /// Pixels with a reading only in the first frame.
    pub only_a: usize,
    /// Pixels with a reading only in the second frame.
    pub only_b: usize,
    /// Mean of `|a − b|` over the pixels read in both, metres.
    pub mean_abs_m: f32,
    /// Largest `|a − b|`, metres.
    pub max_abs_m: f32,
    /// The difference that maps to full colour, metres.
    pub scale_m: f32,
}

/// The signed difference `a − b` of two frames of one snapshot (two filters' outputs) as a
/// picture: red where `a` is farther, blue where it is nearer, full colour at `scale_m`
/// (default: the 99th percentile of `|a − b|`, at least 0.1 mm); pixels read in one frame
/// only are grey (`a` only: light, `b` only: dark); pixels read in neither are black.
///
/// Errors when the frames differ in size or are malformed.
pub fn difference_image(
    a: &DepthFrame,
    b: &DepthFrame,
    scale_m: Option<f32>,
) -> Result<(RgbImage, DiffStats), FrameError> {
    check_frame(0, a)?;
    check_frame_size(1, b, a.width, a.height)?;
    let diffs: Vec<Option<f32>> = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| {
            (x != 0 && y != 0).then(|| f32::from(x) * a.unit_m - f32::from(y) * b.unit_m)
        })
        .collect();
    let mut abs: Vec<f32> = diffs.iter().flatten().map(|d| d.abs()).collect();
    let both = abs.len();
    let mean_abs_m = if both > 0 {
        (abs.iter().map(|&d| f64::from(d)).sum::<f64>() / both as f64) as f32
    } else {
        0.0
    };
    let max_abs_m = abs.iter().copied().fold(0.0, f32::max);
    let scale = match scale_m {
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return Err(FrameError::InvalidArgument {
                name: "scale_m",
                reason: format!("{s} is not a positive number"),
            });
        }
        None => {
            abs.sort_by(f32::total_cmp);
            let p99 = abs
                .get(((abs.len() as f32 * 0.99) as usize).min(abs.len().saturating_sub(1)))
                .copied()
                .unwrap_or(0.0);
            p99.max(1e-4)
        }
    };
    let mut img = RgbImage::new(a.width, a.height);
    let (mut only_a, mut only_b) = (0, 0);
    for (i, (px, d)) in img.data.chunks_exact_mut(3).zip(&diffs).enumerate() {
        let rgb = match d {
            Some(d) => {
                let t = (d.abs() / scale).min(1.0);
                let lo = (255.0 * (1.0 - t)).round() as u8;
                // White at no difference, fading to pure red / blue at the scale.
                if *d >= 0.0 {
                    [255, lo, lo]
                } else {
                    [lo, lo, 255]
                }
            }
            None if a.data[i] != 0 => {
                only_a += 1;
                [150, 150, 150]
            }
            None if b.data[i] != 0 => {
                only_b += 1;
                [70, 70, 70]
            }
            None => [0, 0, 0],
        };
        px.copy_from_slice(&rgb);
    }
    Ok((
        img,
        DiffStats {
            both,
            only_a,
            only_b,
            mean_abs_m,
            max_abs_m,
            scale_m: scale,
        },
    ))
}

/// A distinct, saturated colour for snapshot `k` of `n` (hues around the wheel).
#[must_use]
pub fn snapshot_colour(k: usize, n: usize) -> [u8; 3] {
    let h = 6.0 * k as f32 / n.max(1) as f32;
    let x = 1.0 - ((h % 2.0) - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    let c = |v: f32| (40.0 + 215.0 * v).round() as u8;
    [c(r), c(g), c(b)]
}

/// Top view (left: x to the right, +z — towards the sensor at angle 0 — down) and side view
/// (right: x to the right, +y up) of every snapshot's valid points in the common frame, one
/// colour per snapshot ([`snapshot_colour`]), on one scale; the turntable axis is drawn in
/// dark grey. Each view is `side_px` pixels square (at least 16).
///
/// A well-calibrated rig gives one sharp contour per surface; a wrong one, doubled contours.
#[must_use]
pub fn views_image(snapshots: &[Snapshot], side_px: u32) -> RgbImage {
    let side = side_px.max(16);
    let gap = 4;
    let mut img = RgbImage::new(2 * side + gap, side);
    for y in 0..side {
        for x in side..side + gap {
            img.put(x, y, [255, 255, 255]);
        }
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in snapshots.iter().flat_map(Snapshot::valid_points) {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    if !lo.is_finite() || !hi.is_finite() {
        return img;
    }
    // Include the axis, keep a 5 % margin and one scale for both views.
    lo = lo.min(Vec3::ZERO);
    hi = hi.max(Vec3::ZERO);
    let extent = (hi - lo).max_element().max(1e-3) * 1.1;
    let centre = (lo + hi) * 0.5;
    let s = (side - 1) as f32 / extent;
    let to_px = |a: f32, c: f32| ((a - c) * s + (side as f32 - 1.0) * 0.5).round();
    // The axis: a dot in the top view, a vertical line in the side view.
    let ax = to_px(0.0, centre.x);
    let az = to_px(0.0, centre.z);
    for d in -3..=3 {
        let t = |v: f32| (v + d as f32) as u32;
        img.put(t(ax), az as u32, [90, 90, 90]);
        img.put(ax as u32, t(az), [90, 90, 90]);
    }
    for y in 0..side {
        img.put(side + gap + ax as u32, y, [60, 60, 60]);
    }
    let n = snapshots.len();
    for (k, snap) in snapshots.iter().enumerate() {
        let c = snapshot_colour(k, n);
        for p in snap.valid_points() {
            let x = to_px(p.x, centre.x);
            let zt = to_px(p.z, centre.z);
            let ys = (side as f32 - 1.0) - to_px(p.y, centre.y);
            if x >= 0.0 && x < side as f32 {
                if zt >= 0.0 {
                    img.put(x as u32, zt as u32, c);
                }
                if ys >= 0.0 {
                    img.put(side + gap + x as u32, ys as u32, c);
                }
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn difference_is_signed_and_measured() {
        let mut a = DepthFrame::empty(4, 1, 0.001);
        a.data = vec![500, 500, 700, 0];
        let mut b = a.clone();
        b.data = vec![500, 510, 0, 600];
        let (img, st) = difference_image(&a, &b, Some(0.01)).unwrap();
        assert_eq!((st.both, st.only_a, st.only_b), (2, 1, 1));
        assert!((st.max_abs_m - 0.01).abs() < 1e-6);
        assert_eq!(img.get(0, 0), Some([255, 255, 255]));
        assert_eq!(img.get(1, 0), Some([0, 0, 255])); // a nearer: blue
        let (img, _) = difference_image(&b, &a, Some(0.01)).unwrap();
        assert_eq!(img.get(1, 0), Some([255, 0, 0])); // a farther: red
    }

    #[test]
    fn colours_differ_between_snapshots() {
        let cs: Vec<_> = (0..8).map(|k| snapshot_colour(k, 8)).collect();
        for i in 0..8 {
            for j in 0..i {
                assert_ne!(cs[i], cs[j]);
            }
        }
    }
}
