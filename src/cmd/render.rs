//! `acch render`: render views of an object with ground truth into a folder
//! (images, masks, `labels.csv`, `truth.jsonl`, or a BOP dataset) and
//! optionally a contact sheet.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::common::ObjectArgs;
use acch_capture::labels::{LabelRow, write_labels};
use acch_capture::{
    Background, DEFAULT_DISTANCE, Effects, GroundTruth, Intrinsics, Rendered, Renderer,
    SceneConfig, TextureSet, ViewPose, ViewSpec, check_distance, derive_seed,
};
use acch_eval::bop;
use anyhow::{Context, Result, bail};
use clap::{ArgGroup, Args};
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder, RgbImage};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

/// Arguments of `acch render`.
#[derive(Args, Debug)]
#[command(group(ArgGroup::new("source").required(true).args(["object", "mesh"])))]
pub struct RenderArgs {
    #[command(flatten)]
    object: ObjectArgs,

    /// Views to render. grid:THETAS:PHI_STEP renders every azimuth 0, STEP,
    /// ... < 360 for each comma-separated elevation (degrees, 0-90), theta
    /// slice by theta slice; random:N draws N views with elevation uniform in
    /// [45, 90] and azimuth in [0, 360) from --seed.
    #[arg(long, value_name = "SPEC", default_value = "grid:45,50,60,70,80,90:10")]
    views: ViewSpec,

    /// Background: plain (homogeneous grey), plain:R,G,B (homogeneous colour),
    /// A (yellowish wood), B (blue fabric), C (green felt), clutter (table with
    /// 3-6 distractor objects) or clutter-similar (distractors in the object's
    /// own colours).
    #[arg(long, value_name = "NAME", default_value = "plain")]
    background: Background,

    /// Which instance of the table texture backgrounds A, B, C and clutter
    /// show: training (what the default confidence network is trained on)
    /// or held-out (what the evaluations and the simulated camera show).
    #[arg(long, value_name = "SET", default_value = "training")]
    textures: TextureSet,

    /// Seed for random views, the clutter layout and the per-view noise.
    /// The same command line always writes the same bytes.
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,

    /// Output directory (created if missing; existing files are overwritten).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,

    /// Also write all views tiled as thumbnails (18 per row) into this PNG.
    #[arg(long, value_name = "FILE.png")]
    contact_sheet: Option<PathBuf>,

    /// Camera distance from the object centre, in object bounding radii.
    #[arg(long, value_name = "R", default_value_t = DEFAULT_DISTANCE, allow_negative_numbers = true)]
    distance: f64,

    /// Sensor noise: standard deviation of additive per-channel noise in grey
    /// levels (0-255). 0 = none.
    #[arg(
        long,
        value_name = "SIGMA",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    noise: f32,

    /// Gaussian blur: standard deviation in pixels. 0 = none.
    #[arg(
        long,
        value_name = "SIGMA",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    blur: f32,

    /// Brightness factor applied to every byte of every pixel. 1 =
    /// unchanged. Harsher at the bright end than a change of light or
    /// exposure (x1.4 clips every byte above 182): see --exposure.
    #[arg(
        long,
        value_name = "B",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    brightness: f32,

    /// Exposure: multiplies the light's linear intensity before the sRGB
    /// encoding, as the light's strength, the camera's exposure time or its
    /// gain do (saturating at white). 1 = the training light.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    exposure: f32,

    /// Colour temperature of the scene's light, kelvin (1000-15000), for a
    /// camera white-balanced for the training light's 5000 K: 3000 is
    /// tungsten-warm (red up, blue down), 6500 daylight-cool.
    #[arg(long, value_name = "K", default_value_t = acch_core::light::TRAINING_LIGHT_K)]
    colour_temp_k: f32,

    /// Vignetting: the light at the image corners falls to 1 - V of the
    /// centre's (quadratically in the radius). 0 = none.
    #[arg(
        long,
        value_name = "V",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    vignetting: f32,

    /// Compress every image as JPEG of this quality (1-100) and decode it
    /// again, as a camera streaming MJPEG delivers it. 0 = none (PNG as
    /// rendered).
    #[arg(long, value_name = "Q", default_value_t = 0)]
    jpeg_quality: u8,

    /// Motion blur: every pixel the mean along a straight streak this many
    /// pixels long (the camera or the object moving while the shutter is
    /// open), in the direction of --motion-blur-deg. 0 = none.
    #[arg(
        long,
        value_name = "PX",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    motion_blur_px: f32,

