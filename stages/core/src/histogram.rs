//! Colour cooccurrence histograms over a masked region of an index image.
//!
//! One loop serves the three kinds of the paper: for every reference pixel
//! (colour a) and every offset v of an annulus r_min < |v| <= r_max in a half
//! plane, the pixel at the other end (colour b) counts into bin (d, a, b),
//! where d is the orientation of v in [0°, 180°) (ACCH), the length of v
//! (DCCH), or nothing (CCH). Restricting v to a half plane counts each
//! unordered pixel pair once; its reversed pair is the same pair.

use crate::palette::{IndexImage, NOT_OBJECT};
use std::f32::consts::PI;

/// Which geometry a histogram bins besides the colour pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HistogramKind {
    /// Colour pairs only (Chang and Krumm).
    Cch,
    /// Colour pairs by distance between the two pixels.
    Dcch,
    /// Colour pairs by orientation of the vector between the two pixels.
    Acch,
}

impl HistogramKind {
    /// Stable identifier used in the database file.
    pub fn id(self) -> u8 {
        match self {
            HistogramKind::Cch => 0,
            HistogramKind::Dcch => 1,
            HistogramKind::Acch => 2,
        }
    }

    /// Inverse of [`HistogramKind::id`].
    pub fn from_id(id: u8) -> Option<Self> {
        match id {
            0 => Some(HistogramKind::Cch),
            1 => Some(HistogramKind::Dcch),
            2 => Some(HistogramKind::Acch),
            _ => None,
        }
    }
}

impl std::fmt::Display for HistogramKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            HistogramKind::Cch => "cch",
            HistogramKind::Dcch => "dcch",
            HistogramKind::Acch => "acch",
        })
    }
}

/// Which offsets of the annulus are visited.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OffsetSampling {
    /// Every integer offset in the annulus (about 470 for 10 < r <= 20):
    /// the textbook definition, used to pin it down in tests.
    Dense,
    /// `rings` radii x `angles` orientations over [0°, 180°), rounded to
    /// integer offsets: a fixed cost whatever the scale, the same offsets
    /// scikit-image's `graycomatrix` would be given.
    Polar {
        /// Radii spread evenly over the annulus.
        rings: u16,
        /// Orientations spread evenly over [0°, 180°).
        angles: u16,
    },
}

/// The definition of a histogram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistogramParams {
    /// CCH, DCCH or ACCH.
    pub kind: HistogramKind,
    /// Palette size C.
    pub colours: u16,
    /// Geometric bins D (orientations for ACCH, distances for DCCH, 1 for CCH).
    pub bins: u16,
    /// Inner radius in pixels at the training scale (exclusive).
    pub r_min: f32,
    /// Outer radius in pixels at the training scale (inclusive).
    pub r_max: f32,
    /// Reference-pixel stride in pixels at the training scale.
    pub stride: u16,
    /// Offset set.
    pub sampling: OffsetSampling,
}

impl Default for HistogramParams {
    /// The paper's ACCH (40 colours, annulus 10 < r <= 20) with 12
    /// orientations; the sampling was chosen by measurement (see README).
    fn default() -> Self {
        HistogramParams {
            kind: HistogramKind::Acch,
            colours: 40,
            bins: 12,
            r_min: 10.0,
            r_max: 20.0,
            stride: 2,
            sampling: OffsetSampling::Polar {
                rings: 4,
                angles: 48,
            },
        }
    }
}

/// Why histogram parameters are unusable.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum HistogramError {
    /// A parameter is out of its range.
    #[error("invalid histogram parameter: {0}")]
    Invalid(String),
}

impl HistogramParams {
    /// Geometric bins actually used (1 for CCH).
    pub fn geometric_bins(&self) -> usize {
        match self.kind {
            HistogramKind::Cch => 1,
            _ => self.bins as usize,
        }
    }

    /// Length of the histogram vector: D x C x C.
    pub fn len(&self) -> usize {
        self.geometric_bins() * self.colours as usize * self.colours as usize
    }

