//! The six-tetrahedron (Kuhn/Freudenthal) split of a pseudo-voxel and its triangle table.
//!
//! Cube corner `i` (0..8) sits at offset `(i & 1, (i >> 1) & 1, (i >> 2) & 1)` in cells. Every
//! cube is split around the main diagonal 0 → 7 into the six tetrahedra
//! `[0, 1 << a, (1 << a) | (1 << b), 7]`, one per axis permutation `(a, b, c)`. The split is
//! the same in every cube, so the tetrahedra of neighbouring cubes meet face to face: together
//! they triangulate space as one simplicial complex. Every tetrahedron edge joins a corner `i`
//! to a corner `j` with `i ⊂ j` as bit sets, i.e. it goes from a cell `p` to `p + dir` for one
//! of the seven positive directions `dir = j ^ i` (1..8); that pair `(p, dir)` is the edge's
//! integer key.
//!
//! Orientation is decided here once, with exact integer arithmetic, and is provably the same
//! for any vertex placement strictly inside the edges: every emitted triangle has its three
//! vertices on three tetrahedron edges that each join an inside to an outside corner, so its
//! plane crosses those edges at interior points and strictly separates the inside corners of
//! the tetrahedron from the outside ones. As the vertices slide along their edges (any
//! `t ∈ (0, 1)`) the triangle can never pass through an inside corner `a`, so the sign of
//! `det(v1 − v0, v2 − v0, v0 − a)` is constant on the connected parameter set; it is fixed
//! positive here at the midpoints, i.e. the normal points away from the inside corners.

use std::sync::LazyLock;

/// One end of a triangle vertex's edge: `(corner, dir)`, the edge from cube corner `corner`
/// to corner `corner | dir`.
pub(crate) type EdgeRef = (u8, u8);

/// Offsets of the eight cube corners.
#[inline]
pub(crate) const fn corner_offset(i: u8) -> [i32; 3] {
    [(i & 1) as i32, ((i >> 1) & 1) as i32, ((i >> 2) & 1) as i32]
}

