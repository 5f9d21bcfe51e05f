//! How clean a frame is: its sensor noise, its JPEG blocking and how much
//! fine detail blur has left, measured on the frame alone.
//!
//! Why: a database trained on sharp views holds on a clean frame and loses
//! on a noisy, compressed or blurred one, while smoothed views hold there
//! and cost a little on clean frames (docs/accuracy.md, "A noisy,
//! compressed or blurred camera"). A measure of the frame, whatever the
//! object's match, can say which of the two a frame needs: the robust
//! protocol records it for every image (`--errors`), and choosing the
//! database by it is measured there (docs/accuracy.md, "Which database a
//! frame needs: its measured quality"), and recognition makes that choice
//! for a run with `smoothing = "auto"` ([`FrameQuality::needs_smoothing`]).

/// Side of the square blocks whose noise is estimated one by one, pixels.
const BLOCK: usize = 16;

/// Share of the blocks, the flattest first, whose estimates make the
/// frame's noise: a frame's texture raises a block's estimate, never
/// lowers it, so the flattest blocks see the noise alone.
const FLAT_SHARE: f32 = 0.1;

/// Side of a JPEG coding block, pixels.
const JPEG_BLOCK: usize = 8;

/// Fewest steps standing out that measure blockiness: with fewer (a flat
/// table, nothing in view) a handful of edges that happen to lie on the
/// grid would read as blocking.
const MIN_BLOCK_STEPS: u64 = 2000;

/// Pixels either side of an edge over which its step is taken.
const EDGE_REACH: usize = 3;

/// Smallest step, grey levels, of an edge whose sharpness is measured:
/// weaker ones are texture the noise could make.
const MIN_EDGE_STEP: f32 = 24.0;

/// A frame's measured quality.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameQuality {
    /// Additive noise, standard deviation in grey levels per channel
    /// (Immerkær 1996: the mean absolute response of a mask blind to
    /// planes, in the flattest tenth of 16x16 blocks, averaged over the
    /// channels).
    pub noise_sigma: f32,
    /// How often a grey step larger than its neighbours along a row
    /// (column) falls on the boundary of the 8x8 JPEG grid, over the 1 in 8
    /// of chance: about 1 for an uncompressed frame, above for a blocky
    /// one. Each such step counts once whatever its size, and a frame with
    /// fewer than 2000 of them measures 1, so a few strong edges on the
    /// grid of an otherwise flat frame do not make it blocky.
    pub blockiness: f32,
    /// At the frame's strong edges (a step of at least 24 grey levels
    /// within 3 pixels), the steepest slope over the step, per pixel: about
    /// 0.5 for an edge one pixel wide, 0.34 blurred by a Gaussian of
    /// sigma 1 px, 0.2 by 2 px. NaN: no strong edge.
    pub sharpness: f32,
}

/// Noise, grey levels, above which a frame needs the smoothed databases.
/// Chosen on the development seed of the robust protocol (noise 2 measures
/// 2.2, clean frames at most 1.6 on every table frame).
pub const NOISY_SIGMA: f32 = 2.5;

/// Blockiness above which a frame needs the smoothed databases (JPEG 90
/// measures 1.5 in the median, clean frames at most 1.45 on every table
/// frame). Chosen with [`NOISY_SIGMA`].
pub const BLOCKY: f32 = 1.5;

impl FrameQuality {
    /// Whether the frame is noisy or blocky enough that the databases that
    /// smooth views and frames match it better than the sharp ones
    /// (docs/accuracy.md, "Which database a frame needs"). Sharpness has no
    /// say: a frame with nothing sharp in view measures as a blurred one.
    pub fn needs_smoothing(&self) -> bool {
        self.noise_sigma > NOISY_SIGMA || self.blockiness > BLOCKY
    }
}

/// Sharpness over the object's window below which the object is blurred
/// and the frame needs the smoothed databases (blur 1 px measures about
/// 0.3 there, 2 px 0.22, the clean frames at least 0.34). Chosen on the
/// development seed of the robust protocol (docs/accuracy.md, "A blurred
/// object: its sharpness over its window").
pub const BLURRED: f32 = 0.30;

