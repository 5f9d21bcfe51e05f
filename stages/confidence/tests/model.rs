//! Training, rating and the byte format, through the public API.

mod common;

use acch_confidence::{
    ClassWeighting, ConfidenceError, DEFAULT_THRESHOLD, Kind, Model, SECTION, TrainConfig, roc_auc,
    train, train_with_progress,
};
use acch_core::{ColourSpace, HistogramParams, Palette, View, ViewDatabase};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

type Samples = Vec<(Vec<f32>, bool)>;

fn accuracy(model: &Model, set: &Samples) -> f64 {
    let right = set
        .iter()
        .filter(|(x, l)| (model.predict(x).unwrap() >= 0.5) == *l)
        .count();
    right as f64 / set.len() as f64
}

/// Points in [-1, 1]^4 labelled by a line in the first two coordinates; the
/// other two are noise.
fn linear(n: usize, seed: u64) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let x: Vec<f32> = (0..4).map(|_| rng.random_range(-1.0..1.0)).collect();
            let label = 0.8 * x[0] - 0.6 * x[1] + 0.1 > 0.0;
            // Different scales per input, as the real features have (D_φ
            // is in degrees): standardisation has to cope.
            (vec![x[0], 100.0 * x[1], x[2], 5.0 + x[3]], label)
        })
        .collect()
}

/// XOR of the signs of two coordinates, away from the axes.
fn xor(n: usize, seed: u64) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let mut c = || {
                let v: f32 = rng.random_range(0.1..1.0);
                if rng.random_bool(0.5) { v } else { -v }
            };
            let (a, b) = (c(), c());
            (vec![a, b], (a > 0.0) != (b > 0.0))
        })
        .collect()
}

#[test]
fn learns_a_linear_split() {
    let config = TrainConfig::new(Kind::Features);
    let model = train(&linear(400, 1), &config).unwrap();
    let acc = accuracy(&model, &linear(1000, 2));
    assert!(acc > 0.95, "held-out accuracy {acc}");
}

#[test]
fn learns_xor_with_the_hidden_layer() {
    let config = TrainConfig {
        hidden: 8,
        ..TrainConfig::new(Kind::Response)
    };
    let model = train(&xor(400, 3), &config).unwrap();
    let acc = accuracy(&model, &xor(1000, 4));
    assert!(acc > 0.95, "held-out accuracy {acc}");
    // One hidden unit is a monotone function of one projection: it cannot
    // separate XOR, so the test above really needs the hidden layer.
    let one = train(
        &xor(400, 3),
        &TrainConfig {
            hidden: 1,
            ..config
        },
    )
    .unwrap();
    let acc1 = accuracy(&one, &xor(1000, 4));
    assert!(acc1 < 0.85, "one hidden unit reached {acc1}");
}

/// The minimum of eq. 3 is the relative frequency of reliable examples:
/// with an uninformative input the network outputs it; balanced weighting
/// moves it to one half.
#[test]
fn class_weighting_shifts_the_prior() {
    let mut samples: Samples = (0..90).map(|_| (vec![0.5, 30.0, 0.5, 1.0], true)).collect();
    samples.extend((0..10).map(|_| (vec![0.5, 30.0, 0.5, 1.0], false)));
    let base = TrainConfig {
        l2: 0.0,
        epochs: 1500,
        ..TrainConfig::new(Kind::Features)
    };
    let x = [0.5, 30.0, 0.5, 1.0];
    let uniform = train(&samples, &base).unwrap().predict(&x).unwrap();
    assert!((uniform - 0.9).abs() < 0.01, "{uniform}");
    let balanced = TrainConfig {
        class_weighting: ClassWeighting::Balanced,
        ..base
    };
    let p = train(&samples, &balanced).unwrap().predict(&x).unwrap();
    assert!((p - 0.5).abs() < 0.01, "{p}");
    let manual = TrainConfig {
        class_weighting: ClassWeighting::Manual {
            reliable: 1.0,
            unreliable: 81.0,
        },
        ..base
    };
    // 90 vs 810: 0.1.
    let p = train(&samples, &manual).unwrap().predict(&x).unwrap();
    assert!((p - 0.1).abs() < 0.01, "{p}");
}

#[test]
fn training_is_deterministic_and_reports_progress() {
    let samples = linear(200, 5);
    let config = TrainConfig {
        epochs: 300,
        ..TrainConfig::default()
    };
    let mut losses = Vec::new();
    let a = train_with_progress(&samples, &config, &mut |epoch, loss| {
        assert_eq!(epoch, losses.len() + 1);
        losses.push(loss);
    })
    .unwrap();
    assert_eq!(losses.len(), 300);
    assert!(
        losses[299] < 0.3 * losses[0],
        "{} -> {}",
        losses[0],
        losses[299]
    );
    let b = train(&samples, &config).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.to_bytes(), b.to_bytes());
    let c = train(&samples, &TrainConfig { seed: 9, ..config }).unwrap();
    assert_ne!(a, c);
}

