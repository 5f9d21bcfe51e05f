//! The stages' wake-ups: one futex word per stream, in a shared-memory file
//! of the run.
//!
//! A stage sleeps in the kernel until its upstream stage publishes. The
//! publisher bumps the stream's counter and wakes the futex; the stage
//! waits for the counter to move from the value it read before it last
//! found its queue empty, so a publish between that check and the sleep is
//! never lost. This is the least a wake-up can be: one atomic add and one
//! system call on each side.
//!
//! It replaced an iceoryx2 event on shared-memory semaphores. Measured with
//! `cargo run --release -p acch-ipc --example hop_floor -- --same-cpu
//! --rt 20 --cpu-latency-us 0 --period-ms 33`, one message per 30 fps
//! frame: the event's notify-to-awake took 30-31 µs p50, a bare futex
//! between two C processes 16 µs. After a frame period asleep the
//! processes start cold, and the event's bookkeeping (listener lists, the
//! id bitset, deadline checks) is cache misses on the critical path. With
//! the word, the whole hop (send to the stage awake with its sample) is
//! 24-27 µs p50 there, against 34-35 µs with the event.
//!
//! The files are `/dev/shm/acch-<instance>-<stream>.wake`, mode 0600. Any
//! process of the run creates a stream's file on first use (a restarted
//! stage finds the one its peers use); the launcher removes the run's files
//! when it ends ([`RunFiles`]), and [`remove_stale`] those of runs whose
//! launcher died.

use std::fs::OpenOptions;
use std::io;
use std::os::unix::fs::OpenOptionsExt;
use std::path::PathBuf;
use std::ptr::NonNull;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

/// Where the files live (tmpfs, as iceoryx2's shared memory).
const DIR: &str = "/dev/shm";
/// One page: the mapping's granule.
const LEN: usize = 4096;

/// The path of stream `what`'s wake-up word in run `instance`.
pub fn path(instance: &str, what: &str) -> PathBuf {
    PathBuf::from(DIR).join(format!("acch-{instance}-{what}.wake"))
}

/// A stream's wake-up counter, mapped from its shared-memory file.
pub struct WakeWord {
    word: NonNull<AtomicU32>,
    /// The file, for error messages.
    path: PathBuf,
}

// SAFETY: the mapping is shared memory accessed only through atomics, and
// it lives (unmapped in Drop) as long as the value.
unsafe impl Send for WakeWord {}
// SAFETY: as above; every access is atomic.
unsafe impl Sync for WakeWord {}

impl WakeWord {
    /// Maps stream `what`'s word of run `instance`, creating its file
    /// (0600) if no process of the run has yet.
    pub fn open(instance: &str, what: &str) -> io::Result<Self> {
        let path = path(instance, what);
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .mode(0o600)
            .open(&path)?;
        // Idempotent: whoever comes first sizes the file, a later set_len to
        // the same length changes nothing (a process that opened the file
        // before it was sized sizes it too rather than failing).
        file.set_len(LEN as u64)?;
        // SAFETY: a fresh shared mapping of a file we hold open, LEN bytes,
        // which the file has; no address hint.
        let addr = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                LEN,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                std::os::fd::AsRawFd::as_raw_fd(&file),
                0,
            )
        };
        if addr == libc::MAP_FAILED {
            return Err(io::Error::last_os_error());
        }
        // The mapping outlives the descriptor.
        drop(file);
        let word = NonNull::new(addr.cast::<AtomicU32>()).ok_or_else(io::Error::last_os_error)?;
        Ok(WakeWord { word, path })
    }

    /// The word's file.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }

    fn word(&self) -> &AtomicU32 {
        // SAFETY: page-aligned, mapped for as long as self lives.
        unsafe { self.word.as_ref() }
    }

    /// The counter now. Read it before the last check for input, then pass
    /// it to [`wait`](Self::wait).
    pub fn current(&self) -> u32 {
        self.word().load(Ordering::SeqCst)
    }

    /// Bumps the counter and wakes whoever sleeps on it.
    pub fn post(&self) -> io::Result<()> {
        self.word().fetch_add(1, Ordering::SeqCst);
        // SAFETY: FUTEX_WAKE on a mapped, aligned u32; the other arguments
        // are ignored by this operation.
        let r = unsafe {
            libc::syscall(
                libc::SYS_futex,
                self.word.as_ptr(),
                libc::FUTEX_WAKE,
                i32::MAX,
                std::ptr::null::<libc::timespec>(),
                std::ptr::null::<u32>(),
                0u32,
            )
        };
        if r < 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    }

    /// Sleeps while the counter still reads `seen`, for at most `timeout`
    /// (or until a signal, so the caller can check whether to stop).
    pub fn wait(&self, seen: u32, timeout: Duration) -> io::Result<()> {
        let ts = libc::timespec {
            tv_sec: timeout.as_secs().min(i64::MAX as u64) as libc::time_t,
            tv_nsec: timeout.subsec_nanos() as libc::c_long,
        };
        // SAFETY: FUTEX_WAIT on a mapped, aligned u32 with a valid relative
        // timeout; shared (not PRIVATE): the word is in another process too.
        let r = unsafe {
            libc::syscall(
                libc::SYS_futex,
                self.word.as_ptr(),
                libc::FUTEX_WAIT,
                seen,
                &ts as *const libc::timespec,
                std::ptr::null::<u32>(),
                0u32,
            )
        };
        if r < 0 {
            let e = io::Error::last_os_error();
            // Already moved on, timed out, or a signal: all mean "look again".
            if !matches!(
                e.raw_os_error(),
                Some(libc::EAGAIN | libc::ETIMEDOUT | libc::EINTR)
            ) {
                return Err(e);
            }
        }
        Ok(())
    }
}

