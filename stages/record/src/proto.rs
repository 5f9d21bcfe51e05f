//! Just enough protobuf for the foxglove messages we write (RawImage,
//! PoseInFrame, ImageAnnotations, FrameTransforms, CameraCalibration): a
//! wire encoder, a decoder for `foxglove.RawImage` (replay), and the
//! `FileDescriptorSet`s MCAP readers need to decode them, built here from the
//! foxglove `.proto` files' fields (every field, numbers as in the foxglove
//! schemas) so no protoc step or generated code is needed.

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
    Enum = 14,
}

/// One field of a message in a `.proto` file: name, number, type, type
/// name (messages and enums), and whether it is `repeated`.
struct Field(&'static str, u32, Ty, &'static str, bool);

/// A singular field.
const fn one(name: &'static str, number: u32, ty: Ty, type_name: &'static str) -> Field {
    Field(name, number, ty, type_name, false)
}

/// A `repeated` field.
const fn many(name: &'static str, number: u32, ty: Ty, type_name: &'static str) -> Field {
    Field(name, number, ty, type_name, true)
}

/// `FieldDescriptorProto`: name 1, number 3, label 4 (1 = optional, 3 =
/// repeated), type 5, type_name 6.
fn field_descriptor(buf: &mut Vec<u8>, f: &Field) {
    put_message(buf, 2, |b| {
        put_bytes(b, 1, f.0.as_bytes());
        put_varint(b, 3, u64::from(f.1));
        put_varint(b, 4, if f.4 { 3 } else { 1 });
        put_varint(b, 5, f.2 as u64);
        if !f.3.is_empty() {
            put_bytes(b, 6, f.3.as_bytes());
        }
    });
}

/// An enum nested in a message: its name and values.
struct Enum(&'static str, &'static [(&'static str, i32)]);

/// `FileDescriptorProto` with one message: name 1, package 2, dependency 3,
/// message_type 4 (`DescriptorProto`: name 1, field 2, enum_type 4
/// (`EnumDescriptorProto`: name 1, value 2 (name 1, number 2))), syntax 12.
fn file_descriptor_with(
    set: &mut Vec<u8>,
    (file, package): (&str, &str),
    deps: &[&str],
    message: &str,
    fields: &[Field],
    enums: &[Enum],
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
            for Enum(name, values) in enums {
                put_message(m, 4, |e| {
                    put_bytes(e, 1, name.as_bytes());
                    for (v, n) in values.iter() {
                        put_message(e, 2, |ev| {
                            put_bytes(ev, 1, v.as_bytes());
                            // int32: negative numbers would take 10 bytes; ours are not.
                            put_varint(ev, 2, *n as u64);
                        });
                    }
                });
            }
        });
        put_bytes(b, 12, b"proto3");
    });
}

fn file_descriptor(
    set: &mut Vec<u8>,
    file: &str,
    package: &str,
    deps: &[&str],
    message: &str,
    fields: &[Field],
) {
    file_descriptor_with(set, (file, package), deps, message, fields, &[]);
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
            one("seconds", 1, Ty::Int64, ""),
            one("nanos", 2, Ty::Int32, ""),
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
            one("timestamp", 1, Ty::Message, ".google.protobuf.Timestamp"),
            one("frame_id", 7, Ty::String, ""),
            one("width", 2, Ty::Fixed32, ""),
            one("height", 3, Ty::Fixed32, ""),
            one("encoding", 4, Ty::String, ""),
            one("step", 5, Ty::Fixed32, ""),
            one("data", 6, Ty::Bytes, ""),
        ],
    );
    set
}

/// `foxglove.Vector3` and `foxglove.Quaternion`.
fn vector3_quaternion_files(set: &mut Vec<u8>) {
    let xyz = |w: bool| {
        let mut v = vec![
            one("x", 1, Ty::Double, ""),
            one("y", 2, Ty::Double, ""),
            one("z", 3, Ty::Double, ""),
        ];
        if w {
            v.push(one("w", 4, Ty::Double, ""));
        }
        v
    };
    file_descriptor(
        set,
        "foxglove/Vector3.proto",
        "foxglove",
        &[],
        "Vector3",
        &xyz(false),
    );
    file_descriptor(
        set,
        "foxglove/Quaternion.proto",
        "foxglove",
        &[],
        "Quaternion",
        &xyz(true),
    );
}

