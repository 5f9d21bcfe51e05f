//! Renderable objects: the mesh type of built-in procedural ones and of
//! meshes loaded from OBJ, PLY and glTF files, and the builder that makes
//! them. This module knows no source: [`Object::builtin`] lives in
//! `builtin`, the file loaders and the PLY writer in `mesh`.

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;

use glam::{Vec2, Vec3};

use crate::CaptureError;
use crate::paint::Canvas;
use crate::texture::Texture;

/// One triangle corner.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Vertex {
    /// Position in the object frame.
    pub p: Vec3,
    /// Unit shading normal.
    pub n: Vec3,
    /// Texture coordinates, v = 0 at the top row of the image.
    pub uv: Vec2,
    /// Colour multiplier of the texel, 0-1 per channel, in the textures'
    /// (sRGB-encoded) space: white for textured meshes, the vertex colour
    /// over a white texture for vertex-coloured ones.
    pub c: Vec3,
}

/// A textured (or vertex-coloured) triangle mesh ready to render. Target objects are normalised:
/// the centre of their axis-aligned bounding box is the origin, the farthest
/// vertex lies at distance 1 (the bounding sphere has radius 1) and z is up,
/// so the object stands on the table plane `z = table_z()`. The renderer
/// works in these normalised units; [`Object::radius_m`] is the object's
/// real bounding radius, which turns them into metres. Textures are
/// precomputed once (with mip maps), so an `Object` is cheap to render many
/// times; share it between renderers with an `Arc`.
#[derive(Debug, Clone)]
pub struct Object {
    name: String,
    pub(crate) tris: Vec<[Vertex; 3]>,
    /// Texture index per triangle.
    pub(crate) tri_tex: Vec<u32>,
    pub(crate) textures: Vec<Texture>,
    table_z: f64,
    /// The real bounding radius, metres (one normalised unit).
    radius_m: f64,
    /// Where the normalised frame sits in the mesh file's coordinates.
    file_frame: FileFrame,
}

/// Where an object's normalised frame sits in the coordinates of the file
/// it was loaded from (or the builder's, for a built-in object): a file
/// point `p` is the object point `(up.rotation() * p - centre) / radius`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileFrame {
    /// The file's axis that became +z.
    pub up: UpAxis,
    /// The bounding-box centre, file units, after the up rotation.
    pub centre: glam::DVec3,
    /// The bounding radius, file units: one normalised unit.
    pub radius: f64,
}

impl FileFrame {
    /// The rigid camera-from-object transform in normalised units (object
    /// bounding radii) of a camera that sees the file's model at
    /// `camera_from_file` (file units, as BOP's `cam_R_m2c`, `cam_t_m2c`).
    pub fn camera_from_object(&self, camera_from_file: &glam::DAffine3) -> glam::DAffine3 {
        let r = camera_from_file.matrix3 * self.up.rotation().transpose();
        glam::DAffine3::from_mat3_translation(
            r,
            (r * self.centre + camera_from_file.translation) / self.radius,
        )
    }

    /// The inverse of [`FileFrame::camera_from_object`]: the camera's view
    /// of the file's model, file units.
    pub fn camera_from_file(&self, camera_from_object: &glam::DAffine3) -> glam::DAffine3 {
        let r = camera_from_object.matrix3;
        glam::DAffine3::from_mat3_translation(
            r * self.up.rotation(),
            camera_from_object.translation * self.radius - r * self.centre,
        )
    }
}

/// Which axis of a mesh file points up (becomes the world z axis).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpAxis {
    /// +x is up.
    PosX,
    /// -x is up.
    NegX,
    /// +y is up: the usual OBJ convention (Blender's default export), the
    /// duck's, and glTF's by its specification.
    #[default]
    PosY,
    /// -y is up.
    NegY,
    /// +z is up (no change).
    PosZ,
    /// -z is up.
    NegZ,
}

impl UpAxis {
    /// The proper rotation that takes this axis to +z.
    pub(crate) fn to_z_up(self, p: Vec3) -> Vec3 {
        match self {
            UpAxis::PosZ => p,
            UpAxis::NegZ => Vec3::new(p.x, -p.y, -p.z),
            UpAxis::PosY => Vec3::new(p.x, -p.z, p.y),
            UpAxis::NegY => Vec3::new(p.x, p.z, -p.y),
            UpAxis::PosX => Vec3::new(-p.z, p.y, p.x),
            UpAxis::NegX => Vec3::new(p.z, p.y, -p.x),
        }
    }

