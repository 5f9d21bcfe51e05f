//! What a run reports, whichever executor ran it: counts of what each
//! stage made of the frames, accuracy against the ground truth the source
//! carried, and latency from every frame's timing trail.

use crate::stages::{Rating, Seeded};
use crate::wire::{Hop, Outcome, SmoothedFor, StageId};
use acch_confidence::Tolerance;
use serde::Serialize;

/// Latency percentiles, milliseconds.
#[derive(Serialize, Debug, Clone, Copy, Default, PartialEq)]
pub struct Percentiles {
    /// Median.
    pub p50_ms: f64,
    /// 90th percentile.
    pub p90_ms: f64,
    /// 99th percentile.
    pub p99_ms: f64,
    /// Largest.
    pub max_ms: f64,
}

impl Percentiles {
    /// Percentiles of nanosecond samples (sorts them).
    pub fn of(samples: &mut [u64]) -> Self {
        samples.sort_unstable();
        let at = |q: f64| -> f64 {
            if samples.is_empty() {
                return 0.0;
            }
            let i = ((samples.len() - 1) as f64 * q).round() as usize;
            samples[i] as f64 / 1e6
        };
        Percentiles {
            p50_ms: at(0.5),
            p90_ms: at(0.9),
            p99_ms: at(0.99),
            max_ms: at(1.0),
        }
    }
}

/// Latency of one stage over all frames.
#[derive(Serialize, Debug, Clone)]
pub struct StageLatency {
    /// The stage.
    pub stage: &'static str,
    /// Upstream published -> this stage received (the IPC hop; empty for
    /// capture and in one process).
    pub hop: Percentiles,
    /// Received -> published (compute + publishing).
    pub process: Percentiles,
}

/// What the stages made of the frames, and how right the accepted
/// estimates were where the frames carried ground truth.
#[derive(Serialize, Debug, Clone, Default, PartialEq)]
pub struct Outcomes {
    /// Frames with a result.
    pub results: u64,
    /// Recognition found the object.
    pub found: u64,
    /// Pose estimated.
    pub estimated: u64,
    /// Accepted by the confidence stage and seeded: what a robot acts on.
    pub accepted: u64,
    /// Rated but not accepted: below the threshold, ambiguous, on a broad
    /// crest, misplaced or faint.
    pub rejected: u64,
    /// Of the rejected, those with a far view matching nearly as well
    /// ([`crate::stages::Verdict::ambiguous`]), whatever their rating.
    pub rejected_ambiguous: u64,
    /// Of the rejected, those whose neighbours in azimuth match nearly as
    /// well over 40° or more ([`crate::stages::Verdict::broad`]), whatever
    /// their rating.
    pub rejected_broad: u64,
    /// Of the rejected, those whose region a view beyond the tolerance
    /// holds in place clearly better ([`crate::stages::Verdict::misplaced`]),
    /// whatever their rating.
    pub rejected_misplaced: u64,
    /// Of the rejected, those found faintly and matched weakly
    /// ([`crate::stages::Verdict::faint`]): the object may not be in view.
    pub rejected_faint: u64,
    /// Estimated but not rated (an unrated run).
    pub unrated_estimates: u64,
    /// Seeds made (every accepted estimate has one).
    pub seeds: u64,
    /// Frames a stage could not process (a fault, counted by the stage).
    pub faulted: u64,
    /// Accepted estimates whose frame carried ground truth (a simulated
    /// single-object camera or a labelled recording; none from a real
    /// camera or a scene of several objects): what the errors below are
    /// over.
    pub accepted_with_truth: u64,
    /// Mean |Δφ| of the accepted estimates with ground truth, degrees.
    pub accepted_mean_phi_err_deg: f64,
    /// Mean |Δθ| of the accepted estimates with ground truth, degrees.
    pub accepted_mean_theta_err_deg: f64,
    /// Accepted estimates beyond the failure thresholds (|Δθ| > 10° or
    /// |Δφ| > 20°).
    pub accepted_wrong: u64,
    /// Their sequence numbers.
    pub accepted_wrong_sequences: Vec<u64>,
    /// Frames recognition ran through the smoothed databases: measured
    /// noisy or compressed, the object blurred, or not found by the sharp
    /// ones (`smoothing = "auto"`).
    pub smoothed: u64,
    /// Of them, for the camera's noise or JPEG blocking.
    pub smoothed_for_camera: u64,
    /// Of them, for a blurred object.
    pub smoothed_for_blur: u64,
    /// Of them, because the sharp databases found no object (or found it
    /// only faintly, and the smoothed ones clearly or blurred).
    pub smoothed_for_not_found: u64,
}

