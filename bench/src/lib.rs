//! The latency benchmark (`acch bench`). For every resolution and frame rate
//! it runs the pipeline three ways in one invocation, one after the other on
//! the same machine:
//!
//! - `shm`: the stage processes with frames in shared memory (`acch run`);
//! - `in-process`: the same stage functions chained on one thread
//!   (`acch run --in-process`), the compute floor;
//! - `copy`: the same stage processes with every frame copied through a Unix
//!   socket to recognition, the one stage that reads pixels (`acch run
//!   --transport copy`).
//!
//! Each run is a child `acch run --json FILE`; the benchmark reads their
//! summaries (every frame's CLOCK_MONOTONIC trail) and writes one JSON
//! report and a PNG of latency CDFs. End-to-end latency starts when capture
//! publishes the frame (after rendering it), as in `acch run`.

mod multi;

use acch_viz::plot::{PlotError, draw_err, draw_png};
use plotters::prelude::*;
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Why the benchmark stopped.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// An option is out of range.
    #[error("{0}")]
    Input(String),
    /// A run of `acch run` failed.
    #[error("acch run ({what}) failed: {stderr}")]
    Run {
        /// The mode and configuration.
        what: String,
        /// What it printed on stderr.
        stderr: String,
    },
    /// A file could not be read or written, or a run not started.
    #[error("{}", path.display())]
    Io {
        /// The file or program.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// A run's summary is not what `acch run --json` writes.
    #[error("{what}: not a run summary")]
    Summary {
        /// The mode and configuration.
        what: String,
    },
    /// The plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The CPU latency request was refused.
    #[error(transparent)]
    CpuLatency(#[from] acch_pipeline::RunError),
}

type Result<T, E = BenchError> = std::result::Result<T, E>;

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> BenchError + '_ {
    move |source| BenchError::Io {
        path: path.to_owned(),
        source,
    }
}

/// What to measure (the arguments of `acch bench`).
#[derive(clap::Args, Clone, Debug)]
pub struct BenchArgs {
    /// The `acch` executable whose `run` is measured (the caller's own).
    #[arg(skip)]
    pub exe: PathBuf,
    /// Frames per run.
    #[arg(long, default_value_t = 300)]
    pub frames: u64,
    /// Frames at the start of every run, in every mode, left out of the
    /// percentiles: the first frame through fresh processes maps shared
    /// memory and faults in code and data (its hops take 100-230 µs against
    /// 20-45 µs after), and with `--repeat` those few frames would set the
    /// p99. They are reported on their own (`warmup`).
    #[arg(long, default_value_t = 5)]
    pub warmup: u64,
    /// Frame rates, comma-separated; 0 = free-running.
    #[arg(long, value_delimiter = ',', default_value = "15,30,60,0")]
    pub fps: Vec<f64>,
    /// Frame sizes, comma-separated WIDTHxHEIGHT.
    #[arg(long, value_delimiter = ',', default_value = "640x480,1280x720",
          value_parser = parse_resolution)]
    pub resolution: Vec<(u32, u32)>,
    /// The JSON report.
    #[arg(long, default_value = "bench/results/latency.json")]
    pub json: PathBuf,
    /// The plot: CDFs of per-stage compute, per-hop and end-to-end latency
    /// of the headline configuration (640x480 at 30 fps when measured).
    #[arg(long, default_value = "bench/results/latency.png")]
    pub png: PathBuf,
    /// Seed of the camera trajectory and the scene.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also run the processes under SCHED_FIFO at this priority (mode
    /// `shm-rt`, `acch run --rt-priority`); needs CAP_SYS_NICE.
    #[arg(long, value_name = "PRIORITY")]
    pub rt_priority: Option<u8>,
    /// Hold the CPUs' wake-up latency at this many µs in every mode,
    /// baselines included (`acch run --cpu-latency-us`; 0: idle CPUs poll
    /// instead of halting). Needs root.
    #[arg(long, value_name = "US")]
    pub cpu_latency_us: Option<u32>,
    /// CPUs of the processing stages in every mode (`acch run
    /// --stage-cpus`): auto, none or a list like 1.
    #[arg(long, value_name = "CPUS", default_value = "auto")]
    pub stage_cpus: String,
    /// Runs of every mode per configuration, modes interleaved (shm,
    /// in-process, copy, shm-rt, shm, ...); percentiles pool the frames of
    /// all runs, so a slow spell of the machine weighs on every mode alike.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeat: u32,
    /// Measure several objects at once instead (`acch run --in-process
    /// --objects`, 640x480 at 30 fps): the known objects, in order, as
    /// `acch run --objects` takes them; the first --known of them are
    /// known and the first --in-view of those in view.
    #[arg(long, value_name = "LIST")]
    pub objects: Option<String>,
    /// With --objects: how many objects are known, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,2,4,8",
        requires = "objects"
    )]
    pub known: Vec<usize>,
    /// With --objects: how many of the known are in view, comma-separated
    /// (each at most the number known).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,2,3,4",
        requires = "objects"
    )]
    pub in_view: Vec<usize>,
    /// With --objects: the JSON report.
    #[arg(long, default_value = "bench/results/multi.json")]
    pub objects_json: PathBuf,
    /// With --objects: the plot of e2e latency against objects known.
    #[arg(long, default_value = "bench/results/multi.png")]
    pub objects_png: PathBuf,
    /// Also measure the GStreamer source (mode `gst`, at the rates above
    /// 0): the same scene rendered to PNG files first, then played by
    /// `multifilesrc ! pngdec` at the rate, so capture's cost per frame
    /// and its hop are measured beside the synthetic camera's. Needs a
    /// build with `--features gstreamer`.
    #[arg(long)]
    pub gst: bool,
}

