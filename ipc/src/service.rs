//! The iceoryx2 flavour of the stages' wake-ups: `ipc::Service` with its
//! events on POSIX semaphores in shared memory (futexes) instead of Unix
//! datagram sockets.
//!
//! Every hop ends in a wake-up. On the 2-vCPU machine the socket's notify
//! took 8-9 µs of the publisher's time, and a hop between two processes on
//! one CPU 17.7 µs p50 / 37 µs p99 (6.9 / 17.4 µs under SCHED_FIFO); with
//! a semaphore it was 5.2 / 16.3 µs (4.1 / 8.5 µs), measured with
//! `cargo run --release -p acch-ipc --example hop_floor`. The data
//! services and the events that the launcher and the observers wait on
//! stay on `ipc::Service`: this flavour's *timed* wait polls (iceoryx2
//! waits on a monotonic-clock semaphore by yielding, then sleeping), so it
//! is used only for the stages' inputs, which wait without a timeout
//! ([`Input::wait_blocking`](crate::Input::wait_blocking)). Everything but
//! the event concept is `ipc::Service`'s recommended choice.

use core::fmt::Debug;
use iceoryx2::service::Service as ServiceTrait;
use iceoryx2::service::internal::ServiceInternal;
use iceoryx2_bb_elementary_traits::testing::abandonable::Abandonable;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use iceoryx2_cal::shm_allocator::bump_allocator::BumpAllocator;
use iceoryx2_cal::shm_allocator::pool_allocator::PoolAllocator;
use iceoryx2_cal::*;

/// Inter-process service whose events are shared-memory semaphores; ports
/// stay on the thread that made them, as with `ipc::Service`.
#[derive(Debug, Clone)]
pub struct FutexService {}

impl ServiceTrait for FutexService {
    type StaticStorage = static_storage::recommended::Ipc;
    type ConfigSerializer = serialize::recommended::Recommended;
    type PersistentDynamicStorage<T: Debug + Send + Sync + ZeroCopySend + 'static> =
        dynamic_storage::recommended::PersistentIpc<T>;
    type Bag = bag::recommended::Recommended;
    type DynamicStorage<T: Debug + Send + Sync + ZeroCopySend + 'static> =
        dynamic_storage::recommended::Ipc<T>;
    type ServiceNameHasher = hash::recommended::Recommended;
    type SharedMemory = shared_memory::recommended::Ipc<PoolAllocator>;
    type ResizableSharedMemory = resizable_shared_memory::recommended::Ipc<PoolAllocator>;
    type Connection = zero_copy_connection::recommended::Ipc;
    type Event = event::SemaphoreShmCountingBitSet;
    type Monitoring = monitoring::recommended::Ipc;
    type Reactor = reactor::recommended::Ipc;
    type ArcThreadSafetyPolicy<T: Send + Debug + Abandonable> =
        arc_sync_policy::single_threaded::SingleThreaded<T>;
    type BlackboardMgmt<KeyType: Send + Sync + Debug + ZeroCopySend + 'static> =
        dynamic_storage::recommended::Ipc<KeyType>;
    type BlackboardPayload = shared_memory::recommended::Ipc<BumpAllocator>;
    type UniqueId = iceoryx2::unique_id_generator::unique_system_id::UniqueSystemId;
}

impl ServiceInternal<FutexService> for FutexService {}
