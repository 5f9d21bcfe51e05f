//! Geometry, rendering, determinism and clutter of the scene renderer.

use std::sync::Arc;

use acch_capture::{
    Background, CaptureError, DEFAULT_DISTANCE, Effects, Intrinsics, MAX_EXPOSURE_SAMPLES, Object,
    Renderer, SceneConfig, Trajectory, ViewPose, exposure_samples, mask_bbox,
};
use glam::{DVec2, DVec3};
use image::GrayImage;

fn renderer(object: &str, background: Background, effects: Effects, seed: u64) -> Renderer {
    let object = Arc::new(Object::builtin(object).expect("builtin object"));
    let mut config = SceneConfig::new(object, background);
    config.effects = effects;
    Renderer::new(config, seed)
}

fn view(theta: f64, phi: f64) -> ViewPose {
    ViewPose::new(theta, phi, DEFAULT_DISTANCE).expect("valid view")
}

fn mask_centroid(mask: &GrayImage) -> DVec2 {
    let (mut sum, mut n) = (DVec2::ZERO, 0.0);
    for (x, y, p) in mask.enumerate_pixels() {
        if p[0] != 0 {
            sum += DVec2::new(x as f64, y as f64);
            n += 1.0;
        }
    }
    assert!(n > 0.0, "empty mask");
    sum / n
}

fn count(mask: &GrayImage) -> usize {
    mask.pixels().filter(|p| p[0] != 0).count()
}

#[test]
fn world_origin_projects_to_principal_point() {
    let k = Intrinsics::default();
    for theta in [0.0, 30.0, 45.0, 72.5, 89.999, 90.0] {
        for phi in [0.0, 77.0, 180.0, 350.0] {
            let v = view(theta, phi);
            let p_cam = v
                .world_from_camera()
                .inverse()
                .transform_point3(DVec3::ZERO);
            let px = k.project(p_cam).expect("origin in front of the camera");
            assert!(
                (px - DVec2::new(k.cx, k.cy)).length() < 1e-9,
                "theta {theta} phi {phi}: {px}"
            );
            assert!((p_cam.z - DEFAULT_DISTANCE).abs() < 1e-9);
            // The inverse helper agrees with inverting the pose.
            let q = v
                .camera_from_world()
                .transform_point3(DVec3::new(0.3, -0.2, 0.1));
            let q2 = v
                .world_from_camera()
                .inverse()
                .transform_point3(DVec3::new(0.3, -0.2, 0.1));
            assert!((q - q2).length() < 1e-12);
        }
    }
}

#[test]
fn known_point_projects_where_the_intrinsics_say() {
    let k = Intrinsics::default();
    let v = view(60.0, 40.0);
    let pose = v.world_from_camera();
    // 0.5 right, 0.25 down and 2 forward of the camera, in world coordinates.
    let p_world = pose.transform_point3(DVec3::new(0.5, 0.25, 2.0));
    let p_cam = v.camera_from_world().transform_point3(p_world);
    let px = k.project(p_cam).unwrap();
    assert!(
        (px - DVec2::new(319.5 + 125.0, 239.5 + 62.5)).length() < 1e-9,
        "{px}"
    );
    assert_eq!(k.project(DVec3::new(0.0, 0.0, -1.0)), None);
    // Camera centre and axes as specified.
    let c = pose.translation;
    assert!(
        (c - 5.0
            * DVec3::new(
                0.5 * 40f64.to_radians().cos(),
                0.5 * 40f64.to_radians().sin(),
                0.75f64.sqrt()
            ))
        .length()
            < 1e-9
    );
    let r = pose.matrix3;
    assert!((r.transpose() * r - glam::DMat3::IDENTITY).abs_diff_eq(glam::DMat3::ZERO, 1e-12));
    assert!((r.determinant() - 1.0).abs() < 1e-12);
    assert!(
        (r.z_axis + c.normalize()).length() < 1e-12,
        "forward looks at the origin"
    );
    // Upright: image "down" points down in the world, "right" is horizontal.
    assert!(r.y_axis.z < 0.0 && r.x_axis.z.abs() < 1e-12);
}

#[test]
fn top_view_has_continuous_defined_roll() {
    let a = view(90.0, 30.0).world_from_camera().matrix3;
    let b = ViewPose::new(89.9999, 30.0, DEFAULT_DISTANCE)
        .unwrap()
        .world_from_camera()
        .matrix3;
    assert!(a.abs_diff_eq(b, 1e-5));
    // Image up at the top view is e_theta = (-cos phi, -sin phi, 0).
    let up = -a.y_axis;
    assert!(
        (up - DVec3::new(-30f64.to_radians().cos(), -30f64.to_radians().sin(), 0.0)).length()
            < 1e-12
    );
}

