//! Logs what the acch pipeline sees to rerun, laid out for debugging a
//! pose ([`layout`]): the frame with the detection window, ROI, the
//! segmentation mask as a translucent overlay and the seed's object axes
//! projected into it; the 3-D scene with the camera frustum and the seed,
//! fused and true poses; θ and φ (estimate, fused, truth on one plot per
//! angle), confidence against its threshold with rejected frames marked;
//! the current frame's match-value response as a line over the database
//! views with the θ slices marked ([`response`]); per-stage latency stacked
//! in one plot, and the viewer's drops. The `viz` process (`acch stage
//! viz`) feeds it; nothing here touches IPC.
//!
//! Entity layout (timeline `frame` = sequence, `capture` = capture time):
//!
//! | entity | archetype |
//! | --- | --- |
//! | `world` | view coordinates RDF (the camera's optical frame is the world) |
//! | `world/camera/image` | Pinhole + Image (the frame) |
//! | `world/camera/image/detection`, `.../roi` | Boxes2D |
//! | `world/camera/image/mask` | SegmentationImage (1 = object, translucent) |
//! | `world/camera/image/seed_axes`, `.../truth_axes` | LineStrips2D: object x, y, z axes projected |
//! | `world/camera/seed`, `.../fused`, `.../truth` | Transform3D + axes + box of the object's bounding radius |
//! | `plot/theta/{estimate,fused,truth,rejected}`, `plot/phi/...` | Scalars, degrees |
//! | `plot/confidence/{confidence,threshold,rejected}` | Scalars |
//! | `plot/latency/<n>_<stage>` | Scalars: ms from capture to the stage's publishing (cumulative) |
//! | `plot/dropped` | Scalars: frames the viewer skipped to keep up |
//! | `response/curve`, `response/best`, `response/truth`, `response/axes/*` | LineStrips2D, Points2D: the response plot |
//!
//! [`plot`] draws the figures of the evaluations and the benchmark as PNG.

pub mod layout;
pub mod plot;
pub mod response;

use rerun::components::MarkerShape;
use rerun::datatypes::{ChannelDatatype, ImageFormat, Quaternion};
use rerun::{
    AnnotationContext, Boxes2D, Boxes3D, Color, Image, LineStrips2D, Pinhole, Points2D,
    RecordingStream, RecordingStreamBuilder, Scalars, SegmentationImage, SeriesLines, SeriesPoints,
    TimeCell, Transform3D, TransformAxes3D, ViewCoordinates,
};
use response::ResponsePlot;
use std::path::PathBuf;

/// Why the viewer could not start or log.
#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// The `--rerun` argument is not a sink.
    #[error("bad rerun sink '{0}': use save:FILE.rrd, spawn or connect:URL")]
    BadSink(String),
    /// rerun refused to open the sink or to log.
    #[error("rerun ({what}): {reason}")]
    Rerun {
        /// What was attempted.
        what: String,
        /// rerun's message.
        reason: String,
    },
    /// A frame, mask or response does not have the size its header says.
    #[error("{what}: {got} values, expected {expected}")]
    Size {
        /// Which input.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The length its header implies.
        expected: usize,
    },
}

/// Where the log goes.
#[derive(Clone, Debug, PartialEq)]
pub enum Sink {
    /// An `.rrd` file.
    Save(PathBuf),
    /// A viewer this process starts (`rerun` on the PATH).
    Spawn,
    /// A running viewer's gRPC proxy, e.g. `rerun+http://127.0.0.1:9876/proxy`.
    Connect(String),
}

impl Sink {
    /// Parses `save:FILE.rrd`, `spawn` or `connect:URL` (`connect` alone =
    /// the default local viewer).
    pub fn parse(s: &str) -> Result<Sink, VizError> {
        if let Some(f) = s.strip_prefix("save:").filter(|f| !f.is_empty()) {
            Ok(Sink::Save(PathBuf::from(f)))
        } else if s == "spawn" {
            Ok(Sink::Spawn)
        } else if s == "connect" {
            Ok(Sink::Connect("rerun+http://127.0.0.1:9876/proxy".into()))
        } else if let Some(u) = s.strip_prefix("connect:").filter(|u| !u.is_empty()) {
            Ok(Sink::Connect(u.into()))
        } else {
            Err(VizError::BadSink(s.into()))
        }
    }

