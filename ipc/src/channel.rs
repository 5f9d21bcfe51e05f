//! iceoryx2 services of one pipeline run: a `[u8]` payload with a
//! `#[repr(C)]` user header, plus an event service per data service so a
//! consumer sleeps until its input arrives.

use crate::IpcError;
use crate::msg::{FrameHeader, ResultMsg, StageId};
use crate::wake::WakeWord;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use std::cell::Cell;
use std::collections::VecDeque;
use std::fmt::Debug;
use std::time::Duration;

/// The iceoryx2 service flavour (inter-process, ports stay on one thread).
pub type Svc = ipc::Service;

/// A received frame: header + pixels, borrowed from shared memory.
pub type FrameSample = Sample<Svc, [u8], FrameHeader>;
/// A received stage result: header + the stage's payload (mask, response).
pub type ResultSample = Sample<Svc, [u8], ResultMsg>;

/// Sizes of the services (shared memory is sized from them up front).
#[derive(Clone, Copy, Debug)]
pub struct Qos {
    /// Frames a stage keeps to look pixels up by sequence.
    pub frame_history: usize,
    /// Largest frame payload, bytes.
    pub max_frame_bytes: usize,
}

/// Subscribers of the frame service: recognition, segmentation, pose, the
/// viewer and the recorder.
const FRAME_SUBSCRIBERS: usize = 5;
/// Subscribers of a result service: the next stage, the launcher, the
/// viewer and the recorder.
const RESULT_SUBSCRIBERS: usize = 4;
/// Result samples queued per subscriber before the oldest is dropped.
const RESULT_BUFFER: usize = 8;

/// Names of the services of one run; `instance` keeps concurrent runs apart.
#[derive(Clone, Debug)]
pub struct Names {
    instance: String,
}

impl Names {
    /// Services of run `instance` (the launcher's pid).
    pub fn new(instance: &str) -> Self {
        Names {
            instance: instance.to_owned(),
        }
    }

    fn name(&self, what: &str) -> Result<ServiceName, IpcError> {
        let s = format!("acch/{}/{what}", self.instance);
        ServiceName::new(&s).map_err(|e| IpcError::Iceoryx(format!("service name {s}: {e:?}")))
    }
}

fn err<E: Debug>(what: &str) -> impl FnOnce(E) -> IpcError + '_ {
    move |e| IpcError::Iceoryx(format!("{what}: {e:?}"))
}

fn wake_error(word: &WakeWord, source: std::io::Error) -> IpcError {
    IpcError::Wake {
        path: word.path().to_owned(),
        source,
    }
}

/// One process's handle on iceoryx2.
pub struct Ipc {
    node: Node<Svc>,
    names: Names,
    qos: Qos,
}

impl Ipc {
    /// Creates this process's node.
    pub fn new(names: Names, node_name: &str, qos: Qos) -> Result<Self, IpcError> {
        let node = NodeBuilder::new()
            .name(&NodeName::new(node_name).map_err(err("node name"))?)
            .create::<Svc>()
            .map_err(err("creating the node"))?;
        Ok(Ipc { node, names, qos })
    }

    /// False once the process was asked to terminate (SIGINT, SIGTERM).
    /// Reads the flag iceoryx2's signal handler sets (what `Node::wait`
    /// checks, without its `nanosleep`, a system call on every hop's path).
    pub fn keep_running(&self) -> bool {
        !iceoryx2_bb_posix::signal::SignalHandler::termination_requested()
    }

    fn frame_service(
        &self,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], FrameHeader>,
        IpcError,
    > {
        let h = self.qos.frame_history.max(1);
        self.node
            .service_builder(&self.names.name("frames")?)
            .publish_subscribe::<[u8]>()
            .user_header::<FrameHeader>()
            .enable_safe_overflow(true)
            .history_size(0)
            .subscriber_max_buffer_size(h)
            .subscriber_max_borrowed_samples(h + 1)
            .max_subscribers(FRAME_SUBSCRIBERS)
            .max_publishers(1)
            .open_or_create()
            .map_err(err("frame service"))
    }