/// Whether an object whose window measured `sharpness`
/// ([`QualityMeter::sharpness_within`]) is blurred enough that the
/// databases that smooth views and frames match it better than the sharp
/// ones. NaN (no strong edge in the window) is not: nothing says so.
pub fn is_blurred(sharpness: f32) -> bool {
    sharpness < BLURRED
}

/// Measures frames, reusing its buffers (no allocation per frame once warm).
#[derive(Debug, Default)]
pub struct QualityMeter {
    /// Each 16x16 block's mean mask response.
    blocks: Vec<f32>,
    /// Each block's summed mask response.
    sums: Vec<u32>,
    /// One row's mask response per channel byte.
    response: Vec<u32>,
    /// The last frame measured, grey (empty when it was too small to
    /// measure).
    grey: Vec<f32>,
    /// The last frame's width.
    width: usize,
    /// Buffers of the blockiness.
    steps: StepScratch,
}

impl QualityMeter {
    /// A meter.
    pub fn new() -> Self {
        Self::default()
    }

    /// The quality of the packed RGB frame `rgb`, `width` x `height`.
    /// Frames smaller than 3x3 measure as default (zero).
    pub fn measure(&mut self, rgb: &[u8], width: u32, height: u32) -> FrameQuality {
        let mut q = self.noise_and_blocking(rgb, width, height);
        if width >= 3 && height >= 3 {
            q.sharpness = self.sharpness_within(0, 0, width, height);
        }
        q
    }

    /// [`FrameQuality::sharpness`] over the window `width` x `height` from
    /// column `x`, row `y` of the frame last measured (cut to it): the
    /// object's own edges, whatever the rest of the frame shows (a frame
    /// with nothing sharp in view measures as a blurred one). NaN: no
    /// strong edge, or no frame measured.
    pub fn sharpness_within(&self, x: u32, y: u32, width: u32, height: u32) -> f32 {
        let (fw, fh) = (self.width, self.grey.len() / self.width.max(1));
        let (x0, y0) = (x as usize, y as usize);
        if x0 >= fw || y0 >= fh {
            return f32::NAN;
        }
        let w = (width as usize).min(fw - x0);
        let h = (height as usize).min(fh - y0);
        sharpness(&self.grey[y0 * fw + x0..], fw, w, h)
    }