    /// Opens a recording stream to this sink.
    pub fn open(&self, app: &'static str) -> Result<RecordingStream, VizError> {
        let b = RecordingStreamBuilder::new(app);
        let r = match self {
            Sink::Save(p) => b.save(p),
            Sink::Spawn => b.spawn(),
            Sink::Connect(u) => b.connect_grpc_opts(u.clone()),
        };
        r.map_err(|e| VizError::Rerun {
            what: format!("opening {self:?}"),
            reason: e.to_string(),
        })
    }
}

/// A rigid pose: `camera_from_object`, metres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pose {
    /// Translation (the object centre in the camera frame).
    pub translation: [f64; 3],
    /// Rotation x, y, z, w.
    pub rotation_xyzw: [f64; 4],
}

impl Pose {
    /// `p` (object frame) in the camera frame.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let [x, y, z, w] = self.rotation_xyzw;
        let n = (x * x + y * y + z * z + w * w).sqrt();
        let (x, y, z, w) = if n > 0.0 {
            (x / n, y / n, z / n, w / n)
        } else {
            (0.0, 0.0, 0.0, 1.0)
        };
        // v' = v + 2w (q × v) + 2 q × (q × v)
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let q = [x, y, z];
        let c = cross(q, p);
        let cc = cross(q, c);
        let t = self.translation;
        [0, 1, 2].map(|i| p[i] + 2.0 * w * c[i] + 2.0 * cc[i] + t[i])
    }

    /// Distance from the camera to the object centre.
    pub fn distance(&self) -> f64 {
        let [x, y, z] = self.translation;
        (x * x + y * y + z * z).sqrt()
    }
}

/// The object's origin and the tips of its x, y, z axes (`len` long),
/// projected through pinhole intrinsics fx, fy, cx, cy (no distortion:
/// the overlay of an undistorted image), in pixels; `None` when any of
/// them is not in front of the camera.
pub fn project_axes(intrinsics: [f64; 4], pose: &Pose, len: f64) -> Option<[[f64; 2]; 4]> {
    let [fx, fy, cx, cy] = intrinsics;
    let points = [
        [0.0, 0.0, 0.0],
        [len, 0.0, 0.0],
        [0.0, len, 0.0],
        [0.0, 0.0, len],
    ];
    let mut out = [[0.0; 2]; 4];
    for (o, p) in out.iter_mut().zip(points) {
        let [x, y, z] = pose.apply(p);
        // NaN fails too.
        if z.is_nan() || z <= 1e-6 {
            return None;
        }
        *o = [fx * x / z + cx, fy * y / z + cy];
    }
    Some(out)
}

/// Ground truth of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Truth {
    /// θ, degrees.
    pub theta_deg: f64,
    /// φ, degrees.
    pub phi_deg: f64,
    /// The true pose.
    pub pose: Pose,
}

/// The seeding stage's fused pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Fused {
    /// Fused θ, φ, degrees.
    pub view_deg: [f64; 2],
    /// Fused pose.
    pub pose: Pose,
}

/// The confidence network's verdict.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rating {
    /// Its confidence.
    pub confidence: f64,
    /// The acceptance threshold.
    pub threshold: f64,
    /// `confidence >= threshold`.
    pub accepted: bool,
}

/// What the pipeline concluded about one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Observation {
    /// Frame number.
    pub sequence: u64,
    /// CLOCK_MONOTONIC ns at capture.
    pub capture_ns: u64,
    /// Detection window x, y, width, height (pixels), when found.
    pub window: Option<[u64; 4]>,
    /// Mask bounding box x, y, width, height, when segmented.
    pub roi: Option<[u64; 4]>,
    /// θ, φ degrees, when estimated.
    pub estimate_deg: Option<[f64; 2]>,
    /// The verdict, when rated.
    pub rating: Option<Rating>,
    /// The seed, when accepted.
    pub seed: Option<Pose>,
    /// The fused pose, once the filter holds one.
    pub fused: Option<Fused>,
    /// Ground truth, when known.
    pub truth: Option<Truth>,
    /// Per stage in pipeline order: name and captured -> that stage
    /// published, ms (cumulative: the last is end to end).
    pub since_capture_ms: Vec<(&'static str, f64)>,
}

/// How big the object is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ObjectSize {
    /// Its bounding radius, metres.
    RadiusM(f64),
    /// Unknown: drawn at `1 / radii` of its distance (the camera's
    /// nominal distance in bounding radii, [`NOMINAL_DISTANCE_RADII`]).
    FromDistance,
}

/// The simulated camera flies at 5 bounding radii (acch-capture's
/// `DEFAULT_DISTANCE`); an object of unknown size is drawn as if it did.
pub const NOMINAL_DISTANCE_RADII: f64 = 5.0;

