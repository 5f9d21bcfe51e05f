//! The pose from the object's shape, verified against the image: the
//! silhouette search proposes views and rolls for the region (and another
//! estimate, the colour histograms', may add its own), each candidate is
//! fitted to the image by colour along its contour, and the fitted poses
//! are judged by how sharply the object's colours part from its
//! surroundings along the contour and how well the silhouette covers the
//! region. The best is the estimate (a pose below the lowest elevation
//! the camera sees ranks after every pose above it); the best of those
//! above it that would be a failure if it were right, by more than a
//! neighbour's span, is its rival.

use crate::edges::Edges;
use crate::geometry::{View, view_of};
use crate::lines::{Image, LineParams, LineScratch, fit_covariance, fit_lines};
use crate::model::ShapeModel;
use crate::search::{Region, place_view, search};
use crate::symmetry::Symmetry;
use crate::verify::{Evidence, evidence};
use acch_capture::Intrinsics;
use glam::DAffine3;
use std::sync::Arc;

/// How the shape estimate is made.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeSettings {
    /// The silhouette search tries the roll every this many degrees...
    pub roll_step_deg: f64,
    /// ...within ± this many (180: any roll): how far the camera rolls
    /// about its optical axis, plus what an object off the axis adds.
    pub max_roll_deg: f64,
    /// Candidates the silhouette search hands on.
    pub candidates: usize,
    /// The fit by colour.
    pub lines: LineParams,
    /// Two poses are different views when one would fail as an estimate
    /// of the other: elevation beyond this, degrees...
    pub distinct_theta_deg: f64,
    /// ...or azimuth beyond this.
    pub distinct_phi_deg: f64,
    /// The best's rival lies farther from it than this times those two
    /// tolerances. A nearer candidate that explains the image about as
    /// well says the truth lies between the two, where the best is still
    /// right: on LM-O's development objects with the annotated mask, of
    /// the 49 estimates only such a neighbour held below the margin, 47
    /// were right (docs/real-photographs.md, "Fifth round"); widened from
    /// 1.5 to 1.75, 21 more right estimates were accepted there and 2 more
    /// wrong ones, both within 8° of the truth, once a third, a glue 33°
    /// off, fell to the bar on distance
    /// (`acch_confidence::MAX_DISTANCE_RATIO`; "Eighth round").
    pub rival_span: f64,
    /// The estimate blends the best with its neighbours (the candidates
    /// within the rival span; for a best the camera sees, only those it
    /// sees too), each weighed by `exp((score - best's) /
    /// this)`: the score hardly changes within 12-25° of a right pose, so
    /// the truth tends to lie among neighbours that score alike (0: the
    /// best alone).
    pub blend_score_scale: f32,
    /// How far the best candidate's neighbours are tilted in the polish's
    /// first round, degrees (0: no polish).
    pub polish_deg: f64,
    /// Rounds of the polish of the shape's own best (an anchored view is
    /// polished once), each tilting half as far as the one before around
    /// the best so far: a right pose 3-6° off leaves its contour a
    /// few pixels from the region's edge. On LM-O's development objects
    /// with the annotated mask, a second round (2.5°) raised accepted and
    /// right by 0.5-3.5 points per object (docs/real-photographs.md,
    /// "Sixth round").
    pub polish_rounds: u32,
    /// The fit of a challenger: it starts at the best's own place.
    pub challenger_lines: LineParams,
    /// A view the shape found overrules the colours' anchored one when
    /// its score is higher by this much (the margin acceptance asks of a
    /// pose the shape chose).
    pub overrule_margin: f32,
    /// Elevation below which a pose is not one the camera sees, degrees
    /// (-inf: any): the candidates are ranked with such poses after every
    /// other, so one is the search's best only when the camera sees none
    /// (an anchored view stays the colours'); it is never the best's
    /// rival and is not blended into a best the camera sees. The view
    /// that may overrule an anchor is the first different one in this
    /// ranking, so such a pose overrules only when no pose above the floor
    /// differs from the anchor (barred from that too, the anchor stayed a
    /// wrong estimate where a camera below the database saw the object).
    /// The polish stays free: where it tilts the best below the floor,
    /// acceptance's elevation bar rejects it (on LM-O's ape, holding the
    /// polish above the floor accepted a half turn at the floor that the
    /// bar had rejected). The database covers the elevations the camera
    /// sees and acceptance bars a pose below them
    /// (`acch_confidence::min_theta_deg`), so a pose there is no answer
    /// and no ambiguity. On LM-O's development objects with the annotated
    /// mask, 11 more right estimates were accepted once such rivals no
    /// longer counted, and 20 fewer instances failed once such candidates
    /// came last (docs/real-photographs.md, "Seventh round").
    pub lowest_elevation_deg: f64,
}

