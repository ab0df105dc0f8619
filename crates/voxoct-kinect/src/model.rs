//! Models to put on the simulated turntable: procedural closed meshes generated in code, and
//! STL / OBJ / PLY / 3MF files.

use std::f32::consts::TAU;
use std::path::Path;

use glam::{Mat3, Vec3};
use parry3d::shape::TriMesh;
use voxoct_core::{Aabb, Triangle};

use crate::SourceError;

/// An indexed triangle mesh in metres, in the platform (object) frame: +Y up, the turntable
/// axis is the Y axis and the platform's top face is at y = 0.
///
/// Triangles are wound counter-clockwise seen from outside (outward normals) for the
/// built-in models; loaded files keep their own winding.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Model {
    /// Vertex positions, metres.
    pub vertices: Vec<Vec3>,
    /// Triangles as indices into `vertices`.
    pub indices: Vec<[u32; 3]>,
}

impl Model {
    /// Names accepted by [`Model::builtin`], the default first.
    pub const BUILTIN_NAMES: &'static [&'static str] = &[
        "figurine", "mug", "vase", "sphere", "torus", "box", "cylinder",
    ];

    /// A procedural closed model standing on the platform (min y = 0, centred on the axis,
    /// 10–15 cm tall, inside a 0.3 m wide clip box); `None` for an unknown name (see
    /// [`Model::BUILTIN_NAMES`]).
    ///
    /// - `figurine`: a box plinth, a ring (torus) lying on it, a ball resting in the ring and a
    ///   small head on the ball (overlapping closed components), 13.2 cm tall.
    /// - `mug`: a cup with a hollow (one closed surface of revolution: outer wall, rim, inner
    ///   wall, inner floor) and a torus handle that crosses the wall, 10 cm tall.
    /// - `vase`: a narrow-necked vase with a hollow (one closed surface of revolution: a
    ///   90 mm body, a neck whose mouth is 24 mm wide, 6 mm walls and floor), 13 cm tall. From
    ///   the usual rig no view sees into its body.
    /// - `sphere`: radius 6 cm. `torus`: standing upright, major radius 5 cm, tube 2 cm.
    /// - `box`: 8 × 12 × 6 cm. `cylinder`: radius 4 cm, 12 cm tall.
    #[must_use]
    pub fn builtin(name: &str) -> Option<Self> {
        let m = match name {
            "figurine" => {
                let mut m = lathe_box(Vec3::new(0.09, 0.025, 0.07));
                m.append(&torus(0.028, 0.011, 64, 24).translated(Vec3::new(0.0, 0.034, 0.0)));
                m.append(&sphere(0.035, 48, 24).translated(Vec3::new(0.0, 0.064, 0.0)));
                m.append(&sphere(0.018, 32, 16).translated(Vec3::new(0.0, 0.114, 0.0)));
                m
            }
            "mug" => {
                let (ro, ri, h, floor) = (0.045, 0.039, 0.10, 0.008);
                let mut m = lathe(
                    &[
                        (0.0, 0.0),
                        (ro, 0.0),
                        (ro, h),
                        (ri, h),
                        (ri, floor),
                        (0.0, floor),
                    ],
                    96,
                    0.0,
                );
                let (rh, rt) = (0.024, 0.0065);
                // Handle: a torus in the XY plane whose tube crosses the wall but stays
                // outside the hollow (innermost point 1 mm beyond the inner wall).
                let handle = torus(rh, rt, 64, 20)
                    .rotated(Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2))
                    .translated(Vec3::new(ri + rh + rt + 0.001, 0.055, 0.0));
                m.append(&handle);
                m
            }
            "vase" => lathe(
                &[
                    (0.0, 0.0),
                    (0.030, 0.0),
                    (0.045, 0.040),
                    (0.045, 0.070),
                    (0.018, 0.110),
                    (0.018, 0.130),
                    (0.012, 0.130),
                    (0.012, 0.112),
                    (0.039, 0.072),
                    (0.039, 0.042),
                    (0.026, 0.006),
                    (0.0, 0.006),
                ],
                96,
                0.0,
            ),
            "sphere" => sphere(0.06, 64, 32).translated(Vec3::new(0.0, 0.06, 0.0)),
            "torus" => torus(0.05, 0.02, 96, 32)
                .rotated(Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2))
                .translated(Vec3::new(0.0, 0.07, 0.0)),
            "box" => lathe_box(Vec3::new(0.08, 0.12, 0.06)),
            "cylinder" => cylinder(0.04, 0.12, 96),
            _ => return None,
        };
        Some(m)
    }

    /// A model from a triangle soup (no vertex welding).
    #[must_use]
    pub fn from_triangles(triangles: &[Triangle]) -> Self {
        let mut vertices = Vec::with_capacity(triangles.len() * 3);
        let mut indices = Vec::with_capacity(triangles.len());
        for (i, t) in triangles.iter().enumerate() {
            vertices.extend_from_slice(&t.v);
            let b = (3 * i) as u32;
            indices.push([b, b + 1, b + 2]);
        }
        Self { vertices, indices }
    }

    /// The triangles as a soup.
    #[must_use]
    pub fn triangles(&self) -> Vec<Triangle> {
        self.indices
            .iter()
            .map(|&[a, b, c]| {
                Triangle::new(
                    self.vertices[a as usize],
                    self.vertices[b as usize],
                    self.vertices[c as usize],
                )
            })
            .collect()
    }

    /// The bounding box of the vertices; `None` when there are none.
    #[must_use]
    pub fn bounds(&self) -> Option<Aabb> {
        let first = *self.vertices.first()?;
        let (min, max) = self
            .vertices
            .iter()
            .fold((first, first), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        Some(Aabb::new(min, max))
    }

    /// The signed volume enclosed (positive for a closed mesh with outward winding).
    #[must_use]
    pub fn signed_volume(&self) -> f32 {
        self.triangles()
            .iter()
            .map(|t| t.v[0].dot(t.v[1].cross(t.v[2])) / 6.0)
            .sum()
    }

    /// Appends another model's triangles (a union of separate closed components).
    pub fn append(&mut self, other: &Self) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.indices.extend(
            other
                .indices
                .iter()
                .map(|&[a, b, c]| [a + base, b + base, c + base]),
        );
    }

    /// The model moved by `offset`.
    #[must_use]
    pub fn translated(mut self, offset: Vec3) -> Self {
        for v in &mut self.vertices {
            *v += offset;
        }
        self
    }

    /// The model rotated by `rotation` about the origin.
    #[must_use]
    pub fn rotated(mut self, rotation: Mat3) -> Self {
        for v in &mut self.vertices {
            *v = rotation * *v;
        }
        self
    }

    /// Turns a Z-up model (the usual convention of STL files for printing) into the Y-up
    /// platform frame: `(x, y, z) → (x, z, -y)`, a proper rotation, so the winding survives.
    #[must_use]
    pub fn z_up_to_y_up(mut self) -> Self {
        // The rotation by -90° about +X, written out so that it is exact in f32.
        for v in &mut self.vertices {
            *v = Vec3::new(v.x, v.z, -v.y);
        }
        self
    }

    /// Places the model on the platform: scales it uniformly to `height_m` tall (along +Y),
    /// centres its bounding box on the turntable axis (x = z = 0) and sets its lowest point
    /// to y = 0.
    ///
    /// # Errors
    /// [`SourceError::BadModel`] when the model is empty, not finite, flat along Y, or
    /// `height_m` is not a positive finite number.
    pub fn place_on_platform(&mut self, height_m: f32) -> Result<(), SourceError> {
        let bad = |message: String| SourceError::BadModel {
            what: "to place on the platform".into(),
            message,
        };
        if !(height_m.is_finite() && height_m > 0.0) {
            return Err(bad(format!("target height {height_m} m is not positive")));
        }
        let b = self.bounds().ok_or_else(|| bad("no vertices".into()))?;
        let h = b.max.y - b.min.y;
        if !(h.is_finite() && h > 0.0 && b.min.is_finite() && b.max.is_finite()) {
            return Err(bad(format!(
                "bounding box {:?}..{:?} is not finite or has no height",
                b.min, b.max
            )));
        }
        let s = height_m / h;
        let c = Vec3::new(
            (b.min.x + b.max.x) * 0.5,
            b.min.y,
            (b.min.z + b.max.z) * 0.5,
        );
        for v in &mut self.vertices {
            *v = (*v - c) * s;
        }
        Ok(())
    }

    /// Moves the model, without scaling or turning it, so that its bounding box is centred on
    /// the turntable axis (x = z = 0) and its lowest point is at y = 0. Nothing happens to
    /// a model without vertices.
    pub fn stand_on_platform(&mut self) {
        let Some(b) = self.bounds() else {
            return;
        };
        let c = Vec3::new(
            (b.min.x + b.max.x) * 0.5,
            b.min.y,
            (b.min.z + b.max.z) * 0.5,
        )
        .as_dvec3();
        for v in &mut self.vertices {
            *v = (v.as_dvec3() - c).as_vec3();
        }
    }

    /// Checks that the model can be ray-cast: at least one triangle, every index in range,
    /// every coordinate finite. `what` names the model in the error.
    ///
    /// # Errors
    /// [`SourceError::BadModel`].
    pub fn validate(&self, what: &str) -> Result<(), SourceError> {
        let bad = |message: String| SourceError::BadModel {
            what: what.to_owned(),
            message,
        };
        if self.indices.is_empty() {
            return Err(bad("no triangles".into()));
        }
        if let Some(i) = self.vertices.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!("vertex {i} is not finite")));
        }
        let n = self.vertices.len();
        if let Some(t) = self
            .indices
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= n))
        {
            return Err(bad(format!("triangle {t} refers to a missing vertex")));
        }
        Ok(())
    }

    /// A parry3d `TriMesh` (with its BVH) of this model, for ray casting and point queries.
    ///
    /// # Errors
    /// [`SourceError::BadModel`] when [`Model::validate`] fails or parry rejects the mesh.
    pub fn to_trimesh(&self) -> Result<TriMesh, SourceError> {
        self.validate("for the simulator")?;
        TriMesh::new(self.vertices.clone(), self.indices.clone()).map_err(|e| {
            SourceError::BadModel {
                what: "for the simulator".into(),
                message: e.to_string(),
            }
        })
    }
}

