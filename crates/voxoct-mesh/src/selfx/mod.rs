//! Exact self-intersection test of a triangle mesh.
//!
//! # What counts
//! Triangles are closed point sets. Two triangles `T1`, `T2` of a mesh *intersect
//! improperly* when `T1 ∩ T2` is more than what their shared vertex indices allow:
//! - no shared vertex: `T1 ∩ T2` must be empty (touching counts as intersecting);
//! - one shared vertex `v`: `T1 ∩ T2` must be `{v}`. With `T1 = (v, a, b)` and
//!   `T2 = (v, c, d)` this fails exactly when the segment `ab` meets `T2` or `cd` meets `T1`
//!   (the line where the two planes meet runs through `v`; the shorter of the two chords from
//!   `v` ends on its triangle's opposite edge, inside the other triangle);
//! - a shared edge `uv` with opposite vertices `p`, `q`: `T1 ∩ T2` must be the segment `uv`.
//!   This fails exactly when `u, v, p, q` are coplanar and `p`, `q` lie on the same side of
//!   the line `uv` (a fold): otherwise the planes meet in the line `uv` only, or the two
//!   triangles lie in opposite half-planes;
//! - three shared vertices (a repeated triangle, in either orientation): always improper.
//!
//! A triangle that is not a proper triangle — an index out of range, a repeated index, a
//! non-finite vertex, or three exactly collinear positions — is reported as self-intersecting
//! itself and takes part in no pair test.
//!
//! # Exactness
//! Every decision is the sign of an orientation determinant (`orient3d`, or `orient2d` of a
//! projection onto a coordinate plane), evaluated by Shewchuk's adaptive-precision
//! predicates (the `robust` crate): a floating-point filter, then exact expansion arithmetic
//! when the filter cannot decide. The `f32` coordinates convert to `f64` exactly, and their
//! range keeps every intermediate product far from `f64` overflow and underflow, so every
//! sign is exact. Coplanar configurations are decided in the projection that drops the axis
//! of a non-zero normal component, which maps the common plane bijectively (preserving or
//! reversing every orientation alike), so they are exact too. The sides of a triangle's
//! plane that three points lie on are first decided from one normal per triangle with the
//! same kind of error bound (`exact::sides`), the exact predicate deciding what it cannot.
//!
//! # Speed
//! - Candidate pairs come from a uniform grid (cell edge 2.5 mean triangle extents): each
//!   triangle is entered in every cell its bounding box meets, flagged with the axes along
//!   which that cell is its first; the cells are hashed by their Morton code into buckets
//!   (nearby cells, nearby buckets) and counting-sorted. Two overlapping boxes have exactly
//!   one cell that is, along each axis, the first cell of one of them, and only the entries
//!   whose flags cover all three axes are paired, so each pair is found once.
//! - Pairs around a vertex need no test when the vertex's whole fan is *certified*: closed,
//!   and one-to-one in the projection along a coordinate axis (every triangle with the same
//!   orientation, the projections winding once around the vertex). Then any two of its
//!   triangles meet in exactly their shared vertex or edge. On a smooth scan nearly every
//!   vertex is certified, leaving the exact tests to the pairs that share no vertex.
//! - Within a bucket, the boxes of a block of entries are compared with one entry's without
//!   a branch per candidate (most do not overlap, unpredictably); only the overlapping ones
//!   are looked at further.
//! - With the `parallel` feature the classification, the certificates, the grid's bounds,
//!   the counting sort and the buckets are processed on every core, and the fans and
//!   certificates are computed alongside the boxes and the grid; the result is the same set.
//!
//! [`untangle`] reuses the search state to re-check only the pairs around moved vertices:
//! the grid is built once over the smoothed boxes; the pairs of two moved triangles come
//! from a small grid over the moved ones, rebuilt each round, and those of a moved and an
//! unmoved one from the first grid, visited over the moved one's current box.

use voxoct_core::glam::{Vec3, Vec3A};

use crate::fans::VertexFans;
use crate::mesh::Mesh;

mod exact;
mod grid;