impl Default for ShapeSettings {
    fn default() -> Self {
        ShapeSettings {
            roll_step_deg: 5.0,
            max_roll_deg: 180.0,
            candidates: 8,
            lines: LineParams::default(),
            distinct_theta_deg: 10.0,
            distinct_phi_deg: 20.0,
            rival_span: 1.75,
            blend_score_scale: 0.1,
            polish_deg: 5.0,
            polish_rounds: 2,
            challenger_lines: LineParams {
                lengths_px: vec![8.0, 4.0],
                ..LineParams::default()
            },
            overrule_margin: 0.3,
            lowest_elevation_deg: f64::NEG_INFINITY,
        }
    }
}

/// One candidate, fitted and measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scored {
    /// Camera from object, object radii, after the fit.
    pub pose: DAffine3,
    /// The model's view nearest it.
    pub view: usize,
    /// What it explains of the image.
    pub evidence: Evidence,
    /// What ranks it.
    pub score: f32,
}

/// The shape's estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeEstimate {
    /// Every candidate, the best first, then the others by score.
    pub scored: Vec<Scored>,
    /// The best candidate that would fail as an estimate of the best (a
    /// different view, symmetries allowed for) by more than
    /// [`ShapeSettings::rival_span`] tolerances, of those the camera sees
    /// ([`ShapeSettings::lowest_elevation_deg`]), when there is one.
    pub rival: Option<usize>,
    /// The best is the anchored proposal ([`Proposal::anchored`]).
    pub anchored: bool,
    /// The estimate's covariance: the best pose's from its fit
    /// ([`crate::lines::fit_covariance`]) plus the spread of the poses
    /// blended into [`pose`](Self::pose) about it.
    pub covariance: [[f64; 6]; 6],
    /// The estimate: the best pose blended with its neighbours'
    /// ([`ShapeSettings::blend_score_scale`]), or the best alone when
    /// [`anchored`](Self::anchored). Its evidence is the best's.
    pub pose: DAffine3,
}

impl ShapeEstimate {
    /// The best candidate.
    pub fn best(&self) -> &Scored {
        &self.scored[0]
    }

    /// The estimate's view.
    pub fn view(&self) -> View {
        view_of(&self.pose)
    }

    /// The rival's score; -inf when there is none.
    pub fn rival_score(&self) -> f32 {
        self.rival
            .map_or(f32::NEG_INFINITY, |r| self.scored[r].score)
    }
}

/// The estimate blended from near candidates ([`ShapeEstimator::blend`]).
struct Blend {
    /// The blended pose.
    pose: DAffine3,
    /// The weighted scatter of the blended poses about it, over the
    /// twist `(w, v)` of [`crate::lines::fit_covariance`].
    spread: [[f64; 6]; 6],
}

impl Blend {
    /// `pose` alone, blended with nothing.
    fn alone(pose: DAffine3) -> Self {
        Blend {
            pose,
            spread: [[0.0; 6]; 6],
        }
    }
}

/// The blend's neighbours turn from the best by at most this, degrees.
const BLEND_TURN_DEG: f64 = 30.0;
/// Fitted poses nearer each other than this, degrees, are one pose to
/// the blend ([`ShapeSettings::blend_score_scale`]).
const SAME_POSE_DEG: f64 = 3.0;

/// Turns of the best pose about the object's up axis tried as its
/// challengers, degrees.
const CHALLENGER_TURNS_DEG: [f64; 7] = [30.0, 60.0, 90.0, 180.0, 270.0, 300.0, 330.0];
/// How far the best pose is tilted for its other challengers, degrees.
const CHALLENGER_TILT_DEG: f64 = 20.0;

/// The score that ranks candidates: the sum of every measure of what the
/// pose explains, each a share or a correlation. The contour on the
/// region's edge counts twice and the colour histograms half: on LM-O's
/// development objects the right candidate lost mostly to poses whose
/// contour left the region (the can's half turns, proposed and carried by
/// its colours); weighed so, 586 instead of 539 of 929 instances were
/// ranked right.
pub fn rank_score(e: &Evidence) -> f32 {
    e.separation
        + e.overlap
        + 2.0 * e.region_edge
        + e.contour_edges
        + e.inner_edges
        + e.colour
        + 0.5 * e.histograms
}

