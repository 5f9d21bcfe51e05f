//! Pose: the ACCH of the segmented region, matched against every view of
//! the database; the estimate is the best view, refined between grid
//! points.
//!
//! Its payload ([`ResponsePayload`]) is the match-value response, one f32
//! (native-endian) per database view in database order.

use super::BuildError;
use super::segmentation::{RegionPayload, Segmented};
use crate::config::StageSettings;
use crate::stage::Stage;
use crate::wire::{Envelope, Fault, Hop, Outcome, StageId};
use acch_core::{IndexImage, Rect, ViewDatabase};
use acch_ipc::ZeroCopySend;
use acch_pose::{PoseEstimator, Refinement};
use acch_shape::{Image, Proposal, Region, ShapeEstimate, ShapeEstimator, ShapeSettings};
use std::sync::Arc;

/// A 2-DOF pose estimate.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct PoseEstimate {
    /// Elevation θ, degrees.
    pub theta_deg: f32,
    /// Azimuth φ, degrees in [0, 360).
    pub phi_deg: f32,
    /// The best view's match value (histogram intersection), in [0, 1].
    pub best_value: f32,
    /// Apparent size relative to training the histogram was taken at.
    pub scale: f32,
    /// Index of the best view in the database.
    pub best_view: u32,
    /// The camera's roll about its optical axis, degrees (0 when the roll
    /// is not searched).
    pub roll_deg: f32,
    /// How much more of the region's coloured area a view 20-60° away in
    /// azimuth holds in place than the best view
    /// ([`PoseEstimator::map_rival`]); `-inf` when nothing was
    /// weighed (a database without colour maps), NaN when the region could
    /// not be placed.
    pub map_rival: f32,
    /// The pose the object's shape fitted to the image, which then decides
    /// θ, φ and the roll above; `Nothing` when the database holds no shape
    /// or the frame's pixels did not reach the stage.
    pub shape: Outcome<ShapeFit>,
}

/// The object's shape fitted to the image ([`acch_shape::ShapeEstimator`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct ShapeFit {
    /// Camera-from-object rotation, a unit quaternion (x, y, z, w); the
    /// object frame is the renderer's (z up, centred on the bounding box).
    pub rotation: [f32; 4],
    /// The object's centre in the camera frame, metres.
    pub translation_m: [f32; 3],
    /// How sharply the object's colours part from its surroundings across
    /// the fitted contour, in [-1, 1].
    pub separation: f32,
    /// The fitted silhouette against the region, intersection over union.
    pub overlap: f32,
    /// Share of the fitted contour on the region's edge.
    pub region_edge: f32,
    /// Share of the fitted contour on an image edge of its direction.
    pub contour_edges: f32,
    /// Share of the fitted contour in the frame (the measures above judge
    /// that part).
    pub in_frame: f32,
    /// What chose the fit among the candidates (separation plus overlap).
    pub score: f32,
    /// The best score of a candidate that would fail as an estimate of this
    /// one by more than a neighbour's span
    /// ([`acch_shape::ShapeSettings::rival_span`]), of those not below
    /// the lowest elevation the camera sees; -inf when none did.
    pub rival_score: f32,
    /// Candidates fitted.
    pub candidates: u32,
    /// 1: the colour histograms' view is the estimate (their colours
    /// matched the database well: [`COLOUR_ANCHORED_FROM`]) and the fit
    /// only placed it in 6-DOF; 0: the shape chose the view and its rules
    /// judge it.
    pub anchored: u32,
    /// θ, φ and roll the colour histograms estimated, degrees (NaN when
    /// they made none).
    pub colour_view_deg: [f32; 3],
    /// The pose's covariance from the fit and the spread of the poses
    /// blended into it ([`acch_shape::ShapeEstimate::covariance`]), over `(tx, ty, tz, rx, ry, rz)`
    /// of a left perturbation in the camera frame (metres, radians; the
    /// seed's convention, `acch_seeding`), upper triangle row by row.
    pub covariance: [f32; 21],
}

