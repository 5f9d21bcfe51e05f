//! Temporal fusion of view estimates with the arm's known camera motion.
//!
//! # State
//!
//! The filter tracks the camera's orientation relative to the object,
//! `R = camera_from_object` rotation, with a 3x3 covariance on its tangent
//! space: a left perturbation in the camera frame, `R = exp([δ]×) R̂`, δ in
//! radians: the same convention as the rotation block of [`crate::Seed`].
//! This is the manifold formulation of "the view direction as a unit vector"
//! with one more degree of freedom, and it is the one the method needs: the
//! view direction `u = -Rᵀ t̂` has no azimuth at θ = 90°, where the renderer's
//! convention (image up = `e_θ`) turns φ into the camera's roll about the
//! optical axis. A rotation has neither a wrap-around at φ = 0/360 nor a
//! pole, so the filter needs no special case for either; (θ, φ) are only read
//! out of it (see [`FusedView`]).
//!
//! The translation (object centre in the camera frame) is carried, not
//! filtered: the arm's motion moves it, and each fused measurement replaces
//! it (it comes from the ROI ray and the known distance, which are precise;
//! it is needed to read θ and φ out of the rotation when the object is off
//! the optical axis).
//!
//! # Prediction: what the arm must report
//!
//! Per frame, [`ViewFilter::predict`] takes the camera's rigid motion since
//! the previous frame as `previous_camera_from_current_camera`: the current
//! camera pose expressed in the previous camera's optical frame (OpenCV: x
//! right, y down, z forward), the same as
//! `acch_capture::TrajectoryFrame::camera_motion`. A robot gets it from
//! forward kinematics and the hand-eye calibration:
//! `(base_from_camera_prev)⁻¹ · base_from_camera_cur`. It needs no knowledge
//! of the object: the object is assumed static, so
//! `camera_from_object_cur = motion⁻¹ · camera_from_object_prev` exactly, and
//! the rotation covariance is carried as `Σ' = R_Mᵀ Σ R_M + Q`. `Q` models
//! kinematic and hand-eye errors: a floor per frame plus a fraction of the
//! rotation angle moved (see [`FilterConfig`]). In the simulation the object
//! frame is the world frame.
//!
//! # Update, gating, recovery
//!
//! A measurement is an accepted single-frame estimate turned into a rotation
//! with its covariance by [`crate::seed`]: the covariance of a correct
//! estimate (grid quantisation and roll), see [`Measurement::from_estimate`];
//! the confidence network has already decided that the estimate is used. The residual `r = log(R_m R̂ᵀ)` is
//! gated on its squared Mahalanobis distance `rᵀ (Σ + Σ_m)⁻¹ r` (χ², 3
//! degrees of freedom): a wrong single-frame estimate (a 180° φ flip of a
//! symmetric object, a wrong segmentation) is rejected instead of dragging
//! the fused pose. Gated measurements feed a challenger hypothesis, moved
//! by the same camera motions; when `reinit_after` gated measurements in a
//! row agree with the challenger, it replaces the fused state, so a filter
//! started from a wrong first estimate recovers.
//!
//! An estimate on the database's lowest θ slice is censored: every view at
//! or below that slice lands there, so its θ says nothing
//! ([`theta_censored`]); [`Measurement::without_theta`] keeps its φ and
//! roll only.
//!
//! Pure and allocation-free: every type is `Copy`, nothing is stored on the
//! heap.

use crate::{CovarianceModel, Seed, SeedError, SeedInput};
use glam::{DAffine3, DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// Errors of the filter: inputs that are not finite or not valid poses.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FusionError {
    /// The camera motion is not a finite rigid motion.
    #[error("invalid camera motion: {0}")]
    InvalidMotion(String),
    /// The measurement is not a finite rigid pose with a symmetric
    /// positive-definite rotation covariance.
    #[error("invalid measurement: {0}")]
    InvalidMeasurement(String),
    /// The configuration is out of range.
    #[error("invalid filter configuration: {0}")]
    InvalidConfig(String),
}