    /// Direction of the motion streak, degrees from the image's x axis
    /// towards its y axis (down).
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    motion_blur_deg: f32,

    /// Sensor shot noise: the electrons a pixel collects at white (its
    /// full well over the gain; 400 is a high gain in dim light, 10000 a
    /// large sensor at base gain). The noise is Poisson in the electrons,
    /// so dark colours are relatively noisier than light ones. 0 = none.
    #[arg(
        long,
        value_name = "ELECTRONS",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    full_well_e: f32,

    /// Sensor read noise, electrons (with --full-well-e).
    #[arg(
        long,
        value_name = "ELECTRONS",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    read_noise_e: f32,

    /// Hide this share (0-1) of the object's width behind a dark grey bar
    /// in front of it, full height, at a place drawn per view (a gripper's
    /// finger); the mask keeps what stays visible. 0 = none.
    #[arg(
        long,
        value_name = "SHARE",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    occlusion: f32,
    /// What hides --occlusion: another object instead of the grey bar (a
    /// built-in name such as `can`, `generated-N`, or a mesh file), held
    /// upright in front of the target at half the camera's distance and
    /// stretched over the bar's place; its outline hides up to the share.
    #[arg(long, value_name = "OBJECT", requires = "occlusion")]
    occluder: Option<String>,
    /// Degrees the light is turned about the vertical from the training
    /// light's direction: the object lit from another side (0: as the
    /// training views are lit; 180: from the opposite side).
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    light_azimuth_deg: f32,

    /// Image width in pixels.
    #[arg(long, value_name = "PX", default_value_t = 640)]
    width: u32,

    /// Image height in pixels.
    #[arg(long, value_name = "PX", default_value_t = 480)]
    height: u32,

    /// Focal length in pixels (fx = fy); the principal point is the image centre.
    #[arg(long, value_name = "PX", default_value_t = 500.0)]
    focal: f64,

    /// Camera roll about its optical axis: each view gets a roll uniform in
    /// [-MAX, MAX] degrees (0-180), drawn per view from --seed; a positive
    /// roll turns the image counter-clockwise. 0 = no roll.
    #[arg(
        long,
        value_name = "MAX",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    roll_deg: f64,

    /// What to write: labels (images, masks, labels.csv and truth.jsonl)
    /// or bop (a BOP dataset: camera.json, models/ with the object's PLY
    /// and models_info.json, and test/000000/ with rgb/, mask_visib/,
    /// scene_gt.json, scene_camera.json and scene_gt_info.json).
    #[arg(long, value_enum, default_value = "labels")]
    format: Format,

    /// bop: the object's obj_id in the dataset.
    #[arg(long, value_name = "ID", default_value_t = 1)]
    bop_object_id: u32,
}

/// What `acch render` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    /// Our folder format, labels.csv.
    Labels,
    /// A BOP dataset.
    Bop,
}

/// The split and scene a BOP render writes.
const BOP_SPLIT: &str = "test";

/// Salt of the per-view roll seeds, so they differ from the noise seeds.
const ROLL_SALT: u64 = 0x726f_6c6c_5f64_6567;

/// The roll of view `index` of a run with `seed`: uniform in
/// [-max_deg, max_deg], exactly 0 when `max_deg` is 0.
fn view_roll(seed: u64, index: u64, max_deg: f64) -> f64 {
    if max_deg == 0.0 {
        return 0.0;
    }
    let u = (derive_seed(seed ^ ROLL_SALT, index) >> 11) as f64 / (1u64 << 53) as f64;
    max_deg * (2.0 * u - 1.0)
}

/// One rendered view: its labels row, truth, frame seed, thumbnail and
/// visible pixel count.
type ViewOutput = (LabelRow, GroundTruth, u64, Option<RgbImage>, u64);

/// Thumbnails in a contact sheet row.
const SHEET_COLUMNS: usize = 18;
/// Target thumbnail width in pixels.
const THUMB_WIDTH: u32 = 128;
/// Gap between thumbnails in the contact sheet.
const SHEET_GAP: u32 = 2;

