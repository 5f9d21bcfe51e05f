//! The pipeline's configuration (`pipeline.toml`): every process of a run
//! reads the same file, every key is optional. A struct per TOML table
//! (`[object]`, `[camera]`, ..., [`Ros2Config`] for `[ros2]`) checks its
//! own keys; a refused key is named dotted (`camera.fps`). The settings
//! made from it live here too: [`StageSettings`] (what every stage is
//! built with). This module imports none of the stages, sinks or ROS 2
//! code that read them.

use crate::source::{CameraFile, SourceSpec, SyntheticCamera, SyntheticGroup};
use crate::source_error::SourceError;
use acch_capture::calibration::Calibration;
use acch_capture::{Background, DEFAULT_DISTANCE, Trajectory, UpAxis};
use acch_core::ViewDatabase;
use acch_ipc::sched::{self, Placement, StageCpus};
use acch_ipc::{Ipc, ZenohConfig};
use acch_ros2::names;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The pipeline's configuration: one TOML table per concern, each key
/// optional.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineConfig {
    /// `[object]`: the object to find, and its view database.
    pub object: ObjectConfig,
    /// `[objects]`: several known objects at once instead.
    pub objects: ObjectsConfig,
    /// `[camera]`: where frames come from, their size and pace.
    pub camera: CameraConfig,
    /// `[synthetic]`: the simulated scene and camera of `source =
    /// "synthetic"`.
    pub synthetic: SyntheticConfig,
    /// `[estimate]`: how recognition and pose estimate, and the recipe of
    /// the cached databases.
    pub estimate: EstimateConfig,
    /// `[run]`: the processes, their CPUs and how frames pass between
    /// them.
    pub run: RunConfig,
    /// `[observers]`: the viewer and the recorder.
    pub observers: ObserversConfig,
    /// `[zenoh]`: zenoh endpoints.
    pub zenoh: ZenohConfig,
    /// `[ros2]`: ROS 2 topics over zenoh, the rmw_zenoh way (no ROS
    /// installed).
    pub ros2: Ros2Config,
}

/// `[object]` of the pipeline's configuration: the one object a run finds.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectConfig {
    /// Built-in object name.
    pub name: String,
    /// A mesh file (.obj, .ply, .gltf or .glb) for the simulated scene
    /// instead of the built-in object (its default database is trained for
    /// it and cached).
    pub mesh: Option<PathBuf>,
    /// Which axis of `mesh` (and of `[objects]`' meshes) points up: +y
    /// (the OBJ and glTF convention), -y, +z, -z, +x or -x.
    #[serde(with = "by_name")]
    pub mesh_up: UpAxis,
    /// The unit of `mesh`'s coordinates, metres (unset: metres).
    pub mesh_unit_m: Option<f64>,
    /// The simulated object's real bounding radius, metres; unset = the
    /// built-in object's own size (for example 0.206 for `fruitbox`). The
    /// default database is trained for this size.
    pub radius_m: Option<f64>,
    /// View database; the launcher fills in the cached default.
    pub db: Option<PathBuf>,
    /// With `[estimate] smoothing = "auto"`: the smoothed set's database,
    /// trained from `db`'s object (`acch train --smoothing binomial
    /// --confidence-imaging`); the launcher fills in the cached one.
    pub smoothed_db: Option<PathBuf>,
    /// Where default databases are cached.
    pub cache_dir: Option<PathBuf>,
}

impl Default for ObjectConfig {
    fn default() -> Self {
        ObjectConfig {
            name: "fruitbox".into(),
            mesh: None,
            mesh_up: UpAxis::PosY,
            mesh_unit_m: None,
            radius_m: None,
            db: None,
            smoothed_db: None,
            cache_dir: None,
        }
    }
}

/// `[objects]` of the pipeline's configuration: several known objects
/// recognised in every frame (`acch run --objects`).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectsConfig {
    /// The objects, each a built-in name, `generated-N`, a mesh file or a
    /// view database (`.acchdb`). When set it replaces `[object]`'s
    /// `name`, `mesh` and `db`; the run is in one process
    /// (`--in-process`).
    pub list: Vec<String>,
    /// The view database of each of `list`, in order; the launcher fills
    /// in the cached defaults.
    pub dbs: Vec<PathBuf>,
    /// How many of `list` the simulated scene shows, the first ones (0:
    /// all).
    pub in_view: usize,
    /// Threads the objects' chains run on, kept for the run and each pinned
    /// to a CPU of its own when the run may use as many (0: one per CPU the
    /// run may use, at most one per object). With several objects and
    /// `[run] stage_cpus = "auto"` the run is not pinned, so they spread
    /// over every CPU.
    pub threads: usize,
}

/// `[camera]` of the pipeline's configuration: the frame stream, whatever
/// its source.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// `synthetic` (simulated camera, `[synthetic]`), `folder:DIR` (images,
    /// labels.csv), `mcap:FILE` (replays a recording of `acch run
    /// --record`), `gst:PIPELINE` (a GStreamer pipeline as gst-launch-1.0
    /// writes it, e.g. `gst:v4l2src device=/dev/video0 ! videoconvert`;
    /// cargo feature `gstreamer`) or `camera:DEVICE` (shorthand for a V4L2
    /// camera). A string, not a choice: which sources there are depends on
    /// the build.
    pub source: String,
    /// The camera's calibration for `folder:` and `gst:` sources: a ROS
    /// camera_info YAML or an OpenCV FileStorage YAML (intrinsics and
    /// plumb_bob / rational_polynomial distortion). Unset = the synthetic
    /// camera's intrinsics at the stream's size.
    pub camera_info: Option<PathBuf>,
    /// Width of the synthetic camera's frames (or the width a `gst:`
    /// source asks for), pixels.
    pub width: u32,
    /// Height of the synthetic camera's frames (or the height a `gst:`
    /// source asks for), pixels.
    pub height: u32,
    /// Frame rate; 0 = free-running.
    pub fps: f64,
    /// Frames to capture (0 = until stopped).
    pub frames: u64,
    /// Sequence number of the first frame capture sends: 0, or where a
    /// capture restarted by the launcher continues the run.
    pub first_frame: u64,
    /// Pace of an `mcap:` replay: `recorded` (the recording's own frame
    /// times) or `free` (as fast as the pipeline takes them); `fps` does
    /// not apply to replays.
    #[serde(with = "by_name")]
    pub replay: Replay,
    /// The camera's distance to the object centre the arm reports, metres;
    /// unset = the database's training distance (where the simulated
    /// camera flies, and what a real arm holding the camera there reports).
    pub distance_m: Option<f64>,
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            source: "synthetic".into(),
            camera_info: None,
            width: 640,
            height: 480,
            fps: 30.0,
            frames: 300,
            first_frame: 0,
            replay: Replay::Recorded,
            distance_m: None,
        }
    }
}

/// `[synthetic]` of the pipeline's configuration: the simulated scene and
/// the simulated camera's flaws, for `source = "synthetic"`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SyntheticConfig {
    /// Seed of the trajectory and the scene.
    pub seed: u64,
    /// Background of the simulated scene: plain, plain:R,G,B, A, B, C,
    /// clutter or clutter-similar.
    #[serde(with = "by_name")]
    pub background: Background,
    /// Elevation band the simulated camera sweeps, degrees `[min, max]`
    /// (the default stays inside the paper grid's 45..90; a lower minimum
    /// takes the camera below the database, as a real arm's goes).
    pub elevation_deg: [f64; 2],
    /// The simulated camera rolls about its optical axis within ±this,
    /// degrees (0: upright).
    pub roll_deg: f64,
    /// How long the simulated camera's shutter is open, milliseconds, at
    /// most a frame period: the camera moves along its trajectory (or its
    /// circle around several objects) meanwhile and the frame is blurred
    /// along that motion (0: an instant, no motion blur).
    pub shutter_ms: f64,
    /// The simulated scene's light: its linear exposure against the
    /// training light's (1: the same).
    pub exposure: f64,
    /// The simulated scene's light: its colour temperature, kelvin, for a
    /// camera white-balanced for the training light's 5000 K.
    pub colour_temp_k: f64,
    /// The simulated camera's sensor noise, standard deviation in grey
    /// levels (0: none; a cheap camera in dim light shows 3-6). One object.
    pub noise_sigma: f64,
    /// The simulated camera's lens out of focus: a Gaussian blur of this
    /// sigma, pixels (0: sharp; 2 blurs printed text past reading). One
    /// object.
    pub blur_sigma: f64,
}

