//! Where does the region the chain grows around an occluded object lose
//! the pose? On the same occluded scenes, the pose stage (winner takes all
//! and refinement as deployed) from five masks: the grown region, the
//! grown region without what is not visible object (its extra pixels
//! removed), the grown region with the visible object it missed added, the
//! true visible mask, and the grown region with the visible pixels of
//! every colour it holds none of added (what the foreign-colour cut took);
//! what the region misses and holds beyond the object (the bar, the
//! background); and how often recognition found nothing or segmentation
//! grew no region.
//!
//! `cargo run --release -p acch-eval --example occlusion_region -- [FIRST] [OBJECTS] [N]`
//! (generated objects FIRST.., default 3000, 10 objects, 6 views a background).

use acch_capture::{Object, Renderer};
use acch_eval::protocol::{self, fails};
use acch_pipeline::Stage;
use acch_pipeline::stages::{Pose, Segmented};
use acch_pipeline::wire::Outcome;
use std::sync::Arc;

const MASKS: [&str; 5] = [
    "grown",
    "grown-extra",
    "grown+missed",
    "true",
    "grown+dropped",
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (first, count, n) = protocol::diagnosis_args(10, 6)?;
    let shares = [0.0f32, 0.1, 0.2, 0.3];
    let mut fail = [[0usize; 5]; 4];
    let mut scenes = [0usize; 4];
    // Not detected, no region.
    let mut lost = [[0usize; 2]; 4];
    // Pixels: visible object, missed of it, extra on the bar, extra
    // elsewhere, missed of a colour the region holds none of.
    let mut px = [[0usize; 5]; 4];
    for k in first..first + count {
        let object = Arc::new(Object::builtin(&format!("generated-{k}"))?);
        let (db, _) = acch_eval::train::cached_database(&object, None)?;
        for (s, &share) in shares.iter().enumerate() {
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
                    let frame = protocol::frame_of(&r, i as u64, false, object.radius_m());
                    let out = chain.process(&frame, r.image.as_raw());
                    let seg = &out.rated.posed.segmented;
                    if seg.recognised.detection.done().is_none() {
                        lost[s][0] += 1;
                    } else if seg.region.done().is_none() {
                        lost[s][1] += 1;
                    }
                    scenes[s] += 1;
                    let visible = r.mask.as_raw();
                    let mut grown = vec![0u8; (w * h) as usize];
                    if let Some(region) = chain.last_region() {
                        region.frame_mask(w, h, &mut grown);
                    }
                    let mut held = [0u32; 256];
                    for p in 0..(w * h) as usize {
                        held[index.data[p] as usize] += (grown[p] != 0) as u32;
                    }
                    let dropped = |p: usize| {
                        held[index.data[p] as usize] == 0 && index.data[p] != acch_core::NOT_OBJECT
                    };
                    for p in 0..(w * h) as usize {
                        px[s][4] += (visible[p] != 0 && grown[p] == 0 && dropped(p)) as usize;
                        let (g, t, f) =
                            (grown[p] != 0, visible[p] != 0, full.mask.as_raw()[p] != 0);
                        px[s][0] += t as usize;
                        px[s][1] += (t && !g) as usize;
                        px[s][2] += (g && !t && f) as usize;
                        px[s][3] += (g && !t && !f) as usize;
                    }
                    let with_dropped: Vec<u8> = (0..(w * h) as usize)
                        .map(|p| {
                            if visible[p] != 0 && dropped(p) {
                                255
                            } else {
                                grown[p]
                            }
                        })
                        .collect();
                    let masks: [Vec<u8>; 5] = [
                        grown.clone(),
                        grown.iter().zip(visible).map(|(&g, &t)| g.min(t)).collect(),
                        grown.iter().zip(visible).map(|(&g, &t)| g.max(t)).collect(),
                        visible.to_vec(),
                        with_dropped,
                    ];
                    for (m, mask) in masks.iter().enumerate() {
                        let mut payload = vec![0u8; 2 * (w * h) as usize];
                        let given = Segmented::from_mask(
                            frame.envelope,
                            mask,
                            &index.data,
                            w,
                            &mut payload,
                        )?;
                        let Some(header) = given else {
                            fail[s][m] += 1;
                            continue;
                        };
                        let mut response = vec![0u8; pose.max_payload()];
                        match pose.process(&header, &payload, &mut response) {
                            Ok(Outcome::Done(e)) => {
                                fail[s][m] += fails((e.theta_deg, e.phi_deg), truth) as usize
                            }
                            _ => fail[s][m] += 1,
                        }
                    }
                }
            }
        }
        eprintln!("done generated-{k}");
    }
    println!(
        "share scenes | failures %: {} | missed % of visible, extra on the bar %, extra elsewhere %, missed of a colour the region lacks % (of visible)",
        MASKS.join(" ")
    );
    for (s, share) in shares.iter().enumerate() {
        let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
        let f: Vec<String> = fail[s]
            .iter()
            .map(|&x| format!("{:5.1}", pct(x, scenes[s])))
            .collect();
        println!(
            "{share:.1} {} | {} | {:5.1} {:5.1} {:5.1} {:5.1}",
            scenes[s],
            f.join(" "),
            pct(px[s][1], px[s][0]),
            pct(px[s][2], px[s][0]),
            pct(px[s][3], px[s][0]),
            pct(px[s][4], px[s][0]),
        );
        println!("  not detected {} no region {}", lost[s][0], lost[s][1]);
    }
    Ok(())
}
