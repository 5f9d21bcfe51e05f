//! How the PLY writer colours an object: one texture atlas (every texture
//! in a cell of one image, triangles' texture coordinates remapped into
//! their cell) or, for an object whose textures are all single colours,
//! vertex colours.

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use image::RgbImage;

use crate::object::Object;
use crate::texture::Texture;

/// Texels around a cell's content, wrapped or clamped as the texture's
/// sampler would: bilinear samples (and a few mip levels) near the edge of
/// a texture then read what they read in the texture itself.
const PAD: i64 = 8;
/// Cells start and end on multiples of this, so the atlas' mip levels up to
/// log2(ALIGN) average the same texel blocks as each texture's own did.
const ALIGN: i64 = 16;
/// The largest side of a cell or of the atlas, texels.
const MAX_SIDE: i64 = 32768;
/// The most texels an atlas may hold (3 bytes each).
const MAX_TEXELS: i64 = 1 << 28;

/// How the written file is coloured.
pub(crate) enum ColourMode {
    /// Per-vertex colours (bytes) of each triangle corner.
    Vertex(Vec<[[u8; 3]; 3]>),
    /// The atlas image and each triangle corner's coordinates in it
    /// (v = 0 at the top row).
    Texture(RgbImage, Vec<[Vec2; 3]>),
}

/// One cell: a texture (times a colour) over a range of its texels.
struct Cell {
    tex: u32,
    colour: Vec3,
    /// First texel (x, y) of the cell in the texture's own (wrapping or
    /// clamping) texel grid, and the cell's size.
    x0: i64,
    y0: i64,
    w: i64,
    h: i64,
    /// Where the cell sits in the atlas.
    ax: i64,
    ay: i64,
}

/// The colouring of `obj` as a PLY file can carry it: vertex colours if
/// every texture is a single colour, else a texture atlas. A triangle whose
/// corners' colours differ over a real texture fits neither (PLY colours
/// by texture or by vertex colours, not both): that is an error, which
/// says what cannot be written.
pub(crate) fn bake(obj: &Object) -> Result<ColourMode, String> {
    let solid = |t: u32| obj.textures[t as usize].size() == (1, 1);
    if obj.tri_tex.iter().all(|&t| solid(t)) {
        let colours = obj
            .tris
            .iter()
            .zip(&obj.tri_tex)
            .map(|(tri, &t)| {
                let texel = obj.textures[t as usize].level(0).data[0];
                tri.map(|v| tint(texel, v.c))
            })
            .collect();
        return Ok(ColourMode::Vertex(colours));
    }
    bake_atlas(obj).map(|(img, uv)| ColourMode::Texture(img, uv))
}

/// A texel times a colour multiplier, rounded to bytes.
fn tint(texel: [u8; 3], c: Vec3) -> [u8; 3] {
    let c = c.to_array();
    std::array::from_fn(|k| (texel[k] as f32 * c[k] + 0.5).clamp(0.0, 255.0) as u8)
}

