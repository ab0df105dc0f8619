//! Back-projection, the rig transform and clipping: a frame becomes a [`Snapshot`], the
//! grid of its points in the common object frame.

use glam::{Affine3A, Vec3, Vec3A};

use crate::error::FrameError;
use crate::filter::check_frame_size;
use crate::{ClipBox, DepthFrame, Intrinsics, Rig};

/// The transformed, clipped point grid of one snapshot, in the common object frame.
///
/// `points` has one entry per pixel, row-major like the frame; a pixel without a
/// reading, or whose point fell outside the clip box, is a hole: a point whose
/// coordinates are all NaN (see [`Snapshot::is_hole`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Columns of the grid.
    pub width: u32,
    /// Rows of the grid.
    pub height: u32,
    /// The camera → object transform the points went through.
    pub camera_to_object: Affine3A,
    /// The turntable angle of the snapshot, degrees.
    pub angle_deg: f32,
    /// `width * height` points, metres, object frame; holes are NaN.
    pub points: Vec<Vec3>,
}

/// The point that marks a hole.
pub const HOLE: Vec3 = Vec3::NAN;

impl Snapshot {
    /// Back-projects `frame` through `intr`, transforms it by `rig` at turntable angle
    /// `angle_deg` ([`Rig::camera_to_object`]) and clips it to `clip`.
    ///
    /// Errors when the frame's size differs from the intrinsics', when its data does not
    /// match its size, or when the unit, the angle or the intrinsics are not usable numbers.
    pub fn from_frame(
        frame: &DepthFrame,
        intr: &Intrinsics,
        rig: &Rig,
        angle_deg: f32,
        clip: &ClipBox,
    ) -> Result<Self, FrameError> {
        let mut s = Self {
            width: 0,
            height: 0,
            camera_to_object: Affine3A::IDENTITY,
            angle_deg,
            points: Vec::new(),
        };
        s.fill_from_frame(frame, intr, rig, angle_deg, clip)?;
        Ok(s)
    }

