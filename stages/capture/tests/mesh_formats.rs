//! PLY and glTF 2.0 / GLB loading, vertex-colour shading, the PLY writer
//! and the errors of bad mesh files. Every fixture is written by the test.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use acch_capture::{
    Background, CaptureError, DEFAULT_DISTANCE, Object, Rendered, Renderer, SceneConfig, UpAxis,
    ViewPose,
};
use serde_json::json;

const DUCK: &str = "/work/shared/data/duck/duck.obj";

fn render(obj: &Object, theta: f64, phi: f64, distance: f64) -> Rendered {
    let scene = SceneConfig::new(Arc::new(obj.clone()), Background::Plain([90, 90, 90]));
    Renderer::new(scene, 0).render(&ViewPose::new(theta, phi, distance).unwrap(), 0)
}

/// Pixels of the object in a render.
fn object_pixels(out: &Rendered) -> Vec<[u8; 3]> {
    out.mask
        .enumerate_pixels()
        .filter(|(_, _, m)| m[0] != 0)
        .map(|(x, y, _)| out.image.get_pixel(x, y).0)
        .collect()
}

/// Which primary a pixel is: the one channel well above the other two.
fn primary(px: [u8; 3]) -> Option<usize> {
    let c = px.map(|v| v as f32);
    (0..3).find(|&k| (0..3).all(|j| j == k || c[j] < 0.25 * c[k]) && c[k] > 60.0)
}

// ---------------------------------------------------------------- PLY ----

/// A cube of side 2 around the origin (z up): per face the four corners,
/// counter-clockwise from outside, and its colour. +x red, +y green, +z
/// blue; -x yellow, -y cyan, -z magenta.
fn cube_faces() -> Vec<([[f64; 3]; 4], [u8; 3])> {
    let colours = [
        [255, 0, 0],
        [0, 255, 0],
        [0, 0, 255],
        [255, 255, 0],
        [0, 255, 255],
        [255, 0, 255],
    ];
    let mut faces = Vec::new();
    for (k, colour) in colours.into_iter().enumerate() {
        let (axis, s) = (k % 3, if k < 3 { 1.0 } else { -1.0 });
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let corner = |u: f64, v: f64| {
            let mut p = [0.0; 3];
            p[axis] = s;
            p[a] = u * s;
            p[b] = v;
            p
        };
        faces.push((
            [
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            ],
            colour,
        ));
    }
    faces
}

/// The cube as ASCII PLY: float x y z, uchar colours, quads.
fn ascii_cube() -> String {
    let faces = cube_faces();
    let mut s = String::from(
        "ply\nformat ascii 1.0\ncomment a vertex-coloured cube\nelement vertex 24\n\
         property float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face 6\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for (corners, c) in &faces {
        for p in corners {
            s += &format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], c[0], c[1], c[2]);
        }
    }
    for f in 0..6 {
        s += &format!("4 {} {} {} {}\n", 4 * f, 4 * f + 1, 4 * f + 2, 4 * f + 3);
    }
    s
}

/// The cube as binary little-endian PLY, the same properties as
/// [`ascii_cube`].
fn binary_le_cube() -> Vec<u8> {
    let mut out = b"ply\nformat binary_little_endian 1.0\nelement vertex 24\n\
        property float x\nproperty float y\nproperty float z\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element face 6\nproperty list uchar int vertex_indices\nend_header\n"
        .to_vec();
    for (corners, c) in &cube_faces() {
        for p in corners {
            for x in p {
                out.extend((*x as f32).to_le_bytes());
            }
            out.extend(c);
        }
    }
    for f in 0..6i32 {
        out.push(4);
        for k in 0..4 {
            out.extend((4 * f + k).to_le_bytes());
        }
    }
    out
}