/// Pose's header. `pose`: `Nothing` when the region held no pair of object
/// colours.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Posed {
    /// Segmentation's header.
    pub segmented: Segmented,
    /// The estimate.
    pub pose: Outcome<PoseEstimate>,
}

impl Hop for Posed {
    fn envelope(&self) -> &Envelope {
        self.segmented.envelope()
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        self.segmented.envelope_mut()
    }
}

/// Pose's payload, read in place.
#[derive(Clone, Copy, Debug)]
pub struct ResponsePayload<'a> {
    bytes: &'a [u8],
}

impl<'a> ResponsePayload<'a> {
    /// Reads the response of `header` over a database of `views` views;
    /// `Ok(None)` when nothing was estimated.
    pub fn read(header: &Posed, views: usize, bytes: &'a [u8]) -> Result<Option<Self>, Fault> {
        if header.pose.done().is_none() {
            return Ok(None);
        }
        let bytes = bytes.get(..4 * views).ok_or(Fault::Response)?;
        Ok(Some(ResponsePayload { bytes }))
    }

    /// Views in the response.
    pub fn len(&self) -> usize {
        self.bytes.len() / 4
    }

    /// Whether it holds no view.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The match values, in view order.
    pub fn values(&self) -> impl Iterator<Item = f32> + 'a {
        self.bytes
            .chunks_exact(4)
            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// The match values into `out` (cleared first; no allocation once it
    /// has room).
    pub fn copy_into(&self, out: &mut Vec<f32>) {
        out.clear();
        out.extend(self.values());
    }
}

/// Writes `response` as pose's payload into `out`.
fn write_response(response: &[f32], out: &mut [u8]) -> Result<(), Fault> {
    let out = out.get_mut(..4 * response.len()).ok_or(Fault::Payload)?;
    for (dst, v) in out.chunks_exact_mut(4).zip(response) {
        dst.copy_from_slice(&v.to_ne_bytes());
    }
    Ok(())
}

/// The pose stage.
pub struct Pose {
    estimator: PoseEstimator,
    /// The object's shape, when the database holds one.
    shape: Option<ShapeEstimator>,
    /// The shape's last estimate, every candidate with its evidence.
    last_shape: Option<ShapeEstimate>,
    /// The camera direction of each database view.
    view_directions: Vec<glam::DVec3>,
    /// The ROI's palette indices (the estimator takes an owned image): a
    /// buffer sized for a whole frame, so copying a crop in never allocates.
    index: IndexImage,
    scale: Option<f32>,
    refinement: Refinement,
    refiner: acch_segmentation::ColourRefiner,
    /// The shape's last region was the refiner's.
    refined: bool,
    /// The database's colours are the camera's own
    /// ([`acch_core::FROM_PHOTOGRAPHS_SECTION`]): no region is refined.
    colours_from_photographs: bool,
}

/// A thread on `cpus` that shares the pose stage's work
/// ([`Pose::share_with`]): the shape's fits and the colours' matching with
/// every view, each independent of the others. On the 2-CPU bench machine
/// (docs/latency.md, "Now") the fits alone, shared, took the pose stage
/// in one process from 8.6-8.7 to 7.0-7.5 ms p50.
pub fn pose_helper(cpus: Vec<usize>) -> Result<Arc<rayon::ThreadPool>, BuildError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|_| "acch-pose-helper".to_owned())
        .start_handler(move |_| {
            if let Err(e) = acch_ipc::sched::pin_to(&cpus) {
                tracing::warn!("the pose stage's helper not pinned to CPUs {cpus:?}: {e}");
            }
        })
        .build()
        .map(Arc::new)
        .map_err(|e| BuildError::Threads(e.to_string()))
}

