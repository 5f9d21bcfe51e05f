//! Where the visible part lies: each view's colour map
//! ([`acch_core::colour_map`]), recorded with the database at training, and
//! the map rival of an estimate, how much better a view beyond the
//! tolerance in azimuth holds the query's colours in place than the view
//! chosen.
//!
//! An occluder that hides the side of an object that tells a view from its
//! neighbours leaves a visible part whose pairs both hold and whose
//! centroids have moved: the response cannot place it, and a near miss
//! 20-30° off is rated as sure as a right estimate. The map of the visible
//! part still lies where it lies in the right view (docs/accuracy.md,
//! "Where the visible part lies").

use crate::train::{LabelledView, TrainError, mask_bbox, pose_groups};
use crate::{Estimate, PoseEstimator, phi_error};
use acch_core::{ColourMap, IndexImage, Rect, ViewDatabase};

/// Section of a [`ViewDatabase`] holding each view's colour map: the cell
/// size in pixels at the training scale (`f32` little-endian), then per
/// view in view order its width and height in cells (`u16`
/// little-endian) and its shares ([`ColourMap::cells`]). Absent
/// (databases trained before it), no estimate has a map rival.
pub const VIEW_MAPS_SECTION: &str = "view-colour-maps";

/// Cells across a view of the database's median size: 20 cells of 5-10
/// pixels on the robust protocol's objects, fine enough to see a mark move
/// with a 20° turn, coarse enough to hold under blur and noise (chosen
/// on its development seed with an exploratory patch).
pub const MAP_CELLS_ACROSS: f32 = 20.0;

/// How far, in cells, a query's map may slide beyond a view's edges: the
/// visible part of an occluded object is not centred where the whole was.
pub const MAP_MARGIN_CELLS: usize = 3;

/// Views up to this far from the estimate in azimuth are weighed against
/// it, degrees: the near misses the response cannot tell lie within it,
/// far ones are the rival rule's.
pub const MAP_REACH_DEG: f32 = 60.0;

/// Every view's colour map and the cells' size.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewMaps {
    /// Cell size, pixels at the training scale.
    pub cell_px: f32,
    /// One map per view, in view order.
    pub maps: Vec<ColourMap>,
}

impl ViewMaps {
    /// The section's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = self.cell_px.to_le_bytes().to_vec();
        for m in &self.maps {
            out.extend((m.width() as u16).to_le_bytes());
            out.extend((m.height() as u16).to_le_bytes());
            out.extend(m.cells());
        }
        out
    }

    /// Reads a section of `views` maps of `colours` colours; `None` when it
    /// is of another shape or its cell size is not a positive number.
    pub fn from_bytes(bytes: &[u8], views: usize, colours: usize) -> Option<ViewMaps> {
        let (head, mut rest) = bytes.split_at_checked(4)?;
        let cell_px = f32::from_le_bytes(head.try_into().ok()?);
        if !(cell_px.is_finite() && cell_px > 0.0) {
            return None;
        }
        let mut maps = Vec::with_capacity(views);
        for _ in 0..views {
            let (size, tail) = rest.split_at_checked(4)?;
            let w = u16::from_le_bytes([size[0], size[1]]) as usize;
            let h = u16::from_le_bytes([size[2], size[3]]) as usize;
            let (cells, tail) = tail.split_at_checked(w * h * colours)?;
            maps.push(ColourMap::from_parts(w, h, colours, cells.to_vec()).ok()?);
            rest = tail;
        }
        rest.is_empty().then_some(ViewMaps { cell_px, maps })
    }
}

/// Each view's colour map, when `db` records one for every view (a
/// section of another shape is refused: `None`).
pub fn view_maps(db: &ViewDatabase) -> Option<ViewMaps> {
    let bytes = db.sections.get(VIEW_MAPS_SECTION)?;
    ViewMaps::from_bytes(bytes, db.views().len(), db.params.colours as usize)
}

/// Records `maps` in `db`.
pub fn store_view_maps(db: &mut ViewDatabase, maps: &ViewMaps) {
    db.sections
        .insert(VIEW_MAPS_SECTION.to_owned(), maps.to_bytes());
}

