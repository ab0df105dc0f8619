//! A small z-buffer rasteriser: the mesh seen from three sides, shaded, as one PNG.
//!
//! ```
//! use voxoct::core::glam::Vec3;
//! // One triangle facing the front view.
//! let vertices = [Vec3::ZERO, Vec3::X, Vec3::Y];
//! let img = voxoct::preview::render(&vertices, &[[0, 1, 2]]);
//! assert_eq!((img.width, img.height), (3 * voxoct::preview::VIEW as u32, voxoct::preview::VIEW as u32));
//! let mut png = Vec::new();
//! voxoct::preview::write_preview(&mut png, &vertices, &[[0, 1, 2]])?;
//! assert!(png.starts_with(b"\x89PNG"));
//! # Ok::<(), std::io::Error>(())
//! ```

use voxoct_core::glam::Vec3;
use voxoct_depth::image::{RgbImage, write_png_to};

/// Pixels per view (square).
pub const VIEW: usize = 420;
/// Margin around the model inside a view, pixels.
const MARGIN: f32 = 16.0;

/// One orthographic view: screen right, screen up and the direction towards the viewer.
struct View {
    right: Vec3,
    up: Vec3,
    toward_viewer: Vec3,
}

const VIEWS: [View; 3] = [
    View {
        right: Vec3::X,
        up: Vec3::Y,
        toward_viewer: Vec3::Z,
    },
    View {
        right: Vec3::NEG_Z,
        up: Vec3::Y,
        toward_viewer: Vec3::X,
    },
    View {
        right: Vec3::X,
        up: Vec3::NEG_Z,
        toward_viewer: Vec3::Y,
    },
];

/// Renders `vertices`/`triangles` (outward-oriented) from the front, the side and the
/// top into an RGB image `3 * VIEW` wide and `VIEW` high: faces lit by a light over the
/// viewer's shoulder, back faces dark red, on a soft grey gradient.
#[must_use]
pub fn render(vertices: &[Vec3], triangles: &[[u32; 3]]) -> RgbImage {
    let (w, h) = (3 * VIEW, VIEW);
    let mut rgb = vec![0u8; w * h * 3];
    for (i, px) in rgb.chunks_exact_mut(3).enumerate() {
        // A soft vertical gradient background.
        let y = (i / w) as f32 / h as f32;
        let g = (238.0 - 30.0 * y) as u8;
        px.copy_from_slice(&[g, g, g.saturating_add(8)]);
    }
    if !vertices.is_empty() {
        for (k, view) in VIEWS.iter().enumerate() {
            render_view(&mut rgb, w, k * VIEW, view, vertices, triangles);
        }
    }
    for k in 1..3 {
        for y in 0..h {
            let o = (y * w + k * VIEW) * 3;
            rgb[o..o + 3].copy_from_slice(&[150, 150, 160]);
        }
    }
    RgbImage {
        width: w as u32,
        height: h as u32,
        data: rgb,
    }
}

/// [`render`]s the mesh and writes the picture as PNG to `w_out`
/// ([`voxoct_depth::image::write_png_to`]).
///
/// # Errors
/// The writer's I/O errors.
pub fn write_preview(
    w_out: &mut dyn std::io::Write,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
) -> std::io::Result<()> {
    write_png_to(w_out, &render(vertices, triangles))
}

fn render_view(
    rgb: &mut [u8],
    stride: usize,
    x0: usize,
    view: &View,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
) {
    // Screen coordinates: (right, up, toward viewer).
    let project = |p: Vec3| Vec3::new(p.dot(view.right), p.dot(view.up), p.dot(view.toward_viewer));
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &p in vertices {
        let s = project(p);
        lo = lo.min(s);
        hi = hi.max(s);
    }
    let extent = (hi - lo).max_element().max(1e-9);
    let scale = (VIEW as f32 - 2.0 * MARGIN) / extent;
    let centre = (lo + hi) * 0.5;
    let to_px = |s: Vec3| {
        Vec3::new(
            VIEW as f32 * 0.5 + (s.x - centre.x) * scale,
            VIEW as f32 * 0.5 - (s.y - centre.y) * scale,
            s.z,
        )
    };
    let mut zbuf = vec![f32::NEG_INFINITY; VIEW * VIEW];
    let light = (view.toward_viewer * 0.8 + view.up * 0.45 + view.right * 0.25).normalize();
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let n = (b - a).cross(c - a);
        if n.length_squared() == 0.0 {
            continue;
        }
        let n = n.normalize();
        // Facing the viewer (outward normals): Lambert plus ambient; back faces darker.
        let lambert = n.dot(light).max(0.0);
        let shade = if n.dot(view.toward_viewer) >= 0.0 {
            0.22 + 0.78 * lambert
        } else {
            0.15
        };
        let colour = [
            (90.0 + 150.0 * shade) as u8,
            (110.0 + 135.0 * shade) as u8,
            (140.0 + 110.0 * shade) as u8,
        ];
        let colour = if shade <= 0.15 { [120, 40, 40] } else { colour };
        let (pa, pb, pc) = (to_px(project(a)), to_px(project(b)), to_px(project(c)));
        let area = edge(pa, pb, pc);
        if area.abs() < 1e-12 {
            continue;
        }
        let xmin = pa.x.min(pb.x).min(pc.x).floor().max(0.0) as usize;
        let xmax = (pa.x.max(pb.x).max(pc.x).ceil() as usize).min(VIEW - 1);
        let ymin = pa.y.min(pb.y).min(pc.y).floor().max(0.0) as usize;
        let ymax = (pa.y.max(pb.y).max(pc.y).ceil() as usize).min(VIEW - 1);
        for y in ymin..=ymax {
            for x in xmin..=xmax {
                let p = Vec3::new(x as f32 + 0.5, y as f32 + 0.5, 0.0);
                let (w0, w1, w2) = (
                    edge(pb, pc, p) / area,
                    edge(pc, pa, p) / area,
                    edge(pa, pb, p) / area,
                );
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * pa.z + w1 * pb.z + w2 * pc.z;
                let zi = y * VIEW + x;
                if z > zbuf[zi] {
                    zbuf[zi] = z;
                    let o = (y * stride + x0 + x) * 3;
                    rgb[o..o + 3].copy_from_slice(&colour);
                }
            }
        }
    }
}

/// Twice the signed area of the screen triangle (a, b, p).
fn edge(a: Vec3, b: Vec3, p: Vec3) -> f32 {
    (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_front_facing_triangle_is_lit_and_the_background_stays_grey() {
        let vertices = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let img = render(&vertices, &[[0, 1, 2]]);
        // The front view's centre column, a third of the way up the triangle's bounding box.
        let centre = VIEW as u32 / 3;
        let px = img.get(centre, VIEW as u32 * 2 / 3).unwrap();
        assert_ne!(px[0], px[1], "front face is shaded blue-grey, got {px:?}");
        // A corner is background: grey with a touch of blue.
        let bg = img.get(2, 2).unwrap();
        assert_eq!(bg[0], bg[1]);
        assert_eq!(bg[2], bg[0].saturating_add(8));
    }
}
