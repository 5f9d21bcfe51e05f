//! Evaluating a confidence rating against ground-truth labels
//! (`true` = the estimate was reliable): ranking (ROC AUC), calibration
//! (reliability bins) and what a threshold does (the paper's table 2).
//!
//! Scores and labels pair up by index; every function here is total: it
//! never panics, and answers NaN (or nothing) where a quantity is undefined.

/// Area under the ROC curve of `scores` as a predictor of `labels`: the
/// probability that a random reliable example scores higher than a random
/// unreliable one, ties counting one half (average ranks). 1 = perfect
/// ranking, 0.5 = chance or all tied, 0 = reversed.
///
/// NaN when the lengths differ, a class is absent or a score is not finite.
pub fn roc_auc(scores: &[f32], labels: &[bool]) -> f64 {
    if scores.len() != labels.len() || scores.iter().any(|s| !s.is_finite()) {
        return f64::NAN;
    }
    let n_pos = labels.iter().filter(|&&l| l).count();
    let n_neg = labels.len() - n_pos;
    if n_pos == 0 || n_neg == 0 {
        return f64::NAN;
    }
    let mut order: Vec<usize> = (0..scores.len()).collect();
    order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]));
    // Sum of the (1-based, tie-averaged) ranks of the positives.
    let mut rank_sum = 0.0f64;
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && scores[order[j + 1]] == scores[order[i]] {
            j += 1;
        }
        let avg_rank = (i + j) as f64 / 2.0 + 1.0;
        let pos_in_run = order[i..=j].iter().filter(|&&k| labels[k]).count();
        rank_sum += avg_rank * pos_in_run as f64;
        i = j + 1;
    }
    let (p, n) = (n_pos as f64, n_neg as f64);
    (rank_sum - p * (p + 1.0) / 2.0) / (p * n)
}

/// One bin of a reliability diagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bin {
    /// Lower edge of the bin (inclusive).
    pub lo: f64,
    /// Upper edge (exclusive, except 1 for the last bin).
    pub hi: f64,
    /// Examples whose score falls in the bin.
    pub count: usize,
    /// Mean score in the bin (0 when empty).
    pub mean_confidence: f64,
    /// Fraction of reliable examples in the bin (0 when empty).
    pub accuracy: f64,
}

/// Splits [0, 1] into `bins` equal bins and reports, per bin, the mean
/// score and the fraction of reliable examples: a calibrated rating has
/// `accuracy ≈ mean_confidence` in every bin. Scores outside [0, 1] are
/// clamped; non-finite scores are skipped. Empty when `bins` is 0 or the
/// lengths differ.
pub fn reliability_bins(scores: &[f32], labels: &[bool], bins: usize) -> Vec<Bin> {
    if bins == 0 || scores.len() != labels.len() {
        return Vec::new();
    }
    let mut sum = vec![0.0f64; bins];
    let mut hits = vec![0usize; bins];
    let mut count = vec![0usize; bins];
    for (&s, &l) in scores.iter().zip(labels) {
        if !s.is_finite() {
            continue;
        }
        let s = s.clamp(0.0, 1.0) as f64;
        let k = ((s * bins as f64) as usize).min(bins - 1);
        count[k] += 1;
        sum[k] += s;
        hits[k] += l as usize;
    }
    (0..bins)
        .map(|k| {
            let c = count[k];
            let mean = |x: f64| if c > 0 { x / c as f64 } else { 0.0 };
            Bin {
                lo: k as f64 / bins as f64,
                hi: (k + 1) as f64 / bins as f64,
                count: c,
                mean_confidence: mean(sum[k]),
                accuracy: mean(hits[k] as f64),
            }
        })
        .collect()
}

/// Expected calibration error of reliability bins: the count-weighted mean
/// of `|accuracy − mean_confidence|`; NaN when the bins are empty.
pub fn expected_calibration_error(bins: &[Bin]) -> f64 {
    let total: usize = bins.iter().map(|b| b.count).sum();
    if total == 0 {
        return f64::NAN;
    }
    bins.iter()
        .map(|b| b.count as f64 * (b.accuracy - b.mean_confidence).abs())
        .sum::<f64>()
        / total as f64
}

/// What a threshold does to a test set: the columns "Failures" and "FR" of
/// the paper's table 2, before and after the confidence rating.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Acceptance {
    /// Examples.
    pub total: usize,
    /// Unreliable examples (failures of the estimator).
    pub failures: usize,
    /// Examples whose score reaches the threshold.
    pub accepted: usize,
    /// Accepted examples that are failures.
    pub accepted_failures: usize,
}

impl Acceptance {
    /// Counts over the pairs of `scores` and `labels` (up to the shorter
    /// one); a score is accepted when `score >= threshold` (NaN never is).
    pub fn new(scores: &[f32], labels: &[bool], threshold: f32) -> Acceptance {
        let mut a = Acceptance::default();
        for (&s, &l) in scores.iter().zip(labels) {
            let accepted = s >= threshold;
            a.total += 1;
            a.failures += !l as usize;
            a.accepted += accepted as usize;
            a.accepted_failures += (accepted && !l) as usize;
        }
        a
    }