/// The cube as binary big-endian PLY with other spellings: double
/// coordinates, an unused property, float `diffuse_*` colours, unsigned
/// `vertex_index` lists and an element after the faces.
fn binary_be_cube() -> Vec<u8> {
    let mut out = b"ply\nformat binary_big_endian 1.0\nelement vertex 24\n\
        property double x\nproperty double y\nproperty double z\nproperty float quality\n\
        property float diffuse_red\nproperty float diffuse_green\nproperty float diffuse_blue\n\
        element face 6\nproperty list uchar uint vertex_index\n\
        element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
        .to_vec();
    for (corners, c) in &cube_faces() {
        for p in corners {
            for x in p {
                out.extend(x.to_be_bytes());
            }
            out.extend(0.5f32.to_be_bytes());
            for &ch in c {
                out.extend((ch as f32 / 255.0).to_be_bytes());
            }
        }
    }
    for f in 0..6u32 {
        out.push(4);
        for k in 0..4 {
            out.extend((4 * f + k).to_be_bytes());
        }
    }
    out.extend(0i32.to_be_bytes());
    out.extend(1i32.to_be_bytes());
    out
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn ascii_and_binary_ply_cubes_load_and_render_alike() {
    let dir = tempfile::tempdir().unwrap();
    let files = [
        write(dir.path(), "cube_ascii.ply", ascii_cube()),
        write(dir.path(), "cube_le.ply", binary_le_cube()),
        // The extension is matched case-insensitively.
        write(dir.path(), "cube_be.PLY", binary_be_cube()),
    ];
    let mut renders = Vec::new();
    for f in &files {
        let cube = Object::load_mesh(f, UpAxis::PosZ).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(cube.triangle_count(), 12, "{}: quads fanned", f.display());
        assert!((cube.bounding_radius() - 1.0).abs() < 1e-6);
        // Side 2 m: the bounding radius is the half diagonal.
        assert!(
            (cube.radius_m() - 3f64.sqrt()).abs() < 1e-6,
            "{}",
            cube.radius_m()
        );
        renders.push(render(&cube, 35.0, 45.0, DEFAULT_DISTANCE));
    }
    assert!(object_pixels(&renders[0]).len() > 5000);
    for r in &renders[1..] {
        assert_eq!(
            r.image, renders[0].image,
            "the encodings give the same object"
        );
        assert_eq!(r.mask, renders[0].mask);
    }
}

#[test]
fn vertex_coloured_cube_shows_its_face_colours() {
    let dir = tempfile::tempdir().unwrap();
    let cube =
        Object::load_mesh(write(dir.path(), "cube.ply", ascii_cube()), UpAxis::PosZ).unwrap();
    // From (theta 35, phi 45) the +x, +y and +z faces show: red, green, blue.
    let px = object_pixels(&render(&cube, 35.0, 45.0, DEFAULT_DISTANCE));
    let mut counts = [0usize; 3];
    for &p in &px {
        if let Some(k) = primary(p) {
            counts[k] += 1;
        }
    }
    for (k, name) in ["red", "green", "blue"].iter().enumerate() {
        assert!(
            counts[k] as f64 > 0.15 * px.len() as f64,
            "{name} face: {} of {} pixels ({counts:?})",
            counts[k],
            px.len()
        );
    }
    assert!(
        counts.iter().sum::<usize>() as f64 > 0.97 * px.len() as f64,
        "hidden faces (yellow, cyan, magenta) do not show: {counts:?} of {}",
        px.len()
    );
    // The lit top is the brightest face, the colours scaled by the light.
    let brightest = |k: usize| {
        px.iter()
            .filter(|p| primary(**p) == Some(k))
            .map(|p| p[k])
            .max()
            .unwrap()
    };
    assert!(
        brightest(2) > 200 && brightest(0) < brightest(2),
        "{:?}",
        [0, 1, 2].map(brightest)
    );
}

#[test]
fn vertex_colours_interpolate_across_a_triangle() {
    // A square, red along one edge and blue along the other: its middle
    // shows both mixed (the colour is interpolated, not per face).
    let dir = tempfile::tempdir().unwrap();
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
               property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n\
               -1 -1 0 255 0 0\n1 -1 0 0 0 255\n1 1 0 0 0 255\n-1 1 0 255 0 0\n4 0 1 2 3\n";
    let square = Object::load_mesh(write(dir.path(), "grad.ply", ply), UpAxis::PosZ).unwrap();
    let px = object_pixels(&render(&square, 90.0, 270.0, 4.0));
    let red = px.iter().filter(|p| primary(**p) == Some(0)).count();
    let blue = px.iter().filter(|p| primary(**p) == Some(2)).count();
    let mixed = px
        .iter()
        .filter(|p| p[0] > 60 && p[2] > 60 && p[1] < 10)
        .count();
    let n = px.len() as f64;
    assert!(
        red as f64 > 0.1 * n && blue as f64 > 0.1 * n && mixed as f64 > 0.3 * n,
        "red {red}, blue {blue}, mixed {mixed} of {n}"
    );
}

/// A 4 x 4 PNG: the top half red, the bottom half green.
fn red_over_green() -> image::RgbImage {
    image::RgbImage::from_fn(4, 4, |_, y| {
        if y < 2 {
            image::Rgb([220, 20, 20])
        } else {
            image::Rgb([20, 200, 20])
        }
    })
}

/// Colour above and below the image centre in a top view with world +y up
/// in the image (theta 90, phi 270).
fn top_and_bottom(obj: &Object) -> ([u8; 3], [u8; 3]) {
    let out = render(obj, 90.0, 270.0, 4.0);
    let (cx, cy) = (out.image.width() / 2, out.image.height() / 2);
    (
        out.image.get_pixel(cx, cy - 40).0,
        out.image.get_pixel(cx, cy + 40).0,
    )
}

fn is_red(p: [u8; 3]) -> bool {
    primary(p) == Some(0)
}

fn is_green(p: [u8; 3]) -> bool {
    primary(p) == Some(1)
}

#[test]
fn textured_ply_with_per_vertex_or_per_face_texture_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("textures");
    std::fs::create_dir(&sub).unwrap();
    red_over_green().save(sub.join("rg.png")).unwrap();
    // PLY's v = 0 is the bottom of the image: the +y edge (v = 1) is red.
    let per_vertex = "ply\nformat ascii 1.0\ncomment TextureFile textures/rg.png\n\
        element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        property float texture_u\nproperty float texture_v\n\
        element face 2\nproperty list uchar int vertex_indices\nend_header\n\
        -1 -1 0 0 0\n1 -1 0 1 0\n1 1 0 1 1\n-1 1 0 0 1\n3 0 1 2\n3 0 2 3\n";
    // MeshLab's way: texture coordinates per face corner, and vertex
    // colours too, which the texture overrides.
    let per_face = "ply\nformat ascii 1.0\ncomment TextureFile textures/rg.png\n\
        element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element face 2\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\n\
        end_header\n\
        -1 -1 0 0 0 255\n1 -1 0 0 0 255\n1 1 0 0 0 255\n-1 1 0 0 0 255\n\
        3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 6 0 0 1 1 0 1\n";
    for (name, text) in [("pv.ply", per_vertex), ("pf.ply", per_face)] {
        let obj = Object::load_mesh(write(dir.path(), name, text), UpAxis::PosZ)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(obj.texture_sizes(), vec![(4, 4)], "{name}");
        let (top, bottom) = top_and_bottom(&obj);
        assert!(
            is_red(top) && is_green(bottom),
            "{name}: top {top:?}, bottom {bottom:?}"
        );
    }
}

