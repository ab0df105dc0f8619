//! The simplifier's local tests of a collapse, in `f64`: a segment against a triangle,
//! touching included (whole meshes are checked exactly by `crate::selfx`), and the
//! squared distance from a point to a triangle.

use voxoct_core::glam::{DVec2, DVec3};

/// `(b − a) · ((c − a) × (d − a))`: positive when `d` is on the side of `a b c`'s normal.
#[inline]
fn orient(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    (b - a).cross(c - a).dot(d - a)
}

/// Segment `a b` against triangle `t`, touching included.
pub(crate) fn segment_triangle(a: DVec3, b: DVec3, t: [DVec3; 3]) -> bool {
    let sa = orient(t[0], t[1], t[2], a);
    let sb = orient(t[0], t[1], t[2], b);
    if (sa > 0.0 && sb > 0.0) || (sa < 0.0 && sb < 0.0) {
        return false;
    }
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if sa == 0.0 && sb == 0.0 {
        let (to2, tt) = project(n, t);
        let (a2, b2) = (to2(a), to2(b));
        return point_in_triangle_2d(a2, tt)
            || point_in_triangle_2d(b2, tt)
            || (0..3).any(|i| segments_2d(a2, b2, tt[i], tt[(i + 1) % 3]));
    }
    let x = a + (b - a) * (sa / (sa - sb));
    (0..3).all(|i| (t[(i + 1) % 3] - t[i]).cross(x - t[i]).dot(n) >= 0.0)
}

/// Drops the axis along which `n` is largest; returns the projection and `t` projected.
fn project(n: DVec3, t: [DVec3; 3]) -> (impl Fn(DVec3) -> DVec2, [DVec2; 3]) {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let f = move |x: DVec3| match axis {
        0 => DVec2::new(x.y, x.z),
        1 => DVec2::new(x.z, x.x),
        _ => DVec2::new(x.x, x.y),
    };
    let tt = t.map(f);
    (f, tt)
}

fn cross2(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

fn point_in_triangle_2d(x: DVec2, t: [DVec2; 3]) -> bool {
    let s = [0, 1, 2].map(|i| cross2(t[(i + 1) % 3] - t[i], x - t[i]));
    s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
}

/// Squared distance from `p` to the closest point of triangle `t` (by the triangle's
/// Voronoi regions, as in Ericson, *Real-Time Collision Detection* §5.1.5).
pub(crate) fn point_triangle_sq(p: DVec3, t: [DVec3; 3]) -> f64 {
    let [a, b, c] = t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    if ab.cross(ac) == DVec3::ZERO {
        // No area (corners on a line or in one place): the nearest point of its edges. The
        // regions below assume an area (every denominator is then an edge's or the
        // normal's squared length).
        return [(a, b), (b, c), (c, a)]
            .map(|(x, y)| {
                let d = y - x;
                let s = if d.length_squared() > 0.0 {
                    ((p - x).dot(d) / d.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (p - (x + d * s)).length_squared()
            })
            .into_iter()
            .fold(f64::INFINITY, f64::min);
    }
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length_squared();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length_squared();
    }
    let denom = va + vb + vc;
    let (v, w) = (vb / denom, vc / denom);
    (p - (a + ab * v + ac * w)).length_squared()
}

fn segments_2d(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let d1 = cross2(b - a, c - a);
    let d2 = cross2(b - a, d - a);
    let d3 = cross2(d - c, a - c);
    let d4 = cross2(d - c, b - c);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, d: f64| {
        d == 0.0
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(a, b, c, d1) || on(a, b, d, d2) || on(c, d, a, d3) || on(c, d, b, d4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_through_beside_and_on_a_triangle() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let d = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        // Through its inside, beside it, ending on it, and lying in its plane across it.
        assert!(segment_triangle(d(0.2, 0.2, -0.5), d(0.2, 0.2, 0.5), t));
        assert!(!segment_triangle(d(0.9, 0.9, -0.5), d(0.9, 0.9, 0.5), t));
        assert!(segment_triangle(d(0.2, 0.2, 0.0), d(0.2, 0.2, 0.5), t));
        assert!(segment_triangle(d(-0.5, 0.2, 0.0), d(0.5, 0.2, 0.0), t));
        assert!(!segment_triangle(d(-0.5, -0.2, 0.0), d(-0.1, -0.2, 0.0), t));
    }

    /// Against a plain oracle: the minimum over a fine barycentric sampling of the triangle
    /// (never below the exact distance, and within the sampling's reach above it).
    #[test]
    fn point_triangle_distance_is_the_nearest_point_of_the_triangle() {
        let d = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let tris = [
            [d(0.0, 0.0, 0.0), d(1.0, 0.0, 0.0), d(0.0, 1.0, 0.0)],
            [d(0.3, -0.2, 0.5), d(-0.7, 0.4, 0.1), d(0.2, 0.9, -0.6)],
            [d(0.0, 0.0, 0.0), d(1.0, 1.0, 1.0), d(2.0, 2.0, 2.0)],
            [d(0.5, 0.5, 0.5); 3],
            // Two corners in one place (an edge of zero length).
            [d(0.2, 0.1, 0.0), d(0.2, 0.1, 0.0), d(-0.4, 0.8, 0.3)],
            [d(0.2, 0.1, 0.0), d(-0.4, 0.8, 0.3), d(-0.4, 0.8, 0.3)],
        ];
        let n = 200;
        for t in tris {
            for i in 0..125 {
                let p = d(
                    f64::from(i % 5) - 2.0,
                    f64::from(i / 5 % 5) - 2.0,
                    f64::from(i / 25) - 2.0,
                ) * 0.7;
                let mut best = f64::INFINITY;
                for u in 0..=n {
                    for v in 0..=n - u {
                        let (s, r) = (f64::from(u) / f64::from(n), f64::from(v) / f64::from(n));
                        let q = t[0] + (t[1] - t[0]) * s + (t[2] - t[0]) * r;
                        best = best.min((p - q).length());
                    }
                }
                let exact = point_triangle_sq(p, t).sqrt();
                assert!(
                    exact <= best + 1e-12 && best - exact < 0.02,
                    "{t:?} {p}: {exact} vs {best}"
                );
            }
        }
    }
}
