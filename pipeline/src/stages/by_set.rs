//! A stage held for two database sets, the sharp and the smoothed one, and
//! run on each frame with the set recognition chose for it by the frame's
//! measured noise and JPEG blocking and the object's sharpness (`smoothing
//! = "auto"`).
//!
//! Why per frame: the databases that smooth views and frames hold on noisy,
//! compressed and blurred frames, where the sharp ones lose, and cost on
//! clean frames and among several objects (docs/accuracy.md, "Which
//! database a frame needs"); the frame's own measure tells the cases apart
//! whatever the object's match. Noise and blocking are the camera's, read
//! over the whole frame before any database sees it; blur is read over the
//! window the sharp set found the object in, since a frame with nothing
//! sharp in view measures as a blurred one, and a blurred object, or none
//! found, sends the frame through the smoothed set's recognition again
//! (a blurred object is often lost to the sharp set). A window the sharp
//! set found only under its threshold (faint) is tried there too, and
//! kept unless the smoothed set finds the object clearly. Recognition is the
//! one stage that reads pixels, so it measures and chooses; the later
//! stages follow the choice the header carries. Seeding is not held twice:
//! its fusion spans frames of both sets.

use crate::stage::Stage;
use crate::wire::{DatabaseSet, Fault, FrameImaging, Hop, StageId};
use acch_core::QualityMeter;

/// Stage `S` for the sharp set and, in a run that chooses, the smoothed one.
pub struct BySet<S> {
    sharp: S,
    smoothed: Option<S>,
    /// Recognition's measure of each frame (a run that chooses).
    meter: Option<QualityMeter>,
    last: DatabaseSet,
    /// The sharp set's payload of a frame it found the object in only
    /// faintly, while the smoothed set tries it.
    held: Vec<u8>,
}

impl<S: Stage> BySet<S> {
    /// The stage of a run that does not choose: every frame goes through
    /// `sharp`.
    pub fn sharp_only(sharp: S) -> Self {
        BySet {
            sharp,
            smoothed: None,
            meter: None,
            last: DatabaseSet::Sharp,
            held: Vec::new(),
        }
    }

    /// The stage for both sets. Recognition measures each frame and
    /// chooses; the later stages follow the choice in the header.
    pub fn both(sharp: S, smoothed: S) -> Self {
        BySet {
            sharp,
            smoothed: Some(smoothed),
            meter: (S::ID == StageId::Recognition).then(QualityMeter::new),
            last: DatabaseSet::Sharp,
            held: Vec::new(),
        }
    }

    /// The stage of the sharp set.
    pub fn sharp(&self) -> &S {
        &self.sharp
    }

    /// The stage of the sharp set, to change.
    pub fn sharp_mut(&mut self) -> &mut S {
        &mut self.sharp
    }

    /// The stage of the smoothed set, in a run that chooses.
    pub fn smoothed(&self) -> Option<&S> {
        self.smoothed.as_ref()
    }

    /// Whether the run chooses a set per frame.
    pub fn chooses(&self) -> bool {
        self.smoothed.is_some()
    }

    /// The stage that ran the last frame (the sharp one before any).
    pub fn last_used(&self) -> &S {
        match (self.last, &self.smoothed) {
            (DatabaseSet::Smoothed, Some(s)) => s,
            _ => &self.sharp,
        }
    }

    /// Each set's stage, to change alike (a confidence threshold, say).
    pub fn each_mut(&mut self) -> impl Iterator<Item = &mut S> {
        std::iter::once(&mut self.sharp).chain(self.smoothed.as_mut())
    }
}

/// A part of a [`BySet`] stage: the set's stage's part and, from
/// recognition, what it measured of the frame and chose.
pub struct Chosen<P> {
    /// The measure and the choice (recognition in a run that chooses); the
    /// later stages pass on their input's.
    pub imaging: Option<FrameImaging>,
    /// The stage's own part.
    pub part: P,
}

impl<P: From<Fault>> From<Fault> for Chosen<P> {
    fn from(f: Fault) -> Self {
        Chosen {
            imaging: None,
            part: P::from(f),
        }
    }
}

impl<S: Stage> Stage for BySet<S> {
    const ID: StageId = S::ID;
    const READS_FRAME: bool = S::READS_FRAME;
    type Input = S::Input;
    type Part = Chosen<S::Part>;
    type Output = S::Output;

    fn max_payload(&self) -> usize {
        let smoothed = self.smoothed.as_ref().map_or(0, Stage::max_payload);
        self.sharp.max_payload().max(smoothed)
    }

