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

impl VertexFans {
    /// The fans of `nv` vertices over the triangles that `keep` accepts (whose indices
    /// must then be below `nv`), with the corners' vertex pairs when `corners`.
    pub(crate) fn new(
        nv: usize,
        triangles: &[[u32; 3]],
        keep: impl Fn([u32; 3]) -> bool,
        corners: bool,
    ) -> Self {
        let mut s = Self::default();
        s.rebuild(nv, triangles, keep, corners);
        s
    }

    /// As [`VertexFans::new`], reusing the buffers.
    pub(crate) fn rebuild(
        &mut self,
        nv: usize,
        triangles: &[[u32; 3]],
        keep: impl Fn([u32; 3]) -> bool,
        corners: bool,
    ) {
        self.start.clear();
        self.start.resize(nv + 1, 0);
        for t in triangles {
            if keep(*t) {
                for &k in t {
                    self.start[k as usize + 1] += 1;
                }
            }
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
        // Fill using start[v] as a cursor, then shift back.
        for (i, t) in triangles.iter().enumerate() {
            if !keep(*t) {
                continue;
            }
            for j in 0..3 {
                let c = &mut self.start[t[j] as usize];
                self.tris[*c as usize] = i as u32;
                if corners {
                    self.pairs[*c as usize] = [t[(j + 1) % 3], t[(j + 2) % 3]];
                }
                *c += 1;
            }
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
}
