//! A robust-protocol run against R1's bounds: for each family, the
//! failure rate, the share of the accepted that is wrong and the share not
//! accepted, against the level, each with its bound as a dashed line
//! (failures at most 10 %, wrong among the accepted at most 2 %, accepted
//! at least 70 %: not accepted at most 30 %). Drawn from the `--json` of
//! `acch eval --protocol robust`, so a stored run is plotted without
//! running it again; the clean row's rates are printed.
//!
//! `cargo run --release -p acch-eval --example robust_bounds_plot -- RUN.json OUT.png "TITLE"`

use acch_eval::robust::FAMILIES;
use acch_viz::plot::{Panel, Series, panels};
use serde_json::Value;

/// R1's bounds on each plotted rate.
const BOUNDS: [(&str, f64); 3] = [
    ("failures (≤ 10 %)", 0.10),
    ("wrong among accepted (≤ 2 %)", 0.02),
    ("not accepted (≤ 30 %)", 0.30),
];

/// One row's rate for the series at `k` of [`BOUNDS`].
fn rate(row: &Value, k: usize) -> Option<f64> {
    let get = |key: &str| row[key].as_f64();
    match k {
        0 => get("failure_rate"),
        1 => get("acc_failure_rate"),
        _ => get("accepted_rate").map(|a| 1.0 - a),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: robust_bounds_plot RUN.json OUT.png TITLE";
    let (json, out, title) = (
        args.next().ok_or(usage)?,
        args.next().ok_or(usage)?,
        args.next().ok_or(usage)?,
    );
    let text = std::fs::read_to_string(&json).map_err(|e| format!("{json}: {e}"))?;
    let run: Value = serde_json::from_str(&text).map_err(|e| format!("{json}: {e}"))?;
    let rows = run["rows"]
        .as_array()
        .ok_or_else(|| format!("{json}: no \"rows\": not a robust-protocol --json"))?;
    // The rows with the light search, as the protocol's own plot takes.
    let searched = |r: &&Value| r["light_search"].as_bool() != Some(false);
    let clean = rows
        .iter()
        .filter(searched)
        .find(|r| r["family"] == "clean");
    let mut drawn = Vec::new();
    for family in FAMILIES.iter() {
        let of: Vec<&Value> = rows
            .iter()
            .filter(searched)
            .filter(|r| r["family"] == family.name)
            .collect();
        if of.is_empty() {
            continue;
        }
        let series = (0..BOUNDS.len())
            .map(|k| {
                let mut points: Vec<(f64, f64)> = of
                    .iter()
                    .filter_map(|r| Some((r["level"].as_f64()?, rate(r, k)?)))
                    .collect();
                points.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    name: BOUNDS[k].0.into(),
                    points,
                    reference: Some(BOUNDS[k].1),
                }
            })
            .collect();
        drawn.push(Panel {
            title: format!("{} ({})", family.name.replace('_', " "), family.unit),
            series,
        });
    }
    if drawn.is_empty() {
        return Err(format!("{json}: no family of the protocol in its rows").into());
    }
    if let Some(c) = clean {
        let rates: Vec<String> = (0..BOUNDS.len())
            .filter_map(|k| Some(format!("{:.3}", rate(c, k)?)))
            .collect();
        println!("clean: {}", rates.join(" / "));
    }
    panels(
        std::path::Path::new(&out),
        &title,
        "share of images",
        &drawn,
    )?;
    println!("wrote {out}: {} families", drawn.len());
    Ok(())
}
