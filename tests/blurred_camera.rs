//! A camera that blurs by 2 px: views and frames smoothed alike before
//! quantisation hold the pose; raw pixels, the paper's way, lose it often
//! enough to tell the two apart on the same scenes, so the check can fail.
//! True masks, so quantisation and matching alone are measured; generated
//! objects of the development seed (docs/accuracy.md, "A blurred camera").
//! `acch run --smoothing binomial --confidence-imaging` runs such a
//! database, and says which; `acch run --smoothing auto` chooses it per
//! frame, for a noisy camera and an object out of focus.

mod common;

use acch_capture::{Object, Renderer};
use acch_core::Smoothing;
use acch_eval::protocol::{self, fails};
use acch_pose::train::{TrainConfig, mask_bbox};
use acch_pose::{PoseEstimator, Refinement};
use acch_train::views::{RenderedTraining, train_rendered};
use common::{acch, free_port, ok};
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[test]
fn smoothed_views_and_frames_hold_a_blurred_camera_where_raw_pixels_fail() {
    let (mut scenes, mut smoothed, mut raw) = (0usize, 0usize, 0usize);
    for k in 3000..3004 {
        let object = Arc::new(Object::builtin(&format!("generated-{k}")).unwrap());
        let train = |smoothing| {
            let config = TrainConfig {
                smoothing,
                ..TrainConfig::default()
            };
            train_rendered(&object, &config, &RenderedTraining::default()).unwrap()
        };
        let dbs = [train(Smoothing::Binomial), train(Smoothing::Off)];
        assert_eq!(dbs[0].palette.smoothing(), Smoothing::Binomial);
        let mut estimators = dbs.clone().map(|db| PoseEstimator::new(db).unwrap());
        for b in 0..3 {
            let (mut config, seed, poses) =
                protocol::diagnosis_scenes(&object, k, b, 0xb1, 6).unwrap();
            config.effects.blur_sigma = 2.0;
            let renderer = Renderer::new(config, seed);
            for (i, v) in poses.iter().enumerate() {
                let r = renderer.render(v, acch_capture::frame_seed(seed, i));
                let (w, h) = r.image.dimensions();
                let mask = r.mask.as_raw();
                let roi = mask_bbox(mask, w, h).expect("the object is in view");
                let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
                let mut failed = |d: usize| {
                    let index = dbs[d].palette.quantise(r.image.as_raw(), w, h);
                    estimators[d]
                        .estimate(&index, Some(mask), roi, Some(1.0), Refinement::Parabolic)
                        .is_none_or(|e| fails((e.theta_deg, e.phi_deg), truth))
                };
                smoothed += failed(0) as usize;
                raw += failed(1) as usize;
                scenes += 1;
            }
        }
    }
    let share = |f: usize| f as f64 / scenes as f64;
    eprintln!(
        "{scenes} scenes blurred by 2 px: smoothed fails {:.3}, raw {:.3}",
        share(smoothed),
        share(raw)
    );
    assert!(
        share(smoothed) <= 0.15,
        "smoothed failed {smoothed} of {scenes}"
    );
    // Since training revision 7 (the colour layout) raw databases fail
    // 13 of these 72 where smoothed ones fail 3 (docs/accuracy.md).
    assert!(
        share(raw) >= share(smoothed) + 0.10,
        "raw failed {raw}, smoothed {smoothed}, of {scenes}"
    );
}

/// `acch run --in-process ARGS`: the view database it names, and its
/// summary.
fn run_naming_database(args: &[&str], dir: &Path) -> (PathBuf, serde_json::Value) {
    let mut all = vec!["--in-process"];
    all.extend_from_slice(args);
    let (db, _, summary) = run_naming_databases(&all, dir);
    (db, summary)
}