    /// Always false for valid parameters.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<(), HistogramError> {
        let bad = |m: String| Err(HistogramError::Invalid(m));
        if self.colours == 0 || self.colours as usize > crate::palette::MAX_COLOURS {
            return bad(format!("colours = {} (expected 1..=255)", self.colours));
        }
        if self.bins == 0 {
            return bad("bins = 0 (expected >= 1)".into());
        }
        if !(self.r_min.is_finite() && self.r_max.is_finite()) || self.r_min < 0.0 {
            return bad(format!("r_min = {} must be finite and >= 0", self.r_min));
        }
        if self.r_max <= self.r_min || self.r_max < 1.0 || self.r_max > 512.0 {
            return bad(format!(
                "r_max = {} must exceed r_min = {} and lie in [1, 512]",
                self.r_max, self.r_min
            ));
        }
        if self.stride == 0 {
            return bad("stride = 0 (expected >= 1)".into());
        }
        if let OffsetSampling::Polar { rings, angles } = self.sampling
            && (rings == 0 || angles == 0)
        {
            return bad(format!("polar sampling {rings} rings x {angles} angles"));
        }
        Ok(())
    }

    /// The offsets (dx, dy, geometric bin) at `scale` (1 = training distance),
    /// with y pointing down as in images.
    pub fn offsets(&self, scale: f32) -> Vec<(i32, i32, u16)> {
        let mut out = Vec::new();
        self.offsets_into(scale, &mut out);
        out
    }

    /// [`offsets`](Self::offsets) into `out` (cleared first): no allocation
    /// once `out` has room, so a scale that changes every frame costs none.
    pub fn offsets_into(&self, scale: f32, out: &mut Vec<(i32, i32, u16)>) {
        out.clear();
        let (r_min, r_max) = (self.r_min * scale, self.r_max * scale);
        let d = self.geometric_bins();
        let geometric_bin = |dx: i32, dy: i32| -> u16 {
            let b = match self.kind {
                HistogramKind::Cch => 0.0,
                HistogramKind::Acch => {
                    // Orientation in [0, pi): y is flipped so angles turn
                    // counter-clockwise as on paper.
                    let a = (-dy as f32).atan2(dx as f32).rem_euclid(PI);
                    a / PI * d as f32
                }
                HistogramKind::Dcch => {
                    let r = ((dx * dx + dy * dy) as f32).sqrt();
                    (r - r_min) / (r_max - r_min) * d as f32
                }
            };
            (b.max(0.0) as usize).min(d - 1) as u16
        };
        match self.sampling {
            OffsetSampling::Dense => {
                let r = r_max.floor() as i32;
                for dy in -r..=0 {
                    for dx in -r..=r {
                        // Half plane: above the reference row, or right of it.
                        if dy == 0 && dx <= 0 {
                            continue;
                        }
                        let r2 = (dx * dx + dy * dy) as f32;
                        if r2 > r_min * r_min && r2 <= r_max * r_max {
                            out.push((dx, dy, geometric_bin(dx, dy)));
                        }
                    }
                }
            }
            OffsetSampling::Polar { rings, angles } => {
                for ring in 0..rings {
                    let r = r_min + (r_max - r_min) * (ring as f32 + 0.5) / rings as f32;
                    for k in 0..angles {
                        let a = (k as f32 + 0.5) * PI / angles as f32;
                        let (dx, dy) =
                            ((r * a.cos()).round() as i32, -(r * a.sin()).round() as i32);
                        if (dx, dy) == (0, 0)
                            || out.iter().any(|o: &(i32, i32, u16)| (o.0, o.1) == (dx, dy))
                        {
                            continue;
                        }
                        // Bin by the nominal orientation: rounding must not
                        // move a sample across the 0/180 degree seam.
                        let bin = match self.kind {
                            HistogramKind::Acch => ((a / PI * d as f32) as usize).min(d - 1) as u16,
                            _ => geometric_bin(dx, dy),
                        };
                        out.push((dx, dy, bin));
                    }
                }
            }
        }
    }
}

