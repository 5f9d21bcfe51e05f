//! Keys, tokens, QoS strings, attachments and GIDs against rmw_zenoh's
//! formats (design.md examples, the spec's byte dumps, and GIDs computed by
//! rmw_zenoh's own `simplified_XXH3_128bits`).

use acch_ros2::graph::*;
use acch_ros2::msg::{Message, PoseWithCovarianceStamped};
use acch_ros2::{
    Attachment, AttachmentError, AttachmentFormat, Distro, Durability, Qos, Reliability,
};

const PWCS_HASH: &str = "RIHS01_26432f9803e43727d3c8f668d1fdb3c630f548af631e2f4e31382371bfea3b6e";
const ZID: &str = "aac3178e146ba6f1fc6e6a4085e77f21";

#[test]
fn qos_strings_are_explicit_and_have_rmw_zenohs_six_groups() {
    assert_eq!(Qos::default().to_keyexpr(), "1:2:1,10:,:,:,,");
    let be = Qos {
        reliability: Reliability::BestEffort,
        durability: Durability::Volatile,
        history_depth: 5,
    };
    assert_eq!(be.to_keyexpr(), "2:2:1,5:,:,:,,");
    let latched = Qos {
        reliability: Reliability::Reliable,
        durability: Durability::TransientLocal,
        history_depth: 1,
    };
    assert_eq!(latched.to_keyexpr(), "1:1:1,1:,:,:,,");
    // keyexpr_to_qos: 6 ':' groups; history 2, deadline 2, lifespan 2, liveliness 3 ',' parts.
    let s = Qos::default().to_keyexpr();
    let groups: Vec<&str> = s.split(':').collect();
    let parts: Vec<usize> = groups.iter().map(|g| g.split(',').count()).collect();
    assert_eq!(parts, [1, 1, 2, 2, 2, 3]);
}

#[test]
fn rosbag2_qos_yaml_uses_v9_names_and_infinite_durations() {
    let y = Qos::default().to_rosbag2_yaml(2);
    assert_eq!(
        y,
        "  - history: keep_last\n    depth: 10\n    reliability: reliable\n    durability: volatile\n    \
         deadline:\n      sec: 9223372036\n      nsec: 854775807\n    \
         lifespan:\n      sec: 9223372036\n      nsec: 854775807\n    liveliness: automatic\n    \
         liveliness_lease_duration:\n      sec: 9223372036\n      nsec: 854775807\n    \
         avoid_ros_namespace_conventions: false\n"
    );
}

#[test]
fn data_keys_strip_outer_slashes_and_keep_inner_ones() {
    let ty = PoseWithCovarianceStamped::dds_type();
    assert_eq!(
        data_key(0, "/pose", &ty, PWCS_HASH),
        format!("0/pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/{PWCS_HASH}")
    );
    // design.md: 0/robot1/chatter/std_msgs::msg::dds_::String_/RIHS01_df66…
    let hash = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";
    assert_eq!(
        data_key(0, "/robot1/chatter", "std_msgs::msg::dds_::String_", hash),
        format!("0/robot1/chatter/std_msgs::msg::dds_::String_/{hash}")
    );
    assert_eq!(
        data_key(42, "/acch/fruitbox/seed", &ty, HUMBLE_TYPE_HASH),
        "42/acch/fruitbox/seed/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/TypeHashNotSupported"
    );
}

#[test]
fn humble_uses_type_hash_not_supported() {
    assert_eq!(
        Distro::Humble.type_hash::<PoseWithCovarianceStamped>(),
        "TypeHashNotSupported"
    );
    assert_eq!(
        Distro::Jazzy.type_hash::<PoseWithCovarianceStamped>(),
        PWCS_HASH
    );
}

#[test]
fn node_token_reproduces_the_design_md_example() {
    let node = NodeInfo {
        domain_id: 2,
        zid: ZID,
        node_id: 0,
        enclave: "/",
        namespace: "/",
        name: "listener",
    };
    assert_eq!(
        node_token(&node),
        format!("@ros2_lv/2/{ZID}/0/0/NN/%/%/listener")
    );
}

