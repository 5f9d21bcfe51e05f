//! A run that chooses the database set per frame (`smoothing = "auto"`):
//! recognition measures each frame and sends a noisy one, or one whose
//! object is blurred, through the smoothed databases and a clean one
//! through the sharp ones, every later stage follows the choice the
//! header carries (a frame sent for its blurred object is not smoothed
//! again), what a stage was not built for is a counted fault, and a
//! database that cannot stand in for the sharp one is refused.

use acch_capture::{
    Background, DEFAULT_DISTANCE, Object, Renderer, SceneConfig, ViewPose, ViewSpec,
};
use acch_core::{Smoothing, ViewDatabase};
use acch_pipeline::stages::{BuildError, Stages};
use acch_pipeline::wire::{DatabaseSet, Fault, Intrinsics, SmoothedFor};
use acch_pipeline::{Chain, FrameHeader, Hop, StageSettings};
use acch_pose::train::TrainConfig;
use std::sync::Arc;

fn database(object: &str, smoothing: Smoothing) -> ViewDatabase {
    let object = Arc::new(Object::builtin(object).unwrap());
    let plain = Renderer::new(SceneConfig::new(object.clone(), Background::default()), 0);
    let grid = ViewSpec::Grid {
        thetas_deg: vec![50.0, 70.0, 90.0],
        phi_step_deg: 30.0,
    };
    let config = TrainConfig {
        smoothing,
        ..TrainConfig::default()
    };
    let acch_testkit::Trained { mut db, model } =
        acch_testkit::train_on_views_with(object.name(), &plain, &grid, &config);
    db.sections
        .insert(acch_recognition::SECTION.to_owned(), model.to_bytes());
    db
}

fn settings() -> StageSettings {
    StageSettings {
        width: 640,
        height: 480,
        distance_m: Some(DEFAULT_DISTANCE * Object::builtin("fruitbox").unwrap().radius_m()),
        // The fixtures have no confidence network: the sets are what is
        // checked here, not the rating.
        unrated: true,
        roll_search_deg: 0.0,
        light_search: 0,
        verify_shape: true,
    }
}

/// A frame of fruitbox on background A seen from (70°, 30°), with sensor
/// noise of `noise_sigma` grey levels, blurred by a Gaussian of
/// `blur_sigma` px.
fn frame(noise_sigma: f32, blur_sigma: f32) -> (FrameHeader, Vec<u8>) {
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let mut config = SceneConfig::new(object, Background::A);
    config.effects.noise_sigma = noise_sigma;
    config.effects.blur_sigma = blur_sigma;
    let r =
        Renderer::new(config, 1).render(&ViewPose::new(70.0, 30.0, DEFAULT_DISTANCE).unwrap(), 1);
    let header = FrameHeader::rgb(0, 640, 480, Intrinsics::from(&r.truth.intrinsics));
    (header, r.image.into_raw())
}

/// The match values of the last frame's response.
fn response(chain: &Chain) -> Vec<f32> {
    chain
        .last_response()
        .expect("the frame was estimated")
        .values()
        .collect()
}

/// The fruitbox's sharp and smoothed databases: the two sets of a run.
fn fruitbox_sets() -> (ViewDatabase, ViewDatabase) {
    (
        database("fruitbox", Smoothing::Off),
        database("fruitbox", Smoothing::Binomial),
    )
}

