//! Quadric-error edge collapse (Garland–Heckbert) that keeps the mesh a closed, oriented,
//! embedded 2-manifold.
//!
//! # Error measure
//! Every original triangle contributes its plane, weighted by a third of its area, to each of
//! its three vertices' quadrics; a collapse adds the two quadrics. The *error* of a vertex at
//! `p` is `sqrt(Q(p) / W)`: the area-weighted root-mean-square distance, in metres, from `p`
//! to the planes of the original triangles that were merged into it (`W` is their weight).
//! A collapse is made only while that error is at most [`Simplify::max_error`]. The new
//! vertex goes to the quadric's minimum, regularised towards the edge's midpoint along the
//! directions the quadric leaves free (flat or cylindrical patches), so vertices never
//! slide along the surface.
//!
//! Because the bound is a mean over the merged patch (and a sliver's plane weighs little in
//! it), each collapse must also put its vertex within `max_error` of the triangles around the
//! edge as they are. Still, a vertex may sit further than `max_error` from the original
//! surface where the patch is curved or cornered, or after many collapses; the tests
//! check every vertex within three times the bound (and on a 30 mm sphere at 1 mm leaves,
//! `for_leaf` keeps the mean vertex 0.22 leaf, the worst 0.37 leaf from the sphere).
//!
//! # Guarantees (for a closed, oriented 2-manifold input, as [`crate::mesh_cells`] gives)
//! - **Link condition**: an edge `u w` collapses only if `u` and `w` have exactly two common
//!   neighbours (the apexes of its two triangles) and are not both of valence 3 (a
//!   tetrahedron), so the result stays a closed 2-manifold with the same pieces and genus.
//!   [`Mesh::check_closed_manifold`] is run on the result as a safety net: a failure (never
//!   seen) leaves the input unchanged.
//! - **No flips, no needles**: every triangle changed by a collapse keeps its normal within
//!   [`MAX_NORMAL_TURN_DEG`] of its direction before; within 60° of the mean normal of the
//!   fan it replaces; within 60° of the summed original normals of the clusters at its
//!   corners, and within 90° of each corner's (so turns cannot add up over many collapses,
//!   nor a triangle span a thin part's fold onto the sheet facing the other way); and its
//!   shape quality
//!   (`4√3·area / Σ edge²`, 1 for an equilateral) does not fall below [`MIN_QUALITY`] unless
//!   it was already that low, and never below [`MIN_QUALITY_ABSOLUTE`].
//! - **No self-intersections introduced**: each collapse tests the new fan exactly against
//!   the other triangles around its outer vertices (the local folds). Then one exact test
//!   over all pairs of nearby triangles (a uniform grid; `f64` orientation tests) looks for
//!   intersecting pairs with a changed triangle, which only distant sheets (thin walls) or
//!   a crumpled input can give. If there are any, the original vertices merged into those
//!   triangles and their neighbours are frozen and the round is made again without them:
//!   the first phase's collapses (see *Speed*) are replayed from the input, in their order
//!   and pass by pass, without those that touch a frozen vertex and with every check made
//!   again (no candidate is evaluated or sorted again), in the regions that hold a newly
//!   frozen vertex only (the others' results do not depend on anything outside them and
//!   are kept); the other phases run again, except that a second-phase region whose copy
//!   is the same as in the round before (by a 64-bit fingerprint) takes its result from
//!   there. After [`MAX_RETRIES`] rounds the input is left
//!   unchanged. Intersections the input already had are left as they are (their triangles
//!   do not count as changed). A later round's test is made only around the triangles that
//!   differ from the round before's or that its test found (the `recheck` module): it
//!   finds exactly what the test of the whole mesh would.
//!
//! # Speed
//! Collapses are made in passes (as meshoptimizer does): each pass evaluates the collapse
//! cost of every edge whose neighbourhood changed, orders the edges by cost with a counting
//! sort on the float's exponent bits (coarse classes keep memory access local), and
//! collapses greedily in that order, at most one collapse per vertex per pass;
//! vertex→triangle adjacency is a flat CSR rebuilt per pass. No hash map, no heap.
//!
//! A round has three phases. First the mesh is cut into *regions*, the cubes of a coarse
//! grid (about 8192 triangles each, each triangle in the cube of its centroid), and each
//! region is simplified on its own copy, which fits a core's cache, the regions in
//! parallel with the `parallel` feature. A region moves only vertices whose two rings of
//! triangles are all its own: then no region changes anything another one's checks read
//! (see the `regions` module), so the result does not depend on the threads, and the
//! regions' order does not matter. Then the same with the cubes shifted by half an edge,
//! whose regions hold the first phase's seams, starting from the vertices the first phase
//! could not move. Last, one run over the whole mesh for what is left. A triangle target
//! ([`Simplify::target_triangles`]) is met in cost order over the whole mesh, as one
//! region. Figures: see BENCHMARKS.md (`cargo bench -p voxoct-mesh`).
//!
//! # Memory
//! The rounds work on the input itself, renumbered in place (it is numbered back when
//! left unchanged), beside one working copy. The quadrics (88 bytes a vertex, the largest
//! arrays) are never held for the whole input: each first-phase region computes its
//! vertices' from its own copy, and only the vertices that phase leaves (a fraction of
//! the input's) get one in the shared state for the later phases. The working copy's
//! triangles are the regions' copies: a phase's surviving triangles are put together from
//! its regions' results at its end, and a result kept for a later round is shared, not
//! copied, and holds no growth slack. The first phase's plan, kept for the later rounds,
//! holds no region's triangles: a region's are numbered again from the input's when it
//! is copied.