/// Every set's pose stage of `poses` sharing one [`pose_helper`] on
/// `cpus` (`PipelineConfig::pose_helper_cpus`); `None`: no helper.
pub fn share_with_helper(
    poses: &mut super::BySet<Pose>,
    cpus: Option<Vec<usize>>,
) -> Result<(), BuildError> {
    if let Some(cpus) = cpus {
        let helper = pose_helper(cpus)?;
        for pose in poses.each_mut() {
            pose.share_with(&helper);
        }
    }
    Ok(())
}

impl Pose {
    /// The stage for `db` on frames of `settings`.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let (w, h) = (settings.width, settings.height);
        let estimator = PoseEstimator::new(db.clone())?.with_roll_search(settings.roll_search_deg);
        if !estimator.has_view_maps() {
            tracing::warn!(
                "the database of '{}' records no colour maps of its views (trained before \
                 them): no estimate is weighed against where its region lies; train it again \
                 for that check",
                db.object
            );
        }
        let stored = if settings.verify_shape {
            acch_shape::stored(db)
        } else {
            Ok(None)
        };
        let shape = match stored {
            Ok(Some((model, symmetry))) => Some(ShapeEstimator::new(
                model,
                symmetry,
                ShapeSettings {
                    max_roll_deg: (settings.roll_search_deg as f64 + OFF_AXIS_ROLL_DEG).min(180.0),
                    overrule_margin: acch_confidence::MIN_SHAPE_MARGIN,
                    lowest_elevation_deg: acch_confidence::min_theta_deg(db) as f64,
                    ..ShapeSettings::default()
                },
            )),
            Ok(None) => None,
            Err(e) => return Err(BuildError::Shape(e)),
        };

        Ok(Pose {
            scale: settings.scale(db),
            estimator,
            shape,
            last_shape: None,
            view_directions: db
                .views()
                .iter()
                .map(|v| acch_shape::model::direction(v.theta_deg as f64, v.phi_deg as f64))
                .collect(),
            index: IndexImage::new(w, h, vec![0; w as usize * h as usize]),
            refinement: Refinement::Parabolic,
            refiner: Default::default(),
            refined: false,
            colours_from_photographs: db
                .sections
                .contains_key(acch_core::FROM_PHOTOGRAPHS_SECTION),
        })
    }

    /// Shares the shape's fits and the colours' matching with `helper`'s
    /// thread ([`pose_helper`]); the estimates stay the same bit for bit.
    pub fn share_with(&mut self, helper: &Arc<rayon::ThreadPool>) {
        self.estimator.share_matching_with(Arc::clone(helper));
        if let Some(shape) = &mut self.shape {
            shape.share_fits_with(Arc::clone(helper));
        }
    }

    /// The stage refining the best view by `refinement` instead (the
    /// evaluations compare winner takes all).
    pub fn with_refinement(mut self, refinement: Refinement) -> Self {
        self.refinement = refinement;
        self
    }

    /// The estimator (the database and the response of the last frame).
    pub fn estimator(&self) -> &PoseEstimator {
        &self.estimator
    }
}

impl Pose {
    /// The shape's last estimate, every candidate with its evidence (the
    /// evaluations read it).
    pub fn last_shape(&self) -> Option<&ShapeEstimate> {
        self.last_shape.as_ref()
    }