/// The `FileDescriptorSet` of `foxglove.PoseInFrame`, dependencies first.
pub fn pose_in_frame_descriptor_set() -> Vec<u8> {
    let mut set = Vec::new();
    timestamp_file(&mut set);
    vector3_quaternion_files(&mut set);
    file_descriptor(
        &mut set,
        "foxglove/Pose.proto",
        "foxglove",
        &["foxglove/Quaternion.proto", "foxglove/Vector3.proto"],
        "Pose",
        &[
            one("position", 1, Ty::Message, ".foxglove.Vector3"),
            one("orientation", 2, Ty::Message, ".foxglove.Quaternion"),
        ],
    );
    file_descriptor(
        &mut set,
        "foxglove/PoseInFrame.proto",
        "foxglove",
        &["foxglove/Pose.proto", TIMESTAMP_PROTO],
        "PoseInFrame",
        &[
            one("timestamp", 1, Ty::Message, ".google.protobuf.Timestamp"),
            one("frame_id", 2, Ty::String, ""),
            one("pose", 3, Ty::Message, ".foxglove.Pose"),
        ],
    );
    set
}

const COLOR: &str = ".foxglove.Color";
const POINT2: &str = ".foxglove.Point2";
const KEY_VALUE: &str = ".foxglove.KeyValuePair";
const TIMESTAMP: &str = ".google.protobuf.Timestamp";

/// `foxglove.Color`, `foxglove.Point2` and `foxglove.KeyValuePair`.
fn annotation_base_files(set: &mut Vec<u8>) {
    file_descriptor(
        set,
        "foxglove/Color.proto",
        "foxglove",
        &[],
        "Color",
        &[
            one("r", 1, Ty::Double, ""),
            one("g", 2, Ty::Double, ""),
            one("b", 3, Ty::Double, ""),
            one("a", 4, Ty::Double, ""),
        ],
    );
    file_descriptor(
        set,
        "foxglove/Point2.proto",
        "foxglove",
        &[],
        "Point2",
        &[one("x", 1, Ty::Double, ""), one("y", 2, Ty::Double, "")],
    );
    file_descriptor(
        set,
        "foxglove/KeyValuePair.proto",
        "foxglove",
        &[],
        "KeyValuePair",
        &[
            one("key", 1, Ty::String, ""),
            one("value", 2, Ty::String, ""),
        ],
    );
}

