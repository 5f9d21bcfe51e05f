//! 6-DOF pose seeds from a 2-DOF view estimate.
//!
//! The ACCH pose stage estimates the view direction: the camera sits on the
//! view sphere around the object at elevation θ and azimuth φ, at
//! `c = r (cos θ cos φ, cos θ sin φ, sin θ)` in the object frame (z up,
//! centre at the origin), looking at the centre with image up = `e_θ` (the
//! renderer's convention, see `acch_capture::ViewPose`). With the region of
//! interest's centre, the intrinsics and the distance, this gives the
//! object's full pose in the camera frame:
//!
//! - the object centre lies on the viewing ray through the ROI centre, at
//!   the given distance;
//! - the rotation is the one of a camera looking straight at the object from
//!   (θ, φ), turned by the smallest rotation that takes the optical axis onto
//!   that ray (an off-centre object is seen by a camera that is rotated, not
//!   moved).
//!
//! The covariance reflects the view-grid spacing (quantisation of a winner
//! takes all estimate), the confidence of the estimate (a rating below one
//! widens it towards the failure scale of the method) and the distance and
//! ROI-centre uncertainty.
//!
//! Frames: the camera frame is OpenCV's (x right, y down, z forward); the
//! pose maps object coordinates to camera coordinates. Translation units are
//! those of the distance (metres in the pipeline). The covariance is over
//! the tangent vector `(tx, ty, tz, rx, ry, rz)` of a left perturbation in
//! the camera frame: `T' = (exp(δt), exp(δr)) ∘ T`, i.e. `t' = t + δt`,
//! `R' = exp([δr]×) R`, translation first, rotation in radians.
//!
//! This crate is pure: no I/O, no IPC.

pub mod fusion;

pub use fusion::{
    FilterConfig, FusedView, FusionError, Measurement, Outcome, UNKNOWN_THETA_SIGMA_DEG,
    ViewFilter, theta_censored,
};

use glam::{DAffine3, DMat3, DQuat, DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// Errors of [`seed`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SeedError {
    /// An input is not finite or out of range.
    #[error("invalid seeding input: {0}")]
    InvalidInput(String),
}

/// Pinhole intrinsics in pixels (no distortion); pixel centres at integer
/// coordinates, as in `acch_capture::Intrinsics`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pinhole {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

impl Pinhole {
    /// Unit viewing direction through a pixel, in the camera frame.
    pub fn direction(&self, pixel: DVec2) -> DVec3 {
        DVec3::new(
            (pixel.x - self.cx) / self.fx,
            (pixel.y - self.cy) / self.fy,
            1.0,
        )
        .normalize()
    }
}

/// How far the object centre is from the camera centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Distance {
    /// Known (e.g. from the arm's kinematics), with its standard deviation.
    Known {
        /// Distance, in the unit of the seed's translation.
        value: f64,
        /// Standard deviation, same unit.
        sigma: f64,
    },
    /// From the ROI's apparent scale against training: the object appears
    /// `scale` times as large as in the training views taken at
    /// `train_distance`, so it is `train_distance / scale` away.
    FromScale {
        /// Distance of the training views.
        train_distance: f64,
        /// Apparent size relative to training (> 0).
        scale: f64,
        /// Relative standard deviation of the scale estimate (e.g. 0.1).
        relative_sigma: f64,
    },
}

impl Distance {
    /// The distance and its standard deviation.
    pub fn value_sigma(&self) -> (f64, f64) {
        match *self {
            Distance::Known { value, sigma } => (value, sigma),
            Distance::FromScale {
                train_distance,
                scale,
                relative_sigma,
            } => {
                let d = train_distance / scale;
                (d, d * relative_sigma)
            }
        }
    }
}

/// Spacing of the training views, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridSpacing {
    /// Between θ slices.
    pub theta_deg: f64,
    /// Between neighbouring views of a slice.
    pub phi_deg: f64,
}

/// Tuning of the covariance model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CovarianceModel {
    /// Standard deviation of the ROI centre against the true projection of
    /// the object centre, pixels.
    pub roi_centre_sigma_px: f64,
    /// Standard deviation of a failed estimate, degrees (the method's
    /// failure scale: |Δθ| > 10° or |Δφ| > 20° counts as failure).
    pub failure_sigma_deg: f64,
    /// Standard deviation of the roll about the viewing ray, degrees (the
    /// 2-DOF model assumes no roll).
    pub roll_sigma_deg: f64,
}

