//! ROS 2 without ROS, checked by readers with no code of ours:
//! tests/ros2/check_ros2.py (eclipse-zenoh for the wire, rosbags for CDR,
//! RIHS01 hashes and rosbag2, rmw_zenoh's key, attachment and liveliness
//! formats re-implemented from its source) receives what `acch run --ros2`
//! publishes and reads the bag `--record-format ros2` writes; and
//! tests/ros2/publish_arm.py, an rmw_zenoh-style publisher, feeds the arm's
//! camera pose that seeding fuses over.

mod common;

use common::{Guard, free_port, free_ports};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::sync::Mutex;

/// One pipeline at a time on 2 cores.
static SERIAL: Mutex<()> = Mutex::new(());

const PWCS: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";
const PWCS_DDS: &str = "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_";
/// REP-2011 hashes as rosbags computes them (the checker recomputes them).
const PWCS_HASH: &str = "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";
const CAMERA_INFO_HASH: &str =
    "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275";
const IMAGE_HASH: &str = "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47";
const TF_HASH: &str = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087";

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/ros2")
        .join(name)
}

fn python_has(modules: &str) -> bool {
    Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .status()
        .is_ok_and(|s| s.success())
}

fn require_python() {
    assert!(
        python_has("zenoh, rosbags"),
        "python3 with eclipse-zenoh==1.10.2 and rosbags==0.11.9 is required \
         (scripts/test installs them into its virtual environment)"
    );
}

/// The independent checker, connected to the pipeline's endpoint.
fn checker(port: u16, args: &[&str], out: &Path) -> Child {
    Command::new("python3")
        .arg(script("check_ros2.py"))
        .arg("--connect")
        .arg(format!("tcp/127.0.0.1:{port}"))
        .args(["--timeout", "60"])
        .args(args)
        .arg("--out")
        .arg(out)
        .spawn()
        .unwrap()
}

fn acch_run(config: &Path, args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_acch"))
        .arg("run")
        .arg("--config")
        .arg(config)
        .args(["--stall-timeout", "20"])
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "acch run {}:\n{err}", args.join(" "));
    out
}

/// The counts the recorder reports at exit (`acch record summary: {..}`).
fn record_summary(run: &Output) -> Value {
    let err = String::from_utf8_lossy(&run.stderr);
    let line = err
        .lines()
        .find_map(|l| l.split_once("acch record summary: ").map(|(_, json)| json))
        .unwrap_or_else(|| panic!("no record summary in:\n{err}"));
    serde_json::from_str(line).unwrap()
}

fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn results(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The checker's verdict, with its errors in the message.
fn checked(mut child: Child, out: &Path) -> Value {
    let status = child.wait().unwrap();
    let report = read_json(out);
    assert!(
        status.success() && report["ok"] == true,
        "the independent checker failed: {:#}",
        report["errors"]
    );
    report
}

/// The stamp of a ROS message, ns since the epoch.
fn stamp_ns(msg: &Value) -> u64 {
    let s = &msg["header"]["stamp"];
    s["sec"].as_u64().unwrap() * 1_000_000_000 + s["nanosec"].as_u64().unwrap()
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The parsed liveliness tokens of the checker's report by kind.
fn tokens<'a>(report: &'a Value, kind: &str) -> Vec<&'a Value> {
    report["tokens"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["kind"] == kind)
        .collect()
}