impl Default for SyntheticConfig {
    fn default() -> Self {
        let (lo, hi) = Trajectory::DEFAULT_THETA_BAND;
        SyntheticConfig {
            seed: 0,
            background: Background::A,
            elevation_deg: [lo, hi],
            roll_deg: 0.0,
            shutter_ms: 0.0,
            exposure: 1.0,
            colour_temp_k: acch_core::light::TRAINING_LIGHT_K as f64,
            noise_sigma: 0.0,
            blur_sigma: 0.0,
        }
    }
}

/// `[estimate]` of the pipeline's configuration: how recognition and pose
/// estimate, and what the cached databases are trained for.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct EstimateConfig {
    /// The cached databases smooth views and frames before quantisation:
    /// `off` (the paper's raw pixels), `binomial` (5x5, sigma 1 px; a
    /// noisy, compressed or blurred camera, docs/accuracy.md) or `auto`:
    /// recognition measures each frame's noise and JPEG blocking and the
    /// object's sharpness, and runs a noisy or compressed frame, a blurred
    /// object or one the sharp databases do not find through the smoothed
    /// databases with the confidence trained for such a camera
    /// (`[object] smoothed_db`), the rest through the sharp ones (`db`).
    /// Not for database files otherwise; `auto` not with several objects.
    #[serde(with = "by_name")]
    pub smoothing: SmoothingChoice,
    /// The cached databases trained with their views lit from this many
    /// directions around the vertical (1: the training light's only; 8
    /// holds light from any side, docs/accuracy.md). Not for `[object] db`
    /// or database files, which are used as they are.
    pub light_directions: usize,
    /// The cached databases' confidence networks are trained on scenes
    /// under other light and a worse camera and read the match value
    /// (`acch train --confidence-imaging`). Not for `[object] db` or
    /// database files.
    pub confidence_imaging: bool,
    /// Lights (exposures, colour temperatures) recognition tries in a frame
    /// whose object is weak or lost under the light in use, going on in
    /// the next frame where this one stopped (0, the default: the training
    /// light only). Each costs one more quantisation and scan, and a new
    /// light its table once; off by default because on flat-coloured
    /// objects it makes wrong estimates that are accepted
    /// (docs/accuracy.md).
    pub light_search_per_frame: usize,
    /// The largest roll of the camera about its optical axis the pose
    /// stage searches, degrees either way (0 = none: image up is the
    /// training views' up, as the paper assumes); unset = the search the
    /// database's confidence network was trained with (`acch train
    /// --roll-search-deg`; none for the default database).
    pub roll_search_deg: Option<f64>,
    /// Search, fit and verify the object's shape when its database holds
    /// it (true, the default). False judges by the colour rules alone, as
    /// the paper does: for printed objects that touch or hide each other,
    /// whose regions the shape cannot explain, at the risk real
    /// photographs showed (docs/real-photographs.md).
    pub verify_shape: bool,
    /// Run a database without a confidence network: estimates are
    /// reported as unrated, none is accepted and no seed is published.
    pub unrated: bool,
}

impl Default for EstimateConfig {
    fn default() -> Self {
        EstimateConfig {
            smoothing: SmoothingChoice::default(),
            light_directions: 1,
            confidence_imaging: false,
            light_search_per_frame: 0,
            roll_search_deg: None,
            verify_shape: true,
            unrated: false,
        }
    }
}

/// `[run]` of the pipeline's configuration: the run's processes, where
/// they run and how frames pass between them.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Keeps the shared-memory services of concurrent runs apart (the
    /// launcher sets its pid).
    pub instance: String,
    /// How frames reach recognition: `shm` (zero copy, the pipeline) or
    /// `copy` (the benchmark's baseline: capture writes every frame into a
    /// Unix socket, which recognition reads into its own buffer).
    #[serde(with = "by_name")]
    pub transport: Transport,
    /// Frames queued for each reader of the frame stream.
    pub frame_history: usize,
    /// SCHED_FIFO priority of every process of the run (1..=90), or 0 for
    /// the normal scheduler. Needs CAP_SYS_NICE (or an rtprio limit).
    pub realtime_priority: u8,
    /// Longest wake-up from idle the CPUs may take while the run lasts, µs
    /// (the kernel's CPU latency QoS; 0 = idle CPUs poll instead of
    /// halting). Unset = the system's setting. Needs root.
    pub cpu_latency_us: Option<u32>,
    /// CPUs of the five processing stages: `auto` (the last CPU when there
    /// are two or more; capture, the observers and the launcher keep the
    /// others), `none` (the scheduler decides) or a list such as `1` or
    /// `2,3`. Sharing one CPU turns every hop into a local context switch.
    #[serde(with = "by_name")]
    pub stage_cpus: StageCpus,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            instance: std::process::id().to_string(),
            transport: Transport::Shm,
            frame_history: 4,
            realtime_priority: 0,
            cpu_latency_us: None,
            stage_cpus: StageCpus::Auto,
        }
    }
}

/// `[observers]` of the pipeline's configuration: the processes that
/// watch a run besides the stages.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ObserversConfig {
    /// Where the `viz` process logs to rerun: `save:FILE.rrd`, `spawn` or
    /// `connect:URL`; unset = no viewer process.
    pub rerun: Option<String>,
    /// MCAP file the `record` process writes every frame and result to;
    /// unset = no recorder process.
    pub record: Option<PathBuf>,
    /// What `record` writes: `foxglove` (frames, masks, responses, results
    /// and seeds as Foxglove schemas and JSON, replayable with
    /// `--source mcap:FILE`) or `ros2` (a rosbag2 bag directory of the ROS
    /// 2 topics and every frame, for `ros2 bag play`).
    #[serde(with = "by_name")]
    pub record_format: RecordFormat,
}

impl Default for ObserversConfig {
    fn default() -> Self {
        ObserversConfig {
            rerun: None,
            record: None,
            record_format: RecordFormat::Foxglove,
        }
    }
}