#[test]
fn bad_training_input_is_an_error() {
    let config = TrainConfig::default();
    assert!(matches!(
        train(&[], &config),
        Err(ConfidenceError::NoSamples)
    ));
    let two = vec![(vec![0.0, 1.0], true), (vec![1.0, 0.0], false)];
    assert!(matches!(
        train(&two, &config),
        Err(ConfidenceError::InputSize {
            expected: 4,
            found: 2
        })
    ));
    let ragged = vec![(vec![0.0; 4], true), (vec![1.0; 3], false)];
    assert!(matches!(
        train(&ragged, &config),
        Err(ConfidenceError::InvalidSample { index: 1, .. })
    ));
    let nan = vec![(vec![0.0; 4], true), (vec![f32::NAN; 4], false)];
    assert!(matches!(
        train(&nan, &config),
        Err(ConfidenceError::InvalidSample { index: 1, .. })
    ));
    let one_class = vec![(vec![0.0; 4], true), (vec![1.0; 4], true)];
    assert!(matches!(
        train(&one_class, &config),
        Err(ConfidenceError::OneClass {
            reliable: 2,
            unreliable: 0
        })
    ));
    let ok = vec![(vec![0.0; 4], true), (vec![1.0; 4], false)];
    for bad in [
        TrainConfig {
            hidden: 0,
            ..config
        },
        TrainConfig {
            learning_rate: f64::NAN,
            ..config
        },
        TrainConfig { l2: -1.0, ..config },
        TrainConfig {
            threshold: 1.5,
            ..config
        },
        TrainConfig {
            class_weighting: ClassWeighting::Manual {
                reliable: 0.0,
                unreliable: 1.0,
            },
            ..config
        },
    ] {
        assert!(
            matches!(train(&ok, &bad), Err(ConfidenceError::InvalidConfig(_))),
            "{bad:?}"
        );
    }
    let diverging = TrainConfig {
        learning_rate: 1e300,
        epochs: 5,
        ..config
    };
    assert!(matches!(
        train(&ok, &diverging),
        Err(ConfidenceError::Diverged)
    ));
}

/// Both kinds separate clear responses from ambiguous ones they never saw.
/// The features generalise from fewer examples: the raw response has to
/// learn every peak position separately (at 300 examples its AUC is about
/// 0.95, at 1500 it reaches 1).
#[test]
fn rates_synthetic_responses() {
    let (slices, views) = common::grid();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let make = |rng: &mut ChaCha8Rng, n: usize| -> Vec<(Vec<f32>, bool)> {
        (0..n)
            .map(|i| {
                let reliable = i % 3 != 0;
                (common::response(rng, &views, reliable), reliable)
            })
            .collect()
    };
    let train_set = make(&mut rng, 600);
    let test_set = make(&mut rng, 300);
    for kind in [Kind::Features, Kind::Response] {
        let config = TrainConfig {
            epochs: if kind == Kind::Response { 500 } else { 2000 },
            ..TrainConfig::new(kind)
        };
        let samples: Samples = train_set
            .iter()
            .map(|(r, l)| {
                (
                    kind.input(&config.features, r, &slices, &views).unwrap(),
                    *l,
                )
            })
            .collect();
        let model = train(&samples, &config).unwrap();
        let scores: Vec<f32> = test_set
            .iter()
            .map(|(r, _)| model.rate(r, &slices, &views))
            .collect();
        let labels: Vec<bool> = test_set.iter().map(|(_, l)| *l).collect();
        let auc = roc_auc(&scores, &labels);
        let bound = if kind == Kind::Features { 0.99 } else { 0.95 };
        assert!(auc > bound, "{kind:?}: AUC {auc}");
        let right = scores
            .iter()
            .zip(&labels)
            .filter(|&(&s, &l)| (s >= 0.5) == l)
            .count();
        eprintln!("{kind:?}: AUC {auc:.4}, {right}/300 right at 0.5");
        assert!(right as f64 / 300.0 > 0.9, "{kind:?}: {right}/300 right");
        // rating() accepts the example the model is surest is reliable and
        // rejects the one it is surest is not: outcomes known from the
        // labels, not the formula restated.
        let surest = |reliable: bool| {
            let pick = test_set
                .iter()
                .zip(&scores)
                .filter(|((_, l), _)| *l == reliable)
                .map(|((r, _), s)| (r, *s));
            if reliable {
                pick.max_by(|a, b| a.1.total_cmp(&b.1))
            } else {
                pick.min_by(|a, b| a.1.total_cmp(&b.1))
            }
            .unwrap()
            .0
        };
        let (yes, no) = (
            model.rating(surest(true), &slices, &views),
            model.rating(surest(false), &slices, &views),
        );
        assert!(
            yes.accepted && yes.confidence > DEFAULT_THRESHOLD,
            "{kind:?}: {yes:?}"
        );
        assert!(
            !no.accepted && no.confidence < DEFAULT_THRESHOLD,
            "{kind:?}: {no:?}"
        );
        let (r, _) = &test_set[0];
        // Unratable input is rejected, not a panic.
        assert_eq!(model.rate(&r[1..], &slices, &views), 0.0);
        assert!(model.try_rate(&r[1..], &slices, &views).is_err());
        let mut nan = r.clone();
        nan[5] = f32::NAN;
        assert_eq!(model.rate(&nan, &slices, &views), 0.0);
    }
}