#[test]
fn fruitbox_top_view_mask_is_centred_on_the_projected_centre() {
    let r = renderer("fruitbox", Background::default(), Effects::default(), 0);
    let k = Intrinsics::default();
    for phi in [0.0, 20.0, 45.0, 130.0] {
        let out = r.render(&view(90.0, phi), 0);
        let c = mask_centroid(&out.mask);
        assert!(
            (c - DVec2::new(k.cx, k.cy)).length() < 1.0,
            "phi {phi}: centroid {c}"
        );
    }
}

/// For a pixel of the output of a 90 degree turn about the principal point,
/// the source pixel, if inside the image. The clockwise turn (on screen)
/// takes image right (+u) to image down (+v): out(cx - dy, cy + dx) =
/// in(cx + dx, cy + dy).
fn rotated_source(x: u32, y: u32, clockwise: bool) -> Option<(u32, u32)> {
    let k = Intrinsics::default();
    let (dx, dy) = (x as f64 - k.cx, y as f64 - k.cy);
    let (sx, sy) = if clockwise {
        (k.cx + dy, k.cy - dx)
    } else {
        (k.cx - dy, k.cy + dx)
    };
    (sx >= 0.0 && sy >= 0.0 && sx < k.width as f64 && sy < k.height as f64)
        .then_some((sx as u32, sy as u32))
}

fn rotated_iou(a: &GrayImage, b: &GrayImage, clockwise: bool) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for (x, y, p) in b.enumerate_pixels() {
        let src =
            rotated_source(x, y, clockwise).is_some_and(|(sx, sy)| a.get_pixel(sx, sy)[0] != 0);
        let dst = p[0] != 0;
        inter += (src && dst) as usize;
        union += (src || dst) as usize;
    }
    inter as f64 / union as f64
}

#[test]
fn top_view_phi_plus_90_rotates_the_mask_by_90_degrees() {
    let r = renderer("fruitbox", Background::A, Effects::default(), 0);
    let a = r.render(&view(90.0, 20.0), 0);
    let b = r.render(&view(90.0, 110.0), 0);
    assert!(count(&a.mask) > 2000, "object visible");
    let iou = rotated_iou(&a.mask, &b.mask, true);
    assert!(iou > 0.95, "IoU {iou}");
    // The box top is centrally symmetric, so check the direction on its
    // printed (and evenly lit) texture: the clockwise turn matches, the
    // counter-clockwise one does not.
    let diff = |clockwise: bool| {
        let (mut sum, mut n) = (0.0, 0.0);
        for (x, y, m) in b.mask.enumerate_pixels() {
            let Some((sx, sy)) = rotated_source(x, y, clockwise) else {
                continue;
            };
            if m[0] != 0 && a.mask.get_pixel(sx, sy)[0] != 0 {
                let (p, q) = (b.image.get_pixel(x, y).0, a.image.get_pixel(sx, sy).0);
                sum += (0..3)
                    .map(|i| (p[i] as f64 - q[i] as f64).abs())
                    .sum::<f64>();
                n += 3.0;
            }
        }
        sum / n
    };
    let (right, wrong) = (diff(true), diff(false));
    assert!(
        right < 8.0 && wrong > 4.0 * right,
        "mean abs diff: clockwise {right}, counter-clockwise {wrong}"
    );
}

#[test]
fn top_view_rotation_of_an_asymmetric_mask() {
    let duck = Arc::new(Object::load_obj("/work/shared/data/duck/duck.obj").unwrap());
    let r = Renderer::new(SceneConfig::new(duck, Background::default()), 0);
    let a = r.render(&view(90.0, 200.0), 0).mask;
    let b = r.render(&view(90.0, 290.0), 0).mask;
    let (right, wrong) = (rotated_iou(&a, &b, true), rotated_iou(&a, &b, false));
    assert!(
        right > 0.95 && wrong < 0.85,
        "IoU clockwise {right}, counter-clockwise {wrong}"
    );
}

#[test]
fn mask_and_bbox_match_the_object_pixels() {
    let r = renderer(
        "fruitbox",
        Background::Plain([140, 140, 140]),
        Effects::default(),
        0,
    );
    let out = r.render(&view(50.0, 10.0), 0);
    let b = out.truth.bbox.expect("visible");
    assert_eq!(Some(b), mask_bbox(&out.mask));
    // Outside the mask the plain colour is untouched; inside it mostly differs.
    let (mut inside_diff, mut inside) = (0, 0);
    for (x, y, m) in out.mask.enumerate_pixels() {
        let p = out.image.get_pixel(x, y).0;
        if m[0] == 0 {
            assert_eq!(p, [140, 140, 140], "background pixel ({x}, {y})");
        } else {
            inside += 1;
            inside_diff += (p != [140, 140, 140]) as usize;
            assert!(x >= b.x && x < b.x + b.width && y >= b.y && y < b.y + b.height);
        }
    }
    assert!(inside_diff as f64 > 0.99 * inside as f64);
    assert_eq!(out.truth.theta_deg, 50.0);
    assert_eq!(
        out.truth.world_from_camera,
        view(50.0, 10.0).world_from_camera()
    );
}

