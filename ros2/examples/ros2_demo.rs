//! Publishes acch's ROS 2 topics with made-up values and records them to a
//! bag: the counterpart of `tests/ros2/check_ros2.py`, and a quick way to
//! see acch in `ros2 topic list` / `ros2 topic echo` on a ROS machine.
//!
//! ```text
//! cargo run --release -p acch-ros2 --example ros2_demo -- \
//!     --listen tcp/127.0.0.1:7447 --count 20 --period-ms 50 --bag /tmp/demo_bag
//! ```
//! Options: `--listen EP`, `--connect EP` (repeatable; with neither it
//! listens on tcp/127.0.0.1:7447), `--domain N`, `--count N`,
//! `--period-ms MS`, `--wait-ms MS` (before publishing, so that subscribers
//! can connect), `--linger-ms MS` (after, so that liveliness queries still
//! see the tokens), `--bag DIR`, `--legacy` (77-byte attachments),
//! `--humble` (no type hashes), `--image WxH` (default 640x480).

use acch_ros2::msg::{
    CameraInfo, Header, Image, ImageRef, PoseWithCovarianceStamped, Quaternion, TFMessage, Time,
    Transform, TransformStamped, Vector3,
};
use acch_ros2::{AttachmentFormat, BagWriter, Distro, Node, NodeConfig, Qos, Reliability, now_ns};
use std::path::PathBuf;
use std::time::Duration;
use zenoh::Wait;

struct Args {
    listen: Vec<String>,
    connect: Vec<String>,
    domain: u32,
    count: u32,
    period: Duration,
    wait: Duration,
    linger: Duration,
    bag: Option<PathBuf>,
    legacy: bool,
    humble: bool,
    image: (u32, u32),
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        listen: Vec::new(),
        connect: Vec::new(),
        domain: 0,
        count: 20,
        period: Duration::from_millis(50),
        wait: Duration::from_millis(1000),
        linger: Duration::from_millis(3000),
        bag: None,
        legacy: false,
        humble: false,
        image: (640, 480),
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let num = |s: String| s.parse::<u64>().map_err(|e| format!("{flag} {s}: {e}"));
        match flag.as_str() {
            "--listen" => a.listen.push(value()?),
            "--connect" => a.connect.push(value()?),
            "--domain" => a.domain = num(value()?)? as u32,
            "--count" => a.count = num(value()?)? as u32,
            "--period-ms" => a.period = Duration::from_millis(num(value()?)?),
            "--wait-ms" => a.wait = Duration::from_millis(num(value()?)?),
            "--linger-ms" => a.linger = Duration::from_millis(num(value()?)?),
            "--bag" => a.bag = Some(value()?.into()),
            "--legacy" => a.legacy = true,
            "--humble" => a.humble = true,
            "--image" => {
                let v = value()?;
                let (w, h) = v.split_once('x').ok_or(format!("--image {v}: want WxH"))?;
                a.image = (num(w.into())? as u32, num(h.into())? as u32);
            }
            _ => return Err(format!("unknown argument {flag}")),
        }
    }
    if a.listen.is_empty() && a.connect.is_empty() {
        a.listen.push("tcp/127.0.0.1:7447".into());
    }
    Ok(a)
}

fn open_session(listen: &[String], connect: &[String]) -> Result<zenoh::Session, String> {
    let mut c = zenoh::Config::default();
    let json = |v: &[String]| serde_json::to_string(v).unwrap_or_else(|_| "[]".into());
    for (k, v) in [
        ("mode", "\"peer\"".to_owned()),
        ("scouting/multicast/enabled", "false".to_owned()),
        ("scouting/gossip/enabled", "false".to_owned()),
        ("listen/endpoints", json(listen)),
        ("connect/endpoints", json(connect)),
    ] {
        c.insert_json5(k, &v)
            .map_err(|e| format!("zenoh configuration {k} = {v}: {e}"))?;
    }
    zenoh::open(c)
        .wait()
        .map_err(|e| format!("opening the zenoh session: {e}"))
}

