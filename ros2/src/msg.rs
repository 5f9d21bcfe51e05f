//! ROS 2 message types and their CDR encoding.
//!
//! Every struct lists its fields in the order of the ROS `.msg` file, because
//! CDR has no field names: the order *is* the format. Fixed-size arrays
//! (`float64[36]`) are written without a length, sequences (`float64[]`,
//! `uint8[]`) with a `u32` count, strings as `u32` length (NUL included),
//! bytes and a NUL.
//!
//! The type names, RIHS01 hashes and definitions are constants checked
//! against `rosbags` 0.11.9 (`Stores.ROS2_JAZZY`); they are the same in
//! Humble, Jazzy and Kilted for these types.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// A ROS 2 message type: what rmw_zenoh needs to name it on the wire and
/// what rosbag2 needs to describe it in a bag.
pub trait Message: Serialize + DeserializeOwned {
    /// The ROS type name, `pkg/msg/Type`.
    const TYPE: &'static str;
    /// The REP-2011 type hash, `RIHS01_` and 64 hex digits; rmw_zenoh on
    /// Jazzy and later puts it in every key and token, and a subscriber whose
    /// hash differs by one character never receives anything.
    const TYPE_HASH: &'static str;
    /// The `ros2msg` definition text for MCAP schemas: this type's `.msg`,
    /// then each nested type after a line of 80 `=` and `MSG: pkg/Type`.
    const DEFINITION: &'static str;

    /// The DDS type name rmw_zenoh uses in keys and tokens, e.g.
    /// `geometry_msgs::msg::dds_::PoseWithCovarianceStamped_`.
    fn dds_type() -> String {
        dds_type_name(Self::TYPE)
    }
}

/// A value that encodes to exactly the bytes of message `M`, so it can be
/// published as an `M` without building an owned `M` first (see
/// [`ImageRef`]).
pub trait EncodesAs<M: Message>: Serialize {}

impl<M: Message> EncodesAs<M> for M {}

/// The DDS name of a ROS type name: `pkg/msg/Type` becomes
/// `pkg::msg::dds_::Type_`, as the fastrtps type support rmw_zenoh uses
/// spells it.
pub fn dds_type_name(ros_type: &str) -> String {
    match ros_type.rsplit_once('/') {
        Some((namespace, name)) => format!("{}::dds_::{name}_", namespace.replace('/', "::")),
        None => format!("dds_::{ros_type}_"),
    }
}

/// CDR encoding or decoding failed.
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    /// The `cdr` crate refused the value; it only fails on a string or
    /// sequence longer than `u32::MAX`.
    #[error("encoding a {type_name} as CDR failed")]
    Encode {
        /// The ROS type being encoded.
        type_name: &'static str,
        /// What the `cdr` crate said.
        #[source]
        source: cdr::Error,
    },
    /// Fewer than the 4 bytes of the encapsulation header.
    #[error(
        "{type_name}: a {len}-byte payload is too short for the 4-byte CDR encapsulation header"
    )]
    MissingHeader {
        /// The ROS type being decoded.
        type_name: &'static str,
        /// The payload length.
        len: usize,
    },
    /// An encapsulation other than plain CDR (0x0000 big endian, 0x0001
    /// little endian), e.g. XCDR2 or a parameter list, which ROS 2 never
    /// sends.
    #[error(
        "{type_name}: CDR encapsulation {id:#06x} is not plain CDR (expected 0x0001 little endian or 0x0000 big endian)"
    )]
    Encapsulation {
        /// The ROS type being decoded.
        type_name: &'static str,
        /// The representation identifier found in bytes 0-1.
        id: u16,
    },
    /// The bytes do not hold a valid message of this type.
    #[error("{type_name}: field {field} at byte {offset}: {reason}")]
    Decode {
        /// The ROS type being decoded.
        type_name: &'static str,
        /// The field path, e.g. `header.frame_id` or `transforms[2].header.frame_id`.
        field: String,
        /// The offset in the payload (the header included) where it failed.
        offset: usize,
        /// What was wrong.
        reason: String,
    },
}

/// Encodes `m` as little-endian plain CDR into `out`, header `00 01 00 00`
/// first, exactly the bytes rmw_zenoh sends and rosbag2 stores.
///
/// `out` is cleared and reused: once it has grown to the message size,
/// encoding allocates nothing.
pub fn encode<M: Message>(m: &M, out: &mut Vec<u8>) -> Result<(), CdrError> {
    encode_as::<M, M>(m, out)
}