    /// The rotation that takes this axis to +z, as a matrix: a mesh file's
    /// point `p` lies at `rotation() * p` in the z-up object frame (before
    /// the loader recentres and scales it).
    pub fn rotation(self) -> glam::DMat3 {
        let col = |v: Vec3| self.to_z_up(v).as_dvec3();
        glam::DMat3::from_cols(col(Vec3::X), col(Vec3::Y), col(Vec3::Z))
    }
}

impl FromStr for UpAxis {
    type Err = CaptureError;
    /// Parses `+x`, `-x`, `+y`, `-y`, `+z`, `-z` (`x`, `y`, `z` mean the positive axis).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.trim().to_ascii_lowercase().as_str() {
            "+x" | "x" => UpAxis::PosX,
            "-x" => UpAxis::NegX,
            "+y" | "y" => UpAxis::PosY,
            "-y" => UpAxis::NegY,
            "+z" | "z" => UpAxis::PosZ,
            "-z" => UpAxis::NegZ,
            _ => {
                return Err(CaptureError::UnknownUpAxis {
                    name: s.to_string(),
                });
            }
        })
    }
}

impl fmt::Display for UpAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            UpAxis::PosX => "+x",
            UpAxis::NegX => "-x",
            UpAxis::PosY => "+y",
            UpAxis::NegY => "-y",
            UpAxis::PosZ => "+z",
            UpAxis::NegZ => "-z",
        })
    }
}

impl Object {
    /// The object's name (the built-in name or the mesh file's stem).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Number of distinct textures (a single-colour part counts as one).
    pub fn texture_count(&self) -> usize {
        self.textures.len()
    }

    /// Size in texels of each texture.
    pub fn texture_sizes(&self) -> Vec<(u32, u32)> {
        self.textures.iter().map(Texture::size).collect()
    }

    /// Largest distance of a vertex from the origin (1 for a target object).
    pub fn bounding_radius(&self) -> f64 {
        self.tris
            .iter()
            .flatten()
            .map(|v| v.p.as_dvec3().length())
            .fold(0.0, f64::max)
    }

    /// The real bounding radius, metres: what one normalised unit of the
    /// renderer's scene measures.
    pub fn radius_m(&self) -> f64 {
        self.radius_m
    }

    /// The object with a real bounding radius of `radius_m` metres (a
    /// measured object, or a mesh whose unit is unknown).
    pub fn with_radius_m(mut self, radius_m: f64) -> Result<Object, CaptureError> {
        check_size("the object radius", radius_m)?;
        self.radius_m = radius_m;
        Ok(self)
    }

    /// The object of a mesh whose coordinates are in units of `unit_m`
    /// metres (0.001 for millimetres): scales the real radius the loader
    /// took as metres.
    pub fn with_mesh_unit_m(mut self, unit_m: f64) -> Result<Object, CaptureError> {
        check_size("the mesh unit", unit_m)?;
        let radius_m = self.radius_m * unit_m;
        check_size("the object radius", radius_m)?;
        self.radius_m = radius_m;
        Ok(self)
    }

    /// Where the normalised frame sits in the mesh file's coordinates.
    pub fn file_frame(&self) -> &FileFrame {
        &self.file_frame
    }

    /// The object with the up axis its file was loaded with recorded.
    pub(crate) fn with_file_up(mut self, up: UpAxis) -> Object {
        self.file_frame.up = up;
        self
    }

    /// The lowest z of the object: the height of the table it stands on.
    pub fn table_z(&self) -> f64 {
        self.table_z
    }

    /// The object's size in units of `unit_m` metres (> 0), as the BOP
    /// benchmark's `models_info.json` states it: the diameter (the largest
    /// distance between two vertices) and the axis-aligned bounding box of
    /// the vertices, in the frame [`Object::write_ply`] writes.
    pub fn model_info(&self, unit_m: f64) -> ModelInfo {
        let scale = self.radius_m / unit_m;
        let mut seen = std::collections::HashSet::new();
        let points: Vec<glam::DVec3> = self
            .tris
            .iter()
            .flatten()
            .filter(|v| seen.insert(v.p.to_array().map(f32::to_bits)))
            .map(|v| v.p.as_dvec3() * scale)
            .collect();
        let lo = points
            .iter()
            .fold(glam::DVec3::splat(f64::INFINITY), |a, &p| a.min(p));
        let hi = points
            .iter()
            .fold(glam::DVec3::splat(f64::NEG_INFINITY), |a, &p| a.max(p));
        ModelInfo {
            diameter: diameter(&points),
            min: lo.to_array(),
            size: (hi - lo).to_array(),
        }
    }

