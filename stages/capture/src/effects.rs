//! Image degradations: Gaussian blur, brightness change and sensor noise.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Optional degradations applied after rendering, in this order: blur,
/// brightness, noise. The mask is never affected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effects {
    /// Standard deviation of additive, approximately Gaussian per-channel
    /// noise in grey levels (0..255); 0 = none. Seeded by the frame seed.
    pub noise_sigma: f32,
    /// Standard deviation in pixels of a Gaussian blur (defocus/motion
    /// stand-in); 0 = none. The kernel is cut at 3 sigma, at most 50 pixels.
    pub blur_sigma: f32,
    /// Multiplies every channel (exposure change); 1 = unchanged.
    pub brightness: f32,
}

impl Default for Effects {
    /// No noise, no blur, brightness 1.
    fn default() -> Self {
        Effects {
            noise_sigma: 0.0,
            blur_sigma: 0.0,
            brightness: 1.0,
        }
    }
}

const MAX_RADIUS: usize = 50;

/// Applies the effects in place. `tmp` is reused scratch memory.
pub(crate) fn apply(
    rgb: &mut [u8],
    w: usize,
    h: usize,
    fx: &Effects,
    seed: u64,
    tmp: &mut Vec<f32>,
) {
    if fx.blur_sigma.is_finite() && fx.blur_sigma > 0.0 {
        blur(rgb, w, h, fx.blur_sigma, tmp);
    }
    let gain = if fx.brightness.is_finite() && fx.brightness >= 0.0 {
        fx.brightness
    } else {
        1.0
    };
    let sigma = if fx.noise_sigma.is_finite() && fx.noise_sigma > 0.0 {
        fx.noise_sigma
    } else {
        0.0
    };
    if sigma > 0.0 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Irwin-Hall sum of four uniform bytes: mean 510, sd 147.8; close to
        // Gaussian and far cheaper than Box-Muller per channel.
        let k = sigma / 147.8;
        for v in rgb.iter_mut() {
            let r = rng.next_u32();
            let s = (r & 0xff) + ((r >> 8) & 0xff) + ((r >> 16) & 0xff) + (r >> 24);
            let x = *v as f32 * gain + (s as f32 - 510.0) * k;
            *v = (x + 0.5).clamp(0.0, 255.0) as u8;
        }
    } else if gain != 1.0 {
        for v in rgb.iter_mut() {
            *v = (*v as f32 * gain + 0.5).clamp(0.0, 255.0) as u8;
        }
    }
}

/// Separable Gaussian blur with clamped borders.
fn blur(rgb: &mut [u8], w: usize, h: usize, sigma: f32, tmp: &mut Vec<f32>) {
    let radius = ((3.0 * sigma).ceil() as usize).clamp(1, MAX_RADIUS);
    let mut kernel = [0f32; 2 * MAX_RADIUS + 1];
    let mut sum = 0.0;
    for (i, k) in kernel.iter_mut().enumerate().take(2 * radius + 1) {
        let d = i as f32 - radius as f32;
        *k = (-0.5 * d * d / (sigma * sigma)).exp();
        sum += *k;
    }
    for k in kernel.iter_mut() {
        *k /= sum;
    }
    let kernel = &kernel[..2 * radius + 1];
    tmp.clear();
    tmp.resize(w * h * 3, 0.0);
    let r = radius as isize;
    // Horizontal pass into tmp.
    for y in 0..h {
        let src = &rgb[y * w * 3..(y + 1) * w * 3];
        let dst = &mut tmp[y * w * 3..(y + 1) * w * 3];
        for x in 0..w {
            let mut acc = [0f32; 3];
            for (i, &k) in kernel.iter().enumerate() {
                let xx = (x as isize + i as isize - r).clamp(0, w as isize - 1) as usize;
                for c in 0..3 {
                    acc[c] += k * src[xx * 3 + c] as f32;
                }
            }
            dst[x * 3..x * 3 + 3].copy_from_slice(&acc);
        }
    }
    // Vertical pass back into rgb.
    let stride = w * 3;
    for y in 0..h {
        for i in 0..stride {
            let mut acc = 0.0;
            for (j, &k) in kernel.iter().enumerate() {
                let yy = (y as isize + j as isize - r).clamp(0, h as isize - 1) as usize;
                acc += k * tmp[yy * stride + i];
            }
            rgb[y * stride + i] = (acc + 0.5).clamp(0.0, 255.0) as u8;
        }
    }
}
