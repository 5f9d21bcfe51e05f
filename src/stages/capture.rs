//! The capture process: synthetic camera or image folder into shared memory.

use super::runner::announce_ready;
use super::{PipelineConfig, WAIT, copy};
use acch_capture::{Background, DEFAULT_DISTANCE, Trajectory};
use acch_ipc::{FrameHeader, ShmLocator, StageId, now_ns, pixel_format};
use anyhow::{Context, Result, anyhow, bail};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// A frame source.
enum Source {
    Synthetic {
        renderer: Box<acch_capture::Renderer>,
        trajectory: Trajectory,
        /// The first frame, the template of every render buffer.
        frame: Box<acch_capture::Rendered>,
        seed: u64,
    },
    Folder {
        files: Vec<(PathBuf, Option<acch_capture::labels::LabelRow>)>,
    },
    /// A recording of `acch run --record`, replayed in order.
    Mcap {
        path: PathBuf,
        frames: Box<acch_record::ReplayReader>,
    },
}

/// How an mcap: replay is paced.
#[derive(Clone, Copy, PartialEq)]
enum Pace {
    /// The recording's own capture times.
    Recorded,
    /// The next frame goes out when the pipeline has finished all but
    /// `IN_FLIGHT - 1` of the frames sent: as fast as it goes, nothing dropped.
    Free,
}

/// Frames a free-running replay lets into the pipeline at once (the frame
/// and result queues hold more, so none is dropped).
const IN_FLIGHT: u64 = 2;
/// A free-running replay stops waiting for a result after this long (a
/// frame a stage dropped must not stall the replay).
const RESULT_WAIT: Duration = Duration::from_secs(2);

