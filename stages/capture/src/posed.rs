//! Objects drawn alone at given poses: what a camera at a known pose sees
//! of each model, with nothing else in the scene. The BOP reader derives
//! the visible part of every annotated instance from it (the models at
//! their annotated poses, with a depth test), and shape training reads
//! each view's silhouette and depth from it.

use glam::{DAffine3, DVec3};

use crate::Intrinsics;
use crate::object::Object;
use crate::raster::{Frame, draw_object};

/// A frame of objects at given poses.
#[derive(Debug, Clone, Default)]
pub struct PosedRender {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGB bytes, row-major: each model's colours under a light from the
    /// camera (black where no object is).
    pub rgb: Vec<u8>,
    /// Which object is the nearest surface: `i + 1` for `objects[i]`, 0
    /// for none.
    pub labels: Vec<u8>,
    /// Depth of the nearest surface along the optical axis, in the units
    /// of the poses' translations (0 where no object is).
    pub depth: Vec<f32>,
}

impl PosedRender {
    /// The pixels of object `i` (`objects[i]`) that are the nearest
    /// surface: 255 there, 0 elsewhere.
    pub fn mask_of(&self, i: usize) -> Vec<u8> {
        let label = i as u8 + 1;
        self.labels
            .iter()
            .map(|&l| if l == label { 255 } else { 0 })
            .collect()
    }

    /// How many pixels object `i` covers as the nearest surface.
    pub fn visible_px(&self, i: usize) -> usize {
        let label = i as u8 + 1;
        self.labels.iter().filter(|&&l| l == label).count()
    }
}

/// Draws `objects`, each `(object, camera_from_object, scale)`: the rigid
/// camera-from-object transform in units of `scale` normalised object
/// units (1 for a pose in object bounding radii), with a depth test
/// between them, nothing behind. At most 255 objects.
pub fn render_posed(objects: &[(&Object, DAffine3, f64)], k: &Intrinsics) -> PosedRender {
    assert!(objects.len() < 256, "at most 255 objects are labelled");
    let (w, h) = (k.width as usize, k.height as usize);
    let mut out = PosedRender {
        width: k.width,
        height: k.height,
        rgb: vec![0; 3 * w * h],
        labels: vec![0; w * h],
        depth: vec![0.0; w * h],
    };
    // The rasteriser keeps 1/z; the objects' scales differ, so each is
    // drawn in one common unit: the translation's.
    let mut inv_depth = vec![0f32; w * h];
    let mut frame = Frame {
        rgb: &mut out.rgb,
        mask: &mut out.labels,
        depth: &mut inv_depth,
        w,
        h,
    };
    for (i, (object, camera_from_object, scale)) in objects.iter().enumerate() {
        // Points of the object in the pose's units: scale, then the pose.
        let scaled = DAffine3::from_mat3_translation(
            camera_from_object.matrix3 * *scale,
            camera_from_object.translation,
        );
        draw_object(&mut frame, object, &scaled, DVec3::NEG_Z, k, i as u8 + 1);
    }
    for (d, &iz) in out.depth.iter_mut().zip(&inv_depth) {
        *d = if iz > 0.0 { 1.0 / iz } else { 0.0 };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ViewPose;

    #[test]
    fn the_nearer_object_hides_the_farther_one() {
        let can = Object::builtin("can").unwrap();
        let k = Intrinsics::default();
        let view = ViewPose::new(30.0, 0.0, 6.0).unwrap();
        let near = view.camera_from_world();
        let mut far = near;
        far.translation.z += 2.0;
        let alone = render_posed(&[(&can, far, 1.0)], &k);
        let both = render_posed(&[(&can, far, 1.0), (&can, near, 1.0)], &k);
        let far_alone = alone.visible_px(0);
        assert!(far_alone > 1000, "{far_alone}");
        // The nearer can is larger and straight in front: it hides all of
        // the farther one.
        assert_eq!(both.visible_px(0), 0);
        assert!(both.visible_px(1) > far_alone);
        // Depth is the optical-axis distance to the nearest surface.
        let centre = (k.cy as usize) * k.width as usize + k.cx as usize;
        let d = both.depth[centre] as f64;
        assert!((d - (near.translation.z - 1.0)).abs() < 0.6, "{d}");
    }

    #[test]
    fn a_pose_in_another_unit_draws_the_same_silhouette() {
        let can = Object::builtin("can").unwrap();
        let k = Intrinsics::default();
        let pose = ViewPose::new(50.0, 40.0, 5.0).unwrap().camera_from_world();
        let radii = render_posed(&[(&can, pose, 1.0)], &k);
        // The same pose in millimetres of a can of radius 84 mm.
        let mm = DAffine3::from_mat3_translation(pose.matrix3, pose.translation * 84.0);
        let millimetres = render_posed(&[(&can, mm, 84.0)], &k);
        assert_eq!(radii.labels, millimetres.labels);
        let i = radii.labels.iter().position(|&l| l == 1).unwrap();
        assert!((millimetres.depth[i] / radii.depth[i] - 84.0).abs() < 1e-2);
    }
}
