use super::*;
use std::io::Cursor;

fn info(sequence: u64, w: u32, h: u32) -> FrameInfo {
    FrameInfo {
        sequence,
        capture_ns: 1_000_000 * (sequence + 1) + 7,
        width: w,
        height: h,
        intrinsics: [500.1, 500.2, (w as f64 - 1.0) / 2.0, 0.1 + 0.2],
        truth: sequence.is_multiple_of(2).then(|| FrameTruth {
            theta_deg: 45.0 + 1.0 / 3.0,
            phi_deg: 359.999_999_999_9,
            distance_m: 5.0,
            roll_deg: -12.5 + 1.0 / 9.0,
            camera_from_object: std::array::from_fn(|i| (i as f64).sqrt() - 1.0 / 7.0),
        }),
        arm_world_from_camera: (sequence % 3 != 1)
            .then(|| std::array::from_fn(|i| (i as f64).cbrt() + 1.0 / 3.0)),
        distortion: (sequence % 4 == 3).then(|| {
            (
                "rational_polynomial".to_owned(),
                std::array::from_fn(|i| (i as f64 - 3.5) / 97.0),
            )
        }),
    }
}

fn pixels(seq: u64, w: u32, h: u32) -> Vec<u8> {
    (0..w as usize * h as usize * 3)
        .map(|i| (i as u64 * 31 + seq) as u8)
        .collect()
}

fn record(path: &Path, n: u64) {
    let mut r = Recorder::create(path, 1_700_000_000_000_000_000).unwrap();
    r.set_view_thetas(&[45.0, 45.0, 60.0]);
    for s in 0..n {
        let (w, h) = (6, 4);
        r.frame(&info(s, w, h), &pixels(s, w, h)).unwrap();
        r.mask(s, info(s, w, h).capture_ns, w, h, &[s as u8 & 1; 24])
            .unwrap();
        r.response(s, 0, &[0.5, 0.25, f32::MIN_POSITIVE]).unwrap();
        r.result(
            s,
            0,
            &serde_json::json!({"sequence": s, "estimate_deg": [1.0 / 3.0, 2.0]}),
        )
        .unwrap();
        r.seed(s, 0, [0.0, 0.1, 5.0], [0.0, 0.0, 0.0, 1.0]).unwrap();
        r.overlay(
            s,
            0,
            &Overlay {
                window: Some([1.0, 1.0, 3.0, 2.0]),
                seed_axes: Some([[3.0, 2.0], [4.0, 2.0], [3.0, 3.0], [3.0, 2.0]]),
                caption: "θ 45.3° φ 2.0°".into(),
                ..Default::default()
            },
        )
        .unwrap();
        r.transforms(s, 0, &[("seed", [0.0, 0.1, 5.0], [0.0, 0.0, 0.0, 1.0])])
            .unwrap();
        r.latency(
            s,
            0,
            &LatencyJson {
                sequence: s,
                since_capture_ms: BTreeMap::from([("pose".into(), 2.5)]),
                stage_ms: BTreeMap::from([("pose".into(), 1.0)]),
            },
        )
        .unwrap();
    }
    r.metadata(
        "acch.record",
        BTreeMap::from([("frames".into(), n.to_string())]),
    )
    .unwrap();
    r.finish().unwrap();
}

#[test]
fn frames_replay_bit_exactly_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    record(&path, 5);
    let frames: Vec<ReplayFrame> = ReplayReader::open(&path)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(frames.len(), 5);
    for (s, f) in frames.iter().enumerate() {
        let s = s as u64;
        // Every f64 (intrinsics, truth) comes back with the same bits.
        assert_eq!(f.info, info(s, 6, 4));
        assert_eq!(f.pixels(), pixels(s, 6, 4).as_slice());
    }
    assert_eq!(
        scan(&path).unwrap(),
        RecordingSummary {
            frames: 5,
            width: 6,
            height: 4
        }
    );
    assert_eq!(first_frame_size(&path).unwrap(), (6, 4));
    let results = read_json(&path, TOPIC_RESULT).unwrap();
    assert_eq!(results.len(), 5);
    assert_eq!(results[3]["estimate_deg"][0].as_f64(), Some(1.0 / 3.0));
    let responses = read_json(&path, TOPIC_RESPONSE).unwrap();
    let r: ResponseJson = serde_json::from_value(responses[0].clone()).unwrap();
    assert_eq!(r.values, vec![0.5, 0.25, f32::MIN_POSITIVE]);
    // Views 0 and 2 start the θ slices 45° and 60°.
    assert_eq!(r.slice_edges, vec![1, 0, 1]);
    let latency = read_json(&path, TOPIC_LATENCY).unwrap();
    assert_eq!(latency.len(), 5);
    assert_eq!(latency[4]["since_capture_ms"]["pose"].as_f64(), Some(2.5));
}