// --------------------------------------------------------------- glTF ----

/// Binary buffer contents with their buffer views (4-byte aligned).
#[derive(Default)]
struct Bin {
    data: Vec<u8>,
    views: Vec<serde_json::Value>,
}

impl Bin {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()
        }));
        self.data.extend_from_slice(bytes);
        self.views.len() - 1
    }
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A GLB file: header, JSON chunk, BIN chunk.
fn glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + j.len() + 8 + b.len()) as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(&b);
    out
}

fn png_bytes(img: &image::RgbImage) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// A unit square in glTF's x-y plane (a wall, with glTF's +y up), placed
/// flat on the ground by its node's rotation (-90 degrees about x) under
/// a scaled parent, textured by an embedded PNG (`png`) times
/// `factor`; `material: false` leaves it without any colour.
fn square_glb(png: Option<&[u8]>, factor: Option<[f32; 4]>, material: bool) -> Vec<u8> {
    square_glb_with(png, factor, material, false)
}

/// [`square_glb`], with COLOR_0 (white and grey corners) if `colours`.
fn square_glb_with(
    png: Option<&[u8]>,
    factor: Option<[f32; 4]>,
    material: bool,
    colours: bool,
) -> Vec<u8> {
    let mut bin = Bin::default();
    let pos = bin.view(&f32_bytes(&[
        -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0,
    ]));
    // glTF's v = 0 is the top of the image: the +y edge is red.
    let uv = bin.view(&f32_bytes(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
    let idx: Vec<u8> = [0u16, 1, 2, 0, 2, 3]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let idx = bin.view(&idx);
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"children": [1], "scale": [3.0, 3.0, 3.0]},
            {"mesh": 0, "rotation": [-std::f64::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2]}
        ],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "TEXCOORD_0": 1},
            "indices": 2
        }]}],
        "accessors": [
            {"bufferView": pos, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": uv, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": idx, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    if colours {
        let c = bin.view(&f32_bytes(&[
            1.0, 1.0, 1.0, 0.2, 0.2, 0.2, 1.0, 1.0, 1.0, 0.2, 0.2, 0.2,
        ]));
        doc["accessors"]
            .as_array_mut()
            .unwrap()
            .push(json!({"bufferView": c, "componentType": 5126, "count": 4, "type": "VEC3"}));
        doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = json!(3);
    }
    if material {
        let mut pbr = json!({});
        if let Some(png) = png {
            let img = bin.view(png);
            doc["images"] = json!([{"bufferView": img, "mimeType": "image/png"}]);
            doc["textures"] = json!([{"source": 0}]);
            pbr["baseColorTexture"] = json!({"index": 0});
        }
        if let Some(f) = factor {
            pbr["baseColorFactor"] = json!(f);
        }
        doc["materials"] = json!([{"pbrMetallicRoughness": pbr}]);
        doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    }
    doc["bufferViews"] = json!(bin.views);
    doc["buffers"] = json!([{"byteLength": bin.data.len()}]);
    glb(&doc, &bin.data)
}

#[test]
fn glb_with_an_embedded_png_texture_renders_it_where_its_nodes_place_it() {
    let dir = tempfile::tempdir().unwrap();
    let png = png_bytes(&red_over_green());
    let p = write(dir.path(), "square.glb", square_glb(Some(&png), None, true));
    // glTF is +y up, the default axis.
    let obj = Object::load_mesh(&p, UpAxis::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(obj.triangle_count(), 2);
    assert_eq!(obj.texture_sizes(), vec![(4, 4)]);
    // The node scale (3) is real size: metres, half-diagonal 3 sqrt(2).
    assert!(
        (obj.radius_m() - 3.0 * 2f64.sqrt()).abs() < 1e-5,
        "{}",
        obj.radius_m()
    );
    // Lying flat (the rotation applied), seen from above: a big square.
    let (top, bottom) = top_and_bottom(&obj);
    assert!(
        is_red(top) && is_green(bottom),
        "top {top:?}, bottom {bottom:?}"
    );
    assert!(object_pixels(&render(&obj, 90.0, 270.0, 4.0)).len() > 20_000);

    // baseColorFactor multiplies the texture (linear 0.5: 0.735 encoded).
    let dark = write(
        dir.path(),
        "dark.glb",
        square_glb(Some(&png), Some([0.5, 0.5, 0.5, 1.0]), true),
    );
    let dark = Object::load_mesh(&dark, UpAxis::default()).unwrap();
    let (dark_top, _) = top_and_bottom(&dark);
    let ratio = dark_top[0] as f64 / top[0] as f64;
    assert!(
        (ratio - 0.735).abs() < 0.02,
        "factor 0.5 gives {ratio}: {dark_top:?} vs {top:?}"
    );

    // A factor alone is a solid colour.
    let solid = write(
        dir.path(),
        "solid.glb",
        square_glb(None, Some([0.0, 0.0, 1.0, 1.0]), true),
    );
    let solid = Object::load_mesh(&solid, UpAxis::default()).unwrap();
    let (t, b) = top_and_bottom(&solid);
    assert!(
        primary(t) == Some(2) && primary(b) == Some(2),
        "{t:?} {b:?}"
    );
}

#[test]
fn gltf_with_vertex_colours_in_a_data_uri_buffer() {
    use base64::Engine;
    let dir = tempfile::tempdir().unwrap();
    // A square on the ground (glTF x-z plane), red at -x, blue at +x, with
    // COLOR_0 as normalised bytes (RGBA) and no material.
    let mut data = f32_bytes(&[
        -1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, -1.0, -1.0, 0.0, -1.0,
    ]);
    let colours: [[u8; 4]; 4] = [
        [255, 0, 0, 255],
        [0, 0, 255, 255],
        [0, 0, 255, 255],
        [255, 0, 0, 255],
    ];
    data.extend(colours.iter().flatten());
    data.extend([0u8, 1, 2, 0, 2, 3]);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&data)
    );
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}, "indices": 2}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5121, "normalized": true, "count": 4, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5121, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 16},
            {"buffer": 0, "byteOffset": 64, "byteLength": 6}
        ],
        "buffers": [{"byteLength": data.len(), "uri": uri}]
    });
    let p = write(
        dir.path(),
        "coloured.gltf",
        serde_json::to_vec_pretty(&doc).unwrap(),
    );
    let obj = Object::load_mesh(&p, UpAxis::PosY).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(obj.triangle_count(), 2);
    let out = render(&obj, 90.0, 270.0, 4.0);
    // The same square as a triangle strip (0 1 3 2) renders the same.
    let mut strip = doc.clone();
    strip["meshes"][0]["primitives"][0]["mode"] = json!(5);
    strip["accessors"][2]["count"] = json!(4);
    let mut strip_data = data.clone();
    strip_data[64..68].copy_from_slice(&[0, 1, 3, 2]);
    strip["buffers"][0]["uri"] = json!(format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&strip_data)
    ));
    let p = write(
        dir.path(),
        "strip.gltf",
        serde_json::to_vec(&strip).unwrap(),
    );
    let strip = Object::load_mesh(&p, UpAxis::PosY).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(strip.triangle_count(), 2);
    assert_eq!(render(&strip, 90.0, 270.0, 4.0).mask, out.mask);
    let px = object_pixels(&out);
    let red = px.iter().filter(|p| primary(**p) == Some(0)).count();
    let blue = px.iter().filter(|p| primary(**p) == Some(2)).count();
    let green = px.iter().filter(|p| p[1] > 20).count();
    assert!(
        red as f64 > 0.1 * px.len() as f64 && blue as f64 > 0.1 * px.len() as f64 && green == 0,
        "red {red}, blue {blue}, green {green} of {}",
        px.len()
    );
}

