//! A tiny anti-aliased 2-D painter for the procedural printed textures.
//!
//! Shapes take normalised coordinates: x in [0, 1] across the width, y in
//! [0, 1] down the height. Radii are fractions of the canvas height so discs
//! stay round on non-square canvases.

use crate::texture::Texture;

/// 4x4 supersampling per texel: smooth edges without a real rasteriser.
const SUB: usize = 4;

/// An RGB canvas.
pub(crate) struct Canvas {
    pub w: u32,
    pub h: u32,
    pub data: Vec<[u8; 3]>,
}

impl Canvas {
    /// A canvas filled with one colour.
    pub fn new(w: u32, h: u32, bg: [u8; 3]) -> Self {
        Canvas {
            w,
            h,
            data: vec![bg; (w * h) as usize],
        }
    }

    /// Blends `color` over every texel by the fraction of its subsamples for
    /// which `inside(x, y)` holds (x, y in texel units). Only texels in the
    /// normalised bounding box `[x0, y0, x1, y1]` are visited.
    pub fn fill(&mut self, bbox: [f64; 4], color: [u8; 3], inside: impl Fn(f64, f64) -> bool) {
        let (w, h) = (self.w as f64, self.h as f64);
        let xa = ((bbox[0] * w).floor().max(0.0)) as u32;
        let ya = ((bbox[1] * h).floor().max(0.0)) as u32;
        let xb = ((bbox[2] * w).ceil().min(w)) as u32;
        let yb = ((bbox[3] * h).ceil().min(h)) as u32;
        for ty in ya..yb {
            for tx in xa..xb {
                let mut hits = 0;
                for sy in 0..SUB {
                    for sx in 0..SUB {
                        let x = tx as f64 + (sx as f64 + 0.5) / SUB as f64;
                        let y = ty as f64 + (sy as f64 + 0.5) / SUB as f64;
                        if inside(x, y) {
                            hits += 1;
                        }
                    }
                }
                if hits > 0 {
                    let a = hits as f32 / (SUB * SUB) as f32;
                    let t = &mut self.data[(ty * self.w + tx) as usize];
                    for k in 0..3 {
                        t[k] = (t[k] as f32 * (1.0 - a) + color[k] as f32 * a).round() as u8;
                    }
                }
            }
        }
    }

