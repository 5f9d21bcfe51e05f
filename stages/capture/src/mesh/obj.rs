//! The OBJ loader: UV-mapped meshes whose MTL materials name a diffuse
//! texture (`map_Kd`).

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::{load_texture, mesh_name, smooth_normals};
use crate::CaptureError;
use crate::object::{MeshBuilder, Object, UpAxis, Vertex};

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

/// Loads a textured OBJ mesh (see [`Object::load_obj_with_up`]).
pub(crate) fn load(path: &Path, up: UpAxis) -> Result<Object, CaptureError> {
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
                c: Vec3::ONE,
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
    if b.is_empty() {
        return Err(CaptureError::EmptyMesh {
            path: path.to_path_buf(),
        });
    }
    // OBJ states no unit: metres until the caller says otherwise.
    Ok(b.finish_normalised(&mesh_name(path), 1.0))
}
