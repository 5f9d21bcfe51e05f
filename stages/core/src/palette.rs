//! Colour palette: C representative colours of an object learned by k-means,
//! and an O(1) lookup table from RGB to palette index.

use crate::light::{linear_to_srgb, srgb_to_linear};
use crate::smooth::{self, Smoothing};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Palette index of a pixel whose colour the object does not own (or that
/// lies outside the mask). Histograms skip it.
pub const NOT_OBJECT: u8 = u8::MAX;

/// Most colours a palette can hold (indices 0..MAX_COLOURS, NOT_OBJECT apart).
pub const MAX_COLOURS: usize = NOT_OBJECT as usize;

/// Bits kept per channel in the lookup table: 6 bits = 262 144 entries,
/// finer than sensor noise, and small enough to rebuild on load.
const LUT_BITS: u32 = 6;
const LUT_SIDE: usize = 1 << LUT_BITS;

/// Cells of a lookup table.
pub(crate) const LUT_CELLS: usize = LUT_SIDE * LUT_SIDE * LUT_SIDE;

/// The lookup table's cell of an RGB pixel.
#[inline]
pub(crate) fn lut_cell(rgb: [u8; 3]) -> usize {
    let s = 8 - LUT_BITS;
    let (r, g, b) = (
        (rgb[0] >> s) as usize,
        (rgb[1] >> s) as usize,
        (rgb[2] >> s) as usize,
    );
    (r * LUT_SIDE + g) * LUT_SIDE + b
}

/// Colour space in which k-means runs and distances are measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourSpace {
    /// sRGB bytes as they come, scaled to 0..1.
    Rgb,
    /// CIE L*a*b* (D65), perceptually more uniform.
    Lab,
}

impl ColourSpace {
    /// Stable identifier used in the database file.
    pub fn id(self) -> u8 {
        match self {
            ColourSpace::Rgb => 0,
            ColourSpace::Lab => 1,
        }
    }

    /// Inverse of [`ColourSpace::id`].
    pub fn from_id(id: u8) -> Option<Self> {
        match id {
            0 => Some(ColourSpace::Rgb),
            1 => Some(ColourSpace::Lab),
            _ => None,
        }
    }

    /// Farthest any colour of a lookup-table cell lies from the cell's
    /// centre, in this space. The table decides a whole cell by its centre,
    /// so a rejection distance below this would reject the exact centre
    /// colours of a flat-coloured object (whose k-means spread is 0).
    /// RGB: half the diagonal of a 4x4x4 block (1 % over); Lab: the largest such
    /// distance over the gamut (checked by a test).
    pub fn lut_radius(self) -> f32 {
        match self {
            ColourSpace::Rgb => {
                let half_step = (256 / LUT_SIDE) as f32 / 2.0;
                // 1 % over: the exact bound must survive f32 rounding.
                1.01 * 3f32.sqrt() * half_step * 100.0 / 255.0
            }
            ColourSpace::Lab => 2.96,
        }
    }

    /// Converts an sRGB pixel into this space.
    pub fn convert(self, rgb: [u8; 3]) -> [f32; 3] {
        match self {
            ColourSpace::Rgb => rgb.map(|c| c as f32 / 255.0 * 100.0),
            ColourSpace::Lab => srgb_to_lab(rgb),
        }
    }
}

impl std::str::FromStr for ColourSpace {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "rgb" => Ok(ColourSpace::Rgb),
            "lab" => Ok(ColourSpace::Lab),
            other => Err(format!(
                "unknown colour space '{other}' (expected rgb or lab)"
            )),
        }
    }
}

/// Why a palette could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PaletteError {
    /// The palette size is 0 or larger than [`MAX_COLOURS`].
    #[error("palette size {0} is out of range 1..={max}", max = MAX_COLOURS)]
    BadSize(usize),
    /// Fewer training pixels than colours.
    #[error("{pixels} training pixels are too few for {colours} colours")]
    TooFewPixels {
        /// Pixels given.
        pixels: usize,
        /// Colours asked for.
        colours: usize,
    },
    /// A centre or threshold is not a finite number.
    #[error("palette value is not finite")]
    NotFinite,
}

