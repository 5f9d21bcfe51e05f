//! The built-in procedural objects (`fruitbox`, `can`, `tricolor`) and
//! [`Object::builtin`], which also names the generated population.

use glam::{Vec2, Vec3};

use crate::CaptureError;
use crate::generated::{GENERATED_PREFIX, generated, generated_seed};
use crate::object::{
    BLACK, BLUE, CYAN, GREEN, LIME, MAGENTA, MeshBuilder, NAVY, ORANGE, Object, PINK, PURPLE, RED,
    TEAL, WHITE, YELLOW, canvas_for,
};
use crate::paint::Canvas;
use crate::texture::Texture;

/// Names accepted by [`Object::builtin`].
pub const BUILTIN_OBJECTS: &[&str] = &["fruitbox", "can", "tricolor"];

const CARDBOARD: [u8; 3] = [165, 120, 70];
const SILVER: [u8; 3] = [185, 185, 190];

/// Metres per unit of the built-in geometry: the box is 24 x 15 x 30 cm
/// (a cereal box), the can 8.4 cm across and 12 cm tall (a drink can), the
/// blocks 10 cm long (a toy).
const FRUITBOX_UNIT_M: f64 = 0.30;
const CAN_UNIT_M: f64 = 0.12;
const TRICOLOR_UNIT_M: f64 = 0.10;

impl Object {
    /// A built-in procedural object: `fruitbox` (a printed cereal-style box,
    /// a different multi-coloured pattern on every face), `can` (a cylinder
    /// with an asymmetric wrapped label and a plain metal top) or `tricolor`
    /// (three untextured blocks in red, green and blue); or `generated-N`,
    /// object N of the generated population (a box, can, bottle or stack
    /// of blocks printed like packaging, drawn from seed N).
    pub fn builtin(name: &str) -> Result<Object, CaptureError> {
        if let Some(seed) = generated_seed(name) {
            return Ok(generated(seed));
        }
        match name {
            "fruitbox" => Ok(fruitbox()),
            "can" => Ok(can()),
            "tricolor" => Ok(tricolor()),
            _ => Err(CaptureError::UnknownObject {
                name: name.to_string(),
                valid: format!(
                    "{}, {}N (N a number)",
                    BUILTIN_OBJECTS.join(", "),
                    GENERATED_PREFIX
                ),
            }),
        }
    }
}

