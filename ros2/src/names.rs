//! ROS 2 name rules (rmw's `validate_node_name`, `validate_namespace`,
//! rcl's topic name rules) and rmw_zenoh's name transforms.
//!
//! A name that breaks these rules is refused here, with the rule, instead of
//! producing a token that every rmw_zenoh process rejects with "Received
//! invalid liveliness token" and nothing else.

use std::fmt;

/// Longest node name rmw accepts (`RMW_NODE_NAME_MAX_NAME_LENGTH`).
pub const NODE_NAME_MAX_LEN: usize = 255;
/// Longest fully qualified topic name (`RMW_TOPIC_MAX_NAME_LENGTH`, 255
/// minus 8 reserved for DDS prefixes).
pub const TOPIC_NAME_MAX_LEN: usize = 247;
/// Longest namespace (`RMW_NAMESPACE_MAX_LENGTH`: room for the shortest
/// topic `/X` after it).
pub const NAMESPACE_MAX_LEN: usize = TOPIC_NAME_MAX_LEN - 2;

/// What kind of name was checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NameKind {
    /// A node name such as `pose_publisher`.
    Node,
    /// A namespace such as `/` or `/robot1`.
    Namespace,
    /// A topic name, relative (`pose`) or absolute (`/robot1/pose`).
    Topic,
}

impl fmt::Display for NameKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NameKind::Node => "node name",
            NameKind::Namespace => "namespace",
            NameKind::Topic => "topic name",
        })
    }
}

/// A name breaks a ROS 2 naming rule.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NameError {
    /// The name is empty.
    #[error("{kind} is empty")]
    Empty {
        /// Which kind of name.
        kind: NameKind,
    },
    /// A character outside `[A-Za-z0-9_]` (and `/` where separators are allowed).
    #[error(
        "{kind} {name:?} has {ch:?} at byte {index}: only A-Z, a-z, 0-9 and '_'{sep} are allowed"
    )]
    InvalidChar {
        /// Which kind of name.
        kind: NameKind,
        /// The name.
        name: String,
        /// The offending character.
        ch: char,
        /// Its byte offset.
        index: usize,
        /// `" (and '/' between tokens)"` where slashes are allowed.
        sep: &'static str,
    },
    /// A token (the name, or a part between slashes) starts with a digit.
    #[error("{kind} {name:?}: the token {token:?} starts with a digit")]
    StartsWithDigit {
        /// Which kind of name.
        kind: NameKind,
        /// The name.
        name: String,
        /// The offending token.
        token: String,
    },
    /// Two slashes in a row (an empty token).
    #[error("{kind} {name:?} contains \"//\"")]
    RepeatedSlash {
        /// Which kind of name.
        kind: NameKind,
        /// The name.
        name: String,
    },
    /// A trailing slash (only the root namespace `/` may end in one).
    #[error("{kind} {name:?} ends with '/'")]
    TrailingSlash {
        /// Which kind of name.
        kind: NameKind,
        /// The name.
        name: String,
    },
    /// A namespace must be absolute.
    #[error("namespace {name:?} must start with '/' (e.g. \"/\" or \"/robot1\")")]
    NotAbsolute {
        /// The name.
        name: String,
    },
    /// Private (`~`) and substitution (`{node}`) topic names need rcl's
    /// expansion, which this crate does not do.
    #[error(
        "topic name {name:?}: '~' and '{{...}}' substitutions are not supported; give the name in full"
    )]
    Unexpanded {
        /// The name.
        name: String,
    },
    /// Longer than rmw allows.
    #[error("{kind} {name:?} is {len} characters long; the limit is {max}")]
    TooLong {
        /// Which kind of name.
        kind: NameKind,
        /// The name.
        name: String,
        /// Its length.
        len: usize,
        /// The limit.
        max: usize,
    },
}

fn is_name_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// Checks the `/`-separated tokens of `name` (which has no leading slash).
fn check_tokens(kind: NameKind, full: &str, offset: usize, body: &str) -> Result<(), NameError> {
    for (i, c) in body.char_indices() {
        if !(is_name_char(c) || c == '/') {
            return Err(NameError::InvalidChar {
                kind,
                name: full.to_owned(),
                ch: c,
                index: offset + i,
                sep: " (and '/' between tokens)",
            });
        }
    }
    if body.contains("//") {
        return Err(NameError::RepeatedSlash {
            kind,
            name: full.to_owned(),
        });
    }
    if body.ends_with('/') {
        return Err(NameError::TrailingSlash {
            kind,
            name: full.to_owned(),
        });
    }
    if let Some(token) = body
        .split('/')
        .find(|t| t.starts_with(|c: char| c.is_ascii_digit()))
    {
        return Err(NameError::StartsWithDigit {
            kind,
            name: full.to_owned(),
            token: token.to_owned(),
        });
    }
    Ok(())
}

