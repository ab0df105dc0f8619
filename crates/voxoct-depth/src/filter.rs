//! Filters over the frames of one snapshot: the thesis's three and two better ones.
//!
//! A [`FilterChain`] is one *temporal* filter that turns the N frames of a snapshot
//! into one frame ([`Filter::Basic`], [`Filter::Average`], [`Filter::AverageDiscard`],
//! [`Filter::Median`]), followed by any number of *spatial* filters that clean that
//! frame ([`Filter::Outlier`]). Chains are written by name, joined by `+`:
//! `"average"`, `"median+outlier"`, `"median:5+outlier:2.5"`. A chain without a temporal
//! filter starts with an implied `basic`.

use std::fmt;
use std::str::FromStr;

use crate::DepthFrame;
use crate::error::FrameError;
use crate::noise::KINECT_V1_SIGMA_COEFF;

/// The valid filter names, as listed in errors.
pub const FILTER_NAMES: &str = "basic, average, average-discard, median[:MIN_VALID], outlier[:K]";

/// A filter chain that does not parse ([`FilterChain::parse`], [`FilterChain::new`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FilterError {
    /// A filter name that is not known.
    ///
    /// How to fix: use one of the names listed in the message, joined by `+`.
    #[error("unknown filter `{name}`; valid filters: {valid}")]
    UnknownFilter {
        /// The name given.
        name: String,
        /// The valid names, comma separated.
        valid: &'static str,
    },

    /// A filter chain that names known filters but does not make sense.
    #[error("filter chain `{chain}`: {reason}")]
    BadFilterChain {
        /// The chain as given.
        chain: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// One filter stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Filter {
    /// Temporal: the first frame as it is (the thesis's *Basic*).
    Basic,
    /// Temporal: per pixel, the mean of the valid readings (the thesis's *Average*). A
    /// pixel with no valid reading stays a hole.
    ///
    /// The mean of several frames is finer than their unit, so it is kept in a finer one:
    /// the output's `unit_m` is the input's divided by 4 (2, 1 when the largest reading
    /// would not fit u16 otherwise; 1 for a single frame), rounded to the nearest
    /// sub-unit. On the bunny scan this brings the median distance of snapshot 0's points
    /// to the true surface from 0.26 mm (whole millimetres) to 0.22 mm.
    Average,
    /// Temporal: the mean, but a pixel with any invalid reading among the frames is
    /// dropped (the thesis's *Average-Discard*). Sub-unit output as for
    /// [`Filter::Average`].
    AverageDiscard,
    /// Temporal: per pixel, the median of the valid readings (the mean of the two middle
    /// ones for an even count, rounded). A pixel with fewer than `min_valid` valid readings
    /// is dropped: it flickers (depth edges, grazing surfaces). `min_valid` is capped at
    /// the number of frames; 0 means "more than half of the frames".
    Median {
        /// Minimum number of valid readings; 0 = a majority of the frames.
        min_valid: u16,
    },
    /// Spatial: drops a reading that differs from most of its 3×3 neighbours — precisely,
    /// when more than half of its valid neighbours lie beyond `k·σ(z)` plus one depth unit
    /// (the quantisation step) on the same side, σ being the Kinect v1 noise
    /// ([`crate::noise::kinect_v1_sigma`]); for an odd count, when the neighbours' median lies beyond
    /// the threshold. Also drops a reading with fewer than two valid neighbours. These are
    /// the single errant values and the "flying pixels" between a depth edge's two sides
    /// that made the thesis's protrusions. A plane, however steep, passes: a linear ramp
    /// has as many neighbours above its centre as below. On the border of the frame or of a hole, where the
    /// neighbourhood is one-sided, a surface steeper than the threshold per pixel (beyond
    /// about 68° from facing the sensor at 0.7 m, k = 3) loses its border pixel: those
    /// grazing edge readings are the least reliable anyway.
    Outlier {
        /// Threshold in standard deviations (3 is a good start).
        k: f32,
    },
}

impl Filter {
    /// Default `min_valid` of [`Filter::Median`]: a majority of the frames.
    pub const DEFAULT_MEDIAN_MIN_VALID: u16 = 0;
    /// Default `k` of [`Filter::Outlier`].
    pub const DEFAULT_OUTLIER_K: f32 = 3.0;

    /// Whether the filter turns N frames into one (as opposed to cleaning one frame).
    #[inline]
    #[must_use]
    pub fn is_temporal(&self) -> bool {
        !matches!(self, Self::Outlier { .. })
    }

