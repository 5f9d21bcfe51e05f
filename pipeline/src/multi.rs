//! Several known objects in one frame: one lane (a [`Chain`] over the
//! object's database) per object. Every lane recognises its object in the
//! frame; where two objects' windows cover the same place, only the one
//! that cleared its threshold by the wider margin goes on (non-maximum
//! suppression between objects); then segmentation, pose, confidence and
//! seeding run per detection. The lanes run on a pool of threads that live
//! as long as the chain, each on a CPU of its own (docs/multi.md: a thread
//! started per frame waits for the CPU of the thread that started it).
//! The frame is quantised once for every lane, through a
//! [`JointPalette`] of their palettes.

use crate::chain::Chain;
use crate::config::StageSettings;
use crate::frame::FrameHeader;
use crate::stages::{BuildError, Recognised, Seeded, Window};
use crate::wire::{Outcome, PixelRect};
use acch_core::{JointPalette, ViewDatabase};
use rayon::prelude::*;

/// Windows of two objects overlapping by more than this share of the
/// smaller one claim the same place: the weaker is withdrawn. Of the
/// smaller, not of the union: objects' windows differ in size, and a small
/// window inside a large one on the same object overlaps it little by
/// union (docs/multi.md).
pub const NMS_OVERLAP: f32 = 0.5;

/// One object's chain in a [`MultiChain`].
pub struct Lane {
    /// The object's name (its database's).
    pub object: String,
    /// Its stages.
    pub chain: Chain,
    /// Frames whose detection was withdrawn for another object's.
    pub suppressed: u64,
    recognised: Recognised,
}

/// The chains of several objects over one stream of frames.
pub struct MultiChain {
    lanes: Vec<Lane>,
    seeded: Vec<Seeded>,
    /// The lanes' threads; `None` runs every lane on the caller's.
    pool: Option<rayon::ThreadPool>,
    /// One quantisation pass for every lane's palette (none for one lane,
    /// or palettes that smooth frames differently: each lane quantises).
    joint: Option<JointPalette>,
    /// The frame's joint colours, reused between frames.
    labels: Vec<u16>,
    /// The frame's windows and what suppression keeps, reused between
    /// frames so a frame allocates nothing here.
    windows: Vec<Option<Window>>,
    order: Vec<usize>,
    keep: Vec<bool>,
}

impl MultiChain {
    /// A lane per database, each with its own settings, run on up to
    /// `threads` threads (1: all on the caller's). With as many CPUs
    /// allowed as threads, each thread is pinned to one of them.
    pub fn build(
        objects: &[(&ViewDatabase, StageSettings)],
        threads: usize,
    ) -> Result<Self, BuildError> {
        let lanes = objects
            .iter()
            .map(|(db, settings)| {
                Ok(Lane {
                    object: db.object.clone(),
                    chain: Chain::build(db, settings)?,
                    suppressed: 0,
                    recognised: Recognised::default(),
                })
            })
            .collect::<Result<Vec<_>, BuildError>>()?;
        let threads = threads.clamp(1, lanes.len().max(1));
        let pool = (threads > 1).then(|| lane_pool(threads)).transpose()?;
        let palettes: Vec<_> = objects.iter().map(|(db, _)| &db.palette).collect();
        let joint = match JointPalette::new(&palettes) {
            Ok(joint) if palettes.len() > 1 => Some(joint),
            Ok(_) => None,
            Err(e) => {
                tracing::info!("each object quantises the frame with its own palette: {e}");
                None
            }
        };
        Ok(MultiChain {
            seeded: vec![Seeded::default(); lanes.len()],
            lanes,
            pool,
            joint,
            labels: Vec::new(),
            windows: Vec::new(),
            order: Vec::new(),
            keep: Vec::new(),
        })
    }

    /// Each lane quantises the frame with its own palette, as a chain
    /// alone does, instead of sharing one pass (to measure the sharing).
    pub fn quantise_apart(mut self) -> Self {
        self.joint = None;
        self
    }

    /// Joint colours of the pass the lanes share, if they share one.
    pub fn joint_colours(&self) -> Option<usize> {
        self.joint.as_ref().map(JointPalette::colours)
    }

    /// The lanes, in the order they were built.
    pub fn lanes(&self) -> &[Lane] {
        &self.lanes
    }

    /// The lanes, to change (a confidence threshold, say).
    pub fn lanes_mut(&mut self) -> &mut [Lane] {
        &mut self.lanes
    }

