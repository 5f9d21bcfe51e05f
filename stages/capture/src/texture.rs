//! RGB textures with a mip chain and bilinear sampling.

/// One mip level: `w` x `h` RGB texels, row-major, row 0 at v = 0.
#[derive(Debug, Clone)]
pub(crate) struct Level {
    pub w: u32,
    pub h: u32,
    pub data: Vec<[u8; 3]>,
}

impl Level {
    /// Bilinear sample at texture coordinates (u, v) in [0, 1] (v = 0 at row 0),
    /// wrapping (`repeat`) or clamping at the border. Returns 0..255 floats.
    #[inline(always)]
    pub fn sample(&self, u: f32, v: f32, repeat: bool) -> [f32; 3] {
        let w = self.w as i32;
        let h = self.h as i32;
        let (x, y) = if repeat {
            (
                (u - fast_floor(u)) * w as f32 - 0.5,
                (v - fast_floor(v)) * h as f32 - 0.5,
            )
        } else {
            (
                u.clamp(0.0, 1.0) * w as f32 - 0.5,
                v.clamp(0.0, 1.0) * h as f32 - 0.5,
            )
        };
        let xf = fast_floor(x);
        let yf = fast_floor(y);
        let fx = x - xf;
        let fy = y - yf;
        let (x0, x1) = texel_pair(xf as i32, w, repeat);
        let (y0, y1) = texel_pair(yf as i32, h, repeat);
        let row0 = y0 * self.w as usize;
        let row1 = y1 * self.w as usize;
        let a = self.data[row0 + x0];
        let b = self.data[row0 + x1];
        let c = self.data[row1 + x0];
        let d = self.data[row1 + x1];
        let mut out = [0.0f32; 3];
        for k in 0..3 {
            let top = a[k] as f32 + (b[k] as f32 - a[k] as f32) * fx;
            let bottom = c[k] as f32 + (d[k] as f32 - c[k] as f32) * fx;
            out[k] = top + (bottom - top) * fy;
        }
        out
    }

    /// Bilinear sample with wrap-around, multiplied by `shade_q8 / 256` and
    /// rounded to bytes, in 8-bit fixed point: the three channels ride in
    /// 21-bit lanes of one u64 so each lerp is two multiplies. About twice
    /// as fast as [`Level::sample`]; used for the table, which covers most
    /// pixels.
    #[inline(always)]
    pub fn sample_repeat_q8(&self, u: f32, v: f32, shade_q8: u64) -> [u8; 3] {
        const LANE: u64 = (0xff) | (0xff << 21) | (0xff << 42);
        const HALF: u64 = (0x80) | (0x80 << 21) | (0x80 << 42);
        let (w, h) = (self.w as i32, self.h as i32);
        // Texel-space position in 1/256 texel; +512 keeps it positive so
        // the shift below floors.
        let x = (((u - fast_floor(u)) * w as f32 - 0.5) * 256.0) as i32 + 512;
        let y = (((v - fast_floor(v)) * h as f32 - 0.5) * 256.0) as i32 + 512;
        let (fx, fy) = ((x & 255) as u64, (y & 255) as u64);
        let (x0, x1) = texel_pair((x >> 8) - 2, w, true);
        let (y0, y1) = texel_pair((y >> 8) - 2, h, true);
        let spread = |t: [u8; 3]| t[0] as u64 | (t[1] as u64) << 21 | (t[2] as u64) << 42;
        let (r0, r1) = (y0 * self.w as usize, y1 * self.w as usize);
        let a = spread(self.data[r0 + x0]);
        let b = spread(self.data[r0 + x1]);
        let c = spread(self.data[r1 + x0]);
        let d = spread(self.data[r1 + x1]);
        let top = ((a * (256 - fx) + b * fx + HALF) >> 8) & LANE;
        let bottom = ((c * (256 - fx) + d * fx + HALF) >> 8) & LANE;
        let m = ((top * (256 - fy) + bottom * fy + HALF) >> 8) & LANE;
        // Each shaded lane stays below 2^17, so lanes are read before the
        // final shift (shifting the whole word would spill lane k+1 into k).
        let s = m * shade_q8 + HALF;
        let lane = |k: u32| (((s >> (21 * k)) & 0x1f_ffff) >> 8).min(255) as u8;
        [lane(0), lane(1), lane(2)]
    }
}