    /// An axis-aligned rectangle.
    pub fn rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: [u8; 3]) {
        let (w, h) = (self.w as f64, self.h as f64);
        self.fill([x0, y0, x1, y1], c, |x, y| {
            x >= x0 * w && x < x1 * w && y >= y0 * h && y < y1 * h
        });
    }

    /// A disc of radius `r` (fraction of the height).
    pub fn disc(&mut self, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        self.ring(cx, cy, 0.0, r, c);
    }

    /// An annulus between radii `r0` < `r1` (fractions of the height).
    pub fn ring(&mut self, cx: f64, cy: f64, r0: f64, r1: f64, c: [u8; 3]) {
        let (w, h) = (self.w as f64, self.h as f64);
        let (px, py) = (cx * w, cy * h);
        let (a, b) = (r0 * h, r1 * h);
        let rx = r1 * h / w;
        self.fill([cx - rx, cy - r1, cx + rx, cy + r1], c, |x, y| {
            let d2 = (x - px).powi(2) + (y - py).powi(2);
            d2 >= a * a && d2 < b * b
        });
    }

    /// The part of a disc below its centre line (a bowl).
    pub fn half_disc_lower(&mut self, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        let (w, h) = (self.w as f64, self.h as f64);
        let (px, py, rr) = (cx * w, cy * h, r * h);
        let rx = r * h / w;
        self.fill([cx - rx, cy, cx + rx, cy + r], c, |x, y| {
            y >= py && (x - px).powi(2) + (y - py).powi(2) < rr * rr
        });
    }

    /// A filled simple polygon (even-odd rule) with normalised vertices.
    pub fn polygon(&mut self, pts: &[(f64, f64)], c: [u8; 3]) {
        let (w, h) = (self.w as f64, self.h as f64);
        let p: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x * w, y * h)).collect();
        let bbox = [
            pts.iter().map(|p| p.0).fold(f64::INFINITY, f64::min),
            pts.iter().map(|p| p.1).fold(f64::INFINITY, f64::min),
            pts.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max),
            pts.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max),
        ];
        self.fill(bbox, c, |x, y| {
            let mut inside = false;
            let mut j = p.len() - 1;
            for i in 0..p.len() {
                let (xi, yi) = p[i];
                let (xj, yj) = p[j];
                if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
                    inside = !inside;
                }
                j = i;
            }
            inside
        });
    }

    /// A straight bar of width `width` (fraction of the height) from a to b.
    pub fn bar(&mut self, a: (f64, f64), b: (f64, f64), width: f64, c: [u8; 3]) {
        let (w, h) = (self.w as f64, self.h as f64);
        let (ax, ay, bx, by) = (a.0 * w, a.1 * h, b.0 * w, b.1 * h);
        let (dx, dy) = (bx - ax, by - ay);
        let len = (dx * dx + dy * dy).sqrt().max(1e-9);
        let (nx, ny) = (-dy / len * width * h / 2.0, dx / len * width * h / 2.0);
        let pts = [
            ((ax + nx) / w, (ay + ny) / h),
            ((bx + nx) / w, (by + ny) / h),
            ((bx - nx) / w, (by - ny) / h),
            ((ax - nx) / w, (ay - ny) / h),
        ];
        self.polygon(&pts, c);
    }

    /// Parallel bands cycling through `colors` inside the rectangle
    /// `[x0, y0, x1, y1]`, at `angle_deg` from the x axis, each band `period`
    /// (fraction of the height) wide.
    pub fn stripes(&mut self, region: [f64; 4], angle_deg: f64, period: f64, colors: &[[u8; 3]]) {
        let (w, h) = (self.w as f64, self.h as f64);
        let (s, c) = angle_deg.to_radians().sin_cos();
        let p = period * h;
        let n = colors.len() as i64;
        let [x0, y0, x1, y1] = region;
        for (i, &col) in colors.iter().enumerate() {
            self.fill(region, col, |x, y| {
                if !(x >= x0 * w && x < x1 * w && y >= y0 * h && y < y1 * h) {
                    return false;
                }
                // Distance across the bands selects the colour.
                let t = (-x * s + y * c) / p;
                (t.floor() as i64).rem_euclid(n) == i as i64
            });
        }
    }

    /// A checkerboard of `nx` x `ny` cells inside the rectangle `[x0, y0, x1, y1]`.
    pub fn checks(&mut self, region: [f64; 4], nx: u32, ny: u32, a: [u8; 3], b: [u8; 3]) {
        let [x0, y0, x1, y1] = region;
        for j in 0..ny {
            for i in 0..nx {
                let c = if (i + j) % 2 == 0 { a } else { b };
                let xa = x0 + (x1 - x0) * i as f64 / nx as f64;
                let xb = x0 + (x1 - x0) * (i + 1) as f64 / nx as f64;
                let ya = y0 + (y1 - y0) * j as f64 / ny as f64;
                let yb = y0 + (y1 - y0) * (j + 1) as f64 / ny as f64;
                self.rect(xa, ya, xb, yb, c);
            }
        }
    }

    /// A five-pointed star of outer radius `r` (fraction of the height).
    pub fn star(&mut self, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        let aspect = self.h as f64 / self.w as f64;
        let pts: Vec<(f64, f64)> = (0..10)
            .map(|k| {
                let a = std::f64::consts::PI * (k as f64 / 5.0 - 0.5);
                let rr = if k % 2 == 0 { r } else { r * 0.45 };
                (cx + rr * a.cos() * aspect, cy + rr * a.sin())
            })
            .collect();
        self.polygon(&pts, c);
    }

    /// A linear blend from `a` to `b` across the rectangle `[x0, y0, x1,
    /// y1]`, left to right when `horizontal`, else top to bottom.
    pub fn gradient(&mut self, region: [f64; 4], a: [u8; 3], b: [u8; 3], horizontal: bool) {
        let (w, h) = (self.w as f64, self.h as f64);
        let [x0, y0, x1, y1] = region;
        self.shade(region, |x, y| {
            let t = if horizontal {
                (x / w - x0) / (x1 - x0).max(1e-9)
            } else {
                (y / h - y0) / (y1 - y0).max(1e-9)
            };
            mix(a, b, t.clamp(0.0, 1.0))
        });
    }

    /// A photo-like patch over the rectangle: smooth value noise (two
    /// octaves over a coarse lattice drawn from `seed`) mapped onto the
    /// colour ramp `ramp`.
    pub fn photo(&mut self, region: [f64; 4], ramp: &[[u8; 3]; 3], seed: u64) {
        let h = self.h as f64;
        let lattice = |i: i64, j: i64, octave: u64| {
            let z = crate::derive_seed(seed ^ octave, (i as u64) << 32 ^ j as u64);
            (z >> 11) as f64 / (1u64 << 53) as f64
        };
        let noise = |x: f64, y: f64, octave: u64| {
            let (i, j) = (x.floor() as i64, y.floor() as i64);
            let (fx, fy) = (x - x.floor(), y - y.floor());
            let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
            let top = lattice(i, j, octave) * (1.0 - sx) + lattice(i + 1, j, octave) * sx;
            let bottom =
                lattice(i, j + 1, octave) * (1.0 - sx) + lattice(i + 1, j + 1, octave) * sx;
            top * (1.0 - sy) + bottom * sy
        };
        self.shade(region, |x, y| {
            let (u, v) = (x / h * 6.0, y / h * 6.0);
            let t = (0.7 * noise(u, v, 0) + 0.3 * noise(2.0 * u, 2.0 * v, 1)).clamp(0.0, 1.0);
            if t < 0.5 {
                mix(ramp[0], ramp[1], t * 2.0)
            } else {
                mix(ramp[1], ramp[2], t * 2.0 - 1.0)
            }
        });
    }

    /// Sets every texel whose centre lies in the normalised rectangle to
    /// `colour(x, y)` (texel units).
    fn shade(&mut self, region: [f64; 4], colour: impl Fn(f64, f64) -> [u8; 3]) {
        let (w, h) = (self.w as f64, self.h as f64);
        let xa = (region[0] * w).round().max(0.0) as u32;
        let ya = (region[1] * h).round().max(0.0) as u32;
        let xb = ((region[2] * w).round().min(w)) as u32;
        let yb = ((region[3] * h).round().min(h)) as u32;
        for ty in ya..yb {
            for tx in xa..xb {
                self.data[(ty * self.w + tx) as usize] = colour(tx as f64 + 0.5, ty as f64 + 0.5);
            }
        }
    }

    /// Converts to a texture (builds the mip chain).
    pub fn into_texture(self, repeat: bool) -> Texture {
        Texture::new(self.w, self.h, self.data, repeat)
    }
}

/// `a` blended towards `b` by `t` in [0, 1].
fn mix(a: [u8; 3], b: [u8; 3], t: f64) -> [u8; 3] {
    std::array::from_fn(|k| (a[k] as f64 * (1.0 - t) + b[k] as f64 * t).round() as u8)
}
