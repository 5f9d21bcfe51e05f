//! acch's training recipe and its database cache, below the evaluation
//! protocols: what `acch train` and `acch run` need without the
//! evaluation layer.
//!
//! - [`views`]: view histograms, the recognition model and the shape from
//!   rendered views or photographs, and the images and masks they are
//!   read from;
//! - [`confidence`]: the confidence network's scenes, samples, input
//!   choice and training, and an object's whole database with it;
//! - [`cache`]: the recipes ([`cache::Recipe`]) and the cached databases,
//!   trained on first use;
//! - [`scenes`]: what training shares with the evaluation protocols (the
//!   one home of each): the paper's grid, the failure rule, and how scenes
//!   are rendered, labelled and framed.

pub mod cache;
pub mod confidence;
pub mod scenes;
pub mod views;

use std::path::PathBuf;

/// Why a training could not run; names the input concerned.
#[derive(Debug, thiserror::Error)]
pub enum TrainingError {
    /// An option is out of range; says which and why.
    #[error("{0}")]
    Input(String),
    /// The renderer, an object or a labels file refused its input.
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
    /// The stages the network's training data is collected with could not
    /// be built.
    #[error(transparent)]
    Build(#[from] acch_pipeline::BuildError),
    /// An image could not be read.
    #[error("reading {}", path.display())]
    Image {
        /// The image.
        path: PathBuf,
        /// What the decoder said.
        #[source]
        source: image::ImageError,
    },
    /// A directory could not be created.
    #[error("{}", path.display())]
    Io {
        /// The directory.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// A worker of a parallel loop failed to start.
    #[error("{0}")]
    Worker(String),
}
