//! Free-space carving: what the depth frames say of every cell of a grid.
//!
//! A depth reading `d` at a pixel says that the ray through that pixel is empty up to `d`,
//! and says nothing behind it. For every cell of a region and every view, the cell centre is
//! projected into the view's frame and classified:
//!
//! - **front**: closer than the reading by more than `margin` — seen to be empty;
//! - **near**: within `margin` of the reading — on the seen surface;
//! - **behind**: farther than the reading by more than `margin` — hidden behind the surface;
//! - unknown: outside the frame, behind the camera, or a pixel without reading.
//!
//! [`visibility`] sums this up per cell over all views ([`Seen`]): seen empty by some view,
//! seen on a surface only, or not seen at all. The meshing's closure of unseen space
//! (`voxoct_mesh::closure`) takes the cells seen empty as outside and decides the unseen
//! ones with a minimum cut.
//!
//! [`settle_disagreements`] weighs the same readings against the marked cells' own signed
//! distances, where the two disagree on the side of the surface a cell lies on.

use crate::noise::kinect_v1_sigma;
use crate::{DepthFrame, Intrinsics};
use voxoct_core::glam::{Affine3A, UVec3, Vec3};
use voxoct_core::{Cell, GridSpec, Real};

#[cfg(feature = "parallel")]
use rayon::prelude::*;

/// One depth view for carving: a (filtered) frame and where its camera was.
#[derive(Debug, Clone, Copy)]
pub struct CarveView<'a> {
    /// The frame, unclipped (readings of the background prove space empty too).
    pub frame: &'a DepthFrame,
    /// The camera.
    pub intrinsics: Intrinsics,
    /// Object (common) frame → camera frame: the inverse of `Rig::camera_to_object(angle)`.
    pub object_to_camera: Affine3A,
}

/// How a view sees a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ViewSees {
    Front,
    /// Within the margin, on the camera's side of the reading (or at it).
    Near,
    /// Within the margin, beyond the reading.
    NearBehind,
    Behind,
    Unknown,
}

/// What all views together say of a cell ([`visibility`]).
pub use voxoct_core::Seen;

/// `x.round()` (half away from zero) as an index when it lies in `0..len`, without a libm
/// call (the baseline x86-64 target has no rounding instruction) and with one-instruction
/// `i32` conversions.
#[inline]
fn pixel(x: f32, len: u32) -> Option<usize> {
    // No frame is 2^24 pixels wide; below that, `len` and `x` are exact as f32 and i32.
    let len = len.min(1 << 24) as i32;
    // Rounds to 0 or more above -0.5 (NaN fails too).
    if !(x > -0.5 && x < len as f32) {
        return None;
    }
    // Exact: x and its integer part share the exponent range; in (-0.5, 0) t is 0.
    let t = x as i32;
    let r = t + i32::from(x - t as f32 >= 0.5);
    (r < len).then_some(r as usize)
}

impl CarveView<'_> {
    /// The pixel `p` projects to, as `(u, v)`, and `p`'s depth; `None` behind the camera
    /// or outside the frame.
    #[inline]
    fn pixel_of(&self, p: Vec3) -> Option<((usize, usize), f32)> {
        let q = self.object_to_camera.transform_point3(p);
        let (u, v, z) = self.intrinsics.project(q)?;
        Some((
            (pixel(u, self.frame.width)?, pixel(v, self.frame.height)?),
            z,
        ))
    }

    #[inline]
    fn classify(&self, p: Vec3, margin: f32) -> ViewSees {
        let Some(((u, v), z)) = self.pixel_of(p) else {
            return ViewSees::Unknown;
        };
        let raw = self.frame.data[v * self.frame.width as usize + u];
        if raw == 0 {
            return ViewSees::Unknown;
        }
        let d = f32::from(raw) * self.frame.unit_m;
        if z < d - margin {
            ViewSees::Front
        } else if z > d + margin {
            ViewSees::Behind
        } else if z <= d {
            ViewSees::Near
        } else {
            ViewSees::NearBehind
        }
    }

    /// The reading at `p`'s pixel minus `p`'s depth (positive: `p` lies in front of the
    /// surface this view saw), `p`'s depth, and the largest difference between the reading
    /// and its four neighbours', metres; `None` outside the frame, behind the camera, or
    /// when the pixel or one of its four neighbours has no reading (the border of a hole
    /// or of the frame, where readings flicker).
    #[inline]
    fn ahead_of_reading(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let ((u, v), z) = self.pixel_of(p)?;
        let w = self.frame.width as usize;
        if u == 0 || v == 0 || u + 1 >= w || v + 1 >= self.frame.height as usize {
            return None;
        }
        let data = &self.frame.data;
        let i = v * w + u;
        let d = data[i];
        if d == 0 {
            return None;
        }
        let mut jump = 0;
        for k in [i - 1, i + 1, i - w, i + w] {
            if data[k] == 0 {
                return None;
            }
            jump = jump.max(data[k].abs_diff(d));
        }
        Some((
            f32::from(d) * self.frame.unit_m - z,
            z,
            f32::from(jump) * self.frame.unit_m,
        ))
    }
}

