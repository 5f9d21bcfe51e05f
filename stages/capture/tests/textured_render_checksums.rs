//! Textured objects render byte for byte as before vertex colours came into
//! the rasteriser: white vertex colours multiply by exactly 1.0 and the
//! white-triangle path interpolates one shade, as the old code did. The
//! checksums (FNV-1a over image and mask) were recorded with the renderer
//! before that change (x86-64 Linux). A deliberate change of textured
//! rendering changes them; then record the new values.

use std::path::Path;
use std::sync::Arc;

use acch_capture::{Background, Object, Renderer, SceneConfig, ViewPose};

const DUCK: &str = "/work/shared/data/duck/duck.obj";

fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

#[test]
fn textured_renders_are_unchanged() {
    // Object, background, theta, phi, distance, checksum. Distance 0.6
    // puts the camera inside the fruitbox: triangles are clipped at the
    // near plane. The clutter backgrounds draw distractors (and
    // ClutterSimilar picks their colours from `dominant_colors`).
    let cases = [
        (
            "fruitbox",
            Background::A,
            60.0,
            30.0,
            4.0,
            0x00aa9dd7f105c7fd_u64,
        ),
        (
            "fruitbox",
            Background::A,
            20.0,
            200.0,
            3.0,
            0xfa0706900addafe9,
        ),
        (
            "fruitbox",
            Background::A,
            30.0,
            10.0,
            1.0,
            0x883d1d780325895e,
        ),
        ("can", Background::A, 45.0, 0.0, 4.0, 0x8d06b287a74d0aa3),
        ("can", Background::A, 80.0, 123.0, 2.5, 0xc110ce7c4f451b1f),
        ("can", Background::A, 10.0, 300.0, 0.9, 0xaa869ddfd79e58e0),
        (
            "tricolor",
            Background::A,
            50.0,
            60.0,
            4.0,
            0x6e7cb7e503c257e9,
        ),
        ("can", Background::A, 10.0, 300.0, 0.5, 0x48f2b241dd6de62e),
        (
            "fruitbox",
            Background::A,
            30.0,
            10.0,
            0.6,
            0x22bfd9216f66532b,
        ),
        (
            "fruitbox",
            Background::Clutter,
            40.0,
            70.0,
            4.0,
            0xfd20865778c5f9df,
        ),
        (
            "can",
            Background::ClutterSimilar,
            35.0,
            250.0,
            4.0,
            0x538aed9d82e8df94,
        ),
        ("duck", Background::A, 45.0, 0.0, 4.0, 0xd0b20163ecc0bbb9),
        ("duck", Background::B, 70.0, 200.0, 2.0, 0xfdba9310be22474b),
    ];
    let mut wrong = Vec::new();
    for (name, bg, theta, phi, distance, expected) in cases {
        let obj = if name == "duck" {
            assert!(
                Path::new(DUCK).exists(),
                "{DUCK} is missing: this test needs the duck mesh (the workplace's shared/data/duck)"
            );
            Object::load_obj(DUCK).unwrap()
        } else {
            Object::builtin(name).unwrap()
        };
        let r = Renderer::new(SceneConfig::new(Arc::new(obj), bg), 7);
        let out = r.render(&ViewPose::new(theta, phi, distance).unwrap(), 0);
        let h = fnv(
            out.mask.as_raw(),
            fnv(out.image.as_raw(), 0xcbf2_9ce4_8422_2325),
        );
        if h != expected {
            wrong.push(format!(
                "{name} {bg:?} ({theta}, {phi}, {distance}): {h:#018x}, expected {expected:#018x}"
            ));
        }
    }
    assert!(wrong.is_empty(), "renders changed:\n{}", wrong.join("\n"));
}