// ------------------------------------------------------------- errors ----

fn assert_names(err: &CaptureError, file: &Path, words: &[&str]) {
    let msg = err.to_string();
    assert!(
        msg.contains(&file.display().to_string()),
        "names {}: {msg}",
        file.display()
    );
    for w in words {
        assert!(msg.contains(w), "mentions '{w}': {msg}");
    }
}

#[test]
fn malformed_ply_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("garbage.ply", b"not a ply file at all\n".to_vec()),
        (
            "bad_count.ply",
            b"ply\nformat ascii 1.0\nelement vertex many\nend_header\n".to_vec(),
        ),
        // A count the file cannot hold is refused before anything is
        // reserved for it.
        (
            "huge.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n\
              property float x\nproperty float y\nproperty float z\nend_header\n"
                .to_vec(),
        ),
        ("truncated.ply", binary_le_cube()[..400].to_vec()),
        (
            "bad_index.ply",
            ascii_cube()
                .replace("4 20 21 22 23", "4 20 21 22 99")
                .into_bytes(),
        ),
        (
            "no_xyz.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nelement face 0\n\
              property list uchar int vertex_indices\nend_header\n1\n"
                .to_vec(),
        ),
    ];
    for (name, bytes) in cases {
        let p = write(dir.path(), name, bytes);
        let err = Object::load_mesh(&p, UpAxis::PosZ).unwrap_err();
        assert!(matches!(err, CaptureError::Ply { .. }), "{name}: {err:?}");
        assert_names(&err, &p, &["PLY"]);
    }
}

