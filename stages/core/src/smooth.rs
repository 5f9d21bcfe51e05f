//! Smoothing a frame before it is quantised: a 5x5 binomial kernel
//! ([1 4 6 4 1] / 16 along each axis, a Gaussian of sigma 1 px).
//!
//! Why: a camera's blur mixes neighbouring inks into colours of their own,
//! and the histogram of a blurred frame is far from that of a sharp
//! training view (2 px of blur made 42-56 % of the estimates of generated
//! objects wrong). With training views and frames smoothed alike, a sharp
//! frame matches its views as before, and a blurred one is only a little
//! more blurred than they are (docs/accuracy.md, "A blurred camera").

use std::cell::RefCell;

/// How a palette's frames are smoothed before quantisation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Smoothing {
    /// Quantised as they are (databases trained before smoothing).
    #[default]
    Off,
    /// The 5x5 binomial kernel, sigma 1 px.
    Binomial,
}

impl Smoothing {
    /// Every smoothing, in the order their names are listed.
    pub const ALL: [Smoothing; 2] = [Smoothing::Off, Smoothing::Binomial];

    /// Its identifier in a database file.
    pub fn id(self) -> u8 {
        match self {
            Smoothing::Off => 0,
            Smoothing::Binomial => 1,
        }
    }

    /// The smoothing of identifier `id`, if known.
    pub fn from_id(id: u8) -> Option<Self> {
        match id {
            0 => Some(Smoothing::Off),
            1 => Some(Smoothing::Binomial),
            _ => None,
        }
    }

    /// Its name on command lines and in configurations.
    pub fn name(self) -> &'static str {
        match self {
            Smoothing::Off => "off",
            Smoothing::Binomial => "binomial",
        }
    }
}

impl std::str::FromStr for Smoothing {
    type Err = String;

    /// `off` or `binomial`, in any case.
    fn from_str(s: &str) -> Result<Self, String> {
        Smoothing::ALL
            .into_iter()
            .find(|m| m.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                let names: Vec<_> = Smoothing::ALL.map(Smoothing::name).into();
                format!("unknown smoothing '{s}' (expected {})", names.join(" or "))
            })
    }
}

thread_local! {
    /// Scratch of the horizontal pass and the smoothed frame, kept per
    /// thread so that quantising a stream of frames allocates nothing once
    /// warm (a palette is shared by every stage and lane that reads it).
    static SCRATCH: RefCell<(Vec<u16>, Vec<u8>)> = const { RefCell::new((Vec::new(), Vec::new())) };
}

/// Calls `f` with `rgb` (packed, `width x height`) smoothed by the binomial
/// kernel, edges replicated.
pub fn with_smoothed<R>(rgb: &[u8], width: u32, height: u32, f: impl FnOnce(&[u8]) -> R) -> R {
    SCRATCH.with(|scratch| {
        let mut scratch = scratch.borrow_mut();
        let (rows, out) = &mut *scratch;
        binomial_into(rgb, width as usize, height as usize, rows, out);
        f(out)
    })
}

