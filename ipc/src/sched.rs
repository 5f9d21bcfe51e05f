//! Scheduling of the pipeline's processes: real-time priority and CPU
//! placement.
//!
//! On a loaded machine a stage woken by its input waits for a core behind
//! whatever else is runnable; under SCHED_FIFO it preempts normal work at
//! once. Measured on the 2-core CI machine with builds running beside the
//! pipeline, this cut the per-hop p99 from milliseconds to about 0.15 ms
//! (README, "Latency"). It needs CAP_SYS_NICE (or root, or an rtprio limit).
//!
//! Placement: a wake-up that crosses CPUs costs an inter-processor
//! interrupt, and on a virtual machine an idle vCPU must first be scheduled
//! by the host; measured here (`cargo run --release -p acch-ipc --example
//! hop_floor`), a hop took 30 µs p50 / 65 µs p99 across vCPUs against 7 µs
//! / 15-24 µs when both processes share one. The stages run one after the
//! other on a frame, so they lose nothing by sharing a CPU, and the palette
//! indices one stage writes are still in that CPU's cache when the next
//! reads them.

use std::io;

/// Highest base priority accepted: the stages run at base + 1 ..= base + 5
/// (later stages higher), which leaves the top of the range (up to 99) to
/// the kernel's own threads and to the robot's control loops.
pub const MAX_PRIORITY: u8 = 90;

/// Puts the calling thread under SCHED_FIFO at `priority` (1 ..=
/// [`MAX_PRIORITY`] + 5); processes it starts afterwards inherit the
/// policy.
pub fn set_fifo(priority: u8) -> io::Result<()> {
    if !(1..=MAX_PRIORITY + 5).contains(&priority) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "real-time priority {priority} is out of range 1..={}",
                MAX_PRIORITY + 5
            ),
        ));
    }
    let param = libc::sched_param {
        sched_priority: priority as libc::c_int,
    };
    // SAFETY: sched_setscheduler on our own pid (0) with a valid parameter.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Puts the calling thread back under the normal scheduler (processes
/// beside the pipeline, like the viewer, must not preempt its stages).
pub fn set_normal() -> io::Result<()> {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_setscheduler on our own thread with a valid parameter;
    // leaving a real-time policy needs no privilege.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) } == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Puts the calling thread under SCHED_IDLE: it runs only when nothing
/// else on its CPU wants to (the synthetic camera's rendering, which
/// stands in for a camera's own hardware). Needs no privilege.
pub fn set_idle() -> io::Result<()> {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_setscheduler on our own thread (0) with a valid param.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) } == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// The CPUs the calling thread may run on, ascending.
pub fn allowed_cpus() -> io::Result<Vec<usize>> {
    // SAFETY: cpu_set_t is plain data; all-zero is the empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    // SAFETY: sched_getaffinity writes at most size_of::<cpu_set_t>() bytes
    // into the set we own.
    if unsafe { libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) } != 0
    {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: CPU_ISSET only reads the set, for indices below CPU_SETSIZE.
    Ok((0..libc::CPU_SETSIZE as usize)
        .filter(|&c| unsafe { libc::CPU_ISSET(c, &set) })
        .collect())
}

/// Restricts the calling thread (and the threads and processes it starts
/// afterwards) to `cpus`.
pub fn pin_to(cpus: &[usize]) -> io::Result<()> {
    // SAFETY: as in `allowed_cpus`.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    for &c in cpus {
        if c >= libc::CPU_SETSIZE as usize {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("CPU {c} is beyond the largest CPU set"),
            ));
        }
        // SAFETY: c is below CPU_SETSIZE (checked above).
        unsafe { libc::CPU_SET(c, &mut set) };
    }
    // SAFETY: sched_setaffinity on our own thread (0) reads the set we own.
    if unsafe { libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) } == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// A held request that the CPUs wake from idle within a bound (the kernel's
/// CPU latency QoS, `/dev/cpu_dma_latency`), for as long as it lives.
///
/// An idle vCPU that halts hands its physical core back to the host; waking
/// it costs an interrupt through the hypervisor, and it comes back with
/// caches the host's other work has cooled. At 0 µs the idle loop polls
/// instead of halting. Measured on the 2-vCPU machine (`hop_floor`), a
/// cross-CPU hop fell from 54 to 4.9 µs p50, and the stages, which idle
/// most of every frame period, computed closer to the one-process figures
/// (README, "Latency benchmark"). The price: idle CPUs stay busy, so it is
/// opt-in (`cpu_latency_us`), as on real-time robots (cyclictest and tuned's
/// latency profiles set the same file). Needs root.
#[derive(Debug)]
pub struct CpuLatencyRequest {
    // The kernel drops the request when this descriptor closes.
    _file: std::fs::File,
    micros: u32,
}