#[test]
fn seeds_camera_info_and_tf_reach_rmw_zenoh_readers_and_the_bag_holds_the_same() {
    require_python();
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let config = dir.path().join("pipeline.toml");
    std::fs::write(
        &config,
        // Every other frame on acch/image, from the seeding process's
        // reader of the frame stream.
        format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{port}\"]\n[ros2]\nimage_every = 2\n"),
    )
    .unwrap();
    let (report_path, bag) = (dir.path().join("report.json"), dir.path().join("run"));
    let topics = [
        ("/acch/fruitbox/seed", PWCS),
        ("/acch/fruitbox/fused", PWCS),
        ("/acch/camera_info", "sensor_msgs/msg/CameraInfo"),
        ("/tf", "tf2_msgs/msg/TFMessage"),
        ("/acch/image", "sensor_msgs/msg/Image"),
    ];
    let mut args = vec!["--min-samples", "30", "--bag", bag.to_str().unwrap()];
    let specs: Vec<String> = topics.iter().map(|(t, ty)| format!("{t}:{ty}")).collect();
    for s in &specs {
        args.extend(["--expect-topic", s]);
    }
    let check = checker(port, &args, &report_path);
    let jsonl = dir.path().join("results.jsonl");
    let run = acch_run(
        &config,
        &[
            "--ros2",
            "--frames",
            "120",
            "--record",
            dir.path().join("run.mcap").to_str().unwrap(),
            "--record-format",
            "ros2",
            "--results",
            jsonl.to_str().unwrap(),
        ],
    );
    let report = checked(check, &report_path);

    // Every sample has the current 33-byte attachment.
    let formats = report["attachment_formats"].as_object().unwrap();
    assert_eq!(
        formats.keys().collect::<Vec<_>>(),
        ["current"],
        "{formats:?}"
    );

    // The graph, field by field as rmw_zenoh's Entity::make reads it.
    let nodes = tokens(&report, "NN");
    assert_eq!(nodes.len(), 1, "{:#}", report["tokens"]);
    let node = nodes[0];
    assert_eq!(node["admin_space"], "@ros2_lv");
    assert_eq!(node["domain"], "0");
    let zid = node["zid"].as_str().unwrap();
    assert!(
        zid.len() <= 32
            && zid
                .chars()
                .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())
    );
    assert_eq!(node["nid"], node["eid"], "a node token repeats its id");
    assert_eq!(node["enclave"], "%");
    assert_eq!(node["namespace"], "%");
    assert_eq!(node["node"], "acch");
    let publishers = tokens(&report, "MP");
    assert_eq!(publishers.len(), topics.len(), "{:#}", report["tokens"]);
    let mut eids = Vec::new();
    for (topic, ty) in topics {
        let p = publishers
            .iter()
            .find(|p| p["topic_demangled"] == topic)
            .unwrap_or_else(|| panic!("no publisher token for {topic}"));
        assert_eq!(p["zid"], zid, "{topic}: same session as the node");
        assert_eq!(p["nid"], node["nid"], "{topic}: the node's id");
        eids.push(p["eid"].as_str().unwrap().to_owned());
        assert_eq!(p["enclave"], "%");
        assert_eq!(p["namespace"], "%");
        assert_eq!(p["node"], "acch");
        assert_eq!(p["topic"], topic.replace('/', "%"), "mangled topic");
        assert_eq!(p["ros_type"], ty);
        let (dds, hash, depth) = match ty {
            PWCS => (PWCS_DDS, PWCS_HASH, "10"),
            "sensor_msgs/msg/CameraInfo" => (
                "sensor_msgs::msg::dds_::CameraInfo_",
                CAMERA_INFO_HASH,
                "10",
            ),
            "sensor_msgs/msg/Image" => ("sensor_msgs::msg::dds_::Image_", IMAGE_HASH, "10"),
            _ => ("tf2_msgs::msg::dds_::TFMessage_", TF_HASH, "100"),
        };
        assert_eq!(p["dds_type"], dds);
        assert_eq!(p["type_hash"], hash);
        assert_eq!(p["qos"], format!("1:2:1,{depth}:,:,:,,"));
        let q = &p["qos_parsed"];
        assert_eq!(
            (
                &q["reliability"],
                &q["durability"],
                &q["history"],
                &q["depth"]
            ),
            (&"1".into(), &"2".into(), &"1".into(), &depth.into()),
            "RELIABLE, VOLATILE, KEEP_LAST {depth}"
        );
        // The data key matches the token.
        let key = report["topics"][topic]["key"].as_str().unwrap();
        assert_eq!(key, format!("0/{}/{dds}/{hash}", topic.trim_matches('/')));
    }
    eids.sort();
    eids.dedup();
    assert_eq!(eids.len(), topics.len(), "entity ids are unique");

    // The bag holds every message the reader received, byte for byte as
    // rosbags decodes them, and one of each per frame, except what the
    // recorder says it missed: it drops what it cannot keep up with (by
    // design, so a loaded machine never stalls the pipeline) and counts it.
    let summary = record_summary(&run);
    let missed = |what: &str| summary[what].as_u64().unwrap() as usize;
    let (frames_missed, results_missed) = (missed("frames_missed"), missed("results_missed"));
    // What the recorder counts as missed is forgiven, up to a tenth of the
    // run's 120 frames: more is a recorder that cannot keep up, not load.
    assert!(
        frames_missed <= 12 && results_missed <= 12,
        "the recorder missed {frames_missed} frames and {results_missed} results of 120"
    );
    let bag_topics = &report["bag"]["topics"];
    let bag_count = |topic: &str| bag_topics[topic]["count"].as_u64().unwrap() as usize;
    for (topic, _) in topics {
        let live = report["topics"][topic]["samples"].as_array().unwrap().len();
        assert!(live >= 30, "{topic}: {live} samples");
        // Under load zenoh may drop a sample (congestion control Drop);
        // a few, never many.
        let lost = report["lost"][topic].as_u64().unwrap_or(0) as usize;
        assert!(lost * 20 <= live, "{topic}: {lost} lost of {live}");
        let in_bag = report["topics"][topic]["live_in_bag"].as_u64().unwrap() as usize;
        // Images are written per frame; the rest per result.
        let recorder_missed = match topic {
            "/acch/image" => frames_missed,
            _ => results_missed,
        };
        assert!(
            in_bag + recorder_missed >= live,
            "{topic}: {in_bag} of {live} live messages in the bag, the recorder missed {recorder_missed}"
        );
        // Missing a share is load; a bag without most of it is a bug.
        assert!(
            bag_count(topic) * 10 >= live,
            "{topic}: {} in the bag of {live} live",
            bag_count(topic)
        );
    }
    // The recorder's gaps count frames a loaded capture skipped too.
    for (topic, missed) in [
        ("/acch/camera_info", results_missed),
        ("/acch/image", frames_missed),
    ] {
        let n = bag_count(topic);
        assert!(
            n <= 120 && n + missed >= 120 && n >= 60,
            "{topic}: one per frame: {n} of 120 in the bag (at least half wanted), {missed} missed"
        );
    }
    assert_eq!(bag_topics["/acch/image"]["type"], "sensor_msgs/msg/Image");

    // The ROS seeds are the pipeline's, in metres, stamped with the
    // frame's capture time.
    let results = results(&jsonl);
    let by_stamp = |ns: u64| {
        results
            .iter()
            .find(|r| r["stamp"]["wall_ns"] == ns)
            .unwrap_or_else(|| panic!("no result stamped {ns}"))
    };
    for s in report["topics"]["/acch/fruitbox/seed"]["samples"]
        .as_array()
        .unwrap()
    {
        let msg = &s["message"];
        assert_eq!(msg["header"]["frame_id"], "camera_optical_frame");
        let r = by_stamp(stamp_ns(msg));
        assert_eq!(r["accepted"], true, "a seed of a rejected frame: {r}");
        let p = &msg["pose"]["pose"]["position"];
        let seed = f64s(&r["seed"]["translation"]);
        assert_eq!(
            [p["x"].as_f64(), p["y"].as_f64(), p["z"].as_f64()],
            [Some(seed[0]), Some(seed[1]), Some(seed[2])]
        );
        assert_eq!(
            f64s(&msg["pose"]["covariance"]),
            f64s(&r["seed"]["covariance"])
        );
    }
    let rejected = results.iter().filter(|r| r["accepted"] != true).count();
    let (bag_seeds, accepted) = (bag_count("/acch/fruitbox/seed"), results.len() - rejected);
    assert!(
        bag_seeds <= accepted && bag_seeds + results_missed >= accepted,
        "one seed per accepted frame: {bag_seeds} in the bag, {accepted} accepted, {results_missed} missed"
    );
    assert_eq!(summary["seeds"].as_u64(), Some(bag_seeds as u64));
    for c in report["topics"]["/acch/camera_info"]["samples"]
        .as_array()
        .unwrap()
    {
        let k = f64s(&c["message"]["k"]);
        assert_eq!(
            (
                c["message"]["width"].as_u64(),
                c["message"]["height"].as_u64()
            ),
            (Some(640), Some(480))
        );
        assert!(k[0] > 100.0 && k[4] == k[0] && k[8] == 1.0, "{k:?}");
    }
    for i in report["topics"]["/acch/image"]["samples"]
        .as_array()
        .unwrap()
    {
        let m = &i["message"];
        assert_eq!(
            (m["width"].as_u64(), m["height"].as_u64()),
            (Some(640), Some(480))
        );
        assert_eq!(
            (m["encoding"].as_str(), m["step"].as_u64()),
            (Some("rgb8"), Some(1920))
        );
        assert_eq!(m["data"]["length"], 640 * 480 * 3);
        let r = by_stamp(stamp_ns(m));
        assert_eq!(r["sequence"].as_u64().unwrap() % 2, 0, "every other frame");
    }
    for t in report["topics"]["/tf"]["samples"].as_array().unwrap() {
        let tf = &t["message"]["transforms"][0];
        assert_eq!(tf["header"]["frame_id"], "camera_optical_frame");
        assert_eq!(tf["child_frame_id"], "acch_fruitbox");
    }
}