    /// Runs every lane on frame `frame` (packed RGB `rgb`) and returns each
    /// lane's result, in lane order.
    pub fn process(&mut self, frame: &FrameHeader, rgb: &[u8]) -> &[Seeded] {
        let (width, height) = (frame.envelope.frame.width, frame.envelope.frame.height);
        let pixels = width as usize * height as usize;
        match &self.joint {
            // A frame of another size than its bytes: each lane's
            // recognition refuses it.
            Some(joint) if rgb.len() == 3 * pixels => {
                self.labels.resize(pixels, 0);
                label(
                    joint,
                    self.pool.as_ref(),
                    rgb,
                    (width, height),
                    &mut self.labels,
                );
                let labels = &self.labels[..];
                each_lane(self.pool.as_ref(), &mut self.lanes, |k, lane| {
                    lane.recognised = lane.chain.recognise_quantised(frame, rgb, |out| {
                        // Another size than the lane's: recognition faults.
                        if out.len() == labels.len() {
                            joint.indices(k, labels, out);
                        }
                    })
                });
            }
            _ => each_lane(self.pool.as_ref(), &mut self.lanes, |_, lane| {
                lane.recognised = lane.chain.recognise(frame, rgb)
            }),
        }
        self.windows.clear();
        self.windows
            .extend(self.lanes.iter().map(|l| match l.recognised.detection {
                Outcome::Done(w) => Some(w),
                _ => None,
            }));
        suppress_into(&self.windows, &mut self.order, &mut self.keep);
        for (lane, &keep) in self.lanes.iter_mut().zip(&self.keep) {
            if !keep {
                lane.recognised.detection = Outcome::Nothing;
                lane.suppressed += 1;
            }
        }
        each_lane(self.pool.as_ref(), &mut self.lanes, |_, lane| {
            let r = lane.recognised;
            let _ = lane.chain.finish(&r, rgb);
        });
        for (out, lane) in self.seeded.iter_mut().zip(&self.lanes) {
            *out = lane.chain.last().expect("every lane just ran");
        }
        &self.seeded
    }
}

/// Runs `work` on every lane (with its position), spread over `pool`'s
/// threads (a thread that is done takes a lane another has not started),
/// or on the caller's without one.
fn each_lane(
    pool: Option<&rayon::ThreadPool>,
    lanes: &mut [Lane],
    work: impl Fn(usize, &mut Lane) + Sync + Send,
) {
    match pool {
        Some(pool) => pool.install(|| {
            lanes
                .par_iter_mut()
                .enumerate()
                .with_max_len(1)
                .for_each(|(k, lane)| work(k, lane))
        }),
        None => lanes.iter_mut().enumerate().for_each(|(k, l)| work(k, l)),
    }
}

/// The joint colours of frame `rgb` into `labels`, smoothed first as the
/// palettes smooth (on the caller's thread), labelled in a band per thread
/// of `pool`.
fn label(
    joint: &JointPalette,
    pool: Option<&rayon::ThreadPool>,
    rgb: &[u8],
    (width, height): (u32, u32),
    labels: &mut [u16],
) {
    let Some(pool) = pool else {
        return joint.label(rgb, width, height, labels);
    };
    let band = labels.len().div_ceil(pool.current_num_threads()).max(1);
    let mut in_bands = |rgb: &[u8]| {
        pool.install(|| {
            labels
                .par_chunks_mut(band)
                .zip(rgb.par_chunks(3 * band))
                .for_each(|(l, px)| joint.label_pixels(px, l))
        })
    };
    match joint.smoothing() {
        acch_core::Smoothing::Off => in_bands(rgb),
        acch_core::Smoothing::Binomial => {
            acch_core::smooth::with_smoothed(rgb, width, height, in_bands)
        }
    }
}

/// `threads` threads for the lanes, thread `i` pinned to the `i`-th CPU
/// the process may use when it may use that many: a woken thread is
/// otherwise queued behind the thread that woke it on one CPU while the
/// other idles (about 2 ms a phase here, docs/multi.md).
fn lane_pool(threads: usize) -> Result<rayon::ThreadPool, BuildError> {
    let cpus = acch_ipc::sched::allowed_cpus().unwrap_or_default();
    let pin = cpus.len() >= threads;
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("acch-lane-{i}"))
        .start_handler(move |i| {
            if pin && let Err(e) = acch_ipc::sched::pin_to(&cpus[i..=i]) {
                tracing::warn!("lane thread {i} not pinned to CPU {}: {e}", cpus[i]);
            }
        })
        .build()
        .map_err(|e| BuildError::Threads(e.to_string()))
}

