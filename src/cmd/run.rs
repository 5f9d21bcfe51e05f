//! `acch run`: stream frames through every stage and report accuracy and
//! per-stage latency. The embedded default needs no camera and no files: the
//! built-in fruitbox on the wood background, seen by a simulated eye-in-hand
//! camera moving over the hemisphere, with its database trained on first use
//! and cached.
//!
//! By default every stage runs as its own process (`acch stage NAME`),
//! connected over iceoryx2 shared memory, with seeds and results published on
//! zenoh (see `crate::stages` and `launch`). `--in-process` keeps the stages
//! chained in this process (see `crate::pipeline`): the compute floor the
//! pipeline's overhead is measured against.

use super::common::{self, ObjectArgs};
use crate::model;
use crate::pipeline::{FrameResult, Pipeline};
use acch_capture::{Background, DEFAULT_DISTANCE, Rendered, Trajectory};
use acch_core::ViewDatabase;
use acch_pose::phi_error;
use acch_pose::train::TrainConfig;
use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments of `acch run`.
#[derive(Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub(crate) object: ObjectArgs,
    /// View database; by default one is trained for the object on first use
    /// and cached (see --cache-dir).
    #[arg(long, value_name = "FILE.acchdb")]
    pub(crate) db: Option<PathBuf>,
    /// Where trained default databases are cached.
    #[arg(long, env = "ACCH_CACHE_DIR", value_name = "DIR")]
    pub(crate) cache_dir: Option<PathBuf>,
    /// Background of the simulated scene: plain, A, B, C, clutter, clutter-similar.
    #[arg(long, default_value = "A")]
    pub(crate) background: Background,
    /// Frames to process (default 300, or the configuration's).
    #[arg(long)]
    pub(crate) frames: Option<u64>,
    /// Camera frame rate; 0 runs free (default 30, or the configuration's).
    #[arg(long)]
    pub(crate) fps: Option<f64>,
    /// Frame source: synthetic, folder:DIR (images and labels.csv) or
    /// mcap:FILE (replays an `acch run --record` recording).
    #[arg(long, value_name = "SOURCE")]
    pub(crate) source: Option<String>,
    /// Run every process under SCHED_FIFO at this priority (1..=90): wake-ups
    /// preempt other work, which keeps hop and end-to-end tails short on a
    /// loaded machine. Needs CAP_SYS_NICE or an rtprio limit.
    #[arg(long, value_name = "PRIORITY")]
    pub(crate) rt_priority: Option<u8>,
    /// Longest wake-up from idle the CPUs may take while the run lasts, in
    /// µs (the kernel's CPU latency QoS, /dev/cpu_dma_latency). 0 keeps idle
    /// CPUs polling instead of halting: on a VM a halted vCPU wakes through
    /// the hypervisor, with cold caches. Idle CPUs then stay busy. Needs
    /// root.
    #[arg(long, value_name = "US")]
    pub(crate) cpu_latency_us: Option<u32>,
    /// CPUs of the five processing stages: auto (the last CPU; capture,
    /// observers and launcher on the rest), none (the scheduler decides),
    /// or a list like 1 or 2,3. One shared CPU makes each hop a local
    /// context switch instead of a cross-CPU wake-up (default: auto, or
    /// the configuration's).
    #[arg(long, value_name = "CPUS")]
    pub(crate) stage_cpus: Option<String>,
    /// Pace of an mcap: replay: recorded (the recording's frame times) or
    /// free (as fast as the pipeline takes frames).
    #[arg(long, value_name = "PACE")]
    pub(crate) replay: Option<String>,
    /// Pipeline configuration (TOML; every key is listed in the README).
    #[arg(long, value_name = "FILE")]
    pub(crate) config: Option<PathBuf>,
    /// Chain the stages in this process instead of one process per stage.
    #[arg(long)]
    pub(crate) in_process: bool,
    /// Give up when no result arrives for this many seconds.
    #[arg(long, default_value_t = 20.0)]
    pub(crate) stall_timeout: f64,
    /// Sample every process's resident memory this often (seconds) into
    /// the summary's `rss`.
    #[arg(long, default_value_t = 10.0, value_name = "SECS")]
    pub(crate) rss_every: f64,
    /// Seed of the camera trajectory and the scene.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Print one line per frame.
    #[arg(long, short)]
    pub(crate) verbose: bool,
    /// Write the summary as JSON.
    #[arg(long, value_name = "FILE")]
    pub(crate) json: Option<PathBuf>,
    /// Frame size of the synthetic camera, WIDTHxHEIGHT (default 640x480,
    /// or the configuration's).
    #[arg(long, value_name = "WxH", value_parser = parse_resolution)]
    pub(crate) resolution: Option<(u32, u32)>,
    /// How frames reach the stage processes: shm (zero copy) or copy (the
    /// benchmark's baseline: through a Unix socket per stage).
    #[arg(long)]
    pub(crate) transport: Option<String>,
    /// Log what the pipeline sees to rerun from a `viz` process beside it:
    /// save:FILE.rrd, spawn (starts a viewer) or connect:URL.
    #[arg(long, value_name = "SINK")]
    pub(crate) rerun: Option<String>,
    /// Record every frame and result to this MCAP file from a `record`
    /// process beside the pipeline.
    #[arg(long, value_name = "FILE.mcap")]
    pub(crate) record: Option<PathBuf>,
    /// Also write every frame's latencies (ns) into the JSON summary.
    #[arg(long, hide = true)]
    pub(crate) samples: bool,
}