/// Whether any stage of `m` failed on it.
fn faulted(m: &Seeded) -> bool {
    let failed = |o: &str| o == "failed";
    failed(m.detection().state())
        || failed(m.region().state())
        || failed(m.pose().state())
        || matches!(m.rating(), Rating::Failed(_))
        || matches!(m.seeding.seed, Outcome::Failed(_))
}

impl Outcomes {
    /// Counts over `results`, judged by the paper's failure rule.
    pub fn of(results: &[Seeded]) -> Self {
        let rule = Tolerance::default();
        let mut o = Outcomes {
            results: results.len() as u64,
            ..Default::default()
        };
        let (mut phi, mut theta, mut with_truth) = (0.0, 0.0, 0u64);
        for m in results {
            if let Some(why) = m.envelope().imaging.smoothed_for() {
                o.smoothed += 1;
                *match why {
                    SmoothedFor::Camera => &mut o.smoothed_for_camera,
                    SmoothedFor::Blur => &mut o.smoothed_for_blur,
                    SmoothedFor::NotFound => &mut o.smoothed_for_not_found,
                } += 1;
            }
            o.found += m.detection().done().is_some() as u64;
            o.faulted += faulted(m) as u64;
            let Some(p) = m.pose().done() else { continue };
            o.estimated += 1;
            match m.rating() {
                Rating::Rated(v) if !v.accepted => {
                    o.rejected += 1;
                    o.rejected_ambiguous += v.ambiguous() as u64;
                    o.rejected_broad += v.broad() as u64;
                    o.rejected_misplaced += v.misplaced() as u64;
                    o.rejected_faint += v.faint() as u64;
                }
                Rating::Unrated => o.unrated_estimates += 1,
                _ => {}
            }
            o.seeds += m.seed().is_some() as u64;
            if !m.accepted() {
                continue;
            }
            o.accepted += 1;
            if let Some(t) = m.envelope().frame.truth.get() {
                let (est, truth) = (
                    (p.theta_deg, p.phi_deg),
                    (t.theta_deg as f32, t.phi_deg as f32),
                );
                theta += (est.0 - truth.0).abs() as f64;
                phi += acch_pose::phi_error(est.1, truth.1) as f64;
                with_truth += 1;
                if !rule.reliable(est, truth) {
                    o.accepted_wrong += 1;
                    o.accepted_wrong_sequences.push(m.envelope().frame.sequence);
                }
            }
        }
        o.accepted_with_truth = with_truth;
        let n = with_truth.max(1) as f64;
        o.accepted_mean_phi_err_deg = phi / n;
        o.accepted_mean_theta_err_deg = theta / n;
        o
    }
}

/// Every frame's end-to-end, hop and processing times, nanoseconds.
#[derive(Serialize, Debug, Default, Clone)]
pub struct Samples {
    /// Captured -> final result, per frame.
    pub e2e_ns: Vec<u64>,
    /// Per stage: upstream published -> received (empty in one process).
    pub hop_ns: Vec<(String, Vec<u64>)>,
    /// Per stage: received -> published.
    pub process_ns: Vec<(String, Vec<u64>)>,
}

impl Samples {
    /// The samples of `results`; `hops` when the stages were processes.
    pub fn of(results: &[Seeded], hops: bool) -> Self {
        let trail = |m: &Seeded| m.envelope().trail;
        let mut s = Samples {
            e2e_ns: results.iter().map(|m| trail(m).end_to_end_ns()).collect(),
            ..Default::default()
        };
        for id in StageId::ALL {
            if hops && let Some(_) = id.upstream() {
                s.hop_ns.push((
                    id.name().to_owned(),
                    results.iter().filter_map(|m| trail(m).hop_ns(id)).collect(),
                ));
            }
            s.process_ns.push((
                id.name().to_owned(),
                results.iter().map(|m| trail(m).process_ns(id)).collect(),
            ));
        }
        s
    }

    /// End-to-end percentiles.
    pub fn end_to_end(&self) -> Percentiles {
        Percentiles::of(&mut self.e2e_ns.clone())
    }

