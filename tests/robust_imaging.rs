//! A camera under other light: with recognition's light search the object
//! is found and estimated at half the exposure and under a warm light; with
//! the training light only the same scenes lose it, so the check can fail.
//! The renderer's new effects reach `acch render` and name bad values.
//! Light turned to another side breaks the default database and not the
//! light-tolerant one (`--light-directions 8`). Over exposed, the light
//! chosen by the pose holds where recognition's choice fails.

mod common;

use common::{acch, ok};
use serde_json::Value;

#[test]
fn the_light_search_holds_where_the_training_light_alone_loses_the_object() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("robust.json");
    ok(&acch(
        &[
            "eval",
            "--protocol",
            "robust",
            "--object",
            "fruitbox",
            "--n",
            "4",
            "--seed",
            "11",
            "--families",
            "exposure,colour_temperature",
            "--compare",
            "--json",
            json.to_str().unwrap(),
        ],
        dir.path(),
    ));
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = report["rows"].as_array().unwrap();
    let row = |family: &str, level: f64, search: bool| {
        rows.iter()
            .find(|r| r["family"] == family && r["level"] == level && r["light_search"] == search)
            .unwrap_or_else(|| panic!("no row {family} {level} {search}"))
    };
    let f = |r: &Value, k: &str| r[k].as_f64().unwrap();
    // Only the families asked for.
    assert!(rows.iter().all(|r| r["family"] != "noise"));
    for (family, level) in [("exposure", 0.5), ("colour_temperature", 3500.0)] {
        let (on, off) = (row(family, level, true), row(family, level, false));
        eprintln!(
            "{family} {level}: with the search fail {:.2} accepted {:.2}; without fail {:.2} accepted {:.2}",
            f(on, "failure_rate"),
            f(on, "accepted_rate"),
            f(off, "failure_rate"),
            f(off, "accepted_rate")
        );
        assert!(f(on, "failure_rate") <= 0.1, "{on}");
        // Exposure 0.5 measured 9 of 12 accepted: the shape's verification
        // rejects a few dim frames whose contour it cannot place.
        assert!(f(on, "accepted_rate") >= 0.7, "{on}");
        assert!(f(on, "acc_failure_rate") <= 0.1, "{on}");
        // Without the search the object is lost, estimated wrong, or found
        // only under recognition's threshold and so never accepted: right
        // and accepted at least 20 points less often.
        let right_accepted = |r: &Value| f(r, "accepted_rate") * (1.0 - f(r, "acc_failure_rate"));
        assert!(right_accepted(off) <= right_accepted(on) - 0.2, "{off}");
    }
    // Clean scenes fail and are accepted as without the search; the light
    // chosen by the pose may move one to a neighbouring light, which moves
    // its estimate by a fraction of a degree.
    let (on, off) = (row("clean", 0.0, true), row("clean", 0.0, false));
    assert_eq!(f(on, "failure_rate"), f(off, "failure_rate"));
    // The neighbouring light may move the fitted contour off the region's
    // edge in one scene (measured 9 of 12 accepted against 10).
    let one = 1.0 / f(on, "n") + 1e-9;
    assert!(
        (f(on, "accepted_rate") - f(off, "accepted_rate")).abs() <= one,
        "{on} {off}"
    );
    for k in ["mean_phi_err_deg", "mean_theta_err_deg"] {
        assert!((f(on, k) - f(off, k)).abs() < 0.5, "{k}: {on} {off}");
    }
}

