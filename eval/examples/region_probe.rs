//! Where do objects' estimates go wrong in the robust protocol's scenes:
//! the region the chain grows, or the match? For each scene of `--seed`
//! (the same poses `acch eval --protocol robust` draws), the chain's
//! estimate, the pose stage's estimate from the grown region and from the
//! true visible mask, and the visible pixels the region missed and the
//! pixels it holds beyond the object; a line per scene where one of them
//! is wrong, and the counts. OCCLUSION (default 0) hides that share of each
//! object behind a bar, as the `occlusion` family does. With an output
//! directory, those scenes' images and a picture of the region against the
//! truth (missed in magenta, extra in cyan) are written there.
//!
//! `cargo run --release -p acch-eval --example region_probe -- OBJECTS SEED N [OCCLUSION [DIR]]`
//! (OBJECTS comma-separated built-in names; for example
//! `generated-3027 3 2 0 /tmp/probe`).

use acch_capture::{Object, Renderer};
use acch_eval::protocol::{self, fails};
use acch_eval::robust::{BACKGROUNDS, SceneDraw};
use acch_pipeline::Stage;
use acch_pipeline::stages::{Pose, SINGLE_IMAGE_LIGHT_SEARCH, Segmented};
use acch_pipeline::wire::Outcome;
use std::sync::Arc;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [names, seed, n, rest @ ..] = &args[..] else {
        return Err("usage: region_probe OBJECTS SEED N [OCCLUSION [DIR]]".into());
    };
    let (seed, n): (u64, usize) = (seed.parse()?, n.parse()?);
    let occlusion: f32 = rest.first().map_or(Ok(0.0), |s| s.parse())?;
    let out_dir = rest.get(1).map(std::path::PathBuf::from);
    if let Some(d) = &out_dir {
        std::fs::create_dir_all(d)?;
    }
    println!(
        "scene: truth θ φ | chain θ φ | grown region θ φ | true mask θ φ | visible, missed, extra px"
    );
    // Scenes; wrong or none from the chain, the grown region, the true mask.
    let (mut scenes, mut wrong) = (0, [0; 3]);
    for name in names.split(',') {
        let object = Arc::new(Object::builtin(name)?);
        let (db, _) = acch_eval::train::cached_database(&object, None)?;
        let distance_m = db.train_distance_m as f64;
        for (b, bg) in BACKGROUNDS.iter().enumerate() {
            let mut draw = SceneDraw::new(&object, seed, b, n)?;
            draw.scene.occlusion = occlusion;
            let renderer = Renderer::new(draw.scene, draw.render_seed);
            let mut chain =
                protocol::chain_for_sets(&db, None, distance_m, SINGLE_IMAGE_LIGHT_SEARCH)?;
            let mut pose = Pose::new(&db, &protocol::settings_at(&db, distance_m, 0))?;
            for (i, v) in draw.views.iter().enumerate() {
                let r = renderer.render(v, acch_capture::frame_seed(draw.render_seed, i));
                let (w, h) = r.image.dimensions();
                let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
                let frame = protocol::frame_of(&r, i as u64, false, object.radius_m());
                let out = chain.process(&frame, r.image.as_raw());
                let chain_estimate = out.pose().done().map(|e| (e.theta_deg, e.phi_deg));
                let visible = r.mask.as_raw();
                let mut grown = vec![0u8; (w * h) as usize];
                if let Some(region) = chain.last_region() {
                    region.frame_mask(w, h, &mut grown);
                }
                let (mut shown, mut missed, mut extra) = (0, 0, 0);
                for (&g, &t) in grown.iter().zip(visible) {
                    shown += (t != 0) as usize;
                    missed += (t != 0 && g == 0) as usize;
                    extra += (g != 0 && t == 0) as usize;
                }
                // The pose stage alone, from each mask, on the training palette.
                let index = db.palette.quantise(r.image.as_raw(), w, h);
                let mut from_mask = Vec::new();
                for mask in [&grown[..], visible] {
                    let mut payload = vec![0u8; 2 * (w * h) as usize];
                    let header =
                        Segmented::from_mask(frame.envelope, mask, &index.data, w, &mut payload)?;
                    let mut response = vec![0u8; pose.max_payload()];
                    from_mask.push(header.and_then(|hd| {
                        match pose.process(&hd, &payload, &mut response) {
                            Ok(Outcome::Done(e)) => Some((e.theta_deg, e.phi_deg)),
                            _ => None,
                        }
                    }));
                }
                let estimates = [chain_estimate, from_mask[0], from_mask[1]];
                let bad = estimates.map(|e| e.is_none_or(|e| fails(e, truth)));
                scenes += 1;
                for (w, b) in wrong.iter_mut().zip(bad) {
                    *w += b as usize;
                }
                if !bad.contains(&true) {
                    continue;
                }
                let show = |e: Option<(f32, f32)>| match e {
                    Some(e) => format!(
                        "{:5.1} {:5.1}{}",
                        e.0,
                        e.1,
                        if fails(e, truth) { " wrong" } else { "" }
                    ),
                    None => "none".into(),
                };
                println!(
                    "{name} {bg}{i}: {:5.1} {:5.1} | {} | {} | {} | {shown} {missed} {extra}",
                    truth.0,
                    truth.1,
                    show(chain_estimate),
                    show(from_mask[0]),
                    show(from_mask[1]),
                );
                if let Some(d) = &out_dir {
                    r.image.save(d.join(format!("{name}-{bg}{i}.png")))?;
                    let mut picture = r.image.clone();
                    for (p, (&g, &t)) in picture.pixels_mut().zip(grown.iter().zip(visible)) {
                        match (g != 0, t != 0) {
                            (false, true) => p.0 = [255, 0, 255],
                            (true, false) => p.0 = [0, 255, 255],
                            _ => {}
                        }
                    }
                    picture.save(d.join(format!("{name}-{bg}{i}-region.png")))?;
                }
            }
        }
    }
    println!(
        "{scenes} scenes, wrong or none: chain {}, grown region {}, true mask {}",
        wrong[0], wrong[1], wrong[2]
    );
    Ok(())
}
