//! Scenes of several known objects at once: touching, partly hiding each
//! other, among distractors, with ground truth per object (its view, its
//! visible pixels, how much of it is hidden).
//!
//! World frame: the table is the plane the objects stand on, the camera
//! looks at the group's centre (the origin) from the view sphere, as in a
//! single-object scene. Each object keeps its normalised size (radius 1).

use std::sync::Arc;

use glam::{DAffine3, DMat3, DVec3};
use image::{GrayImage, RgbImage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::background::{Background, Placed, TextureSet, distractor, hsv};
use crate::effects::{self, Effects};
use crate::object::Object;
use crate::raster::{Frame, draw_object, light_world};
use crate::render::{
    BBox, draw_background, exposure_samples, integrate_exposure, mask_bbox, table_of,
};
use crate::texture::Texture;
use crate::{CaptureError, Intrinsics, ViewPose};

/// The most objects one scene holds (labels are one byte, 0 is "none").
pub const MAX_SCENE_OBJECTS: usize = 16;

/// Camera distance to the group's centre of a multi-object scene, bounding
/// radii: far enough back that three or four objects side by side fit the
/// default camera's view.
pub const MULTI_DISTANCE: f64 = 6.5;

/// Where the light comes from, relative to each object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SceneLight {
    /// Each object lit from where its training views were lit: the light
    /// turns with the object's yaw, so only placement, neighbours and
    /// occlusion differ from a single-object scene.
    #[default]
    AsTrained,
    /// One light fixed in the world for every object, so an object turned
    /// on the table is lit from another side than in training.
    World,
}

/// What to render: the objects, their surroundings, the camera.
#[derive(Debug, Clone)]
pub struct MultiScene {
    /// The known objects, 1 to [`MAX_SCENE_OBJECTS`].
    pub objects: Vec<Arc<Object>>,
    /// The table (a plain colour, A, B or C; clutter backgrounds are drawn
    /// as their table, their distractors replaced by `distractors`).
    pub background: Background,
    /// Unknown objects placed around the group.
    pub distractors: usize,
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Blur, brightness and noise.
    pub effects: Effects,
    /// Which instance of the table texture the background shows.
    pub textures: TextureSet,
    /// Where the light comes from.
    pub light: SceneLight,
}

impl MultiScene {
    /// `objects` on `background` with two distractors, the default camera
    /// and no effects.
    pub fn new(objects: Vec<Arc<Object>>, background: Background) -> Self {
        MultiScene {
            objects,
            background,
            distractors: 2,
            intrinsics: Intrinsics::default(),
            effects: Effects::default(),
            textures: TextureSet::default(),
            light: SceneLight::default(),
        }
    }
}

/// What is known about one object of a rendered scene.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectTruth {
    /// Index of the object in [`MultiScene::objects`].
    pub object: usize,
    /// The camera as seen from the object: θ, φ and distance in its own
    /// frame, and the roll that comes from it standing off the optical axis.
    pub view: ViewPose,
    /// Pixels where it is the nearest surface.
    pub visible_px: u32,
    /// Pixels it would cover alone in the scene (no neighbour in front).
    pub alone_px: u32,
    /// Bounding box of its visible pixels.
    pub bbox: Option<BBox>,
    /// Whether the frame's border cuts it.
    pub at_border: bool,
}

impl ObjectTruth {
    /// The share of the object hidden by its neighbours, 0-1.
    pub fn hidden(&self) -> f64 {
        if self.alone_px == 0 {
            return 1.0;
        }
        1.0 - self.visible_px as f64 / self.alone_px as f64
    }
}

/// A rendered multi-object frame.
#[derive(Debug, Clone, Default)]
pub struct MultiRendered {
    /// The colour image.
    pub image: RgbImage,
    /// Per pixel, 1 + the index of the object seen there, 0 for none.
    pub labels: GrayImage,
    /// Ground truth of every object, in scene order.
    pub objects: Vec<ObjectTruth>,
    /// Camera pose: OpenCV camera frame to world frame.
    pub world_from_camera: DAffine3,
}

impl MultiRendered {
    /// The mask of object `i` (255 where it is visible).
    pub fn mask(&self, i: usize) -> GrayImage {
        let label = i as u8 + 1;
        let mut m = self.labels.clone();
        m.iter_mut()
            .for_each(|v| *v = if *v == label { 255 } else { 0 });
        m
    }
}

