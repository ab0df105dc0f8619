//! The exact pair test: orientation predicates (Shewchuk's, through `robust`), segment and
//! triangle tests, and the classification of a triangle.

use robust::{Coord, Coord3D};
use voxoct_core::glam::Vec3;

/// A vertex in `f64` (exact from `f32`).
pub(super) type P = [f64; 3];

/// Marks a triangle that takes part in no pair test (invalid or degenerate).
pub(super) const NO_AXIS: u8 = 3;

#[inline]
pub(super) fn pt(v: Vec3) -> P {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

#[inline]
pub(super) fn sign(x: f64) -> i8 {
    i8::from(x > 0.0) - i8::from(x < 0.0)
}

#[inline]
pub(super) fn c3(a: &P) -> Coord3D<f64> {
    Coord3D {
        x: a[0],
        y: a[1],
        z: a[2],
    }
}

/// Exact sign of the orientation of `d` against the plane `a, b, c`; 0 when coplanar.
#[inline]
pub(super) fn orient3d(a: &P, b: &P, c: &P, d: &P) -> i8 {
    sign(robust::orient3d(c3(a), c3(b), c3(c), c3(d)))
}

/// Exact sign of the orientation of the projections of `a, b, c` that drop axis `k`: the
/// sign of the `k` component of `(b - a) × (c - a)`.
#[inline]
pub(super) fn orient2d(a: &P, b: &P, c: &P, k: usize) -> i8 {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    sign(robust::orient2d(
        Coord { x: a[i], y: a[j] },
        Coord { x: b[i], y: b[j] },
        Coord { x: c[i], y: c[j] },
    ))
}

/// Whether collinear points `x`, `y` lie in lexicographic order (`x <= y`).
#[inline]
pub(super) fn lex_le(x: &P, y: &P) -> bool {
    x.partial_cmp(y).is_some_and(|o| o.is_le())
}

/// Closed segments `pq` and `rs` meet, in the projection dropping axis `k`.
pub(super) fn seg_seg_2d(p: &P, q: &P, r: &P, s: &P, k: usize) -> bool {
    let d1 = orient2d(p, q, r, k);
    let d2 = orient2d(p, q, s, k);
    if d1 * d2 > 0 {
        return false;
    }
    let d3 = orient2d(r, s, p, k);
    let d4 = orient2d(r, s, q, k);
    if d3 * d4 > 0 {
        return false;
    }
    if d1 == 0 && d2 == 0 && d3 == 0 && d4 == 0 {
        // All four on one line: lexicographic order (of the projections, which keep the
        // order along the line) is the order along it; the intervals must overlap.
        let proj = |x: &P| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            [x[i], x[j], 0.0]
        };
        let (p, q, r, s) = (proj(p), proj(q), proj(r), proj(s));
        let (lo1, hi1) = if lex_le(&p, &q) { (p, q) } else { (q, p) };
        let (lo2, hi2) = if lex_le(&r, &s) { (r, s) } else { (s, r) };
        return lex_le(&lo1, &hi2) && lex_le(&lo2, &hi1);
    }
    true
}

/// Closed triangle `t` (not degenerate in projection `k`) contains `x`, all coplanar.
pub(super) fn point_in_tri_2d(x: &P, t: &[P; 3], k: usize) -> bool {
    let o1 = orient2d(&t[0], &t[1], x, k);
    let o2 = orient2d(&t[1], &t[2], x, k);
    let o3 = orient2d(&t[2], &t[0], x, k);
    !((o1 > 0 || o2 > 0 || o3 > 0) && (o1 < 0 || o2 < 0 || o3 < 0))
}

/// Closed segment `pq` meets closed triangle `t`, all in one plane that projection `k`
/// maps bijectively.
pub(super) fn seg_tri_coplanar(p: &P, q: &P, t: &[P; 3], k: usize) -> bool {
    point_in_tri_2d(p, t, k)
        || point_in_tri_2d(q, t, k)
        || seg_seg_2d(p, q, &t[0], &t[1], k)
        || seg_seg_2d(p, q, &t[1], &t[2], k)
        || seg_seg_2d(p, q, &t[2], &t[0], k)
}

