//! Inter-process plumbing of the acch pipeline: iceoryx2 services for frames
//! (`[u8]` pixels + a `#[repr(C)]` [`FrameHeader`]) and for each stage's
//! result ([`ResultMsg`], keyed by sequence), events so that every stage
//! sleeps until its input arrives, the timing trail, the frame history a
//! stage keeps to read the pixels of frame N, shared-memory location checks
//! that show frames are never copied, and zenoh publishing.
//!
//! No algorithm lives here; the stage crates never import this one.

pub mod channel;
pub mod msg;
pub mod sched;
pub mod shm;
pub mod wake;
pub mod zenoh_io;

pub use channel::{FrameHistory, FrameSample, Input, Ipc, Names, Output, Qos, ResultSample, Svc};
pub use msg::{
    ArmPose, FrameHeader, Fused, Observer, ResultMsg, STAGES, StageId, StageTimes, Trail, Truth,
    now_ns, pixel_format,
};
pub use shm::ShmLocator;
pub use zenoh_io::{SeedPublisher, ZenohConfig, open_session};

/// Errors of the IPC layer.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// An iceoryx2 call failed.
    #[error("iceoryx2: {0}")]
    Iceoryx(String),
    /// A zenoh call failed.
    #[error("zenoh: {0}")]
    Zenoh(String),
    /// A stream's wake-up word could not be opened, posted or waited on.
    #[error("wake-up word {}: {source}", path.display())]
    Wake {
        /// Its file.
        path: std::path::PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}

/// Removes the shared-memory resources of dead iceoryx2 nodes (a crashed
/// or killed stage) and the wake-up words of runs whose launcher died
/// ([`wake::remove_stale`]). Returns how many nodes were cleaned.
pub fn remove_stale_resources() -> usize {
    wake::remove_stale();
    use iceoryx2::prelude::*;
    let mut n = 0;
    let _ = Node::<Svc>::list(Config::global_config(), |state| {
        if let NodeState::<Svc>::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            n += 1;
        }
        CallbackProgression::Continue
    });
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_frame_crosses_threads_in_place_and_wakes_the_subscriber() {
        let names = Names::new(&format!("test-{}", std::process::id()));
        let qos = Qos {
            frame_history: 2,
            max_frame_bytes: 64 * 48 * 3,
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let names2 = names.clone();
        let reader = std::thread::spawn(move || {
            let ipc = Ipc::new(names2, "reader", qos).unwrap();
            let input = ipc.frame_input(true).unwrap();
            tx.send(()).unwrap();
            let mut loc = ShmLocator::new();
            for _ in 0..50 {
                input.wait(Duration::from_millis(100)).unwrap();
                if let Some(s) = input.receive().unwrap() {
                    let h = *s.user_header();
                    let here = loc.locate(s.payload().as_ptr() as usize).unwrap();
                    return (h, s.payload()[..4].to_vec(), here, now_ns());
                }
            }
            panic!("no frame arrived");
        });
        rx.recv_timeout(Duration::from_secs(10)).unwrap();
        let ipc = Ipc::new(names, "writer", qos).unwrap();
        let out = ipc.frame_output().unwrap();
        let pixels: Vec<u8> = (0..qos.max_frame_bytes).map(|i| i as u8).collect();
        let mut loc = ShmLocator::new();
        let mut written = (0, 0);
        out.send(&pixels, |h: &mut FrameHeader, addr| {
            written = loc.locate(addr).unwrap();
            h.sequence = 7;
            h.width = 64;
            h.height = 48;
            h.stride = 64 * 3;
            h.pixel_format = pixel_format::RGB8;
            (h.shm_file, h.shm_offset) = written;
            h.trail.stages[0].published_ns = now_ns();
        })
        .unwrap();
        let (h, first, here, woke) = reader.join().unwrap();
        assert_eq!(h.sequence, 7);
        assert_eq!(first, vec![0, 1, 2, 3]);
        // Same shared-memory file and offset in both: no copy.
        assert_eq!(here, written);
        assert_eq!(here, (h.shm_file, h.shm_offset));
        assert!(woke >= h.trail.stages[0].published_ns);
        wake::remove_run(&format!("test-{}", std::process::id()));
    }

    #[test]
    fn stage_names_round_trip() {
        for s in StageId::ALL {
            assert_eq!(StageId::from_name(s.name()), Some(s));
        }
        assert_eq!(StageId::Pose.upstream(), Some(StageId::Segmentation));
        assert_eq!(StageId::Capture.upstream(), None);
    }
}
