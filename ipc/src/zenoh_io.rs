//! zenoh: peer mode, loopback by default, no scouting; the seed and the
//! result of every frame leave the machine here.

use crate::error::ZenohError;
use serde::{Deserialize, Serialize};

/// Where zenoh listens and whom it connects to.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohConfig {
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7447` (loopback default;
    /// `tcp/0.0.0.0:7447` lets a tracker on another machine connect).
    pub listen: Vec<String>,
    /// Endpoints to connect to (a router, or a peer on another machine).
    pub connect: Vec<String>,
    /// Key prefix: results go to `<prefix>/<object>/seed` and `.../result`.
    pub prefix: String,
}

impl Default for ZenohConfig {
    fn default() -> Self {
        ZenohConfig {
            listen: vec!["tcp/127.0.0.1:7447".into()],
            connect: Vec::new(),
            prefix: "acch".into(),
        }
    }
}

fn zerr(what: impl Into<String>) -> impl FnOnce(zenoh::Error) -> ZenohError {
    move |source| ZenohError {
        what: what.into(),
        source,
    }
}

/// Opens a peer session on `listen` / `connect` with multicast and gossip
/// scouting off.
pub fn open_session(listen: &[String], connect: &[String]) -> Result<zenoh::Session, ZenohError> {
    use zenoh::Wait;
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
            .map_err(zerr(format!("configuration {k} = {v}")))?;
    }
    zenoh::open(c)
        .wait()
        .map_err(zerr("opening the session (is the port in use?)"))
}

/// A publisher declared once on one key.
pub struct Publisher {
    publisher: zenoh::pubsub::Publisher<'static>,
    key: String,
}

impl Publisher {
    /// Declares a publisher on `key` in `session`.
    pub fn declare(session: &zenoh::Session, key: &str) -> Result<Self, ZenohError> {
        use zenoh::Wait;
        let publisher = session
            .declare_publisher(key.to_owned())
            .wait()
            .map_err(zerr(format!("declaring a publisher on {key}")))?;
        Ok(Publisher {
            publisher,
            key: key.to_owned(),
        })
    }

    /// Its key expression.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Publishes `bytes` (zenoh takes its own copy).
    pub fn put(&self, bytes: &[u8]) -> Result<(), ZenohError> {
        use zenoh::Wait;
        self.publisher
            .put(bytes)
            .wait()
            .map_err(zerr(format!("publishing on {}", self.key)))
    }
}