    fn result_service(
        &self,
        stage: StageId,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], ResultMsg>,
        IpcError,
    > {
        self.node
            .service_builder(&self.names.name(stage.name())?)
            .publish_subscribe::<[u8]>()
            .user_header::<ResultMsg>()
            .enable_safe_overflow(true)
            .history_size(0)
            .subscriber_max_buffer_size(RESULT_BUFFER)
            .subscriber_max_borrowed_samples(2)
            .max_subscribers(RESULT_SUBSCRIBERS)
            .max_publishers(1)
            .open_or_create()
            .map_err(err("result service"))
    }

    fn event(
        &self,
        what: &str,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<Svc>, IpcError> {
        self.node
            .service_builder(&self.names.name(&format!("{what}/event"))?)
            .event()
            .max_listeners(8)
            .max_notifiers(8)
            .open_or_create()
            .map_err(err("event service"))
    }

    /// Stream `what`'s wake-up word ([`crate::wake`]), which the next
    /// stage sleeps on.
    fn wake_word(&self, what: &str) -> Result<WakeWord, IpcError> {
        WakeWord::open(&self.names.instance, what).map_err(|source| IpcError::Wake {
            path: crate::wake::path(&self.names.instance, what),
            source,
        })
    }

    /// The frame publisher (capture).
    pub fn frame_output(&self) -> Result<Output<FrameHeader>, IpcError> {
        let publisher = self
            .frame_service()?
            .publisher_builder()
            .initial_max_slice_len(self.qos.max_frame_bytes)
            .max_loaned_samples(1)
            .create()
            .map_err(err("frame publisher"))?;
        let notifier = self
            .event("frames")?
            .notifier_builder()
            .create()
            .map_err(err("frame notifier"))?;
        Ok(Output {
            publisher,
            wake: self.wake_word("frames")?,
            notifier,
        })
    }

    /// The first stage's frame subscriber: sleeps on the frames' wake-up
    /// word ([`Input::wait`]).
    pub fn frame_stage_input(&self) -> Result<Input<FrameHeader>, IpcError> {
        let mut input = self.frame_input(false)?;
        input.wake = Some(self.wake_word("frames")?);
        Ok(input)
    }

    /// A frame subscriber; `wake` = also listen for the frame event.
    pub fn frame_input(&self, wake: bool) -> Result<Input<FrameHeader>, IpcError> {
        let subscriber = self
            .frame_service()?
            .subscriber_builder()
            .create()
            .map_err(err("frame subscriber"))?;
        let listener = if wake {
            Some(
                self.event("frames")?
                    .listener_builder()
                    .create()
                    .map_err(err("frame listener"))?,
            )
        } else {
            None
        };
        Ok(Input {
            subscriber,
            listener,
            wake: None,
            seen: Cell::new(0),
        })
    }

    /// The result publisher of `stage`, payloads up to `max_payload` bytes.
    pub fn result_output(
        &self,
        stage: StageId,
        max_payload: usize,
    ) -> Result<Output<ResultMsg>, IpcError> {
        let publisher = self
            .result_service(stage)?
            .publisher_builder()
            .initial_max_slice_len(max_payload.max(1))
            .max_loaned_samples(1)
            .create()
            .map_err(err("result publisher"))?;
        let notifier = self
            .event(stage.name())?
            .notifier_builder()
            .create()
            .map_err(err("result notifier"))?;
        Ok(Output {
            publisher,
            wake: self.wake_word(stage.name())?,
            notifier,
        })
    }

    /// The next stage's subscriber to `stage`'s results: sleeps on the
    /// stream's wake-up word ([`Input::wait`]).
    pub fn result_stage_input(&self, stage: StageId) -> Result<Input<ResultMsg>, IpcError> {
        let subscriber = self
            .result_service(stage)?
            .subscriber_builder()
            .create()
            .map_err(err("result subscriber"))?;
        Ok(Input {
            subscriber,
            listener: None,
            wake: Some(self.wake_word(stage.name())?),
            seen: Cell::new(0),
        })
    }

    /// A subscriber to `stage`'s results that sleeps on its event.
    pub fn result_input(&self, stage: StageId) -> Result<Input<ResultMsg>, IpcError> {
        let subscriber = self
            .result_service(stage)?
            .subscriber_builder()
            .create()
            .map_err(err("result subscriber"))?;
        let listener = Some(
            self.event(stage.name())?
                .listener_builder()
                .create()
                .map_err(err("result listener"))?,
        );
        Ok(Input {
            subscriber,
            listener,
            wake: None,
            seen: Cell::new(0),
        })
    }

    /// Notifier of the control event `what` ("ready", "start").
    pub fn control_notifier(&self, what: &str) -> Result<Notifier<Svc>, IpcError> {
        self.event(what)?
            .notifier_builder()
            .create()
            .map_err(err("control notifier"))
    }

    /// Listener of the control event `what`.
    pub fn control_listener(&self, what: &str) -> Result<Listener<Svc>, IpcError> {
        self.event(what)?
            .listener_builder()
            .create()
            .map_err(err("control listener"))
    }
}

/// Publishes a header + `[u8]` payload and wakes the consumers: the next
/// stage first, on its wake-up word, then everyone else.
pub struct Output<H: Debug + ZeroCopySend + 'static> {
    publisher: Publisher<Svc, [u8], H>,
    wake: WakeWord,
    notifier: Notifier<Svc>,
}

