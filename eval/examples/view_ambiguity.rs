//! Which poses of a robust-protocol run can no image tell apart in φ? A
//! bottle or a can seen from above is its cap or lid, a disc that looks
//! the same turned; a box's lid looks the same turned by 180°. The failure
//! rule (|Δφ| > 20°) counts such a pose as a failure whatever a method
//! answers, so this measures how many there are, independently of any
//! histogram: for each clean pose of an `--errors` CSV, the object is
//! rendered alone on a plain table at its pose, turned in φ by 2° to
//! either side, and turned by every 5° from 25° to 335°; the difference of
//! two renders is the mean absolute difference of their colours over the
//! pixels either shows the object on (grey levels). The far difference is
//! the smallest over the far turns: a pose whose far difference is below
//! a grey level looks the same turned beyond the failure threshold under
//! any real camera's noise (`docs/results/robust/combined/observable.py`
//! takes the limit); `ambiguous` marks the exact symmetries, whose far
//! difference is no larger than a 2° turn's.
//!
//! `cargo run --release -p acch-eval --example view_ambiguity -- ERRORS.csv [MESH.obj] > OUT.csv`
//! (ERRORS.csv: `acch eval --protocol robust --errors`, uncompressed;
//! MESH.obj: the mesh of the object the CSV calls by the mesh's file stem,
//! as the population's duck). Prints one line per clean pose: object,
//! background, image, θ, φ, ambiguous (0/1), the nearest-looking far turn
//! (degrees), the far difference and the 2° turns' smaller one.

use acch_capture::{Background, DEFAULT_DISTANCE, Object, Renderer, SceneConfig, ViewPose};
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Arc;

/// Mean absolute colour difference (grey levels, over the three channels)
/// of two renders over the pixels where either shows the object.
fn difference(a: &acch_capture::Rendered, b: &acch_capture::Rendered) -> f64 {
    let (mut sum, mut n) = (0u64, 0u64);
    for (i, (&ma, &mb)) in a.mask.iter().zip(b.mask.iter()).enumerate() {
        if ma == 0 && mb == 0 {
            continue;
        }
        n += 1;
        let (pa, pb) = (
            &a.image.as_raw()[3 * i..3 * i + 3],
            &b.image.as_raw()[3 * i..3 * i + 3],
        );
        sum += pa
            .iter()
            .zip(pb)
            .map(|(x, y)| x.abs_diff(*y) as u64)
            .sum::<u64>();
    }
    sum as f64 / (3 * n.max(1)) as f64
}

/// The turn of the reference views, degrees.
const NEAR_DEG: f64 = 2.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let csv = args
        .next()
        .ok_or("usage: view_ambiguity ERRORS.csv [MESH.obj]")?;
    let mesh = args.next();
    let text = std::fs::read_to_string(&csv).map_err(|e| format!("{csv}: {e}"))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or(format!("{csv}: empty"))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or(format!("{csv}: no column {name}"))
    };
    let (object, family, background, image, theta, phi) = (
        col("object")?,
        col("family")?,
        col("background")?,
        col("image")?,
        col("theta_deg")?,
        col("phi_deg")?,
    );
    let mut poses = Vec::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        if f.get(family) != Some(&"clean") {
            continue;
        }
        poses.push((
            f[object].to_owned(),
            f[background].to_owned(),
            f[image].to_owned(),
            f[theta].parse::<f64>()?,
            f[phi].parse::<f64>()?,
        ));
    }
    let mut objects: HashMap<String, Arc<Object>> = HashMap::new();
    for (name, ..) in &poses {
        if objects.contains_key(name) {
            continue;
        }
        let loaded = match &mesh {
            Some(path)
                if std::path::Path::new(path)
                    .file_stem()
                    .is_some_and(|s| s.to_string_lossy() == *name) =>
            {
                Object::load_mesh(path, Default::default())?
            }
            _ => Object::builtin(name)?,
        };
        objects.insert(name.clone(), Arc::new(loaded));
    }
    let far: Vec<f64> = (5..=67).map(|k| f64::from(k) * 5.0).collect();
    let rows: Vec<String> = poses
        .par_iter()
        .map(|(name, bg, img, theta, phi)| -> Result<String, String> {
            let config = SceneConfig::new(objects[name].clone(), Background::Plain(Background::DEFAULT_PLAIN));
            let renderer = Renderer::new(config, 0);
            let at = |turn: f64| -> Result<acch_capture::Rendered, String> {
                let view = ViewPose::new(*theta, (phi + turn).rem_euclid(360.0), DEFAULT_DISTANCE)
                    .map_err(|e| e.to_string())?;
                Ok(renderer.render(&view, 0))
            };
            let own = at(0.0)?;
            let near = difference(&own, &at(NEAR_DEG)?).min(difference(&own, &at(-NEAR_DEG)?));
            let (mut best_turn, mut best) = (0.0, f64::INFINITY);
            for &turn in &far {
                let d = difference(&own, &at(turn)?);
                if d < best {
                    (best_turn, best) = (turn, d);
                }
            }
            let ambiguous = u8::from(best <= near);
            Ok(format!(
                "{name},{bg},{img},{theta:.3},{phi:.3},{ambiguous},{best_turn:.0},{best:.2},{near:.2}"
            ))
        })
        .collect::<Result<_, _>>()?;
    println!(
        "object,background,image,theta_deg,phi_deg,ambiguous,far_turn_deg,far_difference,near_difference"
    );
    for row in rows {
        println!("{row}");
    }
    Ok(())
}