/// [`encode`] for a value that encodes as an `M` (e.g. an [`ImageRef`]).
pub fn encode_as<M: Message, B: EncodesAs<M> + ?Sized>(
    m: &B,
    out: &mut Vec<u8>,
) -> Result<(), CdrError> {
    out.clear();
    // The cdr crate writes the encapsulation header, then resets its
    // position so that alignment counts from the byte after the header, as
    // Fast-CDR does.
    cdr::serialize_into::<_, _, _, cdr::CdrLe>(&mut *out, m, cdr::Infinite).map_err(|source| {
        CdrError::Encode {
            type_name: M::TYPE,
            source,
        }
    })
}

/// Decodes a CDR payload (header included, little or big endian) into an `M`.
///
/// Lengths are checked against the bytes actually present before anything
/// is allocated, so a corrupt or hostile sample cannot make this allocate
/// more than its own size. Bytes after the message are ignored, as Fast-CDR
/// ignores them.
pub fn decode<M: Message>(bytes: &[u8]) -> Result<M, CdrError> {
    crate::de::decode(bytes, M::TYPE)
}

/// `serde` helpers for `T[N]` fields: serde derives arrays only up to 32
/// elements, and CDR writes a fixed array as its elements with no count.
mod fixed_array {
    use serde::de::{Error, SeqAccess, Visitor};
    use serde::ser::SerializeTuple;
    use serde::{Deserializer, Serializer};
    use std::fmt;

    pub(crate) fn serialize<S: Serializer, const N: usize>(
        v: &[f64; N],
        s: S,
    ) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(N)?;
        for x in v {
            t.serialize_element(x)?;
        }
        t.end()
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>, const N: usize>(
        d: D,
    ) -> Result<[f64; N], D::Error> {
        struct ArrayVisitor<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for ArrayVisitor<N> {
            type Value = [f64; N];
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of {N} float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[f64; N], A::Error> {
                let mut out = [0.0; N];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq
                        .next_element()?
                        .ok_or_else(|| A::Error::invalid_length(i, &self))?;
                }
                Ok(out)
            }
        }
        d.deserialize_tuple(N, ArrayVisitor::<N>)
    }
}

/// `serde` helpers for `uint8[]`: one length and one copy instead of a
/// serde call per byte (an image is ~1 MB).
mod byte_seq {
    use serde::de::{SeqAccess, Visitor};
    use serde::{Deserializer, Serializer};
    use std::fmt;

    pub(crate) fn serialize<S: Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(v)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        struct BytesVisitor;
        impl<'de> Visitor<'de> for BytesVisitor {
            type Value = Vec<u8>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a uint8 sequence")
            }
            fn visit_bytes<E>(self, v: &[u8]) -> Result<Vec<u8>, E> {
                Ok(v.to_vec())
            }
            fn visit_byte_buf<E>(self, v: Vec<u8>) -> Result<Vec<u8>, E> {
                Ok(v)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<u8>, A::Error> {
                let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 20));
                while let Some(b) = seq.next_element()? {
                    out.push(b);
                }
                Ok(out)
            }
        }
        d.deserialize_byte_buf(BytesVisitor)
    }
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the epoch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Time {
    /// Seconds; `int32` in ROS, so it ends in January 2038.
    pub sec: i32,
    /// Nanoseconds within the second, `0..1_000_000_000`.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after the epoch. Seconds past `i32::MAX`
    /// (2038-01-19) saturate, as ROS cannot represent them.
    pub fn from_ns(ns: u64) -> Time {
        let sec = i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX);
        // The remainder is below 10^9, which fits a u32.
        let nanosec = (ns % 1_000_000_000) as u32;
        Time { sec, nanosec }
    }

    /// Nanoseconds since the epoch (negative before 1970).
    pub fn as_ns(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/msg/Header`: when and in which frame the data was taken.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Acquisition time.
    pub stamp: Time,
    /// The tf frame the data is expressed in.
    pub frame_id: String,
}

/// `geometry_msgs/msg/Point`, in metres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`; the default is the identity (`w = 1`),
/// as in the ROS definition.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w (the scalar part).
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Row-major 6x6 covariance of (x, y, z, rotation about X, Y, Z).
    #[serde(with = "fixed_array")]
    pub covariance: [f64; 36],
}

