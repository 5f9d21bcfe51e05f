//! OBJ loading (the duck) and clear errors for bad input.

use std::path::Path;
use std::sync::Arc;

use acch_capture::{
    Background, CaptureError, DEFAULT_DISTANCE, Object, Renderer, SceneConfig, UpAxis, ViewPose,
};

const DUCK: &str = "/work/shared/data/duck/duck.obj";

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A unit square with UVs, material and a 2x2 PNG texture.
fn textured_square(dir: &Path, texture_name: &str) -> std::path::PathBuf {
    write(
        dir,
        "sq.mtl",
        &format!("newmtl m\nKd 1 1 1\nmap_Kd {texture_name}\n"),
    );
    write(
        dir,
        "sq.obj",
        "mtllib sq.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3 4/4\n",
    )
}

#[test]
fn duck_loads_textured_normalised_and_renders_yellow() {
    let duck = Object::load_obj(DUCK).expect("duck loads");
    assert_eq!(duck.name(), "duck");
    assert_eq!(duck.triangle_count(), 4212);
    assert_eq!(duck.texture_count(), 1);
    assert_eq!(duck.texture_sizes(), vec![(512, 512)]);
    assert!(
        (duck.bounding_radius() - 1.0).abs() < 1e-5,
        "radius {}",
        duck.bounding_radius()
    );
    let r = Renderer::new(SceneConfig::new(Arc::new(duck), Background::default()), 0);
    for (theta, phi) in [(45.0, 0.0), (60.0, 135.0), (90.0, 270.0)] {
        let out = r.render(&ViewPose::new(theta, phi, DEFAULT_DISTANCE).unwrap(), 0);
        let mut n = 0;
        let mut yellow = 0;
        for (x, y, m) in out.mask.enumerate_pixels() {
            if m[0] != 0 {
                n += 1;
                let [r, g, b] = out.image.get_pixel(x, y).0.map(|c| c as i32);
                yellow += (r > 90 && g > 60 && b < g / 2 && r >= g) as usize;
            }
        }
        assert!(n > 3000, "duck visible at ({theta}, {phi}): {n} px");
        assert!(
            yellow as f64 > 0.8 * n as f64,
            "mostly yellow at ({theta}, {phi}): {yellow}/{n}"
        );
    }
}

#[test]
fn duck_stands_upright_with_y_up() {
    // The file's y extent (0.10..1.64) is the duck's height, its z extent
    // (-0.54..0.61) the body's width: with +y up it stands taller.
    let up_y = Object::load_obj(DUCK).unwrap();
    let up_z = Object::load_obj_with_up(DUCK, UpAxis::PosZ).unwrap();
    assert!(
        up_y.table_z() < -0.7,
        "y-up duck stands tall: table_z {}",
        up_y.table_z()
    );
    assert!(
        up_z.table_z() > -0.7,
        "z-up duck lies low: table_z {}",
        up_z.table_z()
    );
    assert_eq!("-z".parse::<UpAxis>().unwrap(), UpAxis::NegZ);
    assert!(
        "w".parse::<UpAxis>()
            .unwrap_err()
            .to_string()
            .contains("'w'")
    );
}

#[test]
fn missing_file_is_a_clear_error() {
    let err = Object::load_obj("/nonexistent/dir/thing.obj").unwrap_err();
    assert!(matches!(err, CaptureError::Io { .. }), "{err:?}");
    assert!(
        err.to_string().contains("/nonexistent/dir/thing.obj"),
        "{err}"
    );
}

#[test]
fn mesh_without_texture_coordinates_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "tri.obj",
        "o plain_triangle\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    let err = Object::load_obj(&p).unwrap_err();
    assert!(
        matches!(err, CaptureError::MissingTexCoords { .. }),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(
        msg.contains("tri.obj")
            && msg.contains("texture coordinates")
            && msg.contains("plain_triangle"),
        "{msg}"
    );
}

#[test]
fn missing_material_texture_or_mtl_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    // No material at all.
    let p = write(
        dir.path(),
        "nomat.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n",
    );
    let err = Object::load_obj(&p).unwrap_err();
    assert!(
        matches!(err, CaptureError::MissingTexture { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("nomat.obj"));

    // Material library missing.
    let p = write(
        dir.path(),
        "nomtl.obj",
        "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n",
    );
    let err = Object::load_obj(&p).unwrap_err();
    assert!(matches!(err, CaptureError::Mtl { .. }), "{err:?}");
    assert!(err.to_string().contains("gone.mtl"), "{err}");

    // Material without map_Kd.
    write(dir.path(), "plain.mtl", "newmtl m\nKd 1 0 0\n");
    let p = write(
        dir.path(),
        "nokd.obj",
        "mtllib plain.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n",
    );
    let err = Object::load_obj(&p).unwrap_err();
    assert!(err.to_string().contains("map_Kd"), "{err}");

    // Texture file missing: the error names the resolved texture path.
    let p = textured_square(dir.path(), "missing.png");
    let err = Object::load_obj(&p).unwrap_err();
    assert!(matches!(err, CaptureError::Texture { .. }), "{err:?}");
    assert!(
        err.to_string()
            .contains(&dir.path().join("missing.png").display().to_string()),
        "{err}"
    );
}

#[test]
fn texture_paths_resolve_relative_to_the_mtl_file() {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("materials");
    std::fs::create_dir(&sub).unwrap();
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 20, 20]))
        .save(sub.join("red.png"))
        .unwrap();
    write(&sub, "sq.mtl", "newmtl m\nmap_Kd red.png\n");
    let p = write(
        dir.path(),
        "sq.obj",
        "mtllib materials/sq.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3 4/4\n",
    );
    let obj = Object::load_obj_with_up(&p, UpAxis::PosZ).expect("loads");
    assert_eq!(obj.triangle_count(), 2);
    assert!((obj.bounding_radius() - 1.0).abs() < 1e-6);
    // A flat square seen from above is red where it is visible.
    let r = Renderer::new(SceneConfig::new(Arc::new(obj), Background::default()), 0);
    let out = r.render(&ViewPose::new(90.0, 0.0, 5.0).unwrap(), 0);
    let px = out.image.get_pixel(320, 240).0;
    assert!(px[0] > 150 && px[1] < 40 && px[2] < 40, "{px:?}");
}

#[test]
fn corrupt_obj_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "bad.obj", "v 0 0 0\nv 1 0\nf 1 2 9\n");
    let err = Object::load_obj(&p).unwrap_err();
    assert!(err.to_string().contains("bad.obj"), "{err}");
    let p = write(dir.path(), "empty.obj", "# nothing\n");
    let err = Object::load_obj(&p).unwrap_err();
    assert!(matches!(err, CaptureError::EmptyMesh { .. }), "{err:?}");
}