#[test]
fn views_lit_from_every_side_hold_a_light_turned_where_the_default_fails() {
    let dir = tempfile::tempdir().unwrap();
    let run = |directions: &str| -> Vec<Value> {
        let json = dir.path().join(format!("light-{directions}.json"));
        ok(&acch(
            &[
                "eval",
                "--protocol",
                "robust",
                "--object",
                "can",
                "--n",
                "4",
                "--seed",
                "11",
                "--families",
                "light_direction",
                "--light-directions",
                directions,
                "--json",
                json.to_str().unwrap(),
            ],
            dir.path(),
        ));
        let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        report["rows"].as_array().unwrap().clone()
    };
    let (default, tolerant) = (run("1"), run("8"));
    let f = |r: &Value, k: &str| r[k].as_f64().unwrap();
    let turned = |rows: &[Value]| -> Vec<Value> {
        rows.iter()
            .filter(|r| r["family"] == "light_direction")
            .cloned()
            .collect()
    };
    let worst = |rows: &[Value]| {
        turned(rows)
            .iter()
            .map(|r| f(r, "failure_rate"))
            .fold(0.0, f64::max)
    };
    assert_eq!(turned(&tolerant).len(), 8, "{tolerant:?}");
    for r in turned(&tolerant) {
        assert!(f(&r, "failure_rate") <= 0.1, "{r}");
        assert!(f(&r, "acc_failure_rate") <= 0.1, "{r}");
        assert!(f(&r, "accepted_rate") >= 0.7, "{r}");
    }
    eprintln!(
        "worst failure rate under a turned light: default {:.2}, light-tolerant {:.2}",
        worst(&default),
        worst(&tolerant)
    );
    assert!(worst(&default) >= worst(&tolerant) + 0.2, "{default:?}");
}

#[test]
fn render_takes_the_light_sensor_motion_jpeg_and_occluder_and_names_bad_values() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--object",
            "fruitbox",
            "--views",
            "random:1",
            "--background",
            "A",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        acch(&args, dir.path())
    };
    let mask_pixels = || {
        let mask = image::open(out.join("view_0000_mask.png"))
            .unwrap()
            .to_luma8();
        mask.pixels().filter(|p| p.0[0] != 0).count()
    };
    let mean = || {
        let img = image::open(out.join("view_0000.png")).unwrap().to_rgb8();
        let n = img.pixels().len() as f64;
        [0, 1, 2].map(|c| img.pixels().map(|p| p.0[c] as f64).sum::<f64>() / n)
    };
    ok(&render(&[]));
    let (clean_mask, clean) = (mask_pixels(), mean());
    ok(&render(&["--exposure", "0.5"]));
    let dim = mean();
    assert!(
        (0..3).all(|c| dim[c] < 0.85 * clean[c]),
        "{dim:?} vs {clean:?}"
    );
    ok(&render(&["--colour-temp-k", "3000"]));
    let warm = mean();
    assert!(
        warm[0] > clean[0] && warm[2] < clean[2],
        "{warm:?} vs {clean:?}"
    );
    ok(&render(&["--occlusion", "0.3"]));
    let hidden = mask_pixels();
    assert!(
        hidden < clean_mask * 85 / 100 && hidden > clean_mask / 3,
        "{hidden} of {clean_mask}"
    );
    ok(&render(&["--jpeg-quality", "40"]));
    assert_eq!(mask_pixels(), clean_mask);
    // The light turned to the other side: the same pixels, shaded otherwise.
    ok(&render(&["--light-azimuth-deg", "180"]));
    assert_eq!(mask_pixels(), clean_mask);
    assert_ne!(mean(), clean);
    // The sensor and the motion: other bytes, the same object pixels.
    for extra in [
        &["--full-well-e", "400", "--read-noise-e", "3"][..],
        &["--motion-blur-px", "6", "--motion-blur-deg", "30"],
    ] {
        ok(&render(extra));
        assert_eq!(mask_pixels(), clean_mask, "{extra:?}");
        assert_ne!(mean(), clean, "{extra:?}");
    }
    for (flag, value) in [
        ("--full-well-e", "-400"),
        ("--read-noise-e", "nan"),
        ("--motion-blur-px", "-2"),
        ("--motion-blur-deg", "720"),
        ("--light-azimuth-deg", "400"),
        ("--colour-temp-k", "200"),
        ("--occlusion", "1.5"),
        ("--vignetting", "-0.1"),
        ("--exposure", "-1"),
        ("--jpeg-quality", "101"),
    ] {
        let out = render(&[flag, value]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(flag),
            "{flag} {value}: {err}"
        );
    }
}