    /// The region the shape judged the last frame by, when it refined
    /// segmentation's by the frame's colours (the evaluations read it).
    pub fn refined_region(&self) -> Option<acch_segmentation::RegionMask<'_>> {
        self.refined.then(|| self.refiner.last()).flatten()
    }

    /// The shape's fit for `region` of the frame `frame` (packed RGB),
    /// with the colour estimate's view among its candidates.
    fn fit_shape(
        &mut self,
        input: &Segmented,
        region: &RegionPayload,
        frame: &[u8],
        colour: Option<&acch_pose::Estimate>,
    ) -> Outcome<ShapeFit> {
        self.last_shape = None;
        self.refined = false;
        let Some(shape) = &mut self.shape else {
            return Outcome::Nothing;
        };
        let f = &input.envelope().frame;
        let (w, h) = (f.width as usize, f.height as usize);
        if frame.len() != 3 * w * h {
            return Outcome::Nothing;
        }
        let i = &f.intrinsics;
        let k = acch_capture::Intrinsics {
            width: f.width,
            height: f.height,
            fx: i.fx,
            fy: i.fy,
            cx: i.cx,
            cy: i.cy,
        };
        if k.validate().is_err() {
            return Outcome::Nothing;
        }
        let image = Image {
            rgb: frame,
            width: w,
            height: h,
        };
        let mut given = acch_segmentation::RegionMask {
            mask: region.mask,
            roi: region.roi.into(),
        };
        // A region grown from recognition's window by colours that match
        // the database's only weakly (a mesh's colours under a real
        // camera) is part of the object: it is refined by the frame's own
        // colours (`acch_segmentation::refine`). Where they match well the
        // grown region is the object already (on rendered frames of the
        // fruitbox, can and generated-3000 the refinement changed nothing
        // and took 5-10 ms). A mask given from elsewhere (an annotation)
        // is taken as it is, and so is a region grown by colours learnt
        // from the camera's own photographs: those grow over the object
        // and beyond (LM-O, databases from the even images: the region
        // covers 0.85-0.94 of the object where it lies on it; refined,
        // more of it spilt off and 1-5 points more estimates failed).
        let grown = matches!(input.recognised.detection, Outcome::Done(_));
        let weak_colours = colour.is_none_or(|e| e.best_value < COLOUR_TRUSTED_AT);
        if grown
            && weak_colours
            && !self.colours_from_photographs
            && let Some(refined) = self.refiner.refine(frame, w, h, given)
        {
            given = refined;
            self.refined = true;
        }
        let roi = given.roi;
        let region = Region {
            mask: given.mask,
            x0: roi.x,
            y0: roi.y,
            width: roi.width,
            k: &k,
        };
        let proposed: Vec<[f64; 3]> = colour
            .map(|e| vec![[e.theta_deg as f64, e.phi_deg as f64, e.roll_deg as f64]])
            .unwrap_or_default();
        // The colour histograms' match of a view, over their best: what
        // tells apart views whose outlines are alike (a box's faces).
        let response = colour.map(|_| self.estimator.response());
        let best = response.map_or(0.0, |r| r.iter().copied().fold(0.0f32, f32::max));
        // Colours that barely match any view (a mesh's colours against a
        // real camera's) say little about which view it is.
        let trust = colour.map_or(0.0, |e| colour_trust(e.best_value));
        let directions = &self.view_directions;
        let colour_of = |theta: f64, phi: f64| -> f32 {
            let (Some(r), true) = (response, best > 0.0) else {
                return 0.0;
            };
            let d = acch_shape::model::direction(theta, phi);
            let mut nearest = (f64::NEG_INFINITY, 0);
            for (i, v) in directions.iter().enumerate() {
                let c = v.dot(d);
                if c > nearest.0 {
                    nearest = (c, i);
                }
            }
            COLOUR_WEIGHT * trust * r[nearest.1] / best
        };
        let colour_fn: Option<&(dyn Fn(f64, f64) -> f32 + Sync)> =
            response.map(|_| &colour_of as _);
        let proposal = Proposal {
            views: &proposed,
            // Trusted colours place the object: the shape verifies them.
            anchored: colour.is_some_and(|e| e.best_value >= COLOUR_ANCHORED_FROM),
            // Below full trust the shape may overrule them: LM-O's can
            // matched its mesh's colours at 0.65-0.8 in views half a turn
            // away; rendered printed packaging, at 0.84-0.96, keeps them.
            overrulable: colour.is_some_and(|e| e.best_value < COLOUR_TRUSTED_AT),
            colour: colour_fn,
        };
        let Some(s) = shape.estimate(&image, &k, &region, &proposal) else {
            return Outcome::Nothing;
        };
        let best = s.best();
        let radius_m = shape.model().radius_m;
        // The pose is the best's blended with its neighbours'; the
        // evidence acceptance judges is the best's own.
        let q = glam::DQuat::from_mat3(&s.pose.matrix3);
        let t = s.pose.translation * radius_m;
        let covariance = seed_covariance(&s.covariance, radius_m);
        let fit = ShapeFit {
            rotation: [q.x as f32, q.y as f32, q.z as f32, q.w as f32],
            translation_m: [t.x as f32, t.y as f32, t.z as f32],
            separation: best.evidence.separation,
            overlap: best.evidence.overlap,
            region_edge: best.evidence.region_edge,
            contour_edges: best.evidence.contour_edges,
            in_frame: best.evidence.in_frame,
            score: best.score,
            rival_score: s.rival_score(),
            candidates: s.scored.len() as u32,
            anchored: u32::from(s.anchored),
            covariance,
            colour_view_deg: colour.map_or([f32::NAN; 3], |e| [e.theta_deg, e.phi_deg, e.roll_deg]),
        };
        self.last_shape = Some(s);
        Outcome::Done(fit)
    }
}