/// `acch run ARGS` over 30 frames: the view database it names, the
/// smoothed one (`--smoothing auto`), and its summary.
fn run_naming_databases(
    args: &[&str],
    dir: &Path,
) -> (PathBuf, Option<PathBuf>, serde_json::Value) {
    let json = dir.join("summary.json");
    let mut all = vec!["run", "--frames", "30", "--fps", "0"];
    all.extend_from_slice(args);
    all.extend(["--json", json.to_str().unwrap()]);
    let out = acch(&all, dir);
    ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    let db = err
        .lines()
        .find_map(|l| l.strip_prefix("acch run: view database "))
        .unwrap_or_else(|| panic!("the run names no database: {err}"));
    let smoothed = err.lines().find_map(|l| {
        l.strip_prefix("acch run: smoothed view database for noisy, compressed or blurred frames ")
    });
    let summary = std::fs::read_to_string(&json).unwrap();
    (
        db.into(),
        smoothed.map(PathBuf::from),
        serde_json::from_str(&summary).unwrap(),
    )
}

#[test]
fn a_run_for_a_noisy_camera_uses_the_smoothing_imaging_aware_database() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("p.toml");
    let zenoh = format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port());
    std::fs::write(&config, &zenoh).unwrap();
    let cfg = config.to_str().unwrap();
    let (default, _) = run_naming_database(&["--config", cfg], dir.path());
    let (robust, summary) = run_naming_database(
        &[
            "--config",
            cfg,
            "--smoothing",
            "binomial",
            "--confidence-imaging",
        ],
        dir.path(),
    );
    assert_ne!(default, robust);
    let name = robust.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.ends_with("-imaging-smoothed.acchdb"), "{name}");
    let load = |p: &Path| acch_core::ViewDatabase::load(p).unwrap();
    assert_eq!(load(&default).palette.smoothing(), Smoothing::Off);
    assert_eq!(load(&robust).palette.smoothing(), Smoothing::Binomial);
    // It estimates as a run should: found, accepted, and none wrong.
    let count = |key: &str| {
        summary[key]
            .as_u64()
            .unwrap_or_else(|| panic!("{key}: {summary}"))
    };
    // Measured 22 of 30: the shape's verification rejects a few noisy
    // frames whose contour it cannot place on the region's edge.
    assert!(count("accepted") >= 20, "{summary}");
    assert_eq!(count("accepted_with_truth"), count("accepted"));
    assert_eq!(count("accepted_wrong"), 0, "{summary}");
    // The configuration's keys choose the same database.
    std::fs::write(
        &config,
        format!("[estimate]\nsmoothing = \"binomial\"\nconfidence_imaging = true\n{zenoh}"),
    )
    .unwrap();
    let (configured, _) = run_naming_database(&["--config", cfg], dir.path());
    assert_eq!(configured, robust);
}

