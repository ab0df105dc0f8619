//! Depth sources for voxoct: a simulated Kinect v1, replay of libfreenect "fakenect"
//! recordings, and a live Kinect v1 through the system libfreenect (feature `freenect`).
//!
//! Every source implements [`DepthSource`], so the scan pipeline takes a
//! `Box<dyn DepthSource>` and does not care where frames come from. Frames are
//! [`DepthFrame`]s in millimetres (`unit_m = 0.001`, 0 = no reading), depth along the optical
//! axis, in the OpenCV camera frame of SCAN_FORMAT.md.
//!
//! # The simulated Kinect
//! [`SimulatedKinect`] ray-casts a triangle mesh standing on a turntable (parry3d `TriMesh`
//! and its BVH). The object turns by `+angle` about +Y with
//! [`SimulatedKinect::set_turntable_angle_deg`], so frames back-projected through
//! [`Rig::camera_to_object`]`(angle)` land on the unrotated model. The scene also holds the
//! turntable disk (top face at y = 0) and the floor, as a real rig sees them. The sensor model
//! follows Khoshelham & Elberink (2012): disparity `d = f·b / z` with `f·b = 580 px × 0.075 m`,
//! Gaussian disparity noise of 1/8 px quantised to 1/8 px, no reading outside 0.4–4.0 m, the
//! IR projector's shadow (a second ray from the projector, 7.5 cm beside the camera),
//! drop-outs at grazing incidence and flicker at depth edges; seeded ([`SimConfig::seed`]),
//! with an exact, noise-free mode ([`SimConfig::exact`]). Built-in closed models
//! ([`Model::builtin`]: figurine, mug, sphere, torus, box, cylinder) need no file; any STL or
//! OBJ loads with [`load_model`] and [`Model::place_on_platform`].
//!
//! Each pixel's rays are cast once per turntable angle and cached; each frame only draws
//! noise. Measured on an idle 2-core machine (test profile, 640×480, figurine): about 75 ms
//! for the first frame at a new angle and about 8 ms for each further frame, so a scan of
//! 8 snapshots × 10 frames renders in about 1.2 s (the `sim_timing` example measures it).
//!
//! # Fakenect replay
//! [`FakenectSource`] serves the depth frames of a directory recorded by libfreenect's
//! `record` tool, converting raw 11-bit disparities with [`raw_disparity_to_m`].
//!
//! # Live Kinect v1
//! With the `freenect` feature, `KinectSource::open(index)` reads a device through
//! `libfreenect_sync` in millimetre mode, and `KinectSource::open_with` in any
//! [`KinectDepth`] mode — raw disparities are converted with the same
//! [`raw_disparity_to_m`] as the fakenect replay; without a device it returns
//! [`SourceError::NoKinect`] at once, with libfreenect's own messages quietened. Under
//! libfreenect's fakenect library it replays a recording such as [`FakenectWriter`] writes:
//! a live scan rehearsed without the hardware.
//!
//! # Example
//! An exact frame of a 6 cm sphere seen head-on from 0.7 m: the pixel on the optical axis
//! sees the sphere's front at 0.64 m.
//! ```
//! use voxoct_kinect::{DepthSource, SimConfig, SimulatedKinect, glam::Vec3};
//! use voxoct_depth::Rig;
//! use std::time::Duration;
//!
//! let config = SimConfig {
//!     rig: Rig { tilt_deg: 0.0, sensor_position_m: Vec3::new(0.0, 0.06, 0.70) },
//!     exact: true,
//!     ..SimConfig::default()
//! };
//! let mut source: Box<dyn DepthSource> = Box::new(SimulatedKinect::builtin("sphere", config)?);
//! let frame = source.grab(Duration::from_secs(1))?;
//! assert_eq!((frame.width, frame.height), (640, 480));
//! let z = frame.depth_m(320, 240).expect("the sphere is in front");
//! assert!((z - 0.64).abs() <= 0.001, "{z}");
//! # Ok::<(), voxoct_kinect::SourceError>(())
//! ```

mod error;
mod fakenect;
#[cfg(feature = "freenect")]
mod kinect;
mod model;
mod sim;

use std::time::Duration;

pub use error::SourceError;
pub use fakenect::{
    FAKENECT_HEIGHT, FAKENECT_WIDTH, FakenectSource, FakenectWriter, MAX_DEPTH_M, RAW_NO_READING,
    decode_fakenect_depth, encode_fakenect_depth, m_to_raw_disparity, raw_disparity_to_m,
};
pub use glam;
#[cfg(feature = "freenect")]
pub use kinect::{KinectOptions, KinectSource};
pub use model::{Model, ModelConvention, ModelUp, load_model, load_model_as, parse_obj};
pub use sim::{NoiseModel, SimConfig, SimTimings, SimulatedKinect};
pub use voxoct_depth::{DepthFrame, Intrinsics, Rig};

/// Which depth stream of a live Kinect v1 is read (`KinectSource`, feature `freenect`).
///
/// Every mode is delivered as millimetre [`DepthFrame`]s. Parses from and prints as `mm`,
/// `raw`, `registered`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum KinectDepth {
    /// `FREENECT_DEPTH_MM`: libfreenect converts with the device's own factory calibration
    /// (the best choice on a real device; not served by libfreenect 0.5's fakenect).
    #[default]
    Mm,
    /// `FREENECT_DEPTH_11BIT`: raw disparities, converted with [`raw_disparity_to_m`] — the
    /// model the fakenect replay uses; the only format libfreenect 0.5's fakenect serves.
    Raw,
    /// `FREENECT_DEPTH_REGISTERED`: millimetres resampled onto the RGB camera's 640×480 image,
    /// so the RGB camera's intrinsics apply (give them in the scanner config). Real device
    /// only: libfreenect 0.5's fakenect does not serve it.
    Registered,
}

impl KinectDepth {
    /// Every mode's name, as parsed.
    pub const NAMES: [&'static str; 3] = ["mm", "raw", "registered"];
}

impl std::fmt::Display for KinectDepth {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Mm => "mm",
            Self::Raw => "raw",
            Self::Registered => "registered",
        })
    }
}

impl std::str::FromStr for KinectDepth {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "mm" => Ok(Self::Mm),
            "raw" | "11bit" => Ok(Self::Raw),
            "registered" => Ok(Self::Registered),
            _ => Err(format!(
                "unknown Kinect depth mode {s:?}; choose one of {}",
                Self::NAMES.join(", ")
            )),
        }
    }
}

/// A source of depth frames: a sensor, a simulator or a recording.
///
/// Object-safe: the scan pipeline holds a `Box<dyn DepthSource>`. The frame size is that of
/// [`DepthSource::intrinsics`].
pub trait DepthSource {
    /// The depth camera's intrinsics; every frame is `width × height` of these.
    fn intrinsics(&self) -> Intrinsics;

    /// The next depth frame, waiting at most about `timeout` where the source can wait
    /// (each source documents what its timeout can do).
    ///
    /// # Errors
    /// The source's failures: no device, end of a recording, a malformed file, a timeout.
    fn grab(&mut self, timeout: Duration) -> Result<DepthFrame, SourceError>;

    /// The sensor's pitch DOWN from the horizon in degrees (the sign of `Rig::tilt_deg`),
    /// where the source knows it.
    fn tilt_deg(&mut self) -> Option<f32> {
        None
    }

    /// Releases the device; the source should not be used afterwards.
    ///
    /// # Errors
    /// A device that fails to close.
    fn shutdown(&mut self) -> Result<(), SourceError> {
        Ok(())
    }
}