/// Tuning of [`ViewFilter`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilterConfig {
    /// Process noise per prediction, degrees (standard deviation about each
    /// axis): kinematic and hand-eye errors that do not scale with motion.
    pub process_sigma_deg: f64,
    /// Process noise proportional to the rotation angle moved (0.02 = 2 %).
    pub process_per_rad: f64,
    /// Gate on the squared Mahalanobis distance of a measurement (χ² with 3
    /// degrees of freedom; 11.34 keeps 99 % of consistent measurements).
    pub gate_chi2: f64,
    /// Gated measurements in a row, agreeing with each other, after which
    /// the filter restarts from them.
    pub reinit_after: u32,
}

impl Default for FilterConfig {
    /// 0.3° per frame plus 2 % of the motion, 99 % gate, restart after 3.
    fn default() -> Self {
        FilterConfig {
            process_sigma_deg: 0.3,
            process_per_rad: 0.02,
            gate_chi2: 11.34,
            reinit_after: 3,
        }
    }
}

impl FilterConfig {
    /// Checks every field.
    pub fn validate(&self) -> Result<(), FusionError> {
        let ok = |x: f64| x.is_finite() && x >= 0.0;
        if !(ok(self.process_sigma_deg) && ok(self.process_per_rad)) {
            return Err(FusionError::InvalidConfig(format!(
                "process noise {}° + {} per rad must be finite and >= 0",
                self.process_sigma_deg, self.process_per_rad
            )));
        }
        if !(self.gate_chi2.is_finite() && self.gate_chi2 > 0.0) {
            return Err(FusionError::InvalidConfig(format!(
                "gate {} must be finite and > 0",
                self.gate_chi2
            )));
        }
        if self.reinit_after == 0 {
            return Err(FusionError::InvalidConfig(
                "reinit_after must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

/// One accepted single-frame estimate as the filter sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// The estimated object pose in the camera frame.
    pub camera_from_object: DAffine3,
    /// Covariance of the rotation (left perturbation in the camera frame,
    /// radians²).
    pub rotation_covariance: DMat3,
}

impl Measurement {
    /// The measurement of an accepted estimate: the seed of `input` with
    /// the covariance of a correct estimate (grid quantisation and roll, the
    /// confidence set to 1). The filter handles wrong estimates as outliers
    /// by gating; the seed's confidence-widened covariance (towards the
    /// 30° failure scale) would widen the gate and let them in.
    ///
    /// One term is added to the seed's: the seed models a φ error as a turn
    /// about the object's z axis, which moves the view direction by only
    /// `cos θ δφ` and at θ = 90° not at all, leaving the covariance singular
    /// near the pole. A real estimate there is off in any direction, so the
    /// view direction's variance across `e_θ` (a turn about the camera's y
    /// axis) is raised to at least its variance along `e_θ`.
    pub fn from_estimate(input: &SeedInput, model: &CovarianceModel) -> Result<Self, SeedError> {
        let s = crate::seed(
            &SeedInput {
                confidence: 1.0,
                ..*input
            },
            model,
        )?;
        let mut m = Measurement::from_seed(&s);
        let var = |spacing_deg: f64| spacing_deg.to_radians().powi(2) / 12.0;
        let (var_theta, var_phi) = (var(input.grid.theta_deg), var(input.grid.phi_deg));
        let ct = input.theta_deg.to_radians().cos();
        let floor = (var_theta - ct * ct * var_phi).max(0.0) + MIN_VARIANCE;
        let ray = input.intrinsics.direction(input.roi_centre_px);
        let y = DQuat::from_rotation_arc(DVec3::Z, ray) * DVec3::Y;
        m.rotation_covariance +=
            outer(y, y) * floor + DMat3::from_diagonal(DVec3::splat(MIN_VARIANCE));
        Ok(m)
    }

    /// The same measurement with its θ information dropped: the variance
    /// of a turn along `e_θ` (about the camera's x axis, through the ROI
    /// centre of `input`) is raised to [`UNKNOWN_THETA_SIGMA_DEG`]², so an
    /// update moves the fused φ (and roll) but not the fused θ.
    ///
    /// For an estimate whose θ is censored: a database covers θ from its
    /// lowest slice up (45° for the paper grid), and below it the refined
    /// estimate sticks to that slice whatever the true θ (see
    /// [`theta_censored`]). Its φ is still informative, its θ is not. A
    /// filter started from such a measurement holds the slice's θ with this
    /// variance until an uncensored measurement replaces it.
    pub fn without_theta(self, input: &SeedInput) -> Measurement {
        let ray = input.intrinsics.direction(input.roi_centre_px);
        let x = DQuat::from_rotation_arc(DVec3::Z, ray) * DVec3::X;
        let var = UNKNOWN_THETA_SIGMA_DEG.to_radians().powi(2);
        let along = x.dot(self.rotation_covariance * x);
        Measurement {
            rotation_covariance: self.rotation_covariance + outer(x, x) * (var - along).max(0.0),
            ..self
        }
    }

    /// The measurement of a seed: its pose and the rotation block of its
    /// covariance, as is (see [`Measurement::from_estimate`] for the
    /// covariance the filter expects).
    pub fn from_seed(seed: &Seed) -> Measurement {
        let c = &seed.covariance;
        Measurement {
            camera_from_object: seed.camera_from_object,
            rotation_covariance: DMat3::from_cols(
                DVec3::new(c[3][3], c[4][3], c[5][3]),
                DVec3::new(c[3][4], c[4][4], c[5][4]),
                DVec3::new(c[3][5], c[4][5], c[5][5]),
            ),
        }
    }
}

/// Standard deviation of θ in a measurement without θ information
/// ([`Measurement::without_theta`]), degrees: the whole elevation range.
pub const UNKNOWN_THETA_SIGMA_DEG: f64 = 90.0;

/// Whether an estimated θ is censored by the database: it lies on the
/// lowest θ slice (`lowest_theta_deg`, within 0.01°), where the refinement
/// saturates for every view at or below that slice, so the true θ may be
/// anywhere below. Views above the highest slice do not exist (θ <= 90°).
pub fn theta_censored(theta_deg: f64, lowest_theta_deg: f64) -> bool {
    theta_deg <= lowest_theta_deg + 0.01
}

/// Variance added to every axis of a measurement so that a grid without
/// spacing (one view) still gives a positive-definite covariance: (0.05°)².
const MIN_VARIANCE: f64 = 7.615e-7;

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// What [`ViewFilter::update`] did with a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// The first measurement: the filter starts from it.
    Initialised,
    /// Fused; squared Mahalanobis distance of the residual.
    Fused {
        /// `rᵀ S⁻¹ r`.
        mahalanobis2: f64,
    },
    /// Rejected by the gate; the fused state is unchanged.
    Gated {
        /// `rᵀ S⁻¹ r`.
        mahalanobis2: f64,
        /// Gated measurements in a row so far.
        in_a_row: u32,
    },
    /// Gated, but the last `reinit_after` gated measurements agreed: the
    /// filter restarted from them.
    Reinitialised {
        /// `rᵀ S⁻¹ r` against the abandoned state.
        mahalanobis2: f64,
    },
}

/// The fused pose, read out of the filter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FusedView {
    /// Elevation, degrees in [0, 90].
    pub theta_deg: f64,
    /// Azimuth, degrees in [0, 360).
    pub phi_deg: f64,
    /// Row-major 2x2 covariance of (θ, φ), degrees². θ is measured along
    /// `e_θ` (signed through the pole), φ as the azimuth of the camera's
    /// look-at frame, which stays defined at θ = 90°.
    pub view_covariance_deg2: [[f64; 2]; 2],
    /// The fused object pose in the camera frame, column-major 3x4 (glam's
    /// `DAffine3::to_cols_array`).
    pub camera_from_object: [f64; 12],
    /// Row-major 3x3 rotation covariance, radians² (left perturbation in the
    /// camera frame, as the seed's rotation block).
    pub rotation_covariance: [[f64; 3]; 3],
    /// Measurements fused since the (last) start.
    pub fused: u32,
    /// Predictions since the last fused measurement.
    pub since_update: u32,
}

/// A pose hypothesis: estimate and tangent covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Hypothesis {
    pose: DAffine3,
    cov: DMat3,
    fused: u32,
    since_update: u32,
}

impl Hypothesis {
    fn new(m: &Measurement) -> Hypothesis {
        Hypothesis {
            pose: m.camera_from_object,
            cov: m.rotation_covariance,
            fused: 1,
            since_update: 0,
        }
    }

