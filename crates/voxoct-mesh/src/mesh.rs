//! The indexed mesh, its closed-manifold check and its statistics.

use voxoct_core::Aabb;
use voxoct_core::glam::Vec3;

use crate::par;

/// An indexed triangle mesh: triangles are counter-clockwise seen from outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, metres.
    pub vertices: Vec<Vec3>,
    /// Triangles as indices into `vertices`, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// What makes a mesh fail [`Mesh::check_closed_manifold`], and where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TopologyError {
    /// The mesh has no triangles (so it encloses no volume).
    #[error("the mesh is empty")]
    Empty,
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} refers to vertex {index}, past the last vertex")]
    IndexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// The bad index.
        index: u32,
    },
    /// A triangle uses one vertex twice.
    #[error("triangle {triangle} uses a vertex twice")]
    RepeatedIndex {
        /// Triangle index.
        triangle: usize,
    },
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex} is not finite")]
    NonFiniteVertex {
        /// Vertex index.
        vertex: u32,
    },
    /// Two vertices have the same position (welding an STL would merge them).
    #[error("vertices {a} and {b} have the same position")]
    DuplicatePosition {
        /// First vertex.
        a: u32,
        /// Second vertex.
        b: u32,
    },
    /// A vertex that no triangle uses.
    #[error("vertex {vertex} is used by no triangle")]
    UnusedVertex {
        /// Vertex index.
        vertex: u32,
    },
    /// A triangle with (numerically) zero area.
    #[error("triangle {triangle} is degenerate (area {area:e})")]
    Degenerate {
        /// Triangle index.
        triangle: usize,
        /// Its area.
        area: f32,
    },
    /// The directed edge `a → b` appears in two triangles: more than two triangles on one
    /// edge, or two neighbours with inconsistent orientation.
    #[error("directed edge {a} -> {b} appears in more than one triangle (triangle {triangle})")]
    RepeatedEdge {
        /// Edge start.
        a: u32,
        /// Edge end.
        b: u32,
        /// One of the triangles.
        triangle: usize,
    },
    /// The directed edge `a → b` has no triangle with `b → a`: a hole or a flipped neighbour.
    #[error("edge {a} -> {b} of triangle {triangle} has no opposite edge {b} -> {a}")]
    OpenEdge {
        /// Edge start.
        a: u32,
        /// Edge end.
        b: u32,
        /// The triangle that has it.
        triangle: usize,
    },
    /// The triangles around a vertex form more than one fan (two sheets touch at it).
    #[error("vertex {vertex}: its {triangles} triangles form {fans} fans instead of one disc")]
    NonManifoldVertex {
        /// Vertex index.
        vertex: u32,
        /// Triangles around it.
        triangles: usize,
        /// Number of separate fans.
        fans: usize,
    },
    /// The enclosed volume is not positive (normals point inward).
    #[error("enclosed volume {volume:e} is not positive")]
    NonPositiveVolume {
        /// Signed volume, cubic metres.
        volume: f64,
    },
    /// Triangles cut through each other (see [`crate::self_intersecting_triangles`]).
    #[error("{triangles} triangles intersect others (the first is triangle {first})")]
    SelfIntersecting {
        /// How many triangles intersect another one.
        triangles: usize,
        /// The lowest-numbered of them.
        first: usize,
    },
}

/// Summary figures of a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshStats {
    /// Number of triangles.
    pub triangles: usize,
    /// Number of vertices.
    pub vertices: usize,
    /// Signed enclosed volume, cubic metres (positive for an outward-oriented closed mesh).
    pub volume: f64,
    /// Total surface area, square metres.
    pub area: f64,
    /// Bounding box of the vertices (`None` when there are none).
    pub bounds: Option<Aabb>,
    /// Number of edge-connected components of triangles (a hollow shell counts two).
    pub components: usize,
}

impl MeshStats {
    /// The genus summed over the components — how many handles (tunnels) the surface has:
    /// 0 for a sphere, 1 for a torus — when the mesh is a closed 2-manifold (as
    /// [`Mesh::check_closed_manifold`] proves). There every edge has two triangles, so a
    /// component with `V` vertices and `F` triangles has Euler characteristic `V - F / 2`
    /// and genus `(2 - (V - F / 2)) / 2`. `None` when the counts cannot be a closed
    /// 2-manifold's (an odd triangle count, or no whole non-negative genus).
    #[must_use]
    pub fn genus(&self) -> Option<usize> {
        if self.triangles % 2 == 1 {
            return None;
        }
        // 2 · Σ genus = 2 · components − Σ χ.
        let twice = (2 * self.components + self.triangles / 2).checked_sub(self.vertices)?;
        (twice % 2 == 0).then_some(twice / 2)
    }
}

