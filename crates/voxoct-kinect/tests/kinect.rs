//! The live Kinect source without a device: opening fails fast and clearly.
#![cfg(feature = "freenect")]

use std::time::{Duration, Instant};

use voxoct_kinect::{KinectSource, SourceError};

#[test]
fn opening_without_a_device_is_a_clear_error() {
    let start = Instant::now();
    match KinectSource::open(0) {
        Err(e @ SourceError::NoKinect { index: 0, .. }) => {
            assert!(KinectSource::library_available());
            let msg = e.to_string();
            assert!(
                msg.contains("no Kinect v1 found") && msg.contains("USB"),
                "{msg}"
            );
        }
        Err(SourceError::FreenectUnavailable) => assert!(!KinectSource::library_available()),
        Err(other) => panic!("unexpected error: {other}"),
        Ok(_) => {
            println!("a Kinect is attached: nothing to check here");
            return;
        }
    }
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );
    assert!(matches!(
        KinectSource::open(-1),
        Err(SourceError::Config { field: "index", .. })
    ));
}
