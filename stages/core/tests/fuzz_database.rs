//! Fuzzes the view-database loader with a fixed budget and a fixed seed
//! (CI time is bounded and a finding reproduces): arbitrary bytes, and a
//! valid database with its bytes flipped, cut or extended, with the
//! checksum recomputed so the payload parser itself is exercised. Every
//! input must give a database or a typed error naming the file, never a
//! panic or an allocation the file cannot back.

use acch_core::{ColourSpace, DbError, HistogramParams, Palette, View, ViewDatabase};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use std::path::Path;

const HEADER_LEN: usize = 24;

fn config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0xACC4_0009),
        ..Config::default()
    }
}

fn sample() -> Vec<u8> {
    let palette = Palette::from_centres(
        ColourSpace::Lab,
        vec![[50.0, 10.0, -10.0], [70.0, -20.0, 30.0]],
        12.5,
    )
    .unwrap();
    let params = HistogramParams {
        colours: 2,
        bins: 3,
        ..HistogramParams::default()
    };
    let mut db = ViewDatabase::new("thing", palette, params, 5.0);
    let n = params.len();
    for (t, p) in [(45.0, 10.0), (90.0, 350.0)] {
        db.push_view(
            View {
                theta_deg: t,
                phi_deg: p,
                size_px: 100.0,
                centre_offset_px: [0.0; 2],
            },
            &vec![1.0 / n as f32; n],
        );
    }
    db.sections.insert("recognition".into(), vec![7; 40]);
    db.sections.insert("confidence".into(), vec![1, 2, 3]);
    db.to_bytes()
}

/// Rewrites the header's length and checksum for the payload as it is now.
fn reseal(bytes: &mut [u8]) {
    if bytes.len() < HEADER_LEN {
        return;
    }
    let len = (bytes.len() - HEADER_LEN) as u64;
    bytes[12..20].copy_from_slice(&len.to_le_bytes());
    let crc = crc32fast::hash(&bytes[HEADER_LEN..]);
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
}

fn check(bytes: &[u8]) {
    let path = Path::new("fuzz.acchdb");
    match ViewDatabase::from_bytes(bytes, path) {
        Ok(db) => {
            // Whatever loads must be usable: consistent sizes, a response.
            let n = db.views().len();
            assert_eq!(db.histograms().len(), n * db.params.len());
            let mut out = vec![0.0; n];
            if n > 0 {
                db.response_into(db.histogram(0), &mut out);
            }
            // And it survives a round trip.
            let again = ViewDatabase::from_bytes(&db.to_bytes(), path).unwrap();
            assert_eq!(again, db);
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.contains("fuzz.acchdb"),
                "error does not name the file: {msg}"
            );
            assert!(!matches!(e, DbError::Io { .. }));
        }
    }
}

#[test]
fn the_sample_loads() {
    let bytes = sample();
    assert!(ViewDatabase::from_bytes(&bytes, Path::new("x")).is_ok());
}

proptest! {
    #![proptest_config(config(4000))]

    #[test]
    fn arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        check(&bytes);
    }
}

// Inputs that get as far as the palette cost a palette build each (tens of
// ms): a smaller budget keeps each of these to a few seconds.
proptest! {
    #![proptest_config(config(160))]

    #[test]
    fn arbitrary_payload_behind_a_valid_header(payload in proptest::collection::vec(any::<u8>(), 0..400)) {
        let mut bytes = sample()[..HEADER_LEN].to_vec();
        bytes.extend_from_slice(&payload);
        reseal(&mut bytes);
        check(&bytes);
    }

    #[test]
    fn flipped_bytes_resealed(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        reseal_it in any::<bool>(),
    ) {
        let mut bytes = sample();
        for (i, v) in flips {
            let i = i.index(bytes.len());
            bytes[i] = v;
        }
        if reseal_it {
            reseal(&mut bytes);
        }
        check(&bytes);
    }

    #[test]
    fn cut_or_extended(cut in any::<prop::sample::Index>(), extra in proptest::collection::vec(any::<u8>(), 0..16), reseal_it in any::<bool>()) {
        let mut bytes = sample();
        let keep = cut.index(bytes.len() + 1);
        bytes.truncate(keep);
        bytes.extend_from_slice(&extra);
        if reseal_it {
            reseal(&mut bytes);
        }
        check(&bytes);
    }

    #[test]
    fn large_counts_are_refused_without_allocating(field in 0usize..64, value in any::<u32>()) {
        // Overwrite any 4 aligned bytes of the payload with a (possibly
        // huge) count and reseal: the loader must not trust it.
        let mut bytes = sample();
        let at = HEADER_LEN + (field * 4).min(bytes.len() - HEADER_LEN - 4);
        bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
        reseal(&mut bytes);
        check(&bytes);
    }
}
