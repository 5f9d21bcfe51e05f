//! rmw_zenoh's wire conventions: data key expressions, liveliness tokens
//! (the ROS graph), QoS strings, the per-sample attachment and entity GIDs.
//!
//! These are plain string and byte builders with no zenoh session, so that
//! every field can be tested against rmw_zenoh's source
//! (`liveliness_utils.cpp`, `attachment_helpers.cpp`).

use crate::msg::Message;
use crate::names::{mangle, strip_slashes};
use std::fmt::Write as _;

/// The liveliness admin space every rmw_zenoh process watches.
pub const ADMIN_SPACE: &str = "@ros2_lv";
/// The SROS enclave rcl uses by default (`/`, mangled to `%` in tokens).
pub const DEFAULT_ENCLAVE: &str = "/";
/// What Humble puts where later distros put the type hash.
pub const HUMBLE_TYPE_HASH: &str = "TypeHashNotSupported";

/// The ROS 2 distribution of the peers: it decides the type-hash chunk.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Distro {
    /// Jazzy and later (Kilted, Rolling): the RIHS01 hash.
    #[default]
    Jazzy,
    /// Humble: the literal `TypeHashNotSupported`.
    Humble,
}

impl Distro {
    /// The type-hash chunk for `M` in keys and tokens.
    pub fn type_hash<M: Message>(self) -> &'static str {
        match self {
            Distro::Jazzy => M::TYPE_HASH,
            Distro::Humble => HUMBLE_TYPE_HASH,
        }
    }

    /// The lowercase name (`jazzy`, `humble`), as in `ROS_DISTRO`.
    pub fn name(self) -> &'static str {
        match self {
            Distro::Jazzy => "jazzy",
            Distro::Humble => "humble",
        }
    }
}

/// Which attachment layout the receivers expect; the two are mutually
/// unreadable (a receiver of one version drops the other's samples).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AttachmentFormat {
    /// 33 bytes, no labels: Jazzy >= 0.2.4, Kilted, Rolling >= 0.6,
    /// Humble >= 0.1.2.
    #[default]
    Current,
    /// 77 bytes with string labels: Jazzy 0.2.0-0.2.3, Humble 0.1.0-0.1.1.
    Legacy,
}

/// QoS reliability (values from `rmw/types.h`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Reliability {
    /// Retransmit until delivered.
    #[default]
    Reliable,
    /// Drop rather than wait.
    BestEffort,
}

impl Reliability {
    /// The `rmw_qos_reliability_policy_e` value.
    pub fn rmw_value(self) -> u8 {
        match self {
            Reliability::Reliable => 1,
            Reliability::BestEffort => 2,
        }
    }

    /// The name rosbag2 writes (`rmw_qos_reliability_policy_to_str`).
    pub fn rmw_name(self) -> &'static str {
        match self {
            Reliability::Reliable => "reliable",
            Reliability::BestEffort => "best_effort",
        }
    }
}

/// QoS durability (values from `rmw/types.h`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Durability {
    /// Late joiners get nothing old.
    #[default]
    Volatile,
    /// Late joiners get the last `depth` samples. Advertising this without
    /// keeping a cache makes subscribers query a cache that is not there.
    TransientLocal,
}

impl Durability {
    /// The `rmw_qos_durability_policy_e` value.
    pub fn rmw_value(self) -> u8 {
        match self {
            Durability::TransientLocal => 1,
            Durability::Volatile => 2,
        }
    }

    /// The name rosbag2 writes (`rmw_qos_durability_policy_to_str`).
    pub fn rmw_name(self) -> &'static str {
        match self {
            Durability::TransientLocal => "transient_local",
            Durability::Volatile => "volatile",
        }
    }
}

/// The QoS an entity advertises. History is always KEEP_LAST; deadline,
/// lifespan and liveliness lease are infinite and liveliness AUTOMATIC,
/// which is what rmw_zenoh reports for an ordinary rclcpp publisher.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Qos {
    /// Reliability.
    pub reliability: Reliability,
    /// Durability.
    pub durability: Durability,
    /// KEEP_LAST depth, at least 1.
    pub history_depth: u32,
}

