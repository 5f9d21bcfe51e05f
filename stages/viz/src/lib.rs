//! Logs what the acch pipeline sees to rerun: the frame with the detection
//! window, ROI and segmentation mask, the match-value response over the
//! view grid (one row per θ slice), θ/φ/confidence against ground truth over
//! time, the seed as a 3-D transform beside the camera, and per-stage
//! latency. The `viz` process (`acch stage viz`) feeds it; nothing here
//! touches IPC.
//!
//! Entity layout (timeline `frame` = sequence, `capture` = capture time):
//!
//! | entity | archetype |
//! | --- | --- |
//! | `world` | view coordinates RDF (the camera's optical frame is the world) |
//! | `world/camera/image` | Pinhole + Image (the frame) |
//! | `world/camera/image/detection`, `.../roi` | Boxes2D |
//! | `world/camera/image/mask` | SegmentationImage (1 = object) |
//! | `world/camera/seed`, `world/camera/truth` | Transform3D + axes + unit box |
//! | `pose/response` | Tensor [θ slice, φ] of match values |
//! | `pose/theta`, `pose/phi`, `pose/confidence`, `truth/theta`, `truth/phi` | Scalars |
//! | `latency/<stage>`, `latency/end_to_end` | Scalars, ms |
//! | `viz/dropped` | Scalars: frames the viewer skipped to keep up |
//!
//! [`plot`] draws the figures of the evaluations and the benchmark as PNG.

pub mod plot;

use rerun::datatypes::{ChannelDatatype, ImageFormat, Quaternion, TensorBuffer, TensorData};
use rerun::{
    AnnotationContext, Boxes2D, Boxes3D, Image, Pinhole, RecordingStream, RecordingStreamBuilder,
    Scalars, SegmentationImage, Tensor, TimeCell, Transform3D, TransformAxes3D, ViewCoordinates,
};
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

/// Arranges the database's views as a grid: one row per θ (a slice of the
/// hemisphere), one column per φ, so the response shows as an image whose
/// rows are θ slices.
#[derive(Clone, Debug, PartialEq)]
pub struct ResponseGrid {
    /// Distinct θ values, ascending (rows).
    pub thetas: Vec<f32>,
    /// Distinct φ values, ascending (columns).
    pub phis: Vec<f32>,
    /// Grid cell (row * phis.len() + column) of every view, in view order.
    cell: Vec<usize>,
}

impl ResponseGrid {
    /// The grid of views given as (θ, φ) degrees in database order.
    pub fn new(views: &[(f32, f32)]) -> ResponseGrid {
        let distinct = |f: fn(&(f32, f32)) -> f32| {
            let mut v: Vec<f32> = views.iter().map(f).collect();
            v.sort_by(f32::total_cmp);
            v.dedup();
            v
        };
        let thetas = distinct(|v| v.0);
        let phis = distinct(|v| v.1);
        let index = |xs: &[f32], x: f32| xs.partition_point(|a| a.total_cmp(&x).is_lt());
        let cell = views
            .iter()
            .map(|&(t, p)| index(&thetas, t) * phis.len() + index(&phis, p))
            .collect();
        ResponseGrid { thetas, phis, cell }
    }

    /// Views in the database.
    pub fn views(&self) -> usize {
        self.cell.len()
    }

    /// Writes `response` (view order) into `out` (rows = θ): cells no view
    /// falls on are NaN.
    pub fn fill(&self, response: &[f32], out: &mut [f32]) -> Result<(), VizError> {
        let cells = self.thetas.len() * self.phis.len();
        if response.len() != self.cell.len() {
            return Err(VizError::Size {
                what: "match-value response",
                got: response.len(),
                expected: self.cell.len(),
            });
        }
        if out.len() != cells {
            return Err(VizError::Size {
                what: "response grid",
                got: out.len(),
                expected: cells,
            });
        }
        out.fill(f32::NAN);
        for (c, r) in self.cell.iter().zip(response) {
            out[*c] = *r;
        }
        Ok(())
    }
}

