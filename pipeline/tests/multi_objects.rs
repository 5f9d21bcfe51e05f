//! Several objects in one frame: every lane of a `MultiChain` finds its
//! own object where it stands, two lanes never report the same place, and
//! a lane whose detection is not withdrawn computes exactly what its chain
//! alone computes on the frame, whether the lanes share one quantisation
//! pass or not.

use acch_capture::{
    Background, MULTI_DISTANCE, MultiRenderer, MultiScene, Object, Renderer, SceneConfig, ViewSpec,
};
use acch_core::{Smoothing, ViewDatabase};
use acch_pipeline::multi::{NMS_OVERLAP, overlap};
use acch_pipeline::wire::Intrinsics;
use acch_pipeline::{Chain, FrameHeader, MultiChain, StageSettings};
use std::sync::Arc;

fn database(name: &str) -> (Arc<Object>, ViewDatabase) {
    let object = Arc::new(Object::builtin(name).unwrap());
    let plain = Renderer::new(SceneConfig::new(object.clone(), Background::default()), 0);
    let grid = ViewSpec::Grid {
        thetas_deg: vec![50.0, 70.0, 90.0],
        phi_step_deg: 20.0,
    };
    let acch_testkit::Trained { mut db, model } = acch_testkit::train_on_views(name, &plain, &grid);
    db.sections
        .insert(acch_recognition::SECTION.to_owned(), model.to_bytes());
    (object, db)
}

fn settings(object: &Object) -> StageSettings {
    StageSettings {
        width: 640,
        height: 480,
        distance_m: Some(MULTI_DISTANCE * object.radius_m()),
        unrated: true,
        roll_search_deg: 0.0,
        light_search: 0,
        verify_shape: true,
    }
}

/// The known object (scene index) under the centre of a window.
fn under_centre(labels: &image::GrayImage, w: &acch_pipeline::stages::Window) -> Option<usize> {
    let r = w.window;
    let label = labels.get_pixel(r.x + r.width / 2, r.y + r.height / 2).0[0];
    (label > 0).then(|| label as usize - 1)
}

#[test]
fn every_lane_finds_its_own_object_and_no_two_report_one_place() {
    let known = [database("fruitbox"), database("can")];
    let lanes: Vec<_> = known.iter().map(|(o, db)| (db, settings(o))).collect();
    let mut multi = MultiChain::build(&lanes, 2).unwrap();
    let mut scene = MultiScene::new(
        known.iter().map(|(o, _)| o.clone()).collect(),
        Background::A,
    );
    scene.distractors = 1;
    let (mut own, mut frames) = (0, 0);
    for seed in 0..8u64 {
        let renderer = MultiRenderer::new(scene.clone(), seed).unwrap();
        let f = renderer
            .render(60.0 + 3.0 * seed as f64, 45.0 * seed as f64, seed)
            .unwrap();
        let header = FrameHeader::rgb(seed, 640, 480, Intrinsics::from(&scene.intrinsics));
        let outs = multi.process(&header, f.image.as_raw()).to_vec();
        let windows: Vec<_> = outs.iter().filter_map(|o| o.detection().done()).collect();
        for (i, a) in windows.iter().enumerate() {
            for b in &windows[i + 1..] {
                assert!(overlap(&a.window, &b.window) <= NMS_OVERLAP, "seed {seed}");
            }
        }
        for (k, out) in outs.iter().enumerate() {
            let visible = f.objects[k].hidden() < 0.3 && !f.objects[k].at_border;
            if !visible {
                continue;
            }
            frames += 1;
            if let Some(w) = out.detection().done() {
                own += (under_centre(&f.labels, &w) == Some(k)) as usize;
            }
        }
    }
    // Both objects in view, mostly visible: each lane on its own object.
    assert!(frames >= 10, "only {frames} clear appearances");
    assert!(
        own * 10 >= frames * 8,
        "{own} of {frames} found on their own object"
    );
}

