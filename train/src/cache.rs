//! The cached databases: where they are kept and named, the recipes they
//! are trained by (each with a file of its own), and the default database
//! `acch run` uses, trained on first use.

use crate::TrainingError;
use crate::confidence::{
    ConfidenceInput, ConfidenceScenes, DEFAULT_CONFIDENCE_SCENES, train_object,
};
use crate::scenes::PAPER_GRID;
use crate::views::{RenderedTraining, add_shape, add_view_maps};
use acch_capture::{DEFAULT_DISTANCE, Object, ViewSpec};
use acch_core::{Smoothing, ViewDatabase};
use acch_pose::train::TrainConfig;
use std::path::PathBuf;
use std::sync::Arc;

/// Revision of the default training recipe; part of cached databases'
/// names so that a changed recipe retrains instead of reusing a stale file.
pub const TRAINING_REVISION: u32 = 8;

/// The roll search the databases of several objects are trained for by
/// default (`acch run --objects`, the multi-object protocol): an object standing off
/// the optical axis is seen rolled, and without the search its wrong
/// estimates are accepted (docs/multi.md).
pub const OFF_AXIS_ROLL_SEARCH_DEG: f64 = 45.0;

/// Where default databases are cached: `dir`, else `$XDG_CACHE_HOME/acch`,
/// `~/.cache/acch`, or the temporary directory.
pub fn cache_dir(dir: Option<PathBuf>) -> PathBuf {
    dir.or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("acch")))
        .or_else(|| std::env::var_os("HOME").map(|d| PathBuf::from(d).join(".cache/acch")))
        .unwrap_or_else(|| std::env::temp_dir().join("acch"))
}

/// The file the default database of `object` is cached in (with
/// `imaging`, the one whose confidence network saw imaged scenes): the
/// format version, the build and the training recipe are in the name, so
/// builds sharing a cache directory never read each other's databases.
pub fn cached_database_path(object: &Object, dir: Option<PathBuf>, imaging: bool) -> PathBuf {
    // The size is in the name: a database's distances are metres of it;
    // a generated object's generator revision too: it is what draws it.
    let generator = match acch_capture::generated_seed(object.name()) {
        Some(_) => format!("-g{}", acch_capture::GENERATOR_REVISION),
        None => String::new(),
    };
    cache_dir(dir).join(format!(
        "{}{generator}-{:.1}mm-v{}-{}-r{}{}.acchdb",
        object.name(),
        object.radius_m() * 1000.0,
        acch_core::database::FORMAT_VERSION,
        env!("CARGO_PKG_VERSION"),
        TRAINING_REVISION,
        if imaging { "-imaging" } else { "" }
    ))
}

/// The roll search that covers a camera's views: as far as 95 % of
/// `rolls` (degrees, either sign) reach, rounded up to 15°, at most 180°;
/// 0 for none.
pub fn roll_search_covering(rolls: impl IntoIterator<Item = f64>) -> f64 {
    let mut rolls: Vec<f64> = rolls.into_iter().map(f64::abs).collect();
    rolls.sort_by(f64::total_cmp);
    let roll = rolls
        .get((rolls.len() * 95 / 100).min(rolls.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0);
    ((roll / 15.0).ceil() * 15.0).min(180.0)
}

/// What a cached database is trained for beyond the default recipe; each
/// recipe has a file of its own beside the default one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Recipe {
    /// Confidence scenes imaged under other light and a worse camera
    /// ([`ConfidenceScenes::imaging`]).
    pub imaging: bool,
    /// Confidence scenes rolled within ± this many degrees and estimated
    /// with that roll search, which runs then use (0: upright, none).
    pub roll_search_deg: f64,
    /// Training views lit from this many directions around the vertical
    /// ([`RenderedTraining::light_directions`]) and half the confidence
    /// scenes lit from a turned one (1: the training light only).
    pub light_directions: usize,
    /// Views and frames smoothed before quantisation
    /// ([`acch_core::smooth`]; off: the paper's raw pixels).
    pub smoothing: Smoothing,
    /// Training views at every 10° of elevation from this one up to 90°
    /// (every 10° of azimuth) instead of the paper's grid: where a real
    /// camera looks from (a dataset's range of views).
    pub lowest_theta_deg: Option<u8>,
    /// The training distance, object radii (default
    /// [`DEFAULT_DISTANCE`]): where a real camera stands, so recognition's
    /// window has the object's size.
    pub distance_radii: Option<f64>,
}

impl Default for Recipe {
    /// The default recipe.
    fn default() -> Self {
        Recipe {
            imaging: false,
            roll_search_deg: 0.0,
            light_directions: 1,
            smoothing: Smoothing::Off,
            lowest_theta_deg: None,
            distance_radii: None,
        }
    }
}

