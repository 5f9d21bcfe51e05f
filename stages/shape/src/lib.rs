//! The object's shape beside its colours.
//!
//! On real photographs a mesh's colours rarely match the camera's, but its
//! outline does: this crate holds each view's silhouette and contour
//! ([`ShapeModel`], trained from the mesh by the renderer), finds the views
//! and rolls whose silhouette matches a segmented region ([`search`]),
//! fits a candidate's contour to the image's edges in 6-DOF ([`refine`]),
//! and says how much of the contour the fitted pose explains ([`explain`]).

#![warn(missing_docs)]

pub mod db;
pub mod edges;
pub mod estimate;
pub mod fit;
pub mod geometry;
pub mod lines;
pub mod model;
pub mod search;
pub mod symmetry;
pub mod verify;

pub use db::{SHAPE_SECTION, SYMMETRY_SECTION, StoredShapeError, default_grid, store, stored};
pub use edges::Edges;
pub use estimate::{Proposal, Scored, ShapeEstimate, ShapeEstimator, ShapeSettings, rank_score};
pub use fit::{Fit, FitParams, explain, refine};
pub use geometry::{View, pose_of, rotation_angle_deg, towards, view_of};
pub use lines::{Image, LineFit, LineParams, LineScratch, fit_lines, judge_lines};
pub use model::{ColourPoint, ContourPoint, ShapeModel, ShapeModelError, ShapeView};
pub use search::{Candidate, Region, overlap_at, place_view, roll_matrix, search};
pub use symmetry::{Symmetry, SymmetryError};
pub use verify::{Evidence, evidence};

/// What the tests of several modules share.
#[cfg(test)]
pub(crate) mod testing {
    use crate::ShapeModel;
    use acch_capture::Object;

    /// Three blocks, whose views' silhouettes are no two alike, and their
    /// shape over 36 views (θ 20°, 50°, 80°; φ every 30°).
    pub fn tricolor() -> (Object, Vec<(f64, f64)>, ShapeModel) {
        let object = Object::builtin("tricolor").unwrap();
        let grid: Vec<(f64, f64)> = [20.0, 50.0, 80.0]
            .iter()
            .flat_map(|&t| (0..12).map(move |p| (t, p as f64 * 30.0)))
            .collect();
        let model = ShapeModel::train(&object, &grid);
        (object, grid, model)
    }
}