    /// The filter's name as [`FilterChain::parse`] reads it.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Basic => "basic",
            Self::Average => "average",
            Self::AverageDiscard => "average-discard",
            Self::Median { .. } => "median",
            Self::Outlier { .. } => "outlier",
        }
    }
}

impl fmt::Display for Filter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Median { min_valid } if *min_valid != Self::DEFAULT_MEDIAN_MIN_VALID => {
                write!(f, "median:{min_valid}")
            }
            #[allow(clippy::float_cmp)]
            Self::Outlier { k } if *k != Self::DEFAULT_OUTLIER_K => write!(f, "outlier:{k}"),
            other => f.write_str(other.name()),
        }
    }
}

impl FromStr for Filter {
    type Err = FilterError;

    /// One filter by name, with an optional `:PARAMETER`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        let (name, param) = match s.split_once(':') {
            Some((n, p)) => (n.trim(), Some(p.trim())),
            None => (s, None),
        };
        let unknown = || FilterError::UnknownFilter {
            name: s.to_owned(),
            valid: FILTER_NAMES,
        };
        let bad_param = |reason: String| FilterError::BadFilterChain {
            chain: s.to_owned(),
            reason,
        };
        let no_param = |f: Filter| match param {
            None => Ok(f),
            Some(p) => Err(bad_param(format!("`{name}` takes no parameter, got `{p}`"))),
        };
        match name.to_ascii_lowercase().as_str() {
            "basic" => no_param(Self::Basic),
            "average" => no_param(Self::Average),
            "average-discard" => no_param(Self::AverageDiscard),
            "median" => {
                let min_valid = match param {
                    None => Self::DEFAULT_MEDIAN_MIN_VALID,
                    Some(p) => p.parse::<u16>().map_err(|_| {
                        bad_param(format!(
                            "median's MIN_VALID must be an integer in 0..=65535, got `{p}`"
                        ))
                    })?,
                };
                Ok(Self::Median { min_valid })
            }
            "outlier" => {
                let k = match param {
                    None => Self::DEFAULT_OUTLIER_K,
                    Some(p) => match p.parse::<f32>() {
                        Ok(k) if k.is_finite() && k > 0.0 => k,
                        _ => {
                            return Err(bad_param(format!(
                                "outlier's K must be a positive number, got `{p}`"
                            )));
                        }
                    },
                };
                Ok(Self::Outlier { k })
            }
            _ => Err(unknown()),
        }
    }
}

/// A temporal filter followed by spatial filters.
///
/// One *temporal* filter turns the N frames of a snapshot into one frame
/// ([`Filter::Basic`], [`Filter::Average`], [`Filter::AverageDiscard`],
/// [`Filter::Median`]); any number of *spatial* filters then clean that frame
/// ([`Filter::Outlier`]). Chains are written by name, joined by `+`, with optional
/// parameters after a colon: `"average"`, `"median+outlier"`, `"median:5+outlier:2.5"`.
/// A chain without a temporal filter starts with an implied `basic`. The default is
/// `average+outlier` (see [`FilterChain::default`]).
///
/// ```
/// use voxoct_depth::DepthFrame;
/// use voxoct_depth::filter::FilterChain;
/// let chain: FilterChain = "average".parse()?;
/// let mut a = DepthFrame::empty(2, 1, 0.001);
/// let mut b = a.clone();
/// a.data = vec![700, 0];
/// b.data = vec![703, 0];
/// let mean = chain.apply(&[a, b])?;
/// // 701.5 mm, kept in quarter millimetres.
/// assert_eq!((mean.data[0], mean.unit_m), (2806, 0.00025));
/// assert!((mean.depth_m(0, 0).unwrap() - 0.7015).abs() < 1e-6);
/// assert_eq!(mean.depth_m(1, 0), None);
/// assert!(FilterChain::parse("avg").unwrap_err().to_string().contains("average-discard"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FilterChain {
    stages: Vec<Filter>,
}