    /// Up to `k` dominant surface colours, most frequent first (area-weighted
    /// over the mesh, quantised to 3 bits per channel).
    pub(crate) fn dominant_colors(&self, k: usize) -> Vec<[u8; 3]> {
        let mut bins: HashMap<u32, (f64, [f64; 3])> = HashMap::new();
        let bary = [
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
            [0.6, 0.2, 0.2],
            [0.2, 0.6, 0.2],
            [0.2, 0.2, 0.6],
        ];
        for (tri, &t) in self.tris.iter().zip(&self.tri_tex) {
            let area = (tri[1].p - tri[0].p).cross(tri[2].p - tri[0].p).length() as f64 / 2.0;
            let tex = &self.textures[t as usize];
            // One colour for the whole triangle keeps a white one exactly 1.
            let uniform = tri[0].c == tri[1].c && tri[0].c == tri[2].c;
            for b in &bary {
                let uv = tri[0].uv * b[0] + tri[1].uv * b[1] + tri[2].uv * b[2];
                let tint = if uniform {
                    tri[0].c
                } else {
                    tri[0].c * b[0] + tri[1].c * b[1] + tri[2].c * b[2]
                };
                let texel = tex.level(0).sample(uv.x, uv.y, tex.repeat);
                let c = [texel[0] * tint.x, texel[1] * tint.y, texel[2] * tint.z];
                let key = (c[0] as u32 >> 5) << 6 | (c[1] as u32 >> 5) << 3 | (c[2] as u32 >> 5);
                let e = bins.entry(key).or_insert((0.0, [0.0; 3]));
                let wgt = area / bary.len() as f64;
                e.0 += wgt;
                for (acc, &ci) in e.1.iter_mut().zip(&c) {
                    *acc += wgt * ci as f64;
                }
            }
        }
        let mut v: Vec<(u32, f64, [f64; 3])> =
            bins.into_iter().map(|(k, (w, s))| (k, w, s)).collect();
        // Ties broken by the bin key so the order is deterministic.
        v.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        v.into_iter()
            .take(k)
            .map(|(_, w, s)| s.map(|x| (x / w).round().clamp(0.0, 255.0) as u8))
            .collect()
    }
}

/// An object's size as the BOP benchmark's `models_info.json` gives it
/// (see [`Object::model_info`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelInfo {
    /// The largest distance between two vertices.
    pub diameter: f64,
    /// The smallest x, y and z of the vertices (`min_x`, `min_y`, `min_z`).
    pub min: [f64; 3],
    /// The extent of the vertices along x, y and z (`size_x`, ...).
    pub size: [f64; 3],
}

/// The largest distance between two of `points`, exactly. All pairs would
/// be O(n^2); a pair can only beat the best distance so far if their
/// distances from a centre add up to more, so with the points sorted by
/// that distance and a good first guess (from farthest-point sweeps) few
/// pairs are measured.
fn diameter(points: &[glam::DVec3]) -> f64 {
    let Some(&first) = points.first() else {
        return 0.0;
    };
    let farthest = |a: glam::DVec3| {
        points
            .iter()
            .map(|&p| (p, p.distance_squared(a)))
            .fold((a, 0.0), |best, x| if x.1 > best.1 { x } else { best })
    };
    let (mut a, mut best2) = (first, 0.0f64);
    for _ in 0..4 {
        let (b, d2) = farthest(a);
        if d2 <= best2 {
            break;
        }
        (a, best2) = (b, d2);
    }
    let lo = points
        .iter()
        .fold(glam::DVec3::splat(f64::INFINITY), |m, &p| m.min(p));
    let hi = points
        .iter()
        .fold(glam::DVec3::splat(f64::NEG_INFINITY), |m, &p| m.max(p));
    let centre = (lo + hi) * 0.5;
    let mut by_r: Vec<(f64, glam::DVec3)> =
        points.iter().map(|&p| (p.distance(centre), p)).collect();
    by_r.sort_by(|x, y| y.0.total_cmp(&x.0));
    let mut best = best2.sqrt();
    for (i, &(ri, pi)) in by_r.iter().enumerate() {
        if 2.0 * ri <= best {
            break;
        }
        for &(rj, pj) in &by_r[i + 1..] {
            if ri + rj <= best {
                break;
            }
            let d2 = pi.distance_squared(pj);
            if d2 > best2 {
                best2 = d2;
                best = d2.sqrt();
            }
        }
    }
    best
}