use crate::mesh::{Mesh, TopologyError};

mod collapse;
mod quadric;
mod recheck;
mod regions;

use quadric::*;
use regions::REGION_TRIANGLES;

/// Largest turn of a surviving triangle's normal in one collapse, degrees.
pub const MAX_NORMAL_TURN_DEG: f32 = 75.0;
/// Triangle quality (`4√3·area / Σ edge²`) below which a collapse may not push a triangle,
/// unless the triangle was already worse.
pub const MIN_QUALITY: f32 = 0.1;
/// Quality below which no collapse may ever push a triangle (far above the degeneracy
/// threshold of [`Mesh::check_closed_manifold`]).
pub const MIN_QUALITY_ABSOLUTE: f32 = 1.0e-3;
/// Rounds of freezing and replaying when the global self-intersection test fails.
pub const MAX_RETRIES: u32 = 4;

/// Options of [`simplify`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Simplify {
    /// Largest error of a collapse, metres: the area-weighted root-mean-square distance from
    /// the new vertex to the planes of the original triangles merged into it. 0 collapses
    /// only edges of flat patches.
    pub max_error: f32,
    /// Stop once the mesh has at most this many triangles (`None`: as few as `max_error`
    /// allows). The error bound holds either way.
    pub target_triangles: Option<usize>,
}

impl Simplify {
    /// Default error bound as a fraction of the leaf edge.
    ///
    /// A quarter of a leaf: the marked-cell surface cannot place detail more finely than
    /// about half a leaf, and a Kinect v1's depth noise (≈ 1.5 mm at 0.7 m) is larger
    /// than a 1 mm leaf, so a deviation of a quarter leaf (RMS over the merged patch) removes
    /// no detail the data holds.
    pub const LEAF_FRACTION: f32 = 0.25;

    /// The default options for meshes of leaves of edge `leaf` metres:
    /// `max_error = LEAF_FRACTION · leaf`, no triangle target.
    #[must_use]
    pub fn for_leaf(leaf: f32) -> Self {
        Self {
            max_error: Self::LEAF_FRACTION * leaf,
            target_triangles: None,
        }
    }
}

/// What [`simplify`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimplifyStats {
    /// Triangles before.
    pub triangles_before: usize,
    /// Triangles after.
    pub triangles_after: usize,
    /// Edge collapses made (in the final round).
    pub collapses: usize,
    /// Collapse passes (in the final round).
    pub passes: usize,
    /// Rounds replayed because the global self-intersection test found new intersections.
    pub retries: u32,
    /// Original vertices frozen by those rounds.
    pub frozen_vertices: usize,
    /// Intersecting triangle pairs that involve a changed triangle, found by the last
    /// global test (0 unless the input was left unchanged after [`MAX_RETRIES`] rounds).
    pub new_intersections: usize,
    /// Why the mesh was left unchanged: an index out of range, or the result is not a closed
    /// manifold (the input was not one; for a closed input this never happens, it is a
    /// safety net). `None` when simplified, and also when left unchanged because of invalid
    /// options or [`MAX_RETRIES`].
    pub skipped: Option<TopologyError>,
}

