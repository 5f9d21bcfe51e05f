//! The supervisor of a multi-process run: it spawns the processes, restarts
//! a stage that dies by a signal or a panic (up to a limit), samples every
//! child's memory and CPU, and stops them all (SIGINT, then SIGKILL after a
//! grace period) however the run ends. What it spawns is the caller's
//! ([`Spawn`]): `acch run` spawns `acch stage NAME`, the tests spawn shells.
//! What a run reports of each process's CPU and memory ([`ProcessUsage`])
//! is measured here too, for the in-process run as well ([`self_usage`]).

use serde::Serialize;
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

/// Starts one process of the run by name, with the configuration file it
/// should read.
pub trait Spawn {
    /// Spawns process `name` reading `config`.
    fn spawn(&mut self, name: &str, config: &Path) -> std::io::Result<Child>;
}

impl<F: FnMut(&str, &Path) -> std::io::Result<Child>> Spawn for F {
    fn spawn(&mut self, name: &str, config: &Path) -> std::io::Result<Child> {
        self(name, config)
    }
}

/// Why the supervisor gave up on a run.
#[derive(Debug, thiserror::Error)]
pub enum SuperviseError {
    /// A process could not be started.
    #[error("starting {name}")]
    Spawn {
        /// The process.
        name: String,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// A process that is not restarted (an observer) exited.
    #[error("{name} exited early with {status}")]
    ExitedEarly {
        /// The process.
        name: String,
        /// How it ended.
        status: ExitStatus,
    },
    /// A stage ended with an orderly error: a restart would only repeat it.
    #[error("{name} exited with {status} (its error is above); not restarting")]
    NotRestartable {
        /// The stage.
        name: String,
        /// How it ended.
        status: ExitStatus,
    },
    /// A stage kept dying.
    #[error("{name} exited with {status} after {restarts} restarts: giving up")]
    GaveUp {
        /// The stage.
        name: String,
        /// How it ended the last time.
        status: ExitStatus,
        /// Restarts it had.
        restarts: u32,
    },
}

/// What to do with a child that exited.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decision {
    /// Start it again.
    Restart,
    /// It ended in order (exit code 1 after printing its error): a bad
    /// input or configuration that a restart would only repeat.
    Orderly,
    /// It reached the restart limit.
    Exhausted,
    /// It is not restarted (an observer).
    Never,
}

/// When a stage is restarted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RestartPolicy {
    /// Restarts allowed per stage in one run: a stage that keeps dying is a
    /// bug or a bad input, not a transient crash.
    pub max_restarts: u32,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        RestartPolicy { max_restarts: 5 }
    }
}

impl RestartPolicy {
    /// What to do with a restartable child that ended with `status` after
    /// `restarts` restarts: restart one killed by a signal or that panicked
    /// (exit code 101).
    pub fn decide(&self, status: ExitStatus, restarts: u32) -> Decision {
        if !(status.signal().is_some() || status.code() == Some(101)) {
            Decision::Orderly
        } else if restarts >= self.max_restarts {
            Decision::Exhausted
        } else {
            Decision::Restart
        }
    }
}

/// One child process.
pub struct Proc {
    /// Its name (`recognition`, `viz`, ...).
    pub name: &'static str,
    /// The process.
    pub child: Child,
    /// Whether it is restarted when it dies (the stages are, the observers
    /// are not).
    pub restartable: bool,
    /// Restarts so far.
    pub restarts: u32,
    /// CPU ticks when the run started (for its CPU time over the run).
    ticks0: Option<u64>,
}

/// One supervised restart.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct Restart {
    /// The stage.
    pub stage: &'static str,
    /// How the old process ended (e.g. "signal: 9 (SIGKILL)").
    pub status: String,
    /// The old process.
    pub old_pid: u32,
    /// The new one.
    pub new_pid: u32,
    /// Seconds since the run started.
    pub at_s: f64,
    /// Dead iceoryx2 nodes cleaned before the restart.
    pub stale_nodes_removed: usize,
    /// Sequence the restarted capture continues at (capture only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_frame: Option<u64>,
}

/// Resident memory of every child at one time.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct RssSample {
    /// Seconds since the run started.
    pub t_s: f64,
    /// (process, VmRSS kB) for every child alive.
    pub rss_kb: Vec<(&'static str, u64)>,
}

/// Resident memory of one process over the run.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct RssTrend {
    /// The process.
    pub process: &'static str,
    /// First sample, kB.
    pub start_kb: u64,
    /// Last sample, kB.
    pub end_kb: u64,
    /// Largest sample, kB.
    pub max_kb: u64,
}

