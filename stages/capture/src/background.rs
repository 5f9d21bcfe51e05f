//! Backgrounds: the table textures and the clutter of distractor objects.

use std::fmt;
use std::str::FromStr;
use std::sync::{Arc, OnceLock};

use glam::{DAffine3, DVec3, Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::CaptureError;
use crate::noise::{fbm, hash2, value_noise};
use crate::object::{MeshBuilder, Object};
use crate::paint::Canvas;
use crate::texture::Texture;

/// What surrounds the target object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Background {
    /// A homogeneous colour everywhere behind the object (no table texture,
    /// no shading). Name `plain` (default colour [`Background::DEFAULT_PLAIN`])
    /// or `plain:R,G,B`.
    Plain([u8; 3]),
    /// A yellowish wood-grain table (the paper's background A). Name `A`.
    A,
    /// A blue textured (woven fabric) table (the paper's background B). Name `B`.
    B,
    /// A green textured (mottled felt) table (the paper's background C). Name `C`.
    C,
    /// A light laminate table with 3-6 randomly coloured and patterned
    /// distractor objects around the target. Name `clutter`.
    Clutter,
    /// Like [`Background::Clutter`] but the distractors are painted in the
    /// target's own dominant colours. Name `clutter-similar`.
    ClutterSimilar,
}

impl Background {
    /// The background names accepted by [`Background::from_str`].
    pub const NAMES: &'static [&'static str] = &[
        "plain",
        "plain:R,G,B",
        "A",
        "B",
        "C",
        "clutter",
        "clutter-similar",
    ];
    /// The colour of the `plain` background.
    pub const DEFAULT_PLAIN: [u8; 3] = [140, 140, 140];

    /// Whether the background has distractor objects.
    pub fn has_clutter(&self) -> bool {
        matches!(self, Background::Clutter | Background::ClutterSimilar)
    }
}

impl Default for Background {
    fn default() -> Self {
        Background::Plain(Background::DEFAULT_PLAIN)
    }
}

impl FromStr for Background {
    type Err = CaptureError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let unknown = || CaptureError::UnknownBackground {
            name: s.to_string(),
            valid: Background::NAMES.join(", "),
        };
        let t = s.trim();
        Ok(match t {
            "plain" => Background::default(),
            "A" | "a" => Background::A,
            "B" | "b" => Background::B,
            "C" | "c" => Background::C,
            "clutter" => Background::Clutter,
            "clutter-similar" | "clutter_similar" => Background::ClutterSimilar,
            _ => {
                let rgb = t.strip_prefix("plain:").ok_or_else(unknown)?;
                let parts: Vec<&str> = rgb.split(',').map(str::trim).collect();
                let [r, g, b] = parts[..] else {
                    return Err(unknown());
                };
                let ch = |v: &str| v.parse::<u8>().map_err(|_| unknown());
                Background::Plain([ch(r)?, ch(g)?, ch(b)?])
            }
        })
    }
}

impl fmt::Display for Background {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Background::Plain(c) if *c == Background::DEFAULT_PLAIN => f.write_str("plain"),
            Background::Plain([r, g, b]) => write!(f, "plain:{r},{g},{b}"),
            Background::A => f.write_str("A"),
            Background::B => f.write_str("B"),
            Background::C => f.write_str("C"),
            Background::Clutter => f.write_str("clutter"),
            Background::ClutterSimilar => f.write_str("clutter-similar"),
        }
    }
}

/// Texels along each side of a table texture tile.
const TABLE_TEXELS: u32 = 1024;
/// World units (object bounding radii) covered by one tile: 128 texels/unit,
/// about one texel per pixel at the default distance.
pub(crate) const TABLE_TILE: f64 = 8.0;

/// Which table texture.
#[derive(Debug, Clone, Copy)]
pub(crate) enum TableKind {
    Wood,
    Fabric,
    Felt,
    Laminate,
}

/// Which instance of each table texture a scene shows. Every background
/// kind (wood, fabric, felt, laminate) comes in two textures of the same
/// look from different seeds: what a model is trained on must not be the
/// very table it is evaluated on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum TextureSet {
    /// The textures training scenes show (the confidence network's).
    #[default]
    Training,
    /// Textures no training scene shows: for evaluation, and for the
    /// simulated camera of `acch run`.
    HeldOut,
}