#[test]
fn same_seed_same_bytes_and_noise_depends_on_the_frame_seed() {
    let fx = Effects {
        noise_sigma: 6.0,
        blur_sigma: 0.8,
        brightness: 0.9,
        ..Effects::default()
    };
    let a = renderer("can", Background::Clutter, fx, 7).render(&view(55.0, 123.0), 42);
    let b = renderer("can", Background::Clutter, fx, 7).render(&view(55.0, 123.0), 42);
    assert_eq!(a.image.as_raw(), b.image.as_raw());
    assert_eq!(a.mask.as_raw(), b.mask.as_raw());
    let c = renderer("can", Background::Clutter, fx, 7).render(&view(55.0, 123.0), 43);
    assert_ne!(a.image.as_raw(), c.image.as_raw());
    assert_eq!(
        a.mask.as_raw(),
        c.mask.as_raw(),
        "noise never touches the mask"
    );
    // The clutter layout follows the scene seed.
    let d = renderer("can", Background::Clutter, fx, 8).render(&view(55.0, 123.0), 42);
    assert_ne!(a.image.as_raw(), d.image.as_raw());
}

#[test]
fn parallel_rendering_matches_sequential() {
    use rayon::prelude::*;
    let r = renderer(
        "fruitbox",
        Background::B,
        Effects {
            noise_sigma: 3.0,
            ..Effects::default()
        },
        1,
    );
    let views: Vec<ViewPose> = (0..8)
        .map(|i| view(45.0 + 5.0 * i as f64, 40.0 * i as f64))
        .collect();
    let seq: Vec<Vec<u8>> = views
        .iter()
        .enumerate()
        .map(|(i, v)| r.render(v, i as u64).image.into_raw())
        .collect();
    let par: Vec<Vec<u8>> = views
        .par_iter()
        .enumerate()
        .map(|(i, v)| r.render(v, i as u64).image.into_raw())
        .collect();
    assert_eq!(seq, par);
}

#[test]
fn render_into_reuses_buffers() {
    let r = renderer("fruitbox", Background::A, Effects::default(), 0);
    let mut out = r.render(&view(60.0, 0.0), 0);
    let (pi, pm) = (out.image.as_ptr(), out.mask.as_ptr());
    for phi in [10.0, 20.0, 30.0] {
        r.render_into(&view(60.0, phi), 0, &mut out);
        assert_eq!(out.image.as_ptr(), pi);
        assert_eq!(out.mask.as_ptr(), pm);
        assert_eq!(out.truth.phi_deg, phi);
    }
    // Re-rendering an earlier view into a used buffer gives the same bytes.
    let fresh = r.render(&view(60.0, 20.0), 0);
    r.render_into(&view(60.0, 20.0), 0, &mut out);
    assert_eq!(fresh.image.as_raw(), out.image.as_raw());
}

#[test]
fn effects_do_what_they_say() {
    let v = view(60.0, 30.0);
    let base = renderer("fruitbox", Background::C, Effects::default(), 0).render(&v, 0);
    let mean = |img: &image::RgbImage| {
        img.as_raw().iter().map(|&b| b as f64).sum::<f64>() / img.as_raw().len() as f64
    };
    let dark = renderer(
        "fruitbox",
        Background::C,
        Effects {
            brightness: 0.5,
            ..Effects::default()
        },
        0,
    )
    .render(&v, 0);
    assert!((mean(&dark.image) - 0.5 * mean(&base.image)).abs() < 1.0);
    let noisy = renderer(
        "fruitbox",
        Background::C,
        Effects {
            noise_sigma: 8.0,
            ..Effects::default()
        },
        0,
    )
    .render(&v, 5);
    let diffs: Vec<f64> = noisy
        .image
        .as_raw()
        .iter()
        .zip(base.image.as_raw())
        .map(|(&a, &b)| a as f64 - b as f64)
        .collect();
    let m = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let sd = (diffs.iter().map(|d| (d - m).powi(2)).sum::<f64>() / diffs.len() as f64).sqrt();
    assert!(
        m.abs() < 0.3 && (sd - 8.0).abs() < 0.5,
        "noise mean {m} sd {sd}"
    );
    // Blur lowers the pixel-to-pixel differences.
    let blurred = renderer(
        "fruitbox",
        Background::C,
        Effects {
            blur_sigma: 2.0,
            ..Effects::default()
        },
        0,
    )
    .render(&v, 0);
    let grad = |img: &image::RgbImage| {
        img.as_raw()
            .windows(4)
            .map(|w| (w[3] as f64 - w[0] as f64).abs())
            .sum::<f64>()
    };
    assert!(grad(&blurred.image) < 0.6 * grad(&base.image));
    assert_eq!(blurred.mask.as_raw(), base.mask.as_raw());
}