impl ObjectSize {
    /// The bounding radius to draw an object at `pose` with, metres.
    pub fn radius(self, pose: &Pose) -> f64 {
        match self {
            ObjectSize::RadiusM(r) => r,
            ObjectSize::FromDistance => pose.distance() / NOMINAL_DISTANCE_RADII,
        }
    }
}

/// Logs observations to one recording stream.
pub struct Logger {
    rec: RecordingStream,
    plot: ResponsePlot,
    size: ObjectSize,
    t0_ns: Option<u64>,
    camera: Option<(u32, u32, [f64; 4])>,
    /// The last response logged (sequence, values), to place the truth on it.
    last_response: Option<(u64, Vec<f32>)>,
}

fn rr<T>(what: &str, r: Result<T, rerun::RecordingStreamError>) -> Result<T, VizError> {
    r.map_err(|e| VizError::Rerun {
        what: what.into(),
        reason: e.to_string(),
    })
}

const IMAGE: &str = "world/camera/image";

/// Colours of the layout: one per quantity, the same in every view.
mod colour {
    pub const ESTIMATE: [u8; 3] = [255, 160, 0];
    pub const SEED: [u8; 3] = [255, 160, 0];
    pub const FUSED: [u8; 3] = [0, 200, 255];
    pub const TRUTH: [u8; 3] = [120, 230, 120];
    pub const REJECTED: [u8; 3] = [255, 50, 50];
    pub const THRESHOLD: [u8; 3] = [230, 70, 70];
    pub const CONFIDENCE: [u8; 3] = [240, 240, 240];
    pub const DETECTION: [u8; 3] = [255, 220, 0];
    pub const ROI: [u8; 3] = [0, 200, 255];
    pub const AXIS: [u8; 3] = [140, 140, 140];
    pub const CURVE: [u8; 3] = [120, 180, 255];
    /// Stages, in pipeline order.
    pub const STAGES: [[u8; 3]; 6] = [
        [150, 150, 150],
        [255, 200, 0],
        [80, 220, 120],
        [255, 110, 60],
        [190, 120, 255],
        [0, 200, 255],
    ];
}

fn rgb(c: [u8; 3]) -> Color {
    Color::from_rgb(c[0], c[1], c[2])
}

/// Entity of the cumulative latency series of the `index`-th stage.
fn latency_path(index: usize, stage: &str) -> String {
    format!("plot/latency/{index}_{stage}")
}

impl Logger {
    /// A logger on `rec` for a database whose views are `views` (θ, φ deg,
    /// database order), drawing the object at `size`: sends the layout
    /// ([`layout::blueprint`]) and logs the static parts (coordinate frame,
    /// mask classes, series styles, the response plot's axes).
    pub fn new(
        rec: RecordingStream,
        views: &[(f32, f32)],
        size: ObjectSize,
        stages: &[&str],
    ) -> Result<Logger, VizError> {
        rr("blueprint", rec.send_blueprint_opts(&layout::blueprint()))?;
        rr("world", rec.log_static("world", &ViewCoordinates::RDF()))?;
        rr(
            "mask classes",
            rec.log_static(
                format!("{IMAGE}/mask"),
                &AnnotationContext::new([
                    (
                        0,
                        "background",
                        rerun::Rgba32::from_unmultiplied_rgba(0, 0, 0, 0),
                    ),
                    (
                        1,
                        "object",
                        rerun::Rgba32::from_unmultiplied_rgba(0, 255, 80, 255),
                    ),
                ]),
            ),
        )?;
        let l = Logger {
            plot: ResponsePlot::new(views),
            rec,
            size,
            t0_ns: None,
            camera: None,
            last_response: None,
        };
        l.log_styles(stages)?;
        l.log_response_axes()?;
        Ok(l)
    }

