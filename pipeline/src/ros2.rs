//! The pipeline as a ROS 2 node, with no ROS installed: seeds, fused poses,
//! camera info and `/tf` as native rmw_zenoh topics on the pipeline's zenoh
//! session ([`Ros2Out`]), the arm's camera pose from a ROS 2 topic as the
//! motion seeding fuses over ([`ArmFeed`]), and the same messages into a
//! rosbag2 bag ([`Ros2Bag`]). The wire formats live in [`acch_ros2`]; this
//! module says which messages a frame's result makes ([`Ros2Messages`]).
//! Its configuration, [`Ros2Config`], is read and checked with the rest in
//! `config`; why it fails, [`Ros2OutError`], sits beside the observers'
//! error in `observe`.

use crate::config::{ArmMessage, Ros2Attachment, Ros2Config, Ros2Distro};
use crate::frame::FrameHeader;
use crate::observe::{Observe, ObserveError, Ros2OutError};
use crate::stages::Seeded;
use crate::wire::{ArmPose, Hop, Intrinsics, Maybe};
use acch_capture::calibration::DistortionModel;
use acch_ros2::msg::{
    CameraInfo, Header, Image, ImageRef, Point, Pose, PoseStamped, PoseWithCovariance,
    PoseWithCovarianceStamped, Quaternion, TFMessage, Time, Transform, TransformStamped, Vector3,
};
use acch_ros2::{
    AttachmentFormat, BagWriter, Distro, Message, Node, NodeConfig, Qos, TopicId, names,
};
use glam::{DAffine3, DMat3, DQuat, DVec3};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// The QoS of every acch topic: RELIABLE, VOLATILE, KEEP_LAST 10 (rclcpp's
/// publisher default, so a default subscriber matches).
const QOS: Qos = Qos {
    reliability: acch_ros2::Reliability::Reliable,
    durability: acch_ros2::Durability::Volatile,
    history_depth: 10,
};

/// tf2's own depth for `/tf`.
const TF_QOS: Qos = Qos {
    history_depth: 100,
    ..QOS
};

impl Ros2Config {
    /// The node of this configuration, named `name`.
    pub fn node_config(&self, name: &str) -> NodeConfig {
        NodeConfig {
            domain_id: self.domain_id,
            namespace: self.namespace.clone(),
            name: name.to_owned(),
            distro: match self.distro {
                Ros2Distro::Jazzy => Distro::Jazzy,
                Ros2Distro::Humble => Distro::Humble,
            },
            attachment: match self.attachment {
                Ros2Attachment::Current => AttachmentFormat::Current,
                Ros2Attachment::Legacy => AttachmentFormat::Legacy,
            },
        }
    }

    /// The tf frame of `object`'s pose.
    pub fn object_frame(object: &str) -> String {
        format!("acch_{object}")
    }
}

/// The topics, relative to the node's namespace.
pub mod topics {
    /// An object's seeds: one per accepted estimate.
    pub fn seed(object: &str) -> String {
        format!("acch/{object}/seed")
    }
    /// An object's pose fused over the arm's motion: one per frame once the
    /// filter holds one.
    pub fn fused(object: &str) -> String {
        format!("acch/{object}/fused")
    }
    /// The camera's intrinsics, one per frame.
    pub const CAMERA_INFO: &str = "acch/camera_info";
    /// Every `image_every`th frame.
    pub const IMAGE: &str = "acch/image";
    /// tf2's topic.
    pub const TF: &str = "/tf";
}

/// The messages of one frame's result, kept between frames so filling them
/// reuses their strings and vectors.
#[derive(Clone, Debug, Default)]
pub struct Ros2Messages {
    /// The seed of an accepted estimate.
    pub seed: PoseWithCovarianceStamped,
    /// The fused pose.
    pub fused: PoseWithCovarianceStamped,
    /// The camera's intrinsics.
    pub camera_info: CameraInfo,
    /// The fused pose on `/tf`.
    pub tf: TFMessage,
}

/// What [`Ros2Messages::fill`] filled for a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Filled {
    /// The estimate was accepted: `seed` holds its seed.
    pub seed: bool,
    /// The filter holds a pose: `fused` and `tf` hold it.
    pub fused: bool,
}

