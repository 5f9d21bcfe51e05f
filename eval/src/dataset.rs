//! Labelled photographs: the table-1 and table-2 figures of a dataset the
//! user brings (a BOP split, or a folder with our labels.csv) on the
//! deployed stages. With masks (`Segment::Mask`) the pose stage gets the
//! annotated visible part, as in table 1; with `Segment::Auto`
//! recognition and segmentation find the object, as in table 2. Either
//! way the confidence stage rates each estimate, so the report carries
//! both the failure rate before confidence and among the accepted.
//!
//! The scale comes from the segmented region: a photograph's distance is
//! what the camera does not know.

use crate::EvalError;
use crate::bop;
use crate::protocol::{errors_fail, progress, rotation_error_deg};
use acch_capture::labels::read_labels;
use acch_core::{IndexImage, ViewDatabase};
use acch_pipeline::stage::{StageCounters, step};
use acch_pipeline::stages::Segmented;
use acch_pipeline::wire::{Intrinsics, StageId};
use acch_pipeline::{Chain, FrameHeader, Stage, StageSettings};
use acch_pose::phi_error;
use acch_train::views::{read_image, read_mask};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One labelled image of the object.
#[derive(Clone, Debug)]
pub struct LabelledImage {
    /// What the report calls it (file, or BOP scene/image/instance).
    pub name: String,
    /// The image.
    pub image: PathBuf,
    /// The object's visible pixels, when annotated.
    pub mask: Option<PathBuf>,
    /// True elevation, degrees (negative: seen from below).
    pub theta_deg: f64,
    /// True azimuth, degrees.
    pub phi_deg: f64,
    /// True roll about the ray to the object, degrees.
    pub roll_deg: f64,
    /// True distance to the object's centre, metres.
    pub distance_m: f64,
    /// The camera, when the dataset says it.
    pub intrinsics: Option<acch_capture::Intrinsics>,
    /// θ, φ and roll of the poses that look the same by the object's
    /// symmetry (the annotated one left out): an estimate right for any
    /// of them is right.
    pub symmetric_views_deg: Vec<[f64; 3]>,
    /// The visible share of the object's silhouette, when known.
    pub visib_fract: Option<f64>,
    /// The object's pose in the camera (camera from object, metres, the
    /// object frame of [`acch_capture::Object`]) and those that look the
    /// same by its symmetry, when the dataset gives whole poses.
    pub pose_truths: Vec<glam::DAffine3>,
    /// BOP's scene id, image id and the instance's index in the image.
    pub bop_ids: Option<(u32, u32, usize)>,
}

impl LabelledImage {
    /// The annotated view and those that look the same, θ, φ, roll.
    pub fn truths_deg(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        std::iter::once([self.theta_deg, self.phi_deg, self.roll_deg])
            .chain(self.symmetric_views_deg.iter().copied())
    }

    /// The truth nearest to `estimate` by the whole rotation, θ, φ, roll.
    pub fn nearest_truth_deg(&self, estimate: [f64; 3]) -> [f64; 3] {
        self.truths_deg()
            .min_by(|a, b| {
                rotation_error_deg(estimate, *a).total_cmp(&rotation_error_deg(estimate, *b))
            })
            .expect("the annotated truth is always there")
    }
}

/// Where the object is taken from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Segment {
    /// The annotated mask (every image must have one).
    Mask,
    /// Recognition and segmentation.
    Auto,
}

/// Options of a dataset evaluation.
#[derive(Clone, Copy, Debug)]
pub struct DatasetOptions {
    /// Where the object is taken from.
    pub segment: Segment,
    /// The largest roll the pose stage searches, degrees (0: none); unset:
    /// what the database was trained with.
    pub roll_search_deg: Option<f32>,
    /// Lights recognition tries when the object is weak or lost
    /// ([`acch_pipeline::StageSettings::light_search`]).
    pub light_search: usize,
}