    /// Names, colours and markers of the time series (static).
    fn log_styles(&self, stages: &[&str]) -> Result<(), VizError> {
        let rec = &self.rec;
        let line = |path: &str, name: &str, c: [u8; 3], width: f32| {
            rr(
                path,
                rec.log_static(
                    path,
                    &SeriesLines::new()
                        .with_names([name])
                        .with_colors([rgb(c)])
                        .with_widths([width]),
                ),
            )
        };
        let marks = |path: &str, name: &str| {
            rr(
                path,
                rec.log_static(
                    path,
                    &SeriesPoints::new()
                        .with_names([name])
                        .with_colors([rgb(colour::REJECTED)])
                        .with_markers([MarkerShape::Cross])
                        .with_marker_sizes([4.0]),
                ),
            )
        };
        for angle in ["theta", "phi"] {
            line(
                &format!("plot/{angle}/estimate"),
                "estimate",
                colour::ESTIMATE,
                1.5,
            )?;
            line(&format!("plot/{angle}/fused"), "fused", colour::FUSED, 2.0)?;
            line(&format!("plot/{angle}/truth"), "truth", colour::TRUTH, 1.5)?;
            marks(&format!("plot/{angle}/rejected"), "rejected")?;
        }
        line(
            "plot/confidence/confidence",
            "confidence",
            colour::CONFIDENCE,
            1.5,
        )?;
        line(
            "plot/confidence/threshold",
            "threshold",
            colour::THRESHOLD,
            2.0,
        )?;
        marks("plot/confidence/rejected", "rejected")?;
        for (i, stage) in stages.iter().enumerate() {
            // The gap below a line is that stage's hop and processing.
            let name = if i + 1 == stages.len() {
                format!("{stage} = end to end")
            } else {
                format!("{stage} published")
            };
            let c = colour::STAGES[i % colour::STAGES.len()];
            line(&latency_path(i, stage), &name, c, 1.5)?;
        }
        line("plot/dropped", "dropped", colour::REJECTED, 1.5)
    }

    /// The response plot's frame, grid, tick labels and θ slices (static:
    /// they depend on the database only).
    fn log_response_axes(&self) -> Result<(), VizError> {
        let rec = &self.rec;
        let p = &self.plot;
        let (x0, x1) = (-response::DX, p.width() + response::DX);
        let grey = rgb(colour::AXIS);
        let ticks = [0.0f32, 0.25, 0.5, 0.75, 1.0];
        let mut strips: Vec<Vec<[f32; 2]>> = vec![vec![
            [x0, ResponsePlot::y(1.0)],
            [x0, ResponsePlot::y(0.0)],
            [x1, ResponsePlot::y(0.0)],
        ]];
        strips.extend(
            ticks[1..]
                .iter()
                .map(|&v| vec![[x0, ResponsePlot::y(v)], [x1, ResponsePlot::y(v)]]),
        );
        rr(
            "response axes",
            rec.log_static(
                "response/axes/grid",
                &LineStrips2D::new(strips)
                    .with_colors([Color::from_unmultiplied_rgba(140, 140, 140, 90)])
                    .with_radii([0.4]),
            ),
        )?;
        let label_points = |path: &str, at: Vec<[f32; 2]>, labels: Vec<String>, c: Color| {
            rr(
                path,
                rec.log_static(
                    path,
                    &Points2D::new(at)
                        .with_radii([0.5])
                        .with_colors([c])
                        .with_labels(labels)
                        .with_show_labels(true),
                ),
            )
        };
        label_points(
            "response/axes/y_ticks",
            ticks
                .iter()
                .map(|&v| [x0 - 4.0 * response::DX, ResponsePlot::y(v)])
                .collect(),
            ticks.iter().map(|v| format!("{v:.2}")).collect(),
            grey,
        )?;
        let seps = p.separators();
        if !seps.is_empty() {
            rr(
                "response slices",
                rec.log_static(
                    "response/axes/slices",
                    &LineStrips2D::new(seps)
                        .with_colors([Color::from_unmultiplied_rgba(200, 200, 200, 160)])
                        .with_radii([0.6]),
                ),
            )?;
        }
        let mid = |s: &response::Slice| {
            ResponsePlot::x(s.start) + (s.len as f32 - 1.0) * response::DX / 2.0
        };
        label_points(
            "response/axes/slice_labels",
            p.slices
                .iter()
                .map(|s| [mid(s), ResponsePlot::y(1.0) - 14.0])
                .collect(),
            p.slices
                .iter()
                .map(|s| format!("θ {}°", s.theta_deg))
                .collect(),
            Color::from_rgb(220, 220, 220),
        )?;
        label_points(
            "response/axes/x_ticks",
            p.slices
                .iter()
                .map(|s| [ResponsePlot::x(s.start), ResponsePlot::y(0.0) + 12.0])
                .collect(),
            p.slices.iter().map(|s| s.start.to_string()).collect(),
            grey,
        )?;
        label_points(
            "response/axes/x_title",
            vec![[p.width() / 2.0, ResponsePlot::y(0.0) + 32.0]],
            vec!["database view index (θ slice by θ slice, φ ascending); y: match value".into()],
            grey,
        )
    }

    /// The stream (to flush it).
    pub fn stream(&self) -> &RecordingStream {
        &self.rec
    }

