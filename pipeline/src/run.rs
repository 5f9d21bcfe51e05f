//! A whole run, by either executor: every stage as a process under the
//! [`supervisor`](crate::supervisor) (the default), or the stages chained
//! in this process ([`Chain`]). Both read the same configuration, the same
//! sources and the same stages, and report the same [`RunSummary`].

use crate::chain::{Chain, Pacing, run_source};
use crate::config::{ConfigError, Pace, PipelineConfig};
use crate::json::{JsonLines, ZenohSink};
use crate::multi::MultiChain;
use crate::node::{NodeError, READY, START};
use crate::observe::{Each, Observe, ObserveError, Observer};
use crate::observers::{RunRecording, Viewing};
use crate::source::Source;
use crate::stages::{BuildError, Seeded};
use crate::streams;
use crate::summary::{Outcomes, Percentiles, Samples, StageLatency};
use crate::supervisor::{
    ProcessUsage, Restart, RestartPolicy, RssSample, Spawn, SuperviseError, Supervisor, rss_trend,
    self_usage, status_field,
};
use crate::wire::{Hop, STAGES, StageId};
use acch_ipc::sched::StageCpus;
use acch_ipc::{IpcError, Wake, remove_stale_resources};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How a run is watched and reported, besides its configuration.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Give up when no result arrives for this long.
    pub stall_timeout: Duration,
    /// Sample every process's resident memory this often.
    pub rss_every: Duration,
    /// Keep every frame's latencies in the summary.
    pub samples: bool,
    /// Write every result as a line of JSON here.
    pub results: Option<PathBuf>,
    /// Publish results and seeds on zenoh (the seeding stage does as a
    /// process; in one process the chain does when this is set).
    pub zenoh: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            stall_timeout: Duration::from_secs(20),
            rss_every: Duration::from_secs(10),
            samples: false,
            results: None,
            zenoh: true,
        }
    }
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The configuration is unusable.
    #[error("invalid pipeline configuration")]
    Config(#[from] ConfigError),
    /// The stages could not be built.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// A stage process failed in this process (the in-process run).
    #[error(transparent)]
    Node(#[from] NodeError),
    /// iceoryx2 or zenoh failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// An observer failed.
    #[error(transparent)]
    Observe(#[from] ObserveError),
    /// The source failed.
    #[error(transparent)]
    Source(#[from] crate::source_error::SourceError),
    /// Streaming through the chain failed.
    #[error(transparent)]
    Stream(#[from] crate::chain::RunSourceError),
    /// A child process could not be kept running.
    #[error(transparent)]
    Supervise(#[from] SuperviseError),
    /// Placement, scheduling or the CPU latency request was refused.
    #[error("{what}")]
    Sched {
        /// What was asked for.
        what: String,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// Not every process announced itself in time.
    #[error("not ready after {secs} s: {missing:?}")]
    NotReady {
        /// How long it waited.
        secs: u64,
        /// Who did not announce itself.
        missing: Vec<&'static str>,
    },
    /// A stop signal came while starting.
    #[error("interrupted while starting")]
    Interrupted,
    /// Several objects asked of the stage processes.
    #[error(
        "objects.list = [{0}]: several objects run in one process only (acch run --in-process); \
         the stage processes carry one object"
    )]
    SeveralObjects(String),
}

impl From<acch_ipc::OpenError> for RunError {
    fn from(e: acch_ipc::OpenError) -> Self {
        RunError::Ipc(e.into())
    }
}
impl From<acch_ipc::NodeError> for RunError {
    fn from(e: acch_ipc::NodeError) -> Self {
        RunError::Ipc(e.into())
    }
}
impl From<acch_ipc::WaitError> for RunError {
    fn from(e: acch_ipc::WaitError) -> Self {
        RunError::Ipc(e.into())
    }
}
impl From<acch_ipc::ReceiveError> for RunError {
    fn from(e: acch_ipc::ReceiveError) -> Self {
        RunError::Ipc(e.into())
    }
}
impl From<acch_ipc::SendError> for RunError {
    fn from(e: acch_ipc::SendError) -> Self {
        RunError::Ipc(e.into())
    }
}

/// What a run reports (`acch run --json`).
#[derive(Serialize, Debug)]
pub struct RunSummary {
    /// The object.
    pub object: String,
    /// The source, as configured.
    pub source: String,
    /// `processes` or `in-process`.
    pub mode: &'static str,
    /// Frames asked for (0: until the source ends).
    pub frames_requested: u64,
    /// Frame rate asked for (0: free-running).
    pub fps_target: f64,
    /// Results per second of streaming.
    pub fps_achieved: f64,
    /// Whether estimates were rated (an unrated run accepts nothing).
    pub unrated: bool,
    /// What the stages made of the frames, and how right they were.
    #[serde(flatten)]
    pub outcomes: Outcomes,
    /// Captured -> result published by seeding (the zenoh put follows).
    pub end_to_end: Percentiles,
    /// Per stage: the hop into it and its processing.
    pub stages: Vec<StageLatency>,
    /// Frame reads by recognition.
    pub frame_reads: u64,
    /// Reads that found the pixels at capture's own shared-memory file and
    /// offset: the frame was not copied.
    pub frame_reads_in_place: u64,
    /// Bytes of frames published (written once by capture).
    pub frame_bytes_published: u64,
    /// How frames reached recognition: `shm`, `copy` or `in-process`.
    pub transport: String,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames requested that produced no result.
    pub dropped: u64,
    /// Results that repeated an earlier sequence (ignored; should be 0).
    pub duplicates: u64,
    /// CPU and peak memory of every process.
    pub processes: Vec<ProcessUsage>,
    /// The processes first started, (name, pid).
    pub pids: Vec<(&'static str, u32)>,
    /// Stages that died during the run and were restarted.
    pub restarts: Vec<Restart>,
    /// Dead iceoryx2 nodes cleaned while the run went on.
    pub stale_nodes_removed_during_run: usize,
    /// Dead iceoryx2 nodes cleaned after the run (should be 0).
    pub stale_nodes_removed: usize,
    /// Resident memory of every child, sampled every `rss_every`.
    pub rss: Vec<RssSample>,
    /// First, last and largest of those samples per process.
    pub rss_trend: Vec<crate::supervisor::RssTrend>,
    /// What each stage counted (a stage process writes them when it
    /// stops; a killed one leaves none).
    pub stage_counters: Vec<serde_json::Value>,
    /// Where the processes ran (`run.stage_cpus`); null when not placed.
    pub placement: Option<acch_ipc::sched::Placement>,
    /// The CPU latency request held during the run, µs (null: none).
    pub cpu_latency_us: Option<u32>,
    /// Every frame's latencies (with `samples`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub samples: Option<Samples>,
    /// With several objects: what the stages made of each (the top-level
    /// outcomes and latencies are those of each frame's last object to
    /// finish).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<ObjectOutcomes>,
}

/// One object's outcomes in a run of several.
#[derive(Serialize, Debug)]
pub struct ObjectOutcomes {
    /// The object.
    pub object: String,
    /// What the stages made of it.
    #[serde(flatten)]
    pub outcomes: Outcomes,
    /// Frames whose detection was withdrawn for another object's.
    pub suppressed: u64,
}

impl RunSummary {
    fn new(cfg: &PipelineConfig, mode: &'static str, got: &[Seeded], elapsed: f64) -> Self {
        let samples = Samples::of(got, mode == "processes");
        let (w, h) = got
            .first()
            .map_or((cfg.camera.width, cfg.camera.height), |m| {
                (m.envelope().frame.width, m.envelope().frame.height)
            });
        let reads = |f: fn(&Seeded) -> u32| got.iter().map(|m| f(m) as u64).sum();
        RunSummary {
            object: cfg.object.name.clone(),
            source: cfg.camera.source.clone(),
            mode,
            frames_requested: cfg.camera.frames,
            fps_target: cfg.camera.fps,
            fps_achieved: got.len() as f64 / elapsed.max(1e-9),
            unrated: cfg.estimate.unrated,
            outcomes: Outcomes::of(got),
            end_to_end: samples.end_to_end(),
            stages: samples.stages(),
            frame_reads: reads(|m| m.envelope().reads.reads),
            frame_reads_in_place: reads(|m| m.envelope().reads.in_place),
            frame_bytes_published: 3 * w as u64 * h as u64 * got.len() as u64,
            transport: if mode == "processes" {
                cfg.run.transport.to_string()
            } else {
                mode.into()
            },
            width: w,
            height: h,
            dropped: cfg.camera.frames.saturating_sub(got.len() as u64),
            duplicates: 0,
            processes: Vec::new(),
            pids: Vec::new(),
            restarts: Vec::new(),
            stale_nodes_removed_during_run: 0,
            stale_nodes_removed: 0,
            rss: Vec::new(),
            rss_trend: Vec::new(),
            stage_counters: Vec::new(),
            placement: None,
            cpu_latency_us: cfg.run.cpu_latency_us,
            samples: None,
            objects: Vec::new(),
        }
    }
}

/// Holds a CPU latency request of `micros`, if given, until the returned
/// guard drops; errors name the setting as `setting` (`--cpu-latency-us`).
pub fn hold_cpu_latency(
    micros: Option<u32>,
    setting: &str,
) -> Result<Option<acch_ipc::sched::CpuLatencyRequest>, RunError> {
    micros
        .map(|us| {
            acch_ipc::sched::CpuLatencyRequest::hold(us).map_err(|source| RunError::Sched {
                what: format!(
                    "{setting} {us}: cannot hold {} (it needs root; run without it)",
                    acch_ipc::sched::CpuLatencyRequest::PATH
                ),
                source,
            })
        })
        .transpose()
}

/// The observers of a run in one process: viewer, recorder, zenoh,
/// results file, as configured.
struct LocalObservers {
    viewer: Option<(Viewing, crate::observers::ViewerThread)>,
    recording: Option<RunRecording>,
    zenoh: Option<ZenohSink>,
    results: Option<JsonLines>,
    got: Collect,
}

/// Collects every final result.
#[derive(Default)]
struct Collect(Vec<Seeded>);

impl Observe for Collect {
    fn result(&mut self, h: &Seeded) -> Result<(), ObserveError> {
        self.0.push(*h);
        Ok(())
    }
}

impl LocalObservers {
    fn open(
        cfg: &PipelineConfig,
        opts: &RunOptions,
        views: &[(f32, f32)],
    ) -> Result<Self, RunError> {
        Ok(LocalObservers {
            viewer: cfg
                .observers
                .rerun
                .as_deref()
                .map(|sink| Viewing::open(sink, views))
                .transpose()?,
            recording: cfg
                .observers
                .record
                .as_deref()
                .map(|p| RunRecording::create(cfg, p, views.len()))
                .transpose()?,
            zenoh: opts.zenoh.then(|| ZenohSink::open(cfg)).transpose()?,
            results: opts
                .results
                .as_deref()
                .map(|p| JsonLines::create(p, &cfg.object.name))
                .transpose()?,
            got: Collect(Vec::with_capacity(cfg.camera.frames as usize)),
        })
    }

    fn each(&mut self) -> Each<'_> {
        let mut v: Vec<&mut dyn Observe> = vec![&mut self.got];
        if let Some((o, _)) = &mut self.viewer {
            v.push(o);
        }
        if let Some(o) = &mut self.recording {
            v.push(o);
        }
        if let Some(o) = &mut self.zenoh {
            v.push(o);
        }
        if let Some(o) = &mut self.results {
            v.push(o);
        }
        Each(v)
    }

    /// Flushes and closes everything; returns the results.
    fn finish(self) -> Result<Vec<Seeded>, RunError> {
        if let Some((v, t)) = self.viewer {
            let s = v.finish(t, [0; 4]);
            tracing::info!("viz: {s:?}");
        }
        if let Some(r) = self.recording {
            r.finish([0; 4])?;
        }
        if let Some(mut r) = self.results {
            r.flush()?;
        }
        Ok(self.got.0)
    }
}

/// Runs the stages chained in this process, on the stages' CPU (as the
/// stage processes), over the configured source, with the configured
/// observers.
pub fn run_in_process(cfg: &PipelineConfig, opts: &RunOptions) -> Result<RunSummary, RunError> {
    if !cfg.objects.list.is_empty() {
        return run_objects(cfg, opts);
    }
    cfg.validate()?;
    let mut cfg = cfg.clone();
    cfg.resolve_stream_size()?;
    let cfg = &cfg;
    // Before the pinning below narrows what this thread may use.
    let helper_cpus = cfg.pose_helper_cpus().map_err(|source| RunError::Sched {
        what: format!("run.stage_cpus = {}", cfg.run.stage_cpus),
        source,
    })?;
    cfg.pin_stage().map_err(|source| RunError::Sched {
        what: format!("run.stage_cpus = {}", cfg.run.stage_cpus),
        source,
    })?;
    let _cpu_latency = hold_cpu_latency(cfg.run.cpu_latency_us, "run.cpu_latency_us =")?;
    let db = cfg.database()?;
    cfg.warn_on_untrained_roll_search(&db);
    let settings = cfg.settings(&db)?;
    let smoothed = cfg.smoothed_database()?;
    let mut chain = Chain::build_for_sets(&db, smoothed.as_ref(), &settings)?;
    crate::stages::share_with_helper(&mut chain.stages_mut().pose, helper_cpus)?;
    let views = crate::observers::view_angles(&db);
    drop((db, smoothed));
    let spec = cfg.source_spec()?;
    let mut source = Source::open(&spec, (settings.width, settings.height), 0)?;
    let mut observers = LocalObservers::open(cfg, opts, &views)?;
    let pacing = pacing(cfg);
    let (cpu0, _) = self_usage();
    let t0 = Instant::now();
    let arm = crate::ros2::ArmFeed::open(&cfg.ros2, &cfg.zenoh).map_err(ObserveError::from)?;
    run_source(
        &mut chain,
        &mut source,
        (cfg.camera.frames, pacing),
        arm.as_ref(),
        &mut observers.each(),
    )?;
    let elapsed = t0.elapsed().as_secs_f64();
    let usage = this_process(cpu0, elapsed);
    let got = observers.finish()?;
    let mut s = RunSummary::new(cfg, "in-process", &got, elapsed);
    s.processes = vec![usage];
    s.stage_counters = std::iter::once(serde_json::json!({
        "stage": "capture",
        "sent": got.len(),
        "skipped_size": source.skipped,
        "camera": source.camera_counters(),
    }))
    .chain(
        chain
            .counters()
            .iter()
            .map(|c| serde_json::to_value(c).expect("counters serialise")),
    )
    .collect();
    if opts.samples {
        s.samples = Some(Samples::of(&got, false));
    }
    Ok(s)
}

/// How a run in this process paces its source.
fn pacing(cfg: &PipelineConfig) -> Pacing {
    match cfg.pace() {
        Some(Pace::Recorded) => Pacing::Recorded,
        // A camera blocks until its next frame: as fast as it delivers.
        Some(Pace::Free | Pace::Source) => Pacing::Free,
        None => Pacing::Rate(cfg.camera.fps),
    }
}

/// This process's CPU since `cpu0` seconds of it, over `elapsed`
/// seconds, and its peak memory.
fn this_process(cpu0: f64, elapsed: f64) -> ProcessUsage {
    let (cpu1, peak_rss_kb) = self_usage();
    ProcessUsage {
        stage: "in-process".into(),
        cpu_s: cpu1 - cpu0,
        cpu_pct: 100.0 * (cpu1 - cpu0) / elapsed.max(1e-9),
        peak_rss_kb,
        cpus: status_field(std::process::id(), "Cpus_allowed_list:").unwrap_or_default(),
    }
}

/// `path` for object `object` of several: `res.jsonl` becomes
/// `res-<object>.jsonl`.
pub fn per_object_path(path: &Path, object: &str) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let name = match path.extension() {
        Some(ext) => format!("{stem}-{object}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{object}"),
    };
    path.with_file_name(name)
}

/// Runs several objects' chains ([`MultiChain`]) in this process over the
/// configured source: every result of object `o` on zenoh at
/// `<prefix>/<o>/result` (and `.../seed`) over one session, and with
/// `results` in a file per object ([`per_object_path`]).
pub fn run_objects(cfg: &PipelineConfig, opts: &RunOptions) -> Result<RunSummary, RunError> {
    cfg.validate()?;
    let mut cfg = cfg.clone();
    cfg.resolve_stream_size()?;
    let cfg = &cfg;
    // Pinned to one CPU the objects' chains would take turns: "auto"
    // leaves them every CPU (docs/multi.md).
    if cfg.run.stage_cpus != StageCpus::Auto {
        cfg.pin_stage().map_err(|source| RunError::Sched {
            what: format!("run.stage_cpus = {}", cfg.run.stage_cpus),
            source,
        })?;
    }
    let _cpu_latency = hold_cpu_latency(cfg.run.cpu_latency_us, "run.cpu_latency_us =")?;
    let dbs = cfg.object_databases()?;
    let lanes = dbs
        .iter()
        .map(|db| Ok((db, cfg.object_settings(db)?)))
        .collect::<Result<Vec<_>, ConfigError>>()?;
    let (width, height) = lanes
        .first()
        .map_or((cfg.camera.width, cfg.camera.height), |(_, s)| {
            (s.width, s.height)
        });
    let threads = match cfg.objects.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    };
    let mut chain = MultiChain::build(&lanes, threads)?;
    drop(lanes);
    let names: Vec<String> = dbs.iter().map(|db| db.object.clone()).collect();
    drop(dbs);
    let mut source = Source::open(&cfg.source_spec()?, (width, height), 0)?;
    let session = opts
        .zenoh
        .then(|| acch_ipc::open_session(&cfg.zenoh.listen, &cfg.zenoh.connect))
        .transpose()
        .map_err(IpcError::from)?;
    let mut sinks = Vec::new();
    let mut files = Vec::new();
    for (i, name) in names.iter().enumerate() {
        if cfg.ros2.enabled {
            // Its name goes into topic and node names.
            cfg.ros2.validate(name)?;
        }
        if let Some(session) = &session {
            let role = crate::ros2::Ros2Role::OneOf { camera: i == 0 };
            sinks.push(ZenohSink::on_session(session.clone(), cfg, name, role)?);
        }
        if let Some(path) = &opts.results {
            files.push(JsonLines::create(&per_object_path(path, name), name)?);
        }
    }
    let pacing = pacing(cfg);
    let mut per_object: Vec<Vec<Seeded>> = vec![Vec::new(); names.len()];
    let mut last_to_finish = Vec::with_capacity(cfg.camera.frames as usize);
    let (cpu0, _) = self_usage();
    let t0 = Instant::now();
    let arm = crate::ros2::ArmFeed::open(&cfg.ros2, &cfg.zenoh).map_err(ObserveError::from)?;
    crate::chain::run_frames(
        &mut source,
        (cfg.camera.frames, pacing),
        arm.as_ref(),
        |frame, rgb| {
            if let Some(first) = sinks.first_mut() {
                // The camera's ROS 2 image, when configured.
                first.frame(frame, rgb)?;
            }
            let outs = chain.process(frame, rgb);
            for (o, out) in outs.iter().enumerate() {
                if let Some(sink) = sinks.get_mut(o) {
                    sink.result(out)?;
                }
                if let Some(file) = files.get_mut(o) {
                    file.result(out)?;
                }
                per_object[o].push(*out);
            }
            if let Some(last) = outs
                .iter()
                .max_by_key(|m| m.envelope().trail.end_to_end_ns())
            {
                last_to_finish.push(*last);
            }
            Ok(())
        },
    )?;
    let elapsed = t0.elapsed().as_secs_f64();
    let usage = this_process(cpu0, elapsed);
    for f in &mut files {
        f.flush()?;
    }
    let mut s = RunSummary::new(cfg, "in-process", &last_to_finish, elapsed);
    s.object = names.join(",");
    s.processes = vec![usage];
    s.objects = chain
        .lanes()
        .iter()
        .zip(&per_object)
        .map(|(lane, got)| ObjectOutcomes {
            object: lane.object.clone(),
            outcomes: Outcomes::of(got),
            suppressed: lane.suppressed,
        })
        .collect();
    // Capture's, then each object's stages', named by the object.
    let capture = serde_json::json!({
        "stage": "capture",
        "sent": last_to_finish.len(),
        "skipped_size": source.skipped,
        "camera": source.camera_counters(),
    });
    s.stage_counters = std::iter::once(capture)
        .chain(chain.lanes().iter().flat_map(|lane| {
            lane.chain.counters().iter().map(|c| {
                let mut v = serde_json::to_value(c).expect("counters serialise");
                v["object"] = serde_json::json!(lane.object);
                v
            })
        }))
        .collect();
    if opts.samples {
        s.samples = Some(Samples::of(&last_to_finish, false));
    }
    Ok(s)
}

/// A file removed when this value drops.
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// The sequence a restarted capture continues at: the frame due now at the
/// configured rate (frames while it was down are lost, as with a camera),
/// and always past the last result seen.
pub fn resume_sequence(fps: f64, since_start: Duration, last_seq: Option<u64>) -> u64 {
    let after_last = last_seq.map_or(0, |l| l + 1);
    if fps > 0.0 {
        ((since_start.as_secs_f64() * fps).floor() as u64 + 1).max(after_last)
    } else {
        // Free-running: frames in flight are at most the queues' depth.
        after_last + 64
    }
}

/// The counters a stage process wrote when it stopped (none for a killed
/// one); the file is removed.
fn read_counters(cfg: &PipelineConfig, name: &str, pid: u32) -> Option<serde_json::Value> {
    let path = cfg.counters_path(name, pid);
    let text = std::fs::read_to_string(&path).ok()?;
    let _ = std::fs::remove_file(&path);
    serde_json::from_str(&text).ok()
}

/// Runs every stage as a process (started by `spawn` as process `name`
/// with the run's configuration file), supervised: waits until all are
/// connected, starts the capture, collects the final result of every frame
/// from the seeding stage's stream, restarts a stage that dies, then stops
/// them all and cleans their shared memory.
pub fn run_processes(
    mut cfg: PipelineConfig,
    opts: &RunOptions,
    spawn: impl Spawn,
) -> Result<RunSummary, RunError> {
    cfg.run.instance = std::process::id().to_string();
    cfg.camera.first_frame = 0;
    cfg.validate()?;
    if !cfg.objects.list.is_empty() {
        return Err(RunError::SeveralObjects(cfg.objects.list.join(", ")));
    }
    // A camera's size is learnt once, here; every process reads it.
    cfg.resolve_stream_size()?;
    // The stages' wake-up files go with the run, however it ends.
    let _wake_files = acch_ipc::wake::RunFiles::new(&cfg.run.instance);
    // One clear error here rather than one from every stage process.
    let db = cfg.database()?;
    cfg.warn_on_untrained_roll_search(&db);
    let smoothed = cfg.smoothed_database()?;
    crate::stages::Stages::for_sets(&db, smoothed.as_ref(), &cfg.settings(&db)?)?;
    drop((db, smoothed));
    let stale = remove_stale_resources();
    if stale > 0 {
        tracing::info!("removed the stale resources of {stale} dead iceoryx2 nodes");
    }
    if cfg.run.realtime_priority > 0 {
        // Set here, before any stage starts: every child inherits it.
        acch_ipc::sched::set_fifo(cfg.run.realtime_priority).map_err(|source| RunError::Sched {
            what: format!(
                "run.realtime_priority = {}: SCHED_FIFO needs CAP_SYS_NICE or an rtprio limit \
                 (ulimit -r); run without it",
                cfg.run.realtime_priority
            ),
            source,
        })?;
    }
    // Held by the launcher for the whole run: the kernel drops it when the
    // launcher exits, however it exits.
    let _cpu_latency = hold_cpu_latency(cfg.run.cpu_latency_us, "run.cpu_latency_us =")?;
    // Before any child starts: capture and the observers inherit the
    // launcher's CPUs; the stages move themselves to theirs.
    let placement = cfg.place_run().map_err(|source| RunError::Sched {
        what: format!("run.stage_cpus = {}", cfg.run.stage_cpus),
        source,
    })?;
    if let Some(p) = &placement {
        tracing::info!("stages on CPUs {:?}, the rest on {:?}", p.stages, p.others);
    }
    let tmp = std::env::temp_dir();
    let config_path = tmp.join(format!("acch-run-{}.toml", cfg.run.instance));
    cfg.save(&config_path)?;
    let _config_guard = RemoveOnDrop(config_path.clone());
    let mut restart_configs: Vec<RemoveOnDrop> = Vec::new();
    // Counter files of every stage process; dropped after the supervisor,
    // so the files they write when stopped on an early return go too.
    let mut counter_files: Vec<RemoveOnDrop> = Vec::new();

    let ipc = cfg.ipc("launcher")?;
    let ready = ipc.control_listener(READY)?;
    let start = ipc.control_notifier(START)?;
    let results = ipc.input::<Seeded>(streams::results(StageId::Seeding), Wake::Event)?;
    let mut results_file = opts
        .results
        .as_deref()
        .map(|p| JsonLines::create(p, &cfg.object.name))
        .transpose()?;
    let mut sup = Supervisor::new(spawn, RestartPolicy::default());
    let observers = cfg.observers();
    for id in StageId::ALL {
        sup.start(id.name(), &config_path, true)?;
    }
    for o in &observers {
        sup.start(o.name(), &config_path, false)?;
    }
    let pids = sup.pids();
    counter_files.extend(
        pids.iter()
            .map(|(n, p)| RemoveOnDrop(cfg.counters_path(n, *p))),
    );
    eprintln!(
        "acch run: pids {}",
        pids.iter()
            .map(|(n, p)| format!("{n}={p}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    wait_until_ready(&ipc, &ready, &mut sup, &observers)?;
    eprintln!(
        "acch run: {} stages connected (instance {}), streaming {} frames of {} at {}",
        STAGES,
        cfg.run.instance,
        cfg.camera.frames,
        cfg.object.name,
        if cfg.camera.fps > 0.0 {
            format!("{} fps", cfg.camera.fps)
        } else {
            "free-running".into()
        }
    );
    start.notify(0)?;
    sup.mark_start();
    let t0 = Instant::now();
    let mut got: Vec<Seeded> = Vec::with_capacity(cfg.camera.frames as usize);
    let mut last = Instant::now();
    let mut next_rss = t0;
    let mut rss: Vec<RssSample> = Vec::new();
    let mut interrupted = false;
    let mut last_seq: Option<u64> = None;
    let mut duplicates = 0u64;
    let mut restarts: Vec<Restart> = Vec::new();
    let mut stale_during_run = 0usize;
    // A restarted capture waits for `start` again once it is connected.
    let mut capture_restarted = false;
    while cfg.camera.frames == 0 || (got.len() as u64) < cfg.camera.frames {
        if !ipc.keep_running() {
            interrupted = true;
            break;
        }
        if Instant::now() >= next_rss {
            rss.push(sup.sample_rss());
            next_rss += opts.rss_every;
        }
        let restart = sup.check(
            |name| {
                if name != StageId::Capture.name() {
                    return Some((config_path.clone(), None));
                }
                // A camera does not wait: continue at the frame due now,
                // past every frame the old capture may have sent.
                let next = resume_sequence(cfg.camera.fps, t0.elapsed(), last_seq);
                if cfg.camera.frames > 0 && next >= cfg.camera.frames {
                    return None;
                }
                let mut c = cfg.clone();
                c.camera.first_frame = next;
                let path = tmp.join(format!("acch-run-{}-capture-{next}.toml", cfg.run.instance));
                c.save(&path).ok()?;
                restart_configs.push(RemoveOnDrop(path.clone()));
                Some((path, Some(next)))
            },
            // The dead node still owns ports (a publisher slot, borrowed
            // samples): free them before the new process opens its own.
            remove_stale_resources,
        )?;
        if let Some(r) = restart {
            eprintln!(
                "acch run: {} (pid {}) ended with {}; cleaned {} dead nodes; restarted as pid {}",
                r.stage, r.old_pid, r.status, r.stale_nodes_removed, r.new_pid
            );
            stale_during_run += r.stale_nodes_removed;
            capture_restarted |= r.stage == StageId::Capture.name();
            counter_files.push(RemoveOnDrop(cfg.counters_path(r.stage, r.new_pid)));
            restarts.push(r);
            // Give the stall timer the restart's time back.
            last = Instant::now();
        }
        // Restarted stages announce themselves; a capture then needs `start`.
        ready.take(Duration::ZERO, |id| {
            if id == StageId::Capture as usize && capture_restarted {
                capture_restarted = false;
                if let Err(e) = start.notify(0) {
                    tracing::warn!("restarting the capture: {e}");
                }
            }
        })?;
        results.wait(Duration::from_millis(200))?;
        while let Some(s) = results.receive()? {
            let m = *s.user_header();
            last = Instant::now();
            let seq = m.envelope().frame.sequence;
            // Sequences only grow; an older one would be a replayed frame.
            if last_seq.is_some_and(|l| seq <= l) {
                duplicates += 1;
                continue;
            }
            last_seq = Some(seq);
            if let Some(f) = &mut results_file {
                f.result(&m)?;
            }
            got.push(m);
        }
        if let Some(l) = last_seq
            && cfg.camera.frames > 0
            && l + 1 >= cfg.camera.frames
        {
            // The last frame is through: anything missing was dropped.
            break;
        }
        if last.elapsed() > opts.stall_timeout {
            tracing::warn!(
                "no result for {:.0} s: stopping",
                opts.stall_timeout.as_secs_f64()
            );
            break;
        }
    }
    let elapsed = t0.elapsed().as_secs_f64();
    rss.push(sup.sample_rss());
    let processes = sup.usage();
    let all_pids = sup.all_pids.clone();
    sup.stop(Duration::from_secs(5));
    drop((results, ready, start, ipc));
    let stale_nodes_removed = remove_stale_resources();
    if interrupted {
        eprintln!("acch run: interrupted");
    }
    if let Some(mut f) = results_file {
        f.flush()?;
    }
    let mut summary = RunSummary::new(&cfg, "processes", &got, elapsed);
    summary.processes = processes;
    summary.placement = placement;
    summary.pids = pids;
    summary.restarts = restarts;
    summary.stale_nodes_removed_during_run = stale_during_run;
    summary.stale_nodes_removed = stale_nodes_removed;
    summary.duplicates = duplicates;
    summary.rss_trend = rss_trend(&rss);
    summary.rss = rss;
    summary.stage_counters = all_pids
        .iter()
        .filter_map(|(name, pid)| read_counters(&cfg, name, *pid))
        .collect();
    if opts.samples {
        summary.samples = Some(Samples::of(&got, true));
    }
    Ok(summary)
}

/// Waits until every stage and observer has announced itself (120 s at
/// most); a child that exits meanwhile ends the wait with its error.
fn wait_until_ready(
    ipc: &acch_ipc::Ipc,
    ready: &acch_ipc::ControlListener,
    sup: &mut Supervisor<impl Spawn>,
    observers: &[Observer],
) -> Result<(), RunError> {
    let mut seen = [false; STAGES + Observer::ALL.len()];
    for o in Observer::ALL {
        seen[o.ready_id()] = !observers.contains(&o);
    }
    let deadline = Instant::now() + Duration::from_secs(120);
    while !seen.iter().all(|s| *s) {
        if !ipc.keep_running() {
            return Err(RunError::Interrupted);
        }
        if Instant::now() > deadline {
            let missing = StageId::ALL
                .iter()
                .map(|s| s.name())
                .chain(Observer::ALL.iter().map(|o| o.name()))
                .zip(seen)
                .filter(|(_, s)| !s)
                .map(|(n, _)| n)
                .collect();
            return Err(RunError::NotReady { secs: 120, missing });
        }
        // Nothing is restarted before the start: any exit ends the run.
        sup.check(|_| None, || 0)?;
        ready.take(Duration::from_millis(200), |id| {
            if let Some(s) = seen.get_mut(id) {
                *s = true;
            }
        })?;
    }
    Ok(())
}

/// The `acch stage NAME` side: runs process `name` of the run configured
/// in `config`.
pub fn run_process(name: &str, config: &Path) -> Result<(), NodeError> {
    let cfg = PipelineConfig::load(config)?;
    if let Some(o) = Observer::from_name(name) {
        match o {
            Observer::Viz => crate::observers::run_viz(&cfg).map(|_| ()),
            Observer::Record => crate::observers::run_record(&cfg).map(|_| ()),
        }?;
        return Ok(());
    }
    let id = StageId::from_name(name).ok_or(ConfigError::Invalid {
        key: "stage",
        value: name.to_owned(),
        why: "must be capture, recognition, segmentation, pose, confidence, seeding, viz or record",
    })?;
    if id == StageId::Capture {
        return crate::node::run_capture(&cfg);
    }
    let db = cfg.database()?;
    let smoothed = cfg.smoothed_database()?;
    let settings = cfg.settings(&db)?;
    use crate::node::run_stage;
    use crate::stages::{Confidence, Pose, Recognition, Seeding, Segmentation, by_set};
    fn none<T>(_: &T) -> Result<(), ObserveError> {
        Ok(())
    }
    let sets = (&db, smoothed.as_ref(), &settings);
    match id {
        StageId::Recognition => run_stage(&cfg, by_set(sets, Recognition::new)?, none),
        StageId::Segmentation => run_stage(&cfg, by_set(sets, Segmentation::new)?, none),
        StageId::Pose => {
            let mut pose = by_set(sets, Pose::new)?;
            // run_stage pins this process to the stages' CPUs; the helper
            // goes beside them.
            let cpus = cfg.pose_helper_cpus().map_err(|source| NodeError::Sched {
                what: format!(
                    "run.stage_cpus = {}: the pose stage's helper",
                    cfg.run.stage_cpus
                ),
                source,
            })?;
            crate::stages::share_with_helper(&mut pose, cpus)?;
            run_stage(&cfg, pose, none)
        }
        StageId::Confidence => run_stage(&cfg, by_set(sets, Confidence::new)?, none),
        StageId::Seeding => {
            let stage = Seeding::new(&db, &settings)?;
            let mut zenoh = ZenohSink::open(&cfg)?;
            // Ends with the process.
            let _images = zenoh.spawn_images(&cfg);
            run_stage(&cfg, stage, |m: &Seeded| zenoh.result(m))
        }
        StageId::Capture => unreachable!("handled above"),
    }
    .map(|_| ())
}
