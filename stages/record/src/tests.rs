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
