//! The recognition model: what an object looks like to the window scan, and
//! its serialised form (a section of the view database).
//!
//! Section layout, little-endian:
//! ```text
//! magic     8 bytes  "ACCHREC\0"
//! version   u32      MODEL_VERSION
//! params    cell_px u16, pair_distance u16, pairs u16, same_colour_pairs u8,
//!           colour_weight f32, window_factor f32, min_visible f32,
//!           found_fraction f32, cell_threshold f32, pixel_threshold f32,
//!           smooth_radius u16, max_growth f32
//! colours   u16 C, then C x f32 (mean share of object pixels per colour)
//! peaks     (version 2) C x f32 largest share of a view's object pixels,
//!           then C x f32 largest pixel count of a view at the training
//!           scale, per colour
//! pairs     u16 K, then K x (u8 a, u8 b, f32 pairs per object pixel)
//! size_px   f32      median sqrt(mask area) at the training scale
//! scores    f32 median training score, f32 threshold
//! ```

use acch_core::{IndexImage, NOT_OBJECT, Palette};
use acch_pose::train::LabelledView;

use crate::Detector;

const MAGIC: &[u8; 8] = b"ACCHREC\0";
/// Version of the serialised model this build reads and writes.
pub const MODEL_VERSION: u32 = 2;
/// The older version this build still reads (no colour peaks).
const MODEL_VERSION_NO_PEAKS: u32 = 1;
/// Name of the view-database section that holds the model.
pub const SECTION: &str = "recognition";

/// Why a model could not be trained, read or used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RecognitionError {
    /// The training views are unusable (none with object pixels, or
    /// buffers that do not match their size).
    #[error(transparent)]
    View(#[from] acch_pose::train::TrainError),
    /// Parameters out of range.
    #[error("recognition parameters: {0}")]
    BadParams(String),
    /// The bytes are not a recognition model.
    #[error("not a recognition model (bad magic bytes)")]
    BadMagic,
    /// Written by another version.
    #[error(
        "recognition model version {found} is not supported (this build reads version {supported}); retrain the database"
    )]
    UnsupportedVersion {
        /// Version found.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The bytes end early or hold inconsistent values.
    #[error("corrupt recognition model: {0}")]
    Corrupt(String),
    /// The model was trained with another palette than the frame's.
    #[error("the model has {model} colours but the palette has {palette}")]
    PaletteMismatch {
        /// Colours in the model.
        model: usize,
        /// Colours in the palette.
        palette: usize,
    },
    /// A frame of zero size.
    #[error("frame size {width}x{height} is empty")]
    EmptyFrame {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
}

/// Tunable parameters of recognition and segmentation. The defaults were
/// chosen by measurement on the table-2 protocol (see the crate docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecognitionParams {
    /// Cell side in pixels.
    pub cell_px: u16,
    /// Pixel distance of the colour pairs (horizontal and vertical offsets).
    pub pair_distance: u16,
    /// Number K of the object's most frequent colour pairs that are counted.
    pub pairs: u16,
    /// Whether pairs of one colour with itself may be among the K.
    pub same_colour_pairs: bool,
    /// Weight of the colour vote against the pair vote, in [0, 1].
    pub colour_weight: f32,
    /// Window side relative to the object's apparent size (sqrt of its area).
    pub window_factor: f32,
    /// Least share of a window that must lie inside the frame.
    pub min_visible: f32,
    /// "Found" threshold as a share of the median training score.
    pub found_fraction: f32,
    /// Segmentation: least mean object likelihood of a cell to join the region.
    pub cell_threshold: f32,
    /// Segmentation: least smoothed object likelihood of a pixel.
    pub pixel_threshold: f32,
    /// Segmentation: radius of the box filter that smooths the likelihood.
    pub smooth_radius: u16,
    /// Segmentation: how far the region may grow beyond the window, as a
    /// share of the window side on each side.
    pub max_growth: f32,
}

impl Default for RecognitionParams {
    fn default() -> Self {
        RecognitionParams {
            cell_px: 8,
            pair_distance: 2,
            pairs: 32,
            same_colour_pairs: false,
            colour_weight: 0.5,
            window_factor: 1.0,
            min_visible: 0.5,
            found_fraction: 0.5,
            cell_threshold: 0.5,
            pixel_threshold: 0.5,
            smooth_radius: 2,
            max_growth: 0.5,
        }
    }
}

