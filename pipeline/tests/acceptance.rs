//! Accepted means rated at or above the threshold with no far view
//! matching nearly as well, no broad crest in azimuth about the estimate,
//! no view beyond the tolerance placing the region's colours clearly
//! better, not both faintly detected and weakly matched,
//! and nothing else: a database without a confidence network is refused
//! unless the run is explicitly unrated (and then nothing is accepted),
//! and a response the network cannot rate is a counted fault, never an
//! accepted estimate.

use acch_capture::{
    Background, DEFAULT_DISTANCE, Object, Renderer, SceneConfig, ViewPose, ViewSpec,
};
use acch_core::ViewDatabase;
use acch_pipeline::stage::{StageCounters, step};
use acch_pipeline::stages::{
    BuildError, Confidence, PoseEstimate, Posed, Rating, Seeding, ShapeFit, Window,
};
use acch_pipeline::wire::{Fault, Intrinsics, Outcome, PixelRect};
use acch_pipeline::{Chain, FrameHeader, StageId, StageSettings};
use std::sync::Arc;

fn database(with_network: bool) -> ViewDatabase {
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let plain = Renderer::new(SceneConfig::new(object, Background::default()), 0);
    let grid = ViewSpec::Grid {
        thetas_deg: vec![50.0, 70.0, 90.0],
        phi_step_deg: 30.0,
    };
    let acch_testkit::Trained { mut db, model } =
        acch_testkit::train_on_views("fruitbox", &plain, &grid);
    db.sections
        .insert(acch_recognition::SECTION.to_owned(), model.to_bytes());
    if with_network {
        let views = db.views().len();
        let samples: Vec<(Vec<f32>, bool)> = (0..16)
            .map(|i| {
                (
                    (0..views).map(|v| ((v + i) % 5) as f32 / 5.0).collect(),
                    i % 2 == 0,
                )
            })
            .collect();
        let config = acch_confidence::TrainConfig {
            epochs: 5,
            ..acch_confidence::TrainConfig::new(acch_confidence::Kind::Response)
        };
        acch_confidence::train(&samples, &config)
            .unwrap()
            .store(&mut db);
    }
    db
}

fn settings(unrated: bool) -> StageSettings {
    StageSettings {
        width: 640,
        height: 480,
        // The training distance: the frames are rendered there.
        distance_m: Some(DEFAULT_DISTANCE * Object::builtin("fruitbox").unwrap().radius_m()),
        unrated,
        roll_search_deg: 0.0,
        light_search: 0,
        verify_shape: true,
    }
}

/// Pose's header of an estimate on a region.
fn posed() -> Posed {
    let mut p = Posed {
        pose: Outcome::Done(PoseEstimate {
            theta_deg: 60.0,
            phi_deg: 30.0,
            best_value: 0.9,
            scale: 1.0,
            best_view: 3,
            roll_deg: 0.0,
            map_rival: -0.2,
            shape: Outcome::Nothing,
        }),
        ..Default::default()
    };
    p.segmented.region = Outcome::Done(PixelRect {
        x: 300,
        y: 200,
        width: 40,
        height: 40,
    });
    let f = &mut p.segmented.recognised.envelope.frame;
    (f.width, f.height) = (640, 480);
    f.intrinsics = Intrinsics::from_array([500.0, 500.0, 319.5, 239.5]);
    p
}

#[test]
fn a_database_without_a_network_is_refused_unless_the_run_is_unrated() {
    let db = database(false);
    match Confidence::new(&db, &settings(false)) {
        Err(e @ BuildError::NoConfidence { .. }) => {
            let msg = e.to_string();
            assert!(
                msg.contains("no confidence network") && msg.contains("--unrated"),
                "{msg}"
            );
        }
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("a database without a network was accepted"),
    }
    assert!(Chain::build(&db, &settings(false)).is_err());
    // Unrated: every estimate is marked so, none is accepted or seeded.
    let mut chain = Chain::build(&db, &settings(true)).unwrap();
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let scene = Renderer::new(SceneConfig::new(object, Background::A), 1);
    let r = scene.render(&ViewPose::new(70.0, 30.0, DEFAULT_DISTANCE).unwrap(), 1);
    let frame = FrameHeader::rgb(0, 640, 480, Intrinsics::from(&r.truth.intrinsics));
    let out = chain.process(&frame, r.image.as_raw());
    assert!(out.pose().done().is_some(), "the scene must be estimated");
    assert_eq!(*out.rating(), Rating::Unrated);
    assert!(!out.accepted());
    assert!(out.seed().is_none());
}

