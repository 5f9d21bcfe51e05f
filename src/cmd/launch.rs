//! `acch run` as a multi-process pipeline: writes the run's configuration,
//! starts every stage as a child process (`acch stage NAME --config FILE`),
//! waits until all are connected, starts the capture, collects the final
//! results from the seeding stage's iceoryx2 service, stops the children
//! cleanly (SIGINT, then SIGKILL after a grace period), removes stale shared
//! memory and prints per-stage and end-to-end latency.

use super::run::{Percentiles, ProcessUsage, RunArgs, Samples, cached_database_at};
use crate::stages::PipelineConfig;
use acch_ipc::{ResultMsg, STAGES, StageId, remove_stale_resources};
use acch_pose::phi_error;
use anyhow::{Context, Result, anyhow, bail};
use serde::Serialize;
use std::path::PathBuf;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

/// The children; killed on drop so nothing outlives the launcher.
struct Children(Vec<(StageId, Child)>);

impl Children {
    fn stop(&mut self, grace: Duration) {
        for (_, c) in &self.0 {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(c.id() as libc::pid_t, libc::SIGINT) };
        }
        let until = Instant::now() + grace;
        for (id, c) in &mut self.0 {
            loop {
                match c.try_wait() {
                    Ok(Some(status)) => {
                        if !status.success() {
                            tracing::warn!("stage {} exited with {status}", id.name());
                        }
                        break;
                    }
                    Ok(None) if Instant::now() < until => {
                        std::thread::sleep(Duration::from_millis(20))
                    }
                    _ => {
                        tracing::warn!("stage {} did not stop in time: killed", id.name());
                        let _ = c.kill();
                        let _ = c.wait();
                        break;
                    }
                }
            }
        }
        self.0.clear();
    }

    fn crashed(&mut self) -> Option<String> {
        self.0.iter_mut().find_map(|(id, c)| match c.try_wait() {
            Ok(Some(status)) => Some(format!("stage {} exited early with {status}", id.name())),
            _ => None,
        })
    }
}

impl Drop for Children {
    fn drop(&mut self) {
        self.stop(Duration::from_secs(3));
    }
}

/// Latency of one hop or stage over all frames.
#[derive(Serialize)]
struct StageLatency {
    stage: &'static str,
    /// Upstream published -> this stage received (the IPC hop).
    hop: Percentiles,
    /// Received -> published (compute + publishing).
    process: Percentiles,
}

#[derive(Serialize)]
struct Summary {
    object: String,
    source: String,
    mode: &'static str,
    frames_requested: u64,
    results: u64,
    fps_target: f64,
    fps_achieved: f64,
    found: u64,
    estimated: u64,
    accepted: u64,
    seeds: u64,
    accepted_mean_phi_err_deg: f64,
    accepted_mean_theta_err_deg: f64,
    /// Capture -> result published by seeding (the zenoh put follows at once).
    end_to_end: Percentiles,
    stages: Vec<StageLatency>,
    /// Frame reads by stages (recognition, segmentation, pose each read every
    /// frame they process).
    frame_reads: u64,
    /// Reads that found the pixels at the capture's own shared-memory file
    /// and offset: the frame was not copied.
    frame_reads_in_place: u64,
    /// Bytes of frames published to shared memory (written once by capture).
    frame_bytes_published: u64,
    /// Dead iceoryx2 nodes cleaned up after the run (should be 0).
    stale_nodes_removed: usize,
    /// `shm` (zero copy) or `copy` (frames through Unix sockets).
    transport: String,
    width: u32,
    height: u32,
    /// Frames requested that produced no result.
    dropped: u64,
    /// CPU and peak memory of every stage process.
    processes: Vec<ProcessUsage>,
    #[serde(skip_serializing_if = "Option::is_none")]
    samples: Option<Samples>,
}

/// Ticks of user + system CPU of `pid` (/proc/PID/stat fields 14, 15).
fn cpu_ticks(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name may hold spaces; fields restart after its ')'.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    Some(f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?)
}