/// Parses `WIDTHxHEIGHT`.
pub(crate) fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT"))?;
    let num = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (16..=8192).contains(n))
            .ok_or_else(|| format!("'{s}': sizes must be 16..8192 pixels"))
    };
    Ok((num(w)?, num(h)?))
}

/// CPU time and peak resident memory of one process over a run.
#[derive(Serialize, Debug, Clone)]
pub struct ProcessUsage {
    /// Stage name (or "in-process").
    pub stage: String,
    /// CPU seconds (user + system) while frames streamed.
    pub cpu_s: f64,
    /// `cpu_s` over the streaming time, percent of one core.
    pub cpu_pct: f64,
    /// Peak resident set, kB (VmHWM / ru_maxrss).
    pub peak_rss_kb: u64,
    /// The CPUs it was allowed on (`Cpus_allowed_list`, e.g. "1" or "0-1").
    pub cpus: String,
}

/// Every frame's latencies, nanoseconds (with `--samples`).
#[derive(Serialize, Debug, Default)]
pub struct Samples {
    /// Captured -> final result, per frame.
    pub e2e_ns: Vec<u64>,
    /// Per stage: upstream published -> received (empty for capture and in
    /// one process).
    pub hop_ns: Vec<(String, Vec<u64>)>,
    /// Per stage: compute time (received -> published; in one process the
    /// stage function's time).
    pub process_ns: Vec<(String, Vec<u64>)>,
}

/// User + system CPU seconds and peak RSS (kB) of this process.
pub(crate) fn self_usage() -> (f64, u64) {
    // SAFETY: getrusage fills the struct we pass.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut ru) };
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 / 1e6;
    (secs(ru.ru_utime) + secs(ru.ru_stime), ru.ru_maxrss as u64)
}

/// Latency percentiles of one stage, milliseconds.
#[derive(Serialize, Debug)]
pub struct Percentiles {
    /// Median.
    pub p50_ms: f64,
    /// 90th percentile.
    pub p90_ms: f64,
    /// 99th percentile.
    pub p99_ms: f64,
    /// Largest.
    pub max_ms: f64,
}

