//! Back-projection, the rig transform, clipping, and snapshot files.

use std::fs;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::Path;

use byteorder::{ByteOrder, LittleEndian, ReadBytesExt, WriteBytesExt};
use glam::{Affine3A, Mat3A, Vec3, Vec3A};

use crate::error::DepthError;
use crate::filter::check_frame_size;
use crate::types::{ClipBox, DepthFrame, Intrinsics, Rig};

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
    ) -> Result<Self, DepthError> {
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
    ) -> Result<(), DepthError> {
        check_frame_size(0, frame, intr.width, intr.height)?;
        let positive = |name, x: f32| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(DepthError::InvalidParameter {
                    name,
                    reason: format!("must be a positive number, got {x}"),
                })
            }
        };
        positive("fx", intr.fx)?;
        positive("fy", intr.fy)?;
        for (name, x) in [("cx", intr.cx), ("cy", intr.cy), ("angle_deg", angle_deg)] {
            if !x.is_finite() {
                return Err(DepthError::InvalidParameter {
                    name,
                    reason: format!("must be finite, got {x}"),
                });
            }
        }
        let t = rig.camera_to_object(angle_deg);
        if !(t.matrix3.is_finite() && t.translation.is_finite()) {
            return Err(DepthError::InvalidParameter {
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

    /// Writes the snapshot file format: a 72-byte little-endian header, then the points.
    ///
    /// | offset | size | field |
    /// |---|---|---|
    /// | 0 | 8 | magic `VOXSNAP\0` |
    /// | 8 | 4 | version (u32, 1) |
    /// | 12 | 4 | width (u32) |
    /// | 16 | 4 | height (u32) |
    /// | 20 | 36 | camera → object rotation, 9 × f32, column-major |
    /// | 56 | 12 | camera → object translation, 3 × f32 |
    /// | 68 | 4 | turntable angle, degrees (f32) |
    /// | 72 | 12 · w · h | points, 3 × f32 each, row-major; holes are NaN |
    pub fn write_to<W: Write>(&self, w: W) -> Result<(), DepthError> {
        let mut w = BufWriter::new(w);
        let map = |source| DepthError::SnapshotIo { offset: 0, source };
        let n = self.width as usize * self.height as usize;
        if self.points.len() != n {
            return Err(DepthError::InvalidParameter {
                name: "points",
                reason: format!(
                    "{} points for a {}x{} snapshot",
                    self.points.len(),
                    self.width,
                    self.height
                ),
            });
        }
        let mut header = Vec::with_capacity(HEADER_LEN);
        header.extend_from_slice(&SNAPSHOT_MAGIC);
        for x in [SNAPSHOT_VERSION, self.width, self.height] {
            header.write_u32::<LittleEndian>(x).map_err(map)?;
        }
        for x in self
            .camera_to_object
            .matrix3
            .to_cols_array()
            .into_iter()
            .chain(self.camera_to_object.translation.to_array())
            .chain([self.angle_deg])
        {
            header.write_f32::<LittleEndian>(x).map_err(map)?;
        }
        debug_assert_eq!(header.len(), HEADER_LEN);
        w.write_all(&header).map_err(map)?;
        let mut buf = [0u8; 12 * 1024];
        for chunk in self.points.chunks(1024) {
            let bytes = &mut buf[..chunk.len() * 12];
            for (p, b) in chunk.iter().zip(bytes.chunks_exact_mut(12)) {
                LittleEndian::write_f32_into(&p.to_array(), b);
            }
            w.write_all(bytes).map_err(map)?;
        }
        w.flush().map_err(map)
    }

    /// Reads a snapshot written by [`Snapshot::write_to`]. Errors name what is wrong and
    /// at which byte: a foreign file (magic), another version, an impossible size, a
    /// truncated file.
    pub fn read_from<R: Read>(r: R) -> Result<Self, DepthError> {
        let mut r = BufReader::new(r);
        let mut header = [0u8; HEADER_LEN];
        let got = read_full(&mut r, &mut header)?;
        if got < 8 {
            let mut found = [0u8; 8];
            found[..got].copy_from_slice(&header[..got]);
            if found[..got] != SNAPSHOT_MAGIC[..got] || got == 0 {
                return Err(DepthError::SnapshotMagic { found });
            }
        } else if header[..8] != SNAPSHOT_MAGIC {
            let mut found = [0u8; 8];
            found.copy_from_slice(&header[..8]);
            return Err(DepthError::SnapshotMagic { found });
        }
        if got < HEADER_LEN {
            return Err(DepthError::SnapshotTruncated {
                offset: got as u64,
                what: "the rest of the 72-byte header",
            });
        }
        let mut h = &header[8..];
        // Reading from a slice of known length cannot fail.
        let mut u32_at = || h.read_u32::<LittleEndian>().unwrap_or(0);
        let version = u32_at();
        if version != SNAPSHOT_VERSION {
            return Err(DepthError::SnapshotVersion {
                found: version,
                supported: SNAPSHOT_VERSION,
            });
        }
        let width = u32_at();
        let height = u32_at();
        let n = u64::from(width) * u64::from(height);
        if n > MAX_POINTS {
            return Err(DepthError::SnapshotHeader {
                field: "width x height",
                offset: 12,
                reason: format!("{width}x{height} exceeds {MAX_POINTS} points"),
            });
        }
        let mut f = [0f32; 13];
        LittleEndian::read_f32_into(&header[20..HEADER_LEN], &mut f);
        if f.iter().any(|x| !x.is_finite()) {
            return Err(DepthError::SnapshotHeader {
                field: "transform/angle",
                offset: 20,
                reason: "not finite".into(),
            });
        }
        let camera_to_object = Affine3A {
            matrix3: Mat3A::from_cols_slice(&f[..9]),
            translation: Vec3A::from_slice(&f[9..12]),
        };
        let angle_deg = f[12];
        let n = n as usize;
        let mut points = Vec::with_capacity(n);
        let mut buf = vec![0u8; 12 * 4096];
        let mut fl = [0f32; 3 * 4096];
        let mut done = 0usize;
        while done < n {
            let k = (n - done).min(4096);
            let bytes = &mut buf[..12 * k];
            let got = read_full(&mut r, bytes)?;
            if got < bytes.len() {
                return Err(DepthError::SnapshotTruncated {
                    offset: (HEADER_LEN + 12 * done + got) as u64,
                    what: "point data",
                });
            }
            LittleEndian::read_f32_into(bytes, &mut fl[..3 * k]);
            points.extend(fl[..3 * k].chunks_exact(3).map(|c| {
                let p = Vec3::new(c[0], c[1], c[2]);
                if p.is_finite() { p } else { HOLE }
            }));
            done += k;
        }
        Ok(Self {
            width,
            height,
            camera_to_object,
            angle_deg,
            points,
        })
    }

    /// Writes the snapshot to `path` atomically (a temporary file in the same directory,
    /// then a rename).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), DepthError> {
        let path = path.as_ref();
        write_atomic(path, |f| self.write_to(f))
    }

    /// Reads a snapshot file; errors name the file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DepthError> {
        let path = path.as_ref();
        let f = fs::File::open(path).map_err(|e| DepthError::io(path, e))?;
        Self::read_from(f).map_err(|e| DepthError::InFile {
            path: path.to_owned(),
            source: Box::new(e),
        })
    }
}

