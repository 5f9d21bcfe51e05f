//! The triangle rasteriser (z-buffer, perspective-correct texturing,
//! per-vertex Lambert + ambient shading times the vertex colour) and the
//! ray-cast table plane.

use glam::{DAffine3, DMat3, DVec3, Vec3};

use crate::Intrinsics;
use crate::object::Object;
use crate::texture::{Level, Texture};

/// Light that reaches every surface regardless of orientation.
pub(crate) const AMBIENT: f32 = 0.45;
/// Strength of the directional light (Lambert).
pub(crate) const DIFFUSE: f32 = 0.6;
/// Near clipping plane (camera z) in object bounding radii.
const NEAR: f64 = 1e-2;
/// Table points farther than this from the camera show the wall colour.
const FAR: f64 = 60.0;

/// The light direction in the world (towards the light): from above and
/// slightly to one side, so box sides differ in brightness.
pub(crate) fn light_world() -> DVec3 {
    DVec3::new(0.35, -0.25, 1.0).normalize()
}

/// The buffers one frame is drawn into.
pub(crate) struct Frame<'a> {
    /// RGB bytes, row-major.
    pub rgb: &'a mut [u8],
    /// 255 where the target is the nearest surface, else 0.
    pub mask: &'a mut [u8],
    /// 1/z of the nearest surface so far (0 = nothing: the table is behind all).
    pub depth: &'a mut [f32],
    pub w: usize,
    pub h: usize,
}

/// A vertex in the camera frame with its attributes.
#[derive(Clone, Copy)]
struct CamVertex {
    p: DVec3,
    u: f32,
    v: f32,
    /// Light times the vertex colour, per channel.
    shade: [f32; 3],
}

/// A projected vertex; attributes are pre-divided by z for perspective-correct
/// interpolation.
#[derive(Clone, Copy)]
struct ScreenVertex {
    x: f64,
    y: f64,
    iz: f32,
    uz: f32,
    vz: f32,
    sz: [f32; 3],
}

fn project(c: CamVertex, k: &Intrinsics) -> ScreenVertex {
    let iz = 1.0 / c.p.z;
    ScreenVertex {
        x: k.fx * c.p.x * iz + k.cx,
        y: k.fy * c.p.y * iz + k.cy,
        iz: iz as f32,
        uz: c.u * iz as f32,
        vz: c.v * iz as f32,
        sz: c.shade.map(|s| s * iz as f32),
    }
}

/// Draws every triangle of `obj`, writing `mask_value` into the mask where it
/// becomes the nearest surface.
pub(crate) fn draw_object(
    frame: &mut Frame,
    obj: &Object,
    cam_from_obj: &DAffine3,
    light_cam: DVec3,
    k: &Intrinsics,
    mask_value: u8,
) {
    let m3 = cam_from_obj.matrix3;
    for (tri, &ti) in obj.tris.iter().zip(&obj.tri_tex) {
        let tex = &obj.textures[ti as usize];
        let pc = tri.map(|v| cam_from_obj.transform_point3(v.p.as_dvec3()));
        if pc.iter().all(|p| p.z.is_nan() || p.z < NEAR) {
            continue;
        }
        // Light both sides: meshes may have inconsistent winding or be open,
        // so orient each vertex normal towards the side the camera sees.
        let face = (pc[1] - pc[0]).cross(pc[2] - pc[0]);
        let facing = if face.dot(pc[0]) <= 0.0 { face } else { -face };
        let cv: [CamVertex; 3] = std::array::from_fn(|j| {
            let mut n = m3 * tri[j].n.as_dvec3();
            if n.dot(facing) < 0.0 {
                n = -n;
            }
            let lambert = n.normalize_or_zero().dot(light_cam).max(0.0) as f32;
            let shade = AMBIENT + DIFFUSE * lambert;
            // Times exactly 1.0 for white: textured meshes shade as before.
            let c = tri[j].c;
            CamVertex {
                p: pc[j],
                u: tri[j].uv.x,
                v: tri[j].uv.y,
                shade: [shade * c.x, shade * c.y, shade * c.z],
            }
        });
        // White triangles interpolate one shade, not three.
        let coloured = tri.iter().any(|v| v.c != Vec3::ONE);
        let draw = |frame: &mut Frame, sv: &[ScreenVertex; 3], level: &Level| {
            if coloured {
                raster::<true>(frame, sv, level, tex.repeat, mask_value);
            } else {
                raster::<false>(frame, sv, level, tex.repeat, mask_value);
            }
        };
        if pc.iter().all(|p| p.z >= NEAR) {
            let sv = cv.map(|c| project(c, k));
            let level = tex.level_for_lod(triangle_lod(&sv, &cv, tex));
            draw(frame, &sv, level);
        } else {
            // Crosses the near plane: clip (rare; objects are far from the camera).
            let (poly, n) = clip_near(&cv);
            for i in 1..n.saturating_sub(1) {
                let sv = [poly[0], poly[i], poly[i + 1]].map(|c| project(c, k));
                draw(frame, &sv, tex.level(0));
            }
        }
    }
}