impl Ros2Messages {
    /// The messages for `object` in camera frame `frame_id`.
    pub fn new(object: &str, frame_id: &str) -> Self {
        let header = Header {
            stamp: Time::default(),
            frame_id: frame_id.to_owned(),
        };
        let mut m = Ros2Messages {
            seed: PoseWithCovarianceStamped {
                header: header.clone(),
                ..Default::default()
            },
            fused: PoseWithCovarianceStamped {
                header: header.clone(),
                ..Default::default()
            },
            camera_info: CameraInfo {
                header: header.clone(),
                distortion_model: "plumb_bob".into(),
                d: vec![0.0; 5],
                ..Default::default()
            },
            tf: TFMessage::default(),
        };
        m.tf.transforms.push(TransformStamped {
            header,
            child_frame_id: Ros2Config::object_frame(object),
            transform: Transform::default(),
        });
        m
    }

    /// Fills the messages of final result `m`, stamped with its frame's
    /// capture time.
    pub fn fill(&mut self, m: &Seeded) -> Filled {
        let frame = &m.envelope().frame;
        let stamp = Time::from_ns(frame.stamp_ns);
        fill_camera_info(
            &mut self.camera_info,
            &frame.intrinsics,
            (frame.width, frame.height),
        );
        self.camera_info.header.stamp = stamp;
        let mut filled = Filled::default();
        if let Some(seed) = m.seed().filter(|_| m.accepted()) {
            self.seed.header.stamp = stamp;
            self.seed.pose = PoseWithCovariance {
                pose: pose_of(
                    DVec3::from_array(seed.translation),
                    DQuat::from_array(seed.rotation_xyzw),
                ),
                covariance: std::array::from_fn(|i| seed.covariance[i / 6][i % 6]),
            };
            filled.seed = true;
        }
        if let Maybe::Present(f) = &m.seeding.fused {
            let a = DAffine3::from_cols_array(&f.camera_from_object);
            let rotation = DQuat::from_mat3(&a.matrix3).normalize();
            self.fused.header.stamp = stamp;
            let mut covariance = [0.0; 36];
            for r in 0..3 {
                for c in 0..3 {
                    covariance[r * 6 + c] = f.translation_covariance[r * 3 + c];
                    covariance[(r + 3) * 6 + c + 3] = f.rotation_covariance[r * 3 + c];
                }
            }
            self.fused.pose = PoseWithCovariance {
                pose: pose_of(a.translation, rotation),
                covariance,
            };
            let t = &mut self.tf.transforms[0];
            t.header.stamp = stamp;
            t.transform = Transform {
                translation: Vector3 {
                    x: a.translation.x,
                    y: a.translation.y,
                    z: a.translation.z,
                },
                rotation: self.fused.pose.pose.orientation,
            };
            filled.fused = true;
        }
        filled
    }
}

fn pose_of(t: DVec3, q: DQuat) -> Pose {
    Pose {
        position: Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        },
    }
}

/// The camera as sensor_msgs/CameraInfo states one: K, its distortion
/// (plumb_bob or rational_polynomial; zeros for none), the identity R
/// and P = [K | 0] (the images are not rectified).
fn fill_camera_info(info: &mut CameraInfo, k: &Intrinsics, (width, height): (u32, u32)) {
    info.width = width;
    info.height = height;
    let lens = k.lens();
    let (model, n) = match lens.model {
        DistortionModel::RationalPolynomial => ("rational_polynomial", 8),
        _ => ("plumb_bob", 5),
    };
    // Reassigned only when they change: this runs for every frame.
    if info.distortion_model != model {
        info.distortion_model = model.into();
    }
    info.d.resize(n, 0.0);
    info.d.copy_from_slice(&lens.coefficients[..n]);
    info.k = [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0];
    info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    info.p = [
        k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0,
    ];
}

/// The ROS 2 publishers of one object's results, on the pipeline's zenoh
/// session (the seeding stage's).
pub struct Ros2Out {
    /// Every `image_every`th frame, until taken to a thread of its own.
    pub images: Option<Ros2Images>,
    seed: acch_ros2::node::Publisher<PoseWithCovarianceStamped>,
    fused: acch_ros2::node::Publisher<PoseWithCovarianceStamped>,
    /// The camera's topics (info and images) go out from one object's
    /// node only when several share a frame.
    camera_info: Option<acch_ros2::node::Publisher<CameraInfo>>,
    tf: Option<acch_ros2::node::Publisher<TFMessage>>,
    messages: Ros2Messages,
    // Last: the publishers go before the node's token.
    _node: Node,
}

/// Which node an object's ROS 2 publishers are declared on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ros2Role {
    /// The one object of the run: node `ros2.node`, with the camera's
    /// topics.
    Only,
    /// One of several objects: node `<ros2.node>_<object>`; `camera` says
    /// whether this one publishes the camera's topics (the first does).
    OneOf {
        /// Publishes camera info and images.
        camera: bool,
    },
}