/// Loads a model file, the format chosen by the extension (case-insensitive): STL (binary or
/// ASCII), OBJ, PLY (ASCII or binary) or 3MF, all through `voxoct_stl`. The model keeps the
/// file's coordinates and units (STL files for printing are usually in millimetres and
/// Z-up: [`load_model_as`] converts them to the platform frame).
///
/// ```
/// use voxoct_kinect::{load_model, SimConfig, SimulatedKinect};
/// let path = std::env::temp_dir().join("voxoct-kinect-doc-tetra.obj");
/// std::fs::write(&path, "v 0 0 0\nv 20 0 0\nv 0 20 0\nv 0 0 20\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")?;
/// // A Z-up model in millimetres: turn it Y-up and make it 12 cm tall on the platform.
/// let mut model = load_model(&path)?.z_up_to_y_up();
/// model.place_on_platform(0.12)?;
/// let b = model.bounds().unwrap();
/// assert!((b.max.y - 0.12).abs() < 1e-6 && b.min.y == 0.0);
/// let sim = SimulatedKinect::new(&model, SimConfig::default())?;
/// # let _ = std::fs::remove_file(&path);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`SourceError::Io`], [`SourceError::Stl`] (STL, PLY and 3MF decoding),
/// [`SourceError::Obj`] (with the line number), [`SourceError::UnknownModelFormat`], or
/// [`SourceError::BadModel`] for a file without triangles or with non-finite coordinates.
pub fn load_model(path: &Path) -> Result<Model, SourceError> {
    load_model_file(path).map(|(model, _)| model)
}

