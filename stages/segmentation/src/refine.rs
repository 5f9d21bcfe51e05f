//! The region refined by the frame's own colours.
//!
//! Region growing weighs colours by the object's model: on a real camera's
//! photographs of a mesh's colours (LM-O) the grown region, even where it
//! lies on the object, covers a median of 0.44-0.47 of it. The frame itself
//! says which colours are the object's: those the region holds, against
//! those around it. [`ColourRefiner`] takes the grown region as the
//! foreground sample and a frame around it as the background's, keeps the
//! pixels whose colour is likelier the object's (smoothed over 5x5), joined
//! to the region, and repeats once with the new region as the sample, as
//! GrabCut does without the graph cut.

use acch_core::Rect;

/// Bins per RGB channel of the colour histograms.
const BINS: usize = 16;
/// Rounds of sampling and keeping.
const ROUNDS: usize = 2;
/// The background sample keeps this many pixels off the region...
const GAP_PX: usize = 3;
/// ...and the smoothing of the object's likelihood reaches this far.
const SMOOTH_PX: usize = 2;

/// Refines regions of frames, reusing its buffers.
#[derive(Clone, Debug, Default)]
pub struct ColourRefiner {
    /// Frame-sized: 1 = region, 0 elsewhere; then the refined region.
    mask: Vec<u8>,
    /// Frame-sized scratch: the candidates (1) and what is kept (2).
    keep: Vec<u8>,
    object: Vec<f32>,
    background: Vec<f32>,
    likely: Vec<f32>,
    integral: Vec<f32>,
    near: Vec<u32>,
    stack: Vec<u32>,
    /// The refined region, cropped to its box...
    crop: Vec<u8>,
    /// ...which is this; `None` when the last refinement gave none.
    crop_roi: Option<Rect>,
}

/// A region: a mask (non-zero = object) over its box in the frame.
#[derive(Clone, Copy, Debug)]
pub struct RegionMask<'a> {
    /// Row-major over `roi`.
    pub mask: &'a [u8],
    /// Where it lies in the frame.
    pub roi: Rect,
}

