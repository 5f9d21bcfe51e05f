//! Renderable objects: built-in procedural ones and meshes loaded from
//! OBJ, PLY and glTF files (the loaders live in `mesh`).

use std::collections::HashMap;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use glam::{Vec2, Vec3};

use crate::CaptureError;
use crate::paint::Canvas;
use crate::texture::Texture;

/// Names accepted by [`Object::builtin`].
pub const BUILTIN_OBJECTS: &[&str] = &["fruitbox", "can", "tricolor"];

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
    /// A built-in procedural object: `fruitbox` (a printed cereal-style box,
    /// a different multi-coloured pattern on every face), `can` (a cylinder
    /// with an asymmetric wrapped label and a plain metal top) or `tricolor`
    /// (three untextured blocks in red, green and blue); or `generated-N`,
    /// object N of the generated population (a box, can, bottle or stack
    /// of blocks printed like packaging, drawn from seed N).
    pub fn builtin(name: &str) -> Result<Object, CaptureError> {
        if let Some(seed) = crate::generated::generated_seed(name) {
            return Ok(crate::generated::generated(seed));
        }
        match name {
            "fruitbox" => Ok(fruitbox()),
            "can" => Ok(can()),
            "tricolor" => Ok(tricolor()),
            _ => Err(CaptureError::UnknownObject {
                name: name.to_string(),
                valid: format!(
                    "{}, {}N (N a number)",
                    BUILTIN_OBJECTS.join(", "),
                    crate::generated::GENERATED_PREFIX
                ),
            }),
        }
    }

    /// Loads a UV-mapped OBJ mesh whose MTL material has a diffuse texture
    /// (`map_Kd`, resolved relative to the MTL file), assuming +y is up.
    /// See [`Object::load_obj_with_up`].
    pub fn load_obj(path: impl AsRef<Path>) -> Result<Object, CaptureError> {
        Object::load_obj_with_up(path, UpAxis::default())
    }

    /// Loads a textured OBJ mesh, rotating `up` onto the world z axis and
    /// normalising it to bounding radius 1. An OBJ file states no unit: its
    /// coordinates are taken as metres (as glTF's are), so the real radius
    /// is the file's bounding radius; [`Object::with_mesh_unit_m`] or
    /// [`Object::with_radius_m`] say otherwise. Every mesh in the file needs
    /// texture coordinates and a material with `map_Kd`; missing normals are
    /// computed (smoothed across edges sharper than 60 degrees only).
    pub fn load_obj_with_up(path: impl AsRef<Path>, up: UpAxis) -> Result<Object, CaptureError> {
        Ok(crate::mesh::obj::load(path.as_ref(), up)?.with_file_up(up))
    }

    /// Loads a mesh file of any supported format, chosen by its extension
    /// (case-insensitive): `.obj` (see [`Object::load_obj_with_up`]),
    /// `.ply` or `.gltf` / `.glb` (glTF 2.0). The mesh is rotated so that
    /// `up` becomes the world z axis and normalised to bounding radius 1.
    ///
    /// Colour: a PLY mesh shows its texture (`comment TextureFile`, with
    /// per-vertex or per-face texture coordinates) if it has one, otherwise
    /// its vertex colours; a glTF primitive shows its base colour (texture
    /// times factor times `COLOR_0`). A mesh without any colour is an error.
    ///
    /// Units: the coordinates are taken as metres. That is glTF's unit (and
    /// +y its up axis, the default [`UpAxis`]); OBJ and PLY files state no
    /// unit. The BOP benchmark's PLY models are in millimetres: load them
    /// with [`Object::with_mesh_unit_m`]`(0.001)`.
    pub fn load_mesh(path: impl AsRef<Path>, up: UpAxis) -> Result<Object, CaptureError> {
        crate::mesh::load(path.as_ref(), up)
    }

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

    /// Writes the object as a binary little-endian PLY file whose
    /// coordinates are in units of `unit_m` metres (0.001: millimetres, as
    /// the BOP benchmark's models are): the object's normalised frame (z
    /// up, bounding-box centre at the origin) times [`Object::radius_m`] /
    /// `unit_m`, with vertex normals. A textured object gets texture
    /// coordinates (`texture_u`, `texture_v`, v = 0 at the bottom of the
    /// image) and one PNG atlas of all its textures next to the file
    /// (`<stem>.png`, named by a `comment TextureFile` line); an object whose
    /// textures are all single colours (`tricolor`, a vertex-coloured mesh)
    /// gets vertex colours (`red`, `green`, `blue`) and no image.
    ///
    /// [`Object::load_mesh`] with [`UpAxis::PosZ`] and then
    /// [`Object::with_mesh_unit_m`]`(unit_m)` reads the same object back.
    /// An object with a real texture under varying vertex colours cannot be
    /// written (a PLY file is coloured by one or the other).
    pub fn write_ply(&self, path: impl AsRef<Path>, unit_m: f64) -> Result<(), CaptureError> {
        check_size("the mesh unit", unit_m)?;
        crate::mesh::ply::write(self, path.as_ref(), unit_m)
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
const CARDBOARD: [u8; 3] = [165, 120, 70];
const SILVER: [u8; 3] = [185, 185, 190];

/// Metres per unit of the built-in geometry: the box is 24 x 15 x 30 cm
/// (a cereal box), the can 8.4 cm across and 12 cm tall (a drink can), the
/// blocks 10 cm long (a toy).
const FRUITBOX_UNIT_M: f64 = 0.30;
const CAN_UNIT_M: f64 = 0.12;
const TRICOLOR_UNIT_M: f64 = 0.10;

/// A real size must be a positive, finite number of metres (at most 1 km).
fn check_size(what: &'static str, metres: f64) -> Result<(), CaptureError> {
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

/// A cereal-style box, 0.8 wide (x), 0.5 deep (y), 1.0 tall (z) before
/// normalisation, with a distinct printed design on every face.
fn fruitbox() -> Object {
    let (sx, sy, sz) = (0.8, 0.5, 1.0);

    // +y: "front": sun, a lettered band, a bowl of fruit.
    let mut front = canvas_for(sx, sz, RED);
    front.ring(0.28, 0.2, 0.14, 0.175, ORANGE);
    front.disc(0.28, 0.2, 0.14, YELLOW);
    front.rect(0.0, 0.38, 1.0, 0.58, WHITE);
    front.rect(0.08, 0.40, 0.13, 0.56, BLUE); // F
    front.rect(0.08, 0.40, 0.28, 0.44, BLUE);
    front.rect(0.08, 0.46, 0.23, 0.50, BLUE);
    front.bar((0.36, 0.40), (0.56, 0.56), 0.045, BLUE); // X
    front.bar((0.56, 0.40), (0.36, 0.56), 0.045, BLUE);
    front.ring(0.76, 0.48, 0.045, 0.085, BLUE); // O
    front.disc(0.36, 0.70, 0.06, ORANGE);
    front.disc(0.55, 0.68, 0.05, PURPLE);
    front.disc(0.70, 0.71, 0.055, YELLOW);
    front.disc(0.47, 0.64, 0.04, PINK);
    front.half_disc_lower(0.52, 0.72, 0.2, GREEN);
    front.rect(0.0, 0.92, 1.0, 1.0, YELLOW);
    front.checks([0.05, 0.935, 0.45, 0.985], 8, 1, NAVY, YELLOW);

    // -y: "back": checks over purple with bands, a big L and a triangle.
    let mut back = canvas_for(sx, sz, WHITE);
    back.checks([0.0, 0.0, 1.0, 0.45], 6, 5, BLUE, WHITE);
    back.rect(0.0, 0.45, 1.0, 1.0, PURPLE);
    back.rect(0.0, 0.55, 1.0, 0.60, YELLOW);
    back.rect(0.0, 0.65, 1.0, 0.70, LIME);
    back.rect(0.0, 0.75, 1.0, 0.80, ORANGE);
    back.rect(0.62, 0.50, 0.72, 0.95, CYAN);
    back.rect(0.62, 0.88, 0.92, 0.95, CYAN);
    back.polygon(&[(0.08, 0.95), (0.42, 0.95), (0.25, 0.60)], RED);

    // +x: a stack of coloured blocks with dots and a white wedge.
    let mut right = canvas_for(sy, sz, WHITE);
    let blocks = [ORANGE, TEAL, MAGENTA, LIME, NAVY, YELLOW];
    for (i, &c) in blocks.iter().enumerate() {
        let y0 = i as f64 / 6.0;
        right.rect(0.0, y0, 1.0, y0 + 1.0 / 6.0, c);
        right.disc(0.2 + 0.12 * i as f64, y0 + 1.0 / 12.0, 0.035, WHITE);
    }
    right.polygon(&[(0.1, 0.3), (0.9, 0.45), (0.1, 0.6)], WHITE);
    right.polygon(&[(0.2, 0.36), (0.65, 0.45), (0.2, 0.54)], RED);

    // -x: diagonal stripes, a magenta ring and a lettered panel.
    let mut left = canvas_for(sy, sz, GREEN);
    left.stripes([0.0, 0.0, 1.0, 1.0], 30.0, 0.06, &[GREEN, YELLOW, BLACK]);
    left.disc(0.5, 0.22, 0.2, WHITE);
    left.ring(0.5, 0.22, 0.11, 0.2, MAGENTA);
    left.rect(0.1, 0.68, 0.9, 0.92, CYAN);
    left.rect(0.25, 0.71, 0.75, 0.75, RED); // T
    left.rect(0.45, 0.71, 0.55, 0.89, RED);

    // +z: top, deliberately asymmetric so every azimuth of a top view differs.
    let mut top = canvas_for(sx, sy, ORANGE);
    top.rect(0.55, 0.0, 1.0, 1.0, CYAN);
    top.bar((0.08, 0.55), (0.36, 0.55), 0.12, NAVY);
    top.polygon(&[(0.34, 0.35), (0.50, 0.55), (0.34, 0.75)], NAVY);
    top.disc(0.66, 0.25, 0.13, RED);
    top.disc(0.80, 0.52, 0.12, YELLOW);
    top.disc(0.91, 0.80, 0.10, GREEN);
    top.rect(0.05, 0.08, 0.25, 0.16, WHITE); // T
    top.rect(0.12, 0.08, 0.18, 0.40, WHITE);
    top.rect(0.0, 0.86, 0.55, 1.0, PURPLE);

    // -z: plain cardboard with a barcode.
    let mut bottom = canvas_for(sx, sy, CARDBOARD);
    bottom.rect(0.3, 0.3, 0.7, 0.7, WHITE);
    for i in 0..14 {
        let x = 0.33 + 0.025 * i as f64;
        bottom.rect(x, 0.35, x + 0.008 + 0.006 * (i % 3) as f64, 0.65, BLACK);
    }

    let mut b = MeshBuilder::new();
    let t = [right, left, front, back, top, bottom].map(|c| b.texture(c.into_texture(false)));
    b.cuboid(
        Vec3::new(-sx / 2.0, -sy / 2.0, 0.0),
        Vec3::new(sx / 2.0, sy / 2.0, sz),
        t,
    );
    b.finish_normalised("fruitbox", FRUITBOX_UNIT_M)
}

/// A drink can, radius 0.35 and height 1.0 before normalisation, whose label
/// has four different panels around the circumference, and whose plain lid
/// has a pull tab and an opening.
fn can() -> Object {
    let (r, h) = (0.35f32, 1.0f32);
    let circumference = std::f32::consts::TAU * r;
    let mut label = canvas_for(circumference, h, RED);
    // Panel 1 (u 0..0.3): white disc with a yellow star on red.
    label.disc(0.15, 0.5, 0.3, WHITE);
    label.star(0.15, 0.5, 0.26, YELLOW);
    label.disc(0.15, 0.5, 0.07, RED);
    // Panel 2 (u 0.3..0.55): green stripes on blue with an orange bar.
    label.rect(0.3, 0.0, 0.55, 1.0, BLUE);
    label.stripes([0.3, 0.0, 0.55, 1.0], 90.0, 0.05, &[BLUE, BLUE, GREEN]);
    label.rect(0.3, 0.62, 0.55, 0.72, ORANGE);
    // Panel 3 (u 0.55..0.8): purple checks across yellow.
    label.rect(0.55, 0.0, 0.8, 1.0, YELLOW);
    label.checks([0.55, 0.3, 0.8, 0.7], 8, 4, PURPLE, YELLOW);
    // Panel 4 (u 0.8..1): white with green blocks and a barcode.
    label.rect(0.8, 0.0, 1.0, 1.0, WHITE);
    for i in 0..5 {
        let y = 0.12 + 0.09 * i as f64;
        label.rect(0.83, y, 0.83 + 0.03 * (i + 2) as f64, y + 0.05, GREEN);
    }
    for i in 0..12 {
        let x = 0.84 + 0.011 * i as f64;
        label.rect(x, 0.72, x + 0.004 + 0.003 * (i % 3) as f64, 0.88, BLACK);
    }
    // Metal rims at the top and bottom of the label.
    label.rect(0.0, 0.0, 1.0, 0.05, SILVER);
    label.rect(0.0, 0.95, 1.0, 1.0, SILVER);

    // An unprinted lid, but with a real can's pull tab and opening: a
    // featureless disc would leave φ unobservable from above (θ > ~80°).
    let mut lid = Canvas::new(128, 128, SILVER);
    lid.ring(0.5, 0.5, 0.41, 0.46, [140, 140, 148]);
    let (opening, tab, hole) = ([52, 50, 56], [150, 150, 160], [88, 88, 96]);
    lid.bar((0.42, 0.2), (0.58, 0.2), 0.1, opening);
    lid.disc(0.42, 0.2, 0.05, opening);
    lid.disc(0.58, 0.2, 0.05, opening);
    lid.bar((0.5, 0.3), (0.5, 0.66), 0.17, tab);
    lid.disc(0.5, 0.3, 0.085, tab);
    lid.disc(0.5, 0.66, 0.085, tab);
    lid.disc(0.5, 0.58, 0.045, hole);
    lid.disc(0.5, 0.42, 0.03, hole);

    let mut b = MeshBuilder::new();
    let side = b.texture(label.into_texture(true));
    let top = b.texture(lid.into_texture(false));
    let bottom = b.texture(Texture::solid(SILVER));
    b.cylinder(Vec2::ZERO, 0.0, h, r, 96, side, top, bottom);
    b.finish_normalised("can", CAN_UNIT_M)
}

/// Three untextured blocks: a blue base slab, a red tower on one end and a
/// green cube on the other, so views are distinguishable by colour layout.
fn tricolor() -> Object {
    let mut b = MeshBuilder::new();
    let red = b.texture(Texture::solid([210, 30, 30]));
    let green = b.texture(Texture::solid([30, 170, 50]));
    let blue = b.texture(Texture::solid([30, 60, 200]));
    b.cuboid(
        Vec3::new(-0.5, -0.4, 0.0),
        Vec3::new(0.5, 0.4, 0.3),
        [blue; 6],
    );
    b.cuboid(
        Vec3::new(-0.5, -0.4, 0.3),
        Vec3::new(-0.1, 0.4, 1.0),
        [red; 6],
    );
    b.cuboid(
        Vec3::new(0.12, 0.05, 0.3),
        Vec3::new(0.42, 0.35, 0.6),
        [green; 6],
    );
    b.finish_normalised("tricolor", TRICOLOR_UNIT_M)
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
