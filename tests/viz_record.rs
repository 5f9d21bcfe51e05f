//! The observers of `acch run`: `--record FILE.mcap` writes a recording the
//! reference Python `mcap` reader reads channel by channel with CRCs
//! validated, `--rerun save:FILE.rrd` writes a file `rerun rrd verify`
//! accepts, and `--source mcap:FILE` replays a recording through the
//! pipeline to the very same poses, bit for bit.

mod common;

use acch_record::{TOPIC_RESULT, read_json};
use common::{acch_run, free_port, summary};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// The results of a recording by sequence.
fn results(path: &Path) -> Vec<Value> {
    let mut v = read_json(path, TOPIC_RESULT).unwrap();
    v.sort_by_key(|r| r["sequence"].as_u64().unwrap());
    v
}

/// What a run concluded about a frame, floats as their bits (the JSON
/// carries shortest round-trip decimals; parsing them back is exact).
fn bits(v: &Value) -> Value {
    match v {
        Value::Number(n) if n.is_f64() => Value::from(n.as_f64().unwrap().to_bits()),
        Value::Array(a) => Value::Array(a.iter().map(bits).collect()),
        other => other.clone(),
    }
}

/// The pose part of a result, floats as bits.
fn pose(r: &Value) -> Value {
    let seed = &r["seed"];
    serde_json::json!({
        "sequence": r["sequence"],
        "accepted": r["accepted"],
        "found": r["found"],
        "roi": r["roi"],
        "estimate_deg": bits(&r["estimate_deg"]),
        "confidence": bits(&r["confidence"]),
        "translation": bits(&seed["translation"]),
        "rotation_xyzw": bits(&seed["rotation_xyzw"]),
        "covariance": bits(&seed["covariance"]),
    })
}

