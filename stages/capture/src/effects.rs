//! Image degradations: the light (exposure, colour temperature,
//! vignetting), Gaussian and motion blur, the sensor's shot and read
//! noise, a brightness change of the bytes, additive noise and JPEG
//! compression.

use acch_core::light::{
    TRAINING_LIGHT_K, colour_temperature_gains, linear_to_srgb, srgb_decode_table,
};
use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Optional degradations applied after rendering, in this order: the light
/// (on linear colour: exposure, colour temperature, vignetting), blur,
/// motion blur, the sensor's shot and read noise (on linear colour),
/// brightness (on the bytes), additive noise, JPEG. The mask is never
/// affected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Effects {
    /// Standard deviation of additive, approximately Gaussian per-channel
    /// noise in grey levels (0..255); 0 = none. Seeded by the frame seed.
    pub noise_sigma: f32,
    /// Standard deviation in pixels of a Gaussian blur (defocus/motion
    /// stand-in); 0 = none. The kernel is cut at 3 sigma, at most 50 pixels.
    pub blur_sigma: f32,
    /// Multiplies every byte of every channel; 1 = unchanged. Harsher at
    /// the bright end than a camera's exposure: x1.4 clips every byte above
    /// 182 (see `exposure`).
    pub brightness: f32,
    /// Multiplies the linear colour, as the light's intensity or the
    /// camera's exposure time and gain do before the sRGB encoding; 1 =
    /// unchanged.
    pub exposure: f32,
    /// Colour temperature of the scene's light, kelvin, against the
    /// camera's white balance for the training light (5000 K): lower is
    /// warmer (redder), higher cooler ([`colour_temperature_gains`]).
    pub colour_temp_k: f32,
    /// Light falloff towards the corners: the linear colour at the image
    /// corners is multiplied by 1 - this, quadratically in the radius; 0 =
    /// none.
    pub vignetting: f32,
    /// JPEG quality 1-100 the frame is compressed with and decoded again;
    /// 0 = none.
    pub jpeg_quality: u8,
    /// Length in pixels of a straight motion streak (the camera or the
    /// object moving during the exposure): every pixel is the mean along
    /// it; 0 = none.
    pub motion_blur_px: f32,
    /// Direction of the motion streak, degrees from the image's x axis
    /// towards y.
    pub motion_blur_deg: f32,
    /// Electrons a pixel collects at white (its full well over the
    /// camera's gain; lower is a higher gain, a noisier image): photon shot
    /// noise, Poisson in the electrons, so darker colours are relatively
    /// noisier; 0 = none. Seeded by the frame seed.
    pub full_well_e: f32,
    /// Read noise in electrons (with `full_well_e` only).
    pub read_noise_e: f32,
}

impl Effects {
    /// Whether the light differs from the training light.
    fn relit(&self) -> bool {
        self.exposure != 1.0 || self.colour_temp_k != TRAINING_LIGHT_K || self.vignetting != 0.0
    }
}

