//! Training: a palette from the object's pixels, then one histogram per
//! labelled view, in θ-slice order.

use acch_core::{
    ColourSpace, HistogramExtractor, HistogramParams, IndexImage, Palette, Rect, Smoothing, View,
    ViewDatabase,
};

/// How to train a database.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainConfig {
    /// Palette size C.
    pub colours: usize,
    /// Colour space of the palette.
    pub space: ColourSpace,
    /// Quantile of training-pixel distances that sets the "not object"
    /// threshold (see [`Palette::train`]); `None` keeps every colour.
    pub reject_quantile: Option<f32>,
    /// Histogram definition (its `colours` is overwritten by `colours`).
    pub params: HistogramParams,
    /// Seed of the k-means initialisation.
    pub seed: u64,
    /// How views and frames are smoothed before quantisation: the palette
    /// learns the smoothed colours and quantises smoothed frames.
    pub smoothing: Smoothing,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            colours: 40,
            space: ColourSpace::Lab,
            reject_quantile: Some(0.99),
            params: HistogramParams::default(),
            seed: 0,
            smoothing: Smoothing::Off,
        }
    }
}

/// One labelled training view: packed RGB, a mask (non-zero = object), and
/// its pose.
#[derive(Clone, Copy, Debug)]
pub struct LabelledView<'a> {
    /// `width * height * 3` bytes.
    pub rgb: &'a [u8],
    /// `width * height` bytes.
    pub mask: &'a [u8],
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Elevation, degrees.
    pub theta_deg: f32,
    /// Azimuth, degrees.
    pub phi_deg: f32,
    /// Apparent size relative to the training distance (distance ratio
    /// train / actual); 1 for views rendered at the training distance.
    pub scale: f32,
    /// Where the object centre projects, pixels, when known (a rendered
    /// view's ground truth): seeds aim at it rather than at the region's
    /// centre.
    pub centre_px: Option<[f32; 2]>,
}

impl<'a> LabelledView<'a> {
    /// A view of `size` (width, height) pixels seen from `view_deg` (θ, φ)
    /// at apparent `scale`.
    pub fn new(
        rgb: &'a [u8],
        mask: &'a [u8],
        (width, height): (u32, u32),
        (theta_deg, phi_deg): (f32, f32),
        scale: f32,
    ) -> Self {
        LabelledView {
            rgb,
            mask,
            width,
            height,
            theta_deg,
            phi_deg,
            scale,
            centre_px: None,
        }
    }

    /// The view with the object centre's projection at `centre_px`.
    pub fn with_centre(mut self, centre_px: [f32; 2]) -> Self {
        self.centre_px = Some(centre_px);
        self
    }

    /// Checks that view `index`'s buffers match its (non-empty) size;
    /// returns its pixel count.
    pub fn check(&self, index: usize) -> Result<usize, TrainError> {
        let n = self.width as usize * self.height as usize;
        if self.rgb.len() != n * 3 || self.mask.len() != n || n == 0 {
            return Err(TrainError::BadView {
                index,
                width: self.width,
                height: self.height,
            });
        }
        Ok(n)
    }
}

