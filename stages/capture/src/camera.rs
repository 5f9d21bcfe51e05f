//! Pinhole intrinsics and camera poses on the view sphere.

use glam::{DAffine3, DMat3, DVec2, DVec3};
use serde::{Deserialize, Serialize};

use crate::CaptureError;

/// Default camera distance from the object centre, in object bounding radii.
pub const DEFAULT_DISTANCE: f64 = 5.0;

/// Pinhole camera intrinsics (no lens distortion). Pixel centres lie at integer
/// coordinates: pixel (0, 0) covers [-0.5, 0.5] x [-0.5, 0.5].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length in pixels along x.
    pub fx: f64,
    /// Focal length in pixels along y.
    pub fy: f64,
    /// Principal point x in pixels.
    pub cx: f64,
    /// Principal point y in pixels.
    pub cy: f64,
}

impl Default for Intrinsics {
    /// 640x480, fx = fy = 500, principal point at the image centre (319.5, 239.5).
    fn default() -> Self {
        Intrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 500.0,
            cx: 319.5,
            cy: 239.5,
        }
    }
}

impl Intrinsics {
    /// Projects a point given in the OpenCV camera frame (x right, y down,
    /// z forward) to pixel coordinates; `None` for points not in front of the
    /// camera. The result may lie outside the image.
    pub fn project(&self, p_cam: DVec3) -> Option<DVec2> {
        if p_cam.z > 1e-12 && p_cam.is_finite() {
            Some(DVec2::new(
                self.fx * p_cam.x / p_cam.z + self.cx,
                self.fy * p_cam.y / p_cam.z + self.cy,
            ))
        } else {
            None
        }
    }

    /// The viewing ray through a pixel, in the camera frame, scaled so that
    /// its z component is 1 (multiply by a depth to get the 3-D point).
    pub fn ray(&self, pixel: DVec2) -> DVec3 {
        DVec3::new(
            (pixel.x - self.cx) / self.fx,
            (pixel.y - self.cy) / self.fy,
            1.0,
        )
    }

    /// Checks that the intrinsics describe a usable camera: a non-empty image
    /// of at most 16384 pixels a side, positive finite focal lengths and a
    /// finite principal point.
    pub fn validate(&self) -> Result<(), CaptureError> {
        let bad = |reason: String| Err(CaptureError::InvalidIntrinsics { reason });
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return bad(format!(
                "image size {}x{} must be between 1x1 and 16384x16384",
                self.width, self.height
            ));
        }
        if !(self.fx.is_finite() && self.fx > 0.0 && self.fy.is_finite() && self.fy > 0.0) {
            return bad(format!(
                "focal lengths fx = {}, fy = {} must be finite and > 0",
                self.fx, self.fy
            ));
        }
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return bad(format!(
                "principal point ({}, {}) must be finite",
                self.cx, self.cy
            ));
        }
        Ok(())
    }
}

/// A camera position on the view sphere around the object centre: elevation
/// `theta_deg` in [0, 90] (90 = straight down), azimuth `phi_deg` in [0, 360)
/// and `distance` from the object centre in object bounding radii. The camera
/// looks at the object centre, rolled by `roll_deg` about its optical axis
/// (0 = image up is `e_θ`; see [`ViewPose::world_from_camera_rotation`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewPose {
    /// Elevation above the table plane in degrees, [0, 90].
    pub theta_deg: f64,
    /// Azimuth about the world z axis in degrees, [0, 360), 0 = from +x.
    pub phi_deg: f64,
    /// Distance from the object centre in object bounding radii.
    pub distance: f64,
    /// Roll ρ of the camera about its optical (forward) axis in degrees,
    /// (-180, 180], 0 = no roll. The rolled axes are
    /// `right' = cos ρ right + sin ρ down`, `down' = -sin ρ right + cos ρ down`,
    /// forward unchanged (a rotation by +ρ about forward), so the image
    /// content turns by ρ counter-clockwise on screen (x right, y down).
    #[serde(default)]
    pub roll_deg: f64,
}