/// One image's outcome.
#[derive(Clone, Debug, Serialize)]
pub struct ImageRow {
    /// The image's name.
    pub name: String,
    /// True θ, φ, roll, degrees.
    pub truth_deg: [f64; 3],
    /// True distance, metres.
    pub distance_m: f64,
    /// Outside the database's θ range.
    pub outside_theta_range: bool,
    /// Estimated θ, φ, roll, degrees; `None`: not found.
    pub estimate_deg: Option<[f64; 3]>,
    /// The paper's failure rule (or no estimate).
    pub failure: bool,
    /// The angle between the estimated and the true camera rotation (θ, φ
    /// and roll together), degrees.
    pub rotation_err_deg: Option<f64>,
    /// The confidence stage accepted it.
    pub accepted: bool,
    /// The network's confidence, when rated.
    pub confidence: Option<f32>,
    /// The colour histograms' best match value.
    pub match_value: Option<f32>,
    /// The visible share of the object's silhouette, when known.
    pub visib_fract: Option<f64>,
    /// The object's shape fitted to the image, when the database holds one.
    pub shape: Option<ShapeRow>,
    /// Every candidate the shape fitted, best first.
    pub candidates: Vec<CandidateRow>,
    /// With automatic segmentation and an annotated mask: the share of
    /// the grown region on the object.
    pub region_on_object: Option<f64>,
    /// With automatic segmentation and an annotated mask: the share of
    /// the object's visible mask the grown region covers.
    pub region_covers_object: Option<f64>,
    /// The same two shares of the region the shape judged by, grown
    /// region refined by the frame's colours (on the object, covering it).
    pub refined_on_object: Option<(f64, f64)>,
    /// The score acch accepts by ([`acceptance_score`]), when rated.
    pub acceptance_score: Option<f32>,
    /// Of an accepted estimate with a 6-DOF pose, against the true pose
    /// (symmetries allowed for): the rotation's error, degrees...
    pub seed_rotation_err_deg: Option<f64>,
    /// ...the translation's, metres...
    pub seed_translation_err_m: Option<f64>,
    /// ...and the translation's over the true distance.
    pub seed_translation_err_rel: Option<f64>,
    /// Seconds the stages took on it.
    pub seconds: f64,
    /// BOP's scene id, image id and the instance's index in the image.
    pub bop_ids: Option<(u32, u32, usize)>,
}

/// The score acch accepts an estimate by: for one its shape chose
/// (verified 1), the smallest of its contour's share on the region's edge,
/// its overlap, its margin over its rival and (for a region recognition
/// found) its contour's share in the frame, each over its bar (0 for an
/// elevation more than 5° below the database's lowest view, or a fit
/// farther than the distance bar); else the network's confidence over
/// its threshold. Accepted means this is at least 1, and the object was
/// found at or above recognition's threshold (and, for the colour rules,
/// no rival, crest, misplacement or faint detection).
pub fn acceptance_score(v: &acch_pipeline::stages::Verdict) -> f32 {
    if v.verified == 1 {
        (v.region_edge / v.min_region_edge)
            .min(v.overlap / v.min_overlap)
            .min(v.shape_margin / v.min_shape_margin)
            .min(if v.detection_margin.is_finite() {
                v.in_frame / v.min_in_frame
            } else {
                f32::INFINITY
            })
            // Below the bar on elevation (the database's lowest view less
            // 5°) or beyond the one on distance: no score can accept it.
            .min(if v.shape_in_range() && v.shape_near() {
                f32::INFINITY
            } else {
                0.0
            })
    } else if v.confidence.is_finite() && v.threshold > 0.0 {
        v.confidence / v.threshold
    } else {
        0.0
    }
}

/// The figures of the instances whose visible share falls in a band.
#[derive(Clone, Debug, Serialize)]
pub struct BandRow {
    /// The band, "[lo, hi)" of the visible share.
    pub band: String,
    /// Instances.
    pub n: usize,
    /// Share failing the paper's rule before acceptance.
    pub failure_rate: f64,
    /// Share accepted.
    pub accepted_rate: f64,
    /// Share accepted and right.
    pub accepted_right_rate: f64,
    /// Share of the accepted that fail.
    pub acc_failure_rate: f64,
}

/// How close accepted 6-DOF seeds are to the true poses.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SeedErrors {
    /// Accepted estimates with a 6-DOF pose and a true pose.
    pub n: usize,
    /// Median rotation error, degrees.
    pub median_rotation_err_deg: Option<f64>,
    /// Median translation error, metres.
    pub median_translation_err_m: Option<f64>,
    /// Median translation error over the distance.
    pub median_translation_err_rel: Option<f64>,
    /// Share within 15° and 10 % of the distance.
    pub within_15deg_10pct: f64,
}

/// One candidate of the shape's estimate.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CandidateRow {
    /// θ, φ, roll of its fitted pose, degrees.
    pub view_deg: [f64; 3],
    /// Whether it is right by the paper's rule (symmetries allowed for).
    pub right: bool,
    /// The angle of its rotation from the truth's, degrees.
    pub rotation_err_deg: f64,
    /// What ranked it.
    pub score: f32,
    /// Share of its contour in the frame.
    pub in_frame: f32,
    /// What it explains of the image.
    pub separation: f32,
    /// Silhouette against region.
    pub overlap: f32,
    /// Contour on the region's edge.
    pub region_edge: f32,
    /// Contour on image edges.
    pub contour_edges: f32,
    /// Inner edges found.
    pub inner_edges: f32,
    /// Chromaticity correlation.
    pub colour: f32,
    /// The colour histograms' match of its view over their best.
    pub histograms: f32,
}

