//! Seeding: an accepted 2-DOF estimate, the ROI's centre, the intrinsics
//! and the distance make an SE(3) seed with a covariance for the 6-DOF
//! tracker; the seeds are fused over the arm's known motion into a pose
//! that outlives rejected frames ([`acch_seeding::fusion`]).

use super::BuildError;
use super::confidence::{Rated, Rating};
use crate::config::StageSettings;
use crate::stage::Stage;
use crate::wire::{Envelope, Fault, Hop, Maybe, Outcome, StageId};
use acch_core::ViewDatabase;
use acch_ipc::ZeroCopySend;
use acch_seeding::{
    CovarianceModel, Distance, FilterConfig, GridSpacing, Measurement, Pinhole, SeedInput,
    ViewFilter, theta_censored,
};
use glam::{DAffine3, DMat3, DVec2};

/// The training views' centre offsets (where the object centre projects
/// relative to the centre of the silhouette's box, pixels at the training
/// scale), by θ slice and φ, interpolated between views: the offset moves
/// fast near the top (a can seen from 80° shows a band of its side under
/// its lid, one from 90° none), so the nearest view alone is off by the
/// whole band.
struct CentreOffsets {
    /// θ slices in ascending order, each with its views by ascending φ.
    slices: Vec<(f32, Vec<PhiOffset>)>,
}

/// A view's φ, degrees, and its centre offset, pixels.
type PhiOffset = (f32, [f32; 2]);

impl CentreOffsets {
    fn new(db: &ViewDatabase) -> Self {
        let mut slices: Vec<(f32, Vec<PhiOffset>)> = Vec::new();
        for v in db.views() {
            let view = (v.phi_deg.rem_euclid(360.0), v.centre_offset_px);
            match slices
                .iter_mut()
                .find(|(t, _)| (*t - v.theta_deg).abs() < 1e-3)
            {
                Some((_, views)) => views.push(view),
                None => slices.push((v.theta_deg, vec![view])),
            }
        }
        slices.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (_, views) in &mut slices {
            views.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        CentreOffsets { slices }
    }

    /// The offset of view (θ, φ): linear in φ within the two slices around
    /// θ, then linear in θ between them (clamped at the outer slices).
    fn at(&self, theta_deg: f32, phi_deg: f32) -> [f32; 2] {
        let Some(last) = self.slices.len().checked_sub(1) else {
            return [0.0; 2];
        };
        let above = self
            .slices
            .partition_point(|(t, _)| *t < theta_deg)
            .min(last);
        let below = above.saturating_sub(1);
        let (ta, tb) = (self.slices[below].0, self.slices[above].0);
        let w = if tb > ta {
            ((theta_deg - ta) / (tb - ta)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let (a, b) = (
            Self::along(&self.slices[below].1, phi_deg),
            Self::along(&self.slices[above].1, phi_deg),
        );
        [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])]
    }

    /// Linear in φ between the two views of a slice around it (wrapping at
    /// 360°).
    fn along(views: &[PhiOffset], phi_deg: f32) -> [f32; 2] {
        let n = views.len();
        if n == 0 {
            return [0.0; 2];
        }
        let phi = phi_deg.rem_euclid(360.0);
        let next = views.partition_point(|(p, _)| *p <= phi) % n;
        let prev = (next + n - 1) % n;
        let (p0, o0) = views[prev];
        let (p1, o1) = views[next];
        let span = (p1 - p0).rem_euclid(360.0);
        let w = if span > 0.0 {
            ((phi - p0).rem_euclid(360.0) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        [o0[0] + w * (o1[0] - o0[0]), o0[1] + w * (o1[1] - o0[1])]
    }
}

/// Relative standard deviation of a known distance handed to the seed (the
/// arm's kinematics).
pub const KNOWN_DISTANCE_RELATIVE_SIGMA: f64 = 0.02;
/// Relative standard deviation of a distance read off the ROI's scale.
pub const SCALE_DISTANCE_RELATIVE_SIGMA: f64 = 0.1;

/// A 6-DOF seed: the object's pose in the camera's optical frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct SeedPose {
    /// Object centre in the camera frame, metres.
    pub translation: [f64; 3],
    /// camera_from_object rotation, quaternion x, y, z, w.
    pub rotation_xyzw: [f64; 4],
    /// Row-major 6x6 covariance over (tx, ty, tz, rx, ry, rz): left
    /// perturbation in the camera frame, rotation in radians.
    pub covariance: [[f64; 6]; 6],
}

/// What a frame's estimate did to the fused pose.
#[repr(u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Fusion {
    /// Nothing: no accepted estimate this frame.
    #[default]
    None = 0,
    /// It started the filter.
    Started = 1,
    /// It was fused.
    Fused = 2,
    /// The gate rejected it as an outlier.
    Gated = 3,
    /// It and the outliers before it agreed: the filter restarted from them.
    Restarted = 4,
}

// SAFETY: a fieldless repr(u32) enum: four bytes, no pointers.
unsafe impl ZeroCopySend for Fusion {}

impl Fusion {
    /// Its name in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Fusion::None => "none",
            Fusion::Started => "started",
            Fusion::Fused => "fused",
            Fusion::Gated => "gated",
            Fusion::Restarted => "restarted",
        }
    }
}

