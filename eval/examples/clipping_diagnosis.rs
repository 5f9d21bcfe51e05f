//! Would a check on clipped pixels reject the wrong estimates of an over
//! exposed object? Per generated object, scenes rendered under the
//! training light and over exposed (exposure 1.25x and 1.5x, byte
//! brightness 1.25x and 1.5x), recognised with the single-image light
//! search as the robust protocol does. For each estimate: accepted or not,
//! wrong or not, and the share of clipped pixels (a channel at 254 or
//! more) in the segmented region, against the largest share in the true
//! mask of the object's clean scenes (a stand-in for what its training
//! views hold, which the database does not store). Then, for limits of
//! "region share above the clean largest plus a margin", what rejecting
//! on it would leave accepted and wrong among the accepted. Beside it,
//! where over exposure is lost: the pose stage on the true mask with the
//! indices of the light the search chose, without the clipped pixels,
//! under the true light (the palette relit by the exposure itself), and
//! under the exposure of the search's grid whose share of mapped mask
//! pixels times match value is highest.
//!
//! `cargo run --release -p acch-eval --example clipping_diagnosis -- [FIRST] [OBJECTS] [N]`
//! (generated objects FIRST.., default 3000, 10 objects, 4 views a background).

use acch_capture::{Background, Effects, Object, Renderer, SceneConfig, TextureSet, ViewSpec};
use acch_core::{NOT_OBJECT, Palette};
use acch_eval::protocol::{self, fails};
use acch_pipeline::Stage;
use acch_pipeline::stages::{Pose, SINGLE_IMAGE_LIGHT_SEARCH, Segmented};
use acch_pipeline::wire::Outcome;
use acch_recognition::EXPOSURES;
use std::sync::Arc;

/// A byte at or above this is taken as clipped.
const CLIPPED: u8 = 254;

/// Share of the set pixels of `mask` (one byte a pixel) whose colour in
/// `rgb` has a clipped channel.
fn clipped_share(rgb: &[u8], mask: impl Iterator<Item = usize>) -> f64 {
    let (mut n, mut clipped) = (0usize, 0usize);
    for p in mask {
        n += 1;
        clipped += rgb[3 * p..3 * p + 3].iter().any(|&c| c >= CLIPPED) as usize;
    }
    clipped as f64 / n.max(1) as f64
}