use exact::*;
use grid::*;
/// Whether triangles `i` and `j` of `mesh` intersect improperly (see
/// [`self_intersecting_triangles`]); for `i == j`, whether the triangle is not a proper
/// triangle (bad or repeated index, non-finite or collinear vertices: such a triangle takes
/// part in no pair). One pair, exactly, without the grid or any shortcut: the reference for
/// the search.
///
/// # Panics
/// If `i` or `j` is not a triangle index.
#[must_use]
pub fn triangles_intersect(mesh: &Mesh, i: usize, j: usize) -> bool {
    let (ti, tj) = (mesh.triangles[i], mesh.triangles[j]);
    let ki = classify(&mesh.vertices, ti).0;
    if i == j {
        return ki == NO_AXIS;
    }
    let kj = classify(&mesh.vertices, tj).0;
    if ki == NO_AXIS || kj == NO_AXIS {
        return false;
    }
    let tri = |idx, k: u8| Tri {
        idx,
        k: k as usize,
        v: &mesh.vertices,
    };
    improper(tri(ti, ki), tri(tj, kj))
}

/// The triangles of `mesh` that intersect another triangle *improperly*, or are not proper
/// triangles, in increasing order. A closed, oriented 2-manifold with none is the boundary
/// of a solid.
///
/// Triangles are closed point sets, and two of them intersect improperly when they meet in
/// more than their shared vertex indices allow:
/// - no shared vertex: they must not meet at all (touching counts);
/// - one shared vertex `v`: they must meet in `v` only;
/// - a shared edge: they must meet in that edge only, that is, they must not be folded onto
///   each other (coplanar with the opposite vertices on the same side of the edge);
/// - a repeated triangle (three shared vertices, either orientation) always does.
///
/// A triangle with an index out of range, a repeated index, a non-finite vertex or three
/// exactly collinear vertices is not a proper triangle: it is reported itself and takes part
/// in no pair.
///
/// Every decision is exact: signs of orientation determinants evaluated with Shewchuk's
/// adaptive-precision predicates, which are exact for `f32` coordinates. Candidate pairs come
/// from a uniform grid over the triangles' bounding boxes; pairs of triangles around a vertex
/// whose whole fan is proved embedded (it projects one-to-one along an axis) need no test.
/// With the `parallel` feature the work is spread over every core, with the same result.
#[must_use]
pub fn self_intersecting_triangles(mesh: &Mesh) -> Vec<u32> {
    let checker = Checker::new(&mesh.vertices, &mesh.triangles, false);
    checker.check_all(&mesh.vertices)
}

/// A triangle's bounding box `[min, max]` (zero-sized at the origin for a bad index).
#[inline]
fn tri_box(vertices: &[Vec3], t: [u32; 3]) -> [Vec3A; 2] {
    let g = |i: u32| Vec3A::from(vertices.get(i as usize).copied().unwrap_or(Vec3::ZERO));
    let (a, b, c) = (g(t[0]), g(t[1]), g(t[2]));
    [a.min(b).min(c), a.max(b).max(c)]
}

/// Largest fan that [`certified`] examines.
const MAX_FAN: usize = 32;

