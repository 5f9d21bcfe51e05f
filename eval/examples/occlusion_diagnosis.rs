//! Why does an occluding bar break the estimate of generated objects?
//! Per object and share, scenes rendered with the bar and the same scenes
//! without it; for each: how many of the bar's pixels over the object
//! quantise to one of the object's colours, how much of the bar the grown
//! region holds, the region's IoU with what stays visible, and the pose
//! from the deployed chain against the pose from the true visible mask.
//!
//! `cargo run --release -p acch-eval --example occlusion_diagnosis -- [FIRST] [OBJECTS] [N]`
//! (generated objects FIRST.., default 3000, 10 objects, 6 views a background).

use acch_capture::{Object, Renderer};
use acch_core::NOT_OBJECT;
use acch_eval::protocol::{self, fails};
use acch_pipeline::Stage;
use acch_pipeline::stages::{Pose, Segmented};
use acch_pipeline::wire::Outcome;
use std::sync::Arc;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (first, count, n) = protocol::diagnosis_args(10, 6)?;
    println!(
        "object share | bar px as object % | bar in region % | IoU | chain fail % acc % acc-fail % | true-mask fail %"
    );
    // (share, best match value, failed, accepted) of every estimate.
    let mut records: Vec<(f32, f32, bool, bool)> = Vec::new();
    for k in first..first + count {
        let object = Arc::new(Object::builtin(&format!("generated-{k}"))?);
        let (db, _) = acch_eval::train::cached_database(&object, None)?;
        for share in [0.0f32, 0.1, 0.2, 0.3] {
            let (mut bar_px, mut bar_obj, mut bar_in, mut iou_sum) = (0usize, 0usize, 0usize, 0.0);
            let (mut scenes, mut chain_fail, mut acc, mut acc_fail, mut true_fail) =
                (0usize, 0usize, 0usize, 0usize, 0usize);
            for b in 0..3 {
                let (base, seed, views) = protocol::diagnosis_scenes(&object, k, b, 0x6f63, n)?;
                let clean = Renderer::new(base.clone(), seed);
                let mut occluded_config = base;
                occluded_config.occlusion = share;
                let occluded = Renderer::new(occluded_config, seed);
                let mut chain = protocol::chain(&db)?;
                let mut pose = Pose::new(
                    &db,
                    &protocol::settings_at(&db, db.train_distance_m as f64, 0),
                )?;
                for (i, v) in views.iter().enumerate() {
                    let fs = acch_capture::frame_seed(seed, i);
                    let full = clean.render(v, fs);
                    let r = occluded.render(v, fs);
                    let (w, h) = r.image.dimensions();
                    let index = db.palette.quantise(r.image.as_raw(), w, h);
                    let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
                    // The bar's pixels over the object.
                    let hidden: Vec<usize> = (0..(w * h) as usize)
                        .filter(|&p| full.mask.as_raw()[p] != 0 && r.mask.as_raw()[p] == 0)
                        .collect();
                    bar_px += hidden.len();
                    bar_obj += hidden
                        .iter()
                        .filter(|&&p| index.data[p] != NOT_OBJECT)
                        .count();
                    let out = chain.process(
                        &protocol::frame_of(&r, i as u64, false, object.radius_m()),
                        r.image.as_raw(),
                    );
                    scenes += 1;
                    match out.pose().done() {
                        Some(e) => {
                            let failed = fails((e.theta_deg, e.phi_deg), truth);
                            chain_fail += failed as usize;
                            let accepted = out.rating().verdict().is_some_and(|v| v.accepted);
                            records.push((share, e.best_value, failed, accepted));
                            if accepted {
                                acc += 1;
                                acc_fail += failed as usize;
                            }
                        }
                        None => chain_fail += 1,
                    }
                    if let Some(region) = chain.last_region() {
                        let mut grown = Vec::new();
                        region.frame_mask(w, h, &mut grown);
                        bar_in += hidden.iter().filter(|&&p| grown[p] != 0).count();
                        iou_sum += protocol::mask_iou(&grown, r.mask.as_raw());
                    }
                    // The pose from the true visible mask.
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
                        true_fail += 1;
                        continue;
                    };
                    let mut response = vec![0u8; pose.max_payload()];
                    match pose.process(&header, &payload, &mut response) {
                        Ok(Outcome::Done(e)) => {
                            true_fail += fails((e.theta_deg, e.phi_deg), truth) as usize
                        }
                        _ => true_fail += 1,
                    }
                }
            }
            let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
            println!(
                "generated-{k} {share:.1} | {:5.1} | {:5.1} | {:.2} | {:5.1} {:5.1} {:5.1} | {:5.1}",
                pct(bar_obj, bar_px),
                pct(bar_in, bar_px),
                iou_sum / scenes as f64,
                pct(chain_fail, scenes),
                pct(acc, scenes),
                pct(acc_fail, acc),
                pct(true_fail, scenes),
            );
        }
    }
    println!(
        "floor on the best match value, among the network's accepted: share | floor accepted % acc-fail %"
    );
    for share in [0.0f32, 0.1, 0.2, 0.3] {
        let n = records.iter().filter(|r| r.0 == share).count().max(1);
        let mut line = format!("{share:.1} |");
        for floor in [0.0f32, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7] {
            let kept: Vec<_> = records
                .iter()
                .filter(|r| r.0 == share && r.3 && r.1 >= floor)
                .collect();
            let wrong = kept.iter().filter(|r| r.2).count();
            line += &format!(
                " {floor:.2}: {:5.1} {:5.1} |",
                100.0 * kept.len() as f64 / n as f64,
                100.0 * wrong as f64 / kept.len().max(1) as f64
            );
        }
        println!("{line}");
    }
    Ok(())
}