/// A configuration that cannot be read or used; names the file or the key
/// and the value.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read or written.
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// Not valid TOML, an unknown key, or a value of the wrong type or
    /// outside its key's closed choice (`run.transport = "udp"`). TOML's error
    /// points at the line and says what is wrong; ours names the key of a
    /// refused value.
    #[error(
        "not a valid pipeline configuration{}",
        toml_key(.0).map(|k| format!(" (key `{k}`)")).unwrap_or_default()
    )]
    Toml(#[source] toml::de::Error),
    /// A value out of range.
    #[error("{key} = {value}: {why}")]
    Invalid {
        /// The dotted key (`camera.fps`, `zenoh.prefix`, ...).
        key: &'static str,
        /// The offending value as written.
        value: String,
        /// What is allowed.
        why: &'static str,
    },
    /// The configuration names no database.
    #[error("the configuration names no database (object.db = ...)")]
    NoDatabase,
    /// Its database could not be read.
    #[error("the view database (object.db = ...)")]
    Database(#[source] acch_core::DbError),
    /// `estimate.smoothing = "auto"` names no smoothed database.
    #[error(
        "estimate.smoothing = \"auto\" needs the smoothed database (object.smoothed_db = ...; \
         `acch train --smoothing binomial --confidence-imaging` of object.db's object)"
    )]
    NoSmoothedDatabase,
    /// The smoothed database could not be read.
    #[error("the smoothed view database (object.smoothed_db = ...)")]
    SmoothedDatabase(#[source] acch_core::DbError),
    /// The simulated scene's object is unknown, or its mesh cannot be read
    /// or sized (the source says why; not repeated here, or a printed
    /// chain would say it twice).
    #[error("the simulated scene's object")]
    Object(#[source] acch_capture::CaptureError),
    /// The camera's calibration file cannot be used.
    #[error("camera.camera_info")]
    CameraInfo(#[source] acch_capture::CaptureError),
    /// The source's frame size could not be read.
    #[error("camera.source = {source_name}")]
    Source {
        /// The source as configured.
        source_name: String,
        /// Why its size is unknown.
        #[source]
        source: SourceError,
    },
}

/// What every stage is built with besides the database.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StageSettings {
    /// Frame width, pixels.
    pub width: u32,
    /// Frame height, pixels.
    pub height: u32,
    /// Known camera distance to the object centre, metres: the scale
    /// follows from it; `None` reads it off the segmented region.
    pub distance_m: Option<f64>,
    /// Run a database that has no confidence network: every estimate is
    /// reported as unrated and none is accepted. Without it such a
    /// database is refused.
    pub unrated: bool,
    /// The largest roll of the camera about its optical axis the pose
    /// stage searches, degrees either way (0: none; the image's up is the
    /// training views' up).
    pub roll_search_deg: f32,
    /// Lights (exposures) recognition tries in a frame whose object is
    /// weak or lost under the light in use ([`acch_recognition::LightSearch`]):
    /// 0 never leaves the training light; `usize::MAX` tries them all.
    pub light_search: usize,
    /// Search, fit and verify the object's shape when the database holds
    /// it (the default). Off, the colour rules alone judge, as in the
    /// paper: for printed objects that touch or hide each other, whose
    /// regions the shape cannot explain (docs/limitations.md).
    pub verify_shape: bool,
}

impl StageSettings {
    /// The apparent scale of the object at the known distance, relative to
    /// the database's training distance.
    pub fn scale(&self, db: &ViewDatabase) -> Option<f32> {
        self.distance_m.map(|d| db.train_distance_m / d as f32)
    }
}

/// `[ros2]` of the pipeline's configuration.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2Config {
    /// Publish on ROS 2 topics (`acch run --ros2`).
    pub enabled: bool,
    /// `ROS_DOMAIN_ID` of the ROS 2 peers.
    pub domain_id: u32,
    /// The node's namespace (`/` or `/robot1`): the topics go under it.
    pub namespace: String,
    /// The node's name, as `ros2 node list` shows it.
    pub node: String,
    /// `jazzy` (type hashes in the keys; also Kilted and Rolling) or
    /// `humble` (no type hashes).
    #[serde(with = "by_name")]
    pub distro: Ros2Distro,
    /// The rmw_zenoh attachment layout: `current` (Jazzy 0.2.4 and later,
    /// Kilted, Rolling, Humble 0.1.2 and later) or `legacy` (Jazzy 0.2.0 to
    /// 0.2.3, Humble 0.1.0 and 0.1.1).
    #[serde(with = "by_name")]
    pub attachment: Ros2Attachment,
    /// The camera's optical frame: `header.frame_id` of every message.
    pub frame_id: String,
    /// Publish each object's fused pose on `/tf` as `<frame_id> ->
    /// acch_<object>` (tf2_msgs/TFMessage).
    pub tf: bool,
    /// Publish every Nth frame on `acch/image` (sensor_msgs/Image, rgb8)
    /// from the recorder's side of the run; 0 = never.
    pub image_every: u32,
    /// A topic with the arm's camera pose in its base frame (`world_from_
    /// camera`, the camera's optical frame in metres): seeding fuses over
    /// its motion. Unset = the source's own arm pose, if any.
    pub arm_topic: Option<String>,
    /// Its type: `pose_stamped` (geometry_msgs/PoseStamped) or
    /// `transform_stamped` (geometry_msgs/TransformStamped).
    #[serde(with = "by_name")]
    pub arm_type: ArmMessage,
    /// How old the arm's last pose may be at a frame's capture before the
    /// frame counts as without one (its motion unknown), ms.
    pub arm_max_age_ms: u32,
}

impl Default for Ros2Config {
    fn default() -> Self {
        Ros2Config {
            enabled: false,
            domain_id: 0,
            namespace: "/".into(),
            node: "acch".into(),
            distro: Ros2Distro::Jazzy,
            attachment: Ros2Attachment::Current,
            frame_id: "camera_optical_frame".into(),
            tf: true,
            image_every: 0,
            arm_topic: None,
            arm_type: ArmMessage::PoseStamped,
            arm_max_age_ms: 200,
        }
    }
}

impl Ros2Config {
    /// Checks every key, naming the bad one.
    pub fn validate(&self, object: &str) -> Result<(), ConfigError> {
        if self.domain_id > 232 {
            return Err(invalid(
                "ros2.domain_id",
                self.domain_id,
                "must be 0..=232 (ROS_DOMAIN_ID)",
            ));
        }
        names::validate_namespace(&self.namespace).map_err(|_| {
            invalid(
                "ros2.namespace",
                &self.namespace,
                "must be / or /name/name (letters, digits, _; not starting with a digit)",
            )
        })?;
        names::validate_node_name(&self.node).map_err(|_| {
            invalid(
                "ros2.node",
                &self.node,
                "must be letters, digits and _, not starting with a digit",
            )
        })?;
        if !valid_frame_id(&self.frame_id) {
            return Err(invalid(
                "ros2.frame_id",
                &self.frame_id,
                "must be a non-empty ASCII tf frame name without spaces or a leading /",
            ));
        }
        if let Some(t) = &self.arm_topic {
            names::validate_topic_name(t).map_err(|_| {
                invalid(
                    "ros2.arm_topic",
                    t,
                    "must be a ROS 2 topic name such as /arm/camera_pose",
                )
            })?;
        }
        if self.enabled {
            // The object's name goes into topic names and a tf frame.
            names::validate_node_name(object).map_err(|_| {
                invalid(
                    "object.name",
                    object,
                    "must be letters, digits and _ to name ROS 2 topics",
                )
            })?;
        }
        Ok(())
    }
}

/// A tf frame name: ASCII, no spaces, no leading slash (tf2 refuses one).
fn valid_frame_id(id: &str) -> bool {
    !id.is_empty()
        && !id.starts_with('/')
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '/' | '-' | '.'))
}

/// A run's smoothing: one for every frame, or chosen per frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SmoothingChoice {
    /// Every frame through databases of this smoothing.
    Fixed(acch_core::Smoothing),
    /// Recognition chooses per frame between the sharp databases and the
    /// smoothed ones (`stages::BySet`).
    ByFrame,
}

impl Default for SmoothingChoice {
    /// The paper's raw pixels, every frame.
    fn default() -> Self {
        SmoothingChoice::Fixed(acch_core::Smoothing::Off)
    }
}

impl SmoothingChoice {
    /// The smoothing of the sharp databases (off when chosen per frame).
    pub fn fixed(self) -> acch_core::Smoothing {
        match self {
            SmoothingChoice::Fixed(s) => s,
            SmoothingChoice::ByFrame => acch_core::Smoothing::Off,
        }
    }

    /// Its name: `off`, `binomial` or `auto`.
    pub fn name(self) -> &'static str {
        match self {
            SmoothingChoice::Fixed(s) => s.name(),
            SmoothingChoice::ByFrame => "auto",
        }
    }
}

impl std::str::FromStr for SmoothingChoice {
    type Err = String;
    /// A smoothing's name or `auto`, in any case.
    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case(SmoothingChoice::ByFrame.name()) {
            return Ok(SmoothingChoice::ByFrame);
        }
        s.parse().map(SmoothingChoice::Fixed).map_err(|_| {
            let fixed: Vec<_> = acch_core::Smoothing::ALL
                .map(acch_core::Smoothing::name)
                .into();
            format!(
                "unknown smoothing '{s}' (expected {} or {})",
                fixed.join(", "),
                SmoothingChoice::ByFrame.name()
            )
        })
    }
}

