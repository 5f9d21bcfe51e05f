//! Parameter exploration for recognition + segmentation (development aid).
//! `cargo run --release -p acch-segmentation --example explore -- OBJECT N BG...`
//! Parameters from environment variables (see `params()`).

use acch_capture::{
    Background, DEFAULT_DISTANCE, Intrinsics, Object, Rendered, Renderer, SceneConfig, ViewSpec,
};
use acch_core::IndexImage;
use acch_pose::train::{LabelledView, TrainConfig, build_database};
use acch_pose::{PoseEstimator, Refinement, phi_error};
use acch_recognition::{Detector, RecognitionModel, RecognitionParams};
use acch_segmentation::Segmenter;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(d)
}

fn params() -> RecognitionParams {
    let d = RecognitionParams::default();
    RecognitionParams {
        cell_px: env("REC_CELL", d.cell_px),
        pair_distance: env("REC_PD", d.pair_distance),
        pairs: env("REC_PAIRS", d.pairs),
        same_colour_pairs: env("REC_SAME", d.same_colour_pairs),
        colour_weight: env("REC_ALPHA", d.colour_weight),
        window_factor: env("REC_WF", d.window_factor),
        min_visible: env("REC_MV", d.min_visible),
        found_fraction: env("REC_FF", d.found_fraction),
        cell_threshold: env("REC_CT", d.cell_threshold),
        pixel_threshold: env("REC_PT", d.pixel_threshold),
        smooth_radius: env("REC_SR", d.smooth_radius),
        max_growth: env("REC_MG", d.max_growth),
    }
}

fn seed_of(set: u64, i: usize) -> u64 {
    set.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(i as u64 + 1)
}

fn renderer(object: Arc<Object>, bg: Background, seed: u64, shift: f64) -> Renderer {
    let mut k = Intrinsics::default();
    k.cx += shift;
    Renderer::new(
        SceneConfig {
            object,
            background: bg,
            intrinsics: k,
            effects: Default::default(),
        },
        seed,
    )
}

