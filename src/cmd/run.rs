//! `acch run`: stream frames through every stage and report accuracy and
//! per-stage latency. The embedded default needs no camera and no files: the
//! built-in fruitbox on the wood background, seen by a simulated eye-in-hand
//! camera moving over the hemisphere, with its database trained on first use
//! and cached.

use super::common::ObjectArgs;
use acch_capture::Background;
use acch_ipc::sched::StageCpus;
use acch_pipeline::config::{ObjectEntry, RecordFormat, Replay, SmoothingChoice, Transport};
use acch_pipeline::{PipelineConfig, RunOptions, RunSummary, StageId};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// Arguments of `acch run`.
#[derive(Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub(crate) object: ObjectArgs,
    /// View database; by default one is trained for the object on first use
    /// and cached (see --cache-dir).
    #[arg(long, value_name = "FILE.acchdb")]
    pub(crate) db: Option<PathBuf>,
    /// With --smoothing auto and --db: the smoothed database of the same
    /// object (`acch train --smoothing binomial --confidence-imaging`).
    /// Without --db both databases are the cached ones, trained on first
    /// use.
    #[arg(long, value_name = "FILE.acchdb", requires = "db")]
    pub(crate) smoothed_db: Option<PathBuf>,
    /// Several known objects at once, comma-separated: built-in names,
    /// generated-N, random:N (N generated objects of the population of
    /// --seed), mesh files and view databases (.acchdb). Every object is
    /// recognised in every frame, and its results and seeds published at
    /// acch/<object>/result and .../seed. A named object's database is
    /// trained (first use, cached) to search the roll within ±45°: objects
    /// off the optical axis are seen rolled. Runs in one process (the
    /// objects' stages as lanes on threads), --in-process or not.
    #[arg(long, value_name = "LIST", conflicts_with_all = ["db", "object", "mesh"])]
    pub(crate) objects: Option<String>,
    /// With --objects: how many of them the simulated scene shows, the
    /// first ones (default: all).
    #[arg(long, value_name = "N", requires = "objects")]
    pub(crate) objects_in_view: Option<usize>,
    /// Where trained default databases are cached.
    #[arg(long, env = "ACCH_CACHE_DIR", value_name = "DIR")]
    pub(crate) cache_dir: Option<PathBuf>,
    /// Use (and on first use train) the databases whose views are lit
    /// from K directions around the vertical: a room's light does not come
    /// from where the training light did (8 holds it from any side;
    /// docs/accuracy.md, "Light from another side"). Default 1, or the
    /// configuration's.
    #[arg(long, value_name = "K")]
    pub(crate) light_directions: Option<usize>,
    /// Use (and on first use train) the databases that smooth views and
    /// frames before quantisation: `off`; `binomial` for a noisy,
    /// compressed or blurred camera, with --confidence-imaging the
    /// configuration measured for such a camera (docs/accuracy.md, "A
    /// noisy, compressed or blurred camera"; it costs a little accuracy on
    /// clean frames and precision among several objects); or `auto`:
    /// recognition measures each frame's noise and JPEG blocking, and the
    /// object's sharpness, and runs a noisy or compressed frame, a blurred
    /// object or one the sharp databases do not find through the smoothed
    /// databases with the confidence for such a camera, the rest through
    /// the sharp ones (both trained on first use; one object). Default
    /// off, or the configuration's.
    #[arg(long, value_name = "off|binomial|auto")]
    pub(crate) smoothing: Option<SmoothingChoice>,
    /// Use (and on first use train) the databases whose confidence network
    /// was trained on scenes under other light and a worse camera and reads
    /// the absolute match value, so a weak match is rejected (`acch train
    /// --confidence-imaging`). Not with --light-directions.
    #[arg(long)]
    pub(crate) confidence_imaging: bool,
    /// Background of the simulated scene: plain, A, B, C, clutter, clutter-similar.
    #[arg(long)]
    pub(crate) background: Option<Background>,
    /// Elevation band the simulated camera sweeps, MIN,MAX degrees (default
    /// 45.5,89.5: inside the database; a lower minimum takes the camera
    /// below it, as a real arm's goes).
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_band)]
    pub(crate) elevation: Option<[f64; 2]>,
    /// Frames to process (default 300, or the configuration's).
    #[arg(long)]
    pub(crate) frames: Option<u64>,
    /// Camera frame rate; 0 runs free (default 30, or the configuration's).
    #[arg(long)]
    pub(crate) fps: Option<f64>,
    /// Frame source: synthetic, folder:DIR (images and labels.csv),
    /// mcap:FILE (replays an `acch run --record` recording),
    /// "gst:PIPELINE" (a GStreamer pipeline as gst-launch-1.0 writes it,
    /// e.g. "gst:v4l2src device=/dev/video0 ! videoconvert"; the build
    /// needs `--features gstreamer`) or camera:/dev/videoN (a V4L2 camera).
    #[arg(long, value_name = "SOURCE")]
    pub(crate) source: Option<String>,
    /// The camera's calibration: a ROS camera_info YAML or an OpenCV
    /// FileStorage YAML (intrinsics, plumb_bob or rational_polynomial
    /// distortion); for folder: and gst: sources.
    #[arg(long, value_name = "FILE.yaml")]
    pub(crate) camera_info: Option<PathBuf>,
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
    pub(crate) stage_cpus: Option<StageCpus>,
    /// Pace of an mcap: replay: recorded (the recording's frame times) or
    /// free (as fast as the pipeline takes frames).
    #[arg(long, value_name = "PACE")]
    pub(crate) replay: Option<Replay>,
    /// Pipeline configuration (TOML; every key is listed in docs/pipeline.md).
    #[arg(long, value_name = "FILE")]
    pub(crate) config: Option<PathBuf>,
    /// Chain the stages in this process instead of one process per stage.
    #[arg(long)]
    pub(crate) in_process: bool,
    /// Run a database that has no confidence network: estimates are
    /// reported as unrated, none is accepted, no seed is published.
    #[arg(long)]
    pub(crate) unrated: bool,
    /// Give up when no result arrives for this many seconds.
    #[arg(long, default_value_t = 20.0)]
    pub(crate) stall_timeout: f64,
    /// Sample every process's resident memory this often (seconds) into
    /// the summary's `rss`.
    #[arg(long, default_value_t = 10.0, value_name = "SECS")]
    pub(crate) rss_every: f64,
    /// Seed of the camera trajectory and the scene.
    #[arg(long)]
    pub(crate) seed: Option<u64>,
    /// Write the summary as JSON.
    #[arg(long, value_name = "FILE")]
    pub(crate) json: Option<PathBuf>,
    /// Write every frame's result as a line of JSON (as published on zenoh).
    #[arg(long, value_name = "FILE.jsonl")]
    pub(crate) results: Option<PathBuf>,
    /// Frame size of the synthetic camera, or the size a gst: source asks
    /// the camera for (it adopts the stream's if the camera has no such
    /// mode), WIDTHxHEIGHT (default 640x480, or the configuration's).
    #[arg(long, value_name = "WxH", value_parser = acch_bench::parse_resolution)]
    pub(crate) resolution: Option<(u32, u32)>,
    /// How frames reach recognition: shm (zero copy) or copy (the
    /// benchmark's baseline: through a Unix socket).
    #[arg(long)]
    pub(crate) transport: Option<Transport>,
    /// Log what the pipeline sees to rerun: save:FILE.rrd, spawn (starts a
    /// viewer) or connect:URL.
    #[arg(long, value_name = "SINK")]
    pub(crate) rerun: Option<String>,
    /// Record every frame and result: to this MCAP file, or with
    /// --record-format ros2 to a rosbag2 bag directory of this name (less
    /// .mcap).
    #[arg(long, value_name = "FILE.mcap")]
    pub(crate) record: Option<PathBuf>,
    /// What --record writes: foxglove (frames, masks, responses, results;
    /// replayable with --source mcap:FILE) or ros2 (the ROS 2 topics and
    /// every frame as sensor_msgs/Image, for `ros2 bag play`).
    #[arg(long, value_name = "FORMAT")]
    pub(crate) record_format: Option<RecordFormat>,
    /// Publish on ROS 2 topics over zenoh as an rmw_zenoh node: the seeds
    /// and fused poses (geometry_msgs/PoseWithCovarianceStamped, metres),
    /// camera info and /tf, under the [ros2] namespace (see
    /// docs/ros2.md). No ROS installation needed.
    #[arg(long)]
    pub(crate) ros2: bool,
    /// Also write every frame's latencies (ns) into the JSON summary.
    #[arg(long, hide = true)]
    pub(crate) samples: bool,
}