    fn at(&mut self, sequence: u64, capture_ns: u64) {
        let t0 = *self.t0_ns.get_or_insert(capture_ns);
        self.rec.set_time_sequence("frame", sequence as i64);
        self.rec.set_time(
            "capture",
            TimeCell::from_duration_nanos(capture_ns.saturating_sub(t0) as i64),
        );
    }

    /// Logs a frame (packed rgb8) and, when they change, the intrinsics
    /// fx, fy, cx, cy.
    pub fn frame(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        width: u32,
        height: u32,
        intrinsics: [f64; 4],
        rgb: &[u8],
    ) -> Result<(), VizError> {
        let expected = width as usize * height as usize * 3;
        if rgb.len() != expected {
            return Err(VizError::Size {
                what: "frame",
                got: rgb.len(),
                expected,
            });
        }
        self.at(sequence, capture_ns);
        if self.camera != Some((width, height, intrinsics)) {
            let [fx, fy, cx, cy] = intrinsics.map(|v| v as f32);
            rr(
                "pinhole",
                self.rec.log(
                    IMAGE,
                    &Pinhole::from_focal_length_and_resolution(
                        [fx, fy],
                        [width as f32, height as f32],
                    )
                    .with_principal_point([cx, cy])
                    .with_image_plane_distance(0.15),
                ),
            )?;
            self.camera = Some((width, height, intrinsics));
        }
        rr(
            "frame",
            self.rec
                .log(IMAGE, &Image::from_rgb24(rgb.to_vec(), [width, height])),
        )
    }

    /// Logs a segmentation mask (`width * height` bytes, non-zero = object:
    /// the segmenter writes 255) as class 1 over class 0.
    pub fn mask(
        &mut self,
        (sequence, capture_ns): (u64, u64),
        (width, height): (u32, u32),
        mask: &[u8],
    ) -> Result<(), VizError> {
        let expected = width as usize * height as usize;
        if mask.len() != expected {
            return Err(VizError::Size {
                what: "mask",
                got: mask.len(),
                expected,
            });
        }
        self.at(sequence, capture_ns);
        rr(
            "mask",
            self.rec.log(
                format!("{IMAGE}/mask"),
                &SegmentationImage::new(
                    mask.iter().map(|&v| u8::from(v != 0)).collect::<Vec<u8>>(),
                    ImageFormat::segmentation([width, height], ChannelDatatype::U8),
                )
                // Translucent: the object stays visible under it.
                .with_opacity(0.4),
            ),
        )
    }

    /// Logs the match-value response (one value per view, database order)
    /// as a line over the view index, the best view marked.
    pub fn response(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        response: &[f32],
    ) -> Result<(), VizError> {
        let Some(curve) = self.plot.curve(response) else {
            return Err(VizError::Size {
                what: "match-value response",
                got: response.len(),
                expected: self.plot.views(),
            });
        };
        self.at(sequence, capture_ns);
        rr(
            "response",
            self.rec.log(
                "response/curve",
                &LineStrips2D::new([curve])
                    .with_colors([rgb(colour::CURVE)])
                    .with_radii([0.8]),
            ),
        )?;
        if let Some(best) = ResponsePlot::best(response) {
            let (t, p) = self.plot.view(best).unwrap_or_default();
            rr(
                "best view",
                self.rec.log(
                    "response/best",
                    &Points2D::new([[ResponsePlot::x(best), ResponsePlot::y(response[best])]])
                        .with_radii([3.0])
                        .with_colors([rgb(colour::ESTIMATE)])
                        .with_labels([format!("best {best}: θ {t}° φ {p}° {:.3}", response[best])])
                        .with_show_labels(true),
                ),
            )?;
        }
        match &mut self.last_response {
            Some((s, v)) => {
                *s = sequence;
                v.clear();
                v.extend_from_slice(response);
            }
            None => self.last_response = Some((sequence, response.to_vec())),
        }
        Ok(())
    }

    /// The truth's view on the response plot, when this frame's response
    /// was logged.
    fn truth_on_response(&self, o: &Observation) -> Result<(), VizError> {
        let path = "response/truth";
        let marked = o.truth.and_then(|t| {
            let (seq, values) = self.last_response.as_ref()?;
            (*seq == o.sequence).then_some(())?;
            let i = self.plot.nearest_view(t.theta_deg, t.phi_deg)?;
            Some((i, values[i]))
        });
        match marked {
            Some((i, v)) => rr(
                path,
                self.rec.log(
                    path,
                    &Points2D::new([[ResponsePlot::x(i), ResponsePlot::y(v)]])
                        .with_radii([3.0])
                        .with_colors([rgb(colour::TRUTH)])
                        .with_labels([format!("truth {i}")])
                        .with_show_labels(true),
                ),
            ),
            None => rr(path, self.rec.log(path, &rerun::Clear::flat())),
        }
    }