impl Default for PoseWithCovariance {
    fn default() -> Self {
        PoseWithCovariance {
            pose: Pose::default(),
            covariance: [0.0; 36],
        }
    }
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// Time and frame.
    pub header: Header,
    /// The pose and its covariance.
    pub pose: PoseWithCovariance,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Time and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`: the pose of `child_frame_id` in
/// `header.frame_id`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Time and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// Parent from child.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`, what `/tf` and `/tf_static` carry (tf2 ignores
/// a bare `TransformStamped` on `/tf`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// `sensor_msgs/msg/RegionOfInterest`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RegionOfInterest {
    /// Leftmost pixel.
    pub x_offset: u32,
    /// Topmost pixel.
    pub y_offset: u32,
    /// Height in pixels.
    pub height: u32,
    /// Width in pixels.
    pub width: u32,
    /// Whether a rectified image should be computed for it.
    pub do_rectify: bool,
}

/// `sensor_msgs/msg/CameraInfo`: intrinsics of a pinhole camera.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// Time and optical frame.
    pub header: Header,
    /// Image height in pixels.
    pub height: u32,
    /// Image width in pixels.
    pub width: u32,
    /// e.g. `plumb_bob`.
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Row-major 3x3 intrinsic matrix.
    #[serde(with = "fixed_array")]
    pub k: [f64; 9],
    /// Row-major 3x3 rectification matrix.
    #[serde(with = "fixed_array")]
    pub r: [f64; 9],
    /// Row-major 3x4 projection matrix.
    #[serde(with = "fixed_array")]
    pub p: [f64; 12],
    /// Horizontal binning.
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// Region of interest.
    pub roi: RegionOfInterest,
}

/// `sensor_msgs/msg/Image`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Time and optical frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding, e.g. `rgb8`, `bgr8`, `mono8`.
    pub encoding: String,
    /// 1 if multi-byte pixels are big endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// `step * height` bytes.
    #[serde(with = "byte_seq")]
    pub data: Vec<u8>,
}

/// An [`Image`] that borrows its pixels: it encodes to the same bytes, so a
/// frame can be published straight from the camera buffer.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ImageRef<'a> {
    /// Time and optical frame.
    pub header: &'a Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding, e.g. `rgb8`.
    pub encoding: &'a str,
    /// 1 if multi-byte pixels are big endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// `step * height` bytes.
    #[serde(serialize_with = "byte_seq::serialize")]
    pub data: &'a [u8],
}

impl EncodesAs<Image> for ImageRef<'_> {}

impl From<glam::DVec3> for Point {
    fn from(v: glam::DVec3) -> Self {
        Point {
            x: v.x,
            y: v.y,
            z: v.z,
        }
    }
}

impl From<glam::Vec3> for Point {
    fn from(v: glam::Vec3) -> Self {
        v.as_dvec3().into()
    }
}

impl From<Point> for glam::DVec3 {
    fn from(p: Point) -> Self {
        glam::DVec3::new(p.x, p.y, p.z)
    }
}

impl From<glam::DVec3> for Vector3 {
    fn from(v: glam::DVec3) -> Self {
        Vector3 {
            x: v.x,
            y: v.y,
            z: v.z,
        }
    }
}

impl From<glam::Vec3> for Vector3 {
    fn from(v: glam::Vec3) -> Self {
        v.as_dvec3().into()
    }
}

impl From<Vector3> for glam::DVec3 {
    fn from(v: Vector3) -> Self {
        glam::DVec3::new(v.x, v.y, v.z)
    }
}

impl From<glam::DQuat> for Quaternion {
    fn from(q: glam::DQuat) -> Self {
        Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        }
    }
}

impl From<glam::Quat> for Quaternion {
    fn from(q: glam::Quat) -> Self {
        q.as_dquat().into()
    }
}

impl From<Quaternion> for glam::DQuat {
    fn from(q: Quaternion) -> Self {
        glam::DQuat::from_xyzw(q.x, q.y, q.z, q.w)
    }
}

/// The line rosbag2 puts between the definitions of nested types.
macro_rules! dep {
    ($name:literal, $body:expr) => {
        concat!(
            "================================================================================\n",
            "MSG: ",
            $name,
            "\n",
            $body
        )
    };
}

macro_rules! time_msg {
    () => {
        "int32 sec\nuint32 nanosec\n"
    };
}
macro_rules! header_msg {
    () => {
        "builtin_interfaces/Time stamp\nstring frame_id\n"
    };
}
macro_rules! xyz_msg {
    () => {
        "float64 x\nfloat64 y\nfloat64 z\n"
    };
}
macro_rules! quaternion_msg {
    () => {
        "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
    };
}
macro_rules! pose_msg {
    () => {
        "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
    };
}
macro_rules! pose_with_covariance_msg {
    () => {
        "geometry_msgs/Pose pose\nfloat64[36] covariance\n"
    };
}
macro_rules! transform_msg {
    () => {
        "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"
    };
}
macro_rules! transform_stamped_msg {
    () => {
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"
    };
}
macro_rules! roi_msg {
    () => {
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
    };
}
/// Header and the Time inside it, as a dependency block.
macro_rules! header_deps {
    () => {
        concat!(
            dep!("std_msgs/Header", header_msg!()),
            dep!("builtin_interfaces/Time", time_msg!())
        )
    };
}
/// Pose and what it contains, as a dependency block.
macro_rules! pose_deps {
    () => {
        concat!(
            dep!("geometry_msgs/Pose", pose_msg!()),
            dep!("geometry_msgs/Point", xyz_msg!()),
            dep!("geometry_msgs/Quaternion", quaternion_msg!())
        )
    };
}
macro_rules! transform_deps {
    () => {
        concat!(
            dep!("geometry_msgs/Transform", transform_msg!()),
            dep!("geometry_msgs/Vector3", xyz_msg!()),
            dep!("geometry_msgs/Quaternion", quaternion_msg!())
        )
    };
}

