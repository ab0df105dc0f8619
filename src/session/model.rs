//! A mesh file as the simulator's model: its units, and the placement rule.

use std::path::Path;

use voxoct_depth::ScannerConfig;
use voxoct_kinect::{Model, ModelConvention, ModelUp};

use super::{SessionError, input};

/// A model file is refused as "too small" when its largest side is under this many leaves:
/// most likely its numbers are metres or inches read as millimetres.
pub const MIN_MODEL_LEAVES: f32 = 10.0;

/// Units of a model file's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelUnits {
    /// Millimetres: how slicers and CAD tools write STL, OBJ and PLY files for printing.
    Mm,
    /// Metres: the library's own unit.
    M,
    /// Inches.
    In,
}

impl ModelUnits {
    /// Metres per unit.
    #[must_use]
    pub fn metres(self) -> f64 {
        match self {
            Self::Mm => 0.001,
            Self::M => 1.0,
            Self::In => 0.0254,
        }
    }

    /// The unit's short name (`mm`, `m`, `in`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Mm => "mm",
            Self::M => "m",
            Self::In => "in",
        }
    }
}

/// Loads a model file as its convention says, standing on the platform at its own size,
/// and checks that it fits the clip box while it turns and is at least
/// [`MIN_MODEL_LEAVES`] leaves of `leaf_m` across. Returns it with a description.
///
/// # Errors
/// [`SessionError::Input`] for `--model`: unreadable, empty, too large or too small.
pub fn load_model(
    path: &Path,
    units: Option<ModelUnits>,
    up: ModelUp,
    config: &ScannerConfig,
    leaf_m: f32,
) -> Result<(Model, String), SessionError> {
    let convention = ModelConvention {
        metres_per_unit: units.map(ModelUnits::metres),
        up,
    };
    let m = voxoct_kinect::load_model_as(path, &convention)
        .map_err(|e| input("--model", format!("--model: {e}")))?;
    let b = m.bounds().ok_or_else(|| {
        input(
            "--model",
            format!("--model {}: no vertices", path.display()),
        )
    })?;
    let size_mm = (b.max - b.min) * 1000.0;
    let up = match up {
        ModelUp::Z => "z",
        ModelUp::Y => "y",
    };
    let units = units.map_or("mm, or the file's own unit", ModelUnits::name);
    let described = format!(
        "{:.1} × {:.1} × {:.1} mm (width × depth × height; read as --model-units {units}, \
         --model-up {up})",
        size_mm.x, size_mm.z, size_mm.y
    );
    // The model turns about the Y axis: its farthest point from the axis sweeps a circle.
    let radius = m
        .vertices
        .iter()
        .map(|v| v.x.hypot(v.z))
        .fold(0.0f32, f32::max);
    let clip = config.clip;
    let room = [-clip.min.x, clip.max.x, -clip.min.z, clip.max.z]
        .into_iter()
        .fold(f32::INFINITY, f32::min);
    if radius > room || b.max.y > clip.max.y {
        return Err(input(
            "--model",
            format!(
                "--model {} is {described}: it does not fit the clip box while it turns (radius \
                 {:.1} mm of {:.1} mm, height up to {:.1} mm); give the file's units and up axis \
                 with --model-units and --model-up, or a larger [clip] with --config",
                path.display(),
                radius * 1000.0,
                room * 1000.0,
                clip.max.y * 1000.0
            ),
        ));
    }
    if size_mm.max_element() < MIN_MODEL_LEAVES * leaf_m * 1000.0 {
        return Err(input(
            "--model",
            format!(
                "--model {} is {described}: too small to scan at --leaf {} m; is the file in \
                 metres or inches (--model-units m / in)?",
                path.display(),
                leaf_m
            ),
        ));
    }
    Ok((
        m,
        format!("simulated Kinect v1, model {}, {described}", path.display()),
    ))
}
