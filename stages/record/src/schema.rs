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
    /// 1 at the first view of each θ slice, else 0 (one per value): a plot
    /// over the view index draws it as the slice separators. Absent in
    /// recordings made before it was recorded.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub slice_edges: Vec<u8>,
}

/// `/acch/latency`: where a frame's time went.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LatencyJson {
    /// Frame number.
    pub sequence: u64,
    /// Per stage, ms from capture to that stage publishing the frame:
    /// cumulative, so plotted together the lines stack (the gap below a
    /// stage's line is its hop and processing); the last is end to end.
    pub since_capture_ms: std::collections::BTreeMap<String, f64>,
    /// Per stage, ms from receiving the frame to publishing it.
    pub stage_ms: std::collections::BTreeMap<String, f64>,
}

/// JSON schema of `acch.Frame`. The schemas here use only what the
/// Foxglove viewers' JSON-schema reader takes (one type a field, typed
/// array items): a field that may be null is declared with its non-null
/// type and says so, and a field of mixed types (`distortion`) is left out
/// of `properties` (JSON Schema allows fields it does not list).
pub const FRAME_SCHEMA: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "acch.Frame",
  "description": "Metadata of a camera frame on /camera/image. Also: distortion, [model, [k1 k2 p1 p2 k3 k4 k5 k6]], when the camera is distorted",
  "type": "object",
  "properties": {
    "sequence": {"type": "integer", "description": "frame number"},
    "capture_ns": {"type": "integer", "description": "CLOCK_MONOTONIC ns at capture"},
    "width": {"type": "integer"},
    "height": {"type": "integer"},
    "intrinsics": {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4,
                   "description": "fx, fy, cx, cy (pixels)"},
    "truth": {"type": "object", "description": "null when the source does not know it", "properties": {
      "theta_deg": {"type": "number"}, "phi_deg": {"type": "number"}, "distance_m": {"type": "number"},
      "roll_deg": {"type": "number"},
      "camera_from_object": {"type": "array", "items": {"type": "number"}, "minItems": 12, "maxItems": 12,
                             "description": "column-major 3x4, OpenCV camera frame"}}},
    "arm_world_from_camera": {"type": "array", "items": {"type": "number"}, "minItems": 12, "maxItems": 12,
                              "description": "the arm's camera pose, column-major 3x4, OpenCV camera axes"}
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
    "values": {"type": "array", "items": {"type": "number"}},
    "slice_edges": {"type": "array", "items": {"type": "integer"},
                    "description": "1 at the first view of each theta slice, else 0"}
  },
  "required": ["sequence", "values"]
}"#;

/// JSON schema of `acch.Latency`.
pub const LATENCY_SCHEMA: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "acch.Latency",
  "description": "Where a frame's time went, ms",
  "type": "object",
  "properties": {
    "sequence": {"type": "integer"},
    "since_capture_ms": {"type": "object", "additionalProperties": {"type": "number"},
                         "description": "per stage: capture -> that stage published (cumulative)"},
    "stage_ms": {"type": "object", "additionalProperties": {"type": "number"},
                 "description": "per stage: received -> published"}
  },
  "required": ["sequence", "since_capture_ms", "stage_ms"]
}"#;

