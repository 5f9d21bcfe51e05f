//! Would another normalisation of the match hold an occluded object? The
//! winner-takes-all view under three match values, on the same occluded
//! scenes, from the region the deployed chain grew and from the true
//! visible mask:
//! - `query`: today's, the intersection of the normalised histograms
//!   (divided by the query's pairs, paper eq. 2);
//! - `model`: Swain and Ballard's, raw pair counts divided by the view's
//!   own pairs (a visible part of the right view scores its share);
//! - `larger`: raw pair counts divided by the larger of the two.
//!
//! The views' pair counts come from rendering the training views again.
//!
//! `cargo run --release -p acch-eval --example occlusion_matching -- [FIRST] [OBJECTS] [N]`

use acch_capture::{Object, Renderer, TextureSet};
use acch_core::HistogramExtractor;
use acch_eval::protocol::{self, fails};
use acch_eval::train::RenderedTraining;
use acch_pose::train::mask_bbox;
use std::sync::Arc;

const SCORERS: [&str; 6] = ["normalised", "visible", "model", "larger", "product", "sum"];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (first, count, n) = protocol::diagnosis_args(10, 6)?;
    let shares = [0.0f32, 0.1, 0.2, 0.3];
    // failures[share][mask][scorer], scenes[share]
    let mut failures = [[[0usize; 6]; 2]; 4];
    let mut scenes = [0usize; 4];
    let mut stage_fail = [0usize; 4];
    let mut theta_err = [[[0f64; 6]; 2]; 4];
    for k in first..first + count {
        let object = Arc::new(Object::builtin(&format!("generated-{k}"))?);
        let (db, _) = acch_eval::train::cached_database(&object, None)?;
        // Every view's pair count at the training scale.
        let training = RenderedTraining::default();
        let views = training.views.views(training.distance, training.seed);
        let renderer = protocol::renderer(
            object.clone(),
            training.background,
            TextureSet::Training,
            training.seed,
        );
        let renders = protocol::render_views(&renderer, &views, training.seed, "train views");
        let mut extractor = HistogramExtractor::new(db.params)?;
        let mut hist = vec![0.0; db.params.len()];
        let mut view_pairs = vec![0.0f32; db.views().len()];
        for r in &renders {
            let l = protocol::labelled(r, training.distance);
            let (w, h) = r.image.dimensions();
            let roi = mask_bbox(r.mask.as_raw(), w, h).ok_or("empty training view")?;
            let index = db.palette.quantise(r.image.as_raw(), w, h);
            let pairs = extractor.extract(&index, Some(r.mask.as_raw()), roi, l.scale, &mut hist);
            let at = db
                .views()
                .iter()
                .position(|v| {
                    (v.theta_deg - l.theta_deg).abs() < 0.01
                        && acch_pose::phi_error(v.phi_deg, l.phi_deg) < 0.01
                })
                .ok_or("training view not in the database")?;
            view_pairs[at] = pairs as f32;
        }
        let mut estimator = acch_pose::PoseEstimator::new(db.clone())?;
        let scale = 1.0;
        let mut stage = acch_pipeline::stages::Pose::new(
            &db,
            &protocol::settings_at(&db, db.train_distance_m as f64, 0),
        )?
        .with_refinement(acch_pose::Refinement::WinnerTakesAll);
        for (s, &share) in shares.iter().enumerate() {
            for b in 0..3 {
                let (mut config, seed, poses) =
                    protocol::diagnosis_scenes(&object, k, b, 0x6f63, n)?;
                config.occlusion = share;
                let occluded = Renderer::new(config, seed);
                let mut chain = protocol::chain(&db)?;
                for (i, v) in poses.iter().enumerate() {
                    let r = occluded.render(v, acch_capture::frame_seed(seed, i));
                    let (w, h) = r.image.dimensions();
                    let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
                    let index = db.palette.quantise(r.image.as_raw(), w, h);
                    chain.process(
                        &protocol::frame_of(&r, i as u64, false, object.radius_m()),
                        r.image.as_raw(),
                    );
                    let mut grown = vec![0u8; (w * h) as usize];
                    if let Some(region) = chain.last_region() {
                        region.frame_mask(w, h, &mut grown);
                    }
                    scenes[s] += 1;
                    {
                        use acch_pipeline::Stage;
                        let mut payload = vec![0u8; 2 * (w * h) as usize];
                        let frame = protocol::frame_of(&r, i as u64, false, object.radius_m());
                        let header = acch_pipeline::stages::Segmented::from_mask(
                            frame.envelope,
                            r.mask.as_raw(),
                            &index.data,
                            w,
                            &mut payload,
                        )?
                        .ok_or("empty")?;
                        let mut response = vec![0u8; stage.max_payload()];
                        if let Ok(acch_pipeline::wire::Outcome::Done(e)) =
                            stage.process(&header, &payload, &mut response)
                        {
                            stage_fail[s] += fails((e.theta_deg, e.phi_deg), truth) as usize;
                        } else {
                            stage_fail[s] += 1;
                        }
                    }
                    for (m, mask) in [&grown[..], r.mask.as_raw()].into_iter().enumerate() {
                        let Some(roi) = mask_bbox(mask, w, h) else {
                            failures[s][m].iter_mut().for_each(|f| *f += 1);
                            continue;
                        };
                        let q = estimator.respond(&index, Some(mask), roi, scale) as f32;
                        if q == 0.0 {
                            failures[s][m].iter_mut().for_each(|f| *f += 1);
                            continue;
                        }
                        let query = estimator.histogram();
                        for (c, _) in SCORERS.iter().enumerate() {
                            let mut best = (f32::NEG_INFINITY, 0usize);
                            for (vi, &nv) in view_pairs.iter().enumerate() {
                                let t = db.histogram(vi);
                                let raw: f32 =
                                    query.iter().zip(t).map(|(a, b)| (a * q).min(b * nv)).sum();
                                let value = match c {
                                    0 => acch_core::intersection(query, t),
                                    1 => raw / q,
                                    2 => raw / nv.max(1.0),
                                    3 => raw / q.max(nv),
                                    4 => raw / q * acch_core::intersection(query, t),
                                    _ => raw / q + acch_core::intersection(query, t),
                                };
                                if value > best.0 {
                                    best = (value, vi);
                                }
                            }
                            let v = db.views()[best.1];
                            failures[s][m][c] += fails((v.theta_deg, v.phi_deg), truth) as usize;
                            theta_err[s][m][c] += (v.theta_deg - truth.0).abs() as f64;
                        }
                    }
                }
            }
        }
        eprintln!("done generated-{k}");
    }
    println!(
        "share scenes | grown: normalised visible model larger | true mask: the same (failure %)"
    );
    for (s, share) in shares.iter().enumerate() {
        let pct = |f: usize| 100.0 * f as f64 / scenes[s].max(1) as f64;
        let f = &failures[s];
        println!(
            "{share:.1} {} | {:5.1} {:5.1} {:5.1} {:5.1} | {:5.1} {:5.1} {:5.1} {:5.1}",
            scenes[s],
            pct(f[0][0]),
            pct(f[0][1]),
            pct(f[0][2]),
            pct(f[0][3]),
            pct(f[1][0]),
            pct(f[1][1]),
            pct(f[1][2]),
            pct(f[1][3])
        );
        println!("  pose stage on the true mask: {:5.1}", pct(stage_fail[s]));
        for m in 0..2 {
            let line: Vec<String> = (0..6)
                .map(|c| {
                    format!(
                        "{} {:4.1}% E(th) {:4.2}",
                        SCORERS[c],
                        pct(f[m][c]),
                        theta_err[s][m][c] / scenes[s] as f64
                    )
                })
                .collect();
            println!("  {}: {}", ["grown", "true"][m], line.join(" | "));
        }
    }
    Ok(())
}