    /// Fraction of examples accepted (the paper's FR); NaN when empty.
    pub fn acceptance_rate(&self) -> f64 {
        self.accepted as f64 / self.total as f64
    }

    /// Fraction of failures without the rating; NaN when empty.
    pub fn failure_rate(&self) -> f64 {
        self.failures as f64 / self.total as f64
    }

    /// Fraction of failures among the accepted; NaN when none is accepted.
    pub fn accepted_failure_rate(&self) -> f64 {
        self.accepted_failures as f64 / self.accepted as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auc_extremes_and_ties() {
        let labels = [false, false, true, true, true];
        let perfect = [0.1, 0.2, 0.7, 0.8, 0.9];
        assert_eq!(roc_auc(&perfect, &labels), 1.0);
        let reversed = [0.9, 0.8, 0.3, 0.2, 0.1];
        assert_eq!(roc_auc(&reversed, &labels), 0.0);
        assert_eq!(roc_auc(&[0.5; 5], &labels), 0.5);
        // One tie across classes out of 6 pairs: (5 + 0.5) / 6.
        let partial = [0.1, 0.7, 0.7, 0.8, 0.9];
        assert!((roc_auc(&partial, &labels) - 5.5 / 6.0).abs() < 1e-12);
        // One inverted pair: 5 / 6.
        let inverted = [0.1, 0.75, 0.7, 0.8, 0.9];
        assert!((roc_auc(&inverted, &labels) - 5.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn auc_matches_pair_counting() {
        // Brute force over all pairs on a pseudo-random set with many ties.
        let mut x = 12345u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let scores: Vec<f32> = (0..200).map(|_| (next() % 11) as f32 / 10.0).collect();
        let labels: Vec<bool> = scores
            .iter()
            .map(|&s| (next() % 100) as f32 / 100.0 < s)
            .collect();
        let mut wins = 0.0;
        let mut pairs = 0.0;
        for (i, &li) in labels.iter().enumerate() {
            for (j, &lj) in labels.iter().enumerate() {
                if li && !lj {
                    pairs += 1.0;
                    wins += match scores[i].total_cmp(&scores[j]) {
                        std::cmp::Ordering::Greater => 1.0,
                        std::cmp::Ordering::Equal => 0.5,
                        std::cmp::Ordering::Less => 0.0,
                    };
                }
            }
        }
        assert!((roc_auc(&scores, &labels) - wins / pairs).abs() < 1e-9);
    }

    #[test]
    fn auc_undefined() {
        assert!(roc_auc(&[0.1, 0.2], &[true, true]).is_nan());
        assert!(roc_auc(&[0.1], &[true, false]).is_nan());
        assert!(roc_auc(&[f32::NAN, 0.2], &[true, false]).is_nan());
        assert!(roc_auc(&[], &[]).is_nan());
    }

    #[test]
    fn reliability_diagram() {
        let scores = [0.05, 0.15, 0.95, 1.0, 0.9, 1.7, -0.2, f32::NAN];
        let labels = [false, false, true, true, false, true, false, true];
        let bins = reliability_bins(&scores, &labels, 2);
        assert_eq!(bins.len(), 2);
        assert_eq!((bins[0].lo, bins[0].hi, bins[1].hi), (0.0, 0.5, 1.0));
        // Low bin: 0.05, 0.15, 0 (clamped -0.2), all unreliable.
        assert_eq!(bins[0].count, 3);
        assert!((bins[0].mean_confidence - 0.2 / 3.0).abs() < 1e-6);
        assert_eq!(bins[0].accuracy, 0.0);
        // High bin: 0.95, 1, 0.9, 1 (clamped); 3 of 4 reliable.
        assert_eq!(bins[1].count, 4);
        assert_eq!(bins[1].accuracy, 0.75);
        assert!((bins[1].mean_confidence - 3.85 / 4.0).abs() < 1e-6);
        let ece = expected_calibration_error(&bins);
        let expect = (3.0 * (0.2f64 / 3.0) + 4.0 * (3.85f64 / 4.0 - 0.75)) / 7.0;
        assert!((ece - expect).abs() < 1e-6, "{ece} vs {expect}");

        assert!(reliability_bins(&scores, &labels, 0).is_empty());
        assert!(reliability_bins(&scores[1..], &labels, 3).is_empty());
        let empty = reliability_bins(&[], &[], 4);
        assert!(empty.iter().all(|b| b.count == 0 && b.accuracy == 0.0));
        assert!(expected_calibration_error(&empty).is_nan());
    }

    #[test]
    fn acceptance_counts() {
        let scores = [0.9, 0.85, 0.8, 0.5, 0.95, f32::NAN];
        let labels = [true, false, true, false, true, false];
        let a = Acceptance::new(&scores, &labels, 0.8);
        assert_eq!(
            a,
            Acceptance {
                total: 6,
                failures: 3,
                accepted: 4,
                accepted_failures: 1
            }
        );
        assert_eq!(a.acceptance_rate(), 4.0 / 6.0);
        assert_eq!(a.failure_rate(), 0.5);
        assert_eq!(a.accepted_failure_rate(), 0.25);
        assert!(
            Acceptance::new(&[0.1], &[true], 0.8)
                .accepted_failure_rate()
                .is_nan()
        );
    }
}
