//! The acch runtime: the pipeline as a library.
//!
//! - **Sources** ([`source`]): the simulated camera, an image folder, an
//!   MCAP recording, a GStreamer pipeline (a real camera; feature
//!   `gstreamer`). Written once; capture runs them.
//! - **Stages** ([`stages`]): recognition, segmentation, pose, confidence
//!   and seeding, each a value with its own buffers that reads its
//!   upstream's typed header and payload view and writes its own
//!   ([`Stage`]). A fault is returned and counted, never dropped.
//! - **Sinks** ([`observe`], [`observers`], [`json`]): the zenoh publisher,
//!   the rerun viewer, the MCAP recorder, a results file.
//! - **Two executors of the same stage values**: the [`Chain`] on one
//!   thread (every evaluation, `acch run --in-process`, the benchmark's
//!   floor) and one [`node`] per process over iceoryx2 (`acch run`), under
//!   the [`supervisor`].
//!
//! Data flows one way: capture -> recognition -> segmentation -> pose ->
//! confidence -> seeding. Every header carries the one before it.

pub mod chain;
pub mod config;
pub mod copy;
pub mod frame;
#[cfg(feature = "gstreamer")]
pub mod gst;
pub mod json;
pub mod multi;
pub mod node;
pub mod observe;
pub mod observers;
pub mod ros2;
pub mod run;
pub mod source;
pub mod source_error;
pub mod stage;
pub mod stages;
pub mod streams;
pub mod summary;
pub mod supervisor;
pub mod wire;

pub use chain::{Chain, Pacing, run_source};
pub use config::{ConfigError, PipelineConfig, StageSettings};
pub use frame::FrameHeader;
pub use multi::MultiChain;
pub use observe::{Observe, ObserveError, Observer};
pub use run::{RunError, RunOptions, RunSummary, run_in_process, run_process, run_processes};
pub use source::{Source, SourceSpec, SyntheticCamera};
pub use source_error::SourceError;
pub use stage::{ObjectWindow, Stage, StageCounters};
pub use stages::{BuildError, Seeded, Stages};
pub use wire::{Fault, Hop, Maybe, Outcome, StageId};