impl Recipe {
    /// The recipe of the smoothed set a run with `smoothing = "auto"` holds
    /// beside this one: views and frames smoothed, the confidence trained
    /// for a worse camera (docs/accuracy.md, "The database set chosen per
    /// frame").
    pub fn smoothed_set(self) -> Recipe {
        Recipe {
            smoothing: Smoothing::Binomial,
            imaging: true,
            ..self
        }
    }

    /// Refuses what cannot be trained, naming the option.
    fn check(&self) -> Result<(), TrainingError> {
        let deg = self.roll_search_deg;
        if !(deg.is_finite() && (0.0..=180.0).contains(&deg)) {
            return Err(TrainingError::Input(format!(
                "--roll-search-deg {deg} must be a finite number of degrees in [0, 180]"
            )));
        }
        if self.light_directions == 0 {
            return Err(TrainingError::Input(
                "--light-directions 0: at least 1 (the training light's)".into(),
            ));
        }
        if self.imaging && self.light_directions > 1 {
            return Err(TrainingError::Input(
                "--confidence-imaging and --light-directions: one at a time".into(),
            ));
        }
        if self.lowest_theta_deg.is_some_and(|t| t > 90) {
            return Err(TrainingError::Input(
                "the lowest training elevation must be at most 90°".into(),
            ));
        }
        if let Some(d) = self.distance_radii {
            acch_capture::check_distance(d)?;
        }
        Ok(())
    }

    /// The training views: the paper's grid, or every 10° from the lowest
    /// elevation.
    fn views(&self) -> ViewSpec {
        match self.lowest_theta_deg {
            None => PAPER_GRID.parse().expect("the paper grid parses"),
            Some(lowest) => ViewSpec::Grid {
                thetas_deg: (lowest..=90).step_by(10).map(f64::from).collect(),
                phi_step_deg: 10.0,
            },
        }
    }

    /// The file's suffix after the default one's stem ("" for the default).
    fn suffix(&self) -> String {
        let mut s = String::new();
        if self.imaging {
            s += "-imaging";
        }
        if self.roll_search_deg > 0.0 {
            s += &format!("-roll{}", self.roll_search_deg);
        }
        if self.light_directions > 1 {
            s += &format!("-lights{}", self.light_directions);
        }
        if self.smoothing != Smoothing::Off {
            s += "-smoothed";
        }
        if let Some(t) = self.lowest_theta_deg {
            s += &format!("-from{t}deg");
        }
        if let Some(d) = self.distance_radii {
            s += &format!("-at{d:.1}r");
        }
        s
    }

    /// What the training message calls it ("" for the default).
    fn what(&self) -> String {
        let mut s = String::new();
        if self.imaging {
            s += "imaging-aware ";
        }
        if self.roll_search_deg > 0.0 {
            s += "roll-searching ";
        }
        if self.light_directions > 1 {
            s += "light-tolerant ";
        }
        if self.smoothing != Smoothing::Off {
            s += "smoothing ";
        }
        s
    }
}

/// The database of `object` trained with `recipe` and the file it is
/// cached in: trained on first use and cached, so later runs start at once.
pub fn cached_recipe_database(
    object: &Arc<Object>,
    dir: Option<PathBuf>,
    recipe: Recipe,
) -> Result<(ViewDatabase, PathBuf), TrainingError> {
    recipe.check()?;
    let default = cached_database_path(object, dir, false);
    let stem = default.file_stem().unwrap_or_default().to_string_lossy();
    let path = default.with_file_name(format!("{stem}{}.acchdb", recipe.suffix()));
    let scenes = ConfidenceScenes {
        roll_deg: recipe.roll_search_deg,
        search_deg: recipe.roll_search_deg,
        imaging: recipe.imaging,
        light_turned: recipe.light_directions > 1,
    };
    let config = TrainConfig {
        smoothing: recipe.smoothing,
        ..TrainConfig::default()
    };
    let training = RenderedTraining {
        views: recipe.views(),
        distance: recipe.distance_radii.unwrap_or(DEFAULT_DISTANCE),
        scenes,
        light_directions: recipe.light_directions,
        ..RenderedTraining::default()
    };
    cached_with(object, path, &recipe.what(), &config, training)
}

/// The default database of a built-in object and the file it is cached
/// in: trained on first use with the default recipe and cached, so later
/// runs start at once.
pub fn cached_database(
    object: &Arc<Object>,
    dir: Option<PathBuf>,
) -> Result<(ViewDatabase, PathBuf), TrainingError> {
    cached_recipe_database(object, dir, Recipe::default())
}

/// [`cached_database`], or with `imaging` the default recipe with the
/// confidence network trained on imaged scenes too
/// ([`ConfidenceScenes::imaging`]).
pub fn cached_database_with(
    object: &Arc<Object>,
    dir: Option<PathBuf>,
    imaging: bool,
) -> Result<(ViewDatabase, PathBuf), TrainingError> {
    let recipe = Recipe {
        imaging,
        ..Recipe::default()
    };
    cached_recipe_database(object, dir, recipe)
}