impl TextureSet {
    /// Added to every seed of the texture generators.
    fn salt(self) -> u32 {
        match self {
            TextureSet::Training => 0,
            TextureSet::HeldOut => 7919,
        }
    }

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            TextureSet::Training => "training",
            TextureSet::HeldOut => "held-out",
        }
    }
}

impl fmt::Display for TextureSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for TextureSet {
    type Err = CaptureError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "training" => Ok(TextureSet::Training),
            "held-out" => Ok(TextureSet::HeldOut),
            _ => Err(CaptureError::UnknownTextureSet { name: s.to_owned() }),
        }
    }
}

/// The tiling table texture of a kind in a set, generated once per process
/// from fixed seeds so a table always looks the same.
pub(crate) fn table_texture(kind: TableKind, set: TextureSet) -> Arc<Texture> {
    static CACHE: [OnceLock<Arc<Texture>>; 8] = [const { OnceLock::new() }; 8];
    CACHE[2 * kind as usize + set as usize]
        .get_or_init(|| Arc::new(make_table(kind, set.salt())))
        .clone()
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn to_u8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| v.round().clamp(0.0, 255.0) as u8)
}

fn make_table(kind: TableKind, salt: u32) -> Texture {
    let n = TABLE_TEXELS;
    let mut data = vec![[0u8; 3]; (n * n) as usize];
    data.par_chunks_mut(n as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, t) in row.iter_mut().enumerate() {
                let (x, y, n) = (x as i32, y as i32, n as i32);
                *t = match kind {
                    TableKind::Wood => wood_texel(x, y, n, salt),
                    TableKind::Fabric => fabric_texel(x, y, n, salt),
                    TableKind::Felt => felt_texel(x, y, n, salt),
                    TableKind::Laminate => laminate_texel(x, y, n, salt),
                };
            }
        });
    Texture::new(n, n, data, true)
}

/// Yellowish planks along x with growth rings, fine streaks and dark seams.
fn wood_texel(x: i32, y: i32, n: i32, salt: u32) -> [u8; 3] {
    const PLANK: i32 = 128;
    let plank = y / PLANK;
    let ly = (y % PLANK) as f32 / PLANK as f32;
    let xs = x as f32 / n as f32;
    let seed = 100 + salt + plank as u32;
    let tint = 0.9 + 0.18 * hash2(plank, 0, 11 + salt);
    let joint = (hash2(plank, 1, 12 + salt) * n as f32) as i32;
    let dx = (x - joint).rem_euclid(n);
    if y % PLANK < 2 || dx < 2 || dx > n - 2 {
        return [92, 62, 34];
    }
    let warp = fbm(xs * 3.0, ly * 2.0, 3, 1 << 20, 3, seed);
    let s = ly * 5.0 + 2.5 * warp + 4.0 * hash2(plank, 2, 13 + salt);
    let ring = s - s.floor();
    let late = ((ring - 0.55) / 0.2).clamp(0.0, 1.0) * ((1.0 - ring) / 0.15).clamp(0.0, 1.0);
    let streak = value_noise(
        xs * 24.0,
        ly * 60.0 + plank as f32 * 61.0,
        24,
        1 << 20,
        seed + 7,
    );
    let light = [226.0, 188.0, 120.0];
    let dark = [172.0, 122.0, 60.0];
    let c = lerp3(light, dark, (0.75 * late + 0.35 * streak).min(1.0));
    to_u8(c.map(|v| v * tint))
}

/// Blue woven fabric: a twill over a mottled dye.
fn fabric_texel(x: i32, y: i32, n: i32, salt: u32) -> [u8; 3] {
    let (xs, ys) = (x as f32 / n as f32, y as f32 / n as f32);
    let mott = fbm(xs * 8.0, ys * 8.0, 8, 8, 4, 21 + salt);
    let twill = (std::f32::consts::TAU * (x + y) as f32 / 8.0).sin();
    let cross = (std::f32::consts::TAU * (x - y) as f32 / 16.0).sin();
    let fiber = hash2(x, y, 23 + salt) - 0.5;
    let k = (0.7 + 0.5 * mott) * (0.9 + 0.08 * twill + 0.04 * cross) + 0.12 * fiber;
    to_u8([42.0 * k, 78.0 * k, 168.0 * k + 10.0])
}