/// JSON schema of `acch.Result` (the JSON published on zenoh). Fields that
/// may be null are declared with their non-null type; `trail` (pairs of a
/// stage name and two times) and `fitted_pose` (a translation and a
/// quaternion) have no single item type, which Foxglove needs, and are
/// described but not listed.
pub const RESULT_SCHEMA: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "acch.Result",
  "description": "Final result of one frame, as published on <prefix>/<object>/result. Also: trail, [[stage, [received_ns, published_ns]]] per stage; fitted_pose, the pose the shape fitted, camera from object, [[tx, ty, tz] metres, [x, y, z, w]], null unless verified",
  "type": "object",
  "properties": {
    "object": {"type": "string"},
    "sequence": {"type": "integer"},
    "accepted": {"type": "boolean"},
    "rating": {"type": "string", "description": "accepted, rejected, unrated, skipped or failed"},
    "confidence": {"type": "number", "description": "null when not rated"},
    "threshold": {"type": "number", "description": "null when not rated"},
    "rival": {"type": "number", "description": "best match beyond 20 degrees of the estimate's azimuth or 10 degrees of its elevation over the best; above max_rival rejected as ambiguous; null when not rated"},
    "max_rival": {"type": "number", "description": "null when not rated"},
    "phi_plateau_deg": {"type": "number", "description": "span in azimuth of the views about the estimate, in its elevation, that match within 2 % of the best, degrees; at or above phi_plateau_limit_deg rejected (the truth may lie farther than the 20 degree tolerance); null when not rated"},
    "phi_plateau_limit_deg": {"type": "number", "description": "null when not rated"},
    "map_rival": {"type": "number", "description": "how much more of the region's coloured area a view 20-60 degrees from the estimate in azimuth holds in place on its colour map than the estimate's view; above max_map_rival rejected as misplaced; null when not rated, when the database has no colour maps or the region could not be placed"},
    "max_map_rival": {"type": "number", "description": "null when not rated"},
    "misplaced": {"type": "boolean", "description": "rejected because a view beyond the tolerance holds the region in place better (map_rival above max_map_rival, or not measurable), whatever the confidence; null when not rated"},
    "detection_margin": {"type": "number", "description": "recognition's score for the window over its threshold, from 0.7 (a window from 0.7x the threshold is found, and faint); null when not rated or the region was not found by recognition"},
    "match_value": {"type": "number", "description": "the best view's match value; null when not rated"},
    "faint": {"type": "boolean", "description": "rejected as faint: detection_margin below 1 (under recognition's threshold), or below 1.3 with match_value below 0.75, whatever the confidence; null when not rated"},
    "min_accepted_detection_margin": {"type": "number", "description": "a detection margin below this is never accepted; null when not rated"},
    "min_clear_detection_margin": {"type": "number", "description": "below this detection margin and min_clear_match_value an estimate is faint; null when not rated"},
    "min_clear_match_value": {"type": "number", "description": "null when not rated"},
    "verified": {"type": "integer", "description": "how the object's shape took part: 1 it chose the pose (its bars decide), 2 it fitted the colours' view (the colour rules decide, with its contour on the region's edge), 0 none; null when not rated"},
    "region_edge": {"type": "number", "description": "share of the fitted contour on the region's edge; null unless verified"},
    "min_region_edge": {"type": "number", "description": "null unless verified"},
    "overlap": {"type": "number", "description": "the fitted silhouette against the region, intersection over union; null unless verified"},
    "min_overlap": {"type": "number", "description": "null unless verified"},
    "shape_margin": {"type": "number", "description": "the fit's score over its rival's (the best candidate beyond 1.75 failure tolerances and not below min_theta_deg); null unless verified, or without such a candidate"},
    "min_shape_margin": {"type": "number", "description": "null unless verified"},
    "in_frame": {"type": "number", "description": "share of the fitted contour in the frame; null unless verified"},
    "min_in_frame": {"type": "number", "description": "null unless verified with a region recognition found"},
    "min_theta_deg": {"type": "number", "description": "the lowest elevation accepted for a pose the shape chose (the database's lowest view less 5 degrees), against estimate_deg[0]; null unless the shape chose it"},
    "max_distance_m": {"type": "number", "description": "the farthest a pose the shape chose may place the object (1.6 times the training distance, or the arm's), against the length of fitted_pose's translation; null unless the shape chose it"},
    "stamp": {"type": "object", "properties": {
      "clock": {"type": "string"}, "captured_ns": {"type": "integer"}, "published_ns": {"type": "integer"},
      "wall_ns": {"type": "integer"}}},
    "found": {"type": "boolean"},
    "roi": {"type": "array", "items": {"type": "integer"}, "description": "x, y, width, height; null when not segmented"},
    "estimate_deg": {"type": "array", "items": {"type": "number"}, "description": "theta, phi; null when not estimated"},
    "roll_deg": {"type": "number", "description": "null when not estimated"},
    "seed": {"type": "object", "description": "null when not accepted", "properties": {
      "object": {"type": "string"}, "sequence": {"type": "integer"},
      "stamp": {"type": "object", "properties": {
        "clock": {"type": "string"}, "captured_ns": {"type": "integer"}, "published_ns": {"type": "integer"},
        "wall_ns": {"type": "integer"}}},
      "frame_id": {"type": "string"}, "child_frame_id": {"type": "string"},
      "translation": {"type": "array", "items": {"type": "number"}}, "translation_unit": {"type": "string"},
      "rotation_xyzw": {"type": "array", "items": {"type": "number"}},
      "covariance": {"type": "array", "items": {"type": "number"}}, "confidence": {"type": "number"}}},
    "fused": {"type": "object", "description": "null until the filter holds a pose", "properties": {
      "view_deg": {"type": "array", "items": {"type": "number"}},
      "view_covariance_deg2": {"type": "array", "items": {"type": "number"}},
      "translation": {"type": "array", "items": {"type": "number"}}, "translation_unit": {"type": "string"},
      "rotation_xyzw": {"type": "array", "items": {"type": "number"}},
      "rotation_covariance": {"type": "array", "items": {"type": "number"}},
      "translation_covariance": {"type": "array", "items": {"type": "number"}},
      "outcome": {"type": "string"}, "fused": {"type": "integer"}, "since_update": {"type": "integer"}}},
    "truth": {"type": "object", "description": "null when the source does not know it", "properties": {
      "theta_deg": {"type": "number"}, "phi_deg": {"type": "number"}, "distance": {"type": "number"},
      "roll_deg": {"type": "number"},
      "translation": {"type": "array", "items": {"type": "number"}}, "translation_unit": {"type": "string"},
      "rotation_xyzw": {"type": "array", "items": {"type": "number"}}}},
    "arm": {"type": "object", "description": "null when the arm reported no pose", "properties": {
      "translation": {"type": "array", "items": {"type": "number"}}, "translation_unit": {"type": "string"},
      "rotation_xyzw": {"type": "array", "items": {"type": "number"}}}},
    "imaging": {"type": "object", "description": "the frame's noise and JPEG blocking and the object's sharpness as recognition measured them, and the database set they chose (sharp or smoothed); null unless the run chooses (smoothing auto)", "properties": {
      "noise_sigma": {"type": "number"}, "blockiness": {"type": "number"},
      "object_sharpness": {"type": "number", "description": "over the object's window; null when not measured"},
      "set": {"type": "string"},
      "smoothed_for": {"type": "string", "description": "why smoothed: camera (noise or JPEG blocking), blur (the object; the frame quantised as it is, not smoothed again) or not_found (by the sharp databases, or found by them only under the threshold and by the smoothed ones clearly, or blurred); null when sharp"}}}
  },
  "required": ["object", "sequence", "accepted", "stamp", "found", "trail"]
}"#;
