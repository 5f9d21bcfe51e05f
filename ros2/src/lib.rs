//! ROS 2 interop for acch without a ROS installation.
//!
//! What it is:
//! - [`Node`]: a plain zenoh session that rmw_zenoh (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`)
//!   sees as a ROS 2 node. It declares the liveliness tokens `ros2 node list` and
//!   `ros2 topic list` are built from, publishes on rmw_zenoh's data key expressions
//!   with its per-sample attachment, and subscribes the same way.
//! - [`msg`]: the ROS 2 messages acch sends (poses, transforms, camera info, images),
//!   encoded as the plain CDR rmw_zenoh and rosbag2 use.
//! - [`BagWriter`]: rosbag2-compatible MCAP bags that `ros2 bag info`/`play` and
//!   `rosbags` open.
//! - [`graph`] and [`names`]: the key, token, QoS-string, attachment and name rules,
//!   exposed for tests and tools.
//!
//! What it is not: no DDS (only rmw_zenoh peers can see it), no rcl (no parameters,
//! services, actions, `/rosout`, `/parameter_events` or remapping), no message
//! generation (the types are written by hand), and no transient-local cache (only
//! VOLATILE is honoured, whatever a [`Qos`] advertises).
//!
//! The wire formats follow rmw_zenoh's source (Jazzy 0.2.x and Rolling) and are
//! checked against `rosbags`, an independent implementation of CDR, RIHS01 hashes
//! and rosbag2 (`tests/ros2/check_ros2.py` checks a running publisher and its bag).
//!
//! ```no_run
//! use acch_ros2::msg::{Header, PoseWithCovarianceStamped, Time};
//! use acch_ros2::{BagWriter, Node, NodeConfig, Qos, now_ns};
//! use zenoh::Wait;
//! # fn main() -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
//! let session = zenoh::open(zenoh::Config::default()).wait()?;
//! let config = NodeConfig { namespace: "/acch".into(), ..NodeConfig::default() };
//! let node = Node::new(&session, config)?;
//! // `ros2 topic echo /acch/fruitbox/seed` shows what this publishes.
//! let mut seed = node.publisher::<PoseWithCovarianceStamped>("fruitbox/seed", Qos::default())?;
//! let mut bag = BagWriter::create("run1".as_ref(), "jazzy")?;
//! let topic = bag.add_topic::<PoseWithCovarianceStamped>(seed.topic(), Qos::default())?;
//!
//! let now = now_ns();
//! let mut msg = PoseWithCovarianceStamped::default();
//! msg.header = Header { stamp: Time::from_ns(now as u64), frame_id: "camera_optical".into() };
//! seed.publish(&msg, now)?;
//! // Record exactly the bytes that went on the wire.
//! bag.write(topic, now as u64, now as u64, seed.last_payload())?;
//! bag.finish()?;
//! # Ok(())
//! # }
//! ```

mod de;

pub mod bag;
pub mod graph;
pub mod msg;
pub mod names;
pub mod node;

pub use bag::{BagError, BagWriter, TopicId};
pub use graph::{
    Attachment, AttachmentError, AttachmentFormat, Distro, Durability, Qos, Reliability,
};
pub use msg::{CdrError, Message, decode, encode};
pub use names::NameError;
pub use node::{
    DeclareError, Node, NodeConfig, PublishError, Publisher, Ros2Error, Subscriber, now_ns,
};
