//! Just enough protobuf for the two foxglove messages we write: a wire
//! encoder, a decoder for `foxglove.RawImage` (replay), and the
//! `FileDescriptorSet`s MCAP readers need to decode them, built here from the
//! foxglove `.proto` files' fields so no protoc step or generated code is
//! needed.

use crate::RecordError;

/// Protobuf wire types.
const VARINT: u32 = 0;
const FIXED64: u32 = 1;
const LEN: u32 = 2;
const FIXED32: u32 = 5;

fn key(buf: &mut Vec<u8>, field: u32, wire: u32) {
    varint(buf, u64::from((field << 3) | wire));
}

fn varint(buf: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        buf.push((v as u8) | 0x80);
        v >>= 7;
    }
    buf.push(v as u8);
}

fn put_varint(buf: &mut Vec<u8>, field: u32, v: u64) {
    key(buf, field, VARINT);
    varint(buf, v);
}

fn put_bytes(buf: &mut Vec<u8>, field: u32, b: &[u8]) {
    key(buf, field, LEN);
    varint(buf, b.len() as u64);
    buf.extend_from_slice(b);
}

fn put_fixed32(buf: &mut Vec<u8>, field: u32, v: u32) {
    key(buf, field, FIXED32);
    buf.extend_from_slice(&v.to_le_bytes());
}

fn put_double(buf: &mut Vec<u8>, field: u32, v: f64) {
    key(buf, field, FIXED64);
    buf.extend_from_slice(&v.to_le_bytes());
}

/// A nested message: encoded into a scratch buffer, then length-prefixed.
fn put_message(buf: &mut Vec<u8>, field: u32, f: impl FnOnce(&mut Vec<u8>)) {
    let mut inner = Vec::new();
    f(&mut inner);
    put_bytes(buf, field, &inner);
}

fn timestamp(buf: &mut Vec<u8>, field: u32, ns: u64) {
    put_message(buf, field, |b| {
        put_varint(b, 1, ns / 1_000_000_000);
        put_varint(b, 2, ns % 1_000_000_000);
    });
}

/// A `foxglove.RawImage` header: everything but the pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct RawImageHeader {
    /// Time stamp, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// Frame of reference (the camera's optical frame).
    pub frame_id: String,
    /// Pixels a row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `rgb8`, `mono8`, ...
    pub encoding: String,
    /// Bytes a row.
    pub step: u32,
}

/// Encodes a `foxglove.RawImage` into `buf` (cleared first, so a caller can
/// reuse one buffer and not allocate per frame once it has grown).
pub fn encode_raw_image(buf: &mut Vec<u8>, h: &RawImageHeader, data: &[u8]) {
    buf.clear();
    timestamp(buf, 1, h.stamp_ns);
    put_fixed32(buf, 2, h.width);
    put_fixed32(buf, 3, h.height);
    put_bytes(buf, 4, h.encoding.as_bytes());
    put_fixed32(buf, 5, h.step);
    put_bytes(buf, 6, data);
    put_bytes(buf, 7, h.frame_id.as_bytes());
}

/// Encodes a `foxglove.PoseInFrame` (translation, quaternion x, y, z, w).
pub fn encode_pose_in_frame(
    buf: &mut Vec<u8>,
    stamp_ns: u64,
    frame_id: &str,
    position: [f64; 3],
    orientation_xyzw: [f64; 4],
) {
    buf.clear();
    timestamp(buf, 1, stamp_ns);
    put_bytes(buf, 2, frame_id.as_bytes());
    put_message(buf, 3, |b| {
        put_message(b, 1, |v| {
            for (i, x) in position.iter().enumerate() {
                put_double(v, i as u32 + 1, *x);
            }
        });
        put_message(b, 2, |q| {
            for (i, x) in orientation_xyzw.iter().enumerate() {
                put_double(q, i as u32 + 1, *x);
            }
        });
    });
}

