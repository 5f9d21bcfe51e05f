//! What the network looks at: the four features of the paper (section 4)
//! and, for the second variant, the whole response normalised by its
//! maximum.
//!
//! # Definitions
//!
//! Let `m` be the response (one match value per view, ordered θ-slice by
//! θ-slice), `g = max m` the global maximum and `i*` the first view that
//! reaches it, in slice `s*`. Ties are resolved towards the nearer
//! candidate (smaller separation), then towards the lower index.
//!
//! * **R_φ** — the best value `m[j]` over the views `j` of slice `s*` whose
//!   azimuth differs from φ(i*) by *more* than the minimum separation
//!   ([`FeatureParams::min_phi_separation_deg`], paper: 20°; wrapped, so
//!   350° and 0° are 10° apart), divided by `g`. In [0, 1]: 1 = a second
//!   peak as high as the first (ambiguous), 0 = nothing else matches.
//! * **D_φ** — the wrapped azimuth separation in degrees, in
//!   (min separation, 180], between `i*` and that view `j`.
//! * **R_θ** — the best value in any slice other than `s*`, divided by `g`.
//! * **D_θ** — the number of slices between `s*` and that slice
//!   (`|k − s*|` for slice index `k`; 1 = the neighbouring elevation).
//!
//! The paper writes the ratios as "global maximum to second best", which is
//! ≥ 1; here they are second / best so that they lie in [0, 1].
//!
//! Edge cases: when slice `s*` has no view beyond the minimum separation,
//! R_φ = D_φ = 0; when there is only one slice, R_θ = D_θ = 0 (no evidence
//! of ambiguity that could be measured). When `g = 0` (nothing matches at
//! all) every ratio whose candidate exists is 1: a flat response is as
//! ambiguous as a response can be.

use crate::ConfidenceError;
use acch_core::View;
use acch_pose::{Slice, phi_error};

/// Default minimum azimuth separation between the global maximum and the
/// second best match in its slice, degrees (paper: 20°).
pub const DEFAULT_MIN_PHI_SEPARATION_DEG: f32 = 20.0;

/// Number of features in [`Features`].
pub const FEATURE_COUNT: usize = 4;

/// Parameters of the feature extraction; stored with a trained model so
/// that rating uses the same definition as training did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureParams {
    /// Views closer than this (or exactly this) in azimuth to the global
    /// maximum are not candidates for the second best match in its slice,
    /// degrees in [0, 180).
    pub min_phi_separation_deg: f32,
}

impl Default for FeatureParams {
    fn default() -> Self {
        FeatureParams {
            min_phi_separation_deg: DEFAULT_MIN_PHI_SEPARATION_DEG,
        }
    }
}

impl FeatureParams {
    /// Checks that the separation is a finite angle in [0, 180).
    pub fn validate(&self) -> Result<(), ConfidenceError> {
        let s = self.min_phi_separation_deg;
        if s.is_finite() && (0.0..180.0).contains(&s) {
            Ok(())
        } else {
            Err(ConfidenceError::InvalidConfig(format!(
                "the minimum azimuth separation must be in [0, 180) degrees, got {s}"
            )))
        }
    }
}

/// The four features of a match-value response (see the module
/// documentation for the exact definitions).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Features {
    /// Second best match in the best θ slice, beyond the minimum azimuth
    /// separation, relative to the global maximum; [0, 1].
    pub r_phi: f32,
    /// Wrapped azimuth separation between those two views, degrees.
    pub d_phi: f32,
    /// Best match in any other θ slice relative to the global maximum;
    /// [0, 1].
    pub r_theta: f32,
    /// Number of slices between the best slice and that slice (1 =
    /// neighbour), as a float for the network.
    pub d_theta: f32,
}