#[test]
fn recordings_open_in_the_reference_tools_and_replay_to_the_same_poses() {
    let frames = 40u64;
    let n = frames.to_string();
    let dir = tempfile::tempdir().unwrap();
    let (mcap_a, rrd, json_a) = (
        dir.path().join("a.mcap"),
        dir.path().join("a.rrd"),
        dir.path().join("a.json"),
    );
    let out = acch_run(
        dir.path(),
        &[
            "--frames",
            &n,
            "--fps",
            "30",
            "--record",
            mcap_a.to_str().unwrap(),
            "--rerun",
            &format!("save:{}", rrd.display()),
            "--json",
            json_a.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "acch run with observers failed");
    let a = summary(&json_a);
    assert_eq!(a["results"], frames, "{a}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("acch record summary"),
        "no recorder summary"
    );
    assert!(stderr.contains("acch viz summary"), "no viewer summary");

    // The reference MCAP reader, CRCs validated, every channel, every
    // protobuf message decoded against its schema, and every message path
    // of the Foxglove layout resolved in this recording.
    let check = Command::new("python3")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/mcap_check.py"))
        .arg(&mcap_a)
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/docs/foxglove-layout.json"
        ))
        .output()
        .unwrap();
    assert!(
        check.status.success(),
        "python mcap reader failed: {}",
        String::from_utf8_lossy(&check.stderr)
    );
    let c: Value = serde_json::from_slice(&check.stdout).unwrap();
    eprintln!("mcap_check: {c}");
    let counts = &c["counts"];
    for topic in [
        "/camera/image",
        "/camera/calibration",
        "/acch/frame",
        "/acch/result",
        "/acch/overlay",
        "/acch/latency",
        "/tf",
    ] {
        assert_eq!(counts[topic], frames, "{topic}: {c}");
        assert_eq!(c["statistics"][topic], frames, "{topic}: {c}");
    }
    assert_eq!(counts["/acch/mask/overlay"], a["found"], "{c}");
    for (topic, n) in c["decoded"].as_object().unwrap() {
        assert_eq!(n, &counts[topic.as_str()], "{topic} not all decoded: {c}");
    }
    assert_eq!(c["decoded"]["/acch/overlay"], frames, "{c}");
    // Detection and ROI boxes (line loops), axes and the mask (line lists).
    let overlay = &c["overlay"];
    assert!(
        overlay["/acch/overlay points type 2"].as_u64() > Some(0),
        "{c}"
    );
    assert!(
        overlay["/acch/overlay points type 4"].as_u64() > Some(0),
        "{c}"
    );
    assert!(
        overlay["/acch/mask/overlay points type 4"].as_u64() > Some(0),
        "{c}"
    );
    assert_eq!(
        c["child_frames"],
        serde_json::json!(["camera_optical", "fused", "seed", "truth"]),
        "{c}"
    );
    assert_eq!(c["calibration"]["K"][0], c["calibration"]["P"][0], "{c}");
    let layout = &c["layout"];
    assert_eq!(layout["unresolved"], serde_json::json!([]), "{c}");
    assert!(layout["paths"].as_u64() >= Some(20), "{c}");
    assert_eq!(counts["/acch/seed"], a["seeds"], "{c}");
    assert_eq!(counts["/acch/mask"], a["found"], "{c}");
    assert_eq!(counts["/acch/response"], a["estimated"], "{c}");
    assert_eq!(c["schemas"]["/camera/image"][0], "foxglove.RawImage", "{c}");
    assert_eq!(c["schemas"]["/acch/seed"][0], "foxglove.PoseInFrame", "{c}");
    assert_eq!(
        c["schemas"]["/acch/overlay"][0], "foxglove.ImageAnnotations",
        "{c}"
    );
    assert_eq!(c["schemas"]["/tf"][0], "foxglove.FrameTransforms", "{c}");
    assert_eq!(
        c["schemas"]["/camera/calibration"][0], "foxglove.CameraCalibration",
        "{c}"
    );
    assert_eq!(c["schemas"]["/acch/result"][1], "jsonschema", "{c}");
    assert!(c["data_section_crc"].as_u64().unwrap() != 0, "{c}");
    let total: u64 = counts
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(c["linear_messages"], total, "{c}");

    // rerun's own verifier (PyPI rerun-sdk 0.36.3).
    let verify = Command::new("rerun")
        .args(["rrd", "verify"])
        .arg(&rrd)
        .env("RERUN_ANALYTICS", "0")
        .output()
        .expect("the rerun CLI (pip install rerun-sdk==0.36.3; .ci/run installs it)");
    assert!(
        verify.status.success(),
        "rerun rrd verify failed: {}{}",
        String::from_utf8_lossy(&verify.stdout),
        String::from_utf8_lossy(&verify.stderr)
    );

    // Replay free-running, recording again: every pose is the same.
    let (mcap_b, json_b) = (dir.path().join("b.mcap"), dir.path().join("b.json"));
    let out = acch_run(
        dir.path(),
        &[
            "--source",
            &format!("mcap:{}", mcap_a.display()),
            "--replay",
            "free",
            "--frames",
            &n,
            "--record",
            mcap_b.to_str().unwrap(),
            "--json",
            json_b.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "replay failed");
    let b = summary(&json_b);
    assert_eq!(b["results"], frames, "{b}");
    let (ra, rb) = (results(&mcap_a), results(&mcap_b));
    assert_eq!(ra.len(), frames as usize);
    assert_eq!(rb.len(), frames as usize);
    let accepted = ra.iter().filter(|r| r["accepted"] == true).count();
    assert!(
        accepted as u64 >= frames / 2,
        "too few accepted: {accepted}"
    );
    for (x, y) in ra.iter().zip(&rb) {
        assert_eq!(
            pose(x),
            pose(y),
            "frame {} differs on replay",
            x["sequence"]
        );
        // Ground truth came through the recording too.
        assert_eq!(x["truth"], y["truth"]);
    }

    // Replay at the recorded pace: the same poses, at the recorded rate.
    let json_c = dir.path().join("c.json");
    let mcap_c = dir.path().join("c.mcap");
    let out = acch_run(
        dir.path(),
        &[
            "--source",
            &format!("mcap:{}", mcap_a.display()),
            "--replay",
            "recorded",
            "--frames",
            &n,
            "--record",
            mcap_c.to_str().unwrap(),
            "--json",
            json_c.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "paced replay failed");
    let c = summary(&json_c);
    // Paced by the recording's stamps: never faster than its 30 fps (a
    // replay as fast as it can runs at hundreds); slower only within a
    // tenth of the pace, as a loaded 2-core machine may be.
    let fps = c["fps_achieved"].as_f64().unwrap();
    assert!(
        (3.0..=36.0).contains(&fps),
        "recorded pace 30 fps, got {fps}: {c}"
    );
    let rc = results(&mcap_c);
    // A short or empty replay must not pass for an identical one.
    assert_eq!(rc.len(), ra.len(), "the paced replay lost frames");
    assert_eq!(c["results"], frames, "{c}");
    for (x, y) in ra.iter().zip(&rc) {
        assert_eq!(
            pose(x),
            pose(y),
            "frame {} differs on paced replay",
            x["sequence"]
        );
    }

    // A truncated recording is refused before the run starts, by name.
    let bytes = std::fs::read(&mcap_a).unwrap();
    let cut = dir.path().join("truncated.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = acch_run(
        dir.path(),
        &[
            "--source",
            &format!("mcap:{}", cut.display()),
            "--frames",
            "5",
        ],
    );
    assert!(!out.status.success(), "a truncated recording replayed");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("truncated.mcap"),
        "error does not name the file"
    );
    assert!(!err.contains("panicked"), "a panic on a bad recording");
}