#[test]
fn a_namespaced_humble_node_with_the_legacy_attachment_runs_in_one_process() {
    require_python();
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let config = dir.path().join("pipeline.toml");
    std::fs::write(
        &config,
        format!(
            "[zenoh]\nlisten = [\"tcp/127.0.0.1:{port}\"]\n[ros2]\nenabled = true\ndomain_id = 7\n\
             namespace = \"/robot1\"\ndistro = \"humble\"\nattachment = \"legacy\"\ntf = false\n"
        ),
    )
    .unwrap();
    let report_path = dir.path().join("report.json");
    let check = checker(
        port,
        &[
            "--domain",
            "7",
            "--distro",
            "humble",
            "--attachment",
            "legacy",
            "--min-samples",
            "20",
            "--expect-topic",
            &format!("/robot1/acch/fruitbox/seed:{PWCS}"),
            "--expect-topic",
            "/robot1/acch/camera_info:sensor_msgs/msg/CameraInfo",
        ],
        &report_path,
    );
    acch_run(&config, &["--in-process", "--frames", "60"]);
    let report = checked(check, &report_path);
    let formats = report["attachment_formats"].as_object().unwrap();
    assert_eq!(
        formats.keys().collect::<Vec<_>>(),
        ["legacy"],
        "{formats:?}"
    );
    assert!(report["topics"].get("/tf").is_none(), "tf = false");
    for t in report["tokens"].as_array().unwrap() {
        assert_eq!(t["domain"], "7");
        assert_eq!(t["namespace"], "%robot1", "{t}");
        if t["kind"] == "MP" {
            assert_eq!(t["type_hash"], "TypeHashNotSupported");
        }
    }
    let seed = &report["topics"]["/robot1/acch/fruitbox/seed"]["key"];
    assert_eq!(
        seed.as_str().unwrap(),
        format!("7/robot1/acch/fruitbox/seed/{PWCS_DDS}/TypeHashNotSupported")
    );
}

