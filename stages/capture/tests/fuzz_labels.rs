//! Fuzzes the labels.csv parser with a fixed budget and a fixed seed:
//! arbitrary text, and valid files with fields replaced by arbitrary
//! strings. Every input must give rows within the documented ranges or an
//! error naming the file and a line, never a panic.

use acch_capture::labels::parse_labels;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use std::path::Path;

fn config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0xACC4_0009),
        ..Config::default()
    }
}

const HEADER: &str = "file,theta_deg,phi_deg,distance_m,bbox_x,bbox_y,bbox_w,bbox_h,mask";

fn check(text: &str) {
    match parse_labels(text, Path::new("dir/labels.csv")) {
        Ok(rows) => {
            for r in rows {
                assert!(!r.file.is_empty());
                assert!((0.0..=90.0).contains(&r.theta_deg), "{r:?}");
                assert!(
                    r.phi_deg.is_finite() && (0.0..360.0).contains(&r.phi_deg),
                    "{r:?}"
                );
                assert!(r.distance_m.is_finite() && r.distance_m > 0.0, "{r:?}");
                if let Some(b) = r.bbox {
                    assert!(b.width > 0 && b.height > 0);
                }
            }
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("dir/labels.csv"),
                "error does not name the file: {msg}"
            );
        }
    }
}

/// Field values: numbers of every kind, quotes, commas, empties.
fn field() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| v.to_string()),
        any::<i64>().prop_map(|v| v.to_string()),
        Just(String::new()),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-0".to_string()),
        "[a-z0-9_./\"', ]{0,12}",
        "\\PC{0,8}",
    ]
}

proptest! {
    #![proptest_config(config(10000))]

    #[test]
    fn arbitrary_text(text in "\\PC{0,200}") {
        check(&text);
    }

    #[test]
    fn arbitrary_text_after_the_header(body in "[a-z0-9.,\"\n\r -]{0,200}") {
        check(&format!("{HEADER}\n{body}"));
    }

    #[test]
    fn valid_rows_with_arbitrary_fields(rows in proptest::collection::vec(proptest::collection::vec(field(), 9), 1..5)) {
        let mut text = format!("\u{feff}{HEADER}\n");
        for r in rows {
            text.push_str(&r.join(","));
            text.push('\n');
        }
        check(&text);
    }

    #[test]
    fn shuffled_or_missing_columns(cols in proptest::sample::subsequence(HEADER.split(',').collect::<Vec<_>>(), 0..=9), values in proptest::collection::vec(field(), 9)) {
        let header = cols.join(",");
        let row = values[..cols.len()].join(",");
        check(&format!("{header}\n{row}\n"));
    }
}
