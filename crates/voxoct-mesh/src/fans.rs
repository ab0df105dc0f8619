//! Vertex → triangle adjacency in compressed rows, shared by the self-intersection test
//! and simplification.

use std::ops::Range;

/// The triangles around every vertex (each fan in triangle order), in compressed rows, and
/// optionally for each corner the corner's two other vertices (next, previous), so that a
/// vertex's fan is read from one place.
#[derive(Debug, Default)]
pub(crate) struct VertexFans {
    /// `start[v]..start[v + 1]` is vertex `v`'s row.
    pub(crate) start: Vec<u32>,
    /// The triangles of each row.
    pub(crate) tris: Vec<u32>,
    /// The (next, previous) vertices of each row's corner; empty unless asked for.
    pub(crate) pairs: Vec<[u32; 2]>,
}

/// Triangles from which [`VertexFans::rebuild`] fills rows in parallel.
const PARALLEL_TRIANGLES: usize = 1 << 15;

/// Parts of [`VertexFans::rebuild`] at most (each reads every triangle).
const MAX_PARTS: usize = 4;

/// `items` split into consecutive slices of the given sizes (summing to at most its length).
fn split_by<T>(mut items: &mut [T], sizes: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut out = Vec::new();
    for n in sizes {
        let (a, b) = std::mem::take(&mut items).split_at_mut(n);
        out.push(a);
        items = b;
    }
    out
}

impl VertexFans {
    /// The fans of `nv` vertices over the triangles that `keep` accepts (whose indices
    /// must then be below `nv`), with the corners' vertex pairs when `corners`.
    pub(crate) fn new(
        nv: usize,
        triangles: &[[u32; 3]],
        keep: impl Fn([u32; 3]) -> bool + Sync,
        corners: bool,
    ) -> Self {
        let mut s = Self::default();
        s.rebuild(nv, triangles, keep, corners);
        s
    }

    /// As [`VertexFans::new`], reusing the buffers. A large mesh's rows are filled in
    /// parallel, a range of vertices per task (each task reads every triangle in order and
    /// fills the rows of its own vertices): the same rows as one pass.
    pub(crate) fn rebuild(
        &mut self,
        nv: usize,
        triangles: &[[u32; 3]],
        keep: impl Fn([u32; 3]) -> bool + Sync,
        corners: bool,
    ) {
        let parts = if triangles.len() >= PARALLEL_TRIANGLES {
            crate::par::threads().clamp(1, MAX_PARTS)
        } else {
            1
        };
        self.rebuild_in_parts(nv, triangles, keep, corners, parts);
    }

    /// [`VertexFans::rebuild`] with the vertices split into `parts` ranges (at least one).
    fn rebuild_in_parts(
        &mut self,
        nv: usize,
        triangles: &[[u32; 3]],
        keep: impl Fn([u32; 3]) -> bool + Sync,
        corners: bool,
        parts: usize,
    ) {
        let parts = parts.max(1);
        // Part `p` has the vertices `bounds[p]..bounds[p + 1]`.
        let bounds: Vec<usize> = (0..=parts).map(|p| nv * p / parts).collect();
        let ranges = || bounds.windows(2).map(|w| w[0]..w[1]);
        self.start.clear();
        self.start.resize(nv + 1, 0);
        // Counts: vertex v's in start[v + 1].
        let count_part = |_: usize, count: &mut [u32], r: Range<usize>| {
            for t in triangles.iter().filter(|t| keep(**t)) {
                for &k in t {
                    if r.contains(&(k as usize)) {
                        count[k as usize - r.start] += 1;
                    }
                }
            }
        };
        if parts == 1 {
            count_part(0, &mut self.start[1..], 0..nv);
        } else {
            let counts = split_by(&mut self.start[1..], ranges().map(|r| r.len()));
            crate::par::for_each_zip(counts, ranges(), count_part);
        }
        for i in 0..nv {
            self.start[i + 1] += self.start[i];
        }
        let len = self.start[nv] as usize;
        self.tris.clear();
        self.tris.resize(len, 0);
        self.pairs.clear();
        if corners {
            self.pairs.resize(len, [0; 2]);
        }
        // Fill using start[v] as a cursor, then shift back. Part p's rows are the entries
        // from start[bounds[p]] (its first vertex's row) on.
        let first: Vec<usize> = bounds.iter().map(|&b| self.start[b] as usize).collect();
        let fill_part = |p: usize,
                         (cursor, tris, pairs): (&mut [u32], &mut [u32], &mut [[u32; 2]]),
                         r: Range<usize>| {
            let base = first[p];
            for (i, t) in triangles.iter().enumerate() {
                if !keep(*t) {
                    continue;
                }
                for j in 0..3 {
                    let k = t[j] as usize;
                    if !r.contains(&k) {
                        continue;
                    }
                    let c = &mut cursor[k - r.start];
                    tris[*c as usize - base] = i as u32;
                    if corners {
                        pairs[*c as usize - base] = [t[(j + 1) % 3], t[(j + 2) % 3]];
                    }
                    *c += 1;
                }
            }
        };
        if parts == 1 {
            fill_part(
                0,
                (&mut self.start[..nv], &mut self.tris, &mut self.pairs),
                0..nv,
            );
        } else {
            let sizes = || first.windows(2).map(|w| w[1] - w[0]);
            let cursors = split_by(&mut self.start[..nv], ranges().map(|r| r.len()));
            let tris = split_by(&mut self.tris, sizes());
            let pairs = if corners {
                split_by(&mut self.pairs, sizes())
            } else {
                (0..parts).map(|_| &mut [][..]).collect()
            };
            let work = cursors
                .into_iter()
                .zip(tris)
                .zip(pairs)
                .map(|((c, t), p)| (c, t, p));
            crate::par::for_each_zip(work, ranges(), fill_part);
        }
        for i in (1..=nv).rev() {
            self.start[i] = self.start[i - 1];
        }
        self.start[0] = 0;
    }