/// What the shape's fit said of one image.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ShapeRow {
    /// How sharply the colours part across the contour.
    pub separation: f32,
    /// The silhouette against the region.
    pub overlap: f32,
    /// What ranked the best candidate ([`acch_shape::rank_score`]).
    pub score: f32,
    /// The best score of a rival ([`acch_shape::ShapeEstimate::rival`]).
    pub rival_score: f32,
    /// θ, φ, roll of the colour histograms' estimate.
    pub colour_view_deg: [f32; 3],
    /// Camera-from-object rotation (x, y, z, w) and translation, metres.
    pub pose: [f32; 7],
}

/// A dataset's figures.
#[derive(Clone, Debug, Serialize)]
pub struct DatasetReport {
    /// "dataset".
    pub protocol: &'static str,
    /// Where the images came from ("bop DIR split", "labels DIR").
    pub source: String,
    /// The database's object.
    pub object: String,
    /// Where the object was taken from.
    pub segment: Segment,
    /// Images (instances).
    pub n: usize,
    /// Share of them whose true θ lies outside the database's range.
    pub outside_theta_range_rate: f64,
    /// Images with no estimate (not found, or no object colours).
    pub not_found: usize,
    /// Share failing the paper's rule, or not found, before confidence.
    pub failure_rate: f64,
    /// Mean |Δφ| over the estimates, degrees.
    pub mean_phi_err_deg: f64,
    /// Mean |Δθ| over the estimates, degrees.
    pub mean_theta_err_deg: f64,
    /// Mean |Δroll| over the estimates, degrees (the estimate is 0 without
    /// the roll search).
    pub mean_roll_err_deg: f64,
    /// Share of the images whose estimated camera rotation is within 10° of
    /// the truth (near θ = 90° the paper's φ rule fails a rolled view whose
    /// rotation is right: φ and roll turn the camera alike there).
    pub rotation_within_10deg: f64,
    /// Share of the images the confidence stage accepted.
    pub accepted_rate: f64,
    /// Share of the accepted that fail.
    pub acc_failure_rate: f64,
    /// Share of the accepted whose rotation is within 10°.
    pub acc_rotation_within_10deg: f64,
    /// Share of the images accepted and right by the paper's rule.
    pub accepted_right_rate: f64,
    /// The same figures by the visible share of the object (>= 0.7,
    /// 0.3-0.7, < 0.3), when the dataset knows it.
    pub bands: Vec<BandRow>,
    /// Accepted 6-DOF seeds against the true poses, when known.
    pub seeds: SeedErrors,
    /// Per image.
    pub images: Vec<ImageRow>,
}

impl DatasetReport {
    /// Prints the figures.
    pub fn print(&self) {
        println!(
            "{} · {} · {} images, segment {:?}, {:.1}% outside the database's θ range",
            self.source,
            self.object,
            self.n,
            self.segment,
            100.0 * self.outside_theta_range_rate
        );
        println!(
            "{:>9} {:>9} {:>9} {:>9} {:>9} {:>8} {:>9} {:>11} {:>12}",
            "E(phi)",
            "E(theta)",
            "E(roll)",
            "not found",
            "failures",
            "rot<=10",
            "accepted",
            "acc. fail.",
            "acc. rot<=10"
        );
        println!(
            "{:>8.2}° {:>8.2}° {:>8.2}° {:>9} {:>8.1}% {:>7.1}% {:>8.1}% {:>10.1}% {:>11.1}%",
            self.mean_phi_err_deg,
            self.mean_theta_err_deg,
            self.mean_roll_err_deg,
            self.not_found,
            100.0 * self.failure_rate,
            100.0 * self.rotation_within_10deg,
            100.0 * self.accepted_rate,
            100.0 * self.acc_failure_rate,
            100.0 * self.acc_rotation_within_10deg
        );
        println!(
            "accepted and right: {:.1}% of the images",
            100.0 * self.accepted_right_rate
        );
        if !self.bands.is_empty() {
            println!(
                "{:>12} {:>6} {:>9} {:>9} {:>14} {:>11}",
                "visible", "n", "failures", "accepted", "acc. and right", "acc. fail."
            );
            for b in &self.bands {
                println!(
                    "{:>12} {:>6} {:>8.1}% {:>8.1}% {:>13.1}% {:>10.1}%",
                    b.band,
                    b.n,
                    100.0 * b.failure_rate,
                    100.0 * b.accepted_rate,
                    100.0 * b.accepted_right_rate,
                    100.0 * b.acc_failure_rate
                );
            }
        }
        if self.seeds.n > 0 {
            println!(
                "accepted 6-DOF seeds: {}, median error {:.1}° and {:.1} mm ({:.1}% of the distance), {:.1}% within 15° and 10%",
                self.seeds.n,
                self.seeds.median_rotation_err_deg.unwrap_or(f64::NAN),
                1000.0 * self.seeds.median_translation_err_m.unwrap_or(f64::NAN),
                100.0 * self.seeds.median_translation_err_rel.unwrap_or(f64::NAN),
                100.0 * self.seeds.within_15deg_10pct
            );
        }
    }

