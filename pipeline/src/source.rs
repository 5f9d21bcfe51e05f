//! Frame sources, written once for both executors: the simulated
//! eye-in-hand camera, a folder of images, an MCAP recording of an
//! earlier run, and a GStreamer pipeline (a real camera; cargo feature
//! `gstreamer`). A source makes frames in order; a frame of another size
//! than the stream's is skipped and named, never passed on.

use crate::frame::FrameHeader;
use crate::source_error::{CameraCounters, SourceError};
use crate::wire::{ArmPose, Intrinsics, Maybe, Truth};
use acch_capture::calibration::Calibration;
use acch_capture::{Background, Object, Rendered, Renderer, SceneConfig, Trajectory, ViewPose};
use acch_ipc::now_ns;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// The simulated camera: an object on a table, seen by an eye-in-hand
/// camera moving over the hemisphere.
#[derive(Clone, Debug)]
pub struct SyntheticCamera {
    /// The object.
    pub object: Arc<Object>,
    /// The table and its clutter.
    pub background: Background,
    /// Which instance of the table's texture: the held-out set by default,
    /// so the scene is not one the confidence network was trained on.
    pub textures: acch_capture::TextureSet,
    /// Seed of the trajectory and the scene.
    pub seed: u64,
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
    /// Camera distance to the object centre, metres.
    pub distance_m: f64,
    /// Frame rate the trajectory is sampled at (it sets how far the arm
    /// moves per frame).
    pub fps: f64,
    /// Elevation band the trajectory sweeps, degrees.
    pub elevation_deg: (f64, f64),
    /// The camera rolls about its optical axis within ±this, degrees
    /// (0: it stays upright).
    pub roll_deg: f64,
    /// The scene's light against the training light's: its linear
    /// exposure and colour temperature, kelvin (`acch_capture::Effects`).
    pub light: (f32, f32),
    /// How long the shutter is open, seconds (at most a frame period):
    /// the camera moves along the trajectory meanwhile and the frame is
    /// blurred along that motion; 0 = an instant, no motion blur.
    pub shutter_s: f64,
    /// Sensor noise, standard deviation in grey levels (0: none).
    pub noise_sigma: f32,
    /// A lens out of focus: a Gaussian blur of this sigma, pixels (0:
    /// sharp).
    pub blur_sigma: f32,
}

impl SyntheticCamera {
    /// The camera's intrinsics: the default focal length (so the object has
    /// its trained size in pixels at any resolution), principal point at the
    /// centre.
    pub fn intrinsics(&self) -> acch_capture::Intrinsics {
        sized_intrinsics(self.width, self.height)
    }
}

/// The simulated camera over several known objects standing together on
/// a table ([`acch_capture::MultiRenderer`]): it circles the group at 20°
/// a second while its elevation swings through the band every 12 s. Its
/// frames carry no ground truth (a frame holds several objects).
#[derive(Clone, Debug)]
pub struct SyntheticGroup {
    /// The objects in view.
    pub objects: Vec<Arc<Object>>,
    /// The table.
    pub background: Background,
    /// Which instance of the table's texture.
    pub textures: acch_capture::TextureSet,
    /// Seed of the layout and of the sensor noise.
    pub seed: u64,
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
    /// Frame rate the motion is sampled at.
    pub fps: f64,
    /// Elevation band the camera swings through, degrees.
    pub elevation_deg: (f64, f64),
    /// How long the shutter is open, seconds (at most a frame period):
    /// the frame is blurred along the camera's motion; 0 = an instant.
    pub shutter_s: f64,
}

impl SyntheticGroup {
    /// Azimuth speed, degrees a second.
    const TURN_DEG_PER_S: f64 = 20.0;
    /// Period of the elevation swing, seconds.
    const SWING_S: f64 = 12.0;

    /// The camera of frame `sequence` at the share `s` in [-0.5, 0.5] of
    /// its exposure (0: the frame's own time).
    fn camera(&self, sequence: u64, s: f64) -> Result<ViewPose, SourceError> {
        let fps = if self.fps > 0.0 { self.fps } else { 30.0 };
        let t = sequence as f64 / fps + s * self.shutter_s;
        let (lo, hi) = self.elevation_deg;
        let swing = 0.5 - 0.5 * (std::f64::consts::TAU * t / Self::SWING_S).cos();
        Ok(ViewPose::new(
            lo + (hi - lo) * swing,
            Self::TURN_DEG_PER_S * t,
            acch_capture::MULTI_DISTANCE,
        )?)
    }
}