/// Which of `windows` survive non-maximum suppression: the strongest by
/// margin over its own threshold (score / threshold, comparable between
/// objects whose models score on different scales) first, each later one
/// kept only if it overlaps no kept window by more than [`NMS_OVERLAP`].
pub fn suppress(windows: &[Option<Window>]) -> Vec<bool> {
    let (mut order, mut keep) = (Vec::new(), Vec::new());
    suppress_into(windows, &mut order, &mut keep);
    keep
}

/// [`suppress`] into `keep`, with `order` as scratch (no allocation once
/// they have grown to the number of lanes).
fn suppress_into(windows: &[Option<Window>], order: &mut Vec<usize>, keep: &mut Vec<bool>) {
    let margin = |i: usize| windows[i].map_or(0.0, |w| w.margin());
    order.clear();
    order.extend((0..windows.len()).filter(|&i| windows[i].is_some()));
    // Unstable sorts do not allocate; ties go to the earlier lane.
    order.sort_unstable_by(|&a, &b| margin(b).total_cmp(&margin(a)).then(a.cmp(&b)));
    keep.clear();
    keep.resize(windows.len(), false);
    let window = |i: usize| windows[i].expect("only detections are ordered").window;
    for (pos, &i) in order.iter().enumerate() {
        let w = window(i);
        let free = order[..pos]
            .iter()
            .filter(|&&k| keep[k])
            .all(|&k| overlap(&window(k), &w) <= NMS_OVERLAP);
        keep[i] = free;
    }
}

/// The intersection of two pixel rectangles over the smaller's area (0
/// when either is empty).
pub fn overlap(a: &PixelRect, b: &PixelRect) -> f32 {
    let ix = (a.x + a.width)
        .min(b.x + b.width)
        .saturating_sub(a.x.max(b.x));
    let iy = (a.y + a.height)
        .min(b.y + b.height)
        .saturating_sub(a.y.max(b.y));
    let inter = ix as f64 * iy as f64;
    let smaller = (a.width as f64 * a.height as f64).min(b.width as f64 * b.height as f64);
    if smaller <= 0.0 {
        return 0.0;
    }
    (inter / smaller) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(x: u32, y: u32, side: u32, score: f32, threshold: f32) -> Option<Window> {
        Some(Window {
            window: PixelRect {
                x,
                y,
                width: side,
                height: side,
            },
            score,
            threshold,
            ..Window::default()
        })
    }

    #[test]
    fn lane_threads_each_run_on_a_cpu_of_their_own() {
        let cpus = acch_ipc::sched::allowed_cpus().unwrap();
        let pool = lane_pool(2).unwrap();
        let mut seen = pool.broadcast(|_| acch_ipc::sched::allowed_cpus().unwrap());
        if cpus.len() < 2 {
            // One CPU: nothing to spread over, the threads are left as they are.
            assert!(seen.iter().all(|s| *s == cpus), "{seen:?}");
            return;
        }
        seen.sort();
        assert_eq!(seen, [vec![cpus[0]], vec![cpus[1]]]);
    }

    #[test]
    fn overlap_is_over_the_smaller_rectangle() {
        let a = PixelRect {
            x: 0,
            y: 0,
            width: 10,
            height: 10,
        };
        let b = PixelRect { x: 5, ..a };
        assert!((overlap(&a, &a) - 1.0).abs() < 1e-6);
        assert!((overlap(&a, &b) - 0.5).abs() < 1e-6);
        // A small window inside a large one: wholly overlapped.
        let inside = PixelRect {
            x: 2,
            y: 2,
            width: 4,
            height: 4,
        };
        assert!((overlap(&a, &inside) - 1.0).abs() < 1e-6);
        assert_eq!(overlap(&a, &PixelRect { x: 20, ..a }), 0.0);
        assert_eq!(overlap(&a, &PixelRect { width: 0, ..b }), 0.0);
    }

    #[test]
    fn the_wider_margin_wins_an_overlap_and_apart_both_stay() {
        // Lane 1 scores lower but clears a lower threshold by more.
        let w = [
            window(100, 100, 80, 0.6, 0.5),
            window(105, 100, 80, 0.5, 0.3),
            None,
            window(400, 100, 80, 0.4, 0.3),
        ];
        assert_eq!(suppress(&w), [false, true, false, true]);
        // Overlapping less than NMS_OVERLAP, both stay.
        let apart = [
            window(100, 100, 80, 0.6, 0.5),
            window(150, 100, 80, 0.5, 0.3),
        ];
        assert_eq!(suppress(&apart), [true, true]);
    }
}