impl<H: Debug + ZeroCopySend + Copy + Default + 'static> Output<H> {
    /// Loans `payload.len()` bytes of shared memory, copies `payload` in
    /// (the one write of these bytes), lets `fill` set the header (given the
    /// payload's address in this process), sends and notifies. Returns the
    /// number of subscribers reached.
    pub fn send(
        &self,
        payload: &[u8],
        fill: impl FnOnce(&mut H, usize),
    ) -> Result<usize, IpcError> {
        let mut sample = self
            .publisher
            .loan_slice_uninit(payload.len())
            .map_err(err("loan"))?;
        let dst = sample.payload_mut();
        let addr = dst.as_ptr() as usize;
        // SAFETY: dst has exactly payload.len() bytes; u8 has no invalid values.
        unsafe {
            std::ptr::copy_nonoverlapping(
                payload.as_ptr(),
                dst.as_mut_ptr().cast::<u8>(),
                payload.len(),
            )
        };
        // SAFETY: every byte was written above.
        let mut sample = unsafe { sample.assume_init() };
        fill(sample.user_header_mut(), addr);
        let n = sample.send().map_err(err("send"))?;
        self.wake
            .post()
            .map_err(|source| wake_error(&self.wake, source))?;
        self.notifier.notify().map_err(err("notify"))?;
        Ok(n)
    }

    /// Loans `len` bytes of shared memory and lets `write` produce the
    /// payload and the header right there (no staging buffer, no copy),
    /// then sends and notifies. Bytes `write` leaves alone keep what an
    /// earlier sample in the same slot held. Returns the number of
    /// subscribers reached.
    pub fn send_in_place(
        &self,
        len: usize,
        write: impl FnOnce(&mut [u8], &mut H),
    ) -> Result<usize, IpcError> {
        let mut sample = self.publisher.loan_slice_uninit(len).map_err(err("loan"))?;
        let dst = sample.payload_mut();
        // SAFETY: the slot lies in a shared-memory segment the kernel
        // zero-filled when it was mapped, so each of its bytes holds either
        // that zero or what an earlier sample wrote: all are initialised u8
        // (which has no invalid values); iceoryx2 types them MaybeUninit
        // only because its API is generic over payload types.
        let bytes = unsafe { std::slice::from_raw_parts_mut(dst.as_mut_ptr().cast::<u8>(), len) };
        let mut header = H::default();
        write(bytes, &mut header);
        // SAFETY: as above, every byte is initialised.
        let mut sample = unsafe { sample.assume_init() };
        *sample.user_header_mut() = header;
        let n = sample.send().map_err(err("send"))?;
        self.wake
            .post()
            .map_err(|source| wake_error(&self.wake, source))?;
        self.notifier.notify().map_err(err("notify"))?;
        Ok(n)
    }
}