impl RunArgs {
    /// The configuration: the file's (or the defaults), with every flag
    /// given laid over it.
    fn config(&self) -> Result<PipelineConfig> {
        let mut cfg = match &self.config {
            Some(p) => PipelineConfig::load(p).with_context(|| format!("in {}", p.display()))?,
            None => PipelineConfig::default(),
        };
        macro_rules! set {
            ($($flag:ident => $($key:ident).+),*) => {
                $(if let Some(v) = &self.$flag { cfg.$($key).+ = v.clone().into(); })*
            };
        }
        set!(frames => camera.frames, fps => camera.fps, source => camera.source,
             replay => camera.replay, seed => synthetic.seed, background => synthetic.background,
             smoothing => estimate.smoothing, transport => run.transport,
             rt_priority => run.realtime_priority, stage_cpus => run.stage_cpus,
             record_format => observers.record_format);
        cfg.ros2.enabled |= self.ros2;
        if let Some(e) = self.elevation {
            cfg.synthetic.elevation_deg = e;
        }
        if let Some((w, h)) = self.resolution {
            (cfg.camera.width, cfg.camera.height) = (w, h);
        }
        if self.cpu_latency_us.is_some() {
            cfg.run.cpu_latency_us = self.cpu_latency_us;
        }
        if self.rerun.is_some() {
            cfg.observers.rerun.clone_from(&self.rerun);
        }
        if self.record.is_some() {
            cfg.observers.record.clone_from(&self.record);
        }
        if self.db.is_some() {
            cfg.object.db.clone_from(&self.db);
            cfg.object.smoothed_db.clone_from(&self.smoothed_db);
        }
        if self.camera_info.is_some() {
            cfg.camera.camera_info.clone_from(&self.camera_info);
        }
        if let Some(name) = &self.object.object {
            cfg.object.name.clone_from(name);
        }
        if let Some(mesh) = &self.object.mesh {
            cfg.object.mesh = Some(mesh.clone());
            if let Some(up) = self.object.mesh_up {
                cfg.object.mesh_up = up;
            }
            cfg.object.mesh_unit_m = self.object.mesh_unit_m;
        }
        if let Some(r) = self.object.object_radius_m {
            cfg.object.radius_m = Some(r);
        }
        cfg.estimate.unrated |= self.unrated;
        // A replay runs the whole recording unless told otherwise.
        if let Some(path) = cfg.camera.source.strip_prefix("mcap:")
            && self.frames.is_none()
        {
            cfg.camera.frames = acch_record::scan(Path::new(path))
                .with_context(|| format!("reading the recording {path}"))?
                .frames;
        }
        // A mesh's object goes by its own name in results and topics.
        if cfg.object.mesh.is_some() {
            cfg.object.name = cfg
                .scene_object()
                .context("invalid pipeline configuration")?
                .name()
                .to_owned();
        }
        if let Some(list) = &self.objects {
            cfg.objects.list = expand_objects(list, cfg.synthetic.seed)?;
            cfg.objects.dbs.clear();
        }
        if let Some(n) = self.objects_in_view {
            cfg.objects.in_view = n;
        }
        if let Some(k) = self.light_directions {
            cfg.estimate.light_directions = k;
        }
        cfg.estimate.confidence_imaging |= self.confidence_imaging;
        cfg.validate().context("invalid pipeline configuration")?;
        if !cfg.objects.list.is_empty() {
            if cfg.objects.dbs.is_empty() {
                cfg.objects.dbs = self.object_databases(&cfg)?;
            }
            return Ok(cfg);
        }
        if cfg.object.db.is_none() {
            let object = std::sync::Arc::new(cfg.scene_object()?);
            let cache = self.cache_dir.clone().or(cfg.object.cache_dir.clone());
            let recipe = acch_train::cache::Recipe {
                light_directions: cfg.estimate.light_directions,
                smoothing: cfg.smoothing(),
                imaging: cfg.estimate.confidence_imaging,
                ..Default::default()
            };
            let (_, path) =
                acch_train::cache::cached_recipe_database(&object, cache.clone(), recipe)?;
            cfg.object.db = Some(path);
            if cfg.estimate.smoothing == SmoothingChoice::ByFrame {
                let smoothed = recipe.smoothed_set();
                let (_, path) =
                    acch_train::cache::cached_recipe_database(&object, cache, smoothed)?;
                cfg.object.smoothed_db = Some(path);
            }
        }
        Ok(cfg)
    }
}

