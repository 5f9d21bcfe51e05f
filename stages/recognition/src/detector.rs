//! The per-frame window scan.

use acch_core::{IndexView, NOT_OBJECT, Rect};

use crate::counts::{ColourCounts, CountLayout, RegionCounts};
use crate::model::{RecognitionError, RecognitionModel, RecognitionParams};

/// A rectangle of cells, `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct CellRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl CellRect {
    /// Columns.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    /// Rows.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    /// Whether the rectangle holds no cell.
    pub fn is_empty(&self) -> bool {
        self.x1 <= self.x0 || self.y1 <= self.y0
    }
    /// Grown by `by` cells on each side, cut to a `grid` (columns, rows).
    pub fn expand(&self, by: u32, grid: (usize, usize)) -> CellRect {
        CellRect {
            x0: self.x0.saturating_sub(by),
            y0: self.y0.saturating_sub(by),
            x1: self.x1.saturating_add(by).min(grid.0 as u32),
            y1: self.y1.saturating_add(by).min(grid.1 as u32),
        }
    }
}

/// Least share of the model's threshold a window must score under the
/// training light to count as found. The threshold (half the training
/// score) is the reference detection margins are measured against, and
/// the faint rule rejects a detection under 1.3x of it with a weak match
/// (`acch_confidence::rejected_as_faint`); a window between 0.7x and 1x of it
/// is found, and faint. A view from above behind a bar scores 0.38-0.49 of
/// the training score, just under the threshold, and was lost; out of
/// view, windows under the training light score at most 0.065 of it on
/// table 2 (0.21 through smoothed databases), far below 0.35
/// (docs/accuracy.md, "Found down to 0.7x the threshold").
pub const MIN_FOUND_MARGIN: f32 = 0.7;

/// The best window of a frame, when its score reaches
/// [`MIN_FOUND_MARGIN`] of the model's threshold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    /// The window in pixels, cut to the frame.
    pub window: Rect,
    /// The window in cells, cut to the frame.
    pub cells: CellRect,
    /// Its vote: the share of the object model found in the window's visible
    /// part, in [0, 1].
    pub score: f32,
    /// The model's threshold the score is measured against (its margin:
    /// score / threshold, at least [`MIN_FOUND_MARGIN`]).
    pub threshold: f32,
    /// Scale (apparent size relative to training) the window was sized for.
    pub scale: f32,
    /// Whether the window hangs over the frame border (the object may be
    /// partly outside the view).
    pub truncated: bool,
    /// Side in cells of the scan's (square) window, before it was cut to
    /// the frame.
    pub window_cells: u32,
}

impl Detection {
    /// Window side in cells: the scan's, and at least the cut window's.
    fn side(&self) -> u32 {
        self.window_cells
            .max(self.cells.width())
            .max(self.cells.height())
    }

    /// Cells segmentation's region may grow over: the window grown by
    /// `max_growth` window sides on each side, cut to the `grid`.
    pub fn search_cells(&self, params: &RecognitionParams, grid: (usize, usize)) -> CellRect {
        let grow = (params.max_growth * self.side() as f32).ceil() as u32;
        self.cells.expand(grow, grid)
    }

    /// The search area grown by one more window side: the ring between the
    /// two is where segmentation samples the background's colours (the
    /// object is not expected there). Every count segmentation reads lies
    /// inside.
    pub fn context_cells(&self, params: &RecognitionParams, grid: (usize, usize)) -> CellRect {
        self.search_cells(params, grid).expand(self.side(), grid)
    }
}

/// Window scores of the last scan, one per window position (row-major), for
/// a heat map. Position (i, j) is the window whose top-left cell is
/// `(origin.0 + i, origin.1 + j)`; positions skipped for lying mostly outside
/// the frame score 0.
#[derive(Clone, Copy, Debug)]
pub struct HeatMap<'a> {
    /// Scores, `width * height`.
    pub scores: &'a [f32],
    /// Positions per row.
    pub width: usize,
    /// Rows of positions.
    pub height: usize,
    /// Cell coordinates of the first position's top-left cell (may be negative).
    pub origin: (i32, i32),
    /// Window size in cells.
    pub window_cells: u32,
    /// Cell side in pixels.
    pub cell_px: u32,
}

