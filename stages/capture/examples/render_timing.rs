//! Single-thread render time per frame for each object and background:
//! `cargo run --release -p acch-capture --example render_timing`.

use std::sync::Arc;
use std::time::Instant;

use acch_capture::{DEFAULT_DISTANCE, Effects, Object, Rendered, Renderer, SceneConfig, ViewSpec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let views = ViewSpec::training_grid().views(DEFAULT_DISTANCE, 0);
    let objects = [
        Object::builtin("fruitbox")?,
        Object::builtin("can")?,
        Object::load_obj("/work/shared/data/duck/duck.obj")?,
    ];
    for object in objects {
        let object = Arc::new(object);
        for bg in ["plain", "A", "clutter"] {
            for effects in [
                Effects::default(),
                Effects {
                    noise_sigma: 4.0,
                    blur_sigma: 1.0,
                    brightness: 0.9,
                    ..Effects::default()
                },
            ] {
                let mut config = SceneConfig::new(object.clone(), bg.parse()?);
                config.effects = effects;
                let t = Instant::now();
                let r = Renderer::new(config, 0);
                let setup = t.elapsed();
                let mut out = Rendered::default();
                r.render_into(&views[0], 0, &mut out); // warm-up
                let t = Instant::now();
                for (i, v) in views.iter().enumerate() {
                    r.render_into(v, i as u64, &mut out);
                }
                let per = t.elapsed().as_secs_f64() * 1e3 / views.len() as f64;
                println!(
                    "{:9} {:8} {:22} setup {:6.1} ms  render {:5.2} ms/frame",
                    object.name(),
                    bg,
                    if effects == Effects::default() {
                        "no effects"
                    } else {
                        "noise+blur+brightness"
                    },
                    setup.as_secs_f64() * 1e3,
                    per
                );
            }
        }
    }
    Ok(())
}