    /// [`Snapshot::from_frame`] into `self`, reusing its point buffer.
    pub fn fill_from_frame(
        &mut self,
        frame: &DepthFrame,
        intr: &Intrinsics,
        rig: &Rig,
        angle_deg: f32,
        clip: &ClipBox,
    ) -> Result<(), FrameError> {
        check_frame_size(0, frame, intr.width, intr.height)?;
        let positive = |name, x: f32| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(FrameError::InvalidArgument {
                    name,
                    reason: format!("must be a positive number, got {x}"),
                })
            }
        };
        positive("fx", intr.fx)?;
        positive("fy", intr.fy)?;
        for (name, x) in [("cx", intr.cx), ("cy", intr.cy), ("angle_deg", angle_deg)] {
            if !x.is_finite() {
                return Err(FrameError::InvalidArgument {
                    name,
                    reason: format!("must be finite, got {x}"),
                });
            }
        }
        let t = rig.camera_to_object(angle_deg);
        if !(t.matrix3.is_finite() && t.translation.is_finite()) {
            return Err(FrameError::InvalidArgument {
                name: "rig",
                reason: format!("transform is not finite: {rig:?}"),
            });
        }
        let w = frame.width as usize;
        let m = t.matrix3;
        // p_obj = M · z·(xf[u], yf[v], 1) + t = z·(col[u] + row[v]) + t.
        let col: Vec<Vec3A> = (0..w)
            .map(|u| m.x_axis * ((u as f32 - intr.cx) / intr.fx))
            .collect();
        let unit = frame.unit_m;
        let (cmin, cmax) = (Vec3A::from(clip.min), Vec3A::from(clip.max));
        self.width = frame.width;
        self.height = frame.height;
        self.camera_to_object = t;
        self.angle_deg = angle_deg;
        self.points.clear();
        self.points.reserve(frame.data.len());
        for (v, row_data) in frame.data.chunks_exact(w.max(1)).enumerate() {
            let row = m.y_axis * ((v as f32 - intr.cy) / intr.fy) + m.z_axis;
            self.points
                .extend(row_data.iter().zip(&col).map(|(&d, &c)| {
                    let z = f32::from(d) * unit;
                    let p = (c + row) * z + t.translation;
                    if d != 0 && p.cmpge(cmin).all() && p.cmple(cmax).all() {
                        Vec3::from(p)
                    } else {
                        HOLE
                    }
                }));
        }
        Ok(())
    }

    /// Whether point `i` is a hole.
    #[inline]
    #[must_use]
    pub fn is_hole(&self, i: usize) -> bool {
        self.points[i].x.is_nan()
    }

    /// Number of points that are not holes.
    #[must_use]
    pub fn valid_count(&self) -> usize {
        self.points.iter().filter(|p| !p.x.is_nan()).count()
    }

    /// The valid points, in grid order.
    pub fn valid_points(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.points.iter().copied().filter(|p| !p.x.is_nan())
    }

    /// The sensor's optical centre in the object frame.
    #[must_use]
    pub fn sensor_position(&self) -> Vec3 {
        Vec3::from(self.camera_to_object.translation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> Rig {
        Rig {
            tilt_deg: 20.0,
            sensor_position_m: Vec3::new(0.0, 0.3, 0.7),
        }
    }

    fn open_clip() -> ClipBox {
        ClipBox {
            min: Vec3::splat(-10.0),
            max: Vec3::splat(10.0),
        }
    }

    #[test]
    fn from_frame_matches_the_plain_formula() {
        let intr = Intrinsics {
            width: 7,
            height: 5,
            fx: 5.0,
            fy: 6.0,
            cx: 3.0,
            cy: 2.0,
        };
        let mut f = DepthFrame::empty(7, 5, 0.001);
        for (i, d) in f.data.iter_mut().enumerate() {
            *d = if i % 4 == 0 { 0 } else { 500 + i as u16 * 3 };
        }
        let s = Snapshot::from_frame(&f, &intr, &rig(), 33.0, &open_clip()).unwrap();
        let t = rig().camera_to_object(33.0);
        assert_eq!(s.points.len(), f.len());
        for v in 0..5 {
            for u in 0..7 {
                let i = (v * 7 + u) as usize;
                match f.depth_m(u, v) {
                    None => assert!(s.is_hole(i)),
                    Some(z) => {
                        let want = t.transform_point3(intr.unproject(u as f32, v as f32, z));
                        assert!((s.points[i] - want).length() < 1e-6, "{u},{v}");
                    }
                }
            }
        }
        assert_eq!(s.valid_count(), f.data.iter().filter(|&&d| d != 0).count());
    }

    #[test]
    fn clipping_makes_holes_in_place() {
        let intr = Intrinsics {
            width: 2,
            height: 1,
            cx: 0.5,
            cy: 0.0,
            ..Intrinsics::KINECT_V1
        };
        let f = DepthFrame {
            width: 2,
            height: 1,
            unit_m: 0.001,
            data: vec![700, 2000],
        };
        let clip = ClipBox {
            min: Vec3::splat(-0.15),
            max: Vec3::splat(0.4),
        };
        let s = Snapshot::from_frame(&f, &intr, &rig(), 0.0, &clip).unwrap();
        assert_eq!(s.points.len(), 2);
        assert!(!s.is_hole(0));
        assert!(s.is_hole(1), "a point 2 m away is outside the clip box");
    }

    #[test]
    fn wrong_size_is_an_error() {
        let f = DepthFrame::empty(4, 4, 0.001);
        let e = Snapshot::from_frame(&f, &Intrinsics::KINECT_V1, &rig(), 0.0, &open_clip());
        assert!(matches!(
            e,
            Err(FrameError::FrameSizeMismatch {
                expected_w: 640,
                found_w: 4,
                ..
            })
        ));
    }
}