/// Peak resident set of `pid`, kB (VmHWM).
fn peak_rss_kb(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// Runs the multi-process pipeline.
pub fn run(args: RunArgs) -> Result<()> {
    let mut cfg = match &args.config {
        Some(p) => PipelineConfig::load(p)?,
        None => PipelineConfig {
            background: args.background.to_string(),
            seed: args.seed,
            ..Default::default()
        },
    };
    if let Some(f) = args.frames {
        cfg.frames = f;
    }
    if let Some(f) = args.fps {
        cfg.fps = f;
    }
    if let Some((w, h)) = args.resolution {
        (cfg.width, cfg.height) = (w, h);
    }
    if let Some(t) = &args.transport {
        cfg.transport.clone_from(t);
    }
    cfg.copies_frames()?;
    if !(cfg.fps.is_finite() && cfg.fps >= 0.0) {
        bail!("fps {} must be a number >= 0", cfg.fps);
    }
    if args.db.is_some() {
        cfg.db.clone_from(&args.db);
    }
    if let Some(name) = &args.object.object {
        cfg.object.clone_from(name);
    }
    cfg.instance = std::process::id().to_string();
    if cfg.db.is_none() {
        let object = std::sync::Arc::new(acch_capture::Object::builtin(&cfg.object)?);
        let (_, path) =
            cached_database_at(&object, args.cache_dir.clone().or(cfg.cache_dir.clone()))?;
        cfg.db = Some(path);
    }
    let stale = remove_stale_resources();
    if stale > 0 {
        tracing::info!("removed the stale resources of {stale} dead iceoryx2 nodes");
    }
    let config_path = std::env::temp_dir().join(format!("acch-run-{}.toml", cfg.instance));
    cfg.save(&config_path)?;
    let _config_guard = RemoveOnDrop(config_path.clone());

    let ipc = cfg.ipc("launcher")?;
    let ready = ipc.control_listener("ready")?;
    let start = ipc.control_notifier("start")?;
    let results = ipc.result_input(StageId::Seeding)?;
    let exe = std::env::current_exe().context("locating the acch executable")?;
    let mut children = Children(Vec::new());
    for id in StageId::ALL {
        let child = Command::new(&exe)
            .arg("stage")
            .arg(id.name())
            .arg("--config")
            .arg(&config_path)
            .spawn()
            .with_context(|| format!("starting stage {}", id.name()))?;
        children.0.push((id, child));
    }
    // Wait until every stage has announced itself.
    let mut seen = [false; STAGES];
    let deadline = Instant::now() + Duration::from_secs(120);
    while !seen.iter().all(|s| *s) {
        if !ipc.keep_running() {
            bail!("interrupted while starting");
        }
        if Instant::now() > deadline {
            bail!("stages not ready after 120 s: {:?}", seen);
        }
        if let Some(e) = children.crashed() {
            bail!("{e}");
        }
        ready
            .timed_wait(
                |e| {
                    if let Some(s) = seen.get_mut(e.id.as_value()) {
                        *s = true;
                    }
                },
                Duration::from_millis(200),
            )
            .or_else(|e| match e {
                iceoryx2::port::listener::ListenerWaitError::InterruptSignal => Ok(0),
                e => Err(anyhow!("waiting for the stages: {e:?}")),
            })?;
    }
    eprintln!(
        "acch run: {} stages connected (instance {}), streaming {} frames of {} at {}",
        STAGES,
        cfg.instance,
        cfg.frames,
        cfg.object,
        if cfg.fps > 0.0 {
            format!("{} fps", cfg.fps)
        } else {
            "free-running".into()
        }
    );
    start
        .notify()
        .map_err(|e| anyhow!("starting the capture: {e:?}"))?;

    let t0 = Instant::now();
    let ticks0: Vec<Option<u64>> = children.0.iter().map(|(_, c)| cpu_ticks(c.id())).collect();
    let mut got: Vec<ResultMsg> = Vec::with_capacity(cfg.frames as usize);
    let mut last = Instant::now();
    let stall = Duration::from_secs_f64(args.stall_timeout.max(1.0));
    let mut interrupted = false;
    let mut last_seq = None;
    while cfg.frames == 0 || (got.len() as u64) < cfg.frames {
        if !ipc.keep_running() {
            interrupted = true;
            break;
        }
        if let Some(e) = children.crashed() {
            bail!("{e}");
        }
        results.wait(Duration::from_millis(200))?;
        while let Some(s) = results.receive()? {
            got.push(*s.user_header());
            last = Instant::now();
        }
        if let Some(m) = got.last()
            && last_seq != Some(m.sequence)
        {
            last_seq = Some(m.sequence);
            if m.sequence + 1 >= cfg.frames && cfg.frames > 0 {
                // The last frame is through: anything missing was dropped.
                break;
            }
        }
        if last.elapsed() > stall {
            tracing::warn!("no result for {:.0} s: stopping", stall.as_secs_f64());
            break;
        }
    }
    let elapsed = t0.elapsed().as_secs_f64();
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    let processes: Vec<ProcessUsage> = children
        .0
        .iter()
        .zip(&ticks0)
        .map(|((id, c), t0)| {
            let cpu_s = match (t0, cpu_ticks(c.id())) {
                (Some(a), Some(b)) => b.saturating_sub(*a) as f64 / hz,
                _ => 0.0,
            };
            ProcessUsage {
                stage: id.name().into(),
                cpu_s,
                cpu_pct: 100.0 * cpu_s / elapsed.max(1e-9),
                peak_rss_kb: peak_rss_kb(c.id()).unwrap_or(0),
            }
        })
        .collect();
    children.stop(Duration::from_secs(5));
    drop(results);
    drop(ready);
    drop(start);
    drop(ipc);
    let stale_nodes_removed = remove_stale_resources();
    if interrupted {
        eprintln!("acch run: interrupted");
    }
    let mut summary = summarise(&cfg, &got, elapsed, stale_nodes_removed);
    summary.processes = processes;
    if args.samples {
        summary.samples = Some(samples(&got));
    }
    print_summary(&summary);
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&summary)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn summarise(
    cfg: &PipelineConfig,
    got: &[ResultMsg],
    elapsed: f64,
    stale_nodes_removed: usize,
) -> Summary {
    let count = |f: fn(&ResultMsg) -> bool| got.iter().filter(|m| f(m)).count() as u64;
    let mut e2e: Vec<u64> = got
        .iter()
        .map(|m| {
            m.trail.stages[StageId::Seeding as usize]
                .published_ns
                .saturating_sub(m.trail.captured_ns)
        })
        .collect();
    let mut stages = Vec::new();
    for id in StageId::ALL.into_iter().skip(1) {
        let up = id.upstream().expect("not capture") as usize;
        let i = id as usize;
        let mut hop: Vec<u64> = got
            .iter()
            .map(|m| {
                m.trail.stages[i]
                    .received_ns
                    .saturating_sub(m.trail.stages[up].published_ns)
            })
            .collect();
        let mut process: Vec<u64> = got
            .iter()
            .map(|m| {
                m.trail.stages[i]
                    .published_ns
                    .saturating_sub(m.trail.stages[i].received_ns)
            })
            .collect();
        stages.push(StageLatency {
            stage: id.name(),
            hop: Percentiles::of(&mut hop),
            process: Percentiles::of(&mut process),
        });
    }
    let mut cap: Vec<u64> = got
        .iter()
        .map(|m| {
            m.trail.stages[0]
                .published_ns
                .saturating_sub(m.trail.stages[0].received_ns)
        })
        .collect();
    stages.insert(
        0,
        StageLatency {
            stage: "capture",
            hop: Percentiles::of(&mut []),
            process: Percentiles::of(&mut cap),
        },
    );
    let accepted: Vec<&ResultMsg> = got.iter().filter(|m| m.accepted == 1).collect();
    let n = accepted.len().max(1) as f64;
    let with_truth = |f: &dyn Fn(&ResultMsg) -> f64| {
        accepted
            .iter()
            .filter(|m| m.truth.valid == 1)
            .map(|m| f(m))
            .sum::<f64>()
            / n
    };
    let bytes = got.first().map_or(0, |m| m.width * m.height * 3) * got.len() as u64;
    Summary {
        object: cfg.object.clone(),
        source: cfg.source.clone(),
        mode: "processes",
        frames_requested: cfg.frames,
        results: got.len() as u64,
        fps_target: cfg.fps,
        fps_achieved: got.len() as f64 / elapsed.max(1e-9),
        found: count(|m| m.found == 1),
        estimated: count(|m| m.estimated == 1),
        accepted: accepted.len() as u64,
        seeds: count(|m| m.seeded == 1 && m.accepted == 1),
        accepted_mean_phi_err_deg: with_truth(&|m| {
            phi_error(m.estimate[1] as f32, m.truth.phi_deg as f32) as f64
        }),
        accepted_mean_theta_err_deg: with_truth(&|m| (m.estimate[0] - m.truth.theta_deg).abs()),
        end_to_end: Percentiles::of(&mut e2e),
        stages,
        frame_reads: got.iter().map(|m| m.frame_reads).sum(),
        frame_reads_in_place: got.iter().map(|m| m.frame_reads_in_place).sum(),
        frame_bytes_published: bytes,
        stale_nodes_removed,
        transport: cfg.transport.clone(),
        width: cfg.width,
        height: cfg.height,
        dropped: cfg.frames.saturating_sub(got.len() as u64),
        processes: Vec::new(),
        samples: None,
    }
}

/// Every frame's end-to-end, hop and processing times.
fn samples(got: &[ResultMsg]) -> Samples {
    let e2e_ns = got
        .iter()
        .map(|m| {
            m.trail.stages[StageId::Seeding as usize]
                .published_ns
                .saturating_sub(m.trail.captured_ns)
        })
        .collect();
    let mut hop_ns = Vec::new();
    let mut process_ns = Vec::new();
    for id in StageId::ALL {
        let i = id as usize;
        if let Some(up) = id.upstream() {
            hop_ns.push((
                id.name().to_owned(),
                got.iter()
                    .map(|m| {
                        m.trail.stages[i]
                            .received_ns
                            .saturating_sub(m.trail.stages[up as usize].published_ns)
                    })
                    .collect(),
            ));
        }
        process_ns.push((
            id.name().to_owned(),
            got.iter()
                .map(|m| {
                    m.trail.stages[i]
                        .published_ns
                        .saturating_sub(m.trail.stages[i].received_ns)
                })
                .collect(),
        ));
    }
    Samples {
        e2e_ns,
        hop_ns,
        process_ns,
    }
}

fn print_summary(s: &Summary) {
    println!(
        "{} of {} frames of {} through {} processes at {:.1} fps: found {}, estimated {}, accepted {}, seeds {}",
        s.results,
        s.frames_requested,
        s.object,
        STAGES,
        s.fps_achieved,
        s.found,
        s.estimated,
        s.accepted,
        s.seeds
    );
    println!(
        "accepted: mean |dphi| {:.2} deg, mean |dtheta| {:.2} deg",
        s.accepted_mean_phi_err_deg, s.accepted_mean_theta_err_deg
    );
    if s.transport == "copy" {
        println!(
            "copy transport: {} frame reads, each from the stage's own copy of the frame (written to 3 Unix sockets per frame)",
            s.frame_reads
        );
    } else {
        println!(
            "zero copy: {} of {} frame reads found the pixels at the capture's shared-memory offset; {:.1} MB of frames written once",
            s.frame_reads_in_place,
            s.frame_reads,
            s.frame_bytes_published as f64 / 1e6
        );
    }
    println!(
        "{:<14} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "latency (ms)", "hop p50", "hop p99", "proc p50", "proc p99", "proc max"
    );
    for st in &s.stages {
        println!(
            "{:<14} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3}",
            st.stage,
            st.hop.p50_ms,
            st.hop.p99_ms,
            st.process.p50_ms,
            st.process.p99_ms,
            st.process.max_ms
        );
    }
    let e = &s.end_to_end;
    println!(
        "end to end (captured -> seed published): p50 {:.3} ms, p90 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        e.p50_ms, e.p90_ms, e.p99_ms, e.max_ms
    );
}
