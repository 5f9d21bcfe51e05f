//! The benchmark's copy baseline: frames written by capture into one Unix
//! stream socket per pixel-reading stage; a thread in the stage reads each
//! frame into a buffer of its own (a ring of `run.frame_history` buffers,
//! reused), where the stage looks frame N up.

use crate::PipelineConfig;
use std::collections::VecDeque;
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// The socket recognition receives its frame copies on.
pub fn socket_path(cfg: &PipelineConfig) -> PathBuf {
    std::env::temp_dir().join(format!("acch-{}-recognition.sock", cfg.run.instance))
}

/// A socket of the copy transport failed.
#[derive(Debug, thiserror::Error)]
#[error("frame copies through {}", path.display())]
pub struct CopyError {
    /// The socket.
    pub path: PathBuf,
    /// What the system said.
    #[source]
    pub source: std::io::Error,
}

/// Capture's end: one connected stream per consumer.
pub struct FrameSender {
    streams: Vec<(PathBuf, UnixStream)>,
}

impl FrameSender {
    /// Connects to every consumer's socket.
    pub fn connect(paths: &[PathBuf]) -> Result<Self, CopyError> {
        let streams = paths
            .iter()
            .map(|p| {
                UnixStream::connect(p)
                    .map(|s| (p.clone(), s))
                    .map_err(|source| CopyError {
                        path: p.clone(),
                        source,
                    })
            })
            .collect::<Result<_, _>>()?;
        Ok(FrameSender { streams })
    }

    /// Writes frame `sequence` to every consumer (blocks while a
    /// consumer's socket buffer is full).
    pub fn send(&mut self, sequence: u64, pixels: &[u8]) -> Result<(), CopyError> {
        let mut head = [0u8; 16];
        head[..8].copy_from_slice(&sequence.to_ne_bytes());
        head[8..].copy_from_slice(&(pixels.len() as u64).to_ne_bytes());
        for (path, s) in &mut self.streams {
            s.write_all(&head)
                .and_then(|_| s.write_all(pixels))
                .map_err(|source| CopyError {
                    path: path.clone(),
                    source,
                })?;
        }
        Ok(())
    }
}

#[derive(Default)]
struct Ring {
    frames: VecDeque<(u64, Vec<u8>)>,
    spare: Vec<Vec<u8>>,
    capacity: usize,
}

/// A stage's end: the frames copied so far.
pub struct FrameReceiver {
    shared: Arc<(Mutex<Ring>, Condvar)>,
    current: Vec<u8>,
    path: PathBuf,
}

impl FrameReceiver {
    /// Binds the stage's socket and starts the thread that accepts
    /// capture and copies every frame in.
    pub fn bind(path: &Path, capacity: usize) -> Result<Self, CopyError> {
        let _ = std::fs::remove_file(path);
        let listener = UnixListener::bind(path).map_err(|source| CopyError {
            path: path.to_owned(),
            source,
        })?;
        let shared = Arc::new((
            Mutex::new(Ring {
                capacity: capacity.max(1),
                ..Default::default()
            }),
            Condvar::new(),
        ));
        let ring = shared.clone();
        std::thread::spawn(move || {
            let Ok((mut stream, _)) = listener.accept() else {
                return;
            };
            let mut head = [0u8; 16];
            while stream.read_exact(&mut head).is_ok() {
                let seq = u64::from_ne_bytes(head[..8].try_into().expect("8 bytes"));
                let len = u64::from_ne_bytes(head[8..].try_into().expect("8 bytes")) as usize;
                let mut buf = ring
                    .0
                    .lock()
                    .ok()
                    .and_then(|mut r| r.spare.pop())
                    .unwrap_or_default();
                buf.resize(len, 0);
                if stream.read_exact(&mut buf).is_err() {
                    return;
                }
                let Ok(mut r) = ring.0.lock() else { return };
                if r.frames.len() == r.capacity
                    && let Some((_, old)) = r.frames.pop_front()
                {
                    r.spare.push(old);
                }
                r.frames.push_back((seq, buf));
                drop(r);
                ring.1.notify_all();
            }
        });
        Ok(FrameReceiver {
            shared,
            current: Vec::new(),
            path: path.to_owned(),
        })
    }

    /// Frame `sequence` (waiting up to `timeout` for its copy to
    /// complete); older frames are released.
    pub fn take(&mut self, sequence: u64, timeout: Duration) -> Option<&[u8]> {
        let until = Instant::now() + timeout;
        let (lock, cond) = &*self.shared;
        let mut r = lock.lock().ok()?;
        loop {
            while r.frames.front().is_some_and(|(s, _)| *s < sequence) {
                let (_, old) = r.frames.pop_front().expect("front exists");
                r.spare.push(old);
            }
            if let Some((s, _)) = r.frames.front() {
                if *s != sequence {
                    return None;
                }
                let (_, buf) = r.frames.pop_front().expect("front exists");
                let old = std::mem::replace(&mut self.current, buf);
                r.spare.push(old);
                return Some(&self.current);
            }
            let left = until.checked_duration_since(Instant::now())?;
            r = cond.wait_timeout(r, left).ok()?.0;
        }
    }
}

impl Drop for FrameReceiver {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
