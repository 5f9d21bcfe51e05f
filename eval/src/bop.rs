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
use acch_capture::{GroundTruth, Intrinsics, Object, UpAxis, ViewPose};
use glam::{DAffine3, DMat3, DVec3};
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

/// The model file of object `obj_id`.
pub fn model_path(dir: &Path, obj_id: u32) -> PathBuf {
    dir.join("models").join(format!("obj_{obj_id:06}.ply"))
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

/// The camera-from-model transform of an instance, millimetres.
pub fn camera_from_model(gt: &GtEntry) -> DAffine3 {
    let r = gt.cam_r_m2c;
    // Row-major in the file; glam's matrices are built from columns.
    let m = DMat3::from_cols_array(&r).transpose();
    DAffine3::from_mat3_translation(m, DVec3::from_array(gt.cam_t_m2c))
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

/// How a model's frame sits in the method's: which axis is up, where its
/// centre is (millimetres, model frame).
#[derive(Clone, Copy, Debug)]
pub struct ModelFrame {
    /// The model's up axis.
    pub up: UpAxis,
    /// The centre of its bounding box, model frame, millimetres.
    pub centre_mm: DVec3,
}

/// An instance as the view the method estimates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceView {
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

/// The view of an instance whose model sits in the method's frame by
/// `frame`.
pub fn instance_view(camera_from_model: &DAffine3, frame: &ModelFrame) -> InstanceView {
    let up = frame.up.rotation();
    let r = camera_from_model.matrix3;
    // The camera centre and axes in the model frame, then turned z-up.
    let centre_cam = r.transpose() * -camera_from_model.translation;
    let d = up * (centre_cam - frame.centre_mm);
    let axes = up * r.transpose();
    let distance = d.length();
    let theta = (d.z / distance).clamp(-1.0, 1.0).asin().to_degrees();
    let phi = d.y.atan2(d.x).to_degrees().rem_euclid(360.0);
    let phi = if phi >= 360.0 { 0.0 } else { phi };
    // The unrolled camera at the same place (θ clamped only to build it:
    // its axes depend on θ through cos and sin, defined for any θ).
    let unrolled = ViewPose {
        theta_deg: theta,
        phi_deg: phi,
        distance: 1.0,
        roll_deg: 0.0,
    }
    .world_from_camera_rotation();
    let right = axes.x_axis;
    let roll = right
        .dot(unrolled.y_axis)
        .atan2(right.dot(unrolled.x_axis))
        .to_degrees();
    InstanceView {
        theta_deg: theta,
        phi_deg: phi,
        roll_deg: if roll <= -180.0 { 180.0 } else { roll },
        distance_m: distance * BOP_UNIT_M,
    }
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
    /// The visible-part mask, when the dataset has it.
    pub mask_visib: Option<PathBuf>,
    /// Model to camera, millimetres.
    pub camera_from_model: DAffine3,
    /// `cam_K`.
    pub camera: CameraEntry,
}

/// Every annotated instance of object `obj_id` in `split` of the dataset
/// at `dir`. Errors name the file: a malformed JSON file, an image named
/// by the annotations but missing, an object id no scene shows (listing
/// those it does).
pub fn read_instances(dir: &Path, split: &str, obj_id: u32) -> Result<Vec<Instance>, EvalError> {
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
    let mut out = Vec::new();
    let mut seen_ids = std::collections::BTreeSet::new();
    for (scene_id, scene) in &scenes {
        let gt: SceneGt = read_json(&scene.join("scene_gt.json"))?;
        let camera_path = scene.join("scene_camera.json");
        let cameras: SceneCamera = read_json(&camera_path)?;
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
                let mask = mask_visib_path(scene, im_id, gt_index);
                out.push(Instance {
                    scene_id: *scene_id,
                    im_id,
                    gt_index,
                    rgb,
                    mask_visib: mask.is_file().then_some(mask),
                    camera_from_model: camera_from_model(inst),
                    camera,
                });
            }
        }
    }
    if out.is_empty() {
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
    Ok(out)
}

/// The entry of object `obj_id` in `DIR/models/models_info.json`.
pub fn read_model_info(dir: &Path, obj_id: u32) -> Result<ModelInfo, EvalError> {
    let path = dir.join("models").join("models_info.json");
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
        let radius_m = 0.12;
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
            let frame = ModelFrame {
                up: UpAxis::PosZ,
                centre_mm: DVec3::ZERO,
            };
            let v = instance_view(&camera_from_model(&gt), &frame);
            assert!((v.theta_deg - theta).abs() < 1e-9, "{v:?}");
            assert!(
                acch_pose::phi_error(v.phi_deg as f32, phi as f32) < 1e-4,
                "{v:?}"
            );
            assert!((v.roll_deg - roll).abs() < 1e-9, "{v:?}");
            assert!((v.distance_m - 5.0 * radius_m).abs() < 1e-12, "{v:?}");
        }
    }

    #[test]
    fn the_up_axis_and_centre_of_the_model_move_the_view() {
        // A camera 1 m above the model's centre at (0, 0, 100) mm, along
        // the model's +y axis (its up): straight down in the method's
        // frame, and sideways if the model were taken as z-up.
        let view = ViewPose::new(90.0, 0.0, 1000.0)
            .unwrap()
            .with_roll(30.0)
            .unwrap();
        let cam_from_world = view.camera_from_world();
        // World (z up, centred, mm) = up * (model - centre).
        let up = UpAxis::PosY.rotation();
        let centre = DVec3::new(0.0, 0.0, 100.0);
        let r = cam_from_world.matrix3 * up;
        let cam_from_model =
            DAffine3::from_mat3_translation(r, cam_from_world.translation - r * centre);
        let frame = ModelFrame {
            up: UpAxis::PosY,
            centre_mm: DVec3::new(0.0, 0.0, 100.0),
        };
        let v = instance_view(&cam_from_model, &frame);
        assert!((v.theta_deg - 90.0).abs() < 1e-6, "{v:?}");
        assert!((v.distance_m - 1.0).abs() < 1e-9, "{v:?}");
        let wrong = instance_view(
            &cam_from_model,
            &ModelFrame {
                up: UpAxis::PosZ,
                ..frame
            },
        );
        assert!(wrong.theta_deg.abs() < 1.0, "{wrong:?}");
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
        let e = read_instances(dir.path(), "test", 1)
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
        let e = read_instances(dir.path(), "test", 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("object 1") && e.contains("objects there: 3"),
            "{e}"
        );
        let e = read_instances(dir.path(), "test", 3)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("000000.png") && e.contains("missing image"),
            "{e}"
        );
        let e = read_instances(dir.path(), "val", 3)
            .unwrap_err()
            .to_string();
        assert!(e.contains("val"), "{e}");
    }
}
