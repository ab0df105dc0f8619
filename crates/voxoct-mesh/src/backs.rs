//! The backs of walls that no view saw, put half a cell behind the surface that was seen.
//!
//! A wall seen from one side only (a vase's body from outside, a cup's floor from above
//! the platform) gets its other side from the closure, which decides whole cells: the
//! back lands behind the last inside cell, or half a cell past it, up to a cell and a half
//! behind the observed surface. The closure's prior, that unseen surface lies next to seen
//! surface, asks for the thinnest wall the grid resolves: half a cell, as [`crate::march`]
//! already puts a back where its edge allows. Where the edge does not allow it (a cell
//! centre deeper than that, or a cell the closure added), the vertex moves off its edge:
//!
//! - Marching records, for every vertex on an edge that leads from an inside cell into
//!   space no reading came near (an absent cell), away from the observed surface, the
//!   plane of that surface: a least-squares fit to the marked cells around the edge's
//!   inside end ([`observed_plane`]). The fit's gradient is normalised: a cell's value is
//!   the mean distance to the triangles that reach it, and the triangles that reach a
//!   cell far from the mean surface are the ones noise brought nearer, so the values
//!   vary by about half a cell per cell across a noisy surface, and the depth must be
//!   read against that slope. Where no surface was seen near but the edge rises from
//!   the floor layer into space above the object's base (the inside of a cup whose
//!   floor no view saw), the plane is the base's own, the platform.
//! - Once the mesh is smoothed and simplified (thin walls hold back the collapses, and
//!   a crumpled marched sheet moved as a whole folds), [`thin`] moves each vertex that
//!   faces away from the plane of a recorded back near it and lies more than
//!   [`BACK_DEPTH_CELLS`] behind that plane to that depth, along the plane's normal; the
//!   untangling then moves any vertex whose triangles came to cut through others back
//!   toward where it was, so the result is proven free of self-intersections as before.

use std::collections::HashMap;

use voxoct_core::glam::{DMat4, DVec3, DVec4, Vec3};
use voxoct_core::vertex_normals;

use crate::mesh::Mesh;
use crate::{par, selfx};

/// How far behind the observed surface the back of a wall that no view saw is put, in
/// cells.
pub(crate) const BACK_DEPTH_CELLS: f32 = 0.5;

/// Farthest a vertex is moved onto the back, in cells (a recorded back is at most a cell
/// and a half behind its surface plus what smoothing moved it; more means a plane fitted
/// across a fold).
const MAX_MOVE_CELLS: f32 = 1.5;

/// How far from a recorded back a vertex of the finished mesh may be to take its plane, in
/// cells: simplification moves vertices within a fraction of a cell of the surface, and
/// marched vertices lie less than a cell apart.
const REACH_CELLS: f32 = 1.0;

/// Fewest marked cells around an edge's inside end to fit a plane to (four unknowns).
const MIN_FIT_CELLS: usize = 6;

/// Least slope of the fitted values, in cells per cell, to trust the fit's direction (half
/// a cell per cell is usual across a noisy surface, see the module docs).
const MIN_SLOPE: f64 = 0.2;

/// A vertex on the back of a wall that no view saw, as marched, with the plane of the
/// surface seen in front of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Back {
    /// Where the vertex was marched (metres).
    pub at: Vec3,
    /// Unit normal of the seen surface, out of the object (toward where it was seen from).
    pub normal: Vec3,
    /// `normal · p` for the points `p` of the seen surface (metres).
    pub offset: f32,
}

