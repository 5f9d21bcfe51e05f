//! What does choosing a single image's light by the pose cost, and what
//! does it buy? Generated objects rendered clean and over exposed (1.25x,
//! 1.5x) on background A, each image through the chain with the single-
//! image light search twice: keeping the light recognition scores best,
//! and choosing among it and its neighbours the one whose indices a
//! training view explains best (the default). Prints the median and 90th
//! percentile time per image and the estimates wrong. Trains the objects'
//! databases on first use.
//!
//! `cargo run --release -p acch-eval --example light_choice_timing -- FIRST COUNT N`
//! (default 3000 5 8)

use acch_capture::{Background, Object, Renderer, SceneConfig, TextureSet, ViewSpec};
use acch_eval::protocol::{self, fails};
use acch_pipeline::stages::SINGLE_IMAGE_LIGHT_SEARCH;
use std::sync::Arc;
use std::time::Instant;

fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (first, count, n) = protocol::diagnosis_args(5, 8)?;
    for exposure in [1.0f32, 1.25, 1.5] {
        // (time ms, wrong) per image: recognition's light, the pose's.
        let mut by = [(Vec::new(), 0usize), (Vec::new(), 0usize)];
        for k in first..first + count {
            let object = Arc::new(Object::builtin(&format!("generated-{k}"))?);
            let (db, _) = acch_eval::train::cached_database(&object, None)?;
            let mut config =
                SceneConfig::new(object.clone(), Background::A).with_textures(TextureSet::HeldOut);
            config.effects.exposure = exposure;
            let renderer = Renderer::new(config, k);
            let views = ViewSpec::Random { n }.views(acch_capture::DEFAULT_DISTANCE, k);
            let distance_m = db.train_distance_m as f64;
            let mut chains = [
                protocol::chain_at(&db, distance_m, SINGLE_IMAGE_LIGHT_SEARCH)?,
                protocol::chain_at(&db, distance_m, SINGLE_IMAGE_LIGHT_SEARCH)?,
            ];
            chains[0]
                .stages_mut()
                .recognition
                .sharp_mut()
                .choose_light_by_recognition();
            for (i, v) in views.iter().enumerate() {
                let scene = renderer.render(v, acch_capture::frame_seed(k, i));
                let frame = protocol::frame_of(&scene, i as u64, false, object.radius_m());
                for (chain, (times, wrong)) in chains.iter_mut().zip(&mut by) {
                    // The relit tables are built on first use: once before
                    // timing.
                    chain.process(&frame, scene.image.as_raw());
                    let t = Instant::now();
                    let out = chain.process(&frame, scene.image.as_raw());
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                    let truth = (scene.truth.theta_deg as f32, scene.truth.phi_deg as f32);
                    *wrong += out
                        .pose()
                        .done()
                        .is_none_or(|e| fails((e.theta_deg, e.phi_deg), truth))
                        as usize;
                }
            }
        }
        let images = (count as usize) * n;
        for (name, (times, wrong)) in ["recognition's light", "the pose's light"].iter().zip(by) {
            println!(
                "exposure {exposure}: {name}: {:.2} ms median, {:.2} ms p90 per image, \
                 {wrong} of {images} failed",
                quantile(times.clone(), 0.5),
                quantile(times, 0.9),
            );
        }
    }
    Ok(())
}