/// Green mottled felt with darker blotches and grain.
fn felt_texel(x: i32, y: i32, n: i32, salt: u32) -> [u8; 3] {
    let (xs, ys) = (x as f32 / n as f32, y as f32 / n as f32);
    let mott = fbm(xs * 6.0, ys * 6.0, 6, 6, 5, 31 + salt);
    let blot = fbm(xs * 3.0, ys * 3.0, 3, 3, 3, 37 + salt);
    let grain = hash2(x, y, 33 + salt) - 0.5;
    let mut c = lerp3([38.0, 98.0, 44.0], [112.0, 172.0, 82.0], mott);
    if blot > 0.58 {
        let d = ((blot - 0.58) / 0.1).min(1.0) * 0.25;
        c = c.map(|v| v * (1.0 - d));
    }
    to_u8(c.map(|v| v * (1.0 + 0.18 * grain)))
}

/// Light grey laminate with faint clouding and speckles.
fn laminate_texel(x: i32, y: i32, n: i32, salt: u32) -> [u8; 3] {
    let (xs, ys) = (x as f32 / n as f32, y as f32 / n as f32);
    let cloud = fbm(xs * 4.0, ys * 4.0, 4, 4, 4, 41 + salt);
    let k = 0.92 + 0.14 * cloud + 0.03 * (hash2(x, y, 43 + salt) - 0.5);
    let mut c = [182.0 * k, 176.0 * k, 164.0 * k];
    let s = hash2(x, y, 47 + salt);
    if s > 0.985 {
        c = c.map(|v| v * 0.62);
    } else if s < 0.01 {
        c = c.map(|v| (v * 1.12).min(255.0));
    }
    to_u8(c)
}

/// An object placed in the world.
pub(crate) struct Placed {
    pub object: Arc<Object>,
    pub world_from_object: DAffine3,
}

pub(crate) fn hsv(h: f32, s: f32, v: f32) -> [u8; 3] {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let c = v * s;
    let x = c * (1.0 - ((h6 % 2.0) - 1.0).abs());
    let (r, g, b) = match h6 as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    to_u8([(r + m) * 255.0, (g + m) * 255.0, (b + m) * 255.0])
}

/// A random printed pattern in the given colours.
fn random_pattern(rng: &mut ChaCha8Rng, w: u32, h: u32, palette: &[[u8; 3]]) -> Canvas {
    let pick = |rng: &mut ChaCha8Rng| palette[rng.random_range(0..palette.len())];
    let mut c = Canvas::new(w, h, pick(rng));
    match rng.random_range(0..4) {
        0 => {
            let cols: Vec<[u8; 3]> = (0..rng.random_range(2..4)).map(|_| pick(rng)).collect();
            let angle = rng.random_range(0.0..180.0);
            let period = rng.random_range(0.08..0.2);
            c.stripes([0.0, 0.0, 1.0, 1.0], angle, period, &cols);
        }
        1 => {
            let (a, b) = (pick(rng), pick(rng));
            let (nx, ny) = (rng.random_range(3..8), rng.random_range(3..8));
            c.checks([0.0, 0.0, 1.0, 1.0], nx, ny, a, b);
        }
        2 => {
            for _ in 0..rng.random_range(4..10) {
                let col = pick(rng);
                c.disc(rng.random(), rng.random(), rng.random_range(0.06..0.2), col);
            }
        }
        _ => {
            for _ in 0..rng.random_range(4..9) {
                let col = pick(rng);
                let (x0, y0) = (rng.random_range(0.0..0.8), rng.random_range(0.0..0.8));
                let (x1, y1) = (
                    x0 + rng.random_range(0.1..0.5),
                    y0 + rng.random_range(0.1..0.5),
                );
                c.rect(x0, y0, x1, y1, col);
            }
        }
    }
    c
}

