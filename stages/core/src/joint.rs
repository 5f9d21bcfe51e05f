//! Several palettes' quantisation in one pass over a frame. Every palette
//! quantises through a lookup table over the same RGB cells, so one table
//! numbering each cell's tuple of the palettes' indices (a joint colour)
//! reads the frame once for all of them; a small table per palette then
//! turns joint colours into its indices, the same indices its own pass
//! gives. Several known objects' recognitions share the pass, and the
//! smoothing before it (docs/multi.md, "Shared quantisation").

use crate::palette::{LUT_CELLS, Palette, lut_cell};
use crate::smooth::{self, Smoothing};
use std::collections::HashMap;

/// Most joint colours a joint palette can number.
pub const MAX_JOINT_COLOURS: usize = u16::MAX as usize + 1;

/// Why palettes could not be joined.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum JointPaletteError {
    /// No palette was given.
    #[error("no palette to join")]
    Empty,
    /// The palettes smooth frames differently, so no one pass serves them.
    #[error(
        "palette {index} smooths frames with {found:?}, palette 0 with {first:?}: one pass cannot serve both"
    )]
    Smoothing {
        /// The first palette that differs.
        index: usize,
        /// Its smoothing.
        found: Smoothing,
        /// The first palette's.
        first: Smoothing,
    },
    /// The palettes split colour space into more joint colours than a
    /// label holds.
    #[error("the palettes make more than {MAX_JOINT_COLOURS} joint colours")]
    TooManyColours,
}

/// One quantisation pass for several palettes: [`label`](Self::label) a
/// frame once, then [`indices`](Self::indices) per palette.
#[derive(Clone, Debug)]
pub struct JointPalette {
    smoothing: Smoothing,
    /// Per lookup cell: its joint colour.
    labels: Vec<u16>,
    /// Per palette: joint colour -> the palette's index.
    tables: Vec<Vec<u8>>,
}

impl JointPalette {
    /// Joins `palettes`, which must smooth frames alike.
    pub fn new(palettes: &[&Palette]) -> Result<Self, JointPaletteError> {
        let first = palettes.first().ok_or(JointPaletteError::Empty)?;
        if let Some((index, p)) = palettes
            .iter()
            .enumerate()
            .find(|(_, p)| p.smoothing() != first.smoothing())
        {
            return Err(JointPaletteError::Smoothing {
                index,
                found: p.smoothing(),
                first: first.smoothing(),
            });
        }
        let mut labels = vec![0u16; LUT_CELLS];
        let mut tables: Vec<Vec<u8>> = vec![Vec::new(); palettes.len()];
        let mut numbers: HashMap<Box<[u8]>, u16> = HashMap::new();
        let mut tuple = vec![0u8; palettes.len()];
        for (cell, label) in labels.iter_mut().enumerate() {
            for (t, p) in tuple.iter_mut().zip(palettes) {
                *t = p.lut()[cell];
            }
            *label = match numbers.get(tuple.as_slice()) {
                Some(&n) => n,
                None => {
                    let n = u16::try_from(numbers.len())
                        .map_err(|_| JointPaletteError::TooManyColours)?;
                    numbers.insert(tuple.clone().into_boxed_slice(), n);
                    for (table, &i) in tables.iter_mut().zip(&tuple) {
                        table.push(i);
                    }
                    n
                }
            };
        }
        Ok(JointPalette {
            smoothing: first.smoothing(),
            labels,
            tables,
        })
    }

    /// Palettes joined.
    pub fn len(&self) -> usize {
        self.tables.len()
    }

    /// Whether no palette is joined (never: [`new`](Self::new) refuses).
    pub fn is_empty(&self) -> bool {
        self.tables.is_empty()
    }

    /// Joint colours: the distinct tuples of the palettes' indices.
    pub fn colours(&self) -> usize {
        self.tables.first().map_or(0, Vec::len)
    }

    /// How the joined palettes smooth a frame before quantising it.
    pub fn smoothing(&self) -> Smoothing {
        self.smoothing
    }