/// Ground truth of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Truth {
    /// θ, degrees.
    pub theta_deg: f64,
    /// φ, degrees.
    pub phi_deg: f64,
    /// camera_from_object translation.
    pub translation: [f64; 3],
    /// camera_from_object rotation x, y, z, w.
    pub rotation_xyzw: [f64; 4],
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
    /// Network confidence, when rated.
    pub confidence: Option<f64>,
    /// The seed (camera_from_object translation, rotation x, y, z, w), when accepted.
    pub seed: Option<([f64; 3], [f64; 4])>,
    /// Ground truth, when known.
    pub truth: Option<Truth>,
    /// Per stage: name and received -> published, ms.
    pub stage_ms: Vec<(&'static str, f64)>,
    /// Captured -> final result published, ms.
    pub end_to_end_ms: f64,
}

/// Logs observations to one recording stream.
pub struct Logger {
    rec: RecordingStream,
    grid: ResponseGrid,
    cells: Vec<f32>,
    t0_ns: Option<u64>,
    camera: Option<(u32, u32, [f64; 4])>,
}

fn rr<T>(what: &str, r: Result<T, rerun::RecordingStreamError>) -> Result<T, VizError> {
    r.map_err(|e| VizError::Rerun {
        what: what.into(),
        reason: e.to_string(),
    })
}

const IMAGE: &str = "world/camera/image";

