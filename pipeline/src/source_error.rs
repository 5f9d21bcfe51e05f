//! What every frame source reports, whatever its kind: why it failed
//! ([`SourceError`]) and what a camera lost ([`CameraCounters`]). Both
//! `source` (the sources and the choice between them) and `gst` (the
//! GStreamer camera) report them, so they live below both.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Errors of a frame source; each names the input it concerns.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The source string is none of the known kinds.
    #[error("unknown source '{0}': use synthetic, folder:DIR, mcap:FILE or gst:PIPELINE")]
    Unknown(String),
    /// A GStreamer pipeline does not parse, start or make frames.
    #[error("gst:{pipeline}: {why}")]
    Gst {
        /// The pipeline as configured (after `gst:`).
        pipeline: String,
        /// What GStreamer said.
        why: String,
    },
    /// A `gst:` source on a build without GStreamer.
    #[error(
        "gst:{0}: this build has no GStreamer source; build with `--features gstreamer` \
         (needs the Debian packages libgstreamer1.0-dev and libgstreamer-plugins-base1.0-dev)"
    )]
    NoGstreamer(String),
    /// A calibration is for another image size than the stream's.
    #[error("{}: {why}", path.display())]
    CalibrationSize {
        /// The calibration file.
        path: PathBuf,
        /// Both sizes.
        why: String,
    },
    /// A folder could not be listed.
    #[error("reading {}", dir.display())]
    Folder {
        /// The folder.
        dir: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// A folder holds no PNG or JPEG image.
    #[error("{} holds no images", .0.display())]
    Empty(PathBuf),
    /// No image of a folder has the stream's size.
    #[error("no image in {} is {width}x{height}", dir.display())]
    NoneOfSize {
        /// The folder.
        dir: PathBuf,
        /// The stream's width.
        width: u32,
        /// The stream's height.
        height: u32,
    },
    /// An image could not be read or decoded.
    #[error("reading {}", path.display())]
    Image {
        /// The image.
        path: PathBuf,
        /// What the decoder said.
        #[source]
        source: image::ImageError,
    },
    /// The renderer, the labels or the trajectory refused their input.
    #[error(transparent)]
    Capture(#[from] acch_capture::CaptureError),
    /// A recording could not be read.
    #[error(transparent)]
    Record(#[from] acch_record::RecordError),
    /// The scene of several objects could not be laid out.
    #[error(transparent)]
    Group(#[from] acch_capture::MultiSceneError),
}

/// What a camera source lost: frames it dropped (the camera or the
/// pipeline could not keep up), frames lost while it was reopened, and
/// how often it failed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CameraCounters {
    /// Frames missing from the stream (gaps in the buffers' time stamps).
    pub dropped: u64,
    /// Frames lost while a failed pipeline was reopened.
    pub lost: u64,
    /// Times the pipeline failed mid-stream and was reopened.
    pub failures: u64,
}
