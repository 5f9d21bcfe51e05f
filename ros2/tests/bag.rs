//! Bags read back with the mcap crate's reader: profile, schemas, channels
//! and their metadata, messages, the rosbag2 record, statistics and
//! metadata.yaml. (`tests/ros2/check_ros2.py --bag` reads them with rosbags.)

use acch_ros2::msg::{CameraInfo, Header, PoseWithCovarianceStamped, Time};
use acch_ros2::{BagError, BagWriter, Message, Qos, Reliability, encode};
use std::path::Path;

fn pose(ns: u64, x: f64) -> PoseWithCovarianceStamped {
    let mut m = PoseWithCovarianceStamped {
        header: Header {
            stamp: Time::from_ns(ns),
            frame_id: "map".into(),
        },
        ..Default::default()
    };
    m.pose.pose.position.x = x;
    m
}

fn records(bytes: &[u8]) -> Vec<mcap::records::Record<'_>> {
    mcap::read::LinearReader::new(bytes)
        .expect("MCAP magic")
        .map(|r| r.expect("valid record"))
        .collect()
}

/// Writes 3 poses and 1 camera info; returns the bag dir and what was written.
fn write_bag(dir: &Path) -> Vec<(String, u64, Vec<u8>)> {
    let mut bag = BagWriter::create(dir, "jazzy").unwrap();
    let best_effort = Qos {
        reliability: Reliability::BestEffort,
        history_depth: 5,
        ..Qos::default()
    };
    let seed = bag
        .add_topic::<PoseWithCovarianceStamped>("/acch/fruitbox/seed", Qos::default())
        .unwrap();
    let info = bag
        .add_topic::<CameraInfo>("camera/camera_info", best_effort)
        .unwrap();
    assert_eq!(
        bag.add_topic::<PoseWithCovarianceStamped>("/acch/fruitbox/seed", Qos::default())
            .unwrap(),
        seed,
        "the same topic and type again is the same topic"
    );
    let mut written = Vec::new();
    let mut buf = Vec::new();
    for (i, t) in [1_000u64, 2_500, 4_000].into_iter().enumerate() {
        let ns = 1_700_000_000_000_000_000 + t;
        encode(&pose(ns, i as f64), &mut buf).unwrap();
        bag.write(seed, ns + 7, ns, &buf).unwrap();
        written.push(("/acch/fruitbox/seed".to_owned(), ns + 7, buf.clone()));
    }
    encode(&CameraInfo::default(), &mut buf).unwrap();
    let ns = 1_700_000_000_000_003_000;
    bag.write(info, ns, ns - 1, &buf).unwrap();
    written.push(("/camera/camera_info".to_owned(), ns, buf.clone()));
    bag.finish().unwrap();
    written
}

#[test]
fn the_mcap_has_the_ros2_layout() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run1");
    let written = write_bag(&dir);
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    assert_eq!(files, ["metadata.yaml", "run1_0.mcap"]);

    let bytes = std::fs::read(dir.join("run1_0.mcap")).unwrap();
    let recs = records(&bytes);
    match &recs[0] {
        mcap::records::Record::Header(h) => {
            assert_eq!(h.profile, "ros2");
            assert_eq!(h.library, "acch");
        }
        r => panic!("first record is {r:?}"),
    }
    let meta: Vec<_> = recs
        .iter()
        .filter_map(|r| match r {
            mcap::records::Record::Metadata(m) => Some(m),
            _ => None,
        })
        .collect();
    assert_eq!(meta.len(), 1);
    assert_eq!(meta[0].name, "rosbag2");
    let serialized = &meta[0].metadata["serialized_metadata"];
    assert!(
        serialized.starts_with("version: 9\nstorage_identifier: mcap\n"),
        "{serialized}"
    );
    assert!(serialized.contains("message_count: 4\n"));

    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("summary section");
    let stats = summary
        .stats
        .expect("statistics record (ros2 bag info needs it)");
    assert_eq!(stats.message_count, 4);
    assert_eq!(stats.schema_count, 2);
    assert_eq!(stats.channel_count, 2);
    assert_eq!(stats.message_start_time, 1_700_000_000_000_001_007);
    assert_eq!(stats.message_end_time, 1_700_000_000_000_004_007);
    assert!(!summary.chunk_indexes.is_empty());

    let mut channels: Vec<_> = summary.channels.values().collect();
    channels.sort_by_key(|c| c.topic.clone());
    assert_eq!(channels[0].topic, "/acch/fruitbox/seed");
    assert_eq!(
        channels[1].topic, "/camera/camera_info",
        "relative names get their slash"
    );
    for (c, ty, depth, rel) in [
        (channels[0], PoseWithCovarianceStamped::TYPE, 10, "reliable"),
        (channels[1], CameraInfo::TYPE, 5, "best_effort"),
    ] {
        assert_eq!(c.message_encoding, "cdr");
        let schema = c.schema.as_ref().expect("schema");
        assert_eq!(schema.name, ty);
        assert_eq!(schema.encoding, "ros2msg");
        let expected_def = if ty == CameraInfo::TYPE {
            CameraInfo::DEFINITION
        } else {
            PoseWithCovarianceStamped::DEFINITION
        };
        assert_eq!(&schema.data[..], expected_def.as_bytes());
        let hash = if ty == CameraInfo::TYPE {
            CameraInfo::TYPE_HASH
        } else {
            PoseWithCovarianceStamped::TYPE_HASH
        };
        assert_eq!(c.metadata["topic_type_hash"], hash);
        let q = &c.metadata["offered_qos_profiles"];
        assert!(q.starts_with("- history: keep_last\n"), "{q}");
        assert!(q.contains(&format!("\n  depth: {depth}\n")), "{q}");
        assert!(q.contains(&format!("\n  reliability: {rel}\n")), "{q}");
        assert!(
            q.ends_with("avoid_ros_namespace_conventions: false"),
            "no final newline, as YAML::Dump: {q:?}"
        );
    }

    let got: Vec<(String, u64, Vec<u8>)> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            assert_eq!(m.sequence, 0);
            (m.channel.topic.clone(), m.log_time, m.data.into_owned())
        })
        .collect();
    assert_eq!(
        got, written,
        "messages are the full CDR payloads, header included"
    );
}

