//! The glTF 2.0 loader, for `.gltf` (JSON with external or `data:` URI
//! buffers and images) and `.glb` (binary container) files: the triangles
//! of every mesh of the default scene, placed by their nodes' transforms,
//! coloured by the material's base colour (texture times factor times the
//! `COLOR_0` vertex colours).
//!
//! The JSON is read with serde rather than the `gltf` crate: that crate
//! turns on serde_json's `raw_value` feature, which would rebuild every
//! crate of the workspace that uses serde_json.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use base64::Engine;
use glam::{DMat3, DMat4, DQuat, DVec3, Vec2, Vec3};
use serde::Deserialize;

use super::{WHITE, flat_normals, linear_to_srgb, mesh_name, texture_from_image};
use crate::CaptureError;
use crate::object::{MeshBuilder, Object, UpAxis, Vertex};
use crate::texture::Texture;

// The subset of the glTF 2.0 schema the loader reads; serde skips the rest.

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Root {
    asset: Asset,
    scene: Option<usize>,
    #[serde(default)]
    scenes: Vec<Scene>,
    #[serde(default)]
    nodes: Vec<Node>,
    #[serde(default)]
    meshes: Vec<Mesh>,
    #[serde(default)]
    accessors: Vec<Accessor>,
    #[serde(default)]
    buffer_views: Vec<BufferView>,
    #[serde(default)]
    buffers: Vec<Buffer>,
    #[serde(default)]
    materials: Vec<Material>,
    #[serde(default)]
    textures: Vec<TextureDef>,
    #[serde(default)]
    images: Vec<Image>,
    #[serde(default)]
    samplers: Vec<Sampler>,
    #[serde(default)]
    extensions_required: Vec<String>,
}

#[derive(Deserialize)]
struct Asset {
    version: String,
}

#[derive(Deserialize)]
struct Scene {
    #[serde(default)]
    nodes: Vec<usize>,
}

#[derive(Deserialize)]
struct Node {
    mesh: Option<usize>,
    #[serde(default)]
    children: Vec<usize>,
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
}

#[derive(Deserialize)]
struct Mesh {
    primitives: Vec<Primitive>,
}

#[derive(Deserialize)]
struct Primitive {
    attributes: HashMap<String, usize>,
    indices: Option<usize>,
    material: Option<usize>,
    #[serde(default = "triangles")]
    mode: u32,
}