impl Default for Effects {
    /// The training light, no noise, no blur, brightness 1, no JPEG.
    fn default() -> Self {
        Effects {
            noise_sigma: 0.0,
            blur_sigma: 0.0,
            brightness: 1.0,
            exposure: 1.0,
            colour_temp_k: TRAINING_LIGHT_K,
            vignetting: 0.0,
            jpeg_quality: 0,
            motion_blur_px: 0.0,
            motion_blur_deg: 0.0,
            full_well_e: 0.0,
            read_noise_e: 0.0,
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
    if fx.relit() {
        light(rgb, w, h, fx);
    }
    if fx.blur_sigma.is_finite() && fx.blur_sigma > 0.0 {
        blur(rgb, w, h, fx.blur_sigma, tmp);
    }
    if fx.motion_blur_px.is_finite() && fx.motion_blur_px >= 1.0 {
        let deg = if fx.motion_blur_deg.is_finite() {
            fx.motion_blur_deg
        } else {
            0.0
        };
        motion_blur(rgb, w, h, fx.motion_blur_px, deg, tmp);
    }
    if fx.full_well_e.is_finite() && fx.full_well_e > 0.0 {
        let read = if fx.read_noise_e.is_finite() {
            fx.read_noise_e.max(0.0)
        } else {
            0.0
        };
        // Its own stream: the additive noise below draws from the seed.
        sensor_noise(rgb, fx.full_well_e, read, seed ^ 0x7365_6e73_6f72);
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
        let k = sigma / IRWIN_HALL_SD;
        for v in rgb.iter_mut() {
            let x = *v as f32 * gain + irwin_hall(&mut rng) * k;
            *v = (x + 0.5).clamp(0.0, 255.0) as u8;
        }
    } else if gain != 1.0 {
        for v in rgb.iter_mut() {
            *v = (*v as f32 * gain + 0.5).clamp(0.0, 255.0) as u8;
        }
    }
    if (1..=100).contains(&fx.jpeg_quality) {
        jpeg(rgb, w, h, fx.jpeg_quality);
    }
}

/// The standard deviation of [`irwin_hall`].
const IRWIN_HALL_SD: f32 = 147.8;

/// A normal draw of mean 0 and sd [`IRWIN_HALL_SD`], approximately: the
/// Irwin-Hall sum of four uniform bytes less its mean, close to Gaussian
/// and far cheaper than Box-Muller per channel.
fn irwin_hall(rng: &mut ChaCha8Rng) -> f32 {
    let r = rng.next_u32();
    let s = (r & 0xff) + ((r >> 8) & 0xff) + ((r >> 16) & 0xff) + (r >> 24);
    s as f32 - 510.0
}

/// Shot and read noise: each linear channel's `full_well` electrons at
/// white, drawn with the Poisson variance of the electrons collected plus
/// the read noise's (a normal approximation, close above a few electrons).
fn sensor_noise(rgb: &mut [u8], full_well: f32, read: f32, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let decode = srgb_decode_table();
    for v in rgb.iter_mut() {
        let electrons = decode[*v as usize] * full_well;
        let sd = (electrons + read * read).sqrt();
        let noise = irwin_hall(&mut rng) / IRWIN_HALL_SD * sd;
        *v = linear_to_srgb((electrons + noise) / full_well);
    }
}

/// Motion blur: each pixel the mean of the frame at `length` + 1 points
/// evenly along a streak through it at `deg` (nearest pixel, borders
/// clamped).
fn motion_blur(rgb: &mut [u8], w: usize, h: usize, length: f32, deg: f32, tmp: &mut Vec<f32>) {
    let length = length.min(2.0 * MAX_RADIUS as f32);
    let taps = length.ceil() as usize + 1;
    let (dy, dx) = deg.to_radians().sin_cos();
    let offset = |i: usize| {
        let t = (i as f32 / (taps - 1) as f32 - 0.5) * length;
        ((t * dx).round() as isize, (t * dy).round() as isize)
    };
    tmp.clear();
    tmp.resize(rgb.len(), 0.0);
    for y in 0..h {
        for (ox, oy) in (0..taps).map(offset) {
            let sy = (y as isize + oy).clamp(0, h as isize - 1) as usize;
            let src = &rgb[sy * w * 3..(sy + 1) * w * 3];
            let dst = &mut tmp[y * w * 3..(y + 1) * w * 3];
            for x in 0..w {
                let sx = (x as isize + ox).clamp(0, w as isize - 1) as usize;
                for c in 0..3 {
                    dst[x * 3 + c] += src[sx * 3 + c] as f32;
                }
            }
        }
    }
    let k = 1.0 / taps as f32;
    for (o, &a) in rgb.iter_mut().zip(tmp.iter()) {
        *o = (a * k + 0.5).clamp(0.0, 255.0) as u8;
    }
}

/// The light: each linear channel times exposure, the colour
/// temperature's gain and the vignetting falloff at the pixel.
fn light(rgb: &mut [u8], w: usize, h: usize, fx: &Effects) {
    let finite = |v: f32, default: f32| {
        if v.is_finite() && v >= 0.0 {
            v
        } else {
            default
        }
    };
    let exposure = finite(fx.exposure, 1.0);
    let cast = colour_temperature_gains(finite(fx.colour_temp_k, TRAINING_LIGHT_K));
    let vignetting = finite(fx.vignetting, 0.0).min(1.0);
    let decode = srgb_decode_table();
    let (cx, cy) = ((w as f32 - 1.0) / 2.0, (h as f32 - 1.0) / 2.0);
    let corner2 = (cx * cx + cy * cy).max(1.0);
    for (i, px) in rgb.chunks_exact_mut(3).enumerate() {
        let (x, y) = ((i % w) as f32 - cx, (i / w) as f32 - cy);
        let falloff = 1.0 - vignetting * (x * x + y * y) / corner2;
        for (c, v) in px.iter_mut().enumerate() {
            *v = linear_to_srgb(decode[*v as usize] * exposure * cast[c] * falloff);
        }
    }
}

/// Compresses the frame as JPEG of `quality` and decodes it again, as a
/// camera streaming MJPEG delivers it.
fn jpeg(rgb: &mut [u8], w: usize, h: usize, quality: u8) {
    let mut bytes = Vec::new();
    let encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality);
    let encoded = image::ImageEncoder::write_image(
        encoder,
        rgb,
        w as u32,
        h as u32,
        image::ExtendedColorType::Rgb8,
    );
    // An in-memory encoding of a well-formed buffer does not fail; if it
    // ever did, the frame stays uncompressed rather than corrupt.
    if encoded.is_err() {
        return;
    }
    if let Ok(decoded) = image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg) {
        let decoded = decoded.to_rgb8();
        if decoded.as_raw().len() == rgb.len() {
            rgb.copy_from_slice(decoded.as_raw());
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
    let stride = w * 3;
    let padded = (w + 2 * radius) * 3;
    tmp.clear();
    tmp.resize(h * stride + padded + stride, 0.0);
    let (horiz, rest) = tmp.split_at_mut(h * stride);
    let (pad, acc) = rest.split_at_mut(padded);
    // Horizontal pass into `horiz`: copy the row with clamped borders into
    // `pad`, then accumulate one tap at a time over the whole row (these
    // loops vectorise).
    for y in 0..h {
        let src = &rgb[y * stride..(y + 1) * stride];
        for (i, p) in pad.chunks_exact_mut(3).enumerate() {
            let x = i.saturating_sub(radius).min(w - 1);
            for c in 0..3 {
                p[c] = src[x * 3 + c] as f32;
            }
        }
        let dst = &mut horiz[y * stride..(y + 1) * stride];
        dst.fill(0.0);
        for (j, &k) in kernel.iter().enumerate() {
            for (d, &s) in dst.iter_mut().zip(&pad[j * 3..j * 3 + stride]) {
                *d += k * s;
            }
        }
    }
    // Vertical pass back into rgb, a whole row per tap.
    for y in 0..h {
        acc.fill(0.0);
        for (j, &k) in kernel.iter().enumerate() {
            let yy = (y + j).saturating_sub(radius).min(h - 1);
            for (a, &s) in acc.iter_mut().zip(&horiz[yy * stride..(yy + 1) * stride]) {
                *a += k * s;
            }
        }
        for (o, &a) in rgb[y * stride..(y + 1) * stride].iter_mut().zip(acc.iter()) {
            *o = (a + 0.5).clamp(0.0, 255.0) as u8;
        }
    }
}