/// [`load_model`], and the metres per file unit when the file states it (3MF).
fn load_model_file(path: &Path) -> Result<(Model, Option<f64>), SourceError> {
    let format =
        voxoct_stl::MeshFormat::from_path(path).map_err(|_| SourceError::UnknownModelFormat {
            path: path.to_owned(),
        })?;
    let io = |source| SourceError::Io {
        path: path.to_owned(),
        source,
    };
    let decoder = |source| SourceError::Stl {
        path: path.to_owned(),
        source,
    };
    voxoct_stl::check_mesh_file(path).map_err(|e| match e {
        voxoct_stl::StlError::Io(source) => io(source),
        e => decoder(e),
    })?;
    let (model, unit) = match format {
        voxoct_stl::MeshFormat::Obj => {
            let text = std::fs::read_to_string(path).map_err(io)?;
            (parse_obj(&text, path)?, None)
        }
        voxoct_stl::MeshFormat::Stl => {
            // The soup as it is (no welding): the simulator ray-casts triangles.
            let bytes = std::fs::read(path).map_err(io)?;
            let tris = voxoct_stl::parse(&bytes).map_err(decoder)?;
            (Model::from_triangles(&tris), None)
        }
        // 3MF and PLY: indexed meshes, read as voxoct-stl reads them (a 3MF states its unit).
        f @ (voxoct_stl::MeshFormat::ThreeMf | voxoct_stl::MeshFormat::Ply) => {
            let bytes = std::fs::read(path).map_err(io)?;
            let m = voxoct_stl::read_mesh(&bytes, f).map_err(decoder)?;
            let model = Model {
                vertices: m.vertices,
                indices: m.triangles,
            };
            (model, m.metres_per_unit)
        }
    };
    model.validate(&path.display().to_string())?;
    Ok((model, unit))
}

