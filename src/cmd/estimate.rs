//! `acch estimate`: the 2-DOF pose of the object in one image.

use acch_confidence::Model as ConfidenceModel;
use acch_core::{IndexImage, Rect, ViewDatabase};
use acch_pipeline::source::sized_intrinsics;
use acch_pipeline::wire::Intrinsics;
use acch_pipeline::{Chain, FrameHeader, Seeded, StageSettings};
use acch_pose::train::mask_bbox;
use acch_pose::{Estimate, PoseEstimator, Refinement};
use acch_train::views::{read_image, read_mask};
use anyhow::{Context, Result, bail};
use clap::Args;
use image::{Rgb, RgbImage};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// An image to estimate from, and how to find the object in it.
#[derive(Args, Clone, Debug)]
pub struct Input {
    /// View database written by `acch train`.
    #[arg(long, value_name = "FILE.acchdb")]
    pub db: PathBuf,
    /// Image (PNG) showing the object.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// Object mask (PNG, non-zero = object), e.g. one that `acch render`
    /// wrote. Without it, recognition and segmentation find the object.
    #[arg(long, value_name = "MASK")]
    pub mask: Option<PathBuf>,
    /// Camera distance to the object centre in metres, when known;
    /// otherwise the scale comes from the object's apparent size.
    #[arg(long, value_name = "METRES")]
    pub distance_m: Option<f32>,
}

/// An input image loaded, quantised and masked.
pub struct Loaded {
    /// The estimator over the database.
    pub estimator: PoseEstimator,
    /// The database's confidence network, if it has one.
    pub confidence: Option<ConfidenceModel>,
    /// The image as palette indices.
    pub index: IndexImage,
    /// The object mask.
    pub mask: Vec<u8>,
    /// Bounding box of the mask.
    pub roi: Rect,
    /// Scale when the distance is known.
    pub scale: Option<f32>,
}

impl Loaded {
    /// Histogram and response at the known or estimated scale.
    pub fn respond(&mut self) -> u64 {
        let scale = self.scale.unwrap_or_else(|| {
            acch_pose::object_size(&self.index, Some(&self.mask), self.roi)
                / self.estimator.database().median_size_px()
        });
        self.estimator
            .respond(&self.index, Some(&self.mask), self.roi, scale)
    }

    /// The pose estimate.
    pub fn estimate(&mut self, refinement: Refinement) -> Option<Estimate> {
        self.estimator.estimate(
            &self.index,
            Some(&self.mask),
            self.roi,
            self.scale,
            refinement,
        )
    }
}

/// Loads database, image and mask. Without a mask, recognition and
/// segmentation find the object; `debug_dir` then receives their pictures.
/// `Ok(None)` means the object was not found.
pub fn load_input(input: &Input, debug_dir: Option<&Path>) -> Result<Option<Loaded>> {
    let db = ViewDatabase::load(&input.db)?;
    let rgb = read_image(&input.image)?.to_rgb8();
    let (w, h) = rgb.dimensions();
    if let Some(d) = input.distance_m
        && !(d.is_finite() && d > 0.0)
    {
        bail!("--distance-m {d} must be a positive number of metres");
    }
    let (mask, roi) = match &input.mask {
        Some(mask_path) => {
            let mask = read_mask(mask_path, (w, h))?;
            let Some(roi) = mask_bbox(&mask, w, h) else {
                bail!("{}: the mask is empty", mask_path.display());
            };
            (mask, roi)
        }
        None => {
            // Recognition and segmentation as deployed; the estimate below
            // is the pose stage's on the same mask.
            let settings = StageSettings {
                width: w,
                height: h,
                distance_m: input.distance_m.map(f64::from),
                unrated: true,
                roll_search_deg: acch_pose::trained_roll_search_deg(&db),
                light_search: 0,
                verify_shape: true,
            };
            let mut chain = Chain::build(&db, &settings)?;
            let k = Intrinsics::from(&sized_intrinsics(w, h));
            let result = chain.process(&FrameHeader::rgb(0, w, h, k), rgb.as_raw());
            let mut mask = Vec::new();
            if let Some(region) = chain.last_region() {
                region.frame_mask(w, h, &mut mask);
            }
            if let Some(dir) = debug_dir {
                write_debug(dir, &rgb, &chain, &result, &mask)?;
            }
            match result.region().done() {
                Some(roi) => (mask, roi.into()),
                None => return Ok(None),
            }
        }
    };
    let scale = input.distance_m.map(|d| db.train_distance_m / d);
    let index = db.palette.quantise(rgb.as_raw(), w, h);
    let confidence = match ConfidenceModel::load(&db) {
        Ok(m) => Some(m),
        Err(acch_confidence::ConfidenceError::MissingSection) => None,
        Err(e) => {
            return Err(e).with_context(|| format!("{}: confidence network", input.db.display()));
        }
    };
    Ok(Some(Loaded {
        // The search the database was trained for (its confidence
        // network's, or the rolls of its photographs; none otherwise).
        estimator: {
            let search = acch_pose::trained_roll_search_deg(&db);
            PoseEstimator::new(db)?.with_roll_search(search)
        },
        confidence,
        index,
        mask,
        roi,
        scale,
    }))
}