/// Scans frames for one object. Holds every buffer it needs: after
/// construction, frames of the same size cause no allocation.
#[derive(Clone, Debug)]
pub struct Detector {
    model: RecognitionModel,
    width: u32,
    height: u32,
    cell: usize,
    gx: usize,
    gy: usize,
    /// Features per cell: colours 0..C, NOT_OBJECT at C, pairs at C+1..,
    /// padded with zeros to a multiple of 8.
    nf: usize,
    colour_feature: [u16; 256],
    /// Palette index -> row/column of `pair_lut` (C for "not object").
    remap: [u8; 256],
    /// (C+1) x (C+1): pair number + 1 for the K pairs, 0 for others.
    pair_lut: Vec<u8>,
    /// Model counts per object pixel, per feature.
    freq: Vec<f32>,
    /// Vote weight per feature (part weight / part total), per object pixel.
    vote: Vec<f32>,
    cell_counts: Vec<u16>,
    integral: Vec<f32>,
    expected: Vec<f32>,
    weight: Vec<f32>,
    run: Vec<f32>,
    scores: Vec<f32>,
    heat_w: usize,
    heat_h: usize,
    heat_origin: (i32, i32),
    window_cells: u32,
    best: f32,
    prepared: bool,
    /// [`MIN_FOUND_MARGIN`] unless measuring.
    min_found_margin: f32,
}

impl Detector {
    /// A detector for `width` x `height` frames.
    pub fn new(model: RecognitionModel, width: u32, height: u32) -> Result<Self, RecognitionError> {
        model.params.validate()?;
        if width == 0 || height == 0 {
            return Err(RecognitionError::EmptyFrame { width, height });
        }
        let c = model.colours();
        let k = model.pairs.len();
        let nf = (c + 1 + k).next_multiple_of(8);
        let mut colour_feature = [c as u16; 256];
        for (i, f) in colour_feature.iter_mut().enumerate().take(c) {
            *f = i as u16;
        }
        let mut remap = [c as u8; 256];
        for (i, r) in remap.iter_mut().enumerate().take(c) {
            *r = i as u8;
        }
        let side = c + 1;
        let mut pair_lut = vec![0u8; side * side];
        for (p, &(a, b, _)) in model.pairs.iter().enumerate() {
            let f = (p + 1) as u8;
            pair_lut[a as usize * side + b as usize] = f;
            pair_lut[b as usize * side + a as usize] = f;
        }
        let mut freq = vec![0f32; nf];
        freq[..c].copy_from_slice(&model.colour_freq);
        for (p, &(_, _, f)) in model.pairs.iter().enumerate() {
            freq[c + 1 + p] = f;
        }
        let col_total: f32 = model.colour_freq.iter().sum();
        let pair_total: f32 = model.pairs.iter().map(|p| p.2).sum();
        let alpha = if pair_total > 0.0 {
            model.params.colour_weight
        } else {
            1.0
        };
        let mut vote = vec![0f32; nf];
        if col_total > 0.0 {
            vote[..c].fill(alpha / col_total);
        }
        if pair_total > 0.0 {
            vote[c + 1..c + 1 + k].fill((1.0 - alpha) / pair_total);
        }
        let mut det = Detector {
            model,
            width: 0,
            height: 0,
            cell: 0,
            gx: 0,
            gy: 0,
            nf,
            colour_feature,
            remap,
            pair_lut,
            freq,
            vote,
            cell_counts: Vec::new(),
            integral: Vec::new(),
            expected: vec![0.0; nf],
            weight: vec![0.0; nf],
            run: vec![0.0; nf],
            scores: Vec::new(),
            heat_w: 0,
            heat_h: 0,
            heat_origin: (0, 0),
            window_cells: 0,
            best: 0.0,
            prepared: false,
            min_found_margin: MIN_FOUND_MARGIN,
        };
        det.resize(width, height);
        Ok(det)
    }