impl RecognitionParams {
    /// Checks ranges.
    pub fn validate(&self) -> Result<(), RecognitionError> {
        let bad = |s: String| Err(RecognitionError::BadParams(s));
        if !(2..=64).contains(&self.cell_px) {
            return bad(format!("cell_px {} is outside 2..=64", self.cell_px));
        }
        if !(1..=32).contains(&self.pair_distance) {
            return bad(format!(
                "pair_distance {} is outside 1..=32",
                self.pair_distance
            ));
        }
        if self.pairs > 254 {
            return bad(format!("pairs {} is more than 254", self.pairs));
        }
        let unit = |v: f32| v.is_finite() && (0.0..=1.0).contains(&v);
        for (name, v) in [
            ("colour_weight", self.colour_weight),
            ("min_visible", self.min_visible),
            ("found_fraction", self.found_fraction),
            ("cell_threshold", self.cell_threshold),
            ("pixel_threshold", self.pixel_threshold),
        ] {
            if !unit(v) {
                return bad(format!("{name} {v} is outside [0, 1]"));
            }
        }
        if !(self.window_factor.is_finite()
            && self.window_factor > 0.05
            && self.window_factor <= 4.0)
        {
            return bad(format!(
                "window_factor {} is outside (0.05, 4]",
                self.window_factor
            ));
        }
        if !(self.max_growth.is_finite() && (0.0..=4.0).contains(&self.max_growth)) {
            return bad(format!("max_growth {} is outside [0, 4]", self.max_growth));
        }
        if self.smooth_radius > 32 {
            return bad(format!(
                "smooth_radius {} is more than 32",
                self.smooth_radius
            ));
        }
        Ok(())
    }
}

/// What an object looks like to the window scan: the mean share of each
/// palette colour among its pixels, its K most frequent colour pairs at a
/// small distance, its apparent size and the score threshold for "found".
#[derive(Clone, Debug, PartialEq)]
pub struct RecognitionModel {
    /// Parameters the model was trained with.
    pub params: RecognitionParams,
    /// Mean share of object pixels per palette colour (length C).
    pub colour_freq: Vec<f32>,
    /// Per colour, the most any one training view holds of it: its largest
    /// share of a view's object pixels and its largest pixel count in a
    /// view at the training scale (`None` in models of version 1). A region
    /// holding more is partly something else.
    pub colour_peaks: Option<ColourPeaks>,
    /// The K colour pairs (a <= b) and their mean count per object pixel.
    pub pairs: Vec<(u8, u8, f32)>,
    /// Median apparent size (sqrt of mask area) at the training scale, px.
    pub size_px: f32,
    /// Median best-window score over the training views.
    pub train_score: f32,
    /// Least window score that counts as "found".
    pub threshold: f32,
}

/// The most of each palette colour one training view holds (see
/// [`RecognitionModel::colour_peaks`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ColourPeaks {
    /// Largest share of a view's object pixels, per colour.
    pub share: Vec<f32>,
    /// Largest pixel count in a view at the training scale, per colour.
    pub pixels: Vec<f32>,
}

impl RecognitionModel {
    /// Number of palette colours C.
    pub fn colours(&self) -> usize {
        self.colour_freq.len()
    }