#[test]
fn the_arm_pose_comes_from_a_ros2_topic() {
    require_python();
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let [arm_port, port] = free_ports();
    let _arm = Guard(
        Command::new("python3")
            .arg(script("publish_arm.py"))
            .arg("--listen")
            .arg(format!("tcp/127.0.0.1:{arm_port}"))
            .args(["--topic", "/arm/camera_pose", "--seconds", "120"])
            .spawn()
            .unwrap(),
    );
    let config = dir.path().join("pipeline.toml");
    std::fs::write(
        &config,
        format!(
            "[zenoh]\nlisten = [\"tcp/127.0.0.1:{port}\"]\nconnect = [\"tcp/127.0.0.1:{arm_port}\"]\n\
             [ros2]\narm_topic = \"/arm/camera_pose\"\n"
        ),
    )
    .unwrap();
    let jsonl = dir.path().join("results.jsonl");
    acch_run(
        &config,
        &["--frames", "60", "--results", jsonl.to_str().unwrap()],
    );
    let results = results(&jsonl);
    let mut from_ros = 0;
    for r in &results {
        let Some(arm) = r["arm"].as_object() else {
            continue;
        };
        // Pose k of the publisher: (0.01 k, 0.2, 0.5) m, 0.5 k degrees about z.
        let t = f64s(&arm["translation"]);
        let k = (t[0] / 0.01).round();
        assert!(
            (t[0] - 0.01 * k).abs() < 1e-9
                && (t[1] - 0.2).abs() < 1e-9
                && (t[2] - 0.5).abs() < 1e-9,
            "not a pose of the arm's topic: {t:?} (the simulated arm's own would be metres off)"
        );
        let q = f64s(&arm["rotation_xyzw"]);
        let half = (0.5 * k).to_radians() / 2.0;
        let same = (q[2] - half.sin()).abs() < 1e-9 && (q[3] - half.cos()).abs() < 1e-9;
        let negated = (q[2] + half.sin()).abs() < 1e-9 && (q[3] + half.cos()).abs() < 1e-9;
        assert!(same || negated, "rotation {q:?} is not pose {k}'s");
        from_ros += 1;
    }
    assert!(
        from_ros * 10 >= results.len() * 9,
        "only {from_ros} of {} frames carried the arm's pose",
        results.len()
    );
}

