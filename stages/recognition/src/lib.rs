//! Object recognition after Ekvall et al. (2005), as used by the paper
//! (section 3.2): the frame is split into cells; per cell, the counts of
//! every palette colour (and "not object") and of the object's K most
//! frequent colour pairs at a small pixel distance are computed once per
//! frame and integrated over the cell grid; every window of the object's
//! trained apparent size is then scored in O(features) with a histogram
//! intersection against the object's model. The best window is the
//! hypothesis; below [`MIN_FOUND_MARGIN`] of the model's threshold the
//! object is "not found".
//!
//! The model ([`RecognitionModel`]) is trained from the same labelled views
//! and palette as the view database and is stored in its
//! [`SECTION`] section. Everything here is a pure algorithm on
//! [`acch_core::IndexImage`] buffers; a [`Detector`] holds its buffers, so
//! frames of one size cause no allocation.
//!
//! ```text
//! per frame    per-cell counts: colour c (incl. "not object"), pair (a, b)
//!              at offsets (d, 0) and (0, d) if among the model's K pairs
//!              integral over the cell grid (exact in f32)
//! per window   h = 4 corner look-ups per feature
//!              score = α Σ_colours min(h, v E) / v ΣE + (1-α) Σ_pairs ... ,
//!              E = model frequency x (size x scale)², v = visible share
//! ```
//!
//! The score is the share of the object model found in the window, so it
//! does not depend on how much background the window holds, and a window
//! hanging over the frame border is compared with the visible part of the
//! model (an object partly out of view is still found; its detection says
//! `truncated`).
//!
//! Defaults, measured with `acch eval --protocol table2` (fruitbox and can,
//! 50 scenes per background, 640x480):
//! - "Found" threshold = 0.5 x the median training score. Window scores
//!   with the object in view: training median 0.60-0.73, no object missed
//!   on any background; with the object out of view (same scenes): at most
//!   0.04 on A, B, C and similar-colour clutter (lowest in-view score 0.50,
//!   fruitbox). Half the training score lies far inside that gap and keeps
//!   objects half out of view (scores 0.55-0.62) found. Windows down to
//!   0.7x of it (0.35 of the training score) are found too, and faint
//!   ([`MIN_FOUND_MARGIN`]): a small top behind a bar scores just under it.
//! - Cells of 8 px, pairs at 2 px, K = 32 pairs of different colours,
//!   α = 0.5, a square window of the object's median apparent size
//!   (sqrt of its area). The scan is not sensitive to these; the cost is
//!   the per-pixel counting, which skips pixels whose colour the object
//!   does not own: 0.4-1.1 ms per frame depending on how much of the
//!   background the palette keeps, plus 0.55 ms for the window scan
//!   (criterion bench `detect_segment` in acch-segmentation).

#![warn(missing_docs)]

mod counts;
mod detector;
mod light;
mod model;

pub use counts::{ColourCounts, CountLayout, MAX_FEATURES, RegionCounts};
pub use detector::{CellRect, Detection, Detector, HeatMap, MIN_FOUND_MARGIN};
pub use light::{
    CANDIDATES, COLOUR_TEMPERATURES_K, EXPOSURES, LightSearch, RELIT_SCORE_FRACTION,
    WEAK_SCORE_FRACTION,
};
pub use model::{
    ColourPeaks, MODEL_VERSION, RecognitionError, RecognitionModel, RecognitionParams, SECTION,
};

#[cfg(test)]
mod tests {
    use super::*;
    use acch_core::{ColourSpace, IndexImage, NOT_OBJECT, Palette};
    use acch_pose::train::LabelledView;

    const COLOURS: [[u8; 3]; 4] = [[220, 30, 30], [30, 200, 40], [40, 40, 220], [230, 220, 40]];
    const GREY: [u8; 3] = [128, 128, 128];
    const W: u32 = 160;
    const H: u32 = 120;

    fn palette() -> Palette {
        let centres = COLOURS
            .iter()
            .map(|&c| ColourSpace::Lab.convert(c))
            .collect();
        Palette::from_centres(ColourSpace::Lab, centres, 20.0).unwrap()
    }