/// Closed segment `pq` meets closed triangle `t` (not degenerate; `k` its projection axis),
/// given `sp`, `sq`: the orientations of `p`, `q` against the plane of `t`.
pub(super) fn seg_tri(p: &P, q: &P, sp: i8, sq: i8, t: &[P; 3], k: usize) -> bool {
    if sp * sq > 0 {
        return false;
    }
    if sp == 0 && sq == 0 {
        return seg_tri_coplanar(p, q, t, k);
    }
    // The line pq crosses the plane in one point, within the closed segment; it lies in the
    // closed triangle when the line passes every directed edge on the same side (or on it).
    let s1 = orient3d(p, q, &t[0], &t[1]);
    let s2 = orient3d(p, q, &t[1], &t[2]);
    let s3 = orient3d(p, q, &t[2], &t[0]);
    !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0))
}

/// Orientations of the points `x` against the plane of `t`: [`orient3d`] of each, with the
/// plane's normal computed once. Each sign comes from `-(n · (x - t0))`, `n` the normal
/// `(t1 - t0) × (t2 - t0)`, when its magnitude exceeds the error bound of that evaluation,
/// else from the exact predicate.
///
/// The bound is Shewchuk's first one for `orient3d` (`(7 + 56ε)ε` times the permanent,
/// ε = 2⁻⁵³), which holds for any evaluation of the determinant as a sum of three terms,
/// each a difference coordinate times a 2×2 minor of differences, with every operation
/// rounded once; here 8ε. `orient3d(a, b, c, x)` is `det[a - x; b - x; c - x]`
/// `= (a - x) · ((b - a) × (c - a))`, hence the minus. Coordinates from `f32` keep every
/// intermediate in the normal range of `f64`, where the bound holds.
#[inline]
pub(super) fn sides(t: &[P; 3], x: &[P; 3]) -> [i8; 3] {
    const BOUND: f64 = 8.0 * (f64::EPSILON / 2.0);
    let d = |p: &P, q: &P| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let (u, w) = (d(&t[1], &t[0]), d(&t[2], &t[0]));
    let n = [
        u[1] * w[2] - u[2] * w[1],
        u[2] * w[0] - u[0] * w[2],
        u[0] * w[1] - u[1] * w[0],
    ];
    let na = [
        (u[1] * w[2]).abs() + (u[2] * w[1]).abs(),
        (u[2] * w[0]).abs() + (u[0] * w[2]).abs(),
        (u[0] * w[1]).abs() + (u[1] * w[0]).abs(),
    ];
    x.each_ref().map(|x| {
        let e = d(x, &t[0]);
        let det = n[0] * e[0] + n[1] * e[1] + n[2] * e[2];
        let perm = na[0] * e[0].abs() + na[1] * e[1].abs() + na[2] * e[2].abs();
        if det.abs() > BOUND * perm {
            -sign(det)
        } else if (0..3).any(|k| x[k] == t[0][k] && t[1][k] == t[0][k] && t[2][k] == t[0][k]) {
            // All four in a plane normal to an axis (a flat closure's floor): coplanar.
            0
        } else {
            orient3d(&t[0], &t[1], &t[2], x)
        }
    })
}

/// Whether all three orientations are strictly on one side.
#[inline]
pub(super) fn one_side(s: [i8; 3]) -> bool {
    (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0)
}

/// Two closed triangles with no shared vertex meet (`k1`, `k2`: their projection axes).
pub(super) fn tri_tri(t1: &[P; 3], t2: &[P; 3], k1: usize, k2: usize) -> bool {
    let s2 = sides(t1, t2);
    if one_side(s2) {
        return false;
    }
    let s1 = if s2 == [0; 3] {
        // Coplanar: most such pairs (neighbours on a flat patch) are told apart by an edge.
        if separated_2d(t1, t2, k1) || separated_2d(t2, t1, k1) {
            return false;
        }
        [0; 3]
    } else {
        let s1 = sides(t2, t1);
        if one_side(s1) {
            return false;
        }
        s1
    };
    // They meet exactly when an edge of one meets the other: the intersection is convex,
    // and an extreme point of it lies on the boundary of one of them.
    (0..3).any(|e| {
        let (i, j) = (e, (e + 1) % 3);
        seg_tri(&t1[i], &t1[j], s1[i], s1[j], t2, k2)
            || seg_tri(&t2[i], &t2[j], s2[i], s2[j], t1, k1)
    })
}