/// Frames of another size than the stream's are skipped, named and counted;
/// the run goes on.
#[test]
fn a_folder_frame_of_another_size_is_skipped_not_fatal() {
    let dir = tempfile::tempdir().unwrap();
    let imgs = dir.path().join("frames");
    std::fs::create_dir(&imgs).unwrap();
    for (name, w, h) in [("a.png", 160, 120), ("b.png", 100, 50), ("c.png", 160, 120)] {
        image::RgbImage::from_pixel(w, h, image::Rgb([90, 120, 30]))
            .save(imgs.join(name))
            .unwrap();
    }
    let json = dir.path().join("run.json");
    let out = acch_run(
        dir.path(),
        &[
            "--source",
            &format!("folder:{}", imgs.display()),
            "--frames",
            "4",
            "--fps",
            "30",
            "--json",
            json.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "run with an odd-sized frame failed");
    assert_eq!(summary(&json)["results"], 4);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("b.png (100x50, the stream is 160x120)"),
        "{err}"
    );
}

/// A viewer that never takes the data (nothing listens at the URL): rerun
/// blocks, the viz process drops what does not fit its queue and counts
/// it, the pipeline delivers every frame and the run ends on time.
#[test]
fn an_absent_viewer_drops_and_counts_but_never_holds_the_pipeline() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("run.json");
    let url = format!("connect:rerun+http://127.0.0.1:{}/proxy", free_port());
    let out = acch_run(
        dir.path(),
        &[
            "--frames",
            "200",
            "--fps",
            "30",
            "--rerun",
            &url,
            "--json",
            json.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "run with an absent viewer failed");
    let s = summary(&json);
    assert_eq!(s["results"], 200);
    // On time: a viewer that held the pipeline would slow it to its
    // connection attempts; a tenth of the pace is the bound (the run's own
    // measure, not a clock that includes waiting for another test's run).
    let fps = s["fps_achieved"].as_f64().unwrap();
    assert!(fps >= 3.0, "30 fps wanted, {fps} achieved: {s}");
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find_map(|l| l.split_once("acch viz summary: ").map(|x| x.1))
        .expect("viz summary");
    let v: Value = serde_json::from_str(line).unwrap();
    let n = |k: &str| v[k].as_u64().unwrap();
    // Every frame is accounted for: logged, dropped for a full queue, or
    // missed by iceoryx2.
    assert_eq!(
        n("frames") + n("frames_queue_full") + n("frames_missed"),
        200,
        "{v}"
    );
}