    /// [`measure`](Self::measure) without the sharpness (NaN), which
    /// [`FrameQuality::needs_smoothing`] does not read.
    pub fn noise_and_blocking(&mut self, rgb: &[u8], width: u32, height: u32) -> FrameQuality {
        let (w, h) = (width as usize, height as usize);
        assert_eq!(
            rgb.len(),
            3 * w * h,
            "RGB buffer does not match {width}x{height}"
        );
        self.grey.clear();
        self.width = w;
        if w < 3 || h < 3 {
            return FrameQuality::default();
        }
        self.grey.extend(
            rgb.chunks_exact(3)
                .map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0),
        );
        let grey = &self.grey;
        let (bw, bh) = ((w - 2).div_ceil(BLOCK), (h - 2).div_ceil(BLOCK));
        // Pixel x in 1..w-1 of row y belongs to block ((y-1)/16, (x-1)/16);
        // each block's mask responses are summed in integers, exactly.
        let mut sums = std::mem::take(&mut self.sums);
        sums.clear();
        sums.resize(bw * bh, 0);
        self.response.resize(3 * w, 0);
        for y in 1..h - 1 {
            let row = |k: usize| &rgb[3 * k * w..3 * (k + 1) * w];
            let (above, here, below) = (row(y - 1), row(y), row(y + 1));
            // [1 -2 1; -2 4 -2; 1 -2 1] per channel byte: zero on any
            // plane. One pass over the row's bytes, the neighbours 3 bytes
            // (a pixel) apart, so it vectorises.
            let n = 3 * w - 6;
            let response = &mut self.response[..n];
            let (a0, a1, a2) = (at(above, 0, n), at(above, 3, n), at(above, 6, n));
            let (h0, h1, h2) = (at(here, 0, n), at(here, 3, n), at(here, 6, n));
            let (b0, b1, b2) = (at(below, 0, n), at(below, 3, n), at(below, 6, n));
            for i in 0..n {
                let v = |r: &[u8]| i32::from(r[i]);
                let corners = v(a0) + v(a2) + v(b0) + v(b2);
                let sides = v(h0) + v(h2) + v(a1) + v(b1);
                response[i] = (corners - 2 * sides + 4 * v(h1)).unsigned_abs();
            }
            let block_row = &mut sums[(y - 1) / BLOCK * bw..][..bw];
            for (sum, chunk) in block_row.iter_mut().zip(response.chunks(3 * BLOCK)) {
                *sum += chunk.iter().sum::<u32>();
            }
        }
        self.blocks.clear();
        self.blocks.extend(sums.iter().enumerate().map(|(b, &sum)| {
            let (bx, by) = (b % bw, b / bw);
            let pixels = |k: usize, len: usize| (len - k * BLOCK).min(BLOCK);
            let n = pixels(bx, w - 2) * pixels(by, h - 2);
            sum as f32 / 3.0 / n.max(1) as f32
        }));
        self.sums = sums;
        let means = &mut self.blocks;
        let flat = ((means.len() as f32 * FLAT_SHARE).ceil() as usize).clamp(1, means.len());
        means.select_nth_unstable_by(flat - 1, f32::total_cmp);
        let flat_mean = means[..flat].iter().sum::<f32>() / flat as f32;
        FrameQuality {
            noise_sigma: flat_mean * (std::f32::consts::FRAC_PI_2).sqrt() / 6.0,
            blockiness: blockiness(grey, w, h, &mut self.steps),
            sharpness: f32::NAN,
        }
    }
}

/// `n` bytes of `r` from `i`.
fn at(r: &[u8], i: usize, n: usize) -> &[u8] {
    &r[i..i + n]
}

/// The rows, then the columns of a `w` x `h` window of a buffer `stride`
/// wide, as (pixels along the line, lines, stride between a line's pixels,
/// stride between lines).
fn rows_then_columns(w: usize, h: usize, stride: usize) -> [(usize, usize, usize, usize); 2] {
    [(w, h, 1, stride), (h, w, stride, 1)]
}

/// Buffers of [`blockiness`], reused between frames.
#[derive(Debug, Default)]
struct StepScratch {
    /// Three rows of steps. Along the rows, the first holds the row's
    /// steps (step i into pixel i); down the columns, the steps into the
    /// row above, this one and the one below.
    rows: [Vec<f32>; 3],
    /// One row's steps standing out (0/1), by pixel.
    flags: Vec<u8>,
}

/// Whether step `s` stands out between its neighbours `before` and
/// `after`: branch-free, as the frames' noise makes it a coin's toss.
#[inline]
fn stands_out(before: f32, s: f32, after: f32) -> u8 {
    ((s > 1.0) & (s > before) & (s > after)) as u8
}