#[test]
fn metadata_yaml_counts_topics_and_times() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run2");
    write_bag(&dir);
    let y = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    let expect = [
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n",
        "  duration:\n    nanoseconds: 3000\n",
        "  starting_time:\n    nanoseconds_since_epoch: 1700000000000001007\n",
        "  message_count: 4\n",
        "  topics_with_message_count:\n    - topic_metadata:\n        name: \"/acch/fruitbox/seed\"\n        type: \"geometry_msgs/msg/PoseWithCovarianceStamped\"\n        serialization_format: cdr\n        offered_qos_profiles:\n          - history: keep_last\n            depth: 10\n",
        "        type_description_hash: \"RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e\"\n      message_count: 3\n",
        "        name: \"/camera/camera_info\"\n",
        "            reliability: best_effort\n",
        "      message_count: 1\n",
        "  relative_file_paths:\n    - \"run2_0.mcap\"\n",
        "  files:\n    - path: \"run2_0.mcap\"\n      starting_time:\n        nanoseconds_since_epoch: 1700000000000001007\n      duration:\n        nanoseconds: 3000\n      message_count: 4\n",
        "  custom_data: ~\n  ros_distro: \"jazzy\"\n",
    ];
    for part in expect {
        assert!(y.contains(part), "metadata.yaml lacks {part:?}:\n{y}");
    }
    assert!(!dir.join("metadata.yaml.tmp").exists());
}

#[test]
fn a_recording_is_never_overwritten() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("busy");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("old_0.mcap"), b"precious").unwrap();
    let e = BagWriter::create(&dir, "jazzy").unwrap_err();
    assert!(
        matches!(&e, BagError::NotEmpty { path } if path == &dir),
        "{e}"
    );
    assert_eq!(std::fs::read(dir.join("old_0.mcap")).unwrap(), b"precious");

    let file = tmp.path().join("afile");
    std::fs::write(&file, b"x").unwrap();
    assert!(matches!(
        BagWriter::create(&file, "jazzy"),
        Err(BagError::NotADirectory { .. })
    ));

    // An existing empty directory is fine.
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    BagWriter::create(&empty, "jazzy")
        .unwrap()
        .finish()
        .unwrap();
    assert!(empty.join("empty_0.mcap").exists());
}

#[test]
fn bad_writes_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let mut bag = BagWriter::create(&tmp.path().join("bad"), "jazzy").unwrap();
    let seed = bag
        .add_topic::<PoseWithCovarianceStamped>("/seed", Qos::default())
        .unwrap();
    let e = bag.write(seed, 1, 1, &[1, 2, 3, 4, 5]).unwrap_err();
    assert!(
        matches!(&e, BagError::NotCdr { topic, len: 5 } if topic == "/seed"),
        "{e}"
    );
    let e = bag
        .add_topic::<CameraInfo>("/seed", Qos::default())
        .unwrap_err();
    assert!(matches!(e, BagError::TypeConflict { .. }), "{e}");
    let e = bag
        .add_topic::<CameraInfo>("/bad topic", Qos::default())
        .unwrap_err();
    assert!(matches!(e, BagError::Name(_)), "{e}");
    bag.finish().unwrap();
}

#[test]
fn an_empty_bag_is_still_a_valid_bag() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("nothing");
    BagWriter::create(&dir, "jazzy").unwrap().finish().unwrap();
    let y = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(
        y.contains("  message_count: 0\n  topics_with_message_count: []\n"),
        "{y}"
    );
    let bytes = std::fs::read(dir.join("nothing_0.mcap")).unwrap();
    assert_eq!(
        mcap::Summary::read(&bytes)
            .unwrap()
            .unwrap()
            .stats
            .unwrap()
            .message_count,
        0
    );
}

#[test]
fn dropping_without_finish_still_closes_the_bag() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("dropped");
    {
        let mut bag = BagWriter::create(&dir, "humble").unwrap();
        let t = bag
            .add_topic::<PoseWithCovarianceStamped>("/seed", Qos::default())
            .unwrap();
        let mut buf = Vec::new();
        encode(&pose(5, 1.0), &mut buf).unwrap();
        bag.write(t, 5, 5, &buf).unwrap();
    }
    let y = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(y.contains("ros_distro: \"humble\""), "{y}");
    let bytes = std::fs::read(dir.join("dropped_0.mcap")).unwrap();
    assert_eq!(mcap::MessageStream::new(&bytes).unwrap().count(), 1);
}

#[test]
fn strings_in_the_yaml_are_quoted_safely() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("quotes");
    BagWriter::create(&dir, "ja\"zzy: #1\n")
        .unwrap()
        .finish()
        .unwrap();
    let y = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(y.contains("  ros_distro: \"ja\\\"zzy: #1\\n\"\n"), "{y}");
}
