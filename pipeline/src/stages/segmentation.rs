//! Segmentation: grow the detection window into a pixel mask over
//! recognition's palette indices and colour counts, read in place.
//!
//! Its payload ([`RegionPayload`]) is pose's whole input: the mask and the
//! palette indices, each cropped to the mask's bounding box (the ROI, in
//! the header), `roi.width * roi.height` bytes each, mask first.

use super::BuildError;
use super::recognition::{Recognised, RecognitionPayload, recognition_model};
use crate::config::StageSettings;
use crate::stage::Stage;
use crate::wire::{Envelope, Fault, Hop, Outcome, PixelRect, StageId};
use acch_core::ViewDatabase;
use acch_ipc::ZeroCopySend;
use acch_recognition::{CountLayout, RecognitionModel};
use acch_segmentation::Segmenter;

/// Segmentation's header. `region`: the ROI (the mask's bounding box) when
/// a region was grown; `Nothing` when no cell of the window resembled the
/// object.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Segmented {
    /// Recognition's header.
    pub recognised: Recognised,
    /// The object's region.
    pub region: Outcome<PixelRect>,
}

impl Segmented {
    /// What the pose stage reads for an object `mask` found by other means
    /// than recognition and segmentation (a ground-truth mask, an
    /// annotation; one byte a pixel of a `width`-wide frame, non-zero =
    /// object): the header, its region the mask's bounding box, with the
    /// region payload written into `out` from the frame's palette
    /// `indices`. `None` when the mask is empty.
    pub fn from_mask(
        envelope: Envelope,
        mask: &[u8],
        indices: &[u8],
        width: u32,
        out: &mut [u8],
    ) -> Result<Option<Self>, Fault> {
        let height = (mask.len() / width.max(1) as usize) as u32;
        let Some(bbox) = acch_pose::train::mask_bbox(mask, width, height) else {
            return Ok(None);
        };
        let roi = PixelRect::from(bbox);
        RegionPayload::write(mask, indices, width, roi, out)?;
        Ok(Some(Segmented {
            recognised: Recognised {
                envelope,
                detection: Outcome::Skipped,
            },
            region: Outcome::Done(roi),
        }))
    }
}

impl Hop for Segmented {
    fn envelope(&self) -> &Envelope {
        &self.recognised.envelope
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        &mut self.recognised.envelope
    }
}

/// Segmentation's payload, read in place.
#[derive(Clone, Copy, Debug)]
pub struct RegionPayload<'a> {
    /// The region.
    pub roi: PixelRect,
    /// The mask over the ROI (255 = object), row-major.
    pub mask: &'a [u8],
    /// The palette indices over the ROI, row-major.
    pub indices: &'a [u8],
}

impl<'a> RegionPayload<'a> {
    /// Reads the payload of `header` from `bytes`; `Ok(None)` when no
    /// region was grown.
    pub fn read(header: &Segmented, bytes: &'a [u8]) -> Result<Option<Self>, Fault> {
        let Outcome::Done(roi) = header.region else {
            return Ok(None);
        };
        let f = &header.envelope().frame;
        if !roi.fits(f.width, f.height) || roi.area() == 0 {
            return Err(Fault::Header);
        }
        let area = roi.area();
        let both = bytes.get(..2 * area).ok_or(Fault::Payload)?;
        let (mask, indices) = both.split_at(area);
        Ok(Some(RegionPayload { roi, mask, indices }))
    }

    /// Writes the payload of `roi` from a frame-sized `mask` and palette
    /// `indices` of a `width`-pixel-wide frame into `out`: what
    /// segmentation publishes and pose reads (the evaluations feed the pose
    /// stage a ground-truth mask this way).
    pub fn write(
        mask: &[u8],
        indices: &[u8],
        width: u32,
        roi: PixelRect,
        out: &mut [u8],
    ) -> Result<(), Fault> {
        let area = roi.area();
        let height = (mask.len() / (width.max(1) as usize)) as u32;
        if mask.len() != indices.len() || !roi.fits(width, height) {
            return Err(Fault::Header);
        }
        let (mask_out, index_out) = out
            .get_mut(..2 * area)
            .ok_or(Fault::Payload)?
            .split_at_mut(area);
        crop(mask, width, roi, mask_out);
        crop(indices, width, roi, index_out);
        Ok(())
    }

