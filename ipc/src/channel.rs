//! iceoryx2 streams of one pipeline run: a `[u8]` payload with a
//! `#[repr(C)]` user header `H` (a typed view the pipeline defines beside
//! the stage that writes it), a wake-up word so the next stage sleeps until
//! its input arrives, and an event for every other listener.

use crate::error::{NodeError, OpenError, ReceiveError, SendError, WaitError};
use crate::wake::WakeWord;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use std::cell::Cell;
use std::fmt::Debug;
use std::time::Duration;

/// The iceoryx2 service flavour (inter-process, ports stay on one thread).
pub type Svc = ipc::Service;

/// What a stream's user header must be: plain data that lives in shared
/// memory as it is.
pub trait Header: Debug + ZeroCopySend + Copy + Default + 'static {}
impl<T: Debug + ZeroCopySend + Copy + Default + 'static> Header for T {}

/// A received sample: header + payload, borrowed from shared memory.
pub type Received<H> = Sample<Svc, [u8], H>;

/// A publish-subscribe service of `[u8]` payloads with header `H`.
type PubSub<H> = iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, [u8], H>;

/// The shape of one stream's service. Shared memory is sized from it up
/// front, and every process of a run must open a stream with the same
/// shape (iceoryx2 refuses another).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamSpec {
    /// The stream's name inside the run ("frames", "recognition", ...).
    pub name: &'static str,
    /// Subscribers it admits.
    pub subscribers: usize,
    /// Samples queued per subscriber; when full, the oldest is dropped.
    pub buffer: usize,
    /// Samples one subscriber may hold at once.
    pub borrowed: usize,
}

/// How an [`Input`] sleeps until its stream publishes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wake {
    /// On the stream's wake-up word: the next stage, whose wake-up is on
    /// the critical path ([`crate::wake`]).
    Word,
    /// On the stream's iceoryx2 event: the launcher and the observers.
    Event,
    /// Not at all: the caller polls (it sleeps on another input).
    Never,
}

/// One process's handle on iceoryx2 for the streams of run `instance`.
pub struct Ipc {
    node: Node<Svc>,
    instance: String,
}

impl Ipc {
    /// Creates this process's node for run `instance` (the launcher's pid:
    /// it keeps concurrent runs apart).
    pub fn new(instance: &str, node_name: &str) -> Result<Self, NodeError> {
        let name = NodeName::new(node_name).map_err(|_| NodeError::Name(node_name.to_owned()))?;
        let node = NodeBuilder::new()
            .name(&name)
            .create::<Svc>()
            .map_err(|source| NodeError::Create {
                node: node_name.to_owned(),
                source,
            })?;
        Ok(Ipc {
            node,
            instance: instance.to_owned(),
        })
    }

    /// The run this node belongs to.
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// False once the process was asked to terminate (SIGINT, SIGTERM).
    /// Reads the flag iceoryx2's signal handler sets (what `Node::wait`
    /// checks, without its `nanosleep`, a system call on every hop's path).
    pub fn keep_running(&self) -> bool {
        !iceoryx2_bb_posix::signal::SignalHandler::termination_requested()
    }

    fn service_name(&self, what: &str) -> Result<(String, ServiceName), OpenError> {
        let name = format!("acch/{}/{what}", self.instance);
        let service = ServiceName::new(&name).map_err(|source| OpenError::Name {
            name: name.clone(),
            source,
        })?;
        Ok((name, service))
    }

    fn service<H: Header>(&self, spec: StreamSpec) -> Result<(String, PubSub<H>), OpenError> {
        let (name, service) = self.service_name(spec.name)?;
        let factory = self
            .node
            .service_builder(&service)
            .publish_subscribe::<[u8]>()
            .user_header::<H>()
            .enable_safe_overflow(true)
            .history_size(0)
            .subscriber_max_buffer_size(spec.buffer.max(1))
            .subscriber_max_borrowed_samples(spec.borrowed.max(1))
            .max_subscribers(spec.subscribers.max(1))
            .max_publishers(1)
            .open_or_create()
            .map_err(|source| OpenError::Service {
                service: name.clone(),
                source,
            })?;
        Ok((name, factory))
    }

    fn event(
        &self,
        what: &str,
    ) -> Result<
        (
            String,
            iceoryx2::service::port_factory::event::PortFactory<Svc>,
        ),
        OpenError,
    > {
        let (name, service) = self.service_name(&format!("{what}/event"))?;
        let factory = self
            .node
            .service_builder(&service)
            .event()
            .max_listeners(8)
            .max_notifiers(8)
            .open_or_create()
            .map_err(|source| OpenError::Event {
                service: name.clone(),
                source,
            })?;
        Ok((name, factory))
    }

