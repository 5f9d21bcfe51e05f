//! Errors of the IPC layer: one enum per operation (opening, sending,
//! receiving, waiting), each keeping the typed error of iceoryx2, zenoh or
//! the system and naming the stream or file it concerns.

use std::path::PathBuf;

use iceoryx2::node::NodeCreationFailure;
use iceoryx2::port::listener::{ListenerCreateError, ListenerWaitError};
use iceoryx2::port::notifier::{NotifierCreateError, NotifierNotifyError};
use iceoryx2::port::publisher::PublisherCreateError;
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::service::builder::event::EventOpenOrCreateError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError;
use iceoryx2::service::service_name::ServiceNameError;

/// Creating this process's iceoryx2 node failed.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The node name is not a valid iceoryx2 name.
    #[error("'{0}' is not a valid iceoryx2 node name")]
    Name(String),
    /// iceoryx2 refused to create the node.
    #[error("creating the iceoryx2 node '{node}'")]
    Create {
        /// The node's name.
        node: String,
        /// What iceoryx2 said.
        #[source]
        source: NodeCreationFailure,
    },
}

/// Opening a stream's service or one of its ports failed.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The stream's name makes no valid service name.
    #[error("'{name}' is not a valid service name")]
    Name {
        /// The service name tried.
        name: String,
        /// What iceoryx2 said.
        #[source]
        source: ServiceNameError,
    },
    /// The publish-subscribe service could not be opened or created (for
    /// example: another run's service of the same name with other sizes).
    #[error("service {service}")]
    Service {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: PublishSubscribeOpenOrCreateError,
    },
    /// The event service could not be opened or created.
    #[error("event service {service}")]
    Event {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: EventOpenOrCreateError,
    },
    /// No publisher port.
    #[error("publisher of {service}")]
    Publisher {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: PublisherCreateError,
    },
    /// No subscriber port (for example: the service admits no more).
    #[error("subscriber of {service}")]
    Subscriber {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: SubscriberCreateError,
    },
    /// No notifier port.
    #[error("notifier of {service}")]
    Notifier {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: NotifierCreateError,
    },
    /// No listener port.
    #[error("listener of {service}")]
    Listener {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: ListenerCreateError,
    },
    /// The stream's wake-up word could not be mapped.
    #[error("wake-up word {}", path.display())]
    Wake {
        /// Its file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
}

/// Publishing a sample failed.
#[derive(Debug, thiserror::Error)]
pub enum SendError {
    /// No shared memory to loan (the payload is larger than the service
    /// was sized for, or every slot is in use).
    #[error("loaning {len} bytes on {service}")]
    Loan {
        /// The service.
        service: String,
        /// Bytes asked for.
        len: usize,
        /// What iceoryx2 said.
        #[source]
        source: iceoryx2::port::LoanError,
    },
    /// The sample could not be delivered.
    #[error("sending on {service}")]
    Send {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: iceoryx2::port::SendError,
    },
    /// The next stage's wake-up word could not be posted.
    #[error("posting the wake-up word {}", path.display())]
    Wake {
        /// Its file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// The observers' event could not be notified.
    #[error("notifying the listeners of {service}")]
    Notify {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: NotifierNotifyError,
    },
}

/// Taking a sample off a subscriber's queue failed.
#[derive(Debug, thiserror::Error)]
#[error("receiving from {service}")]
pub struct ReceiveError {
    /// The service.
    pub service: String,
    /// What iceoryx2 said.
    #[source]
    pub source: iceoryx2::port::ReceiveError,
}

/// Sleeping until a sample arrives failed.
#[derive(Debug, thiserror::Error)]
pub enum WaitError {
    /// Waiting on the wake-up word failed.
    #[error("waiting on the wake-up word {}", path.display())]
    Wake {
        /// Its file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// Waiting on the event failed.
    #[error("waiting for an event of {service}")]
    Listener {
        /// The service.
        service: String,
        /// What iceoryx2 said.
        #[source]
        source: ListenerWaitError,
    },
}

/// A zenoh call failed.
#[derive(Debug, thiserror::Error)]
#[error("zenoh: {what}")]
pub struct ZenohError {
    /// What was being done ("opening the session", "publishing on KEY").
    pub what: String,
    /// What zenoh said.
    #[source]
    pub source: zenoh::Error,
}

/// Any error of the IPC layer.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// See [`NodeError`].
    #[error(transparent)]
    Node(#[from] NodeError),
    /// See [`OpenError`].
    #[error(transparent)]
    Open(#[from] OpenError),
    /// See [`SendError`].
    #[error(transparent)]
    Send(#[from] SendError),
    /// See [`ReceiveError`].
    #[error(transparent)]
    Receive(#[from] ReceiveError),
    /// See [`WaitError`].
    #[error(transparent)]
    Wait(#[from] WaitError),
    /// See [`ZenohError`].
    #[error(transparent)]
    Zenoh(#[from] ZenohError),
}