/// The ground truth of a rendered frame and where the simulated arm put
/// the camera (the object frame is the world frame), in metres: the
/// renderer works in object bounding radii, of `radius_m` metres each.
pub fn metric_truth(t: &acch_capture::GroundTruth, radius_m: f64) -> (Truth, ArmPose) {
    let mut world_from_camera = t.world_from_camera;
    world_from_camera.translation *= radius_m;
    (
        Truth {
            theta_deg: t.theta_deg,
            phi_deg: t.phi_deg,
            distance_m: t.distance * radius_m,
            roll_deg: t.roll_deg,
            camera_from_object: world_from_camera.inverse().to_cols_array(),
        },
        ArmPose {
            world_from_camera: world_from_camera.to_cols_array(),
        },
    )
}

/// Intrinsics of a `width` x `height` synthetic camera with the default
/// focal length.
pub fn sized_intrinsics(width: u32, height: u32) -> acch_capture::Intrinsics {
    acch_capture::Intrinsics {
        width,
        height,
        cx: (width as f64 - 1.0) / 2.0,
        cy: (height as f64 - 1.0) / 2.0,
        ..Default::default()
    }
}

/// Which frames to read.
#[derive(Clone, Debug)]
pub enum SourceSpec {
    /// The simulated camera.
    Synthetic(SyntheticCamera),
    /// The simulated camera over several objects.
    Group(SyntheticGroup),
    /// PNG and JPEG images of a folder, in name order (or in the order of
    /// its labels.csv, which also gives their ground truth), cycled.
    Folder {
        /// The folder.
        dir: PathBuf,
        /// The camera that took them (else the synthetic camera's).
        calibration: Option<CameraFile>,
    },
    /// The frames of an `acch run --record` recording, in order.
    Mcap(PathBuf),
    /// A GStreamer pipeline ending in raw video (a camera, a stream, a
    /// file), as `gst-launch-1.0` writes it.
    Gst {
        /// The pipeline (after `gst:`).
        pipeline: String,
        /// The camera's calibration (else the synthetic camera's
        /// intrinsics at the stream's size).
        calibration: Option<CameraFile>,
    },
}

/// A calibration and the file it came from (errors name it).
#[derive(Clone, Debug)]
pub struct CameraFile {
    /// The file.
    pub path: PathBuf,
    /// What it says.
    pub calibration: Calibration,
}

impl CameraFile {
    /// The intrinsics of a `size` stream: the calibration's, refused when
    /// it is for another image size.
    fn intrinsics(&self, size: (u32, u32)) -> Result<Intrinsics, SourceError> {
        self.calibration.check_size(size.0, size.1).map_err(|why| {
            SourceError::CalibrationSize {
                path: self.path.clone(),
                why,
            }
        })?;
        Ok(Intrinsics::calibrated(&self.calibration))
    }
}

/// The intrinsics of a `size` stream from `calibration`, or the synthetic
/// camera's.
fn intrinsics_of(
    calibration: &Option<CameraFile>,
    size: (u32, u32),
) -> Result<Intrinsics, SourceError> {
    match calibration {
        Some(c) => c.intrinsics(size),
        None => Ok(Intrinsics::from(&sized_intrinsics(size.0, size.1))),
    }
}

/// The intrinsics a recorded frame was seen with, its lens included (a
/// model this build does not know reads as none, with a warning).
fn recorded_intrinsics(info: &acch_record::FrameInfo) -> Intrinsics {
    let k = Intrinsics::from_array(info.intrinsics);
    let Some((model, coefficients)) = &info.distortion else {
        return k;
    };
    match model.parse() {
        Ok(model) => k.with_lens(acch_capture::calibration::Distortion {
            model,
            coefficients: *coefficients,
        }),
        Err(e) => {
            tracing::warn!(
                "frame {}: distortion {model}: {e}; read as none",
                info.sequence
            );
            k
        }
    }
}

