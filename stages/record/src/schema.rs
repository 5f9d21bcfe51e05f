//! The JSON messages of a recording and their JSON schemas (the MCAP
//! `jsonschema` encoding, so Foxglove and other tools can show them).

use serde::{Deserialize, Serialize};

/// Ground truth of a recorded frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameTruth {
    /// Elevation, degrees.
    pub theta_deg: f64,
    /// Azimuth, degrees.
    pub phi_deg: f64,
    /// Camera distance to the object centre, metres.
    pub distance_m: f64,
    /// The camera's roll about its optical axis, degrees (absent in
    /// recordings made before it was recorded: 0).
    #[serde(default)]
    pub roll_deg: f64,
    /// camera_from_object, column-major 3x4 (rotation columns, translation
    /// in metres).
    pub camera_from_object: [f64; 12],
}

/// `/acch/frame`: what a replay needs besides the pixels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameInfo {
    /// Frame number.
    pub sequence: u64,
    /// CLOCK_MONOTONIC ns at capture (replay paces by the differences).
    pub capture_ns: u64,
    /// Pixels a row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// fx, fy, cx, cy, pixels.
    pub intrinsics: [f64; 4],
    /// Ground truth, when the source knew it.
    pub truth: Option<FrameTruth>,
    /// The arm's camera pose `world_from_camera` (column-major 3x4,
    /// OpenCV camera axes), when the arm reported one: a replay fuses over
    /// the same motion. Absent in recordings made before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arm_world_from_camera: Option<[f64; 12]>,
    /// The lens distortion of a calibrated camera: its model
    /// (`plumb_bob`, `rational_polynomial`) and k1 k2 p1 p2 k3 k4 k5 k6.
    /// Absent for an undistorted camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<(String, [f64; 8])>,
}

/// `/acch/response`: the pose stage's match value per database view, in
/// database view order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ResponseJson {
    /// Frame number.
    pub sequence: u64,
    /// Match values.
    pub values: Vec<f32>,
}

/// JSON schema of `acch.Frame`.
pub const FRAME_SCHEMA: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "acch.Frame",
  "description": "Metadata of a camera frame on /camera/image",
  "type": "object",
  "properties": {
    "sequence": {"type": "integer", "description": "frame number"},
    "capture_ns": {"type": "integer", "description": "CLOCK_MONOTONIC ns at capture"},
    "width": {"type": "integer"},
    "height": {"type": "integer"},
    "intrinsics": {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4,
                   "description": "fx, fy, cx, cy (pixels)"},
    "truth": {"type": ["object", "null"], "properties": {
      "theta_deg": {"type": "number"}, "phi_deg": {"type": "number"}, "distance_m": {"type": "number"},
      "camera_from_object": {"type": "array", "items": {"type": "number"}, "minItems": 12, "maxItems": 12,
                             "description": "column-major 3x4, OpenCV camera frame"}}},
    "arm_world_from_camera": {"type": "array", "items": {"type": "number"}, "minItems": 12, "maxItems": 12,
                              "description": "the arm's camera pose, column-major 3x4, OpenCV camera axes"},
    "distortion": {"type": "array", "prefixItems": [
                     {"type": "string", "enum": ["plumb_bob", "rational_polynomial"]},
                     {"type": "array", "items": {"type": "number"}, "minItems": 8, "maxItems": 8}],
                   "description": "lens distortion model and k1 k2 p1 p2 k3 k4 k5 k6"}
  },
  "required": ["sequence", "capture_ns", "width", "height", "intrinsics"]
}"#;

/// JSON schema of `acch.Response`.
pub const RESPONSE_SCHEMA: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "acch.Response",
  "description": "ACCH match value of every database view (database order)",
  "type": "object",
  "properties": {
    "sequence": {"type": "integer"},
    "values": {"type": "array", "items": {"type": "number"}}
  },
  "required": ["sequence", "values"]
}"#;

/// JSON schema of `acch.Result` (the JSON published on zenoh).
pub const RESULT_SCHEMA: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "acch.Result",
  "description": "Final result of one frame, as published on <prefix>/<object>/result",
  "type": "object",
  "properties": {
    "object": {"type": "string"},
    "sequence": {"type": "integer"},
    "accepted": {"type": "boolean"},
    "stamp": {"type": "object", "properties": {
      "clock": {"type": "string"}, "captured_ns": {"type": "integer"}, "published_ns": {"type": "integer"}}},
    "found": {"type": "boolean"},
    "roi": {"type": ["array", "null"], "items": {"type": "integer"}},
    "estimate_deg": {"type": ["array", "null"], "items": {"type": "number"}, "description": "theta, phi"},
    "rating": {"type": "string", "description": "accepted, rejected, unrated, skipped or failed"},
    "confidence": {"type": ["number", "null"]},
    "threshold": {"type": ["number", "null"]},
    "seed": {"type": ["object", "null"]},
    "fused": {"type": ["object", "null"]},
    "truth": {"type": ["object", "null"]},
    "trail": {"type": "array", "description": "[stage, [received_ns, published_ns]]"}
  },
  "required": ["object", "sequence", "accepted", "stamp", "found", "trail"]
}"#;