/// An object's colours and the lookup table that quantises a frame to them.
#[derive(Clone, Debug)]
pub struct Palette {
    space: ColourSpace,
    centres: Vec<[f32; 3]>,
    reject_distance: f32,
    smoothing: Smoothing,
    lut: Vec<u8>,
}

impl PartialEq for Palette {
    fn eq(&self, other: &Self) -> bool {
        // The table is derived from the rest.
        self.space == other.space
            && self.centres == other.centres
            && self.reject_distance == other.reject_distance
            && self.smoothing == other.smoothing
    }
}

impl Palette {
    /// Learns `colours` centres by k-means (k-means++ seeding, `seed` fixed)
    /// on object pixels. `reject_quantile` in (0, 1] sets the distance beyond
    /// which a colour is "not object": that quantile of the training pixels'
    /// distances to their centre, times 1.5; `None` maps every colour to its
    /// nearest centre.
    pub fn train(
        pixels: &[[u8; 3]],
        colours: usize,
        space: ColourSpace,
        reject_quantile: Option<f32>,
        seed: u64,
    ) -> Result<Self, PaletteError> {
        if colours == 0 || colours > MAX_COLOURS {
            return Err(PaletteError::BadSize(colours));
        }
        if pixels.len() < colours {
            return Err(PaletteError::TooFewPixels {
                pixels: pixels.len(),
                colours,
            });
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // k-means on a bounded sample: the palette converges long before
        // every pixel of 216 views has been seen.
        const MAX_SAMPLES: usize = 60_000;
        let sample: Vec<[f32; 3]> = if pixels.len() <= MAX_SAMPLES {
            pixels.iter().map(|&p| space.convert(p)).collect()
        } else {
            (0..MAX_SAMPLES)
                .map(|_| space.convert(pixels[rng.random_range(0..pixels.len())]))
                .collect()
        };
        let centres = kmeans(&sample, colours, 25, &mut rng);
        let reject_distance = match reject_quantile {
            None => f32::INFINITY,
            Some(q) => {
                let mut d: Vec<f32> = sample
                    .iter()
                    .map(|p| nearest(&centres, p).1.sqrt())
                    .collect();
                d.sort_by(f32::total_cmp);
                let q = q.clamp(0.0, 1.0);
                let i = ((d.len() - 1) as f32 * q).round() as usize;
                d[i] * 1.5
            }
        };
        Self::from_centres(space, centres, reject_distance)
    }

    /// Builds a palette from known centres (in `space`) and a rejection
    /// distance (`f32::INFINITY` for none).
    pub fn from_centres(
        space: ColourSpace,
        centres: Vec<[f32; 3]>,
        reject_distance: f32,
    ) -> Result<Self, PaletteError> {
        if centres.is_empty() || centres.len() > MAX_COLOURS {
            return Err(PaletteError::BadSize(centres.len()));
        }
        if centres.iter().flatten().any(|v| !v.is_finite()) || reject_distance.is_nan() {
            return Err(PaletteError::NotFinite);
        }
        let mut palette = Palette {
            space,
            centres,
            reject_distance,
            smoothing: Smoothing::Off,
            lut: vec![NOT_OBJECT; LUT_CELLS],
        };
        palette.build_lut();
        Ok(palette)
    }

    fn build_lut(&mut self) {
        self.build_lut_under([1.0; 3]);
    }

    /// The lookup table for a camera whose light multiplies each linear
    /// channel of the colours the palette was learnt under by `gains`
    /// ([`crate::light`]): a cell stands for its colour divided by them.
    /// A cell saturated in a channel the light raises cannot be divided
    /// back (the ink was anywhere above the clip), so it is matched the
    /// other way round: against each colour as the light renders it,
    /// saturating like the camera.
    fn build_lut_under(&mut self, gains: [f32; 3]) {
        let step = 256 / LUT_SIDE;
        let reject = self.reject_distance.max(self.space.lut_radius());
        let reject2 = reject * reject;
        let rendered: Vec<[f32; 3]> = self
            .centre_rgb()
            .iter()
            .map(|c| {
                let lit = [0, 1, 2].map(|k| crate::light::relight(c[k], gains[k]));
                self.space.convert(lit)
            })
            .collect();
        let top = LUT_SIDE - 1;
        for r in 0..LUT_SIDE {
            for g in 0..LUT_SIDE {
                for b in 0..LUT_SIDE {
                    let cell = [r, g, b];
                    let saturated = (0..3).any(|k| cell[k] == top && gains[k] > 1.0);
                    let (i, d2) = if saturated {
                        // A saturated channel reads 255, whatever lies below.
                        let seen = cell.map(|c| {
                            if c == top {
                                255
                            } else {
                                (c * step + step / 2) as u8
                            }
                        });
                        nearest(&rendered, &self.space.convert(seen))
                    } else {
                        // Each cell stands for the centre of its 4x4x4 RGB block.
                        let rgb = cell.map(|c| (c * step + step / 2) as u8);
                        let rgb = [0, 1, 2].map(|k| match gains[k] {
                            1.0 => rgb[k],
                            g => crate::light::relight(rgb[k], 1.0 / g),
                        });
                        nearest(&self.centres, &self.space.convert(rgb))
                    };
                    self.lut[(r * LUT_SIDE + g) * LUT_SIDE + b] =
                        if d2 <= reject2 { i as u8 } else { NOT_OBJECT };
                }
            }
        }
    }

    /// The same colours seen under other light: the light multiplies each
    /// linear channel of the colours the palette was learnt under by
    /// `gains` (an exposure change all three alike, a colour cast each its
    /// own, [`crate::light`]), and the lookup table maps what the camera
    /// then delivers back to the learnt colour. Gains of 1 give this palette; non-finite or
    /// non-positive gains are refused.
    pub fn relit(&self, gains: [f32; 3]) -> Result<Palette, PaletteError> {
        if gains.iter().any(|g| !g.is_finite() || *g <= 0.0) {
            return Err(PaletteError::NotFinite);
        }
        let mut palette = self.clone();
        palette.build_lut_under(gains);
        Ok(palette)
    }

    /// Number of colours C.
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// Always false: a palette has at least one colour.
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }

