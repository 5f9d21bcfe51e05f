//! The shape model: for every view of a grid over the sphere, the object's
//! silhouette (a small bitmap normalised by its centroid and area, for the
//! search against a region) and its contour (points on the object's
//! surface where it meets the background, with the outward direction of
//! the silhouette there, for the fit to the image's edges).

use crate::geometry::View;
use acch_capture::{Intrinsics, Object, render_posed, world_from_camera_rotation};
use glam::{DAffine3, DVec2, DVec3};
use rayon::prelude::*;

/// Side of a silhouette bitmap, cells.
pub const GRID: usize = 32;
/// 64-bit words of a silhouette bitmap.
pub const WORDS: usize = GRID * GRID / 64;
/// Half the side a bitmap covers, in units of the square root of the
/// silhouette's area: elongated objects reach about 1.5 from their
/// centroid.
pub const GRID_HALF_EXTENT: f64 = 2.0;
/// Camera distance of the template views, object radii.
pub const TEMPLATE_DISTANCE: f64 = 10.0;
/// Focal length of the template views, pixels: a radius is 56 pixels.
const TEMPLATE_FOCAL: f64 = 560.0;
/// Side of a template image, pixels.
const TEMPLATE_SIZE: u32 = 144;
/// About this many contour points are kept per view.
pub const CONTOUR_POINTS: usize = 128;

/// One point of a view's contour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContourPoint {
    /// The surface point, object frame.
    pub object: [f32; 3],
    /// The silhouette's outward direction there, as a direction in the
    /// object frame (in the view's image plane).
    pub normal: [f32; 3],
}

/// One view's shape.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeView {
    /// Elevation, degrees.
    pub theta_deg: f32,
    /// Azimuth, degrees.
    pub phi_deg: f32,
    /// The silhouette's centroid relative to the centre's projection, in
    /// object radii at the object's distance (x right, y down, unrolled).
    pub centroid: [f32; 2],
    /// The silhouette's area, square object radii at the object's distance.
    pub area: f32,
    /// The silhouette, normalised: cell (i, j) at `centroid + sqrt(area) *
    /// GRID_HALF_EXTENT * ((j + 0.5) / GRID * 2 - 1, (i + 0.5) / GRID * 2 -
    /// 1)`, row-major, bit `k % 64` of word `k / 64`.
    pub silhouette: [u64; WORDS],
    /// Contour points.
    pub contour: Vec<ContourPoint>,
    /// Edges inside the silhouette (creases and colour changes of the
    /// rendered view): the surface point and the direction of the
    /// rendered image's gradient there, as a direction in the object frame.
    pub inner_edges: Vec<ContourPoint>,
    /// Colours inside the silhouette: the surface point and the rendered
    /// colour's chromaticity (r and g over r + g + b), which shading does
    /// not change.
    pub colours: Vec<ColourPoint>,
}

/// A colour of the object's surface in one view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourPoint {
    /// The surface point, object frame.
    pub object: [f32; 3],
    /// Chromaticity: r / (r + g + b) and g / (r + g + b).
    pub chroma: [f32; 2],
}

/// Views and their shapes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeModel {
    /// The object's real bounding radius, metres: one object unit.
    pub radius_m: f64,
    /// The views.
    pub views: Vec<ShapeView>,
    /// Each view's camera direction, for [`ShapeModel::nearest_view`].
    directions: Vec<DVec3>,
}

/// Why a shape model could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ShapeModelError {
    /// The bytes end early or say something impossible.
    #[error("the shape model is corrupt: {0}")]
    Corrupt(&'static str),
    /// Written by another layout.
    #[error("the shape model has layout version {0}; this build reads {LAYOUT}")]
    Version(u32),
}

/// Layout version of [`ShapeModel::to_bytes`].
const LAYOUT: u32 = 3;

/// The intrinsics of a template image.
fn template_intrinsics() -> Intrinsics {
    let c = (TEMPLATE_SIZE as f64 - 1.0) / 2.0;
    Intrinsics {
        width: TEMPLATE_SIZE,
        height: TEMPLATE_SIZE,
        fx: TEMPLATE_FOCAL,
        fy: TEMPLATE_FOCAL,
        cx: c,
        cy: c,
    }
}

/// Pixels per object radius in a template image.
fn template_scale() -> f64 {
    TEMPLATE_FOCAL / TEMPLATE_DISTANCE
}