impl Features {
    /// Computes the features of `response` over `views` split into
    /// `slices` (as [`acch_pose::slices`] returns them). Allocates nothing.
    ///
    /// Errors when the response is empty or holds a negative or
    /// non-finite value, when `views` has another length, when the slices
    /// do not cover the response contiguously in order, or when a view of
    /// the best slice has a non-finite azimuth.
    pub fn compute(
        response: &[f32],
        slices: &[Slice],
        views: &[View],
        params: &FeatureParams,
    ) -> Result<Features, ConfidenceError> {
        params.validate()?;
        let (best, g, s_star) = scan_with_slices(response, slices, views)?;
        let ratio = |v: f32| {
            if g > 0.0 {
                (v / g).clamp(0.0, 1.0)
            } else {
                1.0
            }
        };

        // φ: the second best view of slice s* beyond the separation.
        let s = slices[s_star];
        if let Some(index) = (s.start..s.start + s.len).find(|&j| !views[j].phi_deg.is_finite()) {
            return Err(ConfidenceError::InvalidView { index });
        }
        let phi0 = views[best].phi_deg;
        let mut second: Option<(f32, f32)> = None; // (value, separation)
        for j in s.start..s.start + s.len {
            if j == best {
                continue;
            }
            let d = phi_error(views[j].phi_deg, phi0);
            if d.is_nan() || d <= params.min_phi_separation_deg {
                continue;
            }
            let v = response[j];
            if second.is_none_or(|(bv, bd)| v > bv || (v == bv && d < bd)) {
                second = Some((v, d));
            }
        }
        let (r_phi, d_phi) = second.map_or((0.0, 0.0), |(v, d)| (ratio(v), d));

        // θ: the best view of any other slice.
        let mut other: Option<(f32, usize)> = None; // (value, slice distance)
        for (k, sl) in slices.iter().enumerate() {
            if k == s_star {
                continue;
            }
            let v = response[sl.start..sl.start + sl.len]
                .iter()
                .fold(f32::NEG_INFINITY, |a, &b| a.max(b));
            let d = k.abs_diff(s_star);
            if other.is_none_or(|(bv, bd)| v > bv || (v == bv && d < bd)) {
                other = Some((v, d));
            }
        }
        let (r_theta, d_theta) = other.map_or((0.0, 0.0), |(v, d)| (ratio(v), d as f32));

        Ok(Features {
            r_phi,
            d_phi,
            r_theta,
            d_theta,
        })
    }

    /// The features as the network's input vector:
    /// `[r_phi, d_phi, r_theta, d_theta]`.
    pub fn to_array(&self) -> [f32; FEATURE_COUNT] {
        [self.r_phi, self.d_phi, self.r_theta, self.d_theta]
    }
}

/// The whole response divided by its maximum: the input of
/// [`Kind::Response`](crate::Kind::Response) models. An all-zero response
/// becomes all ones (flat: maximally ambiguous).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ResponseFeatures {
    /// Normalised match values in [0, 1], one per view, in database order.
    pub values: Vec<f32>,
}

impl ResponseFeatures {
    /// Normalises `response`; errors as [`normalise_into`] does.
    pub fn compute(response: &[f32]) -> Result<ResponseFeatures, ConfidenceError> {
        let mut values = vec![0.0; response.len()];
        normalise_into(response, &mut values)?;
        Ok(ResponseFeatures { values })
    }
}

/// Writes `response / max(response)` into `out` without allocating.
///
/// Errors when the response is empty, holds a negative or non-finite value,
/// or `out` has another length.
pub fn normalise_into(response: &[f32], out: &mut [f32]) -> Result<(), ConfidenceError> {
    let (_, g) = scan_response(response)?;
    if out.len() != response.len() {
        return Err(ConfidenceError::LengthMismatch {
            what: "output buffer",
            expected: response.len(),
            found: out.len(),
        });
    }
    for (o, &v) in out.iter_mut().zip(response) {
        *o = normalised(v, g);
    }
    Ok(())
}

