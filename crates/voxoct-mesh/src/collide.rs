//! The simplifier's local test of a collapse: a segment against a triangle, in `f64`,
//! touching included (whole meshes are checked exactly by `crate::selfx`).

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
}