impl Percentiles {
    /// Percentiles of nanosecond samples.
    pub fn of(samples: &mut [u64]) -> Self {
        samples.sort_unstable();
        let at = |q: f64| -> f64 {
            if samples.is_empty() {
                return 0.0;
            }
            let i = ((samples.len() - 1) as f64 * q).round() as usize;
            samples[i] as f64 / 1e6
        };
        Percentiles {
            p50_ms: at(0.5),
            p90_ms: at(0.9),
            p99_ms: at(0.99),
            max_ms: at(1.0),
        }
    }
}

#[derive(Serialize)]
struct Summary {
    object: String,
    background: String,
    frames: u64,
    fps_target: f64,
    fps_achieved: f64,
    found: u64,
    estimated: u64,
    accepted: u64,
    accepted_mean_phi_err_deg: f64,
    accepted_mean_theta_err_deg: f64,
    accepted_failure_rate: f64,
    all_failure_rate: f64,
    latency: Latency,
    mode: &'static str,
    /// The CPU latency request held during the run, µs (null: none).
    cpu_latency_us: Option<u32>,
    width: u32,
    height: u32,
    /// Always 0: one thread processes every frame in turn.
    dropped: u64,
    processes: Vec<ProcessUsage>,
    #[serde(skip_serializing_if = "Option::is_none")]
    samples: Option<Samples>,
}

#[derive(Serialize)]
struct Latency {
    capture: Percentiles,
    recognition: Percentiles,
    segmentation: Percentiles,
    pose: Percentiles,
    confidence: Percentiles,
    /// Frame captured to result ready (excludes rendering the frame).
    processing: Percentiles,
}

/// Runs `acch run`.
pub fn run(args: RunArgs) -> Result<()> {
    if args.in_process {
        if args.source.is_some()
            || args.rerun.is_some()
            || args.record.is_some()
            || args.rt_priority.is_some()
        {
            bail!(
                "--source, --rerun, --record and --rt-priority need the multi-process pipeline (drop --in-process)"
            );
        }
        return run_in_process(args);
    }
    super::launch::run(args)
}