/// A best match value (histogram intersection) below this says the
/// object's colours are not the database's (on LM-O's real photographs
/// against meshes' colours: 0.22-0.53, 10th to 90th percentile; rendered
/// printed packaging: 0.84-0.96): the views' colour matches then weigh
/// nothing among the shape's candidates...
pub const COLOUR_TRUSTED_FROM: f32 = 0.5;
/// ...and from this one they weigh fully.
pub const COLOUR_TRUSTED_AT: f32 = 0.8;

/// How far beyond the roll search the shape's silhouette search rolls,
/// degrees: an object off the optical axis looks a little rolled even to
/// an upright camera.
pub const OFF_AXIS_ROLL_DEG: f64 = 20.0;

/// From this best match value on, the colours place the object (its view
/// is the colour histograms' estimate, the shape fits it in 6-DOF), and
/// the colour rules judge it: the rendered protocols' objects, printed
/// packaging under the training light, match at 0.84-0.96; real
/// photographs of meshes' colours at 0.22-0.53.
pub const COLOUR_ANCHORED_FROM: f32 = 0.65;

/// The weight of a trusted colour match among the shape's measures (each
/// in [0, 1]): printed packaging's colours tell apart the faces of a box
/// whose outlines are alike, and there they decide.
pub const COLOUR_WEIGHT: f32 = 4.0;

/// How much the colour histograms' view matches count among the shape's
/// candidates, in [0, 1], by the best match value.
pub fn colour_trust(best_value: f32) -> f32 {
    ((best_value - COLOUR_TRUSTED_FROM) / (COLOUR_TRUSTED_AT - COLOUR_TRUSTED_FROM)).clamp(0.0, 1.0)
}

/// The fit's covariance over its twist `(w, v)` (`R' = exp(w) R`,
/// `t' = t + v`, object units) as the seed's over `(t, r)` in metres: the
/// same perturbation, reordered and scaled. Upper triangle, row by row.
pub fn seed_covariance(twist: &[[f64; 6]; 6], radius_m: f64) -> [f32; 21] {
    // A maps (w, v) to (dt, dr).
    let mut a = [[0.0f64; 6]; 6];
    for r in 0..3 {
        a[r][3 + r] = radius_m;
        a[3 + r][r] = 1.0;
    }
    let mut out = [0f32; 21];
    let mut i = 0;
    for r in 0..6 {
        for c in r..6 {
            let mut v = 0.0;
            for p in 0..6 {
                for q in 0..6 {
                    v += a[r][p] * twist[p][q] * a[c][q];
                }
            }
            out[i] = v as f32;
            i += 1;
        }
    }
    out
}

/// A fit's covariance as a full 6x6 matrix.
// Indices say which triangle entry lands where, in both halves.
#[allow(clippy::needless_range_loop)]
pub fn fit_covariance_matrix(fit: &ShapeFit) -> [[f64; 6]; 6] {
    let mut m = [[0.0; 6]; 6];
    let mut i = 0;
    for r in 0..6 {
        for c in r..6 {
            m[r][c] = fit.covariance[i] as f64;
            m[c][r] = m[r][c];
            i += 1;
        }
    }
    m
}