/// Mean absolute difference between neighbours one pixel apart along x
/// and along y, over the whole image.
fn gradients(img: &image::RgbImage) -> (f64, f64) {
    let (w, h) = img.dimensions();
    let (mut gx, mut gy) = (0.0f64, 0.0f64);
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let p = img.get_pixel(x, y).0;
            let (px, py) = (img.get_pixel(x + 1, y).0, img.get_pixel(x, y + 1).0);
            for c in 0..3 {
                gx += (px[c] as f64 - p[c] as f64).abs();
                gy += (py[c] as f64 - p[c] as f64).abs();
            }
        }
    }
    (gx, gy)
}

#[test]
fn motion_blur_smears_along_its_direction_only() {
    let v = view(60.0, 30.0);
    let render = |fx| renderer("fruitbox", Background::C, fx, 0).render(&v, 0);
    let base = render(Effects::default());
    let streak = |deg| {
        render(Effects {
            motion_blur_px: 8.0,
            motion_blur_deg: deg,
            ..Effects::default()
        })
    };
    let (bx, by) = gradients(&base.image);
    let (hx, hy) = gradients(&streak(0.0).image);
    let (vx, vy) = gradients(&streak(90.0).image);
    // A horizontal streak smooths along x far more than along y (it
    // smooths y's differences too, averaging each row's texture), a
    // vertical one the other way round.
    let (hx, hy, vx, vy) = (hx / bx, hy / by, vx / bx, vy / by);
    eprintln!("kept of the gradient: horizontal x {hx:.2} y {hy:.2}, vertical x {vx:.2} y {vy:.2}");
    assert!(hx < 0.35 && hx < 0.6 * hy, "{hx} {hy}");
    assert!(vy < 0.35 && vy < 0.6 * vx, "{vy} {vx}");
    assert_eq!(streak(45.0).mask.as_raw(), base.mask.as_raw());
}

#[test]
fn a_camera_moving_during_the_exposure_smears_along_its_motion() {
    let r = renderer("fruitbox", Background::A, Effects::default(), 0);
    let k = r.config().intrinsics;
    let v = view(30.0, 30.0);
    let base = r.render(&v, 3);
    let moving = |path: &dyn Fn(f64) -> ViewPose| {
        let mut out = acch_capture::Rendered::default();
        r.render_moving_into(path, 3, &mut out);
        out
    };
    // A still camera: one view, the same bytes as a plain render.
    assert_eq!(exposure_samples(&v, &v, &k), 1);
    let still = moving(&|_| v);
    assert_eq!(still.image.as_raw(), base.image.as_raw());
    // Turning about the object's vertical pans the image along x (and
    // turns it a little about its centre), going up the hemisphere moves
    // it along y; the frame's own view keeps mask and truth.
    let azimuth = |deg: f64| move |s: f64| view(30.0, 30.0 + deg * s);
    let elevation = |deg: f64| move |s: f64| view(30.0 + deg * s, 30.0);
    let (bx, by) = gradients(&base.image);
    let kept = |img: &image::RgbImage| {
        let (gx, gy) = gradients(img);
        (gx / bx, gy / by)
    };
    let across = moving(&azimuth(2.0));
    let up = moving(&elevation(2.0));
    let (ax, ay) = kept(&across.image);
    let (ux, uy) = kept(&up.image);
    let (lx, ly) = kept(&moving(&azimuth(4.0)).image);
    eprintln!(
        "kept of the gradient: azimuth 2° x {ax:.2} y {ay:.2}, 4° x {lx:.2} y {ly:.2}; elevation 2° x {ux:.2} y {uy:.2}"
    );
    assert!(ax < 0.8 && uy < 0.8, "azimuth x {ax}, elevation y {uy}");
    // Each smooths its own direction more than the other does (the
    // table's perspective stripes lose some of both along any motion).
    assert!(uy < 0.8 * ux, "elevation: x {ux} y {uy}");
    assert!(
        ax / ay < 0.8 * (ux / uy),
        "azimuth x/y {} vs elevation {}",
        ax / ay,
        ux / uy
    );
    assert!(lx < 0.9 * ax, "a longer turn smears more: {lx} vs {ax}");
    for m in [&across, &up] {
        assert_eq!(m.mask.as_raw(), base.mask.as_raw());
        assert_eq!(m.truth, base.truth);
    }
    // About a pixel between samples: 2° is 0.035 rad, times the focal
    // length and the half diagonal (500 + 400 px), 31 px.
    let n = exposure_samples(&view(60.0, 29.0), &view(60.0, 31.0), &k);
    assert!((31..=33).contains(&n) && n % 2 == 1, "{n} samples");
    let far = exposure_samples(&view(60.0, 0.0), &view(60.0, 90.0), &k);
    assert_eq!(far, MAX_EXPOSURE_SAMPLES);
}