/// `x.floor()` without the libm call (x86-64 baseline has no SSE4.1 round);
/// exact for |x| < 2^31, NaN gives 0.
#[inline(always)]
pub(crate) fn fast_floor(x: f32) -> f32 {
    let i = x as i32;
    let f = i as f32;
    if f > x { f - 1.0 } else { f }
}

/// The two texel indices a bilinear sample at integer position `i` blends.
#[inline(always)]
fn texel_pair(i: i32, n: i32, repeat: bool) -> (usize, usize) {
    if repeat {
        let a = if i < 0 { n - 1 } else { i.min(n - 1) };
        let b = if i + 1 >= n { 0 } else { (i + 1).max(0) };
        (a as usize, b as usize)
    } else {
        (
            (i.clamp(0, n - 1)) as usize,
            ((i + 1).clamp(0, n - 1)) as usize,
        )
    }
}

/// A texture with its mip chain (level 0 = full resolution).
#[derive(Debug, Clone)]
pub(crate) struct Texture {
    levels: Vec<Level>,
    /// Whether texture coordinates wrap around (else they clamp).
    pub repeat: bool,
}

impl Texture {
    /// Builds a texture and its mip chain (2x2 box filter down to 1x1).
    pub fn new(w: u32, h: u32, data: Vec<[u8; 3]>, repeat: bool) -> Self {
        assert_eq!(data.len(), (w * h) as usize, "texture size mismatch");
        let mut levels = vec![Level { w, h, data }];
        while {
            let last = levels.last().expect("level 0 exists");
            last.w > 1 || last.h > 1
        } {
            let src = levels.last().expect("level exists");
            let nw = (src.w / 2).max(1);
            let nh = (src.h / 2).max(1);
            let mut data = Vec::with_capacity((nw * nh) as usize);
            for y in 0..nh {
                for x in 0..nw {
                    let xs = [(2 * x).min(src.w - 1), (2 * x + 1).min(src.w - 1)];
                    let ys = [(2 * y).min(src.h - 1), (2 * y + 1).min(src.h - 1)];
                    let mut acc = [0u32; 3];
                    for &yy in &ys {
                        for &xx in &xs {
                            let t = src.data[(yy * src.w + xx) as usize];
                            for k in 0..3 {
                                acc[k] += t[k] as u32;
                            }
                        }
                    }
                    data.push(acc.map(|a| ((a + 2) / 4) as u8));
                }
            }
            levels.push(Level { w: nw, h: nh, data });
        }
        Texture { levels, repeat }
    }

    /// A single-colour texture.
    pub fn solid(c: [u8; 3]) -> Self {
        Texture::new(1, 1, vec![c], false)
    }

    /// Full-resolution width and height.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].w, self.levels[0].h)
    }

    /// The mip level for a level-of-detail (log2 of texels per pixel),
    /// clamped to the chain.
    #[inline]
    pub fn level_for_lod(&self, lod: f32) -> &Level {
        let i = if lod > 0.0 { lod as usize } else { 0 };
        &self.levels[i.min(self.levels.len() - 1)]
    }

    /// The level with index `i`, clamped to the chain.
    #[inline]
    pub fn level(&self, i: usize) -> &Level {
        &self.levels[i.min(self.levels.len() - 1)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::hash2;

    #[test]
    fn fixed_point_sampler_matches_float_sampler() {
        let (w, h) = (37u32, 23u32);
        let data: Vec<[u8; 3]> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as i32, (i / w) as i32);
                [0, 1, 2].map(|c| (hash2(x, y, c) * 256.0) as u8)
            })
            .collect();
        let tex = Texture::new(w, h, data, true);
        let level = tex.level(0);
        for shade in [0.45f32, 0.99, 1.05] {
            let q8 = (shade * 256.0).round() as u64;
            for i in 0..2000 {
                let u = hash2(i, 0, 9) * 6.0 - 3.0;
                let v = hash2(i, 1, 9) * 6.0 - 3.0;
                let f = level
                    .sample(u, v, true)
                    .map(|c| (c * q8 as f32 / 256.0).min(255.0));
                let q = level.sample_repeat_q8(u, v, q8);
                for c in 0..3 {
                    assert!(
                        (f[c] - q[c] as f32).abs() <= 2.5,
                        "({u}, {v}) shade {shade}: {f:?} vs {q:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn fast_floor_matches_floor() {
        for x in [-3.5f32, -1.0, -0.25, 0.0, 0.25, 1.0, 2.999, 1e6 + 0.5] {
            assert_eq!(fast_floor(x), x.floor(), "{x}");
        }
    }
}