    /// Writes every estimate of a BOP dataset's instances in the BOP
    /// challenge's results format (`scene_id,im_id,obj_id,score,R,t,time`;
    /// R row-major model to camera, t in millimetres, time in seconds), one
    /// row per estimate with a 6-DOF pose, accepted or not, scored by
    /// [`acceptance_score`]. `object` is the model the dataset's poses are
    /// of (millimetres).
    pub fn write_bop_results(
        &self,
        path: &Path,
        obj_id: u32,
        object: &acch_capture::Object,
    ) -> Result<(), EvalError> {
        use std::fmt::Write as _;
        let mut out = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
        let frame = object.file_frame();
        for r in &self.images {
            let (Some((scene, im, _)), Some(shape)) = (r.bop_ids, r.shape) else {
                continue;
            };
            let [qx, qy, qz, qw, tx, ty, tz] = shape.pose.map(f64::from);
            let rotation =
                glam::DMat3::from_quat(glam::DQuat::from_xyzw(qx, qy, qz, qw).normalize());
            let radii = glam::DVec3::new(tx, ty, tz) / object.radius_m();
            let m = frame.camera_from_file(&glam::DAffine3::from_mat3_translation(rotation, radii));
            let rows = m.matrix3.transpose().to_cols_array();
            let join = |v: &[f64]| {
                v.iter()
                    .map(|x| format!("{x:.6}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            let _ = writeln!(
                out,
                "{scene},{im},{obj_id},{:.6},{},{},{:.6}",
                r.acceptance_score.unwrap_or(0.0),
                join(&rows),
                join(&m.translation.to_array()),
                r.seconds
            );
        }
        std::fs::write(path, out).map_err(|source| EvalError::Io {
            path: path.to_owned(),
            source,
        })
    }

    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        crate::write_json(path, self)
    }
}

/// The images of a folder with our `labels.csv`.
pub fn from_labels(dir: &Path) -> Result<Vec<LabelledImage>, EvalError> {
    let rows = read_labels(dir.join("labels.csv"))?;
    Ok(rows
        .into_iter()
        .map(|r| LabelledImage {
            name: r.file.clone(),
            image: dir.join(&r.file),
            mask: r.mask.as_ref().map(|m| dir.join(m)),
            theta_deg: r.theta_deg,
            phi_deg: r.phi_deg,
            roll_deg: r.roll_deg,
            distance_m: r.distance_m,
            intrinsics: None,
            symmetric_views_deg: Vec::new(),
            visib_fract: None,
            pose_truths: Vec::new(),
            bop_ids: None,
        })
        .collect())
}

/// The instances of object `obj_id` in `split` of the BOP dataset at
/// `dir`, whose model `object` was loaded from (in millimetres) and which
/// looks the same by `symmetry`; what the dataset lacked is derived
/// (cached under `cache`) and said in the second value.
pub fn from_bop(
    dir: &Path,
    split: &str,
    obj_id: u32,
    object: &acch_capture::Object,
    symmetry: &acch_shape::Symmetry,
    cache: &Path,
) -> Result<(Vec<LabelledImage>, Vec<String>), EvalError> {
    let read = bop::read_instances(dir, split, obj_id, cache)?;
    let images = read
        .instances
        .into_iter()
        .map(|i| {
            let v = bop::instance_view(&i.camera_from_model, object);
            let symmetric_views_deg = symmetry
                .equivalents(&v.camera_from_object.matrix3)
                .skip(1)
                .map(|r| {
                    let pose =
                        glam::DAffine3::from_mat3_translation(r, v.camera_from_object.translation);
                    let s = bop::view_of_object(&pose, object);
                    [s.theta_deg, s.phi_deg, s.roll_deg]
                })
                .collect();
            let t_m = v.camera_from_object.translation * object.radius_m();
            let pose_truths = symmetry
                .equivalents(&v.camera_from_object.matrix3)
                .map(|r| glam::DAffine3::from_mat3_translation(r, t_m))
                .collect();
            LabelledImage {
                name: format!(
                    "scene {} image {} instance {}",
                    i.scene_id, i.im_id, i.gt_index
                ),
                image: i.rgb,
                mask: i.mask_visib,
                theta_deg: v.theta_deg,
                phi_deg: v.phi_deg,
                roll_deg: v.roll_deg,
                distance_m: v.distance_m,
                // The size is the image's, read with it.
                intrinsics: Some(bop::intrinsics_of(&i.camera, (0, 0))),
                symmetric_views_deg,
                visib_fract: i.visib_fract,
                pose_truths,
                bop_ids: Some((i.scene_id, i.im_id, i.gt_index)),
            }
        })
        .collect();
    Ok((images, read.derived))
}

/// Which of a BOP dataset's images a database is trained from
/// (`acch eval --bop --train-on`): the evaluation runs on the others.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageParity {
    /// Images with an even id.
    Even,
    /// Images with an odd id.
    Odd,
}