    fn process(
        &mut self,
        input: &S::Input,
        payload: &[u8],
        frame: &[u8],
        out: &mut [u8],
    ) -> Result<Chosen<S::Part>, Fault> {
        let Some(meter) = &mut self.meter else {
            // A later stage, or a run that does not choose: the header's set.
            let set = input.envelope().imaging.set;
            let stage = match (set, &mut self.smoothed) {
                (DatabaseSet::Sharp, _) => &mut self.sharp,
                (DatabaseSet::Smoothed, Some(s)) => s,
                // A frame for a set this stage was not built with: the
                // processes of one run disagree on their configuration.
                (DatabaseSet::Smoothed, None) => return Err(Fault::Header),
            };
            self.last = set;
            let part = stage.process(input, payload, frame, out)?;
            return Ok(Chosen {
                imaging: None,
                part,
            });
        };
        let f = &input.envelope().frame;
        if payload.len() != 3 * f.width as usize * f.height as usize {
            return Err(Fault::FrameSize);
        }
        let q = meter.noise_and_blocking(payload, f.width, f.height);
        let mut imaging = FrameImaging {
            noise_sigma: q.noise_sigma,
            blockiness: q.blockiness,
            object_sharpness: 0.0,
            set: DatabaseSet::Sharp,
        };
        // The meter comes with the smoothed stage (`both`).
        let smoothed = self.smoothed.as_mut().ok_or(Fault::Header)?;
        let part = if q.needs_smoothing() {
            imaging.set = DatabaseSet::Smoothed;
            smoothed.process(input, payload, frame, out)?
        } else {
            let part = self.sharp.process(input, payload, frame, out)?;
            let window = S::object_window(&part);
            let sharpness = window.map_or(f32::NAN, |w| {
                meter.sharpness_within(w.rect.x, w.rect.y, w.rect.width, w.rect.height)
            });
            if !sharpness.is_nan() {
                imaging.object_sharpness = sharpness;
            }
            // `FrameImaging::smoothed_for` reads the choice back from the
            // measures: keep the two in step.
            let mut send = |imaging: FrameImaging, out: &mut [u8]| {
                // The smoothed stage reads why it has the frame: one sent
                // for its blurred object is not smoothed again.
                let mut chosen = *input;
                chosen.envelope_mut().imaging = imaging;
                smoothed.process(&chosen, payload, frame, out)
            };
            let blurred = acch_core::is_blurred(sharpness);
            match window {
                Some(w) if w.clear && !blurred => part,
                Some(w) if !w.clear => {
                    // Found under the threshold only (faint): tried by the
                    // smoothed set as a frame the sharp set found nothing
                    // in, as it was before faint windows were reported, and
                    // smoothed as such. Its estimate is kept when it finds
                    // the object clearly, or when the object is blurred;
                    // otherwise the sharp set's (a faint sharp window kept
                    // frames the smoothed set found clearly and right, and
                    // sent blurred ones on unsmoothed: docs/accuracy.md,
                    // "Found down to 0.7x the threshold").
                    self.held.clear();
                    self.held.extend_from_slice(out);
                    let tried = FrameImaging {
                        object_sharpness: 0.0,
                        set: DatabaseSet::Smoothed,
                        ..imaging
                    };
                    match send(tried, out) {
                        Ok(again)
                            if blurred || S::object_window(&again).is_some_and(|w| w.clear) =>
                        {
                            imaging = tried;
                            again
                        }
                        Err(fault) if blurred => return Err(fault),
                        _ => {
                            out.copy_from_slice(&self.held);
                            part
                        }
                    }
                }
                // A blurred object, or none found: a blurred object can be
                // lost to the sharp set's recognition and found by the
                // smoothed one.
                _ => {
                    imaging.set = DatabaseSet::Smoothed;
                    send(imaging, out)?
                }
            }
        };
        self.last = imaging.set;
        Ok(Chosen {
            imaging: Some(imaging),
            part,
        })
    }

    fn fault_in(chosen: &Chosen<S::Part>) -> Option<Fault> {
        S::fault_in(&chosen.part)
    }