const SNAPSHOT_MAGIC: [u8; 8] = *b"VOXSNAP\0";
const SNAPSHOT_VERSION: u32 = 1;
const HEADER_LEN: usize = 72;
/// Largest grid a snapshot file may declare (refuses absurd allocations on corrupt headers).
const MAX_POINTS: u64 = 1 << 26;

/// Reads until `buf` is full or the stream ends; returns the bytes read.
fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> Result<usize, DepthError> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(source) => {
                return Err(DepthError::SnapshotIo {
                    offset: got as u64,
                    source,
                });
            }
        }
    }
    Ok(got)
}

/// Writes a file atomically: `write` fills a temporary file next to `path`, which is
/// then synced, given the old file's permissions and renamed over `path`. A symlink is
/// followed (its target is replaced, the link stays); a path that exists and is not a
/// regular file (a device, a FIFO) is written to directly, never replaced. Errors name
/// `path`.
pub(crate) fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> Result<(), DepthError>,
) -> Result<(), DepthError> {
    let original = path;
    let resolved;
    let mut old_permissions = None;
    let path = match fs::metadata(original) {
        Ok(m) if !m.is_file() && !m.is_dir() => {
            let mut f = fs::OpenOptions::new()
                .write(true)
                .open(original)
                .map_err(|e| DepthError::io(original, e))?;
            return write(&mut f);
        }
        Ok(m) if m.is_file() => {
            old_permissions = Some(m.permissions());
            resolved = fs::canonicalize(original).map_err(|e| DepthError::io(original, e))?;
            resolved.as_path()
        }
        _ => original,
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let mut f = fs::File::create(&tmp).map_err(|e| DepthError::io(original, e))?;
        write(&mut f).map_err(|e| match e {
            e @ (DepthError::Io { .. } | DepthError::InFile { .. }) => e,
            e => DepthError::InFile {
                path: original.to_owned(),
                source: Box::new(e),
            },
        })?;
        f.sync_all().map_err(|e| DepthError::io(original, e))?;
        if let Some(p) = old_permissions {
            fs::set_permissions(&tmp, p).map_err(|e| DepthError::io(original, e))?;
        }
        fs::rename(&tmp, path).map_err(|e| DepthError::io(original, e))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
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
            Err(DepthError::FrameSizeMismatch {
                expected_w: 640,
                found_w: 4,
                ..
            })
        ));
    }

    fn small() -> Snapshot {
        let intr = Intrinsics {
            width: 5,
            height: 3,
            ..Intrinsics::KINECT_V1
        };
        let mut f = DepthFrame::empty(5, 3, 0.001);
        f.data = (0..15).map(|i| if i == 4 { 0 } else { 600 + i }).collect();
        Snapshot::from_frame(&f, &intr, &rig(), 45.0, &open_clip()).unwrap()
    }

    fn same(a: &Snapshot, b: &Snapshot) -> bool {
        a.width == b.width
            && a.height == b.height
            && a.camera_to_object == b.camera_to_object
            && a.angle_deg.to_bits() == b.angle_deg.to_bits()
            && a.points.iter().zip(&b.points).all(|(p, q)| {
                (p.is_nan() && q.is_nan())
                    || p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits)
            })
            && a.points.len() == b.points.len()
    }

    #[test]
    fn file_round_trip() {
        let s = small();
        let mut bytes = Vec::new();
        s.write_to(&mut bytes).unwrap();
        assert_eq!(bytes.len(), HEADER_LEN + 12 * 15);
        let r = Snapshot::read_from(&bytes[..]).unwrap();
        assert!(same(&s, &r));
        assert!(r.is_hole(4));

        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.snap");
        s.save(&p).unwrap();
        assert!(same(&s, &Snapshot::load(&p).unwrap()));
        let leftovers: Vec<_> = fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "no temporary file left behind");
    }

    #[test]
    fn bad_files_are_clear_errors() {
        let mut bytes = Vec::new();
        small().write_to(&mut bytes).unwrap();

        // Truncated in the points.
        let cut = &bytes[..bytes.len() - 5];
        match Snapshot::read_from(cut) {
            Err(DepthError::SnapshotTruncated { offset, what }) => {
                assert_eq!(offset, cut.len() as u64);
                assert_eq!(what, "point data");
            }
            other => panic!("{other:?}"),
        }
        // Truncated in the header.
        assert!(matches!(
            Snapshot::read_from(&bytes[..30]),
            Err(DepthError::SnapshotTruncated { offset: 30, .. })
        ));
        // Empty and foreign files.
        assert!(matches!(
            Snapshot::read_from(&[][..]),
            Err(DepthError::SnapshotMagic { .. })
        ));
        let e = Snapshot::read_from(
            &b"\x89PNG\r\n\x1a\n and more bytes than a header needs, surely more than seventy-two"
                [..],
        )
        .unwrap_err();
        assert!(matches!(e, DepthError::SnapshotMagic { .. }));
        assert!(e.to_string().contains("not a voxoct snapshot"));
        // Wrong version.
        let mut v2 = bytes.clone();
        v2[8] = 2;
        assert!(matches!(
            Snapshot::read_from(&v2[..]),
            Err(DepthError::SnapshotVersion {
                found: 2,
                supported: 1
            })
        ));
        // Absurd size.
        let mut big = bytes.clone();
        big[12..20].copy_from_slice(&[0xff; 8]);
        assert!(matches!(
            Snapshot::read_from(&big[..]),
            Err(DepthError::SnapshotHeader { offset: 12, .. })
        ));
        // load names the file.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("cut.snap");
        fs::write(&p, cut).unwrap();
        let e = Snapshot::load(&p).unwrap_err();
        assert!(e.to_string().contains("cut.snap"), "{e}");
        assert!(matches!(e.root(), DepthError::SnapshotTruncated { .. }));
        let e = Snapshot::load(dir.path().join("missing.snap")).unwrap_err();
        assert!(matches!(e, DepthError::Io { .. }));
    }
}