/// The six tetrahedra of the split, as cube corner indices.
pub(crate) const TETS: [[u8; 4]; 6] = {
    const PERMS: [[u8; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = [[0u8; 4]; 6];
    let mut k = 0;
    while k < 6 {
        let a = 1u8 << PERMS[k][0];
        let b = 1u8 << PERMS[k][1];
        out[k] = [0, a, a | b, 7];
        k += 1;
    }
    out
};

/// An edge of a cube as the marcher needs it: its lower corner's offset and the row base of
/// its direction in a brick's edge masks (`(dir - 1) · 64`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct CubeEdge {
    pub ox: u32,
    pub oy: u32,
    pub oz: u32,
    pub row: usize,
}

/// Triangles of every cube case (bit `i` set = corner `i` inside), flattened.
pub(crate) struct CaseTable {
    /// `start[case]..start[case + 1]` indexes `local`.
    pub start: [u16; 257],
    /// `edge_start[case]..edge_start[case + 1]` indexes `edges`.
    pub edge_start: [u16; 257],
    /// The distinct edges that the case's triangles use.
    pub edges: Vec<CubeEdge>,
    /// The case's triangles as indices into its slice of `edges`.
    pub local: Vec<[u8; 3]>,
}

pub(crate) static CASES: LazyLock<CaseTable> = LazyLock::new(build);

fn edge(u: u8, v: u8) -> EdgeRef {
    let (lo, hi) = if u & v == u { (u, v) } else { (v, u) };
    debug_assert_eq!(lo & hi, lo, "not a Kuhn edge");
    (lo, lo ^ hi)
}

/// Twice the midpoint of an edge, integer.
fn mid2(e: EdgeRef) -> [i64; 3] {
    let a = corner_offset(e.0);
    let b = corner_offset(e.0 | e.1);
    [0, 1, 2].map(|k| i64::from(a[k] + b[k]))
}

fn sub(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn det(a: [i64; 3], b: [i64; 3], c: [i64; 3]) -> i64 {
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// Orders `tri` so that its normal points away from the inside corner `inside`.
pub(crate) fn orient(tri: [EdgeRef; 3], inside: u8) -> [EdgeRef; 3] {
    let [p0, p1, p2] = tri.map(mid2);
    let a = corner_offset(inside).map(|x| 2 * i64::from(x));
    let d = det(sub(p1, p0), sub(p2, p0), sub(p0, a));
    assert!(d != 0, "triangle plane through an inside corner");
    if d > 0 { tri } else { [tri[0], tri[2], tri[1]] }
}

/// The triangles of one tetrahedron `t` for the inside set `inside` (bit per cube corner).
pub(crate) fn tet_triangles(t: [u8; 4], inside: u8, out: &mut Vec<[EdgeRef; 3]>) {
    let (ins, outs): (Vec<u8>, Vec<u8>) = t.iter().partition(|&&c| inside >> c & 1 == 1);
    match (ins.as_slice(), outs.as_slice()) {
        (&[a], &[b, c, d]) => out.push(orient([edge(a, b), edge(a, c), edge(a, d)], a)),
        (&[a, b, c], &[d]) => out.push(orient([edge(d, a), edge(d, b), edge(d, c)], a)),
        (&[a, b], &[c, d]) => {
            // The quad ac, ad, bd, bc (cyclic), split along ac–bd.
            out.push(orient([edge(a, c), edge(a, d), edge(b, d)], a));
            out.push(orient([edge(a, c), edge(b, d), edge(b, c)], a));
        }
        _ => {}
    }
}

fn build() -> CaseTable {
    let mut start = [0u16; 257];
    let mut edge_start = [0u16; 257];
    let mut tris = Vec::new();
    let mut edges: Vec<EdgeRef> = Vec::new();
    let mut local = Vec::new();
    for case in 0..256usize {
        start[case] = tris.len() as u16;
        edge_start[case] = edges.len() as u16;
        let first_edge = edges.len();
        for t in TETS {
            let before = tris.len();
            tet_triangles(t, case as u8, &mut tris);
            for tri in &tris[before..] {
                local.push(tri.map(|e| {
                    let pos = edges[first_edge..].iter().position(|&x| x == e);
                    let slot = pos.unwrap_or_else(|| {
                        edges.push(e);
                        edges.len() - 1 - first_edge
                    });
                    slot as u8
                }));
            }
        }
    }
    start[256] = tris.len() as u16;
    edge_start[256] = edges.len() as u16;
    let edges = edges
        .into_iter()
        .map(|(c, d)| {
            let [ox, oy, oz] = corner_offset(c).map(|v| v as u32);
            CubeEdge {
                ox,
                oy,
                oz,
                row: (usize::from(d) - 1) * 64,
            }
        })
        .collect();
    CaseTable {
        start,
        edge_start,
        edges,
        local,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tets_are_positive_and_fill_the_cube() {
        let mut vol = 0;
        for t in TETS {
            let p = t.map(|c| corner_offset(c).map(i64::from));
            let d = det(sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0]));
            assert_eq!(d.abs(), 1, "each tetrahedron is 1/6 of the cube");
            vol += d.abs();
        }
        assert_eq!(vol, 6);
    }

    #[test]
    fn every_case_orients_away_from_every_inside_corner_of_its_tet() {
        for case in 0..=255u8 {
            for t in TETS {
                let mut v = Vec::new();
                tet_triangles(t, case, &mut v);
                for tri in v {
                    let [p0, p1, p2] = tri.map(mid2);
                    for &c in &t {
                        let a = corner_offset(c).map(|x| 2 * i64::from(x));
                        let d = det(sub(p1, p0), sub(p2, p0), sub(p0, a));
                        if case >> c & 1 == 1 {
                            assert!(d > 0, "case {case} tet {t:?}");
                        } else {
                            assert!(d < 0, "case {case} tet {t:?}");
                        }
                    }
                }
            }
        }
        assert_eq!(CASES.start[0], CASES.start[1]);
        assert_eq!(CASES.start[255], CASES.start[256]);
    }
}