impl Default for FilterChain {
    /// `average+outlier`: the best-quality chain measured. On snapshot 0 of the bunny
    /// scan (10 simulated Kinect v1 frames), the distance of the points to the true
    /// surface is, median / 95th percentile: basic 0.70 / 2.33 mm, median 0.33 / 1.10 mm,
    /// average 0.22 / 0.76 mm (its sub-unit output beats the median of quantised
    /// readings). The outlier rejection then removes what averaging cannot: isolated
    /// readings and the flying pixels that a depth edge flickering between foreground and
    /// background averages into (the thesis's protrusions). Prefer `median+outlier` for
    /// a sensor with wild single readings.
    fn default() -> Self {
        Self {
            stages: vec![
                Filter::Average,
                Filter::Outlier {
                    k: Filter::DEFAULT_OUTLIER_K,
                },
            ],
        }
    }
}

impl FilterChain {
    /// A chain from its stages: at most one temporal filter, and only in the first place;
    /// without one, [`Filter::Basic`] is implied. Spatial parameters must be positive.
    pub fn new(stages: Vec<Filter>) -> Result<Self, FilterError> {
        let chain_str = || {
            stages
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("+")
        };
        if stages.is_empty() {
            return Err(FilterError::BadFilterChain {
                chain: String::new(),
                reason: "empty chain; name at least one filter".into(),
            });
        }
        for (i, f) in stages.iter().enumerate() {
            if f.is_temporal() && i > 0 {
                return Err(FilterError::BadFilterChain {
                    chain: chain_str(),
                    reason: format!(
                        "`{f}` combines the frames of a snapshot and must come first, once"
                    ),
                });
            }
            if let Filter::Outlier { k } = f
                && !(k.is_finite() && *k > 0.0)
            {
                return Err(FilterError::BadFilterChain {
                    chain: chain_str(),
                    reason: format!("outlier's k must be a positive number, got {k}"),
                });
            }
        }
        let mut stages = stages;
        if !stages[0].is_temporal() {
            stages.insert(0, Filter::Basic);
        }
        Ok(Self { stages })
    }

