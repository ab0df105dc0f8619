//! Free-space carving: which cells of a grid no depth frame could have seen.
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
//! A cell is *hidden* when at least [`MIN_BEHIND`] views put it behind a surface and none
//! puts it in front or near (one view alone is not trusted: a pixel without reading in the
//! other views — the projector's shadow, a drop-out — would leave a stray blob). The object's interior is hidden; so is the space under an overhang and
//! between the object's unseen underside and the platform. Marked as solid, hidden cells keep
//! the solid-mode flood fill from leaking through the parts of the shell the sensor never
//! saw, so the mesh closes there as a solid (a scan is then a printable object even where
//! the scanner saw nothing), instead of becoming a hollow double-walled shell.

use voxoct_core::glam::{Affine3A, UVec3, Vec3};
use voxoct_core::{Cell, GridSpec};
use voxoct_depth::{DepthFrame, Intrinsics};

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

/// Hit count given to a hidden cell added to the octree's cells: high enough to pass any
/// `min_hits`.
pub const HIDDEN_HITS: u32 = 1 << 16;

/// Views that must see a cell behind a surface before it counts as hidden.
pub const MIN_BEHIND: u32 = 2;

/// How a view sees a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seen {
    Front,
    Near,
    Behind,
    Unknown,
}

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
    #[inline]
    fn classify(&self, p: Vec3, margin: f32) -> Seen {
        let q = self.object_to_camera.transform_point3(p);
        let Some((u, v, z)) = self.intrinsics.project(q) else {
            return Seen::Unknown;
        };
        let (Some(u), Some(v)) = (pixel(u, self.frame.width), pixel(v, self.frame.height)) else {
            return Seen::Unknown;
        };
        let raw = self.frame.data[v * self.frame.width as usize + u];
        if raw == 0 {
            return Seen::Unknown;
        }
        let d = f32::from(raw) * self.frame.unit_m;
        if z < d - margin {
            Seen::Front
        } else if z > d + margin {
            Seen::Behind
        } else {
            Seen::Near
        }
    }
}

/// The cells of `grid` in the box `lo..=hi` (grid coordinates) that are hidden from every
/// view (see the module docs), except those `skip` rejects (e.g. cells already marked).
///
/// `margin` is the depth tolerance, metres: the sensor's noise (a few σ) plus half a cell
/// diagonal. The result is sorted by z, then y, then x.
#[must_use]
pub fn hidden_cells(
    views: &[CarveView<'_>],
    grid: &GridSpec,
    lo: UVec3,
    hi: UVec3,
    margin: f32,
    skip: impl Fn(UVec3) -> bool + Sync,
) -> Vec<UVec3> {
    if views.is_empty() || lo.cmpgt(hi).any() {
        return Vec::new();
    }
    let slab = |z: u32| {
        let mut out = Vec::new();
        // The view that saw the last seen cell tries first (neighbours are mostly seen by the
        // same view); the order does not change the result.
        let mut first = 0;
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let c = UVec3::new(x, y, z);
                if skip(c) {
                    continue;
                }
                let p = grid.cell_center(c);
                let mut behind = 0;
                let mut seen = false;
                for k in (first..views.len()).chain(0..first) {
                    match views[k].classify(p, margin) {
                        Seen::Front | Seen::Near => {
                            seen = true;
                            first = k;
                            break;
                        }
                        Seen::Behind => behind += 1,
                        Seen::Unknown => {}
                    }
                }
                if behind >= MIN_BEHIND && !seen {
                    out.push(c);
                }
            }
        }
        out
    };
    #[cfg(feature = "parallel")]
    let slabs: Vec<Vec<UVec3>> = (lo.z..=hi.z).into_par_iter().map(slab).collect();
    #[cfg(not(feature = "parallel"))]
    let slabs: Vec<Vec<UVec3>> = (lo.z..=hi.z).map(slab).collect();
    slabs.concat()
}