#[test]
fn several_objects_publish_their_seeds_from_nodes_of_their_own() {
    require_python();
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let config = dir.path().join("pipeline.toml");
    std::fs::write(
        &config,
        // The group scene shows the two objects touching, where the
        // shape's verification rejects every estimate (docs/limitations.md);
        // this test is about the topics, so the colour rules judge.
        format!(
            "[estimate]\nverify_shape = false\n[zenoh]\nlisten = [\"tcp/127.0.0.1:{port}\"]\n\
             [ros2]\nenabled = true\n"
        ),
    )
    .unwrap();
    // Train (or load) both objects' databases first: on a cold cache that
    // takes longer than the checker waits for samples.
    let warm = dir.path().join("warm.toml");
    std::fs::write(
        &warm,
        format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port()),
    )
    .unwrap();
    acch_run(
        &warm,
        &["--in-process", "--objects", "fruitbox,can", "--frames", "1"],
    );
    let report_path = dir.path().join("report.json");
    let check = checker(
        port,
        &[
            "--min-samples",
            "5",
            "--expect-topic",
            &format!("/acch/fruitbox/seed:{PWCS}"),
            "--expect-topic",
            &format!("/acch/can/seed:{PWCS}"),
            "--expect-topic",
            "/acch/camera_info:sensor_msgs/msg/CameraInfo",
        ],
        &report_path,
    );
    acch_run(
        &config,
        &[
            "--in-process",
            "--objects",
            "fruitbox,can",
            "--frames",
            "60",
        ],
    );
    let report = checked(check, &report_path);
    let node_tokens = tokens(&report, "NN");
    let nodes: Vec<&str> = node_tokens
        .iter()
        .filter_map(|t| t["node"].as_str())
        .collect();
    for node in ["acch_fruitbox", "acch_can"] {
        assert!(nodes.contains(&node), "no node {node}: {nodes:?}");
    }
    // The camera's info comes from one node only, not once per object.
    let publishers = tokens(&report, "MP");
    let info: Vec<&&Value> = publishers
        .iter()
        .filter(|t| t["topic_demangled"] == "/acch/camera_info")
        .collect();
    assert_eq!(info.len(), 1, "{info:?}");
}