/// Receives header + payload samples; sleeps on the stream's wake-up word
/// (a stage's input) or its event (everyone else) when it has one.
pub struct Input<H: Debug + ZeroCopySend + 'static> {
    subscriber: Subscriber<Svc, [u8], H>,
    listener: Option<Listener<Svc>>,
    /// A stage's input: its wake-up word.
    wake: Option<WakeWord>,
    /// The wake-up word as read just before the last look at the queue: a
    /// publish after that look has moved it, so the next wait returns at
    /// once instead of sleeping through it.
    seen: Cell<u32>,
}

impl<H: Debug + ZeroCopySend + 'static> Input<H> {
    /// Sleeps until the upstream publishes (the wake-up word moves on from
    /// what it read before the last [`receive`](Self::receive)), its event
    /// fires, a signal arrives or `timeout` passes (so the caller can check
    /// whether to stop). Drains the pending events.
    pub fn wait(&self, timeout: Duration) -> Result<(), IpcError> {
        if let Some(w) = &self.wake {
            return w
                .wait(self.seen.get(), timeout)
                .map_err(|source| wake_error(w, source));
        }
        if let Some(l) = &self.listener {
            match l.timed_wait(|_| {}, timeout) {
                // A termination request: the caller sees it in `keep_running`.
                Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => {}
                Err(e) => return Err(err("wait")(e)),
            }
        }
        Ok(())
    }

    /// The next queued sample, if any.
    pub fn receive(&self) -> Result<Option<Sample<Svc, [u8], H>>, IpcError> {
        if let Some(w) = &self.wake {
            // Read before looking: see `seen`.
            self.seen.set(w.current());
        }
        self.subscriber.receive().map_err(err("receive"))
    }
}

/// The last frames received, so a stage can read the pixels of frame N when
/// its upstream result for N arrives. Holds the samples themselves (shared
/// memory, no copy); the oldest is released when a newer one comes in.
pub struct FrameHistory {
    frames: VecDeque<FrameSample>,
    capacity: usize,
    /// Frames released without having been looked up.
    pub dropped: u64,
}

impl FrameHistory {
    /// Up to `capacity` frames (the frame service's borrow limit is one more).
    pub fn new(capacity: usize) -> Self {
        FrameHistory {
            frames: VecDeque::with_capacity(capacity.max(1)),
            capacity: capacity.max(1),
            dropped: 0,
        }
    }

    /// Moves every queued frame of `input` into the history.
    pub fn pull(&mut self, input: &Input<FrameHeader>) -> Result<(), IpcError> {
        while let Some(s) = input.receive()? {
            if self.frames.len() == self.capacity {
                self.frames.pop_front();
                self.dropped += 1;
            }
            self.frames.push_back(s);
        }
        Ok(())
    }

    /// Frame `sequence`, pulling newly arrived frames first; releases older frames.
    pub fn get(
        &mut self,
        input: &Input<FrameHeader>,
        sequence: u64,
    ) -> Result<Option<&FrameSample>, IpcError> {
        self.pull(input)?;
        while self
            .frames
            .front()
            .is_some_and(|f| f.user_header().sequence < sequence)
        {
            self.frames.pop_front();
        }
        Ok(self
            .frames
            .front()
            .filter(|f| f.user_header().sequence == sequence))
    }
}
