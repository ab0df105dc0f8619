//! The Kinect v1 depth noise: one model for the filters, the carving margin and the simulator.
//!
//! The Kinect v1 measures a disparity `d = f·b / z` (pixels) between its projected speckle
//! pattern and a reference; the disparity's random error `σ_d` becomes a depth error that
//! grows with the square of the depth:
//!
//! `σ_z = z² · σ_d / (f·b)`, with `f·b` = 580 px × 0.075 m = 43.5 px·m
//! ([`KINECT_V1_FOCAL_BASELINE_PX_M`]).
//!
//! Khoshelham & Elberink (2012), "Accuracy and resolution of Kinect depth data for indoor
//! mapping applications", Sensors 12(2), calibrate `m/(f·b)` = 2.85·10⁻⁵ cm⁻¹ per raw
//! disparity unit (1/8 px) and take `σ_d` = ½ unit (1/16 px), which gives
//! `σ_z = 1.425·10⁻³ m⁻¹ · z²` ([`KINECT_V1_SIGMA_COEFF`]): 0.7 mm at 0.7 m, 1.4 mm at 1 m,
//! 3.6 cm at 5 m. A real Kinect v1 frame (NYU Depth v2) agrees: planes fitted to its walls
//! leave 0.35–0.5 raw units of scatter (ARCHITECTURE.md, voxoct-depth, gives the measurement).

/// `f · b` of the Kinect v1: focal length (580 px) times the projector–camera baseline
/// (0.075 m), px·m.
pub const KINECT_V1_FOCAL_BASELINE_PX_M: f32 = 580.0 * 0.075;

/// `σ_z / z²` of a Kinect v1 depth reading, m⁻¹ (Khoshelham & Elberink 2012).
pub const KINECT_V1_SIGMA_COEFF: f32 = 1.425e-3;

/// Axial noise (one standard deviation) of a Kinect v1 reading at depth `z_m`, metres:
/// `KINECT_V1_SIGMA_COEFF · z²`.
#[inline]
#[must_use]
pub fn kinect_v1_sigma(z_m: f32) -> f32 {
    KINECT_V1_SIGMA_COEFF * z_m * z_m
}

/// The disparity noise `σ_d` of the Kinect v1 that gives [`kinect_v1_sigma`], pixels:
/// `KINECT_V1_SIGMA_COEFF · f·b` ≈ 0.062 px (half a raw disparity unit of 1/8 px).
#[must_use]
pub const fn kinect_v1_disparity_sigma_px() -> f32 {
    KINECT_V1_SIGMA_COEFF * KINECT_V1_FOCAL_BASELINE_PX_M
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disparity_noise_gives_the_depth_noise() {
        // σ_z = z² σ_d / (f·b) at 1 m and 2 m.
        for z in [1.0f32, 2.0] {
            let from_disparity =
                z * z * kinect_v1_disparity_sigma_px() / KINECT_V1_FOCAL_BASELINE_PX_M;
            assert!((from_disparity - kinect_v1_sigma(z)).abs() < 1e-9, "{z}");
        }
        // Half a raw unit of 1/8 px.
        assert!((kinect_v1_disparity_sigma_px() - 0.0625).abs() < 0.001);
    }
}