macro_rules! message {
    ($ty:ty, $name:literal, $hash:literal, $def:expr) => {
        impl Message for $ty {
            const TYPE: &'static str = $name;
            const TYPE_HASH: &'static str = $hash;
            const DEFINITION: &'static str = $def;
        }
    };
}

message!(
    Time,
    "builtin_interfaces/msg/Time",
    "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    time_msg!()
);
message!(
    Header,
    "std_msgs/msg/Header",
    "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    concat!(header_msg!(), dep!("builtin_interfaces/Time", time_msg!()))
);
message!(
    Point,
    "geometry_msgs/msg/Point",
    "RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881",
    xyz_msg!()
);
message!(
    Quaternion,
    "geometry_msgs/msg/Quaternion",
    "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684",
    quaternion_msg!()
);
message!(
    Pose,
    "geometry_msgs/msg/Pose",
    "RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    concat!(
        pose_msg!(),
        dep!("geometry_msgs/Point", xyz_msg!()),
        dep!("geometry_msgs/Quaternion", quaternion_msg!())
    )
);
message!(
    PoseWithCovariance,
    "geometry_msgs/msg/PoseWithCovariance",
    "RIHS01_9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb",
    concat!(pose_with_covariance_msg!(), pose_deps!())
);
message!(
    PoseWithCovarianceStamped,
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e",
    concat!(
        "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n",
        header_deps!(),
        dep!(
            "geometry_msgs/PoseWithCovariance",
            pose_with_covariance_msg!()
        ),
        pose_deps!()
    )
);
message!(
    PoseStamped,
    "geometry_msgs/msg/PoseStamped",
    "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
    concat!(
        "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        header_deps!(),
        pose_deps!()
    )
);
message!(
    Vector3,
    "geometry_msgs/msg/Vector3",
    "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
    xyz_msg!()
);
message!(
    Transform,
    "geometry_msgs/msg/Transform",
    "RIHS01_beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc",
    concat!(
        transform_msg!(),
        dep!("geometry_msgs/Vector3", xyz_msg!()),
        dep!("geometry_msgs/Quaternion", quaternion_msg!())
    )
);
message!(
    TransformStamped,
    "geometry_msgs/msg/TransformStamped",
    "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
    concat!(transform_stamped_msg!(), header_deps!(), transform_deps!())
);
message!(
    TFMessage,
    "tf2_msgs/msg/TFMessage",
    "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    concat!(
        "geometry_msgs/TransformStamped[] transforms\n",
        dep!("geometry_msgs/TransformStamped", transform_stamped_msg!()),
        header_deps!(),
        transform_deps!()
    )
);
message!(
    RegionOfInterest,
    "sensor_msgs/msg/RegionOfInterest",
    "RIHS01_ad16bcba5f9131dcdba6fbded19f726f5440e3c513b4fb586dd3027eeed8abb1",
    roi_msg!()
);
message!(
    CameraInfo,
    "sensor_msgs/msg/CameraInfo",
    "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
    concat!(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n",
        "float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n",
        "uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n",
        header_deps!(),
        dep!("sensor_msgs/RegionOfInterest", roi_msg!())
    )
);
message!(
    Image,
    "sensor_msgs/msg/Image",
    "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
    concat!(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n",
        "uint8 is_bigendian\nuint32 step\nuint8[] data\n",
        header_deps!()
    )
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dds_names_follow_the_fastrtps_type_support() {
        assert_eq!(
            PoseWithCovarianceStamped::dds_type(),
            "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"
        );
        assert_eq!(TFMessage::dds_type(), "tf2_msgs::msg::dds_::TFMessage_");
        assert_eq!(Image::dds_type(), "sensor_msgs::msg::dds_::Image_");
    }

    #[test]
    fn time_from_ns_splits_and_saturates() {
        assert_eq!(
            Time::from_ns(1_700_000_000_123_456_789),
            Time {
                sec: 1_700_000_000,
                nanosec: 123_456_789
            }
        );
        assert_eq!(Time::from_ns(u64::MAX).sec, i32::MAX);
        assert_eq!(
            Time::from_ns(1_700_000_000_123_456_789).as_ns(),
            1_700_000_000_123_456_789
        );
    }

    #[test]
    fn quaternion_defaults_to_identity_like_ros() {
        assert_eq!(Quaternion::default().w, 1.0);
        assert_eq!(Pose::default().orientation, Quaternion::default());
    }
}