/// Builds meshes out of textured quads, boxes and cylinders.
pub(crate) struct MeshBuilder {
    tris: Vec<[Vertex; 3]>,
    tri_tex: Vec<u32>,
    textures: Vec<Texture>,
}

/// Faces of an axis-aligned box, in the order [`MeshBuilder::cuboid`] expects.
pub(crate) const BOX_FACES: usize = 6;

impl MeshBuilder {
    pub fn new() -> Self {
        MeshBuilder {
            tris: Vec::new(),
            tri_tex: Vec::new(),
            textures: Vec::new(),
        }
    }

    /// Adds a texture and returns its index.
    pub fn texture(&mut self, t: Texture) -> u32 {
        self.textures.push(t);
        (self.textures.len() - 1) as u32
    }

    /// Adds a triangle drawn with texture `tex`.
    pub fn tri(&mut self, a: Vertex, b: Vertex, c: Vertex, tex: u32) {
        self.tris.push([a, b, c]);
        self.tri_tex.push(tex);
    }

    /// Whether no triangle has been added.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// A quad with corners top-left, top-right, bottom-right, bottom-left as
    /// seen from outside, mapped to the whole texture, flat-shaded.
    fn quad(&mut self, c: [Vec3; 4], normal: Vec3, tex: u32) {
        let uv = [
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ];
        let v = |i: usize| Vertex {
            p: c[i],
            n: normal,
            uv: uv[i],
            c: Vec3::ONE,
        };
        self.tri(v(0), v(3), v(2), tex);
        self.tri(v(0), v(2), v(1), tex);
    }

    /// An axis-aligned box; `tex` per face in the order +x, -x, +y, -y, +z, -z.
    /// Side textures are upright (image up = +z) as seen from outside; the top
    /// texture has image right = +x and image up = +y, the bottom image right
    /// = +x and image up = -y.
    pub fn cuboid(&mut self, min: Vec3, max: Vec3, tex: [u32; BOX_FACES]) {
        let c = (min + max) * 0.5;
        let h = (max - min) * 0.5;
        let faces = [
            (Vec3::X, Vec3::Y, Vec3::Z),
            (Vec3::NEG_X, Vec3::NEG_Y, Vec3::Z),
            (Vec3::Y, Vec3::NEG_X, Vec3::Z),
            (Vec3::NEG_Y, Vec3::X, Vec3::Z),
            (Vec3::Z, Vec3::X, Vec3::Y),
            (Vec3::NEG_Z, Vec3::X, Vec3::NEG_Y),
        ];
        for (i, &(n, r, u)) in faces.iter().enumerate() {
            let fc = c + n * (n.abs() * h).length();
            let rr = r * (r.abs() * h).length();
            let uu = u * (u.abs() * h).length();
            self.quad(
                [fc - rr + uu, fc + rr + uu, fc + rr - uu, fc - rr - uu],
                n,
                tex[i],
            );
        }
    }