/// The `FileDescriptorSet` of `foxglove.ImageAnnotations` (all its fields,
/// as in the foxglove schemas), dependencies first.
pub fn image_annotations_descriptor_set() -> Vec<u8> {
    let mut set = Vec::new();
    timestamp_file(&mut set);
    annotation_base_files(&mut set);
    let deps = [
        "foxglove/Color.proto",
        "foxglove/KeyValuePair.proto",
        "foxglove/Point2.proto",
        TIMESTAMP_PROTO,
    ];
    file_descriptor(
        &mut set,
        "foxglove/CircleAnnotation.proto",
        "foxglove",
        &deps,
        "CircleAnnotation",
        &[
            one("timestamp", 1, Ty::Message, TIMESTAMP),
            one("position", 2, Ty::Message, POINT2),
            one("diameter", 3, Ty::Double, ""),
            one("thickness", 4, Ty::Double, ""),
            one("fill_color", 5, Ty::Message, COLOR),
            one("outline_color", 6, Ty::Message, COLOR),
            many("metadata", 7, Ty::Message, KEY_VALUE),
        ],
    );
    file_descriptor_with(
        &mut set,
        ("foxglove/PointsAnnotation.proto", "foxglove"),
        &deps,
        "PointsAnnotation",
        &[
            one("timestamp", 1, Ty::Message, TIMESTAMP),
            one("type", 2, Ty::Enum, ".foxglove.PointsAnnotation.Type"),
            many("points", 3, Ty::Message, POINT2),
            one("outline_color", 4, Ty::Message, COLOR),
            many("outline_colors", 5, Ty::Message, COLOR),
            one("fill_color", 6, Ty::Message, COLOR),
            one("thickness", 7, Ty::Double, ""),
            many("metadata", 8, Ty::Message, KEY_VALUE),
        ],
        &[Enum(
            "Type",
            &[
                ("UNKNOWN", 0),
                ("POINTS", 1),
                ("LINE_LOOP", 2),
                ("LINE_STRIP", 3),
                ("LINE_LIST", 4),
            ],
        )],
    );
    file_descriptor(
        &mut set,
        "foxglove/TextAnnotation.proto",
        "foxglove",
        &deps,
        "TextAnnotation",
        &[
            one("timestamp", 1, Ty::Message, TIMESTAMP),
            one("position", 2, Ty::Message, POINT2),
            one("text", 3, Ty::String, ""),
            one("font_size", 4, Ty::Double, ""),
            one("text_color", 5, Ty::Message, COLOR),
            one("background_color", 6, Ty::Message, COLOR),
            many("metadata", 7, Ty::Message, KEY_VALUE),
        ],
    );
    file_descriptor(
        &mut set,
        "foxglove/ImageAnnotations.proto",
        "foxglove",
        &[
            "foxglove/CircleAnnotation.proto",
            "foxglove/KeyValuePair.proto",
            "foxglove/PointsAnnotation.proto",
            "foxglove/TextAnnotation.proto",
            TIMESTAMP_PROTO,
        ],
        "ImageAnnotations",
        &[
            many("circles", 1, Ty::Message, ".foxglove.CircleAnnotation"),
            many("points", 2, Ty::Message, ".foxglove.PointsAnnotation"),
            many("texts", 3, Ty::Message, ".foxglove.TextAnnotation"),
            many("metadata", 4, Ty::Message, KEY_VALUE),
            one("timestamp", 5, Ty::Message, TIMESTAMP),
        ],
    );
    set
}

/// The `FileDescriptorSet` of `foxglove.FrameTransforms`, dependencies first.
pub fn frame_transforms_descriptor_set() -> Vec<u8> {
    let mut set = Vec::new();
    timestamp_file(&mut set);
    vector3_quaternion_files(&mut set);
    file_descriptor(
        &mut set,
        "foxglove/FrameTransform.proto",
        "foxglove",
        &[
            "foxglove/Quaternion.proto",
            "foxglove/Vector3.proto",
            TIMESTAMP_PROTO,
        ],
        "FrameTransform",
        &[
            one("timestamp", 1, Ty::Message, TIMESTAMP),
            one("parent_frame_id", 2, Ty::String, ""),
            one("child_frame_id", 3, Ty::String, ""),
            one("translation", 4, Ty::Message, ".foxglove.Vector3"),
            one("rotation", 5, Ty::Message, ".foxglove.Quaternion"),
        ],
    );
    file_descriptor(
        &mut set,
        "foxglove/FrameTransforms.proto",
        "foxglove",
        &["foxglove/FrameTransform.proto"],
        "FrameTransforms",
        &[many(
            "transforms",
            1,
            Ty::Message,
            ".foxglove.FrameTransform",
        )],
    );
    set
}

/// The `FileDescriptorSet` of `foxglove.CameraCalibration`.
pub fn camera_calibration_descriptor_set() -> Vec<u8> {
    let mut set = Vec::new();
    timestamp_file(&mut set);
    file_descriptor(
        &mut set,
        "foxglove/CameraCalibration.proto",
        "foxglove",
        &[TIMESTAMP_PROTO],
        "CameraCalibration",
        &[
            one("timestamp", 1, Ty::Message, TIMESTAMP),
            one("frame_id", 9, Ty::String, ""),
            one("width", 2, Ty::Fixed32, ""),
            one("height", 3, Ty::Fixed32, ""),
            one("distortion_model", 4, Ty::String, ""),
            many("D", 5, Ty::Double, ""),
            many("K", 6, Ty::Double, ""),
            many("R", 7, Ty::Double, ""),
            many("P", 8, Ty::Double, ""),
        ],
    );
    set
}

