//! Where each colour sits on the object: the centroid of each palette
//! colour's pixels about the object's centroid, and how far apart two such
//! layouts are.
//!
//! The ACCH sees pixel pairs 10-20 px apart. A mark inside a plain lid has
//! the lid's colour on every side, so its pairs are the same wherever the
//! mark sits: a round object seen from above looks alike turned, and φ is
//! a guess. The layout holds what the histogram lacks: from above, the
//! direction from the object's centre to the mark turns with φ.
//!
//! A layout is `3 x C` floats, per palette colour: its share of the
//! object's mapped pixels, then its centroid's offset from the object's
//! centroid (x right, y down), pixels.

use crate::histogram::Rect;
use crate::palette::{IndexImage, MAX_COLOURS};

/// Floats per colour in a layout: share, offset x, offset y.
pub const LAYOUT_FIELDS: usize = 3;

/// Measures the layout of the object in `roi` (its pixels: `mask` non-zero,
/// or the whole ROI without a mask, mapped to one of the `out.len() / 3`
/// colours) into `out`. Returns the object's mapped pixels; 0 leaves `out`
/// all zero.
pub fn layout_into(image: &IndexImage, mask: Option<&[u8]>, roi: Rect, out: &mut [f32]) -> u32 {
    let colours = out.len() / LAYOUT_FIELDS;
    assert!(
        out.len() == colours * LAYOUT_FIELDS && colours <= MAX_COLOURS,
        "layout length"
    );
    if let Some(m) = mask {
        assert_eq!(m.len(), image.data.len(), "mask size");
    }
    // Sums in f64 about the ROI's corner: a 640 x 480 object's coordinate
    // sums pass what an f32 holds exactly.
    let mut sums = [[0f64; 3]; MAX_COLOURS];
    let roi = roi.clamp_to(image.width, image.height);
    let w = image.width as usize;
    for row in 0..roi.height as usize {
        let start = (roi.y as usize + row) * w + roi.x as usize;
        let span = start..start + roi.width as usize;
        let y = row as f64;
        for (x, &i) in image.data[span.clone()].iter().enumerate() {
            let inside = mask.is_none_or(|m| m[start + x] != 0);
            if inside && (i as usize) < colours {
                let s = &mut sums[i as usize];
                s[0] += 1.0;
                s[1] += x as f64;
                s[2] += y;
            }
        }
    }
    out.fill(0.0);
    let (n, sx, sy) = sums[..colours]
        .iter()
        .fold((0.0, 0.0, 0.0), |(n, x, y), s| {
            (n + s[0], x + s[1], y + s[2])
        });
    if n == 0.0 {
        return 0;
    }
    let (cx, cy) = (sx / n, sy / n);
    for (o, s) in out.chunks_exact_mut(LAYOUT_FIELDS).zip(&sums) {
        if s[0] > 0.0 {
            o[0] = (s[0] / n) as f32;
            o[1] = (s[1] / s[0] - cx) as f32;
            o[2] = (s[2] / s[0] - cy) as f32;
        }
    }
    n as u32
}

/// Multiplies a layout's offsets by `k` (to another scale).
pub fn scale_layout(layout: &mut [f32], k: f32) {
    for c in layout.chunks_exact_mut(LAYOUT_FIELDS) {
        c[1] *= k;
        c[2] *= k;
    }
}

/// Undoes a turn of the image by `deg` counter-clockwise (as seen, y down)
/// on a layout's offsets: a rolled camera's layout made upright.
pub fn unroll_layout(layout: &mut [f32], deg: f32) {
    if deg == 0.0 {
        return;
    }
    let (s, c) = deg.to_radians().sin_cos();
    for o in layout.chunks_exact_mut(LAYOUT_FIELDS) {
        let (x, y) = (o[1], o[2]);
        // Seen with y down, a counter-clockwise turn by a takes (x, y) to
        // (x cos a + y sin a, -x sin a + y cos a); this is its inverse.
        o[1] = x * c - y * s;
        o[2] = x * s + y * c;
    }
}