    /// Trains a model from labelled views quantised with `palette` (the
    /// database palette). The threshold is `found_fraction` times the
    /// median score of the best window over the training views.
    pub fn train(
        views: &[LabelledView<'_>],
        palette: &Palette,
        params: &RecognitionParams,
    ) -> Result<Self, RecognitionError> {
        params.validate()?;
        let c = palette.len();
        let mut colour_sum = vec![0f64; c];
        let mut peaks = ColourPeaks {
            share: vec![0.0; c],
            pixels: vec![0.0; c],
        };
        let mut pair_sum = vec![0f64; 256 * 256];
        let mut sizes = Vec::with_capacity(views.len());
        let mut index = IndexImage::default();
        let mut used = Vec::with_capacity(views.len());
        let d = params.pair_distance as usize;
        for (i, v) in views.iter().enumerate() {
            v.check(i)?;
            let area = v.mask.iter().filter(|&&m| m != 0).count();
            if area == 0 {
                continue;
            }
            palette.quantise_into(v.rgb, v.width, v.height, &mut index);
            let (w, h) = (v.width as usize, v.height as usize);
            let mut colours = vec![0u32; c];
            let mut pairs = vec![0u32; 256 * 256];
            for y in 0..h {
                for x in 0..w {
                    let i = y * w + x;
                    if v.mask[i] == 0 {
                        continue;
                    }
                    let a = index.data[i];
                    if a == NOT_OBJECT {
                        continue;
                    }
                    colours[a as usize] += 1;
                    let mut pair = |j: usize| {
                        let b = index.data[j];
                        if v.mask[j] != 0 && b != NOT_OBJECT {
                            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
                            pairs[(lo as usize) << 8 | hi as usize] += 1;
                        }
                    };
                    if x + d < w {
                        pair(i + d);
                    }
                    if y + d < h {
                        pair(i + d * w);
                    }
                }
            }
            let inv = 1.0 / area as f64;
            for (s, &k) in colour_sum.iter_mut().zip(&colours) {
                *s += k as f64 * inv;
            }
            let at_training_scale = 1.0 / (v.scale * v.scale).max(f32::MIN_POSITIVE);
            for (k, &n) in colours.iter().enumerate() {
                peaks.share[k] = peaks.share[k].max((n as f64 * inv) as f32);
                peaks.pixels[k] = peaks.pixels[k].max(n as f32 * at_training_scale);
            }
            for (s, &k) in pair_sum.iter_mut().zip(&pairs) {
                *s += k as f64 * inv;
            }
            sizes.push((area as f32).sqrt() / v.scale);
            used.push(i);
        }
        if used.is_empty() {
            return Err(acch_pose::train::TrainError::NoViews.into());
        }
        let nv = used.len() as f64;
        let colour_freq: Vec<f32> = colour_sum.iter().map(|s| (s / nv) as f32).collect();
        let mut candidates: Vec<(u8, u8, f32)> = pair_sum
            .iter()
            .enumerate()
            .filter(|&(k, &s)| s > 0.0 && (params.same_colour_pairs || (k >> 8) != (k & 0xff)))
            .map(|(k, &s)| ((k >> 8) as u8, (k & 0xff) as u8, (s / nv) as f32))
            .collect();
        candidates.sort_by(|x, y| y.2.total_cmp(&x.2).then((x.0, x.1).cmp(&(y.0, y.1))));
        candidates.truncate(params.pairs as usize);
        sizes.sort_by(f32::total_cmp);
        let size_px = sizes[sizes.len() / 2];
        let mut model = RecognitionModel {
            params: *params,
            colour_freq,
            colour_peaks: Some(peaks),
            pairs: candidates,
            size_px,
            train_score: 0.0,
            threshold: 0.0,
        };
        // Score of the best window on each training view, at its scale.
        let first = &views[used[0]];
        let mut det = Detector::new(model.clone(), first.width, first.height)?;
        let mut scores = Vec::with_capacity(used.len());
        for &i in &used {
            let v = &views[i];
            palette.quantise_into(v.rgb, v.width, v.height, &mut index);
            det.detect(&index, Some(v.scale));
            scores.push(det.best_score());
        }
        scores.sort_by(f32::total_cmp);
        model.train_score = scores[scores.len() / 2];
        model.threshold = params.found_fraction * model.train_score;
        Ok(model)
    }

    /// Serialises the model (see the module docs for the layout).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(64 + self.colour_freq.len() * 4 + self.pairs.len() * 6);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&MODEL_VERSION.to_le_bytes());
        let p = &self.params;
        let u16s = |o: &mut Vec<u8>, v: u16| o.extend_from_slice(&v.to_le_bytes());
        let f32s = |o: &mut Vec<u8>, v: f32| o.extend_from_slice(&v.to_le_bytes());
        u16s(&mut out, p.cell_px);
        u16s(&mut out, p.pair_distance);
        u16s(&mut out, p.pairs);
        out.push(p.same_colour_pairs as u8);
        for v in [
            p.colour_weight,
            p.window_factor,
            p.min_visible,
            p.found_fraction,
            p.cell_threshold,
            p.pixel_threshold,
        ] {
            f32s(&mut out, v);
        }
        u16s(&mut out, p.smooth_radius);
        f32s(&mut out, p.max_growth);
        u16s(&mut out, self.colour_freq.len() as u16);
        for &f in &self.colour_freq {
            f32s(&mut out, f);
        }
        let none = ColourPeaks {
            share: vec![0.0; self.colour_freq.len()],
            pixels: vec![0.0; self.colour_freq.len()],
        };
        // A model without peaks is written with zero peaks, read back as
        // "no peaks" (a trained object holds some of its colours).
        let peaks = self.colour_peaks.as_ref().unwrap_or(&none);
        for &f in peaks.share.iter().chain(&peaks.pixels) {
            f32s(&mut out, f);
        }
        u16s(&mut out, self.pairs.len() as u16);
        for &(a, b, f) in &self.pairs {
            out.push(a);
            out.push(b);
            f32s(&mut out, f);
        }
        f32s(&mut out, self.size_px);
        f32s(&mut out, self.train_score);
        f32s(&mut out, self.threshold);
        out
    }