/// Reads protobuf fields off a byte slice.
struct Fields<'a> {
    data: &'a [u8],
    pos: usize,
}

/// One field's value.
enum Value<'a> {
    Varint(u64),
    Fixed64,
    Len(&'a [u8]),
    Fixed32(u32),
}

// Fixed64 fields (doubles) are skipped: RawImage has none.

impl<'a> Fields<'a> {
    fn varint(&mut self) -> Result<u64, String> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = *self.data.get(self.pos).ok_or("truncated varint")?;
            self.pos += 1;
            v |= u64::from(b & 0x7f) << shift;
            if b < 0x80 {
                return Ok(v);
            }
        }
        Err("varint longer than 10 bytes".into())
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|e| *e <= self.data.len())
            .ok_or_else(|| format!("field of {n} bytes runs past the message end"))?;
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn next_field(&mut self) -> Option<Result<(u32, Value<'a>), String>> {
        if self.pos >= self.data.len() {
            return None;
        }
        Some((|| {
            let k = self.varint()?;
            let field = (k >> 3) as u32;
            let v = match (k & 7) as u32 {
                VARINT => Value::Varint(self.varint()?),
                FIXED64 => {
                    self.take(8)?;
                    Value::Fixed64
                }
                LEN => {
                    let n = usize::try_from(self.varint()?).map_err(|_| "length overflow")?;
                    Value::Len(self.take(n)?)
                }
                FIXED32 => Value::Fixed32(u32::from_le_bytes(
                    self.take(4)?.try_into().expect("4 bytes"),
                )),
                w => return Err(format!("unsupported wire type {w}")),
            };
            Ok((field, v))
        })())
    }
}

/// Decodes a `foxglove.RawImage`: its header and a borrow of its pixels.
pub fn decode_raw_image(data: &[u8]) -> Result<(RawImageHeader, &[u8]), RecordError> {
    let bad = |what: String| RecordError::Decode {
        what: "foxglove.RawImage".into(),
        reason: what,
    };
    let mut h = RawImageHeader {
        stamp_ns: 0,
        frame_id: String::new(),
        width: 0,
        height: 0,
        encoding: String::new(),
        step: 0,
    };
    let mut pixels: &[u8] = &[];
    let mut f = Fields { data, pos: 0 };
    let text = |b: &[u8]| String::from_utf8(b.to_vec()).map_err(|e| bad(e.to_string()));
    while let Some(field) = f.next_field() {
        match field.map_err(bad)? {
            (1, Value::Len(ts)) => {
                let mut t = Fields { data: ts, pos: 0 };
                let (mut s, mut n) = (0u64, 0u64);
                while let Some(x) = t.next_field() {
                    match x.map_err(bad)? {
                        (1, Value::Varint(v)) => s = v,
                        (2, Value::Varint(v)) => n = v,
                        _ => {}
                    }
                }
                h.stamp_ns = s.saturating_mul(1_000_000_000).saturating_add(n);
            }
            (2, Value::Fixed32(v)) => h.width = v,
            (3, Value::Fixed32(v)) => h.height = v,
            (4, Value::Len(b)) => h.encoding = text(b)?,
            (5, Value::Fixed32(v)) => h.step = v,
            (6, Value::Len(b)) => pixels = b,
            (7, Value::Len(b)) => h.frame_id = text(b)?,
            // Unknown fields are skipped, as protobuf readers do.
            _ => {}
        }
    }
    Ok((h, pixels))
}

/// Field types of descriptor.proto's `FieldDescriptorProto.Type`.
#[derive(Clone, Copy)]
enum Ty {
    Double = 1,
    Int64 = 3,
    Int32 = 5,
    Fixed32 = 7,
    String = 9,
    Message = 11,
    Bytes = 12,
}

/// One field of a message in a `.proto` file.
struct Field(&'static str, u32, Ty, &'static str);