/// An RGBA colour, components 0..1.
pub type Rgba = [f64; 4];

/// How a `foxglove.PointsAnnotation` joins its points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointsKind {
    /// Separate points.
    Points = 1,
    /// A closed polygon.
    LineLoop = 2,
    /// An open polyline.
    LineStrip = 3,
    /// Independent segments, two points each.
    LineList = 4,
}

/// A `foxglove.PointsAnnotation`.
#[derive(Clone, Debug, PartialEq)]
pub struct PointsAnnotation {
    /// How the points join.
    pub kind: PointsKind,
    /// Image coordinates, pixels (0, 0 = the top-left pixel's top-left corner).
    pub points: Vec<[f64; 2]>,
    /// Line colour.
    pub color: Rgba,
    /// Per-point (per-segment for a line list) colours; empty = `color`.
    pub colors: Vec<Rgba>,
    /// Fill of a closed polygon, when filled.
    pub fill: Option<Rgba>,
    /// Line width, pixels.
    pub thickness: f64,
}

/// A `foxglove.TextAnnotation`.
#[derive(Clone, Debug, PartialEq)]
pub struct TextAnnotation {
    /// Bottom-left corner of the text, pixels.
    pub position: [f64; 2],
    /// The text.
    pub text: String,
    /// Font size, pixels.
    pub font_size: f64,
    /// Text colour.
    pub color: Rgba,
    /// Background colour.
    pub background: Rgba,
}

/// A `foxglove.Point2`: two doubles, 18 bytes, written without a scratch
/// buffer (a mask overlay has hundreds).
fn put_point2(buf: &mut Vec<u8>, field: u32, [x, y]: [f64; 2]) {
    key(buf, field, LEN);
    varint(buf, 18);
    put_double(buf, 1, x);
    put_double(buf, 2, y);
}

/// A `foxglove.Color`: four doubles, 36 bytes.
fn put_color(buf: &mut Vec<u8>, field: u32, c: Rgba) {
    key(buf, field, LEN);
    varint(buf, 36);
    for (i, v) in c.iter().enumerate() {
        put_double(buf, i as u32 + 1, *v);
    }
}

/// Encodes a `foxglove.ImageAnnotations` into `buf` (cleared first).
pub fn encode_image_annotations(
    buf: &mut Vec<u8>,
    stamp_ns: u64,
    points: &[PointsAnnotation],
    texts: &[TextAnnotation],
) {
    buf.clear();
    for p in points {
        put_message(buf, 2, |b| {
            timestamp(b, 1, stamp_ns);
            put_varint(b, 2, p.kind as u64);
            for pt in &p.points {
                put_point2(b, 3, *pt);
            }
            put_color(b, 4, p.color);
            for c in &p.colors {
                put_color(b, 5, *c);
            }
            if let Some(f) = p.fill {
                put_color(b, 6, f);
            }
            put_double(b, 7, p.thickness);
        });
    }
    for t in texts {
        put_message(buf, 3, |b| {
            timestamp(b, 1, stamp_ns);
            put_point2(b, 2, t.position);
            put_bytes(b, 3, t.text.as_bytes());
            put_double(b, 4, t.font_size);
            put_color(b, 5, t.color);
            put_color(b, 6, t.background);
        });
    }
    timestamp(buf, 5, stamp_ns);
}

/// A `foxglove.FrameTransform`: `child` in `parent`.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTransform {
    /// Parent frame.
    pub parent: String,
    /// Child frame.
    pub child: String,
    /// Translation of the child's origin in the parent, metres.
    pub translation: [f64; 3],
    /// Rotation parent_from_child, x, y, z, w.
    pub rotation_xyzw: [f64; 4],
}