/// A weak match of a good shape: every response of the same sharp shape,
/// half of them scaled down to a third (the object far from anything seen
/// in training) and labelled unreliable. The shape-only inputs cannot tell
/// them apart; the grounded input, which reads the absolute match value,
/// must.
#[test]
fn only_the_grounded_input_rejects_weak_matches_of_a_good_shape() {
    let (slices, views) = common::grid();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let make = |rng: &mut ChaCha8Rng, n: usize| -> Vec<(Vec<f32>, bool)> {
        (0..n)
            .map(|i| {
                let mut r = common::response(rng, &views, true);
                let strong = i % 2 == 0;
                if !strong {
                    let k: f32 = rng.random_range(0.25..0.4);
                    r.iter_mut().for_each(|v| *v *= k);
                }
                (r, strong)
            })
            .collect()
    };
    let (train_set, test_set) = (make(&mut rng, 400), make(&mut rng, 200));
    let labels: Vec<bool> = test_set.iter().map(|(_, l)| *l).collect();
    let auc = |kind: Kind| {
        let config = TrainConfig {
            epochs: if kind == Kind::Features { 1500 } else { 500 },
            ..TrainConfig::new(kind)
        };
        let samples: Samples = train_set
            .iter()
            .map(|(r, l)| {
                (
                    kind.input(&config.features, r, &slices, &views).unwrap(),
                    *l,
                )
            })
            .collect();
        let model = train(&samples, &config).unwrap();
        let scores: Vec<f32> = test_set
            .iter()
            .map(|(r, _)| model.rate(r, &slices, &views))
            .collect();
        roc_auc(&scores, &labels)
    };
    let (features, response, grounded) = (
        auc(Kind::Features),
        auc(Kind::Response),
        auc(Kind::Grounded),
    );
    eprintln!("AUC features {features:.3}, response {response:.3}, grounded {grounded:.3}");
    assert!(grounded > 0.98, "grounded AUC {grounded}");
    for (name, auc) in [("features", features), ("response", response)] {
        assert!(
            auc < 0.75,
            "{name} AUC {auc}: the shape alone told them apart"
        );
    }
    assert_eq!(Kind::Grounded.inputs_for(10), 11);
}

fn small_model(kind: Kind, inputs: usize) -> Model {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let samples: Samples = (0..40)
        .map(|i| {
            let x: Vec<f32> = (0..inputs).map(|_| rng.random_range(0.0..1.0)).collect();
            (x, i % 2 == 0)
        })
        .collect();
    let config = TrainConfig {
        epochs: 50,
        hidden: 5,
        ..TrainConfig::new(kind)
    };
    train(&samples, &config).unwrap()
}