    /// Logs a final result: boxes and axes on the image, poses in 3-D,
    /// θ/φ/confidence against truth and threshold, latencies.
    pub fn observation(&mut self, o: &Observation) -> Result<(), VizError> {
        self.at(o.sequence, o.capture_ns);
        self.truth_on_response(o)?;
        let rec = &self.rec;
        let boxes = |b: Option<[u64; 4]>, label: &str, c: [u8; 3]| -> Result<(), VizError> {
            let path = format!("{IMAGE}/{label}");
            match b {
                Some([x, y, w, h]) => rr(
                    label,
                    rec.log(
                        path,
                        &Boxes2D::from_mins_and_sizes(
                            [[x as f32, y as f32]],
                            [[w as f32, h as f32]],
                        )
                        .with_labels([label])
                        .with_colors([rgb(c)])
                        .with_radii([1.5]),
                    ),
                ),
                None => rr(label, rec.log(path, &rerun::Clear::flat())),
            }
        };
        boxes(o.window, "detection", colour::DETECTION)?;
        boxes(o.roi, "roi", colour::ROI)?;
        let scalar = |path: &str, v: f64| rr(path, rec.log(path, &Scalars::single(v)));
        let rejected = o.rating.is_some_and(|r| !r.accepted);
        if let Some([t, p]) = o.estimate_deg {
            scalar("plot/theta/estimate", t)?;
            scalar("plot/phi/estimate", p)?;
            if rejected {
                scalar("plot/theta/rejected", t)?;
                scalar("plot/phi/rejected", p)?;
            }
        }
        if let Some(r) = o.rating {
            scalar("plot/confidence/confidence", r.confidence)?;
            scalar("plot/confidence/threshold", r.threshold)?;
            if rejected {
                scalar("plot/confidence/rejected", r.confidence)?;
            }
        }
        if let Some(f) = o.fused {
            scalar("plot/theta/fused", f.view_deg[0])?;
            scalar("plot/phi/fused", f.view_deg[1])?;
        }
        if let Some(t) = o.truth {
            scalar("plot/theta/truth", t.theta_deg)?;
            scalar("plot/phi/truth", t.phi_deg)?;
        }
        let size = self.size;
        let pose3d = |name: &str, pose: Option<Pose>, c: [u8; 3], axes: f64| {
            let path = format!("world/camera/{name}");
            let Some(pose) = pose else {
                return rr(name, rec.log(path, &rerun::Clear::recursive()));
            };
            let r = size.radius(&pose);
            let t = pose.translation.map(|v| v as f32);
            let q = Quaternion::from_xyzw(pose.rotation_xyzw.map(|v| v as f32));
            rr(
                name,
                rec.log(path.as_str(), &Transform3D::from_translation_rotation(t, q)),
            )?;
            rr(
                name,
                rec.log(path.as_str(), &TransformAxes3D::new((axes * r) as f32)),
            )?;
            // A cube around the object's bounding sphere.
            rr(
                name,
                rec.log(
                    format!("{path}/bounds"),
                    &Boxes3D::from_half_sizes([[r as f32; 3]])
                        .with_colors([rgb(c)])
                        .with_labels([name]),
                ),
            )
        };
        pose3d("seed", o.seed, colour::SEED, 1.5)?;
        pose3d("fused", o.fused.map(|f| f.pose), colour::FUSED, 1.2)?;
        pose3d("truth", o.truth.map(|t| t.pose), colour::TRUTH, 1.0)?;
        self.image_axes("seed_axes", o.seed, 2.5, 255)?;
        self.image_axes("truth_axes", o.truth.map(|t| t.pose), 1.0, 150)?;
        for (i, (stage, ms)) in o.since_capture_ms.iter().enumerate() {
            scalar(&latency_path(i, stage), *ms)?;
        }
        Ok(())
    }