#[test]
fn ply_without_colour_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let plain = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                 end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let p = write(dir.path(), "plain.ply", plain);
    let err = Object::load_mesh(&p, UpAxis::PosZ).unwrap_err();
    assert!(matches!(err, CaptureError::NoColour { .. }), "{err:?}");
    assert_names(
        &err,
        &p,
        &["has no colour: neither vertex colours nor a texture"],
    );

    // A texture without texture coordinates does not colour anything.
    let named = plain.replace(
        "format ascii 1.0\n",
        "format ascii 1.0\ncomment TextureFile t.png\n",
    );
    let p = write(dir.path(), "no_uv.ply", named);
    let err = Object::load_mesh(&p, UpAxis::PosZ).unwrap_err();
    assert_names(
        &err,
        &p,
        &["has no colour", "t.png", "no texture coordinates"],
    );
}

#[test]
fn missing_texture_files_are_errors_naming_both_files() {
    let dir = tempfile::tempdir().unwrap();
    let ply = "ply\nformat ascii 1.0\ncomment TextureFile gone.png\nelement vertex 3\n\
               property float x\nproperty float y\nproperty float z\nproperty float s\n\
               property float t\nelement face 1\nproperty list uchar int vertex_indices\n\
               end_header\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n";
    let p = write(dir.path(), "tex.ply", ply);
    let err = Object::load_mesh(&p, UpAxis::PosZ).unwrap_err();
    assert!(matches!(err, CaptureError::MeshTexture { .. }), "{err:?}");
    let gone = dir.path().join("gone.png");
    assert_names(&err, &p, &[&gone.display().to_string()]);

    // The same for a glTF image outside the file.
    let doc = json!({
        "asset": {"version": "2.0"},
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "missing%20image.png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 24}
        ],
        "buffers": [{"byteLength": 60, "uri": "tri.bin"}]
    });
    let mut bin = f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend(f32_bytes(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]));
    write(dir.path(), "tri.bin", bin);
    let p = write(dir.path(), "tri.gltf", serde_json::to_vec(&doc).unwrap());
    let err = Object::load_mesh(&p, UpAxis::PosY).unwrap_err();
    assert!(matches!(err, CaptureError::MeshTexture { .. }), "{err:?}");
    // The URI's %20 is decoded to the file's real name.
    let missing = dir.path().join("missing image.png");
    assert_names(&err, &p, &[&missing.display().to_string()]);
}