impl Default for CovarianceModel {
    /// 4 px ROI-centre error, 30° failure scale, 5° roll.
    fn default() -> Self {
        CovarianceModel {
            roi_centre_sigma_px: 4.0,
            failure_sigma_deg: 30.0,
            roll_sigma_deg: 5.0,
        }
    }
}

/// Everything a seed is made from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeedInput {
    /// Estimated elevation, degrees in [0, 90].
    pub theta_deg: f64,
    /// Estimated azimuth, degrees (any finite value).
    pub phi_deg: f64,
    /// Estimated roll of the camera about its optical axis, degrees (the
    /// image turned counter-clockwise by it against image up = `e_θ`); 0
    /// when not estimated.
    pub roll_deg: f64,
    /// Where the object centre projects, pixels: the region of interest's
    /// centre, corrected by the matched view's centre offset.
    pub roi_centre_px: DVec2,
    /// The camera.
    pub intrinsics: Pinhole,
    /// Distance to the object centre.
    pub distance: Distance,
    /// Confidence of the estimate in [0, 1] (1 when unrated).
    pub confidence: f64,
    /// Training-view spacing.
    pub grid: GridSpacing,
}

/// An SE(3) seed with its covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seed {
    /// Maps object coordinates to camera coordinates.
    pub camera_from_object: DAffine3,
    /// Row-major 6x6 covariance over `(tx, ty, tz, rx, ry, rz)` (see the
    /// crate docs).
    pub covariance: [[f64; 6]; 6],
}

impl Seed {
    /// The translation: the object centre in the camera frame.
    pub fn translation(&self) -> DVec3 {
        self.camera_from_object.translation
    }

    /// The rotation as a unit quaternion (glam stores x, y, z, w).
    pub fn rotation(&self) -> DQuat {
        DQuat::from_mat3(&self.camera_from_object.matrix3).normalize()
    }
}

/// The object-to-camera rotation of a camera on the view sphere at (θ, φ)
/// looking at the object centre, image up = `e_θ` (rows: right, down,
/// forward in object coordinates).
pub fn view_rotation(theta_deg: f64, phi_deg: f64) -> DMat3 {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    let forward = -DVec3::new(ct * cp, ct * sp, st);
    let down = DVec3::new(st * cp, st * sp, -ct);
    let right = down.cross(forward);
    DMat3::from_cols(right, down, forward).transpose()
}