/// θ, φ and roll of a fitted pose, degrees.
pub fn fit_view(fit: &ShapeFit) -> [f32; 3] {
    let v = acch_shape::view_of(&fit_pose(fit));
    [v.theta_deg as f32, v.phi_deg as f32, v.roll_deg as f32]
}

/// A fitted pose as camera-from-object, metres.
pub fn fit_pose(fit: &ShapeFit) -> glam::DAffine3 {
    let [x, y, z, w] = fit.rotation.map(f64::from);
    glam::DAffine3::from_rotation_translation(
        glam::DQuat::from_xyzw(x, y, z, w).normalize(),
        glam::DVec3::from_array(fit.translation_m.map(f64::from)),
    )
}

/// The estimate of a region whose colours made none, from the shape alone.
fn shape_only(fit: ShapeFit) -> PoseEstimate {
    let [theta_deg, phi_deg, roll_deg] = fit_view(&fit);
    PoseEstimate {
        theta_deg,
        phi_deg,
        best_value: 0.0,
        scale: f32::NAN,
        best_view: 0,
        roll_deg,
        map_rival: f32::NAN,
        shape: Outcome::Done(fit),
    }
}

impl Stage for Pose {
    const ID: StageId = StageId::Pose;
    const READS_FRAME: bool = true;
    type Input = Segmented;
    type Part = Outcome<PoseEstimate>;
    type Output = Posed;

    fn max_payload(&self) -> usize {
        4 * self.estimator.database().views().len()
    }

    fn process(
        &mut self,
        input: &Segmented,
        payload: &[u8],
        frame: &[u8],
        out: &mut [u8],
    ) -> Result<Outcome<PoseEstimate>, Fault> {
        let Some(region) = RegionPayload::read(input, payload)? else {
            return Ok(Outcome::Skipped);
        };
        let roi = region.roi;
        self.index.width = roi.width;
        self.index.height = roi.height;
        self.index.data.clear();
        self.index.data.extend_from_slice(region.indices);
        let crop = Rect {
            x: 0,
            y: 0,
            width: roi.width,
            height: roi.height,
        };
        let colour = self.estimator.estimate(
            &self.index,
            Some(region.mask),
            crop,
            self.scale,
            self.refinement,
        );
        let shape = self.fit_shape(input, &region, frame, colour.as_ref());
        let Some(e) = colour else {
            return Ok(match shape {
                // The shape alone: no pair of the object's colours in the
                // region, so no response either.
                Outcome::Done(fit) => {
                    write_response(&vec![0.0; self.estimator.database().views().len()], out)?;
                    Outcome::Done(shape_only(fit))
                }
                _ => Outcome::Nothing,
            });
        };
        write_response(self.estimator.response(), out)?;
        let map_rival = self.estimator.map_rival(
            &self.index,
            Some(region.mask),
            crop,
            &e,
            acch_confidence::DEFAULT_MIN_PHI_SEPARATION_DEG,
        );
        let mut estimate = PoseEstimate {
            theta_deg: e.theta_deg,
            phi_deg: e.phi_deg,
            best_value: e.best_value,
            scale: e.scale,
            best_view: e.best_view as u32,
            roll_deg: e.roll_deg,
            map_rival,
            shape,
        };
        if let Outcome::Done(fit) = shape
            && fit.anchored == 0
        {
            // The shape decides the view (trusted colours placed it
            // themselves: the shape verified them).
            let v = fit_view(&fit);
            estimate.theta_deg = v[0];
            estimate.phi_deg = v[1];
            estimate.roll_deg = v[2];
        }
        Ok(Outcome::Done(estimate))
    }

    fn output(input: &Segmented, pose: Outcome<PoseEstimate>) -> Posed {
        Posed {
            segmented: *input,
            pose,
        }
    }
}
