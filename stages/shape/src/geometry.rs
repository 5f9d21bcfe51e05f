//! Poses and views: a camera-from-object pose and the view the method
//! estimates (elevation θ and azimuth φ of the camera about the object's
//! centre, its roll about the ray to that centre, its distance), one the
//! inverse of the other.
//!
//! The object frame is the renderer's: z up, the bounding-box centre at
//! the origin, one unit a bounding radius. A view's roll is measured in
//! the camera turned by the shortest arc to look at the object's centre
//! ([`towards`]): an object off the optical axis is seen as that turned
//! camera sees it, rolled or not.

use acch_capture::{Intrinsics, world_from_camera_rotation};
use glam::{DAffine3, DMat3, DQuat, DVec2, DVec3};

/// A view of the object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Elevation of the camera above the object's horizontal plane,
    /// degrees in [-90, 90].
    pub theta_deg: f64,
    /// Azimuth of the camera about the object's up axis, degrees in
    /// [0, 360).
    pub phi_deg: f64,
    /// Roll of the camera about the ray to the object's centre, degrees
    /// in (-180, 180]: the image turns counter-clockwise by it.
    pub roll_deg: f64,
    /// Distance of the camera from the object's centre, object units.
    pub distance: f64,
}

/// The rotation that turns a camera's optical axis by the shortest arc
/// onto the ray through `pixel`: real-from-turned camera.
pub fn towards(k: &Intrinsics, pixel: DVec2) -> DMat3 {
    let ray = k.ray(pixel).normalize();
    DMat3::from_quat(DQuat::from_rotation_arc(DVec3::Z, ray))
}

/// The camera-from-object pose of `view` with the object's centre on the
/// ray through `centre_px`.
pub fn pose_of(view: &View, k: &Intrinsics, centre_px: DVec2) -> DAffine3 {
    let real_from_turned = towards(k, centre_px);
    let world_from_turned = world_from_camera_rotation(view.theta_deg, view.phi_deg, view.roll_deg);
    DAffine3::from_mat3_translation(
        real_from_turned * world_from_turned.transpose(),
        real_from_turned * DVec3::new(0.0, 0.0, view.distance),
    )
}

/// The view of a camera-from-object pose (the object's centre in front
/// of the camera): the inverse of [`pose_of`].
pub fn view_of(camera_from_object: &DAffine3) -> View {
    let t = camera_from_object.translation;
    let distance = t.length();
    let real_from_turned = DMat3::from_quat(DQuat::from_rotation_arc(DVec3::Z, t / distance));
    // The turned camera's axes in the object's frame.
    let world_from_turned = camera_from_object.matrix3.transpose() * real_from_turned;
    let position = -(camera_from_object.matrix3.transpose() * t) / distance;
    let theta = position.z.clamp(-1.0, 1.0).asin().to_degrees();
    let phi = wrap_360(position.y.atan2(position.x).to_degrees());
    let unrolled = world_from_camera_rotation(theta, phi, 0.0);
    let right = world_from_turned.x_axis;
    let roll = right
        .dot(unrolled.y_axis)
        .atan2(right.dot(unrolled.x_axis))
        .to_degrees();
    View {
        theta_deg: theta,
        phi_deg: phi,
        roll_deg: if roll <= -180.0 { 180.0 } else { roll },
        distance,
    }
}

/// An angle wrapped into [0, 360).
pub fn wrap_360(deg: f64) -> f64 {
    let w = deg.rem_euclid(360.0);
    if w >= 360.0 { 0.0 } else { w }
}

/// The angle between two rotations, degrees.
pub fn rotation_angle_deg(a: &DMat3, b: &DMat3) -> f64 {
    let r = a.transpose() * *b;
    let c = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) / 2.0).clamp(-1.0, 1.0);
    c.acos().to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_view_placed_anywhere_in_the_image_reads_back() {
        let k = Intrinsics::default();
        for (theta, phi, roll, px) in [
            (45.0, 0.0, 0.0, DVec2::new(319.5, 239.5)),
            (-15.0, 123.0, 30.0, DVec2::new(600.0, 20.0)),
            (80.0, 300.0, -170.0, DVec2::new(10.0, 470.0)),
            (5.0, 359.0, 90.0, DVec2::new(100.0, 300.0)),
        ] {
            let view = View {
                theta_deg: theta,
                phi_deg: phi,
                roll_deg: roll,
                distance: 7.5,
            };
            let pose = pose_of(&view, &k, px);
            let centre = k.project(pose.translation).unwrap();
            assert!((centre - px).length() < 1e-6, "{centre}");
            let back = view_of(&pose);
            assert!((back.theta_deg - theta).abs() < 1e-6, "{back:?}");
            assert!((back.phi_deg - phi).abs() < 1e-6, "{back:?}");
            assert!((back.roll_deg - roll).abs() < 1e-6, "{back:?}");
            assert!((back.distance - 7.5).abs() < 1e-9, "{back:?}");
        }
    }

    #[test]
    fn on_the_optical_axis_a_view_is_the_renderers() {
        let view = acch_capture::ViewPose::new(60.0, 40.0, 5.0)
            .unwrap()
            .with_roll(25.0)
            .unwrap();
        let pose = view.camera_from_world();
        let back = view_of(&pose);
        assert!((back.theta_deg - 60.0).abs() < 1e-9);
        assert!((back.phi_deg - 40.0).abs() < 1e-9);
        assert!((back.roll_deg - 25.0).abs() < 1e-9);
        let k = Intrinsics::default();
        let again = pose_of(&back, &k, DVec2::new(k.cx, k.cy));
        assert!(rotation_angle_deg(&again.matrix3, &pose.matrix3) < 1e-6);
    }
}
