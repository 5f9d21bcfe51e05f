//! Where do the clean tables' frames measure? The frame quality
//! (`acch_core::QualityMeter`) of every scene table 2 renders (the object
//! on A, B and C; apart, the same scenes with the object out of view) and
//! of every test view table 1 renders (plain table), for fruitbox, can,
//! tricolor and the duck at seeds 3 and 7: the largest noise and
//! blockiness and the smallest sharpness, and how many frames a per-frame
//! choice of the smoothed database would take
//! ([`acch_core::FrameQuality::needs_smoothing`], bars chosen on the
//! development seed), and the time a measure takes, whole and as
//! recognition takes it for the choice.
//!
//! `cargo run --release -p acch-eval --example frame_quality -- DUCK.obj`

use acch_capture::{DEFAULT_DISTANCE, Object, TextureSet, ViewSpec};
use acch_core::{FrameQuality, QualityMeter};
use acch_eval::protocol;
use std::sync::Arc;

/// Table 2's camera offset that takes the object out of view, pixels.
const OUT_OF_VIEW_PX: f64 = 4000.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let duck = std::env::args()
        .nth(1)
        .ok_or("usage: frame_quality DUCK.obj")?;
    let mut meter = QualityMeter::new();
    let (mut measured, mut spent) = (0u32, std::time::Duration::ZERO);
    // Recognition's measure for the choice: noise and blocking alone.
    let mut spent_choosing = std::time::Duration::ZERO;
    println!("object seed table frames max_noise max_blockiness min_sharpness smoothed");
    for name in ["fruitbox", "can", "tricolor", "duck"] {
        let object = Arc::new(if name == "duck" {
            Object::load_mesh(&duck, Default::default())?
        } else {
            Object::builtin(name)?
        });
        for seed in [3u64, 7] {
            let views = ViewSpec::Random { n: 50 }.views(DEFAULT_DISTANCE, seed);
            let (mut table2, mut empties) = (Vec::new(), Vec::new());
            for (bg, background) in protocol::backgrounds() {
                for (scene, empty) in protocol::render_scenes(
                    &object,
                    (background, TextureSet::HeldOut),
                    &views,
                    seed,
                    bg,
                    Some(OUT_OF_VIEW_PX),
                ) {
                    table2.push(scene);
                    empties.extend(empty);
                }
            }
            let plain =
                protocol::renderer(object.clone(), "plain".parse()?, TextureSet::Training, seed);
            let table1 = protocol::render_views(&plain, &views, seed, "table 1");
            for (table, frames) in [
                ("table2", &table2),
                ("table2-empty", &empties),
                ("table1", &table1),
            ] {
                let q: Vec<FrameQuality> = frames
                    .iter()
                    .map(|r| {
                        let (w, h) = r.image.dimensions();
                        let start = std::time::Instant::now();
                        let q = meter.measure(r.image.as_raw(), w, h);
                        spent += start.elapsed();
                        measured += 1;
                        let start = std::time::Instant::now();
                        let choice = meter.noise_and_blocking(r.image.as_raw(), w, h);
                        spent_choosing += start.elapsed();
                        assert_eq!(choice.needs_smoothing(), q.needs_smoothing());
                        q
                    })
                    .collect();
                let smoothed = q.iter().filter(|q| q.needs_smoothing()).count();
                println!(
                    "{name} {seed} {table} {} {:.3} {:.3} {:.3} {smoothed}",
                    q.len(),
                    q.iter().map(|q| q.noise_sigma).fold(0.0, f32::max),
                    q.iter().map(|q| q.blockiness).fold(0.0, f32::max),
                    q.iter()
                        .map(|q| q.sharpness)
                        .filter(|s| !s.is_nan())
                        .fold(f32::INFINITY, f32::min),
                );
            }
        }
    }
    println!(
        "measuring a frame took {:.2} ms on average over {measured} frames (one thread)",
        spent.as_secs_f64() * 1e3 / f64::from(measured.max(1))
    );
    println!(
        "its noise and blocking alone, recognition's choice (smoothing = \"auto\"): {:.2} ms",
        spent_choosing.as_secs_f64() * 1e3 / f64::from(measured.max(1))
    );
    Ok(())
}