/// Encodes a `foxglove.FrameTransforms` into `buf` (cleared first).
pub fn encode_frame_transforms(buf: &mut Vec<u8>, stamp_ns: u64, transforms: &[FrameTransform]) {
    buf.clear();
    for t in transforms {
        put_message(buf, 1, |b| {
            timestamp(b, 1, stamp_ns);
            put_bytes(b, 2, t.parent.as_bytes());
            put_bytes(b, 3, t.child.as_bytes());
            put_message(b, 4, |v| {
                for (i, x) in t.translation.iter().enumerate() {
                    put_double(v, i as u32 + 1, *x);
                }
            });
            put_message(b, 5, |q| {
                for (i, x) in t.rotation_xyzw.iter().enumerate() {
                    put_double(q, i as u32 + 1, *x);
                }
            });
        });
    }
}

/// A packed `repeated double`.
fn put_doubles(buf: &mut Vec<u8>, field: u32, values: &[f64]) {
    key(buf, field, LEN);
    varint(buf, 8 * values.len() as u64);
    for v in values {
        buf.extend_from_slice(&v.to_le_bytes());
    }
}

/// What a `foxglove.CameraCalibration` says.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// Time stamp, ns since the Unix epoch.
    pub stamp_ns: u64,
    /// The camera's optical frame.
    pub frame_id: String,
    /// Pixels a row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// fx, fy, cx, cy, pixels.
    pub intrinsics: [f64; 4],
    /// Distortion model (`plumb_bob`, `rational_polynomial`) and its
    /// coefficients; none for an undistorted camera.
    pub distortion: Option<(String, Vec<f64>)>,
}