/// Runs `acch render`.
pub fn run(args: RenderArgs) -> Result<()> {
    check_distance(args.distance).context("--distance")?;
    for (name, v) in [
        ("--noise", args.noise),
        ("--blur", args.blur),
        ("--brightness", args.brightness),
        ("--exposure", args.exposure),
        ("--motion-blur-px", args.motion_blur_px),
        ("--full-well-e", args.full_well_e),
        ("--read-noise-e", args.read_noise_e),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{name} {v} must be a finite number >= 0");
        }
    }
    for (name, v, range) in [
        ("--colour-temp-k", args.colour_temp_k, 1000.0..=15000.0),
        ("--vignetting", args.vignetting, 0.0..=1.0),
        ("--occlusion", args.occlusion, 0.0..=1.0),
        (
            "--light-azimuth-deg",
            args.light_azimuth_deg,
            -360.0..=360.0,
        ),
        ("--motion-blur-deg", args.motion_blur_deg, -360.0..=360.0),
    ] {
        if !(v.is_finite() && range.contains(&v)) {
            bail!(
                "{name} {v} must be a finite number in [{}, {}]",
                range.start(),
                range.end()
            );
        }
    }
    if args.jpeg_quality > 100 {
        bail!(
            "--jpeg-quality {} must be 1-100, or 0 for none",
            args.jpeg_quality
        );
    }
    if !(args.roll_deg.is_finite() && (0.0..=180.0).contains(&args.roll_deg)) {
        bail!(
            "--roll-deg {} must be a finite number of degrees in [0, 180]",
            args.roll_deg
        );
    }
    let intrinsics = Intrinsics {
        width: args.width,
        height: args.height,
        fx: args.focal,
        fy: args.focal,
        cx: (args.width as f64 - 1.0) / 2.0,
        cy: (args.height as f64 - 1.0) / 2.0,
    };
    intrinsics.validate()?;

    let object = args.object.load()?;
    let radius_m = object.radius_m();
    let occluder = match args.occluder.as_deref() {
        None => None,
        Some(spec) => {
            let mut objects = super::common::load_objects(spec, 0, Default::default())
                .with_context(|| format!("--occluder {spec}"))?;
            if objects.len() != 1 {
                bail!("--occluder {spec}: name one object, not {}", objects.len());
            }
            objects.pop()
        }
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create output directory {}", args.out.display()))?;

    let views = args
        .views
        .views(args.distance, args.seed)
        .into_iter()
        .enumerate()
        .map(|(i, v)| v.with_roll(view_roll(args.seed, i as u64, args.roll_deg)))
        .collect::<Result<Vec<ViewPose>, _>>()?;
    let config = SceneConfig {
        object,
        background: args.background,
        intrinsics,
        effects: Effects {
            noise_sigma: args.noise,
            blur_sigma: args.blur,
            brightness: args.brightness,
            exposure: args.exposure,
            colour_temp_k: args.colour_temp_k,
            vignetting: args.vignetting,
            jpeg_quality: args.jpeg_quality,
            motion_blur_px: args.motion_blur_px,
            motion_blur_deg: args.motion_blur_deg,
            full_well_e: args.full_well_e,
            read_noise_e: args.read_noise_e,
        },
        textures: args.textures,
        occlusion: args.occlusion,
        occluder,
        light_azimuth_deg: args.light_azimuth_deg,
    };
    let start = Instant::now();
    let renderer = Renderer::new(config, args.seed);
    let object_name = renderer.config().object.name().to_string();
    tracing::info!(
        object = %object_name,
        background = %args.background,
        views = views.len(),
        distractors = renderer.distractor_count(),
        "rendering into {}",
        args.out.display()
    );

    let progress = ProgressBar::new(views.len() as u64);
    progress.set_style(
        ProgressStyle::with_template("{spinner} rendering {bar:40} {pos}/{len} views ({eta})")
            .expect("static template is valid"),
    );
    let want_thumbs = args.contact_sheet.is_some();
    let digits = (views.len().max(1) - 1).to_string().len().max(4);
    let scene = bop::scene_dir(&args.out, BOP_SPLIT, 0);
    if args.format == Format::Bop {
        for sub in ["rgb", "mask_visib"] {
            let dir = scene.join(sub);
            std::fs::create_dir_all(&dir)
                .with_context(|| format!("cannot create directory {}", dir.display()))?;
        }
    }
    let results: Vec<ViewOutput> = views
        .par_iter()
        .enumerate()
        .map_init(Rendered::default, |frame, (i, view)| {
            let frame_seed = derive_seed(args.seed, i as u64);
            renderer.render_into(view, frame_seed, frame);
            let (file, mask) = match args.format {
                Format::Labels => (
                    format!("view_{i:0digits$}.png"),
                    format!("view_{i:0digits$}_mask.png"),
                ),
                Format::Bop => {
                    let rel = |p: PathBuf| -> String {
                        p.strip_prefix(&args.out)
                            .unwrap_or(&p)
                            .to_string_lossy()
                            .into_owned()
                    };
                    (
                        rel(bop::rgb_path(&scene, i as u32)),
                        rel(bop::mask_visib_path(&scene, i as u32, 0)),
                    )
                }
            };
            write_png(
                &args.out.join(&file),
                frame.image.as_raw(),
                frame.image.dimensions(),
                ExtendedColorType::Rgb8,
            )?;
            write_png(
                &args.out.join(&mask),
                frame.mask.as_raw(),
                frame.mask.dimensions(),
                ExtendedColorType::L8,
            )?;
            let visible_px = frame.mask.as_raw().iter().filter(|&&m| m != 0).count() as u64;
            let thumb = want_thumbs.then(|| thumbnail(&frame.image));
            progress.inc(1);
            Ok((
                LabelRow::from_truth(file, Some(mask), &frame.truth, radius_m),
                frame.truth.clone(),
                frame_seed,
                thumb,
                visible_px,
            ))
        })
        .collect::<Result<_>>()?;
    progress.finish_and_clear();

    match args.format {
        Format::Labels => {
            let labels_path = args.out.join("labels.csv");
            let rows: Vec<LabelRow> = results.iter().map(|r| r.0.clone()).collect();
            write_labels(&labels_path, &rows)?;
            let truth_path = args.out.join("truth.jsonl");
            write_truth(&truth_path, &results, (&object_name, radius_m), &args)?;
        }
        Format::Bop => {
            let mut writer = bop::SceneWriter::default();
            for (i, r) in results.iter().enumerate() {
                writer.add(i as u32, args.bop_object_id, &r.1, radius_m, r.4);
            }
            writer.write(&scene)?;
            bop::write_dataset_camera(&args.out, &intrinsics)?;
            bop::write_model(&args.out, args.bop_object_id, &renderer.config().object)?;
        }
    }
    if let Some(sheet) = &args.contact_sheet {
        let thumbs: Vec<&RgbImage> = results.iter().filter_map(|r| r.3.as_ref()).collect();
        write_contact_sheet(sheet, &thumbs)?;
    }
    let visible = results.iter().filter(|r| r.1.bbox.is_some()).count();
    tracing::info!(
        "wrote {} views ({} with the object visible) to {} in {:.2} s",
        results.len(),
        visible,
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Writes a PNG with fast compression (encoding dominates the run time otherwise).
fn write_png(
    path: &Path,
    bytes: &[u8],
    (width, height): (u32, u32),
    color: ExtendedColorType,
) -> Result<()> {
    let write = || -> Result<()> {
        let mut w = BufWriter::new(File::create(path)?);
        PngEncoder::new_with_quality(&mut w, CompressionType::Fast, FilterType::Adaptive)
            .write_image(bytes, width, height, color)?;
        w.flush()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write {}", path.display()))
}

/// The full ground truth, one JSON object per view.
fn write_truth(
    path: &Path,
    results: &[ViewOutput],
    (object, object_radius_m): (&str, f64),
    args: &RenderArgs,
) -> Result<()> {
    let write = || -> Result<()> {
        let mut w = BufWriter::new(File::create(path)?);
        for (i, (row, truth, frame_seed, _, _)) in results.iter().enumerate() {
            let m = truth.world_from_camera;
            let (r, t) = (m.matrix3, m.translation);
            let matrix = [
                [r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x],
                [r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y],
                [r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z],
                [0.0, 0.0, 0.0, 1.0],
            ];
            let line = serde_json::json!({
                "index": i,
                "file": row.file,
                "mask": row.mask,
                "object": object,
                "background": args.background.to_string(),
                "theta_deg": truth.theta_deg,
                "phi_deg": truth.phi_deg,
                "roll_deg": truth.roll_deg,
                // The renderer's unit: distances and world_from_camera are
                // in object bounding radii of object_radius_m metres.
                "distance": truth.distance,
                "object_radius_m": object_radius_m,
                "intrinsics": truth.intrinsics,
                "world_from_camera": matrix,
                "bbox": truth.bbox,
                "scene_seed": args.seed,
                "frame_seed": frame_seed,
                "effects": {
                    "noise": args.noise,
                    "blur": args.blur,
                    "brightness": args.brightness,
                    "exposure": args.exposure,
                    "colour_temp_k": args.colour_temp_k,
                    "vignetting": args.vignetting,
                    "jpeg_quality": args.jpeg_quality,
                    "motion_blur_px": args.motion_blur_px,
                    "motion_blur_deg": args.motion_blur_deg,
                    "full_well_e": args.full_well_e,
                    "read_noise_e": args.read_noise_e,
                    "occlusion": args.occlusion,
                    "light_azimuth_deg": args.light_azimuth_deg,
                },
            });
            serde_json::to_writer(&mut w, &line)?;
            w.write_all(b"\n")?;
        }
        w.flush()?;
        Ok(())
    };
    write().with_context(|| format!("cannot write {}", path.display()))
}

/// A box-filtered thumbnail about [`THUMB_WIDTH`] wide.
fn thumbnail(img: &RgbImage) -> RgbImage {
    let f = (img.width() / THUMB_WIDTH).max(1);
    let (tw, th) = ((img.width() / f).max(1), (img.height() / f).max(1));
    RgbImage::from_fn(tw, th, |x, y| {
        let mut acc = [0u32; 3];
        for dy in 0..f {
            for dx in 0..f {
                let p = img.get_pixel(
                    (x * f + dx).min(img.width() - 1),
                    (y * f + dy).min(img.height() - 1),
                );
                for c in 0..3 {
                    acc[c] += p[c] as u32;
                }
            }
        }
        let n = f * f;
        image::Rgb(acc.map(|a| ((a + n / 2) / n) as u8))
    })
}

/// Tiles thumbnails [`SHEET_COLUMNS`] per row, in view order.
fn write_contact_sheet(path: &Path, thumbs: &[&RgbImage]) -> Result<()> {
    let Some(first) = thumbs.first() else {
        bail!("no views to put on the contact sheet {}", path.display());
    };
    let (tw, th) = first.dimensions();
    let cols = SHEET_COLUMNS.min(thumbs.len()) as u32;
    let rows = thumbs.len().div_ceil(SHEET_COLUMNS) as u32;
    let mut sheet = RgbImage::from_pixel(
        cols * (tw + SHEET_GAP) + SHEET_GAP,
        rows * (th + SHEET_GAP) + SHEET_GAP,
        image::Rgb([32, 32, 32]),
    );
    for (i, t) in thumbs.iter().enumerate() {
        let (c, r) = ((i % SHEET_COLUMNS) as u32, (i / SHEET_COLUMNS) as u32);
        image::imageops::replace(
            &mut sheet,
            *t,
            (SHEET_GAP + c * (tw + SHEET_GAP)) as i64,
            (SHEET_GAP + r * (th + SHEET_GAP)) as i64,
        );
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create directory {}", dir.display()))?;
    }
    write_png(
        path,
        sheet.as_raw(),
        sheet.dimensions(),
        ExtendedColorType::Rgb8,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        render: RenderArgs,
    }

    fn args(extra: &[&str]) -> RenderArgs {
        let dir = std::env::temp_dir().join("acch-render-roll-test-never-written");
        let mut argv = vec!["render", "--object", "fruitbox", "--out"];
        let dir = dir.to_str().unwrap().to_string();
        argv.push(&dir);
        argv.extend_from_slice(extra);
        Cli::try_parse_from(argv).unwrap().render
    }

    #[test]
    fn bad_roll_is_refused_naming_the_option() {
        for bad in ["200", "-5", "NaN", "inf"] {
            let e = run(args(&["--roll-deg", bad])).unwrap_err().to_string();
            assert!(
                e.contains("--roll-deg") && e.contains("[0, 180]"),
                "{bad}: {e}"
            );
        }
        assert_eq!(args(&[]).roll_deg, 0.0);
    }

    #[test]
    fn view_rolls_are_seeded_per_view_and_bounded() {
        let rolls: Vec<f64> = (0..2000).map(|i| view_roll(9, i, 30.0)).collect();
        assert!(rolls.iter().all(|r| (-30.0..=30.0).contains(r)));
        let (min, max) = rolls
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &r| {
                (a.min(r), b.max(r))
            });
        assert!(min < -29.0 && max > 29.0, "{min} {max}");
        assert_eq!(rolls[5], view_roll(9, 5, 30.0));
        assert_ne!(rolls[5], view_roll(10, 5, 30.0));
        assert_ne!(rolls[5], rolls[6]);
        assert!((0..100).all(|i| view_roll(9, i, 0.0) == 0.0));
    }
}
