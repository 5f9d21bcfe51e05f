//! Benchmarks of the ACCH hot paths: histogram extraction over 64, 128 and
//! 256 px square ROIs (default stride 2, and stride 1 which visits every
//! pixel like scikit-image's `graycomatrix`), histogram intersection, the
//! response of a 216-view database, the colour layout (measured over a
//! 128 px ROI, compared with 216 views'), the colour map (measured over a
//! 128 px ROI in 20 cells across, placed on the 11 views a map rival
//! weighs on a 10° grid), and the frame quality measure a run with
//! `smoothing = "auto"` takes of every 640x480 frame.
//!
//! `cargo bench -p acch-core --bench acch` runs them (see bench/README.md).
//! With `ACCH_BENCH_DUMP=FILE` set, the bench instead writes the test image's
//! CRC-32, the default offsets and the stride-1 128 px histogram counts as
//! JSON, which `bench/graycomatrix.py --rust-dump FILE` checks against
//! `graycomatrix`, and exits.

use acch_core::{
    ColourMap, ColourSpace, HistogramExtractor, HistogramParams, IndexImage, LAYOUT_FIELDS,
    Palette, PlacedQuery, QualityMeter, Rect, View, ViewDatabase, intersection, layout_distance,
    layout_into,
};
use criterion::{BenchmarkId, Criterion};
use std::hint::black_box;
use std::time::Duration;

/// Side of the test image; every ROI is its top-left `n` x `n` corner.
const SIDE: u32 = 256;
/// ROI sides benchmarked.
const ROIS: [u32; 3] = [64, 128, 256];
/// Palette size (the default C).
const COLOURS: u32 = 40;
/// CRC-32 of the 256x256 test image; bench/graycomatrix.py asserts the same.
const IMAGE_CRC32: u32 = 0xBDC0_63DA;

/// Palette index of pixel (x, y): 8x8 blocks of a colour that varies from
/// block to block, with a quarter of the pixels replaced by hashed noise.
/// Integer-only so that bench/graycomatrix.py reproduces it exactly.
fn texture(x: u32, y: u32) -> u8 {
    let mut h = x.wrapping_mul(0x9E37_79B1) ^ y.wrapping_mul(0x85EB_CA77);
    h ^= h >> 15;
    h = h.wrapping_mul(0xC2B2_AE3D);
    h ^= h >> 13;
    let (bx, by) = (x / 8, y / 8);
    let block = (bx * 7 + by * 13 + bx * by) % COLOURS;
    if h.is_multiple_of(4) {
        ((h >> 8) % COLOURS) as u8
    } else {
        block as u8
    }
}

fn test_image() -> IndexImage {
    let data = (0..SIDE * SIDE)
        .map(|i| texture(i % SIDE, i / SIDE))
        .collect();
    let image = IndexImage::new(SIDE, SIDE, data);
    let crc = crc32fast::hash(&image.data);
    assert_eq!(crc, IMAGE_CRC32, "test image changed: CRC-32 {crc:08x}");
    image
}

fn roi(n: u32) -> Rect {
    Rect {
        x: 0,
        y: 0,
        width: n,
        height: n,
    }
}

fn stride1() -> HistogramParams {
    HistogramParams {
        stride: 1,
        ..HistogramParams::default()
    }
}

/// Writes the JSON that bench/graycomatrix.py --rust-dump checks.
fn dump(path: &str, image: &IndexImage, mask: &[u8]) {
    let params = stride1();
    let mut e = HistogramExtractor::new(params).expect("valid params");
    let mut h = vec![0.0; params.len()];
    let pairs = e.extract(image, Some(mask), roi(128), 1.0, &mut h);
    let counts: Vec<String> = h
        .iter()
        .map(|&v| format!("{}", (v as f64 * pairs as f64).round() as u64))
        .collect();
    let offsets: Vec<String> = params
        .offsets(1.0)
        .iter()
        .map(|&(dx, dy, d)| format!("[{dx},{dy},{d}]"))
        .collect();
    let json = format!(
        "{{\"image_crc32\":{},\"side\":{SIDE},\"roi\":128,\"colours\":{},\"bins\":{},\"stride\":1,\
         \"pairs\":{pairs},\"offsets\":[{}],\"counts\":[{}]}}\n",
        crc32fast::hash(&image.data),
        params.colours,
        params.bins,
        offsets.join(","),
        counts.join(",")
    );
    std::fs::write(path, json).unwrap_or_else(|e| panic!("{path}: {e}"));
    eprintln!("wrote {path}");
}

fn bench_extract(c: &mut Criterion, image: &IndexImage, mask: &[u8]) {
    let mut group = c.benchmark_group("acch_extract");
    for (name, params) in [
        ("stride2", HistogramParams::default()),
        ("stride1", stride1()),
    ] {
        let mut e = HistogramExtractor::new(params).expect("valid params");
        let mut out = vec![0.0; params.len()];
        for n in ROIS {
            group.bench_with_input(BenchmarkId::new(name, n), &n, |b, &n| {
                b.iter(|| e.extract(image, Some(mask), black_box(roi(n)), 1.0, &mut out))
            });
        }
    }
    group.finish();
}

/// 216 histograms of 128 px ROIs at different places of the test image.
fn view_histograms(image: &IndexImage, mask: &[u8]) -> Vec<Vec<f32>> {
    let params = HistogramParams::default();
    let mut e = HistogramExtractor::new(params).expect("valid params");
    (0..216u32)
        .map(|i| {
            let mut h = vec![0.0; params.len()];
            let r = Rect {
                x: i * 7 % 128,
                y: i * 13 % 128,
                width: 128,
                height: 128,
            };
            e.extract(image, Some(mask), r, 1.0, &mut h);
            h
        })
        .collect()
}

