//! Mesh files: the loaders of OBJ, PLY and glTF 2.0 / GLB meshes, one
//! module per format, and the PLY writer, with the [`Object`] methods that
//! call them ([`Object::load_mesh`], [`Object::write_ply`], ...). Every
//! loader rotates the file's up axis onto +z and normalises the mesh with
//! [`MeshBuilder::finish_normalised`](crate::object::MeshBuilder::finish_normalised),
//! taking the file's coordinates as metres.

mod atlas;
mod gltf;
pub(crate) mod obj;
pub(crate) mod ply;

use std::path::Path;

use glam::Vec3;

use crate::CaptureError;
use crate::object::{Object, UpAxis, Vertex, check_size};
use crate::texture::Texture;

impl Object {
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
        Ok(obj::load(path.as_ref(), up)?.with_file_up(up))
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
        load(path.as_ref(), up)
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
        ply::write(self, path.as_ref(), unit_m)
    }
}

/// The extensions [`load`] accepts, as its error message lists them.
const ACCEPTED: &str = ".obj, .ply, .gltf, .glb";

/// Loads a mesh file, choosing the format by its extension.
pub(crate) fn load(path: &Path, up: UpAxis) -> Result<Object, CaptureError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let object = match ext.as_deref() {
        Some("obj") => obj::load(path, up),
        Some("ply") => ply::load(path, up),
        Some("gltf" | "glb") => gltf::load(path, up),
        _ => Err(CaptureError::UnknownMeshFormat {
            path: path.to_path_buf(),
            accepted: ACCEPTED.to_string(),
        }),
    }?;
    Ok(object.with_file_up(up))
}

/// The object name of a mesh file: its stem.
pub(crate) fn mesh_name(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".to_string())
}

/// Vertex normals for a mesh without them: the area-weighted mean of the
/// normals of the faces sharing the vertex, leaving out faces that meet at
/// more than 60 degrees so creases stay sharp.
pub(crate) fn smooth_normals(faces: &mut [[Vertex; 3]], indices: &[u32]) {
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

/// Flat normals: every corner gets its triangle's normal (glTF's rule for
/// primitives without normals).
pub(crate) fn flat_normals(faces: &mut [[Vertex; 3]]) {
    for f in faces {
        let n = (f[1].p - f[0].p).cross(f[2].p - f[0].p).normalize_or_zero();
        for v in f.iter_mut() {
            v.n = n;
        }
    }
}

/// Loads a texture image file (PNG or JPEG), wrapping at the border.
pub(crate) fn load_texture(path: &Path) -> Result<Texture, CaptureError> {
    let bad = |reason: String| CaptureError::Texture {
        path: path.to_path_buf(),
        reason,
    };
    let img = image::open(path).map_err(|e| bad(e.to_string()))?;
    texture_from_image(&img, true).ok_or_else(|| bad("empty image".to_string()))
}

/// The texture of a decoded image (alpha dropped); `None` for an empty one.
pub(crate) fn texture_from_image(img: &image::DynamicImage, repeat: bool) -> Option<Texture> {
    let rgb = img.to_rgb8();
    let (w, h) = rgb.dimensions();
    if w == 0 || h == 0 {
        return None;
    }
    let data = rgb.pixels().map(|p| p.0).collect();
    Some(Texture::new(w, h, data, repeat))
}

/// Encodes a linear colour value (glTF's vertex colours and factors) with
/// the sRGB transfer curve: textures and images hold sRGB-encoded bytes,
/// and the renderer multiplies in that space.
pub(crate) fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// A white vertex colour: the texel shows unchanged.
pub(crate) const WHITE: Vec3 = Vec3::ONE;