/// `cells` of one grid plus the hidden cells around them, as solid cells one cell deep
/// inside (`mean_sdf = -cell`), ready for a solid-mode mesh.
///
/// The region searched is the bounding box of `cells` grown by one cell, cut at the layer
/// `floor` (cells below it are never added).
#[must_use]
pub fn with_hidden_cells(
    cells: Vec<Cell>,
    grid: &GridSpec,
    views: &[CarveView<'_>],
    margin: f32,
    floor: u32,
) -> Vec<Cell> {
    let Some((lo, hi)) = cells
        .iter()
        .fold(None, |acc: Option<(UVec3, UVec3)>, c| match acc {
            None => Some((c.coord, c.coord)),
            Some((lo, hi)) => Some((lo.min(c.coord), hi.max(c.coord))),
        })
    else {
        return cells;
    };
    let max = UVec3::splat(grid.resolution - 1);
    let lo = lo.saturating_sub(UVec3::ONE).max(UVec3::new(0, floor, 0));
    let hi = (hi + UVec3::ONE).min(max);
    // A dense occupancy bitmap of the region for the skip test.
    let dim = (hi - lo + UVec3::ONE).max(UVec3::ONE);
    let index = |c: UVec3| {
        let d = c - lo;
        (d.z as usize * dim.y as usize + d.y as usize) * dim.x as usize + d.x as usize
    };
    let mut marked = vec![false; dim.x as usize * dim.y as usize * dim.z as usize];
    for c in &cells {
        if c.coord.cmpge(lo).all() && c.coord.cmple(hi).all() {
            marked[index(c.coord)] = true;
        }
    }
    let hidden = hidden_cells(views, grid, lo, hi, margin, |c| marked[index(c)]);
    let mut cells = cells;
    let sdf = -grid.cell * HIDDEN_HITS as f32;
    cells.extend(hidden.into_iter().map(|coord| Cell {
        coord,
        hits: HIDDEN_HITS,
        sdf_sum: sdf,
    }));
    cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use voxoct_depth::Rig;

    /// A frame of a flat wall `dist` metres in front of the camera.
    fn wall(dist: f32) -> DepthFrame {
        let i = Intrinsics::KINECT_V1;
        let mut f = DepthFrame::empty(i.width, i.height, 0.001);
        f.data.fill((dist * 1000.0) as u16);
        f
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
    fn space_in_front_is_seen_and_space_behind_is_hidden() {
        let rig = Rig {
            tilt_deg: 0.0,
            sensor_position_m: Vec3::new(0.0, 0.0, 1.0),
        };
        let frame = wall(1.0); // the wall is the plane z = 0 of the object frame
        let view = CarveView {
            frame: &frame,
            intrinsics: Intrinsics::KINECT_V1,
            object_to_camera: rig.camera_to_object(0.0).inverse(),
        };
        let grid = GridSpec {
            origin: Vec3::splat(-0.08),
            cell: 0.01,
            resolution: 16,
        };
        let hidden = hidden_cells(
            &[view, view],
            &grid,
            UVec3::ZERO,
            UVec3::splat(15),
            0.004,
            |_| false,
        );
        assert!(!hidden.is_empty());
        for c in &hidden {
            assert!(
                grid.cell_center(*c).z < -0.004,
                "{c} is in front of the wall"
            );
        }
        // Every cell well behind the wall is hidden.
        let behind = (0..16)
            .filter(|&z| grid.cell_center(UVec3::new(0, 0, z)).z < -0.004)
            .count();
        assert_eq!(hidden.len(), behind * 16 * 16);
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
        // The same camera seeing far beyond: nothing is hidden any more.
        let b = CarveView {
            frame: &far_frame,
            ..a
        };
        let grid = GridSpec {
            origin: Vec3::splat(-0.08),
            cell: 0.01,
            resolution: 16,
        };
        assert!(
            hidden_cells(&[a, b], &grid, UVec3::ZERO, UVec3::splat(15), 0.004, |_| {
                false
            })
            .is_empty()
        );
    }
}
