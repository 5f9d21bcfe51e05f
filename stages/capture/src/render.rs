//! The scene renderer: configuration, ground truth and the per-frame loop.

use std::cell::RefCell;
use std::sync::Arc;

use glam::{DAffine3, DMat3, DVec3};
use image::{GrayImage, RgbImage};
use serde::{Deserialize, Serialize};

use crate::background::{
    Background, Placed, TABLE_TILE, TableKind, TextureSet, clutter_layout, table_texture,
};
use crate::effects::{self, Effects};
use crate::object::Object;
use crate::raster::{Frame, draw_object, draw_table, light_world};
use crate::texture::Texture;
use crate::{Intrinsics, ViewPose};

/// What to render: the target object, its surroundings, the camera and the
/// image degradations.
#[derive(Debug, Clone)]
pub struct SceneConfig {
    /// The target object (normalised: centre at the origin, radius 1).
    pub object: Arc<Object>,
    /// Table and distractors.
    pub background: Background,
    /// Camera intrinsics (image size and focal lengths).
    pub intrinsics: Intrinsics,
    /// Blur, brightness and noise.
    pub effects: Effects,
    /// Which instance of the table texture the background shows.
    pub textures: TextureSet,
    /// Share of the object's width (0-1) a bar in front of it hides, as a
    /// gripper's finger or a pole would: full height, dark grey, at a place
    /// drawn from the frame seed; the mask keeps only what stays visible.
    /// 0 = none.
    pub occlusion: f32,
    /// Degrees the light is turned about the world's vertical from the
    /// training light's direction (the object lit from another side, as
    /// by a room's lamp once the object is turned on the table); 0 = the
    /// training light.
    pub light_azimuth_deg: f32,
}

impl SceneConfig {
    /// A scene with default intrinsics and no effects.
    pub fn new(object: Arc<Object>, background: Background) -> Self {
        SceneConfig {
            object,
            background,
            intrinsics: Intrinsics::default(),
            effects: Effects::default(),
            textures: TextureSet::default(),
            occlusion: 0.0,
            light_azimuth_deg: 0.0,
        }
    }

    /// The same scene with the textures of `set`.
    pub fn with_textures(self, set: TextureSet) -> Self {
        SceneConfig {
            textures: set,
            ..self
        }
    }
}

/// A pixel rectangle: columns `x .. x + width`, rows `y .. y + height`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BBox {
    /// Leftmost column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels (>= 1).
    pub width: u32,
    /// Height in pixels (>= 1).
    pub height: u32,
}

/// Everything known about a rendered view.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GroundTruth {
    /// Camera elevation in degrees.
    pub theta_deg: f64,
    /// Camera azimuth in degrees.
    pub phi_deg: f64,
    /// Camera distance from the object centre in bounding radii.
    pub distance: f64,
    /// Camera roll about its optical axis in degrees, (-180, 180]
    /// (see [`ViewPose::roll_deg`]).
    pub roll_deg: f64,
    /// Camera pose: OpenCV camera frame to world frame.
    pub world_from_camera: DAffine3,
    /// The camera's intrinsics.
    pub intrinsics: Intrinsics,
    /// Bounding box of the target's visible pixels; `None` if none is visible.
    pub bbox: Option<BBox>,
}

impl GroundTruth {
    /// Where the object centre (the world origin) projects, pixels; `None`
    /// when it is behind the camera.
    pub fn object_centre_px(&self) -> Option<glam::DVec2> {
        let centre = self.world_from_camera.inverse().translation;
        self.intrinsics.project(centre)
    }
}

/// A rendered frame: image, target mask and ground truth.
#[derive(Debug, Clone, Default)]
pub struct Rendered {
    /// The colour image.
    pub image: RgbImage,
    /// 255 where the target object is visible, 0 elsewhere (distractors and
    /// table are 0).
    pub mask: GrayImage,
    /// Ground truth for the frame.
    pub truth: GroundTruth,
}

