//! The silhouette search: the region's shape against every view's
//! silhouette, over rolls, each normalised by its centroid and area (so
//! the object's distance need not be known), by the overlap of the two
//! bitmaps. Each match is a candidate pose.

use crate::geometry::{View, pose_of, towards};
use crate::model::{ShapeModel, WORDS, bitmap};
use acch_capture::Intrinsics;
use glam::{DAffine3, DMat2, DMat3, DVec2};

/// A region of an image: the pixels taken for the object, over a
/// rectangle of it.
#[derive(Clone, Copy, Debug)]
pub struct Region<'a> {
    /// Non-zero where the object is, row-major over the rectangle.
    pub mask: &'a [u8],
    /// The rectangle's left column and top row in the image.
    pub x0: u32,
    /// Top row.
    pub y0: u32,
    /// The rectangle's width (its height is the mask's length over it).
    pub width: u32,
    /// The camera of the whole image.
    pub k: &'a Intrinsics,
}

impl<'a> Region<'a> {
    /// A region over the whole image of `k`.
    pub fn whole(mask: &'a [u8], k: &'a Intrinsics) -> Self {
        Region {
            mask,
            x0: 0,
            y0: 0,
            width: k.width,
            k,
        }
    }

    /// The rectangle's height.
    pub fn height(&self) -> u32 {
        (self.mask.len() / self.width.max(1) as usize) as u32
    }

    /// Whether the image pixel nearest `p` is in the region.
    pub fn contains(&self, p: DVec2) -> bool {
        let (x, y) = (p.x.round() - self.x0 as f64, p.y.round() - self.y0 as f64);
        x >= 0.0
            && y >= 0.0
            && x < self.width as f64
            && y < self.height() as f64
            && self.mask[y as usize * self.width as usize + x as usize] != 0
    }

    /// The image pixels of the region.
    fn pixels(&self) -> impl Iterator<Item = DVec2> + '_ {
        let w = self.width.max(1) as usize;
        self.mask
            .iter()
            .enumerate()
            .filter(|(_, m)| **m != 0)
            .map(move |(i, _)| {
                DVec2::new(
                    (i % w) as f64 + self.x0 as f64,
                    (i / w) as f64 + self.y0 as f64,
                )
            })
    }
}

/// A candidate pose from the silhouette search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// The model's view.
    pub view: usize,
    /// The roll, degrees.
    pub roll_deg: f64,
    /// The overlap of the two normalised silhouettes (intersection over
    /// union of their bitmaps).
    pub overlap: f32,
    /// The pose the match makes: the view rolled, at the distance the
    /// region's size says, its centre where the region's centroid says.
    pub pose: DAffine3,
}

/// The region normalised: seen by the camera turned towards its centroid.
struct Normalised {
    real_from_turned: DMat3,
    /// Centroid, turned pixels.
    centroid: DVec2,
    /// Square root of the area, turned pixels.
    side: f64,
}

/// Maps a turned camera's pixel to the real camera's (same intrinsics).
fn to_real(k: &Intrinsics, real_from_turned: &DMat3, turned_px: DVec2) -> Option<DVec2> {
    k.project(*real_from_turned * k.ray(turned_px))
}

fn normalise(region: &Region) -> Option<Normalised> {
    let k = region.k;
    let (mut n, mut sum) = (0usize, DVec2::ZERO);
    for p in region.pixels() {
        n += 1;
        sum += p;
    }
    if n < 16 {
        return None;
    }
    let real_from_turned = towards(k, sum / n as f64);
    let turned_from_real = real_from_turned.transpose();
    // Each pixel's area in the turned camera is 1 / z^3 of its ray
    // (z = 1 in the real camera) turned.
    let (mut area, mut m) = (0.0, DVec2::ZERO);
    for p in region.pixels() {
        let v = turned_from_real * k.ray(p);
        let a = 1.0 / (v.z * v.z * v.z);
        let px = DVec2::new(k.fx * v.x / v.z + k.cx, k.fy * v.y / v.z + k.cy);
        area += a;
        m += a * px;
    }
    Some(Normalised {
        real_from_turned,
        centroid: m / area,
        side: area.sqrt(),
    })
}