/// A response of another length than the views the recorder was told of
/// carries no slice edges rather than wrong ones.
#[test]
fn slice_edges_need_one_theta_per_view() {
    let mut r = Recorder::new(Cursor::new(Vec::new()), Path::new("mem.mcap"), 0).unwrap();
    r.set_view_thetas(&[45.0, 60.0]);
    r.response(0, 0, &[0.5, 0.5, 0.5]).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&r.scratch).unwrap();
    assert!(json.get("slice_edges").is_none(), "{json}");
    r.response(1, 0, &[0.5, 0.5]).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&r.scratch).unwrap();
    assert_eq!(json["slice_edges"], serde_json::json!([1, 1]));
}

#[test]
fn truncated_recording_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    record(&path, 3);
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.mcap");
    for len in [0, 7, 100, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let e = scan(&cut).expect_err("a truncated file scanned clean");
        assert!(e.to_string().contains("cut.mcap"), "{e}");
    }
}

#[test]
fn corrupt_chunk_fails_its_crc() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    record(&path, 3);
    let mut bytes = std::fs::read(&path).unwrap();
    // Flip a pixel byte: the record structure stays valid, the CRC does not.
    let needle = pixels(1, 6, 4);
    let at = bytes
        .windows(needle.len())
        .position(|w| w == needle.as_slice())
        .unwrap();
    bytes[at + 5] ^= 0xff;
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let e = scan(&bad).expect_err("a corrupt file scanned clean");
    assert!(e.to_string().contains("bad.mcap"), "{e}");
}

#[test]
fn a_missing_file_and_a_wrong_frame_size_are_errors() {
    let e = scan(Path::new("/nonexistent/x.mcap")).unwrap_err();
    assert!(e.to_string().contains("/nonexistent/x.mcap"), "{e}");
    let mut r = Recorder::new(Cursor::new(Vec::new()), Path::new("mem.mcap"), 0).unwrap();
    let e = r.frame(&info(0, 6, 4), &[0; 10]).unwrap_err();
    assert!(e.to_string().contains("frame 0"), "{e}");
}

#[test]
fn an_empty_recording_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.mcap");
    Recorder::create(&path, 0).unwrap().finish().unwrap();
    let e = scan(&path).unwrap_err();
    assert!(e.to_string().contains("no frames"), "{e}");
}

/// What the Foxglove viewers' JSON-schema reader takes: one type a field
/// (no `["number", "null"]`), objects with `properties` or
/// `additionalProperties`, arrays with typed scalar or object `items`.
/// A schema it rejects makes the whole channel unplottable there.
fn foxglove_readable(path: &str, s: &serde_json::Value) -> Result<(), String> {
    let ty = s["type"]
        .as_str()
        .ok_or_else(|| format!("{path}: type {} is not one name", s["type"]))?;
    match ty {
        "object" => {
            let props = s["properties"].as_object();
            if props.is_none() && !s["additionalProperties"].is_object() {
                return Err(format!(
                    "{path}: an object with neither properties nor additionalProperties"
                ));
            }
            for (k, v) in props.into_iter().flatten() {
                foxglove_readable(&format!("{path}.{k}"), v)?;
            }
            if s["additionalProperties"].is_object() {
                foxglove_readable(&format!("{path}.*"), &s["additionalProperties"])?;
            }
            Ok(())
        }
        "array" => match s["items"]["type"].as_str() {
            Some("number" | "integer" | "string" | "boolean") => Ok(()),
            Some("object") => foxglove_readable(&format!("{path}[]"), &s["items"]),
            _ => Err(format!(
                "{path}: array items {} are not one scalar or object type",
                s["items"]
            )),
        },
        "number" | "integer" | "string" | "boolean" => Ok(()),
        other => Err(format!("{path}: type {other}")),
    }
}

#[test]
fn the_json_schemas_are_readable_by_foxglove() {
    for (name, text) in [
        ("acch.Frame", schema::FRAME_SCHEMA),
        ("acch.Response", schema::RESPONSE_SCHEMA),
        ("acch.Result", schema::RESULT_SCHEMA),
        ("acch.Latency", schema::LATENCY_SCHEMA),
    ] {
        let v: serde_json::Value = serde_json::from_str(text).unwrap();
        foxglove_readable(name, &v).unwrap();
    }
    // The check itself refuses what broke the channels before.
    let nullable =
        serde_json::json!({"type": "object", "properties": {"c": {"type": ["number", "null"]}}});
    assert!(foxglove_readable("x", &nullable).is_err());
    let untyped = serde_json::json!({"type": "object", "properties": {"t": {"type": "array"}}});
    assert!(foxglove_readable("x", &untyped).is_err());
}
