//! The pipeline as processes: the configuration every process reads, the
//! generic stage wrapper (block on the input's event, look the frame up,
//! call the stage's pure function, publish), the five processing stages and
//! the capture source.
//!
//! Data flows one way: capture -> recognition -> segmentation -> pose ->
//! confidence -> seeding. Every result message carries the results of the
//! stages before it, so a stage reads exactly one result stream plus, if it
//! needs pixels, the frame of the same sequence from its frame history.

mod capture;
mod config;
pub mod copy;
pub mod json;
mod processing;
mod runner;

pub use capture::{frame_size, run_capture, sized_intrinsics, sized_renderer};
pub use config::{PipelineConfig, hold_cpu_latency};
pub use json::ResultJson;
pub use processing::{Confidence, Pose, Recognition, Seeding, Segmentation};
pub use runner::{Stage, run_stage};

use acch_ipc::StageId;
use std::time::Duration;

/// The stages that read a frame's pixels (every later stage works on
/// recognition's palette indices): the copy baseline sends frames to these.
pub const FRAME_READERS: [StageId; 1] = [StageId::Recognition];

/// How long a stage sleeps on its input before checking for termination.
const WAIT: Duration = Duration::from_millis(200);