#[test]
fn glb_without_colour_or_broken_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "bare.glb", square_glb(None, None, false));
    let err = Object::load_mesh(&p, UpAxis::default()).unwrap_err();
    assert!(matches!(err, CaptureError::NoColour { .. }), "{err:?}");
    assert_names(&err, &p, &["has no colour", "mesh 0 primitive 0"]);

    let whole = square_glb(None, Some([1.0, 0.0, 0.0, 1.0]), true);
    let p = write(dir.path(), "cut.glb", &whole[..whole.len() - 20]);
    let err = Object::load_mesh(&p, UpAxis::default()).unwrap_err();
    assert!(matches!(err, CaptureError::Gltf { .. }), "{err:?}");
    assert_names(&err, &p, &["glTF"]);

    let p = write(dir.path(), "not_json.gltf", "{\"asset\": ");
    let err = Object::load_mesh(&p, UpAxis::default()).unwrap_err();
    assert_names(&err, &p, &["bad JSON"]);

    let draco = json!({
        "asset": {"version": "2.0"},
        "extensionsRequired": ["KHR_draco_mesh_compression"]
    });
    let p = write(
        dir.path(),
        "draco.gltf",
        serde_json::to_vec(&draco).unwrap(),
    );
    let err = Object::load_mesh(&p, UpAxis::default()).unwrap_err();
    assert_names(&err, &p, &["KHR_draco_mesh_compression"]);
}

#[test]
fn unknown_mesh_extension_is_an_error_naming_the_file_and_the_formats() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "model.stl", "solid nothing\n");
    let err = Object::load_mesh(&p, UpAxis::default()).unwrap_err();
    assert!(
        matches!(err, CaptureError::UnknownMeshFormat { .. }),
        "{err:?}"
    );
    assert_names(&err, &p, &[".obj", ".ply", ".gltf", ".glb"]);
    let p = write(dir.path(), "no_extension", "");
    let err = Object::load_mesh(&p, UpAxis::default()).unwrap_err();
    assert_names(&err, &p, &[".ply"]);
}

