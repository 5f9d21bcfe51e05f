//! Two zenoh peers on loopback: a Node publishes, a plain zenoh subscriber
//! and a Node subscriber receive, and a liveliness query sees the tokens.
//! Every wait has a deadline, so a broken build fails instead of hanging.

use acch_ros2::graph;
use acch_ros2::msg::{Header, PoseWithCovarianceStamped, Time};
use acch_ros2::{
    Attachment, AttachmentFormat, Distro, Message, Node, NodeConfig, Qos, decode, encode,
};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use zenoh::Wait;

const DEADLINE: Duration = Duration::from_secs(10);

fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().port()
}

/// A peer with multicast and gossip scouting off, as acch configures them.
fn open_session(listen: &[String], connect: &[String]) -> zenoh::Session {
    let mut c = zenoh::Config::default();
    let json = |v: &[String]| serde_json::to_string(v).unwrap();
    for (k, v) in [
        ("mode", "\"peer\"".to_owned()),
        ("scouting/multicast/enabled", "false".to_owned()),
        ("scouting/gossip/enabled", "false".to_owned()),
        ("listen/endpoints", json(listen)),
        ("connect/endpoints", json(connect)),
    ] {
        c.insert_json5(k, &v).unwrap();
    }
    zenoh::open(c).wait().unwrap()
}

/// A listening peer and a second peer connected to it.
fn pair() -> (zenoh::Session, zenoh::Session) {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let a = open_session(std::slice::from_ref(&endpoint), &[]);
    let b = open_session(&[], &[endpoint]);
    (a, b)
}

fn pose(i: u32) -> PoseWithCovarianceStamped {
    let mut m = PoseWithCovarianceStamped {
        header: Header {
            stamp: Time {
                sec: 1_700_000_000,
                nanosec: i,
            },
            frame_id: "map".into(),
        },
        ..Default::default()
    };
    m.pose.pose.position.x = f64::from(i);
    m.pose.covariance[35] = 0.25;
    m
}

