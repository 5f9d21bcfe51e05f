//! Where each colour lies: a coarse map of an object's colours, cell by
//! cell, and how much of a query's map a view's map holds in place.
//!
//! The histograms count colour pairs wherever they lie, and the layout
//! ([`crate::layout`]) keeps one centroid per colour. When an occluder
//! hides the side of an object that tells a view from its neighbour 20-30°
//! away, the visible part's pairs are held by both views and its centroids
//! move with the hidden part: neither can tell them apart. A map of which
//! colour lies where can, because the visible part still lies where it
//! lies in the right view and not in the turned one (measured on the
//! robust protocol's development seed, docs/accuracy.md, "Where the
//! visible part lies").
//!
//! A map covers the bounding box of the object's pixels with square cells
//! of a given size; each cell holds, per colour, the share of the cell's
//! area that colour covers, in 1/255. A query is compared with a view by
//! the share of its coloured area that the view covers with the same
//! colour in the same cell, at the best shift of one map against the other
//! within a margin of cells: the occluded part's place is unknown, so the
//! visible part is slid over the view.

use crate::{IndexImage, Rect};

/// A coarse map of where an object's colours lie: per cell of a square
/// grid over its pixels' bounding box, each colour's share of the cell's
/// area in 1/255.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColourMap {
    width: usize,
    height: usize,
    colours: usize,
    cells: Vec<u8>,
    /// Per row, each colour's shares summed across it; per column, down
    /// it: bounds that let a shift be skipped unmeasured.
    sums: BandSums,
}

/// A map's shares summed along its rows and along its columns, `colours`
/// per row (column): how much any shift can hold, row (column) by row.
#[derive(Clone, Debug, Default, PartialEq)]
struct BandSums {
    rows: Vec<u32>,
    columns: Vec<u32>,
}

impl BandSums {
    /// All sums of a `width x height` map of `colours` zero (no allocation
    /// once there is room).
    fn reset(&mut self, width: usize, height: usize, colours: usize) {
        self.rows.clear();
        self.rows.resize(height * colours, 0);
        self.columns.clear();
        self.columns.resize(width * colours, 0);
    }

    fn add(&mut self, x: usize, y: usize, colour: usize, colours: usize, share: u8) {
        self.rows[y * colours + colour] += share as u32;
        self.columns[x * colours + colour] += share as u32;
    }
}

/// The most a query's bands (rows or columns, `colours` sums each) can
/// hold of a view's when band `i` of the query lies on band `i + shift` of
/// the view: per band and colour, the smaller sum. No cell holds more than
/// the smaller of its row's (column's) sums, so no shift with this offset
/// holds more.
fn band_bound(query: &[u32], view: &[u32], colours: usize, shift: i64) -> u32 {
    let bands = |sums: &[u32]| (sums.len() / colours.max(1)) as i64;
    let (from, to) = (shift.max(0), (bands(query) + shift).min(bands(view)));
    if from >= to {
        return 0;
    }
    let (v0, v1) = (from as usize * colours, to as usize * colours);
    let q0 = (from - shift) as usize * colours;
    view[v0..v1]
        .iter()
        .zip(&query[q0..q0 + (v1 - v0)])
        .map(|(&v, &q)| v.min(q))
        .sum()
}

/// `lo..=hi` from `centre` outwards (centre, +1, -1, +2, ...): the likely
/// best shifts first, so the bound that skips the others is high early.
fn centre_out(lo: i64, hi: i64, centre: i64) -> impl Iterator<Item = i64> {
    let reach = (hi - centre).max(centre - lo).max(0);
    std::iter::once(centre)
        .chain((1..=reach).flat_map(move |k| [centre + k, centre - k]))
        .filter(move |d| (lo..=hi).contains(d))
}

/// Why a colour map could not be made from its parts.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ColourMapError {
    /// The cells are not `width x height x colours` bytes.
    #[error("a {width} x {height} map of {colours} colours needs {expected} bytes, got {got}")]
    Size {
        /// Cells across.
        width: usize,
        /// Cells down.
        height: usize,
        /// Colours per cell.
        colours: usize,
        /// `width * height * colours`.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
}

impl ColourMap {
    /// A map of `width x height` cells of `colours` shares each (cell
    /// after cell, row after row).
    pub fn from_parts(
        width: usize,
        height: usize,
        colours: usize,
        cells: Vec<u8>,
    ) -> Result<Self, ColourMapError> {
        let expected = width * height * colours;
        if cells.len() != expected {
            return Err(ColourMapError::Size {
                width,
                height,
                colours,
                expected,
                got: cells.len(),
            });
        }
        Ok(ColourMap::with_sums(width, height, colours, cells))
    }