/// How a template point turns with the roll: `q' = roll_matrix(ρ) q`
/// (x right, y down; the image turns counter-clockwise).
pub fn roll_matrix(roll_deg: f64) -> DMat2 {
    let (s, c) = roll_deg.to_radians().sin_cos();
    DMat2::from_cols(glam::DVec2::new(c, -s), glam::DVec2::new(s, c))
}

/// The region's bitmap as a view rolled by `roll_deg` would make it.
fn region_bitmap(region: &Region, norm: &Normalised, roll_deg: f64) -> [u64; WORDS] {
    let k = region.k;
    let m = roll_matrix(roll_deg);
    bitmap(|g| {
        let turned = norm.centroid + m * g * norm.side;
        to_real(k, &norm.real_from_turned, turned).is_some_and(|p| region.contains(p))
    })
}

pub(crate) fn overlap(a: &[u64; WORDS], b: &[u64; WORDS]) -> f32 {
    let (mut inter, mut union) = (0u32, 0u32);
    for (x, y) in a.iter().zip(b) {
        inter += (x & y).count_ones();
        union += (x | y).count_ones();
    }
    if union == 0 {
        0.0
    } else {
        inter as f32 / union as f32
    }
}

/// The `keep` best (view, roll) pairs of `model` for `region`, best first,
/// the roll tried every `roll_step_deg` within ±`max_roll_deg` (180: any);
/// each view keeps its best roll only. Empty when the region has fewer
/// than 16 pixels.
pub fn search(
    model: &ShapeModel,
    region: &Region,
    roll_step_deg: f64,
    max_roll_deg: f64,
    keep: usize,
) -> Vec<Candidate> {
    let Some(norm) = normalise(region) else {
        return Vec::new();
    };
    let step = roll_step_deg.max(0.1);
    let half = (max_roll_deg.clamp(0.0, 180.0) / step).floor() as i64;
    // A full turn tries -180 once, not twice.
    let low = if half as f64 * step >= 180.0 {
        -half + 1
    } else {
        -half
    };
    let roll_list: Vec<f64> = (low..=half).map(|i| i as f64 * step).collect();
    let rolls = roll_list.len();
    let roll_of = |r: usize| roll_list[r];
    let bitmaps: Vec<[u64; WORDS]> = (0..rolls)
        .map(|r| region_bitmap(region, &norm, roll_of(r)))
        .collect();
    let mut best: Vec<(f32, usize, usize)> = model
        .views
        .iter()
        .enumerate()
        .map(|(v, view)| {
            let (o, r) = bitmaps
                .iter()
                .enumerate()
                .map(|(r, b)| (overlap(b, &view.silhouette), r))
                .fold((f32::MIN, 0), |a, b| if b.0 > a.0 { b } else { a });
            (o, v, r)
        })
        .collect();
    best.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    best.truncate(keep);
    best.into_iter()
        .map(|(o, v, r)| {
            let roll = roll_of(r);
            Candidate {
                view: v,
                roll_deg: roll,
                overlap: o,
                pose: placed_pose(model, v, roll, region.k, &norm),
            }
        })
        .collect()
}