/// The default recipe for `object` with its confidence network trained on
/// scenes rolled within ±`search_deg` and estimated with that roll search
/// (which runs then use): for a camera that rolls, or for objects seen off
/// the optical axis (several objects on a table). Cached beside the
/// default one.
pub fn cached_roll_database(
    object: &Arc<Object>,
    dir: Option<PathBuf>,
    search_deg: f64,
) -> Result<(ViewDatabase, PathBuf), TrainingError> {
    let recipe = Recipe {
        roll_search_deg: search_deg,
        ..Recipe::default()
    };
    cached_recipe_database(object, dir, recipe)
}

/// The database of `object` cached at `path`, or trained by `training`
/// on first use and cached there.
fn cached_with(
    object: &Arc<Object>,
    path: PathBuf,
    what: &str,
    config: &TrainConfig,
    training: RenderedTraining,
) -> Result<(ViewDatabase, PathBuf), TrainingError> {
    let dir = path.parent().map(PathBuf::from).unwrap_or_default();
    if path.exists() {
        match ViewDatabase::load(&path) {
            Ok(mut db)
                if acch_pose::view_maps(&db).is_some()
                    && !matches!(acch_shape::stored(&db), Ok(Some(_))) =>
            {
                eprintln!(
                    "acch: adding the shape to the cached {what}database of '{}' (trained before \
                     this build's shapes; {})",
                    object.name(),
                    path.display()
                );
                add_shape(&mut db, object, &training.symmetry);
                db.save(&path)?;
                return Ok((db, path));
            }
            Ok(db) if acch_pose::view_maps(&db).is_some() => return Ok((db, path)),
            Ok(mut db) => {
                eprintln!(
                    "acch: adding the views' colour maps to the cached {what}database of '{}' \
                     (trained before them; {})",
                    object.name(),
                    path.display()
                );
                add_view_maps(&mut db, object, &training)?;
                db.save(&path)?;
                return Ok((db, path));
            }
            Err(e) => tracing::warn!("retraining: the cached database is unusable: {e}"),
        }
    }
    eprintln!(
        "acch: training the {what}database of '{}' (first use; cached in {})",
        object.name(),
        path.display()
    );
    let confidence = Some((DEFAULT_CONFIDENCE_SCENES, ConfidenceInput::Auto));
    // The confidence input chosen is logged where it is chosen.
    let (db, _) = train_object(object, config, &training, confidence)?;
    std::fs::create_dir_all(&dir).map_err(|source| TrainingError::Io {
        path: dir.clone(),
        source,
    })?;
    db.save(&path)?;
    Ok((db, path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_roll_search_covers_95_percent_of_the_rolls_in_steps_of_15_degrees() {
        assert_eq!(roll_search_covering([]), 0.0);
        assert_eq!(roll_search_covering([0.0; 20]), 0.0);
        // Either sign; of three, the 95th percentile is the largest.
        assert_eq!(roll_search_covering([-40.0, 3.0, 10.0]), 45.0);
        let mostly_small = std::iter::repeat_n(10.0, 96).chain([170.0; 4]);
        assert_eq!(roll_search_covering(mostly_small), 15.0);
        assert_eq!(roll_search_covering([30.0]), 30.0);
        assert_eq!(roll_search_covering([179.0]), 180.0);
    }

    #[test]
    fn each_recipe_has_a_file_of_its_own_and_the_old_names_stay() {
        let object = Object::builtin("can").unwrap();
        let default = cached_database_path(&object, Some("/c".into()), false);
        let stem = default.file_stem().unwrap().to_string_lossy().into_owned();
        let name = |r: Recipe| format!("{stem}{}.acchdb", r.suffix());
        let r = Recipe::default();
        assert_eq!(name(r), default.file_name().unwrap().to_string_lossy());
        let imaging = Recipe { imaging: true, ..r };
        assert_eq!(
            name(imaging),
            cached_database_path(&object, Some("/c".into()), true)
                .file_name()
                .unwrap()
                .to_string_lossy()
        );
        let roll = Recipe {
            roll_search_deg: 45.0,
            ..r
        };
        assert_eq!(name(roll), format!("{stem}-roll45.acchdb"));
        let both = Recipe {
            light_directions: 8,
            ..roll
        };
        assert_eq!(name(both), format!("{stem}-roll45-lights8.acchdb"));
        assert!(both.check().is_ok());
        for bad in [
            Recipe {
                light_directions: 0,
                ..r
            },
            Recipe {
                light_directions: 8,
                ..imaging
            },
            Recipe {
                roll_search_deg: f64::NAN,
                ..r
            },
        ] {
            assert!(
                matches!(bad.check(), Err(TrainingError::Input(_))),
                "{bad:?}"
            );
        }
    }
}
