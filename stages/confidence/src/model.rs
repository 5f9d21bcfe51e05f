//! A trained confidence model: which input it reads ([`Kind`]), the
//! network, the feature parameters and the acceptance threshold; training,
//! rating and the byte format stored in the view database.
//!
//! # Byte format (little-endian)
//!
//! ```text
//! magic       8 bytes  "ACCHCONF"
//! version     u32      MODEL_FORMAT_VERSION
//! kind        u8       0 = features, 1 = response, 2 = grounded
//! inputs      u32      network inputs (4 for features, one per view for
//!                      response, one per view and one for grounded)
//! hidden      u32      hidden units
//! min_sep     f32      minimum azimuth separation, degrees
//! threshold   f32      acceptance threshold
//! mean        inputs × f32
//! std         inputs × f32   (each > 0)
//! w1          hidden × inputs × f32 (row per hidden unit)
//! b1          hidden × f32
//! w2          hidden × f32
//! b2          f32
//! ```
//!
//! The length must match exactly and every number must be finite.

use crate::features::{FEATURE_COUNT, FeatureParams, Features, normalised, scan_response};
use crate::network::{FitSettings, Network, fit};
use crate::{ConfidenceError, DEFAULT_THRESHOLD, Rating, SECTION};
use acch_core::{View, ViewDatabase};
use acch_pose::Slice;

const MAGIC: &[u8; 8] = b"ACCHCONF";
/// Version of the model byte format this build reads and writes.
pub const MODEL_FORMAT_VERSION: u32 = 1;
const HEADER_LEN: usize = 8 + 4 + 1 + 4 + 4 + 4 + 4;
/// Largest hidden layer accepted for training or loading.
pub const MAX_HIDDEN: usize = 4096;

/// What the network reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// The four features R_φ, D_φ, R_θ, D_θ (paper, section 4).
    Features,
    /// The whole response normalised by its maximum (the paper's first
    /// variant: the match values are the input vector). Tied to a database
    /// with exactly as many views as the model has inputs.
    Response,
    /// The normalised response and, as one more input, its maximum: the
    /// absolute match value of the best view, the histogram intersection
    /// with the nearest training view. It lets the network tell a weak
    /// match (an image far from anything seen in training) from a strong
    /// one of the same shape; the other two read only the shape. Tied to
    /// a database with one view fewer than the model has inputs.
    Grounded,
}

impl Kind {
    fn id(self) -> u8 {
        match self {
            Kind::Features => 0,
            Kind::Response => 1,
            Kind::Grounded => 2,
        }
    }

    fn from_id(id: u8) -> Option<Kind> {
        match id {
            0 => Some(Kind::Features),
            1 => Some(Kind::Response),
            2 => Some(Kind::Grounded),
            _ => None,
        }
    }

    /// The network input of this kind for one response (allocates: for
    /// building training sets, not for rating).
    pub fn input(
        self,
        params: &FeatureParams,
        response: &[f32],
        slices: &[Slice],
        views: &[View],
    ) -> Result<Vec<f32>, ConfidenceError> {
        match self {
            Kind::Features => Ok(Features::compute(response, slices, views, params)?
                .to_array()
                .to_vec()),
            Kind::Response => {
                let (_, g) = scan_response(response)?;
                Ok(response.iter().map(|&v| normalised(v, g)).collect())
            }
            Kind::Grounded => {
                let (_, g) = scan_response(response)?;
                let mut x: Vec<f32> = response.iter().map(|&v| normalised(v, g)).collect();
                x.push(g);
                Ok(x)
            }
        }
    }

    /// Inputs of a model of this kind that do not depend on the database
    /// (`None`: one per view).
    pub fn fixed_inputs(self) -> Option<usize> {
        match self {
            Kind::Features => Some(FEATURE_COUNT),
            Kind::Response | Kind::Grounded => None,
        }
    }

