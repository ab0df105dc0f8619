//! Replay of recordings made by libfreenect's `record` tool (the "fakenect" format).

use std::path::{Path, PathBuf};
use std::time::Duration;

use voxoct_depth::{DepthFrame, Intrinsics};

use crate::{DepthSource, SourceError};

/// Frame width of a fakenect depth file.
pub const FAKENECT_WIDTH: u32 = 640;
/// Frame height of a fakenect depth file.
pub const FAKENECT_HEIGHT: u32 = 480;
/// Raw 11-bit value meaning "no reading".
pub const RAW_NO_READING: u16 = 2047;
/// Farthest depth accepted from a raw disparity, metres (libfreenect's own
/// `FREENECT_DEPTH_MM_MAX_VALUE` is 10 000 mm).
pub const MAX_DEPTH_M: f32 = 10.0;

/// Coefficients of the disparity model `z = 1 / (A · raw + B)` of [`raw_disparity_to_m`].
const DISPARITY_A: f64 = -0.003_071_101_6;
/// See [`DISPARITY_A`].
const DISPARITY_B: f64 = 3.330_949_516_1;

/// Depth in metres of a raw 11-bit Kinect v1 disparity: `z = 1 / (−0.0030711016 · raw +
/// 3.3309495161)`.
///
/// This is the one disparity→depth model of voxoct: [`FakenectSource`] replays recordings
/// with it, `KinectSource` uses it in raw mode (`FREENECT_DEPTH_11BIT`, the only format the
/// fakenect library of libfreenect 0.5 serves), and [`FakenectWriter`] inverts it
/// ([`m_to_raw_disparity`]) so a written recording replays to the depths it was given. The
/// fit is Nicolas Burrus's, published on the OpenKinect wiki ("Imaging Information") and
/// commonly called libfreenect's approximation (HARDWARE.md). NYU Depth v2's toolbox uses
/// `z = 351.3 / (1092.5 − raw)`, fitted to another device: 5–7 % deeper than this one between
/// 0.4 and 1 m, so a recording's absolute scale is only as good as the model fits its sensor.
/// A real device in `FREENECT_DEPTH_MM` mode converts with its own factory calibration.
///
/// `None` for [`RAW_NO_READING`], for values above 2047, and where the formula gives a depth
/// that is not positive (raw ≥ 1085, where the denominator changes sign) or beyond
/// [`MAX_DEPTH_M`] (raw ≥ about 1052).
///
/// ```
/// # use voxoct_kinect::raw_disparity_to_m;
/// let z = raw_disparity_to_m(800).unwrap();
/// assert!((z - 1.14407).abs() < 1e-4);
/// assert_eq!(raw_disparity_to_m(2047), None);
/// assert_eq!(raw_disparity_to_m(1090), None);
/// ```
#[must_use]
pub fn raw_disparity_to_m(raw: u16) -> Option<f32> {
    if raw >= RAW_NO_READING {
        return None;
    }
    let denom = DISPARITY_A * f64::from(raw) + DISPARITY_B;
    let z = 1.0 / denom;
    (denom > 0.0 && z <= f64::from(MAX_DEPTH_M)).then_some(z as f32)
}

/// One raw disparity as a millimetre pixel of a [`DepthFrame`] (0 = no reading), through
/// [`raw_disparity_to_m`].
pub(crate) fn raw_disparity_to_mm(raw: u16) -> u16 {
    raw_disparity_to_m(raw).map_or(0, |z| (z * 1000.0).round() as u16)
}

/// The raw 11-bit disparity whose depth under [`raw_disparity_to_m`] is nearest to `z_m`
/// metres: the inverse model, rounded to the nearest integer disparity.
///
/// [`RAW_NO_READING`] for a depth that is not finite and positive, or that the model cannot
/// represent (nearer than its raw-0 depth of 0.300 m, or farther than [`MAX_DEPTH_M`]). For
/// every raw value `r` with a depth, `m_to_raw_disparity(raw_disparity_to_m(r)) == r`.
///
/// ```
/// # use voxoct_kinect::{m_to_raw_disparity, raw_disparity_to_m};
/// assert_eq!(m_to_raw_disparity(raw_disparity_to_m(800).unwrap()), 800);
/// assert_eq!(m_to_raw_disparity(0.0), 2047);
/// ```
#[must_use]
pub fn m_to_raw_disparity(z_m: f32) -> u16 {
    if !(z_m.is_finite() && z_m > 0.0 && z_m <= MAX_DEPTH_M) {
        return RAW_NO_READING;
    }
    let raw = ((1.0 / f64::from(z_m) - DISPARITY_B) / DISPARITY_A).round();
    if !(0.0..f64::from(RAW_NO_READING)).contains(&raw) {
        return RAW_NO_READING;
    }
    let raw = raw as u16;
    // Rounding at the far end can step past the last raw value with a depth.
    if raw_disparity_to_m(raw).is_some() {
        raw
    } else {
        RAW_NO_READING
    }
}