    /// Labels a packed RGB frame of `width x height` (smoothed first as
    /// the palettes smooth) into `labels`, one joint colour per pixel;
    /// panics if the lengths do not match.
    pub fn label(&self, rgb: &[u8], width: u32, height: u32, labels: &mut [u16]) {
        match self.smoothing {
            Smoothing::Off => self.label_pixels(rgb, labels),
            Smoothing::Binomial => {
                smooth::with_smoothed(rgb, width, height, |s| self.label_pixels(s, labels))
            }
        }
    }

    /// Labels packed RGB pixels already smoothed as the palettes smooth
    /// (a band of a frame, say, so that threads share a frame); panics if
    /// the lengths do not match.
    pub fn label_pixels(&self, rgb: &[u8], labels: &mut [u16]) {
        assert_eq!(rgb.len(), labels.len() * 3, "RGB and label lengths differ");
        for (l, px) in labels.iter_mut().zip(rgb.chunks_exact(3)) {
            *l = self.labels[lut_cell([px[0], px[1], px[2]])];
        }
    }

    /// Palette `palette`'s indices of labelled pixels into `out`: what
    /// that palette's own quantisation gives. Panics if the lengths differ
    /// or there is no such palette.
    pub fn indices(&self, palette: usize, labels: &[u16], out: &mut [u8]) {
        assert_eq!(labels.len(), out.len(), "label and index lengths differ");
        let table = &self.tables[palette];
        for (o, &l) in out.iter_mut().zip(labels) {
            *o = table[l as usize];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ColourSpace;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn palette(seed: u64, colours: usize) -> Palette {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let centres = (0..colours)
            .map(|_| std::array::from_fn(|_| rng.random_range(0.0..255.0)))
            .collect();
        // Some colours rejected, so "not object" is joined too.
        Palette::from_centres(ColourSpace::Rgb, centres, 90.0).unwrap()
    }

    fn frame(seed: u64, width: u32, height: u32) -> Vec<u8> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..width * height * 3).map(|_| rng.random()).collect()
    }

    fn joined_indices(joint: &JointPalette, rgb: &[u8], width: u32, height: u32) -> Vec<Vec<u8>> {
        let mut labels = vec![0u16; (width * height) as usize];
        joint.label(rgb, width, height, &mut labels);
        (0..joint.len())
            .map(|k| {
                let mut out = vec![0u8; labels.len()];
                joint.indices(k, &labels, &mut out);
                out
            })
            .collect()
    }

    #[test]
    fn each_palettes_indices_are_its_own_quantisations() {
        for smoothing in [Smoothing::Off, Smoothing::Binomial] {
            let palettes: Vec<Palette> = (0..4)
                .map(|s| palette(s, 8 + 4 * s as usize).with_smoothing(smoothing))
                .collect();
            let refs: Vec<&Palette> = palettes.iter().collect();
            let joint = JointPalette::new(&refs).unwrap();
            assert_eq!(joint.len(), 4);
            assert!(joint.colours() > 32, "{} joint colours", joint.colours());
            let (w, h) = (37, 23);
            let rgb = frame(9, w, h);
            let own: Vec<Vec<u8>> = palettes
                .iter()
                .map(|p| p.quantise(&rgb, w, h).data)
                .collect();
            assert_eq!(joined_indices(&joint, &rgb, w, h), own, "{smoothing:?}");
        }
    }

    #[test]
    fn a_joint_palette_told_another_palettes_table_gives_other_indices() {
        // The check above can fail: palette 1's table is not palette 0's.
        let palettes = [palette(1, 12), palette(2, 12)];
        let joint = JointPalette::new(&[&palettes[0], &palettes[1]]).unwrap();
        let (w, h) = (31, 17);
        let rgb = frame(4, w, h);
        let joined = joined_indices(&joint, &rgb, w, h);
        assert_ne!(joined[1], palettes[0].quantise(&rgb, w, h).data);
    }

    #[test]
    fn palettes_smoothing_differently_are_refused_naming_the_one() {
        let a = palette(1, 8);
        let b = palette(2, 8).with_smoothing(Smoothing::Binomial);
        assert_eq!(
            JointPalette::new(&[&a, &a, &b]).unwrap_err(),
            JointPaletteError::Smoothing {
                index: 2,
                found: Smoothing::Binomial,
                first: Smoothing::Off,
            }
        );
        assert_eq!(
            JointPalette::new(&[]).unwrap_err(),
            JointPaletteError::Empty
        );
    }
}