    fn with_sums(width: usize, height: usize, colours: usize, cells: Vec<u8>) -> Self {
        let mut sums = BandSums::default();
        sums.reset(width, height, colours);
        for (cell, shares) in cells.chunks_exact(colours.max(1)).enumerate() {
            let (x, y) = (cell % width, cell / width);
            for (colour, &share) in shares.iter().enumerate() {
                sums.add(x, y, colour, colours, share);
            }
        }
        ColourMap {
            width,
            height,
            colours,
            cells,
            sums,
        }
    }

    /// The map of the pixels of `image` in `roi` (within `mask` when
    /// given) whose index is below `colours`, in cells of `cell_px`
    /// pixels, turned back by `roll_deg` (an image turned
    /// counter-clockwise by it, as [`crate::unroll_layout`]). `None` when
    /// no such pixel lies there or the cell size is not positive.
    pub fn measure(
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        colours: usize,
        cell_px: f32,
        roll_deg: f32,
    ) -> Option<Self> {
        let mut counts = Vec::new();
        let (width, height) =
            count_cells(image, mask, roi, colours, cell_px, roll_deg, &mut counts)?;
        let unit = 255.0 / (cell_px * cell_px);
        let cells = counts.iter().map(|&n| share(n, unit)).collect();
        Some(ColourMap::with_sums(width, height, colours, cells))
    }

    /// The cell-by-cell mean of `maps` (one pose under several lights):
    /// `None` when they are empty or differ in size.
    pub fn mean(maps: &[ColourMap]) -> Option<ColourMap> {
        let first = maps.first()?;
        if maps
            .iter()
            .any(|m| (m.width, m.height, m.colours) != (first.width, first.height, first.colours))
        {
            return None;
        }
        let k = maps.len() as f32;
        let cells = (0..first.cells.len())
            .map(|i| {
                let sum: f32 = maps.iter().map(|m| m.cells[i] as f32).sum();
                (sum / k).round() as u8
            })
            .collect();
        Some(ColourMap::with_sums(
            first.width,
            first.height,
            first.colours,
            cells,
        ))
    }

    /// Cells across.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Cells down.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Colours per cell.
    pub fn colours(&self) -> usize {
        self.colours
    }

    /// The shares, `colours` per cell, cell after cell, row after row.
    pub fn cells(&self) -> &[u8] {
        &self.cells
    }
}

/// A cell's share of `n` pixels, `unit` being 255 over a cell's area.
fn share(n: u32, unit: f32) -> u8 {
    (n as f32 * unit).round().min(255.0) as u8
}

/// Counts, into `counts` (cleared first; no allocation once it has room),
/// the pixels of each colour in each cell of the map
/// [`ColourMap::measure`] describes; its width and height in cells, or
/// `None` when it finds nothing.
fn count_cells(
    image: &IndexImage,
    mask: Option<&[u8]>,
    roi: Rect,
    colours: usize,
    cell_px: f32,
    roll_deg: f32,
    counts: &mut Vec<u32>,
) -> Option<(usize, usize)> {
    if let Some(m) = mask {
        assert_eq!(m.len(), image.data.len(), "mask size");
    }
    counts.clear();
    if !(cell_px.is_finite() && cell_px > 0.0) || colours == 0 {
        return None;
    }
    let roi = roi.clamp_to(image.width, image.height);
    let (s, c) = roll_deg.to_radians().sin_cos();
    let (cx, cy) = (roi.width as f32 / 2.0, roi.height as f32 / 2.0);
    // Seen with y down, an image turned counter-clockwise by a takes
    // (x, y) to (x cos a + y sin a, -x sin a + y cos a); this is its
    // inverse, about the region's centre.
    let place = |x: usize, y: usize| {
        let (x, y) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
        (x * c - y * s, x * s + y * c)
    };
    let w = image.width as usize;
    let pixels = || {
        (0..roi.height as usize).flat_map(move |row| {
            let start = (roi.y as usize + row) * w + roi.x as usize;
            (0..roi.width as usize).filter_map(move |x| {
                let i = start + x;
                let colour = image.data[i] as usize;
                (mask.is_none_or(|m| m[i] != 0) && colour < colours).then_some((x, row, colour))
            })
        })
    };
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for (x, y, _) in pixels() {
        let (u, v) = place(x, y);
        x0 = x0.min(u);
        y0 = y0.min(v);
        x1 = x1.max(u);
        y1 = y1.max(v);
    }
    if x0 > x1 {
        return None;
    }
    let cell = |u: f32, origin: f32| ((u - origin) / cell_px) as usize;
    let (width, height) = (cell(x1, x0) + 1, cell(y1, y0) + 1);
    counts.resize(width * height * colours, 0);
    for (x, y, colour) in pixels() {
        let (u, v) = place(x, y);
        let (i, j) = (cell(u, x0).min(width - 1), cell(v, y0).min(height - 1));
        counts[(j * width + i) * colours + colour] += 1;
    }
    Some((width, height))
}