/// The colour maps of `db`'s views from the labelled views it was trained
/// on (as [`crate::train::build_database`] groups them: the views of one
/// pose make one map, their mean), quantised by its palette, in cells of
/// [`MAP_CELLS_ACROSS`] across its median view at the training scale.
pub fn measure_view_maps(
    db: &ViewDatabase,
    views: &[LabelledView<'_>],
) -> Result<ViewMaps, TrainError> {
    let cell_px = db.median_size_px() / MAP_CELLS_ACROSS;
    let colours = db.params.colours as usize;
    let mut index = IndexImage::default();
    let mut maps = Vec::with_capacity(db.views().len());
    for group in pose_groups(views) {
        let measured: Vec<ColourMap> = group
            .iter()
            .filter_map(|&i| {
                let v = &views[i];
                let roi = mask_bbox(v.mask, v.width, v.height)?;
                db.palette
                    .quantise_into(v.rgb, v.width, v.height, &mut index);
                ColourMap::measure(&index, Some(v.mask), roi, colours, cell_px * v.scale, 0.0)
            })
            .collect();
        if measured.is_empty() {
            continue;
        }
        // Views of one pose share a mask, so their maps one size; should
        // they not, the first stands for the pose.
        maps.push(ColourMap::mean(&measured).unwrap_or_else(|| measured[0].clone()));
    }
    if maps.len() != db.views().len() {
        return Err(TrainError::ViewsMoved {
            views: db.views().len(),
            maps: maps.len(),
        });
    }
    Ok(ViewMaps { cell_px, maps })
}

impl PoseEstimator {
    /// The map rival of `estimate` (of the query last responded to:
    /// `image`, `mask`, `roi` as given to [`Self::estimate`]): the best
    /// share of the query's coloured area that a view of its θ slice
    /// `separation_deg` to [`MAP_REACH_DEG`] from its best view in
    /// azimuth holds in place, minus the share the best view holds.
    /// Above 0 a view beyond the tolerance places the visible part
    /// better. `-inf` when the database records no maps or the slice has
    /// no such view (nothing to weigh); NaN when the query has no colour
    /// to place.
    pub fn map_rival(
        &mut self,
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        estimate: &Estimate,
        separation_deg: f32,
    ) -> f32 {
        let Some(maps) = &self.view_maps else {
            return f32::NEG_INFINITY;
        };
        let colours = self.db.params.colours as usize;
        let cell_px = maps.cell_px * estimate.scale;
        if !self
            .placed
            .measure(image, mask, roi, colours, cell_px, estimate.roll_deg)
        {
            return f32::NAN;
        }
        let best = estimate.best_view;
        let views = self.db.views();
        let slice = self.slices[self.slice_of[best]];
        let mut far = (slice.start..slice.start + slice.len)
            .filter(|&i| {
                let d = phi_error(views[i].phi_deg, views[best].phi_deg);
                d >= separation_deg && d <= MAP_REACH_DEG
            })
            .map(|i| &maps.maps[i])
            .peekable();
        if far.peek().is_none() {
            return f32::NEG_INFINITY;
        }
        let rival = self.placed.best_share_held_by(far, MAP_MARGIN_CELLS);
        rival
            - self
                .placed
                .share_held_by(&maps.maps[best], MAP_MARGIN_CELLS)
    }

    /// Whether the database records its views' colour maps (else no
    /// estimate has a map rival).
    pub fn has_view_maps(&self) -> bool {
        self.view_maps.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_maps_read_back_as_written_and_a_bad_section_is_refused() {
        let maps = ViewMaps {
            cell_px: 6.5,
            maps: vec![
                ColourMap::from_parts(2, 1, 3, vec![1, 2, 3, 4, 5, 6]).unwrap(),
                ColourMap::from_parts(1, 2, 3, vec![7, 8, 9, 10, 11, 12]).unwrap(),
            ],
        };
        let bytes = maps.to_bytes();
        assert_eq!(ViewMaps::from_bytes(&bytes, 2, 3), Some(maps.clone()));
        // Another count of views or colours, a byte short or over, a bad
        // cell size: refused.
        assert_eq!(ViewMaps::from_bytes(&bytes, 1, 3), None);
        assert_eq!(ViewMaps::from_bytes(&bytes, 2, 2), None);
        assert_eq!(ViewMaps::from_bytes(&bytes[..bytes.len() - 1], 2, 3), None);
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(ViewMaps::from_bytes(&longer, 2, 3), None);
        for cell in [0.0f32, -1.0, f32::NAN] {
            let mut bad = bytes.clone();
            bad[..4].copy_from_slice(&cell.to_le_bytes());
            assert_eq!(ViewMaps::from_bytes(&bad, 2, 3), None, "{cell}");
        }
    }
}