/// Whether the line of an edge of `t` has all of `u` strictly on its outer side (away from
/// the opposite vertex of `t`), all coplanar, in the projection dropping axis `k`, which
/// maps their plane bijectively: then `u` lies in an open half-plane and `t` in the closed
/// other one, so they do not meet.
pub(super) fn separated_2d(t: &[P; 3], u: &[P; 3], k: usize) -> bool {
    let o = orient2d(&t[0], &t[1], &t[2], k);
    (0..3).any(|e| {
        let (i, j) = (e, (e + 1) % 3);
        u.iter().all(|x| orient2d(&t[i], &t[j], x, k) == -o)
    })
}

/// A triangle's vertices and projection axis.
#[derive(Clone, Copy)]
pub(super) struct Tri<'a> {
    pub(super) idx: [u32; 3],
    pub(super) k: usize,
    pub(super) v: &'a [Vec3],
}

impl Tri<'_> {
    #[inline]
    pub(super) fn p(&self, i: usize) -> P {
        pt(self.v[self.idx[i] as usize])
    }
    #[inline]
    pub(super) fn pts(&self) -> [P; 3] {
        [self.p(0), self.p(1), self.p(2)]
    }
}

/// Whether two proper triangles intersect improperly (see the module documentation).
pub(super) fn improper(a: Tri<'_>, b: Tri<'_>) -> bool {
    // ma, mb: which corners are shared.
    let (mut ma, mut mb, mut n) = (0u8, 0u8, 0u8);
    for i in 0..3 {
        for j in 0..3 {
            if a.idx[i] == b.idx[j] {
                ma |= 1 << i;
                mb |= 1 << j;
                n += 1;
            }
        }
    }
    match n {
        0 => tri_tri(&a.pts(), &b.pts(), a.k, b.k),
        1 => {
            // Rotate each so that corner 0 is the shared vertex.
            let ra = rotated(a, ma.trailing_zeros() as usize);
            let rb = rotated(b, mb.trailing_zeros() as usize);
            let sa = [
                0,
                orient3d(&rb[0], &rb[1], &rb[2], &ra[1]),
                orient3d(&rb[0], &rb[1], &rb[2], &ra[2]),
            ];
            if seg_tri(&ra[1], &ra[2], sa[1], sa[2], &rb, b.k) {
                return true;
            }
            let sb = [
                0,
                orient3d(&ra[0], &ra[1], &ra[2], &rb[1]),
                orient3d(&ra[0], &ra[1], &ra[2], &rb[2]),
            ];
            seg_tri(&rb[1], &rb[2], sb[1], sb[2], &ra, a.k)
        }
        2 => {
            // Corner 0 of each rotated one is the opposite vertex.
            let ra = rotated(a, (!ma & 7).trailing_zeros() as usize);
            let q = b.p((!mb & 7).trailing_zeros() as usize);
            let (u, v, p) = (&ra[1], &ra[2], &ra[0]);
            orient3d(u, v, p, &q) == 0 && orient2d(u, v, p, a.k) == orient2d(u, v, &q, a.k)
        }
        _ => true,
    }
}

/// The triangle's points rotated so that corner `first` comes first (orientation kept).
#[inline]
pub(super) fn rotated(t: Tri<'_>, first: usize) -> [P; 3] {
    [t.p(first), t.p((first + 1) % 3), t.p((first + 2) % 3)]
}