    /// Pastes the mask back into a frame-sized one (`width` x `height`,
    /// zeros outside the ROI) in `out`.
    pub fn frame_mask(&self, width: u32, height: u32, out: &mut Vec<u8>) {
        out.clear();
        out.resize(width as usize * height as usize, 0);
        let (w, rw) = (width as usize, self.roi.width as usize);
        for (row, src) in self.mask.chunks_exact(rw).enumerate() {
            let at = (self.roi.y as usize + row) * w + self.roi.x as usize;
            out[at..at + rw].copy_from_slice(src);
        }
    }
}

/// Copies `roi` of a `width`-pixel-wide one-byte-per-pixel frame into
/// `out` (`roi.area()` bytes, row-major).
pub(super) fn crop(frame: &[u8], width: u32, roi: PixelRect, out: &mut [u8]) {
    let (w, rw) = (width as usize, roi.width as usize);
    if rw == 0 {
        return;
    }
    for (y, dst) in (roi.y as usize..).zip(out.chunks_exact_mut(rw)) {
        let at = y * w + roi.x as usize;
        dst.copy_from_slice(&frame[at..at + rw]);
    }
}

/// The segmentation stage.
pub struct Segmentation {
    model: RecognitionModel,
    layout: CountLayout,
    segmenter: Segmenter,
    size: (u32, u32),
}

impl Segmentation {
    /// The stage for `db` on frames of `settings`.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let model = recognition_model(db)?;
        Ok(Segmentation {
            layout: CountLayout::new(&model, settings.width, settings.height),
            model,
            segmenter: Segmenter::new(settings.width, settings.height)?,
            size: (settings.width, settings.height),
        })
    }

    /// The grid layout recognition's counts are published in.
    pub fn layout(&self) -> CountLayout {
        self.layout
    }

    /// The segmenter (cell scores and mask of the last frame).
    pub fn segmenter(&self) -> &Segmenter {
        &self.segmenter
    }
}

impl Stage for Segmentation {
    const ID: StageId = StageId::Segmentation;
    type Input = Recognised;
    type Part = Outcome<PixelRect>;
    type Output = Segmented;

    fn max_payload(&self) -> usize {
        2 * self.size.0 as usize * self.size.1 as usize
    }

    fn process(
        &mut self,
        input: &Recognised,
        payload: &[u8],
        _: &[u8],
        out: &mut [u8],
    ) -> Result<Outcome<PixelRect>, Fault> {
        let Outcome::Done(window) = input.detection else {
            return Ok(Outcome::Skipped);
        };
        let f = &input.envelope.frame;
        if (f.width, f.height) != self.size {
            return Err(Fault::FrameSize);
        }
        let read = RecognitionPayload::read(input, self.layout, payload)?;
        let counts = read.counts.ok_or(Fault::Payload)?;
        let Some(seg) =
            self.segmenter
                .segment(read.indices, &counts, &self.model, &window.detection())
        else {
            return Ok(Outcome::Nothing);
        };
        let roi = PixelRect::from(seg.roi.clamp_to(f.width, f.height));
        RegionPayload::write(seg.mask, read.indices.data, f.width, roi, out)?;
        Ok(Outcome::Done(roi))
    }

    fn output(input: &Recognised, region: Outcome<PixelRect>) -> Segmented {
        Segmented {
            recognised: *input,
            region,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cropped_mask_pastes_back_into_the_frame() {
        let (w, h) = (13u32, 9u32);
        let roi = PixelRect {
            x: 3,
            y: 2,
            width: 6,
            height: 5,
        };
        let mut mask = vec![0u8; (w * h) as usize];
        for y in roi.y..roi.y + roi.height {
            for x in roi.x..roi.x + roi.width {
                mask[(y * w + x) as usize] = if (x + y) % 3 == 0 { 0 } else { 255 };
            }
        }
        let mut payload = vec![7u8; 2 * (w * h) as usize];
        crop(&mask, w, roi, &mut payload[..roi.area()]);
        let mut header = Segmented {
            region: Outcome::Done(roi),
            ..Default::default()
        };
        header.envelope_mut().frame.width = w;
        header.envelope_mut().frame.height = h;
        let read = RegionPayload::read(&header, &payload).unwrap().unwrap();
        let mut back = Vec::new();
        read.frame_mask(w, h, &mut back);
        assert_eq!(back, mask);
        // An ROI outside the frame is refused, not read out of bounds.
        let outside = Segmented {
            region: Outcome::Done(PixelRect { x: 10, ..roi }),
            ..header
        };
        assert_eq!(
            RegionPayload::read(&outside, &payload).unwrap_err(),
            Fault::Header
        );
        // A payload shorter than the ROI's two planes is refused too.
        assert_eq!(
            RegionPayload::read(&header, &payload[..2 * roi.area() - 1]).unwrap_err(),
            Fault::Payload
        );
    }
}