/// One line of `INDEX.txt`.
#[derive(Debug, Clone, PartialEq)]
enum Entry {
    /// A depth file.
    Depth(PathBuf),
    /// An accelerometer / tilt dump.
    Accel(PathBuf),
    /// Anything else the recorder writes (colour frames).
    Other,
}

/// Serves the depth frames of a fakenect recording in order.
///
/// A recording is a directory with `INDEX.txt`, one file name per line, named
/// `<kind>-<wall seconds>-<device timestamp>.<ext>`: `d-…pgm` depth frames, `r-…ppm` colour
/// frames and `a-…dump` accelerometer/tilt states. A depth file is `P5 640 480 65535` and one
/// whitespace byte, then 640×480 raw 11-bit disparities as little-endian `u16` (the recording
/// host's byte order, not the big-endian of standard 16-bit PGM); 2047 means no reading.
/// Frames are converted with [`raw_disparity_to_m`] into millimetre [`DepthFrame`]s.
///
/// At the end of the recording [`DepthSource::grab`] returns
/// [`SourceError::EndOfRecording`], unless the source was made [`FakenectSource::looping`].
#[derive(Debug, Clone)]
pub struct FakenectSource {
    dir: PathBuf,
    entries: Vec<Entry>,
    depth_count: usize,
    /// Next entry to look at.
    next: usize,
    looping: bool,
    /// The latest tilt dump passed on the way to the current frame.
    last_accel: Option<PathBuf>,
    intrinsics: Intrinsics,
}

impl FakenectSource {
    /// Opens a recording directory and checks its `INDEX.txt` (the depth files themselves are
    /// read, and checked, as they are served).
    ///
    /// # Errors
    /// [`SourceError::Io`] when `INDEX.txt` cannot be read, [`SourceError::FakenectIndex`]
    /// naming the line of a malformed entry or when no depth frame is listed.
    pub fn open(dir: impl AsRef<Path>) -> Result<Self, SourceError> {
        let dir = dir.as_ref().to_owned();
        let index = dir.join("INDEX.txt");
        let text = std::fs::read_to_string(&index).map_err(|source| SourceError::Io {
            path: index.clone(),
            source,
        })?;
        let mut entries = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let name = line.trim();
            if name.is_empty() {
                continue;
            }
            let entry = parse_entry(name).map_err(|message| SourceError::FakenectIndex {
                path: index.clone(),
                line: i + 1,
                message,
            })?;
            entries.push(match entry {
                'd' => Entry::Depth(dir.join(name)),
                'a' => Entry::Accel(dir.join(name)),
                _ => Entry::Other,
            });
        }
        let depth_count = entries
            .iter()
            .filter(|e| matches!(e, Entry::Depth(_)))
            .count();
        if depth_count == 0 {
            return Err(SourceError::FakenectIndex {
                path: index,
                line: text.lines().count(),
                message: "the index lists no depth frame (d-*.pgm)".into(),
            });
        }
        Ok(Self {
            dir,
            entries,
            depth_count,
            next: 0,
            looping: false,
            last_accel: None,
            // Kinect v1 depth camera, nominal values.
            intrinsics: Intrinsics::KINECT_V1,
        })
    }

    /// Serve the recording round and round instead of ending.
    #[must_use]
    pub fn looping(mut self, looping: bool) -> Self {
        self.looping = looping;
        self
    }

    /// Replace the nominal Kinect v1 intrinsics (f = 580 px) by calibrated ones (for the NYU
    /// recordings: fx 582.62, fy 582.69, cx 313.04, cy 238.44). The size must stay 640×480.
    ///
    /// # Errors
    /// [`SourceError::Config`] for another frame size.
    pub fn with_intrinsics(mut self, intrinsics: Intrinsics) -> Result<Self, SourceError> {
        if (intrinsics.width, intrinsics.height) != (FAKENECT_WIDTH, FAKENECT_HEIGHT) {
            return Err(SourceError::Config {
                field: "intrinsics",
                message: format!(
                    "fakenect frames are 640x480, not {}x{}",
                    intrinsics.width, intrinsics.height
                ),
            });
        }
        self.intrinsics = intrinsics;
        Ok(self)
    }

    /// Number of depth frames in the recording.
    #[must_use]
    pub fn depth_frame_count(&self) -> usize {
        self.depth_count
    }

    /// The recording directory.
    #[must_use]
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// Checks a file name of the index; returns its kind letter.
fn parse_entry(name: &str) -> Result<char, String> {
    if name.contains('/') || name.contains('\\') {
        return Err(format!(
            "{name:?}: a bare file name is expected, not a path"
        ));
    }
    let bad =
        || format!("{name:?} is not <kind>-<seconds>-<timestamp>.<ext> (e.g. d-1.5-1234.pgm)");
    let (kind, rest) = name.split_once('-').ok_or_else(bad)?;
    let (stem, ext) = rest.rsplit_once('.').ok_or_else(bad)?;
    let (secs, stamp) = stem.rsplit_once('-').ok_or_else(bad)?;
    if secs.parse::<f64>().is_err() || stamp.parse::<u32>().is_err() {
        return Err(bad());
    }
    match (kind, ext) {
        ("d", "pgm") => Ok('d'),
        ("r", "ppm") => Ok('r'),
        ("a", "dump") => Ok('a'),
        ("d" | "r" | "a", _) => Err(format!(
            "{name:?}: unexpected extension .{ext} for kind {kind}"
        )),
        _ => Err(format!(
            "{name:?}: unknown kind {kind:?} (d = depth, r = colour, a = accelerometer)"
        )),
    }
}