/// Why training failed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrainError {
    /// No views, or no object pixels in them.
    #[error("no training views with object pixels")]
    NoViews,
    /// A view's buffers do not match its size.
    #[error("training view {index}: buffer sizes do not match {width}x{height}")]
    BadView {
        /// Index of the view.
        index: usize,
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
    },
    /// The palette could not be trained.
    #[error(transparent)]
    Palette(#[from] acch_core::PaletteError),
    /// Invalid histogram parameters.
    #[error(transparent)]
    Params(#[from] acch_core::histogram::HistogramError),
    /// The labelled views do not make the database's views (not the views
    /// it was trained on).
    #[error("the labelled views make {maps} colour maps for a database of {views} views")]
    ViewsMoved {
        /// Views of the database.
        views: usize,
        /// Maps the labelled views made.
        maps: usize,
    },
}

/// Bounding box of the non-zero bytes of a mask, or `None` when it is empty.
pub fn mask_bbox(mask: &[u8], width: u32, height: u32) -> Option<Rect> {
    let w = width as usize;
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for (y, row) in mask.chunks_exact(w).enumerate().take(height as usize) {
        if let Some(first) = row.iter().position(|&b| b != 0) {
            let last = w - 1 - row.iter().rev().position(|&b| b != 0).unwrap_or(0);
            x0 = x0.min(first);
            x1 = x1.max(last);
            y0 = y0.min(y);
            y1 = y;
        }
    }
    (x0 != usize::MAX).then(|| Rect {
        x: x0 as u32,
        y: y0 as u32,
        width: (x1 - x0 + 1) as u32,
        height: (y1 - y0 + 1) as u32,
    })
}

/// Trains a database from labelled views. Views are stored sorted by
/// (θ, φ), so the response reads θ-slice by θ-slice; views of one (θ, φ)
/// (the same pose under several lights, say) make one view, the mean of
/// their histograms, sizes and offsets.
pub fn build_database(
    object: &str,
    train_distance_m: f32,
    views: &[LabelledView<'_>],
    config: &TrainConfig,
) -> Result<ViewDatabase, TrainError> {
    for (index, v) in views.iter().enumerate() {
        v.check(index)?;
    }
    // Palette pixels: a regular subsample of every view's object pixels, so
    // each view contributes in proportion to its area.
    let total: usize = views
        .iter()
        .map(|v| v.mask.iter().filter(|&&m| m != 0).count())
        .sum();
    if total == 0 {
        return Err(TrainError::NoViews);
    }
    let step = (total / 200_000).max(1);
    let mut pixels = Vec::with_capacity(total / step + 1);
    let mut k = 0usize;
    let (mut rows, mut smoothed) = (Vec::new(), Vec::new());
    for v in views {
        // The colours frames will be quantised as.
        let rgb = match config.smoothing {
            Smoothing::Off => v.rgb,
            Smoothing::Binomial => {
                let (w, h) = (v.width as usize, v.height as usize);
                acch_core::smooth::binomial_into(v.rgb, w, h, &mut rows, &mut smoothed);
                &smoothed[..]
            }
        };
        for (i, _) in v.mask.iter().enumerate().filter(|(_, m)| **m != 0) {
            if k.is_multiple_of(step) {
                pixels.push([rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]]);
            }
            k += 1;
        }
    }
    let palette = Palette::train(
        &pixels,
        config.colours,
        config.space,
        config.reject_quantile,
        config.seed,
    )?
    .with_smoothing(config.smoothing);
    let params = HistogramParams {
        colours: config.colours as u16,
        ..config.params
    };
    let mut extractor = HistogramExtractor::new(params)?;
    let mut db = ViewDatabase::new(object, palette, params, train_distance_m);
    let mut index = IndexImage::default();
    let mut hist = vec![0.0; params.len()];
    let rate_at_training = extractor.pair_rate(1.0);
    let mut view_pairs = Vec::with_capacity(views.len());
    let mut mean = vec![0.0; params.len()];
    let per_view = config.colours * acch_core::LAYOUT_FIELDS;
    let (mut layout, mut layout_sum) = (vec![0.0; per_view], vec![0.0; per_view]);
    let mut layouts = Vec::with_capacity(views.len() * per_view);
    let pose = |i: usize| (views[i].theta_deg, views[i].phi_deg.rem_euclid(360.0));
    for group in pose_groups(views) {
        mean.fill(0.0);
        layout_sum.fill(0.0);
        let (mut n, mut size_px, mut offset, mut pairs) = (0usize, 0.0f32, [0.0f32; 2], 0.0f32);
        for &i in &group {
            let v = &views[i];
            let Some(roi) = mask_bbox(v.mask, v.width, v.height) else {
                continue;
            };
            db.palette
                .quantise_into(v.rgb, v.width, v.height, &mut index);
            let found = extractor.extract(&index, Some(v.mask), roi, v.scale, &mut hist);
            mean.iter_mut().zip(&hist).for_each(|(m, h)| *m += h);
            // Layouts at the training scale; a colour's offsets averaged
            // over the views it shows in, by its share.
            acch_core::layout_into(&index, Some(v.mask), roi, &mut layout);
            acch_core::scale_layout(&mut layout, 1.0 / v.scale);
            for (s, l) in layout_sum
                .chunks_exact_mut(acch_core::LAYOUT_FIELDS)
                .zip(layout.chunks_exact(acch_core::LAYOUT_FIELDS))
            {
                s[0] += l[0];
                s[1] += l[0] * l[1];
                s[2] += l[0] * l[2];
            }
            // Kept at the training scale, as the sizes.
            pairs += found as f32 * rate_at_training / extractor.pair_rate(v.scale);
            let area = v.mask.iter().filter(|&&m| m != 0).count() as f32;
            // Sizes and offsets are kept at the training scale.
            size_px += area.sqrt() / v.scale;
            if let Some(c) = v.centre_px {
                let (x, y) = roi.centre();
                offset[0] += (c[0] - x) / v.scale;
                offset[1] += (c[1] - y) / v.scale;
            }
            n += 1;
        }
        if n == 0 {
            continue;
        }
        let k = n as f32;
        if n > 1 {
            mean.iter_mut().for_each(|m| *m /= k);
        }
        let (theta_deg, phi_deg) = pose(group[0]);
        db.push_view(
            View {
                theta_deg,
                phi_deg,
                size_px: size_px / k,
                centre_offset_px: [offset[0] / k, offset[1] / k],
            },
            &mean,
        );
        view_pairs.push(pairs / k);
        for s in layout_sum.chunks_exact(acch_core::LAYOUT_FIELDS) {
            let w = s[0];
            let (x, y) = if w > 0.0 {
                (s[1] / w, s[2] / w)
            } else {
                (0.0, 0.0)
            };
            layouts.extend([w / k, x, y]);
        }
    }
    if db.views().is_empty() {
        return Err(TrainError::NoViews);
    }
    crate::store_view_pairs(&mut db, &view_pairs);
    crate::store_view_layouts(&mut db, &layouts);
    let maps = crate::colour_map::measure_view_maps(&db, views)?;
    crate::colour_map::store_view_maps(&mut db, &maps);
    Ok(db)
}

/// The indices of `views` grouped by pose (θ, then φ in [0, 360)), in the
/// order the database stores its views: a group makes one view.
pub(crate) fn pose_groups(views: &[LabelledView<'_>]) -> Vec<Vec<usize>> {
    let pose = |i: usize| (views[i].theta_deg, views[i].phi_deg.rem_euclid(360.0));
    let mut order: Vec<usize> = (0..views.len()).collect();
    order.sort_by(|&a, &b| {
        pose(a)
            .partial_cmp(&pose(b))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    order
        .chunk_by(|&a, &b| pose(a) == pose(b))
        .map(<[usize]>::to_vec)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 x 64 view of stripes whose colours depend on `salt`.
    fn striped(salt: u8) -> Vec<u8> {
        (0..64 * 64)
            .flat_map(|i| {
                let (x, y) = (i % 64, i / 64);
                let band = ((x / 8 + y / 16) % 4) as u8;
                [
                    band * 60 + salt,
                    255 - band * 50,
                    (band * 90).wrapping_add(salt),
                ]
            })
            .collect()
    }

    #[test]
    fn views_of_one_pose_make_one_view_the_mean_of_theirs() {
        let (a, b) = (striped(0), striped(40));
        let mask = vec![255u8; 64 * 64];
        let config = TrainConfig {
            colours: 8,
            ..TrainConfig::default()
        };
        let view = |rgb, phi| LabelledView::new(rgb, &mask, (64, 64), (45.0, phi), 1.0);
        // The same pixels either way, so the same palette.
        let apart = build_database("o", 1.0, &[view(&a, 0.0), view(&b, 10.0)], &config).unwrap();
        let one = build_database("o", 1.0, &[view(&a, 0.0), view(&b, 0.0)], &config).unwrap();
        assert_eq!(apart.palette, one.palette);
        assert_eq!((apart.views().len(), one.views().len()), (2, 1));
        let (ha, hb) = (apart.histogram(0), apart.histogram(1));
        assert!(ha != hb, "the two lights give different histograms");
        for ((m, x), y) in one.histogram(0).iter().zip(ha).zip(hb) {
            assert!(
                (m - (x + y) / 2.0).abs() <= 1e-6 * (x + y).max(1.0),
                "{m} {x} {y}"
            );
        }
        let size = |db: &ViewDatabase, i: usize| db.views()[i].size_px;
        assert!((size(&one, 0) - (size(&apart, 0) + size(&apart, 1)) / 2.0).abs() < 1e-4);
    }

    #[test]
    fn bbox_of_mask() {
        let mut m = vec![0u8; 5 * 4];
        assert_eq!(mask_bbox(&m, 5, 4), None);
        m[5 + 1] = 1;
        m[2 * 5 + 3] = 255;
        assert_eq!(
            mask_bbox(&m, 5, 4),
            Some(Rect {
                x: 1,
                y: 1,
                width: 3,
                height: 2
            })
        );
    }
}
