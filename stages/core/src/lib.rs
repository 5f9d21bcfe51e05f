//! The ACCH core: colour palette and quantisation, colour cooccurrence
//! histograms (CCH, DCCH, ACCH), histogram intersection and the view database.
//!
//! Everything here is a pure algorithm on plain buffers: no I/O besides the
//! database file, no IPC, no image crate. Frames arrive as packed RGB bytes,
//! masks as one byte per pixel (non-zero = object).

#![warn(missing_docs)]

pub mod colour_map;
pub mod database;
pub mod histogram;
pub mod joint;
pub mod layout;
pub mod light;
pub mod palette;
pub mod quality;
pub mod share;
pub mod smooth;

pub use colour_map::{ColourMap, ColourMapError, PlacedQuery};
pub use database::{DbError, FROM_PHOTOGRAPHS_SECTION, View, ViewDatabase};
pub use histogram::{
    HistogramExtractor, HistogramKind, HistogramParams, OffsetSampling, Rect, intersection,
    match_value, roll_acch, roll_invariant, scaled_intersection,
};
pub use joint::{JointPalette, JointPaletteError};
pub use layout::{LAYOUT_FIELDS, layout_distance, layout_into, scale_layout, unroll_layout};
pub use palette::{ColourSpace, IndexImage, IndexView, NOT_OBJECT, Palette, PaletteError};
pub use quality::{BLOCKY, BLURRED, FrameQuality, NOISY_SIGMA, QualityMeter, is_blurred};
pub use smooth::Smoothing;