/// `v / g` for a response whose maximum is `g` (1 for a zero response).
pub(crate) fn normalised(v: f32, g: f32) -> f32 {
    if g > 0.0 {
        (v / g).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Checks a response and returns its first maximum `(index, value)`.
pub(crate) fn scan_response(response: &[f32]) -> Result<(usize, f32), ConfidenceError> {
    if response.is_empty() {
        return Err(ConfidenceError::EmptyResponse);
    }
    let mut best = (0, response[0]);
    for (i, &v) in response.iter().enumerate() {
        if !v.is_finite() || v < 0.0 {
            return Err(ConfidenceError::InvalidResponse { index: i, value: v });
        }
        if v > best.1 {
            best = (i, v);
        }
    }
    Ok(best)
}

/// The best match among the views the estimate would fail against, in
/// any θ slice, over the global maximum: views whose azimuth is more than
/// `min_phi_separation_deg` from the best view's, or whose elevation is
/// more than `theta_separation_deg` from it (the failure rule's 10°;
/// infinity: azimuth alone). In [0, 1] (0 when no view is that far, 1 for
/// a zero response). Unlike [`Features::r_phi`] it looks across slices:
/// seen from near above, the best view's rival in φ usually sits in a
/// neighbouring slice, and a turn of the object about the vertical is
/// then a turn of the image that the paper's same-slice ratio misses; and
/// a view two slices up or down at the same azimuth matching as well is
/// a tilt the response cannot place.
///
/// Errors as [`Features::compute`] does for the response and the views,
/// and for a `theta_separation_deg` that is not positive.
pub fn rival_ratio(
    response: &[f32],
    views: &[View],
    min_phi_separation_deg: f32,
    theta_separation_deg: f32,
) -> Result<f32, ConfidenceError> {
    FeatureParams {
        min_phi_separation_deg,
    }
    .validate()?;
    if theta_separation_deg.is_nan() || theta_separation_deg <= 0.0 {
        return Err(ConfidenceError::InvalidConfig(format!(
            "the elevation separation of a rival must be positive, got {theta_separation_deg}"
        )));
    }
    let (best, g) = scan_with_views(response, views)?;
    if let Some(index) = views.iter().position(|v| !v.phi_deg.is_finite()) {
        return Err(ConfidenceError::InvalidView { index });
    }
    let (theta0, phi0) = (views[best].theta_deg, views[best].phi_deg);
    let rival = response
        .iter()
        .zip(views)
        .filter(|(_, v)| {
            phi_error(v.phi_deg, phi0) > min_phi_separation_deg
                || (v.theta_deg - theta0).abs() > theta_separation_deg
        })
        .fold(None, |a: Option<f32>, (&m, _)| {
            Some(a.map_or(m, |a| a.max(m)))
        });
    Ok(rival.map_or(0.0, |v| normalised(v, g)))
}

/// How far in azimuth the best match holds: the span, degrees, of the run
/// of views about the best view, in its θ slice and in order of azimuth
/// (around the circle), that match at least `ratio` of the best; 0 when
/// its neighbours on both sides match less, 360 when the whole slice
/// matches so. The truth may lie anywhere on such a plateau: one that
/// spans twice the failure tolerance in φ cannot place the object within
/// it, however sharply the response falls off beyond. A view at the best
/// view's own azimuth (a duplicate) neither extends nor ends it. Walks the
/// slice without sorting it: allocates nothing (O(n²) in the slice's
/// views).
///
/// Errors as [`Features::compute`] does for the response, the views and
/// the slices, and when `ratio` is not in (0, 1].
pub fn phi_plateau_deg(
    response: &[f32],
    slices: &[Slice],
    views: &[View],
    ratio: f32,
) -> Result<f32, ConfidenceError> {
    if !(ratio > 0.0 && ratio <= 1.0) {
        return Err(ConfidenceError::InvalidConfig(format!(
            "the plateau's share of the best match must be in (0, 1], got {ratio}"
        )));
    }
    let (best, g, s_star) = scan_with_slices(response, slices, views)?;
    let run = slices[s_star].start..slices[s_star].start + slices[s_star].len;
    if let Some(index) = run.clone().find(|&j| !views[j].phi_deg.is_finite()) {
        return Err(ConfidenceError::InvalidView { index });
    }
    let phi0 = views[best].phi_deg;
    let floor = ratio * g;
    let mut span = 0.0;
    for turn in [1.0f32, -1.0] {
        // Azimuth from the best view, turning one way, in (0, 360).
        let offset = |j: usize| (turn * (views[j].phi_deg - phi0)).rem_euclid(360.0);
        let mut edge = 0.0;
        loop {
            let next = run
                .clone()
                .filter(|&j| offset(j) > edge)
                .min_by(|&a, &b| offset(a).total_cmp(&offset(b)));
            match next {
                // Around the circle: the whole slice matches.
                None => return Ok(360.0),
                Some(j) if response[j] >= floor => edge = offset(j),
                Some(_) => break,
            }
        }
        span += edge;
    }
    Ok(span.min(360.0))
}

/// [`scan_response`] of a response that must have a value per view.
fn scan_with_views(response: &[f32], views: &[View]) -> Result<(usize, f32), ConfidenceError> {
    let best = scan_response(response)?;
    if views.len() != response.len() {
        return Err(ConfidenceError::LengthMismatch {
            what: "views",
            expected: response.len(),
            found: views.len(),
        });
    }
    Ok(best)
}

/// [`scan_with_views`] of a response split into `slices`, and the index of
/// the slice that holds its maximum.
fn scan_with_slices(
    response: &[f32],
    slices: &[Slice],
    views: &[View],
) -> Result<(usize, f32, usize), ConfidenceError> {
    let (best, g) = scan_with_views(response, views)?;
    check_slices(slices, response.len())?;
    let slice = slices
        .iter()
        .position(|s| (s.start..s.start + s.len).contains(&best))
        .ok_or(ConfidenceError::BadSlices(
            "no slice holds the global maximum",
        ))?;
    Ok((best, g, slice))
}

/// Checks that the slices cover `0..n` contiguously, in order, each
/// non-empty.
fn check_slices(slices: &[Slice], n: usize) -> Result<(), ConfidenceError> {
    let mut next = 0usize;
    for s in slices {
        if s.len == 0 {
            return Err(ConfidenceError::BadSlices("a slice is empty"));
        }
        if s.start != next {
            return Err(ConfidenceError::BadSlices(
                "slices are not contiguous from the first view",
            ));
        }
        next = s
            .start
            .checked_add(s.len)
            .ok_or(ConfidenceError::BadSlices(
                "a slice extends past the response",
            ))?;
    }
    if next != n {
        return Err(ConfidenceError::BadSlices(
            "slices do not cover the response exactly",
        ));
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A grid of `thetas.len()` slices with `per_slice` views spaced evenly
    /// in φ from 0°.
    pub(crate) fn grid(thetas: &[f32], per_slice: usize) -> (Vec<Slice>, Vec<View>) {
        let mut slices = Vec::new();
        let mut views = Vec::new();
        for &t in thetas {
            slices.push(Slice {
                theta_deg: t,
                start: views.len(),
                len: per_slice,
            });
            for k in 0..per_slice {
                views.push(View {
                    theta_deg: t,
                    phi_deg: k as f32 * 360.0 / per_slice as f32,
                    size_px: 100.0,
                    centre_offset_px: [0.0; 2],
                });
            }
        }
        (slices, views)
    }

    const THETAS: [f32; 6] = [45.0, 50.0, 60.0, 70.0, 80.0, 90.0];

    fn feats(r: &[f32], slices: &[Slice], views: &[View]) -> Features {
        Features::compute(r, slices, views, &FeatureParams::default()).unwrap()
    }

    #[test]
    fn one_clear_peak_is_unambiguous() {
        let (slices, views) = grid(&THETAS, 36);
        // A peak at slice 2, φ = 180°, falling off with a Gaussian in φ and
        // θ over a floor of 0.3.
        let r: Vec<f32> = views
            .iter()
            .map(|v| {
                let dp = phi_error(v.phi_deg, 180.0) / 25.0;
                let dt = (v.theta_deg - 60.0) / 8.0;
                0.3 + 0.6 * (-(dp * dp + dt * dt) / 2.0).exp()
            })
            .collect();
        let f = feats(&r, &slices, &views);
        // Best beyond 20° is at 30°: 0.3 + 0.6 e^{-0.72} over 0.9.
        let expect = (0.3 + 0.6 * (-(1.2f32 * 1.2) / 2.0).exp()) / 0.9;
        assert!((f.r_phi - expect).abs() < 1e-5, "{f:?}");
        assert_eq!(f.d_phi, 30.0);
        // The neighbouring slices (50°, 70°) tie; both are one slice away.
        assert_eq!(f.d_theta, 1.0);
        assert!(f.r_theta < 0.9 && f.r_theta > 0.5, "{f:?}");

        // A spike over a flat floor: both ratios are small.
        let mut r = vec![0.1; views.len()];
        r[2 * 36 + 18] = 0.9;
        let f = feats(&r, &slices, &views);
        assert!((f.r_phi - 0.1 / 0.9).abs() < 1e-6);
        assert!((f.r_theta - 0.1 / 0.9).abs() < 1e-6);
        assert_eq!(f.d_theta, 1.0);
    }

    #[test]
    fn the_rival_is_the_best_far_view_in_any_slice() {
        const INF: f32 = f32::INFINITY;
        let (_, views) = grid(&THETAS, 36);
        let mut r = vec![0.2; views.len()];
        r[5 * 36 + 4] = 0.9; // θ = 90°, φ = 40°: the best.
        r[5 * 36 + 5] = 0.88; // φ = 50°: within 20°, no rival.
        r[4 * 36 + 3] = 0.89; // θ = 80°, φ = 30°: within 20°, no rival.
        // Nothing far matches: the floor.
        let floor = rival_ratio(&r, &views, 20.0, INF).unwrap();
        assert!((floor - 0.2 / 0.9).abs() < 1e-6, "{floor}");
        // The same slice's same-slice ratio would miss this one: another
        // slice, 140° away.
        r[4 * 36 + 18] = 0.891; // θ = 80°, φ = 180°
        let rival = rival_ratio(&r, &views, 20.0, INF).unwrap();
        assert!((rival - 0.891 / 0.9).abs() < 1e-6, "{rival}");
        // A tie is a rival of 1; a zero response is all rivals.
        r[18] = 0.9;
        assert_eq!(rival_ratio(&r, &views, 20.0, INF).unwrap(), 1.0);
        assert_eq!(
            rival_ratio(&vec![0.0; views.len()], &views, 20.0, INF).unwrap(),
            1.0
        );
        // A separation of 179.9°: only the opposite view could rival.
        assert!(rival_ratio(&r, &views, 179.9, INF).unwrap() < 0.5);
        assert!(rival_ratio(&r, &views[1..], 20.0, INF).is_err());
        assert!(rival_ratio(&r, &views, 180.0, INF).is_err());
        assert!(rival_ratio(&r, &views, 20.0, 0.0).is_err());
        assert!(rival_ratio(&r, &views, 20.0, f32::NAN).is_err());
    }

    #[test]
    fn a_view_beyond_the_tolerance_in_elevation_is_a_rival_too() {
        let (_, views) = grid(&THETAS, 36);
        let slice = |theta: f32| THETAS.iter().position(|&t| t == theta).unwrap();
        let mut r = vec![0.2; views.len()];
        let best = slice(60.0) * 36 + 4; // θ = 60°, φ = 40°
        r[best] = 0.9;
        r[slice(70.0) * 36 + 4] = 0.895; // 10° up: within the tolerance.
        let near = rival_ratio(&r, &views, 20.0, 10.0).unwrap();
        assert!((near - 0.2 / 0.9).abs() < 1e-6, "{near}");
        // Two slices up, the same azimuth: a tilt the response cannot
        // place; by azimuth alone no rival.
        r[slice(80.0) * 36 + 4] = 0.894;
        let tilted = rival_ratio(&r, &views, 20.0, 10.0).unwrap();
        assert!((tilted - 0.894 / 0.9).abs() < 1e-6, "{tilted}");
        let by_azimuth = rival_ratio(&r, &views, 20.0, f32::INFINITY).unwrap();
        assert!((by_azimuth - 0.2 / 0.9).abs() < 1e-6, "{by_azimuth}");
    }

    #[test]
    fn the_plateau_is_the_run_of_views_about_the_best_that_match_nearly_as_well() {
        let (slices, views) = grid(&THETAS, 36);
        let plateau = |r: &[f32]| phi_plateau_deg(r, &slices, &views, 0.98).unwrap();
        let mut r = vec![0.2; views.len()];
        r[4 * 36 + 1] = 0.9; // θ = 80°, φ = 10°: the best.
        assert_eq!(plateau(&r), 0.0);
        // Neighbours at 0° and 20° within 2 %, 350° just outside it; a view
        // beyond a gap (40°) or in another slice does not extend the run.
        r[4 * 36] = 0.885;
        r[4 * 36 + 2] = 0.883;
        r[4 * 36 + 35] = 0.881;
        r[4 * 36 + 4] = 0.899;
        r[3 * 36 + 3] = 0.899;
        assert_eq!(plateau(&r), 20.0);
        // Across 0°: 350° joins, and 340° beyond it.
        r[4 * 36 + 35] = 0.89;
        r[4 * 36 + 34] = 0.89;
        assert_eq!(plateau(&r), 40.0);
        assert_eq!(phi_plateau_deg(&r, &slices, &views, 0.995).unwrap(), 0.0);
        // The whole slice.
        r[4 * 36..5 * 36].fill(0.89);
        r[4 * 36 + 1] = 0.9;
        assert_eq!(plateau(&r), 360.0);
        // A duplicate of the best view's azimuth neither ends nor extends it.
        let mut twice = views.clone();
        twice[4 * 36 + 3].phi_deg = 10.0;
        let mut r = vec![0.2; views.len()];
        r[4 * 36 + 1] = 0.9;
        r[4 * 36 + 2] = 0.89;
        assert_eq!(phi_plateau_deg(&r, &slices, &twice, 0.98).unwrap(), 10.0);
        // Bad inputs are refused.
        for ratio in [0.0, 1.01, f32::NAN] {
            assert!(phi_plateau_deg(&r, &slices, &views, ratio).is_err());
        }
        assert!(phi_plateau_deg(&r, &slices, &views[1..], 0.98).is_err());
        assert!(phi_plateau_deg(&r, &slices[1..], &views, 0.98).is_err());
        let mut nan = views.clone();
        nan[4 * 36 + 7].phi_deg = f32::NAN;
        assert!(phi_plateau_deg(&r, &slices, &nan, 0.98).is_err());
    }

    #[test]
    fn two_equal_peaks_half_a_turn_apart() {
        let (slices, views) = grid(&THETAS, 36);
        let mut r = vec![0.2; views.len()];
        r[36 + 4] = 0.8; // φ = 40°
        r[36 + 22] = 0.8; // φ = 220°
        let f = feats(&r, &slices, &views);
        assert_eq!(f.r_phi, 1.0);
        assert_eq!(f.d_phi, 180.0);
        assert!((f.r_theta - 0.25).abs() < 1e-6);
    }

    #[test]
    fn runner_up_two_slices_away() {
        let (slices, views) = grid(&THETAS, 36);
        let mut r = vec![0.1; views.len()];
        r[2 * 36 + 5] = 0.9; // slice 2
        r[4 * 36 + 30] = 0.6; // slice 4
        r[36 + 5] = 0.5; // slice 1: a neighbour, but lower
        let f = feats(&r, &slices, &views);
        assert_eq!(f.d_theta, 2.0);
        assert!((f.r_theta - 0.6 / 0.9).abs() < 1e-6);
    }

    #[test]
    fn separation_wraps_around_zero() {
        let (slices, views) = grid(&THETAS, 36);
        let mut r = vec![0.1; views.len()];
        let base = 3 * 36;
        r[base] = 1.0; // φ = 0°
        r[base + 35] = 0.95; // φ = 350°: 10° away, excluded
        r[base + 34] = 0.93; // φ = 340°: exactly 20°, excluded
        r[base + 1] = 0.94; // φ = 10°
        r[base + 2] = 0.92; // φ = 20°
        r[base + 33] = 0.5; // φ = 330°: 30° away, the runner-up
        let f = feats(&r, &slices, &views);
        assert!((f.r_phi - 0.5).abs() < 1e-6, "{f:?}");
        assert_eq!(f.d_phi, 30.0);

        // A wider separation moves the candidate set.
        let p = FeatureParams {
            min_phi_separation_deg: 5.0,
        };
        let f = Features::compute(&r, &slices, &views, &p).unwrap();
        assert_eq!((f.r_phi, f.d_phi), (0.95, 10.0));
    }

    #[test]
    fn degenerate_grids() {
        // One slice: no θ evidence.
        let (slices, views) = grid(&[60.0], 36);
        let mut r = vec![0.1; 36];
        r[7] = 0.7;
        let f = feats(&r, &slices, &views);
        assert_eq!((f.r_theta, f.d_theta), (0.0, 0.0));
        // Slices too coarse for anything beyond 20°... with 1 view each.
        let (slices, views) = grid(&[45.0, 60.0], 1);
        let f = feats(&[0.4, 0.8], &slices, &views);
        assert_eq!((f.r_phi, f.d_phi), (0.0, 0.0));
        assert_eq!((f.r_theta, f.d_theta), (0.5, 1.0));
        // All zero: flat, maximally ambiguous.
        let (slices, views) = grid(&THETAS, 36);
        let f = feats(&vec![0.0; views.len()], &slices, &views);
        assert_eq!((f.r_phi, f.r_theta, f.d_theta), (1.0, 1.0, 1.0));
    }

    #[test]
    fn bad_input_is_an_error() {
        let (slices, views) = grid(&THETAS, 36);
        let p = FeatureParams::default();
        let r = vec![0.5; views.len()];
        assert!(matches!(
            Features::compute(&[], &slices, &views, &p),
            Err(ConfidenceError::EmptyResponse)
        ));
        let mut bad = r.clone();
        bad[3] = f32::NAN;
        assert!(matches!(
            Features::compute(&bad, &slices, &views, &p),
            Err(ConfidenceError::InvalidResponse { index: 3, .. })
        ));
        bad[3] = -0.5;
        assert!(Features::compute(&bad, &slices, &views, &p).is_err());
        assert!(matches!(
            Features::compute(&r[1..], &slices, &views, &p),
            Err(ConfidenceError::LengthMismatch { .. })
        ));
        assert!(matches!(
            Features::compute(&r, &slices[1..], &views, &p),
            Err(ConfidenceError::BadSlices(_))
        ));
        let mut s = slices.clone();
        s[2].len = 0;
        assert!(Features::compute(&r, &s, &views, &p).is_err());
        s[2].len = usize::MAX;
        assert!(Features::compute(&r, &s, &views, &p).is_err());
        let mut v = views.clone();
        v[1].phi_deg = f32::NAN;
        assert!(matches!(
            Features::compute(&r, &slices, &v, &p),
            Err(ConfidenceError::InvalidView { index: 1 })
        ));
        let p = FeatureParams {
            min_phi_separation_deg: f32::NAN,
        };
        assert!(matches!(
            Features::compute(&r, &slices, &views, &p),
            Err(ConfidenceError::InvalidConfig(_))
        ));
    }

    #[test]
    fn response_normalisation() {
        let rf = ResponseFeatures::compute(&[0.2, 0.4, 0.1]).unwrap();
        assert_eq!(rf.values, vec![0.5, 1.0, 0.25]);
        let rf = ResponseFeatures::compute(&[0.0, 0.0]).unwrap();
        assert_eq!(rf.values, vec![1.0, 1.0]);
        let mut out = [0.0; 2];
        assert!(normalise_into(&[0.1, 0.2, 0.3], &mut out).is_err());
        assert!(ResponseFeatures::compute(&[0.1, f32::INFINITY]).is_err());
    }
}
