//! A zenoh session dressed as a ROS 2 node: its liveliness tokens put it in
//! the ROS graph (`ros2 node list`, `ros2 topic list`), and its publishers
//! and subscribers use rmw_zenoh's key expressions and attachment.

use crate::graph::{
    self, Attachment, AttachmentFormat, DEFAULT_ENCLAVE, Distro, NodeInfo, Qos, TopicInfo,
};
use crate::msg::{self, CdrError, EncodesAs, Message};
use crate::names::{self, NameError};
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU32, Ordering};
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::qos::CongestionControl;

/// rmw_zenoh numbers nodes and their entities from one counter per context
/// (per process), starting at 0. One counter for the process keeps every
/// (node id, entity id) pair unique, however many sessions and nodes exist.
static NEXT_ID: AtomicU32 = AtomicU32::new(0);

fn next_id() -> u32 {
    NEXT_ID.fetch_add(1, Ordering::Relaxed)
}

/// Nanoseconds since the UNIX epoch from the system clock, what rmw_zenoh
/// puts in the attachment's source timestamp.
pub fn now_ns() -> i64 {
    match std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        Ok(d) => i64::try_from(d.as_nanos()).unwrap_or(i64::MAX),
        Err(_) => 0,
    }
}

/// Declaring a zenoh entity or liveliness token failed.
#[derive(Debug, thiserror::Error)]
pub enum DeclareError {
    /// The liveliness token (the entity's place in the ROS graph).
    #[error("declaring the liveliness token {key}")]
    Token {
        /// The token's key expression.
        key: String,
        /// What zenoh said.
        #[source]
        source: zenoh::Error,
    },
    /// The zenoh publisher on the data key.
    #[error("declaring a zenoh publisher on {key}")]
    Publisher {
        /// The data key expression.
        key: String,
        /// What zenoh said.
        #[source]
        source: zenoh::Error,
    },
    /// The zenoh subscriber on the data key.
    #[error("declaring a zenoh subscriber on {key}")]
    Subscriber {
        /// The data key expression.
        key: String,
        /// What zenoh said.
        #[source]
        source: zenoh::Error,
    },
    /// KEEP_LAST with depth 0 is meaningless (rclcpp refuses it too).
    #[error("topic {topic}: the KEEP_LAST history depth must be at least 1")]
    ZeroDepth {
        /// The topic.
        topic: String,
    },
}

/// Publishing one sample failed; the publisher stays usable.
#[derive(Debug, thiserror::Error)]
pub enum PublishError {
    /// The message could not be encoded.
    #[error("encoding a sample for {topic}")]
    Encode {
        /// The topic.
        topic: String,
        /// Why.
        #[source]
        source: CdrError,
    },
    /// zenoh refused the put.
    #[error("putting a sample on {key}")]
    Put {
        /// The data key expression.
        key: String,
        /// What zenoh said.
        #[source]
        source: zenoh::Error,
    },
}

/// Any error of a [`Node`] or its entities.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// A node, namespace or topic name breaks the ROS rules.
    #[error(transparent)]
    Name(#[from] NameError),
    /// Declaring something on the session failed.
    #[error(transparent)]
    Declare(#[from] DeclareError),
    /// Publishing failed.
    #[error(transparent)]
    Publish(#[from] PublishError),
}

/// Who the node is and which rmw_zenoh it talks to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// `ROS_DOMAIN_ID` of the peers (the first chunk of every key).
    pub domain_id: u32,
    /// Node namespace, `/` or `/a/b`; relative topics go under it.
    pub namespace: String,
    /// Node name as `ros2 node list` shows it.
    pub name: String,
    /// Decides the type-hash chunk (Humble has none).
    pub distro: Distro,
    /// Must match the receivers' rmw_zenoh version, or they drop every sample.
    pub attachment: AttachmentFormat,
}

impl Default for NodeConfig {
    fn default() -> Self {
        NodeConfig {
            domain_id: 0,
            namespace: "/".into(),
            name: "acch".into(),
            distro: Distro::Jazzy,
            attachment: AttachmentFormat::Current,
        }
    }
}

/// A ROS 2 node on a zenoh session. Dropping it undeclares its token (the
/// node leaves the graph); its publishers and subscribers keep their own.
pub struct Node {
    session: zenoh::Session,
    config: NodeConfig,
    zid: String,
    id: u32,
    token_key: String,
    _token: LivelinessToken,
}

impl std::fmt::Debug for Node {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Node")
            .field("token", &self.token_key)
            .finish_non_exhaustive()
    }
}