    /// Inputs of a model of this kind over a database of `views` views.
    pub fn inputs_for(self, views: usize) -> usize {
        match self {
            Kind::Features => FEATURE_COUNT,
            Kind::Response => views,
            Kind::Grounded => views + 1,
        }
    }
}

/// How examples of the two classes are weighted in the loss.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum ClassWeighting {
    /// Every example counts the same.
    #[default]
    Uniform,
    /// Each class contributes half of the loss, however rare it is.
    Balanced,
    /// Explicit weights per example of each class (finite, > 0).
    Manual {
        /// Weight of a reliable (positive) example.
        reliable: f64,
        /// Weight of an unreliable (negative) example.
        unreliable: f64,
    },
}

/// How to train a model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrainConfig {
    /// What the network reads.
    pub kind: Kind,
    /// Hidden tanh units (1..=[`MAX_HIDDEN`]).
    pub hidden: usize,
    /// Full-batch epochs (Adam steps).
    pub epochs: usize,
    /// Adam step size.
    pub learning_rate: f64,
    /// L2 penalty on the weights (not the biases), added to the mean
    /// cross-entropy as `l2 / 2 · Σ w²`.
    pub l2: f64,
    /// Seed of the weight initialisation.
    pub seed: u64,
    /// Class weighting of the loss.
    pub class_weighting: ClassWeighting,
    /// Feature definition, stored with the model.
    pub features: FeatureParams,
    /// Acceptance threshold stored with the model.
    pub threshold: f32,
}

impl TrainConfig {
    /// Defaults for `kind`: 8 hidden units for the features, 16 for the
    /// response; 2000 epochs of Adam at 0.01; L2 1e-4 (features) or 1e-2
    /// (response: hundreds of inputs overfit a few hundred examples, and
    /// 1e-2 generalised best on synthetic responses); seed 0; uniform class
    /// weights; 20° separation; threshold 0.8.
    pub fn new(kind: Kind) -> TrainConfig {
        let (hidden, l2) = match kind {
            Kind::Features => (8, 1e-4),
            Kind::Response | Kind::Grounded => (16, 1e-2),
        };
        TrainConfig {
            kind,
            hidden,
            epochs: 2000,
            learning_rate: 0.01,
            l2,
            seed: 0,
            class_weighting: ClassWeighting::Uniform,
            features: FeatureParams::default(),
            threshold: DEFAULT_THRESHOLD,
        }
    }

    /// Checks every setting.
    pub fn validate(&self) -> Result<(), ConfidenceError> {
        let bad = |m: String| Err(ConfidenceError::InvalidConfig(m));
        if !(1..=MAX_HIDDEN).contains(&self.hidden) {
            return bad(format!(
                "hidden units must be in 1..={MAX_HIDDEN}, got {}",
                self.hidden
            ));
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return bad(format!(
                "the learning rate must be a positive number, got {}",
                self.learning_rate
            ));
        }
        if !(self.l2.is_finite() && self.l2 >= 0.0) {
            return bad(format!("l2 must be a non-negative number, got {}", self.l2));
        }
        if let ClassWeighting::Manual {
            reliable,
            unreliable,
        } = self.class_weighting
            && !(reliable.is_finite()
                && reliable > 0.0
                && unreliable.is_finite()
                && unreliable > 0.0)
        {
            return bad(format!(
                "class weights must be positive numbers, got {reliable} and {unreliable}"
            ));
        }
        check_threshold(self.threshold)?;
        self.features.validate()
    }
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig::new(Kind::Features)
    }
}

fn check_threshold(t: f32) -> Result<(), ConfidenceError> {
    if (0.0..=1.0).contains(&t) {
        Ok(())
    } else {
        Err(ConfidenceError::InvalidConfig(format!(
            "the threshold must be in [0, 1], got {t}"
        )))
    }
}

/// A trained confidence model. Rating allocates nothing.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    kind: Kind,
    features: FeatureParams,
    threshold: f32,
    net: Network,
}