/// Which axis of a model file points up (the one type for every mesh file's up axis).
pub use voxoct_stl::UpAxis as ModelUp;

/// How to read a model file's numbers: its unit and its up axis.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModelConvention {
    /// Metres per file unit; `None` takes the file's own unit where it states one (3MF) and
    /// millimetres (0.001) otherwise.
    pub metres_per_unit: Option<f64>,
    /// The file's up axis.
    pub up: ModelUp,
}

impl ModelConvention {
    /// Metres per unit of a file that states `file_unit` (or not).
    #[must_use]
    pub fn metres_per_unit_for(&self, file_unit: Option<f64>) -> f64 {
        self.metres_per_unit.or(file_unit).unwrap_or(0.001)
    }
}

/// Loads a model file as slicers write it and stands it on the platform, keeping its size
/// and orientation: the numbers are converted to metres (see [`ModelConvention`]), a Z-up
/// file is turned Y-up by [`Model::z_up_to_y_up`] (a proper rotation), and the model is
/// moved — not scaled — so that its bounding box is centred on the turntable axis and its
/// lowest point is on the platform (y = 0).
///
/// ```
/// use voxoct_kinect::{load_model_as, ModelConvention};
/// let path = std::env::temp_dir().join("voxoct-kinect-doc-tower.obj");
/// // 40 mm wide, 70 mm tall along +Z.
/// std::fs::write(&path, "v 0 0 0\nv 40 0 0\nv 0 40 0\nv 0 0 70\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")?;
/// let model = load_model_as(&path, &ModelConvention::default())?;
/// let b = model.bounds().unwrap();
/// assert!((b.max.y - 0.07).abs() < 1e-6 && b.min.y == 0.0); // 70 mm tall, standing up
/// assert!(model.signed_volume() > 0.0);
/// # let _ = std::fs::remove_file(&path);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`load_model`]; [`SourceError::BadModel`] for a unit that is not finite and positive.
pub fn load_model_as(path: &Path, convention: &ModelConvention) -> Result<Model, SourceError> {
    let (mut model, file_unit) = load_model_file(path)?;
    let m = convention.metres_per_unit_for(file_unit);
    if !(m.is_finite() && m > 0.0) {
        return Err(SourceError::BadModel {
            what: path.display().to_string(),
            message: format!("unit of {m} m is not positive"),
        });
    }
    for v in &mut model.vertices {
        *v = (v.as_dvec3() * m).as_vec3();
    }
    if convention.up == ModelUp::Z {
        model = model.z_up_to_y_up();
    }
    model.stand_on_platform();
    model.validate(&path.display().to_string())?;
    Ok(model)
}

/// Parses Wavefront OBJ text (see `voxoct_stl::obj::parse_obj`): `v x y z [w]` and `f`
/// lines (polygons are fan-triangulated; `a`, `a/b`, `a//c`, `a/b/c` forms; negative
/// indices count back from the last vertex read); every other statement is ignored. `path`
/// only names the file in errors.
///
/// # Errors
/// [`SourceError::Obj`] naming the line: a bad number, a face with fewer than three
/// vertices, an index of 0 or out of range.
pub fn parse_obj(text: &str, path: &Path) -> Result<Model, SourceError> {
    voxoct_stl::obj::parse_obj(text)
        .map(|(vertices, indices)| Model { vertices, indices })
        .map_err(|e| match e {
            voxoct_stl::StlError::Obj { line, message } => SourceError::Obj {
                path: path.to_owned(),
                line,
                message,
            },
            other => SourceError::Obj {
                path: path.to_owned(),
                line: 0,
                message: other.to_string(),
            },
        })
}