    /// The colour space of the centres.
    pub fn space(&self) -> ColourSpace {
        self.space
    }

    /// The centres, in [`Palette::space`].
    pub fn centres(&self) -> &[[f32; 3]] {
        &self.centres
    }

    /// Distance beyond which a colour maps to [`NOT_OBJECT`].
    pub fn reject_distance(&self) -> f32 {
        self.reject_distance
    }

    /// Palette index of one RGB pixel, O(1).
    #[inline]
    pub fn index(&self, rgb: [u8; 3]) -> u8 {
        self.lut[lut_cell(rgb)]
    }

    /// The lookup table: the index of every cell ([`lut_cell`]).
    pub(crate) fn lut(&self) -> &[u8] {
        &self.lut
    }

    /// Nearest centre of a pixel and its distance, computed exactly (not via
    /// the table).
    pub fn nearest(&self, rgb: [u8; 3]) -> (u8, f32) {
        let (i, d2) = nearest(&self.centres, &self.space.convert(rgb));
        (i as u8, d2.sqrt())
    }

    /// An sRGB rendering of each centre (for plots and debug images).
    pub fn centre_rgb(&self) -> Vec<[u8; 3]> {
        self.centres
            .iter()
            .map(|c| match self.space {
                ColourSpace::Rgb => c.map(|v| (v / 100.0 * 255.0).round().clamp(0.0, 255.0) as u8),
                ColourSpace::Lab => lab_to_srgb(*c),
            })
            .collect()
    }

    /// The same palette quantising frames smoothed by `smoothing` first
    /// (the palette's colours must have been learnt from pixels smoothed
    /// alike, [`crate::smooth`]).
    pub fn with_smoothing(mut self, smoothing: Smoothing) -> Self {
        self.smoothing = smoothing;
        self
    }

    /// How frames are smoothed before they are quantised.
    pub fn smoothing(&self) -> Smoothing {
        self.smoothing
    }

    /// Quantises a packed RGB frame (`width * height * 3` bytes) into `out`,
    /// reusing its buffer.
    pub fn quantise_into(&self, rgb: &[u8], width: u32, height: u32, out: &mut IndexImage) {
        let n = width as usize * height as usize;
        assert_eq!(
            rgb.len(),
            n * 3,
            "RGB buffer does not match {width}x{height}"
        );
        out.width = width;
        out.height = height;
        out.data.resize(n, NOT_OBJECT);
        self.quantise_into_slice(rgb, width, height, &mut out.data);
    }

