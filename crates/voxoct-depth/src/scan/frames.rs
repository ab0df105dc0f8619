//! Depth frames as 16-bit greyscale PNG files.

use std::fs;
use std::io::{BufReader, BufWriter};
use std::path::Path;

use super::{MAX_FRAME_SIDE, ScanError};
use crate::filter::check_frame;
use crate::{DepthFrame, SensorConfig};

/// Reads a 16-bit greyscale PNG depth frame; `unit_m` becomes the frame's unit.
/// Errors name the file: missing, not a PNG, another bit depth or colour type.
pub fn read_png_frame(path: &Path, unit_m: f32) -> Result<DepthFrame, ScanError> {
    read_png_frame_sized(path, unit_m, None)
}

/// [`read_png_frame`] that refuses, before decoding any pixel, a PNG whose header is not
/// `expected` = (width, height); and that opens only regular files (a FIFO would block).
pub fn read_png_frame_sized(
    path: &Path,
    unit_m: f32,
    expected: Option<(u32, u32)>,
) -> Result<DepthFrame, ScanError> {
    let meta = fs::metadata(path).map_err(|e| ScanError::io(path, e))?;
    if !meta.is_file() {
        return Err(ScanError::BadFrameFile {
            path: path.to_owned(),
            reason: "not a regular file (a directory, device or FIFO)".into(),
        });
    }
    let file = fs::File::open(path).map_err(|e| ScanError::io(path, e))?;
    let png_err = |e: png::DecodingError| ScanError::Png {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let mut dec = png::Decoder::new(BufReader::new(file));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec.read_info().map_err(png_err)?;
    let info = reader.info();
    let (w, h) = (info.width, info.height);
    if let Some((ew, eh)) = expected
        && (w, h) != (ew, eh)
    {
        return Err(ScanError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("frame is {w}x{h}, the sensor is {ew}x{eh}"),
        });
    }
    if w > MAX_FRAME_SIDE || h > MAX_FRAME_SIDE {
        return Err(ScanError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("{w}x{h} is larger than {MAX_FRAME_SIDE} pixels a side"),
        });
    }
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(ScanError::BadFrameFile {
            path: path.to_owned(),
            reason: format!(
                "{}-bit {:?} PNG; a depth frame is a 16-bit greyscale PNG",
                info.bit_depth as u8, info.color_type
            ),
        });
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| ScanError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("{w}x{h} is too large"),
        })?;
    let mut buf = vec![0u8; size];
    reader.next_frame(&mut buf).map_err(png_err)?;
    let n = w as usize * h as usize;
    if buf.len() < 2 * n {
        return Err(ScanError::BadFrameFile {
            path: path.to_owned(),
            reason: format!("{} bytes of pixels for {w}x{h}", buf.len()),
        });
    }
    let data = buf[..2 * n]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    Ok(DepthFrame {
        width: w,
        height: h,
        unit_m,
        data,
    })
}

/// Writes a frame as a 16-bit greyscale PNG (not atomically; the manifest, written last,
/// is what makes a scan).
pub fn write_png_frame(path: &Path, frame: &DepthFrame) -> Result<(), ScanError> {
    check_frame(0, frame)?;
    let png_err = |e: png::EncodingError| ScanError::Png {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let file = fs::File::create(path).map_err(|e| ScanError::io(path, e))?;
    let mut enc = png::Encoder::new(BufWriter::new(file), frame.width, frame.height);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Sixteen);
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header().map_err(png_err)?;
    let bytes: Vec<u8> = frame.data.iter().flat_map(|d| d.to_be_bytes()).collect();
    w.write_image_data(&bytes).map_err(png_err)?;
    w.finish().map_err(png_err)
}

pub(crate) fn check_sensor_frame(
    sensor: &SensorConfig,
    snapshot: usize,
    f: &DepthFrame,
) -> Result<(), ScanError> {
    check_frame(0, f)?;
    let i = sensor.intrinsics;
    if (f.width, f.height) != (i.width, i.height) {
        return Err(ScanError::ScanMismatch {
            reason: format!(
                "snapshot {snapshot}: a {}x{} frame for a {}x{} sensor",
                f.width, f.height, i.width, i.height
            ),
        });
    }
    #[allow(clippy::float_cmp)]
    if f.unit_m != sensor.depth_unit_m {
        return Err(ScanError::ScanMismatch {
            reason: format!(
                "snapshot {snapshot}: a frame in units of {} m for a sensor in {} m",
                f.unit_m, sensor.depth_unit_m
            ),
        });
    }
    Ok(())
}