#[test]
fn a_trajectory_frame_is_exposed_around_its_own_view() {
    let t = Trajectory::new(5, 30.0, DEFAULT_DISTANCE).expect("trajectory");
    let during = t.during(12, 1.0 / 30.0);
    assert_eq!(during(0.0), t.frame(12).view);
    // The shutter open for a whole frame period reaches half way to the
    // neighbouring frames.
    let (before, after) = (t.view_at(11.5 / 30.0), t.view_at(12.5 / 30.0));
    assert_eq!(during(-0.5), before);
    assert_eq!(during(0.5), after);
}

#[test]
fn another_object_in_front_hides_the_target_within_the_bars_place() {
    let object = Arc::new(Object::builtin("fruitbox").expect("builtin object"));
    let render = |share: f32, occluder: Option<&str>| {
        let mut config = SceneConfig::new(object.clone(), Background::A);
        config.occlusion = share;
        config.occluder = occluder.map(|name| Arc::new(Object::builtin(name).expect("occluder")));
        Renderer::new(config, 4).render(&view(55.0, 120.0), 9)
    };
    let clean = render(0.0, None);
    let bar = render(0.3, None);
    let held = render(0.3, Some("generated-999001"));
    let (w, _) = clean.image.dimensions();
    let pixel = |img: &image::RgbImage, i: usize| img.as_raw()[3 * i..3 * i + 3].to_vec();
    let (mut in_bar, mut hidden, mut colours) = (0, 0, std::collections::HashSet::new());
    for i in 0..clean.mask.as_raw().len() {
        let (x, y) = ((i % w as usize) as u32, (i / w as usize) as u32);
        let under_bar = pixel(&bar.image, i) != pixel(&clean.image, i);
        if under_bar {
            in_bar += 1;
            if pixel(&held.image, i) != pixel(&clean.image, i) {
                colours.insert(pixel(&held.image, i));
            }
        } else {
            // Outside the bar's place nothing changes.
            assert_eq!(pixel(&held.image, i), pixel(&clean.image, i), "({x}, {y})");
            assert_eq!(held.mask.as_raw()[i], clean.mask.as_raw()[i], "({x}, {y})");
        }
        if clean.mask.as_raw()[i] != 0 && held.mask.as_raw()[i] == 0 {
            hidden += 1;
        }
    }
    let (visible, bar_visible) = (count(&clean.mask), count(&bar.mask));
    let bar_hidden = visible - bar_visible;
    eprintln!(
        "target {visible} px; the bar hides {bar_hidden}, the object {hidden} in {} colours; bar place {in_bar} px",
        colours.len()
    );
    assert!(bar_hidden > visible / 5, "{bar_hidden} of {visible}");
    assert!(
        hidden <= bar_hidden && hidden > bar_hidden / 2,
        "{hidden} of {bar_hidden}"
    );
    assert_eq!(count(&held.mask), visible - hidden);
    // Its own inks and shading, not one grey.
    assert!(colours.len() > 50, "{} colours", colours.len());
}