/// Mip level of detail for a whole triangle: log2 of texels per pixel,
/// from the ratio of its texture-space and screen-space areas.
fn triangle_lod(sv: &[ScreenVertex; 3], cv: &[CamVertex; 3], tex: &Texture) -> f32 {
    let screen = ((sv[1].x - sv[0].x) * (sv[2].y - sv[0].y)
        - (sv[1].y - sv[0].y) * (sv[2].x - sv[0].x))
        .abs();
    let (tw, th) = tex.size();
    let texel = (((cv[1].u - cv[0].u) * (cv[2].v - cv[0].v)
        - (cv[1].v - cv[0].v) * (cv[2].u - cv[0].u))
        .abs() as f64)
        * tw as f64
        * th as f64;
    if screen > 1e-12 && texel > 0.0 {
        (0.5 * (texel / screen).log2()) as f32
    } else {
        0.0
    }
}

/// Sutherland-Hodgman clip of a triangle against z >= NEAR (at most 4 vertices).
fn clip_near(v: &[CamVertex; 3]) -> ([CamVertex; 4], usize) {
    let mut out = [v[0]; 4];
    let mut n = 0;
    for i in 0..3 {
        let a = v[i];
        let b = v[(i + 1) % 3];
        let (ia, ib) = (a.p.z >= NEAR, b.p.z >= NEAR);
        if ia {
            out[n] = a;
            n += 1;
        }
        if ia != ib {
            let t = (NEAR - a.p.z) / (b.p.z - a.p.z);
            let tf = t as f32;
            out[n] = CamVertex {
                p: a.p + (b.p - a.p) * t,
                u: a.u + (b.u - a.u) * tf,
                v: a.v + (b.v - a.v) * tf,
                shade: std::array::from_fn(|c| a.shade[c] + (b.shade[c] - a.shade[c]) * tf),
            };
            n += 1;
        }
    }
    (out, n)
}

/// Edge function `a*x + b*y + c`, positive inside, with the tie-break that
/// makes pixels on an edge shared by two triangles belong to exactly one.
#[derive(Clone, Copy)]
struct Edge {
    a: f64,
    b: f64,
    c: f64,
    include_zero: bool,
}

impl Edge {
    fn new(p: &ScreenVertex, q: &ScreenVertex) -> Edge {
        let a = -(q.y - p.y);
        let b = q.x - p.x;
        Edge {
            a,
            b,
            c: -(a * p.x + b * p.y),
            include_zero: a > 0.0 || (a == 0.0 && b < 0.0),
        }
    }

    #[inline(always)]
    fn inside(&self, e: f64) -> bool {
        e > 0.0 || (e == 0.0 && self.include_zero)
    }
}

