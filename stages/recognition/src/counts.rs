//! Per-cell colour counts over a rectangle of the cell grid, and what
//! segmentation reads of a frame for one detection ([`RegionCounts`]):
//! borrowed from the [`crate::Detector`] that counted them, or read in place
//! from the bytes another process published ([`RegionCounts::publish`]).

use crate::detector::{CellRect, Detection};
use crate::model::RecognitionModel;

/// Most counts a cell holds (C + 1): palette indices are bytes.
pub const MAX_FEATURES: usize = 256;

/// Bytes of one published ring sum (`u32`, native-endian).
const RING_SUM_BYTES: usize = 4;

/// How the per-cell colour counts of one model on one frame size are laid
/// out: the cell grid and the width of a published count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountLayout {
    /// Palette colours C; a cell holds C + 1 counts ("not object" last).
    pub colours: usize,
    /// Cell side in pixels.
    pub cell_px: u32,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
}

impl CountLayout {
    /// The layout of `model`'s counts on `width` x `height` frames.
    pub fn new(model: &RecognitionModel, width: u32, height: u32) -> CountLayout {
        CountLayout {
            colours: model.colours(),
            cell_px: u32::from(model.params.cell_px).max(1),
            width,
            height,
        }
    }

    /// Cell grid size (columns, rows).
    pub fn grid(&self) -> (usize, usize) {
        let c = self.cell_px as usize;
        (
            (self.width as usize).div_ceil(c),
            (self.height as usize).div_ceil(c),
        )
    }

    /// Every cell of the grid.
    pub fn all_cells(&self) -> CellRect {
        let (gx, gy) = self.grid();
        CellRect {
            x0: 0,
            y0: 0,
            x1: gx as u32,
            y1: gy as u32,
        }
    }

    /// Counts a cell holds: the colours and "not object".
    pub fn features(&self) -> usize {
        self.colours + 1
    }

    /// Bytes of one published count: one when a cell holds at most 255
    /// pixels (the default 8x8 cells), else two (native-endian `u16`).
    pub fn count_bytes(&self) -> usize {
        if self.cell_px * self.cell_px <= u32::from(u8::MAX) {
            1
        } else {
            2
        }
    }

    /// Bytes of the published counts of the cells of `r`.
    pub fn bytes(&self, r: CellRect) -> usize {
        if r.is_empty() {
            return 0;
        }
        r.width() as usize * r.height() as usize * self.features() * self.count_bytes()
    }

    /// Pixels of the cells of `r` (cells on the right and bottom borders
    /// may be cut by the frame).
    pub fn pixels(&self, r: CellRect) -> u64 {
        if r.is_empty() {
            return 0;
        }
        let c = u64::from(self.cell_px);
        let span =
            |a: u32, b: u32, side: u32| (u64::from(b) * c).min(u64::from(side)) - u64::from(a) * c;
        span(r.x0, r.x1, self.width) * span(r.y0, r.y1, self.height)
    }

    /// Whether `r` lies inside the grid.
    pub fn contains(&self, r: CellRect) -> bool {
        let (gx, gy) = self.grid();
        !r.is_empty() && r.x1 as usize <= gx && r.y1 as usize <= gy
    }
}

#[derive(Clone, Copy)]
enum Store<'a> {
    /// A detector's own counts, `stride` a cell over the whole grid, with
    /// its integral over the grid (`stride` sums a grid corner).
    Detector {
        counts: &'a [u16],
        integral: &'a [f32],
        stride: usize,
    },
    /// Published: one byte a count, C + 1 a cell, cells of `rect` row-major.
    Narrow(&'a [u8]),
    /// Published: two native-endian bytes a count.
    Wide(&'a [u8]),
}

/// The colour counts (C colours, then "not object") of the cells of
/// [`ColourCounts::rect`] of one frame.
#[derive(Clone, Copy)]
pub struct ColourCounts<'a> {
    layout: CountLayout,
    rect: CellRect,
    store: Store<'a>,
}