/// Percentiles in milliseconds of nanosecond samples.
fn pct_ms(v: &[u64]) -> Value {
    let mut s = v.to_vec();
    s.sort_unstable();
    let at = |q: f64| -> f64 {
        if s.is_empty() {
            return 0.0;
        }
        s[((s.len() - 1) as f64 * q).round() as usize] as f64 / 1e6
    };
    json!({"p50_ms": at(0.5), "p90_ms": at(0.9), "p99_ms": at(0.99), "max_ms": at(1.0)})
}

fn q_ms(v: &[u64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_unstable();
    if s.is_empty() {
        return 0.0;
    }
    s[((s.len() - 1) as f64 * q).round() as usize] as f64 / 1e6
}

/// A named series of nanosecond samples.
type Series = (String, Vec<u64>);

/// One run's raw samples and summary.
struct RunResult {
    mode: &'static str,
    summary: Value,
    e2e: Vec<u64>,
    hops: Vec<(String, Vec<u64>)>,
    process: Vec<(String, Vec<u64>)>,
    /// End-to-end latency of the warm-up frames, left out of `e2e`.
    warmup_e2e: Vec<u64>,
    /// Every hop of the warm-up frames, all stages.
    warmup_hops: Vec<u64>,
}

impl RunResult {
    /// The runs of one mode as one: samples pooled, the summary of the
    /// first run with the lowest throughput of any; `e2e_p50_ms_per_run`
    /// keeps each run's median to show the spread.
    fn pooled(mut runs: Vec<RunResult>) -> RunResult {
        let per_run: Vec<f64> = runs.iter().map(|r| q_ms(&r.e2e, 0.5)).collect();
        let slowest = runs
            .iter()
            .filter_map(|r| r.summary["fps_achieved"].as_f64())
            .fold(f64::INFINITY, f64::min);
        let mut all = runs.remove(0);
        for r in runs {
            all.e2e.extend(r.e2e);
            all.warmup_e2e.extend(r.warmup_e2e);
            all.warmup_hops.extend(r.warmup_hops);
            for (into, from) in [(&mut all.hops, r.hops), (&mut all.process, r.process)] {
                for (name, xs) in from {
                    match into.iter_mut().find(|(n, _)| *n == name) {
                        Some((_, v)) => v.extend(xs),
                        None => into.push((name, xs)),
                    }
                }
            }
        }
        if slowest.is_finite() {
            all.summary["fps_achieved"] = json!(slowest);
        }
        all.summary["e2e_p50_ms_per_run"] = json!(per_run);
        all
    }
}

fn series(v: &Value) -> Vec<(String, Vec<u64>)> {
    v.as_array()
        .map(|a| {
            a.iter()
                .filter_map(|p| {
                    let name = p.get(0)?.as_str()?.to_owned();
                    let xs = p.get(1)?.as_array()?.iter().filter_map(Value::as_u64);
                    Some((name, xs.collect()))
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Renders the frames of the `gst` mode for `w` x `h`: the views of the
/// synthetic camera's object as PNG files `view_NNNN.png`.
fn render_frames(args: &BenchArgs, (w, h): (u32, u32), tmp: &Path) -> Result<PathBuf> {
    let dir = tmp.join(format!("frames-{w}x{h}"));
    if dir.exists() {
        return Ok(dir);
    }
    eprintln!(
        "acch bench: rendering {} frames of {w}x{h} for the gst mode",
        args.frames
    );
    let o = Command::new(&args.exe)
        .args(["render", "--object", "fruitbox", "--background", "A"])
        .args(["--views", &format!("random:{}", args.frames)])
        .args(["--width", &w.to_string(), "--height", &h.to_string()])
        .args(["--seed", &args.seed.to_string(), "--out"])
        .arg(&dir)
        .stdout(std::process::Stdio::null())
        .output()
        .map_err(io_err(&args.exe))?;
    if !o.status.success() {
        return Err(BenchError::Run {
            what: format!("rendering the gst mode's frames into {}", dir.display()),
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        });
    }
    Ok(dir)
}

fn run_once(
    args: &BenchArgs,
    mode: &'static str,
    (w, h): (u32, u32),
    fps: f64,
    tmp: &Path,
) -> Result<RunResult> {
    let out = tmp.join(format!("{mode}-{w}x{h}-{fps}.json"));
    let mut cmd = Command::new(&args.exe);
    cmd.arg("run")
        .args(["--frames", &args.frames.to_string()])
        .args(["--fps", &fps.to_string()])
        .args(["--resolution", &format!("{w}x{h}")])
        .args(["--seed", &args.seed.to_string()])
        .args(["--stage-cpus", &args.stage_cpus])
        .arg("--samples")
        .arg("--json")
        .arg(&out);
    if let Some(us) = args.cpu_latency_us {
        cmd.args(["--cpu-latency-us", &us.to_string()]);
    }
    match mode {
        "in-process" => {
            cmd.arg("--in-process");
        }
        "copy" => {
            cmd.args(["--transport", "copy"]);
        }
        "shm-rt" => {
            let p = args.rt_priority.unwrap_or(1);
            cmd.args(["--transport", "shm", "--rt-priority", &p.to_string()]);
        }
        "gst" => {
            let frames = render_frames(args, (w, h), tmp)?;
            cmd.args(["--transport", "shm", "--source"]).arg(format!(
                "gst:multifilesrc location={}/view_%04d.png index=0 \
                 caps=image/png,framerate={}/1000 ! pngdec",
                frames.display(),
                (fps * 1000.0).round()
            ));
        }
        _ => {
            cmd.args(["--transport", "shm"]);
        }
    }
    eprintln!(
        "acch bench: {mode} {w}x{h} at {fps} fps, {} frames",
        args.frames
    );
    measure(args, mode, cmd, &out, format!("{mode} {w}x{h} {fps} fps"))
}

/// Runs `cmd`, an `acch run --samples --json out`, and reads its samples,
/// the first `--warmup` frames set apart.
fn measure(
    args: &BenchArgs,
    mode: &'static str,
    mut cmd: Command,
    out: &Path,
    what: String,
) -> Result<RunResult> {
    let o = cmd
        .stdout(std::process::Stdio::null())
        .output()
        .map_err(io_err(&args.exe))?;
    if !o.status.success() {
        return Err(BenchError::Run {
            what,
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        });
    }
    let text = std::fs::read_to_string(out).map_err(io_err(out))?;
    let _ = std::fs::remove_file(out);
    let mut summary: Value =
        serde_json::from_str(&text).map_err(|_| BenchError::Summary { what: what.clone() })?;
    let samples = summary
        .as_object_mut()
        .and_then(|o| o.remove("samples"))
        .ok_or(BenchError::Summary { what })?;
    let mut e2e: Vec<u64> = samples["e2e_ns"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_u64).collect())
        .unwrap_or_default();
    let mut hops = series(&samples["hop_ns"]);
    let mut process = series(&samples["process_ns"]);
    // Samples come in frame order: the first `warmup` of each series are
    // the run's first frames.
    let skip = |v: &mut Vec<u64>| {
        v.drain(..(args.warmup as usize).min(v.len()))
            .collect::<Vec<_>>()
    };
    let warmup_e2e = skip(&mut e2e);
    let warmup_hops = hops.iter_mut().flat_map(|(_, v)| skip(v)).collect();
    for (_, v) in &mut process {
        skip(v);
    }
    Ok(RunResult {
        mode,
        e2e,
        hops,
        process,
        summary,
        warmup_e2e,
        warmup_hops,
    })
}

/// One mode's figures.
fn figures(r: &RunResult, frames: u64, warmup: u64) -> Value {
    let hops: serde_json::Map<String, Value> = r
        .hops
        .iter()
        .map(|(n, v)| {
            (
                n.clone(),
                json!({"p50_us": q_ms(v, 0.5) * 1e3, "p99_us": q_ms(v, 0.99) * 1e3,
                       "max_us": q_ms(v, 1.0) * 1e3}),
            )
        })
        .collect();
    let compute: serde_json::Map<String, Value> = r
        .process
        .iter()
        .map(|(n, v)| (n.clone(), pct_ms(v)))
        .collect();
    let hop_p99_us = r
        .hops
        .iter()
        .map(|(_, v)| q_ms(v, 0.99) * 1e3)
        .fold(0.0, f64::max);
    let s = &r.summary;
    let results = r.e2e.len() as u64;
    json!({
        "mode": r.mode,
        "e2e_p50_ms": q_ms(&r.e2e, 0.5),
        "e2e_p90_ms": q_ms(&r.e2e, 0.9),
        "e2e_p99_ms": q_ms(&r.e2e, 0.99),
        "e2e_max_ms": q_ms(&r.e2e, 1.0),
        "hop_p99_us": hop_p99_us,
        "hops": hops,
        "compute": compute,
        "throughput_fps": s["fps_achieved"],
        "results": results,
        "dropped": frames.saturating_sub(results + r.warmup_e2e.len() as u64),
        "warmup": {"frames": r.warmup_e2e.len(), "per_run": warmup,
                   "e2e_max_ms": q_ms(&r.warmup_e2e, 1.0),
                   "hop_max_us": q_ms(&r.warmup_hops, 1.0) * 1e3},
        "processes": s["processes"],
        "placement": s.get("placement"),
        "e2e_p50_ms_per_run": s.get("e2e_p50_ms_per_run"),
        "frame_reads": s.get("frame_reads"),
        "frame_reads_in_place": s.get("frame_reads_in_place"),
    })
}

/// Where the processes' extra median latency comes from: the hops (sum of
/// per-hop medians) and the stages' extra compute (sum over stages of the
/// process median minus the in-process median: segmentation and pose copy
/// recognition's palette indices and cell counts out of shared memory).
fn breakdown(shm: &RunResult, inproc: &RunResult) -> Value {
    let hops: f64 = shm.hops.iter().map(|(_, v)| q_ms(v, 0.5)).sum();
    let mut per_stage = serde_json::Map::new();
    let mut compute = 0.0;
    for (name, v) in shm.process.iter().filter(|(n, _)| n != "capture") {
        let floor = inproc
            .process
            .iter()
            .find(|(n, _)| n == name)
            .map_or(0.0, |(_, w)| q_ms(w, 0.5));
        let extra = q_ms(v, 0.5) - floor;
        compute += extra;
        per_stage.insert(name.clone(), json!(extra));
    }
    json!({"hops_p50_sum": hops, "extra_compute_p50_sum": compute, "extra_compute_by_stage": per_stage})
}

#[derive(Serialize)]
struct Machine {
    cpus: usize,
    cpu_model: String,
    kernel: String,
}

fn machine() -> Machine {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    Machine {
        cpus: std::thread::available_parallelism().map_or(0, |n| n.get()),
        cpu_model: cpuinfo
            .lines()
            .find_map(|l| l.strip_prefix("model name"))
            .map(|l| l.trim_start_matches([' ', '\t', ':']).to_owned())
            .unwrap_or_default(),
        kernel: std::fs::read_to_string("/proc/sys/kernel/osrelease")
            .unwrap_or_default()
            .trim()
            .to_owned(),
    }
}

/// Runs the benchmark: every mode of every configuration, the JSON report
/// and the plot.
pub fn run(args: BenchArgs) -> Result<()> {
    if let Some(list) = &args.objects {
        return multi::run(&args, list);
    }
    if let Err(e) = args.stage_cpus.parse::<acch_ipc::sched::StageCpus>() {
        return Err(BenchError::Input(format!(
            "--stage-cpus {}: {e}",
            args.stage_cpus
        )));
    }
    if args.fps.iter().any(|f| !(f.is_finite() && *f >= 0.0)) {
        return Err(BenchError::Input(
            "--fps: every rate must be a number >= 0".into(),
        ));
    }
    if args.warmup >= args.frames {
        return Err(BenchError::Input(format!(
            "--warmup {} leaves nothing to measure of --frames {}",
            args.warmup, args.frames
        )));
    }
    // Held between the runs as well, so every mode meets the same machine;
    // refused here, before anything runs, when it cannot be held.
    let _cpu_latency =
        acch_pipeline::run::hold_cpu_latency(args.cpu_latency_us, "--cpu-latency-us")?;
    let tmp = std::env::temp_dir().join(format!("acch-bench-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
    let mut configs = Vec::new();
    let mut plotted: Option<(String, Vec<RunResult>)> = None;
    for &res in &args.resolution {
        for &fps in &args.fps {
            let mut modes: Vec<&'static str> = vec!["shm", "in-process", "copy"];
            if args.rt_priority.is_some() {
                modes.push("shm-rt");
            }
            // A file source needs a rate to play at.
            if args.gst && fps > 0.0 {
                modes.push("gst");
            }
            let mut by_mode: Vec<Vec<RunResult>> = modes.iter().map(|_| Vec::new()).collect();
            for _ in 0..args.repeat {
                for (m, runs) in modes.iter().zip(&mut by_mode) {
                    runs.push(run_once(&args, m, res, fps, &tmp)?);
                }
            }
            let runs: Vec<RunResult> = by_mode.into_iter().map(RunResult::pooled).collect();
            let frames = args.frames * u64::from(args.repeat);
            let f: Vec<Value> = runs
                .iter()
                .map(|r| figures(r, frames, args.warmup))
                .collect();
            let (shm, inproc, copy) = (&f[0], &f[1], &f[2]);
            let frame_hop = |v: &Value, k: &str| v["hops"]["recognition"][k].as_f64();
            let label = format!("{}x{} at {}", res.0, res.1, fps_label(fps));
            let mut mode_figures = json!({"shm": shm, "in-process": inproc, "copy": copy});
            let mut config = against(shm, inproc, copy);
            for (k, v) in [
                ("resolution", json!(format!("{}x{}", res.0, res.1))),
                ("fps", json!(fps)),
                ("frames", json!(args.frames)),
                ("repeat", json!(args.repeat)),
                ("e2e_p90_ms", shm["e2e_p90_ms"].clone()),
                ("e2e_max_ms", shm["e2e_max_ms"].clone()),
                ("throughput_fps", shm["throughput_fps"].clone()),
                ("overhead_breakdown_ms", breakdown(&runs[0], &runs[1])),
                ("speedup_vs_copy_p99", json!(ratio(copy, shm, "e2e_p99_ms"))),
                (
                    "frame_hop_p50_us",
                    json!({"shm": frame_hop(shm, "p50_us"), "copy": frame_hop(copy, "p50_us")}),
                ),
                (
                    "frame_hop_p99_us",
                    json!({"shm": frame_hop(shm, "p99_us"), "copy": frame_hop(copy, "p99_us")}),
                ),
            ] {
                config[k] = v;
            }
            let of_mode = |m: &str| runs.iter().position(|r| r.mode == m).map(|i| &f[i]);
            if let Some(g) = of_mode("gst") {
                mode_figures["gst"] = g.clone();
                // The GStreamer source beside the synthetic camera: what
                // capture costs a frame (buffer to published) and its hop.
                config["gst_capture"] = json!({
                    "capture_ms": {"synthetic": shm["compute"]["capture"], "gst": g["compute"]["capture"]},
                    "frame_hop_p50_us": {"synthetic": frame_hop(shm, "p50_us"), "gst": frame_hop(g, "p50_us")},
                    "frame_hop_p99_us": {"synthetic": frame_hop(shm, "p99_us"), "gst": frame_hop(g, "p99_us")},
                    "e2e_p99_ms": {"synthetic": shm["e2e_p99_ms"], "gst": g["e2e_p99_ms"]},
                    "capture_cpu_pct": {
                        "synthetic": capture_cpu(shm),
                        "gst": capture_cpu(g),
                    },
                });
            }
            if let Some(rt) = of_mode("shm-rt") {
                mode_figures["shm-rt"] = rt.clone();
                let mut realtime = against(rt, inproc, copy);
                realtime["priority"] = json!(args.rt_priority);
                config["realtime"] = realtime;
            }
            config["modes"] = mode_figures;
            configs.push(config);
            let headline = res == (640, 480) && fps == 30.0;
            if plotted.is_none() || headline {
                plotted = Some((label, runs));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
    let head = configs
        .iter()
        .find(|c| c["resolution"] == "640x480" && c["fps"].as_f64() == Some(30.0))
        .or(configs.first())
        .cloned()
        .ok_or_else(|| {
            BenchError::Input("nothing measured: give at least one --fps and --resolution".into())
        })?;
    let mut report = json!({
        "machine": machine(),
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "cpu_latency_us": args.cpu_latency_us,
        "warmup_frames_per_run": args.warmup,
        "headline": format!("{} at {} fps", head["resolution"].as_str().unwrap_or(""), head["fps"]),
        "targets": {"hop_p99_us": 50.0, "e2e_p99_ms": 15.0, "overhead_vs_inprocess": 0.10,
                    "fps_without_drops": 60.0},
        "configs": configs,
    });
    for k in [
        "e2e_p50_ms",
        "e2e_p99_ms",
        "hop_p99_us",
        "overhead_vs_inprocess",
        "speedup_vs_copy",
        "dropped",
    ] {
        report[k] = head[k].clone();
    }
    if let Some(rt) = head.get("realtime") {
        report["realtime"] = rt.clone();
    }
    for p in [&args.json, &args.png] {
        if let Some(d) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(d).map_err(io_err(d))?;
        }
    }
    let text = serde_json::to_string_pretty(&report).expect("the report serialises") + "\n";
    std::fs::write(&args.json, text).map_err(io_err(&args.json))?;
    if let Some((label, runs)) = &plotted {
        plot(&args.png, label, runs)?;
    }
    print_table(&report);
    eprintln!(
        "acch bench: wrote {} and {}",
        args.json.display(),
        args.png.display()
    );
    Ok(())
}

/// The capture process's CPU share in a mode's figures.
fn capture_cpu(f: &Value) -> Value {
    f["processes"]
        .as_array()
        .and_then(|p| p.iter().find(|p| p["stage"] == "capture"))
        .map_or(Value::Null, |p| p["cpu_pct"].clone())
}

/// `a[k] / b[k]`.
fn ratio(a: &Value, b: &Value, k: &str) -> f64 {
    a[k].as_f64().unwrap_or(0.0) / b[k].as_f64().unwrap_or(0.0).max(1e-12)
}

/// A mode's headline figures, against the in-process floor and the copy
/// baseline.
fn against(m: &Value, inproc: &Value, copy: &Value) -> Value {
    json!({
        "e2e_p50_ms": m["e2e_p50_ms"],
        "e2e_p99_ms": m["e2e_p99_ms"],
        "hop_p99_us": m["hop_p99_us"],
        "dropped": m["dropped"],
        "overhead_vs_inprocess": ratio(m, inproc, "e2e_p50_ms") - 1.0,
        "overhead_vs_inprocess_p99": ratio(m, inproc, "e2e_p99_ms") - 1.0,
        "speedup_vs_copy": ratio(copy, m, "e2e_p50_ms"),
    })
}

fn fps_label(fps: f64) -> String {
    if fps > 0.0 {
        format!("{fps} fps")
    } else {
        "free-running".into()
    }
}

fn print_table(report: &Value) {
    println!(
        "{:<10} {:>6} {:>8} {:>8} {:>9} {:>8} {:>9} {:>8} {:>7} {:>10} {:>10}",
        "size",
        "fps",
        "e2e p50",
        "e2e p99",
        "hop p99",
        "fps got",
        "vs 1-proc",
        "vs copy",
        "dropped",
        "rt e2e p99",
        "rt hop p99"
    );
    for c in report["configs"].as_array().into_iter().flatten() {
        println!(
            "{:<10} {:>6} {:>6.2}ms {:>6.2}ms {:>7.0}us {:>8.1} {:>+8.0}% {:>7.2}x {:>7} {:>10} {:>10}",
            c["resolution"].as_str().unwrap_or(""),
            c["fps"].as_f64().map_or("?".into(), fps_short),
            c["e2e_p50_ms"].as_f64().unwrap_or(0.0),
            c["e2e_p99_ms"].as_f64().unwrap_or(0.0),
            c["hop_p99_us"].as_f64().unwrap_or(0.0),
            c["throughput_fps"].as_f64().unwrap_or(0.0),
            100.0 * c["overhead_vs_inprocess"].as_f64().unwrap_or(0.0),
            c["speedup_vs_copy"].as_f64().unwrap_or(0.0),
            c["dropped"],
            c["realtime"]["e2e_p99_ms"]
                .as_f64()
                .map_or("-".into(), |v| format!("{v:.2}ms")),
            c["realtime"]["hop_p99_us"]
                .as_f64()
                .map_or("-".into(), |v| format!("{v:.0}us")),
        );
    }
}

fn fps_short(f: f64) -> String {
    if f > 0.0 {
        format!("{f}")
    } else {
        "free".into()
    }
}

/// CDFs (latency against fraction of frames) of the headline configuration:
/// left, end to end in the three modes; middle, per-hop latency (shm and
/// copy); right, per-stage compute time (shm processes).
fn plot(path: &Path, label: &str, runs: &[RunResult]) -> Result<()> {
    let e = draw_err;
    Ok(draw_png(path, (1500, 500), |root| {
        let areas = root.split_evenly((1, 3));
        let mut panels: Vec<(String, bool, Vec<Series>)> = Vec::new();
        panels.push((
            format!("end to end, {label}"),
            false,
            runs.iter()
                .map(|r| (r.mode.to_string(), r.e2e.clone()))
                .collect(),
        ));
        let mut hops = Vec::new();
        for r in runs.iter().filter(|r| r.mode != "in-process") {
            for (n, v) in &r.hops {
                hops.push((format!("{} {}", r.mode, n), v.clone()));
            }
        }
        panels.push(("per hop (publish -> awake)".into(), true, hops));
        panels.push((
            "per stage compute (shm processes)".into(),
            false,
            runs[0]
                .process
                .iter()
                .filter(|(n, _)| n != "capture")
                .cloned()
                .collect(),
        ));
        for (area, (title, micro, lines)) in areas.iter().zip(panels) {
            let scale = if micro { 1e3 } else { 1e6 };
            let xmax = lines
                .iter()
                .flat_map(|(_, v)| v.iter())
                .map(|&x| x as f64 / scale)
                .fold(0.0, f64::max)
                .max(1e-3)
                * 1.05;
            let xmin = lines
                .iter()
                .flat_map(|(_, v)| v.iter())
                .map(|&x| x as f64 / scale)
                .fold(f64::INFINITY, f64::min)
                .clamp(1e-3, xmax / 2.0)
                * 0.8;
            let mut chart = ChartBuilder::on(area)
                .caption(&title, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(45)
                .build_cartesian_2d((xmin..xmax).log_scale(), 0.0f64..1.0)
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_desc(if micro { "µs (log)" } else { "ms (log)" })
                .y_desc("fraction of frames")
                .draw()
                .map_err(e)?;
            for (i, (name, v)) in lines.iter().enumerate() {
                let mut s: Vec<f64> = v.iter().map(|&x| (x as f64 / scale).max(xmin)).collect();
                s.sort_by(f64::total_cmp);
                let n = s.len().max(1) as f64;
                let colour = Palette99::pick(i).to_rgba();
                let style = if name.starts_with("copy") {
                    colour.stroke_width(1)
                } else {
                    colour.stroke_width(2)
                };
                chart
                    .draw_series(LineSeries::new(
                        s.iter().enumerate().map(|(k, &x)| (x, (k + 1) as f64 / n)),
                        style,
                    ))
                    .map_err(e)?
                    .label(name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], colour));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerRight)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(e)?;
        }
        Ok(())
    })?)
}

/// Parses `WIDTHxHEIGHT` (16..=8192 pixels each).
pub fn parse_resolution(s: &str) -> Result<(u32, u32), String> {
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