/// Runs the capture process: waits for the launcher's start signal, then
/// writes `cfg.frames` frames into shared memory at `cfg.fps` and stays
/// until terminated (subscribers may still hold its samples).
pub fn run_capture(cfg: &PipelineConfig) -> Result<()> {
    let ipc = cfg.ipc("capture")?;
    let output = ipc.frame_output()?;
    let start = ipc.control_listener("start")?;
    let source = match cfg.source.as_str() {
        "synthetic" => {
            let object = acch_capture::Object::builtin(&cfg.object)?;
            let background: Background = cfg.background.parse()?;
            let renderer = sized_renderer(
                std::sync::Arc::new(object),
                background,
                cfg.seed,
                cfg.intrinsics(),
            );
            let distance = cfg.distance.unwrap_or(DEFAULT_DISTANCE);
            let trajectory = Trajectory::new(
                cfg.seed,
                if cfg.fps > 0.0 { cfg.fps } else { 30.0 },
                distance,
            )?;
            let frame = Box::new(renderer.render(&trajectory.frame(0).view, 0));
            Source::Synthetic {
                renderer: Box::new(renderer),
                trajectory,
                frame,
                seed: cfg.seed,
            }
        }
        s if s.starts_with("folder:") => {
            let dir = PathBuf::from(&s["folder:".len()..]);
            let labels = dir.join("labels.csv");
            let files = if labels.exists() {
                acch_capture::labels::read_labels(&labels)?
                    .into_iter()
                    .map(|r| (dir.join(&r.file), Some(r)))
                    .collect::<Vec<_>>()
            } else {
                let mut v: Vec<_> = std::fs::read_dir(&dir)
                    .with_context(|| format!("reading {}", dir.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "png" || x == "jpg"))
                    .map(|p| (p, None))
                    .collect();
                v.sort_by(|a, b| a.0.cmp(&b.0));
                v
            };
            if files.is_empty() {
                bail!("{} holds no images", dir.display());
            }
            Source::Folder { files }
        }
        s if s.starts_with("mcap:") => {
            let path = PathBuf::from(&s["mcap:".len()..]);
            // Read it through once (every CRC): a truncated or corrupt file
            // fails here, before the run starts, not halfway through.
            let summary = acch_record::scan(&path)?;
            tracing::info!(
                "capture: replaying {} frames of {}x{} from {}",
                summary.frames,
                summary.width,
                summary.height,
                path.display()
            );
            Source::Mcap {
                frames: Box::new(acch_record::ReplayReader::open(&path)?),
                path,
            }
        }
        other => bail!("unknown source '{other}': use synthetic, folder:DIR or mcap:FILE"),
    };
    let pace = match (cfg.source.starts_with("mcap:"), cfg.replay.as_str()) {
        (false, _) => None,
        (true, "recorded") => Some(Pace::Recorded),
        (true, "free") => Some(Pace::Free),
        (true, other) => bail!("unknown replay pace '{other}': use recorded or free"),
    };
    // A free-running replay watches the final results to pace itself.
    let done = if pace == Some(Pace::Free) {
        Some(ipc.result_input(StageId::Seeding)?)
    } else {
        None
    };
    // ... and, when a recorder runs, what it has recorded (a replay
    // recorded again must lose nothing): it notifies "recorded" after each
    // result, with the sequence modulo acch_record::RECORDED_IDS as the event id so
    // notifications of different frames do not merge.
    let recorded = if done.is_some() && cfg.record.is_some() {
        Some(ipc.control_listener(acch_record::RECORDED_EVENT)?)
    } else {
        None
    };
    let mut logged = 0u64;
    let (want_w, want_h) = frame_size(cfg)?;
    // The source (rendering, decoding, reading) runs ahead on a thread of
    // its own, which keeps the launcher's CPUs, as a camera exposes and
    // reads out a frame on its own; this thread only publishes, from the
    // stages' CPU, so the wake-up of recognition is a local one.
    let (frames_tx, frames_rx) = std::sync::mpsc::sync_channel::<Produced>(READ_AHEAD);
    let (recycle_tx, recycle_rx) = std::sync::mpsc::channel::<Box<acch_capture::Rendered>>();
    let producer = {
        let k = cfg.intrinsics();
        let (first, frames, source_name) = (cfg.first_frame, cfg.frames, cfg.source.clone());
        let realtime = cfg.realtime_priority > 0;
        std::thread::Builder::new()
            .name("capture-source".into())
            .spawn(move || -> Result<()> {
                if realtime {
                    // Rendering is the camera's work, not the real-time path.
                    acch_ipc::sched::set_normal().context("capture source: normal scheduling")?;
                }
                produce(
                    source,
                    SourceRun {
                        first,
                        frames,
                        size: (want_w, want_h),
                        intrinsics: [k.fx, k.fy, k.cx, k.cy],
                        name: source_name,
                    },
                    &frames_tx,
                    &recycle_rx,
                )
            })
            .context("starting the capture source thread")?
    };
    cfg.pin_stage()?;
    announce_ready(&ipc, StageId::Capture)?;
    // Wait for the launcher: every subscriber is connected.
    let mut go = false;
    while !go && ipc.keep_running() {
        start.timed_wait(|_| go = true, WAIT).or_else(|e| match e {
            iceoryx2::port::listener::ListenerWaitError::InterruptSignal => Ok(0),
            e => Err(anyhow!("waiting for start: {e:?}")),
        })?;
    }
    let mut locator = ShmLocator::new();
    // The copy baseline: connect to every pixel-reading stage's socket (they
    // are bound before the stages announce readiness).
    let mut copies = if cfg.copies_frames()? {
        Some(copy::FrameSender::connect(
            super::FRAME_READERS
                .map(|id| copy::socket_path(cfg, id))
                .as_slice(),
        )?)
    } else {
        None
    };
    let t0 = Instant::now();
    // Frames sent, results seen (free replay). A restarted capture
    // continues where the run is (`first_frame`), so sequence numbers keep
    // growing and the source keeps its place.
    let mut i = cfg.first_frame;
    let mut finished = cfg.first_frame;
    let mut first_capture_ns = None;
    while ipc.keep_running() && (cfg.frames == 0 || i < cfg.frames) {
        if cfg.fps > 0.0 && pace.is_none() {
            let due = t0 + Duration::from_secs_f64((i - cfg.first_frame) as f64 / cfg.fps);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        if let Some(d) = &done {
            let mut since = Instant::now();
            loop {
                let behind_results = i >= finished + IN_FLIGHT;
                let behind_record = recorded.is_some() && i >= logged + IN_FLIGHT;
                if !(behind_results || behind_record) || !ipc.keep_running() {
                    break;
                }
                if behind_results {
                    d.wait(WAIT.min(RESULT_WAIT))?;
                    while d.receive()?.is_some() {
                        finished += 1;
                    }
                } else if let Some(l) = &recorded {
                    l.timed_wait(|_| logged += 1, WAIT).or_else(|e| match e {
                        iceoryx2::port::listener::ListenerWaitError::InterruptSignal => Ok(0),
                        e => Err(anyhow!("waiting for the recorder: {e:?}")),
                    })?;
                }
                if since.elapsed() > RESULT_WAIT {
                    tracing::warn!("capture: no result for {RESULT_WAIT:?}: sending on");
                    finished = finished.max(i + 1 - IN_FLIGHT);
                    logged = logged.max(i + 1 - IN_FLIGHT);
                    since = Instant::now();
                }
            }
        }
        // The source is done (or failed: its error is returned below).
        let Ok(Produced {
            mut header,
            pixels,
            taken_ns,
        }) = frames_rx.recv()
        else {
            break;
        };
        if pace == Some(Pace::Recorded) {
            // The recording's frame times, from the first frame's.
            let first = *first_capture_ns.get_or_insert(header.capture_ns);
            let due = t0 + Duration::from_nanos(header.capture_ns.saturating_sub(first));
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        // The frame exists now (a camera's exposure time stamp); capture's
        // own span is the publishing (rendering or decoding it ran ahead,
        // `taken_ns` long, and is not part of the frame's latency).
        let captured = now_ns();
        header.capture_ns = captured;
        header.trail.captured_ns = captured;
        header.trail.stages[0].received_ns = captured;
        tracing::trace!("frame {}: source took {taken_ns} ns", header.sequence);
        if let Some(tx) = &mut copies {
            // Published = the copy starts; the header follows on iceoryx2
            // with no pixels.
            header.trail.stages[0].published_ns = now_ns();
            tx.send(header.sequence, pixels.bytes())?;
            output.send(&[], |h, _| *h = header)?;
        } else {
            output.send(pixels.bytes(), |h, addr| {
                let loc = locator.locate(addr).unwrap_or_default();
                (header.shm_file, header.shm_offset) = loc;
                header.trail.stages[0].published_ns = now_ns();
                *h = header;
            })?;
        }
        if let Pixels::Rendered(frame) = pixels {
            // Back to the source for the next frame (no allocation per frame).
            let _ = recycle_tx.send(frame);
        }
        i += 1;
    }
    // Stops a source still rendering ahead, then reports how it ended.
    drop(frames_rx);
    let ended = producer
        .join()
        .map_err(|_| anyhow!("the capture source thread panicked"))?;
    // A source that fails (an unreadable image, a corrupt recording) ends
    // the stream; say why.
    ended?;
    tracing::info!("capture: {} frames sent", i - cfg.first_frame);
    while ipc.keep_running() {
        std::thread::sleep(WAIT);
    }
    Ok(())
}

/// Frames the source may have ready beyond the one being published.
const READ_AHEAD: usize = 1;

/// The pixels of a produced frame, wherever the source keeps them.
enum Pixels {
    /// A synthetic frame (its buffer returns to the renderer).
    Rendered(Box<acch_capture::Rendered>),
    /// A decoded image.
    Owned(Vec<u8>),
    /// A recorded frame.
    Replay(acch_record::ReplayFrame),
}

impl Pixels {
    fn bytes(&self) -> &[u8] {
        match self {
            Pixels::Rendered(f) => f.image.as_raw(),
            Pixels::Owned(p) => p,
            Pixels::Replay(f) => f.pixels(),
        }
    }
}

/// A frame from the source, ready to publish.
struct Produced {
    /// Everything but the time stamps and the shared-memory location;
    /// `capture_ns` holds a recording's own time stamp (its pace).
    header: FrameHeader,
    pixels: Pixels,
    /// How long the source took to make it, nanoseconds.
    taken_ns: u64,
}

/// What the source thread needs to know of the run.
struct SourceRun {
    first: u64,
    frames: u64,
    size: (u32, u32),
    intrinsics: [f64; 4],
    name: String,
}

/// The source thread: makes frames `run.first ..` of `run.size` in order
/// and hands them over (blocking while [`READ_AHEAD`] wait); skips frames
/// of another size. Returns when the run's frames are made, the source
/// ends, or the publisher hangs up; an unreadable input is an error.
fn produce(
    mut source: Source,
    run: SourceRun,
    out: &std::sync::mpsc::SyncSender<Produced>,
    recycle: &std::sync::mpsc::Receiver<Box<acch_capture::Rendered>>,
) -> Result<()> {
    let (want_w, want_h) = run.size;
    // Frames made (the sequence of synthetic and folder frames), source
    // position, frames skipped for their size.
    let mut i = run.first;
    let mut index = run.first;
    let mut skipped = 0u64;
    let mut skipped_in_a_row = 0u64;
    while run.frames == 0 || i < run.frames {
        let started = now_ns();
        let mut header = FrameHeader {
            sequence: i,
            pixel_format: pixel_format::RGB8,
            intrinsics: run.intrinsics,
            ..Default::default()
        };
        let position = index;
        index += 1;
        let pixels = match &mut source {
            Source::Synthetic {
                renderer,
                trajectory,
                frame,
                seed,
            } => {
                let view = trajectory.frame(i).view;
                let mut buffer = recycle.try_recv().unwrap_or_else(|_| frame.clone());
                renderer.render_into(
                    &view,
                    crate::cmd::common::frame_seed(*seed, i as usize),
                    &mut buffer,
                );
                let (w, h) = buffer.image.dimensions();
                (header.width, header.height) = (w as u64, h as u64);
                let t = &buffer.truth;
                header.truth = acch_ipc::Truth {
                    valid: 1,
                    theta_deg: t.theta_deg,
                    phi_deg: t.phi_deg,
                    distance: t.distance,
                    camera_from_object: t.world_from_camera.inverse().to_cols_array(),
                };
                // The simulated arm's forward kinematics: where it put the
                // camera (the object frame is the world frame here).
                header.arm = acch_ipc::ArmPose {
                    valid: 1,
                    world_from_camera: t.world_from_camera.to_cols_array(),
                };
                Pixels::Rendered(buffer)
            }
            Source::Folder { files } => {
                let (path, label) = &files[position as usize % files.len()];
                let img = image::open(path)
                    .with_context(|| format!("reading {}", path.display()))?
                    .to_rgb8();
                (header.width, header.height) = (img.width() as u64, img.height() as u64);
                if let Some(l) = label {
                    let view = acch_capture::ViewPose::new(l.theta_deg, l.phi_deg, l.distance)?;
                    header.truth = acch_ipc::Truth {
                        valid: 1,
                        theta_deg: l.theta_deg,
                        phi_deg: l.phi_deg,
                        distance: l.distance,
                        camera_from_object: view.camera_from_world().to_cols_array(),
                    };
                }
                Pixels::Owned(img.into_raw())
            }
            Source::Mcap { path, frames } => {
                let Some(f) = frames.next().transpose()? else {
                    tracing::info!("capture: end of {}", path.display());
                    break;
                };
                let info = &f.info;
                header.sequence = info.sequence;
                header.intrinsics = info.intrinsics;
                header.capture_ns = info.capture_ns;
                (header.width, header.height) = (info.width as u64, info.height as u64);
                if let Some(t) = &info.truth {
                    header.truth = acch_ipc::Truth {
                        valid: 1,
                        theta_deg: t.theta_deg,
                        phi_deg: t.phi_deg,
                        distance: t.distance,
                        camera_from_object: t.camera_from_object,
                    };
                }
                Pixels::Replay(f)
            }
        };
        if (header.width, header.height) != (want_w as u64, want_h as u64) {
            // One odd frame must not stop a camera: skip it, say which.
            skipped += 1;
            skipped_in_a_row += 1;
            tracing::warn!(
                "capture: skipping {} ({}x{}, the stream is {want_w}x{want_h})",
                source_frame_name(&source, position, header.sequence),
                header.width,
                header.height
            );
            if let Source::Folder { files, .. } = &source
                && skipped_in_a_row >= files.len() as u64
            {
                bail!("no image in {} is {want_w}x{want_h}", run.name);
            }
            continue;
        }
        skipped_in_a_row = 0;
        header.stride = header.width * 3;
        let produced = Produced {
            header,
            pixels,
            taken_ns: now_ns().saturating_sub(started),
        };
        if out.send(produced).is_err() {
            break;
        }
        i += 1;
    }
    if skipped > 0 {
        tracing::warn!("capture: {skipped} frames skipped: not {want_w}x{want_h}");
    }
    Ok(())
}

/// Frame size of the configured source (stages size their buffers).
pub fn frame_size(cfg: &PipelineConfig) -> Result<(u32, u32)> {
    if let Some(dir) = cfg.source.strip_prefix("folder:") {
        let mut first: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("reading {dir}"))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "png" || x == "jpg"))
            .collect();
        first.sort();
        let p = first
            .first()
            .ok_or_else(|| anyhow!("{dir} holds no images"))?;
        let (w, h) =
            image::image_dimensions(p).with_context(|| format!("reading {}", p.display()))?;
        return Ok((w, h));
    }
    if let Some(path) = cfg.source.strip_prefix("mcap:") {
        return Ok(acch_record::first_frame_size(std::path::Path::new(path))?);
    }
    Ok((cfg.width, cfg.height))
}

/// Names a source frame in warnings.
fn source_frame_name(source: &Source, position: u64, sequence: u64) -> String {
    match source {
        Source::Synthetic { .. } => format!("synthetic frame {position}"),
        Source::Folder { files, .. } => files[position as usize % files.len()]
            .0
            .display()
            .to_string(),
        Source::Mcap { path, .. } => format!("frame {sequence} of {}", path.display()),
    }
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

/// The synthetic scene's renderer with the given intrinsics.
pub fn sized_renderer(
    object: std::sync::Arc<acch_capture::Object>,
    background: Background,
    scene_seed: u64,
    intrinsics: acch_capture::Intrinsics,
) -> acch_capture::Renderer {
    acch_capture::Renderer::new(
        acch_capture::SceneConfig {
            object,
            background,
            intrinsics,
            effects: Default::default(),
        },
        scene_seed,
    )
}