/// A cereal-style box, 0.8 wide (x), 0.5 deep (y), 1.0 tall (z) before
/// normalisation, with a distinct printed design on every face.
fn fruitbox() -> Object {
    let (sx, sy, sz) = (0.8, 0.5, 1.0);

    // +y: "front": sun, a lettered band, a bowl of fruit.
    let mut front = canvas_for(sx, sz, RED);
    front.ring(0.28, 0.2, 0.14, 0.175, ORANGE);
    front.disc(0.28, 0.2, 0.14, YELLOW);
    front.rect(0.0, 0.38, 1.0, 0.58, WHITE);
    front.rect(0.08, 0.40, 0.13, 0.56, BLUE); // F
    front.rect(0.08, 0.40, 0.28, 0.44, BLUE);
    front.rect(0.08, 0.46, 0.23, 0.50, BLUE);
    front.bar((0.36, 0.40), (0.56, 0.56), 0.045, BLUE); // X
    front.bar((0.56, 0.40), (0.36, 0.56), 0.045, BLUE);
    front.ring(0.76, 0.48, 0.045, 0.085, BLUE); // O
    front.disc(0.36, 0.70, 0.06, ORANGE);
    front.disc(0.55, 0.68, 0.05, PURPLE);
    front.disc(0.70, 0.71, 0.055, YELLOW);
    front.disc(0.47, 0.64, 0.04, PINK);
    front.half_disc_lower(0.52, 0.72, 0.2, GREEN);
    front.rect(0.0, 0.92, 1.0, 1.0, YELLOW);
    front.checks([0.05, 0.935, 0.45, 0.985], 8, 1, NAVY, YELLOW);

    // -y: "back": checks over purple with bands, a big L and a triangle.
    let mut back = canvas_for(sx, sz, WHITE);
    back.checks([0.0, 0.0, 1.0, 0.45], 6, 5, BLUE, WHITE);
    back.rect(0.0, 0.45, 1.0, 1.0, PURPLE);
    back.rect(0.0, 0.55, 1.0, 0.60, YELLOW);
    back.rect(0.0, 0.65, 1.0, 0.70, LIME);
    back.rect(0.0, 0.75, 1.0, 0.80, ORANGE);
    back.rect(0.62, 0.50, 0.72, 0.95, CYAN);
    back.rect(0.62, 0.88, 0.92, 0.95, CYAN);
    back.polygon(&[(0.08, 0.95), (0.42, 0.95), (0.25, 0.60)], RED);

    // +x: a stack of coloured blocks with dots and a white wedge.
    let mut right = canvas_for(sy, sz, WHITE);
    let blocks = [ORANGE, TEAL, MAGENTA, LIME, NAVY, YELLOW];
    for (i, &c) in blocks.iter().enumerate() {
        let y0 = i as f64 / 6.0;
        right.rect(0.0, y0, 1.0, y0 + 1.0 / 6.0, c);
        right.disc(0.2 + 0.12 * i as f64, y0 + 1.0 / 12.0, 0.035, WHITE);
    }
    right.polygon(&[(0.1, 0.3), (0.9, 0.45), (0.1, 0.6)], WHITE);
    right.polygon(&[(0.2, 0.36), (0.65, 0.45), (0.2, 0.54)], RED);

    // -x: diagonal stripes, a magenta ring and a lettered panel.
    let mut left = canvas_for(sy, sz, GREEN);
    left.stripes([0.0, 0.0, 1.0, 1.0], 30.0, 0.06, &[GREEN, YELLOW, BLACK]);
    left.disc(0.5, 0.22, 0.2, WHITE);
    left.ring(0.5, 0.22, 0.11, 0.2, MAGENTA);
    left.rect(0.1, 0.68, 0.9, 0.92, CYAN);
    left.rect(0.25, 0.71, 0.75, 0.75, RED); // T
    left.rect(0.45, 0.71, 0.55, 0.89, RED);

    // +z: top, deliberately asymmetric so every azimuth of a top view differs.
    let mut top = canvas_for(sx, sy, ORANGE);
    top.rect(0.55, 0.0, 1.0, 1.0, CYAN);
    top.bar((0.08, 0.55), (0.36, 0.55), 0.12, NAVY);
    top.polygon(&[(0.34, 0.35), (0.50, 0.55), (0.34, 0.75)], NAVY);
    top.disc(0.66, 0.25, 0.13, RED);
    top.disc(0.80, 0.52, 0.12, YELLOW);
    top.disc(0.91, 0.80, 0.10, GREEN);
    top.rect(0.05, 0.08, 0.25, 0.16, WHITE); // T
    top.rect(0.12, 0.08, 0.18, 0.40, WHITE);
    top.rect(0.0, 0.86, 0.55, 1.0, PURPLE);

    // -z: plain cardboard with a barcode.
    let mut bottom = canvas_for(sx, sy, CARDBOARD);
    bottom.rect(0.3, 0.3, 0.7, 0.7, WHITE);
    for i in 0..14 {
        let x = 0.33 + 0.025 * i as f64;
        bottom.rect(x, 0.35, x + 0.008 + 0.006 * (i % 3) as f64, 0.65, BLACK);
    }

    let mut b = MeshBuilder::new();
    let t = [right, left, front, back, top, bottom].map(|c| b.texture(c.into_texture(false)));
    b.cuboid(
        Vec3::new(-sx / 2.0, -sy / 2.0, 0.0),
        Vec3::new(sx / 2.0, sy / 2.0, sz),
        t,
    );
    b.finish_normalised("fruitbox", FRUITBOX_UNIT_M)
}