    /// Parses [`RecognitionModel::to_bytes`]; bad input is an error, never a
    /// panic.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, RecognitionError> {
        if bytes.len() < 8 || &bytes[..8] != MAGIC {
            return Err(RecognitionError::BadMagic);
        }
        let mut r = Reader { bytes, pos: 8 };
        let version = r.u32("the version")?;
        if version != MODEL_VERSION && version != MODEL_VERSION_NO_PEAKS {
            return Err(RecognitionError::UnsupportedVersion {
                found: version,
                supported: MODEL_VERSION,
            });
        }
        let params = RecognitionParams {
            cell_px: r.u16("cell_px")?,
            pair_distance: r.u16("pair_distance")?,
            pairs: r.u16("pairs")?,
            same_colour_pairs: r.u8("same_colour_pairs")? != 0,
            colour_weight: r.f32("colour_weight")?,
            window_factor: r.f32("window_factor")?,
            min_visible: r.f32("min_visible")?,
            found_fraction: r.f32("found_fraction")?,
            cell_threshold: r.f32("cell_threshold")?,
            pixel_threshold: r.f32("pixel_threshold")?,
            smooth_radius: r.u16("smooth_radius")?,
            max_growth: r.f32("max_growth")?,
        };
        params
            .validate()
            .map_err(|e| RecognitionError::Corrupt(e.to_string()))?;
        let c = r.u16("the colour count")? as usize;
        if c == 0 || c > NOT_OBJECT as usize {
            return Err(RecognitionError::Corrupt(format!("colour count {c}")));
        }
        let mut colour_freq = Vec::with_capacity(c);
        for _ in 0..c {
            colour_freq.push(r.nonneg("a colour share")?);
        }
        let mut colour_peaks = None;
        if version == MODEL_VERSION {
            let mut read = |what: &str| {
                (0..c)
                    .map(|_| r.nonneg(what))
                    .collect::<Result<Vec<_>, _>>()
            };
            let share = read("a colour's peak share")?;
            let pixels = read("a colour's peak pixel count")?;
            if share.iter().chain(&pixels).any(|&v| v > 0.0) {
                colour_peaks = Some(ColourPeaks { share, pixels });
            }
        }
        let k = r.u16("the pair count")? as usize;
        if k > params.pairs as usize {
            return Err(RecognitionError::Corrupt(format!(
                "{k} pairs, more than the {} the parameters allow",
                params.pairs
            )));
        }
        let mut pairs = Vec::with_capacity(k);
        for _ in 0..k {
            let a = r.u8("a pair colour")?;
            let b = r.u8("a pair colour")?;
            if a as usize >= c || b as usize >= c || a > b {
                return Err(RecognitionError::Corrupt(format!(
                    "pair ({a}, {b}) is invalid"
                )));
            }
            pairs.push((a, b, r.nonneg("a pair frequency")?));
        }
        let size_px = r.nonneg("size_px")?;
        if size_px < 1.0 {
            return Err(RecognitionError::Corrupt(format!(
                "size_px {size_px} is below 1"
            )));
        }
        let train_score = r.nonneg("the training score")?;
        let threshold = r.nonneg("the threshold")?;
        if r.pos != bytes.len() {
            return Err(RecognitionError::Corrupt(format!(
                "{} bytes after the model",
                bytes.len() - r.pos
            )));
        }
        Ok(RecognitionModel {
            params,
            colour_freq,
            colour_peaks,
            pairs,
            size_px,
            train_score,
            threshold,
        })
    }

    /// Reads the model from a view database's [`SECTION`]; `Ok(None)` when
    /// the database has none. Checks that it matches the palette.
    pub fn from_database(db: &acch_core::ViewDatabase) -> Result<Option<Self>, RecognitionError> {
        let Some(bytes) = db.sections.get(SECTION) else {
            return Ok(None);
        };
        let m = Self::from_bytes(bytes)?;
        if m.colours() != db.palette.len() {
            return Err(RecognitionError::PaletteMismatch {
                model: m.colours(),
                palette: db.palette.len(),
            });
        }
        Ok(Some(m))
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], RecognitionError> {
        if self.bytes.len() - self.pos < N {
            return Err(RecognitionError::Corrupt(format!("ends inside {what}")));
        }
        let mut out = [0u8; N];
        out.copy_from_slice(&self.bytes[self.pos..self.pos + N]);
        self.pos += N;
        Ok(out)
    }
    fn u8(&mut self, what: &str) -> Result<u8, RecognitionError> {
        Ok(self.take::<1>(what)?[0])
    }
    fn u16(&mut self, what: &str) -> Result<u16, RecognitionError> {
        Ok(u16::from_le_bytes(self.take(what)?))
    }
    fn u32(&mut self, what: &str) -> Result<u32, RecognitionError> {
        Ok(u32::from_le_bytes(self.take(what)?))
    }
    fn f32(&mut self, what: &str) -> Result<f32, RecognitionError> {
        Ok(f32::from_le_bytes(self.take(what)?))
    }
    fn nonneg(&mut self, what: &str) -> Result<f32, RecognitionError> {
        let v = self.f32(what)?;
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(RecognitionError::Corrupt(format!(
                "{what} {v} is not a finite non-negative number"
            )))
        }
    }
}