#[test]
fn shot_noise_is_relatively_larger_in_dark_colours_and_follows_the_well() {
    let v = view(60.0, 30.0);
    let render = |full_well_e, seed| {
        renderer(
            "fruitbox",
            Background::C,
            Effects {
                full_well_e,
                read_noise_e: 3.0,
                ..Effects::default()
            },
            0,
        )
        .render(&v, seed)
    };
    let base = renderer("fruitbox", Background::C, Effects::default(), 0).render(&v, 0);
    // The noise's sd in grey levels over pixels of dark (< 60) and light
    // (> 180) bytes.
    let sd = |img: &image::RgbImage, dark: bool| {
        let d: Vec<f64> = img
            .as_raw()
            .iter()
            .zip(base.image.as_raw())
            .filter(|&(_, &b)| if dark { b < 60 } else { b > 180 && b < 250 })
            .map(|(&a, &b)| a as f64 - b as f64)
            .collect();
        assert!(d.len() > 1000, "{} pixels", d.len());
        let m = d.iter().sum::<f64>() / d.len() as f64;
        (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
    };
    let (low, high) = (render(400.0, 5), render(4000.0, 5));
    // In linear light the sd is sqrt(e) over e of the signal: relatively
    // larger in the dark, and the sRGB curve's steepness there shows it
    // in bytes too.
    let (dark, light) = (sd(&low.image, true), sd(&low.image, false));
    assert!(dark > light, "dark {dark} light {light}");
    // Ten times the well: about sqrt(10) less noise.
    let ratio = sd(&low.image, false) / sd(&high.image, false);
    assert!((2.4..4.0).contains(&ratio), "{ratio}");
    assert_ne!(render(400.0, 6).image.as_raw(), low.image.as_raw());
    assert_eq!(render(400.0, 5).image.as_raw(), low.image.as_raw());
    assert_eq!(low.mask.as_raw(), base.mask.as_raw());
}

#[test]
fn textured_backgrounds_have_their_colours() {
    let mean_bg = |bg: Background| {
        let out = renderer("tricolor", bg, Effects::default(), 0).render(&view(70.0, 0.0), 0);
        let (mut s, mut n) = ([0.0f64; 3], 0.0);
        for (x, y, m) in out.mask.enumerate_pixels() {
            if m[0] == 0 {
                let p = out.image.get_pixel(x, y).0;
                for c in 0..3 {
                    s[c] += p[c] as f64;
                }
                n += 1.0;
            }
        }
        s.map(|v| v / n)
    };
    let a = mean_bg(Background::A);
    assert!(
        a[0] > a[2] + 60.0 && a[1] > a[2] + 30.0,
        "A is yellowish wood: {a:?}"
    );
    let b = mean_bg(Background::B);
    assert!(b[2] > b[0] + 60.0 && b[2] > b[1] + 40.0, "B is blue: {b:?}");
    let c = mean_bg(Background::C);
    assert!(
        c[1] > c[0] + 40.0 && c[1] > c[2] + 40.0,
        "C is green: {c:?}"
    );
    let p = mean_bg(Background::Plain([10, 200, 30]));
    assert_eq!(p, [10.0, 200.0, 30.0]);
}

#[test]
fn clutter_has_distractors_that_never_hide_the_target_centre() {
    let k = Intrinsics::default();
    for seed in 0..6 {
        for bg in [Background::Clutter, Background::ClutterSimilar] {
            let r = renderer("fruitbox", bg, Effects::default(), seed);
            assert!(
                (3..=6).contains(&r.distractor_count()),
                "{} distractors",
                r.distractor_count()
            );
            let plain = renderer("fruitbox", Background::default(), Effects::default(), seed);
            let views = acch_capture::ViewSpec::Random { n: 6 }.views(DEFAULT_DISTANCE, seed);
            for (i, v) in views.iter().enumerate() {
                let out = r.render(v, i as u64);
                let centre = out.mask.get_pixel(k.cx.round() as u32, k.cy.round() as u32)[0];
                assert_eq!(centre, 255, "seed {seed} {bg} view {v:?}: centre hidden");
                // Distractors can only remove target pixels, never add any.
                let alone = plain.render(v, i as u64).mask;
                assert!(
                    out.mask
                        .pixels()
                        .zip(alone.pixels())
                        .all(|(a, b)| a[0] <= b[0])
                );
            }
        }
    }
    // Distractors are visible: clutter changes background pixels.
    let v = view(60.0, 0.0);
    let clutter = renderer("can", Background::Clutter, Effects::default(), 3).render(&v, 0);
    let similar = renderer("can", Background::ClutterSimilar, Effects::default(), 3).render(&v, 0);
    assert_ne!(clutter.image.as_raw(), similar.image.as_raw());
}

#[test]
fn clutter_similar_distractors_use_the_target_colours() {
    // The tricolor object is pure red, green and blue: the similar
    // distractors' saturated pixels must have those chromaticities.
    let chroma = |p: [u8; 3]| {
        let s = p.iter().map(|&c| c as f64).sum::<f64>().max(1.0);
        [p[0] as f64 / s, p[1] as f64 / s, p[2] as f64 / s]
    };
    let targets = [[210, 30, 30], [30, 170, 50], [30, 60, 200]].map(chroma);
    for seed in [11, 12] {
        let out = renderer(
            "tricolor",
            Background::ClutterSimilar,
            Effects::default(),
            seed,
        )
        .render(&view(90.0, 0.0), 0);
        let (mut saturated, mut similar) = (0, 0);
        for (x, y, p) in out.image.enumerate_pixels() {
            let (mx, mn) = (
                *p.0.iter().max().unwrap() as i32,
                *p.0.iter().min().unwrap() as i32,
            );
            if out.mask.get_pixel(x, y)[0] == 0 && mx - mn > 80 {
                saturated += 1;
                let c = chroma(p.0);
                let near = targets
                    .iter()
                    .any(|t| (0..3).map(|i| (t[i] - c[i]).powi(2)).sum::<f64>().sqrt() < 0.12);
                similar += near as usize;
            }
        }
        assert!(
            saturated > 1000,
            "seed {seed}: distractors visible ({saturated} saturated pixels)"
        );
        assert!(
            similar as f64 > 0.9 * saturated as f64,
            "seed {seed}: {similar} of {saturated} similar"
        );
    }
}

#[test]
fn view_pose_validation() {
    assert!(
        matches!(ViewPose::new(95.0, 0.0, 5.0), Err(CaptureError::InvalidTheta { value }) if value == 95.0)
    );
    assert!(matches!(
        ViewPose::new(-1.0, 0.0, 5.0),
        Err(CaptureError::InvalidTheta { .. })
    ));
    assert!(matches!(
        ViewPose::new(f64::NAN, 0.0, 5.0),
        Err(CaptureError::InvalidTheta { .. })
    ));
    assert!(matches!(
        ViewPose::new(45.0, f64::INFINITY, 5.0),
        Err(CaptureError::InvalidPhi { .. })
    ));
    assert!(matches!(
        ViewPose::new(45.0, 0.0, -2.0),
        Err(CaptureError::InvalidDistance { .. })
    ));
    assert!(matches!(
        ViewPose::new(45.0, 0.0, f64::NAN),
        Err(CaptureError::InvalidDistance { .. })
    ));
    let msg = ViewPose::new(95.0, 0.0, 5.0).unwrap_err().to_string();
    assert!(msg.contains("95") && msg.contains("[0, 90]"), "{msg}");
    assert_eq!(ViewPose::new(45.0, -10.0, 5.0).unwrap().phi_deg, 350.0);
    assert_eq!(ViewPose::new(45.0, 720.0, 5.0).unwrap().phi_deg, 0.0);
    // A hand-built invalid pose renders without panicking.
    let r = renderer("can", Background::A, Effects::default(), 0);
    for bad in [
        ViewPose {
            theta_deg: 120.0,
            phi_deg: -30.0,
            distance: 5.0,
            roll_deg: 0.0,
        },
        ViewPose {
            theta_deg: 45.0,
            phi_deg: 0.0,
            distance: 0.0,
            roll_deg: 0.0,
        },
        ViewPose {
            theta_deg: f64::NAN,
            phi_deg: 0.0,
            distance: 5.0,
            roll_deg: 0.0,
        },
        ViewPose {
            theta_deg: 45.0,
            phi_deg: 0.0,
            distance: 0.5,
            roll_deg: 0.0,
        },
    ] {
        let _ = r.render(&bad, 0);
    }
}

#[test]
fn builtin_objects_are_normalised_and_unknown_names_are_errors() {
    for name in acch_capture::BUILTIN_OBJECTS {
        let o = Object::builtin(name).unwrap();
        assert_eq!(o.name(), *name);
        assert!(
            (o.bounding_radius() - 1.0).abs() < 1e-5,
            "{name}: {}",
            o.bounding_radius()
        );
        assert!(
            o.table_z() < -0.3 && o.table_z() > -1.0,
            "{name}: {}",
            o.table_z()
        );
    }
    assert_eq!(Object::builtin("fruitbox").unwrap().texture_count(), 6);
    let err = Object::builtin("banana").unwrap_err().to_string();
    assert!(
        err.contains("banana") && err.contains("fruitbox") && err.contains("tricolor"),
        "{err}"
    );
}

#[test]
fn every_fruitbox_view_is_distinct_and_centred() {
    // Views in the training grid differ from each other (no symmetric twins)
    // and the object always sits around the image centre.
    let r = renderer("fruitbox", Background::default(), Effects::default(), 0);
    let views = acch_capture::ViewSpec::training_grid().views(DEFAULT_DISTANCE, 0);
    let mut seen = std::collections::HashMap::new();
    for (i, v) in views.iter().enumerate() {
        let out = r.render(v, 0);
        let b = out.truth.bbox.unwrap();
        let (cx, cy) = (
            b.x as f64 + b.width as f64 / 2.0,
            b.y as f64 + b.height as f64 / 2.0,
        );
        assert!(
            (cx - 319.5).abs() < 60.0 && (cy - 239.5).abs() < 60.0,
            "view {i} bbox {b:?}"
        );
        let mut h = std::collections::hash_map::DefaultHasher::new();
        std::hash::Hash::hash(out.image.as_raw(), &mut h);
        if let Some(j) = seen.insert(std::hash::Hasher::finish(&h), i) {
            panic!("views {j} and {i} are identical");
        }
    }
}

#[test]
fn renderer_and_outputs_can_cross_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<Renderer>();
    assert_send_sync::<acch_capture::Rendered>();
    assert_send_sync::<Object>();
    assert_send_sync::<acch_capture::Trajectory>();
}

