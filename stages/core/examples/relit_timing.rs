//! How long relighting a palette takes (one lookup table per light the
//! recognition stage tries for the first time): 40 colours, as trained.

use acch_core::{ColourSpace, Palette};
use std::time::Instant;

fn main() {
    let centres: Vec<[f32; 3]> = (0..40)
        .map(|i| {
            let t = i as f32 / 40.0;
            ColourSpace::Lab.convert([
                (255.0 * t) as u8,
                (255.0 * (1.0 - t)) as u8,
                (37 * i % 256) as u8,
            ])
        })
        .collect();
    let palette = Palette::from_centres(ColourSpace::Lab, centres, 12.0).expect("palette");
    let mut times = Vec::new();
    for k in 0..15 {
        let gain = 0.25 * 2f32.powf(k as f32 / 4.0);
        let start = Instant::now();
        let relit = palette
            .relit([gain * 1.1, gain, gain * 0.8])
            .expect("finite gains");
        times.push(start.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(relit);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "relit palette (40 colours, 64^3 table): median {:.1} ms, max {:.1} ms over {} lights",
        times[times.len() / 2],
        times[times.len() - 1],
        times.len()
    );
    for (kelvin, gains) in [3000.0, 3500.0, 4250.0, 5750.0, 6500.0, 7500.0]
        .map(|k| (k, acch_core::light::colour_temperature_gains(k)))
    {
        println!(
            "{kelvin} K: linear gains R {:.3} G {:.3} B {:.3}",
            gains[0], gains[1], gains[2]
        );
    }
}