/// Per-thread scratch buffers, so frames after the first allocate nothing.
#[derive(Default)]
struct Scratch {
    depth: Vec<f32>,
    blur: Vec<f32>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// Colour shown where camera rays miss the table (above the horizon).
const WALL: [u8; 3] = [118, 120, 126];

/// Renders a scene from any view. Textures, table and clutter layout are
/// prepared once in [`Renderer::new`]; rendering only reads them, so a
/// `Renderer` can be shared between threads (`&Renderer` is `Send`) and views
/// rendered in parallel. Output depends only on the scene seed, the view and
/// the frame seed, never on threads.
///
/// Lighting: ambient 0.45 plus Lambert 0.6 from a fixed world direction above
/// the table, tilted slightly towards +x, -y; surfaces are lit on both sides.
pub struct Renderer {
    config: SceneConfig,
    distractors: Vec<Placed>,
    table: Option<Arc<Texture>>,
}

impl Renderer {
    /// Prepares a scene. `scene_seed` chooses the clutter layout (ignored by
    /// backgrounds without clutter). Invalid effect values (negative or
    /// non-finite) are treated as "no effect".
    pub fn new(config: SceneConfig, scene_seed: u64) -> Self {
        let table = table_of(config.background, config.textures);
        let distractors = match config.background {
            Background::Clutter => clutter_layout(&config.object, false, scene_seed),
            Background::ClutterSimilar => clutter_layout(&config.object, true, scene_seed),
            _ => Vec::new(),
        };
        Renderer {
            config,
            distractors,
            table,
        }
    }

    /// Turns the light about the vertical (see
    /// [`SceneConfig::light_azimuth_deg`]); the scene is otherwise the same.
    pub fn set_light_azimuth_deg(&mut self, deg: f32) {
        self.config.light_azimuth_deg = deg;
    }

    /// The scene configuration.
    pub fn config(&self) -> &SceneConfig {
        &self.config
    }

    /// Number of distractor objects on the table.
    pub fn distractor_count(&self) -> usize {
        self.distractors.len()
    }

    /// The light's direction in the world: the training light's, turned
    /// by `light_azimuth_deg` about the vertical.
    fn light_world(&self) -> DVec3 {
        let turn = f64::from(self.config.light_azimuth_deg);
        let turn = if turn.is_finite() { turn } else { 0.0 };
        DMat3::from_rotation_z(turn.to_radians()) * light_world()
    }

    /// The height of the table plane (the target's lowest z).
    pub fn table_z(&self) -> f64 {
        self.config.object.table_z()
    }

    /// Renders one view. `frame_seed` seeds the sensor noise only.
    pub fn render(&self, view: &ViewPose, frame_seed: u64) -> Rendered {
        let mut out = Rendered::default();
        self.render_into(view, frame_seed, &mut out);
        out
    }

