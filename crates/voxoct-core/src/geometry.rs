//! Plain geometric types shared by every voxoct crate.

use glam::{UVec3, Vec3};

/// The one scalar type of voxoct: metres, single precision.
pub type Real = f32;

/// An axis-aligned box, closed: it contains its faces, edges and corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// A box from its two corners (`min <= max` on every axis is the caller's job).
    #[inline]
    #[must_use]
    pub const fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    /// A cube from its minimum corner and edge length.
    #[inline]
    #[must_use]
    pub fn cube(min: Vec3, edge: Real) -> Self {
        Self {
            min,
            max: min + Vec3::splat(edge),
        }
    }

    /// The centre of the box.
    #[inline]
    #[must_use]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the extent on each axis.
    #[inline]
    #[must_use]
    pub fn half_extents(&self) -> Vec3 {
        (self.max - self.min) * 0.5
    }

    /// The box's surface as 12 triangles, two per face, counter-clockwise seen from outside
    /// (their normals point out of the box): a closed, outward-oriented mesh of it, e.g. to
    /// insert a box into an [`crate::Octree`] or to simulate one.
    ///
    /// ```
    /// use voxoct_core::Aabb;
    /// use voxoct_core::glam::Vec3;
    ///
    /// let b = Aabb::new(Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0));
    /// let tris = b.surface_triangles();
    /// let twice_area = |t: &voxoct_core::Triangle| (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]);
    /// let area: f32 = tris.iter().map(|t| twice_area(t).length() / 2.0).sum();
    /// assert!((area - 2.0 * (6.0 + 8.0 + 12.0)).abs() < 1e-4);
    /// for t in &tris {
    ///     let centroid = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
    ///     assert!(twice_area(t).dot(centroid - b.center()) > 0.0, "{t:?} faces inwards");
    /// }
    /// ```
    #[must_use]
    pub fn surface_triangles(&self) -> [Triangle; 12] {
        let (lo, hi) = (self.min, self.max);
        let c = |i: usize| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        // Each face as a quad of corners, counter-clockwise seen from outside.
        const QUADS: [[usize; 4]; 6] = [
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 2, 3, 1],
            [4, 5, 7, 6],
        ];
        std::array::from_fn(|k| {
            let q = QUADS[k / 2];
            if k % 2 == 0 {
                Triangle::new(c(q[0]), c(q[1]), c(q[2]))
            } else {
                Triangle::new(c(q[0]), c(q[2]), c(q[3]))
            }
        })
    }

    /// Whether the closed box contains `p`.
    #[inline]
    #[must_use]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// A triangle in 3D, vertices in counter-clockwise order seen from the side
/// its normal points to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    /// The three vertices.
    pub v: [Vec3; 3],
}

impl Triangle {
    /// A triangle from its three vertices.
    #[inline]
    #[must_use]
    pub const fn new(a: Vec3, b: Vec3, c: Vec3) -> Self {
        Self { v: [a, b, c] }
    }

    /// The unnormalised normal `(b - a) × (c - a)`: its length is twice the area.
    #[inline]
    #[must_use]
    pub fn scaled_normal(&self) -> Vec3 {
        (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0])
    }

    /// The triangle's bounding box.
    #[inline]
    #[must_use]
    pub fn aabb(&self) -> Aabb {
        Aabb::new(
            self.v[0].min(self.v[1]).min(self.v[2]),
            self.v[0].max(self.v[1]).max(self.v[2]),
        )
    }

    /// Whether every coordinate is finite.
    #[inline]
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.v.iter().all(|p| p.is_finite())
    }
}

/// Half a cube's space diagonal in units of its edge, `√3 / 2`: the farthest a plane that
/// touches a cell of a [`GridSpec`] can pass from the cell's centre, in cells.
pub const HALF_CELL_DIAGONAL: Real = 0.866_025_4;