    /// Quantises a packed RGB frame of `width x height` into `out`, one
    /// index per pixel (for example straight into a shared-memory sample);
    /// panics if the lengths do not match.
    pub fn quantise_into_slice(&self, rgb: &[u8], width: u32, height: u32, out: &mut [u8]) {
        self.quantise_into_slice_smoothed(rgb, width, height, out, self.smoothing);
    }

    /// [`quantise_into_slice`](Self::quantise_into_slice) with the frame
    /// smoothed by `smoothing` instead of the palette's own (a frame
    /// already blurred as much as the palette would smooth it is
    /// quantised as it is).
    pub fn quantise_into_slice_smoothed(
        &self,
        rgb: &[u8],
        width: u32,
        height: u32,
        out: &mut [u8],
        smoothing: Smoothing,
    ) {
        assert_eq!(
            (rgb.len(), out.len()),
            (
                width as usize * height as usize * 3,
                width as usize * height as usize
            ),
            "RGB or index buffer does not match {width}x{height}"
        );
        let lookup = |rgb: &[u8], out: &mut [u8]| {
            for (dst, px) in out.iter_mut().zip(rgb.chunks_exact(3)) {
                *dst = self.index([px[0], px[1], px[2]]);
            }
        };
        match smoothing {
            Smoothing::Off => lookup(rgb, out),
            Smoothing::Binomial => smooth::with_smoothed(rgb, width, height, |s| lookup(s, out)),
        }
    }

    /// Quantises a packed RGB frame into a new index image.
    pub fn quantise(&self, rgb: &[u8], width: u32, height: u32) -> IndexImage {
        let mut out = IndexImage::default();
        self.quantise_into(rgb, width, height, &mut out);
        out
    }
}

/// A frame of palette indices, row-major, one byte per pixel.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct IndexImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` palette indices (or [`NOT_OBJECT`]).
    pub data: Vec<u8>,
}

impl IndexImage {
    /// Wraps index data; panics if the length does not match.
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Self {
        assert_eq!(data.len(), width as usize * height as usize);
        IndexImage {
            width,
            height,
            data,
        }
    }

    /// Index at (x, y).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> u8 {
        self.data[y as usize * self.width as usize + x as usize]
    }

    /// The image, borrowed.
    pub fn view(&self) -> IndexView<'_> {
        IndexView {
            width: self.width,
            height: self.height,
            data: &self.data,
        }
    }
}

