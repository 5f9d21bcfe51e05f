//! BOP datasets (the Benchmark for 6D Object Pose Estimation's format, as
//! `bop_toolkit` reads and writes it), in and out.
//!
//! Layout: `DIR/camera.json`, `DIR/models/{models_info.json,
//! obj_OOOOOO.ply}`, and per split and scene `DIR/SPLIT/SSSSSS/` with
//! `scene_gt.json`, `scene_camera.json`, `scene_gt_info.json`,
//! `rgb/IIIIII.png` and `mask_visib/IIIIII_GGGGGG.png`. Poses are
//! model-to-camera, `cam_R_m2c` a row-major 3x3 and `cam_t_m2c` in
//! millimetres, as are the models; `cam_K` is row-major with pixel centres
//! at integer coordinates (OpenCV's convention, which is ours).
//!
//! Reading turns each annotated instance into the view the method
//! estimates: elevation θ and azimuth φ of the camera about the model's
//! centre (the middle of its bounding box in `models_info.json`) relative
//! to the model's up axis, the distance, and the camera's roll about the
//! ray to that centre (0 when image up is the direction of increasing θ,
//! as [`ViewPose`] defines it).

use crate::EvalError;
use acch_capture::{GroundTruth, Intrinsics, Object, UpAxis};
use glam::{DAffine3, DMat3, DVec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// BOP's unit of length for models and translations: millimetres.
pub const BOP_UNIT_M: f64 = 0.001;

/// One annotated object instance (an entry of `scene_gt.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GtEntry {
    /// Model-to-camera rotation, row-major.
    #[serde(rename = "cam_R_m2c")]
    pub cam_r_m2c: [f64; 9],
    /// Model-to-camera translation, millimetres.
    pub cam_t_m2c: [f64; 3],
    /// The object's id (its model is `models/obj_{id:06}.ply`).
    pub obj_id: u32,
}

/// One image's camera (an entry of `scene_camera.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CameraEntry {
    /// Intrinsic matrix, row-major.
    #[serde(rename = "cam_K")]
    pub cam_k: [f64; 9],
    /// Depth unit in millimetres (unused: no depth is read or written).
    #[serde(default = "unit_depth_scale")]
    pub depth_scale: f64,
}

fn unit_depth_scale() -> f64 {
    1.0
}

/// What is known of an instance's visibility (an entry of
/// `scene_gt_info.json`): only the visible part, which is what our
/// renderer's mask is.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GtInfoEntry {
    /// Bounding box of the visible pixels: x, y, width, height (-1 when
    /// none is visible).
    pub bbox_visib: [i64; 4],
    /// Visible pixels.
    pub px_count_visib: u64,
    /// Pixels of the whole silhouette, occluded or not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub px_count_all: Option<u64>,
    /// The visible share of the silhouette.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub visib_fract: Option<f64>,
}

/// One model's entry in `models_info.json`, millimetres.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ModelInfo {
    /// Largest distance between two vertices.
    pub diameter: f64,
    /// Smallest x of the bounding box.
    pub min_x: f64,
    /// Smallest y.
    pub min_y: f64,
    /// Smallest z.
    pub min_z: f64,
    /// Extent along x.
    pub size_x: f64,
    /// Extent along y.
    pub size_y: f64,
    /// Extent along z.
    pub size_z: f64,
    /// Rotations (with a small translation) that leave the model looking
    /// the same: row-major 4x4 matrices, millimetres, model frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries_discrete: Vec<[f64; 16]>,
    /// Axes about which any turn leaves the model looking the same.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub symmetries_continuous: Vec<ContinuousSymmetry>,
}

/// A continuous symmetry of `models_info.json`: any turn about `axis`
/// through `offset` (millimetres, model frame).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ContinuousSymmetry {
    /// The axis, model frame.
    pub axis: [f64; 3],
    /// A point on it, millimetres.
    pub offset: [f64; 3],
}

impl ModelInfo {
    /// The centre of the bounding box, model frame, millimetres.
    pub fn centre(&self) -> DVec3 {
        DVec3::new(
            self.min_x + self.size_x / 2.0,
            self.min_y + self.size_y / 2.0,
            self.min_z + self.size_z / 2.0,
        )
    }
}