fn triangles() -> u32 {
    4
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Accessor {
    buffer_view: Option<usize>,
    #[serde(default)]
    byte_offset: usize,
    component_type: u32,
    #[serde(default)]
    normalized: bool,
    count: usize,
    #[serde(rename = "type")]
    kind: String,
    sparse: Option<Sparse>,
}

#[derive(Deserialize)]
struct Sparse {
    count: usize,
    indices: SparseIndices,
    values: SparseValues,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct SparseIndices {
    buffer_view: usize,
    #[serde(default)]
    byte_offset: usize,
    component_type: u32,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct SparseValues {
    buffer_view: usize,
    #[serde(default)]
    byte_offset: usize,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct BufferView {
    buffer: usize,
    #[serde(default)]
    byte_offset: usize,
    byte_length: usize,
    byte_stride: Option<usize>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Buffer {
    uri: Option<String>,
    byte_length: usize,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Material {
    pbr_metallic_roughness: Option<Pbr>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Pbr {
    base_color_factor: Option<[f32; 4]>,
    base_color_texture: Option<TextureInfo>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct TextureInfo {
    index: usize,
    #[serde(default)]
    tex_coord: usize,
}

#[derive(Deserialize)]
struct TextureDef {
    source: Option<usize>,
    sampler: Option<usize>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Image {
    uri: Option<String>,
    buffer_view: Option<usize>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct Sampler {
    #[serde(default = "repeat")]
    wrap_s: u32,
    #[serde(default = "repeat")]
    wrap_t: u32,
}

fn repeat() -> u32 {
    10497
}

/// `CLAMP_TO_EDGE`, the one wrap mode that does not repeat.
const CLAMP_TO_EDGE: u32 = 33071;

/// Required extensions the loader can honour: quantised attributes are
/// read like any other component type, and unlit materials differ only in
/// shading.
const SUPPORTED_EXTENSIONS: &[&str] = &["KHR_mesh_quantization", "KHR_materials_unlit"];

/// The JSON and binary chunks of a GLB file.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), String> {
    let word = |at: usize| -> Option<u32> {
        let b = bytes.get(at..at + 4)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let version = word(4).ok_or("truncated GLB header")?;
    if version != 2 {
        return Err(format!(
            "GLB container version {version}; only 2 is supported"
        ));
    }
    let length = (word(8).ok_or("truncated GLB header")? as usize).min(bytes.len());
    let (mut at, mut json, mut bin) = (12usize, None, None);
    while at + 8 <= length {
        let (len, kind) = (word(at).unwrap_or(0) as usize, word(at + 4).unwrap_or(0));
        let data = bytes
            .get(at + 8..at + 8 + len)
            .ok_or_else(|| format!("GLB chunk at byte {at} runs past the end of the file"))?;
        match kind {
            0x4E4F_534A if json.is_none() => json = Some(data),
            0x004E_4942 if bin.is_none() => bin = Some(data),
            _ => {} // unknown chunks are skipped, as the spec asks
        }
        at += 8 + len.div_ceil(4) * 4;
    }
    Ok((json.ok_or("GLB file without a JSON chunk")?, bin))
}

/// Decodes `%XX` escapes of a relative URI.
fn percent_decode(s: &str) -> Vec<u8> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%'
            && let (Some(h), Some(l)) = (
                b.get(i + 1).and_then(|&c| hex(c)),
                b.get(i + 2).and_then(|&c| hex(c)),
            )
        {
            out.push((h * 16 + l) as u8);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    out
}

/// What a URI points to: bytes of a `data:` URI, or a file relative to the
/// glTF file.
enum Uri {
    Data(Vec<u8>),
    File(PathBuf),
}

fn resolve_uri(uri: &str, dir: &Path) -> Result<Uri, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (meta, data) = rest
            .split_once(',')
            .ok_or_else(|| "a data: URI without a comma".to_string())?;
        if !meta.ends_with(";base64") {
            return Err("a data: URI that is not base64".to_string());
        }
        return base64::engine::general_purpose::STANDARD
            .decode(data.trim())
            .map(Uri::Data)
            .map_err(|e| format!("a data: URI with bad base64: {e}"));
    }
    let name = String::from_utf8_lossy(&percent_decode(uri)).into_owned();
    Ok(Uri::File(dir.join(name)))
}

/// The parsed file with its buffers loaded.
struct Doc {
    root: Root,
    buffers: Vec<Vec<u8>>,
}

/// Component size in bytes of a glTF component type.
fn component_size(ct: u32) -> Option<usize> {
    match ct {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

/// Reads one component as a float (normalised integers to [0, 1] or
/// [-1, 1]); `b` holds at least the component's bytes.
fn component(b: &[u8], ct: u32, normalized: bool) -> f32 {
    let scale = |x: f32, max: f32| if normalized { (x / max).max(-1.0) } else { x };
    match ct {
        5120 => scale(b[0] as i8 as f32, 127.0),
        5121 => scale(b[0] as f32, 255.0),
        5122 => scale(i16::from_le_bytes([b[0], b[1]]) as f32, 32767.0),
        5123 => scale(u16::from_le_bytes([b[0], b[1]]) as f32, 65535.0),
        5125 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
        _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

/// Reads one integer component (for indices).
fn integer(b: &[u8], ct: u32) -> u32 {
    match ct {
        5121 => b[0] as u32,
        5123 => u16::from_le_bytes([b[0], b[1]]) as u32,
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    }
}

impl Doc {
    /// The bytes of buffer view `i` from `offset` on, and its stride.
    fn view(&self, i: usize, offset: usize) -> Result<(&[u8], Option<usize>), String> {
        let v = self
            .root
            .buffer_views
            .get(i)
            .ok_or_else(|| format!("buffer view {i} does not exist"))?;
        let buf = self
            .buffers
            .get(v.buffer)
            .ok_or_else(|| format!("buffer view {i}: buffer {} does not exist", v.buffer))?;
        let bytes = v
            .byte_offset
            .checked_add(v.byte_length)
            .and_then(|end| buf.get(v.byte_offset..end))
            .ok_or_else(|| format!("buffer view {i} runs past the end of buffer {}", v.buffer))?;
        let bytes = bytes
            .get(offset..)
            .ok_or_else(|| format!("an offset {offset} past the end of buffer view {i}"))?;
        Ok((bytes, v.byte_stride))
    }

    /// Reads accessor `a` as floats, `n` per element (checked against its
    /// type, which must be one of `kinds`).
    fn floats(&self, a: usize, kinds: &[&str]) -> Result<(Vec<f32>, usize), String> {
        let acc = self
            .root
            .accessors
            .get(a)
            .ok_or_else(|| format!("accessor {a} does not exist"))?;
        let n = match acc.kind.as_str() {
            k if !kinds.contains(&k) => {
                return Err(format!(
                    "accessor {a} is a {k}, expected {}",
                    kinds.join(" or ")
                ));
            }
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            _ => 4,
        };
        let cs = component_size(acc.component_type).ok_or_else(|| {
            format!(
                "accessor {a}: unknown component type {}",
                acc.component_type
            )
        })?;
        let total = acc
            .count
            .checked_mul(n)
            .ok_or_else(|| format!("accessor {a}: count {} too large", acc.count))?;
        let mut out = match acc.buffer_view {
            Some(v) => {
                let (bytes, stride) = self.view(v, acc.byte_offset)?;
                read_elements(bytes, stride, acc.count, n, cs)
                    .ok_or_else(|| format!("accessor {a} runs past the end of buffer view {v}"))?
                    .map(|b| component(b, acc.component_type, acc.normalized))
                    .collect()
            }
            // No buffer view: all zeros, unless sparse values say otherwise.
            None => {
                if total > self.buffers.iter().map(Vec::len).sum::<usize>() + (1 << 20) {
                    return Err(format!("accessor {a}: count {} too large", acc.count));
                }
                vec![0.0; total]
            }
        };
        if let Some(sp) = &acc.sparse {
            let (ib, _) = self.view(sp.indices.buffer_view, sp.indices.byte_offset)?;
            let ics = component_size(sp.indices.component_type)
                .ok_or_else(|| format!("accessor {a}: bad sparse index type"))?;
            let (vb, _) = self.view(sp.values.buffer_view, sp.values.byte_offset)?;
            let idx: Vec<u32> = read_elements(ib, None, sp.count, 1, ics)
                .ok_or_else(|| format!("accessor {a}: sparse indices run past their view"))?
                .map(|b| integer(b, sp.indices.component_type))
                .collect();
            let vals: Vec<f32> = read_elements(vb, None, sp.count, n, cs)
                .ok_or_else(|| format!("accessor {a}: sparse values run past their view"))?
                .map(|b| component(b, acc.component_type, acc.normalized))
                .collect();
            for (k, &i) in idx.iter().enumerate() {
                let i = i as usize;
                if i >= acc.count {
                    return Err(format!("accessor {a}: sparse index {i} out of range"));
                }
                out[i * n..(i + 1) * n].copy_from_slice(&vals[k * n..(k + 1) * n]);
            }
        }
        Ok((out, n))
    }

    /// Reads an index accessor.
    fn indices(&self, a: usize) -> Result<Vec<u32>, String> {
        let acc = self
            .root
            .accessors
            .get(a)
            .ok_or_else(|| format!("accessor {a} does not exist"))?;
        if acc.kind != "SCALAR" || ![5121, 5123, 5125].contains(&acc.component_type) {
            return Err(format!(
                "index accessor {a} is not unsigned integer scalars"
            ));
        }
        if acc.sparse.is_some() || acc.buffer_view.is_none() {
            // Rare for indices; read through the float path (exact below 2^24).
            let (v, _) = self.floats(a, &["SCALAR"])?;
            return Ok(v.into_iter().map(|x| x as u32).collect());
        }
        let cs = component_size(acc.component_type).unwrap_or(4);
        let (bytes, stride) = self.view(acc.buffer_view.unwrap_or(0), acc.byte_offset)?;
        Ok(read_elements(bytes, stride, acc.count, 1, cs)
            .ok_or_else(|| format!("index accessor {a} runs past the end of its buffer view"))?
            .map(|b| integer(b, acc.component_type))
            .collect())
    }
}

/// The components of `count` elements of `n` components of `cs` bytes,
/// `stride` bytes apart (packed if `None`); `None` if they do not fit.
fn read_elements(
    bytes: &[u8],
    stride: Option<usize>,
    count: usize,
    n: usize,
    cs: usize,
) -> Option<impl Iterator<Item = &[u8]>> {
    let elem = n * cs;
    let stride = stride.filter(|&s| s > 0).unwrap_or(elem);
    if count > 0 {
        let last = (count - 1).checked_mul(stride)?.checked_add(elem)?;
        if last > bytes.len() {
            return None;
        }
    }
    Some((0..count).flat_map(move |i| (0..n).map(move |c| &bytes[i * stride + c * cs..])))
}

/// A node's local transform.
fn local_transform(node: &Node) -> DMat4 {
    if let Some(m) = node.matrix {
        return DMat4::from_cols_array(&m);
    }
    let t = node.translation.map_or(DVec3::ZERO, DVec3::from_array);
    let r = node
        .rotation
        .map_or(DQuat::IDENTITY, |q| DQuat::from_array(q).normalize());
    let s = node.scale.map_or(DVec3::ONE, DVec3::from_array);
    DMat4::from_scale_rotation_translation(s, r, t)
}

/// Loads a glTF 2.0 or GLB mesh (see [`Object::load_mesh`]).
pub(crate) fn load(path: &Path, up: UpAxis) -> Result<Object, CaptureError> {
    let bad = |reason: String| CaptureError::Gltf {
        path: path.to_path_buf(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|e| CaptureError::io(path, e))?;
    // The content decides, not the extension: some .gltf files are GLB.
    let (json, bin) = if bytes.starts_with(b"glTF") {
        split_glb(&bytes).map_err(bad)?
    } else {
        (&bytes[..], None)
    };
    let root: Root = serde_json::from_slice(json).map_err(|e| bad(format!("bad JSON: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(bad(format!(
            "glTF version {}; only 2.x is supported",
            root.asset.version
        )));
    }
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str()))
    {
        return Err(bad(format!(
            "requires the extension {ext}, which the loader does not support"
        )));
    }
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (i, buf) in root.buffers.iter().enumerate() {
        let data = match (&buf.uri, i, bin) {
            (None, 0, Some(bin)) => bin.to_vec(),
            (None, ..) => {
                return Err(bad(format!(
                    "buffer {i} has no uri and no GLB binary chunk"
                )));
            }
            (Some(uri), ..) => match resolve_uri(uri, dir)
                .map_err(|e| bad(format!("buffer {i}: {e}")))?
            {
                Uri::Data(d) => d,
                Uri::File(f) => std::fs::read(&f)
                    .map_err(|e| bad(format!("buffer {i}: cannot read {}: {e}", f.display())))?,
            },
        };
        if data.len() < buf.byte_length {
            return Err(bad(format!(
                "buffer {i} holds {} bytes, less than its byteLength {}",
                data.len(),
                buf.byte_length
            )));
        }
        buffers.push(data);
    }
    let doc = Doc { root, buffers };

    // The meshes to draw, with their world transforms.
    let mut instances: Vec<(usize, DMat4)> = Vec::new();
    let scene = doc
        .root
        .scene
        .or((!doc.root.scenes.is_empty()).then_some(0));
    match scene {
        Some(s) => {
            let scene = doc
                .root
                .scenes
                .get(s)
                .ok_or_else(|| bad(format!("scene {s} does not exist")))?;
            // Depth-first with an explicit stack; a depth beyond the node
            // count means a cycle.
            let mut stack: Vec<(usize, DMat4, usize)> = scene
                .nodes
                .iter()
                .map(|&n| (n, DMat4::IDENTITY, 0))
                .collect();
            while let Some((n, parent, depth)) = stack.pop() {
                let node = doc
                    .root
                    .nodes
                    .get(n)
                    .ok_or_else(|| bad(format!("node {n} does not exist")))?;
                if depth > doc.root.nodes.len() {
                    return Err(bad("the node hierarchy has a cycle".to_string()));
                }
                let world = parent * local_transform(node);
                if let Some(m) = node.mesh {
                    instances.push((m, world));
                }
                stack.extend(node.children.iter().rev().map(|&c| (c, world, depth + 1)));
            }
        }
        None => instances.extend((0..doc.root.meshes.len()).map(|m| (m, DMat4::IDENTITY))),
    }

    let mut b = MeshBuilder::new();
    let mut images: HashMap<(usize, bool), u32> = HashMap::new();
    let mut solids: HashMap<[u8; 3], u32> = HashMap::new();
    for (m, world) in instances {
        let mesh = doc
            .root
            .meshes
            .get(m)
            .ok_or_else(|| bad(format!("mesh {m} does not exist")))?;
        let normal_m = {
            let m3 = DMat3::from_mat4(world);
            if m3.determinant().abs() > 1e-300 {
                m3.inverse().transpose()
            } else {
                m3
            }
        };
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let what = format!("mesh {m} primitive {p}");
            let ctx = |e: String| bad(format!("{what}: {e}"));
            if !(4..=6).contains(&prim.mode) {
                continue; // points and lines draw nothing
            }
            let pos_a = *prim
                .attributes
                .get("POSITION")
                .ok_or_else(|| ctx("no POSITION attribute".to_string()))?;
            let (pos, _) = doc.floats(pos_a, &["VEC3"]).map_err(ctx)?;
            let nverts = pos.len() / 3;
            let normals = match prim.attributes.get("NORMAL") {
                Some(&a) => Some(doc.floats(a, &["VEC3"]).map_err(ctx)?.0),
                None => None,
            };
            let material = match prim.material {
                Some(i) => Some(
                    doc.root
                        .materials
                        .get(i)
                        .ok_or_else(|| ctx(format!("material {i} does not exist")))?,
                ),
                None => None,
            };
            let pbr = material.and_then(|m| m.pbr_metallic_roughness.as_ref());
            let factor = pbr.and_then(|p| p.base_color_factor);
            let tex_info = pbr.and_then(|p| p.base_color_texture.as_ref());
            let uv_attr = tex_info.and_then(|t| {
                prim.attributes
                    .get(&format!("TEXCOORD_{}", t.tex_coord))
                    .copied()
            });
            let colours = match prim.attributes.get("COLOR_0") {
                Some(&a) => Some(doc.floats(a, &["VEC3", "VEC4"]).map_err(ctx)?),
                None => None,
            };
            if uv_attr.is_none() && colours.is_none() && factor.is_none() {
                let detail = match tex_info {
                    Some(t) => format!(
                        " ({what}: its base colour texture has no TEXCOORD_{})",
                        t.tex_coord
                    ),
                    None => format!(" ({what})"),
                };
                return Err(CaptureError::NoColour {
                    path: path.to_path_buf(),
                    detail,
                });
            }
            let factor = factor.unwrap_or([1.0; 4]);
            let (tex, uvs) = match (tex_info, uv_attr) {
                (Some(t), Some(a)) => {
                    let tex = image_texture(&doc, t.index, path, dir, &mut images, &mut b)?;
                    (tex, Some(doc.floats(a, &["VEC2"]).map_err(ctx)?.0))
                }
                _ if colours.is_some() => {
                    let white = solid(&mut b, &mut solids, [255; 3]);
                    (white, None)
                }
                _ => {
                    // A plain colour: a single-colour texture, as the
                    // built-in objects' plain parts are.
                    let c =
                        std::array::from_fn(|k| (linear_to_srgb(factor[k]) * 255.0 + 0.5) as u8);
                    (solid(&mut b, &mut solids, c), None)
                }
            };
            let textured_or_vc = uvs.is_some() || colours.is_some();
            let idx = match prim.indices {
                Some(a) => doc.indices(a).map_err(ctx)?,
                None => (0..nverts as u32).collect(),
            };
            let corners: Vec<[u32; 3]> = match prim.mode {
                4 => idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
                // Strips alternate winding; the renderer lights both sides.
                5 => idx.windows(3).map(|t| [t[0], t[1], t[2]]).collect(),
                _ => (1..idx.len().saturating_sub(1))
                    .map(|k| [idx[0], idx[k], idx[k + 1]])
                    .collect(),
            };
            let vertex = |i: u32| -> Result<Vertex, CaptureError> {
                let i = i as usize;
                if i >= nverts {
                    return Err(ctx(format!(
                        "vertex index {i} out of range ({nverts} vertices)"
                    )));
                }
                let at = |v: &[f32], n: usize, k: usize| v.get(i * n + k).copied();
                let p3 = DVec3::new(
                    pos[3 * i] as f64,
                    pos[3 * i + 1] as f64,
                    pos[3 * i + 2] as f64,
                );
                let p = world.transform_point3(p3).as_vec3();
                if !p.is_finite() {
                    return Err(ctx(format!("vertex {i} has a non-finite position")));
                }
                let n = normals.as_ref().map_or(Vec3::ZERO, |nv| {
                    let n = DVec3::new(
                        at(nv, 3, 0).unwrap_or(0.0) as f64,
                        at(nv, 3, 1).unwrap_or(0.0) as f64,
                        at(nv, 3, 2).unwrap_or(0.0) as f64,
                    );
                    up.to_z_up((normal_m * n).as_vec3()).normalize_or_zero()
                });
                let uv = uvs.as_ref().map_or(Vec2::ZERO, |t| {
                    // glTF puts v = 0 at the top of the image, as we do.
                    Vec2::new(at(t, 2, 0).unwrap_or(0.0), at(t, 2, 1).unwrap_or(0.0))
                });
                let c = if textured_or_vc {
                    let vc = colours.as_ref().map_or([1.0; 3], |(cv, n)| {
                        std::array::from_fn(|k| at(cv, *n, k).unwrap_or(1.0))
                    });
                    Vec3::from_array(std::array::from_fn(|k| linear_to_srgb(factor[k] * vc[k])))
                } else {
                    WHITE
                };
                Ok(Vertex {
                    p: up.to_z_up(p),
                    n,
                    uv,
                    c,
                })
            };
            let mut faces = Vec::with_capacity(corners.len());
            for t in &corners {
                faces.push([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?]);
            }
            if normals.is_none() {
                flat_normals(&mut faces);
            }
            for f in faces {
                b.tri(f[0], f[1], f[2], tex);
            }
        }
    }
    if b.is_empty() {
        return Err(CaptureError::EmptyMesh {
            path: path.to_path_buf(),
        });
    }
    // glTF's unit is the metre.
    Ok(b.finish_normalised(&mesh_name(path), 1.0))
}

/// The single-colour texture of `c`, added once.
fn solid(b: &mut MeshBuilder, solids: &mut HashMap<[u8; 3], u32>, c: [u8; 3]) -> u32 {
    *solids
        .entry(c)
        .or_insert_with(|| b.texture(Texture::solid(c)))
}

/// The texture of glTF texture `t` (its image and wrap mode), decoded and
/// added once.
fn image_texture(
    doc: &Doc,
    t: usize,
    path: &Path,
    dir: &Path,
    cache: &mut HashMap<(usize, bool), u32>,
    b: &mut MeshBuilder,
) -> Result<u32, CaptureError> {
    let bad = |reason: String| CaptureError::Gltf {
        path: path.to_path_buf(),
        reason,
    };
    let tex = doc
        .root
        .textures
        .get(t)
        .ok_or_else(|| bad(format!("texture {t} does not exist")))?;
    let source = tex.source.ok_or_else(|| {
        bad(format!(
            "texture {t} has no PNG or JPEG source (only an extension's, e.g. KTX2 or WebP)"
        ))
    })?;
    let repeat = match tex.sampler {
        Some(s) => {
            let s = doc
                .root
                .samplers
                .get(s)
                .ok_or_else(|| bad(format!("sampler {s} does not exist")))?;
            // One flag for both axes: clamp only when both clamp.
            !(s.wrap_s == CLAMP_TO_EDGE && s.wrap_t == CLAMP_TO_EDGE)
        }
        None => true,
    };
    if let Some(&id) = cache.get(&(source, repeat)) {
        return Ok(id);
    }
    let image = doc
        .root
        .images
        .get(source)
        .ok_or_else(|| bad(format!("image {source} does not exist")))?;
    let decoded = match (&image.uri, image.buffer_view) {
        (_, Some(v)) => {
            let (bytes, _) = doc
                .view(v, 0)
                .map_err(|e| bad(format!("image {source}: {e}")))?;
            image::load_from_memory(bytes)
                .map_err(|e| bad(format!("image {source} (embedded): cannot decode: {e}")))?
        }
        (Some(uri), None) => {
            match resolve_uri(uri, dir).map_err(|e| bad(format!("image {source}: {e}")))? {
                Uri::Data(d) => image::load_from_memory(&d)
                    .map_err(|e| bad(format!("image {source} (data: URI): cannot decode: {e}")))?,
                Uri::File(f) => image::open(&f).map_err(|e| CaptureError::MeshTexture {
                    path: f.clone(),
                    mesh: path.to_path_buf(),
                    reason: e.to_string(),
                })?,
            }
        }
        (None, None) => {
            return Err(bad(format!(
                "image {source} has neither uri nor bufferView"
            )));
        }
    };
    let texture = texture_from_image(&decoded, repeat)
        .ok_or_else(|| bad(format!("image {source} is empty")))?;
    let id = b.texture(texture);
    cache.insert((source, repeat), id);
    Ok(id)
}
