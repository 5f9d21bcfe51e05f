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
use crate::bop::{self, ModelFrame};
use crate::protocol::{errors_fail, progress, rotation_error_deg};
use crate::train::{read_image, read_mask};
use acch_capture::labels::read_labels;
use acch_core::{IndexImage, ViewDatabase};
use acch_pipeline::stage::{StageCounters, step};
use acch_pipeline::stages::Segmented;
use acch_pipeline::wire::{Intrinsics, StageId};
use acch_pipeline::{Chain, FrameHeader, Stage, StageSettings};
use acch_pose::phi_error;
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
        })
        .collect())
}

/// The instances of object `obj_id` in `split` of the BOP dataset at
/// `dir`, whose model sits in the method's frame by `frame`.
pub fn from_bop(
    dir: &Path,
    split: &str,
    obj_id: u32,
    frame: &ModelFrame,
) -> Result<Vec<LabelledImage>, EvalError> {
    Ok(bop::read_instances(dir, split, obj_id)?
        .into_iter()
        .map(|i| {
            let v = bop::instance_view(&i.camera_from_model, frame);
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
            }
        })
        .collect())
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
        .views()
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v.theta_deg), hi.max(v.theta_deg))
        });
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
    for (seq, img) in images.iter().enumerate() {
        let rgb = read_image(&img.image)?.to_rgb8();
        let (w, h) = rgb.dimensions();
        if stages.as_ref().is_none_or(|s| s.size != (w, h)) {
            stages = Some(build((w, h))?);
        }
        let s = stages.as_mut().expect("built above");
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
                            &mut response,
                            0,
                            c_pose,
                        );
                        let rated = step(
                            &mut stages.confidence,
                            &posed,
                            &response,
                            &mut [],
                            0,
                            c_conf,
                        );
                        (posed.pose.done(), rated.rating)
                    }
                }
            }
        };
        let estimate = pose.map(|e| [e.theta_deg as f64, e.phi_deg as f64, e.roll_deg as f64]);
        let failure = estimate.is_none_or(|e| {
            errors_fail((
                (e[0] - img.theta_deg).abs(),
                phi_error(e[1] as f32, img.phi_deg as f32) as f64,
            ))
        });
        rows.push(ImageRow {
            name: img.name.clone(),
            truth_deg: [img.theta_deg, img.phi_deg, img.roll_deg],
            distance_m: img.distance_m,
            outside_theta_range: !(theta_min as f64 - 1e-6..=theta_max as f64 + 1e-6)
                .contains(&img.theta_deg),
            estimate_deg: estimate,
            failure,
            rotation_err_deg: estimate
                .map(|e| rotation_error_deg(e, [img.theta_deg, img.phi_deg, img.roll_deg])),
            accepted: rating.accepted(),
            confidence: rating.verdict().map(|v| v.confidence),
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
        images: rows,
    }
}