/// The plane of the observed surface in front of the vertex at fraction `t` of the edge
/// from the inside cell `i` to the outside cell `o` (grid coordinates), as its unit
/// normal and the vertex's signed distance from it in cells: a least-squares fit of
/// `value` (a cell's mean signed distance in cells, finite where marked) over the 27
/// cells around `i`, with the gradient normalised (see the module docs). `None` when fewer
/// than [`MIN_FIT_CELLS`] are marked, the fit is flat, or the edge does not lead away from
/// the surface (a front, where the surface was seen from `o`'s side), or the vertex is not
/// behind it.
pub(crate) fn observed_plane(
    value: impl Fn([i64; 3]) -> f32,
    observed: impl Fn(f32) -> bool,
    i: [i64; 3],
    o: [i64; 3],
    t: f32,
) -> Option<(DVec3, f64)> {
    // Normal equations of f ≈ a + g · (c - i) over the marked cells c.
    let mut m = [[0f64; 4]; 4];
    let mut b = [0f64; 4];
    let mut n = 0;
    for dz in -1..=1i64 {
        for dy in -1..=1i64 {
            for dx in -1..=1i64 {
                let f = value([i[0] + dx, i[1] + dy, i[2] + dz]);
                if !observed(f) {
                    continue;
                }
                n += 1;
                let r = [1.0, dx as f64, dy as f64, dz as f64];
                for (row, &rj) in m.iter_mut().zip(&r) {
                    for (e, &rk) in row.iter_mut().zip(&r) {
                        *e += rj * rk;
                    }
                }
                for (e, &rj) in b.iter_mut().zip(&r) {
                    *e += rj * f64::from(f);
                }
            }
        }
    }
    // The entries are sums of products of -1, 0 and 1: a singular system (the marked cells
    // in one plane) has a determinant of exactly 0, any other one of at least 1.
    let m = DMat4::from_cols_array_2d(&m);
    if n < MIN_FIT_CELLS || m.determinant().abs() < 0.5 {
        return None;
    }
    let [a, gx, gy, gz] = (m.inverse() * DVec4::from_array(b)).to_array();
    let g = DVec3::new(gx, gy, gz);
    let slope = g.length();
    if slope < MIN_SLOPE {
        return None;
    }
    let normal = g / slope;
    let dir = DVec3::new(
        (o[0] - i[0]) as f64,
        (o[1] - i[1]) as f64,
        (o[2] - i[2]) as f64,
    );
    if normal.dot(dir) >= 0.0 {
        return None;
    }
    let depth = (a + g.dot(dir * f64::from(t))) / slope;
    (depth < 0.0).then_some((normal, depth))
}

/// Grid key of a position for the lookup of recorded backs.
fn key(p: Vec3, inv_cell: f32) -> [i32; 3] {
    (p * inv_cell).floor().as_ivec3().to_array()
}