/// One coloured part of a cell of a query's map.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Part {
    x: u16,
    y: u16,
    colour: u16,
    share: u8,
}

/// A query's map, read for matching: only the coloured parts of its cells.
#[derive(Clone, Debug, Default)]
pub struct PlacedQuery {
    width: usize,
    height: usize,
    colours: usize,
    parts: Vec<Part>,
    /// The shares of the parts from each on: what a shift can still gain.
    rest: Vec<u32>,
    total: u32,
    /// Pixels per colour and cell, reused from frame to frame.
    counts: Vec<u32>,
    /// The query's shares summed along rows and columns.
    sums: BandSums,
    /// Per horizontal shift of the view being placed, its column bound.
    column_bounds: Vec<u32>,
    /// The view being placed, on a grid with room for every shift.
    padded: Vec<u8>,
    /// Each part's index on that grid at shift zero.
    at: Vec<u32>,
}

impl PlacedQuery {
    /// Measures the query's map as [`ColourMap::measure`] (no allocation
    /// once its buffers have room); false when it finds nothing.
    pub fn measure(
        &mut self,
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        colours: usize,
        cell_px: f32,
        roll_deg: f32,
    ) -> bool {
        self.parts.clear();
        self.rest.clear();
        self.total = 0;
        self.colours = colours;
        let Some((w, h)) = count_cells(
            image,
            mask,
            roi,
            colours,
            cell_px,
            roll_deg,
            &mut self.counts,
        ) else {
            (self.width, self.height) = (0, 0);
            return false;
        };
        (self.width, self.height) = (w, h);
        let unit = 255.0 / (cell_px * cell_px);
        for (k, &n) in self.counts.iter().enumerate() {
            let share = share(n, unit);
            if share > 0 {
                let cell = k / colours;
                self.parts.push(Part {
                    x: (cell % w) as u16,
                    y: (cell / w) as u16,
                    colour: (k % colours) as u16,
                    share,
                });
                self.total += share as u32;
            }
        }
        self.sums.reset(w, h, colours);
        for p in &self.parts {
            let (x, y, c) = (p.x as usize, p.y as usize, p.colour as usize);
            self.sums.add(x, y, c, colours, p.share);
        }
        // The largest parts first: a shift that cannot beat the best is
        // given up after the fewest parts (the sum is the same).
        self.parts
            .sort_unstable_by_key(|p| std::cmp::Reverse(p.share));
        let mut rest = self.total;
        for p in &self.parts {
            self.rest.push(rest);
            rest -= p.share as u32;
        }
        self.total > 0
    }

    /// The share of the query's coloured area that `view` covers with the
    /// same colour in the same cell, at the best shift of the query over
    /// the view: from either edge of the smaller map against the same edge
    /// of the larger, within `margin` cells beyond (a visible part smaller
    /// than the view, or a region grown into something beside the object,
    /// larger). In [0, 1]; 0 when the query is empty or the maps' colours
    /// differ.
    pub fn share_held_by(&mut self, view: &ColourMap, margin: usize) -> f32 {
        self.best_share_held_by(std::iter::once(view), margin)
    }