impl SourceSpec {
    /// The size of the stream: the camera's, the first image's, or the
    /// recording's first frame's.
    pub fn frame_size(&self) -> Result<(u32, u32), SourceError> {
        match self {
            SourceSpec::Synthetic(c) => Ok((c.width, c.height)),
            SourceSpec::Group(g) => Ok((g.width, g.height)),
            SourceSpec::Folder { dir, .. } => {
                let first = list_images(dir)?;
                let p = first
                    .first()
                    .ok_or_else(|| SourceError::Empty(dir.clone()))?;
                image::image_dimensions(p).map_err(|source| SourceError::Image {
                    path: p.clone(),
                    source,
                })
            }
            SourceSpec::Mcap(path) => Ok(acch_record::first_frame_size(path)?),
            SourceSpec::Gst { pipeline, .. } => Err(SourceError::Gst {
                pipeline: pipeline.clone(),
                why: "a stream's size is known once it runs: probe it".into(),
            }),
        }
    }

    /// Starts a GStreamer source to learn its size: `wanted` when the
    /// stream offers it, else the stream's own (said in a warning). Other
    /// sources have their [`Self::frame_size`].
    pub fn probe_size(&self, wanted: (u32, u32)) -> Result<(u32, u32), SourceError> {
        let SourceSpec::Gst { pipeline, .. } = self else {
            return self.frame_size();
        };
        #[cfg(feature = "gstreamer")]
        {
            let got = crate::gst::GstSource::probe(pipeline, wanted)?;
            if got != wanted {
                tracing::warn!(
                    "capture: gst:{pipeline} gives {}x{} frames, not the configured {}x{}: \
                     using its size (to ask the camera for another mode, put \
                     video/x-raw,width=W,height=H in the pipeline)",
                    got.0,
                    got.1,
                    wanted.0,
                    wanted.1
                );
            }
            Ok(got)
        }
        #[cfg(not(feature = "gstreamer"))]
        {
            let _ = wanted;
            Err(SourceError::NoGstreamer(pipeline.clone()))
        }
    }

    /// Names the source in messages.
    pub fn describe(&self) -> String {
        match self {
            SourceSpec::Synthetic(c) => format!(
                "simulated camera over {} on background {}",
                c.object.name(),
                c.background
            ),
            SourceSpec::Group(g) => format!(
                "simulated camera over {} on background {}",
                g.objects
                    .iter()
                    .map(|o| o.name())
                    .collect::<Vec<_>>()
                    .join(", "),
                g.background
            ),
            SourceSpec::Folder { dir, .. } => format!("folder {}", dir.display()),
            SourceSpec::Mcap(p) => format!("recording {}", p.display()),
            SourceSpec::Gst { pipeline, .. } => format!("gst:{pipeline}"),
        }
    }
}

/// The PNG and JPEG files of `dir`, sorted by name.
fn list_images(dir: &Path) -> Result<Vec<PathBuf>, SourceError> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| SourceError::Folder {
            dir: dir.to_owned(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .is_some_and(|x| x == "png" || x == "jpg" || x == "jpeg")
        })
        .collect();
    v.sort();
    Ok(v)
}

/// The pixels of a produced frame, wherever the source keeps them.
pub enum Pixels {
    /// A synthetic frame (its buffer goes back to the renderer).
    Rendered(Box<Rendered>),
    /// A decoded image.
    Owned(Vec<u8>),
    /// A recorded frame.
    Replay(Box<acch_record::ReplayFrame>),
    /// A GStreamer buffer, mapped (GStreamer's until recycled).
    #[cfg(feature = "gstreamer")]
    Gst(Box<crate::gst::GstPixels>),
}

impl Pixels {
    /// Packed RGB.
    pub fn bytes(&self) -> &[u8] {
        match self {
            Pixels::Rendered(f) => f.image.as_raw(),
            Pixels::Owned(p) => p,
            Pixels::Replay(f) => f.pixels(),
            #[cfg(feature = "gstreamer")]
            Pixels::Gst(f) => f.bytes(),
        }
    }
}

/// A frame from the source, ready to publish.
pub struct Produced {
    /// Everything but the time stamps and the shared-memory location.
    pub header: FrameHeader,
    /// The pixels.
    pub pixels: Pixels,
    /// A recording's own capture time of the frame (its pace), ns.
    pub recorded_ns: Option<u64>,
    /// When a camera captured the frame, CLOCK_MONOTONIC ns (else it is
    /// stamped when published).
    pub captured_ns: Option<u64>,
    /// How long the source took to make it, ns.
    pub taken_ns: u64,
}

