//! ROS 2 name rules and rmw_zenoh's name transforms.

use acch_ros2::NameError;
use acch_ros2::names::*;

#[test]
fn valid_names_pass() {
    for n in ["acch", "pose_publisher", "_private", "Node2"] {
        validate_node_name(n).unwrap_or_else(|e| panic!("{n}: {e}"));
    }
    for ns in ["/", "/robot1", "/a/b_c/D9"] {
        validate_namespace(ns).unwrap_or_else(|e| panic!("{ns}: {e}"));
    }
    for t in [
        "pose",
        "/pose",
        "camera/camera_info",
        "/acch/fruitbox/seed",
        "_x",
    ] {
        validate_topic_name(t).unwrap_or_else(|e| panic!("{t}: {e}"));
    }
}

#[test]
fn node_name_errors_name_the_rule() {
    assert_eq!(
        validate_node_name(""),
        Err(NameError::Empty {
            kind: NameKind::Node
        })
    );
    assert_eq!(
        validate_node_name("my-node"),
        Err(NameError::InvalidChar {
            kind: NameKind::Node,
            name: "my-node".into(),
            ch: '-',
            index: 2,
            sep: "",
        })
    );
    assert!(matches!(
        validate_node_name("a/b"),
        Err(NameError::InvalidChar {
            ch: '/',
            index: 1,
            ..
        })
    ));
    assert_eq!(
        validate_node_name("9lives"),
        Err(NameError::StartsWithDigit {
            kind: NameKind::Node,
            name: "9lives".into(),
            token: "9lives".into(),
        })
    );
    let long = "n".repeat(256);
    assert!(matches!(
        validate_node_name(&long),
        Err(NameError::TooLong {
            len: 256,
            max: 255,
            ..
        })
    ));
    let e = validate_node_name("my-node").unwrap_err().to_string();
    assert!(
        e.contains("\"my-node\"") && e.contains("'-'") && e.contains("byte 2"),
        "{e}"
    );
}

#[test]
fn namespace_errors_name_the_rule() {
    assert_eq!(
        validate_namespace(""),
        Err(NameError::Empty {
            kind: NameKind::Namespace
        })
    );
    assert_eq!(
        validate_namespace("robot1"),
        Err(NameError::NotAbsolute {
            name: "robot1".into()
        })
    );
    assert_eq!(
        validate_namespace("/a//b"),
        Err(NameError::RepeatedSlash {
            kind: NameKind::Namespace,
            name: "/a//b".into()
        })
    );
    assert_eq!(
        validate_namespace("/a/"),
        Err(NameError::TrailingSlash {
            kind: NameKind::Namespace,
            name: "/a/".into()
        })
    );
    assert_eq!(
        validate_namespace("/a/1b"),
        Err(NameError::StartsWithDigit {
            kind: NameKind::Namespace,
            name: "/a/1b".into(),
            token: "1b".into()
        })
    );
    assert!(matches!(
        validate_namespace("/a b"),
        Err(NameError::InvalidChar {
            ch: ' ',
            index: 2,
            ..
        })
    ));
    assert!(matches!(
        validate_namespace("/ü"),
        Err(NameError::InvalidChar {
            ch: 'ü',
            index: 1,
            ..
        })
    ));
    let long = format!("/{}", "n".repeat(245));
    assert!(matches!(
        validate_namespace(&long),
        Err(NameError::TooLong { max: 245, .. })
    ));
}

#[test]
fn topic_errors_name_the_rule() {
    assert_eq!(
        validate_topic_name(""),
        Err(NameError::Empty {
            kind: NameKind::Topic
        })
    );
    assert!(matches!(
        validate_topic_name("/"),
        Err(NameError::TrailingSlash { .. })
    ));
    assert!(matches!(
        validate_topic_name("//pose"),
        Err(NameError::RepeatedSlash { .. })
    ));
    assert!(matches!(
        validate_topic_name("pose/"),
        Err(NameError::TrailingSlash { .. })
    ));
    assert!(matches!(
        validate_topic_name("a//b"),
        Err(NameError::RepeatedSlash { .. })
    ));
    assert!(matches!(
        validate_topic_name("/cam/0image"),
        Err(NameError::StartsWithDigit { token, .. }) if token == "0image"
    ));
    assert!(matches!(
        validate_topic_name("~/pose"),
        Err(NameError::Unexpanded { .. })
    ));
    assert!(matches!(
        validate_topic_name("{node}/pose"),
        Err(NameError::Unexpanded { .. })
    ));
    assert!(matches!(
        validate_topic_name("/pose*"),
        Err(NameError::InvalidChar {
            ch: '*',
            index: 5,
            ..
        })
    ));
}

#[test]
fn resolve_puts_relative_names_under_the_namespace() {
    assert_eq!(resolve_topic("/", "pose").unwrap(), "/pose");
    assert_eq!(resolve_topic("/robot1", "pose").unwrap(), "/robot1/pose");
    assert_eq!(
        resolve_topic("/robot1", "cam/info").unwrap(),
        "/robot1/cam/info"
    );
    assert_eq!(resolve_topic("/robot1", "/tf").unwrap(), "/tf");
    assert!(matches!(
        resolve_topic("robot1", "pose"),
        Err(NameError::NotAbsolute { .. })
    ));
    assert!(matches!(
        resolve_topic("/", "pose/"),
        Err(NameError::TrailingSlash { .. })
    ));
    // Each part fits, the whole does not.
    let ns = format!("/{}", "n".repeat(200));
    let topic = "t".repeat(60);
    assert!(matches!(
        resolve_topic(&ns, &topic),
        Err(NameError::TooLong {
            kind: NameKind::Topic,
            len: 262,
            max: 247,
            ..
        })
    ));
}

#[test]
fn mangle_and_strip_slashes_follow_rmw_zenoh() {
    assert_eq!(mangle("/"), "%");
    assert_eq!(mangle("/robot1"), "%robot1");
    assert_eq!(mangle("/a/b/c"), "%a%b%c");
    assert_eq!(mangle("node"), "node");
    assert_eq!(strip_slashes("/pose"), "pose");
    assert_eq!(strip_slashes("/robot1/chatter/"), "robot1/chatter");
    assert_eq!(strip_slashes("plain"), "plain");
    assert_eq!(
        strip_slashes("//x//"),
        "/x/",
        "only one slash each side, as in C++"
    );
    assert_eq!(strip_slashes(""), "");
}