/// One frame's inputs to the fits.
struct Frame<'a> {
    image: &'a Image<'a>,
    k: &'a Intrinsics,
    region: &'a Region<'a>,
    colour: Option<&'a (dyn Fn(f64, f64) -> f32 + Sync)>,
}

/// What every fit of a frame reads, shared by the threads that fit.
struct Fitter<'a> {
    model: &'a ShapeModel,
    settings: &'a ShapeSettings,
    edges: &'a Edges,
    frame: &'a Frame<'a>,
}

impl Fitter<'_> {
    /// `start` fitted (by the short schedule when `quick`: a challenger
    /// starts at a whole pose, not a grid step away) and measured.
    fn fit(&self, start: &DAffine3, quick: bool, lines: &mut LineScratch) -> Scored {
        let frame = self.frame;
        let params = if quick {
            &self.settings.challenger_lines
        } else {
            &self.settings.lines
        };
        let f = fit_lines(
            self.model,
            frame.image,
            frame.k,
            Some(frame.region),
            start,
            params,
            lines,
        );
        let mut evidence = evidence(
            self.model,
            f.view,
            &f.pose,
            f.separation,
            frame.image,
            self.edges,
            frame.k,
            frame.region,
        );
        if let Some(colour) = frame.colour {
            let v = view_of(&f.pose);
            evidence.histograms = colour(v.theta_deg, v.phi_deg);
        }
        Scored {
            pose: f.pose,
            view: f.view,
            score: rank_score(&evidence),
            evidence,
        }
    }
}

/// The pose from an object's shape.
#[derive(Clone, Debug)]
pub struct ShapeEstimator {
    model: ShapeModel,
    symmetry: Symmetry,
    settings: ShapeSettings,
    edges: Edges,
    lines: LineScratch,
    /// A thread that shares the fits ([`ShapeEstimator::share_fits_with`]),
    /// and its buffers.
    helper: Option<(Arc<rayon::ThreadPool>, LineScratch)>,
}

impl ShapeEstimator {
    /// An estimator of `model`, which looks the same by `symmetry`.
    pub fn new(model: ShapeModel, symmetry: Symmetry, settings: ShapeSettings) -> Self {
        ShapeEstimator {
            model,
            symmetry,
            settings,
            edges: Edges::default(),
            lines: LineScratch::default(),
            helper: None,
        }
    }

    /// Shares every batch of fits with `pool`'s first thread
    /// ([`acch_core::share::in_turn`]). The fits are independent, so the
    /// estimate is the same bit for bit.
    pub fn share_fits_with(&mut self, pool: Arc<rayon::ThreadPool>) {
        self.helper = Some((pool, LineScratch::default()));
    }

    /// The model.
    pub fn model(&self) -> &ShapeModel {
        &self.model
    }

    /// The object's symmetry.
    pub fn symmetry(&self) -> &Symmetry {
        &self.symmetry
    }

    /// Whether `a` would fail as an estimate of `b` (or of any pose that
    /// looks like it).
    pub fn distinct(&self, a: &DAffine3, b: &DAffine3) -> bool {
        self.apart(a, b, 1.0)
    }

    /// Whether `pose` lies at or above the lowest elevation the camera
    /// sees ([`ShapeSettings::lowest_elevation_deg`]).
    fn seen(&self, pose: &DAffine3) -> bool {
        view_of(pose).theta_deg >= self.settings.lowest_elevation_deg
    }

    /// Sorts `scored` best first: the poses the camera sees by score, then
    /// the others by score (a pose it does not see leads only when the
    /// camera sees none).
    fn rank(&self, scored: &mut [Scored]) {
        scored.sort_by(|a, b| {
            self.seen(&b.pose)
                .cmp(&self.seen(&a.pose))
                .then(b.score.total_cmp(&a.score))
        });
    }

    /// The best rival of `scored[0]` (`scored` sorted best first): the
    /// first candidate the camera sees that lies farther than `span`
    /// tolerances from it.
    fn rival(&self, scored: &[Scored], span: f64) -> Option<usize> {
        let best = scored.first()?.pose;
        (1..scored.len())
            .find(|&i| self.seen(&scored[i].pose) && self.apart(&scored[i].pose, &best, span))
    }

    /// Whether `a` lies farther than `span` failure tolerances from `b`
    /// (and from any pose that looks like it).
    fn apart(&self, a: &DAffine3, b: &DAffine3, span: f64) -> bool {
        let va = view_of(a);
        self.symmetry.equivalents(&b.matrix3).all(|r| {
            let vb = view_of(&DAffine3::from_mat3_translation(r, b.translation));
            let dphi = (va.phi_deg - vb.phi_deg + 540.0).rem_euclid(360.0) - 180.0;
            (va.theta_deg - vb.theta_deg).abs() > span * self.settings.distinct_theta_deg
                || dphi.abs() > span * self.settings.distinct_phi_deg
        })
    }