/// The seed of one estimate.
pub fn seed(input: &SeedInput, model: &CovarianceModel) -> Result<Seed, SeedError> {
    let bad = |s: String| Err(SeedError::InvalidInput(s));
    if !(0.0..=90.0).contains(&input.theta_deg) || !input.phi_deg.is_finite() {
        return bad(format!(
            "view (θ {}, φ {}) out of range",
            input.theta_deg, input.phi_deg
        ));
    }
    if !input.roll_deg.is_finite() {
        return bad(format!("roll {} is not finite", input.roll_deg));
    }
    if !input.roi_centre_px.is_finite() {
        return bad(format!("ROI centre {} is not finite", input.roi_centre_px));
    }
    let k = input.intrinsics;
    if !(k.fx > 0.0
        && k.fy > 0.0
        && k.fx.is_finite()
        && k.fy.is_finite()
        && k.cx.is_finite()
        && k.cy.is_finite())
    {
        return bad(format!("intrinsics {k:?} are not a pinhole camera"));
    }
    let (d, d_sigma) = input.distance.value_sigma();
    if !(d.is_finite() && d > 0.0 && d_sigma.is_finite() && d_sigma >= 0.0) {
        return bad(format!("distance {d} ± {d_sigma} must be finite and > 0"));
    }
    if !(0.0..=1.0).contains(&input.confidence) {
        return bad(format!("confidence {} outside [0, 1]", input.confidence));
    }
    let g = input.grid;
    if !(g.theta_deg.is_finite() && g.theta_deg >= 0.0 && g.phi_deg.is_finite() && g.phi_deg >= 0.0)
    {
        return bad(format!("grid spacing {g:?} must be finite and >= 0"));
    }

    // Rotation: look-at camera, rolled about its axis (the camera's axes
    // turn by +roll, so object coordinates turn by -roll), then turned onto
    // the ray through the ROI centre.
    let ray = k.direction(input.roi_centre_px);
    let turn = DQuat::from_rotation_arc(DVec3::Z, ray);
    let look_at = view_rotation(input.theta_deg, input.phi_deg);
    let unroll = DMat3::from_rotation_z(-input.roll_deg.to_radians());
    let rotation = DMat3::from_quat(turn) * unroll * look_at;
    let camera_from_object = DAffine3::from_mat3_translation(rotation, d * ray);

    // Rotation covariance in the look-at camera's frame: a θ error turns the
    // object about the camera x axis; a φ error about the object's z axis,
    // which the look-at camera sees along (0, -cos θ, -sin θ); roll about z.
    // Grid quantisation is uniform over one spacing (variance s²/12); a
    // rating below one blends in the failure scale.
    let c = input.confidence;
    let var = |spacing_deg: f64| {
        let q = spacing_deg.to_radians().powi(2) / 12.0;
        let f = model.failure_sigma_deg.to_radians().powi(2);
        q + (1.0 - c) * f
    };
    let (st, ct) = input.theta_deg.to_radians().sin_cos();
    let x_axis = DVec3::X;
    let z_obj = DVec3::new(0.0, -ct, -st);
    let roll = DVec3::Z;
    let mut rot_cov = outer(x_axis, x_axis) * var(g.theta_deg)
        + outer(z_obj, z_obj) * var(g.phi_deg)
        + outer(roll, roll) * (model.roll_sigma_deg.to_radians().powi(2) + (1.0 - c) * var(0.0));
    let turn_m = DMat3::from_quat(turn) * unroll;
    rot_cov = turn_m * rot_cov * turn_m.transpose();

    // Translation covariance: along the ray from the distance; across it
    // from the ROI-centre error at that distance.
    let lateral = d * model.roi_centre_sigma_px / k.fx.min(k.fy);
    let (u1, u2) = ray.any_orthonormal_pair();
    let trans_cov =
        outer(ray, ray) * d_sigma.powi(2) + (outer(u1, u1) + outer(u2, u2)) * lateral.powi(2);

    let mut covariance = [[0.0; 6]; 6];
    for i in 0..3 {
        for j in 0..3 {
            covariance[i][j] = trans_cov.col(j)[i];
            covariance[3 + i][3 + j] = rot_cov.col(j)[i];
        }
    }
    Ok(Seed {
        camera_from_object,
        covariance,
    })
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The view-grid spacing of a set of training views (θ, φ in degrees): the
/// median gap between distinct elevations and the median azimuth gap
/// within a slice (0 where there is only one).
pub fn grid_spacing(views: impl IntoIterator<Item = (f64, f64)>) -> GridSpacing {
    let mut thetas: Vec<f64> = Vec::new();
    let mut by_theta: Vec<(f64, Vec<f64>)> = Vec::new();
    for (t, p) in views {
        match by_theta.iter_mut().find(|(tt, _)| (*tt - t).abs() < 1e-9) {
            Some((_, ps)) => ps.push(p),
            None => {
                thetas.push(t);
                by_theta.push((t, vec![p]));
            }
        }
    }
    thetas.sort_by(f64::total_cmp);
    let theta_gaps: Vec<f64> = thetas.windows(2).map(|w| w[1] - w[0]).collect();
    let mut phi_gaps = Vec::new();
    for (_, mut ps) in by_theta {
        ps.sort_by(f64::total_cmp);
        if ps.len() > 1 {
            phi_gaps.extend(ps.windows(2).map(|w| w[1] - w[0]));
            phi_gaps.push(360.0 + ps[0] - ps[ps.len() - 1]);
        }
    }
    GridSpacing {
        theta_deg: median(theta_gaps),
        phi_deg: median(phi_gaps),
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Angle between two rotations, degrees.
pub fn rotation_angle_deg(a: DQuat, b: DQuat) -> f64 {
    let dot = a.normalize().dot(b.normalize()).abs().min(1.0);
    (2.0 * dot.acos()).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use acch_capture::{Intrinsics, ViewPose};

    fn pinhole(k: &Intrinsics) -> Pinhole {
        Pinhole {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        }
    }

    fn input(view: &ViewPose, centre: DVec2) -> SeedInput {
        SeedInput {
            theta_deg: view.theta_deg,
            phi_deg: view.phi_deg,
            roll_deg: view.roll_deg,
            roi_centre_px: centre,
            intrinsics: pinhole(&Intrinsics::default()),
            distance: Distance::Known {
                value: view.distance,
                sigma: 0.0,
            },
            confidence: 1.0,
            grid: GridSpacing {
                theta_deg: 10.0,
                phi_deg: 10.0,
            },
        }
    }

    fn max_diff(a: DAffine3, b: DAffine3) -> f64 {
        let a = a.to_cols_array();
        let b = b.to_cols_array();
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn exact_input_reproduces_the_renderer_camera_pose() {
        let k = Intrinsics::default();
        for theta in [0.0, 10.0, 45.0, 67.5, 89.0, 90.0] {
            for phi in [0.0, 33.0, 90.0, 180.0, 271.0, 359.9] {
                for (dist, roll) in [
                    (2.0, 0.0),
                    (5.0, 0.0),
                    (9.0, 0.0),
                    (5.0, 30.0),
                    (5.0, -75.0),
                ] {
                    // A rolled camera too: the seed's rotation carries the
                    // roll the way the renderer's camera does.
                    let view = ViewPose::new(theta, phi, dist)
                        .unwrap()
                        .with_roll(roll)
                        .unwrap();
                    let truth = view.camera_from_world();
                    let centre = k.project(truth.transform_point3(DVec3::ZERO)).unwrap();
                    let s = seed(&input(&view, centre), &CovarianceModel::default()).unwrap();
                    let diff = max_diff(s.camera_from_object, truth);
                    assert!(
                        diff < 1e-6,
                        "θ {theta} φ {phi} d {dist} roll {roll}: diff {diff}"
                    );
                }
            }
        }
    }

    #[test]
    fn off_centre_object_lies_on_the_ray_at_the_distance() {
        let view = ViewPose::new(60.0, 120.0, 5.0).unwrap();
        let k = Intrinsics::default();
        let centre = DVec2::new(450.0, 100.0);
        let s = seed(&input(&view, centre), &CovarianceModel::default()).unwrap();
        let t = s.translation();
        assert!((t.length() - 5.0).abs() < 1e-9);
        let back = k.project(t).unwrap();
        assert!((back - centre).length() < 1e-9);
        // The object's view direction (object centre -> camera centre, in
        // object coordinates) is still (θ, φ).
        let object_from_camera = s.camera_from_object.inverse();
        let cam_in_object = object_from_camera.transform_point3(DVec3::ZERO).normalize();
        assert!((cam_in_object - view.camera_position().normalize()).length() < 1e-9);
    }

    #[test]
    fn covariance_is_symmetric_and_grows_as_confidence_drops() {
        let view = ViewPose::new(50.0, 20.0, 5.0).unwrap();
        let mut inp = input(&view, DVec2::new(300.0, 200.0));
        let sure = seed(&inp, &CovarianceModel::default()).unwrap();
        inp.confidence = 0.5;
        let unsure = seed(&inp, &CovarianceModel::default()).unwrap();
        for i in 0..6 {
            for j in 0..6 {
                assert!((sure.covariance[i][j] - sure.covariance[j][i]).abs() < 1e-12);
            }
            assert!(sure.covariance[i][i] >= 0.0);
        }
        let trace = |s: &Seed| (3..6).map(|i| s.covariance[i][i]).sum::<f64>();
        assert!(trace(&unsure) > trace(&sure));
        // Quantisation alone: σ = 10° / sqrt(12) about the camera x axis.
        let sx = sure.covariance[3][3].sqrt().to_degrees();
        assert!((sx - 10.0 / 12f64.sqrt()).abs() < 0.5, "{sx}");
    }

    #[test]
    fn distance_from_scale() {
        let d = Distance::FromScale {
            train_distance: 5.0,
            scale: 2.0,
            relative_sigma: 0.1,
        };
        assert_eq!(d.value_sigma(), (2.5, 0.25));
    }

    #[test]
    fn grid_spacing_of_a_regular_grid() {
        let views =
            (0..3).flat_map(|i| (0..36).map(move |j| (45.0 + 10.0 * i as f64, 10.0 * j as f64)));
        let g = grid_spacing(views);
        assert_eq!(g.theta_deg, 10.0);
        assert!((g.phi_deg - 10.0).abs() < 1e-9);
    }

    #[test]
    fn bad_input_is_an_error() {
        let view = ViewPose::new(50.0, 20.0, 5.0).unwrap();
        let mut inp = input(&view, DVec2::new(f64::NAN, 0.0));
        assert!(seed(&inp, &CovarianceModel::default()).is_err());
        inp.roi_centre_px = DVec2::ZERO;
        inp.theta_deg = 95.0;
        assert!(seed(&inp, &CovarianceModel::default()).is_err());
    }
}
