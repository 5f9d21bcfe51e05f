//! PLY meshes: the loader (ASCII and binary of either byte order, as
//! scanners, MeshLab and the BOP benchmark write them) and the writer of
//! textured binary PLY files.

use std::collections::HashMap;
use std::io::{Cursor, Write};
use std::path::Path;

use glam::{Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{ElementDef, Encoding, Property, PropertyAccess, PropertyType, ScalarType};

use super::atlas::{self, ColourMode};
use super::{WHITE, mesh_name, smooth_normals, texture_from_image};
use crate::CaptureError;
use crate::object::{MeshBuilder, Object, UpAxis, Vertex};
use crate::texture::Texture;

/// The vertex attributes the loader reads, as slots of [`VertexRow`].
const X: usize = 0;
const NX: usize = 3;
const RED: usize = 6;
const U: usize = 9;
const V: usize = 10;
const SLOTS: usize = 11;

/// The slot of a vertex property, by the names writers use.
fn vertex_slot(name: &str) -> Option<usize> {
    Some(match name {
        "x" => X,
        "y" => X + 1,
        "z" => X + 2,
        "nx" => NX,
        "ny" => NX + 1,
        "nz" => NX + 2,
        "red" | "diffuse_red" => RED,
        "green" | "diffuse_green" => RED + 1,
        "blue" | "diffuse_blue" => RED + 2,
        "s" | "u" | "texture_u" | "texture_s" => U,
        "t" | "v" | "texture_v" | "texture_t" => V,
        _ => return None,
    })
}

/// One vertex as read: the slots the loader knows, others dropped while
/// parsing (a map per vertex would cost ~1 kB each on large scans).
struct VertexRow([f64; SLOTS]);

impl PropertyAccess for VertexRow {
    fn new() -> Self {
        VertexRow([0.0; SLOTS])
    }
    fn set_property(&mut self, key: &str, property: Property) {
        let Some(slot) = vertex_slot(key) else {
            return;
        };
        let colour = (RED..RED + 3).contains(&slot);
        // Integer colours are bytes (or 16-bit); float colours are 0-1.
        let value = match property {
            Property::Char(x) => x as f64 / if colour { 255.0 } else { 1.0 },
            Property::UChar(x) => x as f64 / if colour { 255.0 } else { 1.0 },
            Property::Short(x) => x as f64 / if colour { 255.0 } else { 1.0 },
            Property::UShort(x) => x as f64 / if colour { 65535.0 } else { 1.0 },
            Property::Int(x) => x as f64 / if colour { 255.0 } else { 1.0 },
            Property::UInt(x) => x as f64 / if colour { 255.0 } else { 1.0 },
            Property::Float(x) => x as f64,
            Property::Double(x) => x,
            _ => return,
        };
        self.0[slot] = value;
    }
}

/// One face as read: its corners, per-corner texture coordinates and
/// texture number, and whether a value could not be used.
#[derive(Default)]
struct FaceRow {
    idx: Vec<u32>,
    texcoord: Vec<f32>,
    texnumber: u32,
    bad: Option<&'static str>,
}

/// Converts an integer list to indices; `None` for a negative entry or a
/// list of non-integers.
fn index_list(property: Property) -> Option<Vec<u32>> {
    fn conv<T: TryInto<u32>>(v: Vec<T>) -> Option<Vec<u32>> {
        v.into_iter().map(|x| x.try_into().ok()).collect()
    }
    match property {
        Property::ListChar(v) => conv(v),
        Property::ListUChar(v) => conv(v),
        Property::ListShort(v) => conv(v),
        Property::ListUShort(v) => conv(v),
        Property::ListInt(v) => conv(v),
        Property::ListUInt(v) => Some(v),
        _ => None,
    }
}

impl PropertyAccess for FaceRow {
    fn new() -> Self {
        FaceRow::default()
    }
    fn set_property(&mut self, key: &str, property: Property) {
        match key {
            "vertex_indices" | "vertex_index" => match index_list(property) {
                Some(v) => self.idx = v,
                None => self.bad = Some("vertex indices that are not non-negative integers"),
            },
            "texcoord" => match property {
                Property::ListFloat(v) => self.texcoord = v,
                Property::ListDouble(v) => {
                    self.texcoord = v.into_iter().map(|x| x as f32).collect()
                }
                _ => self.bad = Some("a texcoord that is not a list of floats"),
            },
            "texnumber" => match property {
                Property::UChar(x) => self.texnumber = x as u32,
                Property::UShort(x) => self.texnumber = x as u32,
                Property::UInt(x) => self.texnumber = x,
                Property::Char(x) if x >= 0 => self.texnumber = x as u32,
                Property::Short(x) if x >= 0 => self.texnumber = x as u32,
                Property::Int(x) if x >= 0 => self.texnumber = x as u32,
                _ => self.bad = Some("a texnumber that is not a non-negative integer"),
            },
            _ => {}
        }
    }
}

/// An element the loader does not use: parsed past, nothing stored (a
/// zero-sized row, so even its `Vec` allocates nothing).
struct Ignored;

impl PropertyAccess for Ignored {
    fn new() -> Self {
        Ignored
    }
}

fn scalar_size(t: &ScalarType) -> usize {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest bytes one entry of `element` takes: the parser reserves
/// memory for the count the header states, so a count the file cannot
/// hold is refused before reading.
fn min_entry_bytes(element: &ElementDef, encoding: Encoding) -> usize {
    let bytes: usize = element
        .properties
        .values()
        .map(|p| match (encoding, &p.data_type) {
            // A digit and a separator per value (a list at least its count).
            (Encoding::Ascii, _) => 2,
            (_, PropertyType::Scalar(t)) => scalar_size(t),
            (_, PropertyType::List(count, _)) => scalar_size(count),
        })
        .sum();
    bytes.max(1)
}

/// The file names of `comment TextureFile NAME` lines, in order (MeshLab
/// writes one per texture, indexed by the faces' `texnumber`).
fn texture_files(comments: &[String]) -> Vec<String> {
    comments
        .iter()
        .filter_map(|c| {
            let c = c.trim();
            let (key, rest) = c.split_once(char::is_whitespace)?;
            (key.eq_ignore_ascii_case("texturefile") && !rest.trim().is_empty())
                .then(|| rest.trim().to_string())
        })
        .collect()
}

/// The gist of a ply-rs error, on one line: its first line and the text it
/// choked on. Its line numbers are right in the header but count from the
/// element's start in the payload, so `file_line` drops them there.
fn gist(e: &std::io::Error, file_line: bool) -> String {
    let msg = e.to_string();
    let first = msg.lines().next().unwrap_or("").trim();
    let first = match first.strip_prefix("Line ").and_then(|r| r.split_once(": ")) {
        Some((_, rest)) if !file_line => rest,
        _ => first,
    };
    let at = msg
        .lines()
        .find_map(|l| l.trim().strip_prefix("String: '"))
        .map(|s| s.trim_end_matches('\'').trim());
    match at {
        Some(text) if !text.is_empty() => format!("{first} (at '{text}')"),
        _ => first.to_string(),
    }
}

/// Loads a PLY mesh (see [`Object::load_mesh`]).
pub(crate) fn load(path: &Path, up: UpAxis) -> Result<Object, CaptureError> {
    let bytes = std::fs::read(path).map_err(|e| CaptureError::io(path, e))?;
    let bad = |reason: String| CaptureError::Ply {
        path: path.to_path_buf(),
        reason,
    };
    let mut cursor = Cursor::new(&bytes[..]);
    let header = Parser::<Ignored>::new()
        .read_header(&mut cursor)
        .map_err(|e| bad(format!("bad header: {}", gist(&e, true))))?;
    let mut room = bytes.len().saturating_sub(cursor.position() as usize);
    for element in header.elements.values() {
        let need = element
            .count
            .saturating_mul(min_entry_bytes(element, header.encoding));
        if need > room {
            return Err(bad(format!(
                "element '{}' has {} entries, more than the remaining {} bytes of the file \
                 can hold (is it truncated?)",
                element.name, element.count, room
            )));
        }
        room -= need;
    }

    let (mut vertex_def, mut face_def) = (None, None);
    let (mut vertices, mut faces) = (Vec::new(), Vec::new());
    for element in header.elements.values() {
        // Elements come in file order; anything after the two is not read.
        if vertex_def.is_some() && face_def.is_some() {
            break;
        }
        let read_err =
            |e: std::io::Error| bad(format!("element '{}': {}", element.name, gist(&e, false)));
        match element.name.as_str() {
            "vertex" if vertex_def.is_none() => {
                vertices = Parser::<VertexRow>::new()
                    .read_payload_for_element(&mut cursor, element, &header)
                    .map_err(read_err)?;
                vertex_def = Some(element);
            }
            "face" if face_def.is_none() => {
                faces = Parser::<FaceRow>::new()
                    .read_payload_for_element(&mut cursor, element, &header)
                    .map_err(read_err)?;
                face_def = Some(element);
            }
            _ => {
                Parser::<Ignored>::new()
                    .read_payload_for_element(&mut cursor, element, &header)
                    .map_err(read_err)?;
            }
        }
    }
    let vertex_def = vertex_def.ok_or_else(|| bad("no 'vertex' element".to_string()))?;
    let has = |slot: usize| {
        vertex_def.properties.values().any(|p| {
            vertex_slot(&p.name) == Some(slot) && matches!(p.data_type, PropertyType::Scalar(_))
        })
    };
    let has_all = |first: usize, n: usize| (first..first + n).all(has);
    if !has_all(X, 3) {
        return Err(bad("the vertices have no x, y and z".to_string()));
    }
    let Some(face_def) = face_def else {
        return Err(CaptureError::EmptyMesh {
            path: path.to_path_buf(),
        });
    };
    if !face_def.properties.contains_key("vertex_indices")
        && !face_def.properties.contains_key("vertex_index")
    {
        return Err(bad(
            "the faces have no vertex_indices (or vertex_index) list".to_string(),
        ));
    }
    let (has_normals, has_colours) = (has_all(NX, 3), has_all(RED, 3));
    let has_vertex_uv = has(U) && has(V);
    let has_face_uv = face_def.properties.contains_key("texcoord");
    let texture_names = texture_files(&header.comments);
    let textured = !texture_names.is_empty() && (has_vertex_uv || has_face_uv);
    if !textured && !has_colours {
        let detail = if texture_names.is_empty() {
            String::new()
        } else {
            format!(
                " (it names the texture {} but has no texture coordinates)",
                texture_names[0]
            )
        };
        return Err(CaptureError::NoColour {
            path: path.to_path_buf(),
            detail,
        });
    }

    let dir = path.parent().unwrap_or(Path::new(""));
    let mut b = MeshBuilder::new();
    // Texture per texnumber, loaded when a face first uses it.
    let mut tex_ids: Vec<Option<u32>> = vec![None; texture_names.len()];
    let white = (!textured).then(|| b.texture(Texture::solid([255, 255, 255])));
    let corner = |i: u32, uv: Vec2| -> Result<Vertex, CaptureError> {
        let row = vertices.get(i as usize).ok_or_else(|| {
            bad(format!(
                "vertex index {i} out of range ({} vertices)",
                vertices.len()
            ))
        })?;
        let r = &row.0;
        let vec = |s: usize| Vec3::new(r[s] as f32, r[s + 1] as f32, r[s + 2] as f32);
        let p = vec(X);
        if !p.is_finite() {
            return Err(bad(format!("vertex {i} has a non-finite coordinate")));
        }
        Ok(Vertex {
            p: up.to_z_up(p),
            n: if has_normals {
                up.to_z_up(vec(NX)).normalize_or_zero()
            } else {
                Vec3::ZERO
            },
            uv,
            c: if textured {
                WHITE
            } else {
                vec(RED).clamp(Vec3::ZERO, Vec3::ONE)
            },
        })
    };
    let vertex_uv = |i: u32| -> Vec2 {
        match vertices.get(i as usize) {
            // PLY puts v = 0 at the bottom of the image, as OBJ does.
            Some(row) if has_vertex_uv => Vec2::new(row.0[U] as f32, 1.0 - row.0[V] as f32),
            _ => Vec2::ZERO,
        }
    };
    let mut tris = Vec::with_capacity(faces.len());
    let mut tri_tex = Vec::with_capacity(faces.len());
    let mut indices = Vec::with_capacity(faces.len() * 3);
    for (f, face) in faces.iter().enumerate() {
        if let Some(what) = face.bad {
            return Err(bad(format!("face {f} has {what}")));
        }
        let n = face.idx.len();
        if n < 3 {
            continue; // points and edges draw nothing
        }
        let use_face_uv = textured && has_face_uv;
        if use_face_uv && face.texcoord.len() != 2 * n {
            return Err(bad(format!(
                "face {f}: texcoord has {} values for {n} corners (expected {})",
                face.texcoord.len(),
                2 * n
            )));
        }
        let tex = match white {
            Some(w) => w,
            None => {
                let k = face.texnumber as usize;
                let slot = tex_ids.get_mut(k).ok_or_else(|| {
                    bad(format!(
                        "face {f}: texnumber {k}, but the header names {} texture file(s)",
                        texture_names.len()
                    ))
                })?;
                match *slot {
                    Some(t) => t,
                    None => {
                        let t = b.texture(load_ply_texture(path, dir, &texture_names[k])?);
                        *slot = Some(t);
                        t
                    }
                }
            }
        };
        let uv = |j: usize| -> Vec2 {
            if use_face_uv {
                Vec2::new(face.texcoord[2 * j], 1.0 - face.texcoord[2 * j + 1])
            } else {
                vertex_uv(face.idx[j])
            }
        };
        // Polygons are fanned around their first corner.
        for k in 1..n - 1 {
            let js = [0, k, k + 1];
            let mut v = [Vertex {
                p: Vec3::ZERO,
                n: Vec3::ZERO,
                uv: Vec2::ZERO,
                c: WHITE,
            }; 3];
            for (vj, &j) in v.iter_mut().zip(&js) {
                *vj = corner(face.idx[j], uv(j))?;
                indices.push(face.idx[j]);
            }
            tris.push(v);
            tri_tex.push(tex);
        }
    }
    if tris.is_empty() {
        return Err(CaptureError::EmptyMesh {
            path: path.to_path_buf(),
        });
    }
    if !has_normals {
        smooth_normals(&mut tris, &indices);
    }
    for (v, t) in tris.into_iter().zip(tri_tex) {
        b.tri(v[0], v[1], v[2], t);
    }
    // PLY states no unit: metres until the caller says otherwise.
    Ok(b.finish_normalised(&mesh_name(path), 1.0))
}

/// Loads the texture file `name` of a PLY file, relative to its directory.
fn load_ply_texture(ply: &Path, dir: &Path, name: &str) -> Result<Texture, CaptureError> {
    let file = dir.join(name.replace('\\', "/"));
    let bad = |reason: String| CaptureError::MeshTexture {
        path: file.clone(),
        mesh: ply.to_path_buf(),
        reason,
    };
    let img = image::open(&file).map_err(|e| bad(e.to_string()))?;
    // Wrapping, as for OBJ textures: both come from the same tools.
    texture_from_image(&img, true).ok_or_else(|| bad("empty image".to_string()))
}

/// Writes `obj` as a binary little-endian PLY file in units of `unit_m`
/// metres (see [`Object::write_ply`]).
pub(crate) fn write(obj: &Object, path: &Path, unit_m: f64) -> Result<(), CaptureError> {
    let fail = |reason: String| CaptureError::PlyWrite {
        path: path.to_path_buf(),
        reason,
    };
    let colouring = atlas::bake(obj).map_err(fail)?;
    let scale = obj.radius_m() / unit_m;

    // Corners with equal attributes share one vertex.
    let mut index: HashMap<[u32; 11], u32> = HashMap::new();
    let mut vertices: Vec<[u32; 11]> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(obj.tris.len());
    for (t, tri) in obj.tris.iter().enumerate() {
        let mut face = [0u32; 3];
        for (j, v) in tri.iter().enumerate() {
            let p = (v.p.as_dvec3() * scale).as_vec3();
            let mut key = [0u32; 11];
            for (k, x) in p.to_array().into_iter().chain(v.n.to_array()).enumerate() {
                key[k] = x.to_bits();
            }
            match &colouring {
                ColourMode::Vertex(colours) => {
                    let c = colours[t][j];
                    key[6..9].copy_from_slice(&c.map(u32::from));
                }
                ColourMode::Texture(_, uv) => {
                    // PLY puts v = 0 at the bottom of the image.
                    let q = uv[t][j];
                    key[9] = q.x.to_bits();
                    key[10] = (1.0 - q.y).to_bits();
                }
            }
            face[j] = *index.entry(key).or_insert_with(|| {
                vertices.push(key);
                (vertices.len() - 1) as u32
            });
        }
        faces.push(face);
    }

    let texture_file = match &colouring {
        ColourMode::Texture(img, _) => {
            let png = path.with_extension("png");
            img.save_with_format(&png, image::ImageFormat::Png)
                .map_err(|e| fail(format!("cannot write its texture {}: {e}", png.display())))?;
            Some(
                png.file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
            )
        }
        ColourMode::Vertex(_) => None,
    };

    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    let name: String = obj.name().chars().filter(|c| !c.is_control()).collect();
    header += &format!("comment written by acch: object '{name}', unit {unit_m} m\n");
    if let Some(file) = &texture_file {
        header += &format!("comment TextureFile {file}\n");
    }
    header += &format!("element vertex {}\n", vertices.len());
    for p in ["x", "y", "z", "nx", "ny", "nz"] {
        header += &format!("property float {p}\n");
    }
    if texture_file.is_some() {
        header += "property float texture_u\nproperty float texture_v\n";
    } else {
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    header += &format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        faces.len()
    );

    let file = std::fs::File::create(path).map_err(|e| CaptureError::io(path, e))?;
    let mut out = std::io::BufWriter::new(file);
    let io = |e: std::io::Error| CaptureError::io(path, e);
    out.write_all(header.as_bytes()).map_err(io)?;
    for v in &vertices {
        for x in &v[..6] {
            out.write_all(&x.to_le_bytes()).map_err(io)?;
        }
        if texture_file.is_some() {
            out.write_all(&v[9].to_le_bytes()).map_err(io)?;
            out.write_all(&v[10].to_le_bytes()).map_err(io)?;
        } else {
            out.write_all(&v[6..9].iter().map(|&c| c as u8).collect::<Vec<_>>())
                .map_err(io)?;
        }
    }
    for f in &faces {
        out.write_all(&[3]).map_err(io)?;
        for &i in f {
            out.write_all(&(i as i32).to_le_bytes()).map_err(io)?;
        }
    }
    out.flush().map_err(io)
}
