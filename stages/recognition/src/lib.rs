//! Object recognition after Ekvall et al. (2005), as used by the paper
//! (section 3.2): the frame is split into cells; per cell, the counts of
//! every palette colour (and "not object") and of the object's K most
//! frequent colour pairs at a small pixel distance are computed once per
//! frame and integrated over the cell grid; every window of the object's
//! trained apparent size is then scored in O(features) with a histogram
//! intersection against the object's model. The best window is the
//! hypothesis; below the model's threshold the object is "not found".
//!
//! The model ([`RecognitionModel`]) is trained from the same labelled views
//! and palette as the view database and is stored in its
//! [`SECTION`] section. Everything here is a pure algorithm on
//! [`acch_core::IndexImage`] buffers.

#![warn(missing_docs)]

mod detector;
mod model;

pub use detector::{CellRect, Detection, Detector, HeatMap};
pub use model::{MODEL_VERSION, RecognitionError, RecognitionModel, RecognitionParams, SECTION};
