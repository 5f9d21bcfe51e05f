//! Why does a blur of 2 px break the estimate of generated objects, and
//! would training views blurred as well hold it? Per object and blur, the
//! same scenes through the chain of two databases: the default one (views
//! rendered sharp) and one whose every view's histogram is the mean over
//! the view rendered at each of `--train-blur` sigmas (its palette and
//! recognition model trained on all of them). For each: not found, the
//! chain's failures, and the failures from the true mask, so recognition,
//! segmentation and matching are told apart. Winner takes all with
//! refinement; no confidence network (both chains unrated).
//!
//! `cargo run --release -p acch-eval --example blur_diagnosis -- [FIRST] [OBJECTS] [N] [SIGMAS]`
//! (generated objects FIRST.., default 3000, 10 objects, 6 views a
//! background, training sigmas 0,1,2).

use acch_capture::{Object, Renderer, SceneConfig, TextureSet};
use acch_core::ViewDatabase;
use acch_eval::protocol::{self, fails};
use acch_eval::train::{RenderedTraining, train_views, unrated_chain};
use acch_pipeline::Stage;
use acch_pipeline::stages::{Pose, Segmented};
use acch_pipeline::wire::Outcome;
use acch_pose::train::TrainConfig;
use std::sync::Arc;

const BLURS: [f32; 4] = [0.0, 1.0, 1.5, 2.0];

/// A database whose views are the mean over the training views rendered
/// at each of `sigmas`.
fn blurred_database(
    object: &Arc<Object>,
    sigmas: &[f32],
) -> Result<ViewDatabase, Box<dyn std::error::Error>> {
    let training = RenderedTraining::default();
    let views = training.views.views(training.distance, training.seed);
    let mut renders = Vec::new();
    for &sigma in sigmas {
        let mut config = SceneConfig::new(object.clone(), training.background)
            .with_textures(TextureSet::Training);
        config.effects.blur_sigma = sigma;
        let renderer = Renderer::new(config, training.seed);
        renders.extend(protocol::render_views(
            &renderer,
            &views,
            training.seed,
            "train views",
        ));
    }
    let labelled: Vec<_> = renders
        .iter()
        .map(|r| protocol::labelled(r, training.distance))
        .collect();
    let distance_m = (training.distance * object.radius_m()) as f32;
    Ok(train_views(
        object.name(),
        distance_m,
        &labelled,
        &TrainConfig::default(),
    )?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let first: u64 = args.first().map_or(Ok(3000), |a| a.parse())?;
    let count: u64 = args.get(1).map_or(Ok(10), |a| a.parse())?;
    let n: usize = args.get(2).map_or(Ok(6), |a| a.parse())?;
    let sigmas: Vec<f32> = args
        .get(3)
        .map_or("0,1,2", String::as_str)
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let emulate = args.get(4).is_some_and(|a| a == "smooth");
    println!(
        "training blur sigmas {sigmas:?}, queries of the blurred database smoothed alike: {emulate}"
    );
    println!(
        "blur | database | lost % | chain fail % | true-mask fail %   (pooled over the objects)"
    );
    // [blur][database] -> (scenes, lost, chain failures, true-mask failures)
    let mut tally = [[(0usize, 0usize, 0usize, 0usize); 2]; BLURS.len()];
    let camera = acch_capture::Intrinsics::default();
    for k in first..first + count {
        let object = Arc::new(Object::builtin(&format!("generated-{k}"))?);
        let (sharp, _) = acch_eval::train::cached_database(&object, None)?;
        let blurred = blurred_database(&object, &sigmas)?;
        for (d, db) in [&sharp, &blurred].into_iter().enumerate() {
            let distance_m = db.train_distance_m as f64;
            let mut pose = Pose::new(db, &protocol::settings_at(db, distance_m, 0))?;
            for (l, &blur) in BLURS.iter().enumerate() {
                for b in 0..3 {
                    let (mut config, seed, views) =
                        protocol::diagnosis_scenes(&object, k, b, 0xb1, n)?;
                    // The blurred database's queries also take its first sigma
                    // (a frame smoothed before quantisation, emulated).
                    let pre = if d == 1 && emulate { sigmas[0] } else { 0.0 };
                    config.effects.blur_sigma = (blur * blur + pre * pre).sqrt();
                    let renderer = Renderer::new(config, seed);
                    let mut chain =
                        unrated_chain(db, camera.width, camera.height, distance_m, 0.0, 0)?;
                    for (i, v) in views.iter().enumerate() {
                        let r = renderer.render(v, acch_capture::frame_seed(seed, i));
                        let (w, h) = r.image.dimensions();
                        let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
                        let t = &mut tally[l][d];
                        t.0 += 1;
                        let out = chain.process(
                            &protocol::frame_of(&r, i as u64, false, object.radius_m()),
                            r.image.as_raw(),
                        );
                        match out.pose().done() {
                            Some(e) => t.2 += fails((e.theta_deg, e.phi_deg), truth) as usize,
                            None => {
                                t.1 += 1;
                                t.2 += 1;
                            }
                        }
                        // The pose from the true mask.
                        let index = db.palette.quantise(r.image.as_raw(), w, h);
                        let mut payload = vec![0u8; 2 * (w * h) as usize];
                        let frame = protocol::frame_of(&r, i as u64, false, object.radius_m());
                        let given = Segmented::from_mask(
                            frame.envelope,
                            r.mask.as_raw(),
                            &index.data,
                            w,
                            &mut payload,
                        )?;
                        let Some(header) = given else {
                            t.3 += 1;
                            continue;
                        };
                        let mut response = vec![0u8; pose.max_payload()];
                        t.3 += match pose.process(&header, &payload, &mut response) {
                            Ok(Outcome::Done(e)) => fails((e.theta_deg, e.phi_deg), truth) as usize,
                            _ => 1,
                        };
                    }
                }
            }
        }
        eprintln!("generated-{k} done");
    }
    for (l, &blur) in BLURS.iter().enumerate() {
        for (d, name) in ["sharp views", "blurred views"].iter().enumerate() {
            let (s, lost, fail, true_fail) = tally[l][d];
            let pct = |a: usize| 100.0 * a as f64 / s.max(1) as f64;
            println!(
                "{blur:4.1} | {name:13} | {:5.1} | {:5.1} | {:5.1}",
                pct(lost),
                pct(fail),
                pct(true_fail)
            );
        }
    }
    Ok(())
}