/// Relative area below which a triangle counts as degenerate: `|cross| <= EPS · longest²`.
const DEGENERATE_REL: f32 = 1.0e-6;

/// Whether triangle `t` is degenerate in `f32`; returns its area.
#[inline]
pub(crate) fn triangle_area(v: &[Vec3], t: [u32; 3]) -> (f32, bool) {
    let [a, b, c] = t.map(|i| v[i as usize]);
    let n = (b - a).cross(c - a).length();
    let longest = (b - a)
        .length_squared()
        .max((c - a).length_squared())
        .max((c - b).length_squared());
    (0.5 * n, n.is_nan() || n <= DEGENERATE_REL * longest)
}

/// A small union-find.
pub(crate) struct Dsu(Vec<u32>);

impl Dsu {
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }
    pub(crate) fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = p;
            x = p;
        }
        x
    }
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.0[a.max(b) as usize] = a.min(b);
        }
    }
}

impl Mesh {
    /// Signed enclosed volume, cubic metres (divergence theorem, in `f64` about the first
    /// vertex).
    #[must_use]
    pub fn volume(&self) -> f64 {
        let Some(&o) = self.vertices.first() else {
            return 0.0;
        };
        let o = o.as_dvec3();
        par::sum(&self.triangles, |t| {
            let [a, b, c] = t.map(|i| self.vertices[i as usize].as_dvec3() - o);
            a.dot(b.cross(c))
        }) / 6.0
    }

    /// Total surface area, square metres.
    #[must_use]
    pub fn area(&self) -> f64 {
        par::sum(&self.triangles, |t| {
            let [a, b, c] = t.map(|i| self.vertices[i as usize].as_dvec3());
            0.5 * (b - a).cross(c - a).length()
        })
    }

    /// Triangle and vertex counts, volume, area, bounds, components.
    #[must_use]
    pub fn stats(&self) -> MeshStats {
        let bounds = self.vertices.first().map(|&p0| {
            let (lo, hi) = self
                .vertices
                .iter()
                .fold((p0, p0), |(lo, hi), &p| (lo.min(p), hi.max(p)));
            Aabb::new(lo, hi)
        });
        let mut seen = vec![false; self.vertices.len()];
        let mut components = 0;
        for r in par::triangle_roots(self.vertices.len(), &self.triangles) {
            components += usize::from(!std::mem::replace(&mut seen[r as usize], true));
        }
        MeshStats {
            triangles: self.triangles.len(),
            vertices: self.vertices.len(),
            volume: self.volume(),
            area: self.area(),
            bounds,
            components,
        }
    }