#[test]
fn the_stage_rejects_an_estimate_on_a_broad_crest_in_azimuth() {
    let db = database(true);
    // Slices of 12 views, 30° apart: the best at θ 50°, φ 90°.
    let views = db.views();
    let best = views
        .iter()
        .position(|v| v.theta_deg == 50.0 && v.phi_deg == 90.0)
        .expect("the grid's view");
    let rate = |neighbours: f32| {
        let mut response = vec![0.3f32; views.len()];
        response[best] = 0.9;
        response[best - 1] = neighbours;
        response[best + 1] = neighbours;
        let bytes: Vec<u8> = response.iter().flat_map(|v| v.to_ne_bytes()).collect();
        let mut confidence = Confidence::new(&db, &settings(false)).unwrap();
        let mut counters = StageCounters::new(StageId::Confidence);
        let rated = step(
            &mut confidence,
            &posed(),
            &bytes,
            &[],
            &mut [],
            0,
            &mut counters,
        );
        assert_eq!(counters.total_faults(), 0);
        rated.rating.verdict().expect("rated")
    };
    // φ 60° and 120° within 2 % of the best: a crest 60° wide.
    let crest = rate(0.89);
    assert_eq!(crest.phi_plateau_deg, 60.0);
    assert!(crest.broad() && !crest.accepted, "{crest:?}");
    // The same neighbours well below the best: a peak.
    let peak = rate(0.6);
    assert_eq!(peak.phi_plateau_deg, 0.0);
    assert!(!peak.broad(), "{peak:?}");
}

#[test]
fn a_pose_the_shape_chose_is_judged_against_the_training_distance_or_the_arms() {
    let db = database(true);
    let views = db.views().len();
    let response: Vec<u8> = (0..views)
        .flat_map(|v| (v as f32 / views as f32).to_ne_bytes())
        .collect();
    // A fit the shape chose that explains the region clearly, the object
    // `distance_m` ahead of the camera.
    let fitted = |distance_m: f32| {
        let mut p = posed();
        if let Outcome::Done(e) = &mut p.pose {
            e.shape = Outcome::Done(ShapeFit {
                rotation: [0.0, 0.0, 0.0, 1.0],
                translation_m: [0.0, 0.0, distance_m],
                separation: 0.8,
                overlap: 0.9,
                region_edge: 0.95,
                contour_edges: 0.9,
                in_frame: 1.0,
                score: 5.0,
                rival_score: 4.0,
                candidates: 12,
                anchored: 0,
                colour_view_deg: [f32::NAN; 3],
                covariance: [0.0; 21],
            });
        }
        p
    };
    let judged = |settings: &StageSettings, distance_m: f32| {
        let mut confidence = Confidence::new(&db, settings).unwrap();
        let mut counters = StageCounters::new(StageId::Confidence);
        let posed = fitted(distance_m);
        let rated = step(
            &mut confidence,
            &posed,
            &response,
            &[],
            &mut [],
            0,
            &mut counters,
        );
        rated.rating.verdict().expect("rated")
    };
    // No distance from the arm: the training distance sets the bar.
    let unknown = StageSettings {
        distance_m: None,
        ..settings(false)
    };
    let bar = acch_confidence::MAX_DISTANCE_RATIO * db.train_distance_m;
    let near = judged(&unknown, 0.99 * bar);
    assert!(near.accepted && near.verified == 1, "{near:?}");
    let far = judged(&unknown, 1.01 * bar);
    assert!(!far.accepted && !far.shape_near(), "{far:?}");
    assert_eq!(far.max_distance_m, bar);
    // The arm reports the object twice as far: the bar follows it.
    let arm = StageSettings {
        distance_m: Some(2.0 * db.train_distance_m as f64),
        ..settings(false)
    };
    assert!(judged(&arm, 1.01 * bar).accepted);
}

#[test]
fn a_response_of_the_wrong_length_is_a_counted_fault_not_an_acceptance() {
    let db = database(true);
    let views = db.views().len();
    let mut confidence = Confidence::new(&db, &settings(false)).unwrap();
    let mut seeding = Seeding::new(&db, &settings(false)).unwrap();
    let mut counters = StageCounters::new(StageId::Confidence);
    let mut seed_counters = StageCounters::new(StageId::Seeding);
    let response: Vec<u8> = (0..views)
        .flat_map(|v| (v as f32 / views as f32).to_ne_bytes())
        .collect();
    // The whole response: rated, no fault.
    let rated = step(
        &mut confidence,
        &posed(),
        &response,
        &[],
        &mut [],
        0,
        &mut counters,
    );
    rated.rating.verdict().expect("rated");
    assert_eq!(counters.total_faults(), 0);
    // One value short: a fault, counted, not accepted, not seeded.
    let short = &response[..4 * (views - 1)];
    let rated = step(
        &mut confidence,
        &posed(),
        short,
        &[],
        &mut [],
        0,
        &mut counters,
    );
    assert_eq!(rated.rating, Rating::Failed(Fault::Response));
    assert_eq!(counters.faults_of(Fault::Response), 1);
    let seeded = step(
        &mut seeding,
        &rated,
        &[],
        &[],
        &mut [],
        0,
        &mut seed_counters,
    );
    assert!(!seeded.accepted());
    assert!(seeded.seed().is_none());
    // A response of values the network cannot rate (not finite): the same.
    let nan: Vec<u8> = (0..views).flat_map(|_| f32::NAN.to_ne_bytes()).collect();
    let rated = step(
        &mut confidence,
        &posed(),
        &nan,
        &[],
        &mut [],
        0,
        &mut counters,
    );
    assert_eq!(rated.rating, Rating::Failed(Fault::Response));
    assert_eq!(counters.faults_of(Fault::Response), 2);
}

