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
use acch_core::light::{linear_to_srgb, srgb_decode_table};

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
    /// What hides `occlusion` of the object: `None`, the grey bar; an
    /// object, that object held upright in front of the target at half
    /// the camera's distance, stretched over the bar's place (its inks
    /// and shading, not one grey; its outline hides up to the share).
    pub occluder: Option<Arc<Object>>,
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
            occluder: None,
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
    /// A moving exposure's sum of linear colour, and the view being drawn.
    sum: Vec<f32>,
    sub_rgb: Vec<u8>,
    sub_mask: Vec<u8>,
    sub_depth: Vec<f32>,
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
        self.render_moving_into(|_| *view, frame_seed, out);
    }

    /// Renders a frame whose camera moves while the shutter is open, as a
    /// camera on a moving arm sees it: `path(s)` is the camera's view at
    /// the share `s` in [-0.5, 0.5] of the exposure (0: the frame's own
    /// time). The image is the mean, in linear light as a sensor
    /// integrates it, of views spaced so that nothing in the image moves
    /// more than about a pixel between two ([`exposure_samples`]); the
    /// mask and the ground truth are those of the frame's own view, and
    /// the occluder and the effects are applied once, to the mean. A
    /// camera that does not move renders exactly as
    /// [`Renderer::render_into`].
    pub fn render_moving_into(
        &self,
        path: impl Fn(f64) -> ViewPose,
        frame_seed: u64,
        out: &mut Rendered,
    ) {
        let k = self.config.intrinsics;
        let (w, h) = (k.width, k.height);
        if out.image.dimensions() != (w, h) {
            out.image = RgbImage::new(w, h);
        }
        if out.mask.dimensions() != (w, h) {
            out.mask = GrayImage::new(w, h);
        }
        let view = path(0.0);
        let samples = exposure_samples(&path(-0.5), &path(0.5), &k);
        let (wu, hu) = (w as usize, h as usize);
        SCRATCH.with(|s| {
            let s = &mut *s.borrow_mut();
            self.draw(&view, &mut out.image, &mut out.mask, &mut s.depth);
            // The other views draw into their own mask and depth: the
            // frame's own are its truth and the occluder's depth test.
            let (sub_mask, sub_depth) = (&mut s.sub_mask, &mut s.sub_depth);
            integrate_exposure(
                &mut out.image,
                samples,
                &mut s.sum,
                &mut s.sub_rgb,
                |share, rgb| {
                    sub_mask.resize(wu * hu, 0);
                    self.draw(&path(share), rgb, sub_mask, sub_depth)
                },
            );
            let share = self.config.occlusion;
            if share.is_finite() && share > 0.0 {
                let share = share.min(1.0);
                match &self.config.occluder {
                    None => occlude(&mut out.image, &mut out.mask, share, frame_seed),
                    Some(occluder) => {
                        let mut frame = Frame {
                            rgb: &mut out.image,
                            mask: &mut out.mask,
                            depth: &mut s.depth,
                            w: wu,
                            h: hu,
                        };
                        self.hold_in_front(&mut frame, occluder, &view, share, frame_seed);
                    }
                }
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
            world_from_camera: view.world_from_camera(),
            intrinsics: k,
            bbox: mask_bbox(&out.mask),
        };
    }

    /// Draws the scene from `view` into `rgb` and `mask` (the intrinsics'
    /// size): table, target and distractors, no occluder, no effects.
    fn draw(&self, view: &ViewPose, rgb: &mut [u8], mask: &mut [u8], depth: &mut Vec<f32>) {
        let k = self.config.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let world_from_camera = view.world_from_camera();
        let camera_from_world = view.camera_from_world();
        depth.clear();
        depth.resize(w * h, 0.0);
        mask.fill(0);
        let mut frame = Frame {
            rgb,
            mask,
            depth,
            w,
            h,
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
    }
}

impl Renderer {
    /// Draws `occluder` in front of the target over the bar's place for
    /// `share` ([`bar_span`]): upright in the image, turned about its own
    /// vertical by an angle drawn from `seed`, at half the camera's
    /// distance, stretched so its extent fills the bar's columns and rows.
    /// It moves with the camera (a gripper holding it), so it is drawn
    /// once, over the integrated frame, in front of everything.
    fn hold_in_front(
        &self,
        frame: &mut Frame,
        occluder: &Object,
        view: &ViewPose,
        share: f32,
        seed: u64,
    ) {
        use rand::{Rng, SeedableRng};
        let Some((x0, bar, y0, y1)) = bar_span(&*frame.mask, frame.w, frame.h, share, seed) else {
            return;
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x686f_6c64);
        let turn = DMat3::from_rotation_z(rng.random_range(0.0..std::f64::consts::TAU));
        // The turned vertices, walked once per round rather than stored:
        // a frame allocates nothing here.
        let points = || {
            occluder
                .tris
                .iter()
                .flatten()
                .map(|v| turn * v.p.as_dvec3())
        };
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in points() {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        let (mid, extent) = ((lo + hi) / 2.0, (hi - lo).max(DVec3::splat(1e-9)));
        let k = self.config.intrinsics;
        // The place's pixel edges, a quarter pixel in (so rounding never
        // spills the outline onto a neighbour).
        let (left, right) = (f64::from(x0) - 0.25, f64::from(x0 + bar) - 0.75);
        let (top, bottom) = (f64::from(y0) - 0.25, f64::from(y1) - 0.75);
        // The object's x along the image's x, its vertical (z) up the
        // image (-y), its y away from the camera; its front at half the
        // camera's distance. Stretch and centre are fitted to the place
        // by a few rounds, as perspective widens the front.
        let near = 0.5 * view.distance;
        let mut across = (right - left) * near / k.fx / extent.x;
        let mut up = (bottom - top) * near / k.fy / extent.z;
        let thick = across;
        let mut centre = glam::DVec2::new(
            ((left + right) / 2.0 - k.cx) * near / k.fx,
            ((top + bottom) / 2.0 - k.cy) * near / k.fy,
        );
        let place = |p: DVec3, across: f64, up: f64, centre: glam::DVec2| {
            DVec3::new(
                across * (p.x - mid.x) + centre.x,
                -up * (p.z - mid.z) + centre.y,
                thick * (p.y - lo.y) + near,
            )
        };
        for _ in 0..4 {
            let (mut u, mut v) = (
                (f64::INFINITY, f64::NEG_INFINITY),
                (f64::INFINITY, f64::NEG_INFINITY),
            );
            for p in points() {
                let c = place(p, across, up, centre);
                let (pu, pv) = (k.cx + k.fx * c.x / c.z, k.cy + k.fy * c.y / c.z);
                u = (u.0.min(pu), u.1.max(pu));
                v = (v.0.min(pv), v.1.max(pv));
            }
            across *= (right - left) / (u.1 - u.0).max(1e-9);
            up *= (bottom - top) / (v.1 - v.0).max(1e-9);
            centre.x += ((left + right) - (u.0 + u.1)) / 2.0 * near / k.fx;
            centre.y += ((top + bottom) - (v.0 + v.1)) / 2.0 * near / k.fy;
        }
        let upright = DMat3::from_cols(DVec3::X, DVec3::Z, DVec3::NEG_Y);
        let cam_from_occluder = DAffine3 {
            matrix3: upright * DMat3::from_diagonal(DVec3::new(across, thick, up)) * turn,
            translation: place(DVec3::ZERO, across, up, centre),
        };
        // In front of everything: the scene's depths are forgotten.
        frame.depth.fill(0.0);
        let light_cam = view.camera_from_world().matrix3 * self.light_world();
        draw_object(frame, occluder, &cam_from_occluder, light_cam, &k, 0);
    }
}

/// Where an occluder hiding `share` of the target's width stands, drawn
/// from `seed`: columns `x0 .. x0 + width` and rows `y0 .. y1`, the
/// target's height and a tenth more either way; `None` when the target is
/// not in view.
fn bar_span(
    mask: &[u8],
    w: usize,
    h: usize,
    share: f32,
    seed: u64,
) -> Option<(u32, u32, u32, u32)> {
    use rand::{Rng, SeedableRng};
    let b = bbox_of(mask, w, h)?;
    let bar = ((b.width as f32 * share).round() as u32).clamp(1, b.width);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x6f63_636c_7564_6572);
    let x0 = b.x + rng.random_range(0..=b.width - bar);
    let margin = b.height / 10;
    let (y0, y1) = (
        b.y.saturating_sub(margin),
        (b.y + b.height + margin).min(h as u32),
    );
    Some((x0, bar, y0, y1))
}

/// Most views a moving exposure is integrated from.
pub const MAX_EXPOSURE_SAMPLES: usize = 65;

/// How many views a moving exposure from `start` to `end` is integrated
/// from: one per pixel the camera's turn moves the image at its edge, odd
/// so that the frame's own view is one of them, 1 for a still camera. A
/// turn about the optical axis moves the corners by the half diagonal per
/// radian, any other turn the far scene by the focal length; the camera
/// circles the object, so its translation moves only what is nearer than
/// half the distance to the object more than that, and nothing is.
pub fn exposure_samples(start: &ViewPose, end: &ViewPose, k: &Intrinsics) -> usize {
    let turn = start.world_from_camera_rotation().transpose() * end.world_from_camera_rotation();
    let cos = (turn.x_axis.x + turn.y_axis.y + turn.z_axis.z - 1.0) / 2.0;
    let radians = cos.clamp(-1.0, 1.0).acos();
    let half_diagonal = 0.5 * f64::from(k.width).hypot(f64::from(k.height));
    let pixels = radians * (k.fx.max(k.fy) + half_diagonal);
    if !pixels.is_finite() {
        return 1;
    }
    ((pixels.round() as usize).min(MAX_EXPOSURE_SAMPLES - 1) + 1) | 1
}

/// Turns `rgb`, the view at the middle of an exposure, into the mean in
/// linear light (as a sensor integrates it) of `samples` views evenly
/// over the exposure: `draw(share, into)` draws the view at `share` in
/// [-0.5, 0.5] into `into`, of `rgb`'s size. One sample leaves `rgb` as
/// it is. `sum` and `sub` are scratch.
pub(crate) fn integrate_exposure(
    rgb: &mut [u8],
    samples: usize,
    sum: &mut Vec<f32>,
    sub: &mut Vec<u8>,
    mut draw: impl FnMut(f64, &mut [u8]),
) {
    if samples <= 1 {
        return;
    }
    let decode = srgb_decode_table();
    sum.clear();
    sum.extend(rgb.iter().map(|&v| decode[v as usize]));
    sub.resize(rgb.len(), 0);
    // The middle sample is `rgb` itself.
    for i in (0..samples).filter(|&i| i != samples / 2) {
        draw(i as f64 / (samples - 1) as f64 - 0.5, sub);
        for (total, &v) in sum.iter_mut().zip(sub.iter()) {
            *total += decode[v as usize];
        }
    }
    let n = samples as f32;
    for (v, &total) in rgb.iter_mut().zip(sum.iter()) {
        *v = linear_to_srgb(total / n);
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
    let (w, h) = mask.dimensions();
    let Some((x0, bar, y0, y1)) = bar_span(mask, w as usize, h as usize, share, seed) else {
        return;
    };
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
    bbox_of(mask, w as usize, h as usize)
}

/// Bounding box of the non-zero bytes of a `w` x `h` mask, row-major.
fn bbox_of(mask: &[u8], w: usize, h: usize) -> Option<BBox> {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for (y, row) in mask.chunks_exact(w.max(1)).take(h).enumerate() {
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