    /// The best of `scored` (sorted, best first) blended with its
    /// neighbours within `span` tolerances, each weighed by its score
    /// ([`ShapeSettings::blend_score_scale`]) and taken as the look-alike
    /// nearest the best (the object's symmetries), with the weighted
    /// spread of what it blended about it.
    fn blend(&self, scored: &[Scored], span: f64) -> Blend {
        let best = &scored[0];
        let alone = Blend::alone(best.pose);
        let scale = self.settings.blend_score_scale;
        if scale <= 0.0 {
            return alone;
        }
        let q_best = glam::DQuat::from_mat3(&best.pose.matrix3);
        let mut members: Vec<(f64, glam::DQuat, glam::DVec3)> = Vec::new();
        // A pose the camera does not see blends only into a best it does
        // not see either: ranked below the best, it may score above it.
        let seen = self.seen(&best.pose);
        for c in scored {
            if self.apart(&c.pose, &best.pose, span) || (seen && !self.seen(&c.pose)) {
                continue;
            }
            let nearest = self
                .symmetry
                .equivalents(&c.pose.matrix3)
                .map(|r| glam::DQuat::from_mat3(&r))
                .max_by(|a, b| a.dot(q_best).abs().total_cmp(&b.dot(q_best).abs()))
                .expect("a rotation is its own equivalent");
            // A neighbour by view may be the view upside down (the roll
            // half a turn off): only a near rotation blends.
            if nearest.angle_between(q_best).to_degrees() > BLEND_TURN_DEG {
                continue;
            }
            let q = if nearest.dot(q_best) < 0.0 {
                -nearest
            } else {
                nearest
            };
            // Fits that converged to one pose count once: the challengers
            // and the search often find the same.
            if members
                .iter()
                .any(|(_, p, _)| p.angle_between(q).to_degrees() < SAME_POSE_DEG)
            {
                continue;
            }
            let w = (((c.score - best.score) / scale) as f64).exp();
            members.push((w, q, c.pose.translation));
        }
        let w_sum: f64 = members.iter().map(|m| m.0).sum();
        if !(w_sum.is_finite() && w_sum > 0.0) {
            return alone;
        }
        let q_sum = members.iter().fold(glam::DVec4::ZERO, |s, (w, q, _)| {
            s + *w * glam::DVec4::from(*q)
        });
        let t_sum = members
            .iter()
            .fold(glam::DVec3::ZERO, |s, (w, _, t)| s + *w * *t);
        let q = glam::DQuat::from_vec4(q_sum).normalize();
        let t = t_sum / w_sum;
        // Where the truth lies between neighbours, the estimate is as
        // uncertain as they are apart: their spread over the fit's twist
        // (w, v), R' = exp(w) R, t' = t + v.
        let mut spread = [[0.0; 6]; 6];
        for (w, qi, ti) in &members {
            let dq = *qi * q.inverse();
            let rot = dq.to_scaled_axis();
            let d = ti - t;
            let x = [rot.x, rot.y, rot.z, d.x, d.y, d.z];
            for (r, row) in spread.iter_mut().enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v += w / w_sum * x[r] * x[c];
                }
            }
        }
        Blend {
            pose: DAffine3::from_mat3_translation(glam::DMat3::from_quat(q), t),
            spread,
        }
    }

    /// Each of `starts` fitted (by the short schedule when `quick`) and
    /// measured, in order; shared with the helper thread when there is one
    /// ([`acch_core::share::in_turn`]).
    fn fitted_all(&mut self, starts: &[DAffine3], quick: bool, frame: &Frame) -> Vec<Scored> {
        let fitter = Fitter {
            model: &self.model,
            settings: &self.settings,
            edges: &self.edges,
            frame,
        };
        // Without a helper nothing takes the second buffers (empty ones
        // allocate nothing).
        let mut unused = LineScratch::default();
        let (pool, helper_lines) = match &mut self.helper {
            Some((pool, lines)) => (Some(&**pool), lines),
            None => (None, &mut unused),
        };
        acch_core::share::in_turn(
            pool,
            starts.len(),
            &mut self.lines,
            helper_lines,
            |i, lines| fitter.fit(&starts[i], quick, lines),
        )
    }

    /// `start` fitted and measured.
    fn fitted(&mut self, start: &DAffine3, frame: &Frame) -> Scored {
        self.fitted_all(std::slice::from_ref(start), false, frame)[0]
    }

    /// The best of `start` and the poses tilted from it by `tilt_deg`
    /// about the camera's horizontal and vertical axes, each fitted and
    /// measured.
    fn polish(&mut self, start: &Scored, tilt_deg: f64, frame: &Frame) -> Scored {
        let d = tilt_deg.to_radians();
        let tilted: Vec<DAffine3> = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
            .iter()
            .map(|&(ax, ay)| {
                let turn =
                    glam::DMat3::from_rotation_x(ax * d) * glam::DMat3::from_rotation_y(ay * d);
                DAffine3::from_mat3_translation(turn * start.pose.matrix3, start.pose.translation)
            })
            .collect();
        let mut best = *start;
        for s in self.fitted_all(&tilted, false, frame) {
            if s.score > best.score {
                best = s;
            }
        }
        best
    }

    /// The estimate for `region` of `image` seen by `k`, with what another
    /// estimate proposes ([`Proposal`]); `None` when the region is too
    /// small to place a silhouette.
    pub fn estimate(
        &mut self,
        image: &Image,
        k: &Intrinsics,
        region: &Region,
        proposal: &Proposal,
    ) -> Option<ShapeEstimate> {
        let anchor = if proposal.anchored {
            proposal
                .views
                .first()
                .and_then(|&[t, p, r]| place_view(&self.model, t, p, r, region))
        } else {
            None
        };
        let searched = if anchor.is_some() {
            // The anchor is the estimate: the search only finds its rivals.
            self.settings.candidates.div_ceil(3)
        } else {
            self.settings.candidates
        };
        let mut starts: Vec<DAffine3> = search(
            &self.model,
            region,
            self.settings.roll_step_deg,
            self.settings.max_roll_deg,
            searched,
        )
        .into_iter()
        .map(|c| c.pose)
        .collect();
        if anchor.is_none() {
            starts.extend(
                proposal
                    .views
                    .iter()
                    .filter_map(|&[t, p, r]| place_view(&self.model, t, p, r, region)),
            );
        }
        if starts.is_empty() && anchor.is_none() {
            return None;
        }
        // The gradients about the region: the fits stay near it.
        let margin = 32;
        let h = region.height() as usize;
        self.edges.compute_in(
            image.rgb,
            image.width,
            image.height,
            [
                (region.x0 as usize).saturating_sub(margin),
                (region.y0 as usize).saturating_sub(margin),
                region.x0 as usize + region.width as usize + margin,
                region.y0 as usize + h + margin,
            ],
        );
        let frame = Frame {
            image,
            k,
            region,
            colour: proposal.colour,
        };
        let mut scored = self.fitted_all(&starts, false, &frame);
        self.rank(&mut scored);
        let mut anchored = false;
        if let Some(a) = anchor {
            // The anchor's family: it fitted, its neighbours, and the
            // search's candidates that are the same view; the best of
            // them is the estimate...
            let fitted = self.fitted(&a, &frame);
            let polished = self.polish(&fitted, self.settings.polish_deg, &frame);
            let family = scored
                .iter()
                .position(|c| !self.distinct(&c.pose, &a))
                .filter(|&i| scored[i].score > polished.score);
            let anchor_score = family.map_or(polished.score, |i| scored[i].score);
            // ...unless the proposal allows it and a different view the
            // shape found explains the image better by the overrule
            // margin: colours that match the database fairly well are not
            // always the object's.
            let overruled = proposal.overrulable
                && scored
                    .iter()
                    .find(|c| self.distinct(&c.pose, &a))
                    .is_some_and(|c| c.score >= anchor_score + self.settings.overrule_margin);
            match family {
                Some(i) => {
                    let c = scored.remove(i);
                    scored.insert(if overruled { 1 } else { 0 }, c);
                }
                None => scored.insert(if overruled { 1 } else { 0 }, polished),
            }
            anchored = !overruled;
        }
        // The fit holds the tilt (the grid sets it): the best candidate's
        // neighbours half a grid step away in tilt decide between steps.
        if !anchored && self.settings.polish_deg > 0.0 {
            let mut tilt = self.settings.polish_deg;
            for _ in 0..self.settings.polish_rounds {
                let polished = self.polish(&scored[0], tilt, &frame);
                if polished.score > scored[0].score {
                    scored[0] = polished;
                }
                tilt /= 2.0;
            }
        }
        let best = scored[0].pose;
        // Challengers: the best turned about the object's up axis and
        // tilted; a pose that differs and explains the image about as
        // well makes the best one a guess.
        let turned = CHALLENGER_TURNS_DEG.iter().map(|turn| {
            let r = best.matrix3 * glam::DMat3::from_rotation_z(turn.to_radians());
            DAffine3::from_mat3_translation(r, best.translation)
        });
        let d = CHALLENGER_TILT_DEG.to_radians();
        let tilted = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)].map(|(ax, ay)| {
            let turn = glam::DMat3::from_rotation_x(ax * d) * glam::DMat3::from_rotation_y(ay * d);
            DAffine3::from_mat3_translation(turn * best.matrix3, best.translation)
        });
        let challengers: Vec<DAffine3> = turned.chain(tilted).collect();
        let fitted = self.fitted_all(&challengers, true, &frame);
        scored.extend(fitted);
        scored[1..].sort_by(|a, b| b.score.total_cmp(&a.score));
        let span = self.settings.rival_span;
        let rival = self.rival(&scored, span);
        // Colours that place the object are the estimate: the shape only
        // fitted them.
        let blend = if anchored {
            Blend::alone(best)
        } else {
            self.blend(&scored, span)
        };
        let mut covariance = fit_covariance(
            &self.model,
            image,
            k,
            Some(region),
            &best,
            &self.settings.lines,
            &mut self.lines,
        );
        // The fit's covariance is the best's; the blend adds how far apart
        // what it blended lies.
        for (row, spread) in covariance.iter_mut().zip(blend.spread) {
            for (v, s) in row.iter_mut().zip(spread) {
                *v += s;
            }
        }
        Some(ShapeEstimate {
            scored,
            rival,
            anchored,
            covariance,
            pose: blend.pose,
        })
    }
}