/// Two generated objects, their imaging-aware databases trained on first
/// use: every pooled row holds both objects' images, its rates are the
/// objects' counts summed, its worst is the worse object's; every image is
/// in the CSV, under poses of its object's and background's own; bad lists
/// are named.
#[test]
fn a_population_pools_every_objects_rows_and_names_bad_lists() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("population.json");
    let csv = dir.path().join("population.csv");
    ok(&acch(
        &[
            "eval",
            "--protocol",
            "robust",
            "--objects",
            "generated-11,generated-12",
            "--confidence-imaging",
            "--n",
            "2",
            "--seed",
            "11",
            "--families",
            "exposure",
            "--json",
            json.to_str().unwrap(),
            "--errors",
            csv.to_str().unwrap(),
        ],
        dir.path(),
    ));
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let images: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    // Two objects, clean and six exposures, 2 poses on each of 3 backgrounds.
    assert_eq!(images.len(), 2 * 7 * 6, "{text}");
    for o in report["per_object"].as_array().unwrap() {
        for row in o["rows"].as_array().unwrap() {
            let of_row: Vec<&Vec<&str>> = images
                .iter()
                .filter(|l| {
                    l[col("object")] == o["object"].as_str().unwrap()
                        && l[col("family")] == row["family"].as_str().unwrap()
                        && l[col("level")].parse::<f64>().unwrap() == row["level"].as_f64().unwrap()
                })
                .collect();
            assert_eq!(of_row.len(), 6, "{row}");
            for (column, rate) in [("failure", "failure_rate"), ("accepted", "accepted_rate")] {
                let count = of_row.iter().filter(|l| l[col(column)] == "1").count();
                assert_eq!(
                    count as f64 / 6.0,
                    row[rate].as_f64().unwrap(),
                    "{column} {row}"
                );
            }
        }
    }
    let poses: std::collections::BTreeSet<(&str, &str)> = images
        .iter()
        .map(|l| (l[col("theta_deg")], l[col("phi_deg")]))
        .collect();
    assert_eq!(poses.len(), 2 * 3 * 2, "{poses:?}");
    // A match value and a rival exactly where there is an estimate, in
    // [0, 1]; an accepted image was rated, with no rival above the bar,
    // and is not faint and weak.
    for l in &images {
        for column in ["match_value", "rival"] {
            let value = l[col(column)];
            assert_eq!(
                value.is_empty(),
                l[col("est_theta_deg")].is_empty(),
                "{column} {l:?}"
            );
            if !value.is_empty() {
                assert!(
                    (0.0..=1.0).contains(&value.parse::<f64>().unwrap()),
                    "{column} {l:?}"
                );
            }
        }
        // A detection is found from recognition's floor (a fraction of its
        // threshold, so that half-hidden objects are still estimated).
        let margin = l[col("score_margin")];
        assert_eq!(
            margin.is_empty(),
            l[col("est_theta_deg")].is_empty(),
            "{l:?}"
        );
        if !margin.is_empty() {
            assert!(
                margin.parse::<f64>().unwrap() >= acch_recognition::MIN_FOUND_MARGIN as f64 - 5e-4,
                "{l:?}"
            );
        }
        // Every frame's measured quality: renders with no noise, no JPEG
        // and no blur (only the exposure changes) measure as such (on the
        // development seed, docs/results/robust/quality: clean and
        // exposure frames 0.18-2.42, 0.97-1.02 and 0.29-0.50; noise 4,
        // JPEG 75 and blur 2 px 3.7 and up, 1.5 and up, 0.26 and down).
        let quality = |c: &str| l[col(c)].parse::<f32>().unwrap();
        assert!((0.0..3.5).contains(&quality("noise_sigma")), "{l:?}");
        assert!((0.8..1.2).contains(&quality("blockiness")), "{l:?}");
        let sharpness = quality("sharpness");
        assert!(
            sharpness.is_nan() || (0.25..=0.55).contains(&sharpness),
            "{l:?}"
        );
        if l[col("accepted")] == "1" {
            assert!(!l[col("confidence")].is_empty(), "{l:?}");
            let rival: f32 = l[col("rival")].parse().unwrap();
            assert!(rival <= acch_confidence::MAX_RIVAL_RATIO + 5e-4, "{l:?}");
            // Not both faintly detected and weakly matched (the CSV's three
            // decimals can put a value at the bar either side of it).
            let value = |c: &str| l[col(c)].parse::<f32>().unwrap();
            assert!(
                !acch_confidence::rejected_as_faint(
                    value("score_margin") + 5e-4,
                    value("match_value") + 5e-4
                ),
                "{l:?}"
            );
        }
    }
    assert_eq!(
        report["objects"],
        serde_json::json!(["generated-11", "generated-12"])
    );
    assert_eq!(report["database"], "imaging-aware");
    let per_object = report["per_object"].as_array().unwrap();
    assert_eq!(per_object.len(), 2);
    for o in per_object {
        let input = o["confidence_input"].as_str().unwrap();
        assert!(
            ["features", "response", "grounded"].contains(&input),
            "{input}"
        );
    }
    let rows = report["rows"].as_array().unwrap();
    // Clean and the six exposures.
    assert_eq!(rows.len(), 7);
    let f = |r: &Value, k: &str| r[k].as_f64().unwrap();
    for (k, row) in rows.iter().enumerate() {
        let parts: Vec<&Value> = per_object.iter().map(|o| &o["rows"][k]).collect();
        assert!(
            parts
                .iter()
                .all(|p| p["family"] == row["family"] && p["level"] == row["level"])
        );
        assert_eq!(row["n"], 12, "{row}");
        assert_eq!(row["objects"], 2);
        let count = |r: &Value, k: &str| (f(r, k) * f(r, "n")).round();
        let failed: f64 = parts.iter().map(|p| count(p, "failure_rate")).sum();
        assert!(
            (f(row, "failure_rate") - failed / 12.0).abs() < 1e-9,
            "{row}"
        );
        let accepted: f64 = parts.iter().map(|p| count(p, "accepted_rate")).sum();
        assert!(
            (f(row, "accepted_rate") - accepted / 12.0).abs() < 1e-9,
            "{row}"
        );
        let worst = parts
            .iter()
            .map(|p| f(p, "failure_rate"))
            .fold(0.0, f64::max);
        assert_eq!(f(row, "worst_failure_rate"), worst);
    }

    for (list, named) in [
        ("random:0", "random:0"),
        ("banana", "generated-N"),
        ("generated-07", "generated-07"),
    ] {
        let out = acch(
            &[
                "eval",
                "--protocol",
                "robust",
                "--objects",
                list,
                "--n",
                "1",
            ],
            dir.path(),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{list} was taken");
        assert!(err.contains(named), "{list}: {err}");
    }
    let out = acch(
        &["eval", "--protocol", "table1", "--objects", "generated-11"],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--protocol robust"));
    // A protocol that writes no CSV says so rather than ignoring --errors.
    let out = acch(
        &[
            "eval",
            "--protocol",
            "table2",
            "--object",
            "fruitbox",
            "--errors",
            "x.csv",
        ],
        dir.path(),
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--errors"));
}

/// An over exposed frame: the single-image light search keeping the light
/// recognition scores best gets a development object's pose wrong in most
/// views (5 of 8 at 1.25x when measured), choosing the light whose indices
/// a training view explains best gets it right (0 of 8). Same scenes,
/// same chain otherwise, so the check can fail.
#[test]
fn over_exposed_the_light_chosen_by_the_pose_holds_where_recognitions_choice_fails() {
    use acch_capture::{Background, ViewSpec};
    use acch_eval::protocol::{self, fails};

    let (object, [mut by_recognition, mut by_pose], renderer) =
        single_image_chains("generated-3004", Background::A, 3004, |c| {
            c.effects = exposed(1.25)
        });
    by_recognition
        .stages_mut()
        .recognition
        .sharp_mut()
        .choose_light_by_recognition();
    let views = ViewSpec::Random { n: 8 }.views(acch_capture::DEFAULT_DISTANCE, 3004);
    let mut failed = [0usize; 2];
    for (i, v) in views.iter().enumerate() {
        let scene = renderer.render(v, acch_capture::frame_seed(3004, i));
        let frame = protocol::frame_of(&scene, i as u64, false, object.radius_m());
        let truth = (scene.truth.theta_deg as f32, scene.truth.phi_deg as f32);
        for (chain, failed) in [&mut by_recognition, &mut by_pose]
            .into_iter()
            .zip(&mut failed)
        {
            let out = chain.process(&frame, scene.image.as_raw());
            *failed += out
                .pose()
                .done()
                .is_none_or(|e| fails((e.theta_deg, e.phi_deg), truth))
                as usize;
        }
    }
    eprintln!(
        "failed of 8: recognition's light {}, the pose's {}",
        failed[0], failed[1]
    );
    assert!(failed[0] >= 3, "{failed:?}");
    assert!(failed[1] <= 1, "{failed:?}");
}

/// A development object seen from above (a bottle: its cap and shoulder,
/// a small disc) scores under the training light above recognition's
/// threshold but, at 0.8x exposure, under the right light below the 0.7
/// of the training score a relit detection had to reach: lost in every
/// view when measured. At [`acch_recognition::RELIT_SCORE_FRACTION`] it
/// is found, and the network accepts no estimate found so wrong. Same
/// scenes, same chain otherwise, so the check can fail. The network alone
/// rates here, as when the bar was changed: a cap seen from above has
/// views far away in φ matching within 1 %, and the rival rule rejects
/// them all (`a_far_view_matching_as_well_...` below), as the crest rule
/// does its broad crests.
#[test]
fn seen_from_above_under_another_exposure_a_small_object_is_found_relit() {
    use acch_capture::Background;

    const { assert!(acch_recognition::RELIT_SCORE_FRACTION < 0.7) };
    let (object, mut chains, renderer) =
        single_image_chains("generated-3005", Background::B, 3005, |c| {
            c.effects = exposed(0.8)
        });
    // The build before: relit from 0.7, found from the threshold (found
    // from below it, the cap is found faint under the training light and
    // estimated wrong under it: 5 of 12 accepted wrong with relit at 0.7
    // when measured; the default finds it relit first).
    let before = chains[0].stages_mut().recognition.sharp_mut();
    before.count_relit_from(0.7);
    before.find_from_margin(1.0);
    for chain in &mut chains {
        chain
            .stages_mut()
            .confidence
            .sharp_mut()
            .accept_rivals_to(1.0);
        chain
            .stages_mut()
            .confidence
            .sharp_mut()
            .reject_crests_from(f32::INFINITY);
    }
    // [old bar, default bar]: (found, accepted, accepted wrong, right)
    let (views, tally) = tally_views(&object, &mut chains, &renderer, "grid:86.5:30", 3005);
    eprintln!(
        "of {views} views (found, accepted, accepted wrong, right): bar 0.7 {:?}, default {:?}",
        tally[0], tally[1]
    );
    assert!(tally[0].0 <= views / 4, "{tally:?}");
    assert!(tally[1].1 >= views * 3 / 4, "{tally:?}");
    assert_eq!(tally[1].2, 0, "{tally:?}");
}

/// A development object (a bottle) seen from near above behind a bar over
/// 30 % of its width: its cap and shoulder, a small disc, half hidden,
/// score just under recognition's threshold (half the training score) and
/// were lost. Found from [`acch_recognition::MIN_FOUND_MARGIN`] of it they
/// are estimated right (12 of 12 when measured), and none is accepted:
/// an estimate found under the threshold never is
/// ([`acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN`]). Same scenes, the same chain
/// counting windows as found from the threshold beside it, so the check
/// can fail.
#[test]
fn behind_a_bar_a_view_from_above_is_found_under_the_threshold_and_not_accepted() {
    use acch_capture::Background;

    const { assert!(acch_recognition::MIN_FOUND_MARGIN < 1.0) };
    let (object, mut chains, renderer) =
        single_image_chains("generated-3005", Background::B, 3005, |c| c.occlusion = 0.3);
    chains[0]
        .stages_mut()
        .recognition
        .sharp_mut()
        .find_from_margin(1.0);
    // [from the threshold, default]: (found, accepted, accepted wrong, right)
    let (views, tally) = tally_views(&object, &mut chains, &renderer, "grid:86.5:30", 3005);
    eprintln!(
        "of {views} views (found, accepted, accepted wrong, right): from the threshold {:?}, default {:?}",
        tally[0], tally[1]
    );
    assert!(tally[1].3 >= tally[0].3 + views / 2, "{tally:?}");
    assert_eq!(tally[1].1, tally[0].1, "{tally:?}");
    assert_eq!(tally[1].2, 0, "{tally:?}");
}

/// A development object (a bottle whose cap's mark is too small to show)
/// seen from near above under JPEG at quality 60: views far from the truth
/// in azimuth match as well as the right one, and the network accepts
/// every estimate, some of them wrong (measured: 24 accepted, 5 wrong). A
/// far view matching within [`acch_confidence::MAX_RIVAL_RATIO`] of the
/// best rejects the estimate whatever the network says (measured: none
/// accepted). Same scenes, the same chain with every rival accepted beside
/// it, so the check can fail; neither rejects a broad crest (its cap
/// matches so too), so the rival rule is measured alone. (Until training revision 7 this was a printed
/// box, generated-3004, whose far views the colour layout now tells apart:
/// 24 accepted, none wrong, with every rival.)
#[test]
fn a_far_view_matching_as_well_rejects_an_estimate_the_network_accepts() {
    use acch_capture::{Background, Effects};

    let effects = Effects {
        jpeg_quality: 60,
        ..Default::default()
    };
    let (object, mut chains, renderer) =
        single_image_chains("generated-3007", Background::B, 3007, |c| {
            c.effects = effects
        });
    chains[0]
        .stages_mut()
        .confidence
        .sharp_mut()
        .accept_rivals_to(1.0);
    for chain in &mut chains {
        chain
            .stages_mut()
            .confidence
            .sharp_mut()
            .reject_crests_from(f32::INFINITY);
    }
    // [every rival, default rival bar]: (found, accepted, accepted wrong, right)
    let (views, tally) = tally_views(&object, &mut chains, &renderer, "grid:86:15", 3007);
    eprintln!(
        "of {views} views (found, accepted, accepted wrong, right): every rival {:?}, default {:?}",
        tally[0], tally[1]
    );
    assert!(tally[0].2 >= 3, "{tally:?}");
    assert_eq!(tally[1].2, 0, "{tally:?}");
}

/// Both `chains` over the views of `grid` (a view specification) rendered
/// by `renderer`, seeded by `seed`: the number of views and, per chain,
/// (found, accepted, accepted wrong, found right).
fn tally_views(
    object: &acch_capture::Object,
    chains: &mut [acch_pipeline::Chain; 2],
    renderer: &acch_capture::Renderer,
    grid: &str,
    seed: u64,
) -> (usize, [(usize, usize, usize, usize); 2]) {
    use acch_eval::protocol::{self, fails};

    let views = grid
        .parse::<acch_capture::ViewSpec>()
        .unwrap()
        .views(acch_capture::DEFAULT_DISTANCE, seed);
    let mut tally = [(0usize, 0usize, 0usize, 0usize); 2];
    for (i, v) in views.iter().enumerate() {
        let scene = renderer.render(v, acch_capture::frame_seed(seed, i));
        let frame = protocol::frame_of(&scene, i as u64, false, object.radius_m());
        let truth = (scene.truth.theta_deg as f32, scene.truth.phi_deg as f32);
        for (chain, t) in chains.iter_mut().zip(&mut tally) {
            let out = chain.process(&frame, scene.image.as_raw());
            let Some(e) = out.pose().done() else { continue };
            let wrong = fails((e.theta_deg, e.phi_deg), truth);
            t.0 += 1;
            t.3 += !wrong as usize;
            if out.rating().accepted() {
                t.1 += 1;
                t.2 += wrong as usize;
            }
        }
    }
    (views.len(), tally)
}

/// A camera whose only effect is `exposure`.
fn exposed(exposure: f32) -> acch_capture::Effects {
    acch_capture::Effects {
        exposure,
        ..Default::default()
    }
}

/// Two chains of development object `name`'s cached database searching
/// every light as single images do, and a renderer of it on `background`
/// (held-out table textures, the rest as `configure` sets it), seeded by
/// `seed`.
fn single_image_chains(
    name: &str,
    background: acch_capture::Background,
    seed: u64,
    configure: impl FnOnce(&mut acch_capture::SceneConfig),
) -> (
    std::sync::Arc<acch_capture::Object>,
    [acch_pipeline::Chain; 2],
    acch_capture::Renderer,
) {
    use acch_capture::{Object, Renderer, SceneConfig, TextureSet};
    use acch_pipeline::stages::SINGLE_IMAGE_LIGHT_SEARCH;

    let object = std::sync::Arc::new(Object::builtin(name).unwrap());
    let (db, _) = acch_train::cache::cached_database(&object, None).unwrap();
    let distance_m = db.train_distance_m as f64;
    let chain =
        || acch_eval::protocol::chain_at(&db, distance_m, SINGLE_IMAGE_LIGHT_SEARCH).unwrap();
    let mut config =
        SceneConfig::new(object.clone(), background).with_textures(TextureSet::HeldOut);
    configure(&mut config);
    (object, [chain(), chain()], Renderer::new(config, seed))
}
