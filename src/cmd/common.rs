//! Arguments shared by several subcommands: choosing an object, histogram
//! options.

use acch_capture::{Object, UpAxis};
use acch_core::{ColourSpace, HistogramKind, HistogramParams, OffsetSampling};
use acch_pipeline::config::SmoothingChoice;
use acch_pose::train::TrainConfig;
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::PathBuf;
use std::sync::Arc;

/// Which object to render, and its real size: a built-in one or a mesh
/// file.
#[derive(Args, Clone, Debug)]
pub struct ObjectArgs {
    /// Built-in object: fruitbox (a 24 x 15 x 30 cm printed box), can (a
    /// labelled drink can, 8.4 x 12 cm), tricolor (three untextured
    /// blocks, 10 cm long) or generated-N (object N of the generated
    /// population: a box, can, bottle or stack of blocks printed like
    /// packaging, drawn from seed N).
    #[arg(long, value_name = "NAME", conflicts_with = "mesh")]
    pub object: Option<String>,
    /// A mesh file instead, by its extension: .obj (texture coordinates and
    /// an MTL material with a map_Kd texture, relative to the MTL file),
    /// .ply (a texture named by `comment TextureFile` with texture
    /// coordinates, or vertex colours) or .gltf/.glb (glTF 2.0: base
    /// colour texture, factor or COLOR_0). Its coordinates are taken as
    /// metres (see --mesh-unit-m; BOP's PLY models are in millimetres:
    /// --mesh-unit-m 0.001).
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// Which axis of the mesh file points up: +y, -y, +z, -z, +x or -x.
    /// Default +y (the OBJ and glTF convention); +z for a BOP dataset's
    /// models (`acch eval --bop`).
    #[arg(long, value_name = "AXIS", allow_hyphen_values = true)]
    pub mesh_up: Option<UpAxis>,
    /// The mesh file's unit in metres (0.001 for millimetres, 0.0254 for
    /// inches): poses and distances come out in metres.
    #[arg(
        long,
        value_name = "METRES",
        requires = "mesh",
        conflicts_with = "object_radius_m"
    )]
    pub mesh_unit_m: Option<f64>,
    /// The object's real bounding radius in metres (half its largest
    /// extent through the centre of its bounding box), overriding the
    /// built-in size or the mesh's units.
    #[arg(long, value_name = "METRES")]
    pub object_radius_m: Option<f64>,
}

impl ObjectArgs {
    /// Loads the chosen object at its real size; `fruitbox` when none is
    /// named.
    pub fn load(&self) -> Result<Arc<Object>> {
        let object = match (&self.object, &self.mesh) {
            (_, Some(path)) => Object::load_mesh(path, self.mesh_up.unwrap_or_default())
                .with_context(|| format!("loading mesh {}", path.display()))?,
            (Some(name), None) if is_mesh_path(name) => bail!(
                "--object {name}: --object names a built-in object; a mesh file is read with --mesh {name}"
            ),
            (Some(name), None) => Object::builtin(name)?,
            (None, None) => Object::builtin("fruitbox")?,
        };
        let object = match (self.mesh_unit_m, self.object_radius_m) {
            (Some(unit), _) => object.with_mesh_unit_m(unit).context("--mesh-unit-m")?,
            (None, Some(r)) => object.with_radius_m(r).context("--object-radius-m")?,
            (None, None) => object,
        };
        Ok(Arc::new(object))
    }
}

/// Whether an object named on the command line is a mesh file: anything
/// with a path separator or a file extension (no built-in name has either).
fn is_mesh_path(name: &str) -> bool {
    name.contains('/') || name.contains('.')
}

/// The objects of a comma-separated list: built-in names and
/// `generated-N`, `random:N` (N generated objects of the population of
/// `population_seed`, see [`acch_capture::population`]) and mesh files
/// (anything with a path separator or a file extension), read with `up`.
pub fn load_objects(spec: &str, population_seed: u64, up: UpAxis) -> Result<Vec<Arc<Object>>> {
    let mut objects = Vec::new();
    for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        if let Some(n) = item.strip_prefix("random:") {
            let n: usize = n
                .parse()
                .ok()
                .filter(|&n| (1..=1000).contains(&n))
                .with_context(|| format!("--objects {item}: N must be a number in 1..=1000"))?;
            for name in acch_capture::population(population_seed, n) {
                objects.push(Arc::new(Object::builtin(&name)?));
            }
        } else if is_mesh_path(item) {
            let object = Object::load_mesh(item, up)
                .with_context(|| format!("--objects: loading mesh {item}"))?;
            objects.push(Arc::new(object));
        } else {
            objects.push(Arc::new(
                Object::builtin(item).with_context(|| format!("--objects {item}"))?,
            ));
        }
    }
    if objects.is_empty() {
        bail!("--objects '{spec}' names no object");
    }
    Ok(objects)
}