impl std::fmt::Display for SmoothingChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Declares a closed choice of the configuration: the enum, its names in
/// the TOML file and on the command line (`NAMES`, the only list of them),
/// `FromStr` (an unknown name is refused, naming the allowed ones) and
/// `Display`; a field of it is read and written with `by_name`.
macro_rules! choice {
    (
        $(#[$meta:meta])*
        pub enum $name:ident ($what:literal) {
            $($(#[$vmeta:meta])* $variant:ident = $text:literal,)+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum $name {
            $($(#[$vmeta])* $variant,)+
        }

        impl $name {
            /// Every value's name, as the configuration spells it.
            pub const NAMES: &'static [&'static str] = &[$($text),+];

            /// Its name in the configuration and on the command line.
            pub fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $text,)+
                }
            }
        }

        impl std::str::FromStr for $name {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($text => Ok($name::$variant),)+
                    _ => Err(format!(
                        "unknown {} '{s}' (expected {})",
                        $what,
                        $name::NAMES.join(" or ")
                    )),
                }
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}

choice! {
    /// How frames reach recognition (`transport`).
    pub enum Transport ("transport") {
        /// Zero copy: recognition reads the pixels where capture wrote
        /// them, in shared memory (the pipeline).
        Shm = "shm",
        /// The benchmark's baseline: capture writes every frame into a Unix
        /// socket, which recognition reads into its own buffer.
        Copy = "copy",
    }
}

choice! {
    /// What the recorder writes (`record_format`).
    pub enum RecordFormat ("record format") {
        /// An MCAP file of Foxglove schemas and JSON, replayable with
        /// `--source mcap:FILE`.
        Foxglove = "foxglove",
        /// A rosbag2 bag directory of the ROS 2 topics and every frame.
        Ros2 = "ros2",
    }
}

choice! {
    /// The ROS 2 distribution of the peers (`ros2.distro`).
    pub enum Ros2Distro ("ROS 2 distro") {
        /// Jazzy, Kilted and Rolling: type hashes in the keys.
        Jazzy = "jazzy",
        /// Humble: no type hashes.
        Humble = "humble",
    }
}

choice! {
    /// The rmw_zenoh attachment layout of the peers (`ros2.attachment`).
    pub enum Ros2Attachment ("rmw_zenoh attachment layout") {
        /// Jazzy 0.2.4 and later, Kilted, Rolling, Humble 0.1.2 and later.
        Current = "current",
        /// Jazzy 0.2.0 to 0.2.3, Humble 0.1.0 and 0.1.1.
        Legacy = "legacy",
    }
}

choice! {
    /// The message type of the arm's camera poses (`ros2.arm_type`).
    pub enum ArmMessage ("arm message type") {
        /// geometry_msgs/PoseStamped.
        PoseStamped = "pose_stamped",
        /// geometry_msgs/TransformStamped.
        TransformStamped = "transform_stamped",
    }
}

choice! {
    /// The pace of an `mcap:` replay (`replay`).
    pub enum Replay ("replay pace") {
        /// The recording's own frame times.
        Recorded = "recorded",
        /// As fast as the pipeline takes the frames.
        Free = "free",
    }
}

/// A field read with its type's `FromStr` and written with its `Display`
/// (`#[serde(with = "by_name")]`): the TOML spelling is the type's own, and
/// a name the type does not know is refused as the file is read, with the
/// type's message (which lists the allowed names) and TOML's line and key.
mod by_name {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};
    use std::fmt::Display;
    use std::str::FromStr;

    /// Writes `value` by its name.
    pub fn serialize<T: Display, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(value)
    }

    /// Reads a string and parses it.
    pub fn deserialize<'de, T, D>(d: D) -> Result<T, D::Error>
    where
        T: FromStr,
        T::Err: Display,
        D: Deserializer<'de>,
    {
        String::deserialize(d)?.parse().map_err(D::Error::custom)
    }
}

/// How an `mcap:` replay is paced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// The recording's own capture times.
    Recorded,
    /// The next frame goes out when the pipeline has finished the ones
    /// before: as fast as it goes, nothing dropped.
    Free,
    /// The source's own clock: a camera delivers a frame when it has one
    /// (and drops what the pipeline cannot take).
    Source,
}