    /// The largest [`Self::share_held_by`] among `views` (0 for none): one
    /// bound for them all, so a view's shift stops as soon as it cannot
    /// beat the best so far (the result is the same).
    pub fn best_share_held_by<'a>(
        &mut self,
        views: impl IntoIterator<Item = &'a ColourMap>,
        margin: usize,
    ) -> f32 {
        if self.total == 0 {
            return 0.0;
        }
        let mut best = 0u32;
        for view in views {
            if view.colours == self.colours {
                best = best.max(self.held_at_best_shift(view, margin, best));
            }
        }
        best as f32 / self.total as f32
    }

    /// The most of the query `view` holds over the shifts, or `floor` when
    /// no shift holds more. Exact: a shift is skipped, or its sum given
    /// up, only once it provably cannot beat the best so far.
    fn held_at_best_shift(&mut self, view: &ColourMap, margin: usize, floor: u32) -> u32 {
        if view.cells.is_empty() {
            return floor;
        }
        let m = margin as i64;
        let (qw, qh) = (self.width as i64, self.height as i64);
        let (vw, vh) = (view.width as i64, view.height as i64);
        let shifts = |v: i64, q: i64| ((v - q).min(0) - m, (v - q).max(0) + m);
        let ((x_lo, x_hi), (y_lo, y_hi)) = (shifts(vw, qw), shifts(vh, qh));
        let c = view.colours;
        let mut column_bounds = std::mem::take(&mut self.column_bounds);
        column_bounds.clear();
        column_bounds.extend(
            (x_lo..=x_hi).map(|dx| band_bound(&self.sums.columns, &view.sums.columns, c, dx)),
        );
        // The view on a grid with a border of empty cells wide enough for
        // every shift: each part's cell is its place plus the shift's
        // offset, with no edge to check.
        let (ox, oy) = (-x_lo, -y_lo);
        let pw = (ox + vw).max(ox + x_hi + qw) as usize;
        let ph = (oy + vh).max(oy + y_hi + qh) as usize;
        let (ox, oy) = (ox as usize, oy as usize);
        let mut padded = std::mem::take(&mut self.padded);
        padded.clear();
        padded.resize(pw * ph * c, 0);
        for (y, row) in view.cells.chunks_exact(view.width * c).enumerate() {
            let start = ((y + oy) * pw + ox) * c;
            padded[start..start + row.len()].copy_from_slice(row);
        }
        let mut at = std::mem::take(&mut self.at);
        at.clear();
        at.extend(self.parts.iter().map(|p| {
            let (x, y) = (p.x as usize + ox, p.y as usize + oy);
            ((y * pw + x) * c + p.colour as usize) as u32
        }));
        let held_at = |dx: i64, dy: i64, best: u32| {
            let offset = (dy * pw as i64 + dx) * c as i64;
            let mut held = 0u32;
            for ((p, &rest), &at) in self.parts.iter().zip(&self.rest).zip(&at) {
                // This shift cannot beat the best any more.
                if held + rest <= best {
                    return held;
                }
                held += padded[(at as i64 + offset) as usize].min(p.share) as u32;
            }
            held
        };
        let mut best = floor;
        for dy in centre_out(y_lo, y_hi, (vh - qh) / 2) {
            let row_bound = band_bound(&self.sums.rows, &view.sums.rows, c, dy);
            if row_bound <= best {
                continue;
            }
            for dx in centre_out(x_lo, x_hi, (vw - qw) / 2) {
                if row_bound.min(column_bounds[(dx - x_lo) as usize]) > best {
                    best = best.max(held_at(dx, dy, best));
                }
            }
        }
        (self.column_bounds, self.padded, self.at) = (column_bounds, padded, at);
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w` x `h` image of colour 3 (outside the palette of 2 colours)
    /// with rectangles of colours 0 and 1: `(x, y, width, height, colour)`.
    fn picture(w: u32, h: u32, rects: &[(u32, u32, u32, u32, u8)]) -> IndexImage {
        let mut data = vec![3u8; (w * h) as usize];
        for &(x0, y0, rw, rh, colour) in rects {
            for y in y0..y0 + rh {
                for x in x0..x0 + rw {
                    data[(y * w + x) as usize] = colour;
                }
            }
        }
        IndexImage::new(w, h, data)
    }

    fn whole(image: &IndexImage) -> Rect {
        Rect::full(image.width, image.height)
    }

    #[test]
    fn a_map_holds_each_colours_share_of_each_cell_over_the_objects_box() {
        // Colour 0 fills x 4..12, colour 1 x 12..16, rows 2..10; cells of 4.
        let image = picture(20, 12, &[(4, 2, 8, 8, 0), (12, 2, 4, 8, 1)]);
        let map = ColourMap::measure(&image, None, whole(&image), 2, 4.0, 0.0).unwrap();
        assert_eq!((map.width(), map.height(), map.colours()), (3, 2, 2));
        let cell = |x: usize, y: usize| &map.cells()[(y * 3 + x) * 2..][..2];
        assert_eq!(cell(0, 0), [255, 0]);
        assert_eq!(cell(1, 1), [255, 0]);
        assert_eq!(cell(2, 0), [0, 255]);
        // A mask that hides colour 1 shrinks the box to colour 0's.
        let mask: Vec<u8> = image.data.iter().map(|&i| (i == 0) as u8).collect();
        let masked = ColourMap::measure(&image, Some(&mask), whole(&image), 2, 4.0, 0.0).unwrap();
        assert_eq!((masked.width(), masked.height()), (2, 2));
        assert!(masked.cells().chunks(2).all(|c| c == [255, 0]));
        // Nothing of the palette, or no cell size: no map.
        let blank = picture(8, 8, &[]);
        assert_eq!(
            ColourMap::measure(&blank, None, whole(&blank), 2, 4.0, 0.0),
            None
        );
        assert_eq!(
            ColourMap::measure(&image, None, whole(&image), 2, 0.0, 0.0),
            None
        );
        assert_eq!(
            ColourMap::measure(&image, None, whole(&image), 2, f32::NAN, 0.0),
            None
        );
    }

    #[test]
    fn a_visible_part_is_held_in_place_by_its_own_view_and_not_by_a_turned_one() {
        // The view: 0 on the left, a mark of 1, 0 again, 1 on the right.
        let view_image = picture(
            48,
            16,
            &[
                (0, 0, 16, 16, 0),
                (16, 0, 8, 16, 1),
                (24, 0, 16, 16, 0),
                (40, 0, 8, 16, 1),
            ],
        );
        let view = ColourMap::measure(&view_image, None, whole(&view_image), 2, 4.0, 0.0).unwrap();
        // Its left two thirds, the rest hidden: held whole, slid into place.
        let mask: Vec<u8> = (0..48 * 16).map(|i| ((i % 48) < 32) as u8).collect();
        let mut query = PlacedQuery::default();
        assert!(query.measure(&view_image, Some(&mask), whole(&view_image), 2, 4.0, 0.0));
        assert_eq!(query.share_held_by(&view, 3), 1.0);
        // The same colours with the mark narrower and nearer the left (the
        // object turned): the visible part's colours are all there, its
        // arrangement is not (at best its right three quarters fit).
        let turned_image = picture(
            48,
            16,
            &[
                (0, 0, 12, 16, 0),
                (12, 0, 4, 16, 1),
                (16, 0, 24, 16, 0),
                (40, 0, 8, 16, 1),
            ],
        );
        let turned =
            ColourMap::measure(&turned_image, None, whole(&turned_image), 2, 4.0, 0.0).unwrap();
        assert_eq!(query.share_held_by(&turned, 3), 0.75);
        // Without a margin the part cannot slide, yet it sits at the left
        // edge already; a map of other colours holds nothing.
        assert_eq!(query.share_held_by(&view, 0), 1.0);
        let other = ColourMap::from_parts(1, 1, 3, vec![255, 255, 255]).unwrap();
        assert_eq!(query.share_held_by(&other, 3), 0.0);
        let empty = ColourMap::from_parts(0, 4, 2, vec![]).unwrap();
        assert_eq!(query.share_held_by(&empty, 3), 0.0);
        // The whole view with a blob of its colour grown on 24 px to its
        // left (6 cells, beyond the margin): the view still holds all but
        // the blob, its own part slid back into place.
        let grown_image = picture(
            72,
            16,
            &[
                (0, 0, 24, 16, 1),
                (24, 0, 16, 16, 0),
                (40, 0, 8, 16, 1),
                (48, 0, 16, 16, 0),
                (64, 0, 8, 16, 1),
            ],
        );
        assert!(query.measure(&grown_image, None, whole(&grown_image), 2, 4.0, 0.0));
        assert_eq!(query.share_held_by(&view, 3), 48.0 / 72.0);
    }

    /// Every shift in full: what the bounds and the early stops must give.
    fn held_by_every_shift(query: &PlacedQuery, view: &ColourMap, margin: usize) -> u32 {
        let m = margin as i64;
        let (qw, qh) = (query.width as i64, query.height as i64);
        let (vw, vh) = (view.width as i64, view.height as i64);
        let mut best = 0;
        for dy in (vh - qh).min(0) - m..=(vh - qh).max(0) + m {
            for dx in (vw - qw).min(0) - m..=(vw - qw).max(0) + m {
                let held: u32 = query
                    .parts
                    .iter()
                    .filter_map(|p| {
                        let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
                        ((0..vw).contains(&x) && (0..vh).contains(&y)).then(|| {
                            let k = (y as usize * view.width + x as usize) * view.colours;
                            view.cells[k + p.colour as usize].min(p.share) as u32
                        })
                    })
                    .sum();
                best = best.max(held);
            }
        }
        best
    }

    #[test]
    fn skipping_shifts_that_cannot_win_gives_what_trying_every_shift_gives() {
        // Blotchy pictures of 4 colours (cells of 4 px, blotches of 6), of
        // sizes about one another's, from a fixed generator.
        let mut state = 0x2545_f491_u64;
        let mut next = move |n: u64| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 33) % n
        };
        let mut blotchy = |w: u32, h: u32| {
            let seeds: Vec<u8> = (0..(w / 6 + 1) * (h / 6 + 1))
                .map(|_| next(5) as u8)
                .collect();
            let data = (0..w * h)
                .map(|i| seeds[((i / w) / 6 * (w / 6 + 1) + (i % w) / 6) as usize])
                .collect();
            IndexImage::new(w, h, data)
        };
        let mut query = PlacedQuery::default();
        let mut compared = 0;
        for trial in 0..40u32 {
            let images: Vec<IndexImage> = (0..4)
                .map(|k| blotchy(30 + 8 * k + trial % 3 * 5, 28 + trial % 4 * 6))
                .collect();
            let views: Vec<ColourMap> = images
                .iter()
                .map(|v| ColourMap::measure(v, None, whole(v), 4, 4.0, 0.0).unwrap())
                .collect();
            // Every other query a part of a view, on its cells (held whole:
            // the bounds are tight) or off them; the others pictures of
            // their own.
            if trial % 2 == 0 {
                let image = &images[(trial / 2 % 4) as usize];
                let step = if trial % 4 == 0 { 4 } else { 1 };
                let part = Rect {
                    x: step * (trial % 3),
                    y: step * (trial % 2 + 1),
                    width: image.width - 9,
                    height: image.height - 6,
                };
                assert!(query.measure(image, None, part, 4, 4.0, 0.0));
            } else {
                let image = blotchy(24 + trial % 5 * 9, 20 + trial % 7 * 7);
                assert!(query.measure(&image, None, whole(&image), 4, 4.0, 0.0));
            }
            let margin = (trial % 4) as usize;
            let every: Vec<u32> = views
                .iter()
                .map(|v| held_by_every_shift(&query, v, margin))
                .collect();
            for (view, &held) in views.iter().zip(&every) {
                let share = query.share_held_by(view, margin);
                assert_eq!(share, held as f32 / query.total as f32, "trial {trial}");
            }
            let best = *every.iter().max().unwrap();
            assert_eq!(
                query.best_share_held_by(&views, margin),
                best as f32 / query.total as f32,
                "trial {trial}"
            );
            compared += 1;
        }
        assert_eq!(compared, 40);
    }

    #[test]
    fn a_query_turned_by_the_cameras_roll_is_turned_back_before_it_is_placed() {
        // A bar of 0 over a bar of 1, and the same turned a quarter turn
        // counter-clockwise (0 now on the left).
        let upright = picture(16, 16, &[(0, 0, 16, 8, 0), (0, 8, 16, 8, 1)]);
        let turned = picture(16, 16, &[(0, 0, 8, 16, 0), (8, 0, 8, 16, 1)]);
        let view = ColourMap::measure(&upright, None, whole(&upright), 2, 4.0, 0.0).unwrap();
        let mut query = PlacedQuery::default();
        assert!(query.measure(&turned, None, whole(&turned), 2, 4.0, 90.0));
        assert!(
            query.share_held_by(&view, 0) > 0.95,
            "{}",
            query.share_held_by(&view, 0)
        );
        assert!(query.measure(&turned, None, whole(&turned), 2, 4.0, 0.0));
        assert!(query.share_held_by(&view, 0) < 0.6);
    }

    #[test]
    fn maps_of_one_pose_average_and_bad_parts_are_refused() {
        let a = ColourMap::from_parts(1, 1, 2, vec![255, 0]).unwrap();
        let b = ColourMap::from_parts(1, 1, 2, vec![155, 100]).unwrap();
        assert_eq!(ColourMap::mean(&[a.clone(), b]).unwrap().cells(), [205, 50]);
        let other = ColourMap::from_parts(2, 1, 2, vec![0; 4]).unwrap();
        assert_eq!(ColourMap::mean(&[a, other]), None);
        assert_eq!(ColourMap::mean(&[]), None);
        assert_eq!(
            ColourMap::from_parts(2, 2, 3, vec![0; 11]),
            Err(ColourMapError::Size {
                width: 2,
                height: 2,
                colours: 3,
                expected: 12,
                got: 11
            })
        );
    }
}