fn namespaced_node() -> NodeInfo<'static> {
    NodeInfo {
        domain_id: 7,
        zid: ZID,
        node_id: 3,
        enclave: "/",
        namespace: "/robot1/arm",
        name: "tracker",
    }
}

#[test]
fn namespaced_node_token_field_by_field() {
    let t = node_token(&namespaced_node());
    let f: Vec<&str> = t.split('/').collect();
    assert_eq!(f.len(), 9);
    assert_eq!(f[0], "@ros2_lv");
    assert_eq!(f[1], "7", "domain");
    assert_eq!(f[2], ZID);
    assert_eq!(f[3], "3", "node id");
    assert_eq!(f[4], "3", "a node's entity id is its node id");
    assert_eq!(f[5], "NN");
    assert_eq!(f[6], "%", "enclave / mangled");
    assert_eq!(f[7], "%robot1%arm", "namespace mangled");
    assert_eq!(f[8], "tracker");
}

#[test]
fn publisher_and_subscriber_tokens_field_by_field() {
    let topic = TopicInfo {
        topic: "/robot1/arm/pose",
        dds_type: "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_",
        type_hash: PWCS_HASH,
        qos: Qos::default(),
    };
    for (token, kind) in [
        (publisher_token(&namespaced_node(), 11, &topic), "MP"),
        (subscriber_token(&namespaced_node(), 12, &topic), "MS"),
    ] {
        let f: Vec<&str> = token.split('/').collect();
        assert_eq!(f.len(), 13, "{token}");
        assert!(
            f.iter().all(|p| !p.is_empty()),
            "rmw_zenoh rejects empty parts: {token}"
        );
        assert_eq!(&f[..4], ["@ros2_lv", "7", ZID, "3"]);
        assert_eq!(f[4], if kind == "MP" { "11" } else { "12" });
        assert_eq!(f[5], kind);
        assert_eq!(&f[6..9], ["%", "%robot1%arm", "tracker"]);
        assert_eq!(f[9], "%robot1%arm%pose", "fully qualified topic, mangled");
        assert_eq!(
            f[10],
            "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"
        );
        assert_eq!(f[11], PWCS_HASH);
        assert_eq!(f[12], "1:2:1,10:,:,:,,");
    }
}

#[test]
fn the_spec_example_publisher_token_is_reproduced() {
    let node = NodeInfo {
        domain_id: 0,
        zid: ZID,
        node_id: 0,
        enclave: "/",
        namespace: "/",
        name: "pose_publisher",
    };
    let topic = TopicInfo {
        topic: "/camera/camera_info",
        dds_type: "sensor_msgs::msg::dds_::CameraInfo_",
        type_hash: "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
        qos: Qos::default(),
    };
    assert_eq!(
        publisher_token(&node, 2, &topic),
        format!(
            "@ros2_lv/0/{ZID}/0/2/MP/%/%/pose_publisher/%camera%camera_info/sensor_msgs::msg::dds_::CameraInfo_/RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275/1:2:1,10:,:,:,,"
        )
    );
}

/// GIDs from rmw_zenoh's `simplified_xxhash3.cpp` (compiled from
/// ros2/rmw_zenoh, low64 then high64 little endian), one input per code
/// path of XXH3-128: 1-3, 4-8, 9-16, 17-128, 129-240 and > 240 bytes.
#[test]
fn gid_matches_rmw_zenohs_simplified_xxh3() {
    let token = format!(
        "@ros2_lv/0/{ZID}/0/1/MP/%/%/pose_publisher/%pose/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/{PWCS_HASH}/1:2:1,10:,:,:,,"
    );
    let long = format!("{token}/{token}");
    let cases = [
        ("a", "1f4e961eb632c6e63468f15a70af6fa9"),
        ("abcdefgh", "120f8813b302b742333537af3732c2da"),
        ("abcdefghijklmnop", "30632ff13f158e3e4b8c1b9b80fc581f"),
        (
            &format!("@ros2_lv/2/{ZID}/0/0/NN/%/%/listener"),
            "49877999dacb858702d11ac823785912",
        ),
        (&token, "01bce0c0cb6f393d090702a85e362f8b"),
        (&long, "95bdbe5bf71e6881e7f7b7556e8e2f1c"),
    ];
    for (input, want) in cases {
        let hex: String = gid(input).iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(hex, want, "input of {} bytes", input.len());
    }
}