    fn output(input: &S::Input, chosen: Chosen<S::Part>) -> S::Output {
        let mut header = S::output(input, chosen.part);
        if let Some(imaging) = chosen.imaging {
            header.envelope_mut().imaging = imaging;
        }
        header
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::FrameHeader;
    use crate::stage::ObjectWindow;
    use crate::stages::recognition::{Recognised, Window};
    use crate::wire::{Outcome, PixelRect, SmoothedFor};

    const SIDE: u32 = 64;

    /// A recognition stand-in: finds the object at a fixed margin of the
    /// threshold (None: finds nothing) and fills its payload with `mark`.
    struct FindsAt {
        margin: Option<f32>,
        mark: u8,
        /// Why each frame came, as the header said.
        sent_for: Vec<Option<SmoothedFor>>,
    }

    impl FindsAt {
        fn new(margin: Option<f32>, mark: u8) -> Self {
            FindsAt {
                margin,
                mark,
                sent_for: Vec::new(),
            }
        }
    }

    impl Stage for FindsAt {
        const ID: StageId = StageId::Recognition;
        type Input = FrameHeader;
        type Part = Outcome<Window>;
        type Output = Recognised;

        fn max_payload(&self) -> usize {
            16
        }

        fn process(
            &mut self,
            input: &FrameHeader,
            _payload: &[u8],
            _frame: &[u8],
            out: &mut [u8],
        ) -> Result<Outcome<Window>, Fault> {
            self.sent_for.push(input.envelope.imaging.smoothed_for());
            out.fill(self.mark);
            Ok(self.margin.map_or(Outcome::Nothing, |m| {
                Outcome::Done(Window {
                    window: PixelRect {
                        x: 8,
                        y: 8,
                        width: 48,
                        height: 48,
                    },
                    score: 0.3 * m,
                    threshold: 0.3,
                    ..Default::default()
                })
            }))
        }

        fn object_window(part: &Outcome<Window>) -> Option<ObjectWindow> {
            crate::stages::Recognition::object_window(part)
        }

        fn output(frame: &FrameHeader, detection: Outcome<Window>) -> Recognised {
            Recognised {
                envelope: frame.envelope,
                detection,
            }
        }
    }

    /// A sharp, clean frame (bars 3 px wide: sharp edges, no noise, no
    /// 8 px blocking) or a blurred one (a smooth ramp).
    fn frame(sharp: bool) -> Vec<u8> {
        (0..SIDE * SIDE)
            .flat_map(|i| {
                let x = i % SIDE;
                let v = match sharp {
                    true if (x / 3).is_multiple_of(2) => 40,
                    true => 210,
                    // Bars 8 px wide, their edges spread over the
                    // whole bar.
                    false => (125.0 + 85.0 * (x as f32 * std::f32::consts::PI / 8.0).sin()) as u8,
                };
                [v, v, v]
            })
            .collect()
    }

    /// The set a frame went to, its payload's first byte, its detection
    /// margin and why the smoothed set had it (None: not asked), for the
    /// sharp set finding the object at `sharp` and the smoothed one at
    /// `smoothed` on a clean frame, sharp or blurred.
    fn chosen(
        rgb: &[u8],
        sharp: Option<f32>,
        smoothed: Option<f32>,
    ) -> (DatabaseSet, u8, Option<f32>, Option<SmoothedFor>) {
        let mut stage = BySet::both(FindsAt::new(sharp, 1), FindsAt::new(smoothed, 2));
        let mut frame = FrameHeader::default();
        frame.envelope.frame.width = SIDE;
        frame.envelope.frame.height = SIDE;
        let mut out = vec![0u8; stage.max_payload()];
        let part = stage.process(&frame, rgb, &[], &mut out).unwrap();
        let imaging = part.imaging.expect("recognition measures");
        assert_eq!(stage.last_used().mark, out[0]);
        let asked = stage.smoothed().and_then(|s| s.sent_for.last().copied());
        let margin = part.part.done().map(|w| w.margin());
        (imaging.set, out[0], margin, asked.flatten())
    }

    #[test]
    fn a_faint_sharp_window_gives_way_to_a_clear_smoothed_one_and_only_to_that() {
        use DatabaseSet::{Sharp, Smoothed};
        use SmoothedFor::NotFound;
        let sharp = frame(true);
        let at = |s, m| chosen(&sharp, s, m);
        // Clear in the sharp set: the smoothed set is not asked.
        assert_eq!(at(Some(1.2), Some(1.5)), (Sharp, 1, Some(1.2), None));
        // Faint in the sharp set, clear in the smoothed one (asked as for
        // a frame with none found, smoothed as such): smoothed.
        assert_eq!(
            at(Some(0.8), Some(1.1)),
            (Smoothed, 2, Some(1.1), Some(NotFound))
        );
        // Faint in both, or lost to the smoothed set: the sharp window,
        // its payload back in place.
        assert_eq!(
            at(Some(0.8), Some(0.9)),
            (Sharp, 1, Some(0.8), Some(NotFound))
        );
        assert_eq!(at(Some(0.8), None), (Sharp, 1, Some(0.8), Some(NotFound)));
        // None in the sharp set: the smoothed set's, whatever it is.
        assert_eq!(
            at(None, Some(0.9)),
            (Smoothed, 2, Some(0.9), Some(NotFound))
        );
        assert_eq!(at(None, None), (Smoothed, 2, None, Some(NotFound)));
    }

    #[test]
    fn a_blurred_object_goes_to_the_smoothed_set_unsmoothed_only_when_found_clearly() {
        use DatabaseSet::Smoothed;
        use SmoothedFor::{Blur, NotFound};
        let blurred = frame(false);
        let at = |s, m| chosen(&blurred, s, m);
        assert_eq!(
            at(Some(1.2), Some(0.9)),
            (Smoothed, 2, Some(0.9), Some(Blur))
        );
        // Faint: smoothed as a frame with none found, and kept.
        assert_eq!(
            at(Some(0.8), Some(0.9)),
            (Smoothed, 2, Some(0.9), Some(NotFound))
        );
        assert_eq!(at(Some(0.8), None), (Smoothed, 2, None, Some(NotFound)));
    }
}