impl PipelineConfig {
    /// Reads a TOML file and checks its values ([`Self::validate`]).
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text)
    }

    /// Parses TOML text and checks its values.
    pub fn parse(text: &str) -> Result<Self, ConfigError> {
        let cfg: Self = toml::from_str(text).map_err(ConfigError::Toml)?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Writes it as TOML.
    pub fn save(&self, path: &Path) -> Result<(), ConfigError> {
        let text = toml::to_string(self).expect("a configuration serialises");
        std::fs::write(path, text).map_err(|source| ConfigError::Io {
            path: path.to_owned(),
            source,
        })
    }

    /// The smoothing of the (sharp) databases `[object] db` and `[objects]
    /// dbs`.
    pub fn smoothing(&self) -> acch_core::Smoothing {
        self.estimate.smoothing.fixed()
    }

    /// Checks every value a process would otherwise trip over later: NaN or
    /// negative rates and distances, frame sizes, unknown names. Each
    /// section checks its own keys; what depends on two sections is checked
    /// here.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.camera.validate()?;
        self.synthetic.validate(self.camera.fps)?;
        self.object.validate()?;
        self.estimate.validate()?;
        self.run.validate()?;
        self.validate_smoothing()?;
        self.ros2.validate(&self.object.name)?;
        if let Some(topic) = &self.ros2.arm_topic
            && self.zenoh.connect.is_empty()
        {
            return Err(invalid(
                "ros2.arm_topic",
                topic,
                "needs zenoh.connect: the endpoint of the ROS 2 router or of the arm's publisher",
            ));
        }
        self.validate_objects()?;
        if self.zenoh.prefix.is_empty() || self.zenoh.prefix.contains(['*', '$', '?', '#']) {
            return Err(invalid(
                "zenoh.prefix",
                &self.zenoh.prefix,
                "must be a non-empty key without wildcards",
            ));
        }
        Ok(())
    }

    /// Refuses `smoothing = "auto"` where it cannot choose per frame.
    fn validate_smoothing(&self) -> Result<(), ConfigError> {
        let smoothing = self.estimate.smoothing;
        if smoothing != SmoothingChoice::ByFrame {
            return Ok(());
        }
        if !self.objects.list.is_empty() {
            return Err(invalid(
                "estimate.smoothing",
                smoothing,
                "auto is for one object: several objects share a palette of their sharp databases",
            ));
        }
        if self.object.db.is_some() && self.object.smoothed_db.is_none() {
            return Err(invalid(
                "object.smoothed_db",
                "(unset)",
                "must name the smoothed set's database when object.db names the sharp one and \
                 estimate.smoothing = \"auto\" (acch train --smoothing binomial \
                 --confidence-imaging of object.db's object; acch run --smoothed-db)",
            ));
        }
        if self.estimate.light_directions > 1 {
            return Err(invalid(
                "estimate.smoothing",
                smoothing,
                "auto is not with estimate.light_directions above 1: its smoothed databases' \
                 confidence is trained for a worse camera under the training light's direction",
            ));
        }
        Ok(())
    }

    /// Checks `[objects]`, and refuses what a run of several objects does
    /// not do yet.
    fn validate_objects(&self) -> Result<(), ConfigError> {
        let objects = &self.objects;
        let n = objects.list.len();
        if n > acch_capture::MAX_SCENE_OBJECTS {
            return Err(invalid(
                "objects.list",
                format!("{n} objects"),
                "must be at most 16 objects",
            ));
        }
        if let Some(o) = objects.list.iter().find(|o| o.trim().is_empty()) {
            return Err(invalid(
                "objects.list",
                format!("{o:?}"),
                "names an empty object",
            ));
        }
        if !objects.dbs.is_empty() && objects.dbs.len() != n {
            return Err(invalid(
                "objects.dbs",
                format!("{} files", objects.dbs.len()),
                "must name one database per entry of objects.list",
            ));
        }
        if objects.in_view > n {
            return Err(invalid(
                "objects.in_view",
                objects.in_view,
                "must be at most the number of objects (0: all)",
            ));
        }
        if n == 0 {
            return Ok(());
        }
        if let Some(rerun) = &self.observers.rerun {
            return Err(invalid(
                "observers.rerun",
                rerun,
                "the viewer shows one object: run it without objects.list = [...]",
            ));
        }
        if let Some(r) = &self.observers.record {
            return Err(invalid(
                "observers.record",
                r.display(),
                "recordings hold one object: run it without objects.list = [...]",
            ));
        }
        Ok(())
    }

    /// The entries of `objects.list`, parsed.
    pub fn object_entries(&self) -> Vec<ObjectEntry> {
        self.objects
            .list
            .iter()
            .map(|o| ObjectEntry::parse(o))
            .collect()
    }

    /// The objects the simulated scene of several objects shows: the first
    /// `objects.in_view` (0: all) of `objects.list`.
    pub fn scene_objects(&self) -> Result<Vec<acch_capture::Object>, ConfigError> {
        let n = match self.objects.in_view {
            0 => self.objects.list.len(),
            k => k,
        };
        self.object_entries()
            .into_iter()
            .take(n)
            .map(|e| e.object(self.object.mesh_up, self.object.mesh_unit_m))
            .collect()
    }

    /// The databases of `objects.list` (`objects.dbs`), read.
    pub fn object_databases(&self) -> Result<Vec<ViewDatabase>, ConfigError> {
        if self.objects.dbs.len() != self.objects.list.len() {
            return Err(ConfigError::NoDatabase);
        }
        self.objects
            .dbs
            .iter()
            .map(|p| ViewDatabase::load(p).map_err(ConfigError::Database))
            .collect()
    }

    /// Where stage process `pid` of this run writes its counters when it
    /// stops (the launcher reads and removes it).
    pub fn counters_path(&self, stage: &str, pid: u32) -> PathBuf {
        std::env::temp_dir().join(format!("acch-run-{}-{stage}-{pid}.json", self.run.instance))
    }

    /// Opens this process's iceoryx2 node.
    pub fn ipc(&self, node: &str) -> Result<Ipc, acch_ipc::NodeError> {
        Ipc::new(&self.run.instance, node)
    }

    /// Whether frames are copied through Unix sockets (`run.transport =
    /// "copy"`).
    pub fn copies_frames(&self) -> bool {
        self.run.transport == Transport::Copy
    }

    /// How the source is paced when `camera.fps` does not pace it: an
    /// `mcap:` replay's `camera.replay`, a camera's own clock; `None` for
    /// the others.
    pub fn pace(&self) -> Option<Pace> {
        if self.camera.gst_pipeline().is_some() {
            return Some(Pace::Source);
        }
        self.camera
            .source
            .starts_with("mcap:")
            .then_some(match self.camera.replay {
                Replay::Recorded => Pace::Recorded,
                Replay::Free => Pace::Free,
            })
    }

    /// Fixes the stream's size before the stages start: a camera's is
    /// known once it runs, so it is started once here (every stage
    /// process then reads `camera.width` and `height`). Other sources
    /// know theirs.
    /// A calibration for another image size than the stream's is refused
    /// here too, once, naming both sizes.
    pub fn resolve_stream_size(&mut self) -> Result<(), ConfigError> {
        let spec = self.source_spec()?;
        if self.camera.gst_pipeline().is_some() {
            (self.camera.width, self.camera.height) = spec
                .probe_size((self.camera.width, self.camera.height))
                .map_err(|source| ConfigError::Source {
                    source_name: self.camera.source.clone(),
                    source,
                })?;
        }
        if let Some(c) = self.camera_file()? {
            let (w, h) = self.frame_size()?;
            c.calibration
                .check_size(w, h)
                .map_err(|why| ConfigError::Source {
                    source_name: self.camera.source.clone(),
                    source: SourceError::CalibrationSize { path: c.path, why },
                })?;
        }
        Ok(())
    }

    /// The launcher's side of `run.stage_cpus`: resolves it against the CPUs
    /// this process may use, moves this process (and so capture and the
    /// observers it starts) to the other CPUs, and writes the resolved list
    /// back for the stage processes, which start on those other CPUs.
    pub fn place_run(&mut self) -> std::io::Result<Option<Placement>> {
        let allowed = sched::allowed_cpus()?;
        let placement = self
            .run
            .stage_cpus
            .resolve(&allowed)
            .map_err(std::io::Error::other)?;
        match &placement {
            Some(p) => {
                if !p.others.is_empty() {
                    sched::pin_to(&p.others)?;
                }
                self.run.stage_cpus = StageCpus::List(p.stages.clone());
            }
            None => self.run.stage_cpus = StageCpus::Free,
        }
        Ok(placement)
    }

    /// Pins the calling thread (a stage process's, or the one-process
    /// pipeline's) to the stages' CPUs; returns them, or `None` when the
    /// stages are not placed.
    pub fn pin_stage(&self) -> std::io::Result<Option<Vec<usize>>> {
        let cpus = match &self.run.stage_cpus {
            StageCpus::Free => return Ok(None),
            // Resolved by the launcher for every stage alike.
            StageCpus::List(cpus) => cpus.clone(),
            auto @ StageCpus::Auto => {
                let allowed = sched::allowed_cpus()?;
                match auto.resolve(&allowed).map_err(std::io::Error::other)? {
                    Some(p) => p.stages,
                    None => return Ok(None),
                }
            }
        };
        sched::pin_to(&cpus)?;
        Ok(Some(cpus))
    }

    /// The CPUs for the thread that shares the pose stage's work
    /// (`stages::pose_helper`), asked before the calling thread is
    /// pinned: those it may use beside the stages' when the stages are
    /// placed, all of them otherwise; `None` when no CPU is left beside
    /// the stages' (the helper would only take turns with the stage).
    pub fn pose_helper_cpus(&self) -> std::io::Result<Option<Vec<usize>>> {
        let allowed = sched::allowed_cpus()?;
        let stages = match &self.run.stage_cpus {
            StageCpus::Free => return Ok((allowed.len() >= 2).then_some(allowed)),
            StageCpus::List(cpus) => cpus.clone(),
            auto @ StageCpus::Auto => {
                match auto.resolve(&allowed).map_err(std::io::Error::other)? {
                    Some(p) => p.stages,
                    None => return Ok(None),
                }
            }
        };
        let others: Vec<usize> = allowed
            .into_iter()
            .filter(|c| !stages.contains(c))
            .collect();
        Ok((!others.is_empty()).then_some(others))
    }

    /// Reads the configured database.
    pub fn database(&self) -> Result<ViewDatabase, ConfigError> {
        let path = self.object.db.as_ref().ok_or(ConfigError::NoDatabase)?;
        ViewDatabase::load(path).map_err(ConfigError::Database)
    }

    /// Reads the smoothed set's database of a run with `smoothing =
    /// "auto"`; `None` for a run that does not choose.
    pub fn smoothed_database(&self) -> Result<Option<ViewDatabase>, ConfigError> {
        if self.estimate.smoothing != SmoothingChoice::ByFrame {
            return Ok(None);
        }
        let path = self
            .object
            .smoothed_db
            .as_ref()
            .ok_or(ConfigError::NoSmoothedDatabase)?;
        ViewDatabase::load(path)
            .map(Some)
            .map_err(ConfigError::SmoothedDatabase)
    }

    /// The source this configuration reads.
    pub fn source_spec(&self) -> Result<SourceSpec, ConfigError> {
        let s = self.camera.source.as_str();
        if let Some(dir) = s.strip_prefix("folder:") {
            return Ok(SourceSpec::Folder {
                dir: dir.into(),
                calibration: self.camera_file()?,
            });
        }
        if let Some(pipeline) = self.camera.gst_pipeline() {
            return Ok(SourceSpec::Gst {
                pipeline,
                calibration: self.camera_file()?,
            });
        }
        if let Some(file) = s.strip_prefix("mcap:") {
            return Ok(SourceSpec::Mcap(file.into()));
        }
        if !self.objects.list.is_empty() {
            let [lo, hi] = self.synthetic.elevation_deg;
            return Ok(SourceSpec::Group(SyntheticGroup {
                objects: self
                    .scene_objects()?
                    .into_iter()
                    .map(std::sync::Arc::new)
                    .collect(),
                background: self.synthetic.background,
                textures: acch_capture::TextureSet::HeldOut,
                seed: self.synthetic.seed,
                width: self.camera.width,
                height: self.camera.height,
                fps: self.camera.fps,
                elevation_deg: (lo, hi),
                shutter_s: self.synthetic.shutter_ms / 1000.0,
            }));
        }
        let object = self.scene_object()?;
        let [lo, hi] = self.synthetic.elevation_deg;
        let distance_m = self
            .camera
            .distance_m
            .unwrap_or(DEFAULT_DISTANCE * object.radius_m());
        Ok(SourceSpec::Synthetic(SyntheticCamera {
            object: std::sync::Arc::new(object),
            background: self.synthetic.background,
            textures: acch_capture::TextureSet::HeldOut,
            seed: self.synthetic.seed,
            width: self.camera.width,
            height: self.camera.height,
            distance_m,
            fps: self.camera.fps,
            elevation_deg: (lo, hi),
            roll_deg: self.synthetic.roll_deg,
            shutter_s: self.synthetic.shutter_ms / 1000.0,
            light: (
                self.synthetic.exposure as f32,
                self.synthetic.colour_temp_k as f32,
            ),
            noise_sigma: self.synthetic.noise_sigma as f32,
            blur_sigma: self.synthetic.blur_sigma as f32,
        }))
    }

    /// The size of the stream the source makes (stages size their buffers
    /// and the frame service its shared memory from it).
    pub fn frame_size(&self) -> Result<(u32, u32), ConfigError> {
        if self.camera.gst_pipeline().is_some() {
            // Probed once by the launcher (resolve_stream_size).
            return Ok((self.camera.width, self.camera.height));
        }
        let spec = self.source_spec()?;
        spec.frame_size().map_err(|source| ConfigError::Source {
            source_name: self.camera.source.clone(),
            source,
        })
    }

    /// The calibration `camera.camera_info` names, read.
    pub fn camera_file(&self) -> Result<Option<CameraFile>, ConfigError> {
        let Some(path) = &self.camera.camera_info else {
            return Ok(None);
        };
        let calibration = Calibration::load(path).map_err(ConfigError::CameraInfo)?;
        Ok(Some(CameraFile {
            path: path.clone(),
            calibration,
        }))
    }

    /// The built-in object of the simulated scene, at its configured size.
    pub fn scene_object(&self) -> Result<acch_capture::Object, ConfigError> {
        let object = match &self.object.mesh {
            Some(path) => {
                let object = acch_capture::Object::load_mesh(path, self.object.mesh_up)
                    .map_err(ConfigError::Object)?;
                match self.object.mesh_unit_m {
                    Some(unit) => object.with_mesh_unit_m(unit).map_err(ConfigError::Object)?,
                    None => object,
                }
            }
            None => {
                acch_capture::Object::builtin(&self.object.name).map_err(ConfigError::Object)?
            }
        };
        match self.object.radius_m {
            Some(r) => object.with_radius_m(r).map_err(ConfigError::Object),
            None => Ok(object),
        }
    }

    /// What the stages over `db` are built with: the known distance is
    /// `camera.distance_m`, or `db`'s training distance.
    pub fn settings(&self, db: &ViewDatabase) -> Result<StageSettings, ConfigError> {
        let (width, height) = self.frame_size()?;
        Ok(StageSettings {
            width,
            height,
            distance_m: Some(self.camera.distance_m.unwrap_or(db.train_distance_m as f64)),
            unrated: self.estimate.unrated,
            roll_search_deg: self.roll_search(db),
            light_search: self.estimate.light_search_per_frame,
            verify_shape: self.estimate.verify_shape,
        })
    }

    /// [`settings`](Self::settings) for one of several objects: the
    /// simulated group stands [`acch_capture::MULTI_DISTANCE`] radii away
    /// (as far, in its training distance's radii), unless
    /// `camera.distance_m` says otherwise.
    pub fn object_settings(&self, db: &ViewDatabase) -> Result<StageSettings, ConfigError> {
        let mut s = self.settings(db)?;
        if self.camera.source == "synthetic" && self.camera.distance_m.is_none() {
            let group = acch_capture::MULTI_DISTANCE / DEFAULT_DISTANCE;
            s.distance_m = Some(db.train_distance_m as f64 * group);
        }
        Ok(s)
    }

    /// The roll search of a run over `db`: `estimate.roll_search_deg`, or
    /// the one `db` was trained for ([`acch_pose::ROLL_SEARCH_SECTION`]).
    fn roll_search(&self, db: &ViewDatabase) -> f32 {
        self.estimate
            .roll_search_deg
            .map_or_else(|| acch_pose::trained_roll_search_deg(db), |d| d as f32)
    }

    /// Warns, once per run (the launcher calls it), when
    /// `estimate.roll_search_deg` differs from the search `db` was trained
    /// for: allowed, but its confidence network then rates responses
    /// unlike its training's, and a database from photographs searches
    /// rolls they did not show.
    pub fn warn_on_untrained_roll_search(&self, db: &ViewDatabase) {
        let trained = acch_pose::trained_roll_search_deg(db);
        if let Some(deg) = self.estimate.roll_search_deg
            && deg as f32 != trained
        {
            tracing::warn!(
                "estimate.roll_search_deg = {deg}, but '{}' was trained for {trained} (its confidence network, or the rolls of its photographs): `acch train --roll-search-deg {deg}` trains one for it",
                db.object
            );
        }
    }
}