/// Checks that a camera distance is finite and positive.
pub fn check_distance(distance: f64) -> Result<(), CaptureError> {
    if distance.is_finite() && distance > 0.0 {
        Ok(())
    } else {
        Err(CaptureError::InvalidDistance { value: distance })
    }
}

/// Wraps an angle in degrees into [0, 360).
pub(crate) fn wrap_deg(phi: f64) -> f64 {
    let w = phi.rem_euclid(360.0);
    // rem_euclid can round up to exactly 360 for tiny negative inputs.
    if w >= 360.0 { 0.0 } else { w }
}

/// Wraps an angle in degrees into (-180, 180].
pub(crate) fn wrap_roll_deg(roll: f64) -> f64 {
    if roll > -180.0 && roll <= 180.0 {
        return roll;
    }
    let w = 180.0 - (180.0 - roll).rem_euclid(360.0);
    // rem_euclid can round up to exactly 360.
    if w <= -180.0 { 180.0 } else { w }
}

impl ViewPose {
    /// Validates and builds a view. `phi_deg` may be any finite angle and is
    /// wrapped into [0, 360); `theta_deg` must lie in [0, 90] and `distance`
    /// must be finite and positive.
    pub fn new(theta_deg: f64, phi_deg: f64, distance: f64) -> Result<Self, CaptureError> {
        if !(0.0..=90.0).contains(&theta_deg) {
            return Err(CaptureError::InvalidTheta { value: theta_deg });
        }
        if !phi_deg.is_finite() {
            return Err(CaptureError::InvalidPhi { value: phi_deg });
        }
        check_distance(distance)?;
        Ok(ViewPose {
            theta_deg,
            phi_deg: wrap_deg(phi_deg),
            distance,
            roll_deg: 0.0,
        })
    }

    /// The same view rolled by `roll_deg` about the optical axis (replacing
    /// any roll it had; see [`ViewPose::roll_deg`] for the direction). Any
    /// finite angle is accepted and wrapped into (-180, 180].
    pub fn with_roll(self, roll_deg: f64) -> Result<Self, CaptureError> {
        if !roll_deg.is_finite() {
            return Err(CaptureError::InvalidRoll { value: roll_deg });
        }
        Ok(ViewPose {
            roll_deg: wrap_roll_deg(roll_deg),
            ..self
        })
    }

    /// The camera centre in the world frame:
    /// `r (cos θ cos φ, cos θ sin φ, sin θ)`.
    pub fn camera_position(&self) -> DVec3 {
        let (st, ct) = self.theta_deg.to_radians().sin_cos();
        let (sp, cp) = self.phi_deg.to_radians().sin_cos();
        self.distance * DVec3::new(ct * cp, ct * sp, st)
    }

    /// The rotation whose columns are the camera axes (right, down, forward)
    /// in world coordinates. Image "up" is `e_θ`, the direction of increasing
    /// elevation, which stays defined at θ = 90: a top view is then rotated
    /// by φ about the principal point. A non-zero [`ViewPose::roll_deg`] ρ
    /// then turns right and down about forward:
    /// `right' = cos ρ right + sin ρ down`, `down' = -sin ρ right + cos ρ down`.
    pub fn world_from_camera_rotation(&self) -> DMat3 {
        world_from_camera_rotation(self.theta_deg, self.phi_deg, self.roll_deg)
    }

    /// The camera pose: maps points from the OpenCV camera frame (x right,
    /// y down, z forward) to the world frame (z up, object centre at the
    /// origin). Rotation columns are (right, down, forward); the translation
    /// is the camera centre.
    pub fn world_from_camera(&self) -> DAffine3 {
        DAffine3::from_mat3_translation(self.world_from_camera_rotation(), self.camera_position())
    }

    /// The inverse of [`ViewPose::world_from_camera`].
    pub fn camera_from_world(&self) -> DAffine3 {
        let r = self.world_from_camera_rotation().transpose();
        DAffine3::from_mat3_translation(r, -(r * self.camera_position()))
    }
}