impl<'a> ColourCounts<'a> {
    /// A detector's counts of the whole grid.
    pub(crate) fn of_detector(
        layout: CountLayout,
        counts: &'a [u16],
        integral: &'a [f32],
        stride: usize,
    ) -> ColourCounts<'a> {
        ColourCounts {
            layout,
            rect: layout.all_cells(),
            store: Store::Detector {
                counts,
                integral,
                stride,
            },
        }
    }

    /// Reads, in place, the counts of the cells of `rect` that
    /// [`ColourCounts::write`] wrote (in another process) for a detector
    /// of `layout`. `None` when `rect` is not inside the
    /// grid or `bytes` is not exactly its counts.
    pub fn from_bytes(layout: CountLayout, rect: CellRect, bytes: &'a [u8]) -> Option<Self> {
        if !layout.contains(rect) || bytes.len() != layout.bytes(rect) {
            return None;
        }
        let store = if layout.count_bytes() == 1 {
            Store::Narrow(bytes)
        } else {
            Store::Wide(bytes)
        };
        Some(ColourCounts {
            layout,
            rect,
            store,
        })
    }

    /// The layout (grid, colours) of these counts.
    pub fn layout(&self) -> CountLayout {
        self.layout
    }

    /// The cells whose counts are held.
    pub fn rect(&self) -> CellRect {
        self.rect
    }

    /// Whether every cell of `r` is held.
    pub fn covers(&self, r: CellRect) -> bool {
        !r.is_empty()
            && r.x0 >= self.rect.x0
            && r.y0 >= self.rect.y0
            && r.x1 <= self.rect.x1
            && r.y1 <= self.rect.y1
    }

    /// Row-major position of cell (cx, cy) among the held cells.
    #[inline]
    fn at(&self, cx: u32, cy: u32) -> usize {
        (cy - self.rect.y0) as usize * self.rect.width() as usize + (cx - self.rect.x0) as usize
    }

    /// Sums each of the C + 1 counts over the cells of `r` into
    /// `out[..C + 1]` (exact: integer counts below 2^24). Returns false,
    /// writing nothing, when `r` is not [`ColourCounts::covers`]ed or `out`
    /// is too short.
    pub fn sums(&self, r: CellRect, out: &mut [f32]) -> bool {
        let k = self.layout.features();
        if !self.covers(r) || out.len() < k {
            return false;
        }
        let out = &mut out[..k];
        match self.store {
            Store::Detector {
                integral, stride, ..
            } => {
                // Four corners of the grid integral: O(features).
                let row = self.layout.grid().0 + 1;
                let at = |x: u32, y: u32| (y as usize * row + x as usize) * stride;
                let (a, b, c, d) = (
                    at(r.x0, r.y0),
                    at(r.x1, r.y0),
                    at(r.x0, r.y1),
                    at(r.x1, r.y1),
                );
                for (f, o) in out.iter_mut().enumerate() {
                    *o = integral[d + f] - integral[c + f] - integral[b + f] + integral[a + f];
                }
            }
            Store::Narrow(bytes) => {
                // u8 into u32 lanes vectorises; a region is a few thousand cells.
                let mut acc = [0u32; MAX_FEATURES];
                let acc = &mut acc[..k];
                let w = r.width() as usize * k;
                for cy in r.y0..r.y1 {
                    let row = &bytes[self.at(r.x0, cy) * k..][..w];
                    for cell in row.chunks_exact(k) {
                        for (a, &c) in acc.iter_mut().zip(cell) {
                            *a += u32::from(c);
                        }
                    }
                }
                for (o, &a) in out.iter_mut().zip(acc.iter()) {
                    *o = a as f32;
                }
            }
            Store::Wide(bytes) => {
                out.fill(0.0);
                for cy in r.y0..r.y1 {
                    for cx in r.x0..r.x1 {
                        let cell = &bytes[self.at(cx, cy) * 2 * k..][..2 * k];
                        for (o, c) in out.iter_mut().zip(cell.chunks_exact(2)) {
                            *o += f32::from(u16::from_ne_bytes([c[0], c[1]]));
                        }
                    }
                }
            }
        }
        true
    }

    /// Writes the counts of the cells of `r` into `out` as published: cells
    /// row-major, C + 1 counts a cell, [`CountLayout::count_bytes`] each;
    /// what [`ColourCounts::from_bytes`] reads. Returns false, writing
    /// nothing, when `r` is not covered or `out` is not
    /// [`CountLayout::bytes`]`(r)` long.
    pub fn write(&self, r: CellRect, out: &mut [u8]) -> bool {
        let layout = self.layout;
        if !self.covers(r) || out.len() != layout.bytes(r) {
            return false;
        }
        let (k, b) = (layout.features(), layout.count_bytes());
        let row_out = r.width() as usize * k * b;
        for (cy, dst) in (r.y0..r.y1).zip(out.chunks_exact_mut(row_out)) {
            let at = self.at(r.x0, cy);
            match self.store {
                Store::Detector { counts, stride, .. } => {
                    let src = &counts[at * stride..][..r.width() as usize * stride];
                    for (cell, d) in src.chunks_exact(stride).zip(dst.chunks_exact_mut(k * b)) {
                        if b == 1 {
                            // A count never exceeds the cell's pixels (<= 255 here).
                            for (d, &c) in d.iter_mut().zip(&cell[..k]) {
                                *d = c as u8;
                            }
                        } else {
                            for (d, c) in d.chunks_exact_mut(2).zip(&cell[..k]) {
                                d.copy_from_slice(&c.to_ne_bytes());
                            }
                        }
                    }
                }
                Store::Narrow(bytes) | Store::Wide(bytes) => {
                    dst.copy_from_slice(&bytes[at * k * b..][..row_out]);
                }
            }
        }
        true
    }

    /// Σ count × weight over the C colours of held cell (cx, cy)
    /// (`weights[..C]`; "not object" is not weighed).
    ///
    /// # Panics
    /// When the cell is not held.
    #[inline]
    pub fn weighted(&self, cx: u32, cy: u32, weights: &[f32]) -> f32 {
        assert!(
            (self.rect.x0..self.rect.x1).contains(&cx)
                && (self.rect.y0..self.rect.y1).contains(&cy),
            "cell ({cx}, {cy}) is outside the counts' {:?}",
            self.rect
        );
        let (c, i) = (self.layout.colours, self.at(cx, cy));
        let w = &weights[..c];
        match self.store {
            Store::Detector { counts, stride, .. } => {
                dot(&counts[i * stride..][..c], w, |&n| f32::from(n))
            }
            Store::Narrow(bytes) => dot(&bytes[i * (c + 1)..][..c], w, |&n| f32::from(n)),
            Store::Wide(bytes) => dot(bytes[i * 2 * (c + 1)..][..2 * c].chunks_exact(2), w, |n| {
                f32::from(u16::from_ne_bytes([n[0], n[1]]))
            }),
        }
    }
}

