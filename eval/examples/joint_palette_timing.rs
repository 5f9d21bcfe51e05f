//! What does one quantisation pass shared by several objects save? The
//! frame of a four-object scene quantised with each object's palette in a
//! pass of its own (what a chain alone does), against one
//! [`JointPalette`] pass labelling the frame and a table lookup per object
//! (what `MultiChain` does), raw and with the palettes smoothing frames
//! (`--smoothing binomial`: the joint pass smooths once). Both give the
//! same indices (checked). Trains the objects' databases on first use.
//!
//! `cargo run --release -p acch-eval --example joint_palette_timing`

use acch_capture::{Background, MultiRenderer, MultiScene, Object};
use acch_core::{JointPalette, Palette, Smoothing};
use std::sync::Arc;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let names = ["fruitbox", "can", "generated-3000", "generated-3001"];
    let objects: Vec<Arc<Object>> = names
        .iter()
        .map(|n| Object::builtin(n).map(Arc::new))
        .collect::<Result<_, _>>()?;
    let mut trained: Vec<Palette> = Vec::new();
    for o in &objects {
        trained.push(acch_eval::train::cached_database(o, None)?.0.palette);
    }
    let renderer = MultiRenderer::new(MultiScene::new(objects, Background::B), 3)?;
    let frame = renderer.render(60.0, 30.0, 1)?.image;
    let rgb = frame.as_raw();
    let (width, height) = frame.dimensions();
    let n = rgb.len() / 3;
    for smoothing in [Smoothing::Off, Smoothing::Binomial] {
        let palettes: Vec<Palette> = trained
            .iter()
            .map(|p| p.clone().with_smoothing(smoothing))
            .collect();
        for k in 1..=palettes.len() {
            let ps: Vec<&Palette> = palettes[..k].iter().collect();
            let joint = JointPalette::new(&ps)?;
            let mut own = vec![vec![0u8; n]; k];
            let mut shared = vec![vec![0u8; n]; k];
            let mut labels = vec![0u16; n];
            let (mut t_own, mut t_shared) = (Vec::new(), Vec::new());
            for _ in 0..300 {
                let t = Instant::now();
                for (p, out) in ps.iter().zip(own.iter_mut()) {
                    p.quantise_into_slice(rgb, width, height, out);
                }
                t_own.push(t.elapsed().as_secs_f64() * 1e3);
                let t = Instant::now();
                joint.label(rgb, width, height, &mut labels);
                for (i, out) in shared.iter_mut().enumerate() {
                    joint.indices(i, &labels, out);
                }
                t_shared.push(t.elapsed().as_secs_f64() * 1e3);
            }
            assert_eq!(own, shared, "both ways give the same indices");
            println!(
                "{k} objects ({}), smoothing {smoothing:?}: a pass each {:.3} ms, one joint pass \
                 ({} joint colours) {:.3} ms (medians of 300, {width}x{height})",
                names[..k].join(", "),
                median(t_own),
                joint.colours(),
                median(t_shared),
            );
        }
    }
    Ok(())
}