/// Liveliness keys under `@ros2_lv/<domain>/**` seen from `session`,
/// queried until `want` are all there or the deadline passes.
fn tokens_until(session: &zenoh::Session, domain: u32, want: &[&str]) -> Vec<String> {
    let start = Instant::now();
    loop {
        let replies = session
            .liveliness()
            .get(format!("@ros2_lv/{domain}/**"))
            .timeout(Duration::from_secs(2))
            .wait()
            .unwrap();
        let mut keys = Vec::new();
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                keys.push(sample.key_expr().as_str().to_owned());
            }
        }
        if want.iter().all(|w| keys.iter().any(|k| k == w)) || start.elapsed() > DEADLINE {
            return keys;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_plain_zenoh_subscriber_gets_payload_and_attachment() {
    let (a, b) = pair();
    let node = Node::new(
        &a,
        NodeConfig {
            domain_id: 0,
            namespace: "/acch".into(),
            name: "tracker".into(),
            ..NodeConfig::default()
        },
    )
    .unwrap();
    let mut publisher = node
        .publisher::<PoseWithCovarianceStamped>("fruitbox/seed", Qos::default())
        .unwrap();
    assert_eq!(publisher.topic(), "/acch/fruitbox/seed");
    let key = format!(
        "0/acch/fruitbox/seed/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/{}",
        PoseWithCovarianceStamped::TYPE_HASH
    );
    assert_eq!(publisher.key(), key);

    let sub = b.declare_subscriber(key.as_str()).wait().unwrap();
    // Publish until four samples have arrived: the first ones go out before
    // the subscription reaches the publisher's side, and congestion control
    // Drop (as rmw_zenoh's) may lose one on a loaded machine, so arrival is
    // not asserted per sample; what each sample carries is.
    let start = Instant::now();
    let mut sent = 0u32;
    let mut samples = Vec::new();
    while samples.len() < 4 {
        sent += 1;
        publisher
            .publish(&pose(sent), 1_000 + i64::from(sent))
            .unwrap();
        if let Ok(Some(s)) = sub.recv_timeout(Duration::from_millis(100)) {
            samples.push(s);
        }
        while let Ok(Some(s)) = sub.try_recv() {
            samples.push(s);
        }
        assert!(
            start.elapsed() < DEADLINE,
            "{} of 4 samples arrived on {key}",
            samples.len()
        );
    }
    let mut last_seq = None;
    for s in &samples {
        let payload = s.payload().to_bytes();
        let msg: PoseWithCovarianceStamped = decode(&payload).unwrap();
        let i = msg.header.stamp.nanosec;
        let mut want = Vec::new();
        encode(&pose(i), &mut want).unwrap();
        assert_eq!(
            &payload[..],
            &want[..],
            "the payload is exactly the CDR encoding"
        );
        assert_eq!(payload.len(), 364);

        let att = s
            .attachment()
            .expect("rmw_zenoh drops samples without attachment")
            .to_bytes();
        assert_eq!(att.len(), 33);
        let att = Attachment::decode(&att).unwrap();
        assert_eq!(att.source_timestamp_ns, 1_000 + i64::from(i));
        assert_eq!(
            att.sequence,
            i64::from(i),
            "the sequence counts publications from 1"
        );
        assert_eq!(att.gid, graph::gid(publisher.token()));
        assert_eq!(att.gid, publisher.gid());
        if let Some(prev) = last_seq {
            assert!(att.sequence > prev, "samples arrive in order");
        }
        last_seq = Some(att.sequence);
    }
    assert_eq!(publisher.next_sequence(), i64::from(sent) + 1);

    // Both tokens are visible from the other peer.
    let keys = tokens_until(&b, 0, &[node.token(), publisher.token()]);
    assert!(keys.iter().any(|k| k == node.token()), "{keys:?}");
    assert!(keys.iter().any(|k| k == publisher.token()), "{keys:?}");
    let zid = a.zid().to_string();
    assert_eq!(
        node.token(),
        format!(
            "@ros2_lv/0/{zid}/{id}/{id}/NN/%/%acch/tracker",
            id = node.id()
        )
    );
    assert_eq!(
        publisher.token(),
        format!(
            "@ros2_lv/0/{zid}/{}/{}/MP/%/%acch/tracker/%acch%fruitbox%seed/geometry_msgs::msg::dds_::PoseWithCovarianceStamped_/{}/1:2:1,10:,:,:,,",
            node.id(),
            publisher.entity_id(),
            PoseWithCovarianceStamped::TYPE_HASH
        )
    );
    assert!(
        publisher.entity_id() > node.id(),
        "one counter: the node first, then its entities"
    );

    // Dropping the publisher undeclares its token.
    let pub_token = publisher.token().to_owned();
    drop(publisher);
    let start = Instant::now();
    loop {
        let keys = tokens_until(&b, 0, &[]);
        if !keys.contains(&pub_token) {
            assert!(keys.iter().any(|k| k == node.token()), "the node stays");
            break;
        }
        assert!(
            start.elapsed() < DEADLINE,
            "the token outlived its publisher"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_node_subscriber_receives_a_node_publisher() {
    let (a, b) = pair();
    let config = NodeConfig {
        domain_id: 3,
        name: "talker".into(),
        ..NodeConfig::default()
    };
    let talker = Node::new(&a, config.clone()).unwrap();
    let listener = Node::new(
        &b,
        NodeConfig {
            name: "listener".into(),
            ..config
        },
    )
    .unwrap();
    let (tx, rx) = mpsc::channel();
    let tx = std::sync::Mutex::new(tx);
    let sub = listener
        .subscriber::<PoseWithCovarianceStamped, _>("/seed", Qos::default(), move |m, att| {
            let _ = tx.lock().unwrap().send((m, att));
        })
        .unwrap();
    let mut publisher = talker
        .publisher::<PoseWithCovarianceStamped>("seed", Qos::default())
        .unwrap();
    assert_eq!(sub.key(), publisher.key(), "both sides build the same key");
    assert!(sub.key().starts_with("3/seed/"));

    let start = Instant::now();
    let mut sent = 0;
    let (msg, att) = loop {
        sent += 1;
        publisher.publish(&pose(sent), 42).unwrap();
        if let Ok(got) = rx.recv_timeout(Duration::from_millis(100)) {
            break got;
        }
        assert!(
            start.elapsed() < DEADLINE,
            "the Node subscriber got nothing"
        );
    };
    let i = msg.header.stamp.nanosec;
    assert_eq!(msg, pose(i));
    let att = att.expect("a Node publisher always attaches");
    assert_eq!(att.sequence, i64::from(i));
    assert_eq!(att.source_timestamp_ns, 42);
    assert_eq!(att.gid, publisher.gid());

    let keys = tokens_until(&a, 3, &[sub.token()]);
    assert!(keys.iter().any(|k| k == sub.token()), "{keys:?}");
    let f: Vec<&str> = sub.token().split('/').collect();
    assert_eq!(f[5], "MS");
    assert_eq!(f[9], "%seed");
    // Another domain's query sees none of it.
    assert!(tokens_until(&a, 4, &[]).is_empty());
}

#[test]
fn legacy_format_and_humble_hash_go_on_the_wire() {
    let (a, b) = pair();
    let node = Node::new(
        &a,
        NodeConfig {
            distro: Distro::Humble,
            attachment: AttachmentFormat::Legacy,
            ..NodeConfig::default()
        },
    )
    .unwrap();
    let mut publisher = node
        .publisher::<PoseWithCovarianceStamped>("/old", Qos::default())
        .unwrap();
    assert!(publisher.key().ends_with("/TypeHashNotSupported"));
    assert!(publisher.token().contains("/TypeHashNotSupported/"));
    let sub = b
        .declare_subscriber(publisher.key().to_owned())
        .wait()
        .unwrap();
    let start = Instant::now();
    let sample = loop {
        publisher.publish(&pose(1), 7).unwrap();
        if let Ok(Some(s)) = sub.recv_timeout(Duration::from_millis(100)) {
            break s;
        }
        assert!(start.elapsed() < DEADLINE, "nothing arrived");
    };
    let att = sample.attachment().unwrap().to_bytes();
    assert_eq!(att.len(), 77);
    assert_eq!(&att[..16], b"\x0fsequence_number");
    assert_eq!(Attachment::decode(&att).unwrap().source_timestamp_ns, 7);
}

#[test]
fn bad_names_are_refused_before_anything_is_declared() {
    let session = open_session(&[], &[]);
    let e = Node::new(
        &session,
        NodeConfig {
            name: "bad-name".into(),
            ..NodeConfig::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("\"bad-name\""), "{e}");
    let node = Node::new(&session, NodeConfig::default()).unwrap();
    let e = node
        .publisher::<PoseWithCovarianceStamped>("/2fast", Qos::default())
        .unwrap_err();
    assert!(e.to_string().contains("starts with a digit"), "{e}");
    let e = node
        .publisher::<PoseWithCovarianceStamped>(
            "/ok",
            Qos {
                history_depth: 0,
                ..Qos::default()
            },
        )
        .unwrap_err();
    assert!(e.to_string().contains("at least 1"), "{e}");
}

#[test]
fn a_sample_that_does_not_decode_is_dropped_not_delivered() {
    let (a, b) = pair();
    let node = Node::new(&b, NodeConfig::default()).unwrap();
    let (tx, rx) = mpsc::channel();
    let tx = std::sync::Mutex::new(tx);
    let sub = node
        .subscriber::<PoseWithCovarianceStamped, _>("/seed", Qos::default(), move |m, att| {
            let _ = tx.lock().unwrap().send((m, att));
        })
        .unwrap();
    let raw = a.declare_publisher(sub.key().to_owned()).wait().unwrap();
    let mut good = Vec::new();
    encode(&pose(9), &mut good).unwrap();
    let start = Instant::now();
    loop {
        // Garbage first, then a valid sample without attachment.
        raw.put(vec![0u8, 1, 0, 0, 1]).wait().unwrap();
        raw.put(good.clone()).wait().unwrap();
        if let Ok((m, att)) = rx.recv_timeout(Duration::from_millis(100)) {
            assert_eq!(m, pose(9), "only the valid sample is delivered");
            assert_eq!(att, None, "plain zenoh puts carry no attachment");
            break;
        }
        assert!(start.elapsed() < DEADLINE, "nothing delivered");
    }
}