impl RunArgs {
    /// The database of every entry of `objects.list`: a database file as it
    /// is; for a built-in object or a mesh the cached one trained for the
    /// roll search objects off the optical axis need (on first use).
    fn object_databases(&self, cfg: &PipelineConfig) -> Result<Vec<PathBuf>> {
        let up = cfg.object.mesh_up;
        let cache = self.cache_dir.clone().or(cfg.object.cache_dir.clone());
        cfg.object_entries()
            .into_iter()
            .map(|entry| match entry {
                ObjectEntry::Database(path) => Ok(path),
                other => {
                    let object = std::sync::Arc::new(other.object(up, cfg.object.mesh_unit_m)?);
                    let recipe = acch_train::cache::Recipe {
                        roll_search_deg: acch_train::cache::OFF_AXIS_ROLL_SEARCH_DEG,
                        light_directions: cfg.estimate.light_directions,
                        smoothing: cfg.smoothing(),
                        imaging: cfg.estimate.confidence_imaging,
                        ..Default::default()
                    };
                    Ok(
                        acch_train::cache::cached_recipe_database(&object, cache.clone(), recipe)?
                            .1,
                    )
                }
            })
            .collect()
    }
}

/// `--objects LIST` as configuration entries: `random:N` becomes the
/// names of N generated objects of the population of `seed`.
fn expand_objects(list: &str, seed: u64) -> Result<Vec<String>> {
    let mut out = Vec::new();
    for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        match item.strip_prefix("random:") {
            Some(n) => {
                let n: usize = n
                    .parse()
                    .ok()
                    .filter(|&n| (1..=acch_capture::MAX_SCENE_OBJECTS).contains(&n))
                    .with_context(|| format!("--objects {item}: N must be a number in 1..=16"))?;
                out.extend(acch_capture::population(seed, n));
            }
            None => out.push(item.to_owned()),
        }
    }
    if out.is_empty() {
        bail!("--objects '{list}' names no object");
    }
    Ok(out)
}