/// Histogram and palette options (defaults: the paper's ACCH, chosen by
/// measurement where the paper is silent).
#[derive(Args, Clone, Debug)]
pub struct HistogramArgs {
    /// Histogram kind: acch, dcch or cch.
    #[arg(long, default_value = "acch", value_parser = parse_kind)]
    pub kind: HistogramKind,
    /// Palette size C.
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u16).range(1..=255))]
    pub colours: u16,
    /// Geometric bins D (orientations for acch, distances for dcch).
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u16).range(1..=360))]
    pub bins: u16,
    /// Inner radius of the annulus in pixels at the training distance (exclusive).
    #[arg(long, default_value_t = 10.0)]
    pub r_min: f32,
    /// Outer radius of the annulus in pixels at the training distance.
    #[arg(long, default_value_t = 20.0)]
    pub r_max: f32,
    /// Reference-pixel stride in pixels at the training distance.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub stride: u16,
    /// Offsets: `dense` (every integer offset of the annulus) or
    /// `polar:RINGS:ANGLES` (fixed rings x orientations).
    #[arg(long, default_value = "polar:4:48", value_parser = parse_sampling)]
    pub sampling: OffsetSampling,
    /// Colour space of the palette: lab or rgb.
    #[arg(long, default_value = "lab")]
    pub space: ColourSpace,
    /// Colours farther from the palette than 1.5 x this quantile of the
    /// training pixels' distances count as "not object"; 1 keeps nearly all.
    #[arg(long, default_value_t = 0.99)]
    pub reject_quantile: f32,
    /// Seed of the palette's k-means.
    #[arg(long, default_value_t = 0)]
    pub palette_seed: u64,
    /// Smoothing of views and frames before quantisation: `off` (the
    /// paper's raw pixels) or `binomial` (5x5, sigma 1 px: a blurred or
    /// noisy camera matches sharp training views; costs precision among
    /// several known objects, docs/accuracy.md "A blurred camera"). In
    /// eval's robust and multi protocols: databases trained so on first
    /// use and cached apart from the default ones. eval's robust protocol
    /// also takes `auto`: each frame through the sharp or the smoothed
    /// databases (with the confidence for a worse camera), as its measured
    /// noise and JPEG blocking and the object's sharpness say (`acch run
    /// --smoothing auto`).
    #[arg(long, default_value = "off", value_name = "off|binomial|auto")]
    pub smoothing: SmoothingChoice,
}

impl HistogramArgs {
    /// The training configuration these options describe.
    pub fn train_config(&self) -> Result<TrainConfig> {
        if !(self.reject_quantile > 0.0 && self.reject_quantile <= 1.0) {
            bail!(
                "--reject-quantile {} must lie in (0, 1]",
                self.reject_quantile
            );
        }
        let params = HistogramParams {
            kind: self.kind,
            colours: self.colours,
            bins: self.bins,
            r_min: self.r_min,
            r_max: self.r_max,
            stride: self.stride,
            sampling: self.sampling,
        };
        params.validate()?;
        Ok(TrainConfig {
            colours: self.colours as usize,
            space: self.space,
            reject_quantile: Some(self.reject_quantile),
            params,
            seed: self.palette_seed,
            smoothing: self.smoothing.fixed(),
        })
    }
}

fn parse_kind(s: &str) -> Result<HistogramKind, String> {
    match s.to_ascii_lowercase().as_str() {
        "acch" => Ok(HistogramKind::Acch),
        "dcch" => Ok(HistogramKind::Dcch),
        "cch" => Ok(HistogramKind::Cch),
        _ => Err(format!(
            "unknown histogram kind '{s}' (expected acch, dcch or cch)"
        )),
    }
}

fn parse_sampling(s: &str) -> Result<OffsetSampling, String> {
    if s == "dense" {
        return Ok(OffsetSampling::Dense);
    }
    let parts: Vec<&str> = s.split(':').collect();
    match parts.as_slice() {
        ["polar", rings, angles] => {
            let rings: u16 = rings
                .parse()
                .map_err(|_| format!("bad ring count in '{s}'"))?;
            let angles: u16 = angles
                .parse()
                .map_err(|_| format!("bad angle count in '{s}'"))?;
            if rings == 0 || angles == 0 {
                return Err(format!("'{s}': rings and angles must be at least 1"));
            }
            Ok(OffsetSampling::Polar { rings, angles })
        }
        _ => Err(format!(
            "unknown sampling '{s}' (expected dense or polar:RINGS:ANGLES)"
        )),
    }
}