impl Node {
    /// Validates the names and declares the node's `NN` liveliness token.
    pub fn new(session: &zenoh::Session, config: NodeConfig) -> Result<Node, Ros2Error> {
        names::validate_namespace(&config.namespace)?;
        names::validate_node_name(&config.name)?;
        let zid = session.zid().to_string();
        let id = next_id();
        let token_key = graph::node_token(&NodeInfo {
            domain_id: config.domain_id,
            zid: &zid,
            node_id: id,
            enclave: DEFAULT_ENCLAVE,
            namespace: &config.namespace,
            name: &config.name,
        });
        let token = declare_token(session, &token_key)?;
        Ok(Node {
            session: session.clone(),
            config,
            zid,
            id,
            token_key,
            _token: token,
        })
    }

    /// The configuration it was made with.
    pub fn config(&self) -> &NodeConfig {
        &self.config
    }

    /// The node id in its tokens.
    pub fn id(&self) -> u32 {
        self.id
    }

    /// Its `NN` liveliness token.
    pub fn token(&self) -> &str {
        &self.token_key
    }

    fn info(&self) -> NodeInfo<'_> {
        NodeInfo {
            domain_id: self.config.domain_id,
            zid: &self.zid,
            node_id: self.id,
            enclave: DEFAULT_ENCLAVE,
            namespace: &self.config.namespace,
            name: &self.config.name,
        }
    }

    /// Resolves `topic` and builds what both entity kinds need.
    fn endpoint<M: Message>(&self, topic: &str, qos: Qos) -> Result<Endpoint, Ros2Error> {
        let topic = names::resolve_topic(&self.config.namespace, topic)?;
        if qos.history_depth == 0 {
            return Err(DeclareError::ZeroDepth { topic }.into());
        }
        let dds_type = M::dds_type();
        let type_hash = self.config.distro.type_hash::<M>();
        let key = graph::data_key(self.config.domain_id, &topic, &dds_type, type_hash);
        Ok(Endpoint {
            topic,
            dds_type,
            type_hash,
            key,
            qos,
            entity_id: next_id(),
        })
    }

    /// Declares a publisher of `M` on `topic` (relative names go under the
    /// node's namespace) and its `MP` token.
    ///
    /// The zenoh publisher uses congestion control Drop, as rmw_zenoh does
    /// for KEEP_LAST: a slow subscriber cannot stall the pipeline. zenoh's
    /// own reliability flag stays at its default (reliable) whatever `qos`
    /// says, because setting it needs zenoh's unstable API.
    pub fn publisher<M: Message>(&self, topic: &str, qos: Qos) -> Result<Publisher<M>, Ros2Error> {
        let ep = self.endpoint::<M>(topic, qos)?;
        let publisher = self
            .session
            .declare_publisher(ep.key.clone())
            .congestion_control(CongestionControl::Drop)
            .wait()
            .map_err(|source| DeclareError::Publisher {
                key: ep.key.clone(),
                source,
            })?;
        let token_key = graph::publisher_token(&self.info(), ep.entity_id, &ep.topic_info());
        let token = declare_token(&self.session, &token_key)?;
        Ok(Publisher {
            publisher,
            gid: graph::gid(&token_key),
            _token: token,
            token_key,
            topic: ep.topic,
            key: ep.key,
            entity_id: ep.entity_id,
            sequence: 1,
            format: self.config.attachment,
            payload: Vec::new(),
            attachment: Vec::with_capacity(Attachment::LEGACY_LEN),
            _type: PhantomData,
        })
    }

    /// Declares a subscriber of `M` on `topic` and its `MS` token. Every
    /// sample is decoded and handed to `callback` on a zenoh thread, with
    /// its attachment if it has a readable one (plain zenoh publishers send
    /// none). A sample that does not decode is logged and dropped.
    pub fn subscriber<M, F>(
        &self,
        topic: &str,
        qos: Qos,
        callback: F,
    ) -> Result<Subscriber<M>, Ros2Error>
    where
        M: Message + 'static,
        F: Fn(M, Option<Attachment>) + Send + Sync + 'static,
    {
        let ep = self.endpoint::<M>(topic, qos)?;
        let topic_name = ep.topic.clone();
        let subscriber = self
            .session
            .declare_subscriber(ep.key.clone())
            .callback(move |sample| {
                let payload = sample.payload().to_bytes();
                let msg = match msg::decode::<M>(&payload) {
                    Ok(msg) => msg,
                    Err(e) => {
                        tracing::warn!(topic = %topic_name, error = %e, "dropping a sample that does not decode");
                        return;
                    }
                };
                let attachment = sample.attachment().and_then(|a| {
                    Attachment::decode(&a.to_bytes())
                        .inspect_err(|e| {
                            tracing::debug!(topic = %topic_name, error = %e, "unreadable attachment");
                        })
                        .ok()
                });
                callback(msg, attachment);
            })
            .wait()
            .map_err(|source| DeclareError::Subscriber {
                key: ep.key.clone(),
                source,
            })?;
        let token_key = graph::subscriber_token(&self.info(), ep.entity_id, &ep.topic_info());
        let token = declare_token(&self.session, &token_key)?;
        Ok(Subscriber {
            _subscriber: subscriber,
            _token: token,
            token_key,
            topic: ep.topic,
            key: ep.key,
            entity_id: ep.entity_id,
            _type: PhantomData,
        })
    }
}

