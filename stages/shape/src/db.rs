//! The shape in a view database: the model and the object's symmetry as
//! two sections, written at training and read by the pose stage.

use crate::model::{ShapeModel, ShapeModelError};
use crate::symmetry::Symmetry;
use acch_core::ViewDatabase;

/// Section holding the [`ShapeModel`] ([`ShapeModel::to_bytes`]).
pub const SHAPE_SECTION: &str = "shape-model";
/// Section holding the object's [`Symmetry`] ([`Symmetry::to_bytes`]);
/// absent: none.
pub const SYMMETRY_SECTION: &str = "symmetry";

/// The elevations of the default shape grid, degrees: from a little below
/// the object's horizontal plane (a camera level with a table, an object
/// tipped over) to straight above.
pub const DEFAULT_THETAS_DEG: [f64; 12] = [
    -20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0,
];
/// The azimuth step of the default shape grid, degrees.
pub const DEFAULT_PHI_STEP_DEG: f64 = 10.0;

/// The default shape grid: every azimuth step at every elevation of
/// [`DEFAULT_THETAS_DEG`].
pub fn default_grid() -> Vec<(f64, f64)> {
    let steps = (360.0 / DEFAULT_PHI_STEP_DEG).round() as usize;
    DEFAULT_THETAS_DEG
        .iter()
        .flat_map(|&t| (0..steps).map(move |i| (t, i as f64 * DEFAULT_PHI_STEP_DEG)))
        .collect()
}

/// Writes `model` and `symmetry` into `db`.
pub fn store(db: &mut ViewDatabase, model: &ShapeModel, symmetry: &Symmetry) {
    db.sections
        .insert(SHAPE_SECTION.to_owned(), model.to_bytes());
    if symmetry.is_none() {
        db.sections.remove(SYMMETRY_SECTION);
    } else {
        db.sections
            .insert(SYMMETRY_SECTION.to_owned(), symmetry.to_bytes());
    }
}

/// Why a database's shape could not be read.
#[derive(Debug, thiserror::Error)]
pub enum StoredShapeError {
    /// The model section is damaged.
    #[error(transparent)]
    Model(#[from] ShapeModelError),
    /// The symmetry section is damaged.
    #[error("the symmetry section is corrupt (not a whole number of rotations)")]
    Symmetry,
}

/// The shape `db` holds; `None` when it has none (a database trained from
/// images, or before shapes were recorded).
pub fn stored(db: &ViewDatabase) -> Result<Option<(ShapeModel, Symmetry)>, StoredShapeError> {
    let Some(bytes) = db.sections.get(SHAPE_SECTION) else {
        return Ok(None);
    };
    let model = ShapeModel::from_bytes(bytes)?;
    let symmetry = match db.sections.get(SYMMETRY_SECTION) {
        Some(b) => Symmetry::from_bytes(b).ok_or(StoredShapeError::Symmetry)?,
        None => Symmetry::none(),
    };
    Ok(Some((model, symmetry)))
}
