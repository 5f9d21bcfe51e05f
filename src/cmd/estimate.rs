//! `acch estimate`: the 2-DOF pose of the object in one image.

use acch_core::{IndexImage, Rect, ViewDatabase};
use acch_pose::train::mask_bbox;
use acch_pose::{Estimate, PoseEstimator, Refinement};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::fmt::Write as _;
use std::path::PathBuf;

/// An image to estimate from, and how to find the object in it.
#[derive(Args, Clone, Debug)]
pub struct Input {
    /// View database written by `acch train`.
    #[arg(long, value_name = "FILE.acchdb")]
    pub db: PathBuf,
    /// Image (PNG) showing the object.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// Object mask (PNG, non-zero = object), e.g. one that `acch render` wrote.
    #[arg(long, value_name = "MASK")]
    pub mask: Option<PathBuf>,
    /// Camera distance in object bounding radii, when known; otherwise the
    /// scale comes from the object's apparent size.
    #[arg(long)]
    pub distance: Option<f32>,
}

/// An input image loaded, quantised and masked.
pub struct Loaded {
    /// The estimator over the database.
    pub estimator: PoseEstimator,
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

/// Loads database, image and mask.
pub fn load_input(input: &Input) -> Result<Loaded> {
    let db = ViewDatabase::load(&input.db)?;
    let rgb = image::open(&input.image)
        .with_context(|| format!("reading image {}", input.image.display()))?
        .to_rgb8();
    let (w, h) = rgb.dimensions();
    let Some(mask_path) = &input.mask else {
        bail!("no --mask given: this build estimates from a masked object only");
    };
    let mask = image::open(mask_path)
        .with_context(|| format!("reading mask {}", mask_path.display()))?
        .to_luma8();
    if mask.dimensions() != (w, h) {
        bail!(
            "{}: mask is {}x{} but the image is {w}x{h}",
            mask_path.display(),
            mask.width(),
            mask.height()
        );
    }
    let mask = mask.into_raw();
    let Some(roi) = mask_bbox(&mask, w, h) else {
        bail!("{}: the mask is empty", mask_path.display());
    };
    if let Some(d) = input.distance
        && !(d.is_finite() && d > 0.0)
    {
        bail!("--distance {d} must be a positive number");
    }
    let scale = input.distance.map(|d| db.train_distance / d);
    let index = db.palette.quantise(rgb.as_raw(), w, h);
    Ok(Loaded {
        estimator: PoseEstimator::new(db)?,
        index,
        mask,
        roi,
        scale,
    })
}

/// Arguments of `acch estimate`.
#[derive(Args)]
pub struct EstimateArgs {
    #[command(flatten)]
    input: Input,
    /// Report the best training view only (the paper's winner takes all).
    #[arg(long)]
    wta: bool,
    /// Plot the match-value response over the view index, θ slices marked.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// Write the match-value response as CSV (view, theta_deg, phi_deg, match).
    #[arg(long, value_name = "FILE.csv")]
    csv: Option<PathBuf>,
}

/// Runs `acch estimate`.
pub fn run(args: EstimateArgs) -> Result<()> {
    let mut loaded = load_input(&args.input)?;
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
        let marks: Vec<crate::plot::SliceMark> = est
            .slices()
            .iter()
            .map(|s| crate::plot::SliceMark {
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
        crate::plot::response_plot(path, &title, est.response(), &marks, e.best_view, None)?;
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