/// Half a cell's diagonal, in cells: the farthest a surface through a cell lies from its
/// centre.
const HALF_DIAGONAL: f32 = voxoct_core::HALF_CELL_DIAGONAL;

/// Settles the marked cells (`hits > 0`) on which their own triangles and the views
/// disagree about the side of the surface they lie on. Returns how many it changed.
///
/// A marked cell's value is the mean signed distance from its centre to the planes of the
/// triangles that overlap it ([`Cell::mean_sdf`], negative behind the surface). At the
/// fringe of the noise a few triangles of one view can put a cell that lies in front of
/// the surface behind it (a bump a cell high on a flat face, or at an edge) or the other
/// way round, while every other view's readings pass it. Each view says where the cell
/// lies from its reading at the cell's pixel, as in TSDF fusion (Curless and Levoy, 1996):
/// the reading minus the cell's depth, clipped to the band `T = 2σ + √3/2 · cell` (σ the
/// Kinect v1's noise at that depth, [`kinect_v1_sigma`], over the square root of the
/// frames averaged into the view, `readings`), ignored farther than `T` behind the
/// reading (hidden there, the view says nothing of the cell) and where
/// [`CarveView`]'s pixel or one of its four neighbours has no reading. The views' mean is
/// weighed by `1/σ²`, with the σ of a single frame at a depth edge (a neighbour's reading
/// more than `T` away): there the Kinect's readings flicker between the two sides or drop
/// out, and the pixel's mean may rest on one frame.
///
/// Where that mean and the cell's own value lie on different sides of the surface, the
/// cell's value becomes their mean, each triangle that marked the cell counted as one
/// reading and each view as one: the side with more readings wins, by how far they put
/// the surface. The result is kept within half a cell diagonal of the centre, where the
/// surface of any marked cell lies. Where they agree the cell keeps its value: how deep behind the seen
/// surface a cell lies (which sets the back of a wall no view saw) stays the triangles'.
///
/// With fewer than two views nothing changes: the one view's readings are the very ones
/// its triangles were made of, so there is nothing to weigh them against (on the real NYU
/// frame at 5 mm, settling against the same view only resampled the noise: 9466 cells
/// changed, and the room's genus went from 283 to 555).
///
/// `readings[i]`: the frames averaged into `views[i]` (1 for a single frame); a missing
/// or zero entry counts as 1.
pub fn settle_disagreements(
    cells: &mut [Cell],
    views: &[CarveView<'_>],
    readings: &[u32],
    grid: &GridSpec,
) -> usize {
    if views.len() < 2 {
        return 0;
    }
    // Per view, the divisor from one frame's σ to that of its mean.
    let sqrt_frames: Vec<f32> = (0..views.len())
        .map(|k| (readings.get(k).copied().unwrap_or(1).max(1) as f32).sqrt())
        .collect();
    let most = HALF_DIAGONAL * grid.cell;
    let settle = |c: &mut Cell| -> bool {
        if c.hits == 0 {
            return false;
        }
        let own = c.mean_sdf();
        let p = grid.cell_center(c.coord);
        let (mut sum, mut weights, mut count) = (0.0f32, 0.0f32, 0u32);
        for (view, &sqrt_frames) in views.iter().zip(&sqrt_frames) {
            let Some((s, z, jump)) = view.ahead_of_reading(p) else {
                continue;
            };
            let one_frame = kinect_v1_sigma(z);
            let band = 2.0 * (one_frame / sqrt_frames) + most;
            if s < -band {
                continue;
            }
            // At a depth edge the pixel flickers: its mean may rest on one frame.
            let sigma = if jump > band {
                one_frame
            } else {
                one_frame / sqrt_frames
            };
            let w = 1.0 / (sigma * sigma);
            sum += w * s.min(band);
            weights += w;
            count += 1;
        }
        if count == 0 {
            return false;
        }
        let seen = sum / weights;
        if (own <= 0.0) == (seen <= 0.0) || !seen.is_finite() {
            return false;
        }
        let hits = c.hits as f32;
        // Within half a cell diagonal, as any marked cell's distance (the marcher tells a
        // marked cell from an unobserved inside one by it).
        let settled =
            ((own * hits + seen * count as f32) / (hits + count as f32)).clamp(-most, most);
        c.sdf_sum = (settled * hits) as Real;
        true
    };
    #[cfg(feature = "parallel")]
    let changed = cells.par_iter_mut().map(|c| usize::from(settle(c))).sum();
    #[cfg(not(feature = "parallel"))]
    let changed = cells.iter_mut().map(|c| usize::from(settle(c))).sum();
    changed
}

/// Cells per side of a carving block: blocks are pre-classified per view from a depth
/// pyramid, so that only blocks on a view's surface need the per-cell test.
const BLOCK: u32 = 8;
/// Pixels per side of a depth-pyramid tile.
const TILE: u32 = 2;
/// Slack on projected pixel coordinates (pixels) and on depths (metres) of the block test:
/// far above the rounding error of the per-cell arithmetic, so that a block's verdict is
/// exactly that of each of its cells.
const PIXEL_SLACK: f32 = 0.01;
/// See [`PIXEL_SLACK`].
const DEPTH_SLACK: f32 = 1e-4;
/// Blocks closer to a camera than this (metres) are tested cell by cell: near the camera's
/// centre the pixel coordinates are too sensitive to rounding for [`PIXEL_SLACK`].
const MIN_BLOCK_DEPTH: f32 = 0.05;

/// Per tile of `TILE × TILE` pixels: the smallest reading (`u16::MAX` if none), the largest
/// (0 if none), and whether a pixel has no reading.
#[derive(Debug, Clone, Copy)]
struct Tile {
    min: u16,
    max: u16,
    hole: bool,
}

/// A view's depth pyramid (one level of tiles).
#[derive(Debug)]
struct Pyramid {
    tiles: Vec<Tile>,
    width: usize,
}

impl Pyramid {
    fn new(frame: &DepthFrame) -> Self {
        let (w, h) = (frame.width as usize, frame.height as usize);
        let t = TILE as usize;
        let (tw, th) = (w.div_ceil(t), h.div_ceil(t));
        let mut tiles = vec![
            Tile {
                min: u16::MAX,
                max: 0,
                hole: false,
            };
            tw * th
        ];
        for (y, row) in frame.data.chunks_exact(w.max(1)).take(h).enumerate() {
            let tr = &mut tiles[(y / t) * tw..(y / t + 1) * tw];
            for (x, &raw) in row.iter().enumerate() {
                let tile = &mut tr[x / t];
                if raw == 0 {
                    tile.hole = true;
                } else {
                    tile.min = tile.min.min(raw);
                    tile.max = tile.max.max(raw);
                }
            }
        }
        Self { tiles, width: tw }
    }
}

/// How a view sees every cell of a block, when that is decided without the per-cell test.
#[derive(Debug, Clone, Copy, PartialEq)]
enum BlockSeen {
    /// Every cell is in front: no cell of the block is hidden.
    Front,
    /// Every cell is behind.
    Behind,
    /// Every cell is unknown.
    Unknown,
    /// Every cell is behind or unknown (never in front or near).
    NotSeen,
    /// Cells may differ: test each. The value ranks how likely the view is to see cells
    /// of the block (lower: likelier), to test those views first.
    Mixed(f32),
}

impl CarveView<'_> {
    /// `(u, v, z)` of an object-frame point: pixel coordinates (meaningful only for
    /// `z > 0`) and depth.
    #[inline]
    fn project_any(&self, p: Vec3) -> Corner {
        self.intrinsics
            .project_any(self.object_to_camera.transform_point3(p))
    }

    /// The verdict of this view for every cell whose centre lies in the box with these
    /// projected corners ([`Self::project_any`]), exactly the per-cell [`Self::classify`]
    /// verdict when not `Mixed`.
    fn classify_block(&self, pyramid: &Pyramid, corners: &[Corner; 8], margin: f32) -> BlockSeen {
        let (mut umin, mut umax) = (f32::INFINITY, f32::NEG_INFINITY);
        let (mut vmin, mut vmax) = (f32::INFINITY, f32::NEG_INFINITY);
        let (mut zmin, mut zmax) = (f32::INFINITY, f32::NEG_INFINITY);
        for &[u, v, z] in corners {
            zmin = zmin.min(z);
            zmax = zmax.max(z);
            umin = umin.min(u);
            umax = umax.max(u);
            vmin = vmin.min(v);
            vmax = vmax.max(v);
        }
        // In front of the camera, a box projects into the hull of its corners' images.
        if zmin <= MIN_BLOCK_DEPTH || !corners.iter().flatten().all(|c| c.is_finite()) {
            return BlockSeen::Mixed(f32::INFINITY);
        }
        let (w, h) = (
            self.frame.width.min(1 << 24) as f32,
            self.frame.height.min(1 << 24) as f32,
        );
        let (u0, u1) = (umin - PIXEL_SLACK, umax + PIXEL_SLACK);
        let (v0, v1) = (vmin - PIXEL_SLACK, vmax + PIXEL_SLACK);
        // Every centre must round to a pixel of the frame.
        if !(u0 > -0.5 && u1 < w - 0.5 && v0 > -0.5 && v1 < h - 0.5) {
            return BlockSeen::Mixed(f32::INFINITY);
        }
        // `round` is monotonic: the centres' pixels are in these ranges.
        let px = [(u0 + 0.5) as usize, (u1 + 0.5) as usize];
        let py = [(v0 + 0.5) as usize, (v1 + 0.5) as usize];
        let t = TILE as usize;
        let (mut mn, mut mx, mut hole) = (u16::MAX, 0u16, false);
        for ty in py[0] / t..=py[1] / t {
            let row = &pyramid.tiles[ty * pyramid.width..(ty + 1) * pyramid.width];
            for tile in &row[px[0] / t..=px[1] / t] {
                mn = mn.min(tile.min);
                mx = mx.max(tile.max);
                hole |= tile.hole;
            }
        }
        if mx == 0 {
            return BlockSeen::Unknown;
        }
        // `raw · unit − margin` is monotonic in `raw`, as in `classify`.
        let near = f32::from(mn) * self.frame.unit_m;
        let far = f32::from(mx) * self.frame.unit_m;
        if zmax + DEPTH_SLACK < near - margin && !hole {
            BlockSeen::Front
        } else if zmin - DEPTH_SLACK > far + margin {
            if hole {
                BlockSeen::NotSeen
            } else {
                BlockSeen::Behind
            }
        } else {
            BlockSeen::Mixed(zmin - (near - margin))
        }
    }
}

