//! rosbag2-compatible bags: a directory with one MCAP file (profile `ros2`,
//! `ros2msg` schemas, `cdr` channels) and the `metadata.yaml` that
//! `ros2 bag info`, `ros2 bag play` and `rosbags` need to open it.

use crate::graph::Qos;
use crate::msg::Message;
use crate::names::{self, NameError};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};

/// The rosbag2 metadata version written (Jazzy's).
pub const ROSBAG2_VERSION: u32 = 9;

/// Writing a bag failed.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The directory already holds files; a bag never overwrites a recording.
    #[error(
        "bag directory {path} already exists and is not empty; refusing to overwrite a recording"
    )]
    NotEmpty {
        /// The directory.
        path: PathBuf,
    },
    /// The path exists and is a file.
    #[error("bag path {path} exists and is not a directory")]
    NotADirectory {
        /// The path.
        path: PathBuf,
    },
    /// The MCAP file is named after the directory, which needs a UTF-8 name.
    #[error("bag path {path} has no UTF-8 final component to name the .mcap file after")]
    NoName {
        /// The path.
        path: PathBuf,
    },
    /// A file-system operation failed.
    #[error("{what} {path}")]
    Io {
        /// What was being done.
        what: &'static str,
        /// On which path.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP writer failed.
    #[error("MCAP: {what} in {path}")]
    Mcap {
        /// What was being done.
        what: String,
        /// The MCAP file.
        path: PathBuf,
        /// What the mcap crate said.
        #[source]
        source: mcap::McapError,
    },
    /// A topic name breaks the ROS rules.
    #[error(transparent)]
    Name(#[from] NameError),
    /// The topic is already in the bag with another type.
    #[error(
        "topic {topic} is already in the bag as {existing}; cannot add it again as {requested}"
    )]
    TypeConflict {
        /// The topic.
        topic: String,
        /// Its type in the bag.
        existing: &'static str,
        /// The type asked for.
        requested: &'static str,
    },
    /// A [`TopicId`] this writer did not hand out.
    #[error("topic id {id} is not one of this bag's {count} topics")]
    UnknownTopic {
        /// The id.
        id: usize,
        /// How many topics the bag has.
        count: usize,
    },
    /// The bytes do not start with a plain CDR encapsulation header; rosbag2
    /// stores the header with every message.
    #[error(
        "message for {topic} ({len} bytes) does not start with a CDR header (00 01 00 00 or 00 00 00 00)"
    )]
    NotCdr {
        /// The topic.
        topic: String,
        /// The length of what was passed.
        len: usize,
    },
}

/// A topic of one [`BagWriter`], from [`BagWriter::add_topic`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TopicId(usize);

struct Topic {
    channel_id: u16,
    name: String,
    type_name: &'static str,
    type_hash: &'static str,
    qos: Qos,
    count: u64,
}

/// Writes one rosbag2 bag. Call [`finish`](Self::finish) to close it; if it
/// is dropped instead, it is finished then and errors are only logged.
pub struct BagWriter {
    dir: PathBuf,
    file_name: String,
    mcap_path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    distro: String,
    schemas: HashMap<&'static str, u16>,
    topics: Vec<Topic>,
    /// Smallest and largest log time written.
    bounds: Option<(u64, u64)>,
}

impl std::fmt::Debug for BagWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagWriter")
            .field("mcap", &self.mcap_path)
            .field("topics", &self.topics.len())
            .finish_non_exhaustive()
    }
}