/// The dataset-wide camera (`camera.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DatasetCamera {
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Depth unit in millimetres.
    pub depth_scale: f64,
    /// Focal length x, pixels.
    pub fx: f64,
    /// Focal length y, pixels.
    pub fy: f64,
    /// Image height, pixels.
    pub height: u32,
    /// Image width, pixels.
    pub width: u32,
}

/// `scene_gt.json`: image id -> instances.
pub type SceneGt = BTreeMap<u32, Vec<GtEntry>>;
/// `scene_camera.json`: image id -> camera.
pub type SceneCamera = BTreeMap<u32, CameraEntry>;
/// `scene_gt_info.json`: image id -> per-instance visibility.
pub type SceneGtInfo = BTreeMap<u32, Vec<GtInfoEntry>>;

/// The image of `im_id` in a scene directory.
pub fn rgb_path(scene_dir: &Path, im_id: u32) -> PathBuf {
    scene_dir.join("rgb").join(format!("{im_id:06}.png"))
}

/// The visible-part mask of instance `gt_index` of image `im_id`.
pub fn mask_visib_path(scene_dir: &Path, im_id: u32, gt_index: usize) -> PathBuf {
    scene_dir
        .join("mask_visib")
        .join(format!("{im_id:06}_{gt_index:06}.png"))
}

/// The directory of scene `scene_id` of `split`.
pub fn scene_dir(dir: &Path, split: &str, scene_id: u32) -> PathBuf {
    dir.join(split).join(format!("{scene_id:06}"))
}

/// The model file of object `obj_id` in a dataset as `acch render`
/// writes it.
pub fn model_path(dir: &Path, obj_id: u32) -> PathBuf {
    dir.join("models").join(format!("obj_{obj_id:06}.ply"))
}

/// Where a dataset keeps its models: `DIR/models`, or, in a dataset cut
/// down to one scene (as some packages ship one), the `models/` beside a
/// scene's annotations (`DIR/SPLIT/SCENE/models`, `DIR/models` of a scene
/// directory given as DIR).
pub fn models_dir(dir: &Path) -> PathBuf {
    let top = dir.join("models");
    if top.is_dir() {
        return top;
    }
    let below = |d: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(d)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_dir())
            .collect();
        v.sort();
        v
    };
    for split in below(dir) {
        for scene in below(&split) {
            if scene.join("models").is_dir() {
                return scene.join("models");
            }
        }
    }
    top
}

/// Object `obj_id`'s model file in the dataset at `dir` ([`models_dir`]).
pub fn find_model(dir: &Path, obj_id: u32) -> PathBuf {
    models_dir(dir).join(format!("obj_{obj_id:06}.ply"))
}

/// The scene directories of `split`, by id: every `DIR/SPLIT/SSSSSS` with
/// a `scene_gt.json`, or DIR itself when it is a scene directory.
fn scene_dirs(dir: &Path, split: &str) -> Result<Vec<(u32, PathBuf)>, EvalError> {
    if dir.join("scene_gt.json").is_file() {
        let id = dir
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(|n| n.parse().ok())
            .unwrap_or(0);
        return Ok(vec![(id, dir.to_owned())]);
    }
    let split_dir = dir.join(split);
    let entries = std::fs::read_dir(&split_dir).map_err(|source| EvalError::Io {
        path: split_dir.clone(),
        source,
    })?;
    let mut scenes: Vec<(u32, PathBuf)> = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|source| EvalError::Io {
            path: split_dir.clone(),
            source,
        })?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if let Ok(id) = name.parse::<u32>()
            && entry.path().join("scene_gt.json").is_file()
        {
            scenes.push((id, entry.path()));
        }
    }
    if scenes.is_empty() {
        return Err(EvalError::Input(format!(
            "{}: no scene directories with a scene_gt.json (is this a BOP dataset's split?)",
            split_dir.display()
        )));
    }
    scenes.sort();
    Ok(scenes)
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T, EvalError> {
    let text = std::fs::read_to_string(path).map_err(|source| EvalError::Io {
        path: path.to_owned(),
        source,
    })?;
    serde_json::from_str(&text)
        .map_err(|e| EvalError::Input(format!("{}: not a valid BOP file: {e}", path.display())))
}

fn write_json_compact(path: &Path, value: &impl Serialize) -> Result<(), EvalError> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
            path: dir.to_owned(),
            source,
        })?;
    }
    crate::write_json(path, value)
}