/// A projected point: `(u, v, z)`.
type Corner = [f32; 3];

/// A block's verdicts over all views.
#[derive(Debug, Clone, Default)]
struct BlockPlan {
    /// Some view sees every cell of the block in front: all are empty.
    none: bool,
    /// Views that need the per-cell test (the others see no cell in front or near).
    mixed: Vec<u32>,
}

/// What the views say of every cell of `grid` in the box `lo..=hi` (grid coordinates), in
/// x-fastest order ([`Seen`]). With no views every cell is [`Seen::Unseen`].
///
/// `margin` is the depth tolerance, metres: the sensor's noise (a few σ) plus half a cell
/// diagonal.
///
/// Blocks of cells are first classified per view against the minimum and maximum depth of
/// the pixel tiles they project to; only views that see a block neither wholly in front nor
/// wholly behind test its cells one by one. The result is exactly that of testing every
/// cell against every view.
#[must_use]
pub fn visibility(
    views: &[CarveView<'_>],
    grid: &GridSpec,
    lo: UVec3,
    hi: UVec3,
    margin: f32,
) -> Vec<Seen> {
    if lo.cmpgt(hi).any() {
        return Vec::new();
    }
    #[cfg(feature = "parallel")]
    let pyramids: Vec<Pyramid> = views.par_iter().map(|v| Pyramid::new(v.frame)).collect();
    #[cfg(not(feature = "parallel"))]
    let pyramids: Vec<Pyramid> = views.iter().map(|v| Pyramid::new(v.frame)).collect();
    let blocks = (hi - lo) / BLOCK + UVec3::ONE;
    // Block (b) spans the cell centres from lattice point b to b + 1 (cell `lo + b · BLOCK`):
    // neighbouring blocks share their corners, projected once per view. Centre coordinates
    // are monotonic in the cell coordinate, so the box holds every centre of the block.
    let lattice = blocks + UVec3::ONE;
    let n_lattice = lattice.x as usize * lattice.y as usize * lattice.z as usize;
    let lattice_point = |i: usize| {
        let (x, rest) = (i as u32 % lattice.x, i as u32 / lattice.x);
        let (y, z) = (rest % lattice.y, rest / lattice.y);
        grid.cell_center(lo + UVec3::new(x, y, z) * BLOCK)
    };
    let project = |view: &CarveView<'_>| -> Vec<Corner> {
        (0..n_lattice)
            .map(|i| view.project_any(lattice_point(i)))
            .collect()
    };
    #[cfg(feature = "parallel")]
    let projected: Vec<Vec<Corner>> = views.par_iter().map(project).collect();
    #[cfg(not(feature = "parallel"))]
    let projected: Vec<Vec<Corner>> = views.iter().map(project).collect();
    let plans = plan_blocks(views, &pyramids, &projected, blocks, margin);
    classify_cells(views, grid, &plans, blocks, lo, hi, margin)
}