    /// Parses a chain such as `"median+outlier"` (see [`FilterChain`]); an unknown name is
    /// an [`FilterError::UnknownFilter`] that lists the valid ones.
    pub fn parse(s: &str) -> Result<Self, FilterError> {
        let stages = s
            .split('+')
            .map(|part| {
                if part.trim().is_empty() {
                    Err(FilterError::BadFilterChain {
                        chain: s.to_owned(),
                        reason: format!("empty filter name; valid filters: {FILTER_NAMES}"),
                    })
                } else {
                    part.parse::<Filter>()
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        Self::new(stages).map_err(|e| match e {
            FilterError::BadFilterChain { reason, .. } => FilterError::BadFilterChain {
                chain: s.to_owned(),
                reason,
            },
            e => e,
        })
    }

    /// The stages, temporal one first.
    #[must_use]
    pub fn stages(&self) -> &[Filter] {
        &self.stages
    }

    /// How many of a snapshot's `frames` the chain combines into each pixel, at most: 1
    /// for [`Filter::Basic`], all of them for the mean and the median. (The noise of the
    /// result falls about as the square root of it, as
    /// [`crate::carve::settle_disagreements`] takes it.)
    #[must_use]
    pub fn readings(&self, frames: usize) -> u32 {
        let n = u32::try_from(frames).unwrap_or(u32::MAX).max(1);
        match self.stages[0] {
            Filter::Basic | Filter::Outlier { .. } => 1,
            Filter::Average | Filter::AverageDiscard | Filter::Median { .. } => n,
        }
    }

    /// Filters the frames of one snapshot into one frame of the same size; its unit is the
    /// frames' unit, or a fraction of it after [`Filter::Average`] (read depths through
    /// [`DepthFrame::depth_m`] or `unit_m`).
    ///
    /// Errors when `frames` is empty, when a frame's data does not match its size, or
    /// when the frames differ in size or unit.
    pub fn apply(&self, frames: &[DepthFrame]) -> Result<DepthFrame, FrameError> {
        check_frames(frames)?;
        let mut out = match self.stages[0] {
            Filter::Basic => frames[0].clone(),
            Filter::Average => average(frames, false),
            Filter::AverageDiscard => average(frames, true),
            Filter::Median { min_valid } => median(frames, min_valid),
            // `new` puts a temporal filter first.
            Filter::Outlier { .. } => frames[0].clone(),
        };
        let mut scratch = Vec::new();
        for stage in &self.stages[1..] {
            if let Filter::Outlier { k } = *stage {
                outlier_into(&out, k, &mut scratch);
                std::mem::swap(&mut out.data, &mut scratch);
            }
        }
        Ok(out)
    }
}

impl FromStr for FilterChain {
    type Err = FilterError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

impl fmt::Display for FilterChain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, s) in self.stages.iter().enumerate() {
            if i > 0 {
                f.write_str("+")?;
            }
            write!(f, "{s}")?;
        }
        Ok(())
    }
}

/// Checks that a frame's data matches its size.
pub(crate) fn check_frame(index: usize, f: &DepthFrame) -> Result<(), FrameError> {
    if f.data.len() != f.width as usize * f.height as usize {
        return Err(FrameError::MalformedFrame {
            index,
            len: f.data.len(),
            width: f.width,
            height: f.height,
        });
    }
    if !(f.unit_m.is_finite() && f.unit_m > 0.0) {
        return Err(FrameError::UnitMismatch {
            index,
            expected: f.unit_m.abs().max(f32::MIN_POSITIVE),
            found: f.unit_m,
        });
    }
    Ok(())
}

/// Checks that frame `index` is well formed and `width × height` pixels.
pub(crate) fn check_frame_size(
    index: usize,
    f: &DepthFrame,
    width: u32,
    height: u32,
) -> Result<(), FrameError> {
    check_frame(index, f)?;
    if (f.width, f.height) != (width, height) {
        return Err(FrameError::FrameSizeMismatch {
            index,
            expected_w: width,
            expected_h: height,
            found_w: f.width,
            found_h: f.height,
        });
    }
    Ok(())
}

/// Checks that the frames of one snapshot are well formed, of one size and one unit.
pub(crate) fn check_frames(frames: &[DepthFrame]) -> Result<(), FrameError> {
    let first = frames.first().ok_or(FrameError::NoFrames)?;
    for (i, f) in frames.iter().enumerate() {
        check_frame_size(i, f, first.width, first.height)?;
        #[allow(clippy::float_cmp)]
        if f.unit_m != first.unit_m {
            return Err(FrameError::UnitMismatch {
                index: i,
                expected: first.unit_m,
                found: f.unit_m,
            });
        }
    }
    Ok(())
}

/// Finest sub-unit factor of [`Filter::Average`]'s output.
const AVERAGE_MAX_SUBDIVISION: u16 = 4;

/// Pixels per block in the temporal filters: the block's accumulators stay in L1.
const BLOCK: usize = 2048;

/// Average / Average-Discard. Sums in u32 (exact for up to 65 537 frames of u16); the
/// mean is stored in `unit / k` with the largest `k <= 4` for which the largest reading
/// still fits in u16 (k = 1 for a single frame). Works block by block so that the
/// accumulators stay in cache (one pass over the input, ~6 MB for 10 VGA frames).
fn average(frames: &[DepthFrame], discard: bool) -> DepthFrame {
    let first = &frames[0];
    let n = first.data.len();
    let max = frames
        .iter()
        .map(|f| f.data.iter().copied().fold(0, u16::max))
        .fold(0, u16::max);
    let k = if frames.len() < 2 {
        1
    } else {
        (1..=AVERAGE_MAX_SUBDIVISION)
            .rev()
            .find(|&k| u32::from(max) * u32::from(k) <= u32::from(u16::MAX))
            .unwrap_or(1)
    };
    let need = frames.len() as u32;
    let scale = f32::from(k);
    let mut sum = [0u32; BLOCK];
    let mut cnt = [0u32; BLOCK];
    let mut data = vec![0u16; n];
    for (b, out) in data.chunks_mut(BLOCK).enumerate() {
        let start = b * BLOCK;
        let len = out.len();
        let (sum, cnt) = (&mut sum[..len], &mut cnt[..len]);
        sum.fill(0);
        cnt.fill(0);
        for f in frames {
            let src = &f.data[start..start + len];
            for ((s, c), &d) in sum.iter_mut().zip(cnt.iter_mut()).zip(src) {
                *s += u32::from(d);
                *c += u32::from(d != 0);
            }
        }
        for ((o, &s), &c) in out.iter_mut().zip(sum.iter()).zip(cnt.iter()) {
            let keep = c != 0 && (!discard || c == need);
            // Rounded to nearest (exact below 2^24, i.e. up to 64 frames at k = 4); at
            // most max·k, which fits u16.
            let mean = (s as f32 * scale / c.max(1) as f32 + 0.5) as u16;
            *o = if keep { mean } else { 0 };
        }
    }
    DepthFrame {
        width: first.width,
        height: first.height,
        unit_m: first.unit_m / f32::from(k),
        data,
    }
}

/// Pixels per block of the rank-based median.
const MEDIAN_BLOCK: usize = 256;
/// Up to this many frames, the median is computed by ranks (branch-free, vectorised over
/// pixels, O(N²) per pixel); beyond, by sorting each pixel's readings.
const MEDIAN_RANK_MAX_FRAMES: usize = 24;

/// Per-pixel temporal median of the valid readings.
fn median(frames: &[DepthFrame], min_valid: u16) -> DepthFrame {
    let first = &frames[0];
    let nf = frames.len();
    let need = if min_valid == 0 {
        nf / 2 + 1
    } else {
        usize::from(min_valid).min(nf)
    };
    let data = if nf <= MEDIAN_RANK_MAX_FRAMES {
        median_by_rank(frames, need)
    } else {
        median_by_sort(frames, need)
    };
    DepthFrame {
        width: first.width,
        height: first.height,
        unit_m: first.unit_m,
        data,
    }
}

/// The median of the sorted valid readings `lo..hi` middle pair, rounded up.
#[inline]
fn mid(lo: u32, hi: u32) -> u16 {
    (lo + hi).div_ceil(2) as u16
}

/// Median by sorting each pixel's valid readings.
fn median_by_sort(frames: &[DepthFrame], need: usize) -> Vec<u16> {
    let n = frames[0].data.len();
    let mut buf = Vec::with_capacity(frames.len());
    (0..n)
        .map(|i| {
            buf.clear();
            buf.extend(frames.iter().map(|f| f.data[i]).filter(|&d| d != 0));
            let c = buf.len();
            if c < need || c == 0 {
                return 0;
            }
            buf.sort_unstable();
            mid(u32::from(buf[(c - 1) / 2]), u32::from(buf[c / 2]))
        })
        .collect()
}

/// Median by ranks: with readings mapped to `d − 1` (so a missing 0 becomes the largest
/// value), reading `i`'s stable rank is `#{j < i: m_j <= m_i} + #{j > i: m_j < m_i}`; the
/// valid readings take ranks `0..c` and the median is the mean of ranks `(c−1)/2` and
/// `c/2`. Every step is a branch-free loop over a block of pixels.
fn median_by_rank(frames: &[DepthFrame], need: usize) -> Vec<u16> {
    let nf = frames.len();
    let n = frames[0].data.len();
    let mut m = vec![[0u16; MEDIAN_BLOCK]; nf];
    let mut rank = [0u16; MEDIAN_BLOCK];
    let mut cnt = [0u16; MEDIAN_BLOCK];
    let mut lo = [0u32; MEDIAN_BLOCK];
    let mut hi = [0u32; MEDIAN_BLOCK];
    let mut data = vec![0u16; n];
    for (b, out) in data.chunks_mut(MEDIAN_BLOCK).enumerate() {
        let start = b * MEDIAN_BLOCK;
        let len = out.len();
        cnt[..len].fill(0);
        for (mi, f) in m.iter_mut().zip(frames) {
            for ((x, &d), c) in mi[..len]
                .iter_mut()
                .zip(&f.data[start..start + len])
                .zip(&mut cnt[..len])
            {
                *x = d.wrapping_sub(1);
                *c += u16::from(d != 0);
            }
        }
        lo[..len].fill(0);
        hi[..len].fill(0);
        for i in 0..nf {
            rank[..len].fill(0);
            let mi = &m[i][..len];
            for (j, mj) in m.iter().enumerate() {
                let mj = &mj[..len];
                if j < i {
                    for ((r, &a), &b) in rank[..len].iter_mut().zip(mj).zip(mi) {
                        *r += u16::from(a <= b);
                    }
                } else if j > i {
                    for ((r, &a), &b) in rank[..len].iter_mut().zip(mj).zip(mi) {
                        *r += u16::from(a < b);
                    }
                }
            }
            for p in 0..len {
                let c = cnt[p];
                let v = u32::from(mi[p]) + 1;
                let r = rank[p];
                lo[p] += if r == c.wrapping_sub(1) / 2 { v } else { 0 };
                hi[p] += if r == c / 2 { v } else { 0 };
            }
        }
        for (p, o) in out.iter_mut().enumerate() {
            let c = usize::from(cnt[p]);
            *o = if c >= need && c > 0 {
                mid(lo[p], hi[p])
            } else {
                0
            };
        }
    }
    data
}

/// Minimum number of valid 3×3 neighbours a reading needs to survive [`Filter::Outlier`].
const OUTLIER_MIN_NEIGHBOURS: usize = 2;

/// Spatial outlier rejection of `src` into `out` (resized to the frame).
fn outlier_into(src: &DepthFrame, k: f32, out: &mut Vec<u16>) {
    let w = src.width as usize;
    let h = src.height as usize;
    out.clear();
    out.resize(src.data.len(), 0);
    // Threshold in units for a reading d (units): k·σ(d·unit)/unit + 1 = a·d² + 1.
    let a = k * KINECT_V1_SIGMA_COEFF * src.unit_m;
    let data = &src.data;
    // Border pixels: neighbours gathered with bounds checks.
    let border = |u: usize, v: usize, out: &mut [u16]| {
        let d = data[v * w + u];
        if d == 0 {
            return;
        }
        let mut nb = [0u16; 8];
        let mut c = 0;
        for vv in v.saturating_sub(1)..=(v + 1).min(h - 1) {
            for uu in u.saturating_sub(1)..=(u + 1).min(w - 1) {
                let x = data[vv * w + uu];
                if (uu, vv) != (u, v) && x != 0 {
                    nb[c] = x;
                    c += 1;
                }
            }
        }
        if keep_reading(d, &nb[..c], a) {
            out[v * w + u] = d;
        }
    };
    for v in 0..h {
        if v == 0 || v + 1 == h {
            for u in 0..w {
                border(u, v, out);
            }
        } else {
            border(0, v, out);
            if w > 1 {
                border(w - 1, v, out);
            }
        }
    }
    if w < 3 || h < 3 {
        return;
    }
    // Interior: all eight neighbours exist; a branch-free loop over equal-length slices
    // (the compiler vectorises it).
    let iw = w - 2;
    for v in 1..h - 1 {
        let up = &data[(v - 1) * w..v * w];
        let row = &data[v * w..(v + 1) * w];
        let dn = &data[(v + 1) * w..(v + 2) * w];
        // Every slice has length `iw`, so the indexing below needs no bounds checks.
        let (ul, uc, ur) = (&up[..iw], &up[1..iw + 1], &up[2..iw + 2]);
        let (cl, cc, cr) = (&row[..iw], &row[1..iw + 1], &row[2..iw + 2]);
        let (dl, dc, dr) = (&dn[..iw], &dn[1..iw + 1], &dn[2..iw + 2]);
        let out_row = &mut out[v * w + 1..v * w + 1 + iw];
        for x in 0..iw {
            let d = cc[x];
            let df = f32::from(d);
            let t = a * df * df + 1.0;
            // In integers: n > d + t ⇔ n > ⌊d + t⌋, and n < d − t ⇔ 2d − n > ⌊d + t⌋.
            let lim = (df + t) as i32;
            let d2 = 2 * i32::from(d);
            let (mut c, mut hi, mut lo) = (0u32, 0u32, 0u32);
            for n in [ul[x], uc[x], ur[x], cl[x], cr[x], dl[x], dc[x], dr[x]] {
                let valid = n != 0;
                let ni = i32::from(n);
                c += u32::from(valid);
                hi += u32::from(valid & (ni > lim));
                lo += u32::from(valid & (d2 - ni > lim));
            }
            let keep = d != 0 && c >= OUTLIER_MIN_NEIGHBOURS as u32 && 2 * hi <= c && 2 * lo <= c;
            out_row[x] = if keep { d } else { 0 };
        }
    }
}

/// Whether reading `d` survives [`Filter::Outlier`] given its valid neighbours `nb` and
/// `a = k·C·unit`: at least two neighbours, and no more than half of them beyond the
/// threshold on the same side.
fn keep_reading(d: u16, nb: &[u16], a: f32) -> bool {
    let c = nb.len();
    if c < OUTLIER_MIN_NEIGHBOURS {
        return false;
    }
    let df = f32::from(d);
    let t = a * df * df + 1.0;
    let hi = nb.iter().filter(|&&x| f32::from(x) > df + t).count();
    let lo = nb.iter().filter(|&&x| f32::from(x) < df - t).count();
    2 * hi <= c && 2 * lo <= c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: u32, h: u32, data: Vec<u16>) -> DepthFrame {
        DepthFrame {
            width: w,
            height: h,
            unit_m: 0.001,
            data,
        }
    }