/// Reads one whitespace-delimited header token starting at `*pos`.
fn token<'a>(bytes: &'a [u8], pos: &mut usize) -> Option<(usize, &'a [u8])> {
    while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    let start = *pos;
    while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    (*pos > start).then(|| (start, &bytes[start..*pos]))
}

/// Decodes one fakenect depth file (header and raw little-endian pixels) into a millimetre
/// frame. `path` names the file in errors.
///
/// # Errors
/// [`SourceError::FakenectHeader`] with the byte offset, [`SourceError::FakenectShort`].
pub fn decode_fakenect_depth(bytes: &[u8], path: &Path) -> Result<DepthFrame, SourceError> {
    let header = |offset: usize, message: String| SourceError::FakenectHeader {
        path: path.to_owned(),
        offset,
        message,
    };
    let mut pos = 0;
    let mut field = |what: &str| -> Result<(usize, String), SourceError> {
        let (at, t) = token(bytes, &mut pos)
            .ok_or_else(|| header(pos, format!("missing {what} (file ends in the header)")))?;
        Ok((at, String::from_utf8_lossy(t).into_owned()))
    };
    let (at, magic) = field("magic number")?;
    if magic != "P5" {
        return Err(header(at, format!("magic {magic:?}, expected \"P5\"")));
    }
    let mut numbers = [0u32; 3];
    for (slot, (what, want)) in numbers.iter_mut().zip([
        ("width", FAKENECT_WIDTH),
        ("height", FAKENECT_HEIGHT),
        ("maximum value", 65535),
    ]) {
        let (at, t) = field(what)?;
        *slot = t
            .parse()
            .map_err(|_| header(at, format!("{what} {t:?} is not a number")))?;
        if *slot != want {
            return Err(header(at, format!("{what} {slot}, expected {want}")));
        }
    }
    // Exactly one whitespace byte separates the header from the pixels.
    match bytes.get(pos) {
        Some(b) if b.is_ascii_whitespace() => pos += 1,
        _ => return Err(header(pos, "no whitespace byte after the header".into())),
    }
    let n = (FAKENECT_WIDTH * FAKENECT_HEIGHT) as usize;
    let body = &bytes[pos..];
    if body.len() < 2 * n {
        return Err(SourceError::FakenectShort {
            path: path.to_owned(),
            expected: 2 * n,
            found: body.len(),
        });
    }
    let mut frame = DepthFrame::empty(FAKENECT_WIDTH, FAKENECT_HEIGHT, 0.001);
    for (out, px) in frame.data.iter_mut().zip(body.chunks_exact(2)) {
        *out = raw_disparity_to_mm(u16::from_le_bytes([px[0], px[1]]));
    }
    Ok(frame)
}