impl Ros2Out {
    /// Declares the node and its publishers on `session`.
    pub fn declare(
        session: &zenoh::Session,
        config: &Ros2Config,
        object: &str,
        role: Ros2Role,
    ) -> Result<Self, Ros2OutError> {
        let (name, camera) = match role {
            Ros2Role::Only => (config.node.clone(), true),
            Ros2Role::OneOf { camera } => (format!("{}_{object}", config.node), camera),
        };
        let node = Node::new(session, config.node_config(&name))?;
        Ok(Ros2Out {
            images: match config.image_every {
                _ if !camera => None,
                0 => None,
                every => Some(Ros2Images {
                    publisher: node.publisher(topics::IMAGE, QOS)?,
                    header: Header {
                        stamp: Time::default(),
                        frame_id: config.frame_id.clone(),
                    },
                    every: u64::from(every),
                }),
            },
            seed: node.publisher(&topics::seed(object), QOS)?,
            fused: node.publisher(&topics::fused(object), QOS)?,
            camera_info: if camera {
                Some(node.publisher(topics::CAMERA_INFO, QOS)?)
            } else {
                None
            },
            tf: if config.tf {
                Some(node.publisher(topics::TF, TF_QOS)?)
            } else {
                None
            },
            messages: Ros2Messages::new(object, &config.frame_id),
            _node: node,
        })
    }

    /// Publishes what final result `m` makes: its camera info, its seed
    /// when accepted, the fused pose and its transform once there is one.
    pub fn publish(&mut self, m: &Seeded) -> Result<(), Ros2OutError> {
        let filled = self.messages.fill(m);
        let now = acch_ros2::node::now_ns();
        let msgs = &self.messages;
        if let Some(info) = &mut self.camera_info {
            info.publish(&msgs.camera_info, now)?;
        }
        if filled.seed {
            self.seed.publish(&msgs.seed, now)?;
        }
        if filled.fused {
            self.fused.publish(&msgs.fused, now)?;
            if let Some(tf) = &mut self.tf {
                tf.publish(&msgs.tf, now)?;
            }
        }
        Ok(())
    }
}

/// Publishes every `image_every`th frame on `acch/image` (rgb8), off the
/// hot path: the seeding process does it on a thread of its own that reads
/// the frame stream like an observer, dropping what it cannot keep up with.
pub struct Ros2Images {
    publisher: acch_ros2::node::Publisher<Image>,
    header: Header,
    every: u64,
}

impl Ros2Images {
    /// Reads the frame stream of `cfg`'s run on a thread until the process
    /// is told to stop, publishing every `image_every`th frame.
    pub fn spawn(
        mut self,
        cfg: &crate::PipelineConfig,
    ) -> std::thread::JoinHandle<Result<(), ObserveError>> {
        let cfg = cfg.clone();
        std::thread::spawn(move || {
            let out = self.publish_until_stopped(&cfg);
            if let Err(e) = &out {
                tracing::warn!("ros2: {} stopped: {e}", topics::IMAGE);
            }
            out
        })
    }

    fn publish_until_stopped(&mut self, cfg: &crate::PipelineConfig) -> Result<(), ObserveError> {
        {
            // iceoryx2 ports stay on the thread that opens them.
            let ipc = cfg
                .ipc("seeding-images")
                .map_err(acch_ipc::IpcError::from)?;
            let frames = ipc
                .input::<FrameHeader>(
                    crate::streams::frames(cfg.run.frame_history),
                    acch_ipc::Wake::Never,
                )
                .map_err(acch_ipc::IpcError::from)?;
            while ipc.keep_running() {
                let mut got = false;
                while let Some(f) = frames.receive().map_err(acch_ipc::IpcError::from)? {
                    self.frame(f.user_header(), f.payload())?;
                    got = true;
                }
                if !got {
                    std::thread::sleep(std::time::Duration::from_millis(5));
                }
            }
            Ok(())
        }
    }
}

/// A frame's pixels as sensor_msgs/Image, borrowing them.
fn image_of<'a>(header: &'a Header, h: &FrameHeader, pixels: &'a [u8]) -> ImageRef<'a> {
    let f = &h.envelope.frame;
    ImageRef {
        header,
        height: f.height,
        width: f.width,
        encoding: "rgb8",
        is_bigendian: 0,
        step: h.stride,
        data: pixels,
    }
}

impl Observe for Ros2Images {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<(), ObserveError> {
        let f = &h.envelope.frame;
        if pixels.is_empty() || !f.sequence.is_multiple_of(self.every) {
            return Ok(());
        }
        self.header.stamp = Time::from_ns(f.stamp_ns);
        let image = image_of(&self.header, h, pixels);
        self.publisher
            .publish_as(&image, acch_ros2::node::now_ns())
            .map_err(Ros2OutError::from)?;
        Ok(())
    }