/// Simplifies a closed, oriented 2-manifold mesh in place by quadric-error edge collapse
/// (see the module docs for the error measure and the guarantees).
///
/// A mesh whose result fails [`Mesh::check_closed_manifold`] (as one that is not a closed
/// manifold to begin with may) is left unchanged, the error in [`SimplifyStats::skipped`];
/// so is any mesh when `max_error` is negative or not finite.
/// Otherwise the vertices are renumbered in the order the triangles first use them (also
/// when no collapse could be made); triangles keep their relative order.
pub fn simplify(mesh: &mut Mesh, opts: &Simplify) -> SimplifyStats {
    simplify_in_regions(mesh, opts, REGION_TRIANGLES)
}

/// [`simplify`] with regions of about `per_region` triangles (0: the whole mesh as one).
pub(crate) fn simplify_in_regions(
    mesh: &mut Mesh,
    opts: &Simplify,
    per_region: usize,
) -> SimplifyStats {
    let mut stats = SimplifyStats {
        triangles_before: mesh.triangles.len(),
        triangles_after: mesh.triangles.len(),
        ..SimplifyStats::default()
    };
    if !(opts.max_error.is_finite() && opts.max_error >= 0.0) {
        return stats;
    }
    // Indices in range are all the collapses need to run; whether the input is a closed
    // manifold is decided by the check of the result, which leaves the input unchanged when
    // it fails (the full check of a large input would cost a sixth of the time).
    let nv = mesh.vertices.len();
    if let Some((i, &k)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find_map(|(i, t)| t.iter().find(|&&k| k as usize >= nv).map(|k| (i, k)))
    {
        stats.skipped = Some(TopologyError::IndexOutOfRange {
            triangle: i,
            index: k,
        });
        return stats;
    }
    if opts
        .target_triangles
        .is_some_and(|t| t >= mesh.triangles.len())
    {
        return stats;
    }
    // The rounds work on the input itself, renumbered (no copy of it is kept); it is
    // numbered back when it is left unchanged.
    let order = mesh.renumber_by_first_use();
    // A triangle target is met in the order of cost over the whole mesh: one region.
    let per_region = if opts.target_triangles.is_some() {
        0
    } else {
        per_region
    };
    match run_rounds(mesh, opts, per_region, &mut stats) {
        Some(out) => {
            *mesh = out;
            stats.triangles_after = mesh.triangles.len();
        }
        None => restore_numbering(mesh, &order),
    }
    stats
}

/// The rounds of collapses on `original` (renumbered by first use) until one introduces
/// no self-intersection: its result, a closed manifold, or `None` when the input is to be
/// left unchanged (after [`MAX_RETRIES`] rounds, or when the result fails the check; the
/// error is then in `stats.skipped`).
fn run_rounds(
    original: &Mesh,
    opts: &Simplify,
    per_region: usize,
    stats: &mut SimplifyStats,
) -> Option<Mesh> {
    let nv = original.vertices.len();
    let mut frozen = vec![false; nv];
    let mut rounds = regions::Rounds::new(original, opts, per_region);
    // The latest round's result and every self-intersecting triangle of it.
    let mut last: Option<recheck::Previous> = None;
    loop {
        let regions::Round {
            pos,
            tris,
            parent,
            moved,
            passes,
            collapses,
        } = rounds.next(&frozen);
        let candidate = Mesh {
            vertices: pos,
            triangles: tris,
        };
        let all = match &last {
            _ if collapses == 0 => Vec::new(),
            None => crate::selfx::self_intersecting_triangles(&candidate),
            Some(prev) => recheck::intersecting_since(&candidate, prev),
        };
        let bad = new_intersections(&candidate, &moved, &all);
        stats.new_intersections = bad.len();
        if bad.is_empty() {
            let mut candidate = candidate;
            candidate.remove_unused_vertices();
            // The collapses keep the mesh closed by construction; this check (a few per cent
            // of the time) makes sure that no rounding breaks the promise.
            if let Err(e) = candidate.check_closed_manifold() {
                stats.skipped = Some(e);
                return None;
            }
            stats.passes = passes;
            stats.collapses = collapses;
            return Some(candidate);
        }
        if stats.retries == MAX_RETRIES {
            return None;
        }
        stats.retries += 1;
        // Freeze every original vertex merged into a vertex of an intersecting triangle or
        // into one of their neighbours.
        let mut hit = vec![false; nv];
        for &t in &bad {
            for k in candidate.triangles[t as usize] {
                hit[k as usize] = true;
            }
        }
        let mut near = hit.clone();
        for t in &candidate.triangles {
            if t.iter().any(|&k| hit[k as usize]) {
                for &k in t {
                    near[k as usize] = true;
                }
            }
        }
        let hit = near;
        for (v, f) in frozen.iter_mut().enumerate() {
            let mut r = v;
            while parent[r] as usize != r {
                r = parent[r] as usize;
            }
            if hit[r] && !*f {
                *f = true;
                stats.frozen_vertices += 1;
            }
        }
        last = Some(recheck::Previous::new(candidate, all));
    }
}

/// A round's collapses `(u, w)` in order, and where each pass's collapses end.
type RoundLog = (Vec<(u32, u32)>, Vec<usize>);

/// Undoes [`Mesh::renumber_by_first_use`], given what it returned.
fn restore_numbering(mesh: &mut Mesh, old_of: &[u32]) {
    let mut vertices = mesh.vertices.clone();
    for (new, &old) in old_of.iter().enumerate() {
        vertices[old as usize] = mesh.vertices[new];
    }
    mesh.vertices = vertices;
    for t in &mut mesh.triangles {
        *t = t.map(|k| old_of[k as usize]);
    }
}

/// `mesh` renumbered by first use, as a copy.
#[cfg(test)]
fn renumbered_by_first_use(mesh: &Mesh) -> Mesh {
    let mut out = mesh.clone();
    out.renumber_by_first_use();
    out
}

/// The changed triangles (with a moved vertex) among `all`, the triangles that cut through
/// another one by the exact check ([`crate::selfx`]), in increasing order. Every new
/// intersection involves a changed triangle; intersections between unchanged ones were in
/// the input.
fn new_intersections(mesh: &Mesh, moved: &[bool], all: &[u32]) -> Vec<u32> {
    let changed = |t: u32| {
        mesh.triangles[t as usize]
            .iter()
            .any(|&k| moved[k as usize])
    };
    all.iter().copied().filter(|&t| changed(t)).collect()
}

#[cfg(test)]
mod tests {
    use super::collapse::Collapser;
    use super::*;
    use crate::{Cell, GridSpec, MeshOptions};
    use voxoct_core::glam::{IVec3, Vec3};

    /// A smoothed 1 mm mesh of a ball of radius 6 cells, renumbered by first use.
    fn ball() -> Mesh {
        ball_of(16, 6.0)
    }

    /// A smoothed 1 mm mesh of a ball of `radius` cells centred in a grid of `resolution`
    /// cells, renumbered by first use.
    pub(super) fn ball_of(resolution: i32, radius: f32) -> Mesh {
        let grid = GridSpec {
            origin: Vec3::ZERO,
            cell: 0.001,
            resolution: resolution as u32,
        };
        let c = IVec3::splat(resolution / 2);
        let mut cells = Vec::new();
        for z in 0..resolution {
            for y in 0..resolution {
                for x in 0..resolution {
                    let p = IVec3::new(x, y, z);
                    let d = (p - c).as_vec3().length() - radius;
                    if d.abs() < 1.0 {
                        cells.push(Cell {
                            coord: p.as_uvec3(),
                            hits: 1,
                            sdf_sum: d * 0.001,
                        });
                    }
                }
            }
        }
        let mesh = crate::mesh_cells(&cells, &grid, &MeshOptions::smooth()).unwrap();
        renumbered_by_first_use(&mesh)
    }

    /// One round on `mesh`: run, or the replay of `log`.
    fn round(mesh: &Mesh, frozen: &[bool], log: Option<&RoundLog>) -> Collapser {
        let mut work = Collapser::new(
            mesh.clone(),
            initial_quadrics(mesh),
            frozen.to_vec(),
            &Simplify::for_leaf(0.001),
            origin(mesh),
        );
        match log {
            None => work.run(),
            Some((log, ends)) => work.replay(log, ends),
        }
        work
    }

    /// The candidates taken from the active vertices' fans are those of the look at every
    /// triangle, in the same order, for any set of active and frozen vertices.
    #[test]
    fn candidates_from_the_fans_are_those_of_every_triangle() {
        let mesh = ball();
        let nv = mesh.vertices.len();
        let frozen: Vec<bool> = (0..nv).map(|v| v % 7 == 3).collect();
        let mut work = Collapser::new(
            mesh.clone(),
            initial_quadrics(&mesh),
            frozen,
            &Simplify::for_leaf(0.001),
            origin(&mesh),
        );
        work.csr.rebuild(nv, &work.tris, |_| true, true);
        let bits = |c: &[collapse::Candidate]| -> Vec<(u32, u32, u32, [u32; 3])> {
            c.iter()
                .map(|c| (c.key, c.u, c.w, c.p.to_array().map(f32::to_bits)))
                .collect()
        };
        let (mut all, mut fans, mut scratch) = (Vec::new(), Vec::new(), Vec::new());
        for every in [1, 2, 5, 40, nv + 1] {
            work.active = (0..nv).map(|v| v % every == 1 % every).collect();
            work.candidates_with(&mut all, &mut scratch, 0);
            work.candidates_with(&mut fans, &mut scratch, usize::MAX);
            assert!(!all.is_empty() || every > nv);
            assert_eq!(bits(&all), bits(&fans), "every {every}th vertex active");
        }
    }

    #[test]
    fn a_replay_without_frozen_vertices_repeats_the_round_and_spares_frozen_ones() {
        let mesh = ball();
        let nv = mesh.vertices.len();
        let none = vec![false; nv];
        let first = round(&mesh, &none, None);
        assert!(first.collapses > nv / 4, "{} collapses", first.collapses);
        let log = (first.log.clone(), first.pass_ends.clone());
        let again = round(&mesh, &none, Some(&log));
        assert_eq!(again.tris, first.tris);
        assert_eq!(again.pos, first.pos);
        assert_eq!(again.log, first.log);
        // Freeze every third vertex: none of them moves or merges, the rest still collapse,
        // and the result is a closed manifold.
        let frozen: Vec<bool> = (0..nv).map(|v| v % 3 == 0).collect();
        let part = round(&mesh, &frozen, Some(&log));
        assert!(part.collapses > 0 && part.collapses < first.collapses);
        for v in (0..nv).filter(|&v| frozen[v]) {
            assert_eq!(part.parent[v] as usize, v);
            assert_eq!(part.pos[v], mesh.vertices[v]);
        }
        let mut out = Mesh {
            vertices: part.pos,
            triangles: part.tris,
        };
        out.remove_unused_vertices();
        out.check_closed_manifold().unwrap();
    }

    /// A closed mesh of cells within `r` of three centres (two of them close, so thin walls
    /// and narrow gaps), smoothed.
    fn lumps(r: f32) -> Mesh {
        let grid = GridSpec {
            origin: Vec3::ZERO,
            cell: 0.001,
            resolution: 64,
        };
        let centres = [
            Vec3::new(20.0, 20.0, 20.0),
            Vec3::new(20.0 + 2.0 * r + 1.5, 21.0, 20.0),
            Vec3::new(40.0, 40.0, 35.0),
        ];
        let mut cells = Vec::new();
        for z in 0..64 {
            for y in 0..64 {
                for x in 0..64 {
                    let p = IVec3::new(x, y, z).as_vec3();
                    let d = centres
                        .iter()
                        .map(|c| (p - *c).length() - r)
                        .fold(f32::INFINITY, f32::min);
                    if d.abs() < 1.0 {
                        cells.push(Cell {
                            coord: p.as_uvec3(),
                            hits: 1,
                            sdf_sum: d * 0.001,
                        });
                    }
                }
            }
        }
        crate::mesh_cells(&cells, &grid, &MeshOptions::smooth()).unwrap()
    }

    /// Every guarantee of a simplification of `mesh` into `out`: closed and valid, fewer
    /// triangles, the same pieces and genus, every vertex near the input surface.
    fn check(mesh: &Mesh, out: &Mesh, stats: &SimplifyStats, opts: &Simplify) {
        assert_eq!(stats.skipped, None);
        out.check_closed_manifold().unwrap();
        assert_eq!(crate::self_intersecting_triangles(out), Vec::<u32>::new());
        assert!(out.triangles.len() * 3 < mesh.triangles.len());
        let (a, b) = (mesh.stats(), out.stats());
        assert_eq!(a.components, b.components);
        assert_eq!(
            mesh.vertices.len() as i64 - mesh.triangles.len() as i64 / 2,
            out.vertices.len() as i64 - out.triangles.len() as i64 / 2
        );
        // Every output vertex lies within three bounds of some input vertex's plane patch:
        // checked coarsely against the nearest input vertex (input edges are under a cell).
        for p in &out.vertices {
            let d = mesh
                .vertices
                .iter()
                .map(|q| (*p - *q).length())
                .fold(f32::INFINITY, f32::min);
            assert!(d < 0.001 + 3.0 * opts.max_error, "{d}");
        }
    }

    #[test]
    fn regions_keep_every_guarantee_and_reach_the_single_regions_size() {
        let mesh = lumps(9.0);
        let opts = Simplify::for_leaf(0.001);
        let mut whole = mesh.clone();
        let one = simplify_in_regions(&mut whole, &opts, 0);
        check(&mesh, &whole, &one, &opts);
        for per_region in [256, 1024, 4096] {
            let mut out = mesh.clone();
            let stats = simplify_in_regions(&mut out, &opts, per_region);
            check(&mesh, &out, &stats, &opts);
            // The seams are simplified too: not 5 % more triangles than with one region.
            let (n, m) = (out.triangles.len() as f64, whole.triangles.len() as f64);
            assert!(n < 1.05 * m, "{per_region}: {n} vs {m}");
        }
    }

    #[cfg(feature = "parallel")]
    #[test]
    fn regions_give_the_same_mesh_on_any_number_of_threads() {
        let mesh = lumps(7.0);
        let opts = Simplify::for_leaf(0.001);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut out = mesh.clone();
            let stats = pool.install(|| simplify_in_regions(&mut out, &opts, 512));
            (out, stats)
        };
        let (a, sa) = run(1);
        let (b, sb) = run(3);
        assert!(sa.collapses > 0);
        assert_eq!(sa, sb);
        assert_eq!(a, b);
    }

    #[test]
    fn a_later_round_replays_the_first_without_the_frozen_vertices() {
        let mesh = renumbered_by_first_use(&lumps(7.0));
        let nv = mesh.vertices.len();
        let opts = Simplify::for_leaf(0.001);
        let mut rounds = regions::Rounds::new(&mesh, &opts, 512);
        let none = vec![false; nv];
        let first = rounds.next(&none);
        // Nothing newly frozen: the same result.
        let again = rounds.next(&none);
        assert_eq!((&again.pos, &again.tris), (&first.pos, &first.tris));
        // Freeze every seventh vertex: they stay where they are, the result is closed, and it
        // is what a fresh sequence of rounds gives.
        let frozen: Vec<bool> = (0..nv).map(|v| v % 7 == 0).collect();
        let part = rounds.next(&frozen);
        for v in (0..nv).filter(|&v| frozen[v]) {
            assert_eq!(part.parent[v] as usize, v);
            assert_eq!(part.pos[v], mesh.vertices[v]);
        }
        let mut fresh = regions::Rounds::new(&mesh, &opts, 512);
        fresh.next(&none);
        let want = fresh.next(&frozen);
        assert_eq!((&part.pos, &part.tris), (&want.pos, &want.tris));
        let mut out = Mesh {
            vertices: part.pos,
            triangles: part.tris,
        };
        out.remove_unused_vertices();
        out.check_closed_manifold().unwrap();
    }
}