/// Parses `MIN,MAX` degrees (checked with the rest of the configuration).
fn parse_band(s: &str) -> Result<[f64; 2], String> {
    let (lo, hi) = s
        .split_once(',')
        .ok_or_else(|| format!("'{s}' is not MIN,MAX"))?;
    let num = |v: &str| {
        v.trim()
            .parse::<f64>()
            .map_err(|_| format!("'{s}': '{v}' is not a number of degrees"))
    };
    Ok([num(lo)?, num(hi)?])
}

/// Runs `acch run`.
pub fn run(args: RunArgs) -> Result<()> {
    for (name, v) in [
        ("--stall-timeout", args.stall_timeout),
        ("--rss-every", args.rss_every),
    ] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{name} {v}: must be a positive number of seconds");
        }
    }
    let cfg = args.config()?;
    let opts = RunOptions {
        stall_timeout: Duration::from_secs_f64(args.stall_timeout.max(1.0)),
        rss_every: Duration::from_secs_f64(args.rss_every.max(0.1)),
        samples: args.samples,
        results: args.results.clone(),
        zenoh: true,
    };
    if cfg.estimate.unrated {
        eprintln!(
            "acch run: UNRATED: the run rates no estimate, so none is accepted and no seed is published"
        );
    }
    // Which recipe a run uses shows in its databases' names.
    let single = cfg.object.db.iter().filter(|_| cfg.objects.list.is_empty());
    for db in single.chain(&cfg.objects.dbs) {
        eprintln!("acch run: view database {}", db.display());
    }
    if let Some(db) = cfg
        .object
        .smoothed_db
        .as_ref()
        .filter(|_| cfg.estimate.smoothing == SmoothingChoice::ByFrame)
    {
        eprintln!(
            "acch run: smoothed view database for noisy, compressed or blurred frames {}",
            db.display()
        );
    }
    // The stage processes carry one object: several run in one process.
    let summary = if args.in_process || !cfg.objects.list.is_empty() {
        let what = if cfg.objects.list.is_empty() {
            cfg.object.name.clone()
        } else {
            cfg.objects.list.join(", ")
        };
        let how = if args.in_process || cfg.objects.list.is_empty() {
            ""
        } else {
            " (several objects run as lanes on threads of one process; the stage processes carry one object)"
        };
        eprintln!(
            "acch run: {} frames of {what} in one process{how}",
            cfg.camera.frames
        );
        acch_pipeline::run_in_process(&cfg, &opts)?
    } else {
        let exe = std::env::current_exe().context("locating the acch executable")?;
        let spawn = move |name: &str, config: &Path| {
            Command::new(&exe)
                .arg("stage")
                .arg(name)
                .arg("--config")
                .arg(config)
                .spawn()
        };
        acch_pipeline::run_processes(cfg, &opts, spawn)?
    };
    print_summary(&summary);
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&summary)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// The rejected count, with how many a far view's match, a broad crest in
/// azimuth, a view placing the region better or a faint detection
/// rejected whatever their rating.
fn rejections(o: &acch_pipeline::summary::Outcomes) -> String {
    if o.rejected_ambiguous + o.rejected_broad + o.rejected_misplaced + o.rejected_faint == 0 {
        return o.rejected.to_string();
    }
    format!(
        "{} ({} for a far view matching as well, {} for a broad crest in azimuth, {} for a \
         view beyond the tolerance placing it better, {} found faintly and matched weakly)",
        o.rejected, o.rejected_ambiguous, o.rejected_broad, o.rejected_misplaced, o.rejected_faint
    )
}