    fn result(&mut self, _: &Seeded) -> Result<(), ObserveError> {
        Ok(())
    }
}

/// The arm's camera pose from a ROS 2 topic, sampled at each frame's
/// capture: a frame without a fresh pose has none (its motion is unknown,
/// so seeding restarts its filter rather than predict with a stale pose).
pub struct ArmFeed {
    latest: Arc<Mutex<Option<(ArmPose, u64)>>>,
    max_age_ns: u64,
    topic: String,
    _subscriber: ArmSubscriber,
    _node: Node,
    _session: zenoh::Session,
}

/// Held, not read: dropping it undeclares the subscription.
#[allow(dead_code)]
enum ArmSubscriber {
    Pose(acch_ros2::node::Subscriber<PoseStamped>),
    Transform(acch_ros2::node::Subscriber<TransformStamped>),
}

impl ArmFeed {
    /// Subscribes to `config.arm_topic` over a session connected to
    /// `zenoh.connect`; `None` when no arm topic is configured.
    pub fn open(
        config: &Ros2Config,
        zenoh: &acch_ipc::ZenohConfig,
    ) -> Result<Option<Self>, Ros2OutError> {
        let Some(topic) = &config.arm_topic else {
            return Ok(None);
        };
        if zenoh.connect.is_empty() {
            return Err(Ros2OutError::NoPeers);
        }
        // No listener: the run's own endpoint is the seeding stage's.
        let session = acch_ipc::open_session(&[], &zenoh.connect)?;
        let node = Node::new(
            &session,
            config.node_config(&format!("{}_arm", config.node)),
        )?;
        let latest: Arc<Mutex<Option<(ArmPose, u64)>>> = Arc::default();
        let store = |at: &Arc<Mutex<Option<(ArmPose, u64)>>>, pose: ArmPose| {
            if let Ok(mut l) = at.lock() {
                *l = Some((pose, acch_ipc::now_ns()));
            }
        };
        let subscriber = if config.arm_type == ArmMessage::TransformStamped {
            let at = latest.clone();
            ArmSubscriber::Transform(node.subscriber::<TransformStamped, _>(
                topic,
                QOS,
                move |m, _| {
                    let t = m.transform.translation;
                    let q = m.transform.rotation;
                    if let Some(pose) = arm_pose(DVec3::new(t.x, t.y, t.z), [q.x, q.y, q.z, q.w]) {
                        store(&at, pose);
                    }
                },
            )?)
        } else {
            let at = latest.clone();
            ArmSubscriber::Pose(node.subscriber::<PoseStamped, _>(topic, QOS, move |m, _| {
                let (p, q) = (m.pose.position, m.pose.orientation);
                if let Some(pose) = arm_pose(DVec3::new(p.x, p.y, p.z), [q.x, q.y, q.z, q.w]) {
                    store(&at, pose);
                }
            })?)
        };
        tracing::info!("arm: camera poses from {topic} ({})", config.arm_type);
        Ok(Some(ArmFeed {
            latest,
            max_age_ns: u64::from(config.arm_max_age_ms) * 1_000_000,
            topic: topic.clone(),
            _subscriber: subscriber,
            _node: node,
            _session: session,
        }))
    }

    /// Gives frame `h`, captured at CLOCK_MONOTONIC `captured_ns`, the
    /// arm's last pose if it is fresh, else none.
    pub fn stamp(&self, h: &mut FrameHeader, captured_ns: u64) {
        let latest = self.latest.lock().ok().and_then(|l| *l);
        h.envelope.frame.arm = match latest {
            Some((pose, at)) if captured_ns.saturating_sub(at) <= self.max_age_ns => {
                Maybe::Present(pose)
            }
            _ => Maybe::Absent,
        };
    }

    /// The topic it reads.
    pub fn topic(&self) -> &str {
        &self.topic
    }
}

/// `world_from_camera` of a ROS pose; `None` for a quaternion that is not
/// one (zero or not finite), which a frame must not carry as motion.
fn arm_pose(translation: DVec3, xyzw: [f64; 4]) -> Option<ArmPose> {
    let q = DQuat::from_array(xyzw);
    let norm = q.length();
    if !(norm.is_finite() && norm > 1e-6 && translation.is_finite()) {
        tracing::warn!("arm: ignoring a pose with quaternion {xyzw:?}, translation {translation}");
        return None;
    }
    let a = DAffine3::from_mat3_translation(DMat3::from_quat(q / norm), translation);
    Some(ArmPose {
        world_from_camera: a.to_cols_array(),
    })
}