fn io_err(what: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> BagError {
    let path = path.to_owned();
    move |source| BagError::Io { what, path, source }
}

/// A YAML double-quoted scalar: JSON string syntax is valid YAML, so
/// serde_json does the escaping.
fn quote(s: &str) -> String {
    serde_json::Value::String(s.to_owned()).to_string()
}

impl BagWriter {
    /// Creates the bag directory `dir` (it may exist if empty) and
    /// `<dir>/<dirname>_0.mcap` in it. `distro_name` goes into the
    /// metadata's `ros_distro` (e.g. `jazzy`).
    pub fn create(dir: &Path, distro_name: &str) -> Result<BagWriter, BagError> {
        match std::fs::metadata(dir) {
            Ok(m) if !m.is_dir() => {
                return Err(BagError::NotADirectory {
                    path: dir.to_owned(),
                });
            }
            Ok(_) => {
                let mut entries =
                    std::fs::read_dir(dir).map_err(io_err("listing the bag directory", dir))?;
                if entries.next().is_some() {
                    return Err(BagError::NotEmpty {
                        path: dir.to_owned(),
                    });
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                std::fs::create_dir_all(dir).map_err(io_err("creating the bag directory", dir))?;
            }
            Err(e) => return Err(io_err("reading the bag directory", dir)(e)),
        }
        let stem = dir
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| BagError::NoName {
                path: dir.to_owned(),
            })?;
        let file_name = format!("{stem}_0.mcap");
        let mcap_path = dir.join(&file_name);
        // create_new: even a race with another recorder cannot clobber a file.
        let file = File::create_new(&mcap_path).map_err(io_err("creating", &mcap_path))?;
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library("acch")
            .compression(Some(mcap::Compression::Zstd))
            .create(BufWriter::new(file))
            .map_err(|source| BagError::Mcap {
                what: "writing the header".into(),
                path: mcap_path.clone(),
                source,
            })?;
        Ok(BagWriter {
            dir: dir.to_owned(),
            file_name,
            mcap_path,
            writer: Some(writer),
            distro: distro_name.to_owned(),
            schemas: HashMap::new(),
            topics: Vec::new(),
            bounds: None,
        })
    }

    /// The MCAP file being written.
    pub fn mcap_path(&self) -> &Path {
        &self.mcap_path
    }

    fn mcap_err(&self, what: String) -> impl FnOnce(mcap::McapError) -> BagError + '_ {
        move |source| BagError::Mcap {
            what,
            path: self.mcap_path.clone(),
            source,
        }
    }

    fn writer(&mut self) -> &mut mcap::Writer<BufWriter<File>> {
        // Only finish_inner takes the writer, and nothing runs after it.
        self.writer
            .as_mut()
            .unwrap_or_else(|| unreachable!("BagWriter used after finish"))
    }

    /// Adds a topic of type `M` (a relative name gets a leading `/`) with
    /// the QoS its publisher offers. The schema is written once per type;
    /// adding the same topic and type again returns the same id.
    pub fn add_topic<M: Message>(&mut self, topic: &str, qos: Qos) -> Result<TopicId, BagError> {
        let topic = names::resolve_topic("/", topic)?;
        if let Some(i) = self.topics.iter().position(|t| t.name == topic) {
            let existing = self.topics[i].type_name;
            if existing != M::TYPE {
                return Err(BagError::TypeConflict {
                    topic,
                    existing,
                    requested: M::TYPE,
                });
            }
            return Ok(TopicId(i));
        }
        let schema_id = match self.schemas.get(M::TYPE) {
            Some(&id) => id,
            None => {
                let id = self
                    .writer()
                    .add_schema(M::TYPE, "ros2msg", M::DEFINITION.as_bytes());
                let id = id.map_err(self.mcap_err(format!("adding the schema {}", M::TYPE)))?;
                self.schemas.insert(M::TYPE, id);
                id
            }
        };
        let mut qos_yaml = qos.to_rosbag2_yaml(0);
        // rosbag2 stores YAML::Dump output, which has no final newline.
        qos_yaml.pop();
        let metadata = BTreeMap::from([
            ("offered_qos_profiles".to_owned(), qos_yaml),
            ("topic_type_hash".to_owned(), M::TYPE_HASH.to_owned()),
        ]);
        let channel_id = self
            .writer()
            .add_channel(schema_id, &topic, "cdr", &metadata);
        let channel_id =
            channel_id.map_err(self.mcap_err(format!("adding the channel {topic}")))?;
        self.topics.push(Topic {
            channel_id,
            name: topic,
            type_name: M::TYPE,
            type_hash: M::TYPE_HASH,
            qos,
            count: 0,
        });
        Ok(TopicId(self.topics.len() - 1))
    }

    /// Writes one message: `cdr` is the full CDR payload, header included
    /// (the zenoh payload as received). `log_time_ns` is when it was
    /// received or recorded, `publish_time_ns` when it was sent.
    pub fn write(
        &mut self,
        topic: TopicId,
        log_time_ns: u64,
        publish_time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let count = self.topics.len();
        let t = self
            .topics
            .get(topic.0)
            .ok_or(BagError::UnknownTopic { id: topic.0, count })?;
        if !matches!(cdr, [0, 0 | 1, _, _, ..]) {
            return Err(BagError::NotCdr {
                topic: t.name.clone(),
                len: cdr.len(),
            });
        }
        let header = mcap::records::MessageHeader {
            channel_id: t.channel_id,
            sequence: 0,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        let result = self.writer().write_to_known_channel(&header, cdr);
        result.map_err(|source| BagError::Mcap {
            what: format!("writing a message on {}", self.topics[topic.0].name),
            path: self.mcap_path.clone(),
            source,
        })?;
        self.topics[topic.0].count += 1;
        self.bounds = Some(match self.bounds {
            None => (log_time_ns, log_time_ns),
            Some((lo, hi)) => (lo.min(log_time_ns), hi.max(log_time_ns)),
        });
        Ok(())
    }

    /// Writes the `rosbag2` metadata record and the MCAP summary, syncs the
    /// file, then writes `metadata.yaml` (atomically, via a rename).
    pub fn finish(mut self) -> Result<(), BagError> {
        self.finish_inner()
    }

    fn finish_inner(&mut self) -> Result<(), BagError> {
        let Some(mut writer) = self.writer.take() else {
            return Ok(());
        };
        let path = self.mcap_path.clone();
        let mcap_err = |what: &str| {
            let path = path.clone();
            let what = what.to_owned();
            move |source| BagError::Mcap { what, path, source }
        };
        let record = mcap::records::Metadata {
            name: "rosbag2".into(),
            metadata: BTreeMap::from([("serialized_metadata".to_owned(), self.metadata_yaml(0))]),
        };
        writer
            .write_metadata(&record)
            .map_err(mcap_err("writing the rosbag2 metadata record"))?;
        writer.finish().map_err(mcap_err("writing the summary"))?;
        let file = writer
            .into_inner()
            .into_inner()
            .map_err(|e| io_err("flushing", &path)(e.into_error()))?;
        file.sync_all().map_err(io_err("syncing", &path))?;

        let yaml = format!("rosbag2_bagfile_information:\n{}", self.metadata_yaml(2));
        let final_path = self.dir.join("metadata.yaml");
        let tmp = self.dir.join("metadata.yaml.tmp");
        let mut f = File::create(&tmp).map_err(io_err("creating", &tmp))?;
        f.write_all(yaml.as_bytes())
            .and_then(|()| f.sync_all())
            .map_err(io_err("writing", &tmp))?;
        std::fs::rename(&tmp, &final_path).map_err(io_err("renaming into place", &final_path))
    }

    /// The bag metadata in rosbag2 Jazzy's (version 9) layout and key
    /// order, every line indented by `indent` spaces.
    fn metadata_yaml(&self, indent: usize) -> String {
        let p = " ".repeat(indent);
        // An empty bag gets rosbag2's "no start yet" (time_point::max).
        let (start, duration) = match self.bounds {
            Some((lo, hi)) => (lo, hi - lo),
            None => (i64::MAX as u64, 0),
        };
        let total: u64 = self.topics.iter().map(|t| t.count).sum();
        let file = quote(&self.file_name);
        let mut s = String::new();
        // Writing to a String cannot fail.
        let _ = write!(
            s,
            "{p}version: {ROSBAG2_VERSION}\n\
             {p}storage_identifier: mcap\n\
             {p}duration:\n{p}  nanoseconds: {duration}\n\
             {p}starting_time:\n{p}  nanoseconds_since_epoch: {start}\n\
             {p}message_count: {total}\n"
        );
        if self.topics.is_empty() {
            let _ = writeln!(s, "{p}topics_with_message_count: []");
        } else {
            let _ = writeln!(s, "{p}topics_with_message_count:");
        }
        for t in &self.topics {
            let _ = write!(
                s,
                "{p}  - topic_metadata:\n\
                 {p}      name: {name}\n\
                 {p}      type: {ty}\n\
                 {p}      serialization_format: cdr\n\
                 {p}      offered_qos_profiles:\n{qos}\
                 {p}      type_description_hash: {hash}\n\
                 {p}    message_count: {count}\n",
                name = quote(&t.name),
                ty = quote(t.type_name),
                qos = t.qos.to_rosbag2_yaml(indent + 8),
                hash = quote(t.type_hash),
                count = t.count,
            );
        }
        let _ = write!(
            s,
            "{p}compression_format: \"\"\n\
             {p}compression_mode: \"\"\n\
             {p}relative_file_paths:\n{p}  - {file}\n\
             {p}files:\n\
             {p}  - path: {file}\n\
             {p}    starting_time:\n{p}      nanoseconds_since_epoch: {start}\n\
             {p}    duration:\n{p}      nanoseconds: {duration}\n\
             {p}    message_count: {total}\n\
             {p}custom_data: ~\n\
             {p}ros_distro: {distro}\n",
            distro = quote(&self.distro),
        );
        s
    }
}

impl Drop for BagWriter {
    fn drop(&mut self) {
        if self.writer.is_some()
            && let Err(e) = self.finish_inner()
        {
            tracing::warn!(bag = %self.dir.display(), error = %e, "closing the bag on drop failed");
        }
    }
}