    fn wake_word(&self, what: &str) -> Result<WakeWord, OpenError> {
        WakeWord::open(&self.instance, what).map_err(|source| OpenError::Wake {
            path: crate::wake::path(&self.instance, what),
            source,
        })
    }

    /// The publisher of stream `spec`, payloads up to `max_payload` bytes.
    pub fn output<H: Header>(
        &self,
        spec: StreamSpec,
        max_payload: usize,
    ) -> Result<Output<H>, OpenError> {
        let (service, factory) = self.service::<H>(spec)?;
        let publisher = factory
            .publisher_builder()
            .initial_max_slice_len(max_payload.max(1))
            .max_loaned_samples(1)
            .create()
            .map_err(|source| OpenError::Publisher {
                service: service.clone(),
                source,
            })?;
        Ok(Output {
            publisher,
            wake: self.wake_word(spec.name)?,
            notifier: self.notifier(spec.name, &service)?,
            service,
        })
    }

    /// A subscriber of stream `spec` that sleeps as `wake` says.
    pub fn input<H: Header>(&self, spec: StreamSpec, wake: Wake) -> Result<Input<H>, OpenError> {
        let (service, factory) = self.service::<H>(spec)?;
        let subscriber =
            factory
                .subscriber_builder()
                .create()
                .map_err(|source| OpenError::Subscriber {
                    service: service.clone(),
                    source,
                })?;
        let (word, listener) = match wake {
            Wake::Word => (Some(self.wake_word(spec.name)?), None),
            Wake::Event => (None, Some(self.listener(spec.name, &service)?)),
            Wake::Never => (None, None),
        };
        Ok(Input {
            subscriber,
            listener,
            wake: word,
            seen: Cell::new(0),
            service,
        })
    }

    fn notifier(&self, what: &str, service: &str) -> Result<Notifier<Svc>, OpenError> {
        let (_, event) = self.event(what)?;
        event
            .notifier_builder()
            .create()
            .map_err(|source| OpenError::Notifier {
                service: service.to_owned(),
                source,
            })
    }

    fn listener(&self, what: &str, service: &str) -> Result<Listener<Svc>, OpenError> {
        let (_, event) = self.event(what)?;
        event
            .listener_builder()
            .create()
            .map_err(|source| OpenError::Listener {
                service: service.to_owned(),
                source,
            })
    }

    /// Notifier of the control event `what` ("ready", "start").
    pub fn control_notifier(&self, what: &str) -> Result<Control, OpenError> {
        let (service, _) = self.event(what)?;
        Ok(Control {
            notifier: self.notifier(what, &service)?,
            service,
        })
    }

    /// Listener of the control event `what`.
    pub fn control_listener(&self, what: &str) -> Result<ControlListener, OpenError> {
        let (service, _) = self.event(what)?;
        Ok(ControlListener {
            listener: self.listener(what, &service)?,
            service,
        })
    }
}

/// Publishes a header + `[u8]` payload and wakes the consumers: the next
/// stage first, on its wake-up word, then everyone else.
pub struct Output<H: Header> {
    publisher: Publisher<Svc, [u8], H>,
    wake: WakeWord,
    notifier: Notifier<Svc>,
    service: String,
}

impl<H: Header> Output<H> {
    /// Loans `payload.len()` bytes of shared memory, copies `payload` in
    /// (the one write of these bytes), lets `fill` set the header (given the
    /// payload's address in this process), sends and notifies. Returns the
    /// number of subscribers reached.
    pub fn send(
        &self,
        payload: &[u8],
        fill: impl FnOnce(&mut H, usize),
    ) -> Result<usize, SendError> {
        let mut sample = self.loan(payload.len())?;
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
        self.deliver(sample)
    }

    /// Loans `len` bytes of shared memory and lets `write` produce the
    /// payload and the header right there (no staging buffer, no copy),
    /// then sends and notifies. Bytes `write` leaves alone keep what an
    /// earlier sample in the same slot held. Returns the number of
    /// subscribers reached, or `write`'s error (nothing is sent then).
    pub fn send_in_place<E>(
        &self,
        len: usize,
        write: impl FnOnce(&mut [u8], &mut H) -> Result<(), E>,
    ) -> Result<Result<usize, E>, SendError> {
        let mut sample = self.loan(len)?;
        let dst = sample.payload_mut();
        // SAFETY: the slot lies in a shared-memory segment the kernel
        // zero-filled when it was mapped, so each of its bytes holds either
        // that zero or what an earlier sample wrote: all are initialised u8
        // (which has no invalid values); iceoryx2 types them MaybeUninit
        // only because its API is generic over payload types.
        let bytes = unsafe { std::slice::from_raw_parts_mut(dst.as_mut_ptr().cast::<u8>(), len) };
        let mut header = H::default();
        if let Err(e) = write(bytes, &mut header) {
            return Ok(Err(e));
        }
        // SAFETY: as above, every byte is initialised.
        let mut sample = unsafe { sample.assume_init() };
        *sample.user_header_mut() = header;
        self.deliver(sample).map(Ok)
    }