    /// Per-stage latency percentiles.
    pub fn stages(&self) -> Vec<StageLatency> {
        StageId::ALL
            .iter()
            .map(|id| {
                let find = |v: &[(String, Vec<u64>)]| {
                    v.iter()
                        .find(|(n, _)| n == id.name())
                        .map_or(Percentiles::default(), |(_, x)| {
                            Percentiles::of(&mut x.clone())
                        })
                };
                StageLatency {
                    stage: id.name(),
                    hop: find(&self.hop_ns),
                    process: find(&self.process_ns),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stages::{Evidence, PoseEstimate, Rules, Verdict};
    use crate::wire::{Maybe, Truth};

    fn frame(seq: u64, est: Option<(f32, f32)>, confidence: f32, truth: (f64, f64)) -> Seeded {
        let mut m = Seeded::default();
        m.envelope_mut().frame.sequence = seq;
        m.envelope_mut().frame.truth = Maybe::Present(Truth {
            theta_deg: truth.0,
            phi_deg: truth.1,
            ..Default::default()
        });
        if let Some((t, p)) = est {
            m.rated.posed.pose = Outcome::Done(PoseEstimate {
                theta_deg: t,
                phi_deg: p,
                ..Default::default()
            });
            let evidence = Evidence {
                confidence,
                rival: 0.0,
                phi_plateau_deg: 0.0,
                map_rival: f32::NEG_INFINITY,
                detection_margin: f32::INFINITY,
                match_value: 1.0,
                shape: None,
            };
            let rules = Rules {
                max_rival: 1.0,
                phi_plateau_limit_deg: f32::INFINITY,
                ..Rules::with_threshold(0.8)
            };
            let v = Verdict::new(evidence, rules);
            m.rated.rating = Rating::Rated(v);
            if v.accepted {
                m.seeding.seed = Outcome::Done(Default::default());
            }
        }
        m
    }

    /// `m` with its verdict judged on a detection 1.1x over its threshold
    /// and a best match of 0.5.
    fn faint(mut m: Seeded) -> Seeded {
        if let Rating::Rated(v) = m.rated.rating {
            let evidence = Evidence {
                confidence: v.confidence,
                rival: v.rival,
                phi_plateau_deg: v.phi_plateau_deg,
                map_rival: v.map_rival,
                detection_margin: 1.1,
                match_value: 0.5,
                shape: None,
            };
            let rules = Rules {
                threshold: v.threshold,
                max_rival: v.max_rival,
                phi_plateau_limit_deg: v.phi_plateau_limit_deg,
                max_map_rival: v.max_map_rival,
                ..Rules::with_threshold(v.threshold)
            };
            m.rated.rating = Rating::Rated(Verdict::new(evidence, rules));
            m.seeding.seed = Outcome::Skipped;
        }
        m
    }

    #[test]
    fn wrong_accepted_estimates_are_counted_by_the_paper_rule() {
        let results = [
            frame(0, Some((60.0, 10.0)), 0.9, (62.0, 15.0)),
            // φ off by 25° across the 0/360 seam: wrong, and accepted.
            frame(1, Some((60.0, 350.0)), 0.95, (60.0, 15.0)),
            // Wrong but rejected: not a wrong accepted pose.
            frame(2, Some((30.0, 10.0)), 0.1, (60.0, 10.0)),
            frame(3, None, 0.0, (60.0, 10.0)),
            // Rated 0.99, but found faintly and matched weakly.
            faint(frame(4, Some((60.0, 10.0)), 0.99, (60.0, 10.0))),
        ];
        let o = Outcomes::of(&results);
        assert_eq!(o.estimated, 4);
        assert_eq!(o.accepted, 2);
        assert_eq!(o.rejected, 2);
        assert_eq!((o.rejected_faint, o.rejected_ambiguous), (1, 0));
        assert_eq!(o.seeds, 2);
        assert_eq!(o.accepted_wrong, 1);
        assert_eq!(o.accepted_with_truth, 2);
        assert_eq!(o.accepted_wrong_sequences, vec![1]);
        assert!((o.accepted_mean_theta_err_deg - 1.0).abs() < 1e-9);
        assert!((o.accepted_mean_phi_err_deg - 15.0).abs() < 1e-9);
    }

    #[test]
    fn percentiles_of_no_samples_are_zero() {
        assert_eq!(Percentiles::of(&mut []), Percentiles::default());
        let p = Percentiles::of(&mut [3_000_000, 1_000_000, 2_000_000]);
        assert_eq!((p.p50_ms, p.max_ms), (2.0, 3.0));
    }
}