fn bake_atlas(obj: &Object) -> Result<(RgbImage, Vec<[Vec2; 3]>), String> {
    // Cells by texture and (uniform) triangle colour, in first-use order.
    let mut cell_of: HashMap<(u32, [u32; 3]), usize> = HashMap::new();
    let mut cells: Vec<Cell> = Vec::new();
    let mut ranges: Vec<[f32; 4]> = Vec::new(); // u0, v0, u1, v1 per cell
    let mut tri_cell = Vec::with_capacity(obj.tris.len());
    let mut tri_uv = Vec::with_capacity(obj.tris.len());
    for (i, (tri, &t)) in obj.tris.iter().zip(&obj.tri_tex).enumerate() {
        let tex = &obj.textures[t as usize];
        if tri[1].c != tri[0].c || tri[2].c != tri[0].c {
            return Err(format!(
                "triangle {i} has varying vertex colours over a texture; a PLY file \
                 colours by a texture or by vertex colours, not both"
            ));
        }
        let uv = tri.map(|v| v.uv);
        if uv.iter().any(|p| !p.is_finite()) {
            return Err(format!("triangle {i} has non-finite texture coordinates"));
        }
        // A repeating texture looks the same shifted by whole repeats:
        // moving each triangle next to the origin keeps cells small.
        let uv = if tex.repeat {
            let lo = uv[0].min(uv[1]).min(uv[2]).floor();
            uv.map(|p| p - lo)
        } else {
            uv
        };
        let key = (t, tri[0].c.to_array().map(f32::to_bits));
        let k = *cell_of.entry(key).or_insert_with(|| {
            cells.push(Cell {
                tex: t,
                colour: tri[0].c,
                x0: 0,
                y0: 0,
                w: 0,
                h: 0,
                ax: 0,
                ay: 0,
            });
            ranges.push([
                f32::INFINITY,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::NEG_INFINITY,
            ]);
            cells.len() - 1
        });
        let r = &mut ranges[k];
        for p in &uv {
            r[0] = r[0].min(p.x);
            r[1] = r[1].min(p.y);
            r[2] = r[2].max(p.x);
            r[3] = r[3].max(p.y);
        }
        tri_cell.push(k);
        tri_uv.push(uv);
    }

    // Each cell covers its triangles' texels plus the padding, aligned.
    for (cell, r) in cells.iter_mut().zip(&ranges) {
        let (tw, th) = obj.textures[cell.tex as usize].size();
        let span = |lo: f32, hi: f32, n: u32| -> Result<(i64, i64), String> {
            let a = (lo as f64 * n as f64).floor() - PAD as f64;
            let b = (hi as f64 * n as f64).ceil() + PAD as f64;
            if (b - a) > MAX_SIDE as f64 {
                return Err(format!(
                    "the texture coordinates of texture {} span {:.0} texels, more than an atlas cell holds ({MAX_SIDE})",
                    cell.tex,
                    b - a
                ));
            }
            let a = (a as i64).div_euclid(ALIGN) * ALIGN;
            let b = (b as i64 + ALIGN - 1).div_euclid(ALIGN) * ALIGN;
            Ok((a, b - a))
        };
        (cell.x0, cell.w) = span(r[0], r[2], tw)?;
        (cell.y0, cell.h) = span(r[1], r[3], th)?;
    }

    // Shelf packing, tallest first, rows about as wide as the atlas is tall.
    let area: i64 = cells.iter().map(|c| c.w * c.h).sum();
    if area > MAX_TEXELS {
        return Err(format!(
            "the textures need {area} atlas texels, more than {MAX_TEXELS}"
        ));
    }
    let widest = cells.iter().map(|c| c.w).max().unwrap_or(ALIGN);
    let row_w = widest.max(((area as f64).sqrt().ceil() as i64 + ALIGN - 1) / ALIGN * ALIGN);
    let mut order: Vec<usize> = (0..cells.len()).collect();
    order.sort_by_key(|&i| (std::cmp::Reverse(cells[i].h), i));
    let (mut x, mut y, mut row_h, mut atlas_w) = (0i64, 0i64, 0i64, 0i64);
    for &i in &order {
        let c = &mut cells[i];
        if x > 0 && x + c.w > row_w {
            (x, y, row_h) = (0, y + row_h, 0);
        }
        (c.ax, c.ay) = (x, y);
        x += c.w;
        row_h = row_h.max(c.h);
        atlas_w = atlas_w.max(x);
    }
    let atlas_h = y + row_h;
    if atlas_w > MAX_SIDE || atlas_h > MAX_SIDE {
        return Err(format!(
            "the atlas would be {atlas_w} x {atlas_h} texels, more than {MAX_SIDE} a side"
        ));
    }

    let mut img = RgbImage::new(atlas_w as u32, atlas_h as u32);
    for c in &cells {
        fill_cell(&mut img, c, &obj.textures[c.tex as usize]);
    }
    let (aw, ah) = (atlas_w as f32, atlas_h as f32);
    let uv = tri_uv
        .iter()
        .zip(&tri_cell)
        .map(|(uv, &k)| {
            let c = &cells[k];
            let (tw, th) = obj.textures[c.tex as usize].size();
            uv.map(|p| {
                Vec2::new(
                    ((c.ax - c.x0) as f32 + p.x * tw as f32) / aw,
                    ((c.ay - c.y0) as f32 + p.y * th as f32) / ah,
                )
            })
        })
        .collect();
    Ok((img, uv))
}

/// Copies a cell's texels (wrapped or clamped, times its colour) into the
/// atlas.
fn fill_cell(img: &mut RgbImage, c: &Cell, tex: &Texture) {
    let level = tex.level(0);
    let (tw, th) = (level.w as i64, level.h as i64);
    let index = |i: i64, n: i64| {
        if tex.repeat {
            i.rem_euclid(n)
        } else {
            i.clamp(0, n - 1)
        }
    };
    let white = c.colour == Vec3::ONE;
    for y in 0..c.h {
        let ty = index(c.y0 + y, th);
        for x in 0..c.w {
            let tx = index(c.x0 + x, tw);
            let texel = level.data[(ty * tw + tx) as usize];
            let px = if white { texel } else { tint(texel, c.colour) };
            img.put_pixel((c.ax + x) as u32, (c.ay + y) as u32, image::Rgb(px));
        }
    }
}