/// A drink can, radius 0.35 and height 1.0 before normalisation, whose label
/// has four different panels around the circumference, and whose plain lid
/// has a pull tab and an opening.
fn can() -> Object {
    let (r, h) = (0.35f32, 1.0f32);
    let circumference = std::f32::consts::TAU * r;
    let mut label = canvas_for(circumference, h, RED);
    // Panel 1 (u 0..0.3): white disc with a yellow star on red.
    label.disc(0.15, 0.5, 0.3, WHITE);
    label.star(0.15, 0.5, 0.26, YELLOW);
    label.disc(0.15, 0.5, 0.07, RED);
    // Panel 2 (u 0.3..0.55): green stripes on blue with an orange bar.
    label.rect(0.3, 0.0, 0.55, 1.0, BLUE);
    label.stripes([0.3, 0.0, 0.55, 1.0], 90.0, 0.05, &[BLUE, BLUE, GREEN]);
    label.rect(0.3, 0.62, 0.55, 0.72, ORANGE);
    // Panel 3 (u 0.55..0.8): purple checks across yellow.
    label.rect(0.55, 0.0, 0.8, 1.0, YELLOW);
    label.checks([0.55, 0.3, 0.8, 0.7], 8, 4, PURPLE, YELLOW);
    // Panel 4 (u 0.8..1): white with green blocks and a barcode.
    label.rect(0.8, 0.0, 1.0, 1.0, WHITE);
    for i in 0..5 {
        let y = 0.12 + 0.09 * i as f64;
        label.rect(0.83, y, 0.83 + 0.03 * (i + 2) as f64, y + 0.05, GREEN);
    }
    for i in 0..12 {
        let x = 0.84 + 0.011 * i as f64;
        label.rect(x, 0.72, x + 0.004 + 0.003 * (i % 3) as f64, 0.88, BLACK);
    }
    // Metal rims at the top and bottom of the label.
    label.rect(0.0, 0.0, 1.0, 0.05, SILVER);
    label.rect(0.0, 0.95, 1.0, 1.0, SILVER);

    // An unprinted lid, but with a real can's pull tab and opening: a
    // featureless disc would leave φ unobservable from above (θ > ~80°).
    let mut lid = Canvas::new(128, 128, SILVER);
    lid.ring(0.5, 0.5, 0.41, 0.46, [140, 140, 148]);
    let (opening, tab, hole) = ([52, 50, 56], [150, 150, 160], [88, 88, 96]);
    lid.bar((0.42, 0.2), (0.58, 0.2), 0.1, opening);
    lid.disc(0.42, 0.2, 0.05, opening);
    lid.disc(0.58, 0.2, 0.05, opening);
    lid.bar((0.5, 0.3), (0.5, 0.66), 0.17, tab);
    lid.disc(0.5, 0.3, 0.085, tab);
    lid.disc(0.5, 0.66, 0.085, tab);
    lid.disc(0.5, 0.58, 0.045, hole);
    lid.disc(0.5, 0.42, 0.03, hole);

    let mut b = MeshBuilder::new();
    let side = b.texture(label.into_texture(true));
    let top = b.texture(lid.into_texture(false));
    let bottom = b.texture(Texture::solid(SILVER));
    b.cylinder(Vec2::ZERO, 0.0, h, r, 96, side, top, bottom);
    b.finish_normalised("can", CAN_UNIT_M)
}

/// Three untextured blocks: a blue base slab, a red tower on one end and a
/// green cube on the other, so views are distinguishable by colour layout.
fn tricolor() -> Object {
    let mut b = MeshBuilder::new();
    let red = b.texture(Texture::solid([210, 30, 30]));
    let green = b.texture(Texture::solid([30, 170, 50]));
    let blue = b.texture(Texture::solid([30, 60, 200]));
    b.cuboid(
        Vec3::new(-0.5, -0.4, 0.0),
        Vec3::new(0.5, 0.4, 0.3),
        [blue; 6],
    );
    b.cuboid(
        Vec3::new(-0.5, -0.4, 0.3),
        Vec3::new(-0.1, 0.4, 1.0),
        [red; 6],
    );
    b.cuboid(
        Vec3::new(0.12, 0.05, 0.3),
        Vec3::new(0.42, 0.35, 0.6),
        [green; 6],
    );
    b.finish_normalised("tricolor", TRICOLOR_UNIT_M)
}