    /// Checks that the mesh is a closed, oriented 2-manifold enclosing positive volume:
    /// valid indices, finite and pairwise distinct vertex positions, every vertex used, no
    /// degenerate triangle (in `f32`), every directed edge exactly once with its opposite
    /// exactly once (so every edge has exactly two triangles, oriented consistently), the
    /// triangles around every vertex one single disc, and a positive signed volume.
    ///
    /// # Errors
    /// The first [`TopologyError`] found, naming the triangle, edge or vertex.
    pub fn check_closed_manifold(&self) -> Result<(), TopologyError> {
        let nv = self.vertices.len();
        if self.triangles.is_empty() {
            return Err(TopologyError::Empty);
        }
        if let Some(i) = par::position_first(&self.vertices, |p| !p.is_finite()) {
            return Err(TopologyError::NonFiniteVertex { vertex: i as u32 });
        }
        let bad_triangle = |t: &[u32; 3]| {
            t.iter().any(|&k| k as usize >= nv)
                || t[0] == t[1]
                || t[1] == t[2]
                || t[0] == t[2]
                || triangle_area(&self.vertices, *t).1
        };
        if let Some(i) = par::position_first(&self.triangles, bad_triangle) {
            let t = self.triangles[i];
            if let Some(&k) = t.iter().find(|&&k| k as usize >= nv) {
                return Err(TopologyError::IndexOutOfRange {
                    triangle: i,
                    index: k,
                });
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                return Err(TopologyError::RepeatedIndex { triangle: i });
            }
            let (area, _) = triangle_area(&self.vertices, t);
            return Err(TopologyError::Degenerate { triangle: i, area });
        }
        // Fans: around v every triangle (v, a, b) gives a link edge a -> b, in CSR.
        let mut start = vec![0u32; nv + 1];
        for t in &self.triangles {
            for &k in t {
                start[k as usize + 1] += 1;
            }
        }
        if let Some(v) = start[1..].iter().position(|&c| c == 0) {
            return Err(TopologyError::UnusedVertex { vertex: v as u32 });
        }
        for i in 0..nv {
            start[i + 1] += start[i];
        }
        let mut link = vec![(0u32, 0u32); 3 * self.triangles.len()];
        for t in &self.triangles {
            for k in 0..3 {
                let v = t[k] as usize;
                link[start[v] as usize] = (t[(k + 1) % 3], t[(k + 2) % 3]);
                start[v] += 1;
            }
        }
        // `start[v]` is now the end of v's fan: shift back.
        for i in (1..=nv).rev() {
            start[i] = start[i - 1];
        }
        start[0] = 0;
        // Distinct positions (+0.0 and -0.0 are the same point).
        let key = |p: Vec3| p.to_array().map(|x| if x == 0.0 { 0 } else { x.to_bits() });
        let mut order: Vec<([u32; 3], u32)> = self
            .vertices
            .iter()
            .enumerate()
            .map(|(i, &p)| (key(p), i as u32))
            .collect();
        par::sort(&mut order);
        for w in order.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(TopologyError::DuplicatePosition {
                    a: w[0].1,
                    b: w[1].1,
                });
            }
        }
        drop(order);
        // Every directed edge v -> a is a link start `a` of v; it is unique when the starts
        // are, and its opposite a -> v exists when `a` is also a link end. With both, each
        // link vertex has one successor and one predecessor, so the link is a set of
        // cycles, and it must be exactly one.
        let fan = |v: usize| &link[start[v] as usize..start[v + 1] as usize];
        let vertex_ok = |v: usize| {
            let f = fan(v);
            for (i, e) in f.iter().enumerate() {
                if f[i + 1..].iter().any(|x| x.0 == e.0) || !f.iter().any(|x| x.1 == e.0) {
                    return false;
                }
            }
            fan_steps(f) == f.len()
        };
        if !par::all(nv, vertex_ok) {
            // Name the first problem in the order: repeated edge, open edge, fan.
            self.check_edges()?;
            for v in 0..nv {
                let f = fan(v);
                if fan_steps(f) != f.len() {
                    return Err(TopologyError::NonManifoldVertex {
                        vertex: v as u32,
                        triangles: f.len(),
                        fans: count_cycles(f),
                    });
                }
            }
        }
        let volume = self.volume();
        if volume.is_nan() || volume <= 0.0 {
            return Err(TopologyError::NonPositiveVolume { volume });
        }
        Ok(())
    }

    /// Checks that the mesh is the boundary of a solid: a closed, oriented 2-manifold with
    /// positive volume ([`Self::check_closed_manifold`]) whose triangles do not cut through
    /// each other ([`Self::self_intersecting_triangles`], exact). This is what a CAD kernel,
    /// a boolean library or a slicer means by watertight.
    ///
    /// # Errors
    /// The first [`TopologyError`] of [`Self::check_closed_manifold`], else
    /// [`TopologyError::SelfIntersecting`] with the number of self-intersecting triangles.
    pub fn check_valid_solid(&self) -> Result<(), TopologyError> {
        self.check_closed_manifold()?;
        let bad = self.self_intersecting_triangles();
        match bad.first() {
            None => Ok(()),
            Some(&first) => Err(TopologyError::SelfIntersecting {
                triangles: bad.len(),
                first: first as usize,
            }),
        }
    }

    /// The triangles that intersect another triangle improperly (more than in their shared
    /// vertices or edge), or are not proper triangles, in increasing order: see
    /// [`crate::self_intersecting_triangles`].
    #[must_use]
    pub fn self_intersecting_triangles(&self) -> Vec<u32> {
        crate::selfx::self_intersecting_triangles(self)
    }

    /// The edge part of [`Self::check_closed_manifold`], by sorting all directed edges:
    /// slower, used only to name the first bad edge.
    fn check_edges(&self) -> Result<(), TopologyError> {
        let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * self.triangles.len());
        for (i, t) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                edges.push(((u64::from(a) << 32) | u64::from(b), i as u32));
            }
        }
        edges.sort_unstable();
        for w in edges.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(TopologyError::RepeatedEdge {
                    a: (w[0].0 >> 32) as u32,
                    b: w[0].0 as u32,
                    triangle: w[1].1 as usize,
                });
            }
        }
        for &(e, tri) in &edges {
            let rev = e.rotate_right(32);
            if edges.binary_search_by_key(&rev, |x| x.0).is_err() {
                return Err(TopologyError::OpenEdge {
                    a: (e >> 32) as u32,
                    b: e as u32,
                    triangle: tri as usize,
                });
            }
        }
        Ok(())
    }

    /// Removes every connected piece of fewer than `min_triangles` triangles and the
    /// vertices only they used; returns how many pieces were removed.
    ///
    /// On a closed, oriented 2-manifold this keeps the invariant: pieces share no vertex
    /// (each vertex's fan is one disc), so each piece is closed on its own. Removing a small
    /// outward piece deletes a stray blob; removing a small inward one (a bubble inside a
    /// solid) fills the bubble.
    pub fn remove_small_components(&mut self, min_triangles: usize) -> usize {
        self.retain_components(|_| min_triangles)
    }

    /// Removes every connected piece with fewer triangles than `fraction` of the largest
    /// piece's (stray blobs, bubbles inside a solid), as [`Mesh::remove_small_components`]
    /// does; returns how many pieces were removed. `fraction <= 0` removes nothing.
    pub fn remove_pieces_below_fraction(&mut self, fraction: f32) -> usize {
        if fraction.is_nan() || fraction <= 0.0 {
            return 0;
        }
        self.retain_components(|largest| (fraction * largest as f32).ceil() as usize)
    }

    /// Keeps the pieces of at least `min(largest piece's triangles)` triangles.
    fn retain_components(&mut self, min: impl FnOnce(usize) -> usize) -> usize {
        if self.triangles.is_empty() {
            return 0;
        }
        let (roots, size) = self.triangle_components();
        let min_triangles = min(size.iter().copied().max().unwrap_or(0));
        if min_triangles <= 1 {
            return 0;
        }
        let removed = size.iter().filter(|&&n| n > 0 && n < min_triangles).count();
        if removed == 0 {
            return 0;
        }
        let mut keep = roots.iter().map(|&r| size[r as usize] >= min_triangles);
        self.triangles.retain(|_| keep.next().unwrap_or(true));
        self.remove_unused_vertices();
        removed
    }

    /// For each triangle its piece's root vertex, and for each root the piece's triangles.
    pub(crate) fn triangle_components(&self) -> (Vec<u32>, Vec<usize>) {
        let roots = par::triangle_roots(self.vertices.len(), &self.triangles);
        let mut size = vec![0usize; self.vertices.len()];
        for &r in &roots {
            size[r as usize] += 1;
        }
        (roots, size)
    }

    /// Removes vertices that no triangle uses, renumbering the rest in order.
    pub fn remove_unused_vertices(&mut self) {
        let mut map = vec![u32::MAX; self.vertices.len()];
        for t in &self.triangles {
            for &k in t {
                map[k as usize] = 0;
            }
        }
        let mut n = 0u32;
        let mut kept = Vec::with_capacity(self.vertices.len());
        for (i, m) in map.iter_mut().enumerate() {
            if *m == 0 {
                *m = n;
                n += 1;
                kept.push(self.vertices[i]);
            }
        }
        for t in &mut self.triangles {
            *t = t.map(|k| map[k as usize]);
        }
        self.vertices = kept;
    }

    /// Renumbers the vertices in the order the triangles first use them (the unused ones
    /// last, in their order), so that walking the triangles in order touches vertex data in
    /// order (the marcher numbers vertices by grid edge, far from its triangle order: this
    /// halves a simplification's time); returns the old index of each new one. The
    /// triangles keep their order and orientation.
    pub(crate) fn renumber_by_first_use(&mut self) -> Vec<u32> {
        let nv = self.vertices.len();
        let mut new_of = vec![u32::MAX; nv];
        let mut old_of = Vec::with_capacity(nv);
        for t in &mut self.triangles {
            for k in t.iter_mut() {
                let m = &mut new_of[*k as usize];
                if *m == u32::MAX {
                    *m = old_of.len() as u32;
                    old_of.push(*k);
                }
                *k = *m;
            }
        }
        for (old, m) in new_of.iter().enumerate() {
            if *m == u32::MAX {
                old_of.push(old as u32);
            }
        }
        drop(new_of);
        self.vertices = old_of.iter().map(|&o| self.vertices[o as usize]).collect();
        old_of
    }

    /// The triangles as a soup of [`voxoct_core::Triangle`] (e.g. for an STL writer or an
    /// octree).
    #[must_use]
    pub fn triangle_soup(&self) -> Vec<voxoct_core::Triangle> {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                voxoct_core::Triangle::new(a, b, c)
            })
            .collect()
    }
}