/// Prefixes of the sources that name something.
const SOURCE_PREFIXES: [&str; 4] = ["folder:", "mcap:", "gst:", "camera:"];

/// A refused value: its dotted key, the value as written and what is
/// allowed.
fn invalid(key: &'static str, value: impl std::fmt::Display, why: &'static str) -> ConfigError {
    ConfigError::Invalid {
        key,
        value: value.to_string(),
        why,
    }
}

/// A distance in metres: positive, finite, at most 1000.
fn check_metres(key: &'static str, value: Option<f64>) -> Result<(), ConfigError> {
    match value {
        Some(d) if !(d.is_finite() && d > 0.0 && d <= 1000.0) => Err(invalid(
            key,
            d,
            "must be a positive number of metres up to 1000",
        )),
        _ => Ok(()),
    }
}

impl ObjectConfig {
    /// Checks its sizes.
    fn validate(&self) -> Result<(), ConfigError> {
        check_metres("object.radius_m", self.radius_m)
    }
}

impl CameraConfig {
    /// Checks the rate, distance, frame size and source.
    fn validate(&self) -> Result<(), ConfigError> {
        if !(self.fps.is_finite() && (0.0..=10_000.0).contains(&self.fps)) {
            return Err(invalid(
                "camera.fps",
                self.fps,
                "must be a number in 0..=10000 (0 = free-running)",
            ));
        }
        check_metres("camera.distance_m", self.distance_m)?;
        for (key, v) in [("camera.width", self.width), ("camera.height", self.height)] {
            if !(16..=8192).contains(&v) {
                return Err(invalid(key, v, "must be 16..=8192 pixels"));
            }
        }
        let s = self.source.as_str();
        if !(s == "synthetic" || SOURCE_PREFIXES.iter().any(|p| s.starts_with(p))) {
            return Err(invalid(
                "camera.source",
                s,
                "must be synthetic, folder:DIR, mcap:FILE, gst:PIPELINE or camera:DEVICE",
            ));
        }
        if SOURCE_PREFIXES
            .iter()
            .any(|p| s.strip_prefix(p).is_some_and(|r| r.trim().is_empty()))
        {
            return Err(invalid(
                "camera.source",
                s,
                "names no directory, file, pipeline or device",
            ));
        }
        if self.gst_pipeline().is_some() && !cfg!(feature = "gstreamer") {
            return Err(invalid(
                "camera.source",
                s,
                "this build has no GStreamer source: build with `--features gstreamer` \
                 (needs the Debian packages libgstreamer1.0-dev and \
                 libgstreamer-plugins-base1.0-dev)",
            ));
        }
        Ok(())
    }

    /// The GStreamer pipeline of a `gst:` or `camera:` source.
    pub fn gst_pipeline(&self) -> Option<String> {
        if let Some(p) = self.source.strip_prefix("gst:") {
            return Some(p.trim().to_owned());
        }
        self.source
            .strip_prefix("camera:")
            .map(|device| format!("v4l2src device={} ! videoconvert", device.trim()))
    }
}

impl SyntheticConfig {
    /// Checks the scene and the camera's flaws; the shutter against the
    /// frame period at `fps`.
    fn validate(&self, fps: f64) -> Result<(), ConfigError> {
        let [lo, hi] = self.elevation_deg;
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= 90.0) {
            return Err(invalid(
                "synthetic.elevation_deg",
                format!("[{lo}, {hi}]"),
                "must be [min, max] with 0 <= min < max <= 90",
            ));
        }
        let in_range =
            |v: f64, range: std::ops::RangeInclusive<f64>| v.is_finite() && range.contains(&v);
        if !(self.exposure.is_finite() && self.exposure > 0.0) {
            return Err(invalid(
                "synthetic.exposure",
                self.exposure,
                "must be a positive number (1: the training light)",
            ));
        }
        if !in_range(self.noise_sigma, 0.0..=64.0) {
            return Err(invalid(
                "synthetic.noise_sigma",
                self.noise_sigma,
                "must be 0..=64 grey levels",
            ));
        }
        if !in_range(self.blur_sigma, 0.0..=8.0) {
            return Err(invalid(
                "synthetic.blur_sigma",
                self.blur_sigma,
                "must be 0..=8 pixels",
            ));
        }
        if !in_range(self.colour_temp_k, 1000.0..=15000.0) {
            return Err(invalid(
                "synthetic.colour_temp_k",
                self.colour_temp_k,
                "must be 1000..=15000 kelvin",
            ));
        }
        // The synthetic trajectory runs at 30 fps when the stream is free.
        let frame_ms = 1000.0 / if fps > 0.0 { fps } else { 30.0 };
        if !in_range(self.shutter_ms, 0.0..=frame_ms) {
            return Err(invalid(
                "synthetic.shutter_ms",
                self.shutter_ms,
                "must be 0 up to a frame period (1000 / camera.fps milliseconds)",
            ));
        }
        if !in_range(self.roll_deg, 0.0..=180.0) {
            return Err(invalid(
                "synthetic.roll_deg",
                self.roll_deg,
                "must be 0..=180 degrees",
            ));
        }
        Ok(())
    }
}

impl EstimateConfig {
    /// Checks the light directions and the roll search.
    fn validate(&self) -> Result<(), ConfigError> {
        if !(1..=64).contains(&self.light_directions) {
            return Err(invalid(
                "estimate.light_directions",
                self.light_directions,
                "must be 1 (the training light's) to 64",
            ));
        }
        if let Some(deg) = self.roll_search_deg
            && !(deg.is_finite() && (0.0..=180.0).contains(&deg))
        {
            return Err(invalid(
                "estimate.roll_search_deg",
                deg,
                "must be 0..=180 degrees",
            ));
        }
        Ok(())
    }
}

