//! A population of generated objects, so that accuracy is measured over
//! many objects with a spread and not over the three built-in ones.
//!
//! `generated-N` is drawn from seed N alone: a box, a can, a bottle or an
//! irregular stack of blocks, 8-35 cm across, printed like packaging with
//! bands, rows of glyph-like text, logos, gradients, photo-like patches,
//! stripes and checks in 3-6 colours. The same N is the same object on
//! every machine and in every build that keeps [`GENERATOR_REVISION`].

use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::object::{
    BLACK, BLUE, CYAN, GREEN, LIME, MAGENTA, MeshBuilder, NAVY, ORANGE, Object, PINK, PURPLE, RED,
    TEAL, WHITE, YELLOW, canvas_for,
};
use crate::paint::Canvas;
use crate::texture::Texture;

/// The name of generated object `N` is this prefix followed by N.
pub const GENERATED_PREFIX: &str = "generated-";

/// Changes whenever the same seed would draw another object (so cached
/// databases of generated objects are not reused across it).
pub const GENERATOR_REVISION: u32 = 1;

/// The seed of a generated object's name, `None` for any other name.
pub fn generated_seed(name: &str) -> Option<u64> {
    let digits = name.strip_prefix(GENERATED_PREFIX)?;
    // Only canonical decimal: `generated-07` would name the same object twice.
    if digits.is_empty() || (digits.len() > 1 && digits.starts_with('0')) {
        return None;
    }
    digits.parse().ok()
}

/// The names of `n` generated objects of population `population`: seeds
/// `population * 1000 ..`, so the populations of two evaluation seeds never
/// share an object (up to 1000 objects each).
pub fn population(population: u64, n: usize) -> Vec<String> {
    (0..n as u64)
        .map(|i| format!("{GENERATED_PREFIX}{}", population * 1000 + i))
        .collect()
}

/// Print colours the generator draws from, beside random ones.
const INKS: [[u8; 3]; 14] = [
    RED, YELLOW, WHITE, BLUE, GREEN, ORANGE, PURPLE, MAGENTA, CYAN, NAVY, LIME, BLACK, PINK, TEAL,
];

/// Generated object `seed` (see the module documentation).
pub fn generated(seed: u64) -> Object {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6765_6e65_7261_7465);
    let inks = palette(&mut rng);
    let name = format!("{GENERATED_PREFIX}{seed}");
    // Real height of one unit of the un-normalised geometry.
    let unit_m = rng.random_range(0.08..0.30);
    let mut b = MeshBuilder::new();
    match rng.random_range(0..4u32) {
        0 => {
            let (sx, sy, sz) = (
                rng.random_range(0.35..1.0f32),
                rng.random_range(0.2..0.8f32),
                rng.random_range(0.5..1.2f32),
            );
            printed_box(&mut b, &mut rng, &inks, Vec3::ZERO, Vec3::new(sx, sy, sz));
        }
        1 => {
            let r = rng.random_range(0.2..0.5f32);
            let h = rng.random_range(0.6..1.4f32);
            let side = label(&mut b, &mut rng, &inks, std::f32::consts::TAU * r, h);
            let top = lid(&mut b, &mut rng, &inks, r);
            let bottom = b.texture(Texture::solid(pick(&mut rng, &inks)));
            b.cylinder(Vec2::ZERO, 0.0, h, r, 64, side, top, bottom);
        }
        2 => bottle(&mut b, &mut rng, &inks),
        _ => {
            // Two to four blocks, each on the one before, offset sideways.
            let mut z = 0.0f32;
            let mut centre = Vec2::ZERO;
            for _ in 0..rng.random_range(2..=4) {
                let size = Vec3::new(
                    rng.random_range(0.2..0.8),
                    rng.random_range(0.2..0.6),
                    rng.random_range(0.2..0.6),
                );
                let min = (centre - size.truncate() / 2.0).extend(z);
                printed_box(&mut b, &mut rng, &inks, min, min + size);
                z += size.z;
                centre += Vec2::new(rng.random_range(-0.25..0.25), rng.random_range(-0.15..0.15));
            }
        }
    }
    b.finish_normalised(&name, unit_m)
}

/// 3-6 distinct inks: mostly print colours, some drawn at random.
fn palette(rng: &mut ChaCha8Rng) -> Vec<[u8; 3]> {
    let n = rng.random_range(3..=6);
    let mut inks: Vec<[u8; 3]> = Vec::with_capacity(n);
    while inks.len() < n {
        let c = if rng.random_bool(0.7) {
            INKS[rng.random_range(0..INKS.len())]
        } else {
            [rng.random(), rng.random(), rng.random()]
        };
        if !inks.contains(&c) {
            inks.push(c);
        }
    }
    inks
}