fn header(ns: i64, frame: &str) -> Header {
    Header {
        stamp: Time::from_ns(ns.max(0) as u64),
        frame_id: frame.into(),
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse_args()?;
    let session = open_session(&args.listen, &args.connect)?;
    let node = Node::new(
        &session,
        NodeConfig {
            domain_id: args.domain,
            namespace: "/acch".into(),
            name: "tracker".into(),
            distro: if args.humble {
                Distro::Humble
            } else {
                Distro::Jazzy
            },
            attachment: if args.legacy {
                AttachmentFormat::Legacy
            } else {
                AttachmentFormat::Current
            },
        },
    )?;
    let sensor = Qos {
        reliability: Reliability::BestEffort,
        history_depth: 5,
        ..Qos::default()
    };
    let mut seed = node.publisher::<PoseWithCovarianceStamped>("fruitbox/seed", Qos::default())?;
    let mut info = node.publisher::<CameraInfo>("camera/camera_info", sensor)?;
    let mut image = node.publisher::<Image>("camera/image_raw", sensor)?;
    let mut tf = node.publisher::<TFMessage>("/tf", Qos::default())?;
    // A subscriber too, so that the graph shows an MS token.
    let _echo = node.subscriber::<PoseWithCovarianceStamped, _>(
        "fruitbox/seed",
        Qos::default(),
        |m, att| {
            tracing::debug!(x = m.pose.pose.position.x, ?att, "echo");
        },
    )?;

    let mut bag = match &args.bag {
        Some(dir) => {
            let mut bag = BagWriter::create(dir, Distro::Jazzy.name())?;
            let ids = (
                bag.add_topic::<PoseWithCovarianceStamped>(seed.topic(), Qos::default())?,
                bag.add_topic::<CameraInfo>(info.topic(), sensor)?,
                bag.add_topic::<Image>(image.topic(), sensor)?,
                bag.add_topic::<TFMessage>(tf.topic(), Qos::default())?,
            );
            Some((bag, ids))
        }
        None => None,
    };

    eprintln!("{}", node.token());
    for t in [seed.token(), info.token(), image.token(), tf.token()] {
        eprintln!("{t}");
    }
    std::thread::sleep(args.wait);

    let (w, h) = args.image;
    let pixels: Vec<u8> = (0..w as usize * h as usize * 3)
        .map(|i| (i % 256) as u8)
        .collect();
    for i in 0..args.count {
        let ns = now_ns();
        let t = f64::from(i) * 0.1;
        let mut pose = PoseWithCovarianceStamped {
            header: header(ns, "camera_optical"),
            ..Default::default()
        };
        pose.pose.pose.position = glam::DVec3::new(0.1 * t.cos(), 0.1 * t.sin(), 0.8).into();
        pose.pose.pose.orientation = glam::DQuat::from_rotation_y(t).into();
        for k in 0..6 {
            pose.pose.covariance[k * 7] = 0.001 * (k + 1) as f64;
        }
        seed.publish(&pose, ns)?;

        let fx = 525.0;
        let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
        let cam = CameraInfo {
            header: header(ns, "camera_optical"),
            height: h,
            width: w,
            distortion_model: "plumb_bob".into(),
            d: vec![0.01, -0.02, 0.0, 0.0, 0.0],
            k: [fx, 0.0, cx, 0.0, fx, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, 0.0, 0.0, fx, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            ..Default::default()
        };
        info.publish(&cam, ns)?;

        let img_header = header(ns, "camera_optical");
        image.publish_as(
            &ImageRef {
                header: &img_header,
                height: h,
                width: w,
                encoding: "rgb8",
                is_bigendian: 0,
                step: w * 3,
                data: &pixels,
            },
            ns,
        )?;

        let transform = |parent: &str, child: &str, z: f64, q: Quaternion| TransformStamped {
            header: header(ns, parent),
            child_frame_id: child.into(),
            transform: Transform {
                translation: Vector3 { x: 0.0, y: 0.0, z },
                rotation: q,
            },
        };
        tf.publish(
            &TFMessage {
                transforms: vec![
                    transform("world", "camera_optical", 1.2, Quaternion::default()),
                    transform(
                        "camera_optical",
                        "fruitbox",
                        0.8,
                        pose.pose.pose.orientation,
                    ),
                ],
            },
            ns,
        )?;

        if let Some((bag, (s, c, im, t))) = &mut bag {
            let log = now_ns().max(0) as u64;
            let sent = ns.max(0) as u64;
            bag.write(*s, log, sent, seed.last_payload())?;
            bag.write(*c, log, sent, info.last_payload())?;
            bag.write(*im, log, sent, image.last_payload())?;
            bag.write(*t, log, sent, tf.last_payload())?;
        }
        std::thread::sleep(args.period);
    }
    if let Some((bag, _)) = bag {
        bag.finish()?;
    }
    std::thread::sleep(args.linger);
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        let mut msg = e.to_string();
        let mut source = e.source();
        while let Some(s) = source {
            msg.push_str(&format!(": {s}"));
            source = s.source();
        }
        eprintln!("ros2_demo: {msg}");
        std::process::exit(1);
    }
}
