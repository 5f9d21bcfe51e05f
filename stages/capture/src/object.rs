//! Renderable objects: built-in procedural ones and textured OBJ meshes.

use std::cell::RefCell;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
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
}

/// A textured triangle mesh ready to render. Target objects are normalised:
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
}

/// Which axis of a mesh file points up (becomes the world z axis).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UpAxis {
    /// +x is up.
    PosX,
    /// -x is up.
    NegX,
    /// +y is up: the usual OBJ convention (Blender's default export), and the
    /// duck's.
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
    fn to_z_up(self, p: Vec3) -> Vec3 {
        match self {
            UpAxis::PosZ => p,
            UpAxis::NegZ => Vec3::new(p.x, -p.y, -p.z),
            UpAxis::PosY => Vec3::new(p.x, -p.z, p.y),
            UpAxis::NegY => Vec3::new(p.x, p.z, -p.y),
            UpAxis::PosX => Vec3::new(-p.z, p.y, p.x),
            UpAxis::NegX => Vec3::new(p.z, p.y, -p.x),
        }
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
    /// (three untextured blocks in red, green and blue).
    pub fn builtin(name: &str) -> Result<Object, CaptureError> {
        match name {
            "fruitbox" => Ok(fruitbox()),
            "can" => Ok(can()),
            "tricolor" => Ok(tricolor()),
            _ => Err(CaptureError::UnknownObject {
                name: name.to_string(),
                valid: BUILTIN_OBJECTS.join(", "),
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
        load_obj_impl(path.as_ref(), up)
    }

    /// The object's name (the built-in name or the OBJ file's stem).
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

    /// The lowest z of the object: the height of the table it stands on.
    pub fn table_z(&self) -> f64 {
        self.table_z
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
            for b in &bary {
                let uv = tri[0].uv * b[0] + tri[1].uv * b[1] + tri[2].uv * b[2];
                let c = tex.level(0).sample(uv.x, uv.y, tex.repeat);
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

    fn tri(&mut self, a: Vertex, b: Vertex, c: Vertex, tex: u32) {
        self.tris.push([a, b, c]);
        self.tri_tex.push(tex);
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
        };
        let bot_c = Vertex {
            p: centre.extend(z0),
            n: Vec3::NEG_Z,
            uv: Vec2::splat(0.5),
        };
        for k in 0..segments {
            let (d0, d1) = (at(k), at(k + 1));
            let (u0, u1) = (k as f32 / segments as f32, (k + 1) as f32 / segments as f32);
            let v = |d: Vec2, z: f32, u: f32, vv: f32| Vertex {
                p: (centre + d * radius).extend(z),
                n: d.extend(0.0),
                uv: Vec2::new(u, vv),
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

fn canvas_for(w: f32, h: f32, bg: [u8; 3]) -> Canvas {
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

/// Resolves a `map_Kd` value relative to the MTL file's directory. Options
/// such as `-bm 1.0` before the file name are skipped.
fn resolve_texture(mtl_dir: &Path, value: &str) -> PathBuf {
    let value = value.trim();
    let name = if value.starts_with('-') {
        value.split_whitespace().last().unwrap_or(value)
    } else {
        value
    };
    mtl_dir.join(name.replace('\\', "/"))
}

fn load_obj_impl(path: &Path, up: UpAxis) -> Result<Object, CaptureError> {
    let file = std::fs::File::open(path).map_err(|e| CaptureError::io(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mtl_error: RefCell<Option<CaptureError>> = RefCell::new(None);
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, materials) = tobj::load_obj_buf(&mut reader, &opts, |rel| {
        let mtl_path = dir.join(rel);
        match tobj::load_mtl(&mtl_path) {
            Ok((mut mats, map)) => {
                let mtl_dir = mtl_path.parent().unwrap_or(Path::new("")).to_path_buf();
                for m in &mut mats {
                    if let Some(t) = &m.diffuse_texture {
                        m.diffuse_texture =
                            Some(resolve_texture(&mtl_dir, t).to_string_lossy().into_owned());
                    }
                }
                Ok((mats, map))
            }
            Err(e) => {
                let reason = match std::fs::File::open(&mtl_path) {
                    Err(io) => io.to_string(),
                    Ok(_) => e.to_string(),
                };
                mtl_error.borrow_mut().get_or_insert(CaptureError::Mtl {
                    path: mtl_path.clone(),
                    obj: path.to_path_buf(),
                    reason,
                });
                Err(e)
            }
        }
    })
    .map_err(|e| CaptureError::Obj {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let materials = materials.map_err(|e| CaptureError::Obj {
        path: path.to_path_buf(),
        reason: format!("material library: {e}"),
    })?;

    let bad = |reason: String| CaptureError::Obj {
        path: path.to_path_buf(),
        reason,
    };
    let mut b = MeshBuilder::new();
    let mut tex_ids: HashMap<PathBuf, u32> = HashMap::new();
    for model in &models {
        let mesh = &model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let mesh_name = if model.name.is_empty() {
            "(unnamed)"
        } else {
            &model.name
        };
        if mesh.texcoords.is_empty() {
            return Err(CaptureError::MissingTexCoords {
                path: path.to_path_buf(),
                mesh: mesh_name.to_string(),
            });
        }
        let missing = |detail: String| CaptureError::MissingTexture {
            path: path.to_path_buf(),
            mesh: mesh_name.to_string(),
            detail,
        };
        let material = match mesh.material_id {
            Some(id) => materials
                .get(id)
                .ok_or_else(|| missing(format!("material #{id} is not defined")))?,
            None => return Err(missing("no material (usemtl/mtllib)".to_string())),
        };
        let tex_path = PathBuf::from(
            material
                .diffuse_texture
                .as_deref()
                .ok_or_else(|| missing(format!("material '{}' has no map_Kd", material.name)))?,
        );
        let tex = match tex_ids.get(&tex_path) {
            Some(&t) => t,
            None => {
                let t = b.texture(load_texture(&tex_path)?);
                tex_ids.insert(tex_path, t);
                t
            }
        };

        let pos = |i: u32| -> Result<Vec3, CaptureError> {
            let i = i as usize;
            mesh.positions
                .get(3 * i..3 * i + 3)
                .map(|p| up.to_z_up(Vec3::new(p[0], p[1], p[2])))
                .ok_or_else(|| bad(format!("vertex index {} out of range", i + 1)))
        };
        let uv_at = |i: u32| -> Result<Vec2, CaptureError> {
            let i = i as usize;
            mesh.texcoords
                .get(2 * i..2 * i + 2)
                // OBJ puts v = 0 at the bottom of the image, we at the top.
                .map(|t| Vec2::new(t[0], 1.0 - t[1]))
                .ok_or_else(|| bad(format!("texture coordinate index {} out of range", i + 1)))
        };
        let nrm_at = |i: u32| -> Result<Vec3, CaptureError> {
            let i = i as usize;
            mesh.normals
                .get(3 * i..3 * i + 3)
                .map(|n| up.to_z_up(Vec3::new(n[0], n[1], n[2])).normalize_or_zero())
                .ok_or_else(|| bad(format!("normal index {} out of range", i + 1)))
        };
        let tidx = if mesh.texcoord_indices.is_empty() {
            &mesh.indices
        } else {
            &mesh.texcoord_indices
        };
        let has_normals = !mesh.normals.is_empty();
        let nidx = if mesh.normal_indices.is_empty() {
            &mesh.indices
        } else {
            &mesh.normal_indices
        };
        let nfaces = mesh.indices.len() / 3;
        let mut faces = Vec::with_capacity(nfaces);
        for f in 0..nfaces {
            let mut v = [Vertex {
                p: Vec3::ZERO,
                n: Vec3::ZERO,
                uv: Vec2::ZERO,
            }; 3];
            for (j, vj) in v.iter_mut().enumerate() {
                let k = 3 * f + j;
                vj.p = pos(mesh.indices[k])?;
                vj.uv = uv_at(
                    *tidx
                        .get(k)
                        .ok_or_else(|| bad("texture coordinate indices missing".into()))?,
                )?;
                if has_normals {
                    vj.n = nrm_at(
                        *nidx
                            .get(k)
                            .ok_or_else(|| bad("normal indices missing".into()))?,
                    )?;
                }
            }
            faces.push(v);
        }
        if !has_normals {
            smooth_normals(&mut faces, &mesh.indices);
        }
        for v in faces {
            b.tri(v[0], v[1], v[2], tex);
        }
    }
    if b.tris.is_empty() {
        return Err(CaptureError::EmptyMesh {
            path: path.to_path_buf(),
        });
    }
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".to_string());
    // OBJ states no unit: metres until the caller says otherwise.
    Ok(b.finish_normalised(&name, 1.0))
}

/// Vertex normals for a mesh without them: the area-weighted mean of the
/// normals of the faces sharing the vertex, leaving out faces that meet at
/// more than 60 degrees so creases stay sharp.
fn smooth_normals(faces: &mut [[Vertex; 3]], indices: &[u32]) {
    let face_n: Vec<Vec3> = faces
        .iter()
        .map(|v| (v[1].p - v[0].p).cross(v[2].p - v[0].p))
        .collect();
    let nverts = indices.iter().copied().max().map_or(0, |m| m as usize + 1);
    // Compressed adjacency: the faces around each vertex.
    let mut start = vec![0usize; nverts + 1];
    for &i in indices {
        start[i as usize + 1] += 1;
    }
    for i in 0..nverts {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut adj = vec![0usize; indices.len()];
    for (k, &i) in indices.iter().enumerate() {
        adj[fill[i as usize]] = k / 3;
        fill[i as usize] += 1;
    }
    let cos_limit = 0.5f32;
    for (f, face) in faces.iter_mut().enumerate() {
        let nf = face_n[f].normalize_or_zero();
        for (j, v) in face.iter_mut().enumerate() {
            let vi = indices[3 * f + j] as usize;
            let mut sum = Vec3::ZERO;
            for &g in &adj[start[vi]..start[vi + 1]] {
                if face_n[g].normalize_or_zero().dot(nf) >= cos_limit {
                    sum += face_n[g];
                }
            }
            v.n = if sum.length_squared() > 0.0 {
                sum.normalize()
            } else {
                nf
            };
        }
    }
}

fn load_texture(path: &Path) -> Result<Texture, CaptureError> {
    let img = image::open(path).map_err(|e| CaptureError::Texture {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let rgb = img.to_rgb8();
    let (w, h) = rgb.dimensions();
    if w == 0 || h == 0 {
        return Err(CaptureError::Texture {
            path: path.to_path_buf(),
            reason: "empty image".to_string(),
        });
    }
    let data = rgb.pixels().map(|p| p.0).collect();
    Ok(Texture::new(w, h, data, true))
}