    /// A vertical cylinder standing on `z0`, smooth-shaded side. The side
    /// texture wraps once around (u grows counter-clockwise seen from above,
    /// so it reads left to right from outside; v = 0 at the top); the caps map
    /// their texture's inscribed disc (image right = +x, image up = +y).
    #[allow(clippy::too_many_arguments)]
    pub fn cylinder(
        &mut self,
        centre: Vec2,
        z0: f32,
        z1: f32,
        radius: f32,
        segments: u32,
        side: u32,
        top: u32,
        bottom: u32,
    ) {
        let at = |k: u32| {
            let a = std::f32::consts::TAU * k as f32 / segments as f32;
            Vec2::new(a.cos(), a.sin())
        };
        let top_c = Vertex {
            p: centre.extend(z1),
            n: Vec3::Z,
            uv: Vec2::splat(0.5),
            c: Vec3::ONE,
        };
        let bot_c = Vertex {
            p: centre.extend(z0),
            n: Vec3::NEG_Z,
            uv: Vec2::splat(0.5),
            c: Vec3::ONE,
        };
        for k in 0..segments {
            let (d0, d1) = (at(k), at(k + 1));
            let (u0, u1) = (k as f32 / segments as f32, (k + 1) as f32 / segments as f32);
            let v = |d: Vec2, z: f32, u: f32, vv: f32| Vertex {
                p: (centre + d * radius).extend(z),
                n: d.extend(0.0),
                uv: Vec2::new(u, vv),
                c: Vec3::ONE,
            };
            let (tl, tr, br, bl) = (
                v(d0, z1, u0, 0.0),
                v(d1, z1, u1, 0.0),
                v(d1, z0, u1, 1.0),
                v(d0, z0, u0, 1.0),
            );
            self.tri(tl, bl, br, side);
            self.tri(tl, br, tr, side);
            let cap = |d: Vec2, z: f32, n: Vec3, flip: f32| Vertex {
                p: (centre + d * radius).extend(z),
                n,
                uv: Vec2::new(0.5 + 0.5 * d.x, 0.5 - 0.5 * flip * d.y),
                c: Vec3::ONE,
            };
            self.tri(
                top_c,
                cap(d0, z1, Vec3::Z, 1.0),
                cap(d1, z1, Vec3::Z, 1.0),
                top,
            );
            self.tri(
                bot_c,
                cap(d1, z0, Vec3::NEG_Z, -1.0),
                cap(d0, z0, Vec3::NEG_Z, -1.0),
                bottom,
            );
        }
    }

    /// Finishes the mesh as is (distractors keep their own units; their
    /// real size is never asked for, so one unit counts as 1 m).
    pub fn finish_raw(self, name: &str) -> Object {
        let table_z = self
            .tris
            .iter()
            .flatten()
            .map(|v| v.p.z as f64)
            .fold(f64::INFINITY, f64::min);
        Object {
            name: name.to_string(),
            tris: self.tris,
            tri_tex: self.tri_tex,
            textures: self.textures,
            table_z,
            radius_m: 1.0,
            file_frame: FileFrame {
                up: UpAxis::PosZ,
                centre: glam::DVec3::ZERO,
                radius: 1.0,
            },
        }
    }

    /// Finishes the mesh normalised: bounding-box centre at the origin,
    /// bounding radius 1; one unit of the mesh as built is `unit_m` metres.
    pub fn finish_normalised(mut self, name: &str, unit_m: f64) -> Object {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for v in self.tris.iter().flatten() {
            lo = lo.min(v.p);
            hi = hi.max(v.p);
        }
        let centre = (lo.as_dvec3() + hi.as_dvec3()) * 0.5;
        let radius = self
            .tris
            .iter()
            .flatten()
            .map(|v| (v.p.as_dvec3() - centre).length())
            .fold(0.0, f64::max);
        let scale = if radius > 0.0 { 1.0 / radius } else { 1.0 };
        for v in self.tris.iter_mut().flatten() {
            v.p = ((v.p.as_dvec3() - centre) * scale).as_vec3();
        }
        let mut object = self.finish_raw(name);
        object.radius_m = if radius > 0.0 {
            radius * unit_m
        } else {
            unit_m
        };
        object.file_frame.centre = centre;
        object.file_frame.radius = if radius > 0.0 { radius } else { 1.0 };
        object
    }
}

// Saturated print colours.
pub(crate) const RED: [u8; 3] = [220, 30, 40];
pub(crate) const YELLOW: [u8; 3] = [250, 210, 20];
pub(crate) const WHITE: [u8; 3] = [245, 245, 240];
pub(crate) const BLUE: [u8; 3] = [30, 70, 200];
pub(crate) const GREEN: [u8; 3] = [40, 170, 60];
pub(crate) const ORANGE: [u8; 3] = [250, 130, 20];
pub(crate) const PURPLE: [u8; 3] = [130, 40, 160];
pub(crate) const MAGENTA: [u8; 3] = [220, 40, 150];
pub(crate) const CYAN: [u8; 3] = [20, 180, 210];
pub(crate) const NAVY: [u8; 3] = [20, 30, 110];
pub(crate) const LIME: [u8; 3] = [150, 210, 40];
pub(crate) const BLACK: [u8; 3] = [25, 25, 30];
pub(crate) const PINK: [u8; 3] = [250, 140, 170];
pub(crate) const TEAL: [u8; 3] = [0, 130, 130];