/// A database whose network's threshold is 0, and its confidence stage:
/// whatever it rates is accepted unless a rule rejects it.
fn accepting_every_rating() -> (ViewDatabase, Confidence) {
    let mut db = database(true);
    let mut model = acch_confidence::Model::load(&db).unwrap();
    model.set_threshold(0.0).unwrap();
    model.store(&mut db);
    let confidence = Confidence::new(&db, &settings(false)).unwrap();
    (db, confidence)
}

#[test]
fn a_far_view_matching_as_well_is_rejected_whatever_the_network_says() {
    let (db, mut confidence) = accepting_every_rating();
    let views = db.views().len();
    let mut counters = StageCounters::new(StageId::Confidence);
    let bytes = |r: &[f32]| -> Vec<u8> { r.iter().flat_map(|v| v.to_ne_bytes()).collect() };
    let mut rate = |confidence: &mut Confidence, r: &[f32]| {
        step(
            confidence,
            &posed(),
            &bytes(r),
            &[],
            &mut [],
            0,
            &mut counters,
        )
        .rating
        .verdict()
        .expect("rated")
    };
    // One peak over a floor: every rating clears a threshold of 0.
    let mut response = vec![0.1f32; views];
    response[0] = 0.9;
    let clear = rate(&mut confidence, &response);
    assert!(clear.accepted && !clear.ambiguous(), "{clear:?}");
    // A view half a turn away in φ matching as well: rejected.
    let opposite = db
        .views()
        .iter()
        .position(|v| {
            v.theta_deg == db.views()[0].theta_deg
                && acch_pose::phi_error(v.phi_deg, db.views()[0].phi_deg) == 180.0
        })
        .expect("the grid holds the opposite view");
    response[opposite] = 0.9;
    let tie = rate(&mut confidence, &response);
    assert!(tie.confidence >= tie.threshold, "{tie:?}");
    assert!(
        !tie.accepted && tie.ambiguous() && tie.rival == 1.0,
        "{tie:?}"
    );
    // Just under the bar: accepted again.
    response[opposite] = 0.9 * acch_confidence::MAX_RIVAL_RATIO * 0.999;
    assert!(rate(&mut confidence, &response).accepted);
    // The same azimuth beyond the tolerance in elevation: a tilt the
    // response cannot place, rejected; by azimuth alone it was accepted.
    response[opposite] = 0.1;
    let (theta0, phi0) = (db.views()[0].theta_deg, db.views()[0].phi_deg);
    let tilted = db
        .views()
        .iter()
        .position(|v| v.phi_deg == phi0 && (v.theta_deg - theta0).abs() > 10.0)
        .expect("the grid holds a view two slices away");
    response[tilted] = 0.9;
    let tilt = rate(&mut confidence, &response);
    assert!(!tilt.accepted && tilt.ambiguous(), "{tilt:?}");
    confidence.rivals_in_azimuth_only();
    assert!(rate(&mut confidence, &response).accepted);
}

#[test]
fn a_faint_detection_matched_weakly_is_rejected_whatever_the_network_says() {
    let (db, mut confidence) = accepting_every_rating();
    let views = db.views().len();
    let mut counters = StageCounters::new(StageId::Confidence);
    // One clear peak: accepted on its own.
    let mut response = vec![0.1f32; views];
    response[0] = 0.9;
    let bytes: Vec<u8> = response.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut rate = |score: Option<f32>, best_value: f32| {
        let mut input = posed();
        if let Some(score) = score {
            input.segmented.recognised.detection = Outcome::Done(Window {
                score,
                threshold: 0.4,
                ..Default::default()
            });
        }
        if let Outcome::Done(p) = &mut input.pose {
            p.best_value = best_value;
        }
        step(
            &mut confidence,
            &input,
            &bytes,
            &[],
            &mut [],
            0,
            &mut counters,
        )
        .rating
        .verdict()
        .expect("rated")
    };
    // Found 1.1x over recognition's threshold, best match 0.5: the object
    // may not be in view.
    let faint = rate(Some(0.44), 0.5);
    assert!(
        faint.faint() && !faint.accepted && !faint.ambiguous(),
        "{faint:?}"
    );
    assert!((faint.detection_margin - 1.1).abs() < 1e-5, "{faint:?}");
    assert_eq!(faint.match_value, 0.5);
    // Either clear: accepted.
    assert!(rate(Some(0.44), 0.8).accepted, "a good match");
    assert!(rate(Some(0.6), 0.5).accepted, "a clear detection");
    // A region recognition did not find (a given mask) has no margin.
    let given = rate(None, 0.5);
    assert!(
        given.accepted && given.detection_margin.is_infinite(),
        "{given:?}"
    );
    assert_eq!(counters.total_faults(), 0);
}