    fn predict(&mut self, motion: &DAffine3, q: DMat3) {
        let rm = motion.matrix3;
        self.pose = motion.inverse() * self.pose;
        self.cov = symmetric(rm.transpose() * self.cov * rm + q);
        self.since_update += 1;
    }

    /// Residual and its squared Mahalanobis distance.
    fn innovation(&self, m: &Measurement) -> Option<(DVec3, DMat3, f64)> {
        let r = log_so3(m.camera_from_object.matrix3 * self.pose.matrix3.transpose());
        let s = self.cov + m.rotation_covariance;
        if s.determinant().abs() < 1e-300 {
            return None;
        }
        let s_inv = s.inverse();
        Some((r, s_inv, r.dot(s_inv * r)))
    }

    fn fuse(&mut self, m: &Measurement, r: DVec3, s_inv: DMat3) {
        let k = self.cov * s_inv;
        let delta = k * r;
        let rot = DMat3::from_quat(DQuat::from_scaled_axis(delta)) * self.pose.matrix3;
        let rot = orthonormalise(rot);
        // Joseph form keeps the covariance symmetric positive semi-definite.
        let i_k = DMat3::IDENTITY - k;
        self.cov =
            symmetric(i_k * self.cov * i_k.transpose() + k * m.rotation_covariance * k.transpose());
        self.pose = DAffine3::from_mat3_translation(rot, m.camera_from_object.translation);
        self.fused += 1;
        self.since_update = 0;
    }
}

/// Recursive filter over successive view estimates (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewFilter {
    config: FilterConfig,
    main: Option<Hypothesis>,
    challenger: Option<Hypothesis>,
    gated_in_a_row: u32,
}