    #[test]
    fn thesis_filters_per_pixel() {
        let a = frame(3, 1, vec![700, 0, 0]);
        let b = frame(3, 1, vec![703, 800, 0]);
        let c = frame(3, 1, vec![702, 802, 0]);
        let fr = [a, b, c];
        assert_eq!(
            FilterChain::parse("basic")
                .unwrap()
                .apply(&fr)
                .unwrap()
                .data,
            vec![700, 0, 0]
        );
        // Quarter units: (700 + 703 + 702) / 3 = 701.67 -> 2806.67 -> 2807.
        let avg = FilterChain::parse("average").unwrap().apply(&fr).unwrap();
        assert_eq!(avg.data, vec![2807, 3204, 0]);
        assert_eq!(avg.unit_m, 0.00025);
        let avg = FilterChain::parse("average-discard")
            .unwrap()
            .apply(&fr)
            .unwrap();
        assert_eq!(avg.data, vec![2807, 0, 0]);
        // A single frame keeps its unit; readings near u16::MAX keep whole units.
        let one = FilterChain::parse("average")
            .unwrap()
            .apply(&fr[..1])
            .unwrap();
        assert_eq!((one.data[0], one.unit_m), (700, 0.001));
        let big = [frame(1, 1, vec![30_000]), frame(1, 1, vec![30_001])];
        let avg = FilterChain::parse("average").unwrap().apply(&big).unwrap();
        assert_eq!((avg.data[0], avg.unit_m), (60_001, 0.0005));
        // Majority of 3 = 2 valid readings: pixel 1 (2 valid) survives.
        assert_eq!(
            FilterChain::parse("median")
                .unwrap()
                .apply(&fr)
                .unwrap()
                .data,
            vec![702, 801, 0]
        );
        assert_eq!(
            FilterChain::parse("median:3")
                .unwrap()
                .apply(&fr)
                .unwrap()
                .data,
            vec![702, 0, 0]
        );
    }