#[test]
fn a_run_that_chooses_per_frame_sends_a_noisy_or_blurred_camera_through_the_smoothed_databases() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("p.toml");
    let zenoh = format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port());
    let count = |summary: &serde_json::Value, key: &str| {
        summary[key]
            .as_u64()
            .unwrap_or_else(|| panic!("{key}: {summary}"))
    };
    // A clean camera, in one process: both databases named, every frame
    // through the sharp one.
    std::fs::write(&config, &zenoh).unwrap();
    let cfg = config.to_str().unwrap();
    let args = ["--config", cfg, "--smoothing", "auto"];
    let mut in_process = vec!["--in-process"];
    in_process.extend(args);
    let (sharp, smoothed, summary) = run_naming_databases(&in_process, dir.path());
    let smoothed = smoothed.expect("the run names its smoothed database");
    let load = |p: &Path| acch_core::ViewDatabase::load(p).unwrap();
    assert_eq!(load(&sharp).palette.smoothing(), Smoothing::Off);
    assert_eq!(load(&smoothed).palette.smoothing(), Smoothing::Binomial);
    let name = smoothed.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.ends_with("-imaging-smoothed.acchdb"), "{name}");
    assert_eq!(count(&summary, "results"), 30, "{summary}");
    assert_eq!(count(&summary, "smoothed"), 0, "{summary}");
    assert_eq!(count(&summary, "smoothed_for_not_found"), 0, "{summary}");
    assert!(count(&summary, "accepted") >= 24, "{summary}");
    assert_eq!(count(&summary, "accepted_wrong"), 0, "{summary}");
    // A noisy camera, in the stage processes: every frame through the
    // smoothed databases, and estimated as well. Free-running, the
    // processes drop frames the slower stages cannot take in time (pose
    // drops, and counts, a frame whose pixels left its queue rather than
    // estimate it unverified): measured 22 of 30 delivered, each frame
    // either delivered or counted as dropped.
    std::fs::write(&config, format!("[synthetic]\nnoise_sigma = 5.0\n{zenoh}")).unwrap();
    let (_, _, summary) = run_naming_databases(&args, dir.path());
    let results = count(&summary, "results");
    assert!(results >= 15, "{summary}");
    assert_eq!(results + count(&summary, "dropped"), 30, "{summary}");
    assert_eq!(count(&summary, "smoothed"), results, "{summary}");
    assert_eq!(count(&summary, "smoothed_for_camera"), results, "{summary}");
    // Measured 22 of 30 (the shape's verification rejects a few).
    assert!(count(&summary, "accepted") * 3 >= results * 2, "{summary}");
    assert_eq!(count(&summary, "accepted_wrong"), 0, "{summary}");
    assert_eq!(count(&summary, "faulted"), 0, "{summary}");
    // A lens out of focus by 2 px, in one process (every frame taken): the
    // camera's noise and blocking say nothing, the object's sharpness sends
    // every frame through the smoothed databases, found and accepted as
    // that recipe alone does, but from the frame as it is rather than
    // smoothed again, so no less accurately (docs/accuracy.md, "A blurred
    // object" and "A blurred frame is not smoothed again").
    std::fs::write(&config, format!("[synthetic]\nblur_sigma = 2.0\n{zenoh}")).unwrap();
    let (_, _, auto) = run_naming_databases(&in_process, dir.path());
    let recipe = ["--smoothing", "binomial", "--confidence-imaging"];
    let (_, alone) = run_naming_database(&[&["--config", cfg][..], &recipe].concat(), dir.path());
    assert_eq!(count(&auto, "smoothed"), count(&auto, "results"), "{auto}");
    assert_eq!(count(&auto, "smoothed_for_camera"), 0, "{auto}");
    assert_eq!(
        count(&auto, "smoothed_for_blur") + count(&auto, "smoothed_for_not_found"),
        count(&auto, "results"),
        "{auto}"
    );
    assert!(
        count(&auto, "smoothed_for_blur") * 5 >= count(&auto, "results") * 4,
        "{auto}"
    );
    for key in ["results", "found"] {
        assert_eq!(
            count(&auto, key),
            count(&alone, key),
            "{key}: {auto} {alone}"
        );
    }
    // The shape's verification accepts few blurred frames either way
    // (measured 9 of 30 from the frame as it is, none wrong, mean |Δθ|
    // 1.57° and |Δφ| 4.8°; 12 smoothed again, none wrong, 0.51° and
    // 12.7°). Smoothed again it accepted 7 before the shape's polish had a
    // second round (the frame as it is 9 then too), and before the region
    // was refined by the frame's colours (`acch_segmentation::refine`) 5,
    // one of them wrong. The frame as it is accepts a third of the frames
    // or near it, none wrong, and places them no worse in azimuth.
    assert!(count(&auto, "accepted") >= 6, "{auto}");
    assert_eq!(count(&auto, "accepted_wrong"), 0, "{auto}");
    let phi_err = |summary: &serde_json::Value| {
        summary["accepted_mean_phi_err_deg"]
            .as_f64()
            .unwrap_or_else(|| panic!("accepted_mean_phi_err_deg: {summary}"))
    };
    assert!(phi_err(&auto) <= phi_err(&alone) + 1.0, "{auto} {alone}");
    assert!(count(&alone, "accepted_wrong") <= 1, "{alone}");
    let theta_err = |summary: &serde_json::Value| {
        summary["accepted_mean_theta_err_deg"]
            .as_f64()
            .unwrap_or_else(|| panic!("accepted_mean_theta_err_deg: {summary}"))
    };
    assert!(theta_err(&auto) <= 3.0, "{auto}");
}
