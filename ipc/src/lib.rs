//! Inter-process plumbing of the acch pipeline: iceoryx2 streams of a
//! `[u8]` payload with a typed `#[repr(C)]` header ([`Output`], [`Input`];
//! the header types are the pipeline's, defined beside the stage that
//! writes them), the stages' futex wake-ups ([`wake`]), CPU placement and
//! scheduling ([`sched`]), shared-memory location checks that show frames
//! are never copied ([`ShmLocator`]), the clock of every timing trail
//! ([`now_ns`]) and zenoh sessions ([`zenoh_io`]).
//!
//! No algorithm lives here, and nothing here knows what a stage computes.

pub mod channel;
pub mod error;
pub mod sched;
pub mod shm;
pub mod wake;
pub mod zenoh_io;

pub use channel::{
    Control, ControlListener, Header, Input, Ipc, Output, Received, StreamSpec, Svc, Wake,
};
pub use error::{IpcError, NodeError, OpenError, ReceiveError, SendError, WaitError, ZenohError};
pub use iceoryx2::prelude::ZeroCopySend;
pub use shm::ShmLocator;
pub use zenoh_io::{Publisher, ZenohConfig, open_session};

/// CLOCK_MONOTONIC now, nanoseconds (the clock of every timing trail).
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec we own.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// CLOCK_REALTIME now, nanoseconds since the Unix epoch (the clock of ROS
/// 2 time stamps and MCAP log times).
pub fn wall_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Sets iceoryx2's log level from `IOX2_LOG_LEVEL`, or to errors only:
/// it warns in every process that it runs on its default configuration,
/// which is intended.
pub fn quiet_iceoryx2_logs() {
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
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

    /// A header as a pipeline stream would carry.
    #[repr(C)]
    #[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
    struct TestHeader {
        sequence: u64,
        location: [u64; 2],
        published_ns: u64,
    }

    const FRAMES: StreamSpec = StreamSpec {
        name: "frames",
        subscribers: 2,
        buffer: 2,
        borrowed: 3,
    };

    #[test]
    fn a_frame_crosses_threads_in_place_and_wakes_the_subscriber() {
        let instance = format!("test-{}", std::process::id());
        let bytes = 64 * 48 * 3;
        let (tx, rx) = std::sync::mpsc::channel();
        let instance2 = instance.clone();
        let reader = std::thread::spawn(move || {
            let ipc = Ipc::new(&instance2, "reader").unwrap();
            let input = ipc.input::<TestHeader>(FRAMES, Wake::Word).unwrap();
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
        let ipc = Ipc::new(&instance, "writer").unwrap();
        let out = ipc.output::<TestHeader>(FRAMES, bytes).unwrap();
        let pixels: Vec<u8> = (0..bytes).map(|i| i as u8).collect();
        let mut loc = ShmLocator::new();
        let mut written = (0, 0);
        out.send(&pixels, |h, addr| {
            written = loc.locate(addr).unwrap();
            h.sequence = 7;
            h.location = [written.0, written.1];
            h.published_ns = now_ns();
        })
        .unwrap();
        let (h, first, here, woke) = reader.join().unwrap();
        assert_eq!(h.sequence, 7);
        assert_eq!(first, vec![0, 1, 2, 3]);
        // Same shared-memory file and offset in both: no copy.
        assert_eq!(here, written);
        assert_eq!([here.0, here.1], h.location);
        assert!(woke >= h.published_ns);
        wake::remove_run(&instance);
    }

    #[test]
    fn a_payload_larger_than_the_service_is_a_typed_loan_error_naming_the_stream() {
        let instance = format!("test-loan-{}", std::process::id());
        let ipc = Ipc::new(&instance, "writer").unwrap();
        let out = ipc.output::<TestHeader>(FRAMES, 16).unwrap();
        let err = out.send(&[0u8; 4096], |_, _| {}).unwrap_err();
        assert!(matches!(err, SendError::Loan { len: 4096, .. }), "{err:?}");
        assert!(err.to_string().contains("frames"), "{err}");
        wake::remove_run(&instance);
    }

    #[test]
    fn a_write_that_fails_sends_nothing() {
        let instance = format!("test-fail-{}", std::process::id());
        let ipc = Ipc::new(&instance, "both").unwrap();
        let input = ipc.input::<TestHeader>(FRAMES, Wake::Never).unwrap();
        let out = ipc.output::<TestHeader>(FRAMES, 16).unwrap();
        let r = out.send_in_place(8, |_, _| Err::<(), _>("no")).unwrap();
        assert_eq!(r, Err("no"));
        assert!(input.receive().unwrap().is_none());
        assert_eq!(
            out.send_in_place(8, |_, h| {
                h.sequence = 3;
                Ok::<(), ()>(())
            })
            .unwrap(),
            Ok(1)
        );
        assert_eq!(input.receive().unwrap().unwrap().user_header().sequence, 3);
        wake::remove_run(&instance);
    }
}