/// Whether the triangles around vertex `v` (its `fan`) cannot intersect each other
/// improperly, proved exactly: all are proper, each link vertex starts exactly one and ends
/// exactly one of them (closed), and along some coordinate axis every one projects with the
/// same orientation and the projections wind once around `v`. Then the projection maps each
/// triangle one-to-one onto a sector at `v`, the sectors meet only in `v` or (consecutive
/// ones) along the ray of their shared edge, so any two of the triangles meet in exactly
/// their shared vertex or edge.
fn certified(
    v: u32,
    fan: &[u32],
    triangles: &[[u32; 3]],
    vertices: &[Vec3],
    facts: &[(u8, u8)],
) -> bool {
    let m = fan.len();
    if !(3..=MAX_FAN).contains(&m) {
        return false;
    }
    let mut link = [(0u32, 0u32); MAX_FAN];
    let mut all = 0x3fu8;
    for (l, &t) in link.iter_mut().zip(fan) {
        let (k, signs) = facts[t as usize];
        if k == NO_AXIS {
            return false;
        }
        all &= signs;
        let tri = triangles[t as usize];
        // v's corner, without a branch (which corner it is varies).
        let r = usize::from(tri[1] == v) | (usize::from(tri[2] == v) << 1);
        *l = (tri[[1, 2, 0, 0][r]], tri[[2, 0, 1, 1][r]]);
    }
    if all == 0 {
        return false;
    }
    let link = &link[..m];
    // Closed: starts distinct, ends distinct, and each end is some triangle's start (so the
    // ends are the starts, permuted); `succ[i]` is the triangle that starts where triangle i
    // ends.
    let mut succ = [0u8; MAX_FAN];
    for (i, l) in link.iter().enumerate() {
        if link[i + 1..].iter().any(|x| x.0 == l.0 || x.1 == l.1) {
            return false;
        }
        match link.iter().position(|x| x.0 == l.1) {
            Some(j) => succ[i] = j as u8,
            None => return false,
        }
    }
    let k = all.trailing_zeros() as usize;
    let (k, flip) = if k < 3 { (k, 1) } else { (k - 3, -1) };
    // Winding: the sectors (start, end] that hold the direction of the first link vertex.
    let pv = pt(vertices[v as usize]);
    let r = pt(vertices[link[0].0 as usize]);
    let mut side = [0i8; MAX_FAN];
    for (s, l) in side.iter_mut().zip(link).skip(1) {
        *s = flip * orient2d(&pv, &pt(vertices[l.0 as usize]), &r, k);
    }
    let mut count = 0;
    for i in 0..m {
        if side[i] > 0 && side[succ[i] as usize] <= 0 {
            count += 1;
        }
    }
    count == 1
}

/// The vertices of triangle `t` whose fans are certified by `cert` (others `u32::MAX`).
#[inline]
fn certified_of(cert: &[bool], t: [u32; 3]) -> [u32; 3] {
    t.map(|v| {
        if cert.get(v as usize).copied().unwrap_or(false) {
            v
        } else {
            u32::MAX
        }
    })
}

/// Whether the indices are in range and distinct.
#[inline]
fn valid_indices(nv: usize, t: [u32; 3]) -> bool {
    t.iter().all(|&i| (i as usize) < nv) && t[0] != t[1] && t[1] != t[2] && t[0] != t[2]
}

/// The state of one self-intersection search, kept for re-checking after local moves.
pub(crate) struct Checker<'a> {
    triangles: &'a [[u32; 3]],
    /// Also treat triangles that [`Mesh::check_closed_manifold`] calls degenerate as
    /// improper.
    f32_degenerate: bool,
    facts: Vec<(u8, u8)>,
    fans: VertexFans,
    cert: Vec<bool>,
    /// The grid over the boxes the triangles had when the search was prepared. A
    /// triangle's current box and certified vertices are computed where they are used
    /// (stored, they were 44 bytes a triangle at the peak of a large mesh's smoothing).
    index: Index,
    /// The triangles moved since then (their boxes in `index` are stale), as flags and
    /// as a list in the order they were first moved.
    touched: Vec<bool>,
    touched_list: Vec<u32>,
}

/// The fans of the proper-indexed triangles of a mesh with `nv` vertices, as the search
/// uses them (see [`Checker::with_fans`]).
pub(crate) fn vertex_fans(nv: usize, triangles: &[[u32; 3]]) -> VertexFans {
    VertexFans::new(nv, triangles, |t| valid_indices(nv, t), false)
}

impl<'a> Checker<'a> {
    /// Prepares the search over the triangles' current boxes.
    pub(crate) fn new(vertices: &[Vec3], triangles: &'a [[u32; 3]], f32_degenerate: bool) -> Self {
        Self::with_fans(vertices, triangles, f32_degenerate, None)
    }