#[test]
fn load_mesh_reads_obj_files_as_load_obj_does() {
    assert!(
        Path::new(DUCK).exists(),
        "{DUCK} is missing: this test needs the duck mesh (the workplace's shared/data/duck)"
    );
    let a = Object::load_obj_with_up(DUCK, UpAxis::PosY).unwrap();
    let b = Object::load_mesh(DUCK, UpAxis::PosY).unwrap();
    assert_eq!(a.triangle_count(), b.triangle_count());
    let (ra, rb) = (
        render(&a, 45.0, 30.0, DEFAULT_DISTANCE),
        render(&b, 45.0, 30.0, DEFAULT_DISTANCE),
    );
    assert_eq!(ra.image, rb.image);
}

// ------------------------------------------------------ PLY round trip ----

/// Writes `obj` as PLY in millimetres, reads it back and compares: the
/// same triangles, size and renders.
fn round_trip(obj: &Object, dir: &Path) -> Object {
    let unit = 0.001;
    let p = dir.join(format!("{}.ply", obj.name()));
    obj.write_ply(&p, unit).unwrap_or_else(|e| panic!("{e}"));
    let back = Object::load_mesh(&p, UpAxis::PosZ)
        .and_then(|o| o.with_mesh_unit_m(unit))
        .unwrap_or_else(|e| panic!("{}: {e}", obj.name()));
    assert_eq!(
        back.triangle_count(),
        obj.triangle_count(),
        "{}",
        obj.name()
    );
    let rel = (back.radius_m() - obj.radius_m()).abs() / obj.radius_m();
    assert!(
        rel < 1e-6,
        "{}: radius {} vs {}",
        obj.name(),
        back.radius_m(),
        obj.radius_m()
    );
    assert!((back.table_z() - obj.table_z()).abs() < 1e-5);
    for (theta, phi, d) in [
        (30.0, 20.0, DEFAULT_DISTANCE),
        (60.0, 200.0, 3.0),
        (85.0, 290.0, 4.0),
    ] {
        let (a, b) = (render(obj, theta, phi, d), render(&back, theta, phi, d));
        let (mut mask_diff, mut mask_n, mut abs_sum, mut n) = (0usize, 0usize, 0u64, 0u64);
        for ((ma, mb), (pa, pb)) in a
            .mask
            .pixels()
            .zip(b.mask.pixels())
            .zip(a.image.pixels().zip(b.image.pixels()))
        {
            mask_n += (ma[0] != 0) as usize;
            mask_diff += (ma[0] != mb[0]) as usize;
            if ma[0] != 0 || mb[0] != 0 {
                for k in 0..3 {
                    abs_sum += (pa[k] as i64 - pb[k] as i64).unsigned_abs();
                }
                n += 3;
            }
        }
        let mean = abs_sum as f64 / n as f64;
        println!(
            "{} ({theta}, {phi}): mean |diff| {mean:.4} over {} object pixels, {mask_diff} mask pixels differ",
            obj.name(),
            n / 3
        );
        assert!(
            mean < 1.0,
            "{} ({theta}, {phi}): mean |diff| {mean}",
            obj.name()
        );
        assert!(
            (mask_diff as f64) < 0.005 * mask_n as f64,
            "{} ({theta}, {phi}): {mask_diff} of {mask_n} mask pixels differ",
            obj.name()
        );
    }
    back
}

#[test]
fn builtin_objects_survive_a_ply_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["fruitbox", "can"] {
        let obj = Object::builtin(name).unwrap();
        round_trip(&obj, dir.path());
        let header = std::fs::read(dir.path().join(format!("{name}.ply"))).unwrap();
        let header = String::from_utf8_lossy(&header[..600]);
        assert!(
            header.contains(&format!("comment TextureFile {name}.png")),
            "{header}"
        );
        assert!(
            header.contains("property float texture_u")
                && header.contains("format binary_little_endian")
        );
        assert!(dir.path().join(format!("{name}.png")).exists());
    }
    // Single-colour textures are written as vertex colours, without an image.
    let tricolor = Object::builtin("tricolor").unwrap();
    round_trip(&tricolor, dir.path());
    let header = std::fs::read(dir.path().join("tricolor.ply")).unwrap();
    let header = String::from_utf8_lossy(&header[..400]);
    assert!(
        header.contains("property uchar red") && !header.contains("TextureFile"),
        "{header}"
    );
    assert!(!dir.path().join("tricolor.png").exists());
}