/// Steps of the walk around a link from its first edge until it closes (or gives up).
fn fan_steps(fan: &[(u32, u32)]) -> usize {
    let first = fan[0].0;
    let mut cur = first;
    let mut steps = 0;
    while let Some(&(_, next)) = fan.iter().find(|e| e.0 == cur) {
        steps += 1;
        cur = next;
        if cur == first || steps > fan.len() {
            break;
        }
    }
    steps
}

/// Number of cycles of a link given as successor pairs (each `a` at most once).
fn count_cycles(fan: &[(u32, u32)]) -> usize {
    let mut seen = vec![false; fan.len()];
    let mut cycles = 0;
    for i in 0..fan.len() {
        if seen[i] {
            continue;
        }
        cycles += 1;
        let mut j = i;
        while !seen[j] {
            seen[j] = true;
            let next = fan[j].1;
            match fan.iter().position(|e| e.0 == next) {
                Some(k) => j = k,
                None => break,
            }
        }
    }
    cycles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbering_by_first_use_keeps_the_triangles_and_puts_unused_vertices_last() {
        let p = |i: u32| Vec3::splat(i as f32);
        let mut m = Mesh {
            vertices: (0..6).map(p).collect(),
            triangles: vec![[4, 2, 5], [2, 4, 0], [5, 0, 4]],
        };
        assert_eq!(m.renumber_by_first_use(), vec![4, 2, 5, 0, 1, 3]);
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 0, 3], [2, 3, 0]]);
        assert_eq!(m.vertices, vec![p(4), p(2), p(5), p(0), p(1), p(3)]);
        // Then dropping the unused ones keeps the others' numbers.
        m.remove_unused_vertices();
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 0, 3], [2, 3, 0]]);
        assert_eq!(m.vertices, vec![p(4), p(2), p(5), p(0)]);
    }

    /// A closed torus of `n × m` quads (each two triangles) around the z axis.
    fn torus(n: u32, m: u32) -> Mesh {
        let mut vertices = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let (a, b) = (
                    std::f32::consts::TAU * i as f32 / n as f32,
                    std::f32::consts::TAU * j as f32 / m as f32,
                );
                let r = 2.0 + b.cos();
                vertices.push(Vec3::new(r * a.cos(), r * a.sin(), b.sin()));
            }
        }
        let at = |i: u32, j: u32| (i % n) * m + j % m;
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let (p, q, r, s) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                triangles.extend([[p, q, r], [p, r, s]]);
            }
        }
        Mesh {
            vertices,
            triangles,
        }
    }

    #[test]
    fn genus_counts_the_handles_of_a_closed_mesh() {
        let t = torus(6, 4);
        t.check_closed_manifold().unwrap();
        assert_eq!(t.stats().genus(), Some(1));
        let tetra = Mesh {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        };
        tetra.check_closed_manifold().unwrap();
        assert_eq!(tetra.stats().genus(), Some(0));
        // A torus and a tetrahedron: one handle in all.
        let mut both = t.clone();
        let k = both.vertices.len() as u32;
        both.vertices
            .extend(tetra.vertices.iter().map(|&v| v + Vec3::splat(10.0)));
        both.triangles
            .extend(tetra.triangles.iter().map(|t| t.map(|i| i + k)));
        assert_eq!(both.stats().components, 2);
        assert_eq!(both.stats().genus(), Some(1));
        // Counts no closed mesh has: an odd triangle count, or more vertices than a sphere.
        let mut open = tetra.clone();
        open.triangles.pop();
        assert_eq!(open.stats().genus(), None);
        let mut spare = tetra.clone();
        spare.vertices.push(Vec3::ONE);
        assert_eq!(spare.stats().genus(), None);
    }
}