enum Kind {
    Synthetic {
        renderer: Box<Renderer>,
        trajectory: Trajectory,
        /// The first frame, the template of every render buffer.
        template: Box<Rendered>,
        intrinsics: Intrinsics,
        seed: u64,
        /// The object's real bounding radius: the renderer's unit, metres.
        radius_m: f64,
        /// How long the shutter is open, seconds.
        shutter_s: f64,
    },
    Group {
        renderer: Box<acch_capture::MultiRenderer>,
        group: Box<SyntheticGroup>,
        intrinsics: Intrinsics,
    },
    Folder {
        dir: PathBuf,
        files: Vec<(PathBuf, Option<acch_capture::labels::LabelRow>)>,
        intrinsics: Intrinsics,
    },
    Mcap {
        path: PathBuf,
        frames: Box<acch_record::ReplayReader>,
    },
    #[cfg(feature = "gstreamer")]
    Gst {
        camera: Box<crate::gst::GstSource>,
        intrinsics: Intrinsics,
    },
}

/// An open source, making frames `first ..` of a `width` x `height` stream.
pub struct Source {
    kind: Kind,
    size: (u32, u32),
    /// Sequence of the next synthetic or folder frame.
    next: u64,
    /// Frames skipped in a row for their size.
    skipped_in_a_row: u64,
    /// Frames skipped for their size.
    pub skipped: u64,
    /// Render buffers handed back for reuse: boxed, as they travel in
    /// [`Pixels::Rendered`], so a buffer moves by its pointer.
    #[allow(clippy::vec_box)]
    spare: Vec<Box<Rendered>>,
}

impl Source {
    /// Whether the frames are rendered (the synthetic camera), not read.
    pub fn renders(&self) -> bool {
        matches!(self.kind, Kind::Synthetic { .. } | Kind::Group { .. })
    }

    /// Opens `spec` for a stream of `size`, starting at frame `first` (a
    /// restarted capture continues where the run is). A recording is read
    /// through once first (every CRC): a truncated or corrupt file fails
    /// here, not halfway through the run.
    pub fn open(spec: &SourceSpec, size: (u32, u32), first: u64) -> Result<Self, SourceError> {
        let kind = match spec {
            SourceSpec::Synthetic(c) => {
                let renderer = Renderer::new(
                    SceneConfig {
                        object: c.object.clone(),
                        background: c.background,
                        intrinsics: c.intrinsics(),
                        effects: acch_capture::Effects {
                            exposure: c.light.0,
                            colour_temp_k: c.light.1,
                            noise_sigma: c.noise_sigma,
                            blur_sigma: c.blur_sigma,
                            ..Default::default()
                        },
                        textures: c.textures,
                        occlusion: 0.0,
                        occluder: None,
                        light_azimuth_deg: 0.0,
                    },
                    c.seed,
                );
                let (lo, hi) = c.elevation_deg;
                let fps = if c.fps > 0.0 { c.fps } else { 30.0 };
                let radius_m = c.object.radius_m();
                let distance = c.distance_m / radius_m;
                let mut trajectory = Trajectory::with_elevation(c.seed, fps, distance, lo, hi)?;
                if c.roll_deg > 0.0 {
                    trajectory = trajectory.with_roll(c.roll_deg)?;
                }
                let template = Box::new(renderer.render(&trajectory.frame(0).view, 0));
                Kind::Synthetic {
                    renderer: Box::new(renderer),
                    trajectory,
                    template,
                    intrinsics: Intrinsics::from(&c.intrinsics()),
                    seed: c.seed,
                    radius_m,
                    shutter_s: c.shutter_s,
                }
            }
            SourceSpec::Group(g) => {
                let mut scene = acch_capture::MultiScene::new(g.objects.clone(), g.background);
                scene.intrinsics = sized_intrinsics(g.width, g.height);
                scene.textures = g.textures;
                Kind::Group {
                    renderer: Box::new(acch_capture::MultiRenderer::new(scene, g.seed)?),
                    intrinsics: Intrinsics::from(&sized_intrinsics(g.width, g.height)),
                    group: Box::new(g.clone()),
                }
            }
            SourceSpec::Folder { dir, calibration } => {
                let labels = dir.join("labels.csv");
                let files: Vec<_> = if labels.exists() {
                    acch_capture::labels::read_labels(&labels)?
                        .into_iter()
                        .map(|r| (dir.join(&r.file), Some(r)))
                        .collect()
                } else {
                    list_images(dir)?.into_iter().map(|p| (p, None)).collect()
                };
                if files.is_empty() {
                    return Err(SourceError::Empty(dir.clone()));
                }
                Kind::Folder {
                    dir: dir.clone(),
                    files,
                    intrinsics: intrinsics_of(calibration, size)?,
                }
            }
            SourceSpec::Mcap(path) => {
                let summary = acch_record::scan(path)?;
                tracing::info!(
                    "capture: replaying {} frames of {}x{} from {}",
                    summary.frames,
                    summary.width,
                    summary.height,
                    path.display()
                );
                Kind::Mcap {
                    frames: Box::new(acch_record::ReplayReader::open(path)?),
                    path: path.clone(),
                }
            }
            #[cfg(feature = "gstreamer")]
            SourceSpec::Gst {
                pipeline,
                calibration,
            } => {
                let intrinsics = intrinsics_of(calibration, size)?;
                Kind::Gst {
                    camera: Box::new(crate::gst::GstSource::open(pipeline, size)?),
                    intrinsics,
                }
            }
            #[cfg(not(feature = "gstreamer"))]
            SourceSpec::Gst { pipeline, .. } => {
                return Err(SourceError::NoGstreamer(pipeline.clone()));
            }
        };
        Ok(Source {
            kind,
            size,
            next: first,
            skipped_in_a_row: 0,
            skipped: 0,
            spare: Vec::new(),
        })
    }