fn iou(a: &[u8], b: &[u8]) -> f64 {
    let (mut i, mut u) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x != 0, y != 0);
        i += (x && y) as u64;
        u += (x || y) as u64;
    }
    if u == 0 { 0.0 } else { i as f64 / u as f64 }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("fruitbox");
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let bgs: Vec<String> = if args.len() > 3 {
        args[3..].to_vec()
    } else {
        vec!["A".into(), "B".into(), "C".into(), "clutter-similar".into()]
    };
    let object = Arc::new(Object::builtin(name).unwrap());
    let t = Instant::now();
    let plain = renderer(object.clone(), Background::default(), 1, 0.0);
    let grid = ViewSpec::training_grid().views(DEFAULT_DISTANCE, 0);
    let train: Vec<Rendered> = grid
        .par_iter()
        .enumerate()
        .map(|(i, v)| plain.render(v, seed_of(0, i)))
        .collect();
    let labelled: Vec<LabelledView> = train
        .iter()
        .map(|r| LabelledView {
            rgb: r.image.as_raw(),
            mask: r.mask.as_raw(),
            width: r.image.width(),
            height: r.image.height(),
            theta_deg: r.truth.theta_deg as f32,
            phi_deg: r.truth.phi_deg as f32,
            scale: 1.0,
        })
        .collect();
    let mut cfg = TrainConfig::default();
    cfg.reject_quantile = Some(env("REJECT_Q", 0.99f32));
    let db = build_database(name, DEFAULT_DISTANCE as f32, &labelled, &cfg).unwrap();
    let p = params();
    let model = RecognitionModel::train(&labelled, &db.palette, &p).unwrap();
    eprintln!(
        "trained in {:.1}s: size {:.1}px train score {:.3} threshold {:.3} pairs {:?}",
        t.elapsed().as_secs_f64(),
        model.size_px,
        model.train_score,
        model.threshold,
        &model.pairs[..model.pairs.len().min(6)]
    );
    let est0 = PoseEstimator::new(db.clone()).unwrap();
    let det0 = Detector::new(model.clone(), 640, 480).unwrap();
    let seg0 = Segmenter::new(640, 480).unwrap();
    let verbose = env("VERBOSE", 0u32);
    println!(
        "{:<16} {:>6} {:>6} {:>7} {:>7} {:>6} {:>5} {:>7} {:>7} {:>6} {:>6} {:>6}",
        "bg",
        "iou",
        "iouMed",
        "dphi",
        "dtheta",
        "fail",
        "nf",
        "gtFail",
        "roiFail",
        "score",
        "empty",
        "emptyMx"
    );
    for bg in &bgs {
        let background: Background = bg.parse().unwrap();
        let seed = env("SEED", 1u64);
        let r = renderer(object.clone(), background, seed, 0.0);
        let empty = renderer(object.clone(), background, seed, 4000.0);
        let views = ViewSpec::Random { n }.views(DEFAULT_DISTANCE, seed);
        let rows: Vec<(f64, f64, f64, bool, bool, bool, bool, f32, f32)> = views
            .par_iter()
            .enumerate()
            .map_init(
                || (est0_clone(&est0), det0.clone(), seg0.clone(), IndexImage::default()),
                |(est, det, seg, index), (i, v)| {
                    let f = r.render(v, seed_of(seed, i));
                    let (w, h) = f.image.dimensions();
                    est.database().palette.quantise_into(f.image.as_raw(), w, h, index);
                    let gt = f.mask.as_raw();
                    // Oracle pose with the ground-truth mask.
                    let gt_roi = acch_pose::train::mask_bbox(gt, w, h).unwrap();
                    let e = est.estimate(index, Some(gt), gt_roi, Some(1.0), Refinement::Parabolic);
                    let fail_of = |e: Option<acch_pose::Estimate>| match e {
                        Some(e) => {
                            (e.theta_deg - v.theta_deg as f32).abs() > 10.0
                                || phi_error(e.phi_deg, v.phi_deg as f32) > 20.0
                        }
                        None => true,
                    };
                    let gt_fail = fail_of(e);
                    let d = det.detect(index, Some(1.0));
                    let score = det.best_score();
                    // Empty scene score.
                    let fe = empty.render(v, seed_of(seed, i));
                    est.database().palette.quantise_into(fe.image.as_raw(), w, h, index);
                    det.detect(index, Some(1.0));
                    let empty_score = det.best_score();
                    est.database().palette.quantise_into(f.image.as_raw(), w, h, index);
                    det.detect(index, Some(1.0));
                    let Some(d) = d else {
                        return (0.0, 0.0, 0.0, true, true, gt_fail, true, score, empty_score);
                    };
                    let Some(s) = seg.segment(index, det, &d) else {
                        return (0.0, 0.0, 0.0, true, true, gt_fail, true, score, empty_score);
                    };
                    let io = iou(s.mask, gt);
                    let (mask, roi) = (s.mask.to_vec(), s.roi);
                    if std::env::var("DUMP").map(|d| d.split(',').any(|x| x == i.to_string())).unwrap_or(false) {
                        let mut img = f.image.clone();
                        for (k, px) in img.pixels_mut().enumerate() {
                            let (m, g) = (mask[k] != 0, gt[k] != 0);
                            if m && !g { px.0 = [255, 0, 255]; }
                            if !m && g { px.0 = [0, 255, 255]; }
                        }
                        img.save(format!("/tmp/seg_{name}_{bg}_{i}.png")).unwrap();
                        f.image.save(format!("/tmp/raw_{name}_{bg}_{i}.png")).unwrap();
                        let wts = *seg.colour_weights();
                        let wimg = image::GrayImage::from_fn(w, h, |x, y| image::Luma([wts[index.get(x, y) as usize]]));
                        wimg.save(format!("/tmp/w_{name}_{bg}_{i}.png")).unwrap();
                        let (gx, gy) = det.grid();
                        let (reg, cs) = (seg.region(), seg.cell_scores());
                        for cy in 0..gy {
                            let line: String = (0..gx).map(|cx| {
                                let k = cy * gx + cx;
                                match reg[k] { 0 => ' ', 1 => if cs[k] >= 0.5 { '+' } else { '.' }, _ => if cs[k] >= 0.5 { '#' } else { '?' } }
                            }).collect();
                            eprintln!("{line}");
                        }
                        eprintln!("det cells {:?}", d.cells);
                        let rgbs = est.database().palette.centre_rgb();
                        let freq = det.model_freq();
                        let mut lost = vec![0u32; 256];
                        let mut kept = vec![0u32; 256];
                        for k in 0..(w * h) as usize {
                            if gt[k] != 0 && mask[k] == 0 { lost[index.data[k] as usize] += 1; }
                            if gt[k] != 0 && mask[k] != 0 { kept[index.data[k] as usize] += 1; }
                        }
                        for k in 0..256 {
                            if lost[k] + kept[k] > 50 {
                                eprintln!("colour {k:3} {:?} f {:.3} w {:3} lost {} kept {}", rgbs.get(k), freq.get(k).copied().unwrap_or(0.0), wts[k], lost[k], kept[k]);
                            }
                        }
                    }
                    let e = est.estimate(index, Some(&mask), roi, Some(1.0), Refinement::Parabolic);
                    let fail = fail_of(e);
                    let e2 = est.estimate(index, Some(&mask), roi, None, Refinement::Parabolic);
                    let roi_fail = fail_of(e2);
                    let (dp, dt) = e
                        .map(|e| (phi_error(e.phi_deg, v.phi_deg as f32) as f64, (e.theta_deg - v.theta_deg as f32).abs() as f64))
                        .unwrap_or((0.0, 0.0));
                    if verbose > 0 {
                        eprintln!(
                            "{bg} {i}: θ {:.0} φ {:.0} iou {io:.2} score {score:.2} empty {empty_score:.2} dφ {dp:.0} dθ {dt:.0} win {:?}",
                            v.theta_deg, v.phi_deg, d.window
                        );
                    }
                    (io, dp, dt, fail, false, gt_fail, roi_fail, score, empty_score)
                },
            )
            .collect();
        let nn = rows.len() as f64;
        let found: Vec<_> = rows.iter().filter(|r| !r.4).collect();
        let nf = found.len().max(1) as f64;
        let mut ious: Vec<f64> = rows.iter().map(|r| r.0).collect();
        ious.sort_by(f64::total_cmp);
        let empty_max = rows.iter().map(|r| r.8).fold(0f32, f32::max);
        println!(
            "{:<16} {:>6.3} {:>6.3} {:>7.2} {:>7.2} {:>5.0}% {:>5} {:>6.0}% {:>6.0}% {:>6.3} {:>6.3} {:>6.3}",
            bg,
            rows.iter().map(|r| r.0).sum::<f64>() / nn,
            ious[ious.len() / 2],
            found.iter().map(|r| r.1).sum::<f64>() / nf,
            found.iter().map(|r| r.2).sum::<f64>() / nf,
            100.0 * rows.iter().filter(|r| r.3).count() as f64 / nn,
            rows.iter().filter(|r| r.4).count(),
            100.0 * rows.iter().filter(|r| r.5).count() as f64 / nn,
            100.0 * rows.iter().filter(|r| r.6).count() as f64 / nn,
            rows.iter().map(|r| r.7 as f64).sum::<f64>() / nn,
            rows.iter().map(|r| r.8 as f64).sum::<f64>() / nn,
            empty_max
        );
    }
    // Timing on one frame, sequential.
    let r = renderer(object.clone(), Background::A, 1, 0.0);
    let f = r.render(&ViewSpec::Random { n: 1 }.views(DEFAULT_DISTANCE, 3)[0], 5);
    let mut index = IndexImage::default();
    db.palette
        .quantise_into(f.image.as_raw(), 640, 480, &mut index);
    let (mut det, mut seg) = (det0.clone(), seg0.clone());
    let reps = 200;
    let t = Instant::now();
    for _ in 0..reps {
        det.prepare(&index);
    }
    let prep = t.elapsed().as_secs_f64() / reps as f64;
    let t = Instant::now();
    let mut d = None;
    for _ in 0..reps {
        d = det.scan(1.0);
    }
    let scan = t.elapsed().as_secs_f64() / reps as f64;
    let d = d.unwrap();
    let t = Instant::now();
    for _ in 0..reps {
        seg.segment(&index, &det, &d);
    }
    let sg = t.elapsed().as_secs_f64() / reps as f64;
    let t = Instant::now();
    for _ in 0..reps {
        db.palette
            .quantise_into(f.image.as_raw(), 640, 480, &mut index);
    }
    let q = t.elapsed().as_secs_f64() / reps as f64;
    let owned = index.data.iter().filter(|&&v| v != 255).count();
    println!("owned pixels {owned} of {}", index.data.len());
    println!(
        "timing: quantise {:.3} ms, prepare {:.3} ms, scan {:.3} ms, segment {:.3} ms",
        q * 1e3,
        prep * 1e3,
        scan * 1e3,
        sg * 1e3
    );
}

fn est0_clone(e: &PoseEstimator) -> PoseEstimator {
    PoseEstimator::new(e.database().clone()).unwrap()
}
