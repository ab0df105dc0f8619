//! A realistic single-view snapshot, generated analytically: a 640×480 depth image
//! (f = 580 px) of a sphere of radius 7.5 cm at 0.7 m, triangulated by pixel adjacency.

use voxoct_core::Triangle;
use voxoct_core::glam::Vec3;

/// Sphere centre in the camera frame (x right, y down, z forward), metres.
pub const CENTRE: Vec3 = Vec3::new(0.0, 0.0, 0.7);
/// Sphere radius, metres.
pub const RADIUS: f32 = 0.075;

/// Back-projected points of the 640×480 image (`None` where the ray misses the sphere).
pub fn points() -> (usize, usize, Vec<Option<Vec3>>) {
    let (w, h, f) = (640usize, 480usize, 580.0f32);
    let (cx, cy) = (319.5f32, 239.5f32);
    let mut pts = Vec::with_capacity(w * h);
    for v in 0..h {
        for u in 0..w {
            let d = Vec3::new((u as f32 - cx) / f, (v as f32 - cy) / f, 1.0);
            // |t d - c|² = r²  →  t² d·d - 2 t d·c + c·c - r² = 0, nearest root.
            let (a, b, c) = (
                d.dot(d),
                d.dot(CENTRE),
                CENTRE.dot(CENTRE) - RADIUS * RADIUS,
            );
            let disc = b * b - a * c;
            pts.push((disc >= 0.0).then(|| d * ((b - disc.sqrt()) / a)));
        }
    }
    (w, h, pts)
}

/// Triangles (i, i+w, i+1) and (i+1, i+w, i+w+1), wound so normals face the sensor,
/// dropping any with a squared edge above 1e-4 m².
pub fn triangles() -> Vec<Triangle> {
    let (w, h, pts) = points();
    let mut out = Vec::new();
    let ok = |a: Vec3, b: Vec3, c: Vec3| {
        a.distance_squared(b) <= 1e-4
            && b.distance_squared(c) <= 1e-4
            && c.distance_squared(a) <= 1e-4
    };
    for v in 0..h - 1 {
        for u in 0..w - 1 {
            let i = v * w + u;
            let (p, q, r, s) = (pts[i], pts[i + 1], pts[i + w], pts[i + w + 1]);
            if let (Some(p), Some(q), Some(r)) = (p, q, r)
                && ok(p, r, q)
            {
                out.push(Triangle::new(p, r, q));
            }
            if let (Some(q), Some(r), Some(s)) = (q, r, s)
                && ok(q, r, s)
            {
                out.push(Triangle::new(q, r, s));
            }
        }
    }
    out
}

/// The bench's root: 1 m, centred on the sphere.
pub fn root_min() -> Vec3 {
    CENTRE - Vec3::splat(0.5)
}
