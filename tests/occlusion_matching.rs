//! A bar hiding 30 % of an object's width: matched by the share of its
//! visible pairs the whole view holds, the right view wins; matched by
//! the normalised histograms (the paper's match value), a view whose
//! whole resembles the visible part takes it often enough to tell the two
//! apart on the same scenes, so the check can fail. True visible masks, so
//! the matching alone is measured; generated objects of the development
//! seed (docs/accuracy.md, "An occluded object"). The chain's region holds
//! both parts of an object the bar parts.

use acch_capture::{Object, Renderer};
use acch_eval::protocol::{self, fails};
use acch_pose::train::mask_bbox;
use acch_pose::{Matching, PoseEstimator, Refinement};
use std::sync::Arc;

#[test]
fn visible_part_matching_holds_an_occluded_view_where_the_normalised_match_fails() {
    let (mut scenes, mut visible, mut normalised) = (0usize, 0usize, 0usize);
    for k in 3000..3004 {
        let object = Arc::new(Object::builtin(&format!("generated-{k}")).unwrap());
        let (db, _) = acch_train::cache::cached_database(&object, None).unwrap();
        let by = |m| PoseEstimator::new(db.clone()).unwrap().with_matching(m);
        let (mut vis, mut norm) = (by(Matching::Visible), by(Matching::Normalised));
        assert_eq!(
            vis.matching(),
            Matching::Visible,
            "the database has its views' pairs"
        );
        for b in 0..3 {
            let (mut config, seed, poses) =
                protocol::diagnosis_scenes(&object, k, b, 0x6f63, 6).unwrap();
            config.occlusion = 0.3;
            let renderer = Renderer::new(config, seed);
            for (i, v) in poses.iter().enumerate() {
                let r = renderer.render(v, acch_capture::frame_seed(seed, i));
                let (w, h) = r.image.dimensions();
                let index = db.palette.quantise(r.image.as_raw(), w, h);
                let mask = r.mask.as_raw();
                let roi = mask_bbox(mask, w, h).expect("part of the object stays visible");
                let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
                let failed = |e: &mut PoseEstimator| {
                    e.estimate(&index, Some(mask), roi, Some(1.0), Refinement::Parabolic)
                        .is_none_or(|e| fails((e.theta_deg, e.phi_deg), truth))
                };
                visible += failed(&mut vis) as usize;
                normalised += failed(&mut norm) as usize;
                scenes += 1;
            }
        }
    }
    let share = |f: usize| f as f64 / scenes as f64;
    eprintln!(
        "{scenes} occluded scenes: visible-part matching fails {:.3}, normalised {:.3}",
        share(visible),
        share(normalised)
    );
    assert!(
        share(visible) <= 0.03,
        "visible-part matching failed {visible} of {scenes}"
    );
    assert!(
        share(normalised) >= share(visible) + 0.05,
        "normalised matching failed {normalised}, visible-part {visible}, of {scenes}"
    );
}

/// A bar across an object leaves it in two parts: the chain's region holds
/// both (segmentation keeps every large part), so it misses little of what
/// stays visible. Measured on these 72 scenes: 1.7 % missed, and 4.8 % when
/// segmentation keeps the largest part alone, so the check can fail
/// (docs/accuracy.md, "An object parted by an occluder").
#[test]
fn the_region_of_an_object_a_bar_parts_holds_both_parts() {
    let (mut visible, mut missed) = (0usize, 0usize);
    for k in 3000..3004 {
        let object = Arc::new(Object::builtin(&format!("generated-{k}")).unwrap());
        let (db, _) = acch_train::cache::cached_database(&object, None).unwrap();
        let mut chain = protocol::chain(&db).unwrap();
        for b in 0..3 {
            let (mut config, seed, poses) =
                protocol::diagnosis_scenes(&object, k, b, 0x6f63, 6).unwrap();
            config.occlusion = 0.2;
            let renderer = Renderer::new(config, seed);
            for (i, v) in poses.iter().enumerate() {
                let r = renderer.render(v, acch_capture::frame_seed(seed, i));
                let (w, h) = r.image.dimensions();
                chain.process(
                    &protocol::frame_of(&r, i as u64, false, object.radius_m()),
                    r.image.as_raw(),
                );
                let region = chain.last_region().expect("a region is grown");
                let mut grown = Vec::new();
                region.frame_mask(w, h, &mut grown);
                for (&t, &g) in r.mask.as_raw().iter().zip(&grown) {
                    visible += (t != 0) as usize;
                    missed += (t != 0 && g == 0) as usize;
                }
            }
        }
    }
    let share = missed as f64 / visible as f64;
    eprintln!("the region misses {share:.3} of the visible object at 20 % occlusion");
    assert!(share <= 0.03, "missed {missed} of {visible} visible pixels");
}