impl ColourRefiner {
    /// `region` of the `width` x `height` packed-RGB frame `rgb`, refined
    /// by the frame's colours (255 = object over the returned box); `None`
    /// when nothing is left or the inputs disagree in size.
    pub fn refine(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
        region: RegionMask<'_>,
    ) -> Option<RegionMask<'_>> {
        let n = width * height;
        let r = region.roi;
        if rgb.len() != 3 * n
            || region.mask.len() != (r.width * r.height) as usize
            || (r.x + r.width) as usize > width
            || (r.y + r.height) as usize > height
        {
            return None;
        }
        if self.mask.len() != n {
            // Room for the largest region of the frame size up front: a
            // frame allocates nothing after the first.
            let grid = (width + 1) * (height + 1);
            for buffer in [&mut self.near, &mut self.stack] {
                buffer.reserve(grid.max(n));
            }
            self.likely.reserve(grid);
            self.integral.reserve(grid);
            self.crop.reserve(n);
        }
        self.mask.clear();
        self.mask.resize(n, 0);
        self.keep.clear();
        self.keep.resize(n, 0);
        let rw = r.width as usize;
        for (row, src) in region.mask.chunks_exact(rw.max(1)).enumerate() {
            let at = (r.y as usize + row) * width + r.x as usize;
            for (m, &s) in self.mask[at..at + rw].iter_mut().zip(src) {
                *m = u8::from(s != 0);
            }
        }
        self.crop_roi = None;
        let mut bounds = bounds_of(&self.mask, width, r)?;
        for _ in 0..ROUNDS {
            bounds = self.round(rgb, width, height, bounds)?;
        }
        let (x0, y0, x1, y1) = bounds;
        self.crop.clear();
        for y in y0..y1 {
            self.crop.extend(
                self.mask[y * width + x0..y * width + x1]
                    .iter()
                    .map(|&m| m * 255),
            );
        }
        self.crop_roi = Some(Rect {
            x: x0 as u32,
            y: y0 as u32,
            width: (x1 - x0) as u32,
            height: (y1 - y0) as u32,
        });
        self.last()
    }

    /// The region the last [`refine`](Self::refine) returned.
    pub fn last(&self) -> Option<RegionMask<'_>> {
        self.crop_roi.map(|roi| RegionMask {
            mask: &self.crop,
            roi,
        })
    }

    /// One round: samples the colours, keeps the likely pixels joined to
    /// the region within half its size around its box, fills holes.
    /// Returns the new region's box.
    fn round(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
        (x0, y0, x1, y1): (usize, usize, usize, usize),
    ) -> Option<(usize, usize, usize, usize)> {
        let reach = (x1 - x0).max(y1 - y0) / 2 + 4;
        let grow = |reach: usize| {
            (
                x0.saturating_sub(reach),
                y0.saturating_sub(reach),
                (x1 + reach).min(width),
                (y1 + reach).min(height),
            )
        };
        let inner = grow(reach);
        let outer = grow(2 * reach);
        // The background sample: the outer box but the region and a gap
        // around it (a count of region pixels in a square, by an integral).
        let (ox0, oy0, ox1, oy1) = outer;
        let ow = ox1 - ox0;
        self.near.clear();
        self.near.resize((ow + 1) * (oy1 - oy0 + 1), 0);
        for y in oy0..oy1 {
            let mut run = 0;
            for x in ox0..ox1 {
                run += u32::from(self.mask[y * width + x]);
                let i = (y - oy0 + 1) * (ow + 1) + (x - ox0 + 1);
                self.near[i] = self.near[i - ow - 1] + run;
            }
        }
        self.object.clear();
        self.object.resize(BINS * BINS * BINS, 0.5);
        self.background.clear();
        self.background.resize(BINS * BINS * BINS, 0.5);
        let (mut fg, mut bg) = (0.0f32, 0.0f32);
        for y in oy0..oy1 {
            let (ya, yb) = (y.saturating_sub(GAP_PX).max(oy0), (y + GAP_PX + 1).min(oy1));
            for x in ox0..ox1 {
                let i = y * width + x;
                let bin = bin_of(&rgb[3 * i..3 * i + 3]);
                if self.mask[i] != 0 {
                    self.object[bin] += 1.0;
                    fg += 1.0;
                    continue;
                }
                let (xa, xb) = (x.saturating_sub(GAP_PX).max(ox0), (x + GAP_PX + 1).min(ox1));
                let at = |x: usize, y: usize| self.near[(y - oy0) * (ow + 1) + (x - ox0)];
                if at(xb, yb) + at(xa, ya) - at(xa, yb) - at(xb, ya) == 0 {
                    self.background[bin] += 1.0;
                    bg += 1.0;
                }
            }
        }
        let bins = (BINS * BINS * BINS) as f32;
        let (fg, bg) = (fg + 0.5 * bins, bg + 0.5 * bins);
        // Each colour's likelihood of being the object's, in `object`.
        for (o, &b) in self.object.iter_mut().zip(&self.background) {
            let (f, b) = (*o / fg, b / bg);
            *o = f / (f + b);
        }
        // The object's likelihood over the inner box, smoothed.
        let (ix0, iy0, ix1, iy1) = inner;
        let iw = ix1 - ix0;
        self.likely.clear();
        self.likely.resize((iw + 1) * (iy1 - iy0 + 1), 0.0);
        for y in iy0..iy1 {
            let mut run = 0.0;
            let row = (y - iy0 + 1) * (iw + 1);
            for (x, px) in rgb[3 * (y * width + ix0)..3 * (y * width + ix1)]
                .chunks_exact(3)
                .enumerate()
            {
                run += self.object[bin_of(px)];
                self.likely[row + x + 1] = self.likely[row + x - iw] + run;
            }
        }
        std::mem::swap(&mut self.likely, &mut self.integral);
        for y in iy0..iy1 {
            let (ya, yb) = (
                y.saturating_sub(SMOOTH_PX).max(iy0),
                (y + SMOOTH_PX + 1).min(iy1),
            );
            for x in ix0..ix1 {
                let (xa, xb) = (
                    x.saturating_sub(SMOOTH_PX).max(ix0),
                    (x + SMOOTH_PX + 1).min(ix1),
                );
                let at = |x: usize, y: usize| self.integral[(y - iy0) * (iw + 1) + (x - ix0)];
                let sum = at(xb, yb) + at(xa, ya) - at(xa, yb) - at(xb, ya);
                let area = ((xb - xa) * (yb - ya)) as f32;
                self.keep[y * width + x] = u8::from(sum > 0.5 * area);
            }
        }
        // Kept: the candidates joined to the region (4-connected).
        self.stack.clear();
        for y in y0..y1 {
            for x in x0..x1 {
                let i = y * width + x;
                if self.mask[i] != 0 && self.keep[i] == 1 {
                    self.keep[i] = 2;
                    self.stack.push(i as u32);
                }
            }
        }
        spread(&mut self.keep, &mut self.stack, width, inner, |k| k == 1, 2);
        // The new region, holes filled: what the inner box's border does
        // not reach through pixels not kept.
        for y in iy0..iy1 {
            for x in ix0..ix1 {
                let i = y * width + x;
                let border = x == ix0 || y == iy0 || x + 1 == ix1 || y + 1 == iy1;
                if border && self.keep[i] != 2 && self.keep[i] != 3 {
                    self.keep[i] = 3;
                    self.stack.push(i as u32);
                }
            }
        }
        spread(&mut self.keep, &mut self.stack, width, inner, |k| k < 2, 3);
        // Clear the old region (it lies within the inner box) and write
        // the new one; leave `keep` zero for the next round.
        for y in iy0..iy1 {
            for x in ix0..ix1 {
                let i = y * width + x;
                self.mask[i] = u8::from(self.keep[i] != 3);
                self.keep[i] = 0;
            }
        }
        let inner_rect = Rect {
            x: ix0 as u32,
            y: iy0 as u32,
            width: iw as u32,
            height: (iy1 - iy0) as u32,
        };
        bounds_of(&self.mask, width, inner_rect)
    }
}

