//! Morton (Z-order) codes: a spatially coherent order of points, shared by the point streams'
//! batches and the normal orientation's walk.

use glam::Vec3;
use rayon::prelude::*;

/// Spreads the low 21 bits of `v` to every third bit.
fn spread3(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// 63-bit Morton code of the grid cell `(x, y, z)` (21 bits each): x in the lowest bit of each
/// triple, then y, then z.
pub fn interleave(x: u32, y: u32, z: u32) -> u64 {
    spread3(u64::from(x)) | (spread3(u64::from(y)) << 1) | (spread3(u64::from(z)) << 2)
}

/// 63-bit Morton code of `p` on a 2^21 grid over the box `lo..lo + 1/scale`.
pub fn morton(p: Vec3, lo: Vec3, scale: Vec3) -> u64 {
    let max = ((1u32 << 21) - 1) as f32;
    let q = ((p - lo) * scale * max).clamp(Vec3::ZERO, Vec3::splat(max));
    interleave(q.x as u32, q.y as u32, q.z as u32)
}

/// Indices of `positions` sorted by Morton code over their bounding box, ties by index. The
/// sort key is the code's top 32 bits (about 10.7 bits per axis: far finer than a batch) above
/// the 32-bit index, so one `u64` per point is sorted: 8 bytes of scratch per point.
pub fn morton_order(positions: &[Vec3]) -> Vec<u32> {
    let Some(&first) = positions.first() else {
        return Vec::new();
    };
    let (lo, hi) = positions
        .par_iter()
        .fold(|| (first, first), |(lo, hi), &p| (lo.min(p), hi.max(p)))
        .reduce(|| (first, first), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    let extent = hi - lo;
    let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), extent.recip(), Vec3::ZERO);
    let mut keys: Vec<u64> = positions
        .par_iter()
        .enumerate()
        .map(|(i, &p)| ((morton(p, lo, scale) >> 31) << 32) | i as u64)
        .collect();
    keys.par_sort_unstable();
    keys.into_par_iter().map(|k| k as u32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_codes_interleave_axes() {
        assert_eq!(spread3(0b111), 0b1001001);
        let lo = Vec3::ZERO;
        let s = Vec3::ONE;
        assert_eq!(morton(Vec3::ZERO, lo, s), 0);
        let max = (1u64 << 63) - 1;
        assert_eq!(morton(Vec3::ONE, lo, s), max);
        // x is the lowest bit of each triple, then y, then z.
        let one = 1.0 / ((1u32 << 21) - 1) as f32;
        assert_eq!(morton(Vec3::new(one, 0.0, 0.0), lo, s), 1);
        assert_eq!(morton(Vec3::new(0.0, one, 0.0), lo, s), 2);
        assert_eq!(morton(Vec3::new(0.0, 0.0, one), lo, s), 4);
    }
}