#[test]
fn the_duck_survives_a_ply_round_trip() {
    assert!(
        Path::new(DUCK).exists(),
        "{DUCK} is missing: this test needs the duck mesh (the workplace's shared/data/duck)"
    );
    let dir = tempfile::tempdir().unwrap();
    let duck = Object::load_obj(DUCK).unwrap();
    let back = round_trip(&duck, dir.path());
    // The duck's UVs stay inside its one texture: the atlas is that texture.
    assert_eq!(back.texture_sizes(), vec![(512, 512)]);
}

#[test]
fn a_vertex_coloured_ply_survives_a_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let cube =
        Object::load_mesh(write(dir.path(), "cube.ply", ascii_cube()), UpAxis::PosZ).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    round_trip(&cube, &out);
}

#[test]
fn a_tinted_texture_survives_a_round_trip_and_varying_tints_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let png = png_bytes(&red_over_green());
    // baseColorFactor is one tint over the texture: baked into its cell.
    let p = write(
        dir.path(),
        "tinted.glb",
        square_glb(Some(&png), Some([0.5, 0.8, 0.5, 1.0]), true),
    );
    let tinted = Object::load_mesh(&p, UpAxis::default()).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    round_trip(&tinted, &out);
    // COLOR_0 varying over a texture cannot be written to a PLY file.
    let p = write(
        dir.path(),
        "varying.glb",
        square_glb_with(Some(&png), None, true, true),
    );
    let varying = Object::load_mesh(&p, UpAxis::default()).unwrap();
    let target = dir.path().join("varying.ply");
    let err = varying.write_ply(&target, 0.001).unwrap_err();
    assert!(matches!(err, CaptureError::PlyWrite { .. }), "{err:?}");
    assert_names(&err, &target, &["varying vertex colours"]);
    // Not a usable unit either.
    assert!(tinted.write_ply(dir.path().join("x.ply"), 0.0).is_err());
}

#[test]
fn model_info_gives_bop_sizes_in_the_unit_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    // The side-2 m cube: 2000 mm wide, centred, diameter its diagonal.
    let cube =
        Object::load_mesh(write(dir.path(), "cube.ply", ascii_cube()), UpAxis::PosZ).unwrap();
    let info = cube.model_info(0.001);
    assert!(
        (info.diameter - 2000.0 * 3f64.sqrt()).abs() < 1e-3,
        "{info:?}"
    );
    for k in 0..3 {
        assert!(
            (info.min[k] + 1000.0).abs() < 1e-3 && (info.size[k] - 2000.0).abs() < 1e-3,
            "{info:?}"
        );
    }
    // The fruitbox is 24 x 15 x 30 cm; its diameter the box diagonal.
    let info = Object::builtin("fruitbox").unwrap().model_info(0.001);
    for ((size, min), expect) in info.size.iter().zip(info.min).zip([240.0, 150.0, 300.0]) {
        // Centred: the bounding box runs from -size/2 to size/2.
        assert!(
            (size - expect).abs() < 0.01 && (min + expect / 2.0).abs() < 0.01,
            "{info:?}"
        );
    }
    let diagonal = (240f64.powi(2) + 150f64.powi(2) + 300f64.powi(2)).sqrt();
    assert!((info.diameter - diagonal).abs() < 0.01, "{info:?}");
    // A written and re-read object has the same sizes.
    let fb = Object::builtin("fruitbox").unwrap();
    let p = dir.path().join("fb.ply");
    fb.write_ply(&p, 0.001).unwrap();
    let back = Object::load_mesh(&p, UpAxis::PosZ)
        .unwrap()
        .with_mesh_unit_m(0.001)
        .unwrap();
    let again = back.model_info(0.001);
    assert!(
        (again.diameter - info.diameter).abs() < 0.01,
        "{again:?} vs {info:?}"
    );
}