/// The camera-from-model transform of an instance, millimetres, its
/// rotation made orthonormal: LM-O's annotations are rounded so that
/// R Rᵀ is up to 1e-2 off the identity, enough to make the angle between
/// an estimate and the annotation read 0° where it is 1°.
pub fn camera_from_model(gt: &GtEntry) -> DAffine3 {
    let r = gt.cam_r_m2c;
    // Row-major in the file; glam's matrices are built from columns.
    let m = DMat3::from_cols_array(&r).transpose();
    DAffine3::from_mat3_translation(nearest_rotation(m), DVec3::from_array(gt.cam_t_m2c))
}

/// The rotation nearest a matrix close to one (its polar factor, by the
/// Newton iteration R <- (R + R⁻ᵀ) / 2, which converges quadratically).
pub fn nearest_rotation(m: DMat3) -> DMat3 {
    let mut r = m;
    for _ in 0..8 {
        if r.determinant().abs() < 1e-12 {
            break;
        }
        r = (r + r.inverse().transpose()) * 0.5;
    }
    r
}

/// The intrinsics of `cam_K` for an image of `width` x `height`.
pub fn intrinsics_of(camera: &CameraEntry, (width, height): (u32, u32)) -> Intrinsics {
    let k = camera.cam_k;
    Intrinsics {
        width,
        height,
        fx: k[0],
        fy: k[4],
        cx: k[2],
        cy: k[5],
    }
}

/// An instance as the view the method estimates ([`acch_shape::View`]):
/// the object's pose in the camera, in the object's normalised frame
/// (`object`'s [`FileFrame`](acch_capture::FileFrame) places it in the
/// model's), and its view, distance in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceView {
    /// Camera from object, object bounding radii.
    pub camera_from_object: DAffine3,
    /// Camera elevation above the model's horizontal plane, degrees in
    /// [-90, 90] (negative: from below, outside any database).
    pub theta_deg: f64,
    /// Camera azimuth about the up axis, degrees in [0, 360).
    pub phi_deg: f64,
    /// Roll about the ray to the centre, degrees in (-180, 180].
    pub roll_deg: f64,
    /// Distance of the camera from the centre, metres.
    pub distance_m: f64,
}

/// The view of an instance seen at `camera_from_model` (millimetres) of
/// the model `object` was loaded from (in millimetres).
pub fn instance_view(camera_from_model: &DAffine3, object: &Object) -> InstanceView {
    let camera_from_object = object.file_frame().camera_from_object(camera_from_model);
    view_of_object(&camera_from_object, object)
}

/// The view of a camera-from-object pose (object radii) of `object`.
pub fn view_of_object(camera_from_object: &DAffine3, object: &Object) -> InstanceView {
    let v = acch_shape::view_of(camera_from_object);
    InstanceView {
        camera_from_object: *camera_from_object,
        theta_deg: v.theta_deg,
        phi_deg: v.phi_deg,
        roll_deg: v.roll_deg,
        distance_m: v.distance * object.radius_m(),
    }
}

/// The symmetry `models_info.json` lists for a model, in the frame of the
/// object loaded from it (its small translations dropped: the turns are
/// taken about the bounding-box centre).
pub fn symmetry_of_model(info: &ModelInfo, object: &Object) -> acch_shape::Symmetry {
    let up = object.file_frame().up.rotation();
    let to_object = |m: DMat3| up * m * up.transpose();
    let mut turns: Vec<DMat3> = info
        .symmetries_discrete
        .iter()
        .map(|m| {
            to_object(
                DMat3::from_cols_array(&[m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]])
                    .transpose(),
            )
        })
        .collect();
    for c in &info.symmetries_continuous {
        let axis = up * DVec3::from_array(c.axis);
        turns.extend(
            acch_shape::Symmetry::continuous(axis)
                .turns()
                .iter()
                .copied(),
        );
    }
    acch_shape::Symmetry::of_turns(turns)
}

/// One annotated instance of the object, with its files.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Scene id.
    pub scene_id: u32,
    /// Image id.
    pub im_id: u32,
    /// Index of the instance in the image's `scene_gt.json` list.
    pub gt_index: usize,
    /// The image.
    pub rgb: PathBuf,
    /// The visible-part mask: the dataset's, or derived by acch.
    pub mask_visib: Option<PathBuf>,
    /// The visible share of the object's silhouette, when known.
    pub visib_fract: Option<f64>,
    /// Model to camera, millimetres.
    pub camera_from_model: DAffine3,
    /// `cam_K`.
    pub camera: CameraEntry,
}