fn check_len(kind: NameKind, name: &str, max: usize) -> Result<(), NameError> {
    if name.len() > max {
        return Err(NameError::TooLong {
            kind,
            name: name.to_owned(),
            len: name.len(),
            max,
        });
    }
    Ok(())
}

/// Validates a node name: one token of `[A-Za-z0-9_]`, not starting with a
/// digit, at most 255 characters.
pub fn validate_node_name(name: &str) -> Result<(), NameError> {
    let kind = NameKind::Node;
    if name.is_empty() {
        return Err(NameError::Empty { kind });
    }
    if let Some((index, ch)) = name.char_indices().find(|&(_, c)| !is_name_char(c)) {
        return Err(NameError::InvalidChar {
            kind,
            name: name.to_owned(),
            ch,
            index,
            sep: "",
        });
    }
    check_tokens(kind, name, 0, name)?;
    check_len(kind, name, NODE_NAME_MAX_LEN)
}

/// Validates a namespace: `/`, or `/a/b` with tokens of `[A-Za-z0-9_]` not
/// starting with a digit, no `//`, no trailing `/`.
pub fn validate_namespace(namespace: &str) -> Result<(), NameError> {
    let kind = NameKind::Namespace;
    if namespace.is_empty() {
        return Err(NameError::Empty { kind });
    }
    let Some(body) = namespace.strip_prefix('/') else {
        return Err(NameError::NotAbsolute {
            name: namespace.to_owned(),
        });
    };
    if !body.is_empty() {
        check_tokens(kind, namespace, 1, body)?;
    }
    check_len(kind, namespace, NAMESPACE_MAX_LEN)
}

/// Validates a topic name, relative (`pose`, `camera/info`) or absolute
/// (`/robot1/pose`), by the same token rules as a namespace. `~` and `{}`
/// substitutions are refused.
pub fn validate_topic_name(topic: &str) -> Result<(), NameError> {
    let kind = NameKind::Topic;
    if topic.is_empty() {
        return Err(NameError::Empty { kind });
    }
    if topic.contains(['~', '{', '}']) {
        return Err(NameError::Unexpanded {
            name: topic.to_owned(),
        });
    }
    let (offset, body) = match topic.strip_prefix('/') {
        Some(body) => (1, body),
        None => (0, topic),
    };
    if body.is_empty() {
        // "/" alone: a namespace, not a topic.
        return Err(NameError::TrailingSlash {
            kind,
            name: topic.to_owned(),
        });
    }
    if body.starts_with('/') {
        return Err(NameError::RepeatedSlash {
            kind,
            name: topic.to_owned(),
        });
    }
    check_tokens(kind, topic, offset, body)?;
    check_len(kind, topic, TOPIC_NAME_MAX_LEN)
}

/// The fully qualified name of `topic` in `namespace`: a relative name goes
/// under the namespace, an absolute one stays as it is. Both are validated.
pub fn resolve_topic(namespace: &str, topic: &str) -> Result<String, NameError> {
    validate_namespace(namespace)?;
    validate_topic_name(topic)?;
    let full = if topic.starts_with('/') {
        topic.to_owned()
    } else if namespace == "/" {
        format!("/{topic}")
    } else {
        format!("{namespace}/{topic}")
    };
    check_len(NameKind::Topic, &full, TOPIC_NAME_MAX_LEN)?;
    Ok(full)
}

/// rmw_zenoh's `mangle_name`: every `/` becomes `%`, so a ROS name fits in
/// one chunk of a liveliness key (`/` → `%`, `/robot1/pose` → `%robot1%pose`).
pub fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// rmw_zenoh's `strip_slashes`: drops one leading and one trailing `/`, so
/// `/robot1/pose` becomes `robot1/pose` in the data key (inner slashes stay).
pub fn strip_slashes(name: &str) -> &str {
    let name = name.strip_prefix('/').unwrap_or(name);
    name.strip_suffix('/').unwrap_or(name)
}