impl ShapeModel {
    /// The shape of `object` from each of `views` (θ, φ in degrees).
    pub fn train(object: &Object, views: &[(f64, f64)]) -> ShapeModel {
        ShapeModel::of_views(
            object.radius_m(),
            views
                .par_iter()
                .map(|&(theta, phi)| shape_view(object, theta, phi))
                .collect(),
        )
    }

    /// The model of these views.
    pub fn of_views(radius_m: f64, views: Vec<ShapeView>) -> ShapeModel {
        let directions = views
            .iter()
            .map(|v| direction(v.theta_deg as f64, v.phi_deg as f64))
            .collect();
        ShapeModel {
            radius_m,
            views,
            directions,
        }
    }

    /// The model as bytes (little-endian), for a database section.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend(LAYOUT.to_le_bytes());
        out.extend(self.radius_m.to_le_bytes());
        out.extend((self.views.len() as u32).to_le_bytes());
        for v in &self.views {
            for x in [v.theta_deg, v.phi_deg, v.centroid[0], v.centroid[1], v.area] {
                out.extend(x.to_le_bytes());
            }
            for w in v.silhouette {
                out.extend(w.to_le_bytes());
            }
            for list in [&v.contour, &v.inner_edges] {
                out.extend((list.len() as u32).to_le_bytes());
                for p in list {
                    for x in p.object.iter().chain(&p.normal) {
                        out.extend(x.to_le_bytes());
                    }
                }
            }
            out.extend((v.colours.len() as u32).to_le_bytes());
            for p in &v.colours {
                for x in p.object.iter().chain(&p.chroma) {
                    out.extend(x.to_le_bytes());
                }
            }
        }
        out
    }

    /// Reads [`ShapeModel::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<ShapeModel, ShapeModelError> {
        let mut r = Reader(bytes);
        let layout = r.u32()?;
        if layout != LAYOUT {
            return Err(ShapeModelError::Version(layout));
        }
        let radius_m = f64::from_le_bytes(r.take()?);
        if !(radius_m.is_finite() && radius_m > 0.0) {
            return Err(ShapeModelError::Corrupt(
                "the radius is not a positive length",
            ));
        }
        let n = r.u32()? as usize;
        let mut views = Vec::with_capacity(n.min(1 << 16));
        for _ in 0..n {
            let [theta_deg, phi_deg, cx, cy, area] =
                [r.f32()?, r.f32()?, r.f32()?, r.f32()?, r.f32()?];
            let mut silhouette = [0u64; WORDS];
            for w in &mut silhouette {
                *w = r.u64()?;
            }
            let mut lists = [Vec::new(), Vec::new()];
            for list in &mut lists {
                let m = r.u32()? as usize;
                if m > r.0.len() / 24 {
                    return Err(ShapeModelError::Corrupt("more points than bytes"));
                }
                list.reserve(m);
                for _ in 0..m {
                    let mut f = [0f32; 6];
                    for x in &mut f {
                        *x = r.f32()?;
                    }
                    list.push(ContourPoint {
                        object: [f[0], f[1], f[2]],
                        normal: [f[3], f[4], f[5]],
                    });
                }
            }
            let m = r.u32()? as usize;
            if m > r.0.len() / 20 {
                return Err(ShapeModelError::Corrupt("more colours than bytes"));
            }
            let mut colours = Vec::with_capacity(m);
            for _ in 0..m {
                let mut f = [0f32; 5];
                for x in &mut f {
                    *x = r.f32()?;
                }
                colours.push(ColourPoint {
                    object: [f[0], f[1], f[2]],
                    chroma: [f[3], f[4]],
                });
            }
            let [contour, inner_edges] = lists;
            views.push(ShapeView {
                theta_deg,
                phi_deg,
                centroid: [cx, cy],
                area,
                silhouette,
                contour,
                inner_edges,
                colours,
            });
        }
        if !r.0.is_empty() {
            return Err(ShapeModelError::Corrupt("bytes after the last view"));
        }
        Ok(ShapeModel::of_views(radius_m, views))
    }

    /// The view of the model nearest to the direction of `view` (its
    /// camera's position), by the angle between the two.
    pub fn nearest_view(&self, view: &View) -> usize {
        let d = direction(view.theta_deg, view.phi_deg);
        let mut best = (f64::NEG_INFINITY, 0);
        for (i, v) in self.directions.iter().enumerate() {
            let c = v.dot(d);
            if c > best.0 {
                best = (c, i);
            }
        }
        best.1
    }
}

/// The unit direction of the camera at elevation `theta` and azimuth `phi`.
pub fn direction(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    DVec3::new(ct * cp, ct * sp, st)
}

struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], ShapeModelError> {
        if self.0.len() < N {
            return Err(ShapeModelError::Corrupt("ends early"));
        }
        let (a, b) = self.0.split_at(N);
        self.0 = b;
        Ok(a.try_into().expect("N bytes"))
    }
    fn u32(&mut self) -> Result<u32, ShapeModelError> {
        self.take().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Result<u64, ShapeModelError> {
        self.take().map(u64::from_le_bytes)
    }
    fn f32(&mut self) -> Result<f32, ShapeModelError> {
        self.take().map(f32::from_le_bytes)
    }
}

/// The camera-from-object pose of an unrolled template view.
pub(crate) fn template_pose(theta: f64, phi: f64) -> DAffine3 {
    let world_from_camera = world_from_camera_rotation(theta, phi, 0.0);
    DAffine3::from_mat3_translation(
        world_from_camera.transpose(),
        DVec3::new(0.0, 0.0, TEMPLATE_DISTANCE),
    )
}

/// Renders one view and reads its shape.
fn shape_view(object: &Object, theta: f64, phi: f64) -> ShapeView {
    let k = template_intrinsics();
    let pose = template_pose(theta, phi);
    let render = render_posed(&[(object, pose, 1.0)], &k);
    let (w, h) = (k.width as usize, k.height as usize);
    let mask: Vec<bool> = render.labels.iter().map(|&l| l != 0).collect();
    let scale = template_scale();
    let centre = DVec2::new(k.cx, k.cy);
    // Centroid and area.
    let (mut n, mut sx, mut sy) = (0usize, 0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            if mask[y * w + x] {
                n += 1;
                sx += x as f64;
                sy += y as f64;
            }
        }
    }
    let n_f = n.max(1) as f64;
    let centroid_px = DVec2::new(sx / n_f, sy / n_f);
    let side = (n_f).sqrt();
    let silhouette = bitmap(|p| {
        let q = centroid_px + p * side;
        let (x, y) = (q.x.round(), q.y.round());
        x >= 0.0
            && y >= 0.0
            && (x as usize) < w
            && (y as usize) < h
            && mask[y as usize * w + x as usize]
    });
    let contour = contour_points(&mask, &render.depth, w, h, &k, &pose);
    let (inner_edges, colours) = inner_points(&mask, &render.rgb, &render.depth, w, h, &k, &pose);
    let c = (centroid_px - centre) / scale;
    ShapeView {
        theta_deg: theta as f32,
        phi_deg: phi as f32,
        centroid: [c.x as f32, c.y as f32],
        area: (n as f64 / (scale * scale)) as f32,
        silhouette,
        contour,
        inner_edges,
        colours,
    }
}