/// A triangle's projection axis ([`NO_AXIS`] when it is not a proper triangle) and the exact
/// signs of its normal's components (bit `k`: positive, bit `3 + k`: negative).
pub(super) fn classify(vertices: &[Vec3], t: [u32; 3]) -> (u8, u8) {
    let n = vertices.len();
    if t.iter().any(|&i| i as usize >= n) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return (NO_AXIS, 0);
    }
    let [a, b, c] = t.map(|i| vertices[i as usize]);
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return (NO_AXIS, 0);
    }
    let (a, b, c) = (pt(a), pt(b), pt(c));
    let mut signs = 0u8;
    for k in 0..3 {
        match orient2d(&a, &b, &c, k) {
            1 => signs |= 1 << k,
            -1 => signs |= 8 << k,
            _ => {}
        }
    }
    if signs == 0 {
        return (NO_AXIS, 0);
    }
    // Among the exactly non-zero components, the largest (best-conditioned projection).
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let nrm = [
        (u[1] * w[2] - u[2] * w[1]).abs(),
        (u[2] * w[0] - u[0] * w[2]).abs(),
        (u[0] * w[1] - u[1] * w[0]).abs(),
    ];
    let k = (0..3)
        .filter(|&k| signs & (9 << k) != 0)
        .max_by(|&x, &y| nrm[x].total_cmp(&nrm[y]))
        .unwrap_or(0);
    (k as u8, signs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A point from `f32`s: small lattice coordinates (coplanar and collinear cases are
    /// common) at a scale, or arbitrary values.
    fn point() -> impl Strategy<Value = P> {
        prop_oneof![
            (prop::array::uniform3(-4i32..=4), -30i32..30)
                .prop_map(|(c, e)| c.map(|x| { f64::from(x as f32 * 2f32.powi(e)) })),
            prop::array::uniform3(-1.0f32..1.0).prop_map(|c| c.map(f64::from)),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        /// The filtered signs of `sides` are the exact predicate's, coplanar points included.
        #[test]
        fn sides_agree_with_the_exact_predicate(
            t in prop::array::uniform3(point()),
            x in prop::array::uniform3(point()),
            mix in prop::array::uniform3((-2i32..=2, -2i32..=2)),
        ) {
            // Half the points exactly in the plane of t where the lattice allows it.
            let x: [P; 3] = std::array::from_fn(|i| {
                let (a, b) = (f64::from(mix[i].0), f64::from(mix[i].1));
                let p: P = std::array::from_fn(|k| t[0][k] + a * (t[1][k] - t[0][k]) + b * (t[2][k] - t[0][k]));
                if i % 2 == 0 && p.iter().all(|&c| f64::from(c as f32) == c) { p } else { x[i] }
            });
            let want = x.each_ref().map(|x| orient3d(&t[0], &t[1], &t[2], x));
            prop_assert_eq!(sides(&t, &x), want);
        }

        /// `tri_tri` with its shortcuts (filtered sides, planes normal to an axis, coplanar
        /// pairs separated by an edge) agrees with the edge loop alone on exact sides, on
        /// coplanar, axis-aligned and general pairs.
        #[test]
        fn tri_tri_agrees_with_the_edge_loop(
            t1 in prop::array::uniform3(point()),
            t2 in prop::array::uniform3(point()),
            flat in prop::option::of(0usize..3),
            coplanar in any::<bool>(),
            mix in prop::array::uniform3(prop::option::of((-3i32..=3, -3i32..=3))),
            abc in prop::array::uniform3((-3i32..=3, -3i32..=3)),
            lattice in (prop::array::uniform3(prop::array::uniform3(-4i32..=4)), -30i32..30),
        ) {
            // Coplanar pairs on one lattice, so that t2's points are exact.
            let mut t1 = if coplanar {
                lattice.0.map(|c| c.map(|x| f64::from(x as f32 * 2f32.powi(lattice.1))))
            } else {
                t1
            };
            if let Some(k) = flat {
                t1[1][k] = t1[0][k];
                t1[2][k] = t1[0][k];
            }
            // Some of t2's points in the plane of t1 (exactly, where f32 allows it).
            let t2: [P; 3] = std::array::from_fn(|i| match if coplanar { Some(abc[i]) } else { mix[i] } {
                Some((a, b)) => {
                    let (a, b) = (f64::from(a) / 2.0, f64::from(b) / 2.0);
                    let p: P = std::array::from_fn(|k| {
                        t1[0][k] + a * (t1[1][k] - t1[0][k]) + b * (t1[2][k] - t1[0][k])
                    });
                    if p.iter().all(|&c| f64::from(c as f32) == c) { p } else { t2[i] }
                }
                None => t2[i],
            });
            let v: Vec<Vec3> = t1.iter().chain(&t2).map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)).collect();
            let (k1, _) = classify(&v, [0, 1, 2]);
            let (k2, _) = classify(&v, [3, 4, 5]);
            prop_assume!(k1 != NO_AXIS && k2 != NO_AXIS);
            let (k1, k2) = (usize::from(k1), usize::from(k2));
            let s2 = t2.each_ref().map(|x| orient3d(&t1[0], &t1[1], &t1[2], x));
            let s1 = t1.each_ref().map(|x| orient3d(&t2[0], &t2[1], &t2[2], x));
            let want = (0..3).any(|e| {
                let (i, j) = (e, (e + 1) % 3);
                seg_tri(&t1[i], &t1[j], s1[i], s1[j], &t2, k2)
                    || seg_tri(&t2[i], &t2[j], s2[i], s2[j], &t1, k1)
            });
            prop_assert_eq!(tri_tri(&t1, &t2, k1, k2), want);
            prop_assert_eq!(tri_tri(&t2, &t1, k2, k1), want);
        }
    }
}