    fn resize(&mut self, width: u32, height: u32) {
        let cell = self.model.params.cell_px as usize;
        self.width = width;
        self.height = height;
        self.cell = cell;
        self.gx = (width as usize).div_ceil(cell);
        self.gy = (height as usize).div_ceil(cell);
        self.cell_counts = vec![0; self.gx * self.gy * self.nf];
        self.integral = vec![0.0; (self.gx + 1) * (self.gy + 1) * self.nf];
        self.prepared = false;
    }

    /// The model.
    pub fn model(&self) -> &RecognitionModel {
        &self.model
    }

    /// Frame size the buffers are laid out for.
    pub fn frame_size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Counts of the last prepared frame for cell (cx, cy): the C colours,
    /// "not object" at C, the K pairs from C + 1, zero padding.
    pub fn cell_counts(&self, cx: usize, cy: usize) -> &[u16] {
        let i = (cy * self.gx + cx) * self.nf;
        &self.cell_counts[i..i + self.nf]
    }

    /// The colour counts of the last prepared frame (every cell), as
    /// segmentation reads them; `None` before a frame was prepared.
    pub fn colour_counts(&self) -> Option<ColourCounts<'_>> {
        self.prepared.then(|| {
            ColourCounts::of_detector(
                self.count_layout(),
                &self.cell_counts,
                &self.integral,
                self.nf,
            )
        })
    }

    /// How this detector's colour counts are laid out (and published).
    pub fn count_layout(&self) -> CountLayout {
        CountLayout::new(&self.model, self.width, self.height)
    }

    /// Best window score of the last scan (also when below the threshold).
    pub fn best_score(&self) -> f32 {
        self.best
    }

    /// Window scores of the last scan.
    pub fn heat_map(&self) -> HeatMap<'_> {
        HeatMap {
            scores: &self.scores[..self.heat_w * self.heat_h],
            width: self.heat_w,
            height: self.heat_h,
            origin: self.heat_origin,
            window_cells: self.window_cells,
            cell_px: self.cell as u32,
        }
    }

    /// Computes the per-cell counts of a frame and their integral over the
    /// cell grid. [`Detector::detect`] calls it; call it directly to scan one
    /// frame at several scales with [`Detector::scan`].
    pub fn prepare<'a>(&mut self, image: impl Into<IndexView<'a>>) {
        let image = image.into();
        if image.width != self.width || image.height != self.height {
            self.resize(image.width, image.height);
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let (cell, gx, gy, nf) = (self.cell, self.gx, self.gy, self.nf);
        let d = self.model.params.pair_distance as usize;
        let data = &image.data[..w * h];
        self.cell_counts.fill(0);
        let cf = &self.colour_feature;
        let remap = &self.remap;
        let lut = &self.pair_lut[..];
        let side = self.model.colours() + 1;
        // Pair number p + 1 is stored: feature C + 1 + p.
        let pair_base = side - 1;
        let not = self.model.colours();
        // Pixels whose colour the object does not own are skipped: they form
        // no object pair, and their count per cell is derived afterwards
        // (incrementing one shared counter per background pixel would
        // serialise the loop on that counter).
        for cy in 0..gy {
            let y_lo = cy * cell;
            let y_hi = (y_lo + cell).min(h);
            let cells = &mut self.cell_counts[cy * gx * nf..(cy + 1) * gx * nf];
            for y in y_lo..y_hi {
                let row = &data[y * w..(y + 1) * w];
                // The last rows have no pair below: an empty slice.
                let down: &[u8] = if y + d < h {
                    &data[(y + d) * w..(y + d + 1) * w]
                } else {
                    &[]
                };
                for (cx, counts) in cells.chunks_exact_mut(nf).enumerate() {
                    let x_lo = cx * cell;
                    let x_hi = (x_lo + cell).min(w);
                    let counts: &mut [u16] = &mut counts[..nf];
                    for x in x_lo..x_hi {
                        let a = row[x];
                        if a == NOT_OBJECT {
                            continue;
                        }
                        counts[cf[a as usize] as usize] += 1;
                        let lrow = &lut[remap[a as usize] as usize * side..][..side];
                        if let Some(&b) = row.get(x + d) {
                            let f = lrow[remap[b as usize] as usize];
                            if f != 0 {
                                counts[pair_base + f as usize] += 1;
                            }
                        }
                        if let Some(&b) = down.get(x) {
                            let f = lrow[remap[b as usize] as usize];
                            if f != 0 {
                                counts[pair_base + f as usize] += 1;
                            }
                        }
                    }
                }
            }
            // "Not object" count per cell: the cell's pixels minus the rest.
            let ph = y_hi - y_lo;
            for (cx, counts) in cells.chunks_exact_mut(nf).enumerate() {
                let pw = ((cx + 1) * cell).min(w) - cx * cell;
                let owned: u32 = counts[..not].iter().map(|&n| n as u32).sum();
                counts[not] = ((pw * ph) as u32 - owned) as u16;
            }
        }
        self.build_integral();
        self.prepared = true;
    }

    /// What segmentation reads of the last prepared frame for `detection`
    /// (found on it): see [`RegionCounts`]. `None` before a frame was
    /// prepared.
    pub fn region_counts(&self, detection: &Detection) -> Option<RegionCounts<'_>> {
        RegionCounts::around(self.colour_counts()?, detection, &self.model)
    }

    /// Integral over the cell grid: I(x, y) = sum of cells left of x and
    /// above y.
    fn build_integral(&mut self) {
        let (gx, gy, nf) = (self.gx, self.gy, self.nf);
        let row = gx + 1;
        self.integral[..row * nf].fill(0.0);
        let mut run = std::mem::take(&mut self.run);
        for cy in 0..gy {
            run.fill(0.0);
            let base = (cy + 1) * row * nf;
            self.integral[base..base + nf].fill(0.0);
            for cx in 0..gx {
                let at = (cy * gx + cx) * nf;
                let counts = &self.cell_counts[at..at + nf];
                for (r, &c) in run.iter_mut().zip(counts) {
                    *r += c as f32;
                }
                let (above, here) = self.integral.split_at_mut(base);
                let up = &above[(cy * row + cx + 1) * nf..][..nf];
                let out = &mut here[(cx + 1) * nf..][..nf];
                for ((o, &u), &r) in out.iter_mut().zip(up).zip(run.iter()) {
                    *o = u + r;
                }
            }
        }
        self.run = run;
    }

    /// Scans the prepared frame with windows sized for `scale` (apparent
    /// size relative to training; 1 at the training distance; invalid
    /// values count as 1) and returns the best window if its score reaches
    /// [`MIN_FOUND_MARGIN`] of the threshold. `None` also before any frame
    /// was prepared.
    pub fn scan(&mut self, scale: f32) -> Option<Detection> {
        if !self.prepared {
            self.best = 0.0;
            return None;
        }
        let scale = if scale.is_finite() && scale > 0.0 {
            scale
        } else {
            1.0
        };
        let p = self.model.params;
        let (gx, gy, nf, cell) = (self.gx as i32, self.gy as i32, self.nf, self.cell as i64);
        let side_px = (self.model.size_px * scale * p.window_factor).max(1.0);
        let wc = ((side_px / cell as f32).round() as i32).max(1);
        self.window_cells = wc as u32;
        // Expected counts of a whole object at this scale.
        let area = (self.model.size_px * scale).powi(2);
        for ((e, w), (&f, &v)) in self
            .expected
            .iter_mut()
            .zip(self.weight.iter_mut())
            .zip(self.freq.iter().zip(&self.vote))
        {
            *e = f * area;
            *w = v / area.max(1e-6);
        }
        let (x_lo, y_lo) = (-(wc - 1), -(wc - 1));
        let (nx, ny) = ((gx + wc - 1) as usize, (gy + wc - 1) as usize);
        if self.scores.len() < nx * ny {
            self.scores.resize(nx * ny, 0.0);
        }
        self.heat_w = nx;
        self.heat_h = ny;
        self.heat_origin = (x_lo, y_lo);
        let (w_px, h_px) = (self.width as i64, self.height as i64);
        let win_area = (wc as i64 * cell).pow(2) as f32;
        let row = self.gx + 1;
        let mut best = (f32::NEG_INFINITY, CellRect::default(), false);
        for j in 0..ny {
            let y0 = y_lo + j as i32;
            let (cy0, cy1) = (y0.max(0), (y0 + wc).min(gy));
            let vis_h = ((cy1 as i64 * cell).min(h_px) - cy0 as i64 * cell).max(0);
            for i in 0..nx {
                let x0 = x_lo + i as i32;
                let (cx0, cx1) = (x0.max(0), (x0 + wc).min(gx));
                let vis_w = ((cx1 as i64 * cell).min(w_px) - cx0 as i64 * cell).max(0);
                let v = (vis_w * vis_h) as f32 / win_area;
                let slot = &mut self.scores[j * nx + i];
                if v < p.min_visible || v <= 0.0 {
                    *slot = 0.0;
                    continue;
                }
                let v = v.min(1.0);
                let at = |x: i32, y: i32| (y as usize * row + x as usize) * nf;
                let ig = &self.integral;
                let (a, b, c, d) = (at(cx0, cy0), at(cx1, cy0), at(cx0, cy1), at(cx1, cy1));
                let (ia, ib, ic, id) = (
                    &ig[a..a + nf],
                    &ig[b..b + nf],
                    &ig[c..c + nf],
                    &ig[d..d + nf],
                );
                let mut acc = 0f32;
                for f in 0..nf {
                    let s = id[f] - ic[f] - ib[f] + ia[f];
                    acc += s.min(v * self.expected[f]) * self.weight[f];
                }
                let score = acc / v;
                *slot = score;
                if score > best.0 {
                    let truncated = x0 < 0 || y0 < 0 || x0 + wc > gx || y0 + wc > gy;
                    best = (
                        score,
                        CellRect {
                            x0: cx0 as u32,
                            y0: cy0 as u32,
                            x1: cx1 as u32,
                            y1: cy1 as u32,
                        },
                        truncated,
                    );
                }
            }
        }
        self.best = best.0.max(0.0);
        // best.0 is -inf when no window was scored.
        if best.0 < self.found_score() || best.1.is_empty() {
            return None;
        }
        let cells = best.1;
        let window = Rect {
            x: cells.x0 * cell as u32,
            y: cells.y0 * cell as u32,
            width: cells.width() * cell as u32,
            height: cells.height() * cell as u32,
        }
        .clamp_to(self.width, self.height);
        Some(Detection {
            window,
            cells,
            score: best.0,
            threshold: self.model.threshold,
            scale,
            truncated: best.2,
            window_cells: wc as u32,
        })
    }

    /// Least window score that counts as found: [`MIN_FOUND_MARGIN`] of
    /// the model's threshold.
    pub fn found_score(&self) -> f32 {
        self.min_found_margin * self.model.threshold
    }

    /// Counts a window as found from `margin` of the model's threshold
    /// instead of [`MIN_FOUND_MARGIN`] (the evaluations compare the two).
    pub fn set_min_found_margin(&mut self, margin: f32) {
        self.min_found_margin = margin;
    }

    /// Finds the object in a frame quantised with the database palette.
    /// `scale` is its apparent size relative to training when known (from
    /// the distance); `None` assumes the training distance (segmentation
    /// then adapts the region to the actual size). `None` is returned when
    /// no window reaches [`Detector::found_score`]: the object is not in
    /// view.
    pub fn detect<'a>(
        &mut self,
        image: impl Into<IndexView<'a>>,
        scale: Option<f32>,
    ) -> Option<Detection> {
        self.prepare(image);
        self.scan(scale.unwrap_or(1.0))
    }
}