/// A closed surface of revolution about +Y. `profile` is a polyline of `(radius, y)` from a
/// point on the axis to another point on the axis, with the solid on its left (counter-
/// clockwise in the (r, y) half-plane, e.g. bottom centre → outer rim → top centre); it is
/// swept through `segments` steps starting at angle `theta0`. Outward winding.
fn lathe(profile: &[(f32, f32)], segments: u32, theta0: f32) -> Model {
    debug_assert!(profile.len() >= 3 && segments >= 3);
    let ring = |r: f32, y: f32| -> Vec<Vec3> {
        (0..segments)
            .map(|j| {
                let t = theta0 + TAU * j as f32 / segments as f32;
                Vec3::new(r * t.cos(), y, r * t.sin())
            })
            .collect()
    };
    let n = profile.len();
    let mut vertices = vec![Vec3::new(0.0, profile[0].1, 0.0)];
    for &(r, y) in &profile[1..n - 1] {
        vertices.extend(ring(r, y));
    }
    let top = vertices.len() as u32;
    vertices.push(Vec3::new(0.0, profile[n - 1].1, 0.0));
    let at = |ring: usize, j: u32| 1 + ring as u32 * segments + j % segments;
    let mut indices = Vec::new();
    for j in 0..segments {
        indices.push([at(0, j), at(0, j + 1), 0]);
        for i in 0..n - 3 {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
            indices.push([a, b, c]);
            indices.push([b, d, c]);
        }
        indices.push([at(n - 3, j), top, at(n - 3, j + 1)]);
    }
    Model { vertices, indices }
}

/// A closed cylinder about +Y standing on y = 0.
pub(crate) fn cylinder(radius: f32, height: f32, segments: u32) -> Model {
    lathe(
        &[(0.0, 0.0), (radius, 0.0), (radius, height), (0.0, height)],
        segments,
        0.0,
    )
}

/// A UV sphere of radius `r` centred on the origin.
fn sphere(r: f32, slices: u32, stacks: u32) -> Model {
    let profile: Vec<(f32, f32)> = (0..=stacks)
        .map(|i| {
            let a = -std::f32::consts::FRAC_PI_2 + std::f32::consts::PI * i as f32 / stacks as f32;
            // Exact zeros at the poles keep them on the axis.
            let rr = if i == 0 || i == stacks {
                0.0
            } else {
                r * a.cos()
            };
            (rr, r * a.sin())
        })
        .collect();
    lathe(&profile, slices, 0.0)
}