#[test]
fn held_out_tables_are_other_textures_of_the_same_look() {
    use acch_capture::TextureSet;
    let object = std::sync::Arc::new(acch_capture::Object::builtin("fruitbox").unwrap());
    let view = acch_capture::ViewPose::new(60.0, 30.0, acch_capture::DEFAULT_DISTANCE).unwrap();
    for background in [
        acch_capture::Background::A,
        acch_capture::Background::B,
        acch_capture::Background::C,
        acch_capture::Background::Clutter,
    ] {
        let render = |set| {
            let config =
                acch_capture::SceneConfig::new(object.clone(), background).with_textures(set);
            acch_capture::Renderer::new(config, 5).render(&view, 1)
        };
        let (train, held) = (render(TextureSet::Training), render(TextureSet::HeldOut));
        // The table, where no object covers it (distractors, the same on
        // both, included).
        let table: Vec<usize> = (0..train.mask.as_raw().len())
            .filter(|&i| train.mask.as_raw()[i] == 0 && held.mask.as_raw()[i] == 0)
            .collect();
        let (a, b) = (train.image.as_raw(), held.image.as_raw());
        let differ = table
            .iter()
            .filter(|&&i| (0..3).any(|c| a[3 * i + c].abs_diff(b[3 * i + c]) > 2))
            .count();
        assert!(
            differ * 2 > table.len(),
            "{background}: only {differ} of {} table pixels differ",
            table.len()
        );
        let mean = |img: &[u8]| {
            let mut m = [0f64; 3];
            for &i in &table {
                for c in 0..3 {
                    m[c] += img[3 * i + c] as f64 / table.len() as f64;
                }
            }
            m
        };
        let (ma, mb) = (mean(a), mean(b));
        for c in 0..3 {
            assert!(
                (ma[c] - mb[c]).abs() < 0.15 * ma[c].max(20.0),
                "{background}: the look changed: {ma:?} against {mb:?}"
            );
        }
        // The object is rendered the same on both.
        assert_eq!(train.mask, held.mask);
    }
    assert_eq!(
        "held-out".parse::<TextureSet>().unwrap(),
        TextureSet::HeldOut
    );
    assert!("lunar".parse::<TextureSet>().is_err());
}