/// First, last and largest sample per process.
pub fn rss_trend(samples: &[RssSample]) -> Vec<RssTrend> {
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

/// Ticks of user + system CPU of `pid` (/proc/PID/stat fields 14, 15).
pub fn cpu_ticks(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name may hold spaces; fields restart after its ')'.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    Some(f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?)
}

/// A memory figure of `pid` in kB (`VmRSS:`, `VmHWM:`).
pub fn status_kb(pid: u32, key: &str) -> Option<u64> {
    status_field(pid, key)?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// CPU time and peak resident memory of one process over a run.
#[derive(Serialize, Debug, Clone, PartialEq)]
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

/// User + system CPU seconds and peak RSS (kB) of this process.
pub fn self_usage() -> (f64, u64) {
    // SAFETY: getrusage fills the struct we pass.
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut ru) };
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 / 1e6;
    (secs(ru.ru_utime) + secs(ru.ru_stime), ru.ru_maxrss as u64)
}

/// The value of line `key` of /proc/PID/status, trimmed.
pub fn status_field(pid: u32, key: &str) -> Option<String> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix(key))
        .map(|v| v.trim().to_owned())
}

/// The children of a run; stopped on drop so nothing outlives the
/// supervisor.
pub struct Supervisor<S: Spawn> {
    spawn: S,
    policy: RestartPolicy,
    procs: Vec<Proc>,
    started: Instant,
    /// Every process started, restarts included: (name, pid).
    pub all_pids: Vec<(&'static str, u32)>,
}

impl<S: Spawn> Supervisor<S> {
    /// A supervisor that starts processes with `spawn`.
    pub fn new(spawn: S, policy: RestartPolicy) -> Self {
        Supervisor {
            spawn,
            policy,
            procs: Vec::new(),
            started: Instant::now(),
            all_pids: Vec::new(),
        }
    }

    /// Starts process `name` on `config`; `restartable` when it is a stage.
    pub fn start(
        &mut self,
        name: &'static str,
        config: &Path,
        restartable: bool,
    ) -> Result<u32, SuperviseError> {
        let child = self
            .spawn
            .spawn(name, config)
            .map_err(|source| SuperviseError::Spawn {
                name: name.to_owned(),
                source,
            })?;
        let pid = child.id();
        self.all_pids.push((name, pid));
        self.procs.push(Proc {
            name,
            child,
            restartable,
            restarts: 0,
            ticks0: None,
        });
        Ok(pid)
    }

    /// The children now.
    pub fn procs(&self) -> &[Proc] {
        &self.procs
    }

    /// (name, pid) of every child now.
    pub fn pids(&self) -> Vec<(&'static str, u32)> {
        self.procs.iter().map(|p| (p.name, p.child.id())).collect()
    }

    /// Marks now as the start of the run: restart times and CPU times count
    /// from here.
    pub fn mark_start(&mut self) {
        self.started = Instant::now();
        for p in &mut self.procs {
            p.ticks0 = cpu_ticks(p.child.id());
        }
    }

    /// Seconds since [`mark_start`](Self::mark_start).
    pub fn elapsed_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Every child's resident memory now.
    pub fn sample_rss(&self) -> RssSample {
        RssSample {
            t_s: self.elapsed_s(),
            rss_kb: self
                .procs
                .iter()
                .map(|p| (p.name, status_kb(p.child.id(), "VmRSS:").unwrap_or(0)))
                .collect(),
        }
    }

    /// CPU and peak memory of every child since the start.
    pub fn usage(&self) -> Vec<ProcessUsage> {
        // SAFETY: sysconf has no preconditions.
        let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
        let elapsed = self.elapsed_s();
        self.procs
            .iter()
            .map(|p| {
                let pid = p.child.id();
                let cpu_s = match (p.ticks0, cpu_ticks(pid)) {
                    (Some(a), Some(b)) => b.saturating_sub(a) as f64 / hz,
                    _ => 0.0,
                };
                ProcessUsage {
                    stage: p.name.into(),
                    cpu_s,
                    cpu_pct: 100.0 * cpu_s / elapsed.max(1e-9),
                    peak_rss_kb: status_kb(pid, "VmHWM:").unwrap_or(0),
                    cpus: status_field(pid, "Cpus_allowed_list:").unwrap_or_default(),
                }
            })
            .collect()
    }

