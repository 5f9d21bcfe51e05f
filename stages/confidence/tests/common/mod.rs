//! Synthetic match-value responses for the tests.

#![allow(dead_code)]

use acch_core::View;
use acch_pose::{Slice, phi_error};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The paper's section 5 grid: θ in {45, 50, 60, 70, 80, 90}, φ every 10°.
pub fn grid() -> (Vec<Slice>, Vec<View>) {
    let mut slices = Vec::new();
    let mut views = Vec::new();
    for t in [45.0f32, 50.0, 60.0, 70.0, 80.0, 90.0] {
        slices.push(Slice {
            theta_deg: t,
            start: views.len(),
            len: 36,
        });
        for k in 0..36 {
            views.push(View {
                theta_deg: t,
                phi_deg: k as f32 * 10.0,
                size_px: 100.0,
                centre_offset_px: [0.0; 2],
            });
        }
    }
    (slices, views)
}

fn bump(v: &View, theta: f32, phi: f32, height: f32) -> f32 {
    let dp = phi_error(v.phi_deg, phi) / 20.0;
    let dt = (v.theta_deg - theta) / 10.0;
    height * (-(dp * dp + dt * dt) / 2.0).exp()
}

/// A response with one clear peak (reliable) or with a competing peak of
/// similar height far away in φ or in θ (ambiguous), plus noise.
pub fn response(rng: &mut ChaCha8Rng, views: &[View], reliable: bool) -> Vec<f32> {
    let thetas = [45.0f32, 50.0, 60.0, 70.0, 80.0, 90.0];
    let t0 = thetas[rng.random_range(0..6)];
    let p0 = rng.random_range(0..36) as f32 * 10.0;
    let floor = rng.random_range(0.3..0.6);
    let h0 = rng.random_range(0.2..0.35);
    let second = if reliable {
        None
    } else if rng.random_bool(0.5) {
        // Same elevation, at least 60° away in azimuth.
        Some((t0, (p0 + rng.random_range(6..=30) as f32 * 10.0) % 360.0))
    } else {
        // Two or more slices away, any azimuth.
        let k0 = thetas.iter().position(|&t| t == t0).unwrap();
        let far: Vec<usize> = (0..6usize).filter(|&k| k.abs_diff(k0) >= 2).collect();
        let k = far[rng.random_range(0..far.len())];
        Some((thetas[k], rng.random_range(0..36) as f32 * 10.0))
    };
    let h1 = h0 * rng.random_range(0.9..1.0);
    views
        .iter()
        .map(|v| {
            let mut m = floor + bump(v, t0, p0, h0) + rng.random_range(0.0..0.02);
            if let Some((t, p)) = second {
                m += bump(v, t, p, h1);
            }
            m.min(1.0)
        })
        .collect()
}