    fn loan(
        &self,
        len: usize,
    ) -> Result<
        iceoryx2::sample_mut_uninit::SampleMutUninit<Svc, [std::mem::MaybeUninit<u8>], H>,
        SendError,
    > {
        self.publisher
            .loan_slice_uninit(len)
            .map_err(|source| SendError::Loan {
                service: self.service.clone(),
                len,
                source,
            })
    }

    fn deliver(
        &self,
        sample: iceoryx2::sample_mut::SampleMut<Svc, [u8], H>,
    ) -> Result<usize, SendError> {
        let n = sample.send().map_err(|source| SendError::Send {
            service: self.service.clone(),
            source,
        })?;
        self.wake.post().map_err(|source| SendError::Wake {
            path: self.wake.path().to_owned(),
            source,
        })?;
        self.notifier.notify().map_err(|source| SendError::Notify {
            service: self.service.clone(),
            source,
        })?;
        Ok(n)
    }
}

/// Receives header + payload samples of one stream; sleeps on its wake-up
/// word (a stage's input) or its event (everyone else).
pub struct Input<H: Header> {
    subscriber: Subscriber<Svc, [u8], H>,
    listener: Option<Listener<Svc>>,
    /// A stage's input: its wake-up word.
    wake: Option<WakeWord>,
    /// The wake-up word as read just before the last look at the queue: a
    /// publish after that look has moved it, so the next wait returns at
    /// once instead of sleeping through it.
    seen: Cell<u32>,
    service: String,
}

impl<H: Header> Input<H> {
    /// Sleeps until the upstream publishes (the wake-up word moves on from
    /// what it read before the last [`receive`](Self::receive)), its event
    /// fires, a signal arrives or `timeout` passes (so the caller can check
    /// whether to stop). Drains the pending events. Returns at once for a
    /// [`Wake::Never`] input.
    pub fn wait(&self, timeout: Duration) -> Result<(), WaitError> {
        if let Some(w) = &self.wake {
            return w
                .wait(self.seen.get(), timeout)
                .map_err(|source| WaitError::Wake {
                    path: w.path().to_owned(),
                    source,
                });
        }
        if let Some(l) = &self.listener {
            match l.timed_wait(|_| {}, timeout) {
                // A termination request: the caller sees it in `keep_running`.
                Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => {}
                Err(source) => {
                    return Err(WaitError::Listener {
                        service: self.service.clone(),
                        source,
                    });
                }
            }
        }
        Ok(())
    }

    /// The next queued sample, if any.
    pub fn receive(&self) -> Result<Option<Received<H>>, ReceiveError> {
        if let Some(w) = &self.wake {
            // Read before looking: see `seen`.
            self.seen.set(w.current());
        }
        self.subscriber.receive().map_err(|source| ReceiveError {
            service: self.service.clone(),
            source,
        })
    }
}

/// A control event's notifier ("ready", "start").
pub struct Control {
    notifier: Notifier<Svc>,
    service: String,
}

impl Control {
    /// Fires the event with id `id` (a stage's readiness names the stage).
    pub fn notify(&self, id: usize) -> Result<(), SendError> {
        self.notifier
            .notify_with_custom_event_id(EventId::new(id))
            .map(|_| ())
            .map_err(|source| SendError::Notify {
                service: self.service.clone(),
                source,
            })
    }
}

/// A control event's listener.
pub struct ControlListener {
    listener: Listener<Svc>,
    service: String,
}

impl ControlListener {
    /// Calls `f` with the id of every event fired until now, waiting up to
    /// `timeout` for the first (`Duration::ZERO`: not at all). A signal
    /// ends the wait early (the caller sees it in [`Ipc::keep_running`]).
    pub fn take(&self, timeout: Duration, mut f: impl FnMut(usize)) -> Result<(), WaitError> {
        let r = if timeout.is_zero() {
            self.listener.try_wait(|e| f(e.id.as_value()))
        } else {
            self.listener.timed_wait(|e| f(e.id.as_value()), timeout)
        };
        match r {
            Ok(_) | Err(iceoryx2::port::listener::ListenerWaitError::InterruptSignal) => Ok(()),
            Err(source) => Err(WaitError::Listener {
                service: self.service.clone(),
                source,
            }),
        }
    }
}