/// An axis-aligned box of `size`, centred on the Y axis, standing on y = 0 (a four-sided
/// lathe rotated by 45° and scaled, so it is closed and outward-wound like the others).
fn lathe_box(size: Vec3) -> Model {
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let mut m = lathe(
        &[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
        4,
        std::f32::consts::FRAC_PI_4,
    );
    let s = Vec3::new(size.x * 0.5 / h, size.y, size.z * 0.5 / h);
    for v in &mut m.vertices {
        *v *= s;
    }
    m
}

/// A torus about +Y centred on the origin: major radius `big`, tube radius `small`.
fn torus(big: f32, small: f32, segments: u32, tube_segments: u32) -> Model {
    let ring = |k: u32| {
        let p = TAU * (k % tube_segments) as f32 / tube_segments as f32;
        (big + small * p.cos(), small * p.sin())
    };
    let mut vertices = Vec::new();
    for k in 0..tube_segments {
        let (r, y) = ring(k);
        for j in 0..segments {
            let t = TAU * j as f32 / segments as f32;
            vertices.push(Vec3::new(r * t.cos(), y, r * t.sin()));
        }
    }
    let at = |k: u32, j: u32| (k % tube_segments) * segments + j % segments;
    let mut indices = Vec::new();
    for k in 0..tube_segments {
        for j in 0..segments {
            let (a, b, c, d) = (at(k, j), at(k + 1, j), at(k, j + 1), at(k + 1, j + 1));
            indices.push([a, b, c]);
            indices.push([b, d, c]);
        }
    }
    Model { vertices, indices }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Every undirected edge is used by exactly two triangles, once in each direction.
    fn closed_and_oriented(m: &Model) -> bool {
        let mut count: HashMap<(u32, u32), i32> = HashMap::new();
        for &[a, b, c] in &m.indices {
            for (p, q) in [(a, b), (b, c), (c, a)] {
                *count.entry((p, q)).or_default() += 1;
            }
        }
        count
            .iter()
            .all(|(&(p, q), &n)| n == 1 && count.get(&(q, p)) == Some(&1))
    }

    #[test]
    fn builtins_are_closed_outward_and_stand_on_the_platform() {
        for name in Model::BUILTIN_NAMES {
            let m = Model::builtin(name).unwrap();
            // Every component is closed and oriented, so the whole edge multiset is too.
            assert!(closed_and_oriented(&m), "{name} is not closed/oriented");
            assert!(m.signed_volume() > 0.0, "{name} is wound inwards");
            let b = m.bounds().unwrap();
            assert!(b.min.y.abs() < 1e-6, "{name} min y {}", b.min.y);
            let h = b.max.y - b.min.y;
            assert!((0.099..=0.15).contains(&h), "{name} height {h}");
            assert!(b.min.x >= -0.15 && b.max.x <= 0.15, "{name} {b:?}");
            assert!(b.min.z >= -0.15 && b.max.z <= 0.15, "{name} {b:?}");
            m.to_trimesh().unwrap();
        }
        assert!(Model::builtin("teapot").is_none());
    }

    #[test]
    fn sphere_volume_is_close_to_the_formula() {
        let m = Model::builtin("sphere").unwrap();
        let exact = 4.0 / 3.0 * std::f32::consts::PI * 0.06f32.powi(3);
        let v = m.signed_volume();
        assert!((v / exact - 1.0).abs() < 0.01, "{v} vs {exact}");
    }

    #[test]
    fn mug_has_a_hollow_and_a_handle() {
        use parry3d::query::{Ray, RayCast};
        let mesh = Model::builtin("mug").unwrap().to_trimesh().unwrap();
        let hit = |o: Vec3, d: Vec3| {
            let t = mesh.cast_local_ray(&Ray::new(o, d), 1.0, true).unwrap();
            o + d * t
        };
        // (Rays avoid the mesh's edges: parry's ray/triangle test may miss an exact edge.)
        // Straight down near the axis: the inner floor, 8 mm above the platform.
        let p = hit(Vec3::new(0.0011, 0.2, 0.0007), -Vec3::Y);
        assert!((p.y - 0.008).abs() < 1e-5, "{p}");
        // Down through the wall: the rim.
        let p = hit(Vec3::new(0.042, 0.2, 0.0013), -Vec3::Y);
        assert!((p.y - 0.10).abs() < 1e-5, "{p}");
        // Towards the axis at the handle's height: the handle's outer side.
        let p = hit(Vec3::new(0.3, 0.0553, 0.0003), -Vec3::X);
        assert!((p.x - (0.0705 + 0.024 + 0.0065)).abs() < 1e-4, "{p}");
    }

    #[test]
    fn obj_parses_fans_negative_and_slash_forms() {
        let text = "# a quad and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                    vn 0 0 1\nf 1/1/1 2/2/1 3//1 4\nv 0 0 1\nf -1 -5 -4\n";
        let m = parse_obj(text, Path::new("t.obj")).unwrap();
        assert_eq!(m.vertices.len(), 5);
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3], [4, 0, 1]]);
    }

    #[test]
    fn obj_errors_name_the_line() {
        let cases = [
            ("v 0 0 0\nv 1 x 0\n", 2, "bad vertex coordinate"),
            ("v 0 0\n", 1, "2 coordinates"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "at least 3"),
            ("v 0 0 0\n\nf 1 2 0\n", 3, "index 0"),
            ("v 0 0 0\nf 1 2 -3\n", 2, "before the first vertex"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", 4, "has 3 vertices"),
            ("v 0 0 0\nf a b c\n", 2, "bad face index"),
        ];
        for (text, line, needle) in cases {
            match parse_obj(text, Path::new("m.obj")) {
                Err(SourceError::Obj {
                    line: l, message, ..
                }) => {
                    assert_eq!(l, line, "{text:?}: {message}");
                    assert!(message.contains(needle), "{text:?}: {message}");
                }
                other => panic!("{text:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn placing_scales_centres_and_grounds() {
        let mut m = Model::builtin("box")
            .unwrap()
            .translated(Vec3::new(3.0, -2.0, 1.0))
            .rotated(Mat3::from_diagonal(Vec3::splat(10.0)));
        m.place_on_platform(0.1).unwrap();
        let b = m.bounds().unwrap();
        assert!(
            (b.max.y - 0.1).abs() < 1e-5 && b.min.y.abs() < 1e-6,
            "{b:?}"
        );
        assert!((b.min.x + b.max.x).abs() < 1e-5 && (b.min.z + b.max.z).abs() < 1e-5);
        assert!(Model::default().place_on_platform(0.1).is_err());
        assert!(m.place_on_platform(f32::NAN).is_err());
    }

    #[test]
    fn z_up_becomes_y_up() {
        let m = Model {
            vertices: vec![Vec3::Z],
            indices: vec![],
        }
        .z_up_to_y_up();
        assert!((m.vertices[0] - Vec3::Y).length() < 1e-6);
    }
}