/// Scan-converts one triangle. Pixel centres are at integer coordinates.
/// `COLOURED`: the three shade channels differ (a vertex-coloured
/// triangle); else channel 0 stands for all three.
fn raster<const COLOURED: bool>(
    frame: &mut Frame,
    v: &[ScreenVertex; 3],
    level: &Level,
    repeat: bool,
    mask_value: u8,
) {
    let (a, mut b, mut c) = (v[0], v[1], v[2]);
    let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if area.is_nan() || area.abs() <= 1e-9 {
        return; // degenerate or NaN
    }
    if area < 0.0 {
        std::mem::swap(&mut b, &mut c);
    }
    let inv_area = 1.0 / area.abs();
    let (wmax, hmax) = ((frame.w - 1) as f64, (frame.h - 1) as f64);
    let minx = a.x.min(b.x).min(c.x).max(0.0).ceil();
    let maxx = a.x.max(b.x).max(c.x).min(wmax).floor();
    let miny = a.y.min(b.y).min(c.y).max(0.0).ceil();
    let maxy = a.y.max(b.y).max(c.y).min(hmax).floor();
    if !(minx <= maxx && miny <= maxy) {
        return;
    }
    let (x0, x1, y0, y1) = (minx as usize, maxx as usize, miny as usize, maxy as usize);
    // Edge opposite each vertex: its value / area is that vertex's weight.
    let e = [Edge::new(&b, &c), Edge::new(&c, &a), Edge::new(&a, &b)];
    let w = frame.w;
    for y in y0..=y1 {
        let fy = y as f64;
        // The span of this row inside all three half-planes (padded by a
        // pixel; the exact test below decides).
        let (mut lo, mut hi) = (x0 as f64, x1 as f64);
        for ed in &e {
            if ed.a != 0.0 {
                let xb = -(ed.b * fy + ed.c) / ed.a;
                if ed.a > 0.0 {
                    lo = lo.max(xb.floor() - 1.0);
                } else {
                    hi = hi.min(xb.ceil() + 1.0);
                }
            }
        }
        if lo.is_nan() || hi.is_nan() || lo > hi {
            continue;
        }
        let (xs, xe) = (lo as usize, hi as usize);
        let fx = xs as f64;
        let mut w0 = e[0].a * fx + e[0].b * fy + e[0].c;
        let mut w1 = e[1].a * fx + e[1].b * fy + e[1].c;
        let mut w2 = e[2].a * fx + e[2].b * fy + e[2].c;
        let row = y * w;
        for x in xs..=xe {
            if e[0].inside(w0) && e[1].inside(w1) && e[2].inside(w2) {
                let b0 = (w0 * inv_area) as f32;
                let b1 = (w1 * inv_area) as f32;
                let b2 = (w2 * inv_area) as f32;
                let iz = b0 * a.iz + b1 * b.iz + b2 * c.iz;
                let idx = row + x;
                if iz > frame.depth[idx] {
                    frame.depth[idx] = iz;
                    let z = 1.0 / iz;
                    let u = (b0 * a.uz + b1 * b.uz + b2 * c.uz) * z;
                    let vv = (b0 * a.vz + b1 * b.vz + b2 * c.vz) * z;
                    let s0 = (b0 * a.sz[0] + b1 * b.sz[0] + b2 * c.sz[0]) * z;
                    let (s1, s2) = if COLOURED {
                        (
                            (b0 * a.sz[1] + b1 * b.sz[1] + b2 * c.sz[1]) * z,
                            (b0 * a.sz[2] + b1 * b.sz[2] + b2 * c.sz[2]) * z,
                        )
                    } else {
                        (s0, s0)
                    };
                    let t = level.sample(u, vv, repeat);
                    let o = idx * 3;
                    frame.rgb[o] = (t[0] * s0 + 0.5).min(255.0) as u8;
                    frame.rgb[o + 1] = (t[1] * s1 + 0.5).min(255.0) as u8;
                    frame.rgb[o + 2] = (t[2] * s2 + 0.5).min(255.0) as u8;
                    frame.mask[idx] = mask_value;
                }
            }
            w0 += e[0].a;
            w1 += e[1].a;
            w2 += e[2].a;
        }
    }
}