/// Every block's [`BlockPlan`], x-fastest: which views see it wholly in front, and which
/// need the per-cell test. `projected[k]` holds view `k`'s projections of the block lattice
/// (`blocks + 1` points a side).
fn plan_blocks(
    views: &[CarveView<'_>],
    pyramids: &[Pyramid],
    projected: &[Vec<Corner>],
    blocks: UVec3,
    margin: f32,
) -> Vec<BlockPlan> {
    let lattice = blocks + UVec3::ONE;
    // One row of blocks (along x); the view that saw the last block in front tries first
    // (most blocks are in front of some view; the order does not change the result).
    let plan_row = |row: usize| {
        let (by, bz) = (row as u32 % blocks.y, row as u32 / blocks.y);
        let mut first = 0;
        let mut plans = Vec::with_capacity(blocks.x as usize);
        for bx in 0..blocks.x {
            let corner_index: [usize; 8] = std::array::from_fn(|c| {
                let c = c as u32;
                let (x, y, z) = (bx + (c & 1), by + (c >> 1 & 1), bz + (c >> 2));
                (z as usize * lattice.y as usize + y as usize) * lattice.x as usize + x as usize
            });
            let mut out = BlockPlan::default();
            let mut mixed = Vec::new();
            for k in (first..views.len()).chain(0..first) {
                let corners = corner_index.map(|c| projected[k][c]);
                match views[k].classify_block(&pyramids[k], &corners, margin) {
                    BlockSeen::Front => {
                        out.none = true;
                        first = k;
                        break;
                    }
                    BlockSeen::Behind | BlockSeen::Unknown | BlockSeen::NotSeen => {}
                    BlockSeen::Mixed(rank) => mixed.push((rank, k as u32)),
                }
            }
            if out.none {
                plans.push(BlockPlan {
                    none: true,
                    ..BlockPlan::default()
                });
                continue;
            }
            // Views likelier to see the cells first: most cells that are not hidden stop at
            // the first view.
            mixed.sort_by(|a, b| a.0.total_cmp(&b.0));
            out.mixed = mixed.into_iter().map(|(_, k)| k).collect();
            plans.push(out);
        }
        plans
    };
    let n_rows = blocks.y as usize * blocks.z as usize;
    #[cfg(feature = "parallel")]
    let plans: Vec<BlockPlan> = (0..n_rows)
        .into_par_iter()
        .flat_map_iter(plan_row)
        .collect();
    #[cfg(not(feature = "parallel"))]
    let plans: Vec<BlockPlan> = (0..n_rows).flat_map(plan_row).collect();
    plans
}

/// The per-cell verdicts of [`visibility`] from the blocks' `plans`.
#[allow(clippy::too_many_arguments)]
fn classify_cells(
    views: &[CarveView<'_>],
    grid: &GridSpec,
    plans: &[BlockPlan],
    blocks: UVec3,
    lo: UVec3,
    hi: UVec3,
    margin: f32,
) -> Vec<Seen> {
    let (dim_x, dim_y) = ((hi.x - lo.x + 1) as usize, (hi.y - lo.y + 1) as usize);
    let slab = |z: u32| {
        let mut out = Vec::with_capacity(dim_x * dim_y);
        let bz = ((z - lo.z) / BLOCK) as usize;
        for y in lo.y..=hi.y {
            let row = (bz * blocks.y as usize + ((y - lo.y) / BLOCK) as usize) * blocks.x as usize;
            for x in lo.x..=hi.x {
                let c = UVec3::new(x, y, z);
                let plan = &plans[row + ((x - lo.x) / BLOCK) as usize];
                if plan.none {
                    out.push(Seen::Empty);
                    continue;
                }
                let mut near = false;
                let mut near_behind = false;
                let mut front = false;
                if !plan.mixed.is_empty() {
                    let p = grid.cell_center(c);
                    for &k in &plan.mixed {
                        match views[k as usize].classify(p, margin) {
                            ViewSees::Front => {
                                front = true;
                                break;
                            }
                            ViewSees::Near => near = true,
                            ViewSees::NearBehind => near_behind = true,
                            ViewSees::Behind | ViewSees::Unknown => {}
                        }
                    }
                }
                out.push(if front {
                    Seen::Empty
                } else if near {
                    Seen::Surface
                } else if near_behind {
                    Seen::BehindSurface
                } else {
                    Seen::Unseen
                });
            }
        }
        out
    };
    #[cfg(feature = "parallel")]
    let slabs: Vec<Vec<Seen>> = (lo.z..=hi.z).into_par_iter().map(slab).collect();
    #[cfg(not(feature = "parallel"))]
    let slabs: Vec<Vec<Seen>> = (lo.z..=hi.z).map(slab).collect();
    slabs.concat()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Rig;

    /// A frame of a flat wall `dist` metres in front of the camera.
    fn wall(dist: f32) -> DepthFrame {
        let i = Intrinsics::KINECT_V1;
        let mut f = DepthFrame::empty(i.width, i.height, 0.001);
        f.data.fill((dist * 1000.0) as u16);
        f
    }

    /// A camera 1 m in front of the plane z = 0 of the object frame, looking at it head-on
    /// (the plane [`wall`]`(1.0)` shows).
    fn head_on() -> Affine3A {
        Rig {
            tilt_deg: 0.0,
            sensor_position_m: Vec3::new(0.0, 0.0, 1.0),
        }
        .camera_to_object(0.0)
        .inverse()
    }

    /// `frame` seen by the [`head_on`] camera.
    fn head_on_view(frame: &DepthFrame) -> CarveView<'_> {
        CarveView {
            frame,
            intrinsics: Intrinsics::KINECT_V1,
            object_to_camera: head_on(),
        }
    }

    /// The cells of `settle_disagreements`'s test: 2 mm cells around the origin, the wall
    /// of [`wall`] through z = 0, column (4, 4) of centres at x = y = 1 mm.
    fn settle_grid() -> GridSpec {
        GridSpec {
            origin: Vec3::splat(-0.008),
            cell: 0.002,
            resolution: 8,
        }
    }

    fn marked(z: u32, hits: u32, mean_sdf: f32) -> Cell {
        Cell {
            coord: UVec3::new(4, 4, z),
            hits,
            sdf_sum: mean_sdf * hits as f32,
        }
    }

    #[test]
    fn views_settle_the_cells_that_disagree_with_them_and_leave_the_others() {
        let frame = wall(1.0);
        let view = head_on_view(&frame);
        let grid = settle_grid();
        // Centres: z = 4 lies 1 mm in front of the wall, z = 3 1 mm behind it, z = 1 5 mm
        // behind it (beyond the band: 2σ/√4 + √3/2 · 2 mm = 3.2 mm at 1 m).
        assert!((grid.cell_center(UVec3::new(4, 4, 4)).z - 0.001).abs() < 1e-6);
        let mut cells = vec![
            // A bump: one triangle puts a cell in front of the wall behind the surface.
            marked(4, 1, -0.0005),
            // Ten triangles against three views: the cell stays behind, nearer the surface.
            marked(4, 10, -0.0005),
            // Agreeing with the views: left as it is.
            marked(3, 2, -0.0003),
            marked(4, 3, 0.0004),
            // Hidden behind the wall for every view: the views say nothing.
            marked(1, 1, 0.0004),
            // Not marked.
            marked(4, 0, 0.0),
        ];
        let before = cells.clone();
        // One view: its readings are those its triangles were made of.
        assert_eq!(settle_disagreements(&mut cells, &[view], &[4], &grid), 0);
        assert_eq!(cells, before);
        let views = [view; 3];
        assert_eq!(settle_disagreements(&mut cells, &views, &[4; 3], &grid), 2);
        // (1 · -0.5 + 3 · 1) / 4 mm and (10 · -0.5 + 3 · 1) / 13 mm.
        assert!(
            (cells[0].mean_sdf() - 0.000_625).abs() < 2e-5,
            "{:?}",
            cells[0]
        );
        assert!(
            (cells[1].mean_sdf() + 0.002 / 13.0).abs() < 2e-5,
            "{:?}",
            cells[1]
        );
        assert_eq!(cells[0].hits, 1);
        assert_eq!(&cells[2..], &before[2..]);

        // Where the pixel or a neighbour of it has no reading, a view says nothing.
        let mut holed = wall(1.0);
        let (w, h) = (holed.width as usize, holed.height as usize);
        for v in h / 2 - 40..h / 2 + 40 {
            holed.data[v * w + w / 2 - 40..v * w + w / 2 + 40].fill(0);
        }
        let blind = CarveView {
            frame: &holed,
            ..view
        };
        let mut cells = before.clone();
        assert_eq!(
            settle_disagreements(&mut cells, &[blind; 3], &[4; 3], &grid),
            0
        );
        assert_eq!(cells, before);
    }

    /// At a depth edge a view's reading counts as a single frame's: a clean view that puts
    /// the cell 1 mm in front outweighs one whose edge pixel puts it 1 mm behind.
    #[test]
    fn a_reading_at_a_depth_edge_counts_as_one_frame() {
        let grid = settle_grid();
        let to_camera = head_on();
        let p = grid.cell_center(UVec3::new(4, 4, 4));
        let (u, v, _) = Intrinsics::KINECT_V1
            .project(to_camera.transform_point3(p))
            .unwrap();
        let (u, v) = (u.round() as usize, v.round() as usize);
        let clean = wall(1.0);
        // 1 mm nearer than the cell, beside a background pixel 1 m farther.
        let mut edge = wall(0.998);
        let w = edge.width as usize;
        edge.data[v * w + u + 1] = 2000;
        let mut cells = vec![marked(4, 2, -0.0005)];
        let views = [head_on_view(&clean), head_on_view(&edge)];
        assert_eq!(settle_disagreements(&mut cells, &views, &[4, 4], &grid), 1);
        // The views' mean (4 · 1 − 1 · 1) / 5 mm, then (2 · −0.5 + 2 · 0.6) / 4 mm.
        assert!(
            (cells[0].mean_sdf() - 0.000_05).abs() < 2e-5,
            "{:?}",
            cells[0]
        );
        // Without the edge both views weigh the same: their mean is 0, on the cell's side.
        let flat = wall(0.998);
        let mut cells = vec![marked(4, 2, -0.0005)];
        let views = [head_on_view(&clean), head_on_view(&flat)];
        assert_eq!(settle_disagreements(&mut cells, &views, &[4, 4], &grid), 0);
    }

    proptest::proptest! {
        /// Against flat walls seen head-on, where every view's reading of a cell is known
        /// exactly, every cell comes out as the rule says, cell by cell: untouched unless
        /// marked, seen by some view within the band and on the other side of the surface
        /// than its own value, and two views or more; then the readings' mean, its hits and
        /// coordinate kept.
        #[test]
        fn settling_follows_the_rule_cell_by_cell(
            cells in proptest::collection::vec(
                (0u32..8, 0u32..8, 0u32..8, 0u32..12, -3.0f32..3.0),
                1..40,
            ),
            views in 1usize..5,
            frames in 1u32..12,
        ) {
            let frame = wall(1.0);
            let view = head_on_view(&frame);
            let grid = settle_grid();
            let mut cells: Vec<Cell> = cells
                .into_iter()
                .map(|(x, y, z, hits, mm)| Cell {
                    coord: UVec3::new(x, y, z),
                    hits,
                    sdf_sum: mm * 1e-3 * hits as f32,
                })
                .collect();
            let before = cells.clone();
            let changed =
                settle_disagreements(&mut cells, &vec![view; views], &vec![frames; views], &grid);
            let mut expected_changes = 0;
            for (c, b) in cells.iter().zip(&before) {
                proptest::prop_assert_eq!((c.coord, c.hits), (b.coord, b.hits));
                let p = grid.cell_center(b.coord);
                // The wall is z = 0; the camera looks down -z from z = 1.
                let ahead = p.z;
                let sigma = kinect_v1_sigma(1.0 - p.z) / (frames as f32).sqrt();
                let band = 2.0 * sigma + HALF_DIAGONAL * grid.cell;
                let own = b.mean_sdf();
                let seen = ahead.min(band);
                let settles =
                    views > 1 && b.hits > 0 && ahead >= -band && (own <= 0.0) != (seen <= 0.0);
                if settles {
                    expected_changes += 1;
                    let (h, n) = (b.hits as f32, views as f32);
                    let most = HALF_DIAGONAL * grid.cell;
                    let want = ((own * h + seen * n) / (h + n)).clamp(-most, most);
                    proptest::prop_assert!(
                        (c.mean_sdf() - want).abs() < 1e-5,
                        "{:?} -> {:?}, want {}", b, c, want
                    );
                } else {
                    proptest::prop_assert_eq!(c, b);
                }
            }
            proptest::prop_assert_eq!(changed, expected_changes);
        }
    }

    #[test]
    fn pixel_rounds_like_round() {
        for x in [
            -1.0f32,
            -0.5,
            -0.49,
            -0.0,
            0.0,
            0.25,
            0.49999997,
            0.5,
            1.5,
            2.5,
            638.5,
            639.49,
            639.5,
            640.0,
            f32::NAN,
            f32::INFINITY,
            -f32::INFINITY,
            1e30,
        ] {
            let r = x.round();
            let want = (0.0..640.0).contains(&r).then_some(r as usize);
            assert_eq!(pixel(x, 640), want, "{x}");
        }
        assert_eq!(pixel(0.0, 0), None);
    }

    #[test]
    fn space_in_front_is_seen_and_space_behind_is_unseen() {
        let frame = wall(1.0); // the wall is the plane z = 0 of the object frame
        let view = head_on_view(&frame);
        let grid = GridSpec {
            origin: Vec3::splat(-0.08),
            cell: 0.01,
            resolution: 16,
        };
        let seen = visibility(&[view, view], &grid, UVec3::ZERO, UVec3::splat(15), 0.004);
        let unseen: Vec<UVec3> = (0..16 * 16 * 16u32)
            .filter(|&i| seen[i as usize] == Seen::Unseen)
            .map(|i| UVec3::new(i % 16, i / 16 % 16, i / 256))
            .collect();
        assert!(!unseen.is_empty());
        for c in &unseen {
            assert!(
                grid.cell_center(*c).z < -0.004,
                "{c} is in front of the wall"
            );
        }
        // Every cell well behind the wall is unseen.
        let behind = (0..16)
            .filter(|&z| grid.cell_center(UVec3::new(0, 0, z)).z < -0.004)
            .count();
        assert_eq!(unseen.len(), behind * 16 * 16);
    }

    /// The per-cell reference: every view classifies every cell.
    fn visibility_per_cell(
        views: &[CarveView<'_>],
        grid: &GridSpec,
        lo: UVec3,
        hi: UVec3,
        margin: f32,
    ) -> Vec<Seen> {
        let mut out = Vec::new();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let c = UVec3::new(x, y, z);
                    let seen: Vec<ViewSees> = views
                        .iter()
                        .map(|v| v.classify(grid.cell_center(c), margin))
                        .collect();
                    out.push(if seen.contains(&ViewSees::Front) {
                        Seen::Empty
                    } else if seen.contains(&ViewSees::Near) {
                        Seen::Surface
                    } else if seen.contains(&ViewSees::NearBehind) {
                        Seen::BehindSurface
                    } else {
                        Seen::Unseen
                    });
                }
            }
        }
        out
    }

    #[test]
    fn block_pretest_gives_exactly_the_per_cell_result() {
        let i = Intrinsics::KINECT_V1;
        // A bumpy surface with holes and a border without readings, seen from six angles
        // around a turntable: blocks of every kind (in front, behind, straddling, partly
        // outside the frame).
        let frames: Vec<DepthFrame> = (0..6u32)
            .map(|k| {
                let mut f = DepthFrame::empty(i.width, i.height, 0.001);
                for y in 0..i.height {
                    for x in 0..i.width {
                        let h = (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503) ^ k)
                            .wrapping_mul(0x9E37_79B9);
                        let raw = if (x / 5 * 7 + y / 6 * 3 + k) % 97 == 0 || x < 40 * k || y > 400
                        {
                            0
                        } else {
                            (620 + (x / 16 + y / 24 + k) % 7 * 9 + h % 3) as u16
                        };
                        f.data[(y * i.width + x) as usize] = raw;
                    }
                }
                f
            })
            .collect();
        let rig = Rig {
            tilt_deg: 20.0,
            sensor_position_m: Vec3::new(0.0, 0.25, 0.6),
        };
        let views: Vec<CarveView<'_>> = frames
            .iter()
            .enumerate()
            .map(|(k, frame)| CarveView {
                frame,
                intrinsics: i,
                object_to_camera: rig.camera_to_object(k as f32 * 60.0).inverse(),
            })
            .collect();
        let grid = GridSpec {
            origin: Vec3::splat(-0.2),
            cell: 1.0 / 256.0,
            resolution: 128,
        };
        let (lo, hi) = (UVec3::new(3, 0, 5), UVec3::new(122, 100, 117));
        let want = visibility_per_cell(&views, &grid, lo, hi, 0.004);
        // Every kind of block verdict occurs.
        let pyramid = Pyramid::new(views[0].frame);
        let mut kinds = Vec::new();
        for z in (lo.z..hi.z).step_by(BLOCK as usize) {
            for y in (lo.y..hi.y).step_by(BLOCK as usize) {
                for x in (lo.x..hi.x).step_by(BLOCK as usize) {
                    let corners = std::array::from_fn(|i| {
                        let i = i as u32;
                        let d = UVec3::new(i & 1, i >> 1 & 1, i >> 2) * BLOCK;
                        views[0].project_any(grid.cell_center(UVec3::new(x, y, z) + d))
                    });
                    let k =
                        std::mem::discriminant(&views[0].classify_block(&pyramid, &corners, 0.004));
                    if !kinds.contains(&k) {
                        kinds.push(k);
                    }
                }
            }
        }
        assert_eq!(kinds.len(), 5, "{kinds:?}");
        let count = |k: Seen| want.iter().filter(|&&s| s == k).count();
        for k in [
            Seen::Empty,
            Seen::Surface,
            Seen::BehindSurface,
            Seen::Unseen,
        ] {
            assert!(count(k) > 100, "{} cells {k:?}", count(k));
        }
        let got = visibility(&views, &grid, lo, hi, 0.004);
        let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{differ} of {} cells differ", want.len());
    }

    #[test]
    fn a_second_view_that_sees_through_uncovers_the_cell() {
        let front = Rig {
            tilt_deg: 0.0,
            sensor_position_m: Vec3::new(0.0, 0.0, 1.0),
        };
        let wall_frame = wall(1.0);
        let far_frame = wall(3.0);
        let a = CarveView {
            frame: &wall_frame,
            intrinsics: Intrinsics::KINECT_V1,
            object_to_camera: front.camera_to_object(0.0).inverse(),
        };
        // The same camera seeing far beyond: every cell is seen empty.
        let b = CarveView {
            frame: &far_frame,
            ..a
        };
        let grid = GridSpec {
            origin: Vec3::splat(-0.08),
            cell: 0.01,
            resolution: 16,
        };
        let seen = visibility(&[a, b], &grid, UVec3::ZERO, UVec3::splat(15), 0.004);
        assert!(seen.iter().all(|&s| s == Seen::Empty));
    }
}