#[inline]
fn dot<T>(counts: impl IntoIterator<Item = T>, weights: &[f32], value: impl Fn(T) -> f32) -> f32 {
    counts
        .into_iter()
        .zip(weights)
        .map(|(n, &w)| value(n) * w)
        .sum()
}

/// What segmentation reads of a frame for one detection, besides the
/// palette indices: the colour counts of every cell of the search area
/// ([`Detection::search_cells`]) and their sums over the ring around it
/// ([`Detection::context_cells`] minus the search area: the background
/// sample). Published, that is the search area's cells and C + 1 sums:
/// about a fifth of the grid's counts for the default scene.
#[derive(Clone, Copy)]
pub struct RegionCounts<'a> {
    cells: ColourCounts<'a>,
    search: CellRect,
    ring: [f32; MAX_FEATURES],
}

impl<'a> RegionCounts<'a> {
    /// The region counts of `detection` (of `model`) from `counts`, which
    /// must cover its context; `None` when they do not.
    pub fn around(
        counts: ColourCounts<'a>,
        detection: &Detection,
        model: &RecognitionModel,
    ) -> Option<Self> {
        let grid = counts.layout().grid();
        let search = detection.search_cells(&model.params, grid);
        let ctx = detection.context_cells(&model.params, grid);
        let (mut outer, mut ring) = ([0.0; MAX_FEATURES], [0.0; MAX_FEATURES]);
        if !counts.sums(ctx, &mut outer) || !counts.sums(search, &mut ring) {
            return None;
        }
        for (r, &o) in ring.iter_mut().zip(&outer) {
            // Exact: integer sums below 2^24.
            *r = o - *r;
        }
        Some(RegionCounts {
            cells: counts,
            search,
            ring,
        })
    }

    /// Bytes of the published counts of search area `search`: C + 1 ring
    /// sums (`u32`, native-endian), then the cells' counts
    /// ([`ColourCounts::write`]).
    pub fn published_len(layout: CountLayout, search: CellRect) -> usize {
        layout.features() * RING_SUM_BYTES + layout.bytes(search)
    }

    /// Writes these counts into the start of `out`
    /// ([`RegionCounts::published_len`] of the search area): what
    /// [`RegionCounts::from_bytes`] reads in another process. Returns
    /// false, writing nothing, when `out` is shorter.
    pub fn publish(&self, out: &mut [u8]) -> bool {
        let layout = self.cells.layout;
        let Some(out) = out.get_mut(..Self::published_len(layout, self.search)) else {
            return false;
        };
        let (ring, cells) = out.split_at_mut(layout.features() * RING_SUM_BYTES);
        for (d, &r) in ring.chunks_exact_mut(RING_SUM_BYTES).zip(&self.ring) {
            d.copy_from_slice(&(r as u32).to_ne_bytes());
        }
        self.cells.write(self.search, cells)
    }

    /// Reads, in place, what [`RegionCounts::publish`] wrote (in another
    /// process) for search area `search` with a detector of `layout`.
    /// `None` when `search` is not inside the grid or `bytes` is not
    /// exactly [`RegionCounts::published_len`] long.
    pub fn from_bytes(layout: CountLayout, search: CellRect, bytes: &'a [u8]) -> Option<Self> {
        if bytes.len() != Self::published_len(layout, search) {
            return None;
        }
        let (ring_bytes, cells) = bytes.split_at(layout.features() * RING_SUM_BYTES);
        let cells = ColourCounts::from_bytes(layout, search, cells)?;
        let mut ring = [0.0; MAX_FEATURES];
        for (r, b) in ring.iter_mut().zip(ring_bytes.chunks_exact(RING_SUM_BYTES)) {
            *r = u32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f32;
        }
        Some(RegionCounts {
            cells,
            search,
            ring,
        })
    }

    /// The per-cell counts (covering at least the search area).
    pub fn cells(&self) -> &ColourCounts<'a> {
        &self.cells
    }

    /// The search area.
    pub fn search(&self) -> CellRect {
        self.search
    }

    /// The C + 1 counts summed over the ring.
    pub fn ring(&self) -> &[f32] {
        &self.ring[..self.cells.layout.features()]
    }
}
