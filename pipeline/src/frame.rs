//! The frame stream's header, written by capture: the [`Envelope`] every
//! later header carries, plus how the pixels are laid out and where capture
//! put them in shared memory. The pixels are the payload, packed RGB.

use crate::wire::{Envelope, FrameMeta, Hop, Intrinsics, Maybe, Trail};
use acch_ipc::ZeroCopySend;

/// Pixel formats of a frame.
#[repr(u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelFormat {
    /// Packed 8-bit RGB, 3 bytes a pixel.
    #[default]
    Rgb8 = 1,
}

// SAFETY: a fieldless repr(u32) enum: four bytes, no pointers.
unsafe impl ZeroCopySend for PixelFormat {}

/// Where capture wrote the pixels: hash of the shared-memory file name and
/// the offset inside it (see [`acch_ipc::ShmLocator`]); a reader that finds
/// them at the same place reads the same physical pages.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ZeroCopySend)]
pub struct ShmLocation {
    /// Hash of the file's name (0: not in shared memory).
    pub file: u64,
    /// Offset in the file.
    pub offset: u64,
}

/// The header of a frame sample.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct FrameHeader {
    /// The frame, its trail (capture's times filled) and its reads (none
    /// yet).
    pub envelope: Envelope,
    /// Bytes a row.
    pub stride: u32,
    /// Layout of the pixels.
    pub format: PixelFormat,
    /// Where capture wrote the pixels.
    pub location: ShmLocation,
}

impl Hop for FrameHeader {
    fn envelope(&self) -> &Envelope {
        &self.envelope
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        &mut self.envelope
    }
    fn pixels_at(&self) -> Option<(u64, u64)> {
        Some((self.location.file, self.location.offset))
    }
}

impl FrameHeader {
    /// The header of packed RGB frame `sequence` of `width` x `height`
    /// pixels seen with `intrinsics`; no truth, no arm pose, no times.
    pub fn rgb(sequence: u64, width: u32, height: u32, intrinsics: Intrinsics) -> Self {
        FrameHeader {
            envelope: Envelope {
                frame: FrameMeta {
                    sequence,
                    width,
                    height,
                    intrinsics,
                    truth: Maybe::Absent,
                    arm: Maybe::Absent,
                    stamp_ns: 0,
                },
                trail: Trail::default(),
                reads: Default::default(),
                imaging: Default::default(),
            },
            stride: width * 3,
            format: PixelFormat::Rgb8,
            location: ShmLocation::default(),
        }
    }

    /// Stamps the moment the frame exists (a camera's exposure time
    /// stamp): capture's receive time, the trail's start and the frame's
    /// wall-clock time stamp.
    pub fn stamp_captured(&mut self, captured_ns: u64) {
        // The wall clock of that moment (a camera's frame is older than
        // now by the time it took to arrive).
        let age = acch_ipc::now_ns().saturating_sub(captured_ns);
        self.envelope.frame.stamp_ns = acch_ipc::wall_ns().saturating_sub(age);
        let t = &mut self.envelope.trail;
        t.captured_ns = captured_ns;
        t.stages[0].received_ns = captured_ns;
    }
}