/// How well the silhouette of `pose` covers `region`: the intersection
/// over union of the silhouette of the model's view `view` placed at the
/// pose and the region, over the view's bitmap.
pub fn overlap_at(model: &ShapeModel, view: usize, pose: &DAffine3, region: &Region) -> f32 {
    let k = region.k;
    let Some(centre) = k.project(pose.translation) else {
        return 0.0;
    };
    let seen = crate::geometry::view_of(pose);
    let real_from_turned = towards(k, centre);
    let v = &model.views[view];
    let scale = k.fx / seen.distance;
    let m = roll_matrix(seen.roll_deg);
    let c = DVec2::new(v.centroid[0] as f64, v.centroid[1] as f64);
    let side = (v.area as f64).sqrt();
    let turned_centre = DVec2::new(k.cx, k.cy);
    let bits = bitmap(|g| {
        let q = c + g * side;
        let turned = turned_centre + m * q * scale;
        to_real(k, &real_from_turned, turned).is_some_and(|p| region.contains(p))
    });
    overlap(&bits, &v.silhouette)
}

/// The pose of the model's view nearest (`theta_deg`, `phi_deg`) rolled
/// by `roll_deg`, placed over `region` by its centroid and area (a
/// candidate from another estimate of the view, such as the colour
/// histograms'); `None` for a region of fewer than 16 pixels.
pub fn place_view(
    model: &ShapeModel,
    theta_deg: f64,
    phi_deg: f64,
    roll_deg: f64,
    region: &Region,
) -> Option<DAffine3> {
    let norm = normalise(region)?;
    let v = model.nearest_view(&View {
        theta_deg,
        phi_deg,
        roll_deg,
        distance: 1.0,
    });
    Some(placed_pose(model, v, roll_deg, region.k, &norm))
}

/// The pose of view `v` rolled by `roll_deg` whose silhouette covers the
/// normalised region.
fn placed_pose(
    model: &ShapeModel,
    v: usize,
    roll_deg: f64,
    k: &Intrinsics,
    norm: &Normalised,
) -> DAffine3 {
    let view = &model.views[v];
    // Turned pixels per object radius, and the distance that makes it.
    let scale = norm.side / (view.area as f64).sqrt();
    let distance = k.fx / scale;
    let centroid = DVec2::new(view.centroid[0] as f64, view.centroid[1] as f64);
    let centre_turned = norm.centroid - roll_matrix(roll_deg) * centroid * scale;
    let centre = to_real(k, &norm.real_from_turned, centre_turned).unwrap_or(norm.centroid);
    pose_of(
        &View {
            theta_deg: view.theta_deg as f64,
            phi_deg: view.phi_deg as f64,
            roll_deg,
            distance,
        },
        k,
        centre,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{rotation_angle_deg, view_of};
    use acch_capture::render_posed;

    #[test]
    fn a_rendered_view_finds_its_own_view_and_roll_anywhere_in_the_image() {
        let (object, grid, model) = crate::testing::tricolor();
        let k = Intrinsics::default();
        for (v, roll, px) in [
            (4usize, 0.0, DVec2::new(320.0, 240.0)),
            (15, 40.0, DVec2::new(480.0, 120.0)),
            (30, -120.0, DVec2::new(150.0, 380.0)),
        ] {
            let (theta, phi) = grid[v];
            let truth = pose_of(
                &View {
                    theta_deg: theta,
                    phi_deg: phi,
                    roll_deg: roll,
                    distance: 8.0,
                },
                &k,
                px,
            );
            let render = render_posed(&[(&object, truth, 1.0)], &k);
            let region = Region::whole(&render.labels, &k);
            let found = search(&model, &region, 5.0, 180.0, 3);
            let best = found[0];
            assert_eq!(best.view, v, "{found:?}");
            assert!(best.overlap > 0.9, "{found:?}");
            let d = (best.roll_deg - roll + 540.0).rem_euclid(360.0) - 180.0;
            assert!(d.abs() <= 5.0, "{found:?}");
            // The placed pose is near the truth.
            assert!(rotation_angle_deg(&best.pose.matrix3, &truth.matrix3) < 8.0);
            let back = view_of(&best.pose);
            assert!((back.distance / 8.0 - 1.0).abs() < 0.08, "{back:?}");
            let c = k.project(best.pose.translation).unwrap();
            assert!((c - px).length() < 6.0, "{c} {px}");
        }
    }
}