fn print_summary(s: &RunSummary) {
    let o = &s.outcomes;
    println!(
        "{} of {} frames of {} ({}) at {:.1} fps: found {}, estimated {}, accepted {}, rejected {}, seeds {}",
        o.results,
        s.frames_requested,
        s.object,
        s.mode,
        s.fps_achieved,
        o.found,
        o.estimated,
        o.accepted,
        rejections(o),
        o.seeds
    );
    if s.unrated {
        println!("accepted: none (unrated run: nothing accepted)");
    } else if o.accepted_with_truth == 0 {
        // A real camera, or a scene of several objects: nothing to judge by.
        println!("accepted: no ground truth in the frames, so no errors to report");
    } else {
        println!(
            "accepted: mean |dphi| {:.2} deg, mean |dtheta| {:.2} deg, {} of {} with ground truth beyond the failure thresholds",
            o.accepted_mean_phi_err_deg,
            o.accepted_mean_theta_err_deg,
            o.accepted_wrong,
            o.accepted_with_truth,
        );
    }
    if o.faulted > 0 {
        println!(
            "faults: {} frames a stage could not process (see stage_counters)",
            o.faulted
        );
    }
    for object in &s.objects {
        let o = &object.outcomes;
        println!(
            "  {}: found {}, estimated {}, accepted {}, rejected {}, withdrawn for another object {}",
            object.object,
            o.found,
            o.estimated,
            o.accepted,
            rejections(o),
            object.suppressed
        );
    }
    if !s.restarts.is_empty() || s.dropped > 0 {
        println!(
            "reliability: {} frames dropped, {} restarts ({}), {} dead nodes cleaned during the run",
            s.dropped,
            s.restarts.len(),
            s.restarts
                .iter()
                .map(|r| r.stage)
                .collect::<Vec<_>>()
                .join(", "),
            s.stale_nodes_removed_during_run
        );
    }
    for t in &s.rss_trend {
        println!(
            "rss {:<13} start {:>7} kB, end {:>7} kB, max {:>7} kB",
            t.process, t.start_kb, t.end_kb, t.max_kb
        );
    }
    match s.transport.as_str() {
        "copy" => println!(
            "copy transport: {} frame reads, each from recognition's own copy of the frame",
            s.frame_reads
        ),
        "shm" => println!(
            "zero copy: {} of {} frame reads found the pixels at the capture's shared-memory offset; {:.1} MB of frames written once",
            s.frame_reads_in_place,
            s.frame_reads,
            s.frame_bytes_published as f64 / 1e6
        ),
        _ => {}
    }
    println!(
        "{:<14} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "latency (ms)", "hop p50", "hop p99", "proc p50", "proc p99", "proc max"
    );
    for st in &s.stages {
        let hop = st.stage != StageId::Capture.name() && s.mode == "processes";
        let (h50, h99) = if hop {
            (
                format!("{:.3}", st.hop.p50_ms),
                format!("{:.3}", st.hop.p99_ms),
            )
        } else {
            ("-".into(), "-".into())
        };
        println!(
            "{:<14} {:>9} {:>9} {:>9.3} {:>9.3} {:>9.3}",
            st.stage, h50, h99, st.process.p50_ms, st.process.p99_ms, st.process.max_ms
        );
    }
    let e = &s.end_to_end;
    println!(
        "end to end (captured -> result published): p50 {:.3} ms, p90 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        e.p50_ms, e.p90_ms, e.p99_ms, e.max_ms
    );
}