/// How far apart two layouts of the same palette place their colours:
/// the root mean square of the colours' offset differences, after the mean
/// difference is taken out (an occluder or a segmentation that moves the
/// object's centroid moves every offset alike). Each colour is weighted by
/// the square root of the smaller of its two shares: a small mark, which
/// is what turns with the object, counts for more than its area, a colour
/// one layout lacks for nothing (measured on the robust protocol's
/// development seed against weights by share: docs/accuracy.md). Pixels;
/// 0 when the layouts share fewer than two colours (nothing to place
/// against each other).
pub fn layout_distance(a: &[f32], b: &[f32]) -> f32 {
    debug_assert_eq!(a.len(), b.len(), "layouts of one palette");
    let (mut weight, mut mx, mut my, mut square, mut shared) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0);
    for (p, q) in a
        .chunks_exact(LAYOUT_FIELDS)
        .zip(b.chunks_exact(LAYOUT_FIELDS))
    {
        let share = p[0].min(q[0]);
        if share > 0.0 {
            let w = share.sqrt();
            let (dx, dy) = (p[1] - q[1], p[2] - q[2]);
            weight += w;
            mx += w * dx;
            my += w * dy;
            square += w * (dx * dx + dy * dy);
            shared += 1;
        }
    }
    if shared < 2 {
        return 0.0;
    }
    let (mx, my) = (mx / weight, my / weight);
    (square / weight - mx * mx - my * my).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 60 x 60 disc of colour 0 (radius 25) with a mark of colour 1
    /// (radius 6) at `mark`, on colour 2 around it (masked out).
    fn lid(mark: (f32, f32)) -> (IndexImage, Vec<u8>) {
        let (w, h) = (60u32, 60u32);
        let mut data = vec![2u8; (w * h) as usize];
        let mut mask = vec![0u8; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let (fx, fy) = (x as f32 - 29.5, y as f32 - 29.5);
                let i = (y * w + x) as usize;
                if fx * fx + fy * fy <= 25.0 * 25.0 {
                    mask[i] = 1;
                    let (mx, my) = (fx - mark.0, fy - mark.1);
                    data[i] = u8::from(mx * mx + my * my <= 36.0);
                }
            }
        }
        (IndexImage::new(w, h, data), mask)
    }

    fn measured(mark: (f32, f32)) -> Vec<f32> {
        let (image, mask) = lid(mark);
        let mut out = vec![0.0; 3 * LAYOUT_FIELDS];
        layout_into(&image, Some(&mask), Rect::full(60, 60), &mut out);
        out
    }

    #[test]
    fn a_mark_sits_where_it_was_painted() {
        let l = measured((12.0, 0.0));
        // Shares: the mark's disc against the lid's; colour 2 is masked out.
        let mark_share = l[3];
        assert!((mark_share - 36.0 / 625.0).abs() < 0.01, "{mark_share}");
        assert_eq!(l[6], 0.0);
        // The mark 12 px right of the centre, the lid's rest a little left:
        // the shares' moments balance about the centroid.
        let (lid_x, mark_x) = (l[1], l[4]);
        assert!(mark_x > 10.0 && mark_x < 12.5, "{mark_x}");
        assert!(lid_x < 0.0);
        assert!((l[0] * lid_x + mark_share * mark_x).abs() < 1e-3);
        assert!(l[2].abs() < 0.1 && l[5].abs() < 0.1);
    }

    #[test]
    fn the_distance_tells_turned_lids_apart_and_not_a_moved_centroid() {
        let right = measured((12.0, 0.0));
        let below = measured((0.0, 12.0));
        let left = measured((-12.0, 0.0));
        assert_eq!(layout_distance(&right, &right), 0.0);
        let quarter = layout_distance(&right, &below);
        let half = layout_distance(&right, &left);
        assert!(quarter > 1.0 && half > quarter, "{quarter} {half}");
        // Every offset moved alike (the centroid found elsewhere): the same
        // layout.
        let mut moved = right.clone();
        for c in moved.chunks_exact_mut(LAYOUT_FIELDS) {
            c[1] += 7.0;
            c[2] -= 3.0;
        }
        assert!(layout_distance(&right, &moved) < 1e-3);
        // One colour alone places nothing.
        let mut one = right.clone();
        one[3] = 0.0;
        assert_eq!(layout_distance(&one, &below), 0.0);
    }

    #[test]
    fn a_turned_layout_unrolled_is_the_upright_one() {
        // The mark right of the centre, the image then turned 90°
        // counter-clockwise as seen: the mark is above the centre (y up is
        // negative).
        let upright = measured((12.0, 0.0));
        let mut turned = measured((0.0, -12.0));
        assert!(layout_distance(&upright, &turned) > 1.0);
        unroll_layout(&mut turned, 90.0);
        for (a, b) in upright.iter().zip(&turned) {
            assert!((a - b).abs() < 0.05, "{upright:?} {turned:?}");
        }
    }

    #[test]
    fn nothing_mapped_measures_nothing() {
        let image = IndexImage::new(4, 4, vec![crate::NOT_OBJECT; 16]);
        let mut out = vec![1.0; 2 * LAYOUT_FIELDS];
        assert_eq!(layout_into(&image, None, Rect::full(4, 4), &mut out), 0);
        assert!(out.iter().all(|&v| v == 0.0));
    }
}
