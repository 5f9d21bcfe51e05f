//! `acch run` as a multi-process pipeline: writes the run's configuration,
//! starts every stage as a child process (`acch stage NAME --config FILE`),
//! waits until all are connected, starts the capture, collects the final
//! results from the seeding stage's iceoryx2 service, stops the children
//! cleanly (SIGINT, then SIGKILL after a grace period), removes stale shared
//! memory and prints per-stage and end-to-end latency.

use super::run::{Percentiles, ProcessUsage, RunArgs, Samples, cached_database_at};
use crate::stages::PipelineConfig;
use acch_ipc::{Observer, ResultMsg, STAGES, StageId, remove_stale_resources};
use acch_pose::phi_error;
use anyhow::{Context, Result, anyhow, bail};
use serde::Serialize;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

/// One child process: a stage (restarted when it dies) or an observer.
struct Proc {
    name: &'static str,
    child: Child,
    /// Set for pipeline stages; observers are not restarted.
    stage: Option<StageId>,
}

/// The children (stages, then observers by name); killed on drop so
/// nothing outlives the launcher.
struct Children(Vec<Proc>);

impl Children {
    fn stop(&mut self, grace: Duration) {
        for p in &self.0 {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(p.child.id() as libc::pid_t, libc::SIGINT) };
        }
        let until = Instant::now() + grace;
        for p in &mut self.0 {
            let (id, c) = (p.name, &mut p.child);
            // A stage that was about to sleep when the signal came notices
            // it at the end of its sleep (200 ms at most).
            loop {
                match c.try_wait() {
                    Ok(Some(status)) => {
                        if !status.success() {
                            tracing::warn!("{id} exited with {status}");
                        }
                        break;
                    }
                    Ok(None) if Instant::now() < until => {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                    _ => {
                        tracing::warn!("{id} did not stop in time: killed");
                        let _ = c.kill();
                        let _ = c.wait();
                        break;
                    }
                }
            }
        }
        self.0.clear();
    }

    /// The first child that has exited (reaped), with its status.
    fn exited(&mut self) -> Option<(usize, ExitStatus)> {
        self.0
            .iter_mut()
            .enumerate()
            .find_map(|(i, p)| match p.child.try_wait() {
                Ok(Some(status)) => Some((i, status)),
                _ => None,
            })
    }
}

impl Drop for Children {
    fn drop(&mut self) {
        self.stop(Duration::from_secs(3));
    }
}

/// Restarts allowed per stage in one run: a stage that keeps dying is a
/// bug or a bad input, not a transient crash.
const MAX_RESTARTS: u32 = 5;

/// Whether a stage that ended with `status` is worth restarting: killed by
/// a signal or panicked (101). An orderly error exit (1) means a bad input
/// or configuration that a restart would only repeat.
fn restartable(status: ExitStatus) -> bool {
    status.signal().is_some() || status.code() == Some(101)
}

/// One supervised restart.
#[derive(Serialize, Clone, Debug)]
struct Restart {
    stage: &'static str,
    /// How the old process ended (e.g. "signal: 9 (SIGKILL)").
    status: String,
    old_pid: u32,
    new_pid: u32,
    /// Seconds since the start signal.
    at_s: f64,
    /// Dead iceoryx2 nodes cleaned before the restart.
    stale_nodes_removed: usize,
    /// Sequence the restarted capture continues at (capture only).
    #[serde(skip_serializing_if = "Option::is_none")]
    first_frame: Option<u64>,
}