#[test]
fn roll_90_turns_the_render_counter_clockwise() {
    let r = renderer("fruitbox", Background::default(), Effects::default(), 0);
    let v = view(90.0, 0.0);
    let a = r.render(&v, 0);
    let b = r.render(&v.with_roll(90.0).unwrap(), 0);
    assert_eq!(b.truth.roll_deg, 90.0);
    assert_eq!(a.truth.roll_deg, 0.0);
    let (ba, bb) = (a.truth.bbox.unwrap(), b.truth.bbox.unwrap());
    // The 24 x 15 cm top face is far from square, so the swap shows.
    assert!(ba.width.abs_diff(ba.height) > 20, "{ba:?}");
    assert!(
        ba.width.abs_diff(bb.height) <= 1 && ba.height.abs_diff(bb.width) <= 1,
        "roll 0 {ba:?}, roll 90 {bb:?}"
    );
    // The whole mask turns counter-clockwise, and so does the texture.
    let (ccw, cw) = (
        rotated_iou(&a.mask, &b.mask, false),
        rotated_iou(&a.mask, &b.mask, true),
    );
    assert!(ccw > 0.97, "IoU counter-clockwise {ccw}, clockwise {cw}");
    let diff = |clockwise: bool| {
        let (mut sum, mut n) = (0.0, 0.0);
        for (x, y, m) in b.mask.enumerate_pixels() {
            let Some((sx, sy)) = rotated_source(x, y, clockwise) else {
                continue;
            };
            if m[0] != 0 && a.mask.get_pixel(sx, sy)[0] != 0 {
                let (p, q) = (b.image.get_pixel(x, y).0, a.image.get_pixel(sx, sy).0);
                sum += (0..3)
                    .map(|i| (p[i] as f64 - q[i] as f64).abs())
                    .sum::<f64>();
                n += 3.0;
            }
        }
        sum / n
    };
    let (right, wrong) = (diff(false), diff(true));
    assert!(
        right < 4.0 && wrong > 4.0 * right,
        "mean abs diff: counter-clockwise {right}, clockwise {wrong}"
    );
}

#[test]
fn a_turned_light_shades_the_object_otherwise_and_moves_nothing() {
    let object = Arc::new(Object::builtin("fruitbox").expect("builtin object"));
    let lit = |deg: f32| {
        let mut config = SceneConfig::new(object.clone(), Background::default());
        config.light_azimuth_deg = deg;
        Renderer::new(config, 1).render(&view(60.0, 30.0), 0)
    };
    let (base, turned, full_turn) = (lit(0.0), lit(180.0), lit(360.0));
    assert_eq!(
        base.mask, turned.mask,
        "the light moves no pixel of the object"
    );
    let on_object = |r: &acch_capture::Rendered| -> Vec<[u8; 3]> {
        r.image
            .pixels()
            .zip(base.mask.pixels())
            .filter(|(_, m)| m[0] != 0)
            .map(|(p, _)| p.0)
            .collect()
    };
    let (a, b) = (on_object(&base), on_object(&turned));
    let changed = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert!(
        changed * 4 > a.len(),
        "{changed} of {} object pixels changed",
        a.len()
    );
    // Outside the object (the plain table, lit from straight above as
    // much as before) nothing changes.
    for ((p, q), m) in base
        .image
        .pixels()
        .zip(turned.image.pixels())
        .zip(base.mask.pixels())
    {
        if m[0] == 0 {
            assert_eq!(p, q);
        }
    }
    // A whole turn is the training light again (up to rounding).
    let same = on_object(&full_turn)
        .iter()
        .zip(&a)
        .filter(|(x, y)| x.iter().zip(y.iter()).all(|(u, v)| u.abs_diff(*v) <= 1))
        .count();
    assert_eq!(same, a.len());
}