/// A borrowed frame of palette indices, row-major, one byte per pixel: an
/// [`IndexImage`], or indices another process left in shared memory, read
/// where they are.
#[derive(Clone, Copy, Debug)]
pub struct IndexView<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` palette indices (or [`NOT_OBJECT`]).
    pub data: &'a [u8],
}

impl<'a> IndexView<'a> {
    /// Views `data` as a `width` x `height` frame; `None` if the length
    /// does not match.
    pub fn new(width: u32, height: u32, data: &'a [u8]) -> Option<Self> {
        (data.len() == width as usize * height as usize).then_some(IndexView {
            width,
            height,
            data,
        })
    }
}

impl<'a> From<&'a IndexImage> for IndexView<'a> {
    fn from(image: &'a IndexImage) -> Self {
        image.view()
    }
}

fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

fn nearest(centres: &[[f32; 3]], p: &[f32; 3]) -> (usize, f32) {
    let mut best = (0, f32::INFINITY);
    for (i, c) in centres.iter().enumerate() {
        let d = dist2(c, p);
        if d < best.1 {
            best = (i, d);
        }
    }
    best
}

/// Lloyd's k-means with k-means++ seeding. Empty clusters are re-seeded at the
/// point farthest from its centre so that all k colours stay in use.
fn kmeans(points: &[[f32; 3]], k: usize, iterations: usize, rng: &mut ChaCha8Rng) -> Vec<[f32; 3]> {
    let mut centres = Vec::with_capacity(k);
    centres.push(points[rng.random_range(0..points.len())]);
    let mut d2: Vec<f32> = points.iter().map(|p| dist2(p, &centres[0])).collect();
    while centres.len() < k {
        let total: f64 = d2.iter().map(|&d| d as f64).sum();
        let next = if total <= 0.0 {
            points[rng.random_range(0..points.len())]
        } else {
            let mut target = rng.random::<f64>() * total;
            let mut chosen = points.len() - 1;
            for (i, &d) in d2.iter().enumerate() {
                target -= d as f64;
                if target <= 0.0 {
                    chosen = i;
                    break;
                }
            }
            points[chosen]
        };
        for (d, p) in d2.iter_mut().zip(points) {
            *d = d.min(dist2(p, &next));
        }
        centres.push(next);
    }
    let mut assign = vec![0usize; points.len()];
    for _ in 0..iterations {
        let mut changed = false;
        let mut sums = vec![[0f64; 4]; k];
        let mut worst = (0usize, -1f32);
        for (i, p) in points.iter().enumerate() {
            let (c, d) = nearest(&centres, p);
            if assign[i] != c {
                assign[i] = c;
                changed = true;
            }
            if d > worst.1 {
                worst = (i, d);
            }
            let s = &mut sums[c];
            s[0] += p[0] as f64;
            s[1] += p[1] as f64;
            s[2] += p[2] as f64;
            s[3] += 1.0;
        }
        for (c, s) in centres.iter_mut().zip(&sums) {
            if s[3] > 0.0 {
                *c = [
                    (s[0] / s[3]) as f32,
                    (s[1] / s[3]) as f32,
                    (s[2] / s[3]) as f32,
                ];
            } else {
                *c = points[worst.0];
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    centres
}

const WHITE: [f32; 3] = [0.950_47, 1.0, 1.088_83];

fn lab_f(t: f32) -> f32 {
    if t > 216.0 / 24389.0 {
        t.cbrt()
    } else {
        (24389.0 / 27.0 * t + 16.0) / 116.0
    }
}

fn lab_f_inv(t: f32) -> f32 {
    if t * t * t > 216.0 / 24389.0 {
        t * t * t
    } else {
        (116.0 * t - 16.0) / (24389.0 / 27.0)
    }
}

/// sRGB to CIE L*a*b* (D65).
fn srgb_to_lab(rgb: [u8; 3]) -> [f32; 3] {
    let [r, g, b] = rgb.map(srgb_to_linear);
    let x = 0.412_456_4 * r + 0.357_576_1 * g + 0.180_437_5 * b;
    let y = 0.212_672_9 * r + 0.715_152_2 * g + 0.072_175 * b;
    let z = 0.019_333_9 * r + 0.119_192 * g + 0.950_304_1 * b;
    let (fx, fy, fz) = (
        lab_f(x / WHITE[0]),
        lab_f(y / WHITE[1]),
        lab_f(z / WHITE[2]),
    );
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

fn lab_to_srgb(lab: [f32; 3]) -> [u8; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let fx = fy + lab[1] / 500.0;
    let fz = fy - lab[2] / 200.0;
    let (x, y, z) = (
        lab_f_inv(fx) * WHITE[0],
        lab_f_inv(fy) * WHITE[1],
        lab_f_inv(fz) * WHITE[2],
    );
    let r = 3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z;
    let g = -0.969_266 * x + 1.876_010_8 * y + 0.041_556 * z;
    let b = 0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z;
    [linear_to_srgb(r), linear_to_srgb(g), linear_to_srgb(b)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Largest distance, in `space`, from a lookup cell's centre colour to
    /// any of its corner colours, over every cell.
    fn widest_cell(space: ColourSpace) -> f32 {
        let step = 256 / LUT_SIDE;
        let mut widest = 0f32;
        for r in 0..LUT_SIDE {
            for g in 0..LUT_SIDE {
                for b in 0..LUT_SIDE {
                    let cell = [r, g, b];
                    let centre = space.convert(cell.map(|c| (c * step + step / 2) as u8));
                    for corner in 0..8 {
                        let rgb: [u8; 3] = std::array::from_fn(|k| {
                            (cell[k] * step + if corner >> k & 1 == 1 { step - 1 } else { 0 }) as u8
                        });
                        let p = space.convert(rgb);
                        let d2: f32 = (0..3).map(|k| (p[k] - centre[k]).powi(2)).sum();
                        widest = widest.max(d2.sqrt());
                    }
                }
            }
        }
        widest
    }

    #[test]
    fn lut_radius_covers_every_cell_and_is_tight() {
        for space in [ColourSpace::Rgb, ColourSpace::Lab] {
            let widest = widest_cell(space);
            let radius = space.lut_radius();
            assert!(
                widest <= radius,
                "{space:?}: cell radius {widest} > {radius}"
            );
            assert!(
                widest > 0.85 * radius,
                "{space:?}: {radius} is loose for {widest}"
            );
        }
    }

    #[test]
    fn a_relit_palette_maps_colours_under_the_other_light_back() {
        let colours = [
            [200u8, 30, 30],
            [30, 30, 200],
            [240, 240, 240],
            [90, 160, 60],
        ];
        let centres = colours
            .iter()
            .map(|&c| ColourSpace::Lab.convert(c))
            .collect();
        let p = Palette::from_centres(ColourSpace::Lab, centres, 8.0).expect("palette");
        let gains = [0.5, 0.45, 0.35];
        let relit = p.relit(gains).unwrap();
        for (i, c) in colours.iter().enumerate() {
            let seen = [0, 1, 2].map(|k| crate::light::relight(c[k], gains[k]));
            assert_eq!(relit.index(seen), i as u8, "{c:?} seen as {seen:?}");
            assert_eq!(p.index(seen), NOT_OBJECT, "{c:?} seen as {seen:?}");
        }
        assert_eq!(p.relit([1.0; 3]).unwrap().lut, p.lut);
        assert!(p.relit([1.0, f32::NAN, 1.0]).is_err());
        assert!(p.relit([1.0, 0.0, 1.0]).is_err());
    }

    #[test]
    fn a_relit_palette_maps_inks_the_light_saturates_to_the_ink() {
        // Paper white, cream and a light grey under brighter light: the
        // first two saturate, and divided back from 255 they would read as
        // the grey (or as nothing).
        let colours = [
            [245u8, 245, 240],
            [250, 225, 160],
            [150, 150, 150],
            [200, 30, 30],
        ];
        let centres = colours
            .iter()
            .map(|&c| ColourSpace::Lab.convert(c))
            .collect();
        let p = Palette::from_centres(ColourSpace::Lab, centres, 8.0).expect("palette");
        for gains in [[2.0; 3], [1.6, 1.0, 0.55]] {
            let relit = p.relit(gains).unwrap();
            for (i, c) in colours.iter().enumerate() {
                let seen = [0, 1, 2].map(|k| crate::light::relight(c[k], gains[k]));
                assert_eq!(
                    relit.index(seen),
                    i as u8,
                    "{c:?} seen as {seen:?} under {gains:?}"
                );
            }
        }
    }

    #[test]
    fn a_flat_coloured_object_keeps_its_colours_with_zero_spread() {
        // Three exact colours, as a flat-shaded object gives: k-means finds
        // them with zero spread, so the learned rejection distance is 0.
        let colours = [[200u8, 30, 30], [30, 30, 200], [240, 240, 240]];
        for space in [ColourSpace::Rgb, ColourSpace::Lab] {
            let centres = colours.iter().map(|&c| space.convert(c)).collect();
            let p = Palette::from_centres(space, centres, 0.0).expect("palette");
            for (i, &c) in colours.iter().enumerate() {
                assert_eq!(p.index(c), i as u8, "{space:?}: colour {c:?}");
            }
            assert_eq!(
                p.index([20, 160, 20]),
                NOT_OBJECT,
                "{space:?}: green is not the object's"
            );
        }
    }

    #[test]
    fn lab_round_trip_is_close() {
        for rgb in [[0, 0, 0], [255, 255, 255], [200, 30, 40], [10, 120, 250]] {
            let back = lab_to_srgb(srgb_to_lab(rgb));
            for c in 0..3 {
                assert!(
                    (back[c] as i32 - rgb[c] as i32).abs() <= 1,
                    "{rgb:?} -> {back:?}"
                );
            }
        }
    }

    #[test]
    fn kmeans_finds_separated_clusters() {
        let mut pixels = Vec::new();
        for i in 0..300u32 {
            let j = (i % 7) as u8;
            pixels.push([250 - j, j, j]);
            pixels.push([j, 250 - j, j]);
            pixels.push([j, j, 250 - j]);
        }
        for space in [ColourSpace::Rgb, ColourSpace::Lab] {
            let p = Palette::train(&pixels, 3, space, None, 7).unwrap();
            let (r, g, b) = (
                p.index([255, 0, 0]),
                p.index([0, 255, 0]),
                p.index([0, 0, 255]),
            );
            assert!(r != g && g != b && r != b, "{space:?}: {r} {g} {b}");
            assert_eq!(p.index([245, 4, 4]), r);
        }
    }

    #[test]
    fn far_colours_are_rejected() {
        let pixels: Vec<[u8; 3]> = (0..200).map(|i| [200 + (i % 10) as u8, 20, 20]).collect();
        let p = Palette::train(&pixels, 2, ColourSpace::Lab, Some(0.99), 1).unwrap();
        assert_ne!(p.index([205, 20, 20]), NOT_OBJECT);
        assert_eq!(p.index([20, 20, 200]), NOT_OBJECT);
    }

    #[test]
    fn bad_sizes_are_errors() {
        let px = vec![[1u8, 2, 3]; 4];
        assert_eq!(
            Palette::train(&px, 0, ColourSpace::Rgb, None, 0).unwrap_err(),
            PaletteError::BadSize(0)
        );
        assert!(matches!(
            Palette::train(&px, 5, ColourSpace::Rgb, None, 0),
            Err(PaletteError::TooFewPixels { .. })
        ));
    }

    #[test]
    fn quantise_maps_every_pixel() {
        let pixels = [[255u8, 0, 0], [0, 0, 255]];
        let p = Palette::from_centres(
            ColourSpace::Rgb,
            pixels
                .iter()
                .map(|&c| ColourSpace::Rgb.convert(c))
                .collect(),
            f32::INFINITY,
        )
        .unwrap();
        let img = p.quantise(&[255, 0, 0, 0, 0, 255, 250, 5, 5], 3, 1);
        assert_eq!(img.data, vec![0, 1, 0]);
    }

    #[test]
    fn a_smoothing_palette_quantises_the_smoothed_frame() {
        let pixels = [[255u8, 0, 0], [0, 0, 255], [128, 0, 128]];
        let centres = pixels
            .iter()
            .map(|&c| ColourSpace::Rgb.convert(c))
            .collect();
        let raw = Palette::from_centres(ColourSpace::Rgb, centres, 60.0).unwrap();
        let smoothing = raw.clone().with_smoothing(Smoothing::Binomial);
        assert_ne!(raw, smoothing);
        // Red stripes on blue, 2 px wide: smoothed, the stripes' edges and
        // narrow gaps turn purple.
        let (w, h) = (12u32, 6u32);
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                if (i % w) / 2 % 2 == 0 {
                    [255, 0, 0]
                } else {
                    [0, 0, 255]
                }
            })
            .collect();
        let (mut rows, mut smoothed) = (Vec::new(), Vec::new());
        smooth::binomial_into(&rgb, w as usize, h as usize, &mut rows, &mut smoothed);
        let expected = raw.quantise(&smoothed, w, h);
        let got = smoothing.quantise(&rgb, w, h);
        assert_eq!(got, expected);
        assert_ne!(got, raw.quantise(&rgb, w, h));
        assert!(got.data.contains(&2), "{:?}", got.data);
        let mut slice = vec![0u8; (w * h) as usize];
        smoothing.quantise_into_slice(&rgb, w, h, &mut slice);
        assert_eq!(slice, got.data);
        // Told the frame needs no smoothing, it quantises the raw pixels.
        smoothing.quantise_into_slice_smoothed(&rgb, w, h, &mut slice, Smoothing::Off);
        assert_eq!(slice, raw.quantise(&rgb, w, h).data);
        raw.quantise_into_slice_smoothed(&rgb, w, h, &mut slice, Smoothing::Binomial);
        assert_eq!(slice, got.data);
    }
}