fn pick(rng: &mut ChaCha8Rng, inks: &[[u8; 3]]) -> [u8; 3] {
    inks[rng.random_range(0..inks.len())]
}

/// An axis-aligned box from `min` to `max` with a printed design per face.
fn printed_box(b: &mut MeshBuilder, rng: &mut ChaCha8Rng, inks: &[[u8; 3]], min: Vec3, max: Vec3) {
    let s = max - min;
    // Faces in MeshBuilder::cuboid's order: +x, -x, +y, -y, +z, -z.
    let sizes = [
        (s.y, s.z),
        (s.y, s.z),
        (s.x, s.z),
        (s.x, s.z),
        (s.x, s.y),
        (s.x, s.y),
    ];
    let faces = sizes.map(|(w, h)| {
        let canvas = printed(rng, inks, w, h);
        b.texture(canvas.into_texture(false))
    });
    b.cuboid(min, max, faces);
}

/// A wrapped label `circumference` wide and `h` tall.
fn label(
    b: &mut MeshBuilder,
    rng: &mut ChaCha8Rng,
    inks: &[[u8; 3]],
    circumference: f32,
    h: f32,
) -> u32 {
    let canvas = printed(rng, inks, circumference, h);
    b.texture(canvas.into_texture(true))
}

/// A cap or lid: a plain disc with one off-centre mark (so φ stays
/// observable from above), or a printed design.
fn lid(b: &mut MeshBuilder, rng: &mut ChaCha8Rng, inks: &[[u8; 3]], r: f32) -> u32 {
    let canvas = if rng.random_bool(0.5) {
        let mut c = canvas_for(2.0 * r, 2.0 * r, pick(rng, inks));
        let (x, y) = (rng.random_range(0.25..0.75), rng.random_range(0.2..0.35));
        c.disc(x, y, rng.random_range(0.06..0.14), pick(rng, inks));
        c
    } else {
        printed(rng, inks, 2.0 * r, 2.0 * r)
    };
    b.texture(canvas.into_texture(false))
}

/// A bottle: a labelled body, a narrower shoulder, a neck and a cap.
fn bottle(b: &mut MeshBuilder, rng: &mut ChaCha8Rng, inks: &[[u8; 3]]) {
    let r = rng.random_range(0.18..0.35f32);
    let body = rng.random_range(0.5..0.9f32);
    let shoulder = rng.random_range(0.1..0.25f32);
    let neck = rng.random_range(0.1..0.3f32);
    let glass = pick(rng, inks);
    let plain = b.texture(Texture::solid(glass));
    let side = label(b, rng, inks, std::f32::consts::TAU * r, body);
    b.cylinder(Vec2::ZERO, 0.0, body, r, 64, side, plain, plain);
    let r_shoulder = r * rng.random_range(0.6..0.8);
    let shoulder_label = label(b, rng, inks, std::f32::consts::TAU * r_shoulder, shoulder);
    b.cylinder(
        Vec2::ZERO,
        body,
        body + shoulder,
        r_shoulder,
        48,
        shoulder_label,
        plain,
        plain,
    );
    let r_neck = r * rng.random_range(0.25..0.45);
    b.cylinder(
        Vec2::ZERO,
        body + shoulder,
        body + shoulder + neck,
        r_neck,
        32,
        plain,
        plain,
        plain,
    );
    let cap = lid(b, rng, inks, r_neck * 1.2);
    let cap_side = b.texture(Texture::solid(pick(rng, inks)));
    let z = body + shoulder + neck;
    b.cylinder(
        Vec2::ZERO,
        z,
        z + 0.08,
        r_neck * 1.2,
        32,
        cap_side,
        cap,
        cap_side,
    );
}

