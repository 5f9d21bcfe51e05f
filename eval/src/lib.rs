//! acch's evaluation protocols, on the in-process
//! [`Chain`](acch_pipeline::Chain) of the very stages `acch run` deploys:
//!
//! - [`table1`]: the paper's table 1, pose with ground-truth masks;
//! - [`table2`]: the paper's table 2, textured backgrounds, recognition,
//!   segmentation and the confidence network;
//! - [`sequence`]: camera trajectories, single frames against the seeding
//!   stage's fused pose, and active re-view after a rejection ([`review`]);
//! - [`roll`]: a camera that rolls, a database trained to search it;
//! - [`robust`]: exposure, colour temperature, noise, blur, JPEG,
//!   occlusion and distance, with and without the light search;
//! - [`multi`]: several known objects in one scene, each with the others
//!   known and alone;
//! - [`dataset`]: labelled photographs the user brings, a [`bop`] split or
//!   a folder with labels.csv.
//!
//! One home for what they share ([`protocol`]): the paper's grid, the
//! backgrounds and the failure rule. The databases they run on are trained
//! by [`acch_train`], the layer below.

pub mod bop;
pub mod dataset;
pub mod multi;
pub mod protocol;
pub mod review;
pub mod robust;
pub mod roll;
pub mod sequence;
pub mod table1;
pub mod table2;

use std::path::PathBuf;

/// Why a protocol or a training could not run; names the input concerned.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// An option is out of range; says which and why.
    #[error("{0}")]
    Input(String),
    /// The renderer, an object, a trajectory or a labels file refused its
    /// input.
    #[error(transparent)]
    Capture(#[from] acch_capture::CaptureError),
    /// A view database could not be read or written.
    #[error(transparent)]
    Database(#[from] acch_core::DbError),
    /// The view database could not be trained.
    #[error(transparent)]
    Train(#[from] acch_pose::train::TrainError),
    /// The recognition model could not be trained.
    #[error(transparent)]
    Recognition(#[from] acch_recognition::RecognitionError),
    /// The confidence network could not be trained or used.
    #[error("the confidence network")]
    Confidence(#[from] acch_confidence::ConfidenceError),
    /// The stages could not be built.
    #[error(transparent)]
    Build(#[from] acch_pipeline::BuildError),
    /// A pose estimator could not be built.
    #[error(transparent)]
    Pose(#[from] acch_pose::PoseError),
    /// The fusion filter failed.
    #[error(transparent)]
    Fusion(#[from] acch_seeding::FusionError),
    /// An image could not be read.
    #[error("reading {}", path.display())]
    Image {
        /// The image.
        path: PathBuf,
        /// What the decoder said.
        #[source]
        source: image::ImageError,
    },
    /// A file could not be written.
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// A plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] acch_viz::plot::PlotError),
    /// A worker of a parallel loop failed to start.
    #[error("{0}")]
    Worker(String),
    /// A database could not be trained or its cache used.
    #[error(transparent)]
    Training(#[from] acch_train::TrainingError),
}

/// Writes `value` as pretty JSON (with a final newline) to `path`.
pub fn write_json(path: &std::path::Path, value: &impl serde::Serialize) -> Result<(), EvalError> {
    let text = serde_json::to_string_pretty(value).expect("reports serialise") + "\n";
    std::fs::write(path, text).map_err(|source| EvalError::Io {
        path: path.to_owned(),
        source,
    })
}