/// A rectangle of pixels (a region of interest).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Rect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Rect {
    /// The whole of a `width` x `height` image.
    pub fn full(width: u32, height: u32) -> Self {
        Rect {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// This rectangle cut to a `width` x `height` image.
    pub fn clamp_to(self, width: u32, height: u32) -> Self {
        let x = self.x.min(width);
        let y = self.y.min(height);
        Rect {
            x,
            y,
            width: self.width.min(width - x),
            height: self.height.min(height - y),
        }
    }

    /// Area in pixels.
    pub fn area(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// Its centre, pixels (pixel centres at integer coordinates).
    pub fn centre(&self) -> (f32, f32) {
        (
            self.x as f32 + (self.width as f32 - 1.0) / 2.0,
            self.y as f32 + (self.height as f32 - 1.0) / 2.0,
        )
    }
}

/// Computes histograms, reusing its buffers: after the first frames of a
/// given ROI size it does not allocate.
#[derive(Debug, Clone)]
pub struct HistogramExtractor {
    params: HistogramParams,
    /// Scale whose offsets are cached in `offsets`.
    scale: f32,
    offsets: Vec<(i32, i32, u16)>,
    pad: usize,
    stride: usize,
    /// Linear offsets into `buf` and bin bases (d x C x C), for the current
    /// padded width.
    linear: Vec<(isize, u32)>,
    linear_width: usize,
    buf: Vec<u8>,
    counts: Vec<u32>,
}

impl HistogramExtractor {
    /// An extractor for `params`.
    pub fn new(params: HistogramParams) -> Result<Self, HistogramError> {
        params.validate()?;
        let mut e = HistogramExtractor {
            params,
            scale: f32::NAN,
            offsets: Vec::new(),
            pad: 0,
            stride: 1,
            linear: Vec::new(),
            linear_width: 0,
            buf: Vec::new(),
            counts: vec![0; params.len()],
        };
        e.set_scale(1.0);
        Ok(e)
    }

    /// The parameters.
    pub fn params(&self) -> &HistogramParams {
        &self.params
    }

    fn set_scale(&mut self, scale: f32) {
        if scale == self.scale {
            return;
        }
        self.scale = scale;
        self.params.offsets_into(scale, &mut self.offsets);
        self.pad = self
            .offsets
            .iter()
            .map(|&(dx, dy, _)| dx.unsigned_abs().max(dy.unsigned_abs()) as usize)
            .max()
            .unwrap_or(0);
        // The stride follows the scale so that a closer object costs the same
        // and samples the same share of its pixels.
        self.stride = ((self.params.stride as f32 * scale).round() as usize).max(1);
        self.linear_width = 0;
    }

    /// Pixel pairs counted per pixel of object area measured at the
    /// training scale, at `scale` (the number of annulus offsets times the
    /// object's area there over the reference pixels' stride squared): a
    /// view of `n` pairs at scale 1 has about `n * rate(scale) / rate(1)`
    /// at `scale`, whole. The stride is rounded to whole pixels, so the
    /// count does not follow the scale smoothly.
    pub fn pair_rate(&mut self, scale: f32) -> f32 {
        let scale = usable_scale(scale);
        self.set_scale(scale);
        let stride = self.stride as f32;
        self.offsets.len() as f32 * scale * scale / (stride * stride)
    }

    /// Computes the normalised histogram of the pixels of `roi` whose mask
    /// byte is non-zero (all of them without a mask) into `out`
    /// (`params.len()` values summing to 1, or all 0 when no pair was
    /// found). `scale` stretches the annulus and the stride: 1 at the
    /// training distance, 2 when the object looks twice as large.
    /// Returns the number of pixel pairs counted.
    pub fn extract(
        &mut self,
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        scale: f32,
        out: &mut [f32],
    ) -> u64 {
        assert_eq!(out.len(), self.params.len(), "output length");
        if let Some(m) = mask {
            assert_eq!(m.len(), image.data.len(), "mask size");
        }
        self.set_scale(usable_scale(scale));
        let roi = roi.clamp_to(image.width, image.height);
        let (w, h, pad) = (roi.width as usize, roi.height as usize, self.pad);
        let pw = w + 2 * pad;
        let ph = h + 2 * pad;
        self.buf.clear();
        self.buf.resize(pw * ph, NOT_OBJECT);
        let colours = self.params.colours as usize;
        let iw = image.width as usize;
        for row in 0..h {
            let src = (roi.y as usize + row) * iw + roi.x as usize;
            let dst = (row + pad) * pw + pad;
            let src_row = &image.data[src..src + w];
            let dst_row = &mut self.buf[dst..dst + w];
            match mask {
                Some(m) => {
                    let m_row = &m[src..src + w];
                    for ((d, &s), &k) in dst_row.iter_mut().zip(src_row).zip(m_row) {
                        *d = if k != 0 && (s as usize) < colours {
                            s
                        } else {
                            NOT_OBJECT
                        };
                    }
                }
                None => {
                    for (d, &s) in dst_row.iter_mut().zip(src_row) {
                        *d = if (s as usize) < colours {
                            s
                        } else {
                            NOT_OBJECT
                        };
                    }
                }
            }
        }
        if self.linear_width != pw {
            let cc = (colours * colours) as u32;
            self.linear.clear();
            self.linear.extend(
                self.offsets
                    .iter()
                    .map(|&(dx, dy, d)| (dy as isize * pw as isize + dx as isize, d as u32 * cc)),
            );
            self.linear_width = pw;
        }
        self.counts.fill(0);
        let mut pairs = 0u64;
        let buf = &self.buf[..];
        let counts = &mut self.counts[..];
        for ry in (0..h).step_by(self.stride) {
            let row_start = (ry + pad) * pw + pad;
            for rx in (0..w).step_by(self.stride) {
                let p = row_start + rx;
                let a = buf[p];
                if a == NOT_OBJECT {
                    continue;
                }
                let a_row = a as u32 * colours as u32;
                for &(off, base) in &self.linear {
                    // In bounds: |dx|, |dy| <= pad and the border is `pad` wide.
                    let b = buf[(p as isize + off) as usize];
                    if b != NOT_OBJECT {
                        // b < C and a < C were ensured when filling `buf`.
                        counts[(base + a_row + b as u32) as usize] += 1;
                        pairs += 1;
                    }
                }
            }
        }
        if pairs == 0 {
            out.fill(0.0);
        } else {
            let inv = 1.0 / pairs as f64;
            for (o, &c) in out.iter_mut().zip(counts.iter()) {
                *o = (c as f64 * inv) as f32;
            }
        }
        pairs
    }
}

/// The scale an extractor works at for `scale`: within 0.05-20, 1 for
/// what is not a positive number.
fn usable_scale(scale: f32) -> f32 {
    if scale.is_finite() && scale > 0.0 {
        scale.clamp(0.05, 20.0)
    } else {
        1.0
    }
}

/// The ACCH `h` (`bins` orientations x `colours` x `colours`) of the same
/// view with the image turned `shift` orientation bins counter-clockwise
/// (`shift` x 180° / `bins`), into `out`: bin d moves to d + shift, and a
/// pair whose orientation passes 0° or 180° comes back the other way
/// round, (a, b) as (b, a), because orientations are kept in [0°, 180°).
pub fn roll_acch(h: &[f32], colours: usize, bins: usize, shift: i32, out: &mut [f32]) {
    let block = colours * colours;
    assert_eq!(h.len(), bins * block, "histogram length");
    assert_eq!(out.len(), h.len(), "output length");
    let d = bins as i32;
    for to in 0..d {
        let from = to - shift;
        let (src, reversed) = (from.rem_euclid(d) as usize, from.div_euclid(d) % 2 != 0);
        let (src, dst) = (
            &h[src * block..(src + 1) * block],
            &mut out[to as usize * block..(to as usize + 1) * block],
        );
        if reversed {
            for a in 0..colours {
                for b in 0..colours {
                    dst[a * colours + b] = src[b * colours + a];
                }
            }
        } else {
            dst.copy_from_slice(src);
        }
    }
}

/// The part of an ACCH that no roll changes: its colour pairs summed over
/// orientations and over both orders, `colours` x `colours`, into `out`.
pub fn roll_invariant(h: &[f32], colours: usize, out: &mut [f32]) {
    let block = colours * colours;
    assert_eq!(out.len(), block, "output length");
    assert_eq!(h.len() % block, 0, "histogram length");
    out.fill(0.0);
    for bin in h.chunks_exact(block) {
        for a in 0..colours {
            for b in 0..colours {
                out[a * colours + b] += bin[a * colours + b] + bin[b * colours + a];
            }
        }
    }
}

/// Histogram intersection s(h1, h2) = sum of min(h1, h2) (paper eq. 1).
pub fn intersection(h1: &[f32], h2: &[f32]) -> f32 {
    assert_eq!(h1.len(), h2.len(), "histogram lengths differ");
    // Eight independent sums let the compiler vectorise the loop.
    let mut acc = [0f32; 8];
    let (c1, c2) = (h1.chunks_exact(8), h2.chunks_exact(8));
    let (r1, r2) = (c1.remainder(), c2.remainder());
    for (a, b) in c1.zip(c2) {
        for i in 0..8 {
            acc[i] += if a[i] < b[i] { a[i] } else { b[i] };
        }
    }
    let tail: f32 = r1.iter().zip(r2).map(|(a, b)| a.min(*b)).sum();
    acc.iter().sum::<f32>() + tail
}

/// Intersection of the query `h` with the view `t` taken `k` times,
/// sum of min(h, k t): for normalised histograms of a query of `q` pairs
/// and a view of `n`, `k = n / q` compares their pair counts, so the share
/// of the query's pairs the whole view holds (a visible part of the right
/// view scores 1, the view is not diluted by the pairs an occluder hid).
pub fn scaled_intersection(h: &[f32], t: &[f32], k: f32) -> f32 {
    assert_eq!(h.len(), t.len(), "histogram lengths differ");
    let mut acc = [0f32; 8];
    let (c1, c2) = (h.chunks_exact(8), t.chunks_exact(8));
    let (r1, r2) = (c1.remainder(), c2.remainder());
    for (a, b) in c1.zip(c2) {
        for i in 0..8 {
            let kb = k * b[i];
            acc[i] += if a[i] < kb { a[i] } else { kb };
        }
    }
    let tail: f32 = r1.iter().zip(r2).map(|(a, b)| a.min(k * b)).sum();
    acc.iter().sum::<f32>() + tail
}

/// Match value m(h1, h2) = s(h1, h2) / #h1 (paper eq. 2): 1 for a perfect
/// match, 0 for nothing in common or an empty h1.
pub fn match_value(h1: &[f32], h2: &[f32]) -> f32 {
    let total: f32 = h1.iter().sum();
    if total <= 0.0 {
        0.0
    } else {
        intersection(h1, h2) / total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(
        kind: HistogramKind,
        colours: u16,
        bins: u16,
        r_min: f32,
        r_max: f32,
    ) -> HistogramParams {
        HistogramParams {
            kind,
            colours,
            bins,
            r_min,
            r_max,
            stride: 1,
            sampling: OffsetSampling::Dense,
        }
    }

    fn counts(
        e: &mut HistogramExtractor,
        img: &IndexImage,
        mask: Option<&[u8]>,
    ) -> (Vec<f32>, u64) {
        let mut h = vec![0.0; e.params().len()];
        let n = e.extract(img, mask, Rect::full(img.width, img.height), 1.0, &mut h);
        (h.iter().map(|v| (v * n as f32).round()).collect(), n)
    }

    /// A 2x1 image "0 1" with r in (0, 1]: one offset (1, 0) right at 0 deg
    /// and three upward/diagonal offsets that leave the image. Exactly one
    /// pair (a=0 at the reference, b=1) at orientation bin 0.
    #[test]
    fn two_pixel_image_counts_by_hand() {
        let img = IndexImage::new(2, 1, vec![0, 1]);
        let mut e = HistogramExtractor::new(params(HistogramKind::Acch, 2, 2, 0.0, 1.0)).unwrap();
        let (h, n) = counts(&mut e, &img, None);
        assert_eq!(n, 1);
        // Layout: d * C * C + a * C + b.
        assert_eq!(h, vec![0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    }

    /// A 2x2 image with a red top row and a blue bottom row:
    /// ```text
    /// 0 0
    /// 1 1
    /// ```
    /// Offsets with 0 < r <= 1.5 in the half plane: (1,0) at 0 deg,
    /// (1,-1) at 45, (0,-1) at 90, (-1,-1) at 135. With 2 orientation bins
    /// (below/above 90 deg, like the paper's figure 1):
    /// - (1,0): reference (0,0)->(1,0) gives 0-0; (0,1)->(1,1) gives 1-1: bin 0.
    /// - (1,-1) from (0,1) reaches (1,0): 1-0, bin 0.
    /// - (0,-1) from (0,1) and (1,1): 1-0 twice, bin 1 (90 deg).
    /// - (-1,-1) from (1,1) reaches (0,0): 1-0, bin 1.
    #[test]
    fn two_colour_block_counts_by_hand() {
        let img = IndexImage::new(2, 2, vec![0, 0, 1, 1]);
        let mut e = HistogramExtractor::new(params(HistogramKind::Acch, 2, 2, 0.0, 1.5)).unwrap();
        let (h, n) = counts(&mut e, &img, None);
        assert_eq!(n, 6);
        let bin = |d: usize, a: usize, b: usize| h[d * 4 + a * 2 + b];
        assert_eq!(bin(0, 0, 0), 1.0);
        assert_eq!(bin(0, 1, 1), 1.0);
        assert_eq!(bin(0, 1, 0), 1.0);
        assert_eq!(bin(1, 1, 0), 3.0);
        assert_eq!(h.iter().sum::<f32>(), 6.0);

        // The CCH is the same loop without the orientation.
        let mut e = HistogramExtractor::new(params(HistogramKind::Cch, 2, 2, 0.0, 1.5)).unwrap();
        let (h, _) = counts(&mut e, &img, None);
        assert_eq!(h, vec![1.0, 0.0, 4.0, 1.0]);

        // The DCCH splits by length: 1 (axis offsets) vs sqrt 2 (diagonals),
        // with the annulus 0.9 < r <= 1.5 cut in two at 1.2.
        let mut e = HistogramExtractor::new(params(HistogramKind::Dcch, 2, 2, 0.9, 1.5)).unwrap();
        let (h, _) = counts(&mut e, &img, None);
        assert_eq!(&h[..4], &[1.0, 0.0, 2.0, 1.0]);
        assert_eq!(&h[4..], &[0.0, 0.0, 2.0, 0.0]);
    }

    #[test]
    fn mask_and_annulus_exclude_pixels() {
        let img = IndexImage::new(3, 1, vec![0, 1, 0]);
        // Masking the middle pixel leaves the pair (0, 0) at distance 2.
        let mask = [1, 0, 1];
        let mut e = HistogramExtractor::new(params(HistogramKind::Cch, 2, 1, 0.0, 2.0)).unwrap();
        let (h, n) = counts(&mut e, &img, Some(&mask));
        assert_eq!((h, n), (vec![1.0, 0.0, 0.0, 0.0], 1));
        // An annulus 1 < r <= 2 drops the neighbours, keeps the ends.
        let mut e = HistogramExtractor::new(params(HistogramKind::Cch, 2, 1, 1.0, 2.0)).unwrap();
        let (h, n) = counts(&mut e, &img, None);
        assert_eq!((h, n), (vec![1.0, 0.0, 0.0, 0.0], 1));
    }

    /// Rotating an image by 90 degrees counter-clockwise turns every offset by
    /// 90 degrees: bin d moves to d + D/2, and a pair that leaves the half
    /// plane comes back reversed (b, a) at d - D/2.
    #[test]
    fn rotating_a_view_shifts_the_angle_bins() {
        let (w, c) = (24usize, 3usize);
        let mut state = 12345u32;
        let data: Vec<u8> = (0..w * w)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                ((state >> 16) % c as u32) as u8
            })
            .collect();
        let img = IndexImage::new(w as u32, w as u32, data.clone());
        // Counter-clockwise: new(x, y) = old(w-1-y, x).
        let rot: Vec<u8> = (0..w * w)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                data[x * w + (w - 1 - y)]
            })
            .collect();
        let img_rot = IndexImage::new(w as u32, w as u32, rot);
        // Exact check with bins that do not split the lattice axes: D = 2
        // puts 0 and 90 deg at the start of their bins in both images.
        let p = params(HistogramKind::Acch, c as u16, 2, 2.0, 5.0);
        let mut e = HistogramExtractor::new(p).unwrap();
        let (h, _) = counts(&mut e, &img, None);
        let (hr, _) = counts(&mut e, &img_rot, None);
        let at = |h: &[f32], d: usize, a: usize, b: usize| h[(d * c + a) * c + b];
        assert!(h.iter().sum::<f32>() > 1000.0);
        for a in 0..c {
            for b in 0..c {
                assert_eq!(at(&hr, 1, a, b), at(&h, 0, a, b), "bin 1 ({a},{b})");
                assert_eq!(at(&hr, 0, a, b), at(&h, 1, b, a), "bin 0 ({a},{b})");
            }
        }
    }

    /// The same check as above through [`roll_acch`]: a 90° turn is a roll
    /// by D/2 bins; a roll by D is a full reversal, by 2D the identity; the
    /// roll-invariant part is the same for the turned image.
    #[test]
    fn a_quarter_turn_is_a_roll_by_half_the_bins() {
        let (w, c) = (24usize, 3usize);
        let mut state = 987u32;
        let data: Vec<u8> = (0..w * w)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                ((state >> 16) % c as u32) as u8
            })
            .collect();
        let rot: Vec<u8> = (0..w * w)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                data[x * w + (w - 1 - y)]
            })
            .collect();
        let p = params(HistogramKind::Acch, c as u16, 2, 2.0, 5.0);
        let mut e = HistogramExtractor::new(p).unwrap();
        let (h, _) = counts(&mut e, &IndexImage::new(w as u32, w as u32, data), None);
        let (hr, _) = counts(&mut e, &IndexImage::new(w as u32, w as u32, rot), None);
        let mut rolled = vec![0.0; h.len()];
        roll_acch(&h, c, 2, 1, &mut rolled);
        assert_eq!(rolled, hr);
        // Turning back.
        roll_acch(&hr, c, 2, -1, &mut rolled);
        assert_eq!(rolled, h);
        // 180°: every pair reversed; 360°: nothing changes.
        roll_acch(&h, c, 2, 2, &mut rolled);
        let at = |h: &[f32], d: usize, a: usize, b: usize| h[(d * c + a) * c + b];
        for d in 0..2 {
            for a in 0..c {
                for b in 0..c {
                    assert_eq!(at(&rolled, d, a, b), at(&h, d, b, a));
                }
            }
        }
        roll_acch(&h, c, 2, 4, &mut rolled);
        assert_eq!(rolled, h);
        let (mut inv, mut inv_r) = (vec![0.0; c * c], vec![0.0; c * c]);
        roll_invariant(&h, c, &mut inv);
        roll_invariant(&hr, c, &mut inv_r);
        assert_eq!(inv, inv_r);
    }

    #[test]
    fn intersection_properties() {
        let img = IndexImage::new(8, 8, (0..64).map(|i| (i * 7 % 5) as u8).collect());
        let mut e = HistogramExtractor::new(HistogramParams {
            colours: 5,
            r_min: 1.0,
            r_max: 3.0,
            stride: 1,
            ..HistogramParams::default()
        })
        .unwrap();
        let mut h1 = vec![0.0; e.params().len()];
        let mut h2 = h1.clone();
        e.extract(&img, None, Rect::full(8, 8), 1.0, &mut h1);
        e.extract(
            &img,
            None,
            Rect {
                x: 0,
                y: 0,
                width: 5,
                height: 8,
            },
            1.0,
            &mut h2,
        );
        assert!(
            (intersection(&h1, &h1) - 1.0).abs() < 1e-5,
            "self-match is 1"
        );
        assert!((match_value(&h1, &h1) - 1.0).abs() < 1e-5);
        let m = match_value(&h1, &h2);
        assert!(m > 0.0 && m <= 1.0 + 1e-6, "bounded by 1: {m}");
        assert!(
            (intersection(&h1, &h2) - intersection(&h2, &h1)).abs() < 1e-6,
            "symmetric"
        );
        assert_eq!(match_value(&vec![0.0; h1.len()], &h1), 0.0);
    }

    #[test]
    fn validation_rejects_bad_parameters() {
        let ok = HistogramParams::default();
        assert!(ok.validate().is_ok());
        for bad in [
            HistogramParams { colours: 0, ..ok },
            HistogramParams { bins: 0, ..ok },
            HistogramParams {
                r_min: f32::NAN,
                ..ok
            },
            HistogramParams { r_min: -1.0, ..ok },
            HistogramParams { r_max: 5.0, ..ok },
            HistogramParams { stride: 0, ..ok },
        ] {
            assert!(HistogramExtractor::new(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn scale_stretches_the_annulus() {
        let p = HistogramParams::default();
        let near = p.offsets(1.0);
        let far = p.offsets(2.0);
        let max_r = |o: &[(i32, i32, u16)]| {
            o.iter()
                .map(|&(x, y, _)| ((x * x + y * y) as f32).sqrt())
                .fold(0.0, f32::max)
        };
        assert!(max_r(&near) <= 20.5 && max_r(&far) > 30.0);
        // Polar sampling keeps the cost constant across scales.
        assert!(far.len() >= near.len());
        assert!(far.len() <= 4 * 48);
    }
}