/// Builds one distractor standing on z = 0 around the z axis and returns it
/// with its footprint radius.
pub(crate) fn distractor(
    rng: &mut ChaCha8Rng,
    palette: &[[u8; 3]],
    height_limit: f32,
    i: usize,
) -> (Object, f32) {
    let mut b = MeshBuilder::new();
    let pattern = |rng: &mut ChaCha8Rng| random_pattern(rng, 128, 128, palette).into_texture(false);
    if rng.random_bool(0.55) {
        let (sx, sy) = (
            rng.random_range(0.35..0.9f32),
            rng.random_range(0.3..0.8f32),
        );
        let sz = rng.random_range(0.25..1.1f32).min(height_limit);
        let side = b.texture(pattern(rng));
        let other = b.texture(pattern(rng));
        let top = b.texture(pattern(rng));
        b.cuboid(
            Vec3::new(-sx / 2.0, -sy / 2.0, 0.0),
            Vec3::new(sx / 2.0, sy / 2.0, sz),
            [side, side, other, other, top, top],
        );
        (
            b.finish_raw(&format!("distractor-{i}")),
            (sx * sx + sy * sy).sqrt() / 2.0,
        )
    } else {
        let r = rng.random_range(0.18..0.4f32);
        let sz = rng.random_range(0.35..1.1f32).min(height_limit);
        let side = b.texture(random_pattern(rng, 256, 128, palette).into_texture(true));
        let lid = palette[rng.random_range(0..palette.len())];
        let top = b.texture(Texture::solid(lid));
        b.cylinder(Vec2::ZERO, 0.0, sz, r, 48, side, top, top);
        (b.finish_raw(&format!("distractor-{i}")), r)
    }
}

/// Places 3-6 distractors on the table around the target. They stay at
/// least 0.15 outside the target's bounding cylinder (radius 1) and low
/// enough that for any elevation >= 45 deg none of them hides the target's
/// centre: the line of sight to the centre descends at >= 45 deg, so at
/// horizontal distance d it is d above the centre, higher than any
/// distractor top closer than d.
pub(crate) fn clutter_layout(target: &Object, similar: bool, seed: u64) -> Vec<Placed> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0063_6c75_7474_6572);
    let palette: Vec<[u8; 3]> = if similar {
        let base = target.dominant_colors(6);
        let base = if base.is_empty() {
            vec![[128, 128, 128]]
        } else {
            base
        };
        // Jittered copies of the target's colours: similar, not identical.
        (0..12)
            .map(|k| {
                let c = base[k % base.len()];
                c.map(|v| (v as i32 + rng.random_range(-14..=14)).clamp(0, 255) as u8)
            })
            .collect()
    } else {
        (0..8)
            .map(|_| {
                hsv(
                    rng.random(),
                    rng.random_range(0.55..1.0),
                    rng.random_range(0.45..1.0),
                )
            })
            .collect()
    };
    let table_z = target.table_z();
    let count = rng.random_range(3..=6);
    let mut placed: Vec<(f64, f64, f64)> = Vec::new(); // x, y, footprint radius
    let mut out = Vec::new();
    for i in 0..count {
        // Height limit derived from the closest possible position (see above).
        let (obj, fr) = distractor(&mut rng, &palette, 1.1, i);
        let fr = fr as f64;
        let height = obj
            .tris
            .iter()
            .flatten()
            .map(|v| v.p.z as f64)
            .fold(0.0, f64::max);
        let lo = 1.15 + fr;
        let hi = (2.7f64).max(lo + 0.3);
        let spot = (0..200).find_map(|_| {
            let rho = rng.random_range(lo..hi);
            let ang = rng.random_range(0.0..std::f64::consts::TAU);
            let (x, y) = (rho * ang.cos(), rho * ang.sin());
            let free = placed
                .iter()
                .all(|&(px, py, pr)| ((x - px).powi(2) + (y - py).powi(2)).sqrt() > pr + fr + 0.1);
            // Keep the top below the 45-degree line of sight to the centre.
            (free && table_z + height < rho - fr).then_some((x, y))
        });
        if let Some((x, y)) = spot {
            placed.push((x, y, fr));
            let yaw = rng.random_range(0.0..std::f64::consts::TAU);
            out.push(Placed {
                object: Arc::new(obj),
                world_from_object: DAffine3::from_translation(DVec3::new(x, y, table_z))
                    * DAffine3::from_rotation_z(yaw),
            });
        }
    }
    out
}