    /// What a camera source lost so far (zero for other sources).
    pub fn camera_counters(&self) -> CameraCounters {
        match &self.kind {
            #[cfg(feature = "gstreamer")]
            Kind::Gst { camera, .. } => camera.counters,
            _ => CameraCounters::default(),
        }
    }

    /// Whether the source makes frames on its own clock, whether or not
    /// they are taken (a live camera); a file or a renderer waits.
    pub fn is_live(&self) -> bool {
        match &self.kind {
            #[cfg(feature = "gstreamer")]
            Kind::Gst { camera, .. } => camera.is_live(),
            _ => false,
        }
    }

    /// A flag that, set from another thread, ends a camera's wait for its
    /// next frame (`None` for sources that never wait).
    pub fn stop_flag(&self) -> Option<Arc<AtomicBool>> {
        match &self.kind {
            #[cfg(feature = "gstreamer")]
            Kind::Gst { camera, .. } => Some(camera.stop_flag()),
            _ => None,
        }
    }

    /// Hands a synthetic frame's buffer back, so the next frame reuses it
    /// (no allocation per frame).
    pub fn recycle(&mut self, pixels: Pixels) {
        if let Pixels::Rendered(b) = pixels {
            self.spare.push(b);
        }
    }

    /// The next frame of the stream's size, skipping (and naming) frames of
    /// another size; `None` when the source has ended. An unreadable input
    /// is an error.
    pub fn next_frame(&mut self) -> Result<Option<Produced>, SourceError> {
        loop {
            let started = now_ns();
            let Some(mut p) = self.make()? else {
                return Ok(None);
            };
            let (w, h) = (
                p.header.envelope.frame.width,
                p.header.envelope.frame.height,
            );
            if (w, h) != self.size {
                // One odd frame must not stop a camera: skip it, say which.
                let (want_w, want_h) = self.size;
                tracing::warn!(
                    "capture: skipping {} ({w}x{h}, the stream is {want_w}x{want_h})",
                    self.name_of(&p)
                );
                self.skipped += 1;
                self.skipped_in_a_row += 1;
                if let Kind::Folder { dir, files, .. } = &self.kind
                    && self.skipped_in_a_row >= files.len() as u64
                {
                    return Err(SourceError::NoneOfSize {
                        dir: dir.clone(),
                        width: want_w,
                        height: want_h,
                    });
                }
                self.recycle(p.pixels);
                continue;
            }
            self.skipped_in_a_row = 0;
            self.next += 1;
            p.taken_ns = now_ns().saturating_sub(started);
            return Ok(Some(p));
        }
    }

    /// Names a frame in warnings.
    fn name_of(&self, p: &Produced) -> String {
        let seq = p.header.envelope.frame.sequence;
        match &self.kind {
            Kind::Synthetic { .. } | Kind::Group { .. } => format!("synthetic frame {seq}"),
            Kind::Folder { files, .. } => files[self.position(files.len())].0.display().to_string(),
            Kind::Mcap { path, .. } => format!("frame {seq} of {}", path.display()),
            #[cfg(feature = "gstreamer")]
            Kind::Gst { .. } => format!("camera frame {seq}"),
        }
    }

