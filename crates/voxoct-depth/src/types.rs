//! The basic types every stage shares: frames, intrinsics, the rig, the clip box and the
//! scanner settings that bundle them.

use glam::{Affine3A, Mat3A, Vec3, Vec3A};

/// One depth image: `width × height` values, row-major from the top-left pixel.
///
/// A value times [`DepthFrame::unit_m`] is the depth along the optical axis in metres;
/// 0 means "no reading".
#[derive(Debug, Clone, PartialEq)]
pub struct DepthFrame {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Metres per stored unit (0.001 for millimetres).
    pub unit_m: f32,
    /// `width * height` values, row-major; 0 = no reading.
    pub data: Vec<u16>,
}

impl DepthFrame {
    /// A frame with every pixel set to "no reading".
    #[must_use]
    pub fn empty(width: u32, height: u32, unit_m: f32) -> Self {
        Self {
            width,
            height,
            unit_m,
            data: vec![0; width as usize * height as usize],
        }
    }

    /// The raw value at column `u`, row `v`.
    ///
    /// # Panics
    /// When `(u, v)` is outside the frame.
    #[inline]
    #[must_use]
    pub fn get(&self, u: u32, v: u32) -> u16 {
        assert!(
            u < self.width && v < self.height,
            "pixel ({u}, {v}) outside {}x{}",
            self.width,
            self.height
        );
        self.data[v as usize * self.width as usize + u as usize]
    }

    /// Depth in metres at column `u`, row `v`; `None` for no reading.
    #[inline]
    #[must_use]
    pub fn depth_m(&self, u: u32, v: u32) -> Option<f32> {
        match self.get(u, v) {
            0 => None,
            d => Some(f32::from(d) * self.unit_m),
        }
    }

    /// Number of pixels.
    #[inline]
    #[must_use]
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the frame has no pixels.
    #[inline]
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

/// Pinhole intrinsics of the depth camera, pixels (pixel centres are integers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point, column.
    pub cx: f32,
    /// Principal point, row.
    pub cy: f32,
}

impl Intrinsics {
    /// Kinect v1 depth camera, 640×480, the nominal values most tools use (f = 580 px).
    pub const KINECT_V1: Self = Self {
        width: 640,
        height: 480,
        fx: 580.0,
        fy: 580.0,
        cx: 319.5,
        cy: 239.5,
    };

    /// Camera-frame point (OpenCV convention: x right, y down, z forward) of pixel
    /// `(u, v)` at depth `z` metres.
    #[inline]
    #[must_use]
    pub fn unproject(&self, u: f32, v: f32, z: f32) -> Vec3 {
        Vec3::new((u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z)
    }

    /// Pixel coordinates `(u, v)` and depth of a camera-frame point; `None` behind the camera.
    #[inline]
    #[must_use]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        (p.z > 0.0).then(|| {
            let [u, v, z] = self.project_any(p);
            (u, v, z)
        })
    }

    /// `[u, v, z]` of a camera-frame point: pixel coordinates (meaningful only for `z > 0`)
    /// and depth. The one projection formula of the crate ([`Intrinsics::project`] and the
    /// carving's block test use it, so their results agree exactly).
    #[inline]
    #[must_use]
    pub fn project_any(&self, p: Vec3) -> [f32; 3] {
        [
            p.x * self.fx / p.z + self.cx,
            p.y * self.fy / p.z + self.cy,
            p.z,
        ]
    }
}

impl Default for Intrinsics {
    fn default() -> Self {
        Self::KINECT_V1
    }
}

/// Where the sensor sits relative to the turntable (SCAN_FORMAT.md, `[rig]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig {
    /// The sensor is pitched DOWN by this angle, degrees.
    pub tilt_deg: f32,
    /// Sensor optical centre in the platform frame at turntable angle 0, metres.
    pub sensor_position_m: Vec3,
}