impl DepthSource for FakenectSource {
    fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// Reads the next depth file; never waits, so `timeout` is ignored.
    fn grab(&mut self, _timeout: Duration) -> Result<DepthFrame, SourceError> {
        let mut wrapped = false;
        loop {
            if self.next >= self.entries.len() {
                if !self.looping || wrapped {
                    return Err(SourceError::EndOfRecording {
                        dir: self.dir.clone(),
                        frames: self.depth_count,
                    });
                }
                self.next = 0;
                wrapped = true;
            }
            let entry = self.entries[self.next].clone();
            self.next += 1;
            match entry {
                Entry::Depth(path) => {
                    let bytes = std::fs::read(&path).map_err(|source| SourceError::Io {
                        path: path.clone(),
                        source,
                    })?;
                    return decode_fakenect_depth(&bytes, &path);
                }
                Entry::Accel(path) => self.last_accel = Some(path),
                Entry::Other => {}
            }
        }
    }

    /// The tilt from the latest `a-` dump before the current frame, as pitch down in degrees
    /// (the dump's motor angle is in half degrees, positive up); `None` without one.
    fn tilt_deg(&mut self) -> Option<f32> {
        let bytes = std::fs::read(self.last_accel.as_ref()?).ok()?;
        // freenect_raw_tilt_state: three i16 accelerometer values, then the i8 tilt angle.
        let half_degrees = *bytes.get(6)? as i8;
        Some(-f32::from(half_degrees) / 2.0)
    }
}

/// The bytes of one fakenect depth file: the header `P5 640 480 65535\n`, then the raw
/// disparities as little-endian `u16`, row-major from the top-left pixel.
///
/// This is what libfreenect's `record` tool writes on a little-endian host (x86, ARM): it
/// `fwrite`s the frame buffer as it is, and the fakenect library `memcpy`s the bytes after
/// the header's newline back into its frame buffer, so the byte order is the host's (on a
/// big-endian host neither tool would read these files correctly; neither exists in practice).
///
/// # Errors
/// [`SourceError::Config`] when `raw` is not 640×480 values or holds a value above 2047.
pub fn encode_fakenect_depth(raw: &[u16]) -> Result<Vec<u8>, SourceError> {
    let n = (FAKENECT_WIDTH * FAKENECT_HEIGHT) as usize;
    if raw.len() != n {
        return Err(SourceError::Config {
            field: "raw",
            message: format!(
                "a fakenect depth frame has {n} pixels (640x480), not {}",
                raw.len()
            ),
        });
    }
    if let Some((i, v)) = raw.iter().enumerate().find(|&(_, &v)| v > RAW_NO_READING) {
        return Err(SourceError::Config {
            field: "raw",
            message: format!("pixel {i} holds {v}, above the 11-bit range (2047 = no reading)"),
        });
    }
    let header = format!("P5 {FAKENECT_WIDTH} {FAKENECT_HEIGHT} 65535\n");
    let mut bytes = Vec::with_capacity(header.len() + 2 * n);
    bytes.extend_from_slice(header.as_bytes());
    for v in raw {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    Ok(bytes)
}

/// Writes a fakenect recording (`INDEX.txt` and `d-*.pgm` depth files) that both
/// [`FakenectSource`] and libfreenect's fakenect library replay.
///
/// Depth files are named `d-<seconds>-<timestamp>.pgm` like the `record` tool's
/// (`%c-%f-%u`): `seconds` starts at 1.000000 and grows by the frame interval given to
/// [`FakenectWriter::create`]; the fakenect library sleeps between frames to reproduce these
/// gaps, so the interval sets the replay's frame rate. `timestamp` is the frame's time in
/// microseconds from the first frame. Each depth file is written through a temporary file and
/// renamed; `INDEX.txt` is written the same way by [`FakenectWriter::finish`], so a recording
/// without its index is never mistaken for a complete one.
///
/// ```
/// use std::time::Duration;
/// use voxoct_kinect::{DepthFrame, DepthSource, FakenectSource, FakenectWriter};
///
/// let dir = tempfile::tempdir()?;
/// let mut frame = DepthFrame::empty(640, 480, 0.001);
/// frame.data.fill(800); // 0.8 m everywhere
/// let mut writer = FakenectWriter::create(dir.path().join("rec"), Duration::from_millis(500))?;
/// writer.add_frame(&frame)?;
/// writer.finish()?;
/// let mut replay = FakenectSource::open(dir.path().join("rec"))?;
/// let back = replay.grab(Duration::from_secs(1))?;
/// // Depth is quantised to the disparity steps: about 2 mm at 0.8 m.
/// assert!(back.data.iter().all(|&mm| mm.abs_diff(800) <= 1));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct FakenectWriter {
    dir: PathBuf,
    interval_s: f64,
    lines: Vec<String>,
}