/// Points well inside the silhouette (three pixels from its edge): the
/// strongest rendered gradient of each cell of a grid sized for about
/// [`INNER_POINTS`], and one colour per cell.
fn inner_points(
    mask: &[bool],
    rgb: &[u8],
    depth: &[f32],
    w: usize,
    h: usize,
    k: &Intrinsics,
    pose: &DAffine3,
) -> (Vec<ContourPoint>, Vec<ColourPoint>) {
    let inside = |x: usize, y: usize| {
        x >= 3
            && y >= 3
            && x + 3 < w
            && y + 3 < h
            && (0..7).all(|dy| (0..7).all(|dx| mask[(y + dy - 3) * w + x + dx - 3]))
    };
    let area = mask.iter().filter(|&&m| m).count().max(1);
    let cell = ((area as f64 / INNER_POINTS as f64).sqrt().round() as usize).max(2);
    let object_from_camera = pose.inverse();
    let lift = |x: usize, y: usize| -> Option<DVec3> {
        let z = depth[y * w + x] as f64;
        (z > 0.0).then(|| {
            object_from_camera.transform_point3(DVec3::new(
                (x as f64 - k.cx) / k.fx * z,
                (y as f64 - k.cy) / k.fy * z,
                z,
            ))
        })
    };
    let at = |x: usize, y: usize, c: usize| rgb[3 * (y * w + x) + c] as f64;
    let (mut edges, mut colours) = (Vec::new(), Vec::new());
    for cy in (0..h).step_by(cell) {
        for cx in (0..w).step_by(cell) {
            let mut best: Option<(f64, usize, usize, DVec2)> = None;
            for y in cy..(cy + cell).min(h) {
                for x in cx..(cx + cell).min(w) {
                    if !inside(x, y) {
                        continue;
                    }
                    // The strongest channel's Sobel gradient.
                    let mut g = DVec2::ZERO;
                    for c in 0..3 {
                        let gx = at(x + 1, y - 1, c) + 2.0 * at(x + 1, y, c) + at(x + 1, y + 1, c)
                            - at(x - 1, y - 1, c)
                            - 2.0 * at(x - 1, y, c)
                            - at(x - 1, y + 1, c);
                        let gy = at(x - 1, y + 1, c) + 2.0 * at(x, y + 1, c) + at(x + 1, y + 1, c)
                            - at(x - 1, y - 1, c)
                            - 2.0 * at(x, y - 1, c)
                            - at(x + 1, y - 1, c);
                        let v = DVec2::new(gx, gy);
                        if v.length_squared() > g.length_squared() {
                            g = v;
                        }
                    }
                    if best.is_none_or(|b| g.length() > b.0) {
                        best = Some((g.length(), x, y, g));
                    }
                }
            }
            let Some((strength, x, y, g)) = best else {
                continue;
            };
            // The cell's centre pixel's colour, when inside.
            let (mx, my) = ((cx + cell / 2).min(w - 1), (cy + cell / 2).min(h - 1));
            if inside(mx, my)
                && let Some(o) = lift(mx, my)
            {
                let sum = at(mx, my, 0) + at(mx, my, 1) + at(mx, my, 2) + 1.0;
                colours.push(ColourPoint {
                    object: o.as_vec3().to_array(),
                    chroma: [(at(mx, my, 0) / sum) as f32, (at(mx, my, 1) / sum) as f32],
                });
            }
            if strength < INNER_GRADIENT {
                continue;
            }
            if let Some(o) = lift(x, y) {
                let d = g / strength;
                let dir = object_from_camera.matrix3 * DVec3::new(d.x, d.y, 0.0);
                edges.push(ContourPoint {
                    object: o.as_vec3().to_array(),
                    normal: dir.as_vec3().to_array(),
                });
            }
        }
    }
    (edges, colours)
}

/// About this many inner edge and colour points are kept per view.
pub const INNER_POINTS: usize = 64;
/// The rendered gradient (Sobel, one channel) an inner edge needs.
const INNER_GRADIENT: f64 = 80.0;

/// A normalised bitmap: bit set where `inside(p)` holds for the cell's
/// centre `p` in units of the square root of the area about the centroid
/// (unrotated).
pub(crate) fn bitmap(inside: impl Fn(DVec2) -> bool) -> [u64; WORDS] {
    let mut bits = [0u64; WORDS];
    for i in 0..GRID {
        for j in 0..GRID {
            if inside(grid_point(i, j)) {
                let k = i * GRID + j;
                bits[k / 64] |= 1 << (k % 64);
            }
        }
    }
    bits
}

/// The centre of cell (i, j), in units of the square root of the area.
fn grid_point(i: usize, j: usize) -> DVec2 {
    let u = |k: usize| ((k as f64 + 0.5) / GRID as f64 * 2.0 - 1.0) * GRID_HALF_EXTENT;
    DVec2::new(u(j), u(i))
}