    /// The object's axes (x red, y green, z blue, one bounding radius
    /// long) projected into the image.
    fn image_axes(
        &self,
        name: &str,
        pose: Option<Pose>,
        radius: f32,
        alpha: u8,
    ) -> Result<(), VizError> {
        let path = format!("{IMAGE}/{name}");
        let projected = match (pose, self.camera) {
            (Some(p), Some((_, _, k))) => project_axes(k, &p, self.size.radius(&p)),
            _ => None,
        };
        let Some(px) = projected else {
            return rr(name, self.rec.log(path, &rerun::Clear::flat()));
        };
        let px = px.map(|[x, y]| [x as f32, y as f32]);
        let strips = [[px[0], px[1]], [px[0], px[2]], [px[0], px[3]]];
        rr(
            name,
            self.rec.log(
                path,
                &LineStrips2D::new(strips)
                    .with_colors([
                        Color::from_unmultiplied_rgba(255, 40, 40, alpha),
                        Color::from_unmultiplied_rgba(40, 230, 40, alpha),
                        Color::from_unmultiplied_rgba(60, 120, 255, alpha),
                    ])
                    .with_radii([radius]),
            ),
        )
    }

    /// Logs how many frames the viewer has skipped so far.
    pub fn dropped(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        dropped: u64,
    ) -> Result<(), VizError> {
        self.at(sequence, capture_ns);
        rr(
            "dropped",
            self.rec
                .log("plot/dropped", &Scalars::single(dropped as f64)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rerun::log::{Chunk, LogMsg};
    use std::collections::BTreeSet;

    #[test]
    fn sinks_parse_and_bad_ones_are_named() {
        assert_eq!(
            Sink::parse("save:/tmp/a.rrd").unwrap(),
            Sink::Save("/tmp/a.rrd".into())
        );
        assert_eq!(Sink::parse("spawn").unwrap(), Sink::Spawn);
        assert_eq!(
            Sink::parse("connect:rerun+http://1.2.3.4:9876/proxy").unwrap(),
            Sink::Connect("rerun+http://1.2.3.4:9876/proxy".into())
        );
        for bad in ["", "save:", "connect:", "file.rrd", "spawnx"] {
            let e = Sink::parse(bad).unwrap_err().to_string();
            assert!(e.contains(&format!("'{bad}'")), "{e}");
        }
    }

    #[test]
    fn axes_project_through_the_pinhole() {
        // Object 2 m ahead, rotated 90° about the camera's z: its x axis
        // points along the camera's y (down the image).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let pose = Pose {
            translation: [0.0, 0.0, 2.0],
            rotation_xyzw: [0.0, 0.0, h, h],
        };
        let k = [100.0, 100.0, 320.0, 240.0];
        let px = project_axes(k, &pose, 0.5).unwrap();
        let near =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9;
        assert!(near(px[0], [320.0, 240.0]), "{px:?}");
        assert!(near(px[1], [320.0, 265.0]), "x tip {px:?}");
        assert!(near(px[2], [295.0, 240.0]), "y tip {px:?}");
        // The z tip is 0.5 m further away: it projects onto the centre.
        assert!(near(px[3], [320.0, 240.0]), "z tip {px:?}");
        let behind = Pose {
            translation: [0.0, 0.0, -2.0],
            ..pose
        };
        assert!(project_axes(k, &behind, 0.5).is_none());
    }

    /// What reached the sink, decoded.
    #[derive(Default)]
    struct Sent {
        /// Entity paths with data on the timelines (not static).
        temporal: BTreeSet<String>,
        /// Entity paths with any data.
        all: BTreeSet<String>,
        /// The blueprint's view origins.
        origins: Vec<String>,
        /// Whether a blueprint was made the default.
        default: bool,
    }

    fn sent(msgs: &[LogMsg]) -> Sent {
        let mut s = Sent::default();
        for m in msgs {
            match m {
                LogMsg::ArrowMsg(store, arrow) => {
                    let chunk = Chunk::from_arrow_msg(arrow).unwrap();
                    if store.kind() == rerun::StoreKind::Recording {
                        // Entity paths print with a leading slash.
                        let path = chunk
                            .entity_path()
                            .to_string()
                            .trim_start_matches('/')
                            .to_owned();
                        if !chunk.is_static() {
                            s.temporal.insert(path.clone());
                        }
                        s.all.insert(path);
                    } else {
                        for batch in chunk
                            .iter_component::<rerun::blueprint::components::ViewOrigin>(
                                "ViewBlueprint:space_origin".into(),
                            )
                        {
                            s.origins.extend(
                                batch
                                    .iter()
                                    .map(|o| o.0.to_string().trim_start_matches('/').to_owned()),
                            );
                        }
                    }
                }
                LogMsg::BlueprintActivationCommand(c) => s.default |= c.make_default,
                LogMsg::SetStoreInfo(_) => {}
            }
        }
        s
    }

    #[test]
    fn every_view_of_the_layout_shows_what_the_logger_logs() {
        let (rec, storage) = RecordingStreamBuilder::new("acch-test").memory().unwrap();
        let views = [(45.0, 0.0), (45.0, 180.0), (85.0, 0.0), (85.0, 180.0)];
        let stages = ["capture", "pose", "seeding"];
        let mut l = Logger::new(rec, &views, ObjectSize::RadiusM(0.2), &stages).unwrap();
        let k = [500.0, 500.0, 2.0, 1.0];
        l.frame(0, 10, 4, 2, k, &[9; 24]).unwrap();
        l.mask((0, 10), (4, 2), &[0, 1, 1, 0, 0, 1, 1, 0]).unwrap();
        l.response(0, 10, &[0.5, 0.7, 0.2, 0.1]).unwrap();
        let pose = Pose {
            translation: [0.0, 0.0, 1.0],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        };
        l.observation(&Observation {
            sequence: 0,
            capture_ns: 10,
            window: Some([0, 0, 2, 2]),
            roi: None,
            estimate_deg: Some([45.0, 180.0]),
            // Rejected: below its threshold.
            rating: Some(Rating {
                confidence: 0.3,
                threshold: 0.8,
                accepted: false,
            }),
            seed: Some(pose),
            fused: Some(Fused {
                view_deg: [46.0, 178.0],
                pose,
            }),
            truth: Some(Truth {
                theta_deg: 44.0,
                phi_deg: 179.0,
                pose,
            }),
            since_capture_ms: vec![("capture", 1.0), ("pose", 3.0), ("seeding", 4.0)],
        })
        .unwrap();
        l.dropped(0, 10, 0).unwrap();
        let e = l
            .frame(1, 20, 4, 2, [5.0; 4], &[0; 5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame: 5 values, expected 24"), "{e}");
        let e = l.response(1, 20, &[0.5]).unwrap_err().to_string();
        assert!(e.contains("1 values, expected 4"), "{e}");
        l.stream().flush_blocking().unwrap();
        let s = sent(&storage.take());

        // The blueprint reached the sink, as the default, with every view.
        assert!(s.default, "no blueprint activation made it the default");
        let mut want: Vec<String> = layout::PANELS.iter().map(|p| p.origin.into()).collect();
        let mut got = s.origins.clone();
        want.sort();
        got.sort();
        assert_eq!(got, want);
        let paths = &s.all;
        for origin in &s.origins {
            let under = paths
                .iter()
                .any(|p| p == origin || p.starts_with(&format!("{origin}/")));
            assert!(under, "view {origin} shows nothing; logged: {paths:?}");
        }
        // Related series share a plot: each under its view's origin.
        for p in [
            "world/camera/image/mask",
            "world/camera/image/seed_axes",
            "world/camera/image/truth_axes",
            "world/camera/seed/bounds",
            "world/camera/fused/bounds",
            "world/camera/truth/bounds",
            "plot/theta/estimate",
            "plot/theta/fused",
            "plot/theta/truth",
            "plot/theta/rejected",
            "plot/phi/fused",
            "plot/confidence/threshold",
            "plot/confidence/rejected",
            "plot/latency/0_capture",
            "plot/latency/2_seeding",
            "response/curve",
            "response/best",
            "response/truth",
        ] {
            assert!(s.temporal.contains(p), "{p} not logged: {:?}", s.temporal);
        }
        // The response plot's axes depend on the database only: static.
        for p in ["response/axes/slices", "response/axes/slice_labels"] {
            assert!(
                s.all.contains(p) && !s.temporal.contains(p),
                "{p}: {:?}",
                s.all
            );
        }
    }

    #[test]
    fn an_accepted_frame_marks_nothing_rejected_and_no_truth_means_no_truth_marker() {
        let (rec, storage) = RecordingStreamBuilder::new("acch-test").memory().unwrap();
        let mut l = Logger::new(rec, &[(45.0, 0.0)], ObjectSize::FromDistance, &["pose"]).unwrap();
        l.response(3, 10, &[0.9]).unwrap();
        l.observation(&Observation {
            sequence: 3,
            capture_ns: 10,
            estimate_deg: Some([45.0, 0.0]),
            rating: Some(Rating {
                confidence: 0.9,
                threshold: 0.8,
                accepted: true,
            }),
            ..Default::default()
        })
        .unwrap();
        l.stream().flush_blocking().unwrap();
        let paths = sent(&storage.take()).temporal;
        assert!(paths.contains("plot/confidence/confidence"), "{paths:?}");
        for p in [
            "plot/confidence/rejected",
            "plot/theta/rejected",
            "plot/theta/truth",
        ] {
            assert!(!paths.contains(p), "{p} logged for an accepted frame");
        }
    }
}