    /// Renders one view into `out`, reusing its buffers (and per-thread
    /// scratch memory): no allocation once the sizes are established.
    pub fn render_into(&self, view: &ViewPose, frame_seed: u64, out: &mut Rendered) {
        let k = self.config.intrinsics;
        let (w, h) = (k.width, k.height);
        if out.image.dimensions() != (w, h) {
            out.image = RgbImage::new(w, h);
        }
        if out.mask.dimensions() != (w, h) {
            out.mask = GrayImage::new(w, h);
        }
        let world_from_camera = view.world_from_camera();
        let camera_from_world = view.camera_from_world();
        let (wu, hu) = (w as usize, h as usize);
        SCRATCH.with(|s| {
            let s = &mut *s.borrow_mut();
            s.depth.clear();
            s.depth.resize(wu * hu, 0.0);
            out.mask.fill(0);
            let mut frame = Frame {
                rgb: &mut out.image,
                mask: &mut out.mask,
                depth: &mut s.depth,
                w: wu,
                h: hu,
            };
            draw_background(
                &mut frame,
                (self.table.as_deref(), self.config.background),
                &world_from_camera,
                &k,
                self.table_z(),
            );
            let light_cam = camera_from_world.matrix3 * self.light_world();
            draw_object(
                &mut frame,
                &self.config.object,
                &camera_from_world,
                light_cam,
                &k,
                255,
            );
            for d in &self.distractors {
                let cam_from_obj = camera_from_world * d.world_from_object;
                draw_object(&mut frame, &d.object, &cam_from_obj, light_cam, &k, 0);
            }
            let share = self.config.occlusion;
            if share.is_finite() && share > 0.0 {
                occlude(&mut out.image, &mut out.mask, share.min(1.0), frame_seed);
            }
            effects::apply(
                &mut out.image,
                wu,
                hu,
                &self.config.effects,
                frame_seed,
                &mut s.blur,
            );
        });
        out.truth = GroundTruth {
            theta_deg: view.theta_deg,
            phi_deg: view.phi_deg,
            distance: view.distance,
            roll_deg: view.roll_deg,
            world_from_camera,
            intrinsics: k,
            bbox: mask_bbox(&out.mask),
        };
    }
}

/// Draws what lies behind the objects: `table` (the texture of
/// `background`) as the plane `z = table_z`, or `background`'s plain colour.
pub(crate) fn draw_background(
    frame: &mut Frame,
    (table, background): (Option<&Texture>, Background),
    world_from_camera: &DAffine3,
    k: &Intrinsics,
    table_z: f64,
) {
    if let Some(table) = table {
        draw_table(
            frame,
            table,
            TABLE_TILE,
            &world_from_camera.matrix3,
            world_from_camera.translation,
            k,
            table_z,
            WALL,
        );
    } else {
        let c = match background {
            Background::Plain(c) => c,
            _ => Background::DEFAULT_PLAIN,
        };
        for px in frame.rgb.chunks_exact_mut(3) {
            px.copy_from_slice(&c);
        }
    }
}

/// The table texture of `background` (none for a plain colour), from the
/// textures of `set`.
pub(crate) fn table_of(background: Background, set: TextureSet) -> Option<Arc<Texture>> {
    match background {
        Background::Plain(_) => None,
        Background::A => Some(TableKind::Wood),
        Background::B => Some(TableKind::Fabric),
        Background::C => Some(TableKind::Felt),
        Background::Clutter | Background::ClutterSimilar => Some(TableKind::Laminate),
    }
    .map(|kind| table_texture(kind, set))
}

/// Grey of the occluding bar (a gripper finger's anodised aluminium).
const OCCLUDER_RGB: [f32; 3] = [70.0, 72.0, 78.0];

/// Hides `share` of the object's width behind a vertical bar at a place
/// drawn from `seed`: the bar spans the object's height and a tenth more
/// either way, shaded lighter towards its middle like a cylinder, and
/// clears the mask under it.
fn occlude(image: &mut RgbImage, mask: &mut GrayImage, share: f32, seed: u64) {
    use rand::{Rng, SeedableRng};
    let Some(b) = mask_bbox(mask) else {
        return;
    };
    let bar = ((b.width as f32 * share).round() as u32).clamp(1, b.width);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x6f63_636c_7564_6572);
    let x0 = b.x + rng.random_range(0..=b.width - bar);
    let (w, h) = mask.dimensions();
    let margin = b.height / 10;
    let (y0, y1) = (b.y.saturating_sub(margin), (b.y + b.height + margin).min(h));
    for x in x0..(x0 + bar).min(w) {
        let across = (x - x0) as f32 / bar.max(1) as f32 * 2.0 - 1.0;
        let shade = 0.75 + 0.35 * (1.0 - across * across).sqrt();
        let c = OCCLUDER_RGB.map(|v| (v * shade).round().clamp(0.0, 255.0) as u8);
        for y in y0..y1 {
            image.put_pixel(x, y, image::Rgb(c));
            mask.put_pixel(x, y, image::Luma([0]));
        }
    }
}

/// Bounding box of the non-zero pixels of a mask.
pub fn mask_bbox(mask: &GrayImage) -> Option<BBox> {
    let (w, h) = mask.dimensions();
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (y, row) in mask.as_raw().chunks_exact(w.max(1) as usize).enumerate() {
        if let Some(first) = row.iter().position(|&m| m != 0) {
            let last = row.iter().rposition(|&m| m != 0).unwrap_or(first);
            x0 = x0.min(first as u32);
            x1 = x1.max(last as u32);
            y0 = y0.min(y as u32);
            y1 = y1.max(y as u32);
        }
    }
    (x0 != u32::MAX && h > 0).then(|| BBox {
        x: x0,
        y: y0,
        width: x1 - x0 + 1,
        height: y1 - y0 + 1,
    })
}