    /// A frame with a 40x40 checker of the four colours (5 px tiles) at
    /// (x0, y0) (when given) over `bg`; returns RGB and mask.
    fn frame(at: Option<(u32, u32)>, bg: impl Fn(u32, u32) -> [u8; 3]) -> (Vec<u8>, Vec<u8>) {
        let mut rgb = Vec::with_capacity((W * H * 3) as usize);
        let mut mask = Vec::with_capacity((W * H) as usize);
        for y in 0..H {
            for x in 0..W {
                let inside =
                    at.filter(|&(x0, y0)| x >= x0 && x < x0 + 40 && y >= y0 && y < y0 + 40);
                let c = match inside {
                    Some((x0, y0)) => COLOURS[(((x - x0) / 5 + 2 * ((y - y0) / 5)) % 4) as usize],
                    None => bg(x, y),
                };
                rgb.extend_from_slice(&c);
                mask.push(if inside.is_some() { 255 } else { 0 });
            }
        }
        (rgb, mask)
    }

    fn model() -> RecognitionModel {
        model_with_cells(RecognitionParams::default().cell_px)
    }

    fn model_with_cells(cell_px: u16) -> RecognitionModel {
        let frames: Vec<_> = [(10, 10), (60, 40), (100, 70)]
            .iter()
            .map(|&at| frame(Some(at), |_, _| GREY))
            .collect();
        let views: Vec<LabelledView> = frames
            .iter()
            .map(|(rgb, mask)| LabelledView {
                rgb,
                mask,
                width: W,
                height: H,
                theta_deg: 90.0,
                phi_deg: 0.0,
                scale: 1.0,
                centre_px: None,
            })
            .collect();
        let params = RecognitionParams {
            pairs: 8,
            cell_px,
            ..RecognitionParams::default()
        };
        RecognitionModel::train(&views, &palette(), &params).unwrap()
    }

