//! Light, in the one model the renderer draws it with and recognition
//! searches it with: the camera delivers sRGB bytes, and a change of the
//! light (its intensity, the exposure, its colour temperature against the
//! camera's white balance) multiplies each channel of the *linear* colour
//! by a gain (the von Kries model of colour constancy).

/// The colour temperature of the training light, kelvin: the camera's
/// white balance is set for it, so under it a grey surface stays grey.
pub const TRAINING_LIGHT_K: f32 = 5000.0;

/// Linear value (0-1) of an sRGB byte.
pub fn srgb_to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// [`srgb_to_linear`] of every byte, computed once per process: what
/// decodes a whole frame (the renderer's light, noise and moving
/// exposure) without a `powf` per channel.
pub fn srgb_decode_table() -> &'static [f32; 256] {
    static TABLE: std::sync::LazyLock<[f32; 256]> =
        std::sync::LazyLock::new(|| std::array::from_fn(|c| srgb_to_linear(c as u8)));
    &TABLE
}

/// sRGB byte of a linear value (clipped to 0-1, as a sensor saturates).
pub fn linear_to_srgb(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let v = if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0).round() as u8
}

/// An sRGB byte seen under light that multiplies its linear value by
/// `gain`.
pub fn relight(c: u8, gain: f32) -> u8 {
    linear_to_srgb(srgb_to_linear(c) * gain)
}

/// The linear-RGB white of a black body at `kelvin` (CIE 1960 uv of the
/// Planckian locus after Krystek 1985, 1000-15000 K, to linear sRGB at
/// luminance 1).
fn planckian_rgb(kelvin: f32) -> [f32; 3] {
    let t = kelvin.clamp(1000.0, 15000.0) as f64;
    let u = (0.860_117_757 + 1.541_182_54e-4 * t + 1.286_412_12e-7 * t * t)
        / (1.0 + 8.424_202_35e-4 * t + 7.081_451_63e-7 * t * t);
    let v = (0.317_398_726 + 4.228_062_45e-5 * t + 4.204_816_91e-8 * t * t)
        / (1.0 - 2.897_418_16e-5 * t + 1.614_560_53e-7 * t * t);
    let d = 2.0 * u - 8.0 * v + 4.0;
    let (x, y) = (3.0 * u / d, 2.0 * v / d);
    let (xx, yy, zz) = (x / y, 1.0, (1.0 - x - y) / y);
    [
        3.240_454_2 * xx - 1.537_138_5 * yy - 0.498_531_4 * zz,
        -0.969_266 * xx + 1.876_010_8 * yy + 0.041_556 * zz,
        0.055_643_4 * xx - 0.204_025_9 * yy + 1.057_225_2 * zz,
    ]
    .map(|c| c as f32)
}

/// The linear-RGB gains a light of `kelvin` gives a camera white-balanced
/// for [`TRAINING_LIGHT_K`], at unchanged luminance: below 5000 K red up
/// and blue down (warm, tungsten-like), above it the other way (cool,
/// daylight shade). 5000 K gives [1, 1, 1].
pub fn colour_temperature_gains(kelvin: f32) -> [f32; 3] {
    let (light, white) = (planckian_rgb(kelvin), planckian_rgb(TRAINING_LIGHT_K));
    let g = [0, 1, 2].map(|k| light[k] / white[k]);
    let luminance = 0.2126 * g[0] + 0.7152 * g[1] + 0.0722 * g[2];
    g.map(|c| c / luminance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transfer_round_trips_every_byte() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(c)), c);
            assert_eq!(srgb_decode_table()[c as usize], srgb_to_linear(c));
            assert_eq!(relight(c, 1.0), c);
        }
        assert_eq!(relight(200, 4.0), 255);
        assert!(relight(128, 0.5) < 128 && relight(128, 0.5) > 64);
    }

    #[test]
    fn warm_light_is_red_and_cool_light_is_blue_at_the_same_luminance() {
        let g = colour_temperature_gains(TRAINING_LIGHT_K);
        assert!(g.iter().all(|c| (c - 1.0).abs() < 1e-5), "{g:?}");
        let warm = colour_temperature_gains(3500.0);
        let cool = colour_temperature_gains(6500.0);
        assert!(warm[0] > 1.1 && warm[2] < 0.8, "{warm:?}");
        assert!(cool[0] < 0.95 && cool[2] > 1.15, "{cool:?}");
        for g in [warm, cool] {
            let y = 0.2126 * g[0] + 0.7152 * g[1] + 0.0722 * g[2];
            assert!((y - 1.0).abs() < 1e-5);
        }
    }
}