/// The instances of one object, and what acch derived to read them.
#[derive(Clone, Debug, Default)]
pub struct Instances {
    /// Every annotated instance, in scene, image and annotation order.
    pub instances: Vec<Instance>,
    /// What the dataset lacked and acch derived, one sentence each.
    pub derived: Vec<String>,
}

/// Revision of how visible masks are derived; part of the cache key (2:
/// rendered at the annotations' nearest rotations).
const DERIVE_REVISION: u32 = 2;

/// Every annotated instance of object `obj_id` in `split` of the dataset
/// at `dir`. What a scene lacks is derived and said in
/// [`Instances::derived`]: without `scene_camera.json` every image takes
/// `camera.json`'s intrinsics; without `mask_visib/` the visible part of
/// each instance is rendered (every annotated model at its pose, with a
/// depth test) and cached under `cache`, with the visible share of each
/// silhouette. Errors name the file: a malformed JSON file, an image named
/// by the annotations but missing, an object id no scene shows (listing
/// those it does), a model a derivation needs but cannot read.
pub fn read_instances(
    dir: &Path,
    split: &str,
    obj_id: u32,
    cache: &Path,
) -> Result<Instances, EvalError> {
    let split_dir = dir.join(split);
    let scenes = scene_dirs(dir, split)?;
    let dataset_camera = dir.join("camera.json");
    let mut out = Instances::default();
    let mut seen_ids = std::collections::BTreeSet::new();
    let (mut cameras_derived, mut masks_derived) = (Vec::new(), Vec::new());
    for (scene_id, scene) in &scenes {
        let gt: SceneGt = read_json(&scene.join("scene_gt.json"))?;
        let camera_path = scene.join("scene_camera.json");
        let cameras: SceneCamera = if camera_path.is_file() {
            read_json(&camera_path)?
        } else {
            cameras_derived.push(*scene_id);
            // The scene's own camera.json (a cut-down dataset), else the
            // dataset's.
            let own = scene.join("camera.json");
            let k: DatasetCamera = read_json(if own.is_file() { &own } else { &dataset_camera })?;
            let entry = CameraEntry {
                cam_k: [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
                depth_scale: k.depth_scale,
            };
            gt.keys().map(|&im| (im, entry.clone())).collect()
        };
        let mut found = Vec::new();
        for (&im_id, instances) in &gt {
            for (gt_index, inst) in instances.iter().enumerate() {
                seen_ids.insert(inst.obj_id);
                if inst.obj_id != obj_id {
                    continue;
                }
                let camera = cameras.get(&im_id).cloned().ok_or_else(|| {
                    EvalError::Input(format!(
                        "{}: no camera for image {im_id}, which scene_gt.json annotates",
                        camera_path.display()
                    ))
                })?;
                let rgb = rgb_path(scene, im_id);
                if !rgb.is_file() {
                    return Err(EvalError::Input(format!(
                        "{}: missing image of scene {scene_id}, image {im_id} (annotated in {})",
                        rgb.display(),
                        scene.join("scene_gt.json").display()
                    )));
                }
                found.push((im_id, gt_index, rgb, camera, camera_from_model(inst)));
            }
        }
        if found.is_empty() {
            continue;
        }
        let (mask_root, info) = if scene.join("mask_visib").is_dir() {
            let info_path = scene.join("scene_gt_info.json");
            let info: Option<SceneGtInfo> = if info_path.is_file() {
                Some(read_json(&info_path)?)
            } else {
                None
            };
            (scene.clone(), info)
        } else {
            masks_derived.push(*scene_id);
            let root = derive_visible_masks(dir, scene, &gt, &cameras, cache)?;
            let info: SceneGtInfo = read_json(&root.join("scene_gt_info.json"))?;
            (root, Some(info))
        };
        for (im_id, gt_index, rgb, camera, camera_from_model) in found {
            let mask = mask_visib_path(&mask_root, im_id, gt_index);
            let visib_fract = info
                .as_ref()
                .and_then(|i| i.get(&im_id))
                .and_then(|v| v.get(gt_index))
                .and_then(|e| e.visib_fract);
            out.instances.push(Instance {
                scene_id: *scene_id,
                im_id,
                gt_index,
                rgb,
                mask_visib: mask.is_file().then_some(mask),
                visib_fract,
                camera_from_model,
                camera,
            });
        }
    }
    if out.instances.is_empty() {
        let ids: Vec<String> = seen_ids.iter().map(u32::to_string).collect();
        return Err(EvalError::Input(format!(
            "{}: object {obj_id} is not annotated in any scene (objects there: {})",
            split_dir.display(),
            if ids.is_empty() {
                "none".to_string()
            } else {
                ids.join(", ")
            }
        )));
    }
    let list = |ids: &[u32]| {
        ids.iter()
            .map(u32::to_string)
            .collect::<Vec<_>>()
            .join(", ")
    };
    if !cameras_derived.is_empty() {
        out.derived.push(format!(
            "cam_K of every image from camera.json (no scene_camera.json in scene {})",
            list(&cameras_derived)
        ));
    }
    if !masks_derived.is_empty() {
        out.derived.push(format!(
            "visible masks and visible shares rendered from every annotated model at its pose with a depth test (no mask_visib/ in scene {}), cached in {}",
            list(&masks_derived),
            cache.join("bop-derived").display()
        ));
    }
    Ok(out)
}

/// Object `obj_id`'s model, `models/obj_ID.ply`, in millimetres with +z
/// up (the BOP convention).
pub fn load_model(dir: &Path, obj_id: u32) -> Result<Object, EvalError> {
    let path = find_model(dir, obj_id);
    Ok(Object::load_mesh(&path, UpAxis::PosZ)?.with_mesh_unit_m(BOP_UNIT_M)?)
}

/// The visible masks and `scene_gt_info.json` of a scene without
/// `mask_visib/`, rendered once and cached: the directory that holds
/// them as a scene would.
fn derive_visible_masks(
    dir: &Path,
    scene: &Path,
    gt: &SceneGt,
    cameras: &SceneCamera,
    cache: &Path,
) -> Result<PathBuf, EvalError> {
    let ids: std::collections::BTreeSet<u32> = gt.values().flatten().map(|e| e.obj_id).collect();
    // The key: what the masks are made of.
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    hasher.update(&DERIVE_REVISION.to_le_bytes());
    hasher.update(serde_json::to_string(gt).unwrap_or_default().as_bytes());
    hasher.update(
        serde_json::to_string(cameras)
            .unwrap_or_default()
            .as_bytes(),
    );
    for &id in &ids {
        let path = find_model(dir, id);
        let bytes = std::fs::read(&path).map_err(|source| EvalError::Io {
            path: path.clone(),
            source,
        })?;
        hasher.update(&bytes);
    }
    let name = scene
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let root = cache
        .join("bop-derived")
        .join(format!("{name}-{:016x}", hasher.digest()));
    let done = root.join("scene_gt_info.json");
    if done.is_file() {
        return Ok(root);
    }
    let models: BTreeMap<u32, Object> = ids
        .iter()
        .map(|&id| {
            load_model(dir, id).map(|m| (id, m)).map_err(|e| {
                EvalError::Input(format!(
                    "deriving the visible masks of {}: {e}",
                    scene.display()
                ))
            })
        })
        .collect::<Result<_, _>>()?;
    let masks = root.join("mask_visib");
    std::fs::create_dir_all(&masks).map_err(|source| EvalError::Io {
        path: masks.clone(),
        source,
    })?;
    let bar = crate::protocol::progress(gt.len() as u64, "visible masks");
    let images: Vec<(&u32, &Vec<GtEntry>)> = gt.iter().collect();
    let infos: Vec<(u32, Vec<GtInfoEntry>)> = images
        .par_iter()
        .map(|&(&im_id, entries)| {
            let camera = cameras.get(&im_id).ok_or_else(|| {
                EvalError::Input(format!("{}: no camera for image {im_id}", scene.display()))
            })?;
            let size = image::image_dimensions(rgb_path(scene, im_id)).map_err(|source| {
                EvalError::Image {
                    path: rgb_path(scene, im_id),
                    source,
                }
            })?;
            let k = intrinsics_of(camera, size);
            let posed: Vec<(&Object, DAffine3, f64)> = entries
                .iter()
                .map(|e| {
                    let m = &models[&e.obj_id];
                    let frame = m.file_frame();
                    let c = frame.camera_from_object(&camera_from_model(e));
                    // In millimetres, so depths compare across models.
                    let mm =
                        DAffine3::from_mat3_translation(c.matrix3, c.translation * frame.radius);
                    (m, mm, frame.radius)
                })
                .collect();
            let scene_render = acch_capture::render_posed(&posed, &k);
            let mut info = Vec::with_capacity(entries.len());
            for (g, one) in posed.iter().enumerate() {
                let visible = scene_render.mask_of(g);
                let alone = acch_capture::render_posed(std::slice::from_ref(one), &k);
                let all = alone.visible_px(0) as u64;
                let mask = image::GrayImage::from_raw(k.width, k.height, visible)
                    .expect("the render's size");
                let visible_px = mask.iter().filter(|&&v| v != 0).count() as u64;
                let bbox_visib = acch_capture::mask_bbox(&mask).map_or([-1; 4], |b| {
                    [b.x as i64, b.y as i64, b.width as i64, b.height as i64]
                });
                let path = mask_visib_path(&root, im_id, g);
                mask.save(&path).map_err(|source| EvalError::Image {
                    path: path.clone(),
                    source,
                })?;
                info.push(GtInfoEntry {
                    bbox_visib,
                    px_count_visib: visible_px,
                    px_count_all: Some(all),
                    visib_fract: Some(if all > 0 {
                        visible_px as f64 / all as f64
                    } else {
                        0.0
                    }),
                });
            }
            bar.inc(1);
            Ok((im_id, info))
        })
        .collect::<Result<_, EvalError>>()?;
    bar.finish_and_clear();
    let info: SceneGtInfo = infos.into_iter().collect();
    // Written last: its presence says the directory is whole.
    let partial = root.join(format!("scene_gt_info.json.{}", std::process::id()));
    write_json_compact(&partial, &info)?;
    std::fs::rename(&partial, &done).map_err(|source| EvalError::Io {
        path: done.clone(),
        source,
    })?;
    Ok(root)
}

/// The entry of object `obj_id` in `DIR/models/models_info.json`, or,
/// when the dataset has no such file, one derived from the model (its
/// diameter and bounding box, no symmetry): the second value says which.
pub fn model_info(dir: &Path, obj_id: u32) -> Result<(ModelInfo, bool), EvalError> {
    if models_dir(dir).join("models_info.json").is_file() {
        return Ok((read_model_info(dir, obj_id)?, false));
    }
    let model = load_model(dir, obj_id)?;
    let m = model.model_info(BOP_UNIT_M);
    // model_info is about the bounding-box centre; the file's frame is
    // that centre's offset from the model's origin.
    let c = model.file_frame().centre;
    Ok((
        ModelInfo {
            diameter: m.diameter,
            min_x: m.min[0] + c.x,
            min_y: m.min[1] + c.y,
            min_z: m.min[2] + c.z,
            size_x: m.size[0],
            size_y: m.size[1],
            size_z: m.size[2],
            symmetries_discrete: Vec::new(),
            symmetries_continuous: Vec::new(),
        },
        true,
    ))
}

/// The entry of object `obj_id` in `DIR/models/models_info.json`.
pub fn read_model_info(dir: &Path, obj_id: u32) -> Result<ModelInfo, EvalError> {
    let path = models_dir(dir).join("models_info.json");
    let infos: BTreeMap<u32, ModelInfo> = read_json(&path)?;
    infos.get(&obj_id).cloned().ok_or_else(|| {
        let ids: Vec<String> = infos.keys().map(u32::to_string).collect();
        EvalError::Input(format!(
            "{}: no model {obj_id} (models there: {})",
            path.display(),
            ids.join(", ")
        ))
    })
}

/// The annotations of one scene as they are rendered, written at the end.
#[derive(Default)]
pub struct SceneWriter {
    gt: SceneGt,
    camera: SceneCamera,
    info: SceneGtInfo,
}

impl SceneWriter {
    /// Records image `im_id`: the one object `obj_id`, of real bounding
    /// radius `radius_m`, seen as `truth`, with `visible_px` pixels of it
    /// visible. The model frame is the renderer's object frame in
    /// millimetres, as [`write_model`] writes it.
    pub fn add(
        &mut self,
        im_id: u32,
        obj_id: u32,
        truth: &GroundTruth,
        radius_m: f64,
        visible_px: u64,
    ) {
        let camera_from_world = truth.world_from_camera.inverse();
        let r = camera_from_world.matrix3;
        // The renderer's unit is one bounding radius.
        let t = camera_from_world.translation * (radius_m / BOP_UNIT_M);
        self.gt.insert(
            im_id,
            vec![GtEntry {
                cam_r_m2c: r.transpose().to_cols_array(),
                cam_t_m2c: t.to_array(),
                obj_id,
            }],
        );
        let k = truth.intrinsics;
        self.camera.insert(
            im_id,
            CameraEntry {
                cam_k: [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0],
                depth_scale: 1.0,
            },
        );
        let bbox_visib = truth.bbox.map_or([-1; 4], |b| {
            [b.x as i64, b.y as i64, b.width as i64, b.height as i64]
        });
        self.info.insert(
            im_id,
            vec![GtInfoEntry {
                bbox_visib,
                px_count_visib: visible_px,
                px_count_all: None,
                visib_fract: None,
            }],
        );
    }

    /// Writes `scene_gt.json`, `scene_camera.json` and `scene_gt_info.json`
    /// into `scene_dir`.
    pub fn write(&self, scene_dir: &Path) -> Result<(), EvalError> {
        write_json_compact(&scene_dir.join("scene_gt.json"), &self.gt)?;
        write_json_compact(&scene_dir.join("scene_camera.json"), &self.camera)?;
        write_json_compact(&scene_dir.join("scene_gt_info.json"), &self.info)
    }
}

/// Writes `DIR/camera.json`.
pub fn write_dataset_camera(dir: &Path, k: &Intrinsics) -> Result<(), EvalError> {
    write_json_compact(
        &dir.join("camera.json"),
        &DatasetCamera {
            cx: k.cx,
            cy: k.cy,
            depth_scale: 1.0,
            fx: k.fx,
            fy: k.fy,
            height: k.height,
            width: k.width,
        },
    )
}

/// Writes the object's model as `DIR/models/obj_{obj_id:06}.ply` (in
/// millimetres, z up, in the renderer's object frame) with its texture,
/// and `models_info.json`.
pub fn write_model(dir: &Path, obj_id: u32, object: &Object) -> Result<(), EvalError> {
    let path = model_path(dir, obj_id);
    let models = path.parent().expect("a model path has a directory");
    std::fs::create_dir_all(models).map_err(|source| EvalError::Io {
        path: models.to_owned(),
        source,
    })?;
    object.write_ply(&path, BOP_UNIT_M)?;
    let m = object.model_info(BOP_UNIT_M);
    let info = ModelInfo {
        diameter: m.diameter,
        min_x: m.min[0],
        min_y: m.min[1],
        min_z: m.min[2],
        size_x: m.size[0],
        size_y: m.size[1],
        size_z: m.size[2],
        symmetries_discrete: Vec::new(),
        symmetries_continuous: Vec::new(),
    };
    write_json_compact(
        &models.join("models_info.json"),
        &BTreeMap::from([(obj_id, info)]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use acch_capture::ViewPose;

    fn truth_of(view: ViewPose) -> GroundTruth {
        GroundTruth {
            theta_deg: view.theta_deg,
            phi_deg: view.phi_deg,
            distance: view.distance,
            roll_deg: view.roll_deg,
            world_from_camera: view.world_from_camera(),
            intrinsics: Intrinsics::default(),
            bbox: None,
        }
    }

    #[test]
    fn a_written_pose_reads_back_as_its_view() {
        let dir = tempfile::tempdir().unwrap();
        let can = Object::builtin("can").unwrap();
        write_model(dir.path(), 1, &can).unwrap();
        let read = load_model(dir.path(), 1).unwrap();
        let radius_m = can.radius_m();
        assert!((read.radius_m() / radius_m - 1.0).abs() < 1e-6);
        for (theta, phi, roll) in [
            (45.0, 0.0, 0.0),
            (60.0, 123.4, 17.0),
            (89.0, 300.0, -44.0),
            (20.0, 359.5, 170.0),
        ] {
            let view = ViewPose::new(theta, phi, 5.0)
                .unwrap()
                .with_roll(roll)
                .unwrap();
            let mut w = SceneWriter::default();
            w.add(0, 1, &truth_of(view), radius_m, 10);
            let gt = &w.gt[&0][0];
            // Through JSON, as a reader sees it.
            let gt: GtEntry = serde_json::from_str(&serde_json::to_string(gt).unwrap()).unwrap();
            let v = instance_view(&camera_from_model(&gt), &read);
            assert!((v.theta_deg - theta).abs() < 1e-4, "{v:?}");
            assert!(
                acch_pose::phi_error(v.phi_deg as f32, phi as f32) < 1e-3,
                "{v:?}"
            );
            assert!((v.roll_deg - roll).abs() < 1e-3, "{v:?}");
            assert!((v.distance_m - 5.0 * radius_m).abs() < 1e-6, "{v:?}");
        }
    }

    #[test]
    fn a_rounded_annotation_becomes_the_rotation_it_rounds() {
        let largest = |m: DMat3| m.to_cols_array().iter().fold(0f64, |a, x| a.max(x.abs()));
        let exact = DMat3::from_euler(glam::EulerRot::ZYX, 0.4, -0.3, 1.1);
        // Rounded to two decimals, as coarse as LM-O's worst.
        let rounded =
            DMat3::from_cols_array(&exact.to_cols_array().map(|x| (x * 100.0).round() / 100.0));
        assert!(largest(rounded * rounded.transpose() - DMat3::IDENTITY) > 1e-3);
        let r = nearest_rotation(rounded);
        assert!(largest(r * r.transpose() - DMat3::IDENTITY) < 1e-12);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        // Within the rounding of the rotation it rounds.
        assert!(largest(r - exact) < 0.01);
        // The angle to a rotation 1° off reads 1°, not 0°.
        let off = exact * DMat3::from_rotation_z(1f64.to_radians());
        let angle = acch_shape::rotation_angle_deg(&r, &off);
        assert!((angle - 1.0).abs() < 0.6, "{angle}");
    }

    #[test]
    fn the_up_axis_of_the_model_moves_the_view() {
        // A camera straight above the model's centre: from above when +z
        // is up, from the side when +y is.
        let dir = tempfile::tempdir().unwrap();
        let can = Object::builtin("can").unwrap();
        write_model(dir.path(), 1, &can).unwrap();
        let view = ViewPose::new(90.0, 0.0, 8.0).unwrap();
        let mut w = SceneWriter::default();
        w.add(0, 1, &truth_of(view), can.radius_m(), 10);
        let pose = camera_from_model(&w.gt[&0][0]);
        let z_up = load_model(dir.path(), 1).unwrap();
        let v = instance_view(&pose, &z_up);
        assert!((v.theta_deg - 90.0).abs() < 1e-4, "{v:?}");
        let y_up = Object::load_mesh(find_model(dir.path(), 1), UpAxis::PosY)
            .unwrap()
            .with_mesh_unit_m(BOP_UNIT_M)
            .unwrap();
        let side = instance_view(&pose, &y_up);
        assert!(side.theta_deg.abs() < 1.0, "{side:?}");
        assert!((side.distance_m - v.distance_m).abs() < 1e-6);
    }

    #[test]
    fn malformed_json_and_unknown_objects_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let scene = scene_dir(dir.path(), "test", 0);
        std::fs::create_dir_all(&scene).unwrap();
        std::fs::write(
            scene.join("scene_gt.json"),
            "{\"0\": [{\"cam_R_m2c\": [1,2]",
        )
        .unwrap();
        std::fs::write(scene.join("scene_camera.json"), "{}").unwrap();
        let e = read_instances(dir.path(), "test", 1, dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scene_gt.json") && e.contains("not a valid BOP file"),
            "{e}"
        );

        let mut w = SceneWriter::default();
        w.add(
            0,
            3,
            &truth_of(ViewPose::new(60.0, 0.0, 5.0).unwrap()),
            0.1,
            1,
        );
        w.write(&scene).unwrap();
        let e = read_instances(dir.path(), "test", 1, dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("object 1") && e.contains("objects there: 3"),
            "{e}"
        );
        let e = read_instances(dir.path(), "test", 3, dir.path())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("000000.png") && e.contains("missing image"),
            "{e}"
        );
        let e = read_instances(dir.path(), "val", 3, dir.path())
            .unwrap_err()
            .to_string();
        assert!(e.contains("val"), "{e}");
    }
}