    #[test]
    fn median_ignores_a_wild_reading() {
        let fr: Vec<_> = [700u16, 701, 5000, 699, 700]
            .iter()
            .map(|&d| frame(1, 1, vec![d]))
            .collect();
        let out = FilterChain::parse("median").unwrap().apply(&fr).unwrap();
        assert_eq!(out.data, vec![700]);
    }

    #[test]
    fn outlier_drops_a_spike_and_keeps_a_steep_plane() {
        let (w, h) = (20u32, 12u32);
        // A ramp of 6 mm per column at ~0.7 m: far steeper than 3σ (2.1 mm).
        let mut data: Vec<u16> = (0..h)
            .flat_map(|_| (0..w).map(|u| 650 + 6 * u as u16))
            .collect();
        let spike = 5 * w as usize + 7;
        data[spike] += 40;
        let f = frame(w, h, data.clone());
        let out = FilterChain::parse("outlier").unwrap().apply(&[f]).unwrap();
        for (i, (&o, &d)) in out.data.iter().zip(&data).enumerate() {
            let (u, v) = (i % w as usize, i / w as usize);
            let border = u == 0 || v == 0 || u + 1 == w as usize || v + 1 == h as usize;
            if i == spike {
                assert_eq!(o, 0, "spike kept");
            } else if !border {
                assert_eq!(o, d, "pixel {i} dropped");
            }
        }
        // Neighbours of the spike survive too: the median ignores the one spike.
        assert_eq!(out.data[spike + 1], data[spike + 1]);
    }