/// A regular cubic grid: the cells of one octree depth.
///
/// Cell `(i, j, k)` spans `origin + cell * (i, j, k)` to `origin + cell * (i + 1, j + 1, k + 1)`;
/// valid coordinates are `0..resolution` on each axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridSpec {
    /// Minimum corner of cell `(0, 0, 0)` (the octree root's minimum corner).
    pub origin: Vec3,
    /// Edge length of one cell, metres.
    pub cell: Real,
    /// Number of cells along each axis (`2^depth`).
    pub resolution: u32,
}

impl GridSpec {
    /// Centre of cell `coord`.
    #[inline]
    #[must_use]
    pub fn cell_center(&self, coord: UVec3) -> Vec3 {
        self.origin + (coord.as_vec3() + Vec3::splat(0.5)) * self.cell
    }

    /// The grid-plane corner `origin + cell * coord` (coordinates may go up to
    /// `resolution`, the far faces of the last cells).
    ///
    /// Every box voxoct-core tests is built from these corners, computed exactly this
    /// way, so neighbouring cells share their faces bit for bit and a node's box at one
    /// depth has the very same corners as the union of its children (the cell edge of
    /// each depth is the root edge divided by a power of two, so `i * cell` rounds the
    /// same at every depth).
    #[inline]
    #[must_use]
    pub fn corner(&self, coord: UVec3) -> Vec3 {
        self.origin + coord.as_vec3() * self.cell
    }

    /// The closed box of cell `coord`: from [`corner(coord)`](Self::corner) to
    /// `corner(coord + 1)`.
    #[inline]
    #[must_use]
    pub fn cell_aabb(&self, coord: UVec3) -> Aabb {
        Aabb::new(
            self.origin + coord.as_vec3() * self.cell,
            self.origin + (coord.as_vec3() + Vec3::ONE) * self.cell,
        )
    }

    /// The closed box of the whole grid.
    #[inline]
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        Aabb::new(
            self.origin,
            self.origin + Vec3::splat(self.resolution as Real) * self.cell,
        )
    }
}

/// What the depth views together say of a cell: the verdict of
/// `voxoct_depth::carve::visibility`, which the closure of unseen space
/// (`voxoct_mesh::closure`) reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seen {
    /// Some view sees the cell in front of its reading: empty space.
    Empty,
    /// No view sees it empty, some view sees it on its surface: within the margin of a
    /// reading, on the camera's side of it (or at it).
    Surface,
    /// No view sees it empty or on the camera's side of a reading, some view sees it within
    /// the margin beyond a reading: just behind an observed surface.
    BehindSurface,
    /// No view sees it in front of or on its surface: it is behind every reading that covers
    /// it, or covered by none.
    Unseen,
}

/// One marked cell of an octree at some depth, with what the insertions left in it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// Integer grid coordinates at the cell's depth (see [`GridSpec`]).
    pub coord: UVec3,
    /// How many inserted triangles overlap the cell (summed over children for coarser depths).
    pub hits: u32,
    /// Sum over those triangles of the signed distance from the cell centre to the
    /// triangle's plane, metres, positive on the side the triangle's normal points to.
    /// `sdf_sum / hits` is the mean signed distance.
    pub sdf_sum: Real,
}

impl Cell {
    /// The thesis's value: 1 for a marked cell.
    #[inline]
    #[must_use]
    pub fn value(&self) -> Real {
        if self.hits > 0 { 1.0 } else { 0.0 }
    }

    /// Mean signed distance from the cell centre to the triangles that marked it
    /// (0 when `hits == 0`).
    #[inline]
    #[must_use]
    pub fn mean_sdf(&self) -> Real {
        if self.hits > 0 {
            self.sdf_sum / self.hits as Real
        } else {
            0.0
        }
    }
}

/// Area-weighted unit vertex normals of an outward-wound mesh (zero for a vertex whose
/// triangles are all degenerate or that no triangle uses). Indices must be in range.
#[must_use]
pub fn vertex_normals(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; vertices.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        // The cross product's length is twice the area: area weighting for free.
        let f = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += f;
        }
    }
    for v in &mut n {
        *v = v.normalize_or_zero();
    }
    n
}
