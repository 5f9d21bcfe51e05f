//! The image's edges: the colour gradient of each pixel, taken from the
//! channel where it is strongest (as LINE-2D does), so an edge between two
//! colours of equal brightness still counts. Its direction, not its sign,
//! is compared with a contour's: the object may be brighter or darker than
//! what lies behind it.

/// The gradient of every pixel of an image.
#[derive(Clone, Debug, Default)]
pub struct Edges {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Horizontal gradient (Sobel, the strongest channel), per pixel.
    pub gx: Vec<f32>,
    /// Vertical gradient, per pixel.
    pub gy: Vec<f32>,
}

impl Edges {
    /// Computes the gradients of a packed RGB image into `self`, reusing
    /// its buffers.
    pub fn compute(&mut self, rgb: &[u8], width: usize, height: usize) {
        self.compute_in(rgb, width, height, [0, 0, width, height]);
    }

    /// Computes the gradients of the pixels in `[x0, y0, x1, y1)` only
    /// (zero elsewhere): the region about an object is all a fit reads.
    pub fn compute_in(&mut self, rgb: &[u8], width: usize, height: usize, rect: [usize; 4]) {
        assert_eq!(rgb.len(), 3 * width * height, "packed RGB of the size");
        self.width = width;
        self.height = height;
        self.gx.clear();
        self.gx.resize(width * height, 0.0);
        self.gy.clear();
        self.gy.resize(width * height, 0.0);
        if width < 3 || height < 3 {
            return;
        }
        let at = |x: usize, y: usize, c: usize| rgb[3 * (y * width + x) + c] as f32;
        let [x0, y0, x1, y1] = rect;
        for y in y0.max(1)..y1.min(height - 1) {
            for x in x0.max(1)..x1.min(width - 1) {
                let (mut best, mut bx, mut by) = (-1.0f32, 0.0, 0.0);
                for c in 0..3 {
                    let gx = (at(x + 1, y - 1, c) + 2.0 * at(x + 1, y, c) + at(x + 1, y + 1, c))
                        - (at(x - 1, y - 1, c) + 2.0 * at(x - 1, y, c) + at(x - 1, y + 1, c));
                    let gy = (at(x - 1, y + 1, c) + 2.0 * at(x, y + 1, c) + at(x + 1, y + 1, c))
                        - (at(x - 1, y - 1, c) + 2.0 * at(x, y - 1, c) + at(x + 1, y - 1, c));
                    let m = gx * gx + gy * gy;
                    if m > best {
                        (best, bx, by) = (m, gx, gy);
                    }
                }
                let i = y * width + x;
                self.gx[i] = bx;
                self.gy[i] = by;
            }
        }
    }

    /// The gradient at the pixel nearest `(x, y)`; zero outside the image.
    #[inline]
    pub fn at(&self, x: f64, y: f64) -> (f32, f32) {
        let (xi, yi) = (x.round(), y.round());
        if xi < 0.0 || yi < 0.0 || xi >= self.width as f64 || yi >= self.height as f64 {
            return (0.0, 0.0);
        }
        let i = yi as usize * self.width + xi as usize;
        (self.gx[i], self.gy[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edge_between_two_colours_of_one_brightness_is_found_across_it() {
        // Left half red, right half green, equally bright.
        let (w, h) = (20, 10);
        let mut rgb = vec![0u8; 3 * w * h];
        for y in 0..h {
            for x in 0..w {
                let o = 3 * (y * w + x);
                if x < 10 {
                    rgb[o] = 200;
                } else {
                    rgb[o + 1] = 200;
                }
            }
        }
        let mut e = Edges::default();
        e.compute(&rgb, w, h);
        let (gx, gy) = e.at(9.0, 5.0);
        assert!(gx.abs() > 500.0 && gy.abs() < 1e-3, "{gx} {gy}");
        assert_eq!(e.at(4.0, 5.0), (0.0, 0.0));
        assert_eq!(e.at(-1.0, 5.0), (0.0, 0.0));
    }
}