#[test]
fn bytes_round_trip_exactly() {
    let (slices, views) = common::grid();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for (kind, inputs) in [
        (Kind::Features, 4),
        (Kind::Response, views.len()),
        (Kind::Grounded, views.len() + 1),
    ] {
        let mut model = small_model(kind, inputs);
        model.set_threshold(0.65).unwrap();
        let back = Model::from_bytes(&model.to_bytes()).unwrap();
        assert_eq!(back, model);
        assert_eq!(back.threshold(), 0.65);
        assert_eq!(back.kind(), kind);
        for _ in 0..20 {
            let reliable = rng.random_bool(0.5);
            let r = common::response(&mut rng, &views, reliable);
            let a = model.rate(&r, &slices, &views);
            let b = back.rate(&r, &slices, &views);
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }
}

fn database(views: &[View]) -> ViewDatabase {
    let palette = Palette::from_centres(ColourSpace::Lab, vec![[50.0, 0.0, 0.0]], 10.0).unwrap();
    let params = HistogramParams {
        colours: 1,
        bins: 2,
        ..HistogramParams::default()
    };
    let mut db = ViewDatabase::new("box", palette, params, 5.0);
    let h = vec![1.0 / params.len() as f32; params.len()];
    for v in views {
        db.push_view(*v, &h);
    }
    db
}

#[test]
fn stored_in_the_database() {
    let (slices, views) = common::grid();
    let mut db = database(&views);
    assert!(matches!(
        Model::load(&db),
        Err(ConfidenceError::MissingSection)
    ));
    let model = small_model(Kind::Response, views.len());
    model.store(&mut db);
    assert!(db.sections.contains_key(SECTION));
    let back = ViewDatabase::from_bytes(&db.to_bytes(), std::path::Path::new("x")).unwrap();
    let loaded = Model::load(&back).unwrap();
    assert_eq!(loaded, model);
    let r = vec![0.5; views.len()];
    assert_eq!(
        loaded.rate(&r, &slices, &views).to_bits(),
        model.rate(&r, &slices, &views).to_bits()
    );
    // A response model does not fit a database with other views.
    let other = database(&views[..36]);
    let mut other = other;
    model.store(&mut other);
    assert!(matches!(
        Model::load(&other),
        Err(ConfidenceError::InputSize { .. })
    ));
}

#[test]
fn corrupt_bytes_are_errors() {
    let model = small_model(Kind::Features, 4);
    let bytes = model.to_bytes();
    // Every truncation.
    for cut in 0..bytes.len() {
        let e = Model::from_bytes(&bytes[..cut]).unwrap_err();
        assert!(
            matches!(
                e,
                ConfidenceError::BadMagic | ConfidenceError::Truncated { .. }
            ),
            "cut at {cut}: {e}"
        );
    }
    let patched = |at: usize, v: &[u8]| {
        let mut b = bytes.clone();
        b[at..at + v.len()].copy_from_slice(v);
        Model::from_bytes(&b)
    };
    assert!(matches!(patched(0, b"X"), Err(ConfidenceError::BadMagic)));
    assert!(matches!(
        patched(8, &7u32.to_le_bytes()),
        Err(ConfidenceError::UnsupportedVersion { found: 7, .. })
    ));
    assert!(matches!(
        patched(12, &[9]),
        Err(ConfidenceError::Corrupt(_))
    ));
    // A features model with 5 inputs; a response model whose claimed size
    // does not match the bytes; absurd hidden sizes.
    assert!(matches!(
        patched(13, &5u32.to_le_bytes()),
        Err(ConfidenceError::Corrupt(_))
    ));
    let mut b = bytes.clone();
    b[12] = 1;
    b[13..17].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        Model::from_bytes(&b),
        Err(ConfidenceError::Truncated { .. })
    ));
    for hidden in [0u32, u32::MAX] {
        assert!(matches!(
            patched(17, &hidden.to_le_bytes()),
            Err(ConfidenceError::Corrupt(_))
        ));
    }
    assert!(matches!(
        patched(21, &f32::NAN.to_le_bytes()),
        Err(ConfidenceError::Corrupt(_))
    ));
    assert!(matches!(
        patched(25, &2.0f32.to_le_bytes()),
        Err(ConfidenceError::Corrupt(_))
    ));
    // Non-finite weight (the last one is b2), zero standard deviation.
    let last = bytes.len() - 4;
    assert!(matches!(
        patched(last, &f32::INFINITY.to_le_bytes()),
        Err(ConfidenceError::Corrupt(_))
    ));
    let std0 = 29 + 4 * 4;
    assert!(matches!(
        patched(std0, &0.0f32.to_le_bytes()),
        Err(ConfidenceError::Corrupt(_))
    ));
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(
        Model::from_bytes(&long),
        Err(ConfidenceError::Corrupt(_))
    ));
    // Random damage: an error or a valid model, never a panic.
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    for _ in 0..2000 {
        let mut b = bytes.clone();
        for _ in 0..rng.random_range(1..4) {
            let i = rng.random_range(0..b.len());
            b[i] = rng.random();
        }
        if let Ok(m) = Model::from_bytes(&b) {
            let (slices, views) = common::grid();
            let c = m.rate(&vec![0.5; views.len()], &slices, &views);
            assert!((0.0..=1.0).contains(&c), "{c}");
        }
    }
}
