//! Frame sources for acch: a synthetic scene renderer with ground truth.
//!
//! The renderer places a pinhole camera on the view sphere around an object
//! standing on a table and draws z-buffered, perspective-correct textured
//! (or vertex-coloured) triangles with Lambert + ambient light over a
//! ray-cast table plane, with optional blur, brightness change and sensor
//! noise. Each image comes with its ground truth: elevation θ, azimuth φ,
//! roll, distance, camera pose, intrinsics, the target's visible-pixel mask
//! and its bounding box.
//!
//! Conventions:
//! - World: z up; the target's bounding-sphere centre at the origin, radius 1
//!   (distances are in bounding radii); the table is the plane
//!   `z = object.table_z()` (the object's lowest z), the object stands on it.
//! - Camera centre `c = r (cos θ cos φ, cos θ sin φ, sin θ)`; OpenCV camera
//!   frame (x right, y down, z forward); forward = -c/|c|; image up
//!   `e_θ = (-sin θ cos φ, -sin θ sin φ, cos θ)`; right = down × forward.
//!   `world_from_camera` has rotation columns (right, down, forward) and
//!   translation `c`. A camera roll ρ (`ViewPose::roll_deg`) turns right and
//!   down by +ρ about forward (`right' = cos ρ right + sin ρ down`), so the
//!   image content turns by ρ counter-clockwise on screen.
//! - Everything is seeded: the same seeds give the same bytes.
//!
//! ```no_run
//! use std::sync::Arc;
//! use acch_capture::{Background, Object, Renderer, SceneConfig, ViewPose, DEFAULT_DISTANCE};
//!
//! let object = Arc::new(Object::builtin("fruitbox")?);
//! let renderer = Renderer::new(SceneConfig::new(object, Background::A), 0);
//! let view = ViewPose::new(60.0, 30.0, DEFAULT_DISTANCE)?;
//! let frame = renderer.render(&view, 0);
//! frame.image.save("view.png").unwrap();
//! # Ok::<(), acch_capture::CaptureError>(())
//! ```
#![warn(missing_docs)]

mod background;
mod builtin;
pub mod calibration;
mod camera;
mod effects;
mod error;
mod generated;
pub mod labels;
mod mesh;
mod multi;
mod noise;
mod object;
mod paint;
mod posed;
mod raster;
mod render;
mod texture;
mod trajectory;
mod views;

pub use background::{Background, TextureSet};
pub use builtin::BUILTIN_OBJECTS;
pub use calibration::{Calibration, Distortion, DistortionModel};
pub use camera::{
    DEFAULT_DISTANCE, Intrinsics, ViewPose, check_distance, world_from_camera_rotation,
};
pub use effects::Effects;
pub use error::CaptureError;
pub use generated::{GENERATED_PREFIX, GENERATOR_REVISION, generated_seed, population};
pub use multi::{
    MAX_SCENE_OBJECTS, MULTI_DISTANCE, MultiRendered, MultiRenderer, MultiScene, MultiSceneError,
    ObjectTruth, SceneLight, view_from,
};
pub use object::{FileFrame, ModelInfo, Object, UpAxis};
pub use posed::{PosedRender, render_posed};
pub use render::{
    BBox, GroundTruth, MAX_EXPOSURE_SAMPLES, Rendered, Renderer, SceneConfig, exposure_samples,
    mask_bbox,
};
pub use trajectory::{Frames, Trajectory, TrajectoryFrame};
pub use views::ViewSpec;

/// Frame seed of view `i` of a set rendered with `set_seed`: distinct per
/// view, fixed per set seed (the per-frame noise of every protocol and of
/// the simulated camera).
pub fn frame_seed(set_seed: u64, i: usize) -> u64 {
    set_seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i as u64 + 1)
}

/// Derives an independent seed for item `index` from a base seed (SplitMix64
/// finaliser), e.g. the noise seed of view `index` of a dataset.
pub fn derive_seed(base: u64, index: u64) -> u64 {
    let mut z = base ^ index.wrapping_add(1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}
