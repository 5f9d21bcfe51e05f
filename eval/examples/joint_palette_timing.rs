//! Would one quantisation pass shared by several objects save time? The
//! frame of a four-object scene quantised with each object's palette in a
//! pass of its own (what the lanes do), against one pass through a joint
//! table (every RGB cell's tuple of the objects' indices, numbered) and a
//! small table per object from that number to its index. Both give the
//! same indices (checked). Trains the objects' databases on first use.
//!
//! `cargo run --release -p acch-eval --example joint_palette_timing`

use acch_capture::{Background, MultiRenderer, MultiScene, Object};
use acch_core::Palette;
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

/// The palettes' lookup tables: 6 bits a channel.
const SIDE: usize = 64;

fn cell(px: &[u8]) -> usize {
    ((px[0] as usize >> 2) * SIDE + (px[1] as usize >> 2)) * SIDE + (px[2] as usize >> 2)
}

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
    let mut palettes: Vec<Palette> = Vec::new();
    for o in &objects {
        palettes.push(acch_eval::train::cached_database(o, None)?.0.palette);
    }
    let renderer = MultiRenderer::new(MultiScene::new(objects, Background::B), 3)?;
    let frame = renderer.render(60.0, 30.0, 1)?.image;
    let rgb = frame.as_raw();
    let (width, height) = frame.dimensions();
    let n = rgb.len() / 3;
    for k in 1..=palettes.len() {
        let ps = &palettes[..k];
        // The joint table: each cell's tuple of indices, numbered.
        let mut joint = vec![0u16; SIDE * SIDE * SIDE];
        let mut number: HashMap<Vec<u8>, u16> = HashMap::new();
        let mut per_object: Vec<Vec<u8>> = vec![Vec::new(); k];
        for (c, j) in joint.iter_mut().enumerate() {
            let px = [
                (c / (SIDE * SIDE)) << 2,
                (c / SIDE % SIDE) << 2,
                (c % SIDE) << 2,
            ]
            .map(|v| v as u8);
            let tuple: Vec<u8> = ps.iter().map(|p| p.index(px)).collect();
            let next = u16::try_from(number.len())?;
            *j = *number.entry(tuple.clone()).or_insert_with(|| {
                for (t, &i) in per_object.iter_mut().zip(&tuple) {
                    t.push(i);
                }
                next
            });
        }
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
            for (l, px) in labels.iter_mut().zip(rgb.chunks_exact(3)) {
                *l = joint[cell(px)];
            }
            for (table, out) in per_object.iter().zip(shared.iter_mut()) {
                for (o, &l) in out.iter_mut().zip(&labels) {
                    *o = table[l as usize];
                }
            }
            t_shared.push(t.elapsed().as_secs_f64() * 1e3);
        }
        assert_eq!(own, shared, "both ways give the same indices");
        println!(
            "{k} objects ({}): a pass each {:.3} ms, one joint pass ({} joint colours) {:.3} ms \
             (medians of 300, 640x480)",
            names[..k].join(", "),
            median(t_own),
            number.len(),
            median(t_shared),
        );
    }
    Ok(())
}