/// Encodes a `foxglove.CameraCalibration` into `buf` (cleared first): K
/// from the intrinsics, R the identity, P = [K | 0].
pub fn encode_camera_calibration(buf: &mut Vec<u8>, c: &Calibration) {
    buf.clear();
    let [fx, fy, cx, cy] = c.intrinsics;
    timestamp(buf, 1, c.stamp_ns);
    put_fixed32(buf, 2, c.width);
    put_fixed32(buf, 3, c.height);
    let (model, d) = match &c.distortion {
        Some((m, d)) => (m.as_str(), d.as_slice()),
        None => ("plumb_bob", &[0.0; 5][..]),
    };
    put_bytes(buf, 4, model.as_bytes());
    put_doubles(buf, 5, d);
    put_doubles(buf, 6, &[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]);
    put_doubles(buf, 7, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    put_doubles(
        buf,
        8,
        &[fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    );
    put_bytes(buf, 9, c.frame_id.as_bytes());
}

/// The runs of object pixels of a mask (`width` bytes a row, non-zero =
/// object) as segments for a `LINE_LIST` one pixel thick: a translucent
/// fill of the mask that costs a few points a row instead of an image.
pub fn mask_runs(mask: &[u8], width: u32, out: &mut Vec<[f64; 2]>) {
    out.clear();
    if width == 0 {
        return;
    }
    for (y, row) in mask.chunks_exact(width as usize).enumerate() {
        let yc = y as f64 + 0.5;
        let mut x = 0;
        while x < row.len() {
            if row[x] == 0 {
                x += 1;
                continue;
            }
            let start = x;
            while x < row.len() && row[x] != 0 {
                x += 1;
            }
            out.push([start as f64, yc]);
            out.push([x as f64, yc]);
        }
    }
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

    #[test]
    fn mask_runs_cover_each_row_of_object_pixels() {
        let mask = [
            0, 1, 1, 0, 1, /* row 2 */ 0, 0, 0, 0, 0, /* row 3 */ 1, 1, 1, 1, 1,
        ];
        let mut runs = Vec::new();
        mask_runs(&mask, 5, &mut runs);
        assert_eq!(
            runs,
            vec![
                [1.0, 0.5],
                [3.0, 0.5],
                [4.0, 0.5],
                [5.0, 0.5],
                [0.0, 2.5],
                [5.0, 2.5]
            ]
        );
    }

    /// The annotation, transform and calibration messages decode in
    /// prost-reflect with our descriptors, field by field.
    #[test]
    fn overlay_transform_and_calibration_messages_decode_in_prost_reflect() {
        let pool = DescriptorPool::decode(image_annotations_descriptor_set().as_slice()).unwrap();
        let d = pool
            .get_message_by_name("foxglove.ImageAnnotations")
            .unwrap();
        let mut buf = Vec::new();
        let points = [PointsAnnotation {
            kind: PointsKind::LineList,
            points: vec![[1.0, 2.0], [3.5, 4.0]],
            color: [1.0, 0.0, 0.0, 1.0],
            colors: vec![[0.0, 1.0, 0.0, 0.5]],
            fill: None,
            thickness: 2.0,
        }];
        let texts = [TextAnnotation {
            position: [10.0, 20.0],
            text: "seed".into(),
            font_size: 14.0,
            color: [1.0; 4],
            background: [0.0, 0.0, 0.0, 0.5],
        }];
        encode_image_annotations(&mut buf, 7_000_000_001, &points, &texts);
        let m = DynamicMessage::decode(d, buf.as_slice()).unwrap();
        let p = m.get_field_by_name("points").unwrap();
        let p = p.as_list().unwrap()[0].as_message().unwrap().clone();
        assert_eq!(*p.get_field_by_name("type").unwrap(), V::EnumNumber(4));
        let pts = p.get_field_by_name("points").unwrap();
        let second = pts.as_list().unwrap()[1].as_message().unwrap().clone();
        assert_eq!(*second.get_field_by_name("x").unwrap(), V::F64(3.5));
        let c = p.get_field_by_name("outline_colors").unwrap();
        let c = c.as_list().unwrap()[0].as_message().unwrap().clone();
        assert_eq!(*c.get_field_by_name("a").unwrap(), V::F64(0.5));
        assert_eq!(*p.get_field_by_name("thickness").unwrap(), V::F64(2.0));
        let t = m.get_field_by_name("texts").unwrap();
        let t = t.as_list().unwrap()[0].as_message().unwrap().clone();
        assert_eq!(t.get_field_by_name("text").unwrap().as_str(), Some("seed"));
        let ts = m.get_field_by_name("timestamp").unwrap();
        let ts = ts.as_message().unwrap();
        assert_eq!(ts.get_field_by_name("seconds").unwrap().as_i64(), Some(7));

        let pool = DescriptorPool::decode(frame_transforms_descriptor_set().as_slice()).unwrap();
        let d = pool
            .get_message_by_name("foxglove.FrameTransforms")
            .unwrap();
        encode_frame_transforms(
            &mut buf,
            5,
            &[FrameTransform {
                parent: "camera_optical".into(),
                child: "seed".into(),
                translation: [0.0, 0.1, 1.0],
                rotation_xyzw: [0.0, 0.0, 0.6, 0.8],
            }],
        );
        let m = DynamicMessage::decode(d, buf.as_slice()).unwrap();
        let t = m.get_field_by_name("transforms").unwrap();
        let t = t.as_list().unwrap()[0].as_message().unwrap().clone();
        assert_eq!(
            t.get_field_by_name("child_frame_id").unwrap().as_str(),
            Some("seed")
        );
        let r = t.get_field_by_name("rotation").unwrap();
        let w = r.as_message().unwrap().get_field_by_name("w").unwrap();
        assert_eq!(*w, V::F64(0.8));

        let pool = DescriptorPool::decode(camera_calibration_descriptor_set().as_slice()).unwrap();
        let d = pool
            .get_message_by_name("foxglove.CameraCalibration")
            .unwrap();
        encode_camera_calibration(
            &mut buf,
            &Calibration {
                stamp_ns: 1,
                frame_id: "camera_optical".into(),
                width: 640,
                height: 480,
                intrinsics: [500.0, 501.0, 320.0, 240.0],
                distortion: None,
            },
        );
        let m = DynamicMessage::decode(d, buf.as_slice()).unwrap();
        let k: Vec<f64> = m
            .get_field_by_name("K")
            .unwrap()
            .as_list()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(k, vec![500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0]);
        let p = m.get_field_by_name("P").unwrap();
        assert_eq!(p.as_list().unwrap().len(), 12);
        assert_eq!(m.get_field_by_name("height").unwrap().as_u32(), Some(480));
        assert_eq!(
            m.get_field_by_name("distortion_model").unwrap().as_str(),
            Some("plumb_bob")
        );
    }
}