/// The pose fused over the frames so far, carried through the arm's motion.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct FusedPose {
    /// Fused θ, φ, degrees.
    pub view_deg: [f64; 2],
    /// Row-major 2x2 covariance of (θ, φ), degrees².
    pub view_covariance_deg2: [f64; 4],
    /// Fused `camera_from_object`, column-major 3x4.
    pub camera_from_object: [f64; 12],
    /// Row-major 3x3 rotation covariance, radians² (camera frame).
    pub rotation_covariance: [f64; 9],
    /// Row-major 3x3 translation covariance, m² (camera frame): the
    /// translation is the last fused seed's, carried through the motion,
    /// and so is its covariance.
    pub translation_covariance: [f64; 9],
    /// Estimates fused since the filter (re)started.
    pub fused: u32,
    /// Frames predicted since the last fused estimate.
    pub since_update: u32,
}

/// Seeding's part: the seed of this frame and the fused pose after it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct SeedingPart {
    /// `Done` when the estimate was accepted and seeded; `Nothing` when it
    /// was not accepted.
    pub seed: Outcome<SeedPose>,
    /// What this frame's estimate did to the fused pose.
    pub fusion: Fusion,
    /// The fused pose, once the filter holds one.
    pub fused: Maybe<FusedPose>,
}

impl From<Fault> for SeedingPart {
    fn from(f: Fault) -> Self {
        SeedingPart {
            seed: Outcome::Failed(f),
            ..Default::default()
        }
    }
}

/// Seeding's header: the final result of a frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Seeded {
    /// Confidence's header.
    pub rated: Rated,
    /// The seed and the fused pose.
    pub seeding: SeedingPart,
}

impl Hop for Seeded {
    fn envelope(&self) -> &Envelope {
        self.rated.envelope()
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        self.rated.envelope_mut()
    }
}

impl Seeded {
    /// Recognition's window.
    pub fn detection(&self) -> &Outcome<super::Window> {
        &self.rated.posed.segmented.recognised.detection
    }

    /// Segmentation's region.
    pub fn region(&self) -> &Outcome<crate::wire::PixelRect> {
        &self.rated.posed.segmented.region
    }

    /// Pose's estimate.
    pub fn pose(&self) -> &Outcome<super::PoseEstimate> {
        &self.rated.posed.pose
    }

    /// Confidence's verdict.
    pub fn rating(&self) -> &Rating {
        &self.rated.rating
    }

    /// The seed, when the estimate was accepted.
    pub fn seed(&self) -> Option<SeedPose> {
        self.seeding.seed.done()
    }

    /// Whether the frame's estimate was accepted and seeded: what a robot
    /// acts on.
    pub fn accepted(&self) -> bool {
        self.rating().accepted() && self.seed().is_some()
    }
}

/// The seeding stage (the filter's state lives here).
pub struct Seeding {
    grid: GridSpacing,
    /// Metres.
    train_distance_m: f64,
    /// The known distance, metres.
    distance_m: Option<f64>,
    covariance: CovarianceModel,
    filter: ViewFilter,
    /// The database's lowest θ slice: an estimate there may stand for any
    /// view below it, so it fuses φ only.
    lowest_theta_deg: f64,
    /// The arm's camera pose at the last frame, to predict by the motion
    /// since (absolute poses, so frames dropped upstream cost nothing).
    last_arm: Option<DAffine3>,
    /// Where the object centre projects relative to the centre of its
    /// silhouette's box, per training view.
    centre_offsets: CentreOffsets,
    /// The translation covariance of the last fused seed, carried through
    /// the motion since.
    translation_covariance: DMat3,
}