/// Writes what recognition and segmentation saw: the window-score heat map,
/// the frame with the window (red) and grown region (green), and the mask.
fn write_debug(
    dir: &Path,
    rgb: &RgbImage,
    chain: &Chain,
    result: &Seeded,
    mask: &[u8],
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let (w, h) = rgb.dimensions();
    let save = |img: &RgbImage, name: &str| {
        let path = dir.join(name);
        img.save(&path)
            .with_context(|| format!("writing {}", path.display()))
    };
    // Heat map: each window position's score at its centre cell.
    let heat = chain.stages().recognition.last_used().detector().heat_map();
    let max = heat.scores.iter().copied().fold(f32::EPSILON, f32::max);
    let cell = heat.cell_px as i64;
    let half = heat.window_cells as i64 / 2;
    let mut img = RgbImage::new(w, h);
    for j in 0..heat.height {
        for i in 0..heat.width {
            let v = heat.scores[j * heat.width + i] / max;
            let colour = heat_colour(v);
            let (cx, cy) = (
                (heat.origin.0 as i64 + i as i64 + half) * cell,
                (heat.origin.1 as i64 + j as i64 + half) * cell,
            );
            for y in cy.max(0)..(cy + cell).min(h as i64) {
                for x in cx.max(0)..(cx + cell).min(w as i64) {
                    img.put_pixel(x as u32, y as u32, colour);
                }
            }
        }
    }
    save(&img, "heat.png")?;
    let mut img = rgb.clone();
    if let Some(d) = result.detection().done() {
        draw_rect(&mut img, d.window.into(), Rgb([230, 20, 20]));
    }
    if let Some(roi) = result.region().done() {
        draw_rect(&mut img, roi.into(), Rgb([20, 200, 20]));
    }
    save(&img, "window.png")?;
    let img = RgbImage::from_fn(w, h, |x, y| {
        let m = mask.get((y * w + x) as usize).copied().unwrap_or(0);
        let p = rgb.get_pixel(x, y).0;
        if m != 0 {
            Rgb(p)
        } else {
            Rgb(p.map(|c| c / 4))
        }
    });
    save(&img, "mask.png")
}

fn heat_colour(v: f32) -> Rgb<u8> {
    let v = v.clamp(0.0, 1.0);
    // Dark blue through red to yellow.
    let r = (255.0 * (1.5 * v).min(1.0)) as u8;
    let g = (255.0 * (2.0 * v - 1.0).clamp(0.0, 1.0)) as u8;
    let b = (255.0 * (0.5 - v).clamp(0.0, 0.5) * 1.2) as u8;
    Rgb([r, g, b])
}