/// Ray-casts the table plane `z = table_z` for every pixel: the hit point's
/// world x, y index the tiling texture (`tile` world units per repeat), with
/// the mip level chosen from the pixel's footprint on the plane. Pixels whose
/// rays miss the table (or hit it very far away) show `wall`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn draw_table(
    frame: &mut Frame,
    tex: &Texture,
    tile: f64,
    world_from_cam: &DMat3,
    centre: DVec3,
    k: &Intrinsics,
    table_z: f64,
    wall: [u8; 3],
) {
    /// Pixels per run sharing one mip level (the footprint varies slowly).
    const SPAN: usize = 16;
    let shade = AMBIENT + DIFFUSE * light_world().z.max(0.0) as f32;
    let shade_q8 = (shade * 256.0).round() as u64;
    let (right, down, fwd) = (
        world_from_cam.x_axis,
        world_from_cam.y_axis,
        world_from_cam.z_axis,
    );
    let tpu = tex.size().0 as f64 / tile;
    let inv_tile = 1.0 / tile;
    let step = right / k.fx;
    // Rays hit the plane at t = num / d.z with d.z < 0 (camera above it).
    let num = table_z - centre.z;
    for y in 0..frame.h {
        let dy = (y as f64 - k.cy) / k.fy;
        let d0 = fwd + down * dy - right * (k.cx / k.fx);
        // Along the row the ray is d0 + step x, so the hit point's
        // coordinates are ratios of linear functions of x: one division
        // per pixel.
        let (ax, bx) = (
            (centre.x * d0.z + num * d0.x) * inv_tile,
            (centre.x * step.z + num * step.x) * inv_tile,
        );
        let (ay, by) = (
            (centre.y * d0.z + num * d0.y) * inv_tile,
            (centre.y * step.z + num * step.y) * inv_tile,
        );
        // |d|^2 as a quadratic in x, for the far cut-off.
        let (q0, q1, q2) = (
            d0.length_squared(),
            2.0 * d0.dot(step),
            step.length_squared(),
        );
        let row = &mut frame.rgb[y * frame.w * 3..(y + 1) * frame.w * 3];
        for (s, span) in row.chunks_mut(SPAN * 3).enumerate() {
            let x0 = s * SPAN;
            // Mip level from the footprint (in texels) at the span's middle:
            // pixel angle x range, stretched by the slant (geometric mean).
            let xm = (x0 + span.len() / 6) as f64;
            let dm = d0 + step * xm;
            let level = if num < 0.0 && dm.z < -1e-9 {
                let len = dm.length();
                let fp = (num / dm.z * len / k.fx * (len / -dm.z).sqrt() * tpu) as f32;
                // floor(log2(fp)) from the float's exponent field.
                if fp >= 1.0 {
                    ((fp.to_bits() >> 23) & 0xff) as usize - 127
                } else {
                    0
                }
            } else {
                usize::MAX // horizon: the coarsest level
            };
            let lvl = tex.level(level);
            for (i, px) in span.chunks_exact_mut(3).enumerate() {
                let x = (x0 + i) as f64;
                let dz = d0.z + step.z * x;
                let inv = 1.0 / dz;
                let t = num * inv;
                let col = if dz < -1e-9 && num < 0.0 && t * t * (q0 + x * (q1 + x * q2)) < FAR * FAR
                {
                    lvl.sample_repeat_q8(
                        ((ax + bx * x) * inv) as f32,
                        ((ay + by * x) * inv) as f32,
                        shade_q8,
                    )
                } else {
                    wall
                };
                px.copy_from_slice(&col);
            }
        }
    }
}