fn bench_matching(c: &mut Criterion, image: &IndexImage, mask: &[u8]) {
    let views = view_histograms(image, mask);
    let params = HistogramParams::default();
    let (query, other) = (&views[0], &views[101]);
    c.bench_function(&format!("intersection/{}", params.len()), |b| {
        b.iter(|| intersection(black_box(query), black_box(other)))
    });

    let centres: Vec<[f32; 3]> = (0..COLOURS)
        .map(|i| {
            [
                (i % 4) as f32 / 3.0,
                (i / 4 % 5) as f32 / 4.0,
                (i / 20) as f32,
            ]
        })
        .collect();
    let palette =
        Palette::from_centres(ColourSpace::Rgb, centres, f32::INFINITY).expect("valid palette");
    let mut db = ViewDatabase::new("bench", palette, params, 3.0);
    for (i, h) in views.iter().enumerate() {
        let view = View {
            theta_deg: (i / 36) as f32 * 15.0,
            phi_deg: (i % 36) as f32 * 10.0,
            size_px: 128.0,
            centre_offset_px: [0.0; 2],
        };
        db.push_view(view, h);
    }
    let mut response = vec![0.0; db.views().len()];
    c.bench_function(&format!("response_into/{}", db.views().len()), |b| {
        b.iter(|| db.response_into(black_box(query), &mut response))
    });
}

/// What the colour layout adds to an estimate: the query's layout over a
/// 128 px ROI, and its distance to every view's of a 216-view database.
fn bench_layout(c: &mut Criterion, image: &IndexImage, mask: &[u8]) {
    let per_view = COLOURS as usize * LAYOUT_FIELDS;
    let mut query = vec![0.0; per_view];
    c.bench_function("layout/measure/128", |b| {
        b.iter(|| layout_into(black_box(image), Some(mask), roi(128), &mut query))
    });
    // Views: the layouts of 216 ROIs across the image.
    let views: Vec<f32> = (0..216u32)
        .flat_map(|i| {
            let mut l = vec![0.0; per_view];
            let r = Rect {
                x: i % 12 * 10,
                y: i / 12 * 7,
                width: 128,
                height: 128,
            };
            layout_into(image, Some(mask), r, &mut l);
            l
        })
        .collect();
    c.bench_function("layout/distance/216", |b| {
        b.iter(|| {
            views
                .chunks_exact(per_view)
                .map(|v| layout_distance(black_box(&query), v))
                .sum::<f32>()
        })
    });
}

fn bench_colour_map(c: &mut Criterion, image: &IndexImage, mask: &[u8]) {
    let cell_px = 128.0 / 20.0;
    let mut query = PlacedQuery::default();
    c.bench_function("colour_map/measure/128", |b| {
        b.iter(|| {
            query.measure(
                black_box(image),
                Some(mask),
                roi(128),
                COLOURS as usize,
                cell_px,
                0.0,
            )
        })
    });
    // The estimate's view and the 10 views 20-60° either side of it.
    let views: Vec<ColourMap> = (0..11u32)
        .map(|i| {
            let r = Rect {
                x: i * 10,
                y: i * 7,
                width: 128,
                height: 128,
            };
            ColourMap::measure(image, Some(mask), r, COLOURS as usize, cell_px, 0.0)
                .expect("the test image holds every colour")
        })
        .collect();
    c.bench_function("colour_map/held/11", |b| {
        b.iter(|| {
            views
                .iter()
                .map(|v| black_box(&mut query).share_held_by(v, 3))
                .sum::<f32>()
        })
    });
}

/// A 640x480 RGB frame: 8x8 blocks of a colour that varies from block to
/// block (their edges off the JPEG grid), with a quarter of the pixels
/// hashed noise.
fn rgb_frame() -> (Vec<u8>, u32, u32) {
    let (w, h) = (640u32, 480u32);
    let mut rgb = Vec::with_capacity(3 * (w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            // Blocks offset by 3 px: their edges off the JPEG grid, where
            // only the noise makes steps.
            let i = texture(x + 3, y + 3) as u32;
            for c in 0..3u32 {
                rgb.push(((i * (37 + 11 * c)) % 256) as u8);
            }
        }
    }
    (rgb, w, h)
}

fn bench_quality(c: &mut Criterion) {
    let (rgb, w, h) = rgb_frame();
    let mut meter = QualityMeter::new();
    c.bench_function("quality/noise_and_blocking/640x480", |b| {
        b.iter(|| meter.noise_and_blocking(black_box(&rgb), w, h))
    });
    c.bench_function("quality/measure/640x480", |b| {
        b.iter(|| meter.measure(black_box(&rgb), w, h))
    });
}

fn main() {
    let image = test_image();
    let mask = vec![1u8; image.data.len()];
    if let Ok(path) = std::env::var("ACCH_BENCH_DUMP") {
        dump(&path, &image, &mask);
        return;
    }
    let mut c = Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30)
        .configure_from_args();
    bench_extract(&mut c, &image, &mask);
    bench_matching(&mut c, &image, &mask);
    bench_layout(&mut c, &image, &mask);
    bench_colour_map(&mut c, &image, &mask);
    bench_quality(&mut c);
    c.final_summary();
}