/// The bag directory `--record PATH` names in the ros2 format: PATH, less
/// a `.mcap` extension (the bag is `DIR/DIR_0.mcap` beside
/// `DIR/metadata.yaml`, as `ros2 bag record -o DIR` writes it).
pub fn bag_dir(path: &Path) -> std::path::PathBuf {
    if path.extension().is_some_and(|e| e == "mcap") {
        path.with_extension("")
    } else {
        path.to_owned()
    }
}

/// Records a run as a rosbag2 bag (`--record-format ros2`): the topics of
/// [`Ros2Out`] with the same bytes, plus every frame on `acch/image`.
pub struct Ros2Bag {
    bag: BagWriter,
    seed: TopicId,
    fused: TopicId,
    camera_info: TopicId,
    tf: Option<TopicId>,
    image: TopicId,
    messages: Ros2Messages,
    header: Header,
    payload: Vec<u8>,
    /// Messages written per topic: frames, seeds, fused, camera info.
    pub counts: [u64; 4],
}

impl Ros2Bag {
    /// Creates bag directory `dir` for `object`'s results.
    pub fn create(dir: &Path, config: &Ros2Config, object: &str) -> Result<Self, Ros2OutError> {
        let mut bag = BagWriter::create(dir, config.distro.name())?;
        // The names the node publishes under.
        let resolve = |t: &str| {
            names::resolve_topic(&config.namespace, t).map_err(acch_ros2::node::Ros2Error::from)
        };
        let seed =
            bag.add_topic::<PoseWithCovarianceStamped>(&resolve(&topics::seed(object))?, QOS)?;
        let fused =
            bag.add_topic::<PoseWithCovarianceStamped>(&resolve(&topics::fused(object))?, QOS)?;
        let camera_info = bag.add_topic::<CameraInfo>(&resolve(topics::CAMERA_INFO)?, QOS)?;
        let image = bag.add_topic::<Image>(&resolve(topics::IMAGE)?, QOS)?;
        let tf = if config.tf {
            Some(bag.add_topic::<TFMessage>(topics::TF, TF_QOS)?)
        } else {
            None
        };
        Ok(Ros2Bag {
            bag,
            seed,
            fused,
            camera_info,
            tf,
            image,
            messages: Ros2Messages::new(object, &config.frame_id),
            header: Header {
                stamp: Time::default(),
                frame_id: config.frame_id.clone(),
            },
            payload: Vec::new(),
            counts: [0; 4],
        })
    }

    /// The MCAP file inside the bag.
    pub fn mcap_path(&self) -> &Path {
        self.bag.mcap_path()
    }

    fn write<M: Message>(
        &mut self,
        topic: TopicId,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), Ros2OutError> {
        acch_ros2::encode(msg, &mut self.payload)?;
        self.bag.write(topic, stamp_ns, stamp_ns, &self.payload)?;
        Ok(())
    }

    /// Completes the bag: its summary, the rosbag2 metadata and
    /// metadata.yaml.
    pub fn finish(self) -> Result<(), Ros2OutError> {
        Ok(self.bag.finish()?)
    }
}

impl Observe for Ros2Bag {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<(), ObserveError> {
        if pixels.is_empty() {
            return Ok(());
        }
        let f = &h.envelope.frame;
        self.header.stamp = Time::from_ns(f.stamp_ns);
        let image = image_of(&self.header, h, pixels);
        acch_ros2::msg::encode_as::<Image, _>(&image, &mut self.payload)
            .map_err(Ros2OutError::from)?;
        self.bag
            .write(self.image, f.stamp_ns, f.stamp_ns, &self.payload)
            .map_err(Ros2OutError::from)?;
        self.counts[0] += 1;
        Ok(())
    }

    fn result(&mut self, m: &Seeded) -> Result<(), ObserveError> {
        let stamp = m.envelope().frame.stamp_ns;
        let filled = self.messages.fill(m);
        let msgs = std::mem::take(&mut self.messages);
        let out = (|| -> Result<(), Ros2OutError> {
            self.write(self.camera_info, stamp, &msgs.camera_info)?;
            self.counts[3] += 1;
            if filled.seed {
                self.write(self.seed, stamp, &msgs.seed)?;
                self.counts[1] += 1;
            }
            if filled.fused {
                self.write(self.fused, stamp, &msgs.fused)?;
                self.counts[2] += 1;
                if let Some(tf) = self.tf {
                    self.write(tf, stamp, &msgs.tf)?;
                }
            }
            Ok(())
        })();
        self.messages = msgs;
        Ok(out?)
    }
}