/// A printed face `w` x `h` units: a ground and 3-8 elements over it.
fn printed(rng: &mut ChaCha8Rng, inks: &[[u8; 3]], w: f32, h: f32) -> Canvas {
    let mut c = canvas_for(w, h, pick(rng, inks));
    let unit = |rng: &mut ChaCha8Rng| rng.random_range(0.0..1.0f64);
    for _ in 0..rng.random_range(3..=8) {
        let ink = pick(rng, inks);
        match rng.random_range(0..8u32) {
            // A band across the face.
            0 => {
                let y = unit(rng);
                c.rect(0.0, y, 1.0, y + rng.random_range(0.04..0.25), ink);
            }
            // A row of glyph-like text on a plate.
            1 => {
                let (x0, y0) = (rng.random_range(0.0..0.5), rng.random_range(0.0..0.9));
                let size = rng.random_range(0.04..0.12);
                let glyphs = rng.random_range(3..10);
                let plate = pick(rng, inks);
                c.rect(
                    x0,
                    y0,
                    x0 + size * 0.8 * glyphs as f64 + 0.02,
                    y0 + size + 0.02,
                    plate,
                );
                text(&mut c, rng, (x0 + 0.01, y0 + 0.01), size, glyphs, ink);
            }
            // A logo: disc, ring, star or triangle.
            2 => {
                let (x, y, r) = (unit(rng), unit(rng), rng.random_range(0.05..0.25));
                match rng.random_range(0..4u32) {
                    0 => c.disc(x, y, r, ink),
                    1 => c.ring(x, y, r * 0.5, r, ink),
                    2 => c.star(x, y, r, ink),
                    _ => c.polygon(&[(x - r, y + r), (x + r, y + r), (x, y - r)], ink),
                }
            }
            // A gradient panel between two inks.
            3 => {
                let region = panel(rng);
                c.gradient(region, ink, pick(rng, inks), rng.random_bool(0.5));
            }
            // A photo-like patch: smooth blobs of two or three inks.
            4 => {
                let region = panel(rng);
                let ramp = [ink, pick(rng, inks), pick(rng, inks)];
                c.photo(region, &ramp, rng.random());
            }
            5 => {
                let region = panel(rng);
                let (a, b2) = (ink, pick(rng, inks));
                c.stripes(
                    region,
                    rng.random_range(0.0..180.0),
                    rng.random_range(0.03..0.12),
                    &[a, b2],
                );
            }
            6 => {
                let region = panel(rng);
                c.checks(
                    region,
                    rng.random_range(2..9),
                    rng.random_range(2..9),
                    ink,
                    pick(rng, inks),
                );
            }
            // A diagonal bar.
            _ => c.bar(
                (unit(rng), unit(rng)),
                (unit(rng), unit(rng)),
                rng.random_range(0.03..0.1),
                ink,
            ),
        }
    }
    c
}

/// A rectangle covering 15-70 % of the face's width and height.
fn panel(rng: &mut ChaCha8Rng) -> [f64; 4] {
    let (w, h) = (rng.random_range(0.15..0.7), rng.random_range(0.15..0.7));
    let (x, y) = (
        rng.random_range(0.0..1.0 - w),
        rng.random_range(0.0..1.0 - h),
    );
    [x, y, x + w, y + h]
}

/// `n` glyphs of height `size` from `origin`: each a few strokes in a cell.
fn text(
    c: &mut Canvas,
    rng: &mut ChaCha8Rng,
    origin: (f64, f64),
    size: f64,
    n: usize,
    ink: [u8; 3],
) {
    let stroke = size * 0.18;
    // Stroke ends on a 3 x 3 grid of the glyph's cell, as letters have.
    let at = |x0: f64, k: u32| {
        (
            x0 + (k % 3) as f64 * size * 0.3,
            origin.1 + (k / 3) as f64 * size * 0.45,
        )
    };
    for g in 0..n {
        let x0 = origin.0 + g as f64 * size * 0.8;
        for _ in 0..rng.random_range(1..=3) {
            let (a, b) = (rng.random_range(0..9u32), rng.random_range(0..9u32));
            if a != b {
                c.bar(at(x0, a), at(x0, b), stroke, ink);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_only_canonical_numbers_are_generated() {
        assert_eq!(generated_seed("generated-17"), Some(17));
        assert_eq!(generated_seed("generated-0"), Some(0));
        for bad in [
            "generated-",
            "generated-07",
            "generated-x",
            "fruitbox",
            "generated--1",
        ] {
            assert_eq!(generated_seed(bad), None, "{bad}");
        }
        let names = population(3, 2);
        assert_eq!(names, ["generated-3000", "generated-3001"]);
        assert!(
            population(7, 1000)
                .iter()
                .all(|n| !population(3, 1000).contains(n))
        );
    }

    #[test]
    fn a_seed_is_one_object_and_seeds_differ() {
        let a = generated(5);
        let b = generated(5);
        assert_eq!(a.triangle_count(), b.triangle_count());
        assert_eq!(a.texture_sizes(), b.texture_sizes());
        assert_eq!(a.radius_m(), b.radius_m());
        assert_eq!(a.dominant_colors(6), b.dominant_colors(6));
        // Over a handful of seeds the objects are not all alike.
        let objects: Vec<Object> = (0..12).map(generated).collect();
        let shapes: std::collections::HashSet<usize> =
            objects.iter().map(Object::triangle_count).collect();
        assert!(shapes.len() >= 4, "triangle counts {shapes:?}");
        let colours: std::collections::HashSet<Vec<[u8; 3]>> =
            objects.iter().map(|o| o.dominant_colors(4)).collect();
        assert_eq!(
            colours.len(),
            objects.len(),
            "two objects print the same colours"
        );
        for o in &objects {
            assert!(
                (0.04..=0.6).contains(&o.radius_m()),
                "{}: {}",
                o.name(),
                o.radius_m()
            );
            assert!((o.bounding_radius() - 1.0).abs() < 1e-3);
        }
    }
}