    /// The row of vertex `v`.
    #[inline]
    pub(crate) fn range(&self, v: u32) -> Range<usize> {
        self.start[v as usize] as usize..self.start[v as usize + 1] as usize
    }

    /// The triangles around `v`, in triangle order.
    #[inline]
    pub(crate) fn fan(&self, v: u32) -> &[u32] {
        &self.tris[self.range(v)]
    }

    /// The (next, previous) vertices of `v`'s corners (built with `corners`).
    #[inline]
    pub(crate) fn corners(&self, v: u32) -> &[[u32; 2]] {
        &self.pairs[self.range(v)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fans_list_each_vertexs_triangles_in_order_and_skip_rejected_ones() {
        let tris = [[0, 1, 2], [0, 2, 3], [3, 3, 1], [1, 0, 3]];
        let all = VertexFans::new(4, &tris, |_| true, true);
        assert_eq!(all.fan(0), [0, 1, 3]);
        assert_eq!(all.fan(3), [1, 2, 2, 3]);
        assert_eq!(all.corners(0), [[1, 2], [2, 3], [3, 1]]);
        let valid = VertexFans::new(4, &tris, |t| t[0] != t[1], false);
        assert_eq!(valid.fan(3), [1, 3]);
        assert_eq!(valid.fan(1), [0, 3]);
        assert!(valid.pairs.is_empty());
    }

    proptest::proptest! {
        /// Rows filled by vertex ranges in parallel are those of one pass, with and without
        /// corners and a filter, whatever the number of parts (more than vertices too), and
        /// a rebuild after a larger mesh leaves nothing of it.
        #[test]
        fn rows_filled_in_parts_are_those_of_one_pass(
            nv in 1usize..40,
            raw in proptest::collection::vec(proptest::array::uniform3(0u32..40), 0..200),
            parts in 2usize..9,
            corners in proptest::bool::ANY,
            filtered in proptest::bool::ANY,
        ) {
            let tris: Vec<[u32; 3]> = raw.iter().map(|t| t.map(|k| k % nv as u32)).collect();
            let keep = |t: [u32; 3]| !filtered || t[0] != t[1];
            let mut one = VertexFans::default();
            one.rebuild_in_parts(nv, &tris, keep, corners, 1);
            let mut many = VertexFans::new(2 * nv, &[[0, 1, 2]; 3], |_| true, true);
            many.rebuild_in_parts(nv, &tris, keep, corners, parts);
            proptest::prop_assert_eq!(&one.start, &many.start);
            proptest::prop_assert_eq!(&one.tris, &many.tris);
            proptest::prop_assert_eq!(&one.pairs, &many.pairs);
            for v in 0..nv as u32 {
                let want: Vec<u32> = (0..tris.len() as u32)
                    .filter(|&i| keep(tris[i as usize]))
                    .flat_map(|i| tris[i as usize].iter().filter(move |&&k| k == v).map(move |_| i))
                    .collect();
                proptest::prop_assert_eq!(one.fan(v), &want[..]);
            }
        }
    }
}