/// Renders a [`MultiScene`]. The layout (where each object stands, its yaw,
/// the distractors) is drawn once from the scene seed in [`MultiRenderer::new`].
pub struct MultiRenderer {
    scene: MultiScene,
    placed: Vec<Placed>,
    /// The yaw of each object about the world z axis, radians.
    yaws: Vec<f64>,
    distractors: Vec<Placed>,
    table: Option<Arc<Texture>>,
    table_z: f64,
}

/// Why a multi-object scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum MultiSceneError {
    /// No object, or more than [`MAX_SCENE_OBJECTS`].
    #[error("a scene holds 1 to {MAX_SCENE_OBJECTS} objects, not {count}")]
    ObjectCount {
        /// The objects asked for.
        count: usize,
    },
    /// The camera is invalid.
    #[error(transparent)]
    Camera(#[from] CaptureError),
}

/// The radius of an object's footprint on the table: its largest distance
/// from the vertical axis through its centre.
fn footprint(object: &Object) -> f64 {
    object
        .tris
        .iter()
        .flatten()
        .map(|v| v.p.truncate().as_dvec2().length())
        .fold(0.0, f64::max)
}

impl MultiRenderer {
    /// Lays out `scene` from `seed`: the objects stand in a group, each
    /// 0.02-0.3 radii from a neighbour's footprint, footprints never
    /// overlapping, at random yaws; the distractors stand around the group.
    pub fn new(scene: MultiScene, seed: u64) -> Result<Self, MultiSceneError> {
        let n = scene.objects.len();
        if n == 0 || n > MAX_SCENE_OBJECTS {
            return Err(MultiSceneError::ObjectCount { count: n });
        }
        scene.intrinsics.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6d75_6c74_6900);
        let radii: Vec<f64> = scene.objects.iter().map(|o| footprint(o)).collect();
        let mut spots: Vec<(f64, f64)> = vec![(0.0, 0.0)];
        for i in 1..n {
            let mut spot = None;
            for attempt in 0..400 {
                let j = rng.random_range(0..i);
                let gap = rng.random_range(0.02..0.3) + attempt as f64 * 0.01;
                let a = rng.random_range(0.0..std::f64::consts::TAU);
                let d = radii[i] + radii[j] + gap;
                let p = (spots[j].0 + d * a.cos(), spots[j].1 + d * a.sin());
                let free = spots.iter().zip(&radii).all(|(q, r)| {
                    ((p.0 - q.0).powi(2) + (p.1 - q.1).powi(2)).sqrt() >= r + radii[i] + 0.02
                });
                if free {
                    spot = Some(p);
                    break;
                }
            }
            // 400 growing gaps always find room; this only keeps it total.
            spots.push(spot.unwrap_or((spots.len() as f64 * 2.5, 0.0)));
        }
        let (mx, my) = spots
            .iter()
            .fold((0.0, 0.0), |(x, y), p| (x + p.0, y + p.1));
        let centre = (mx / n as f64, my / n as f64);
        // The table sits as far below the look-at point as the objects'
        // centres sit above it on average.
        let lift: Vec<f64> = scene.objects.iter().map(|o| -o.table_z()).collect();
        let table_z = -lift.iter().sum::<f64>() / n as f64;
        let mut yaws = Vec::with_capacity(n);
        let placed: Vec<Placed> = scene
            .objects
            .iter()
            .zip(&spots)
            .zip(&lift)
            .map(|((object, p), lift)| {
                let yaw = rng.random_range(0.0..std::f64::consts::TAU);
                yaws.push(yaw);
                let at = DVec3::new(p.0 - centre.0, p.1 - centre.1, table_z + lift);
                Placed {
                    object: object.clone(),
                    world_from_object: DAffine3::from_translation(at)
                        * DAffine3::from_rotation_z(yaw),
                }
            })
            .collect();
        let extent = placed
            .iter()
            .zip(&radii)
            .map(|(p, r)| p.world_from_object.translation.truncate().length() + r)
            .fold(0.0, f64::max);
        let palette: Vec<[u8; 3]> = (0..8)
            .map(|_| {
                hsv(
                    rng.random(),
                    rng.random_range(0.55..1.0),
                    rng.random_range(0.45..1.0),
                )
            })
            .collect();
        let mut taken: Vec<(f64, f64, f64)> = Vec::new();
        let mut distractors = Vec::new();
        for i in 0..scene.distractors {
            let (object, fr) = distractor(&mut rng, &palette, 1.1, i);
            let fr = fr as f64;
            let spot = (0..200).find_map(|_| {
                let rho = rng.random_range(extent + fr + 0.1..extent + fr + 2.0);
                let a = rng.random_range(0.0..std::f64::consts::TAU);
                let (x, y) = (rho * a.cos(), rho * a.sin());
                taken
                    .iter()
                    .all(|&(tx, ty, tr)| ((x - tx).powi(2) + (y - ty).powi(2)).sqrt() > tr + fr)
                    .then_some((x, y))
            });
            if let Some((x, y)) = spot {
                taken.push((x, y, fr));
                let yaw = rng.random_range(0.0..std::f64::consts::TAU);
                distractors.push(Placed {
                    object: Arc::new(object),
                    world_from_object: DAffine3::from_translation(DVec3::new(x, y, table_z))
                        * DAffine3::from_rotation_z(yaw),
                });
            }
        }
        let table = table_of(scene.background, scene.textures);
        Ok(MultiRenderer {
            scene,
            placed,
            yaws,
            distractors,
            table,
            table_z,
        })
    }

    /// The scene.
    pub fn scene(&self) -> &MultiScene {
        &self.scene
    }

    /// Where object `i` stands: its frame to the world's.
    pub fn world_from_object(&self, i: usize) -> Option<DAffine3> {
        self.placed.get(i).map(|p| p.world_from_object)
    }

    /// Renders the scene from camera elevation `theta_deg` and azimuth
    /// `phi_deg` at [`MULTI_DISTANCE`]; `frame_seed` seeds the sensor noise.
    pub fn render(
        &self,
        theta_deg: f64,
        phi_deg: f64,
        frame_seed: u64,
    ) -> Result<MultiRendered, CaptureError> {
        let camera = ViewPose::new(theta_deg, phi_deg, MULTI_DISTANCE)?;
        Ok(self.render_view(&camera, frame_seed))
    }

    /// Renders the scene from `camera` (a view of the group's centre).
    pub fn render_view(&self, camera: &ViewPose, frame_seed: u64) -> MultiRendered {
        let (image, labels) = self.draw(camera, frame_seed);
        let world_from_camera = camera.world_from_camera();
        let camera_from_world = camera.camera_from_world();
        let objects = (0..self.placed.len())
            .map(|i| self.truth(i, &labels, &camera_from_world, &world_from_camera))
            .collect();
        MultiRendered {
            image,
            labels,
            objects,
            world_from_camera,
        }
    }

    /// The image alone, without the truth (which draws every object once
    /// more on its own): what a simulated camera sends.
    pub fn render_image(&self, camera: &ViewPose, frame_seed: u64) -> RgbImage {
        self.render_moving_image(|_| *camera, frame_seed)
    }

    /// The image of a camera moving while the shutter is open: `path(s)`
    /// is the camera at the share `s` in [-0.5, 0.5] of the exposure, and
    /// the image the mean, in linear light, of views spaced so nothing
    /// moves more than about a pixel between two, as
    /// [`crate::Renderer::render_moving_into`] exposes one object. A
    /// camera that does not move renders exactly as
    /// [`MultiRenderer::render_image`].
    pub fn render_moving_image(&self, path: impl Fn(f64) -> ViewPose, frame_seed: u64) -> RgbImage {
        let k = self.scene.intrinsics;
        let samples = exposure_samples(&path(-0.5), &path(0.5), &k);
        let (mut image, mut labels, mut depth) = self.canvas();
        self.draw_scene(&path(0.0), &mut image, &mut labels, &mut depth);
        let (mut sum, mut sub) = (Vec::new(), Vec::new());
        integrate_exposure(&mut image, samples, &mut sum, &mut sub, |share, rgb| {
            self.draw_scene(&path(share), rgb, &mut labels, &mut depth)
        });
        let mut blur = Vec::new();
        let (w, h) = (k.width as usize, k.height as usize);
        effects::apply(&mut image, w, h, &self.scene.effects, frame_seed, &mut blur);
        image
    }

    /// The image and the labels.
    fn draw(&self, camera: &ViewPose, frame_seed: u64) -> (RgbImage, GrayImage) {
        let (mut image, mut labels, mut depth) = self.canvas();
        self.draw_scene(camera, &mut image, &mut labels, &mut depth);
        let k = self.scene.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let mut blur = Vec::new();
        effects::apply(&mut image, w, h, &self.scene.effects, frame_seed, &mut blur);
        (image, labels)
    }

    /// An image, its labels and depth of the intrinsics' size.
    fn canvas(&self) -> (RgbImage, GrayImage, Vec<f32>) {
        let k = self.scene.intrinsics;
        (
            RgbImage::new(k.width, k.height),
            GrayImage::new(k.width, k.height),
            vec![0f32; k.width as usize * k.height as usize],
        )
    }

    /// Draws the scene from `camera` into `rgb` and `labels` (the
    /// intrinsics' size, `labels` cleared here): table, objects and
    /// distractors, no effects.
    fn draw_scene(&self, camera: &ViewPose, rgb: &mut [u8], labels: &mut [u8], depth: &mut [f32]) {
        let k = self.scene.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let world_from_camera = camera.world_from_camera();
        let camera_from_world = camera.camera_from_world();
        labels.fill(0);
        depth.fill(0.0);
        let mut frame = Frame {
            rgb,
            mask: labels,
            depth,
            w,
            h,
        };
        draw_background(
            &mut frame,
            (self.table.as_deref(), self.scene.background),
            &world_from_camera,
            &k,
            self.table_z,
        );
        let world_light = camera_from_world.matrix3 * light_world();
        for (i, p) in self.placed.iter().enumerate() {
            let cam_from_obj = camera_from_world * p.world_from_object;
            draw_object(
                &mut frame,
                &p.object,
                &cam_from_obj,
                self.light_cam(&camera_from_world, i),
                &k,
                i as u8 + 1,
            );
        }
        for d in &self.distractors {
            let cam_from_obj = camera_from_world * d.world_from_object;
            draw_object(&mut frame, &d.object, &cam_from_obj, world_light, &k, 0);
        }
    }

    /// The light towards which object `i` is shaded, in the camera frame.
    fn light_cam(&self, camera_from_world: &DAffine3, i: usize) -> DVec3 {
        let world = match self.scene.light {
            SceneLight::World => light_world(),
            SceneLight::AsTrained => DMat3::from_rotation_z(self.yaws[i]) * light_world(),
        };
        camera_from_world.matrix3 * world
    }

    fn truth(
        &self,
        i: usize,
        labels: &GrayImage,
        camera_from_world: &DAffine3,
        world_from_camera: &DAffine3,
    ) -> ObjectTruth {
        let label = i as u8 + 1;
        let visible_px = labels.iter().filter(|&&v| v == label).count() as u32;
        let mut own = labels.clone();
        own.iter_mut()
            .for_each(|v| *v = u8::from(*v == label) * 255);
        let bbox = mask_bbox(&own);
        // The object alone: its own pixels, with no neighbour in front.
        let k = self.scene.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let mut rgb = vec![0u8; 3 * w * h];
        let mut depth = vec![0f32; w * h];
        own.fill(0);
        let p = &self.placed[i];
        draw_object(
            &mut Frame {
                rgb: &mut rgb,
                mask: &mut own,
                depth: &mut depth,
                w,
                h,
            },
            &p.object,
            &(*camera_from_world * p.world_from_object),
            DVec3::Z,
            &k,
            255,
        );
        let alone_px = own.iter().filter(|&&v| v != 0).count() as u32;
        let at_border = mask_bbox(&own).is_some_and(|b| {
            b.x == 0 || b.y == 0 || b.x + b.width >= k.width || b.y + b.height >= k.height
        });
        ObjectTruth {
            object: i,
            view: view_from(world_from_camera, &p.world_from_object),
            visible_px,
            alone_px,
            bbox,
            at_border,
        }
    }
}