/// [`FrameQuality::blockiness`] of `grey`, `w` x `h` (at least 3 x 3),
/// over its rows and columns (1, chance, when too few steps stand out to
/// tell). Each step is taken once, and the counts are made without
/// branches over whole rows, so they vectorise.
fn blockiness(grey: &[f32], w: usize, h: usize, scratch: &mut StepScratch) -> f32 {
    // Steps larger than both neighbours, counted by their place on the grid
    // (a step into pixel i is on the boundary when i is a multiple of 8):
    // every place alike, so content does not favour the boundary.
    let mut by_place = [0u64; JPEG_BLOCK];
    let StepScratch { rows, flags } = scratch;
    // Along each row: step i is into pixel i, counted for i in 2..w-1.
    let step = &mut rows[0];
    step.resize(w, 0.0);
    flags.clear();
    flags.resize(w.next_multiple_of(JPEG_BLOCK), 0);
    for row in grey.chunks_exact(w) {
        for ((s, &here), &before) in step[1..].iter_mut().zip(&row[1..]).zip(row) {
            *s = (here - before).abs();
        }
        for (((f, &before), &s), &after) in flags[2..w - 1]
            .iter_mut()
            .zip(&step[1..])
            .zip(&step[2..])
            .zip(&step[3..])
        {
            *f = stands_out(before, s, after);
        }
        let mut row_places = [0u32; JPEG_BLOCK];
        for chunk in flags.chunks_exact(JPEG_BLOCK) {
            for (n, &f) in row_places.iter_mut().zip(chunk) {
                *n += u32::from(f);
            }
        }
        for (total, n) in by_place.iter_mut().zip(row_places) {
            *total += u64::from(n);
        }
    }
    // Down each column, the columns side by side: the steps into rows i-1,
    // i and i+1, each row's taken once and passed on.
    let down = |into: &mut Vec<f32>, k: usize| {
        let (above, here) = (&grey[(k - 1) * w..k * w], &grey[k * w..(k + 1) * w]);
        into.clear();
        into.extend(here.iter().zip(above).map(|(&h, &a)| (h - a).abs()));
    };
    let [into_above, into_here, into_below] = rows;
    down(into_above, 1);
    down(into_here, 2);
    for i in 2..h - 1 {
        down(into_below, i + 1);
        let count: u32 = into_above
            .iter()
            .zip(into_here.iter())
            .zip(into_below.iter())
            .map(|((&before, &s), &after)| u32::from(stands_out(before, s, after)))
            .sum();
        by_place[i % JPEG_BLOCK] += u64::from(count);
        std::mem::swap(into_above, into_here);
        std::mem::swap(into_here, into_below);
    }
    let total: u64 = by_place.iter().sum();
    if total < MIN_BLOCK_STEPS {
        1.0
    } else {
        (by_place[0] as f64 * JPEG_BLOCK as f64 / total as f64) as f32
    }
}