fn draw_rect(img: &mut RgbImage, r: Rect, c: Rgb<u8>) {
    let (w, h) = img.dimensions();
    let r = r.clamp_to(w, h);
    if r.width == 0 || r.height == 0 {
        return;
    }
    for t in 0..2u32 {
        for x in r.x..r.x + r.width {
            for y in [
                r.y + t.min(r.height - 1),
                r.y + r.height - 1 - t.min(r.height - 1),
            ] {
                img.put_pixel(x, y, c);
            }
        }
        for y in r.y..r.y + r.height {
            for x in [
                r.x + t.min(r.width - 1),
                r.x + r.width - 1 - t.min(r.width - 1),
            ] {
                img.put_pixel(x, y, c);
            }
        }
    }
}

/// Arguments of `acch estimate`.
#[derive(Args)]
pub struct EstimateArgs {
    #[command(flatten)]
    input: Input,
    /// Confidence below which the estimate is reported as rejected
    /// (default: the threshold stored in the database, 0.8 unless trained
    /// otherwise).
    #[arg(long)]
    threshold: Option<f32>,
    /// Report the best training view only (the paper's winner takes all).
    #[arg(long)]
    wta: bool,
    /// Plot the match-value response over the view index, θ slices marked.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// Without --mask: write the recognition heat map, the window and the
    /// mask as images into this folder.
    #[arg(long, value_name = "DIR")]
    debug_dir: Option<PathBuf>,
    /// Write the match-value response as CSV (view, theta_deg, phi_deg, match).
    #[arg(long, value_name = "FILE.csv")]
    csv: Option<PathBuf>,
}

/// Runs `acch estimate`.
pub fn run(args: EstimateArgs) -> Result<()> {
    let Some(mut loaded) = load_input(&args.input, args.debug_dir.as_deref())? else {
        println!(
            "not found: no window of {} resembles the object",
            args.input.image.display()
        );
        return Ok(());
    };
    let refinement = if args.wta {
        Refinement::WinnerTakesAll
    } else {
        Refinement::Parabolic
    };
    let Some(e) = loaded.estimate(refinement) else {
        bail!(
            "{}: no object colours inside the mask",
            args.input.image.display()
        );
    };
    let est = &loaded.estimator;
    let views = est.database().views();
    println!(
        "theta {:.1} deg  phi {:.1} deg  match {:.4}  scale {:.3}",
        e.theta_deg, e.phi_deg, e.best_value, e.scale
    );
    if est.roll_search_deg() > 0.0 {
        println!(
            "roll {:.1} deg (searched within ±{:.0})",
            e.roll_deg,
            est.roll_search_deg()
        );
    }
    if let Some(model) = &mut loaded.confidence {
        if let Some(t) = args.threshold {
            model
                .set_threshold(t)
                .with_context(|| format!("--threshold {t}"))?;
        }
        let r = model.rating(est.response(), est.slices(), est.database().views());
        println!(
            "confidence {:.3}  {} (threshold {})",
            r.confidence,
            if r.accepted { "accepted" } else { "rejected" },
            model.threshold()
        );
    }
    println!("top 5 views:");
    for (rank, (i, m)) in est.top(5).into_iter().enumerate() {
        println!(
            "  {}. view {:>3}  theta {:>4.0}  phi {:>5.0}  match {:.4}",
            rank + 1,
            i,
            views[i].theta_deg,
            views[i].phi_deg,
            m
        );
    }
    if let Some(path) = &args.plot {
        let marks: Vec<acch_viz::plot::SliceMark> = est
            .slices()
            .iter()
            .map(|s| acch_viz::plot::SliceMark {
                start: s.start,
                len: s.len,
                theta_deg: s.theta_deg,
            })
            .collect();
        let title = format!(
            "{}: θ {:.1}°, φ {:.1}° (match {:.3})",
            args.input.image.display(),
            e.theta_deg,
            e.phi_deg,
            e.best_value
        );
        acch_viz::plot::response_plot(path, &title, est.response(), &marks, e.best_view, None)?;
    }
    if let Some(path) = &args.csv {
        let mut s = String::from("view,theta_deg,phi_deg,match\n");
        for (i, (v, m)) in views.iter().zip(est.response()).enumerate() {
            writeln!(s, "{i},{},{},{m}", v.theta_deg, v.phi_deg)?;
        }
        std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