/// Spreads from the pixels on `stack` (already marked `to`) to their
/// 4-neighbours within `bounds` (first column and row, one past the last)
/// whose value in `buf` can be entered, marking them `to`.
fn spread(
    buf: &mut [u8],
    stack: &mut Vec<u32>,
    width: usize,
    (x0, y0, x1, y1): (usize, usize, usize, usize),
    enters: impl Fn(u8) -> bool,
    to: u8,
) {
    while let Some(i) = stack.pop() {
        let i = i as usize;
        let (x, y) = (i % width, i / width);
        for (inside, j) in [
            (x > x0, i.wrapping_sub(1)),
            (x + 1 < x1, i + 1),
            (y > y0, i.wrapping_sub(width)),
            (y + 1 < y1, i + width),
        ] {
            if inside && enters(buf[j]) {
                buf[j] = to;
                stack.push(j as u32);
            }
        }
    }
}

/// The histogram bin of an RGB pixel.
fn bin_of(px: &[u8]) -> usize {
    let q = |v: u8| v as usize * BINS / 256;
    (q(px[0]) * BINS + q(px[1])) * BINS + q(px[2])
}

/// The box of the mask's non-zero pixels within `rect`, as first column,
/// first row and one past the last of each; `None` when there are none.
fn bounds_of(mask: &[u8], width: usize, rect: Rect) -> Option<(usize, usize, usize, usize)> {
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for y in rect.y as usize..(rect.y + rect.height) as usize {
        for x in rect.x as usize..(rect.x + rect.width) as usize {
            if mask[y * width + x] != 0 {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x + 1);
                y1 = y1.max(y + 1);
            }
        }
    }
    (x1 > 0).then_some((x0, y0, x1, y1))
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 160;
    const H: usize = 120;

    /// A frame of a two-coloured disc (radius 30 at (80, 60)) on a
    /// background striped in two other colours, one of them near the
    /// disc's first colour but in another histogram bin; and the disc's
    /// mask.
    fn scene() -> (Vec<u8>, Vec<bool>) {
        let mut rgb = vec![0u8; 3 * W * H];
        let mut disc = vec![false; W * H];
        for y in 0..H {
            for x in 0..W {
                let (dx, dy) = (x as f64 - 80.0, y as f64 - 60.0);
                let inside = dx * dx + dy * dy <= 30.0 * 30.0;
                let c = if inside {
                    if (x / 6 + y / 6) % 2 == 0 {
                        [200, 40, 40]
                    } else {
                        [240, 230, 40]
                    }
                } else if (x / 10) % 2 == 0 {
                    [60, 60, 200]
                } else {
                    [170, 40, 40]
                };
                rgb[3 * (y * W + x)..3 * (y * W + x) + 3].copy_from_slice(&c);
                disc[y * W + x] = inside;
            }
        }
        (rgb, disc)
    }

    /// Share of the disc a region covers, and share of the region off it.
    fn cover_and_spill(region: RegionMask<'_>, disc: &[bool]) -> (f64, f64) {
        let (mut on, mut off) = (0usize, 0usize);
        let r = region.roi;
        for (i, &m) in region.mask.iter().enumerate() {
            if m == 0 {
                continue;
            }
            let (x, y) = (
                r.x as usize + i % r.width as usize,
                r.y as usize + i / r.width as usize,
            );
            if disc[y * W + x] {
                on += 1;
            } else {
                off += 1;
            }
        }
        let all = disc.iter().filter(|&&d| d).count();
        (
            on as f64 / all as f64,
            off as f64 / (on + off).max(1) as f64,
        )
    }

    #[test]
    fn a_region_on_part_of_the_object_grows_to_the_whole_by_the_frames_colours() {
        let (rgb, disc) = scene();
        // The left half of the disc's inner part, as a grown region on a
        // real photograph covers about half the object.
        let roi = Rect {
            x: 55,
            y: 40,
            width: 25,
            height: 40,
        };
        let mut part = vec![0u8; 25 * 40];
        for (i, m) in part.iter_mut().enumerate() {
            let (x, y) = (55 + i % 25, 40 + i / 25);
            *m = if disc[y * W + x] { 255 } else { 0 };
        }
        let given = RegionMask { mask: &part, roi };
        let (before, _) = cover_and_spill(given, &disc);
        let mut refiner = ColourRefiner::default();
        let refined = refiner.refine(&rgb, W, H, given).expect("a region");
        let (cover, spill) = cover_and_spill(refined, &disc);
        assert!(before < 0.5, "the test's region covers {before}");
        assert!(cover > 0.95, "covers {cover} of the disc");
        assert!(spill < 0.03, "{spill} of the region off the disc");
        // The same again: the buffers are reused and the answer the same.
        let again = refiner.refine(&rgb, W, H, given).expect("a region");
        assert_eq!(cover_and_spill(again, &disc), (cover, spill));
    }

    #[test]
    fn inputs_that_disagree_in_size_give_none() {
        let (rgb, _) = scene();
        let mask = vec![255u8; 10 * 10];
        let mut refiner = ColourRefiner::default();
        let at = |x, y, width, height| RegionMask {
            mask: &mask,
            roi: Rect {
                x,
                y,
                width,
                height,
            },
        };
        assert!(
            refiner.refine(&rgb, W, H, at(155, 0, 10, 10)).is_none(),
            "beyond the frame"
        );
        assert!(
            refiner.refine(&rgb, W, H, at(0, 0, 10, 9)).is_none(),
            "mask of another size"
        );
        assert!(
            refiner.refine(&rgb[3..], W, H, at(0, 0, 10, 10)).is_none(),
            "short frame"
        );
        let empty = vec![0u8; 100];
        let none = RegionMask {
            mask: &empty,
            roi: Rect {
                x: 0,
                y: 0,
                width: 10,
                height: 10,
            },
        };
        assert!(
            refiner.refine(&rgb, W, H, none).is_none(),
            "an empty region"
        );
    }
}