    /// Reaps a child that has exited, if any: restarts a stage that died by
    /// a signal or a panic on the configuration `restart_config` gives for
    /// it (`None`: let it be, such as a capture whose every frame was
    /// sent), after `before_restart` (which cleans the dead node's shared
    /// memory and returns how many nodes it cleaned). An observer's exit, an
    /// orderly error or a stage past the restart limit ends the run.
    pub fn check(
        &mut self,
        mut restart_config: impl FnMut(&'static str) -> Option<(std::path::PathBuf, Option<u64>)>,
        before_restart: impl FnOnce() -> usize,
    ) -> Result<Option<Restart>, SuperviseError> {
        let Some((i, status)) =
            self.procs
                .iter_mut()
                .enumerate()
                .find_map(|(i, p)| match p.child.try_wait() {
                    Ok(Some(status)) => Some((i, status)),
                    _ => None,
                })
        else {
            return Ok(None);
        };
        let p = &self.procs[i];
        let name = p.name;
        let decision = if p.restartable {
            self.policy.decide(status, p.restarts)
        } else {
            Decision::Never
        };
        match decision {
            Decision::Never => {
                return Err(SuperviseError::ExitedEarly {
                    name: name.into(),
                    status,
                });
            }
            Decision::Orderly => {
                return Err(SuperviseError::NotRestartable {
                    name: name.into(),
                    status,
                });
            }
            Decision::Exhausted => {
                return Err(SuperviseError::GaveUp {
                    name: name.into(),
                    status,
                    restarts: p.restarts,
                });
            }
            Decision::Restart => {}
        }
        let old_pid = p.child.id();
        let stale = before_restart();
        let Some((config, first_frame)) = restart_config(name) else {
            tracing::warn!("{name} exited with {status}; not needed any more");
            self.procs.remove(i);
            return Ok(None);
        };
        let child = self
            .spawn
            .spawn(name, &config)
            .map_err(|source| SuperviseError::Spawn {
                name: name.into(),
                source,
            })?;
        let new_pid = child.id();
        let p = &mut self.procs[i];
        p.child = child;
        p.restarts += 1;
        p.ticks0 = cpu_ticks(new_pid);
        self.all_pids.push((name, new_pid));
        Ok(Some(Restart {
            stage: name,
            status: status.to_string(),
            old_pid,
            new_pid,
            at_s: self.elapsed_s(),
            stale_nodes_removed: stale,
            first_frame,
        }))
    }

    /// Stops every child: SIGINT, then SIGKILL for those still running
    /// after `grace`.
    pub fn stop(&mut self, grace: Duration) {
        for p in &self.procs {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(p.child.id() as libc::pid_t, libc::SIGINT) };
        }
        let until = Instant::now() + grace;
        for p in &mut self.procs {
            let (name, c) = (p.name, &mut p.child);
            // A stage about to sleep when the signal came notices it at the
            // end of its sleep (200 ms at most).
            loop {
                match c.try_wait() {
                    Ok(Some(status)) => {
                        if !status.success() {
                            tracing::warn!("{name} exited with {status}");
                        }
                        break;
                    }
                    Ok(None) if Instant::now() < until => {
                        std::thread::sleep(Duration::from_millis(20));
                    }
                    _ => {
                        tracing::warn!("{name} did not stop in time: killed");
                        let _ = c.kill();
                        let _ = c.wait();
                        break;
                    }
                }
            }
        }
        self.procs.clear();
    }
}

impl<S: Spawn> Drop for Supervisor<S> {
    fn drop(&mut self) {
        self.stop(Duration::from_secs(3));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::process::Command;

    /// Spawns `sh -c SCRIPT` for each process name, from a table.
    fn shells(
        table: &'static [(&'static str, &'static str)],
    ) -> impl FnMut(&str, &Path) -> std::io::Result<Child> {
        move |name, _| {
            let script = table
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, s)| *s)
                .expect("a process of the table");
            Command::new("sh").args(["-c", script]).spawn()
        }
    }

