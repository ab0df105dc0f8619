//! Triangulation of a snapshot by pixel adjacency.

use glam::Vec3;
use voxoct_core::Triangle;

use crate::snapshot::Snapshot;

/// Default squared-edge threshold, m² (1 cm edges), as ARCHITECTURE.md fixes it.
pub const DEFAULT_MAX_EDGE_SQ: f32 = 1e-4;

/// A triangle whose `sin²` of the angle at its first vertex is below this is a
/// zero-area sliver and is dropped.
const SLIVER_SIN_SQ: f32 = 1e-10;

/// Appends the triangles of `s` to `out` (which the caller may reuse between snapshots).
///
/// For pixel `i` of the `w × h` grid, the triangles over `(i, i+1, i+w)` and
/// `(i+1, i+w+1, i+w)`; none in the last row or column, none with a hole, none with a
/// squared edge length above `max_edge_sq`. The vertices are wound as `(i, i+w, i+1)` and
/// `(i+1, i+w, i+w+1)`, so that every normal `(b − a) × (c − a)` faces the sensor (the
/// outside of the object); triangles that are zero-area slivers, or so close to edge-on
/// that rounding turns them away from the sensor, are dropped.
pub fn triangulate(s: &Snapshot, max_edge_sq: f32, out: &mut Vec<Triangle>) {
    let w = s.width as usize;
    let h = s.height as usize;
    if w < 2 || h < 2 || s.points.len() != w * h {
        return;
    }
    let sensor = s.sensor_position();
    let pts = &s.points;
    for v in 0..h - 1 {
        let top = &pts[v * w..(v + 1) * w];
        let bot = &pts[(v + 1) * w..(v + 2) * w];
        for u in 0..w - 1 {
            let p00 = top[u];
            let p10 = top[u + 1];
            let p01 = bot[u];
            if p10.x.is_nan() || p01.x.is_nan() {
                continue;
            }
            // The diagonal both triangles share.
            let diag = p10.distance_squared(p01);
            if diag > max_edge_sq {
                continue;
            }
            if !p00.x.is_nan() {
                push(out, p00, p01, p10, max_edge_sq, sensor);
            }
            let p11 = bot[u + 1];
            if !p11.x.is_nan() {
                push(out, p10, p01, p11, max_edge_sq, sensor);
            }
        }
    }
}

/// Pushes triangle `(a, b, c)` unless an edge is too long, it is a sliver or it is turned
/// away from the sensor.
#[inline(always)]
fn push(out: &mut Vec<Triangle>, a: Vec3, b: Vec3, c: Vec3, max: f32, sensor: Vec3) {
    let ab = b - a;
    let ac = c - a;
    let ab2 = ab.length_squared();
    let ac2 = ac.length_squared();
    if ab2 > max || ac2 > max || b.distance_squared(c) > max {
        return;
    }
    let n = ab.cross(ac);
    if n.length_squared() <= SLIVER_SIN_SQ * ab2 * ac2 || n.dot(sensor - a) <= 0.0 {
        return;
    }
    out.push(Triangle::new(a, b, c));
}

/// [`triangulate`] into a new vector.
#[must_use]
pub fn triangulate_vec(s: &Snapshot, max_edge_sq: f32) -> Vec<Triangle> {
    let mut out = Vec::new();
    triangulate(s, max_edge_sq, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::snapshot::HOLE;
    use glam::Affine3A;

    fn grid(w: u32, h: u32, f: impl Fn(u32, u32) -> Vec3) -> Snapshot {
        Snapshot {
            width: w,
            height: h,
            camera_to_object: Affine3A::from_translation(Vec3::new(0.0, 0.0, 1.0)),
            angle_deg: 0.0,
            points: (0..h)
                .flat_map(|v| (0..w).map(move |u| (u, v)))
                .map(|(u, v)| f(u, v))
                .collect(),
        }
    }

    /// A flat grid facing +z with the sensor at z = 1: pixel (u, v) at (u, −v)·1 mm
    /// (image rows go down, +y goes up).
    fn flat(u: u32, v: u32) -> Vec3 {
        Vec3::new(u as f32 * 1e-3, -(v as f32) * 1e-3, 0.0)
    }

    #[test]
    fn two_triangles_per_interior_pixel_facing_the_sensor() {
        let s = grid(5, 4, flat);
        let t = triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ);
        assert_eq!(t.len(), 2 * 4 * 3);
        for tri in &t {
            assert!(tri.scaled_normal().z > 0.0, "{tri:?}");
        }
        // The first pair is exactly (i, i+w, i+1), (i+1, i+w, i+w+1) of pixel 0.
        assert_eq!(t[0].v, [s.points[0], s.points[5], s.points[1]]);
        assert_eq!(t[1].v, [s.points[1], s.points[5], s.points[6]]);
    }

    #[test]
    fn holes_long_edges_and_slivers_drop_triangles() {
        // One hole in the middle of a 3x3 grid: only the two triangles of the top-left
        // and bottom-right quads that avoid it remain.
        let s = grid(
            3,
            3,
            |u, v| if (u, v) == (1, 1) { HOLE } else { flat(u, v) },
        );
        let t = triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ);
        assert_eq!(t.len(), 2);
        assert_eq!(t[0].v, [s.points[0], s.points[3], s.points[1]]);
        assert_eq!(t[1].v, [s.points[5], s.points[7], s.points[8]]);
        // A step of 2 cm in depth between columns 1 and 2 cuts the grid.
        let s = grid(4, 2, |u, v| {
            flat(u, v)
                + if u >= 2 {
                    Vec3::new(0.0, 0.0, -0.02)
                } else {
                    Vec3::ZERO
                }
        });
        assert_eq!(triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ).len(), 4);
        // A collapsed column makes zero-area triangles.
        let s = grid(2, 2, |u, v| if u == 1 { Vec3::ZERO } else { flat(u, v) });
        assert_eq!(triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ).len(), 0);
        // Only the edge (i+w, i+w+1) of the second triangle is too long.
        let dir = (flat(1, 0) - flat(0, 1)).normalize();
        let s = grid(2, 2, |u, v| match (u, v) {
            (1, 1) => flat(1, 0) + dir * 0.0099,
            _ => flat(u, v),
        });
        let t = triangulate_vec(&s, DEFAULT_MAX_EDGE_SQ);
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].v[0], s.points[0]);
        // Appends.
        let mut out = triangulate_vec(&grid(2, 2, flat), DEFAULT_MAX_EDGE_SQ);
        triangulate(&grid(2, 2, flat), DEFAULT_MAX_EDGE_SQ, &mut out);
        assert_eq!(out.len(), 4);
    }
}
