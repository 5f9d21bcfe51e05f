//! Seeding: an accepted 2-DOF estimate, the ROI's centre, the intrinsics
//! and the distance make an SE(3) seed with a covariance for the 6-DOF
//! tracker; the seeds are fused over the arm's known motion into a pose
//! that outlives rejected frames ([`acch_seeding::fusion`]).

use super::confidence::{Rated, Rating};
use super::{BuildError, StageSettings};
use crate::stage::Stage;
use crate::wire::{Envelope, Fault, Hop, Maybe, Outcome, StageId};
use acch_core::ViewDatabase;
use acch_ipc::ZeroCopySend;
use acch_seeding::{
    CovarianceModel, Distance, FilterConfig, GridSpacing, Measurement, Pinhole, SeedInput,
    ViewFilter, theta_censored,
};
use glam::{DAffine3, DVec2};

/// Relative standard deviation of a known distance handed to the seed (the
/// arm's kinematics).
pub const KNOWN_DISTANCE_RELATIVE_SIGMA: f64 = 0.02;
/// Relative standard deviation of a distance read off the ROI's scale.
pub const SCALE_DISTANCE_RELATIVE_SIGMA: f64 = 0.1;

/// A 6-DOF seed: the object's pose in the camera's optical frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct SeedPose {
    /// Object centre in the camera frame (object bounding radii).
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
    train_distance: f64,
    distance: Option<f64>,
    covariance: CovarianceModel,
    filter: ViewFilter,
    /// The database's lowest θ slice: an estimate there may stand for any
    /// view below it, so it fuses φ only.
    lowest_theta_deg: f64,
    /// The arm's camera pose at the last frame, to predict by the motion
    /// since (absolute poses, so frames dropped upstream cost nothing).
    last_arm: Option<DAffine3>,
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
            train_distance: db.train_distance as f64,
            distance: settings.distance,
            covariance: CovarianceModel::default(),
            filter: ViewFilter::new(FilterConfig::default())?,
            lowest_theta_deg: db
                .views()
                .iter()
                .map(|v| v.theta_deg as f64)
                .fold(f64::INFINITY, f64::min),
            last_arm: None,
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
        if let Some(last) = self.last_arm
            && let Err(e) = self.filter.predict(&(last.inverse() * arm))
        {
            tracing::warn!("frame {}: {e}: fused pose dropped", frame.sequence);
            self.filter.reset();
        }
        self.last_arm = Some(arm);
    }

    /// The seed input of an accepted estimate.
    fn seed_input(&self, input: &Rated) -> Option<SeedInput> {
        let verdict = input.rating.verdict().filter(|v| v.accepted)?;
        let pose = input.posed.pose.done()?;
        let roi = input.posed.segmented.region.done()?;
        let k = input.envelope().frame.intrinsics;
        Some(SeedInput {
            theta_deg: (pose.theta_deg as f64).clamp(0.0, 90.0),
            phi_deg: pose.phi_deg as f64,
            roi_centre_px: DVec2::new(
                roi.x as f64 + (roi.width as f64 - 1.0) / 2.0,
                roi.y as f64 + (roi.height as f64 - 1.0) / 2.0,
            ),
            intrinsics: Pinhole {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            distance: match self.distance {
                Some(d) => Distance::Known {
                    value: d,
                    sigma: KNOWN_DISTANCE_RELATIVE_SIGMA * d,
                },
                None => Distance::FromScale {
                    train_distance: self.train_distance,
                    scale: (pose.scale as f64).max(1e-3),
                    relative_sigma: SCALE_DISTANCE_RELATIVE_SIGMA,
                },
            },
            confidence: (verdict.confidence as f64).clamp(0.0, 1.0),
            grid: self.grid,
        })
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

    fn process(&mut self, input: &Rated, _: &[u8], _: &mut [u8]) -> Result<SeedingPart, Fault> {
        self.predict(input);
        let sequence = input.envelope().frame.sequence;
        let (seed, fusion) = match self.seed_input(input) {
            None if input.posed.pose.done().is_some() => (Outcome::Nothing, Fusion::None),
            None => (Outcome::Skipped, Fusion::None),
            Some(s) => match acch_seeding::seed(&s, &self.covariance) {
                Ok(seed) => {
                    let fusion = self.fuse(&s, sequence);
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
