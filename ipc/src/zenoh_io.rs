//! zenoh: peer mode, loopback by default, no scouting; the seed and the
//! result of every frame leave the machine here.

use crate::IpcError;
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

fn zerr<E: std::fmt::Display>(what: &'static str) -> impl FnOnce(E) -> IpcError {
    move |e| IpcError::Zenoh(format!("{what}: {e}"))
}

/// Opens a peer session on `listen` / `connect` with multicast and gossip
/// scouting off.
pub fn open_session(listen: &[String], connect: &[String]) -> Result<zenoh::Session, IpcError> {
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
        c.insert_json5(k, &v).map_err(zerr("zenoh configuration"))?;
    }
    zenoh::open(c)
        .wait()
        .map_err(zerr("opening the zenoh session (is the port in use?)"))
}

/// The publishers of one object's seeds and results.
pub struct SeedPublisher {
    session: zenoh::Session,
    seed_key: String,
    result_key: String,
}

impl SeedPublisher {
    /// Opens the session of `config` for `object`.
    pub fn new(config: &ZenohConfig, object: &str) -> Result<Self, IpcError> {
        let session = open_session(&config.listen, &config.connect)?;
        Ok(SeedPublisher {
            session,
            seed_key: format!("{}/{object}/seed", config.prefix),
            result_key: format!("{}/{object}/result", config.prefix),
        })
    }

    /// The seed key expression.
    pub fn seed_key(&self) -> &str {
        &self.seed_key
    }

    /// Publishes a seed (JSON).
    pub fn put_seed(&self, json: Vec<u8>) -> Result<(), IpcError> {
        use zenoh::Wait;
        self.session
            .put(&self.seed_key, json)
            .wait()
            .map_err(zerr("publishing the seed"))
    }

    /// Publishes a per-frame result (JSON).
    pub fn put_result(&self, json: Vec<u8>) -> Result<(), IpcError> {
        use zenoh::Wait;
        self.session
            .put(&self.result_key, json)
            .wait()
            .map_err(zerr("publishing the result"))
    }
}