impl ImageParity {
    /// Whether `image` is one of these (an image without BOP ids is not).
    pub fn holds(self, image: &LabelledImage) -> bool {
        image
            .bop_ids
            .is_some_and(|(_, im_id, _)| (im_id % 2 == 0) == (self == ImageParity::Even))
    }

    /// `images` split into those to train on (these) and those to
    /// evaluate on (the rest), so that no evaluated image was trained on.
    pub fn split(self, images: Vec<LabelledImage>) -> (Vec<LabelledImage>, Vec<LabelledImage>) {
        images.into_iter().partition(|i| self.holds(i))
    }
}

/// A database trained from `images` themselves (photographs: the
/// histograms and recognition from their annotated masks and views) with
/// the shape of `object`, which looks the same by `symmetry`.
pub fn train_on_images(
    images: &[LabelledImage],
    object: &acch_capture::Object,
    symmetry: &acch_shape::Symmetry,
    config: &acch_pose::train::TrainConfig,
) -> Result<ViewDatabase, EvalError> {
    let bar = progress(images.len() as u64, "loading");
    let mut loaded = Vec::with_capacity(images.len());
    for img in images {
        let rgb = read_image(&img.image)?.to_rgb8();
        let Some(mask) = &img.mask else {
            return Err(EvalError::Input(format!(
                "{}: no mask to train from",
                img.name
            )));
        };
        let mask = read_mask(mask, rgb.dimensions())?;
        loaded.push((rgb, mask, img));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let views: Vec<acch_train::views::RealView> = loaded
        .iter()
        .map(|(rgb, mask, img)| acch_train::views::RealView {
            rgb,
            mask,
            view_deg: (img.theta_deg, img.phi_deg),
            roll_deg: img.roll_deg,
            distance_m: img.distance_m,
        })
        .collect();
    let mut db = acch_train::views::train_real_views(object.name(), &views, config)?;
    acch_train::views::add_shape(&mut db, object, symmetry);
    Ok(db)
}

/// The recipe of a database for a dataset's camera: training views from
/// the lowest elevation its annotations show (rounded down to 10°, at
/// least 0°: the renderer's camera stays above the table) up to 90°, at
/// the median distance of its instances (object radii of `object`), with
/// the roll searched as far as 95 % of its instances roll (rounded up to
/// 15°). BOP's own training images are rendered for its test scenes'
/// range of poses the same way.
pub fn dataset_recipe(
    images: &[LabelledImage],
    object: &acch_capture::Object,
) -> acch_train::cache::Recipe {
    let lowest = images
        .iter()
        .map(|i| i.theta_deg)
        .fold(90.0f64, f64::min)
        .max(0.0);
    let mut distances: Vec<f64> = images.iter().map(|i| i.distance_m).collect();
    distances.sort_by(f64::total_cmp);
    let median = distances.get(distances.len() / 2).copied();
    acch_train::cache::Recipe {
        roll_search_deg: acch_train::cache::roll_search_covering(images.iter().map(|i| i.roll_deg)),
        lowest_theta_deg: Some(((lowest / 10.0).floor() * 10.0) as u8),
        distance_radii: median.map(|d| ((d / object.radius_m()) * 10.0).round() / 10.0),
        ..Default::default()
    }
}

/// Of a frame-sized `region` (non-zero = in it) against the object's
/// frame-sized `truth` mask: the share of the region on the object, and
/// the share of the object the region covers.
fn shares(region: &[u8], truth: &[u8]) -> (f64, f64) {
    let (mut on, mut all, mut object) = (0usize, 0usize, 0usize);
    for (r, t) in region.iter().zip(truth) {
        object += usize::from(*t != 0);
        if *r != 0 {
            all += 1;
            on += usize::from(*t != 0);
        }
    }
    (
        on as f64 / all.max(1) as f64,
        on as f64 / object.max(1) as f64,
    )
}

/// The figures by visible share, when any instance's is known.
fn bands(rows: &[ImageRow]) -> Vec<BandRow> {
    if rows.iter().all(|r| r.visib_fract.is_none()) {
        return Vec::new();
    }
    let share = |k: usize, of: usize| k as f64 / of.max(1) as f64;
    [
        (0.7, 1.01, "[0.7, 1]"),
        (0.3, 0.7, "[0.3, 0.7)"),
        (0.0, 0.3, "[0, 0.3)"),
    ]
    .iter()
    .map(|&(lo, hi, name)| {
        let b: Vec<&ImageRow> = rows
            .iter()
            .filter(|r| r.visib_fract.is_some_and(|v| v >= lo && v < hi))
            .collect();
        let accepted = b.iter().filter(|r| r.accepted).count();
        let wrong = b.iter().filter(|r| r.accepted && r.failure).count();
        BandRow {
            band: name.to_owned(),
            n: b.len(),
            failure_rate: share(b.iter().filter(|r| r.failure).count(), b.len()),
            accepted_rate: share(accepted, b.len()),
            accepted_right_rate: share(accepted - wrong, b.len()),
            acc_failure_rate: share(wrong, accepted),
        }
    })
    .collect()
}

/// The accepted seeds' errors against the true poses.
fn seed_errors(rows: &[ImageRow]) -> SeedErrors {
    let with: Vec<&ImageRow> = rows
        .iter()
        .filter(|r| r.seed_rotation_err_deg.is_some())
        .collect();
    let median = |f: &dyn Fn(&ImageRow) -> Option<f64>| {
        let mut v: Vec<f64> = with.iter().filter_map(|r| f(r)).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        (n > 0).then(|| (v[(n - 1) / 2] + v[n / 2]) / 2.0)
    };
    SeedErrors {
        n: with.len(),
        median_rotation_err_deg: median(&|r| r.seed_rotation_err_deg),
        median_translation_err_m: median(&|r| r.seed_translation_err_m),
        median_translation_err_rel: median(&|r| r.seed_translation_err_rel),
        within_15deg_10pct: with
            .iter()
            .filter(|r| {
                r.seed_rotation_err_deg.is_some_and(|e| e <= 15.0)
                    && r.seed_translation_err_rel.is_some_and(|e| e <= 0.1)
            })
            .count() as f64
            / with.len().max(1) as f64,
    }
}

/// |a - b| of two rolls, wrapped, degrees.
fn roll_error(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// The stages for frames of one size.
struct Sized {
    size: (u32, u32),
    chain: Chain,
}

/// Evaluates `db` on `images`; `source` names them in the report.
pub fn evaluate(
    db: &ViewDatabase,
    images: &[LabelledImage],
    options: &DatasetOptions,
    source: &str,
) -> Result<DatasetReport, EvalError> {
    if images.is_empty() {
        return Err(EvalError::Input(format!("{source}: no images")));
    }
    if options.segment == Segment::Mask
        && let Some(i) = images.iter().find(|i| i.mask.is_none())
    {
        return Err(EvalError::Input(format!(
            "{source}: {} has no mask; evaluate with automatic segmentation instead",
            i.name
        )));
    }
    let (theta_min, theta_max) = db
        .theta_range_deg()
        .unwrap_or((f32::INFINITY, f32::NEG_INFINITY));
    let build = |size: (u32, u32)| -> Result<Sized, EvalError> {
        let settings = StageSettings {
            width: size.0,
            height: size.1,
            distance_m: None,
            unrated: true,
            roll_search_deg: options
                .roll_search_deg
                .unwrap_or_else(|| acch_pose::trained_roll_search_deg(db)),
            light_search: options.light_search,
            verify_shape: true,
        };
        Ok(Sized {
            size,
            chain: Chain::build(db, &settings)?,
        })
    };
    let mut stages: Option<Sized> = None;
    let mut counters = [
        StageCounters::new(StageId::Pose),
        StageCounters::new(StageId::Confidence),
    ];
    let mut index = IndexImage::default();
    let (mut region, mut response) = (Vec::new(), Vec::new());
    let mut rows = Vec::with_capacity(images.len());
    let bar = progress(images.len() as u64, "images");
    let mut frame_mask = Vec::new();
    for (seq, img) in images.iter().enumerate() {
        let (mut region_on_object, mut region_covers_object) = (None, None);
        let mut refined_on_object = None;
        let rgb = read_image(&img.image)?.to_rgb8();
        let (w, h) = rgb.dimensions();
        if stages.as_ref().is_none_or(|s| s.size != (w, h)) {
            stages = Some(build((w, h))?);
        }
        let s = stages.as_mut().expect("built above");
        let started = std::time::Instant::now();
        let k = match img.intrinsics {
            Some(k) => acch_capture::Intrinsics {
                width: w,
                height: h,
                ..k
            },
            None => acch_pipeline::source::sized_intrinsics(w, h),
        };
        let frame = FrameHeader::rgb(seq as u64, w, h, Intrinsics::from(&k));
        let (pose, rating) = match options.segment {
            Segment::Auto => {
                let out = s.chain.process(&frame, rgb.as_raw());
                // How much of the grown region lies on the object.
                if let (Some(region), Some(path)) = (s.chain.last_region(), &img.mask) {
                    let truth = read_mask(path, (w, h))?;
                    region.frame_mask(w, h, &mut frame_mask);
                    let (on, covers) = shares(&frame_mask, &truth);
                    (region_on_object, region_covers_object) = (Some(on), Some(covers));
                    let pose = s.chain.stages().pose.last_used();
                    if let Some(refined) = pose.refined_region() {
                        frame_mask.fill(0);
                        let r = refined.roi;
                        for (row, src) in refined.mask.chunks_exact(r.width as usize).enumerate() {
                            let at = (r.y as usize + row) * w as usize + r.x as usize;
                            frame_mask[at..at + src.len()].copy_from_slice(src);
                        }
                        refined_on_object = Some(shares(&frame_mask, &truth));
                    }
                }
                (out.pose().done(), *out.rating())
            }
            Segment::Mask => {
                let path = img.mask.as_ref().expect("checked above");
                let mask = read_mask(path, (w, h))?;
                db.palette.quantise_into(rgb.as_raw(), w, h, &mut index);
                region.resize(2 * w as usize * h as usize, 0);
                let given =
                    Segmented::from_mask(frame.envelope, &mask, &index.data, w, &mut region)
                        .map_err(|f| EvalError::Input(format!("{}: {f}", path.display())))?;
                match given {
                    None => (None, Default::default()),
                    Some(segmented) => {
                        // The chain's own pose and confidence stages, fed
                        // the annotated mask instead of segmentation's.
                        let stages = s.chain.stages_mut();
                        response.resize(stages.pose.max_payload(), 0);
                        let [c_pose, c_conf] = &mut counters;
                        let posed = step(
                            &mut stages.pose,
                            &segmented,
                            &region,
                            rgb.as_raw(),
                            &mut response,
                            0,
                            c_pose,
                        );
                        let rated = step(
                            &mut stages.confidence,
                            &posed,
                            &response,
                            &[],
                            &mut [],
                            0,
                            c_conf,
                        );
                        (posed.pose.done(), rated.rating)
                    }
                }
            }
        };
        let candidates: Vec<CandidateRow> = s
            .chain
            .stages()
            .pose
            .last_used()
            .last_shape()
            .map(|est| {
                est.scored
                    .iter()
                    .map(|c| {
                        let v = acch_shape::view_of(&c.pose);
                        let e = [v.theta_deg, v.phi_deg, v.roll_deg];
                        let t = img.nearest_truth_deg(e);
                        let right = img.truths_deg().any(|t| {
                            !errors_fail((
                                (e[0] - t[0]).abs(),
                                phi_error(e[1] as f32, t[1] as f32) as f64,
                            ))
                        });
                        CandidateRow {
                            view_deg: e,
                            right,
                            rotation_err_deg: rotation_error_deg(e, t),
                            score: c.score,
                            in_frame: c.evidence.in_frame,
                            separation: c.evidence.separation,
                            overlap: c.evidence.overlap,
                            region_edge: c.evidence.region_edge,
                            contour_edges: c.evidence.contour_edges,
                            inner_edges: c.evidence.inner_edges,
                            colour: c.evidence.colour,
                            histograms: c.evidence.histograms,
                        }
                    })
                    .collect()
            })
            .unwrap_or_default();
        let seconds = started.elapsed().as_secs_f64();
        // An accepted 6-DOF pose against the truths.
        let seed_err = pose
            .filter(|_| rating.accepted())
            .and_then(|e| e.shape.done())
            .filter(|_| !img.pose_truths.is_empty())
            .map(|f| {
                let est = acch_pipeline::stages::fit_pose(&f);
                let rot = img
                    .pose_truths
                    .iter()
                    .map(|t| acch_shape::rotation_angle_deg(&est.matrix3, &t.matrix3))
                    .fold(f64::INFINITY, f64::min);
                let t = img.pose_truths[0].translation;
                let err = (est.translation - t).length();
                (rot, err, err / t.length())
            });
        let estimate = pose.map(|e| [e.theta_deg as f64, e.phi_deg as f64, e.roll_deg as f64]);
        // Scored against the truth it is nearest to, by symmetry.
        let truth = estimate.map_or([img.theta_deg, img.phi_deg, img.roll_deg], |e| {
            img.nearest_truth_deg(e)
        });
        let failure = estimate.is_none_or(|e| {
            img.truths_deg().all(|t| {
                errors_fail((
                    (e[0] - t[0]).abs(),
                    phi_error(e[1] as f32, t[1] as f32) as f64,
                ))
            })
        });
        rows.push(ImageRow {
            name: img.name.clone(),
            truth_deg: truth,
            distance_m: img.distance_m,
            outside_theta_range: !(theta_min as f64 - 1e-6..=theta_max as f64 + 1e-6)
                .contains(&img.theta_deg),
            estimate_deg: estimate,
            failure,
            rotation_err_deg: estimate.map(|e| rotation_error_deg(e, truth)),
            visib_fract: img.visib_fract,
            shape: pose.and_then(|e| e.shape.done()).map(|f| ShapeRow {
                separation: f.separation,
                overlap: f.overlap,
                score: f.score,
                rival_score: f.rival_score,
                colour_view_deg: f.colour_view_deg,
                pose: [
                    f.rotation[0],
                    f.rotation[1],
                    f.rotation[2],
                    f.rotation[3],
                    f.translation_m[0],
                    f.translation_m[1],
                    f.translation_m[2],
                ],
            }),
            candidates,
            region_on_object,
            region_covers_object,
            refined_on_object,
            acceptance_score: rating.verdict().map(|v| acceptance_score(&v)),
            seed_rotation_err_deg: seed_err.map(|e| e.0),
            seed_translation_err_m: seed_err.map(|e| e.1),
            seed_translation_err_rel: seed_err.map(|e| e.2),
            seconds,
            bop_ids: img.bop_ids,
            accepted: rating.accepted(),
            confidence: rating.verdict().map(|v| v.confidence),
            match_value: pose.map(|e| e.best_value),
        });
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(summarise(db, rows, options.segment, source))
}

fn summarise(
    db: &ViewDatabase,
    rows: Vec<ImageRow>,
    segment: Segment,
    source: &str,
) -> DatasetReport {
    let n = rows.len();
    let estimated: Vec<&ImageRow> = rows.iter().filter(|r| r.estimate_deg.is_some()).collect();
    let mean = |f: &dyn Fn(&ImageRow, [f64; 3]) -> f64| {
        estimated
            .iter()
            .map(|r| f(r, r.estimate_deg.expect("filtered")))
            .sum::<f64>()
            / estimated.len().max(1) as f64
    };
    let accepted = rows.iter().filter(|r| r.accepted).count();
    let within_10 = |r: &&ImageRow| r.rotation_err_deg.is_some_and(|e| e <= 10.0);
    let share = |k: usize, of: usize| k as f64 / of.max(1) as f64;
    DatasetReport {
        protocol: "dataset",
        source: source.to_owned(),
        object: db.object.clone(),
        segment,
        n,
        outside_theta_range_rate: share(rows.iter().filter(|r| r.outside_theta_range).count(), n),
        not_found: n - estimated.len(),
        failure_rate: share(rows.iter().filter(|r| r.failure).count(), n),
        mean_phi_err_deg: mean(&|r, e| phi_error(e[1] as f32, r.truth_deg[1] as f32) as f64),
        mean_theta_err_deg: mean(&|r, e| (e[0] - r.truth_deg[0]).abs()),
        mean_roll_err_deg: mean(&|r, e| roll_error(e[2], r.truth_deg[2])),
        rotation_within_10deg: share(rows.iter().filter(|r| within_10(r)).count(), n),
        accepted_rate: share(accepted, n),
        acc_rotation_within_10deg: share(
            rows.iter().filter(|r| r.accepted && within_10(r)).count(),
            accepted,
        ),
        acc_failure_rate: share(
            rows.iter().filter(|r| r.accepted && r.failure).count(),
            accepted,
        ),
        accepted_right_rate: share(rows.iter().filter(|r| r.accepted && !r.failure).count(), n),
        bands: bands(&rows),
        seeds: seed_errors(&rows),
        images: rows,
    }
}