/// A real size must be a positive, finite number of metres (at most 1 km).
pub(crate) fn check_size(what: &'static str, metres: f64) -> Result<(), CaptureError> {
    if metres.is_finite() && metres > 0.0 && metres <= 1000.0 {
        Ok(())
    } else {
        Err(CaptureError::InvalidSize { what, metres })
    }
}

/// Texels per unit of the un-normalised builtin geometry.
const TEXELS_PER_UNIT: f32 = 320.0;

pub(crate) fn canvas_for(w: f32, h: f32, bg: [u8; 3]) -> Canvas {
    Canvas::new(
        (w * TEXELS_PER_UNIT).round() as u32,
        (h * TEXELS_PER_UNIT).round() as u32,
        bg,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::hash2;
    use glam::DVec3;

    fn brute_force_diameter(p: &[DVec3]) -> f64 {
        let mut best = 0.0f64;
        for (i, a) in p.iter().enumerate() {
            for b in &p[i + 1..] {
                best = best.max(a.distance(*b));
            }
        }
        best
    }

    #[test]
    fn diameter_is_the_largest_pairwise_distance() {
        let r = |i: i32, k: i32| hash2(i, k, 3) as f64 * 2.0 - 1.0;
        // A box, a sphere (all points at one distance: the pruning's worst
        // case), a rod and a box away from the origin.
        let point = |shape: &str, i: i32| {
            let p = DVec3::new(r(i, 0), r(i, 1), r(i, 2));
            match shape {
                "sphere" => p.normalize_or(DVec3::X),
                "rod" => p * DVec3::new(5.0, 0.1, 0.1),
                "offset" => p * DVec3::new(1.0, 0.5, 1.0) + DVec3::new(7.0, -3.0, 0.0),
                _ => p,
            }
        };
        for shape in ["cube", "sphere", "rod", "offset"] {
            for n in [1, 2, 3, 50, 700] {
                let p: Vec<DVec3> = (0..n).map(|i| point(shape, i)).collect();
                let (fast, slow) = (diameter(&p), brute_force_diameter(&p));
                assert!(
                    (fast - slow).abs() <= 1e-12 * slow.max(1.0),
                    "{shape} n={n}: {fast} vs {slow}"
                );
            }
        }
        assert_eq!(diameter(&[]), 0.0);
    }

    #[test]
    fn up_axis_rotation_is_the_proper_rotation_the_loaders_apply() {
        let axes = [
            (UpAxis::PosX, Vec3::X),
            (UpAxis::NegX, Vec3::NEG_X),
            (UpAxis::PosY, Vec3::Y),
            (UpAxis::NegY, Vec3::NEG_Y),
            (UpAxis::PosZ, Vec3::Z),
            (UpAxis::NegZ, Vec3::NEG_Z),
        ];
        for (up, dir) in axes {
            let r = up.rotation();
            assert_eq!(r * dir.as_dvec3(), DVec3::Z, "{up}");
            assert_eq!(r.determinant(), 1.0, "{up}");
            let p = Vec3::new(0.3, -1.7, 2.5);
            assert_eq!(r * p.as_dvec3(), up.to_z_up(p).as_dvec3(), "{up}");
        }
    }

    #[test]
    fn dominant_colours_include_vertex_colours() {
        // A white texture under a red vertex colour is red.
        let mut b = MeshBuilder::new();
        let white = b.texture(Texture::solid([255, 255, 255]));
        let v = |x: f32, y: f32| Vertex {
            p: Vec3::new(x, y, 0.0),
            n: Vec3::Z,
            uv: Vec2::ZERO,
            c: Vec3::new(0.8, 0.1, 0.1),
        };
        b.tri(v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0), white);
        let obj = b.finish_normalised("red", 1.0);
        let c = obj.dominant_colors(1)[0];
        assert!(
            (c[0] as i32 - 204).abs() <= 1 && (c[1] as i32 - 26).abs() <= 1,
            "{c:?}"
        );
    }
}
