//! Hash-based value noise for procedural textures. Periodic variants tile
//! seamlessly, so a finite texture can cover an infinite table.

/// A well-mixed 32-bit integer hash (lowbias32).
#[inline]
pub(crate) fn hash_u32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// A hash of a lattice point and a seed, uniform in [0, 1).
#[inline]
pub(crate) fn hash2(ix: i32, iy: i32, seed: u32) -> f32 {
    let h = hash_u32(
        (ix as u32).wrapping_mul(0x9e37_79b1)
            ^ hash_u32((iy as u32) ^ seed.wrapping_mul(0x85eb_ca77)),
    );
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Smoothly interpolated value noise in [0, 1] with a lattice of period
/// `px` x `py` cells (so the noise repeats after `px` units in x and `py` in y).
pub(crate) fn value_noise(x: f32, y: f32, px: i32, py: i32, seed: u32) -> f32 {
    let x0 = x.floor();
    let y0 = y.floor();
    let fx = x - x0;
    let fy = y - y0;
    let ix = (x0 as i32).rem_euclid(px);
    let iy = (y0 as i32).rem_euclid(py);
    let ix1 = (ix + 1) % px;
    let iy1 = (iy + 1) % py;
    let sx = fx * fx * (3.0 - 2.0 * fx);
    let sy = fy * fy * (3.0 - 2.0 * fy);
    let a = hash2(ix, iy, seed);
    let b = hash2(ix1, iy, seed);
    let c = hash2(ix, iy1, seed);
    let d = hash2(ix1, iy1, seed);
    let top = a + (b - a) * sx;
    let bottom = c + (d - c) * sx;
    top + (bottom - top) * sy
}

/// Fractal sum of `octaves` periodic value-noise layers, normalised to [0, 1].
/// `(x, y)` are in units of the coarsest lattice, which has `px` x `py` cells.
pub(crate) fn fbm(x: f32, y: f32, px: i32, py: i32, octaves: u32, seed: u32) -> f32 {
    let mut sum = 0.0;
    let mut norm = 0.0;
    let mut amp = 1.0;
    let mut scale = 1;
    for o in 0..octaves {
        let s = scale as f32;
        sum += amp
            * value_noise(
                x * s,
                y * s,
                px * scale,
                py * scale,
                seed.wrapping_add(o * 7919),
            );
        norm += amp;
        amp *= 0.5;
        scale *= 2;
    }
    sum / norm
}