/// `FieldDescriptorProto`: name 1, number 3, label 4 (1 = optional), type 5,
/// type_name 6, json_name 10.
fn field_descriptor(buf: &mut Vec<u8>, f: &Field) {
    put_message(buf, 2, |b| {
        put_bytes(b, 1, f.0.as_bytes());
        put_varint(b, 3, u64::from(f.1));
        put_varint(b, 4, 1);
        put_varint(b, 5, f.2 as u64);
        if !f.3.is_empty() {
            put_bytes(b, 6, f.3.as_bytes());
        }
    });
}

/// `FileDescriptorProto` with one message: name 1, package 2, dependency 3,
/// message_type 4 (`DescriptorProto`: name 1, field 2), syntax 12.
fn file_descriptor(
    set: &mut Vec<u8>,
    file: &str,
    package: &str,
    deps: &[&str],
    message: &str,
    fields: &[Field],
) {
    put_message(set, 1, |b| {
        put_bytes(b, 1, file.as_bytes());
        put_bytes(b, 2, package.as_bytes());
        for d in deps {
            put_bytes(b, 3, d.as_bytes());
        }
        put_message(b, 4, |m| {
            put_bytes(m, 1, message.as_bytes());
            for f in fields {
                field_descriptor(m, f);
            }
        });
        put_bytes(b, 12, b"proto3");
    });
}

const TIMESTAMP_PROTO: &str = "google/protobuf/timestamp.proto";

fn timestamp_file(set: &mut Vec<u8>) {
    file_descriptor(
        set,
        TIMESTAMP_PROTO,
        "google.protobuf",
        &[],
        "Timestamp",
        &[
            Field("seconds", 1, Ty::Int64, ""),
            Field("nanos", 2, Ty::Int32, ""),
        ],
    );
}

/// The `FileDescriptorSet` of `foxglove.RawImage` (schema data of its MCAP
/// schema record, encoding `protobuf`), dependencies first.
pub fn raw_image_descriptor_set() -> Vec<u8> {
    let mut set = Vec::new();
    timestamp_file(&mut set);
    file_descriptor(
        &mut set,
        "foxglove/RawImage.proto",
        "foxglove",
        &[TIMESTAMP_PROTO],
        "RawImage",
        &[
            Field("timestamp", 1, Ty::Message, ".google.protobuf.Timestamp"),
            Field("frame_id", 7, Ty::String, ""),
            Field("width", 2, Ty::Fixed32, ""),
            Field("height", 3, Ty::Fixed32, ""),
            Field("encoding", 4, Ty::String, ""),
            Field("step", 5, Ty::Fixed32, ""),
            Field("data", 6, Ty::Bytes, ""),
        ],
    );
    set
}