struct Endpoint {
    topic: String,
    dds_type: String,
    type_hash: &'static str,
    key: String,
    qos: Qos,
    entity_id: u32,
}

impl Endpoint {
    fn topic_info(&self) -> TopicInfo<'_> {
        TopicInfo {
            topic: &self.topic,
            dds_type: &self.dds_type,
            type_hash: self.type_hash,
            qos: self.qos,
        }
    }
}

fn declare_token(session: &zenoh::Session, key: &str) -> Result<LivelinessToken, DeclareError> {
    session
        .liveliness()
        .declare_token(key.to_owned())
        .wait()
        .map_err(|source| DeclareError::Token {
            key: key.to_owned(),
            source,
        })
}

/// Publishes `M` the way an rmw_zenoh publisher does. Dropping it
/// undeclares the publisher and its token.
pub struct Publisher<M: Message> {
    publisher: zenoh::pubsub::Publisher<'static>,
    _token: LivelinessToken,
    token_key: String,
    topic: String,
    key: String,
    entity_id: u32,
    gid: [u8; 16],
    sequence: i64,
    format: AttachmentFormat,
    payload: Vec<u8>,
    attachment: Vec<u8>,
    _type: PhantomData<fn(&M)>,
}

impl<M: Message> std::fmt::Debug for Publisher<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher")
            .field("key", &self.key)
            .field("sequence", &self.sequence)
            .finish_non_exhaustive()
    }
}

impl<M: Message> Publisher<M> {
    /// Encodes `msg` and puts it with the attachment (sequence number,
    /// `source_timestamp_ns`, GID). The encode and attachment buffers are
    /// reused, so after the first call this allocates nothing itself;
    /// zenoh copies the bytes into its own buffers.
    pub fn publish(&mut self, msg: &M, source_timestamp_ns: i64) -> Result<(), Ros2Error> {
        self.publish_as(msg, source_timestamp_ns)
    }

    /// [`publish`](Self::publish) for a value that encodes as an `M`, e.g.
    /// an [`ImageRef`](crate::msg::ImageRef) borrowing the camera buffer.
    pub fn publish_as<B: EncodesAs<M> + ?Sized>(
        &mut self,
        msg: &B,
        source_timestamp_ns: i64,
    ) -> Result<(), Ros2Error> {
        msg::encode_as::<M, B>(msg, &mut self.payload).map_err(|source| PublishError::Encode {
            topic: self.topic.clone(),
            source,
        })?;
        Attachment {
            sequence: self.sequence,
            source_timestamp_ns,
            gid: self.gid,
        }
        .encode(self.format, &mut self.attachment);
        // Counted even if the put fails: receivers then see the gap.
        self.sequence += 1;
        self.publisher
            .put(self.payload.as_slice())
            .attachment(self.attachment.as_slice())
            .wait()
            .map_err(|source| {
                PublishError::Put {
                    key: self.key.clone(),
                    source,
                }
                .into()
            })
    }

    /// The fully qualified topic name.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// The data key expression.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Its `MP` liveliness token.
    pub fn token(&self) -> &str {
        &self.token_key
    }

    /// The entity id in its token.
    pub fn entity_id(&self) -> u32 {
        self.entity_id
    }

    /// The GID sent in every attachment.
    pub fn gid(&self) -> [u8; 16] {
        self.gid
    }

    /// The sequence number the next sample will carry.
    pub fn next_sequence(&self) -> i64 {
        self.sequence
    }

    /// The CDR payload of the last sample published (empty before the
    /// first), e.g. to record exactly what went on the wire with
    /// [`BagWriter::write`](crate::BagWriter::write) without encoding twice.
    pub fn last_payload(&self) -> &[u8] {
        &self.payload
    }
}

/// Receives `M` the way an rmw_zenoh subscription does. Dropping it
/// undeclares the subscriber and its token.
pub struct Subscriber<M: Message> {
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _token: LivelinessToken,
    token_key: String,
    topic: String,
    key: String,
    entity_id: u32,
    _type: PhantomData<fn(M)>,
}

impl<M: Message> std::fmt::Debug for Subscriber<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscriber")
            .field("key", &self.key)
            .finish_non_exhaustive()
    }
}

impl<M: Message> Subscriber<M> {
    /// The fully qualified topic name.
    pub fn topic(&self) -> &str {
        &self.topic
    }

    /// The data key expression.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Its `MS` liveliness token.
    pub fn token(&self) -> &str {
        &self.token_key
    }

    /// The entity id in its token.
    pub fn entity_id(&self) -> u32 {
        self.entity_id
    }
}