#[test]
fn the_stage_rejects_an_estimate_another_view_places_clearly_better() {
    let (db, mut confidence) = accepting_every_rating();
    let mut counters = StageCounters::new(StageId::Confidence);
    let mut response = vec![0.1f32; db.views().len()];
    response[0] = 0.9;
    let bytes: Vec<u8> = response.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut rate = |confidence: &mut Confidence, map_rival: f32| {
        let mut input = posed();
        if let Outcome::Done(p) = &mut input.pose {
            p.map_rival = map_rival;
        }
        step(confidence, &input, &bytes, &[], &mut [], 0, &mut counters)
            .rating
            .verdict()
            .expect("rated")
    };
    let misplaced = rate(&mut confidence, 0.3);
    assert!(
        misplaced.misplaced() && !misplaced.accepted && !misplaced.ambiguous(),
        "{misplaced:?}"
    );
    assert_eq!(misplaced.max_map_rival, acch_confidence::MAX_MAP_RIVAL);
    // At the bar, or nothing weighed: accepted; not measurable: rejected.
    assert!(rate(&mut confidence, acch_confidence::MAX_MAP_RIVAL).accepted);
    assert!(rate(&mut confidence, f32::NEG_INFINITY).accepted);
    assert!(!rate(&mut confidence, f32::NAN).accepted);
    // Another bar, to measure the rule apart: the same estimate passes
    // under a looser one, and a tighter one rejects what the default
    // passes.
    confidence.accept_map_rivals_to(0.5);
    let loose = rate(&mut confidence, 0.3);
    assert!(loose.accepted && !loose.misplaced(), "{loose:?}");
    assert_eq!(loose.max_map_rival, 0.5);
    confidence.accept_map_rivals_to(0.0);
    assert!(!rate(&mut confidence, acch_confidence::MAX_MAP_RIVAL).accepted);
    assert_eq!(counters.total_faults(), 0);
}

#[test]
fn an_occluded_objects_visible_part_is_placed_in_its_own_view_not_a_turned_one() {
    use acch_core::Rect;
    let db = database(false);
    let (w, h) = (640, 480);
    // Fruitbox from a grid view (θ 70°, φ 90°) with a bar over 30 % of its
    // width, its true visible mask.
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let mut scene = SceneConfig::new(object, Background::A);
    scene.occlusion = 0.3;
    let r =
        Renderer::new(scene, 3).render(&ViewPose::new(70.0, 90.0, DEFAULT_DISTANCE).unwrap(), 0);
    let index = db.palette.quantise(r.image.as_raw(), w, h);
    let mask = r.mask.as_raw();
    let mut estimator = acch_pose::PoseEstimator::new(db.clone()).unwrap();
    assert!(
        estimator.has_view_maps(),
        "training records the views' maps"
    );
    let whole = Rect::full(w, h);
    let estimate = estimator
        .estimate(
            &index,
            Some(mask),
            whole,
            Some(1.0),
            acch_pose::Refinement::Parabolic,
        )
        .expect("estimated");
    let view_at = |phi: f32| {
        db.views()
            .iter()
            .position(|v| v.theta_deg == 70.0 && v.phi_deg == phi)
            .expect("a grid view")
    };
    // Its own view places it best: no view 30-60° away does better.
    let own = acch_pose::Estimate {
        best_view: view_at(90.0),
        ..estimate
    };
    let rival = estimator.map_rival(&index, Some(mask), whole, &own, 20.0);
    assert!(rival < 0.0, "{rival}");
    // Claimed to be the view 30° on, the true view 30° back places it
    // clearly better: that estimate would be rejected.
    for turned in [60.0, 120.0] {
        let wrong = acch_pose::Estimate {
            best_view: view_at(turned),
            ..estimate
        };
        let rival = estimator.map_rival(&index, Some(mask), whole, &wrong, 20.0);
        assert!(
            rival > acch_confidence::MAX_MAP_RIVAL,
            "φ {turned}: {rival}"
        );
    }
}