impl CpuLatencyRequest {
    /// The kernel's interface.
    pub const PATH: &'static str = "/dev/cpu_dma_latency";
    /// Largest bound the kernel takes (its default: no constraint, 2000 s).
    pub const MAX_MICROS: u32 = 2_000_000_000;

    /// Asks that no CPU take longer than `micros` to leave an idle state
    /// until the request is dropped.
    pub fn hold(micros: u32) -> io::Result<Self> {
        if micros > Self::MAX_MICROS {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "CPU latency {micros} µs is out of range 0..={}",
                    Self::MAX_MICROS
                ),
            ));
        }
        use std::io::Write;
        let mut file = std::fs::OpenOptions::new().write(true).open(Self::PATH)?;
        // Four bytes are read as a binary s32 (any other length as hex text).
        file.write_all(&(micros as i32).to_ne_bytes())?;
        Ok(CpuLatencyRequest {
            _file: file,
            micros,
        })
    }

    /// The bound this request holds, µs.
    pub fn micros(&self) -> u32 {
        self.micros
    }

    /// The bound in force now (the tightest of all held requests), µs.
    pub fn in_force() -> io::Result<u32> {
        use std::io::Read;
        let mut value = [0u8; 4];
        std::fs::File::open(Self::PATH)?.read_exact(&mut value)?;
        Ok(i32::from_ne_bytes(value).max(0) as u32)
    }
}

/// Where the processes of a run go: the five processing stages on
/// `stages`, capture, the observers and the launcher on `others`.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Placement {
    /// CPUs of the processing stages (recognition .. seeding).
    pub stages: Vec<usize>,
    /// CPUs of everything else; empty = wherever the scheduler likes.
    pub others: Vec<usize>,
}

/// How the stages are placed, as configured (`stage_cpus`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StageCpus {
    /// The last allowed CPU for the stages, the rest for everything else,
    /// when at least two CPUs are allowed; no placement otherwise.
    Auto,
    /// No placement: the scheduler decides.
    Free,
    /// These CPUs for the stages, the other allowed CPUs for the rest.
    List(Vec<usize>),
}

impl std::str::FromStr for StageCpus {
    type Err = String;
    /// `auto`, `none` or a comma-separated list of CPU numbers (`1`, `2,3`).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "auto" => Ok(StageCpus::Auto),
            "none" => Ok(StageCpus::Free),
            list => {
                let mut cpus = list
                    .split(',')
                    .map(|c| {
                        c.trim()
                            .parse::<usize>()
                            .ok()
                            .filter(|&c| c < libc::CPU_SETSIZE as usize)
                            .ok_or_else(|| {
                                format!(
                                    "'{c}' is not a CPU number (auto, none or a list like 1 or 2,3)"
                                )
                            })
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                cpus.sort_unstable();
                cpus.dedup();
                Ok(StageCpus::List(cpus))
            }
        }
    }
}

impl std::fmt::Display for StageCpus {
    /// As [`FromStr`](std::str::FromStr) reads it: `auto`, `none` or the
    /// list (`2,3`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StageCpus::Auto => f.write_str("auto"),
            StageCpus::Free => f.write_str("none"),
            StageCpus::List(cpus) => {
                for (i, c) in cpus.iter().enumerate() {
                    if i > 0 {
                        f.write_str(",")?;
                    }
                    write!(f, "{c}")?;
                }
                Ok(())
            }
        }
    }
}