/// Points on the silhouette's boundary (the object's pixels with a
/// neighbour outside it, holes included), thinned to about
/// [`CONTOUR_POINTS`] spread evenly, each lifted onto the surface by the
/// depth and given the outward direction of the smoothed mask.
fn contour_points(
    mask: &[bool],
    depth: &[f32],
    w: usize,
    h: usize,
    k: &Intrinsics,
    pose: &DAffine3,
) -> Vec<ContourPoint> {
    let at = |x: isize, y: isize| -> f64 {
        if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
            0.0
        } else {
            f64::from(u8::from(mask[y as usize * w + x as usize]))
        }
    };
    let mut boundary = Vec::new();
    for y in 0..h as isize {
        for x in 0..w as isize {
            if at(x, y) > 0.0
                && (at(x - 1, y) == 0.0
                    || at(x + 1, y) == 0.0
                    || at(x, y - 1) == 0.0
                    || at(x, y + 1) == 0.0)
            {
                boundary.push((x, y));
            }
        }
    }
    if boundary.is_empty() {
        return Vec::new();
    }
    // Thin to one point per cell of a grid sized for the wanted count
    // (the boundary's length in pixels is about its pixel count).
    let cell = ((boundary.len() as f64 / CONTOUR_POINTS as f64).max(1.0)).round() as isize;
    let mut taken = std::collections::BTreeMap::new();
    for &(x, y) in &boundary {
        let key = (y / cell, x / cell);
        let centre = (
            (key.1 * cell) as f64 + cell as f64 / 2.0,
            (key.0 * cell) as f64 + cell as f64 / 2.0,
        );
        let d = (x as f64 - centre.0).powi(2) + (y as f64 - centre.1).powi(2);
        taken
            .entry(key)
            .and_modify(|e: &mut (f64, isize, isize)| {
                if d < e.0 {
                    *e = (d, x, y);
                }
            })
            .or_insert((d, x, y));
    }
    let object_from_camera = pose.inverse();
    let world_from_camera = object_from_camera.matrix3;
    let mut out = Vec::with_capacity(taken.len());
    for &(_, x, y) in taken.values() {
        // The mask's gradient over a 5x5 neighbourhood points inwards.
        let (mut gx, mut gy) = (0.0, 0.0);
        for dy in -2..=2isize {
            for dx in -2..=2isize {
                let m = at(x + dx, y + dy);
                gx += m * dx as f64;
                gy += m * dy as f64;
            }
        }
        let g = DVec2::new(gx, gy);
        if g.length() < 1e-9 {
            continue;
        }
        let outward = -g.normalize();
        let z = depth[y as usize * w + x as usize] as f64;
        if z <= 0.0 {
            continue;
        }
        let camera = DVec3::new(
            (x as f64 - k.cx) / k.fx * z,
            (y as f64 - k.cy) / k.fy * z,
            z,
        );
        let object = object_from_camera.transform_point3(camera);
        let normal = world_from_camera * DVec3::new(outward.x, outward.y, 0.0);
        out.push(ContourPoint {
            object: object.as_vec3().to_array(),
            normal: normal.as_vec3().to_array(),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn can_model() -> ShapeModel {
        let can = Object::builtin("can").unwrap();
        ShapeModel::train(&can, &[(30.0, 0.0), (90.0, 0.0), (-10.0, 200.0)])
    }

    #[test]
    fn a_model_reads_back_and_refuses_damage() {
        let model = can_model();
        let bytes = model.to_bytes();
        assert_eq!(ShapeModel::from_bytes(&bytes).unwrap(), model);
        assert!(ShapeModel::from_bytes(&bytes[..bytes.len() - 3]).is_err());
        let mut other = bytes.clone();
        other[0] = 9;
        assert!(matches!(
            ShapeModel::from_bytes(&other),
            Err(ShapeModelError::Version(9))
        ));
    }

    #[test]
    fn contour_points_lie_on_the_surface_at_the_silhouettes_edge() {
        let model = can_model();
        for v in &model.views {
            assert!(
                (CONTOUR_POINTS / 2..CONTOUR_POINTS * 2).contains(&v.contour.len()),
                "{}",
                v.contour.len()
            );
            let pose = template_pose(v.theta_deg as f64, v.phi_deg as f64);
            let k = template_intrinsics();
            for p in &v.contour {
                let o = glam::Vec3::from_array(p.object).as_dvec3();
                // On the can: within its bounding sphere, near its surface.
                assert!(o.length() <= 1.01, "{o}");
                // Projected, a step outwards leaves the silhouette's disc
                // about the centroid farther than the point itself.
                let px = k.project(pose.transform_point3(o)).unwrap();
                let n = glam::Vec3::from_array(p.normal).as_dvec3();
                let out = k.project(pose.transform_point3(o + n * 0.05)).unwrap();
                let c = DVec2::new(k.cx, k.cy)
                    + DVec2::from(v.centroid.map(f64::from)) * template_scale();
                assert!(
                    (out - c).length() > (px - c).length() - 0.5,
                    "{px} {out} {c}"
                );
            }
        }
        // From above, the can is a disc: area pi * r^2 of its radius
        // (0.7 of the bounding radius for a can 8.4 cm wide and 12 cm
        // tall), centred on the centre.
        let top = &model.views[1];
        let r = (0.042f64).hypot(0.06);
        // The top is nearer the camera than the centre, so larger.
        let nearer = TEMPLATE_DISTANCE / (TEMPLATE_DISTANCE - 0.06 / r);
        let expected = std::f64::consts::PI * (0.042 / r * nearer).powi(2);
        assert!(
            (top.area as f64 / expected - 1.0).abs() < 0.12,
            "{} {expected}",
            top.area
        );
        assert!(top.centroid[0].abs() < 0.05 && top.centroid[1].abs() < 0.05);
    }
}