    fn position(&self, files: usize) -> usize {
        ((self.next + self.skipped) % files as u64) as usize
    }

    /// Makes the next frame of the source, whatever its size.
    fn make(&mut self) -> Result<Option<Produced>, SourceError> {
        let sequence = self.next;
        let position = self.skipped;
        match &mut self.kind {
            Kind::Synthetic {
                renderer,
                trajectory,
                template,
                intrinsics,
                seed,
                radius_m,
                shutter_s,
            } => {
                let mut buffer = self.spare.pop().unwrap_or_else(|| template.clone());
                renderer.render_moving_into(
                    trajectory.during(sequence, *shutter_s),
                    acch_capture::frame_seed(*seed, sequence as usize),
                    &mut buffer,
                );
                let (w, h) = buffer.image.dimensions();
                let mut header = FrameHeader::rgb(sequence, w, h, *intrinsics);
                let (truth, arm) = metric_truth(&buffer.truth, *radius_m);
                let frame = &mut header.envelope.frame;
                frame.truth = Maybe::Present(truth);
                // The simulated arm's forward kinematics.
                frame.arm = Maybe::Present(arm);
                Ok(Some(Produced {
                    header,
                    pixels: Pixels::Rendered(buffer),
                    recorded_ns: None,
                    captured_ns: None,
                    taken_ns: 0,
                }))
            }
            Kind::Group {
                renderer,
                group,
                intrinsics,
            } => {
                // Every camera of the exposure is valid if its middle one is
                // (the elevation stays within the band).
                let camera = group.camera(sequence, 0.0)?;
                let seed = acch_capture::frame_seed(group.seed, sequence as usize);
                let image = renderer
                    .render_moving_image(|s| group.camera(sequence, s).unwrap_or(camera), seed);
                let (w, h) = image.dimensions();
                Ok(Some(Produced {
                    header: FrameHeader::rgb(sequence, w, h, *intrinsics),
                    pixels: Pixels::Owned(image.into_raw()),
                    recorded_ns: None,
                    captured_ns: None,
                    taken_ns: 0,
                }))
            }
            Kind::Folder {
                files, intrinsics, ..
            } => {
                let n = files.len() as u64;
                let (path, label) = &files[((sequence + position) % n) as usize];
                let img = image::open(path)
                    .map_err(|source| SourceError::Image {
                        path: path.clone(),
                        source,
                    })?
                    .to_rgb8();
                let mut header = FrameHeader::rgb(sequence, img.width(), img.height(), *intrinsics);
                if let Some(l) = label {
                    let view = ViewPose::new(l.theta_deg, l.phi_deg, l.distance_m)?
                        .with_roll(l.roll_deg)?;
                    header.envelope.frame.truth = Maybe::Present(Truth {
                        theta_deg: l.theta_deg,
                        phi_deg: l.phi_deg,
                        distance_m: l.distance_m,
                        roll_deg: view.roll_deg,
                        camera_from_object: view.camera_from_world().to_cols_array(),
                    });
                }
                Ok(Some(Produced {
                    header,
                    pixels: Pixels::Owned(img.into_raw()),
                    recorded_ns: None,
                    captured_ns: None,
                    taken_ns: 0,
                }))
            }
            Kind::Mcap { path, frames } => {
                let Some(f) = frames.next().transpose()? else {
                    tracing::info!("capture: end of {}", path.display());
                    return Ok(None);
                };
                let info = &f.info;
                let mut header = FrameHeader::rgb(
                    info.sequence,
                    info.width,
                    info.height,
                    recorded_intrinsics(info),
                );
                if let Some(t) = &info.truth {
                    header.envelope.frame.truth = Maybe::Present(Truth {
                        theta_deg: t.theta_deg,
                        phi_deg: t.phi_deg,
                        distance_m: t.distance_m,
                        roll_deg: t.roll_deg,
                        camera_from_object: t.camera_from_object,
                    });
                }
                if let Some(a) = info.arm_world_from_camera {
                    header.envelope.frame.arm = Maybe::Present(ArmPose {
                        world_from_camera: a,
                    });
                }
                let recorded_ns = Some(info.capture_ns);
                Ok(Some(Produced {
                    header,
                    pixels: Pixels::Replay(Box::new(f)),
                    recorded_ns,
                    captured_ns: None,
                    taken_ns: 0,
                }))
            }
            #[cfg(feature = "gstreamer")]
            Kind::Gst { camera, intrinsics } => {
                let Some(f) = camera.next_frame()? else {
                    return Ok(None);
                };
                Ok(Some(Produced {
                    header: FrameHeader::rgb(sequence, f.width, f.height, *intrinsics),
                    pixels: Pixels::Gst(Box::new(f.pixels)),
                    recorded_ns: None,
                    captured_ns: Some(f.captured_ns),
                    taken_ns: 0,
                }))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frame `index` of the simulated camera with its shutter open for
    /// `shutter_s`.
    fn synthetic_frame(shutter_s: f64, index: u64) -> Produced {
        let object = Arc::new(Object::builtin("fruitbox").expect("built-in object"));
        let camera = SyntheticCamera {
            distance_m: acch_capture::DEFAULT_DISTANCE * object.radius_m(),
            object,
            background: Background::A,
            textures: acch_capture::TextureSet::HeldOut,
            seed: 2,
            width: 320,
            height: 240,
            fps: 30.0,
            elevation_deg: (45.5, 89.5),
            roll_deg: 0.0,
            light: (1.0, acch_core::light::TRAINING_LIGHT_K),
            shutter_s,
            noise_sigma: 0.0,
            blur_sigma: 0.0,
        };
        let mut source = Source::open(&SourceSpec::Synthetic(camera), (320, 240), index)
            .expect("the synthetic camera opens");
        source.next_frame().expect("a frame").expect("not ended")
    }

    #[test]
    fn an_open_shutter_blurs_the_frame_and_keeps_its_truth() {
        let still = synthetic_frame(0.0, 40);
        let moving = synthetic_frame(1.0 / 30.0, 40);
        let truth = |p: &Produced| p.header.envelope.frame.truth;
        assert!(matches!(truth(&still), Maybe::Present(_)));
        assert_eq!(truth(&still), truth(&moving));
        let changed = still
            .pixels
            .bytes()
            .iter()
            .zip(moving.pixels.bytes())
            .filter(|(a, b)| a != b)
            .count();
        // The camera moves about a degree in a frame: the texture smears,
        // not the whole frame.
        let n = still.pixels.bytes().len();
        assert!(
            changed > n / 20 && changed < n,
            "{changed} of {n} bytes changed"
        );
    }

    /// Frame `index` of the simulated camera circling two objects at 10
    /// fps with its shutter open for `shutter_s`.
    fn group_frame(shutter_s: f64, index: u64) -> Produced {
        let objects = ["fruitbox", "can"]
            .map(|name| Arc::new(Object::builtin(name).expect("built-in object")))
            .to_vec();
        let group = SyntheticGroup {
            objects,
            background: Background::A,
            textures: acch_capture::TextureSet::HeldOut,
            seed: 2,
            width: 320,
            height: 240,
            fps: 10.0,
            elevation_deg: (45.5, 89.5),
            shutter_s,
        };
        let mut source = Source::open(&SourceSpec::Group(group), (320, 240), index)
            .expect("the group camera opens");
        source.next_frame().expect("a frame").expect("not ended")
    }

    /// Sum of the absolute differences between horizontal neighbours.
    fn horizontal_gradient(rgb: &[u8], width: usize) -> u64 {
        rgb.chunks_exact(width * 3)
            .flat_map(|row| row.windows(4).map(|w| w[0].abs_diff(w[3]) as u64))
            .sum()
    }

    #[test]
    fn an_open_shutter_blurs_the_group_along_the_cameras_circle() {
        // At 10 fps with the shutter open all frame long the camera turns
        // 2° about the group in the exposure.
        let still = group_frame(0.0, 40);
        let moving = group_frame(0.1, 40);
        let (a, b) = (still.pixels.bytes(), moving.pixels.bytes());
        assert_eq!(a.len(), b.len());
        let changed = a.iter().zip(b).filter(|(x, y)| x != y).count();
        assert!(
            changed > a.len() / 20,
            "{changed} of {} bytes changed",
            a.len()
        );
        // The camera turns about the group: the frame smears sideways
        // (to 0.75 of the still gradient here).
        let (sharp, smeared) = (horizontal_gradient(a, 320), horizontal_gradient(b, 320));
        assert!(
            (smeared as f64) < 0.9 * sharp as f64,
            "horizontal gradient {smeared} against {sharp} still"
        );
    }
}