/// The mean, over the strong edges of the `w` x `h` window at the start of
/// `grey` (rows `row_stride` apart) along x and along y, of the steepest
/// central slope over the edge's step (see [`FrameQuality::sharpness`]).
fn sharpness(grey: &[f32], row_stride: usize, w: usize, h: usize) -> f32 {
    let (mut sum, mut n) = (0f64, 0u64);
    for (len, lines, stride, line_step) in rows_then_columns(w, h, row_stride) {
        if len < 2 * EDGE_REACH + 3 {
            continue;
        }
        for line in 0..lines {
            let at = |i: usize| grey[line * line_step + i * stride];
            let slope = |i: usize| (at(i + 1) - at(i - 1)).abs() / 2.0;
            for i in EDGE_REACH + 1..len - EDGE_REACH - 1 {
                let s = slope(i);
                // The steepest point of the edge: a maximum of the slope.
                if s < slope(i - 1) || s <= slope(i + 1) {
                    continue;
                }
                let (lo, hi) = (i - EDGE_REACH..=i + EDGE_REACH)
                    .map(at)
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
                        (lo.min(v), hi.max(v))
                    });
                if hi - lo >= MIN_EDGE_STEP {
                    sum += (s / (hi - lo)) as f64;
                    n += 1;
                }
            }
        }
    }
    if n == 0 {
        f32::NAN
    } else {
        (sum / n as f64) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A 160x120 frame: a grey ramp with a few step edges.
    fn scene() -> (Vec<u8>, u32, u32) {
        let (w, h) = (160u32, 120u32);
        let mut rgb = Vec::with_capacity(3 * (w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let base = 60.0 + 0.5 * x as f32 + 0.3 * y as f32;
                let step = if (x / 40 + y / 30) % 2 == 0 {
                    40.0
                } else {
                    0.0
                };
                let v = (base + step) as u8;
                rgb.extend_from_slice(&[v, v, v]);
            }
        }
        (rgb, w, h)
    }

    fn noisy(rgb: &[u8], sigma: f32, seed: u64) -> Vec<u8> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rgb.chunks_exact(3)
            .flat_map(|p| {
                // The same noise in every channel: a grey frame stays grey.
                let u: f32 = (0..12).map(|_| rng.random::<f32>()).sum::<f32>() - 6.0;
                let v = (p[0] as f32 + sigma * u).round().clamp(0.0, 255.0) as u8;
                [v, v, v]
            })
            .collect()
    }

    #[test]
    fn the_noise_estimate_follows_added_noise_not_edges() {
        let (rgb, w, h) = scene();
        let mut meter = QualityMeter::new();
        let clean = meter.measure(&rgb, w, h);
        assert!(clean.noise_sigma < 0.5, "{clean:?}");
        for sigma in [2.0f32, 4.0, 6.0] {
            let q = meter.measure(&noisy(&rgb, sigma, 1), w, h);
            assert!(
                (q.noise_sigma - sigma).abs() < 0.25 * sigma,
                "sigma {sigma}: {q:?}"
            );
        }
    }

    #[test]
    fn steps_on_the_jpeg_grid_raise_blockiness() {
        let (w, h) = (256usize, 256usize);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let texture: Vec<f32> = (0..w * h).map(|_| rng.random_range(0.0..100.0)).collect();
        // Each 8x8 block's mean with a little of its detail left, as a
        // coarse JPEG leaves it.
        let blocked: Vec<f32> = (0..w * h)
            .map(|i| {
                let (bx, by) = (i % w / 8 * 8, i / w / 8 * 8);
                let mean = (0..64)
                    .map(|k| texture[(by + k / 8) * w + bx + k % 8])
                    .sum::<f32>()
                    / 64.0;
                mean + 0.03 * (texture[i] - mean)
            })
            .collect();
        let rgb = |g: &[f32]| -> Vec<u8> { g.iter().flat_map(|&v| [v as u8 + 50; 3]).collect() };
        let mut meter = QualityMeter::new();
        let clean = meter.measure(&rgb(&texture), w as u32, h as u32).blockiness;
        let blocky = meter.measure(&rgb(&blocked), w as u32, h as u32).blockiness;
        assert!((0.9..1.1).contains(&clean), "{clean}");
        assert!(blocky > 3.0, "{blocky}");
        // A flat frame has no step: chance, not blocky.
        assert_eq!(meter.measure(&[9; 3 * 64 * 64], 64, 64).blockiness, 1.0);
    }

    /// Vertical bars 12 px wide of two greys, blurred by a Gaussian of
    /// `sigma` px (none at 0).
    fn bars(sigma: f32) -> (Vec<u8>, u32, u32) {
        let (w, h) = (96u32, 32u32);
        let value = |x: f32| {
            if (x / 12.0).rem_euclid(2.0) < 1.0 {
                60.0
            } else {
                180.0
            }
        };
        let row: Vec<f32> = (0..w)
            .map(|x| {
                if sigma == 0.0 {
                    return value(x as f32);
                }
                let (mut s, mut k) = (0.0, 0.0);
                for d in -12i32..=12 {
                    let g = (-(d * d) as f32 / (2.0 * sigma * sigma)).exp();
                    s += g * value((x as i32 + d) as f32);
                    k += g;
                }
                s / k
            })
            .collect();
        let rgb = (0..h)
            .flat_map(|_| {
                row.iter()
                    .flat_map(|&v| [v.round() as u8; 3])
                    .collect::<Vec<_>>()
            })
            .collect();
        (rgb, w, h)
    }

    #[test]
    fn blur_lowers_the_sharpness_as_the_gaussian_predicts() {
        let mut meter = QualityMeter::new();
        let at = |meter: &mut QualityMeter, sigma| {
            let (rgb, w, h) = bars(sigma);
            meter.measure(&rgb, w, h).sharpness
        };
        let sharp = at(&mut meter, 0.0);
        let one = at(&mut meter, 1.0);
        let two = at(&mut meter, 2.0);
        assert!((sharp - 0.5).abs() < 0.02, "{sharp}");
        assert!((one - 0.34).abs() < 0.03, "{one}");
        assert!((0.17..0.26).contains(&two), "{two}");
        // A flat frame has no edge to measure.
        assert!(
            meter
                .measure(&[128; 3 * 64 * 64], 64, 64)
                .sharpness
                .is_nan()
        );
    }

    #[test]
    fn a_window_measures_its_own_edges() {
        // Sharp bars beside bars blurred by 2 px, each 96x32, one frame.
        let ((sharp, w, h), (blurred, _, _)) = (bars(0.0), bars(2.0));
        let (w2, h2) = (2 * w as usize, h as usize);
        let frame: Vec<u8> = (0..h2)
            .flat_map(|y| {
                let row = |rgb: &[u8]| rgb[3 * y * w as usize..][..3 * w as usize].to_vec();
                [row(&sharp), row(&blurred)].concat()
            })
            .collect();
        let mut meter = QualityMeter::new();
        let whole = meter.measure(&frame, w2 as u32, h2 as u32).sharpness;
        let (left, right) = (
            meter.sharpness_within(0, 0, w, h),
            meter.sharpness_within(w, 0, w, h),
        );
        // Each half measures as the frame of its bars alone; the whole
        // frame, between the two, says nothing of either.
        let alone = |rgb: &[u8]| QualityMeter::new().measure(rgb, w, h).sharpness;
        assert!((left - alone(&sharp)).abs() < 0.02, "{left}");
        assert!((right - alone(&blurred)).abs() < 0.02, "{right}");
        assert!(left > whole && whole > right, "{left} {whole} {right}");
        assert!(!is_blurred(left) && is_blurred(right), "{left} {right}");
        // A window cut to the frame, one outside it, no edge at all.
        assert_eq!(meter.sharpness_within(w, 0, 10 * w, 10 * h), right);
        assert!(meter.sharpness_within(3 * w, 0, w, h).is_nan());
        assert!(!is_blurred(f32::NAN));
        assert!(QualityMeter::new().sharpness_within(0, 0, 8, 8).is_nan());
    }

    #[test]
    fn a_tiny_frame_measures_as_zero() {
        let mut meter = QualityMeter::new();
        let q = meter.measure(&[0; 12], 2, 2);
        assert_eq!((q.noise_sigma, q.blockiness), (0.0, 0.0));
    }

    /// The noise and blockiness by their definitions, one pixel (one step)
    /// at a time in floats, columns walked down the frame.
    fn by_definition(rgb: &[u8], w: usize, h: usize) -> (f32, f32) {
        let (bw, bh) = ((w - 2).div_ceil(BLOCK), (h - 2).div_ceil(BLOCK));
        let (mut sums, mut counts) = (vec![0f64; bw * bh], vec![0f64; bw * bh]);
        let v = |x: usize, y: usize, c: usize| f64::from(rgb[3 * (y * w + x) + c]);
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let mut m = 0.0;
                for c in 0..3 {
                    let corners = v(x - 1, y - 1, c)
                        + v(x + 1, y - 1, c)
                        + v(x - 1, y + 1, c)
                        + v(x + 1, y + 1, c);
                    let sides = v(x - 1, y, c) + v(x + 1, y, c) + v(x, y - 1, c) + v(x, y + 1, c);
                    m += (corners - 2.0 * sides + 4.0 * v(x, y, c)).abs();
                }
                let b = (y - 1) / BLOCK * bw + (x - 1) / BLOCK;
                sums[b] += m / 3.0;
                counts[b] += 1.0;
            }
        }
        let mut means: Vec<f64> = sums.iter().zip(&counts).map(|(s, n)| s / n).collect();
        means.sort_by(f64::total_cmp);
        let flat = ((means.len() as f32 * FLAT_SHARE).ceil() as usize).clamp(1, means.len());
        let noise = means[..flat].iter().sum::<f64>() / flat as f64
            * std::f64::consts::FRAC_PI_2.sqrt()
            / 6.0;
        let grey: Vec<f32> = rgb
            .chunks_exact(3)
            .map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0)
            .collect();
        let mut by_place = [0u64; JPEG_BLOCK];
        for (len, lines, stride, line_step) in rows_then_columns(w, h, w) {
            for line in 0..lines {
                let at = |i: usize| grey[line * line_step + i * stride];
                let step = |i: usize| (at(i) - at(i - 1)).abs();
                for i in 2..len - 1 {
                    let s = step(i);
                    if s > 1.0 && s > step(i - 1) && s > step(i + 1) {
                        by_place[i % JPEG_BLOCK] += 1;
                    }
                }
            }
        }
        let total: u64 = by_place.iter().sum();
        let blockiness = if total < MIN_BLOCK_STEPS {
            1.0
        } else {
            by_place[0] as f32 * JPEG_BLOCK as f32 / total as f32
        };
        (noise as f32, blockiness)
    }

    #[test]
    fn the_fast_measure_is_the_definition() {
        let mut meter = QualityMeter::new();
        let (rgb, w, _) = scene();
        // Sizes that are not whole blocks, noise and JPEG-like blocks.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for (sigma, (w2, h2)) in [(0.0, (160, 120)), (3.0, (150, 107)), (6.0, (37, 29))] {
            let crop: Vec<u8> = (0..h2)
                .flat_map(|y| rgb[3 * y * w as usize..][..3 * w2].to_vec())
                .collect();
            let mut frame = noisy(&crop, sigma, rng.random());
            if sigma == 3.0 {
                for (i, p) in frame.iter_mut().enumerate() {
                    let x = (i / 3) % w2;
                    *p = p.saturating_add(if x % 8 == 0 { 9 } else { 0 });
                }
            }
            let q = meter.noise_and_blocking(&frame, w2 as u32, h2 as u32);
            let (noise, blockiness) = by_definition(&frame, w2, h2);
            assert!((q.noise_sigma - noise).abs() < 1e-4, "{q:?} {noise}");
            assert_eq!(q.blockiness, blockiness, "{w2}x{h2}");
            assert!(q.sharpness.is_nan());
            if sigma == 3.0 {
                // Enough steps to tell, most on the grid's columns.
                assert!(q.blockiness > 1.5, "{q:?}");
            }
        }
        // Narrow frames, tall enough that their noise makes the 2000 steps
        // that count (each grid place tested at widths below, at and
        // above a block), then a wider one after them: buffers of an
        // earlier frame's size do not leak into the next.
        for (w2, h2) in [(3, 3000), (5, 1500), (8, 1000), (9, 900), (64, 160)] {
            let frame = noisy(&vec![128; 3 * w2 * h2], 6.0, rng.random());
            let q = meter.noise_and_blocking(&frame, w2 as u32, h2 as u32);
            let (noise, blockiness) = by_definition(&frame, w2, h2);
            assert!(
                (q.noise_sigma - noise).abs() < 1e-3,
                "{w2}x{h2}: {q:?} {noise}"
            );
            assert_eq!(q.blockiness, blockiness, "{w2}x{h2}");
            assert_ne!(
                blockiness, 1.0,
                "{w2}x{h2}: too few steps to test the count"
            );
        }
    }

    #[test]
    fn a_window_off_the_frame_measures_nothing() {
        let mut meter = QualityMeter::new();
        assert!(
            meter.sharpness_within(0, 0, 10, 10).is_nan(),
            "no frame yet"
        );
        let (rgb, w, h) = scene();
        meter.measure(&rgb, w, h);
        assert!(meter.sharpness_within(w, 0, 10, 10).is_nan());
        assert!(meter.sharpness_within(5, h, 10, 10).is_nan());
        assert!(meter.sharpness_within(w + 7, h + 9, 10, 10).is_nan());
        // A frame too small to measure leaves nothing to cut a window from.
        meter.noise_and_blocking(&[0; 6], 2, 1);
        assert!(meter.sharpness_within(1, 0, 10, 10).is_nan());
    }
}
