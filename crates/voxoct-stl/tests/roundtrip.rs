//! Round trips: indexed mesh → STL → triangles → weld gives the same mesh.

use proptest::prelude::*;
use voxoct_stl::glam::Vec3;
use voxoct_stl::{StlFormat, parse, weld, write};

fn mesh() -> impl Strategy<Value = (Vec<Vec3>, Vec<[u32; 3]>)> {
    prop::collection::vec(prop::array::uniform3(-1.0e3f32..1.0e3), 3..40).prop_flat_map(|pts| {
        let n = pts.len() as u32;
        let vertices: Vec<Vec3> = pts.into_iter().map(Vec3::from_array).collect();
        let tris = prop::collection::vec(
            (0..n, 0..n, 0..n).prop_filter("distinct", |(a, b, c)| a != b && b != c && a != c),
            0..60,
        )
        .prop_map(|v| v.into_iter().map(|(a, b, c)| [a, b, c]).collect::<Vec<_>>());
        (Just(vertices), tris)
    })
}

fn check(
    format: StlFormat,
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
) -> Result<(), TestCaseError> {
    let mut bytes = Vec::new();
    write(&mut bytes, vertices, triangles, format, 1.0).unwrap();
    let soup = parse(&bytes).unwrap();
    prop_assert_eq!(soup.len(), triangles.len());
    for (t, s) in triangles.iter().zip(&soup) {
        for k in 0..3 {
            // Exact bits: binary stores f32, ASCII uses shortest round-trip notation.
            prop_assert_eq!(s.v[k], vertices[t[k] as usize]);
        }
    }
    // Re-welding gives the same triangles over the used vertices, in first-use order.
    let (wv, wt) = weld(&soup);
    prop_assert_eq!(wt.len(), triangles.len());
    for (a, b) in triangles.iter().zip(&wt) {
        for k in 0..3 {
            prop_assert_eq!(vertices[a[k] as usize], wv[b[k] as usize]);
        }
    }
    Ok(())
}

proptest! {
    #[test]
    fn binary_round_trip((v, t) in mesh()) {
        check(StlFormat::Binary, &v, &t)?;
    }

    #[test]
    fn ascii_round_trip((v, t) in mesh()) {
        check(StlFormat::Ascii, &v, &t)?;
    }

    #[test]
    fn normals_follow_the_winding((v, t) in mesh()) {
        let mut bytes = Vec::new();
        write(&mut bytes, &v, &t, StlFormat::Binary, 2.0).unwrap();
        for (i, tri) in t.iter().enumerate() {
            let rec = &bytes[84 + 50 * i..];
            let f = |k: usize| f32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().unwrap());
            let n = Vec3::new(f(0), f(1), f(2));
            let [a, b, c] = tri.map(|i| v[i as usize]);
            let want = (b - a).cross(c - a).normalize_or_zero();
            if want != Vec3::ZERO {
                prop_assert!(n.dot(want) > 0.999, "{} vs {}", n, want);
            }
        }
    }
}

#[test]
fn weld_merges_negative_zero() {
    use voxoct_stl::glam::Vec3 as V;
    let t = voxoct_core::Triangle::new(V::new(-0.0, 0.0, 0.0), V::X, V::Y);
    let u = voxoct_core::Triangle::new(V::ZERO, V::Y, V::Z);
    let (v, tris) = weld(&[t, u]);
    assert_eq!(v.len(), 4);
    assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3]]);
}