    /// [`Checker::new`], with the triangles' [`vertex_fans`] when they are already built.
    pub(crate) fn with_fans(
        vertices: &[Vec3],
        triangles: &'a [[u32; 3]],
        f32_degenerate: bool,
        fans: Option<VertexFans>,
    ) -> Self {
        let nv = vertices.len();
        let facts = crate::par::map(triangles, |t| fact(vertices, *t, f32_degenerate));
        // The fans (built on one thread) and certificates alongside the boxes and the grid,
        // so that the serial parts of each overlap the other's parallel ones.
        let ((fans, cert), index) = crate::par::join(
            || {
                let fans = fans.unwrap_or_else(|| vertex_fans(nv, triangles));
                let mut cert = Vec::new();
                crate::par::map_into(&mut cert, nv, |v| {
                    certified(v as u32, fans.fan(v as u32), triangles, vertices, &facts)
                });
                (fans, cert)
            },
            || {
                Index::build(
                    triangles.len(),
                    |t| tri_box(vertices, triangles[t]),
                    None,
                    |t| facts[t].0 != NO_AXIS,
                )
            },
        );
        Self {
            triangles,
            f32_degenerate,
            facts,
            fans,
            cert,
            index,
            touched: Vec::new(),
            touched_list: Vec::new(),
        }
    }

    /// Every flagged triangle, in increasing order.
    pub(crate) fn check_all(&self, vertices: &[Vec3]) -> Vec<u32> {
        let mut out = self.index.pairs(self, vertices, None);
        self.add_improper(&mut out, 0..self.triangles.len());
        out.sort_unstable();
        out.dedup();
        out
    }

    fn add_improper(&self, out: &mut Vec<u32>, ts: impl Iterator<Item = usize>) {
        out.extend(ts.filter(|&t| self.facts[t].0 == NO_AXIS).map(|t| t as u32));
    }

    /// The vertices of triangle `t` whose fans are certified (others `u32::MAX`).
    #[inline]
    fn certified_vertices(&self, t: u32) -> [u32; 3] {
        certified_of(&self.cert, self.triangles[t as usize])
    }

    /// Triangle `t`'s current bounding box.
    #[inline]
    fn tri_box(&self, vertices: &[Vec3], t: u32) -> [Vec3A; 2] {
        tri_box(vertices, self.triangles[t as usize])
    }