    fn wait_for<S: Spawn>(
        s: &mut Supervisor<S>,
        mut f: impl FnMut(&mut Supervisor<S>) -> bool,
    ) -> bool {
        let until = Instant::now() + Duration::from_secs(10);
        while Instant::now() < until {
            if f(s) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }

    #[test]
    fn the_policy_restarts_crashes_not_orderly_errors() {
        let p = RestartPolicy { max_restarts: 2 };
        let killed = ExitStatus::from_raw(libc::SIGKILL);
        let panicked = ExitStatus::from_raw(101 << 8);
        let orderly = ExitStatus::from_raw(1 << 8);
        assert_eq!(p.decide(killed, 0), Decision::Restart);
        assert_eq!(p.decide(panicked, 1), Decision::Restart);
        assert_eq!(p.decide(killed, 2), Decision::Exhausted);
        assert_eq!(p.decide(orderly, 0), Decision::Orderly);
    }

    #[test]
    fn a_killed_stage_is_restarted_until_the_limit() {
        static TABLE: [(&str, &str); 2] = [("crasher", "kill -9 $$"), ("steady", "sleep 30")];
        let mut s = Supervisor::new(shells(&TABLE), RestartPolicy { max_restarts: 2 });
        let cfg = Path::new("/dev/null");
        s.start("steady", cfg, true).unwrap();
        s.start("crasher", cfg, true).unwrap();
        s.mark_start();
        let mut restarts = Vec::new();
        let mut cleaned = 0;
        let err = loop {
            match s.check(
                |_| Some((cfg.to_owned(), None)),
                || {
                    cleaned += 1;
                    0
                },
            ) {
                Ok(Some(r)) => restarts.push(r),
                Ok(None) => std::thread::sleep(Duration::from_millis(10)),
                Err(e) => break e,
            }
        };
        assert_eq!(restarts.len(), 2, "{restarts:?}");
        assert!(restarts.iter().all(|r| r.stage == "crasher"));
        assert!(
            restarts[0].status.contains("signal: 9"),
            "{:?}",
            restarts[0]
        );
        assert_ne!(restarts[0].old_pid, restarts[0].new_pid);
        assert_eq!(cleaned, 2);
        assert!(
            matches!(err, SuperviseError::GaveUp { ref name, restarts: 2, .. } if name == "crasher"),
            "{err}"
        );
        // Two starts of the crasher after the first, and the steady one.
        assert_eq!(s.all_pids.len(), 4);
        let steady = s.procs().iter().find(|p| p.name == "steady").unwrap();
        assert_eq!(steady.restarts, 0);
    }

    #[test]
    fn an_orderly_error_or_an_observer_ends_the_run() {
        static TABLE: [(&str, &str); 2] = [("stage", "exit 1"), ("viz", "exit 0")];
        for (name, restartable) in [("stage", true), ("viz", false)] {
            let mut s = Supervisor::new(shells(&TABLE), RestartPolicy::default());
            s.start(name, Path::new("/dev/null"), restartable).unwrap();
            let mut got = None;
            assert!(wait_for(&mut s, |s| {
                got = s.check(|_| None, || 0).err();
                got.is_some()
            }));
            match (name, got.unwrap()) {
                ("stage", SuperviseError::NotRestartable { status, .. }) => {
                    assert_eq!(status.code(), Some(1))
                }
                ("viz", SuperviseError::ExitedEarly { .. }) => {}
                (n, e) => panic!("{n}: {e}"),
            }
        }
    }

    #[test]
    fn stopping_signals_then_kills_what_ignores_the_signal() {
        static TABLE: [(&str, &str); 2] = [
            ("polite", "trap 'exit 0' INT; while :; do sleep 0.05; done"),
            ("stubborn", "trap '' INT; while :; do sleep 0.05; done"),
        ];
        let mut s = Supervisor::new(shells(&TABLE), RestartPolicy::default());
        let polite = s.start("polite", Path::new("/dev/null"), true).unwrap();
        let stubborn = s.start("stubborn", Path::new("/dev/null"), true).unwrap();
        // Let the shells install their traps.
        std::thread::sleep(Duration::from_millis(300));
        let rss = s.sample_rss();
        assert_eq!(rss.rss_kb.len(), 2);
        assert!(rss.rss_kb.iter().all(|(_, kb)| *kb > 0), "{rss:?}");
        let t = Instant::now();
        s.stop(Duration::from_millis(500));
        assert!(
            t.elapsed() >= Duration::from_millis(450),
            "the stubborn one was not waited for"
        );
        assert!(s.procs().is_empty());
        for pid in [polite, stubborn] {
            // Reaped: no process of that pid is left (or it is another one).
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
            assert!(
                !stat.contains("(sh)") || stat.contains(" Z "),
                "{pid}: {stat}"
            );
        }
    }

    #[test]
    fn memory_trends_keep_first_last_and_largest() {
        let samples = [
            RssSample {
                t_s: 0.0,
                rss_kb: vec![("a", 10), ("b", 0)],
            },
            RssSample {
                t_s: 1.0,
                rss_kb: vec![("a", 30), ("b", 5)],
            },
            RssSample {
                t_s: 2.0,
                rss_kb: vec![("a", 20)],
            },
        ];
        let t = rss_trend(&samples);
        assert_eq!(
            t,
            vec![
                RssTrend {
                    process: "a",
                    start_kb: 10,
                    end_kb: 20,
                    max_kb: 30
                },
                RssTrend {
                    process: "b",
                    start_kb: 5,
                    end_kb: 5,
                    max_kb: 5
                },
            ]
        );
    }
}
