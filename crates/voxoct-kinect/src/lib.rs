//! Depth sources for voxoct: a simulated Kinect v1, replay of libfreenect "fakenect"
//! recordings, and a live Kinect v1 through the system libfreenect (feature `freenect`).
//!
//! Every source implements [`DepthSource`], so the scan pipeline takes a
//! `Box<dyn DepthSource>` and does not care where frames come from. Frames are
//! [`DepthFrame`]s in millimetres (`unit_m = 0.001`, 0 = no reading), depth along the optical
//! axis, in the OpenCV camera frame of SCAN_FORMAT.md.
//!
//! - [`SimulatedKinect`]: ray-casts a mesh on a turntable with the Kinect v1 noise model
//!   of `voxoct_depth::noise` ([`NoiseModel`], [`SimConfig`]); built-in models
//!   ([`Model::builtin`]) or any STL/OBJ/PLY/3MF ([`load_model`]).
//! - [`FakenectSource`] replays a libfreenect `fakenect` recording; [`FakenectWriter`]
//!   writes one.
//! - `KinectSource` (feature `freenect`) reads a live Kinect v1 through libfreenect.
//!
//! ARCHITECTURE.md (section voxoct-kinect) explains the design; timings are in
//! BENCHMARKS.md.
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