    proptest::proptest! {
        /// Both median algorithms agree with a plain sort-based median.
        #[test]
        fn median_by_rank_matches_sorting(
            frames in proptest::collection::vec(
                proptest::collection::vec(
                    proptest::prop_oneof![1 => proptest::strategy::Just(0u16), 3 => 1u16..8, 1 => proptest::strategy::Just(u16::MAX)],
                    300,
                ),
                1..12,
            ),
            min_valid in 0u16..6,
        ) {
            let fr: Vec<_> = frames.into_iter().map(|d| frame(300, 1, d)).collect();
            let nf = fr.len();
            let need = if min_valid == 0 { nf / 2 + 1 } else { usize::from(min_valid).min(nf) };
            let got = median(&fr, min_valid).data;
            proptest::prop_assert_eq!(&got, &median_by_sort(&fr, need));
            for (i, &g) in got.iter().enumerate() {
                let mut v: Vec<u32> = fr.iter().map(|f| u32::from(f.data[i])).filter(|&d| d != 0).collect();
                v.sort_unstable();
                let want = if v.len() >= need && !v.is_empty() {
                    let c = v.len();
                    (v[(c - 1) / 2] + v[c / 2]).div_ceil(2) as u16
                } else {
                    0
                };
                proptest::prop_assert_eq!(g, want, "pixel {}", i);
            }
        }

        /// The fast interior path decides exactly as the plain definition.
        #[test]
        fn outlier_matches_its_definition(
            data in proptest::collection::vec(
                proptest::prop_oneof![1 => proptest::strategy::Just(0u16), 8 => 695u16..710],
                7 * 6,
            ),
            k in 0.5f32..4.0,
        ) {
            let f = frame(7, 6, data);
            let mut out = Vec::new();
            outlier_into(&f, k, &mut out);
            let a = k * KINECT_V1_SIGMA_COEFF * f.unit_m;
            for v in 0..6usize {
                for u in 0..7usize {
                    let d = f.data[v * 7 + u];
                    let mut nb = Vec::new();
                    for vv in v.saturating_sub(1)..=(v + 1).min(5) {
                        for uu in u.saturating_sub(1)..=(u + 1).min(6) {
                            let x = f.data[vv * 7 + uu];
                            if (uu, vv) != (u, v) && x != 0 {
                                nb.push(x);
                            }
                        }
                    }
                    let want = if d != 0 && keep_reading(d, &nb, a) { d } else { 0 };
                    proptest::prop_assert_eq!(out[v * 7 + u], want, "pixel ({}, {})", u, v);
                }
            }
        }
    }