/// The rotation of a camera at elevation `theta_deg` (any, negative below
/// the horizontal) and azimuth `phi_deg` looking at the origin, rolled by
/// `roll_deg` about its optical axis: columns right, down and forward in
/// the world ([`ViewPose::world_from_camera_rotation`], whose elevation
/// is limited to a camera above the table).
pub fn world_from_camera_rotation(theta_deg: f64, phi_deg: f64, roll_deg: f64) -> DMat3 {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    let (sp, cp) = phi_deg.to_radians().sin_cos();
    let forward = -DVec3::new(ct * cp, ct * sp, st);
    let up = DVec3::new(-st * cp, -st * sp, ct);
    let down = -up;
    let right = down.cross(forward);
    if roll_deg == 0.0 {
        return DMat3::from_cols(right, down, forward);
    }
    let (sr, cr) = roll_deg.to_radians().sin_cos();
    DMat3::from_cols(cr * right + sr * down, cr * down - sr * right, forward)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roll_turns_the_image_counter_clockwise() {
        let k = Intrinsics::default();
        let v = ViewPose::new(60.0, 30.0, DEFAULT_DISTANCE).unwrap();
        // A world point 0.5 to the camera's right of the object centre.
        let r0 = v.world_from_camera_rotation();
        let p = 0.5 * r0.x_axis;
        let px = |v: &ViewPose| {
            k.project(v.camera_from_world().transform_point3(p))
                .unwrap()
        };
        let a = px(&v);
        assert!(a.x > k.cx + 10.0 && (a.y - k.cy).abs() < 1e-9, "{a}");
        // Rolled by +90: the point right of centre moves up (y decreases),
        // a counter-clockwise quarter turn on screen.
        let b = px(&v.with_roll(90.0).unwrap());
        assert!((b.x - k.cx).abs() < 1e-9, "{b}");
        assert!((b.y - (k.cy - (a.x - k.cx))).abs() < 1e-9, "{a} {b}");
        // A small positive roll turns it counter-clockwise too (up-right).
        let c = px(&v.with_roll(10.0).unwrap());
        assert!(c.y < k.cy && c.x > k.cx, "{c}");
        let ang = (-(c.y - k.cy)).atan2(c.x - k.cx).to_degrees();
        assert!((ang - 10.0).abs() < 1e-9, "{ang}");
        // Still a proper rotation, forward unchanged.
        let r = v.with_roll(37.0).unwrap().world_from_camera_rotation();
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        assert!(r.z_axis.abs_diff_eq(r0.z_axis, 0.0));
    }

    #[test]
    fn roll_is_wrapped_and_validated() {
        let v = ViewPose::new(45.0, 0.0, 5.0).unwrap();
        assert_eq!(v.roll_deg, 0.0);
        for (given, want) in [
            (0.0, 0.0),
            (180.0, 180.0),
            (-180.0, 180.0),
            (190.0, -170.0),
            (-190.0, 170.0),
            (540.0, 180.0),
            (-30.0, -30.0),
            (1e-20, 1e-20),
            (-1e-20, -1e-20),
        ] {
            assert_eq!(v.with_roll(given).unwrap().roll_deg, want, "{given}");
        }
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let e = v.with_roll(bad).unwrap_err();
            assert!(matches!(e, CaptureError::InvalidRoll { .. }));
            assert!(e.to_string().contains("roll"), "{e}");
        }
        // Roll 0 is bit-identical to no roll; a full turn is the same pose.
        let r = v.world_from_camera_rotation();
        assert_eq!(v.with_roll(0.0).unwrap().world_from_camera_rotation(), r);
        let full = v.with_roll(360.0).unwrap();
        assert_eq!(full.roll_deg, 0.0);
    }

    #[test]
    fn top_view_roll_equals_an_azimuth_change() {
        // At the top view, +90 deg of azimuth turns the image clockwise, so
        // a +90 roll (counter-clockwise) equals -90 deg of azimuth.
        let rolled = ViewPose::new(90.0, 20.0, 5.0)
            .unwrap()
            .with_roll(90.0)
            .unwrap()
            .world_from_camera_rotation();
        let turned = ViewPose::new(90.0, 290.0, 5.0)
            .unwrap()
            .world_from_camera_rotation();
        assert!(rolled.abs_diff_eq(turned, 1e-12), "{rolled} {turned}");
    }
}