impl Default for Qos {
    /// RELIABLE, VOLATILE, KEEP_LAST 10 (rclcpp's default for publishers).
    fn default() -> Self {
        Qos {
            reliability: Reliability::Reliable,
            durability: Durability::Volatile,
            history_depth: 10,
        }
    }
}

impl Qos {
    /// `rmw_qos_history_policy_e` KEEP_LAST.
    pub const HISTORY_KEEP_LAST: u8 = 1;
    /// `RMW_DURATION_INFINITE` seconds.
    pub const INFINITE_SEC: u64 = 9_223_372_036;
    /// `RMW_DURATION_INFINITE` nanoseconds.
    pub const INFINITE_NSEC: u64 = 854_775_807;

    /// The QoS chunk of a liveliness token:
    /// `<rel>:<dur>:<hist>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:<liveliness>,<lease s>,<ns>`.
    ///
    /// Reliability, durability and history are written out even where they
    /// equal rmw_zenoh's defaults, because an empty field is read as the
    /// *receiver's* default, and Jazzy's default durability changed in 0.2.3.
    /// The durations and liveliness are left empty (= infinite / AUTOMATIC
    /// on every version). RELIABLE/VOLATILE/KEEP_LAST 10 gives
    /// `1:2:1,10:,:,:,,`.
    pub fn to_keyexpr(&self) -> String {
        format!(
            "{}:{}:{},{}:,:,:,,",
            self.reliability.rmw_value(),
            self.durability.rmw_value(),
            Self::HISTORY_KEEP_LAST,
            self.history_depth
        )
    }

    /// This QoS as one entry of rosbag2's `offered_qos_profiles` (metadata
    /// version 9: policy names, not numbers), indented by `indent` spaces,
    /// each line ending in a newline. The first line starts with `- `.
    pub fn to_rosbag2_yaml(&self, indent: usize) -> String {
        let pad = " ".repeat(indent);
        let inf = format!(
            "\n{pad}    sec: {}\n{pad}    nsec: {}",
            Self::INFINITE_SEC,
            Self::INFINITE_NSEC
        );
        let mut s = String::new();
        // Writing to a String cannot fail.
        let _ = write!(
            s,
            "{pad}- history: keep_last\n\
             {pad}  depth: {depth}\n\
             {pad}  reliability: {rel}\n\
             {pad}  durability: {dur}\n\
             {pad}  deadline:{inf}\n\
             {pad}  lifespan:{inf}\n\
             {pad}  liveliness: automatic\n\
             {pad}  liveliness_lease_duration:{inf}\n\
             {pad}  avoid_ros_namespace_conventions: false\n",
            depth = self.history_depth,
            rel = self.reliability.rmw_name(),
            dur = self.durability.rmw_name(),
        );
        s
    }
}

/// The data key expression rmw_zenoh publishes and subscribes on:
/// `<domain>/<topic without outer slashes>/<dds type>/<type hash>`. Inner
/// slashes of the topic stay, so `/robot1/pose` is two chunks.
pub fn data_key(domain_id: u32, topic: &str, dds_type: &str, type_hash: &str) -> String {
    format!(
        "{domain_id}/{}/{dds_type}/{type_hash}",
        strip_slashes(topic)
    )
}

/// Who a liveliness token belongs to: the node part shared by all of a
/// node's tokens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeInfo<'a> {
    /// `ROS_DOMAIN_ID`.
    pub domain_id: u32,
    /// The zenoh session id, `session.zid().to_string()`.
    pub zid: &'a str,
    /// The node id (unique within the session).
    pub node_id: u32,
    /// The SROS enclave, normally `/`.
    pub enclave: &'a str,
    /// The node namespace, `/` or `/a/b`.
    pub namespace: &'a str,
    /// The node name.
    pub name: &'a str,
}