impl Seeding {
    /// The stage for `db` with `settings`.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let grid = acch_seeding::grid_spacing(
            db.views()
                .iter()
                .map(|v| (v.theta_deg as f64, v.phi_deg as f64)),
        );
        Ok(Seeding {
            grid,
            train_distance_m: db.train_distance_m as f64,
            distance_m: settings.distance_m,
            covariance: CovarianceModel::default(),
            filter: ViewFilter::new(FilterConfig::default())?,
            lowest_theta_deg: db
                .theta_range_deg()
                .map_or(f64::INFINITY, |(lowest, _)| lowest as f64),
            last_arm: None,
            centre_offsets: CentreOffsets::new(db),
            translation_covariance: DMat3::ZERO,
        })
    }

    /// Forgets the fused pose and the arm's last pose: the next frame
    /// starts a new sequence (another trajectory, another scene).
    pub fn reset(&mut self) {
        self.filter.reset();
        self.last_arm = None;
    }

    /// The filter's configuration.
    pub fn filter_config(&self) -> &FilterConfig {
        self.filter.config()
    }

    /// The database's lowest θ slice, degrees.
    pub fn lowest_theta_deg(&self) -> f64 {
        self.lowest_theta_deg
    }

    /// Carries the fused pose through the arm's motion since the last
    /// frame; without the arm's pose the motion is unknown and the fused
    /// pose is dropped.
    fn predict(&mut self, input: &Rated) {
        let frame = &input.envelope().frame;
        let Maybe::Present(arm) = frame.arm else {
            self.filter.reset();
            self.last_arm = None;
            return;
        };
        let arm = DAffine3::from_cols_array(&arm.world_from_camera);
        if let Some(last) = self.last_arm {
            let motion = last.inverse() * arm;
            match self.filter.predict(&motion) {
                Ok(()) => {
                    // As the filter moves the pose: motion⁻¹ · pose.
                    let r = motion.matrix3;
                    self.translation_covariance = r.transpose() * self.translation_covariance * r;
                }
                Err(e) => {
                    tracing::warn!("frame {}: {e}: fused pose dropped", frame.sequence);
                    self.filter.reset();
                }
            }
        }
        self.last_arm = Some(arm);
    }

    /// The seed input of an accepted estimate.
    fn seed_input(&self, input: &Rated) -> Option<SeedInput> {
        let verdict = input.rating.verdict().filter(|v| v.accepted)?;
        let pose = input.posed.pose.done()?;
        let roi = input.posed.segmented.region.done()?;
        let k = input.envelope().frame.intrinsics;
        // The centre's ray, not the silhouette box's: the offset of the
        // estimated view at this frame's scale.
        let (cx, cy) = acch_core::Rect::from(roi).centre();
        let offset = self.centre_offsets.at(pose.theta_deg, pose.phi_deg);
        Some(SeedInput {
            theta_deg: (pose.theta_deg as f64).clamp(0.0, 90.0),
            phi_deg: pose.phi_deg as f64,
            roll_deg: pose.roll_deg as f64,
            // Undistorted: the seed's ray is a pinhole camera's.
            roi_centre_px: k.undistort(DVec2::new(
                (cx + offset[0] * pose.scale) as f64,
                (cy + offset[1] * pose.scale) as f64,
            )),
            intrinsics: Pinhole {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            distance: match self.distance_m {
                Some(d) => Distance::Known {
                    value: d,
                    sigma: KNOWN_DISTANCE_RELATIVE_SIGMA * d,
                },
                None => Distance::FromScale {
                    train_distance: self.train_distance_m,
                    scale: (pose.scale as f64).max(1e-3),
                    relative_sigma: SCALE_DISTANCE_RELATIVE_SIGMA,
                },
            },
            // A verified estimate has no network's rating: the shape's
            // rules accepted it.
            confidence: if verdict.confidence.is_finite() {
                (verdict.confidence as f64).clamp(0.0, 1.0)
            } else {
                1.0
            },
            grid: self.grid,
        })
    }

    /// The seed of an accepted estimate: the pose the object's shape
    /// fitted, with its covariance (the fit's and the blend's spread), when
    /// the shape chose the view;
    /// else (the colours placed the object, or there is no shape) the view
    /// placed on the region's ray at its distance.
    fn seed_of(
        &self,
        input: &Rated,
        s: &SeedInput,
    ) -> Result<acch_seeding::Seed, acch_seeding::SeedError> {
        match input
            .posed
            .pose
            .done()
            .and_then(|p| p.shape.done())
            .filter(|f| f.anchored == 0)
        {
            Some(fit) => Ok(acch_seeding::Seed {
                camera_from_object: super::pose::fit_pose(&fit),
                covariance: super::pose::fit_covariance_matrix(&fit),
            }),
            None => acch_seeding::seed(s, &self.covariance),
        }
    }

    /// Fuses a seeded estimate (the filter runs only while the arm's pose
    /// is known).
    fn fuse(&mut self, input: &SeedInput, sequence: u64) -> Fusion {
        if self.last_arm.is_none() {
            return Fusion::None;
        }
        let censored = theta_censored(input.theta_deg, self.lowest_theta_deg);
        let m = match Measurement::from_estimate(input, &self.covariance) {
            Ok(m) if censored => m.without_theta(input),
            Ok(m) => m,
            Err(e) => {
                tracing::warn!("frame {sequence}: not fused: {e}");
                return Fusion::None;
            }
        };
        match self.filter.update(&m) {
            Ok(acch_seeding::Outcome::Initialised) => Fusion::Started,
            Ok(acch_seeding::Outcome::Fused { .. }) => Fusion::Fused,
            Ok(acch_seeding::Outcome::Gated { .. }) => Fusion::Gated,
            Ok(acch_seeding::Outcome::Reinitialised { .. }) => Fusion::Restarted,
            Err(e) => {
                tracing::warn!("frame {sequence}: not fused: {e}");
                Fusion::None
            }
        }
    }

    fn fused(&self) -> Maybe<FusedPose> {
        self.filter
            .state()
            .map(|f| FusedPose {
                view_deg: [f.theta_deg, f.phi_deg],
                view_covariance_deg2: [
                    f.view_covariance_deg2[0][0],
                    f.view_covariance_deg2[0][1],
                    f.view_covariance_deg2[1][0],
                    f.view_covariance_deg2[1][1],
                ],
                camera_from_object: f.camera_from_object,
                rotation_covariance: std::array::from_fn(|i| f.rotation_covariance[i / 3][i % 3]),
                translation_covariance: std::array::from_fn(|i| {
                    self.translation_covariance.col(i % 3)[i / 3]
                }),
                fused: f.fused,
                since_update: f.since_update,
            })
            .into()
    }
}