impl Logger {
    /// A logger on `rec` for a database whose views are `views` (θ, φ deg);
    /// logs the static parts (coordinate frame, mask classes).
    pub fn new(rec: RecordingStream, views: &[(f32, f32)]) -> Result<Logger, VizError> {
        let grid = ResponseGrid::new(views);
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
                        rerun::Rgba32::from_unmultiplied_rgba(0, 255, 80, 110),
                    ),
                ]),
            ),
        )?;
        Ok(Logger {
            cells: vec![0.0; grid.thetas.len() * grid.phis.len()],
            grid,
            rec,
            t0_ns: None,
            camera: None,
        })
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
                    .with_image_plane_distance(1.0),
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

    /// Logs a segmentation mask (`width * height` bytes, 0/1).
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
                    mask.to_vec(),
                    ImageFormat::segmentation([width, height], ChannelDatatype::U8),
                ),
            ),
        )
    }

    /// Logs the match-value response (one value per view, database order)
    /// as a θ x φ grid.
    pub fn response(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        response: &[f32],
    ) -> Result<(), VizError> {
        self.grid.fill(response, &mut self.cells)?;
        self.at(sequence, capture_ns);
        let shape = [self.grid.thetas.len() as u64, self.grid.phis.len() as u64];
        let data = TensorData::new(shape.to_vec(), TensorBuffer::F32(self.cells.clone().into()));
        rr(
            "response",
            self.rec.log(
                "pose/response",
                &Tensor::new(data).with_dim_names(["theta slice", "phi"]),
            ),
        )
    }

    /// Logs a final result: boxes, θ/φ/confidence, seed, truth, latencies.
    pub fn observation(&mut self, o: &Observation) -> Result<(), VizError> {
        self.at(o.sequence, o.capture_ns);
        let rec = &self.rec;
        let boxes = |b: Option<[u64; 4]>, label: &str, rgb: [u8; 3]| -> Result<(), VizError> {
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
                        .with_colors([rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2])]),
                    ),
                ),
                None => rr(label, rec.log(path, &rerun::Clear::flat())),
            }
        };
        boxes(o.window, "detection", [255, 200, 0])?;
        boxes(o.roi, "roi", [0, 200, 255])?;
        let scalar = |path: &str, v: f64| rr(path, rec.log(path, &Scalars::single(v)));
        if let Some([t, p]) = o.estimate_deg {
            scalar("pose/theta", t)?;
            scalar("pose/phi", p)?;
        }
        if let Some(c) = o.confidence {
            scalar("pose/confidence", c)?;
        }
        let pose = |path: &str, t: [f64; 3], q: [f64; 4], len: f32| -> Result<(), VizError> {
            let t = t.map(|v| v as f32);
            let q = Quaternion::from_xyzw(q.map(|v| v as f32));
            rr(
                path,
                rec.log(path, &Transform3D::from_translation_rotation(t, q)),
            )?;
            rr(path, rec.log(path, &TransformAxes3D::new(len)))?;
            // The object's bounding sphere has radius 1: a unit box.
            rr(
                path,
                rec.log(
                    format!("{path}/bounds"),
                    &Boxes3D::from_half_sizes([[1.0, 1.0, 1.0]]),
                ),
            )
        };
        match o.seed {
            Some((t, q)) => pose("world/camera/seed", t, q, 1.5)?,
            None => rr(
                "seed",
                rec.log("world/camera/seed", &rerun::Clear::recursive()),
            )?,
        }
        if let Some(t) = o.truth {
            scalar("truth/theta", t.theta_deg)?;
            scalar("truth/phi", t.phi_deg)?;
            pose("world/camera/truth", t.translation, t.rotation_xyzw, 1.0)?;
        }
        for (stage, ms) in &o.stage_ms {
            scalar(&format!("latency/{stage}"), *ms)?;
        }
        scalar("latency/end_to_end", o.end_to_end_ms)
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
                .log("viz/dropped", &Scalars::single(dropped as f64)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn the_response_grid_puts_each_theta_slice_on_a_row() {
        // Database order need not be grid order; one cell has no view.
        let views = [
            (30.0, 0.0),
            (30.0, 90.0),
            (60.0, 90.0),
            (60.0, 0.0),
            (90.0, 0.0),
        ];
        let g = ResponseGrid::new(&views);
        assert_eq!(g.thetas, vec![30.0, 60.0, 90.0]);
        assert_eq!(g.phis, vec![0.0, 90.0]);
        let mut out = vec![0.0; 6];
        g.fill(&[1.0, 2.0, 3.0, 4.0, 5.0], &mut out).unwrap();
        assert_eq!(&out[..5], &[1.0, 2.0, 4.0, 3.0, 5.0]);
        assert!(out[5].is_nan());
        let e = g.fill(&[1.0], &mut out).unwrap_err().to_string();
        assert!(e.contains("1 values, expected 5"), "{e}");
    }

    #[test]
    fn a_frame_and_its_result_reach_the_stream() {
        let (rec, storage) = RecordingStreamBuilder::new("acch-test").memory().unwrap();
        let mut l = Logger::new(rec, &[(30.0, 0.0), (30.0, 90.0)]).unwrap();
        l.frame(0, 10, 4, 2, [5.0, 5.0, 1.5, 0.5], &[9; 24])
            .unwrap();
        l.mask((0, 10), (4, 2), &[0, 1, 1, 0, 0, 1, 1, 0]).unwrap();
        l.response(0, 10, &[0.5, 0.7]).unwrap();
        l.observation(&Observation {
            sequence: 0,
            capture_ns: 10,
            window: Some([0, 0, 2, 2]),
            roi: None,
            estimate_deg: Some([30.0, 90.0]),
            confidence: Some(0.9),
            seed: Some(([0.0, 0.0, 5.0], [0.0, 0.0, 0.0, 1.0])),
            truth: Some(Truth::default()),
            stage_ms: vec![("pose", 2.0)],
            end_to_end_ms: 8.0,
        })
        .unwrap();
        let e = l
            .frame(1, 20, 4, 2, [5.0; 4], &[0; 5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame: 5 values, expected 24"), "{e}");
        l.stream().flush_blocking().unwrap();
        let msgs = storage.take();
        // Store info + the static logs + one chunk or more of per-frame data.
        assert!(msgs.len() >= 3, "{} messages", msgs.len());
    }
}