    /// After `moved` vertices changed position: updates what depends on them and returns
    /// the flagged triangles among the pairs that involve them (increasing order). With no
    /// flagged pair before the move except those around `moved`, that is every one.
    ///
    /// The pairs of two moved triangles (moved now or before) come from a small grid over
    /// the moved ones' current boxes; those of a triangle moved now and one never moved,
    /// from the prepared grid, visiting the cells of the moved one's current box (the
    /// other's box there is current).
    pub(crate) fn recheck(
        &mut self,
        vertices: &[Vec3],
        moved: &[u32],
        dirty: &mut [bool],
    ) -> Vec<u32> {
        let mut tris: Vec<u32> = Vec::new();
        for &v in moved {
            tris.extend_from_slice(self.fans.fan(v));
        }
        tris.sort_unstable();
        tris.dedup();
        if self.touched.is_empty() {
            self.touched = vec![false; self.triangles.len()];
        }
        let mut verts: Vec<u32> = Vec::new();
        for &t in &tris {
            let tri = self.triangles[t as usize];
            self.facts[t as usize] = fact(vertices, tri, self.f32_degenerate);
            dirty[t as usize] = true;
            if !self.touched[t as usize] {
                self.touched[t as usize] = true;
                self.touched_list.push(t);
            }
            verts.extend_from_slice(&tri);
        }
        verts.sort_unstable();
        verts.dedup();
        for &v in &verts {
            let ok = certified(v, self.fans.fan(v), self.triangles, vertices, &self.facts);
            self.cert[v as usize] = ok;
        }
        let side = Index::build(
            self.touched_list.len(),
            |i| self.tri_box(vertices, self.touched_list[i]),
            Some(&self.touched_list),
            |i| self.facts[self.touched_list[i] as usize].0 != NO_AXIS,
        );
        let mut out = side.pairs(self, vertices, Some(dirty));
        self.index
            .pairs_with_untouched(self, vertices, &tris, &self.touched, &mut out);
        self.add_improper(&mut out, tris.iter().map(|&t| t as usize));
        for &t in &tris {
            dirty[t as usize] = false;
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// [`classify`], and with `f32_degenerate` the degenerate test of
/// [`Mesh::check_closed_manifold`] on top.
fn fact(vertices: &[Vec3], t: [u32; 3], f32_degenerate: bool) -> (u8, u8) {
    let f = classify(vertices, t);
    if f32_degenerate && f.0 != NO_AXIS && crate::mesh::triangle_area(vertices, t).1 {
        return (NO_AXIS, 0);
    }
    f
}

/// Moves the vertices of improper triangles — self-intersecting, collinear, or degenerate
/// as [`Mesh::check_closed_manifold`] counts them — back toward `safe` (the same
/// connectivity with no improper triangle) until none is left: each round, every vertex of
/// a flagged triangle goes to the next of `moved + f · (safe - moved)` for f = 1/2, 3/4, 7/8,
/// then to `safe` itself, and the triangles around the moved vertices are checked again.
/// Every round moves a vertex, and a pair of triangles whose vertices are all at `safe` is
/// proper, so this ends. Returns `true` when no triangle is left flagged (the mesh is
/// proven free of self-intersections), `false` when flagged triangles are left with every
/// vertex at `safe` (`safe` was not clean). `fans`: the mesh's [`vertex_fans`], when
/// already built.
pub(crate) fn untangle(mesh: &mut Mesh, safe: &[Vec3], fans: Option<VertexFans>) -> bool {
    let Mesh {
        vertices,
        triangles,
    } = mesh;
    let target = vertices.clone();
    let mut checker = Checker::with_fans(vertices, triangles, true, fans);
    let mut flagged = checker.check_all(vertices);
    if flagged.is_empty() {
        return true;
    }
    let mut level = vec![0u8; vertices.len()];
    let mut dirty = vec![false; triangles.len()];
    let mut moved: Vec<u32> = Vec::new();
    while !flagged.is_empty() {
        moved.clear();
        for &t in &flagged {
            moved.extend_from_slice(&triangles[t as usize]);
        }
        moved.sort_unstable();
        moved.dedup();
        moved.retain(|&v| level[v as usize] < UNTANGLE_STEPS);
        if moved.is_empty() {
            return false;
        }
        for &v in &moved {
            let l = &mut level[v as usize];
            *l += 1;
            let (s, m) = (safe[v as usize], target[v as usize]);
            vertices[v as usize] = if *l == UNTANGLE_STEPS {
                s
            } else {
                // Clamped so that rounding cannot leave the segment between the two.
                (s + (m - s) * 0.5f32.powi(i32::from(*l))).clamp(s.min(m), s.max(m))
            };
        }
        flagged = checker.recheck(vertices, &moved, &mut dirty);
    }
    true
}

/// Steps from the moved position to the safe one in [`untangle`].
const UNTANGLE_STEPS: u8 = 4;

/// Whether two triangles given by their certified vertices (others `u32::MAX`) share one:
/// a vertex whose fan is [`certified`].
#[inline]
fn shares_certified(a: [u32; 3], b: [u32; 3]) -> bool {
    // Without branches: which vertex is shared, if any, varies unpredictably.
    let s = |v: u32| (v != u32::MAX) & ((v == b[0]) | (v == b[1]) | (v == b[2]));
    s(a[0]) | s(a[1]) | s(a[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Cell, GridSpec, MeshOptions, Placement, mesh_cells};
    use proptest::prelude::*;
    use voxoct_core::glam::UVec3;

    /// What [`Checker::recheck`] must return after moving `moved`: both triangles of every
    /// improper pair with a member around a moved vertex, and those of them that are not
    /// proper triangles, by the one-pair reference. (A triangle with a repeated or bad index
    /// is around no vertex: it is flagged whatever moves.)
    fn reference_recheck(mesh: &Mesh, moved: &[u32]) -> Vec<u32> {
        let nv = mesh.vertices.len();
        let dirty: Vec<bool> = (0..mesh.triangles.len())
            .map(|t| {
                let tri = mesh.triangles[t];
                valid_indices(nv, tri) && tri.iter().any(|v| moved.contains(v))
            })
            .collect();
        let mut out = Vec::new();
        for i in 0..mesh.triangles.len() {
            for j in i..mesh.triangles.len() {
                if (dirty[i] || dirty[j]) && triangles_intersect(mesh, i, j) {
                    out.extend([i as u32, j as u32]);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Moves `rounds` of vertices of `mesh` (to anywhere, also outside the prepared grid)
    /// and compares every re-check with the reference, then the full search with all pairs.
    fn check_moves(mut mesh: Mesh, rounds: &[Vec<(usize, [f32; 3])>]) -> Result<(), TestCaseError> {
        let triangles = mesh.triangles.clone();
        let mut ck = Checker::new(&mesh.vertices, &triangles, false);
        prop_assert_eq!(
            ck.check_all(&mesh.vertices),
            self_intersecting_triangles(&mesh)
        );
        let mut dirty = vec![false; triangles.len()];
        for round in rounds {
            let mut moved: Vec<u32> = Vec::new();
            for &(v, p) in round {
                let v = v % mesh.vertices.len();
                mesh.vertices[v] = Vec3::from_array(p);
                moved.push(v as u32);
            }
            moved.sort_unstable();
            moved.dedup();
            let got = ck.recheck(&mesh.vertices, &moved, &mut dirty);
            prop_assert_eq!(got, reference_recheck(&mesh, &moved));
            prop_assert!(dirty.iter().all(|d| !d));
        }
        let n = mesh.triangles.len();
        let want = (0..n)
            .filter(|&i| (0..n).any(|j| triangles_intersect(&mesh, i, j)))
            .map(|i| i as u32)
            .collect::<Vec<_>>();
        prop_assert_eq!(self_intersecting_triangles(&mesh), want);
        Ok(())
    }

    fn moves(spread: f32) -> impl Strategy<Value = Vec<Vec<(usize, [f32; 3])>>> {
        prop::collection::vec(
            prop::collection::vec(
                (0usize..10_000, prop::array::uniform3(-spread..spread)),
                1..6,
            ),
            1..5,
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Re-checks after moves agree with the reference, on triangle soups with shared
        /// vertices.
        #[test]
        fn recheck_after_moves_matches_the_reference_on_soups(
            verts in prop::collection::vec(prop::array::uniform3(-1.0f32..1.0), 4..40),
            picks in prop::collection::vec((0usize..1000, 0usize..1000, 0usize..1000), 1..60),
            rounds in moves(1.5),
        ) {
            let n = verts.len();
            let mesh = Mesh {
                vertices: verts.iter().map(|v| Vec3::from_array(*v)).collect(),
                triangles: picks
                    .iter()
                    .map(|&(a, b, c)| [a % n, (a + 1 + b % 3) % n, (a + 2 + c % 4) % n].map(|x| x as u32))
                    .collect(),
            };
            check_moves(mesh, &rounds)?;
        }

        /// Re-checks after moves agree with the reference on the mesher's closed meshes
        /// (certified fans, moves of about a cell).
        #[test]
        fn recheck_after_moves_matches_the_reference_on_meshes(
            cells in prop::collection::vec((0u32..6, 0u32..6, 0u32..6, -0.9f32..0.9), 1..24),
            rounds in moves(0.004),
        ) {
            let grid = GridSpec { origin: Vec3::ZERO, cell: 0.001, resolution: 8 };
            let cells: Vec<Cell> = cells
                .iter()
                .map(|&(x, y, z, s)| Cell { coord: UVec3::new(x, y, z), hits: 1, sdf_sum: s * 0.001 })
                .collect();
            let opts = MeshOptions { placement: Placement::SignedDistance, ..MeshOptions::thesis() };
            let mesh = mesh_cells(&cells, &grid, &opts).unwrap();
            // Moves relative to where the vertex is: small, so that pairs are near.
            let rounds: Vec<Vec<(usize, [f32; 3])>> = rounds
                .iter()
                .map(|r| {
                    r.iter()
                        .map(|&(v, d)| {
                            let p = mesh.vertices[v % mesh.vertices.len()];
                            (v, (p + Vec3::from_array(d) * 0.25).to_array())
                        })
                        .collect()
                })
                .collect();
            check_moves(mesh, &rounds)?;
        }
    }
}