    #[test]
    fn outlier_drops_isolated_readings() {
        let mut data = vec![0u16; 25];
        data[12] = 700;
        let out = FilterChain::parse("outlier")
            .unwrap()
            .apply(&[frame(5, 5, data)])
            .unwrap();
        assert!(out.data.iter().all(|&d| d == 0));
    }

    #[test]
    fn chain_parsing_and_errors() {
        let c = FilterChain::parse("average+outlier").unwrap();
        assert_eq!(c, FilterChain::default());
        assert_eq!(c.to_string(), "average+outlier");
        let c = FilterChain::parse(" Median:5 + outlier ").unwrap();
        assert_eq!(c.to_string(), "median:5+outlier");
        let c: FilterChain = "outlier:2.5".parse().unwrap();
        assert_eq!(c.stages(), &[Filter::Basic, Filter::Outlier { k: 2.5 }]);
        assert_eq!(c.to_string(), "basic+outlier:2.5");
        assert_eq!(
            FilterChain::parse(&c.to_string()).unwrap(),
            c,
            "display round-trips"
        );

        let e = FilterChain::parse("median+blur").unwrap_err();
        assert!(matches!(&e, FilterError::UnknownFilter { name, .. } if name == "blur"));
        let msg = e.to_string();
        for n in ["basic", "average", "average-discard", "median", "outlier"] {
            assert!(msg.contains(n), "{msg}");
        }
        for bad in [
            "outlier+median",
            "average+median",
            "",
            "median+",
            "outlier:-1",
            "median:x",
            "basic:3",
        ] {
            assert!(
                matches!(
                    FilterChain::parse(bad),
                    Err(FilterError::BadFilterChain { .. })
                ),
                "{bad}"
            );
        }
    }

    #[test]
    fn frames_must_agree() {
        let chain = FilterChain::parse("average").unwrap();
        assert!(matches!(chain.apply(&[]), Err(FrameError::NoFrames)));
        let a = frame(2, 2, vec![1; 4]);
        let b = frame(2, 1, vec![1; 2]);
        assert!(matches!(
            chain.apply(&[a.clone(), b]),
            Err(FrameError::FrameSizeMismatch { index: 1, .. })
        ));
        let mut c = a.clone();
        c.unit_m = 0.0005;
        assert!(matches!(
            chain.apply(&[a.clone(), c]),
            Err(FrameError::UnitMismatch { index: 1, .. })
        ));
        let bad = frame(2, 2, vec![1; 3]);
        assert!(matches!(
            chain.apply(&[bad]),
            Err(FrameError::MalformedFrame {
                index: 0,
                len: 3,
                ..
            })
        ));
    }
}