/// What a publisher or subscriber token says about its topic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TopicInfo<'a> {
    /// The fully qualified topic name, leading slash included.
    pub topic: &'a str,
    /// The DDS type name, e.g. `geometry_msgs::msg::dds_::PoseStamped_`.
    pub dds_type: &'a str,
    /// `RIHS01_…` or `TypeHashNotSupported`.
    pub type_hash: &'a str,
    /// The advertised QoS.
    pub qos: Qos,
}

/// The kind of entity a token announces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EntityKind {
    /// `NN`.
    Node,
    /// `MP`.
    Publisher,
    /// `MS`.
    Subscriber,
}

impl EntityKind {
    /// The two-letter code in the token.
    pub fn code(self) -> &'static str {
        match self {
            EntityKind::Node => "NN",
            EntityKind::Publisher => "MP",
            EntityKind::Subscriber => "MS",
        }
    }
}

fn node_part(node: &NodeInfo<'_>, entity_id: u32, kind: EntityKind) -> String {
    format!(
        "{ADMIN_SPACE}/{}/{}/{}/{entity_id}/{}/{}/{}/{}",
        node.domain_id,
        node.zid,
        node.node_id,
        kind.code(),
        mangle(node.enclave),
        mangle(node.namespace),
        mangle(node.name),
    )
}

/// A node's token:
/// `@ros2_lv/<domain>/<zid>/<nid>/<nid>/NN/<enclave%>/<namespace%>/<name>`
/// (the node id appears twice: it is also the entity id).
pub fn node_token(node: &NodeInfo<'_>) -> String {
    node_part(node, node.node_id, EntityKind::Node)
}

fn entity_token(
    node: &NodeInfo<'_>,
    entity_id: u32,
    kind: EntityKind,
    topic: &TopicInfo<'_>,
) -> String {
    format!(
        "{}/{}/{}/{}/{}",
        node_part(node, entity_id, kind),
        mangle(topic.topic),
        mangle(topic.dds_type),
        mangle(topic.type_hash),
        topic.qos.to_keyexpr()
    )
}

/// A publisher's token: the node part with `MP`, then
/// `<topic%>/<dds type>/<hash>/<qos>`.
pub fn publisher_token(node: &NodeInfo<'_>, entity_id: u32, topic: &TopicInfo<'_>) -> String {
    entity_token(node, entity_id, EntityKind::Publisher, topic)
}

/// A subscriber's token: like [`publisher_token`] with `MS`.
pub fn subscriber_token(node: &NodeInfo<'_>, entity_id: u32, topic: &TopicInfo<'_>) -> String {
    entity_token(node, entity_id, EntityKind::Subscriber, topic)
}

/// The GID rmw_zenoh derives for an entity: XXH3-128 (seed 0) of its full
/// liveliness token, low 64 bits little endian, then high 64 bits.
/// Receivers recompute it from the token, so the attachment's GID then
/// matches what `ros2 topic info -v` shows.
pub fn gid(token: &str) -> [u8; 16] {
    let h = xxhash_rust::xxh3::xxh3_128(token.as_bytes());
    let mut g = [0u8; 16];
    g[..8].copy_from_slice(&(h as u64).to_le_bytes());
    g[8..].copy_from_slice(&((h >> 64) as u64).to_le_bytes());
    g
}

/// The metadata rmw_zenoh requires on every sample (a sample without it is
/// dropped with "Unable to obtain attachment").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Attachment {
    /// Per-publisher sequence number, 1 for the first sample.
    pub sequence: i64,
    /// When the sample was published, ns since the UNIX epoch.
    pub source_timestamp_ns: i64,
    /// The publisher's GID.
    pub gid: [u8; 16],
}