impl Rig {
    /// Camera frame → platform frame with the turntable at angle 0:
    /// `p_rig = R_x(-tilt) · diag(1, -1, -1) · p_cam + sensor_position`.
    #[must_use]
    pub fn camera_to_rig(&self) -> Affine3A {
        let flip = Mat3A::from_diagonal(Vec3::new(1.0, -1.0, -1.0));
        let r = Mat3A::from_rotation_x(-self.tilt_deg.to_radians()) * flip;
        Affine3A::from_mat3_translation(r.into(), self.sensor_position_m)
    }

    /// Camera frame → common object frame for a snapshot taken at turntable angle
    /// `angle_deg`: `p_obj = R_y(-angle) · p_rig`.
    #[must_use]
    pub fn camera_to_object(&self, angle_deg: f32) -> Affine3A {
        Affine3A::from_rotation_y(-angle_deg.to_radians()) * self.camera_to_rig()
    }

    /// The optical axis (camera +z) in the platform frame at angle 0.
    #[must_use]
    pub fn optical_axis(&self) -> Vec3 {
        Vec3::from(self.camera_to_rig().matrix3 * Vec3A::Z)
    }
}

/// The clip box in the common (platform/object) frame, metres, inclusive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClipBox {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl ClipBox {
    /// Whether `p` lies inside the closed box.
    #[inline]
    #[must_use]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
}

/// The `[sensor]` table: intrinsics and the depth unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorConfig {
    /// Image size, focal lengths and principal point.
    pub intrinsics: Intrinsics,
    /// Metres per stored depth value (0.001 = millimetres).
    pub depth_unit_m: f32,
}

impl Default for SensorConfig {
    /// Kinect v1 intrinsics, millimetre units.
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::KINECT_V1,
            depth_unit_m: 0.001,
        }
    }
}

/// The settings of a scanner: the `[sensor]`, `[rig]` and `[clip]` tables, either in a
/// scan's manifest or in a file of their own (which overrides a recorded or live scan's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScannerConfig {
    /// `[sensor]`.
    pub sensor: SensorConfig,
    /// `[rig]`.
    pub rig: Rig,
    /// `[clip]`.
    pub clip: ClipBox,
}

impl Default for ScannerConfig {
    /// The example of SCAN_FORMAT.md: Kinect v1, tilt 19.65°, sensor at (0, 0.30, 0.7) m,
    /// clip box ±0.15 m wide, 3 mm to 0.40 m high.
    fn default() -> Self {
        Self {
            sensor: SensorConfig::default(),
            rig: Rig {
                tilt_deg: 19.65,
                sensor_position_m: Vec3::new(0.0, 0.30, 0.7),
            },
            clip: ClipBox {
                min: Vec3::new(-0.15, 0.003, -0.15),
                max: Vec3::new(0.15, 0.40, 0.15),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn optical_axis_points_down_and_towards_the_axis() {
        let rig = Rig {
            tilt_deg: 30.0,
            sensor_position_m: Vec3::new(0.0, 0.3, 0.7),
        };
        let a = rig.optical_axis();
        let t = 30f32.to_radians();
        assert!(
            (a - Vec3::new(0.0, -t.sin(), -t.cos())).length() < 1e-6,
            "{a}"
        );
    }

    #[test]
    fn turntable_angle_rotates_into_the_object_frame() {
        let rig = Rig {
            tilt_deg: 0.0,
            sensor_position_m: Vec3::new(0.0, 0.0, 1.0),
        };
        // A point on the optical axis 1 m ahead is the platform origin.
        let p = rig
            .camera_to_object(90.0)
            .transform_point3(Vec3::new(0.0, 0.0, 1.0));
        assert!(p.length() < 1e-6, "{p}");
        // The sensor itself, at angle 90°, sits at R_y(-90°)·(0,0,1) = (-1, 0, 0) in the object frame.
        let s = rig.camera_to_object(90.0).transform_point3(Vec3::ZERO);
        assert!((s - Vec3::new(-1.0, 0.0, 0.0)).length() < 1e-6, "{s}");
    }
}