/// Resident memory of every child at one time.
#[derive(Serialize, Clone, Debug)]
struct RssSample {
    /// Seconds since the start signal.
    t_s: f64,
    /// (process, VmRSS kB) for every child alive.
    rss_kb: Vec<(&'static str, u64)>,
}

/// Resident memory of one process over the run.
#[derive(Serialize, Clone, Debug)]
struct RssTrend {
    process: &'static str,
    /// First sample after the start, kB.
    start_kb: u64,
    /// Last sample before stopping, kB.
    end_kb: u64,
    /// Largest sample, kB.
    max_kb: u64,
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
    /// Accepted poses further from the frame's ground truth than the
    /// evaluation's failure thresholds (|dtheta| > 10 deg or |dphi| > 20 deg).
    accepted_wrong: u64,
    /// Their sequence numbers.
    accepted_wrong_sequences: Vec<u64>,
    /// The processes first started, (name, pid).
    pids: Vec<(&'static str, u32)>,
    /// Stages that died during the run and were restarted.
    restarts: Vec<Restart>,
    /// Dead iceoryx2 nodes cleaned while the run went on (one per restart).
    stale_nodes_removed_during_run: usize,
    /// Results that repeated an earlier sequence (ignored; should be 0).
    duplicates: u64,
    /// Resident memory of every child, sampled every `--rss-every` seconds.
    rss: Vec<RssSample>,
    /// First, last and largest of those samples per process.
    rss_trend: Vec<RssTrend>,
    /// What each stage process counted (written when it stopped; a killed
    /// process leaves none).
    stage_counters: Vec<serde_json::Value>,
    /// Where the processes ran (`stage_cpus`); null when not placed.
    placement: Option<acch_ipc::sched::Placement>,
    /// The CPU latency request held during the run, µs (null: none).
    cpu_latency_us: Option<u32>,
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
    status_kb(pid, "VmHWM:")
}

/// Resident set of `pid` now, kB (VmRSS).
fn rss_kb(pid: u32) -> Option<u64> {
    status_kb(pid, "VmRSS:")
}

fn status_kb(pid: u32, key: &str) -> Option<u64> {
    status_field(pid, key)?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The value of line `key` of /proc/PID/status, trimmed.
pub(super) fn status_field(pid: u32, key: &str) -> Option<String> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix(key))
        .map(|v| v.trim().to_owned())
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
    if let Some(s) = &args.source {
        cfg.source.clone_from(s);
    }
    if let Some(r) = &args.replay {
        cfg.replay.clone_from(r);
    }
    if let Some(p) = args.rt_priority {
        cfg.realtime_priority = p;
    }
    if args.cpu_latency_us.is_some() {
        cfg.cpu_latency_us = args.cpu_latency_us;
    }
    if let Some(c) = &args.stage_cpus {
        cfg.stage_cpus.clone_from(c);
    }
    // A replay runs the whole recording unless told otherwise.
    if let Some(path) = cfg.source.strip_prefix("mcap:")
        && args.frames.is_none()
    {
        cfg.frames = acch_record::scan(std::path::Path::new(path))
            .with_context(|| format!("reading the recording {path}"))?
            .frames;
    }
    if args.rerun.is_some() {
        cfg.rerun.clone_from(&args.rerun);
    }
    if args.record.is_some() {
        cfg.record.clone_from(&args.record);
    }
    if args.db.is_some() {
        cfg.db.clone_from(&args.db);
    }
    if let Some(name) = &args.object.object {
        cfg.object.clone_from(name);
    }
    for (name, v) in [
        ("--stall-timeout", args.stall_timeout),
        ("--rss-every", args.rss_every),
    ] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{name} {v}: must be a positive number of seconds");
        }
    }
    cfg.instance = std::process::id().to_string();
    // The stages' wake-up files go with the run, however it ends.
    let _wake_files = acch_ipc::wake::RunFiles::new(&cfg.instance);
    cfg.first_frame = 0;
    // One clear error here rather than one from every stage process.
    cfg.validate().context("invalid pipeline configuration")?;
    if let Some(db) = &cfg.db {
        acch_core::ViewDatabase::load(db).context("the view database (db = ...)")?;
    }
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
    if cfg.realtime_priority > 0 {
        // Set here, before any stage starts: every child inherits it.
        acch_ipc::sched::set_fifo(cfg.realtime_priority).with_context(|| {
            format!(
                "realtime_priority = {}: SCHED_FIFO needs CAP_SYS_NICE or an rtprio limit \
                 (ulimit -r); run without it",
                cfg.realtime_priority
            )
        })?;
    }
    // Held by the launcher for the whole run: the kernel drops it when the
    // launcher exits, however it exits.
    let _cpu_latency = cfg.hold_cpu_latency()?;
    // Before any child starts: capture and the observers inherit the
    // launcher's CPUs; the stages move themselves to theirs.
    let placement = cfg.place_run()?;
    if let Some(p) = &placement {
        tracing::info!("stages on CPUs {:?}, the rest on {:?}", p.stages, p.others);
    }
    let config_path = std::env::temp_dir().join(format!("acch-run-{}.toml", cfg.instance));
    cfg.save(&config_path)?;
    let _config_guard = RemoveOnDrop(config_path.clone());
    let mut restart_configs: Vec<RemoveOnDrop> = Vec::new();
    // Counter files of every stage process; dropped after `children`, so
    // the files they write when stopped on an early return go too.
    let mut counter_files: Vec<RemoveOnDrop> = Vec::new();

    let ipc = cfg.ipc("launcher")?;
    let ready = ipc.control_listener("ready")?;
    let start = ipc.control_notifier("start")?;
    let results = ipc.result_input(StageId::Seeding)?;
    let exe = std::env::current_exe().context("locating the acch executable")?;
    let spawn = |name: &str, config: &Path| -> Result<Child> {
        Command::new(&exe)
            .arg("stage")
            .arg(name)
            .arg("--config")
            .arg(config)
            .spawn()
            .with_context(|| format!("starting {name}"))
    };
    let mut children = Children(Vec::new());
    let observers = cfg.observers();
    for id in StageId::ALL {
        let child = spawn(id.name(), &config_path)?;
        children.0.push(Proc {
            name: id.name(),
            child,
            stage: Some(id),
        });
    }
    for o in &observers {
        let child = spawn(o.name(), &config_path)?;
        children.0.push(Proc {
            name: o.name(),
            child,
            stage: None,
        });
    }
    let pids: Vec<(&'static str, u32)> =
        children.0.iter().map(|p| (p.name, p.child.id())).collect();
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
    // Wait until every stage and observer has announced itself.
    let mut seen = [false; STAGES + Observer::ALL.len()];
    for o in Observer::ALL {
        seen[o.ready_id()] = !observers.contains(&o);
    }
    let deadline = Instant::now() + Duration::from_secs(120);
    while !seen.iter().all(|s| *s) {
        if !ipc.keep_running() {
            bail!("interrupted while starting");
        }
        if Instant::now() > deadline {
            bail!("stages not ready after 120 s: {:?}", seen);
        }
        if let Some((i, status)) = children.exited() {
            bail!("{} exited early with {status}", children.0[i].name);
        }
        wait_ready(&ready, Duration::from_millis(200), |id| {
            if let Some(s) = seen.get_mut(id) {
                *s = true;
            }
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
    let mut ticks0: Vec<Option<u64>> = children.0.iter().map(|p| cpu_ticks(p.child.id())).collect();
    let mut got: Vec<ResultMsg> = Vec::with_capacity(cfg.frames as usize);
    let mut last = Instant::now();
    let stall = Duration::from_secs_f64(args.stall_timeout.max(1.0));
    let rss_every = Duration::from_secs_f64(args.rss_every.max(0.1));
    let mut next_rss = t0;
    let mut rss: Vec<RssSample> = Vec::new();
    let mut interrupted = false;
    let mut last_seq: Option<u64> = None;
    let mut duplicates = 0u64;
    let mut restarts: Vec<Restart> = Vec::new();
    let mut restart_count = [0u32; STAGES];
    let mut stale_during_run = 0usize;
    // A restarted capture waits for `start` again once it is connected.
    let mut capture_restarted = false;
    let mut all_pids: Vec<(&'static str, u32)> = pids.clone();
    while cfg.frames == 0 || (got.len() as u64) < cfg.frames {
        if !ipc.keep_running() {
            interrupted = true;
            break;
        }
        if Instant::now() >= next_rss {
            rss.push(RssSample {
                t_s: t0.elapsed().as_secs_f64(),
                rss_kb: children
                    .0
                    .iter()
                    .map(|p| (p.name, rss_kb(p.child.id()).unwrap_or(0)))
                    .collect(),
            });
            next_rss += rss_every;
        }
        if let Some((i, status)) = children.exited() {
            let Some(id) = children.0[i].stage else {
                bail!("{} exited early with {status}", children.0[i].name);
            };
            if !restartable(status) {
                bail!(
                    "{} exited with {status} (its error is above); not restarting",
                    id.name()
                );
            }
            if restart_count[id as usize] >= MAX_RESTARTS {
                bail!(
                    "{} exited with {status} after {MAX_RESTARTS} restarts: giving up",
                    id.name()
                );
            }
            let old_pid = children.0[i].child.id();
            // The dead node still owns ports (a publisher slot, borrowed
            // samples): free them before the new process opens its own.
            let stale = remove_stale_resources();
            stale_during_run += stale;
            let mut first_frame = None;
            let child = if id == StageId::Capture {
                // A camera does not wait: continue at the frame due now, past
                // every frame the old capture may have sent.
                let next = resume_sequence(&cfg, t0.elapsed(), last_seq);
                if cfg.frames > 0 && next >= cfg.frames {
                    // Every frame was sent already; nothing to restart.
                    tracing::warn!("capture exited with {status} after its last frame");
                    None
                } else {
                    let mut c = cfg.clone();
                    c.first_frame = next;
                    let path = std::env::temp_dir()
                        .join(format!("acch-run-{}-capture-{next}.toml", cfg.instance));
                    c.save(&path)?;
                    restart_configs.push(RemoveOnDrop(path.clone()));
                    first_frame = Some(next);
                    capture_restarted = true;
                    Some(spawn(id.name(), &path)?)
                }
            } else {
                Some(spawn(id.name(), &config_path)?)
            };
            let Some(child) = child else {
                children.0.remove(i);
                ticks0.remove(i);
                continue;
            };
            let new_pid = child.id();
            children.0[i].child = child;
            ticks0[i] = cpu_ticks(new_pid);
            restart_count[id as usize] += 1;
            all_pids.push((id.name(), new_pid));
            counter_files.push(RemoveOnDrop(cfg.counters_path(id.name(), new_pid)));
            let r = Restart {
                stage: id.name(),
                status: status.to_string(),
                old_pid,
                new_pid,
                at_s: t0.elapsed().as_secs_f64(),
                stale_nodes_removed: stale,
                first_frame,
            };
            eprintln!(
                "acch run: {} (pid {old_pid}) ended with {}; cleaned {stale} dead nodes; restarted as pid {new_pid}",
                r.stage, r.status
            );
            restarts.push(r);
            // Give the stall timer the restart's time back.
            last = Instant::now();
        }
        // Restarted stages announce themselves; a capture then needs `start`.
        wait_ready(&ready, Duration::ZERO, |id| {
            if id == StageId::Capture as usize && capture_restarted {
                capture_restarted = false;
                if let Err(e) = start.notify() {
                    tracing::warn!("restarting the capture: {e:?}");
                }
            }
        })?;
        results.wait(Duration::from_millis(200))?;
        while let Some(s) = results.receive()? {
            let m = *s.user_header();
            last = Instant::now();
            // Sequences only grow; an older one would be a replayed frame.
            if last_seq.is_some_and(|l| m.sequence <= l) {
                duplicates += 1;
                continue;
            }
            last_seq = Some(m.sequence);
            got.push(m);
        }
        if let Some(l) = last_seq
            && cfg.frames > 0
            && l + 1 >= cfg.frames
        {
            // The last frame is through: anything missing was dropped.
            break;
        }
        if last.elapsed() > stall {
            tracing::warn!("no result for {:.0} s: stopping", stall.as_secs_f64());
            break;
        }
    }
    let elapsed = t0.elapsed().as_secs_f64();
    rss.push(RssSample {
        t_s: elapsed,
        rss_kb: children
            .0
            .iter()
            .map(|p| (p.name, rss_kb(p.child.id()).unwrap_or(0)))
            .collect(),
    });
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    let processes: Vec<ProcessUsage> = children
        .0
        .iter()
        .zip(&ticks0)
        .map(|(p, t0)| {
            let cpu_s = match (t0, cpu_ticks(p.child.id())) {
                (Some(a), Some(b)) => b.saturating_sub(*a) as f64 / hz,
                _ => 0.0,
            };
            ProcessUsage {
                stage: p.name.into(),
                cpu_s,
                cpu_pct: 100.0 * cpu_s / elapsed.max(1e-9),
                peak_rss_kb: peak_rss_kb(p.child.id()).unwrap_or(0),
                cpus: status_field(p.child.id(), "Cpus_allowed_list:").unwrap_or_default(),
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
    summary.placement = placement;
    summary.pids = pids;
    summary.restarts = restarts;
    summary.stale_nodes_removed_during_run = stale_during_run;
    summary.duplicates = duplicates;
    summary.rss_trend = rss_trend(&rss);
    summary.rss = rss;
    summary.stage_counters = all_pids
        .iter()
        .filter_map(|(name, pid)| read_counters(&cfg, name, *pid))
        .collect();
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

/// Takes every pending `ready` event without blocking longer than
/// `timeout`, calling `f` with the announcing stage's (or observer's) id.
fn wait_ready(
    ready: &iceoryx2::port::listener::Listener<acch_ipc::Svc>,
    timeout: Duration,
    mut f: impl FnMut(usize),
) -> Result<()> {
    let r = if timeout.is_zero() {
        ready.try_wait(|e| f(e.id.as_value()))
    } else {
        ready.timed_wait(|e| f(e.id.as_value()), timeout)
    };
    r.map(|_| ()).or_else(|e| match e {
        iceoryx2::port::listener::ListenerWaitError::InterruptSignal => Ok(()),
        e => Err(anyhow!("waiting for the stages: {e:?}")),
    })
}

/// The sequence a restarted capture continues at: the frame due now at
/// the configured rate (frames while it was down are lost, as with a
/// camera), and always past the last result seen.
fn resume_sequence(cfg: &PipelineConfig, since_start: Duration, last_seq: Option<u64>) -> u64 {
    let after_last = last_seq.map_or(0, |l| l + 1);
    if cfg.fps > 0.0 {
        ((since_start.as_secs_f64() * cfg.fps).floor() as u64 + 1).max(after_last)
    } else {
        // Free-running: frames in flight are at most the queues' depth.
        after_last + 64
    }
}

/// The counters a stage process wrote when it stopped (none for a process
/// that was killed).
fn read_counters(cfg: &PipelineConfig, name: &str, pid: u32) -> Option<serde_json::Value> {
    let path = cfg.counters_path(name, pid);
    let text = std::fs::read_to_string(&path).ok()?;
    let _ = std::fs::remove_file(&path);
    serde_json::from_str(&text).ok()
}

fn rss_trend(samples: &[RssSample]) -> Vec<RssTrend> {
    let mut out: Vec<RssTrend> = Vec::new();
    for s in samples {
        for &(process, kb) in &s.rss_kb {
            if kb == 0 {
                continue;
            }
            match out.iter_mut().find(|t| t.process == process) {
                Some(t) => {
                    t.end_kb = kb;
                    t.max_kb = t.max_kb.max(kb);
                }
                None => out.push(RssTrend {
                    process,
                    start_kb: kb,
                    end_kb: kb,
                    max_kb: kb,
                }),
            }
        }
    }
    out
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
    let wrong: Vec<u64> = accepted
        .iter()
        .filter(|m| {
            m.truth.valid == 1
                && ((m.estimate[0] - m.truth.theta_deg).abs() > super::eval::FAIL_THETA_DEG as f64
                    || phi_error(m.estimate[1] as f32, m.truth.phi_deg as f32)
                        > super::eval::FAIL_PHI_DEG)
        })
        .map(|m| m.sequence)
        .collect();
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
        placement: None,
        cpu_latency_us: cfg.cpu_latency_us,
        accepted_wrong: wrong.len() as u64,
        accepted_wrong_sequences: wrong,
        pids: Vec::new(),
        restarts: Vec::new(),
        stale_nodes_removed_during_run: 0,
        duplicates: 0,
        rss: Vec::new(),
        rss_trend: Vec::new(),
        stage_counters: Vec::new(),
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
        "accepted: mean |dphi| {:.2} deg, mean |dtheta| {:.2} deg, {} beyond the failure thresholds",
        s.accepted_mean_phi_err_deg, s.accepted_mean_theta_err_deg, s.accepted_wrong
    );
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