impl StageCpus {
    /// The placement on a machine where `allowed` CPUs may be used; `None`
    /// when nothing is to be pinned. A list naming a CPU outside `allowed`
    /// is an error (the kernel would refuse it in every stage process).
    pub fn resolve(&self, allowed: &[usize]) -> Result<Option<Placement>, String> {
        match self {
            StageCpus::Free => Ok(None),
            StageCpus::Auto => Ok(match allowed {
                [.., last] if allowed.len() >= 2 => Some(Placement {
                    stages: vec![*last],
                    others: allowed[..allowed.len() - 1].to_vec(),
                }),
                _ => None,
            }),
            StageCpus::List(cpus) => {
                if let Some(c) = cpus.iter().find(|c| !allowed.contains(c)) {
                    return Err(format!(
                        "CPU {c} is not available to this process (allowed: {allowed:?})"
                    ));
                }
                let others: Vec<usize> = allowed
                    .iter()
                    .copied()
                    .filter(|c| !cpus.contains(c))
                    .collect();
                Ok(Some(Placement {
                    stages: cpus.clone(),
                    others,
                }))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calling thread's scheduling policy and priority.
    fn current() -> (libc::c_int, libc::c_int) {
        // SAFETY: both calls only read our own scheduling state.
        let policy = unsafe { libc::sched_getscheduler(0) };
        let mut param = libc::sched_param { sched_priority: 0 };
        unsafe { libc::sched_getparam(0, &mut param) };
        (policy, param.sched_priority)
    }

    #[test]
    fn stage_cpus_parse_and_resolve() {
        let two = [0, 1];
        assert_eq!(
            "auto".parse::<StageCpus>().unwrap().resolve(&two),
            Ok(Some(Placement {
                stages: vec![1],
                others: vec![0]
            }))
        );
        // One CPU: nothing to separate.
        assert_eq!(StageCpus::Auto.resolve(&[3]), Ok(None));
        assert_eq!("none".parse::<StageCpus>().unwrap().resolve(&two), Ok(None));
        assert_eq!(
            " 3, 2,3"
                .parse::<StageCpus>()
                .unwrap()
                .resolve(&[0, 1, 2, 3]),
            Ok(Some(Placement {
                stages: vec![2, 3],
                others: vec![0, 1]
            }))
        );
        // Every allowed CPU for the stages leaves the rest unplaced.
        assert_eq!(
            StageCpus::List(vec![0, 1]).resolve(&two),
            Ok(Some(Placement {
                stages: vec![0, 1],
                others: vec![]
            }))
        );
        assert!(
            StageCpus::List(vec![5])
                .resolve(&two)
                .unwrap_err()
                .contains("CPU 5")
        );
        // Written as read, the list sorted once.
        for (text, shown) in [("auto", "auto"), ("none", "none"), (" 3, 2,3", "2,3")] {
            let cpus: StageCpus = text.parse().unwrap();
            assert_eq!(cpus.to_string(), shown);
            assert_eq!(shown.parse::<StageCpus>(), Ok(cpus));
        }
        for bad in ["", "x", "1,", "-1", "99999"] {
            assert!(bad.parse::<StageCpus>().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_thread_is_pinned_where_it_is_told() {
        std::thread::spawn(|| {
            let allowed = allowed_cpus().unwrap();
            assert!(!allowed.is_empty());
            let last = *allowed.last().unwrap();
            pin_to(&[last]).unwrap();
            assert_eq!(allowed_cpus().unwrap(), vec![last]);
            assert!(pin_to(&[libc::CPU_SETSIZE as usize]).is_err());
        })
        .join()
        .unwrap();
    }

    #[test]
    fn a_cpu_latency_request_holds_while_it_lives_or_says_why_not() {
        let e = CpuLatencyRequest::hold(CpuLatencyRequest::MAX_MICROS + 1).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        match CpuLatencyRequest::hold(0) {
            Ok(request) => {
                assert_eq!(request.micros(), 0);
                // The tightest request is in force, and none is tighter.
                assert_eq!(CpuLatencyRequest::in_force().unwrap(), 0);
            }
            Err(e) => assert!(
                matches!(
                    e.kind(),
                    io::ErrorKind::PermissionDenied | io::ErrorKind::NotFound
                ),
                "{e}"
            ),
        }
    }

    #[test]
    fn out_of_range_priorities_are_refused() {
        for p in [0, MAX_PRIORITY + 6] {
            let e = set_fifo(p).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{p}");
        }
    }

    #[test]
    fn a_thread_goes_real_time_or_says_why_not() {
        // In a thread of its own, so the test harness keeps its policy.
        std::thread::spawn(|| match set_fifo(1) {
            Ok(()) => {
                assert_eq!(current(), (libc::SCHED_FIFO, 1));
                set_normal().unwrap();
                assert_eq!(current(), (libc::SCHED_OTHER, 0));
            }
            Err(e) => assert_eq!(e.raw_os_error(), Some(libc::EPERM), "{e}"),
        })
        .join()
        .unwrap();
    }
}