impl Stage for Seeding {
    const ID: StageId = StageId::Seeding;
    type Input = Rated;
    type Part = SeedingPart;
    type Output = Seeded;

    fn max_payload(&self) -> usize {
        0
    }

    fn process(
        &mut self,
        input: &Rated,
        _: &[u8],
        _: &[u8],
        _: &mut [u8],
    ) -> Result<SeedingPart, Fault> {
        self.predict(input);
        let sequence = input.envelope().frame.sequence;
        let (seed, fusion) = match self.seed_input(input) {
            None if input.posed.pose.done().is_some() => (Outcome::Nothing, Fusion::None),
            None => (Outcome::Skipped, Fusion::None),
            Some(s) => match self.seed_of(input, &s) {
                Ok(seed) => {
                    let fusion = self.fuse(&s, sequence);
                    if matches!(fusion, Fusion::Started | Fusion::Fused | Fusion::Restarted) {
                        let c = &seed.covariance;
                        self.translation_covariance = DMat3::from_cols_array_2d(&[
                            [c[0][0], c[1][0], c[2][0]],
                            [c[0][1], c[1][1], c[2][1]],
                            [c[0][2], c[1][2], c[2][2]],
                        ]);
                    }
                    let pose = SeedPose {
                        translation: seed.translation().to_array(),
                        rotation_xyzw: seed.rotation().to_array(),
                        covariance: seed.covariance,
                    };
                    (Outcome::Done(pose), fusion)
                }
                Err(e) => {
                    tracing::warn!("frame {sequence}: no seed: {e}");
                    (Outcome::Failed(Fault::Seed), Fusion::None)
                }
            },
        };
        Ok(SeedingPart {
            seed,
            fusion,
            fused: self.fused(),
        })
    }

    fn fault_in(part: &SeedingPart) -> Option<Fault> {
        match part.seed {
            Outcome::Failed(f) => Some(f),
            _ => None,
        }
    }

    fn output(input: &Rated, seeding: SeedingPart) -> Seeded {
        Seeded {
            rated: *input,
            seeding,
        }
    }
}