/// Moves the vertices of `mesh` on the back of an unseen wall to [`BACK_DEPTH_CELLS`]
/// behind the seen surface (see the module docs): a vertex takes the plane of the
/// nearest recorded back within [`REACH_CELLS`] whose normal its own
/// ([`vertex_normals`]) opposes; it moves when it lies deeper than that, by at most
/// [`MAX_MOVE_CELLS`]. Any triangle this makes improper is mended by the untangling
/// (vertices back toward their unmoved positions). Returns `None` when nothing moved (the
/// mesh is as it was), else whether the result is proven free of self-intersections
/// (`false`: the mesh had some before, and is left as it was).
pub(crate) fn thin(mesh: &mut Mesh, backs: &[Back], cell: f32) -> Option<bool> {
    if backs.is_empty() || mesh.triangles.is_empty() {
        return None;
    }
    let inv = 1.0 / cell;
    let mut buckets: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
    for (k, b) in backs.iter().enumerate() {
        buckets.entry(key(b.at, inv)).or_default().push(k as u32);
    }
    let normals = vertex_normals(&mesh.vertices, &mesh.triangles);
    let reach2 = (REACH_CELLS * cell).powi(2);
    let mut moved = mesh.vertices.clone();
    par::fill(&mut moved, |v| {
        let p = mesh.vertices[v];
        let k = key(p, inv);
        let mut best: Option<(f32, &Back)> = None;
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = buckets.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                        continue;
                    };
                    for b in list.iter().map(|&j| &backs[j as usize]) {
                        let d2 = b.at.distance_squared(p);
                        if d2 <= reach2
                            && normals[v].dot(b.normal) < 0.0
                            && best.is_none_or(|(e, _)| d2 < e)
                        {
                            best = Some((d2, b));
                        }
                    }
                }
            }
        }
        let Some((_, b)) = best else { return p };
        let depth = (b.normal.dot(p) - b.offset) * inv;
        if depth >= -BACK_DEPTH_CELLS {
            return p;
        }
        p + b.normal * ((-BACK_DEPTH_CELLS - depth).min(MAX_MOVE_CELLS) * cell)
    });
    drop((buckets, normals));
    if moved == mesh.vertices {
        return None;
    }
    let safe = std::mem::replace(&mut mesh.vertices, moved);
    if selfx::untangle(mesh, &safe, None) {
        Some(true)
    } else {
        mesh.vertices = safe;
        Some(false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Cell, Floor, GridSpec, MeshOptions, mesh_cells};
    use voxoct_core::glam::UVec3;

    const GRID: GridSpec = GridSpec {
        origin: Vec3::ZERO,
        cell: 0.001,
        resolution: 64,
    };

    /// A cell of [`GRID`] with the mean signed distance `sdf` (cells; `-inf`: added by a
    /// closure, no reading).
    fn cell(x: u32, y: u32, z: u32, sdf: f32) -> Cell {
        Cell {
            coord: UVec3::new(x, y, z),
            hits: 1,
            sdf_sum: sdf * GRID.cell,
        }
    }

    /// Heights (cells, as the grid's `y` of cell centres) of the vertices of `mesh` above
    /// the square 10..22 of a plate 2..30 wide, split at `split`: (below, above).
    fn heights(mesh: &Mesh, split: f32) -> (Vec<f32>, Vec<f32>) {
        let inner = |c: f32| (10.0..22.0).contains(&(c / GRID.cell - 0.5));
        let ys = mesh
            .vertices
            .iter()
            .filter(|p| inner(p.x) && inner(p.z))
            .map(|p| p.y / GRID.cell - 0.5);
        ys.partition(|&y| y < split)
    }

    /// Asserts that there are heights `ys` and that each is within 0.05 cell of `want`.
    fn all_at(ys: &[f32], want: f32, what: &str) {
        assert!(!ys.is_empty(), "no {what} vertex");
        for y in ys {
            assert!((y - want).abs() < 0.05, "{what} at {y}, not {want}");
        }
    }

    /// A plate seen from above only, its surface at y = 10.3 (cells): the readings marked
    /// the layers 9 to 11 with the distances a noisy field holds (half a cell per cell). The
    /// seen top stays where it was measured; the back, which the edges put past the deepest
    /// marked cell (1.95 cells down), comes up to half a cell behind the top.
    #[test]
    fn the_back_of_a_wall_seen_from_one_side_is_half_a_cell_behind_it() {
        let mut cells = Vec::new();
        for x in 2..30 {
            for z in 2..30 {
                for y in 9..=11 {
                    cells.push(cell(x, y, z, 0.5 * (y as f32 - 10.3)));
                }
            }
        }
        let opts = MeshOptions {
            floor: Floor::None,
            ..MeshOptions::default()
        };
        let (mesh, certified) = crate::mesh_cells_certified(&cells, &GRID, &opts).unwrap();
        mesh.check_valid_solid().unwrap();
        assert!(certified);
        let (back, top) = heights(&mesh, 10.0);
        all_at(&top, 10.3, "top");
        all_at(&back, 9.8, "back");
    }

    /// A cup's floor that no view saw, the floor layer (5) filled by a closure, under space
    /// no reading came near: its top is put half a cell above the base (at 4.5, where the
    /// edges into the dropped layer below put it), not half a cell above the layer.
    #[test]
    fn the_top_of_an_unseen_floor_is_half_a_cell_above_the_base() {
        let cells: Vec<Cell> = (2..30)
            .flat_map(|x| (2..30).map(move |z| cell(x, 5, z, f32::NEG_INFINITY)))
            .collect();
        let opts = MeshOptions {
            floor: Floor::LowestMarked,
            ..MeshOptions::default()
        };
        let mesh = mesh_cells(&cells, &GRID, &opts).unwrap();
        mesh.check_valid_solid().unwrap();
        let (base, top) = heights(&mesh, 4.8);
        all_at(&base, 4.5, "base");
        all_at(&top, 5.0, "top");
    }

    /// Values of a plane seen from +y, as the noisy field reads them: `slope` cells per cell
    /// (see the module docs), the surface at `y = h` (cells), marked within a cell of it.
    fn plane_field(h: f64, slope: f64) -> impl Fn([i64; 3]) -> f32 {
        move |g: [i64; 3]| {
            let d = g[1] as f64 - h;
            if d.abs() <= 1.0 {
                (slope * d) as f32
            } else {
                f32::INFINITY
            }
        }
    }

    #[test]
    fn a_plane_fit_reads_the_depth_against_the_fields_slope() {
        let marked = |f: f32| f.is_finite();
        for slope in [1.0, 0.5, 0.3] {
            // The surface at y = 0.2; the edge from (0, 0, 0) down to (0, -1, 0), the
            // vertex at a tenth of it: 0.3 cells behind the surface, whatever the slope.
            let (n, depth) =
                observed_plane(plane_field(0.2, slope), marked, [0; 3], [0, -1, 0], 0.1).unwrap();
            assert!((n - DVec3::Y).length() < 1e-6, "{n}");
            assert!((depth + 0.3).abs() < 1e-6, "{depth}");
        }
        // Up, toward where the surface was seen from: a front, not a back.
        assert_eq!(
            observed_plane(plane_field(0.2, 0.5), marked, [0; 3], [0, 1, 0], 0.1),
            None
        );
        // Too few marked cells to fit.
        let few = |g: [i64; 3]| if g == [0; 3] { -0.2 } else { f32::INFINITY };
        assert_eq!(observed_plane(few, marked, [0; 3], [0, -1, 0], 0.1), None);
        // Marked cells in one layer only: no slope across it to fit.
        let flat = |g: [i64; 3]| if g[1] == 0 { -0.2 } else { f32::INFINITY };
        assert_eq!(observed_plane(flat, marked, [0; 3], [0, -1, 0], 0.1), None);
    }
}