/// `rgb` smoothed by the binomial kernel into `out` (resized), through the
/// horizontal pass in `rows`. Integer arithmetic, rounded: the same bytes
/// on every machine.
pub fn binomial_into(
    rgb: &[u8],
    width: usize,
    height: usize,
    rows: &mut Vec<u16>,
    out: &mut Vec<u8>,
) {
    let n = width * height * 3;
    assert_eq!(rgb.len(), n, "RGB buffer does not match {width}x{height}");
    rows.resize(n, 0);
    out.resize(n, 0);
    if n == 0 {
        return;
    }
    // Horizontal: [1 4 6 4 1], at most 16 x 255; the interior in flat
    // slices (vectorised), the two pixels at each end with edges replicated.
    let stride = width * 3;
    let clamp = |x: isize| x.clamp(0, width as isize - 1) as usize;
    for y in 0..height {
        let src = &rgb[y * stride..][..stride];
        let dst = &mut rows[y * stride..][..stride];
        if width > 4 {
            let inner = stride - 12;
            let taps = (
                &src[..inner],
                &src[3..][..inner],
                &src[6..][..inner],
                &src[9..][..inner],
                &src[12..][..inner],
            );
            for (i, d) in dst[6..][..inner].iter_mut().enumerate() {
                *d = taps.0[i] as u16
                    + 4 * taps.1[i] as u16
                    + 6 * taps.2[i] as u16
                    + 4 * taps.3[i] as u16
                    + taps.4[i] as u16;
            }
        }
        for x in (0..width).filter(|&x| x < 2 || x + 2 >= width) {
            let at = |d: isize| clamp(x as isize + d) * 3;
            let (a, b, c, e, f) = (at(-2), at(-1), x * 3, at(1), at(2));
            for ch in 0..3 {
                dst[c + ch] = src[a + ch] as u16
                    + 4 * src[b + ch] as u16
                    + 6 * src[c + ch] as u16
                    + 4 * src[e + ch] as u16
                    + src[f + ch] as u16;
            }
        }
    }
    // Vertical: [1 4 6 4 1] over the horizontal sums, at most 256 x 255 =
    // 65 280, so u16 lanes hold it (twice as many per vector as u32);
    // divided by 256 with rounding.
    let row = |y: isize| &rows[(y.clamp(0, height as isize - 1) as usize) * stride..][..stride];
    for y in 0..height {
        let yi = y as isize;
        let (r0, r1, r2, r3, r4) = (row(yi - 2), row(yi - 1), row(yi), row(yi + 1), row(yi + 2));
        let dst = &mut out[y * stride..][..stride];
        for i in 0..stride {
            let s = r0[i] + 4 * r1[i] + 6 * r2[i] + 4 * r3[i] + r4[i];
            dst[i] = ((s + 128) >> 8) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn smoothed(rgb: &[u8], w: usize, h: usize) -> Vec<u8> {
        let (mut rows, mut out) = (Vec::new(), Vec::new());
        binomial_into(rgb, w, h, &mut rows, &mut out);
        out
    }

    #[test]
    fn smoothing_is_named_as_it_is_parsed() {
        for m in [Smoothing::Off, Smoothing::Binomial] {
            assert_eq!(m.name().parse::<Smoothing>(), Ok(m));
            assert_eq!(m.name().to_uppercase().parse::<Smoothing>(), Ok(m));
        }
        let err = "gaussian".parse::<Smoothing>().unwrap_err();
        assert!(err.contains("'gaussian'"), "{err}");
    }

    #[test]
    fn a_flat_frame_stays_as_it_is() {
        let rgb: Vec<u8> = [10u8, 200, 255].repeat(7 * 5);
        assert_eq!(smoothed(&rgb, 7, 5), rgb);
    }

    #[test]
    fn an_edge_becomes_the_kernels_ramp() {
        // Left half 0, right half 255, every row alike.
        let (w, h) = (8, 3);
        let rgb: Vec<u8> = (0..w * h)
            .flat_map(|i| [if i % w < 4 { 0 } else { 255 }; 3])
            .collect();
        let out = smoothed(&rgb, w, h);
        let row: Vec<u8> = out[..w * 3].iter().step_by(3).copied().collect();
        // Cumulative [1 4 6 4 1] / 16 across the edge, times 255.
        assert_eq!(row, vec![0, 0, 16, 80, 175, 239, 255, 255]);
        assert!(out.chunks(w * 3).all(|r| r == &out[..w * 3]));
    }

    #[test]
    fn a_single_bright_pixel_spreads_as_the_kernel() {
        let (w, h) = (5, 5);
        let mut rgb = vec![0u8; w * h * 3];
        rgb[(2 * w + 2) * 3] = 255;
        let out = smoothed(&rgb, w, h);
        let red: Vec<u32> = out.iter().step_by(3).map(|&v| v as u32).collect();
        // 255 x 36 / 256 in the middle, 255 / 256 in the corners.
        assert_eq!(red[2 * w + 2], 36);
        assert_eq!(red[0], 1);
        assert_eq!(red[2 * w], 6);
        assert!(out.iter().skip(1).step_by(3).all(|&g| g == 0));
    }

    #[test]
    fn the_thread_scratch_serves_frames_of_any_size() {
        let a: Vec<u8> = (0..4 * 3 * 3).map(|i| (i * 7) as u8).collect();
        let b: Vec<u8> = (0..9 * 6 * 3).map(|i| (i * 5) as u8).collect();
        for (rgb, w, h) in [(&a, 4, 3), (&b, 9, 6), (&a, 4, 3)] {
            let direct = smoothed(rgb, w, h);
            with_smoothed(rgb, w as u32, h as u32, |s| assert_eq!(s, &direct[..]));
        }
    }
}
