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
//! (a blurred object is often lost to the sharp set). Recognition is the
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
            let part = stage.process(input, payload, out)?;
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
            smoothed.process(input, payload, out)?
        } else {
            let part = self.sharp.process(input, payload, out)?;
            let window = S::object_window(&part);
            let sharpness = window.map_or(f32::NAN, |w| {
                meter.sharpness_within(w.x, w.y, w.width, w.height)
            });
            if !sharpness.is_nan() {
                imaging.object_sharpness = sharpness;
            }
            // A blurred object, or none found: a blurred object can be lost
            // to the sharp set's recognition and found by the smoothed one.
            // `FrameImaging::smoothed_for` reads this choice back from the
            // measures: keep the two in step.
            if window.is_none() || acch_core::is_blurred(sharpness) {
                imaging.set = DatabaseSet::Smoothed;
                // The smoothed stage reads why it has the frame: one sent
                // for its blurred object is not smoothed again.
                let mut chosen = *input;
                chosen.envelope_mut().imaging = imaging;
                smoothed.process(&chosen, payload, out)?
            } else {
                part
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