impl RunConfig {
    /// Checks the instance name, the frame history and the scheduling.
    fn validate(&self) -> Result<(), ConfigError> {
        if !(1..=64).contains(&self.frame_history) {
            return Err(invalid(
                "run.frame_history",
                self.frame_history,
                "must be 1..=64 frames",
            ));
        }
        if self.realtime_priority > sched::MAX_PRIORITY {
            return Err(invalid(
                "run.realtime_priority",
                self.realtime_priority,
                "must be 0 (off) or 1..=90",
            ));
        }
        if let Some(us) = self.cpu_latency_us
            && us > sched::CpuLatencyRequest::MAX_MICROS
        {
            return Err(invalid(
                "run.cpu_latency_us",
                us,
                "must be 0..=2000000000 µs (unset: the system's setting)",
            ));
        }
        if self.instance.is_empty()
            || !self
                .instance
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(invalid(
                "run.instance",
                &self.instance,
                "must be letters, digits, - or _",
            ));
        }
        Ok(())
    }
}

/// The dotted key (`run.transport`, `ros2.distro`) of the value TOML's
/// error is about, `None` when it is not about one key: TOML records it,
/// and writes it out only when it has no line to point at. An unknown key
/// is reported against its table, so its name is taken from serde's
/// message (`unknown field `x`, expected ...`) and joined to the table's.
fn toml_key(e: &toml::de::Error) -> Option<String> {
    let mut plain = e.clone();
    plain.set_input(None);
    let text = plain.to_string();
    let table = text
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("in `")?.strip_suffix('`'));
    let unknown = e
        .message()
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split_once('`'))
        .map(|(key, _)| key);
    match (table, unknown) {
        (Some(table), Some(key)) => Some(format!("{table}.{key}")),
        (table, key) => table.or(key).map(str::to_owned),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngAlgorithm, RngSeed};

    fn config(cases: u32) -> Config {
        Config {
            cases,
            failure_persistence: None,
            rng_algorithm: RngAlgorithm::ChaCha,
            rng_seed: RngSeed::Fixed(0xACC4_0009),
            ..Config::default()
        }
    }

    #[test]
    fn the_pose_helper_goes_beside_the_stages_and_nowhere_without_a_cpu_to_spare() {
        // On a thread of its own, pinned to the first two CPUs this process
        // may use (when it may use two), so the answer does not depend on
        // the test harness's threads.
        std::thread::spawn(|| {
            let allowed = sched::allowed_cpus().unwrap();
            let helper = |stage_cpus: StageCpus| {
                let mut cfg = PipelineConfig::default();
                cfg.run.stage_cpus = stage_cpus;
                cfg.pose_helper_cpus().unwrap()
            };
            if allowed.len() < 2 {
                assert_eq!(helper(StageCpus::Auto), None);
                assert_eq!(helper(StageCpus::Free), None);
                return;
            }
            let (a, b) = (allowed[0], allowed[1]);
            sched::pin_to(&[a, b]).unwrap();
            // auto: the stages on the last CPU, the helper on the other.
            assert_eq!(helper(StageCpus::Auto), Some(vec![a]));
            assert_eq!(helper(StageCpus::List(vec![a])), Some(vec![b]));
            // The stages on every CPU: nothing beside them.
            assert_eq!(helper(StageCpus::List(vec![a, b])), None);
            // Not placed: anywhere.
            assert_eq!(helper(StageCpus::Free), Some(vec![a, b]));
        })
        .join()
        .unwrap();
    }

    #[test]
    fn the_default_round_trips_and_is_valid() {
        let d = PipelineConfig::default();
        let back = PipelineConfig::parse(&toml::to_string(&d).unwrap()).unwrap();
        assert_eq!(back, d);
    }

    #[test]
    fn bad_values_name_the_key() {
        for (text, key) in [
            ("[camera]\nfps = nan", "camera.fps"),
            ("[camera]\nfps = -1.0", "camera.fps"),
            ("[camera]\nfps = inf", "camera.fps"),
            ("[camera]\ndistance_m = -2.0", "camera.distance_m"),
            ("[camera]\ndistance_m = nan", "camera.distance_m"),
            ("[object]\nradius_m = 0.0", "object.radius_m"),
            ("[object]\nradius_m = 1e9", "object.radius_m"),
            // The key before distances were metric: refused, never misread.
            ("[camera]\ndistance = 5.0", "camera.distance"),
            ("[camera]\nwidth = 0", "camera.width"),
            ("[camera]\nheight = 100000", "camera.height"),
            ("[run]\nframe_history = 0", "run.frame_history"),
            ("[synthetic]\nexposure = 0.0", "synthetic.exposure"),
            ("[synthetic]\nshutter_ms = 40.0", "synthetic.shutter_ms"),
            ("[synthetic]\nshutter_ms = -1.0", "synthetic.shutter_ms"),
            (
                "[synthetic]\ncolour_temp_k = 100.0",
                "synthetic.colour_temp_k",
            ),
            (
                "[estimate]\nroll_search_deg = 200.0",
                "estimate.roll_search_deg",
            ),
            ("[synthetic]\nnoise_sigma = -1.0", "synthetic.noise_sigma"),
            ("[synthetic]\nblur_sigma = 9.0", "synthetic.blur_sigma"),
            (
                "[estimate]\nsmoothing = \"auto\"\n[objects]\nlist = [\"fruitbox\", \"can\"]",
                "estimate.smoothing",
            ),
            (
                "[estimate]\nsmoothing = \"auto\"\nlight_directions = 8",
                "estimate.smoothing",
            ),
            ("[camera]\nsource = \"camera\"", "camera.source"),
            ("[camera]\nsource = \"folder:\"", "camera.source"),
            (
                "[synthetic]\nelevation_deg = [50.0, 40.0]",
                "synthetic.elevation_deg",
            ),
            (
                "[synthetic]\nelevation_deg = [-1.0, 40.0]",
                "synthetic.elevation_deg",
            ),
            ("[camera]\nframes = -5", "camera.frames"),
            ("[camera]\nfps = \"fast\"", "camera.fps"),
            // A dotted key is the same key as its section's.
            ("camera.fps = \"x\"", "camera.fps"),
            // Unknown keys, at the top and in a section: named in full.
            ("colour = 1", "colour"),
            ("[camera]\ncolour = 1", "camera.colour"),
            // A key of the flat layout before the sections: refused, named.
            ("fps = 30.0", "fps"),
            ("[zenoh]\nprefix = \"a/*\"", "zenoh.prefix"),
            ("[run]\ncpu_latency_us = 2000000001", "run.cpu_latency_us"),
            ("[run]\ncpu_latency_us = -1", "run.cpu_latency_us"),
            ("[camera]\nframes = 1\n[ros2]\ndistro = 7", "ros2.distro"),
            ("[objects]\nin_view = 3", "objects.in_view"),
        ] {
            let e = PipelineConfig::parse(text).expect_err(text);
            let msg = named(&e);
            assert!(msg.contains(key), "{text}: {msg}");
        }
        // The closed choices: refused as the file is read, naming the key
        // and the allowed values; a number where a name belongs as well.
        for (text, key, allowed) in [
            ("[run]\ntransport = \"udp\"", "run.transport", "shm or copy"),
            ("[run]\ntransport = 1", "run.transport", "a string"),
            (
                "[observers]\nrecord_format = \"rosbag\"",
                "observers.record_format",
                "foxglove or ros2",
            ),
            (
                "[camera]\nreplay = \"fast\"",
                "camera.replay",
                "recorded or free",
            ),
            (
                "[estimate]\nsmoothing = \"gaussian\"",
                "estimate.smoothing",
                "off, binomial or auto",
            ),
            (
                "[object]\nmesh_up = \"up\"",
                "object.mesh_up",
                "+x, -x, +y, -y, +z, -z",
            ),
            (
                "[synthetic]\nbackground = \"Z\"",
                "synthetic.background",
                "clutter-similar",
            ),
            // Refused whatever the source, not only for the simulated scene.
            (
                "[camera]\nsource = \"folder:d\"\n[synthetic]\nbackground = \"Z\"",
                "synthetic.background",
                "clutter-similar",
            ),
            (
                "[run]\nstage_cpus = \"x\"",
                "run.stage_cpus",
                "auto, none or a list",
            ),
            (
                "[ros2]\ndistro = \"iron\"",
                "ros2.distro",
                "jazzy or humble",
            ),
            (
                "[ros2]\nattachment = \"old\"",
                "ros2.attachment",
                "current or legacy",
            ),
            (
                "[ros2]\narm_type = \"pose\"",
                "ros2.arm_type",
                "pose_stamped or transform_stamped",
            ),
            (
                "[run]\nstage_cpus = \"1,\"",
                "run.stage_cpus",
                "auto, none or a list",
            ),
        ] {
            let e = PipelineConfig::parse(text).expect_err(text);
            let msg = named(&e);
            assert!(msg.contains(key), "{text}: {msg}");
            assert!(msg.contains(allowed), "{text}: {msg}");
        }
    }

    #[test]
    fn a_printed_chain_says_each_cause_once() {
        let e = PipelineConfig::parse("[run]\ntransport = \"udp\"").unwrap_err();
        let chain = anyhow_chain(&e);
        assert_eq!(
            chain.matches("unknown transport 'udp'").count(),
            1,
            "{chain}"
        );
        let mut cfg = PipelineConfig::default();
        cfg.object.name = "nosuch".into();
        let e = cfg.scene_object().unwrap_err();
        let chain = anyhow_chain(&e);
        assert_eq!(
            chain.matches("unknown object 'nosuch'").count(),
            1,
            "{chain}"
        );
    }

    /// What the error says besides TOML's quote of the line, which holds
    /// the key whatever the error: the message must name it.
    fn named(e: &ConfigError) -> String {
        match e {
            ConfigError::Toml(source) => format!("{e}: {}", source.message()),
            e => anyhow_chain(e),
        }
    }

    #[test]
    fn the_closed_choices_are_written_as_read() {
        let text = "[object]\nmesh_up = \"-z\"\n\
                    [camera]\nreplay = \"free\"\n\
                    [synthetic]\nbackground = \"plain:1,2,3\"\n\
                    [estimate]\nsmoothing = \"binomial\"\n\
                    [run]\ntransport = \"copy\"\nstage_cpus = \"2,3\"\n\
                    [observers]\nrecord_format = \"ros2\"\n";
        let c = PipelineConfig::parse(text).unwrap();
        assert_eq!(c.object.mesh_up, UpAxis::NegZ);
        assert_eq!(
            c.estimate.smoothing,
            SmoothingChoice::Fixed(acch_core::Smoothing::Binomial)
        );
        assert_eq!(c.synthetic.background, Background::Plain([1, 2, 3]));
        assert_eq!(c.camera.replay, Replay::Free);
        assert_eq!(c.run.transport, Transport::Copy);
        assert_eq!(c.observers.record_format, RecordFormat::Ros2);
        assert_eq!(c.run.stage_cpus, StageCpus::List(vec![2, 3]));
        let written = toml::to_string(&c).unwrap();
        for line in text.lines() {
            assert!(written.lines().any(|l| l == line), "{line} in {written}");
        }
        assert_eq!(PipelineConfig::parse(&written).unwrap(), c);
        // What the launcher writes back for the stage processes.
        let mut placed = c.clone();
        placed.run.stage_cpus = StageCpus::Free;
        let written = toml::to_string(&placed).unwrap();
        assert!(written.contains("stage_cpus = \"none\""), "{written}");
        assert_eq!(PipelineConfig::parse(&written).unwrap(), placed);
    }

    /// The error and its sources, as the command line prints them.
    fn anyhow_chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut cur = e.source();
        while let Some(c) = cur {
            s.push_str(": ");
            s.push_str(&c.to_string());
            cur = c.source();
        }
        s
    }

    /// A value of any TOML type, including the awkward floats.
    fn value() -> impl Strategy<Value = String> {
        prop_oneof![
            any::<i64>().prop_map(|v| v.to_string()),
            any::<f64>().prop_map(|v| format!("{v:?}")),
            Just("nan".to_string()),
            Just("-inf".to_string()),
            Just("-0.0".to_string()),
            any::<bool>().prop_map(|v| v.to_string()),
            "[a-zA-Z0-9:/._ *-]{0,12}".prop_map(|v| format!("{v:?}")),
            Just("[]".to_string()),
            Just("[20.0, 90.0]".to_string()),
            Just("[\"tcp/127.0.0.1:0\"]".to_string()),
            Just("\"0,1\"".to_string()),
        ]
    }

    /// Dotted keys: a line `camera.fps = 1` sets `fps` in `[camera]`.
    const KEYS: [&str; 21] = [
        "object.name",
        "object.db",
        "camera.source",
        "synthetic.background",
        "synthetic.elevation_deg",
        "camera.frames",
        "camera.fps",
        "camera.replay",
        "synthetic.seed",
        "camera.distance_m",
        "object.radius_m",
        "run.frame_history",
        "camera.width",
        "camera.height",
        "run.transport",
        "estimate.unrated",
        "run.instance",
        "camera.first_frame",
        "observers.rerun",
        "run.stage_cpus",
        "run.cpu_latency_us",
    ];

    proptest! {
        #![proptest_config(config(20000))]

        #[test]
        fn arbitrary_text_never_panics(text in "\\PC{0,120}") {
            let _ = PipelineConfig::parse(&text);
        }

        #[test]
        fn arbitrary_values_are_valid_or_refused(
            entries in proptest::collection::vec((0..KEYS.len(), value()), 0..6),
            zenoh in proptest::option::of((value(), value(), value())),
        ) {
            let mut text = String::new();
            for (k, v) in &entries {
                text.push_str(&format!("{} = {v}\n", KEYS[*k]));
            }
            if let Some((l, c, p)) = zenoh {
                text.push_str(&format!("[zenoh]\nlisten = {l}\nconnect = {c}\nprefix = {p}\n"));
            }
            match PipelineConfig::parse(&text) {
                Ok(c) => {
                    let camera = &c.camera;
                    prop_assert!(camera.fps.is_finite() && camera.fps >= 0.0);
                    prop_assert!(camera.distance_m.is_none_or(|d| d.is_finite() && d > 0.0));
                    prop_assert!(c.object.radius_m.is_none_or(|d| d.is_finite() && d > 0.0));
                    prop_assert!((16..=8192).contains(&camera.width));
                    prop_assert!((16..=8192).contains(&camera.height));
                    prop_assert!(c.run.frame_history >= 1);
                    // What was accepted is written back and read the same.
                    let again = PipelineConfig::parse(&toml::to_string(&c).unwrap());
                    prop_assert!(again.is_ok(), "{:?}", again.err());
                }
                Err(e) => {
                    // Either TOML's own message (with line and key) or ours
                    // (key = value: why).
                    let m = anyhow_chain(&e);
                    prop_assert!(m.contains("TOML") || m.contains(" = "), "{}", m);
                }
            }
        }
    }
}