/// An attachment that neither format can read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum AttachmentError {
    /// Neither 33 (current) nor 77 (legacy) bytes.
    #[error(
        "attachment is {len} bytes; expected 33 (rmw_zenoh >= Jazzy 0.2.4) or 77 (Jazzy 0.2.0-0.2.3, labelled)"
    )]
    Length {
        /// The length found.
        len: usize,
    },
    /// The GID's length prefix is not 16.
    #[error("attachment byte {offset}: GID length prefix is {found:#04x}, expected 0x10")]
    GidLength {
        /// Where the prefix is.
        offset: usize,
        /// What it says.
        found: u8,
    },
    /// A label of the legacy format is missing or wrong.
    #[error("legacy attachment byte {offset}: expected the label {expected:?}")]
    Label {
        /// Where the label should start (at its length byte).
        offset: usize,
        /// The label expected there.
        expected: &'static str,
    },
}

const LABEL_SEQUENCE: &str = "sequence_number";
const LABEL_TIMESTAMP: &str = "source_timestamp";
const LABEL_GID: &str = "source_gid";

fn push_label(out: &mut Vec<u8>, label: &str) {
    // zenoh-ext writes a string as a LEB128 length and its bytes; these
    // labels are shorter than 128, so the length is one byte.
    out.push(label.len() as u8);
    out.extend_from_slice(label.as_bytes());
}

impl Attachment {
    /// Size of the current format.
    pub const CURRENT_LEN: usize = 33;
    /// Size of the legacy, labelled format.
    pub const LEGACY_LEN: usize = 77;

    /// Writes the attachment into `out` (cleared first; no allocation once
    /// `out` has grown to 77 bytes). Current: `seq i64 LE | ts i64 LE | 0x10
    /// | gid`. Legacy: each field preceded by its zenoh-ext string label.
    pub fn encode(&self, format: AttachmentFormat, out: &mut Vec<u8>) {
        out.clear();
        let legacy = format == AttachmentFormat::Legacy;
        if legacy {
            push_label(out, LABEL_SEQUENCE);
        }
        out.extend_from_slice(&self.sequence.to_le_bytes());
        if legacy {
            push_label(out, LABEL_TIMESTAMP);
        }
        out.extend_from_slice(&self.source_timestamp_ns.to_le_bytes());
        if legacy {
            push_label(out, LABEL_GID);
        }
        // zenoh-ext length-prefixes fixed arrays like slices: LEB128(16).
        out.push(16);
        out.extend_from_slice(&self.gid);
    }

    /// Reads either format, telling them apart by length.
    pub fn decode(bytes: &[u8]) -> Result<Attachment, AttachmentError> {
        match bytes.len() {
            Self::CURRENT_LEN => Self::decode_fields(bytes, &[]),
            Self::LEGACY_LEN => {
                Self::decode_fields(bytes, &[LABEL_SEQUENCE, LABEL_TIMESTAMP, LABEL_GID])
            }
            len => Err(AttachmentError::Length { len }),
        }
    }

    /// Reads the three fields, each after its label if `labels` is not empty.
    fn decode_fields(bytes: &[u8], labels: &[&'static str]) -> Result<Attachment, AttachmentError> {
        let mut pos = 0;
        let label = |pos: &mut usize, i: usize| -> Result<(), AttachmentError> {
            let Some(&expected) = labels.get(i) else {
                return Ok(());
            };
            let end = *pos + 1 + expected.len();
            let ok = bytes.get(*pos) == Some(&(expected.len() as u8))
                && bytes.get(*pos + 1..end) == Some(expected.as_bytes());
            if !ok {
                return Err(AttachmentError::Label {
                    offset: *pos,
                    expected,
                });
            }
            *pos = end;
            Ok(())
        };
        let word = |pos: &mut usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[*pos..*pos + 8]);
            *pos += 8;
            i64::from_le_bytes(b)
        };
        label(&mut pos, 0)?;
        let sequence = word(&mut pos);
        label(&mut pos, 1)?;
        let source_timestamp_ns = word(&mut pos);
        label(&mut pos, 2)?;
        if bytes[pos] != 16 {
            return Err(AttachmentError::GidLength {
                offset: pos,
                found: bytes[pos],
            });
        }
        let mut gid = [0u8; 16];
        gid.copy_from_slice(&bytes[pos + 1..pos + 17]);
        Ok(Attachment {
            sequence,
            source_timestamp_ns,
            gid,
        })
    }
}