/// The `FileDescriptorSet` of `foxglove.PoseInFrame`, dependencies first.
pub fn pose_in_frame_descriptor_set() -> Vec<u8> {
    let mut set = Vec::new();
    timestamp_file(&mut set);
    let xyz = |w: bool| {
        let mut v = vec![
            Field("x", 1, Ty::Double, ""),
            Field("y", 2, Ty::Double, ""),
            Field("z", 3, Ty::Double, ""),
        ];
        if w {
            v.push(Field("w", 4, Ty::Double, ""));
        }
        v
    };
    file_descriptor(
        &mut set,
        "foxglove/Vector3.proto",
        "foxglove",
        &[],
        "Vector3",
        &xyz(false),
    );
    file_descriptor(
        &mut set,
        "foxglove/Quaternion.proto",
        "foxglove",
        &[],
        "Quaternion",
        &xyz(true),
    );
    file_descriptor(
        &mut set,
        "foxglove/Pose.proto",
        "foxglove",
        &["foxglove/Quaternion.proto", "foxglove/Vector3.proto"],
        "Pose",
        &[
            Field("position", 1, Ty::Message, ".foxglove.Vector3"),
            Field("orientation", 2, Ty::Message, ".foxglove.Quaternion"),
        ],
    );
    file_descriptor(
        &mut set,
        "foxglove/PoseInFrame.proto",
        "foxglove",
        &["foxglove/Pose.proto", TIMESTAMP_PROTO],
        "PoseInFrame",
        &[
            Field("timestamp", 1, Ty::Message, ".google.protobuf.Timestamp"),
            Field("frame_id", 2, Ty::String, ""),
            Field("pose", 3, Ty::Message, ".foxglove.Pose"),
        ],
    );
    set
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost_reflect::{DescriptorPool, DynamicMessage, Value as V};

    fn header() -> RawImageHeader {
        RawImageHeader {
            stamp_ns: 1_700_000_000_123_456_789,
            frame_id: "camera_optical".into(),
            width: 3,
            height: 2,
            encoding: "rgb8".into(),
            step: 9,
        }
    }

    #[test]
    fn raw_image_round_trips_through_our_decoder() {
        let pixels: Vec<u8> = (0..18).collect();
        let mut buf = Vec::new();
        encode_raw_image(&mut buf, &header(), &pixels);
        let (h, p) = decode_raw_image(&buf).unwrap();
        assert_eq!(h, header());
        assert_eq!(p, &pixels[..]);
    }

    #[test]
    fn truncated_raw_image_is_an_error_not_a_panic() {
        let mut buf = Vec::new();
        encode_raw_image(&mut buf, &header(), &[7; 18]);
        for cut in [1, 5, buf.len() - 3] {
            let e = decode_raw_image(&buf[..cut]);
            assert!(e.is_err(), "cut at {cut} decoded");
        }
    }

    /// An independent protobuf implementation (prost-reflect, what rerun
    /// itself uses for MCAP) decodes our messages with our descriptors.
    #[test]
    fn descriptors_decode_our_messages_in_prost_reflect() {
        let pool = DescriptorPool::decode(raw_image_descriptor_set().as_slice()).unwrap();
        let d = pool.get_message_by_name("foxglove.RawImage").unwrap();
        let mut buf = Vec::new();
        encode_raw_image(&mut buf, &header(), &[1, 2, 3]);
        let m = DynamicMessage::decode(d, buf.as_slice()).unwrap();
        assert_eq!(m.get_field_by_name("width").unwrap().as_u32(), Some(3));
        assert_eq!(m.get_field_by_name("step").unwrap().as_u32(), Some(9));
        assert_eq!(
            m.get_field_by_name("encoding").unwrap().as_str(),
            Some("rgb8")
        );
        assert_eq!(
            m.get_field_by_name("data").unwrap().as_bytes().unwrap(),
            &[1u8, 2, 3][..]
        );
        let ts = m.get_field_by_name("timestamp").unwrap();
        let ts = ts.as_message().unwrap();
        assert_eq!(
            ts.get_field_by_name("nanos").unwrap().as_i32(),
            Some(123_456_789)
        );

        let pool = DescriptorPool::decode(pose_in_frame_descriptor_set().as_slice()).unwrap();
        let d = pool.get_message_by_name("foxglove.PoseInFrame").unwrap();
        encode_pose_in_frame(
            &mut buf,
            5,
            "camera_optical",
            [1.0, -2.0, 3.5],
            [0.0, 0.0, 0.6, 0.8],
        );
        let m = DynamicMessage::decode(d, buf.as_slice()).unwrap();
        let pose = m.get_field_by_name("pose").unwrap();
        let q = pose
            .as_message()
            .unwrap()
            .get_field_by_name("orientation")
            .unwrap();
        let w = q.as_message().unwrap().get_field_by_name("w").unwrap();
        assert_eq!(*w, V::F64(0.8));
        let p = pose
            .as_message()
            .unwrap()
            .get_field_by_name("position")
            .unwrap();
        let y = p.as_message().unwrap().get_field_by_name("y").unwrap();
        assert_eq!(*y, V::F64(-2.0));
    }
}