impl ViewFilter {
    /// An empty filter; it starts with the first measurement.
    pub fn new(config: FilterConfig) -> Result<ViewFilter, FusionError> {
        config.validate()?;
        Ok(ViewFilter {
            config,
            main: None,
            challenger: None,
            gated_in_a_row: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &FilterConfig {
        &self.config
    }

    /// Forgets everything (e.g. when the object is known to have moved).
    pub fn reset(&mut self) {
        self.main = None;
        self.challenger = None;
        self.gated_in_a_row = 0;
    }

    /// Whether a fused pose exists.
    pub fn is_initialised(&self) -> bool {
        self.main.is_some()
    }

    /// Moves the state by the camera's motion since the previous frame,
    /// `previous_camera_from_current_camera` (see the module docs). Call it
    /// once per frame, before that frame's [`ViewFilter::update`]; before the
    /// first measurement it only checks the input.
    pub fn predict(&mut self, motion: &DAffine3) -> Result<(), FusionError> {
        check_rigid(motion).map_err(FusionError::InvalidMotion)?;
        let angle = log_so3(motion.matrix3).length();
        let sigma =
            self.config.process_sigma_deg.to_radians() + self.config.process_per_rad * angle;
        let q = DMat3::from_diagonal(DVec3::splat(sigma * sigma));
        if let Some(h) = &mut self.main {
            h.predict(motion, q);
        }
        if let Some(h) = &mut self.challenger {
            h.predict(motion, q);
        }
        Ok(())
    }

    /// Fuses one accepted estimate of the current frame, or gates it out.
    pub fn update(&mut self, m: &Measurement) -> Result<Outcome, FusionError> {
        check_measurement(m)?;
        let Some(main) = &mut self.main else {
            self.main = Some(Hypothesis::new(m));
            return Ok(Outcome::Initialised);
        };
        let Some((r, s_inv, d2)) = main.innovation(m) else {
            return Err(FusionError::InvalidMeasurement(
                "state plus measurement covariance is singular".into(),
            ));
        };
        if d2 <= self.config.gate_chi2 {
            main.fuse(m, r, s_inv);
            self.challenger = None;
            self.gated_in_a_row = 0;
            return Ok(Outcome::Fused { mahalanobis2: d2 });
        }
        // Gated: the measurement either joins the challenger or starts a
        // new one; a challenger that has absorbed enough takes over.
        self.gated_in_a_row += 1;
        let agrees = match &mut self.challenger {
            Some(c) => match c.innovation(m) {
                Some((rc, sc_inv, dc2)) if dc2 <= self.config.gate_chi2 => {
                    c.fuse(m, rc, sc_inv);
                    true
                }
                _ => false,
            },
            None => false,
        };
        if !agrees {
            self.challenger = Some(Hypothesis::new(m));
        }
        if let Some(c) = self.challenger
            && c.fused >= self.config.reinit_after
        {
            self.main = Some(c);
            self.challenger = None;
            self.gated_in_a_row = 0;
            return Ok(Outcome::Reinitialised { mahalanobis2: d2 });
        }
        Ok(Outcome::Gated {
            mahalanobis2: d2,
            in_a_row: self.gated_in_a_row,
        })
    }

    /// The fused pose, once a measurement has arrived.
    pub fn state(&self) -> Option<FusedView> {
        let h = self.main?;
        let (theta, phi) = view_of(&h.pose);
        // Jacobian of (θ, φ) with respect to δ by central differences: u and
        // the look-at azimuth are smooth in δ even at the pole.
        let step = 1e-6;
        let e_theta = {
            let (st, ct) = theta.to_radians().sin_cos();
            let (sp, cp) = phi.to_radians().sin_cos();
            DVec3::new(-st * cp, -st * sp, ct)
        };
        let mut jac = [[0.0; 3]; 2];
        for (k, axis) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
            let turned = |sign: f64| {
                let rot = DMat3::from_quat(DQuat::from_scaled_axis(axis * sign * step));
                DAffine3::from_mat3_translation(rot * h.pose.matrix3, h.pose.translation)
            };
            let (plus, minus) = (turned(1.0), turned(-1.0));
            let du = view_direction(&plus) - view_direction(&minus);
            jac[0][k] = e_theta.dot(du).to_degrees() / (2.0 * step);
            let dphi = wrap_180(view_of(&plus).1 - view_of(&minus).1);
            jac[1][k] = dphi / (2.0 * step);
        }
        let c = h.cov;
        let cov = |i: usize, j: usize| c.col(j)[i];
        let mut view_cov = [[0.0; 2]; 2];
        for (a, row) in view_cov.iter_mut().enumerate() {
            for (b, out) in row.iter_mut().enumerate() {
                let mut s = 0.0;
                for i in 0..3 {
                    for j in 0..3 {
                        s += jac[a][i] * cov(i, j) * jac[b][j];
                    }
                }
                *out = s;
            }
        }
        let mut rotation_covariance = [[0.0; 3]; 3];
        for (i, row) in rotation_covariance.iter_mut().enumerate() {
            for (j, out) in row.iter_mut().enumerate() {
                *out = cov(i, j);
            }
        }
        Some(FusedView {
            theta_deg: theta,
            phi_deg: phi,
            view_covariance_deg2: view_cov,
            camera_from_object: h.pose.to_cols_array(),
            rotation_covariance,
            fused: h.fused,
            since_update: h.since_update,
        })
    }
}

/// Unit vector from the object centre to the camera centre, object frame.
fn view_direction(camera_from_object: &DAffine3) -> DVec3 {
    let r = camera_from_object.matrix3;
    (-(r.transpose() * camera_from_object.translation)).normalize_or(DVec3::Z)
}

/// (θ, φ) in degrees of a camera pose: θ from the view direction, φ from the
/// horizontal parts of the view direction and of the look-at camera's down
/// axis. For a look-at camera these are `cos θ (cos φ, sin φ)` and
/// `sin θ (cos φ, sin φ)`; their sum never vanishes, so φ stays defined at
/// the pole (where it is the roll) as well as at the horizon.
pub fn view_of(camera_from_object: &DAffine3) -> (f64, f64) {
    let u = view_direction(camera_from_object);
    let ray = camera_from_object.translation.normalize_or(DVec3::Z);
    // Undo the turn of an off-centre object to get the look-at camera.
    let turn = DMat3::from_quat(DQuat::from_rotation_arc(DVec3::Z, ray));
    let look_at = turn.transpose() * camera_from_object.matrix3;
    let down = look_at.transpose() * DVec3::Y;
    let theta = u.z.clamp(-1.0, 1.0).asin().to_degrees().clamp(0.0, 90.0);
    let phi = (u.y + down.y).atan2(u.x + down.x).to_degrees();
    (theta, wrap_360(phi))
}

fn wrap_360(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w >= 360.0 { 0.0 } else { w }
}

fn wrap_180(deg: f64) -> f64 {
    (deg + 180.0).rem_euclid(360.0) - 180.0
}

/// The rotation vector of a rotation matrix (angle in [0, π]).
fn log_so3(r: DMat3) -> DVec3 {
    let q = DQuat::from_mat3(&r).normalize();
    // q and -q are the same rotation; the positive scalar part gives the
    // shorter rotation vector.
    let q = if q.w < 0.0 { -q } else { q };
    q.to_scaled_axis()
}

fn orthonormalise(r: DMat3) -> DMat3 {
    DMat3::from_quat(DQuat::from_mat3(&r).normalize())
}

fn symmetric(m: DMat3) -> DMat3 {
    (m + m.transpose()) * 0.5
}

fn check_rigid(t: &DAffine3) -> Result<(), String> {
    if !t.is_finite() {
        return Err(format!("{t:?} is not finite"));
    }
    let r = t.matrix3;
    let err = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    if err > 1e-6 || r.determinant() < 0.0 {
        return Err(format!(
            "rotation is not orthonormal (|RᵀR - I| = {err:.2e}, det {:.3})",
            r.determinant()
        ));
    }
    Ok(())
}

fn check_measurement(m: &Measurement) -> Result<(), FusionError> {
    check_rigid(&m.camera_from_object).map_err(FusionError::InvalidMeasurement)?;
    if m.camera_from_object.translation.length() <= 0.0 {
        return Err(FusionError::InvalidMeasurement(
            "the object centre is at the camera centre".into(),
        ));
    }
    let c = m.rotation_covariance;
    let asym = (c - c.transpose())
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    let scale = c.to_cols_array().iter().fold(0.0f64, |a, x| a.max(x.abs()));
    // Positive definite: leading principal minors > 0 (Sylvester).
    let m1 = c.x_axis.x;
    let m2 = c.x_axis.x * c.y_axis.y - c.y_axis.x * c.x_axis.y;
    let m3 = c.determinant();
    if !c.is_finite() || asym > 1e-9 * scale.max(1e-300) || !(m1 > 0.0 && m2 > 0.0 && m3 > 0.0) {
        return Err(FusionError::InvalidMeasurement(format!(
            "rotation covariance {c:?} is not symmetric positive definite"
        )));
    }
    Ok(())
}
