//! Morton codes (x in the lowest bit) and bit helpers of the storage.

use glam::UVec3;

/// The brick coordinates of a brick-cache key `x | y << 21 | z << 42`.
#[inline]
pub(super) fn brick_coords(key: u64) -> UVec3 {
    let m = (1 << 21) - 1;
    UVec3::new((key & m) as u32, (key >> 21 & m) as u32, (key >> 42) as u32)
}

/// Index of the region at region coordinates `rc` (each below `2^SPLIT_DEPTH`): their
/// Morton code, by table.
#[inline(always)]
pub(super) fn region_index(rc: UVec3) -> usize {
    const SPREAD: [u16; 8] = [0, 1, 8, 9, 64, 65, 72, 73];
    let s = |v: u32| usize::from(SPREAD[(v & 7) as usize]);
    s(rc.x) | s(rc.y) << 1 | s(rc.z) << 2
}

/// Morton index of a 4×4×4 local coordinate (bits `z1 y1 x1 z0 y0 x0`).
#[inline]
pub(super) fn morton2(l: UVec3) -> u32 {
    morton2_axis(l.x) | morton2_axis(l.y) << 1 | morton2_axis(l.z) << 2
}

/// The Morton bits of one coordinate below 4 (x's place; shift by the axis).
#[inline(always)]
pub(super) fn morton2_axis(v: u32) -> u32 {
    (v & 1) | (v & 2) << 2
}

#[inline]
pub(super) fn demorton2(bit: u32) -> UVec3 {
    UVec3::new(
        (bit & 1) | (bit >> 2) & 2,
        (bit >> 1) & 1 | (bit >> 3) & 2,
        (bit >> 2) & 1 | (bit >> 4) & 2,
    )
}

/// Spreads the low 21 bits of `v` to every third bit.
#[inline]
pub(super) fn part1by2(v: u32) -> u64 {
    let mut x = u64::from(v) & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

#[inline]
pub(super) fn compact1by2(x: u64) -> u32 {
    let mut x = x & 0x1249_2492_4924_9249;
    x = (x | x >> 2) & 0x10c3_0c30_c30c_30c3;
    x = (x | x >> 4) & 0x100f_00f0_0f00_f00f;
    x = (x | x >> 8) & 0x001f_0000_ff00_00ff;
    x = (x | x >> 16) & 0x001f_0000_0000_ffff;
    x = (x | x >> 32) & 0x1f_ffff;
    x as u32
}

/// Morton code (x in the lowest bit) of coordinates below `2^21`.
#[inline]
pub(super) fn morton3(c: UVec3) -> u64 {
    part1by2(c.x) | part1by2(c.y) << 1 | part1by2(c.z) << 2
}

#[inline]
pub(super) fn demorton3(m: u64) -> UVec3 {
    UVec3::new(compact1by2(m), compact1by2(m >> 1), compact1by2(m >> 2))
}

/// Set bits of a mask, lowest first.
pub(super) struct BitIter(pub(super) u64);

impl Iterator for BitIter {
    type Item = u32;
    #[inline]
    fn next(&mut self) -> Option<u32> {
        if self.0 == 0 {
            return None;
        }
        let b = self.0.trailing_zeros();
        self.0 &= self.0 - 1;
        Some(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn morton_round_trips() {
        for c in [
            UVec3::ZERO,
            UVec3::new(1, 2, 3),
            UVec3::new(0x1f_ffff, 0, 7),
            UVec3::splat(0x1f_ffff),
        ] {
            assert_eq!(demorton3(morton3(c)), c);
        }
        assert_eq!(morton3(UVec3::new(1, 0, 0)), 1);
        assert_eq!(morton3(UVec3::new(0, 1, 0)), 2);
        assert_eq!(morton3(UVec3::new(0, 0, 1)), 4);
        for bit in 0..64 {
            assert_eq!(morton2(demorton2(bit)), bit);
            assert_eq!(u64::from(morton2(demorton2(bit))), morton3(demorton2(bit)));
        }
    }
}