#[test]
fn a_lane_computes_what_its_chain_alone_computes() {
    let known = [database("fruitbox"), database("tricolor")];
    let lanes: Vec<_> = known.iter().map(|(o, db)| (db, settings(o))).collect();
    let mut multi = MultiChain::build(&lanes, 1).unwrap();
    let mut alone = Chain::build(lanes[0].0, &lanes[0].1).unwrap();
    // Only the fruitbox in view: the tricolor lane finds nothing there or
    // is withdrawn; the fruitbox lane must match its chain bit for bit.
    let scene = MultiScene::new(vec![known[0].0.clone()], Background::B);
    let mut compared = 0;
    for seed in 0..4u64 {
        let f = MultiRenderer::new(scene.clone(), seed)
            .unwrap()
            .render(70.0, 30.0 + 80.0 * seed as f64, seed)
            .unwrap();
        let header = FrameHeader::rgb(seed, 640, 480, Intrinsics::from(&scene.intrinsics));
        let withdrawn = multi.lanes()[0].suppressed;
        let outs = multi.process(&header, f.image.as_raw()).to_vec();
        let single = alone.process(&header, f.image.as_raw());
        // Alone in view, the fruitbox is found and never withdrawn for
        // the tricolor: every frame is compared, on a real detection.
        assert_eq!(multi.lanes()[0].suppressed, withdrawn, "seed {seed}");
        assert!(
            single.detection().done().is_some(),
            "seed {seed}: not found"
        );
        assert_eq!(outs[0].detection(), single.detection(), "seed {seed}");
        assert_eq!(outs[0].region(), single.region(), "seed {seed}");
        assert_eq!(outs[0].pose(), single.pose(), "seed {seed}");
        compared += 1;
    }
    assert_eq!(compared, 4);
}

#[test]
fn sharing_one_quantisation_pass_changes_nothing_a_lane_computes() {
    let known = [database("fruitbox"), database("can"), database("tricolor")];
    let mut scene = MultiScene::new(
        known[..2].iter().map(|(o, _)| o.clone()).collect(),
        Background::C,
    );
    scene.distractors = 1;
    for smoothing in [Smoothing::Off, Smoothing::Binomial] {
        let dbs: Vec<ViewDatabase> = known
            .iter()
            .map(|(_, db)| {
                let mut db = db.clone();
                db.palette = db.palette.clone().with_smoothing(smoothing);
                db
            })
            .collect();
        // The light searched too: a relit lane quantises on its own.
        let lanes: Vec<_> = dbs
            .iter()
            .zip(&known)
            .map(|(db, (o, _))| {
                let light_search = 4;
                (
                    db,
                    StageSettings {
                        light_search,
                        verify_shape: true,
                        ..settings(o)
                    },
                )
            })
            .collect();
        let mut shared = MultiChain::build(&lanes, 2).unwrap();
        assert!(shared.joint_colours().is_some_and(|c| c > 16));
        let mut apart = MultiChain::build(&lanes, 2).unwrap().quantise_apart();
        assert_eq!(apart.joint_colours(), None);
        let mut found = 0;
        for seed in 0..6u64 {
            let f = MultiRenderer::new(scene.clone(), seed)
                .unwrap()
                .render(65.0, 60.0 * seed as f64, seed)
                .unwrap();
            // Every other frame dimmed, so lanes search other light.
            let gain = if seed % 2 == 0 { 1.0 } else { 0.6 };
            let rgb: Vec<u8> = f
                .image
                .as_raw()
                .iter()
                .map(|&c| (c as f32 * gain) as u8)
                .collect();
            let header = FrameHeader::rgb(seed, 640, 480, Intrinsics::from(&scene.intrinsics));
            let a = shared.process(&header, &rgb).to_vec();
            let b = apart.process(&header, &rgb).to_vec();
            for (k, (a, b)) in a.iter().zip(&b).enumerate() {
                let at = format!("{smoothing:?}, seed {seed}, lane {k}");
                assert_eq!(a.detection(), b.detection(), "{at}");
                assert_eq!(a.region(), b.region(), "{at}");
                assert_eq!(a.pose(), b.pose(), "{at}");
                found += a.detection().done().is_some() as usize;
            }
        }
        assert!(
            found >= 6,
            "{smoothing:?}: only {found} detections compared"
        );
    }
}