    /// Background noise: grey with scattered single pixels of object colours.
    fn noisy(x: u32, y: u32) -> [u8; 3] {
        let h = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) % 17;
        if h < 4 { COLOURS[h as usize] } else { GREY }
    }

    fn quantised(rgb: &[u8]) -> IndexImage {
        palette().quantise(rgb, W, H)
    }

    #[test]
    fn the_model_learns_colours_pairs_and_size() {
        let m = model();
        assert_eq!(m.colours(), 4);
        for f in &m.colour_freq {
            assert!((f - 0.25).abs() < 0.02, "{:?}", m.colour_freq);
        }
        assert!(!m.pairs.is_empty() && m.pairs.iter().all(|p| p.0 < p.1));
        assert!((m.size_px - 40.0).abs() < 0.5, "{}", m.size_px);
        assert!(m.train_score > 0.9, "{}", m.train_score);
        assert_eq!(m.threshold, m.params.found_fraction * m.train_score);
    }

    #[test]
    fn the_window_lands_on_the_object() {
        let mut det = Detector::new(model(), W, H).unwrap();
        let (rgb, _) = frame(Some((84, 24)), noisy);
        let d = det.detect(&quantised(&rgb), Some(1.0)).expect("found");
        let (cx, cy) = (
            d.window.x + d.window.width / 2,
            d.window.y + d.window.height / 2,
        );
        assert!((84..124).contains(&cx) && (24..64).contains(&cy), "{d:?}");
        assert!(!d.truncated);
        let heat = det.heat_map();
        assert_eq!(heat.scores.len(), heat.width * heat.height);
        let best = heat.scores.iter().copied().fold(0.0, f32::max);
        assert_eq!(best, d.score);
    }

    #[test]
    fn the_light_search_finds_an_object_in_dim_light_and_nothing_in_an_empty_frame() {
        let mut det = Detector::new(model(), W, H).unwrap();
        let mut indices = vec![0u8; (W * H) as usize];
        let (rgb, _) = frame(Some((84, 24)), noisy);
        let dim: Vec<u8> = rgb
            .iter()
            .map(|&c| acch_core::light::relight(c, EXPOSURES[2]))
            .collect();
        // Under the training light alone the dim object is lost.
        let mut off = LightSearch::new(&palette(), 0);
        assert!(
            off.detect(&mut det, &dim, (W, H), (&mut indices, false), None)
                .is_none()
        );
        let mut search = LightSearch::new(&palette(), CANDIDATES);
        let d = search
            .detect(&mut det, &dim, (W, H), (&mut indices, false), None)
            .expect("found under the light searched");
        let (cx, cy) = (
            d.window.x + d.window.width / 2,
            d.window.y + d.window.height / 2,
        );
        assert!((84..124).contains(&cx) && (24..64).contains(&cy), "{d:?}");
        // This palette's colours are far apart: a light a step off maps
        // them as well, and the first of equals is kept.
        let g = search.gains();
        assert!(
            g.iter().all(|g| (EXPOSURES[0]..=EXPOSURES[4]).contains(g)),
            "{g:?}"
        );
        // The indices left are the frame under that light: the object's.
        assert_eq!(indices, quantised(&rgb).data);
        // A clean frame is the training light's, found at once.
        assert!(
            search
                .detect(&mut det, &rgb, (W, H), (&mut indices, false), None)
                .is_some()
        );
        assert_eq!(search.gains(), [1.0; 3]);
        // No light makes an object of a frame without one.
        let (empty, _) = frame(None, noisy);
        assert!(
            search
                .detect(&mut det, &empty, (W, H), (&mut indices, false), None)
                .is_none()
        );
    }

    #[test]
    fn a_light_rated_better_is_taken_with_its_indices_and_one_that_loses_the_object_is_not() {
        let (rgb, _) = frame(Some((84, 24)), noisy);
        let dim: Vec<u8> = rgb
            .iter()
            .map(|&c| acch_core::light::relight(c, EXPOSURES[2]))
            .collect();
        let mut det = Detector::new(model(), W, H).unwrap();
        let mut indices = vec![0u8; (W * H) as usize];
        let mut search = LightSearch::new(&palette(), CANDIDATES);
        let found = search
            .detect(&mut det, &dim, (W, H), (&mut indices, false), None)
            .expect("found under the light searched");
        let (before, before_indices) = (search.gains(), indices.clone());
        // Rated best: the light in use (the first rated) keeps all.
        let mut calls = 0;
        let kept = search.choose_light(&mut det, &dim, (W, H), (&mut indices, found), None, |_| {
            calls += 1;
            Some(if calls == 1 { 1.0 } else { 0.0 })
        });
        assert_eq!(calls, 1 + CANDIDATES);
        assert_eq!((kept, search.gains()), (Some(found), before));
        assert_eq!(indices, before_indices);
        // Rated best: the light mapping least of the frame, the darkest
        // exposure's neighbour that loses the object. Not taken.
        let lost = |idx: &[u8]| Some(idx.iter().filter(|&&i| i == NOT_OBJECT).count() as f32);
        let kept = search.choose_light(&mut det, &dim, (W, H), (&mut indices, found), None, lost);
        assert_eq!((kept, search.gains()), (Some(found), before));
        assert_eq!(indices, before_indices);
        // Rated best: a neighbour under which the object still counts
        // (the next exposure, up or down, maps these far-apart colours as
        // well). Taken, with its own indices and detection.
        let mut calls = 0;
        let moved = search
            .choose_light(&mut det, &dim, (W, H), (&mut indices, found), None, |_| {
                calls += 1;
                Some(if calls == 2 { 1.0 } else { 0.0 })
            })
            .expect("still found");
        let after = search.gains();
        assert_ne!(after, before);
        let relit = palette().relit(after).unwrap().quantise(&dim, W, H);
        assert_eq!(indices, relit.data);
        let mut fresh = Detector::new(model(), W, H).unwrap();
        assert_eq!(fresh.detect(&relit, None), Some(moved));
    }

    #[test]
    fn indices_said_to_be_written_are_used_and_others_are_not() {
        let mut det = Detector::new(model(), W, H).unwrap();
        let (rgb, _) = frame(Some((84, 24)), noisy);
        let (empty, _) = frame(None, noisy);
        let mut search = LightSearch::new(&palette(), 0);
        // The object's frame quantised by another (a joint palette): the
        // empty RGB frame handed beside it is not read.
        let mut indices = quantised(&rgb).data;
        assert!(
            search
                .detect(&mut det, &empty, (W, H), (&mut indices, true), None)
                .is_some()
        );
        // Not said to be written: the RGB frame is quantised over them.
        let mut indices = quantised(&rgb).data;
        assert!(
            search
                .detect(&mut det, &empty, (W, H), (&mut indices, false), None)
                .is_none()
        );
    }

    /// Every cell count of `r` and the sums over every rectangle of `rects`
    /// read the same from `a` and `b`.
    fn assert_same_counts(a: &ColourCounts, b: &ColourCounts, r: CellRect, rects: &[CellRect]) {
        let c = a.layout().colours;
        // Distinct weights so that a count read from the wrong place shows.
        let weights: Vec<f32> = (0..c).map(|i| 1.0 + i as f32 * 1.5).collect();
        for cy in r.y0..r.y1 {
            for cx in r.x0..r.x1 {
                assert_eq!(a.weighted(cx, cy, &weights), b.weighted(cx, cy, &weights));
            }
        }
        let (mut x, mut y) = (vec![0.0; c + 1], vec![0.0; c + 1]);
        for &q in rects {
            assert!(a.sums(q, &mut x) && b.sums(q, &mut y), "{q:?}");
            assert_eq!(x, y);
        }
    }

    #[test]
    fn colour_counts_published_around_a_detection_read_the_same_in_place() {
        let (rgb, _) = frame(Some((60, 40)), noisy);
        let image = quantised(&rgb);
        let mut det = Detector::new(model(), W, H).unwrap();
        assert!(det.colour_counts().is_none(), "nothing prepared yet");
        let found = det.detect(&image, Some(1.0)).expect("found");
        let layout = det.count_layout();
        let params = det.model().params;
        let grid = layout.grid();
        let search = found.search_cells(&params, grid);
        let ctx = found.context_cells(&params, grid);
        let own = det.colour_counts().expect("prepared");
        let whole = layout.all_cells();
        assert!(own.sums(whole, &mut [0.0; 16]));
        // The context (on this small frame, most of the grid) and the
        // search area inside it.
        for published in [ctx, search] {
            let mut bytes = vec![0u8; layout.bytes(published)];
            // 8x8 cells: one byte per count, C + 1 a cell.
            let cells = (published.width() * published.height()) as usize;
            assert_eq!(bytes.len(), cells * (layout.colours + 1));
            assert!(own.write(published, &mut bytes));
            let read = ColourCounts::from_bytes(layout, published, &bytes).expect("read");
            assert_same_counts(&own, &read, published, &[found.cells, published]);
            // Only the published cells can be read.
            assert_eq!(read.sums(whole, &mut [0.0; 16]), published == whole);
        }
        assert!(search.width() < grid.0 as u32, "{search:?}");
        let mut bytes = vec![0u8; layout.bytes(ctx)];
        assert!(own.write(ctx, &mut bytes));
        // Bytes of another length, or a rectangle off the grid, are refused.
        assert!(ColourCounts::from_bytes(layout, ctx, &bytes[1..]).is_none());
        let off = CellRect {
            x1: grid.0 as u32 + 1,
            ..ctx
        };
        assert!(ColourCounts::from_bytes(layout, off, &bytes).is_none());
        assert!(!own.write(off, &mut bytes));
    }

    #[test]
    fn region_counts_publish_the_search_area_and_the_ring_sums() {
        let (rgb, _) = frame(Some((60, 40)), noisy);
        let image = quantised(&rgb);
        let mut det = Detector::new(model(), W, H).unwrap();
        let found = det.detect(&image, Some(1.0)).expect("found");
        let layout = det.count_layout();
        let region = det.region_counts(&found).expect("prepared");
        let search = region.search();
        assert_eq!(
            search,
            found.search_cells(&det.model().params, layout.grid())
        );
        let mut bytes = vec![0u8; RegionCounts::published_len(layout, search)];
        assert!(region.publish(&mut bytes));
        assert!(!region.publish(&mut bytes[1..]));
        let read = RegionCounts::from_bytes(layout, search, &bytes).expect("read");
        assert_eq!(read.search(), search);
        assert_eq!(read.ring(), region.ring());
        assert_eq!(read.ring().len(), layout.colours + 1);
        // The ring holds the background's pixels: some counted, all sums whole.
        assert!(read.ring().iter().sum::<f32>() > 0.0);
        assert!(read.ring().iter().all(|&v| v >= 0.0 && v.fract() == 0.0));
        assert_same_counts(region.cells(), read.cells(), search, &[found.cells, search]);
        // Published counts cover the search area only, not the context: no
        // ring can be summed from them again.
        let ctx = found.context_cells(&det.model().params, layout.grid());
        if ctx != search {
            assert!(RegionCounts::around(*read.cells(), &found, det.model()).is_none());
        }
        assert!(RegionCounts::from_bytes(layout, search, &bytes[1..]).is_none());
    }

    #[test]
    fn colour_counts_of_cells_over_255_pixels_travel_as_u16() {
        let (rgb, _) = frame(Some((60, 40)), |_, _| GREY);
        let image = quantised(&rgb);
        let mut det = Detector::new(model_with_cells(16), W, H).unwrap();
        det.prepare(&image);
        let layout = det.count_layout();
        let (gx, gy) = layout.grid();
        let whole = layout.all_cells();
        let own = det.colour_counts().expect("prepared");
        let mut bytes = vec![0u8; layout.bytes(whole)];
        assert_eq!(bytes.len(), gx * gy * (layout.colours + 1) * 2);
        assert!(own.write(whole, &mut bytes));
        let published = ColourCounts::from_bytes(layout, whole, &bytes).expect("read");
        let corner = CellRect {
            x0: 1,
            y0: 1,
            x1: 3,
            y1: 2,
        };
        assert_same_counts(&own, &published, whole, &[whole, corner]);
        // A 16x16 cell of background alone counts 256 "not object" pixels.
        let c = layout.colours;
        assert!((0..gy).any(|cy| (0..gx).any(|cx| det.cell_counts(cx, cy)[c] > 255)));
    }

    #[test]
    fn an_empty_frame_is_not_found() {
        let mut det = Detector::new(model(), W, H).unwrap();
        let (rgb, _) = frame(None, noisy);
        assert_eq!(det.detect(&quantised(&rgb), Some(1.0)), None);
        assert!(det.best_score() < det.found_score());
        let (rgb, _) = frame(None, |_, _| COLOURS[1]);
        assert_eq!(det.detect(&quantised(&rgb), Some(1.0)), None);
    }

    /// `frame`'s object at `at` with a grey bar over all but its `visible`
    /// leftmost columns.
    fn barred(at: (u32, u32), visible: u32) -> Vec<u8> {
        let (mut rgb, _) = frame(Some(at), noisy);
        for y in at.1..at.1 + 40 {
            for x in at.0 + visible..at.0 + 40 {
                let i = ((y * W + x) * 3) as usize;
                rgb[i..i + 3].copy_from_slice(&GREY);
            }
        }
        rgb
    }

    #[test]
    fn a_window_under_the_threshold_is_found_faint_down_to_the_least_margin() {
        let mut det = Detector::new(model(), W, H).unwrap();
        // 30 % of the object in view scores under the threshold (half the
        // training score) and above 0.7x of it: found, with its margin.
        let d = det
            .detect(&quantised(&barred((84, 24), 12)), Some(1.0))
            .expect("found");
        let margin = d.score / d.threshold;
        assert!((MIN_FOUND_MARGIN..1.0).contains(&margin), "{d:?}");
        assert_eq!(d.threshold, det.model().threshold);
        let cx = d.window.x + d.window.width / 2;
        assert!((76..124).contains(&cx), "{d:?}");
        // 15 % of it scores under 0.7x: not found.
        assert_eq!(
            det.detect(&quantised(&barred((84, 24), 6)), Some(1.0)),
            None
        );
        assert!(det.best_score() > 0.0 && det.best_score() < det.found_score());
        assert_eq!(det.found_score(), MIN_FOUND_MARGIN * det.model().threshold);
    }

    #[test]
    fn an_object_at_the_border_is_found_truncated() {
        let mut det = Detector::new(model(), W, H).unwrap();
        // 20 of its 40 columns in view (columns from 160 on are not drawn).
        let (rgb, _) = frame(Some((140, 40)), noisy);
        let d = det.detect(&quantised(&rgb), Some(1.0)).expect("found");
        assert!(d.truncated, "{d:?}");
        assert!(d.window.x + d.window.width == W, "{d:?}");
    }

    #[test]
    fn other_frame_sizes_are_handled() {
        let mut det = Detector::new(model(), 64, 48).unwrap();
        let (rgb, _) = frame(Some((50, 50)), noisy);
        assert!(det.detect(&quantised(&rgb), Some(1.0)).is_some());
        assert_eq!(det.frame_size(), (W, H));
    }

    #[test]
    fn the_model_round_trips_and_bad_bytes_are_errors() {
        let m = model();
        let bytes = m.to_bytes();
        assert_eq!(RecognitionModel::from_bytes(&bytes).unwrap(), m);
        // A model of version 1 has no colour peaks and reads as such.
        let peaks = m
            .colour_peaks
            .as_ref()
            .expect("a trained model has colour peaks");
        assert!(
            peaks.share.iter().all(|s| (s - 0.25).abs() < 0.03),
            "{peaks:?}"
        );
        let freq: Vec<u8> = m.colour_freq.iter().flat_map(|f| f.to_le_bytes()).collect();
        let at = bytes.windows(freq.len()).position(|w| w == freq).unwrap() + freq.len();
        let mut v1 = bytes.clone();
        v1.drain(at..at + 8 * m.colours());
        v1[8..12].copy_from_slice(&1u32.to_le_bytes());
        let old = RecognitionModel::from_bytes(&v1).unwrap();
        assert_eq!(
            old,
            RecognitionModel {
                colour_peaks: None,
                ..m.clone()
            }
        );
        assert_eq!(
            RecognitionModel::from_bytes(b"PNG"),
            Err(RecognitionError::BadMagic)
        );
        let mut v = bytes.clone();
        v[8] = 7;
        assert!(matches!(
            RecognitionModel::from_bytes(&v),
            Err(RecognitionError::UnsupportedVersion { found: 7, .. })
        ));
        for cut in [12, 20, bytes.len() - 1] {
            assert!(
                matches!(
                    RecognitionModel::from_bytes(&bytes[..cut]),
                    Err(RecognitionError::Corrupt(_))
                ),
                "cut at {cut}"
            );
        }
        let mut v = bytes.clone();
        v.push(0);
        assert!(matches!(
            RecognitionModel::from_bytes(&v),
            Err(RecognitionError::Corrupt(_))
        ));
        // A NaN threshold (the last 4 bytes).
        let mut v = bytes.clone();
        let n = v.len();
        v[n - 4..].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            RecognitionModel::from_bytes(&v),
            Err(RecognitionError::Corrupt(_))
        ));
    }

    #[test]
    fn bad_input_is_an_error() {
        let p = palette();
        let bad = RecognitionParams {
            cell_px: 1,
            ..RecognitionParams::default()
        };
        assert!(matches!(
            RecognitionModel::train(&[], &p, &bad),
            Err(RecognitionError::BadParams(_))
        ));
        assert_eq!(
            RecognitionModel::train(&[], &p, &RecognitionParams::default()),
            Err(RecognitionError::View(
                acch_pose::train::TrainError::NoViews
            ))
        );
        let view = LabelledView {
            rgb: &[0; 5],
            mask: &[0; 4],
            width: 2,
            height: 2,
            theta_deg: 90.0,
            phi_deg: 0.0,
            scale: 1.0,
            centre_px: None,
        };
        assert!(matches!(
            RecognitionModel::train(&[view], &p, &RecognitionParams::default()),
            Err(RecognitionError::View(
                acch_pose::train::TrainError::BadView { index: 0, .. }
            ))
        ));
        assert!(matches!(
            Detector::new(model(), 0, 10),
            Err(RecognitionError::EmptyFrame { .. })
        ));
    }
}