const GID_0_15: [u8; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15];

fn example() -> Attachment {
    Attachment {
        sequence: 1,
        source_timestamp_ns: 1_700_000_000_123_456_789,
        gid: GID_0_15,
    }
}

#[test]
fn current_attachment_is_the_spec_dump() {
    let mut out = Vec::new();
    example().encode(AttachmentFormat::Current, &mut out);
    let want: Vec<u8> = [
        &[0x01, 0, 0, 0, 0, 0, 0, 0][..],
        &[0x15, 0xcd, 0x85, 0x3d, 0xfe, 0x9c, 0x97, 0x17],
        &[0x10],
        &GID_0_15,
    ]
    .concat();
    assert_eq!(out, want);
    assert_eq!(out.len(), Attachment::CURRENT_LEN);
    assert_eq!(Attachment::decode(&out).unwrap(), example());
}

#[test]
fn legacy_attachment_is_the_spec_dump() {
    let mut out = Vec::new();
    example().encode(AttachmentFormat::Legacy, &mut out);
    let want: Vec<u8> = [
        &b"\x0fsequence_number"[..],
        &[0x01, 0, 0, 0, 0, 0, 0, 0],
        b"\x10source_timestamp",
        &[0x15, 0xcd, 0x85, 0x3d, 0xfe, 0x9c, 0x97, 0x17],
        b"\x0asource_gid",
        &[0x10],
        &GID_0_15,
    ]
    .concat();
    assert_eq!(out, want);
    assert_eq!(out.len(), Attachment::LEGACY_LEN);
    assert_eq!(Attachment::decode(&out).unwrap(), example());
}

#[test]
fn negative_and_large_values_survive_both_formats() {
    let a = Attachment {
        sequence: i64::MAX,
        source_timestamp_ns: -5,
        gid: [0xff; 16],
    };
    let mut out = Vec::new();
    for format in [AttachmentFormat::Current, AttachmentFormat::Legacy] {
        a.encode(format, &mut out);
        assert_eq!(Attachment::decode(&out).unwrap(), a);
    }
}

#[test]
fn malformed_attachments_say_what_is_wrong() {
    assert_eq!(
        Attachment::decode(&[0; 32]),
        Err(AttachmentError::Length { len: 32 })
    );
    let mut out = Vec::new();
    example().encode(AttachmentFormat::Current, &mut out);
    out[16] = 0x0f;
    assert_eq!(
        Attachment::decode(&out),
        Err(AttachmentError::GidLength {
            offset: 16,
            found: 0x0f
        })
    );
    example().encode(AttachmentFormat::Legacy, &mut out);
    out[26] = b'X'; // inside "source_timestamp"
    assert_eq!(
        Attachment::decode(&out),
        Err(AttachmentError::Label {
            offset: 24,
            expected: "source_timestamp"
        })
    );
}

#[test]
fn attachment_encode_reuses_its_buffer() {
    let mut out = Vec::with_capacity(Attachment::LEGACY_LEN);
    let ptr = out.as_ptr();
    for format in [
        AttachmentFormat::Legacy,
        AttachmentFormat::Current,
        AttachmentFormat::Legacy,
    ] {
        example().encode(format, &mut out);
        assert_eq!(out.as_ptr(), ptr);
    }
}

#[test]
fn the_message_trait_gives_the_dds_name() {
    assert_eq!(
        PoseWithCovarianceStamped::TYPE,
        "geometry_msgs/msg/PoseWithCovarianceStamped"
    );
    assert_eq!(
        PoseWithCovarianceStamped::dds_type(),
        "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"
    );
}