/// The camera `world_from_camera` as seen from an object standing at
/// `world_from_object`: θ, φ and distance of the camera centre in the
/// object's frame, and the roll between the camera and one looking straight
/// at the object's centre from there (non-zero when the object stands off
/// the optical axis).
pub fn view_from(world_from_camera: &DAffine3, world_from_object: &DAffine3) -> ViewPose {
    let object_from_camera = world_from_object.inverse() * *world_from_camera;
    let p = object_from_camera.translation;
    let distance = p.length().max(f64::MIN_POSITIVE);
    let theta = (p.z / distance).clamp(0.0, 1.0).asin().to_degrees();
    let phi = p.y.atan2(p.x).to_degrees();
    let straight = ViewPose::new(theta, phi, distance).expect("a finite view");
    let r0 = straight.world_from_camera_rotation();
    let down = object_from_camera.matrix3.y_axis;
    // down' = -sin(roll) right + cos(roll) down (ViewPose::roll_deg).
    let roll = (-down.dot(r0.x_axis))
        .atan2(down.dot(r0.y_axis))
        .to_degrees();
    straight.with_roll(roll).expect("a finite roll")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn objects(names: &[&str]) -> Vec<Arc<Object>> {
        names
            .iter()
            .map(|n| Arc::new(Object::builtin(n).unwrap()))
            .collect()
    }

    #[test]
    fn an_object_at_the_origin_sees_the_camera_it_was_rendered_from() {
        let camera = ViewPose::new(62.0, 137.0, 5.0).unwrap();
        let v = view_from(&camera.world_from_camera(), &DAffine3::IDENTITY);
        assert!((v.theta_deg - 62.0).abs() < 1e-9, "{v:?}");
        assert!((v.phi_deg - 137.0).abs() < 1e-9, "{v:?}");
        assert!(
            (v.distance - 5.0).abs() < 1e-9 && v.roll_deg.abs() < 1e-9,
            "{v:?}"
        );
        // Turning the object by 40° turns the camera's azimuth by -40°.
        let turned = view_from(
            &camera.world_from_camera(),
            &DAffine3::from_rotation_z(40f64.to_radians()),
        );
        assert!((turned.phi_deg - 97.0).abs() < 1e-9, "{turned:?}");
        // A rolled camera keeps its roll.
        let rolled = view_from(
            &camera.with_roll(12.0).unwrap().world_from_camera(),
            &DAffine3::IDENTITY,
        );
        assert!((rolled.roll_deg - 12.0).abs() < 1e-9, "{rolled:?}");
    }

    #[test]
    fn every_object_is_labelled_where_it_is_seen_and_footprints_never_overlap() {
        let scene = MultiScene::new(objects(&["fruitbox", "can", "tricolor"]), Background::A);
        for seed in 0..6 {
            let r = MultiRenderer::new(scene.clone(), seed).unwrap();
            for i in 0..3 {
                for j in i + 1..3 {
                    let (a, b) = (
                        r.world_from_object(i).unwrap().translation,
                        r.world_from_object(j).unwrap().translation,
                    );
                    let d = (a - b).truncate().length();
                    let need = footprint(&scene.objects[i]) + footprint(&scene.objects[j]);
                    assert!(
                        d >= need + 0.019 && d <= need + 3.0,
                        "seed {seed}: {d} vs {need}"
                    );
                }
            }
            let f = r.render(60.0, 45.0 * seed as f64, seed).unwrap();
            assert_eq!(f.objects.len(), 3);
            for t in &f.objects {
                let counted = f
                    .labels
                    .iter()
                    .filter(|&&v| v == t.object as u8 + 1)
                    .count();
                assert_eq!(counted as u32, t.visible_px);
                assert!(t.visible_px <= t.alone_px, "{t:?}");
                assert!(t.alone_px > 1000, "seed {seed}: {t:?}");
                assert!((0.0..=1.0).contains(&t.hidden()));
            }
        }
    }

    #[test]
    fn the_same_seeds_give_the_same_bytes_and_other_seeds_other_layouts() {
        let scene = MultiScene::new(objects(&["fruitbox", "can"]), Background::B);
        let a = MultiRenderer::new(scene.clone(), 3).unwrap();
        let b = MultiRenderer::new(scene.clone(), 3).unwrap();
        let c = MultiRenderer::new(scene, 4).unwrap();
        let (fa, fb) = (
            a.render(70.0, 10.0, 1).unwrap(),
            b.render(70.0, 10.0, 1).unwrap(),
        );
        assert_eq!(fa.image, fb.image);
        assert_eq!(fa.objects, fb.objects);
        assert_ne!(a.world_from_object(1), c.world_from_object(1));
    }

    #[test]
    fn a_world_light_shades_turned_objects_otherwise_than_their_training_light() {
        let mut scene = MultiScene::new(objects(&["fruitbox"]), Background::A);
        scene.distractors = 0;
        let trained = MultiRenderer::new(scene.clone(), 5).unwrap();
        scene.light = SceneLight::World;
        let world = MultiRenderer::new(scene, 5).unwrap();
        let (a, b) = (
            trained.render(60.0, 0.0, 0).unwrap(),
            world.render(60.0, 0.0, 0).unwrap(),
        );
        assert_eq!(a.labels, b.labels);
        assert_ne!(a.image, b.image);
    }

    #[test]
    fn no_object_or_too_many_is_refused() {
        let none = MultiScene::new(Vec::new(), Background::A);
        assert!(matches!(
            MultiRenderer::new(none, 0),
            Err(MultiSceneError::ObjectCount { count: 0 })
        ));
        let many = MultiScene::new(objects(&["can"; MAX_SCENE_OBJECTS + 1]), Background::A);
        assert!(MultiRenderer::new(many, 0).is_err());
    }
}