impl Drop for WakeWord {
    fn drop(&mut self) {
        // SAFETY: the mapping made in `open`, unmapped once.
        unsafe { libc::munmap(self.word.as_ptr().cast(), LEN) };
    }
}

/// Removes run `instance`'s wake-up files when dropped: the launcher holds
/// one for as long as the run lasts, however it ends.
pub struct RunFiles {
    instance: String,
}

impl RunFiles {
    /// The files of run `instance` (none need exist yet).
    pub fn new(instance: &str) -> Self {
        RunFiles {
            instance: instance.to_owned(),
        }
    }
}

impl Drop for RunFiles {
    fn drop(&mut self) {
        remove_run(&self.instance);
    }
}

/// Removes the wake-up files of run `instance`; returns how many.
pub fn remove_run(instance: &str) -> usize {
    let prefix = format!("acch-{instance}-");
    remove_where(|name| name.strip_prefix(&prefix).is_some())
}

/// Removes the wake-up files of runs whose launcher (the instance is its
/// pid) is no longer alive; returns how many.
pub fn remove_stale() -> usize {
    remove_where(|name| {
        let pid = name
            .strip_prefix("acch-")
            .and_then(|rest| rest.split('-').next())
            .and_then(|p| p.parse::<u32>().ok());
        pid.is_some_and(|pid| !std::path::Path::new(&format!("/proc/{pid}")).exists())
    })
}

fn remove_where(doomed: impl Fn(&str) -> bool) -> usize {
    let Ok(dir) = std::fs::read_dir(DIR) else {
        return 0;
    };
    dir.filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_str()
                .is_some_and(|n| n.ends_with(".wake") && doomed(n))
        })
        .filter(|e| std::fs::remove_file(e.path()).is_ok())
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    #[test]
    fn a_post_wakes_a_sleeper_and_a_post_before_the_sleep_is_not_lost() {
        let instance = format!("test-wake-{}", std::process::id());
        let a = WakeWord::open(&instance, "s").unwrap();
        let b = WakeWord::open(&instance, "s").unwrap();
        // Posted between the read and the sleep: the wait returns at once.
        let seen = b.current();
        a.post().unwrap();
        let t = Instant::now();
        b.wait(seen, Duration::from_secs(5)).unwrap();
        assert!(t.elapsed() < Duration::from_secs(1));
        // A sleeper is woken by a post from another thread.
        let seen = b.current();
        let poster = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            a.post().unwrap();
        });
        let t = Instant::now();
        b.wait(seen, Duration::from_secs(5)).unwrap();
        assert!(t.elapsed() < Duration::from_secs(4));
        assert_ne!(b.current(), seen);
        poster.join().unwrap();
        // No post: the wait ends at its timeout.
        let t = Instant::now();
        b.wait(b.current(), Duration::from_millis(30)).unwrap();
        assert!(t.elapsed() >= Duration::from_millis(30));
        let mode = std::fs::metadata(path(&instance, "s")).unwrap();
        assert_eq!(
            std::os::unix::fs::PermissionsExt::mode(&mode.permissions()) & 0o777,
            0o600
        );
        assert_eq!(remove_run(&instance), 1);
        assert!(!path(&instance, "s").exists());
    }

    #[test]
    fn files_of_dead_runs_are_stale_and_of_live_ones_are_not() {
        // A pid that cannot be alive (above the kernel's limit).
        let dead = "4194304999";
        let live = std::process::id().to_string();
        let _d = WakeWord::open(dead, "frames").unwrap();
        let _l = WakeWord::open(&live, "frames").unwrap();
        remove_stale();
        assert!(!path(dead, "frames").exists());
        assert!(path(&live, "frames").exists());
        assert_eq!(remove_run(&live), 1);
    }
}