/// What another estimate (the colour histograms') tells the shape.
#[derive(Clone, Copy, Default)]
pub struct Proposal<'a> {
    /// Views it proposes, θ, φ and roll in degrees, best first.
    pub views: &'a [[f64; 3]],
    /// The first view is the estimate (colours that match the database
    /// well place a textured object better than its outline): the shape
    /// fits it in 6-DOF and judges it against its own candidates.
    pub anchored: bool,
    /// The anchor gives way to a different view the shape found that
    /// scores [`ShapeSettings::overrule_margin`] higher.
    pub overrulable: bool,
    /// How well the object's colours match each view, `colour(θ, φ)` in
    /// [0, 1]: what tells apart views whose outlines are alike.
    pub colour: Option<&'a (dyn Fn(f64, f64) -> f32 + Sync)>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{pose_of, rotation_angle_deg};
    use acch_capture::render_posed;
    use glam::DVec2;

    #[test]
    fn a_rival_lies_beyond_the_span_a_distinct_pose_beyond_the_tolerance() {
        let (_, _, model) = crate::testing::tricolor();
        let k = Intrinsics::default();
        let at = |theta_deg: f64, phi_deg: f64| {
            let view = View {
                theta_deg,
                phi_deg,
                roll_deg: 0.0,
                distance: 8.0,
            };
            pose_of(&view, &k, DVec2::new(320.0, 240.0))
        };
        let plain = ShapeEstimator::new(model.clone(), Symmetry::none(), ShapeSettings::default());
        let best = at(40.0, 100.0);
        // 12° of elevation or 25° of azimuth: a failure if it were right,
        // but within 1.5 tolerances, so not a rival; 16° and 31° are.
        for (near, far) in [
            (at(52.0, 100.0), at(56.0, 100.0)),
            (at(40.0, 125.0), at(40.0, 131.0)),
        ] {
            assert!(plain.distinct(&near, &best));
            assert!(!plain.apart(&near, &best, 1.5));
            assert!(plain.apart(&far, &best, 1.5));
        }
        // A half turn is a rival unless the object looks the same by it.
        let turned = at(40.0, 280.0);
        assert!(plain.apart(&turned, &best, 1.5));
        let symmetric = ShapeEstimator::new(
            model,
            Symmetry::parse("z:2").unwrap(),
            ShapeSettings::default(),
        );
        assert!(!symmetric.apart(&turned, &best, 1.5));
        assert!(!symmetric.distinct(&turned, &best));
    }

    /// A candidate at a view of the frame's centre, with no evidence.
    fn candidate(theta_deg: f64, phi_deg: f64, roll_deg: f64, score: f32) -> Scored {
        let view = View {
            theta_deg,
            phi_deg,
            roll_deg,
            distance: 8.0,
        };
        Scored {
            pose: pose_of(&view, &Intrinsics::default(), DVec2::new(320.0, 240.0)),
            view: 0,
            evidence: Evidence::default(),
            score,
        }
    }

    #[test]
    fn a_pose_below_the_lowest_elevation_is_neither_the_best_nor_its_rival() {
        let (_, _, model) = crate::testing::tricolor();
        let scored = |theta_deg, phi_deg, score| candidate(theta_deg, phi_deg, 0.0, score);
        let candidates = [
            scored(-20.0, 100.0, 6.0),
            scored(40.0, 100.0, 5.0),
            scored(-30.0, 280.0, 4.9),
            scored(40.0, 280.0, 4.0),
        ];
        let ranked = |estimator: &ShapeEstimator| {
            let mut c = candidates.to_vec();
            estimator.rank(&mut c);
            // As `estimate` leaves them: the best, then the rest by score.
            c[1..].sort_by(|a, b| b.score.total_cmp(&a.score));
            let rival = estimator.rival(&c, 1.5).map(|i| view_of(&c[i].pose));
            (view_of(&c[0].pose), rival)
        };
        let floored = ShapeEstimator::new(
            model.clone(),
            Symmetry::none(),
            ShapeSettings {
                lowest_elevation_deg: 0.0,
                ..ShapeSettings::default()
            },
        );
        let (best, rival) = ranked(&floored);
        assert!((best.theta_deg - 40.0).abs() < 1e-6, "{best:?}");
        let rival = rival.expect("the half turn the camera sees");
        assert!((rival.theta_deg - 40.0).abs() < 1e-6, "{rival:?}");
        assert!((rival.phi_deg - 280.0).abs() < 1e-6, "{rival:?}");
        // Without a floor the score alone ranks: the pose from below is
        // the best, and the next by score (from above) its rival.
        let any = ShapeEstimator::new(model, Symmetry::none(), ShapeSettings::default());
        let (best, rival) = ranked(&any);
        assert!((best.theta_deg + 20.0).abs() < 1e-6, "{best:?}");
        let rival = rival.expect("a rival");
        assert!((rival.theta_deg - 40.0).abs() < 1e-6, "{rival:?}");
        // A neighbour below the floor that scores above the best is not
        // blended into it; without a floor it pulls the blend down.
        let near = [
            candidate(5.0, 100.0, 0.0, 5.0),
            candidate(-3.0, 100.0, 0.0, 5.3),
        ];
        let blended = |estimator: &ShapeEstimator| view_of(&estimator.blend(&near, 1.5).pose);
        assert!((blended(&floored).theta_deg - 5.0).abs() < 1e-6);
        assert!(blended(&any).theta_deg < 0.0, "{:?}", blended(&any));
    }

    #[test]
    fn the_estimate_blends_the_best_with_near_poses_that_score_alike_each_once() {
        let (_, _, model) = crate::testing::tricolor();
        let scored = |theta_deg, roll_deg, score| candidate(theta_deg, 100.0, roll_deg, score);
        let estimator =
            ShapeEstimator::new(model.clone(), Symmetry::none(), ShapeSettings::default());
        let blended = |candidates: &[Scored]| view_of(&estimator.blend(candidates, 1.5).pose);
        // Alike in score 10° apart: halfway, once however often the
        // neighbour was found.
        let pair = [scored(40.0, 0.0, 5.0), scored(50.0, 0.0, 5.0)];
        let twice = [pair[0], pair[1], pair[1]];
        for candidates in [&pair[..], &twice[..]] {
            let v = blended(candidates);
            assert!((v.theta_deg - 45.0).abs() < 0.5, "{v:?}");
            assert!((v.phi_deg - 100.0).abs() < 0.5, "{v:?}");
            // Each 5° from the blend: a rotation variance of (5°)², all
            // about the camera's x axis (an elevation seen at the image's
            // centre tilts the camera up and down: R' = exp(w) R, w in
            // camera axes), the translations alike.
            let spread = estimator.blend(candidates, 1.5).spread;
            assert!(
                (spread[0][0] - 5f64.to_radians().powi(2)).abs() < 2e-4,
                "{spread:?}"
            );
            assert!(spread[1][1] < 1e-6 && spread[2][2] < 1e-6, "{spread:?}");
            assert!((3..6).all(|i| spread[i][i] < 1e-9), "{spread:?}");
        }
        // Lower by 0.2 (twice the scale): weighed e^-2 = 0.135.
        let v = blended(&[scored(40.0, 0.0, 5.0), scored(50.0, 0.0, 4.8)]);
        assert!((v.theta_deg - 41.2).abs() < 0.3, "{v:?}");
        // Beyond the span (20° of elevation), upside down, or blending
        // switched off: the best alone.
        let best = scored(40.0, 0.0, 5.0);
        for (candidates, scale) in [
            ([best, scored(60.0, 0.0, 5.0)], 0.1),
            ([best, scored(40.0, 180.0, 5.0)], 0.1),
            ([best, scored(50.0, 0.0, 5.0)], 0.0),
        ] {
            let estimator = ShapeEstimator::new(
                model.clone(),
                Symmetry::none(),
                ShapeSettings {
                    blend_score_scale: scale,
                    ..ShapeSettings::default()
                },
            );
            let alone = estimator.blend(&candidates, 1.5);
            let v = view_of(&alone.pose);
            assert_eq!(alone.spread, [[0.0; 6]; 6]);
            assert!((v.theta_deg - 40.0).abs() < 1e-6, "{v:?}");
            assert!((v.roll_deg - 0.0).abs() < 1e-6, "{v:?}");
        }
    }

    #[test]
    fn a_helper_thread_changes_no_bit_of_the_estimate() {
        let (object, _, model) = crate::testing::tricolor();
        let k = Intrinsics::default();
        let alone =
            &mut ShapeEstimator::new(model.clone(), Symmetry::default(), ShapeSettings::default());
        let shared = &mut ShapeEstimator::new(model, Symmetry::default(), ShapeSettings::default());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        shared.share_fits_with(Arc::new(pool));
        let mut spread_seen = false;
        let span = ShapeSettings::default().rival_span;
        for (theta, phi, roll) in [(50.0, 60.0, 0.0), (20.0, 210.0, 30.0), (80.0, 300.0, -60.0)] {
            let view = View {
                theta_deg: theta,
                phi_deg: phi,
                roll_deg: roll,
                distance: 8.0,
            };
            let truth = pose_of(&view, &k, DVec2::new(300.0, 250.0));
            let render = render_posed(&[(&object, truth, 1.0)], &k);
            let image = Image {
                rgb: &render.rgb,
                width: k.width as usize,
                height: k.height as usize,
            };
            let region = Region::whole(&render.labels, &k);
            let proposal = Proposal::default();
            let a = alone.estimate(&image, &k, &region, &proposal).unwrap();
            let b = shared.estimate(&image, &k, &region, &proposal).unwrap();
            // Not a vacuous comparison: the estimate is the object's pose,
            // after a search, a polish and the challengers.
            assert!(
                rotation_angle_deg(&a.best().pose.matrix3, &truth.matrix3) < 10.0,
                "{:?}",
                a.view()
            );
            assert!(a.scored.len() > 11, "{}", a.scored.len());
            assert_eq!(a, b, "at θ {theta} φ {phi} roll {roll}");
            // The estimate names its rival beyond the span and blends the
            // best with what lies within it.
            let best = a.best().pose;
            if let Some(r) = a.rival {
                assert!(alone.apart(&a.scored[r].pose, &best, span));
                assert!((1..r).all(|i| !alone.apart(&a.scored[i].pose, &best, span)));
            }
            let blended = if a.anchored {
                Blend::alone(best)
            } else {
                alone.blend(&a.scored, span)
            };
            assert_eq!(a.pose, blended.pose);
            // Its covariance is the best's fit's and the blend's spread:
            // weighed broadly (scale 1), the neighbours spread the
            // estimate measurably.
            let mut wide = ShapeEstimator::new(
                alone.model.clone(),
                Symmetry::default(),
                ShapeSettings {
                    blend_score_scale: 1.0,
                    ..ShapeSettings::default()
                },
            );
            let w = wide.estimate(&image, &k, &region, &proposal).unwrap();
            let spread = wide.blend(&w.scored, span).spread;
            let fit = fit_covariance(
                &wide.model,
                &image,
                &k,
                Some(&region),
                &w.best().pose,
                &wide.settings.lines,
                &mut LineScratch::default(),
            );
            let turn = |m: &[[f64; 6]; 6]| (0..3).map(|i| m[i][i]).sum::<f64>();
            spread_seen |= turn(&spread) > 0.1 * turn(&fit);
            for r in 0..6 {
                for c in 0..6 {
                    let want = fit[r][c] + spread[r][c];
                    assert!(
                        (w.covariance[r][c] - want).abs() <= 1e-9 * want.abs().max(1e-12),
                        "{r},{c}: {} against {want}",
                        w.covariance[r][c]
                    );
                }
            }
        }
        assert!(spread_seen, "no estimate blended neighbours apart");
    }
}