/// Trains a model on `(input, reliable)` samples, where each input is what
/// [`Kind::input`] returns for `config.kind`. See
/// [`train_with_progress`].
pub fn train(samples: &[(Vec<f32>, bool)], config: &TrainConfig) -> Result<Model, ConfidenceError> {
    train_with_progress(samples, config, &mut |_, _| {})
}

/// Trains a model, calling `progress(epoch, loss)` after every epoch
/// (epochs count from 1 to `config.epochs`; `loss` is the objective —
/// weighted mean cross-entropy of eq. 3 plus L2 — before that epoch's
/// update). Deterministic: the same samples and config give the same model.
///
/// Errors on an invalid config, no samples, inputs of unequal length (or
/// not 4 long for [`Kind::Features`]), non-finite inputs, a training set
/// with only one class, or a diverged optimisation (non-finite weights).
pub fn train_with_progress(
    samples: &[(Vec<f32>, bool)],
    config: &TrainConfig,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Model, ConfidenceError> {
    config.validate()?;
    let first = samples.first().ok_or(ConfidenceError::NoSamples)?;
    let d = first.0.len();
    if d == 0 {
        return Err(ConfidenceError::InvalidSample {
            index: 0,
            reason: "the input is empty".into(),
        });
    }
    if let Some(expected) = config.kind.fixed_inputs().filter(|&n| n != d) {
        return Err(ConfidenceError::InputSize { expected, found: d });
    }
    let mut x = Vec::with_capacity(samples.len() * d);
    let mut labels = Vec::with_capacity(samples.len());
    for (index, (input, label)) in samples.iter().enumerate() {
        if input.len() != d {
            return Err(ConfidenceError::InvalidSample {
                index,
                reason: format!("{} inputs, the first sample has {d}", input.len()),
            });
        }
        // Bounded so that standardisation cannot overflow f32.
        if let Some(v) = input.iter().find(|v| !(v.is_finite() && v.abs() < 1e15)) {
            return Err(ConfidenceError::InvalidSample {
                index,
                reason: format!("input value {v} is not a finite number of sane size"),
            });
        }
        x.extend_from_slice(input);
        labels.push(*label);
    }
    let positives = labels.iter().filter(|&&l| l).count();
    let negatives = labels.len() - positives;
    if positives == 0 || negatives == 0 {
        return Err(ConfidenceError::OneClass {
            reliable: positives,
            unreliable: negatives,
        });
    }
    let class_weights = match config.class_weighting {
        ClassWeighting::Uniform => (1.0, 1.0),
        ClassWeighting::Balanced => (
            labels.len() as f64 / (2 * positives) as f64,
            labels.len() as f64 / (2 * negatives) as f64,
        ),
        ClassWeighting::Manual {
            reliable,
            unreliable,
        } => (reliable, unreliable),
    };
    let net = fit(
        &x,
        &labels,
        d,
        &FitSettings {
            hidden: config.hidden,
            epochs: config.epochs,
            learning_rate: config.learning_rate,
            l2: config.l2,
            seed: config.seed,
            class_weights,
        },
        progress,
    );
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    if !(finite(&net.w1) && finite(&net.b1) && finite(&net.w2) && net.b2.is_finite()) {
        return Err(ConfidenceError::Diverged);
    }
    Ok(Model {
        kind: config.kind,
        features: config.features,
        threshold: config.threshold,
        net,
    })
}

impl Model {
    /// What the network reads.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// Number of network inputs (4, or the number of views).
    pub fn inputs(&self) -> usize {
        self.net.inputs
    }

    /// Number of hidden units.
    pub fn hidden(&self) -> usize {
        self.net.hidden
    }

    /// The feature definition the model was trained with.
    pub fn feature_params(&self) -> FeatureParams {
        self.features
    }

    /// The acceptance threshold.
    pub fn threshold(&self) -> f32 {
        self.threshold
    }

    /// Changes the acceptance threshold (in [0, 1]).
    pub fn set_threshold(&mut self, threshold: f32) -> Result<(), ConfidenceError> {
        check_threshold(threshold)?;
        self.threshold = threshold;
        Ok(())
    }

    /// The network's output for a raw input vector (what [`Kind::input`]
    /// returns): the probability that the estimate is reliable.
    pub fn predict(&self, input: &[f32]) -> Result<f32, ConfidenceError> {
        if input.len() != self.net.inputs {
            return Err(ConfidenceError::InputSize {
                expected: self.net.inputs,
                found: input.len(),
            });
        }
        Ok(self.net.predict(|i| input[i]))
    }

    /// Confidence that the estimate read off `response` is reliable, in
    /// [0, 1]; errors when the response, slices or views are invalid (see
    /// [`Features::compute`]) or the response length does not match a
    /// [`Kind::Response`] model. Allocates nothing.
    pub fn try_rate(
        &self,
        response: &[f32],
        slices: &[Slice],
        views: &[View],
    ) -> Result<f32, ConfidenceError> {
        match self.kind {
            Kind::Features => {
                let f = Features::compute(response, slices, views, &self.features)?.to_array();
                Ok(self.net.predict(|i| f[i]))
            }
            Kind::Response => {
                if response.len() != self.net.inputs {
                    return Err(ConfidenceError::InputSize {
                        expected: self.net.inputs,
                        found: response.len(),
                    });
                }
                let (_, g) = scan_response(response)?;
                Ok(self.net.predict(|i| normalised(response[i], g)))
            }
            Kind::Grounded => {
                if response.len() + 1 != self.net.inputs {
                    return Err(ConfidenceError::InputSize {
                        expected: self.net.inputs - 1,
                        found: response.len(),
                    });
                }
                let (_, g) = scan_response(response)?;
                let n = response.len();
                Ok(self
                    .net
                    .predict(|i| if i < n { normalised(response[i], g) } else { g }))
            }
        }
    }

    /// [`try_rate`](Self::try_rate), with 0 (reject) for input it cannot
    /// rate: an estimate from an invalid response is not reliable. The
    /// per-frame call; allocates nothing.
    pub fn rate(&self, response: &[f32], slices: &[Slice], views: &[View]) -> f32 {
        self.try_rate(response, slices, views).unwrap_or(0.0)
    }

    /// [`rate`](Self::rate) and the decision against the model's threshold.
    pub fn rating(&self, response: &[f32], slices: &[Slice], views: &[View]) -> Rating {
        Rating::new(self.rate(response, slices, views), self.threshold)
    }

    /// Serialises the model (see the module documentation for the layout).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = &self.net;
        let floats = 2 * n.inputs + n.hidden * n.inputs + 2 * n.hidden + 1;
        let mut out = Vec::with_capacity(HEADER_LEN + 4 * floats);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&MODEL_FORMAT_VERSION.to_le_bytes());
        out.push(self.kind.id());
        out.extend_from_slice(&(n.inputs as u32).to_le_bytes());
        out.extend_from_slice(&(n.hidden as u32).to_le_bytes());
        out.extend_from_slice(&self.features.min_phi_separation_deg.to_le_bytes());
        out.extend_from_slice(&self.threshold.to_le_bytes());
        for v in n
            .mean
            .iter()
            .chain(&n.std)
            .chain(&n.w1)
            .chain(&n.b1)
            .chain(&n.w2)
            .chain(std::iter::once(&n.b2))
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Parses [`to_bytes`](Self::to_bytes) output. A wrong magic, another
    /// version, a wrong length, an unknown kind, impossible sizes or a
    /// non-finite number give an error, never a panic.
    pub fn from_bytes(bytes: &[u8]) -> Result<Model, ConfidenceError> {
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err(ConfidenceError::BadMagic);
        }
        if bytes.len() < HEADER_LEN {
            return Err(ConfidenceError::Truncated {
                expected: HEADER_LEN,
                found: bytes.len(),
            });
        }
        let u32_at = |at: usize| {
            let mut b = [0u8; 4];
            b.copy_from_slice(&bytes[at..at + 4]);
            u32::from_le_bytes(b)
        };
        let f32_at = |at: usize| f32::from_bits(u32_at(at));
        let version = u32_at(8);
        if version != MODEL_FORMAT_VERSION {
            return Err(ConfidenceError::UnsupportedVersion {
                found: version,
                supported: MODEL_FORMAT_VERSION,
            });
        }
        let corrupt = |m: String| Err(ConfidenceError::Corrupt(m));
        let Some(kind) = Kind::from_id(bytes[12]) else {
            return corrupt(format!("unknown model kind {}", bytes[12]));
        };
        let inputs = u32_at(13) as usize;
        let hidden = u32_at(17) as usize;
        let min_sep = f32_at(21);
        let threshold = f32_at(25);
        if inputs == 0 || kind.fixed_inputs().is_some_and(|n| n != inputs) {
            return corrupt(format!("{inputs} inputs for a {kind:?} model"));
        }
        if !(1..=MAX_HIDDEN).contains(&hidden) {
            return corrupt(format!("{hidden} hidden units"));
        }
        let features = FeatureParams {
            min_phi_separation_deg: min_sep,
        };
        features
            .validate()
            .map_err(|e| ConfidenceError::Corrupt(e.to_string()))?;
        check_threshold(threshold).map_err(|e| ConfidenceError::Corrupt(e.to_string()))?;
        // inputs < 2^32 and hidden <= 4096: no overflow on 64-bit, checked
        // anyway for 32-bit targets.
        let floats = inputs
            .checked_mul(hidden)
            .and_then(|w| w.checked_add(inputs.checked_mul(2)?))
            .and_then(|n| n.checked_add(2 * hidden + 1));
        let expected = floats
            .and_then(|n| n.checked_mul(4))
            .and_then(|n| n.checked_add(HEADER_LEN));
        let Some(expected) = expected else {
            return corrupt("sizes overflow".into());
        };
        if bytes.len() < expected {
            return Err(ConfidenceError::Truncated {
                expected,
                found: bytes.len(),
            });
        }
        if bytes.len() > expected {
            return corrupt(format!("{} bytes after the model", bytes.len() - expected));
        }
        let all: Vec<f32> = bytes[HEADER_LEN..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if let Some(v) = all.iter().find(|v| !v.is_finite()) {
            return corrupt(format!("a weight is not a finite number ({v})"));
        }
        let (mean, rest) = all.split_at(inputs);
        let (std, rest) = rest.split_at(inputs);
        let (w1, rest) = rest.split_at(inputs * hidden);
        let (b1, rest) = rest.split_at(hidden);
        let (w2, b2) = rest.split_at(hidden);
        if std.iter().any(|&s| s <= 0.0) {
            return corrupt("a standard deviation is not positive".into());
        }
        Ok(Model {
            kind,
            features,
            threshold,
            net: Network {
                inputs,
                hidden,
                mean: mean.to_vec(),
                std: std.to_vec(),
                w1: w1.to_vec(),
                b1: b1.to_vec(),
                w2: w2.to_vec(),
                b2: b2[0],
            },
        })
    }

    /// Stores the model in `db`'s [`SECTION`] section, replacing any.
    pub fn store(&self, db: &mut ViewDatabase) {
        db.sections.insert(SECTION.to_owned(), self.to_bytes());
    }

    /// Loads the model from `db`'s [`SECTION`] section. Errors when the
    /// section is missing or corrupt, or when a [`Kind::Response`] model
    /// does not have one input per view of `db`.
    pub fn load(db: &ViewDatabase) -> Result<Model, ConfidenceError> {
        let bytes = db
            .sections
            .get(SECTION)
            .ok_or(ConfidenceError::MissingSection)?;
        let model = Model::from_bytes(bytes)?;
        let expected = model.kind.inputs_for(db.views().len());
        if model.inputs() != expected {
            return Err(ConfidenceError::InputSize {
                expected,
                found: model.inputs(),
            });
        }
        Ok(model)
    }
}
