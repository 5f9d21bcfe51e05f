//! What a fitted pose explains of the image, measured several ways; each
//! is a share or a correlation in [-1, 1], so one policy can weigh them
//! for any object.

use crate::edges::Edges;
use crate::fit::{FitParams, Projected, find_edge, project_contour, project_points};
use crate::lines::Image;
use crate::model::ShapeModel;
use crate::search::{Region, overlap_at};
use acch_capture::Intrinsics;
use glam::{DAffine3, Vec3};

/// The evidence for one pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Evidence {
    /// Share of the contour that falls in the frame: the measures below
    /// judge that part only.
    pub in_frame: f32,
    /// How sharply the object's colours part from its surroundings across
    /// the contour (the colour fit's own measure).
    pub separation: f32,
    /// The silhouette against the region, intersection over union.
    pub overlap: f32,
    /// Share of the contour points that lie on the region's edge (the
    /// region inside them, not outside).
    pub region_edge: f32,
    /// Share of the contour points that lie on an image edge of their
    /// direction.
    pub contour_edges: f32,
    /// Share of the edges inside the rendered view found in the image.
    pub inner_edges: f32,
    /// Correlation of the rendered view's chromaticity with the image's
    /// over the region (0 when the view's colours barely vary).
    pub colour: f32,
    /// The colour histograms' match of the pose's view over their best
    /// view's, in [0, 1] (0 when not weighed).
    pub histograms: f32,
}

/// Measures `pose` of view `view`.
#[allow(clippy::too_many_arguments)]
pub fn evidence(
    model: &ShapeModel,
    view: usize,
    pose: &DAffine3,
    separation: f32,
    image: &Image,
    edges: &Edges,
    k: &Intrinsics,
    region: &Region,
) -> Evidence {
    let params = FitParams::default();
    let mut points: Vec<Projected> = Vec::new();
    project_contour(model, view, pose, k, &mut points);
    let n = points.len().max(1) as f32;
    let in_frame = points.len() as f32 / model.views[view].contour.len().max(1) as f32;
    let region_edge = points
        .iter()
        .filter(|p| {
            region.contains(p.px - p.normal * 2.0) && !region.contains(p.px + p.normal * 2.0)
        })
        .count() as f32
        / n;
    let contour_edges = points
        .iter()
        .filter(|p| find_edge(edges, p.px, p.normal, params.explained_px, &params).is_some())
        .count() as f32
        / n;
    project_points(&model.views[view].inner_edges, pose, k, &mut points);
    let cos_max = params.max_angle_deg.to_radians().cos() as f32;
    let found = points
        .iter()
        .filter(|p| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (gx, gy) = edges.at(p.px.x + dx as f64, p.px.y + dy as f64);
                    let m = (gx * gx + gy * gy).sqrt();
                    m >= params.min_gradient
                        && (gx * p.normal.x as f32 + gy * p.normal.y as f32).abs() >= cos_max * m
                })
            })
        })
        .count();
    let inner_edges = if points.is_empty() {
        0.0
    } else {
        found as f32 / points.len() as f32
    };
    Evidence {
        in_frame,
        separation,
        overlap: overlap_at(model, view, pose, region),
        region_edge,
        contour_edges,
        inner_edges,
        colour: colour_correlation(model, view, pose, image, k, region),
        histograms: 0.0,
    }
}

/// The correlation of the view's chromaticity with the image's at its
/// colour points that fall in the region, r and g averaged.
fn colour_correlation(
    model: &ShapeModel,
    view: usize,
    pose: &DAffine3,
    image: &Image,
    k: &Intrinsics,
    region: &Region,
) -> f32 {
    let mut sums = [[0f64; 5]; 2];
    let mut n = 0f64;
    for c in &model.views[view].colours {
        let cam = pose.transform_point3(Vec3::from_array(c.object).as_dvec3());
        let Some(px) = k.project(cam) else { continue };
        if !region.contains(px) {
            continue;
        }
        let (x, y) = (px.x.round() as usize, px.y.round() as usize);
        if x >= image.width || y >= image.height {
            continue;
        }
        let o = 3 * (y * image.width + x);
        let p = &image.rgb[o..o + 3];
        let sum = p[0] as f64 + p[1] as f64 + p[2] as f64 + 1.0;
        for (ch, s) in sums.iter_mut().enumerate() {
            let a = c.chroma[ch] as f64;
            let b = p[ch] as f64 / sum;
            s[0] += a;
            s[1] += b;
            s[2] += a * a;
            s[3] += b * b;
            s[4] += a * b;
        }
        n += 1.0;
    }
    if n < 8.0 {
        return 0.0;
    }
    let mut total = 0.0;
    for s in &sums {
        let va = s[2] - s[0] * s[0] / n;
        let vb = s[3] - s[1] * s[1] / n;
        let cov = s[4] - s[0] * s[1] / n;
        // A view whose chromaticity barely varies (a white object) says
        // nothing by correlation: its spread below 0.02 counts as none.
        if va / n < 0.02 * 0.02 || vb <= 0.0 {
            continue;
        }
        total += cov / (va * vb).sqrt();
    }
    (total / 2.0) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{View, pose_of};
    use acch_capture::render_posed;
    use glam::DVec2;

    /// The evidence of the true pose of the tricolor's view, its centre
    /// at pixel `centre`, against its own rendered silhouette.
    fn evidence_at(centre: DVec2) -> Evidence {
        let (object, grid, model) = crate::testing::tricolor();
        let k = Intrinsics::default();
        let view_index = 13;
        let (theta_deg, phi_deg) = grid[view_index];
        let view = View {
            theta_deg,
            phi_deg,
            roll_deg: 0.0,
            distance: 8.0,
        };
        let pose = pose_of(&view, &k, centre);
        let render = render_posed(&[(&object, pose, 1.0)], &k);
        let (w, h) = (k.width as usize, k.height as usize);
        let image = Image {
            rgb: &render.rgb,
            width: w,
            height: h,
        };
        let mut edges = Edges::default();
        edges.compute(&render.rgb, w, h);
        let region = Region::whole(&render.labels, &k);
        evidence(&model, view_index, &pose, 1.0, &image, &edges, &k, &region)
    }

    #[test]
    fn a_contour_beyond_the_frame_is_measured_as_such_and_explains_nothing() {
        let k = Intrinsics::default();
        let inside = evidence_at(DVec2::new(k.width as f64 / 2.0, k.height as f64 / 2.0));
        assert!(inside.in_frame > 0.99, "{inside:?}");
        assert!(inside.region_edge > 0.9, "{inside:?}");
        // Half beyond the left border: the measures judge the half inside
        // (all of it on the region's edge), and say how much that is.
        let cut = evidence_at(DVec2::new(0.0, k.height as f64 / 2.0));
        assert!(cut.in_frame > 0.3 && cut.in_frame < 0.7, "{cut:?}");
        assert!(cut.region_edge > 0.9, "{cut:?}");
    }
}
