//! Real-time scheduling of the pipeline's processes.
//!
//! On a loaded machine a stage woken by its input waits for a core behind
//! whatever else is runnable; under SCHED_FIFO it preempts normal work at
//! once. Measured on the 2-core CI machine with builds running beside the
//! pipeline, this cut the per-hop p99 from milliseconds to about 0.15 ms
//! (README, "Latency"). It needs CAP_SYS_NICE (or root, or an rtprio limit).

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