#[test]
fn a_noisy_or_blurred_frame_goes_through_the_smoothed_databases_and_a_clean_one_through_the_sharp()
{
    let (sharp, smoothed) = fruitbox_sets();
    let mut both = Chain::build_for_sets(&sharp, Some(&smoothed), &settings()).unwrap();
    let mut sharp_only = Chain::build(&sharp, &settings()).unwrap();
    let mut smoothed_only = Chain::build(&smoothed, &settings()).unwrap();
    // The smoothed databases quantising frames as they are: what a frame
    // already blurred is matched as.
    let mut unsmoothed = smoothed.clone();
    unsmoothed.palette = unsmoothed.palette.clone().with_smoothing(Smoothing::Off);
    let mut smoothed_frames_as_they_are = Chain::build(&unsmoothed, &settings()).unwrap();
    for (noise, blur, want, why) in [
        (0.0, 0.0, DatabaseSet::Sharp, None),
        (5.0, 0.0, DatabaseSet::Smoothed, Some(SmoothedFor::Camera)),
        (0.0, 2.0, DatabaseSet::Smoothed, Some(SmoothedFor::Blur)),
    ] {
        let (header, rgb) = frame(noise, blur);
        let out = both.process(&header, &rgb);
        let imaging = out.envelope().imaging;
        assert_eq!(imaging.set, want, "noise {noise}, blur {blur}: {imaging:?}");
        assert_eq!(imaging.smoothed_for(), why, "{imaging:?}");
        // The measure is the frame's: near the noise added (a clean render
        // measures below 1, a blurred one less), blockiness about 1
        // (nothing compressed).
        assert!(
            (imaging.noise_sigma - noise.max(0.5)).abs() < 1.0,
            "noise {noise}: {imaging:?}"
        );
        assert!((0.8..1.2).contains(&imaging.blockiness), "{imaging:?}");
        // The object's sharpness is measured on a frame the camera's
        // measure left to the sharp set: above the bar when sharp (a
        // one-pixel edge reads 0.5), below it when blurred (2 px reads
        // about 0.2); not on a noisy frame.
        let sharpness = imaging.object_sharpness;
        match (noise, blur) {
            (0.0, 0.0) => assert!(
                (acch_core::BLURRED..0.6).contains(&sharpness),
                "{imaging:?}"
            ),
            (0.0, _) => assert!(
                (0.1..acch_core::BLURRED).contains(&sharpness),
                "{imaging:?}"
            ),
            _ => assert_eq!(sharpness, 0.0, "{imaging:?}"),
        }
        // Every stage ran the chosen set's database: the same estimate and
        // response as a chain of that database alone, and not the other's;
        // a frame sent for its blurred object, quantised as it is.
        let (same, other) = match why {
            None => (&mut sharp_only, &mut smoothed_only),
            Some(SmoothedFor::Blur) => {
                smoothed_only.process(&header, &rgb);
                assert_ne!(response(&both), response(&smoothed_only), "smoothed again");
                (&mut smoothed_frames_as_they_are, &mut sharp_only)
            }
            Some(_) => (&mut smoothed_only, &mut sharp_only),
        };
        let alone = same.process(&header, &rgb);
        assert_eq!(out.pose(), alone.pose(), "noise {noise}, blur {blur}");
        assert_eq!(out.region(), alone.region(), "noise {noise}, blur {blur}");
        assert_eq!(
            response(&both),
            response(same),
            "noise {noise}, blur {blur}"
        );
        other.process(&header, &rgb);
        assert_ne!(
            response(&both),
            response(other),
            "noise {noise}, blur {blur}"
        );
        let pose = both.stages().pose.last_used();
        let chosen = match want {
            DatabaseSet::Sharp => both.stages().pose.sharp(),
            DatabaseSet::Smoothed => both.stages().pose.smoothed().unwrap(),
        };
        assert!(std::ptr::eq(pose, chosen));
    }
    // A run that does not choose measures nothing and says sharp.
    let (header, rgb) = frame(5.0, 0.0);
    let out = sharp_only.process(&header, &rgb);
    assert_eq!(out.envelope().imaging, Default::default());
}

#[test]
fn a_frame_the_sharp_set_finds_nothing_in_goes_through_the_smoothed_set_which_finds_nothing_either()
{
    let (sharp, smoothed) = fruitbox_sets();
    let mut both = Chain::build_for_sets(&sharp, Some(&smoothed), &settings()).unwrap();
    // Another object where the fruitbox would be: nothing to find.
    let can = Arc::new(Object::builtin("can").unwrap());
    let r = Renderer::new(SceneConfig::new(can, Background::A), 1)
        .render(&ViewPose::new(70.0, 30.0, DEFAULT_DISTANCE).unwrap(), 1);
    let header = FrameHeader::rgb(0, 640, 480, Intrinsics::from(&r.truth.intrinsics));
    let out = both.process(&header, r.image.as_raw());
    let imaging = out.envelope().imaging;
    // Tried with both sets, found by neither, nothing measured of an
    // object that is not there.
    assert_eq!(imaging.set, DatabaseSet::Smoothed, "{imaging:?}");
    assert_eq!(imaging.object_sharpness, 0.0, "{imaging:?}");
    assert_eq!(imaging.smoothed_for(), Some(SmoothedFor::NotFound));
    assert!(out.detection().done().is_none(), "{:?}", out.detection());
    assert!(std::ptr::eq(
        both.stages().recognition.last_used(),
        both.stages().recognition.smoothed().unwrap()
    ));
}

#[test]
fn a_frame_for_a_set_a_stage_does_not_hold_is_a_counted_fault() {
    let sharp = database("fruitbox", Smoothing::Off);
    let mut chain = Chain::build(&sharp, &settings()).unwrap();
    let (header, rgb) = frame(0.0, 0.0);
    let mut recognised = chain.recognise(&header, &rgb);
    assert!(recognised.detection.done().is_some(), "fruitbox is in view");
    recognised.envelope_mut().imaging.set = DatabaseSet::Smoothed;
    let out = chain.finish(&recognised, &rgb);
    assert!(out.region().done().is_none());
    assert_eq!(chain.counters()[1].faults_of(Fault::Header), 1);
}

#[test]
fn a_smoothed_database_that_cannot_stand_in_for_the_sharp_one_is_refused() {
    let sharp = database("fruitbox", Smoothing::Off);
    let refused = |smoothed: &ViewDatabase, what: &str| match Stages::for_sets(
        &sharp,
        Some(smoothed),
        &settings(),
    ) {
        Err(e @ BuildError::SmoothedSet { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains(what), "{msg}");
        }
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("accepted a smoothed database that {what}"),
    };
    refused(&sharp, "does not smooth frames");
    refused(&database("can", Smoothing::Binomial), "another object");
    let mut farther = database("fruitbox", Smoothing::Binomial);
    farther.train_distance_m *= 2.0;
    refused(&farther, "another distance");
    // The same object, views and distance, smoothing: accepted.
    let smoothed = database("fruitbox", Smoothing::Binomial);
    assert!(Stages::for_sets(&sharp, Some(&smoothed), &settings()).is_ok());
}
