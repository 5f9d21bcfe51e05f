//! `acch run --in-process --objects fruitbox,can`: one pipeline over a
//! simulated table holding both; an independent subscriber per object
//! (Python `eclipse-zenoh`, tests/pipeline_subscriber.py) receives every
//! frame's result on that object's own key and checks each verdict; the
//! results file is split per object; an object not in view is not
//! reported found in most frames; without `--in-process` several objects
//! still run, in one process, and the run says so.

mod common;

use common::{acch, free_ports, ok, zenoh_subscriber};
use serde_json::Value;

/// The two tests' pipelines one at a time: two pipelines on 2 cores stall
/// each other, and the first counts its drops (it asserts none).
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn rows(path: &std::path::Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn each_object_is_published_on_its_own_key_with_its_own_results() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let frames = 40u64;
    let dir = tempfile::tempdir().unwrap();
    let [p_fruitbox, p_can, p_run] = free_ports();
    let (_s1, mut fruitbox_report) = zenoh_subscriber("fruitbox", p_fruitbox, frames);
    let (_s2, mut can_report) = zenoh_subscriber("can", p_can, frames);
    let config = dir.path().join("p.toml");
    std::fs::write(
        &config,
        format!(
            "[zenoh]\nlisten = [\"tcp/127.0.0.1:{p_run}\"]\nconnect = [\"tcp/127.0.0.1:{p_fruitbox}\", \"tcp/127.0.0.1:{p_can}\"]\n"
        ),
    )
    .unwrap();
    let (results, json) = (dir.path().join("r.jsonl"), dir.path().join("s.json"));
    let run = [
        "run",
        "--in-process",
        "--objects",
        "fruitbox,can,tricolor",
        // The scene shows the first two; tricolor is known, not in view.
        "--objects-in-view",
        "2",
        "--frames",
        &frames.to_string(),
        "--fps",
        "15",
        "--config",
        config.to_str().unwrap(),
        "--results",
        results.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ];
    ok(&acch(&run, dir.path()));
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let objects = summary["objects"].as_array().expect("per-object outcomes");
    assert_eq!(objects.len(), 3, "{summary}");
    let found = |name: &str| {
        objects
            .iter()
            .find(|o| o["object"] == name)
            .unwrap_or_else(|| panic!("no {name} in {summary}"))["found"]
            .as_u64()
            .unwrap()
    };
    eprintln!(
        "found: fruitbox {}, can {}, tricolor {}",
        found("fruitbox"),
        found("can"),
        found("tricolor")
    );
    assert!(found("fruitbox") >= frames * 3 / 4, "{summary}");
    assert!(found("can") >= frames * 3 / 4, "{summary}");
    assert!(found("tricolor") <= frames / 4, "{summary}");
    assert_eq!(summary["dropped"], 0, "{summary}");
    // Capture's counters, then every object's five stages', each counting
    // every frame.
    let counters = summary["stage_counters"].as_array().unwrap();
    assert_eq!(counters.len(), 1 + 3 * 5, "{summary}");
    for name in ["fruitbox", "can", "tricolor"] {
        let recognition = counters
            .iter()
            .find(|c| c["object"] == name && c["stage"] == "recognition")
            .unwrap_or_else(|| panic!("no recognition counters of {name}: {summary}"));
        assert_eq!(recognition["processed"], frames, "{recognition}");
    }
    for (name, report) in [("fruitbox", &mut fruitbox_report), ("can", &mut can_report)] {
        let file = rows(&dir.path().join(format!("r-{name}.jsonl")));
        assert_eq!(file.len() as u64, frames, "{name}");
        assert!(
            file.iter().all(|r| r["object"] == name),
            "{name}: {}",
            file[0]
        );
        let r: Value = serde_json::from_str(&report.next().unwrap().unwrap()).unwrap();
        eprintln!("{name} subscriber: {r}");
        assert_eq!(r["results"], frames, "{name}: {r}");
        assert_eq!(r["bad_verdicts"], serde_json::json!([]), "{name}: {r}");
        assert_eq!(
            r["seeds_without_acceptance"],
            serde_json::json!([]),
            "{name}: {r}"
        );
        let accepted = file.iter().filter(|r| r["accepted"] == true).count() as u64;
        assert_eq!(r["seeds"].as_u64().unwrap(), accepted, "{name}: {r}");
    }
    assert!(!results.exists(), "one file per object, none for all");
}

#[test]
fn several_objects_run_in_one_process_without_being_asked_and_say_so() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let config = common::loopback_config(dir.path());
    let json = dir.path().join("s.json");
    let args = [
        "run",
        "--objects",
        "fruitbox,can",
        "--frames",
        "5",
        "--json",
        json.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
    ];
    let out = acch(&args, dir.path());
    ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("lanes on threads of one process"), "{err}");
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(summary["mode"], "in-process", "{summary}");
    let objects: Vec<&str> = summary["objects"]
        .as_array()
        .expect("per-object outcomes")
        .iter()
        .map(|o| o["object"].as_str().unwrap())
        .collect();
    assert_eq!(objects, ["fruitbox", "can"], "{summary}");
}