fn run_in_process(args: RunArgs) -> Result<()> {
    let fps = args.fps.unwrap_or(30.0);
    let frames = args.frames.unwrap_or(300);
    if !(fps.is_finite() && fps >= 0.0) {
        bail!("--fps {} must be a number >= 0", fps);
    }
    // On the stages' CPU, as in the multi-process run, so both compare alike.
    let placement = crate::stages::PipelineConfig {
        stage_cpus: args.stage_cpus.clone().unwrap_or_else(|| "auto".into()),
        cpu_latency_us: args.cpu_latency_us,
        ..Default::default()
    };
    placement
        .validate()
        .context("invalid pipeline configuration")?;
    placement.pin_stage()?;
    let _cpu_latency = crate::stages::hold_cpu_latency(args.cpu_latency_us, "--cpu-latency-us")?;
    let object = args.object.load()?;
    let db = match &args.db {
        Some(path) => ViewDatabase::load(path)?,
        None => cached_database(&object, args.cache_dir.clone())?,
    };
    let (rw, rh) = args.resolution.unwrap_or((640, 480));
    let renderer = crate::stages::sized_renderer(
        object.clone(),
        args.background,
        args.seed,
        crate::stages::sized_intrinsics(rw, rh),
    );
    let trajectory = Trajectory::new(
        args.seed,
        if fps > 0.0 { fps } else { 30.0 },
        DEFAULT_DISTANCE,
    )?;
    let mut frame = renderer.render(&trajectory.frame(0).view, 0);
    let (w, h) = frame.image.dimensions();
    let mut pipeline = Pipeline::new(db, w, h, Some(DEFAULT_DISTANCE as f32))?;
    eprintln!(
        "acch run: {} on background {}, {} frames at {}, {} stages in one process",
        object.name(),
        args.background,
        frames,
        if fps > 0.0 {
            format!("{} fps", fps)
        } else {
            "free-running".into()
        },
        if pipeline.confidence().is_some() {
            5
        } else {
            4
        },
    );

    let n = frames as usize;
    let mut times: [Vec<u64>; 6] = std::array::from_fn(|_| Vec::with_capacity(n));
    let (mut found, mut estimated, mut accepted, mut acc_fail, mut all_fail) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let (mut sum_phi, mut sum_theta) = (0.0f64, 0.0f64);
    let bar = if args.verbose {
        indicatif::ProgressBar::hidden()
    } else {
        common::progress(frames, "frames")
    };
    let (cpu0, _) = self_usage();
    let start = Instant::now();
    for i in 0..frames {
        if fps > 0.0 {
            let due = start + Duration::from_secs_f64(i as f64 / fps);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        let t = Instant::now();
        let view = trajectory.frame(i).view;
        renderer.render_into(&view, common::frame_seed(args.seed, i as usize), &mut frame);
        times[0].push(t.elapsed().as_nanos() as u64);
        let r = pipeline.process(frame.image.as_raw(), w, h);
        for (k, v) in [
            r.times.recognition_ns,
            r.times.segmentation_ns,
            r.times.pose_ns,
            r.times.confidence_ns,
            r.times.total_ns(),
        ]
        .into_iter()
        .enumerate()
        {
            times[k + 1].push(v);
        }
        found += r.detection.is_some() as u64;
        let errors = r.estimate.map(|e| {
            (
                (e.theta_deg - frame.truth.theta_deg as f32).abs(),
                phi_error(e.phi_deg, frame.truth.phi_deg as f32),
            )
        });
        let failed = errors.is_none_or(|(dt, dp)| {
            dt > super::eval::FAIL_THETA_DEG || dp > super::eval::FAIL_PHI_DEG
        });
        if let Some((dt, dp)) = errors {
            estimated += 1;
            all_fail += failed as u64;
            if r.accepted() {
                accepted += 1;
                acc_fail += failed as u64;
                sum_theta += dt as f64;
                sum_phi += dp as f64;
            }
        }
        if args.verbose {
            println!("{}", frame_line(i, &frame, &r));
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let elapsed = start.elapsed().as_secs_f64();
    let (cpu1, peak_rss_kb) = self_usage();
    let processes = vec![ProcessUsage {
        stage: "in-process".into(),
        cpu_s: cpu1 - cpu0,
        cpu_pct: 100.0 * (cpu1 - cpu0) / elapsed.max(1e-9),
        peak_rss_kb,
        cpus: super::launch::status_field(std::process::id(), "Cpus_allowed_list:")
            .unwrap_or_default(),
    }];
    let samples = args.samples.then(|| Samples {
        e2e_ns: times[5].clone(),
        hop_ns: Vec::new(),
        process_ns: [
            "capture",
            "recognition",
            "segmentation",
            "pose",
            "confidence",
        ]
        .iter()
        .zip(&times)
        .map(|(n, v)| (n.to_string(), v.clone()))
        .collect(),
    });
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let [
        capture,
        recognition,
        segmentation,
        pose,
        confidence,
        processing,
    ] = times;
    let pct = |mut v: Vec<u64>| Percentiles::of(&mut v);
    let summary = Summary {
        object: object.name().to_owned(),
        background: args.background.to_string(),
        frames,
        fps_target: fps,
        fps_achieved: frames as f64 / elapsed,
        found,
        estimated,
        accepted,
        accepted_mean_phi_err_deg: sum_phi / accepted.max(1) as f64,
        accepted_mean_theta_err_deg: sum_theta / accepted.max(1) as f64,
        accepted_failure_rate: ratio(acc_fail, accepted),
        all_failure_rate: ratio(all_fail, estimated),
        latency: Latency {
            capture: pct(capture),
            recognition: pct(recognition),
            segmentation: pct(segmentation),
            pose: pct(pose),
            confidence: pct(confidence),
            processing: pct(processing),
        },
        mode: "in-process",
        cpu_latency_us: args.cpu_latency_us,
        width: w,
        height: h,
        dropped: 0,
        processes,
        samples,
    };
    print_summary(&summary);
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&summary)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn frame_line(i: u64, frame: &Rendered, r: &FrameResult) -> String {
    let truth = format!(
        "truth θ {:5.1} φ {:5.1}",
        frame.truth.theta_deg, frame.truth.phi_deg
    );
    match (r.estimate, r.rating) {
        (None, _) => format!("{i:5}  {truth}  not found"),
        (Some(e), rating) => format!(
            "{i:5}  {truth}  est θ {:5.1} φ {:5.1}  match {:.3}  {}  {:.2} ms",
            e.theta_deg,
            e.phi_deg,
            e.best_value,
            match rating {
                Some(c) => format!(
                    "conf {:.2} {}",
                    c.confidence,
                    if c.accepted { "accepted" } else { "rejected" }
                ),
                None => "unrated".into(),
            },
            r.times.total_ns() as f64 / 1e6
        ),
    }
}

fn print_summary(s: &Summary) {
    println!(
        "{} frames of {} on background {} at {:.1} fps: found {}, estimated {}, accepted {}",
        s.frames, s.object, s.background, s.fps_achieved, s.found, s.estimated, s.accepted
    );
    println!(
        "accepted: mean |dphi| {:.2} deg, mean |dtheta| {:.2} deg, failures {:.1} % (all estimates: {:.1} %)",
        s.accepted_mean_phi_err_deg,
        s.accepted_mean_theta_err_deg,
        100.0 * s.accepted_failure_rate,
        100.0 * s.all_failure_rate
    );
    println!(
        "{:<14} {:>8} {:>8} {:>8} {:>8}",
        "latency (ms)", "p50", "p90", "p99", "max"
    );
    let l = &s.latency;
    for (name, p) in [
        ("capture", &l.capture),
        ("recognition", &l.recognition),
        ("segmentation", &l.segmentation),
        ("pose", &l.pose),
        ("confidence", &l.confidence),
        ("processing", &l.processing),
    ] {
        println!(
            "{name:<14} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
            p.p50_ms, p.p90_ms, p.p99_ms, p.max_ms
        );
    }
}

/// The default database of a built-in object: trained on first use with the
/// default settings and cached, so later runs start at once.
fn cached_database(
    object: &std::sync::Arc<acch_capture::Object>,
    dir: Option<PathBuf>,
) -> Result<ViewDatabase> {
    cached_database_at(object, dir).map(|(db, _)| db)
}

/// [`cached_database`] and the file it is cached in.
pub(crate) fn cached_database_at(
    object: &std::sync::Arc<acch_capture::Object>,
    dir: Option<PathBuf>,
) -> Result<(ViewDatabase, PathBuf)> {
    let dir = dir
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("acch")))
        .or_else(|| std::env::var_os("HOME").map(|d| PathBuf::from(d).join(".cache/acch")))
        .unwrap_or_else(|| std::env::temp_dir().join("acch"));
    let path = dir.join(format!(
        "{}-v{}-{}-r{}.acchdb",
        object.name(),
        acch_core::database::FORMAT_VERSION,
        env!("CARGO_PKG_VERSION"),
        model::TRAINING_REVISION
    ));
    if path.exists() {
        match ViewDatabase::load(&path) {
            Ok(db) => return Ok((db, path)),
            Err(e) => eprintln!("acch run: retraining: cached database unusable: {e}"),
        }
    }
    eprintln!(
        "acch run: training the database of '{}' (first use; cached in {})",
        object.name(),
        path.display()
    );
    let training = model::RenderedTraining {
        views: super::eval::PAPER_GRID.parse()?,
        background: Background::default(),
        distance: DEFAULT_DISTANCE,
        seed: 0,
    };
    let confidence = Some((
        model::DEFAULT_CONFIDENCE_SCENES,
        model::DEFAULT_CONFIDENCE_KIND,
    ));
    let db = model::train_object(object, &TrainConfig::default(), &training, confidence)?;
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    db.save(&path)?;
    Ok((db, path))
}