/// One estimate: (condition, accepted, wrong, region share, clean largest,
/// the pose from the true mask wrong, from the true mask without its
/// clipped pixels wrong, from the true mask quantised under the true light
/// wrong, from the true mask under the exposure whose share of mapped mask
/// pixels times match value is highest wrong).
type Record = (&'static str, bool, bool, f64, f64, bool, bool, bool, bool);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (first, count, n) = protocol::diagnosis_args(10, 4)?;
    let conditions: [(&str, Effects); 5] = [
        ("clean", Effects::default()),
        (
            "exposure 1.25",
            Effects {
                exposure: 1.25,
                ..Effects::default()
            },
        ),
        (
            "exposure 1.5",
            Effects {
                exposure: 1.5,
                ..Effects::default()
            },
        ),
        (
            "brightness 1.25",
            Effects {
                brightness: 1.25,
                ..Effects::default()
            },
        ),
        (
            "brightness 1.5",
            Effects {
                brightness: 1.5,
                ..Effects::default()
            },
        ),
    ];
    let mut records: Vec<Record> = Vec::new();
    for k in first..first + count {
        let object = Arc::new(Object::builtin(&format!("generated-{k}"))?);
        let (db, _) = acch_eval::train::cached_database(&object, None)?;
        let mut chain =
            protocol::chain_at(&db, db.train_distance_m as f64, SINGLE_IMAGE_LIGHT_SEARCH)?;
        let mut pose = Pose::new(
            &db,
            &protocol::settings_at(&db, db.train_distance_m as f64, 0),
        )?;
        let mut payload = Vec::new();
        let mut response = vec![0u8; pose.max_payload()];
        let mut clean_largest = 0f64;
        // The palette under every exposure the light search tries.
        let exposures: Vec<Palette> = EXPOSURES
            .iter()
            .map(|&e| db.palette.relit([e; 3]))
            .collect::<Result<_, _>>()?;
        let mut estimates = Vec::new();
        for (name, effects) in &conditions {
            for (b, bg) in ["A", "B", "C"].iter().enumerate() {
                let background: Background = bg.parse()?;
                let mut config =
                    SceneConfig::new(object.clone(), background).with_textures(TextureSet::HeldOut);
                config.effects = *effects;
                let seed = protocol::scene_seed(5_000 + k, b, 0, 0x636c);
                let renderer = Renderer::new(config, seed);
                let views = ViewSpec::Random { n }.views(acch_capture::DEFAULT_DISTANCE, seed);
                for (i, v) in views.iter().enumerate() {
                    let r = renderer.render(v, acch_capture::frame_seed(seed, i));
                    let (w, _) = r.image.dimensions();
                    let rgb = r.image.as_raw();
                    if *name == "clean" {
                        let truth = r.mask.as_raw();
                        let share = clipped_share(rgb, (0..truth.len()).filter(|&p| truth[p] != 0));
                        clean_largest = clean_largest.max(share);
                    }
                    let frame = protocol::frame_of(&r, i as u64, false, object.radius_m());
                    let out = chain.process(&frame, rgb);
                    payload.resize(2 * rgb.len() / 3, 0);
                    let Some(e) = out.pose().done() else {
                        continue;
                    };
                    let Some(region) = chain.last_region() else {
                        continue;
                    };
                    let roi = region.roi;
                    let pixels = (0..roi.height).flat_map(|y| {
                        (0..roi.width).filter_map(move |x| {
                            let m = region.mask[(y * roi.width + x) as usize];
                            (m != 0).then_some(((roi.y + y) * w + roi.x + x) as usize)
                        })
                    });
                    let share = clipped_share(rgb, pixels);
                    let wrong = fails(
                        (e.theta_deg, e.phi_deg),
                        (r.truth.theta_deg as f32, r.truth.phi_deg as f32),
                    );
                    let accepted = out.rating().verdict().is_some_and(|v| v.accepted);
                    // The pose stage on the true mask, with the indices of
                    // the light recognition chose, and on the true mask
                    // without its clipped pixels.
                    let indices = chain
                        .last_recognition()
                        .ok_or("no indices")?
                        .indices
                        .data
                        .to_vec();
                    let truth = r.mask.as_raw();
                    let unclipped: Vec<u8> = truth
                        .iter()
                        .zip(rgb.chunks_exact(3))
                        .map(|(&m, px)| {
                            if px.iter().any(|&c| c >= CLIPPED) {
                                0
                            } else {
                                m
                            }
                        })
                        .collect();
                    // Exposure multiplies the linear light: the palette
                    // relit by it is the true light's (brightness has none).
                    let true_light = db
                        .palette
                        .relit([effects.exposure; 3])?
                        .quantise(rgb, w, r.image.height())
                        .data;
                    let mut true_wrong = [true; 4];
                    for (t, (mask, indices)) in true_wrong.iter_mut().zip([
                        (&truth[..], &indices[..]),
                        (&unclipped[..], &indices[..]),
                        (&truth[..], &true_light[..]),
                    ]) {
                        let given =
                            Segmented::from_mask(frame.envelope, mask, indices, w, &mut payload)?;
                        if let Some(header) = given
                            && let Ok(Outcome::Done(e)) =
                                pose.process(&header, &payload, &mut response)
                        {
                            *t = fails(
                                (e.theta_deg, e.phi_deg),
                                (r.truth.theta_deg as f32, r.truth.phi_deg as f32),
                            );
                        }
                    }
                    // Another criterion for the light than recognition's
                    // score: the share of mask pixels the palette maps
                    // times the pose's match value.
                    let mask_px = truth.iter().filter(|&&m| m != 0).count().max(1) as f32;
                    let mut best = f32::MIN;
                    for palette in &exposures {
                        let relit = palette.quantise(rgb, w, r.image.height()).data;
                        let mapped = truth
                            .iter()
                            .zip(&relit)
                            .filter(|&(&m, &x)| m != 0 && x != NOT_OBJECT)
                            .count() as f32
                            / mask_px;
                        let given =
                            Segmented::from_mask(frame.envelope, truth, &relit, w, &mut payload)?;
                        if let Some(header) = given
                            && let Ok(Outcome::Done(e)) =
                                pose.process(&header, &payload, &mut response)
                            && mapped * e.best_value > best
                        {
                            best = mapped * e.best_value;
                            true_wrong[3] = fails(
                                (e.theta_deg, e.phi_deg),
                                (r.truth.theta_deg as f32, r.truth.phi_deg as f32),
                            );
                        }
                    }
                    estimates.push((*name, accepted, wrong, share, true_wrong));
                }
            }
        }
        records.extend(
            estimates
                .into_iter()
                .map(|(c, a, wr, s, t)| (c, a, wr, s, clean_largest, t[0], t[1], t[2], t[3])),
        );
        eprintln!(
            "generated-{k}: clean largest clipped share {:.1} %",
            100.0 * clean_largest
        );
    }
    println!(
        "condition | estimates | accepted % acc-fail % | region clipped % (right accepted / wrong accepted, means) | then per margin: accepted % acc-fail % | wrong % of the estimates: chain, true mask, true mask without clipped pixels, true mask under the true light (exposure only), true mask under the exposure mapping x matching best"
    );
    let margins = [0.02, 0.05, 0.1, 0.2];
    println!(
        "margins: {}",
        margins
            .map(|m| format!("+{:.0} points", 100.0 * m))
            .join(", ")
    );
    for (name, _) in &conditions {
        let rows: Vec<&Record> = records.iter().filter(|r| r.0 == *name).collect();
        let total = rows.len().max(1) as f64;
        let acc: Vec<&&Record> = rows.iter().filter(|r| r.1).collect();
        let acc_wrong = acc.iter().filter(|r| r.2).count();
        let mean = |v: Vec<f64>| v.iter().sum::<f64>() / v.len().max(1) as f64;
        let right_share = mean(acc.iter().filter(|r| !r.2).map(|r| r.3).collect());
        let wrong_share = mean(acc.iter().filter(|r| r.2).map(|r| r.3).collect());
        let mut line = format!(
            "{name:16} | {:3} | {:5.1} {:5.1} | {:5.1} / {:5.1} |",
            rows.len(),
            100.0 * acc.len() as f64 / total,
            100.0 * acc_wrong as f64 / acc.len().max(1) as f64,
            100.0 * right_share,
            100.0 * wrong_share,
        );
        for m in margins {
            let kept: Vec<&&&Record> = acc.iter().filter(|r| r.3 <= r.4 + m).collect();
            let kept_wrong = kept.iter().filter(|r| r.2).count();
            line += &format!(
                " {:5.1} {:5.1} |",
                100.0 * kept.len() as f64 / total,
                100.0 * kept_wrong as f64 / kept.len().max(1) as f64
            );
        }
        let pct = |v: usize| 100.0 * v as f64 / total;
        line += &format!(
            " chain {:5.1} true mask {:5.1} without clipped {:5.1} under the true light {:5.1} \
             under the light mapping x matching best {:5.1}",
            pct(rows.iter().filter(|r| r.2).count()),
            pct(rows.iter().filter(|r| r.5).count()),
            pct(rows.iter().filter(|r| r.6).count()),
            pct(rows.iter().filter(|r| r.7).count()),
            pct(rows.iter().filter(|r| r.8).count()),
        );
        println!("{line}");
    }
    Ok(())
}
