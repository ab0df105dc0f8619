//! The triangle/box overlap test against independent oracles: parry3d's SAT and
//! brute-force sampling of the triangle; plus exact touching and monotonicity.

use parry3d::bounding_volume::Aabb as PAabb;
use parry3d::query::details::intersection_test_aabb_triangle as parry_test;
use parry3d::shape::Triangle as PTriangle;
use proptest::prelude::*;
use voxoct_core::glam::Vec3;
use voxoct_core::{Aabb, Triangle, intersection_test_aabb_triangle};

fn vec3(r: std::ops::Range<f32>) -> impl Strategy<Value = Vec3> {
    (r.clone(), r.clone(), r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn aabb() -> impl Strategy<Value = Aabb> {
    (vec3(-2.0..2.0), vec3(0.01..2.0)).prop_map(|(min, ext)| Aabb::new(min, min + ext))
}

fn triangle(r: std::ops::Range<f32>) -> impl Strategy<Value = Triangle> {
    (vec3(r.clone()), vec3(r.clone()), vec3(r)).prop_map(|(a, b, c)| Triangle::new(a, b, c))
}

fn parry(b: &Aabb, t: &Triangle) -> bool {
    parry_test(
        &PAabb::new(b.min, b.max),
        &PTriangle::new(t.v[0], t.v[1], t.v[2]),
    )
}

fn grown(b: &Aabb, eps: f32) -> Aabb {
    Aabb::new(b.min - Vec3::splat(eps), b.max + Vec3::splat(eps))
}

/// Twice the area relative to the squared longest edge: ~0 for slivers.
fn fatness(t: &Triangle) -> f32 {
    let e = [t.v[1] - t.v[0], t.v[2] - t.v[1], t.v[0] - t.v[2]];
    let longest = e.iter().map(|e| e.length_squared()).fold(0.0, f32::max);
    if longest == 0.0 {
        0.0
    } else {
        t.scaled_normal().length() / longest
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Agreement with parry3d wherever the answer is robust. The two legitimately
    /// differ (1) within a rounding tolerance of touching: parry works in f32 around the
    /// box centre, we in f64, so a configuration is only compared when parry gives the
    /// same answer for the box grown and shrunk by 1e-4; and (2) for slivers and
    /// degenerate triangles, where parry's normal is unreliable (we test those as
    /// segments; see the brute-force test).
    #[test]
    fn agrees_with_parry(b in aabb(), t in triangle(-3.0..3.0)) {
        prop_assume!(fatness(&t) > 1e-3);
        let eps = 1e-4;
        let shrunk = grown(&b, -eps);
        let robust = parry(&grown(&b, eps), &t) == parry(&shrunk, &t);
        prop_assume!(robust);
        prop_assert_eq!(intersection_test_aabb_triangle(&b, &t), parry(&b, &t));
    }

    /// Same, with triangles small relative to the box and close to it, where edge axes
    /// and the normal decide more often.
    #[test]
    fn agrees_with_parry_near_the_box(b in aabb(), c in vec3(-0.2..1.2), d1 in vec3(-0.3..0.3), d2 in vec3(-0.3..0.3)) {
        let p = b.min + c * (b.max - b.min);
        let t = Triangle::new(p, p + d1, p + d2);
        prop_assume!(fatness(&t) > 1e-3);
        let eps = 1e-4;
        let robust = parry(&grown(&b, eps), &t) == parry(&grown(&b, -eps), &t);
        prop_assume!(robust);
        prop_assert_eq!(intersection_test_aabb_triangle(&b, &t), parry(&b, &t));
    }

    /// A sampled point of the triangle inside the box implies overlap; degenerate
    /// triangles included (their samples lie on the segment or point they are).
    #[test]
    fn sampled_point_inside_implies_overlap(b in aabb(), c in vec3(-0.2..1.2), d1 in vec3(-0.5..0.5), d2 in vec3(-0.5..0.5), kind in 0u8..4) {
        let p = b.min + c * (b.max - b.min);
        let t = match kind {
            0 => Triangle::new(p, p + d1, p + d2),
            1 => Triangle::new(p, p + d1, p + d1 * 0.5),   // collinear
            2 => Triangle::new(p, p + d1, p + d1),         // repeated vertex
            _ => Triangle::new(p, p, p),                   // a point
        };
        // Points inside the box by a margin beyond f32 rounding.
        let inner = grown(&b, -1e-5);
        let n = 12;
        let mut inside = false;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                let q = t.v[0] + (t.v[1] - t.v[0]) * u + (t.v[2] - t.v[0]) * v;
                inside |= inner.contains(q);
            }
        }
        if inside {
            prop_assert!(intersection_test_aabb_triangle(&b, &t));
        }
    }

    /// A triangle with a vertex exactly on the box surface touches it: exact, no
    /// tolerance.
    #[test]
    fn vertex_on_surface_touches(b in aabb(), face in 0usize..6, s in 0.0f32..=1.0, r in 0.0f32..=1.0, d1 in vec3(0.0..1.0), d2 in vec3(0.0..1.0)) {
        let axis = face % 3;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut p = Vec3::ZERO;
        p[axis] = if face < 3 { b.min[axis] } else { b.max[axis] };
        p[u] = (b.min[u] + s * (b.max[u] - b.min[u])).clamp(b.min[u], b.max[u]);
        p[v] = (b.min[v] + r * (b.max[v] - b.min[v])).clamp(b.min[v], b.max[v]);
        // The other vertices point away from the box along the face normal.
        let sign = if face < 3 { -1.0 } else { 1.0 };
        let (mut a, mut c) = (d1, d2);
        a[axis] = sign * (d1[axis] + 0.1);
        c[axis] = sign * (d2[axis] + 0.1);
        let t = Triangle::new(p, p + a, p + c);
        prop_assert!(intersection_test_aabb_triangle(&b, &t));
        // Moved out by a visible gap, it no longer touches.
        let mut gap = Vec3::ZERO;
        gap[axis] = sign * 1e-3;
        let t = Triangle::new(p + gap, p + gap + a, p + gap + c);
        prop_assert!(!intersection_test_aabb_triangle(&b, &t));
    }

    /// Monotone: accepted by a box, accepted by every box containing it.
    #[test]
    fn monotone_in_the_box(b in aabb(), t in triangle(-3.0..3.0), g1 in vec3(0.0..0.5), g2 in vec3(0.0..0.5)) {
        let big = Aabb::new(b.min - g1, b.max + g2);
        if intersection_test_aabb_triangle(&b, &t) {
            prop_assert!(intersection_test_aabb_triangle(&big, &t));
        }
    }
}

#[test]
fn triangle_in_a_face_plane_touches() {
    let b = Aabb::new(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.4, 0.5, 0.7));
    // Lies in the plane z = 0.7, covering part of the top face.
    let t = Triangle::new(
        Vec3::new(0.0, 0.0, 0.7),
        Vec3::new(0.3, 0.0, 0.7),
        Vec3::new(0.0, 0.35, 0.7),
    );
    assert!(intersection_test_aabb_triangle(&b, &t));
    // Same, one float step above.
    let z = f32::from_bits(0.7f32.to_bits() + 1);
    let t = Triangle::new(
        Vec3::new(0.0, 0.0, z),
        Vec3::new(0.3, 0.0, z),
        Vec3::new(0.0, 0.35, z),
    );
    assert!(!intersection_test_aabb_triangle(&b, &t));
}