impl FakenectWriter {
    /// Recorded time of the first frame, seconds.
    const START_S: f64 = 1.0;

    /// Creates the recording directory `dir` (it may exist but must be empty); frames will be
    /// `interval` apart in recorded time.
    ///
    /// # Errors
    /// [`SourceError::Config`] for a zero or over-an-hour interval or a directory that is not
    /// empty, [`SourceError::Write`] when it cannot be created.
    pub fn create(dir: impl AsRef<Path>, interval: Duration) -> Result<Self, SourceError> {
        let dir = dir.as_ref().to_owned();
        if interval.is_zero() || interval > Duration::from_secs(3600) {
            return Err(SourceError::Config {
                field: "interval",
                message: format!("the frame interval must be between 0 and 1 h, got {interval:?}"),
            });
        }
        std::fs::create_dir_all(&dir).map_err(|source| SourceError::Write {
            path: dir.clone(),
            source,
        })?;
        let mut entries = std::fs::read_dir(&dir).map_err(|source| SourceError::Io {
            path: dir.clone(),
            source,
        })?;
        if entries.next().is_some() {
            return Err(SourceError::Config {
                field: "dir",
                message: format!(
                    "{} is not empty; a fakenect recording needs a directory of its own",
                    dir.display()
                ),
            });
        }
        Ok(Self {
            dir,
            interval_s: interval.as_secs_f64(),
            lines: Vec::new(),
        })
    }

    /// Appends one depth frame of raw 11-bit disparities (640×480, row-major, 2047 = no
    /// reading).
    ///
    /// # Errors
    /// [`SourceError::Config`] for a wrong size or a value above 2047,
    /// [`SourceError::Write`] when the file cannot be written.
    pub fn add_raw(&mut self, raw: &[u16]) -> Result<(), SourceError> {
        let bytes = encode_fakenect_depth(raw)?;
        let i = self.lines.len();
        let offset_s = i as f64 * self.interval_s;
        let name = format!(
            "d-{:.6}-{}.pgm",
            Self::START_S + offset_s,
            (offset_s * 1e6).round() as u64 % (1 << 32)
        );
        write_atomic(&self.dir.join(&name), &bytes)?;
        self.lines.push(name);
        Ok(())
    }

    /// Appends a depth frame given as depths (any unit), converted to raw disparities with
    /// [`m_to_raw_disparity`]; pixels without a reading, or out of the model's range, become
    /// 2047.
    ///
    /// # Errors
    /// [`SourceError::Config`] when the frame is not 640×480, [`SourceError::Write`].
    pub fn add_frame(&mut self, frame: &DepthFrame) -> Result<(), SourceError> {
        if (frame.width, frame.height) != (FAKENECT_WIDTH, FAKENECT_HEIGHT) {
            return Err(SourceError::Config {
                field: "frame",
                message: format!(
                    "fakenect frames are 640x480, not {}x{}",
                    frame.width, frame.height
                ),
            });
        }
        let raw: Vec<u16> = frame
            .data
            .iter()
            .map(|&v| {
                if v == 0 {
                    RAW_NO_READING
                } else {
                    m_to_raw_disparity(f32::from(v) * frame.unit_m)
                }
            })
            .collect();
        self.add_raw(&raw)
    }

    /// Depth frames written so far.
    #[must_use]
    pub fn frames(&self) -> usize {
        self.lines.len()
    }

    /// Writes `INDEX.txt` (one depth file name per line) and returns the recording directory.
    ///
    /// # Errors
    /// [`SourceError::Config`] when no frame was added, [`SourceError::Write`].
    pub fn finish(self) -> Result<PathBuf, SourceError> {
        if self.lines.is_empty() {
            return Err(SourceError::Config {
                field: "frames",
                message: "a fakenect recording needs at least one depth frame".into(),
            });
        }
        let mut index = self.lines.join("\n");
        index.push('\n');
        write_atomic(&self.dir.join("INDEX.txt"), index.as_bytes())?;
        Ok(self.dir)
    }
}

/// Writes `bytes` to `path` atomically ([`voxoct_stl::write_atomic`]: a synced temporary
/// file beside it, renamed over it; never a partial file, never a replaced symlink or device).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SourceError> {
    voxoct_stl::write_atomic(path, |w| std::io::Write::write_all(w, bytes)).map_err(|source| {
        SourceError::Write {
            path: path.to_owned(),
            source,
        }
    })
}