/// One entry of `objects.list`: what it names.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ObjectEntry {
    /// A built-in name or `generated-N`.
    Builtin(String),
    /// A mesh file (anything with a path separator or an extension).
    Mesh(PathBuf),
    /// A view database file (`.acchdb`): no mesh, so nothing to render.
    Database(PathBuf),
}

impl ObjectEntry {
    /// Reads an entry.
    pub fn parse(entry: &str) -> Self {
        let e = entry.trim();
        if e.ends_with(".acchdb") {
            ObjectEntry::Database(e.into())
        } else if e.contains('/') || e.contains('.') {
            ObjectEntry::Mesh(e.into())
        } else {
            ObjectEntry::Builtin(e.into())
        }
    }

    /// The object to render, read with `up` and in `unit_m` metres.
    pub fn object(
        &self,
        up: acch_capture::UpAxis,
        unit_m: Option<f64>,
    ) -> Result<acch_capture::Object, ConfigError> {
        match self {
            ObjectEntry::Builtin(name) => {
                acch_capture::Object::builtin(name).map_err(ConfigError::Object)
            }
            ObjectEntry::Mesh(path) => {
                let o = acch_capture::Object::load_mesh(path, up).map_err(ConfigError::Object)?;
                match unit_m {
                    Some(unit) => o.with_mesh_unit_m(unit).map_err(ConfigError::Object),
                    None => Ok(o),
                }
            }
            ObjectEntry::Database(path) => Err(ConfigError::Invalid {
                key: "objects.list",
                value: path.display().to_string(),
                why: "a view database has no mesh for the simulated scene: name the object \
                      (a built-in name or a mesh file), or use another source",
            }),
        }
    }
}
