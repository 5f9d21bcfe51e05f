//! Camera calibration files and lens distortion.
//!
//! Real cameras come calibrated by ROS (`camera_calibration`, a camera_info
//! YAML file) or by OpenCV (`calibrateCamera` saved with `cv::FileStorage`).
//! [`Calibration::load`] reads both into [`Intrinsics`] and a [`Distortion`]
//! in OpenCV's lens model, so that a pixel of a raw (distorted) image can be
//! moved to where an ideal pinhole camera would have seen it
//! ([`Distortion::undistort_pixel`]) before its viewing ray is cast.
//!
//! Conventions are OpenCV's: normalised image coordinates are `(x/z, y/z)`
//! of a point in the camera frame (x right, y down, z forward); a pixel is
//! `(fx x + cx, fy y + cy)` with pixel centres at integer coordinates.
//!
//! ```no_run
//! use std::path::Path;
//! use acch_capture::Calibration;
//! use glam::DVec2;
//!
//! let calib = Calibration::load(Path::new("camera.yaml"))?;
//! let ideal = calib.undistort_pixel(DVec2::new(600.0, 60.0));
//! let ray = calib.intrinsics.ray(ideal);
//! # let _ = ray;
//! # Ok::<(), acch_capture::CaptureError>(())
//! ```

use std::borrow::Cow;
use std::fmt;
use std::io::Read;
use std::path::Path;
use std::str::FromStr;

use glam::{DMat2, DVec2};
use serde::{Deserialize, Serialize};
use yaml_rust2::{Yaml, YamlLoader, yaml::Hash};

use crate::{CaptureError, Intrinsics};

/// A lens distortion model, named as ROS names it (`distortion_model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DistortionModel {
    /// An ideal pinhole lens.
    #[default]
    None,
    /// OpenCV's 5 coefficients k1 k2 p1 p2 k3: polynomial radial and
    /// tangential distortion (ROS `plumb_bob`).
    PlumbBob,
    /// OpenCV's 8 coefficients k1 k2 p1 p2 k3 k4 k5 k6: the radial factor is
    /// `(1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)`
    /// (ROS `rational_polynomial`), for wide-angle lenses.
    RationalPolynomial,
}

impl DistortionModel {
    /// The ROS name: `none`, `plumb_bob` or `rational_polynomial`.
    pub fn name(self) -> &'static str {
        match self {
            DistortionModel::None => "none",
            DistortionModel::PlumbBob => "plumb_bob",
            DistortionModel::RationalPolynomial => "rational_polynomial",
        }
    }

    /// How many of the 8 coefficients the model uses: 0, 5 or 8.
    pub fn coefficient_count(self) -> usize {
        match self {
            DistortionModel::None => 0,
            DistortionModel::PlumbBob => 5,
            DistortionModel::RationalPolynomial => 8,
        }
    }
}

impl fmt::Display for DistortionModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DistortionModel {
    type Err = String;

    /// Parses a ROS model name; `none` and the empty string mean no
    /// distortion. ROS's `equidistant` (fisheye) is refused by name, since
    /// its formula differs and reading it as plumb_bob would be silently wrong.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "" | "none" => Ok(DistortionModel::None),
            "plumb_bob" => Ok(DistortionModel::PlumbBob),
            "rational_polynomial" => Ok(DistortionModel::RationalPolynomial),
            "equidistant" | "fisheye" => Err(format!(
                "distortion model '{}' (fisheye) is not supported: only plumb_bob and rational_polynomial are",
                s.trim()
            )),
            _ => Err(format!(
                "unknown distortion model '{}': only plumb_bob and rational_polynomial (or none) are supported",
                s.trim()
            )),
        }
    }
}

/// Lens distortion in OpenCV's model. `coefficients` are
/// k1 k2 p1 p2 k3 k4 k5 k6; the ones the model does not use are 0.
/// Deserialising does not check the values: call [`Distortion::validate`].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    /// Which formula the coefficients belong to.
    pub model: DistortionModel,
    /// k1 k2 p1 p2 k3 k4 k5 k6 (OpenCV's order).
    pub coefficients: [f64; 8],
}

/// Fixed-point iterations of [`Distortion::undistort_normalised`], as in
/// OpenCV's `undistortPoints`.
const FIXED_POINT_ITERATIONS: usize = 20;
/// Newton steps that finish what the fixed-point iterations leave: they
/// converge slowly for strong barrel distortion in image corners.
const NEWTON_STEPS: usize = 10;
/// Convergence: change of a normalised coordinate (1e-12 × f ≈ 1e-9 px).
const CONVERGED: f64 = 1e-12;

impl Distortion {
    /// The names of the 8 coefficients, in order.
    pub const COEFFICIENT_NAMES: [&'static str; 8] =
        ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"];

    /// ROS `plumb_bob` / OpenCV 5-coefficient distortion: k1 k2 p1 p2 k3.
    pub fn plumb_bob(k: [f64; 5]) -> Self {
        Distortion {
            model: DistortionModel::PlumbBob,
            coefficients: [k[0], k[1], k[2], k[3], k[4], 0.0, 0.0, 0.0],
        }
    }

    /// ROS `rational_polynomial` / OpenCV 8-coefficient distortion:
    /// k1 k2 p1 p2 k3 k4 k5 k6.
    pub fn rational_polynomial(k: [f64; 8]) -> Self {
        Distortion {
            model: DistortionModel::RationalPolynomial,
            coefficients: k,
        }
    }

    /// Builds a distortion from a list of coefficients as calibration files
    /// store it (ROS `D`, OpenCV `distCoeffs`). With `model` given, the count
    /// must fit it (plumb_bob takes 4 or 5, k3 = 0 when 4); without it the
    /// model follows from the count as in OpenCV: 0 none, 4 or 5 plumb_bob,
    /// 8 rational_polynomial. Other counts (OpenCV's 12 and 14: thin prism,
    /// tilted sensor) are refused, naming the count.
    pub fn from_coefficients(
        model: Option<DistortionModel>,
        coefficients: &[f64],
    ) -> Result<Distortion, String> {
        let n = coefficients.len();
        let mut c = [0.0; 8];
        let model = match model {
            Some(DistortionModel::None) => {
                if coefficients.iter().any(|&v| v != 0.0) {
                    return Err(format!(
                        "distortion model none, but {n} non-zero distortion coefficients are given"
                    ));
                }
                return Ok(Distortion::default());
            }
            Some(m @ DistortionModel::PlumbBob) if n == 4 || n == 5 => m,
            Some(m @ DistortionModel::RationalPolynomial) if n == 8 => m,
            Some(m) => {
                let takes = match m {
                    DistortionModel::PlumbBob => "4 or 5 (k1 k2 p1 p2 [k3])",
                    _ => "8 (k1 k2 p1 p2 k3 k4 k5 k6)",
                };
                return Err(format!(
                    "distortion model {m} takes {takes} coefficients, {n} are given"
                ));
            }
            None => match n {
                0 => return Ok(Distortion::default()),
                4 | 5 => DistortionModel::PlumbBob,
                8 => DistortionModel::RationalPolynomial,
                _ => {
                    return Err(format!(
                        "{n} distortion coefficients are not supported: only 4 or 5 (plumb_bob: k1 k2 p1 p2 [k3]) \
                         and 8 (rational_polynomial: k1 k2 p1 p2 k3 k4 k5 k6); OpenCV's 12 and 14 \
                         (thin prism, tilted sensor) are not"
                    ));
                }
            },
        };
        c[..n].copy_from_slice(coefficients);
        Ok(Distortion {
            model,
            coefficients: c,
        })
    }

    /// True for an ideal pinhole lens (model none or all coefficients 0):
    /// callers can skip undistortion altogether.
    pub fn is_none(&self) -> bool {
        self.model == DistortionModel::None || self.coefficients.iter().all(|&c| c == 0.0)
    }

    /// Refuses non-finite coefficients, and non-zero coefficients the model
    /// does not use (they would be silently ignored).
    pub fn validate(&self) -> Result<(), CaptureError> {
        let used = self.model.coefficient_count();
        for (i, (&c, name)) in self
            .coefficients
            .iter()
            .zip(Self::COEFFICIENT_NAMES)
            .enumerate()
        {
            let reason = if !c.is_finite() {
                format!("distortion coefficient {name} = {c} must be finite")
            } else if i >= used && c != 0.0 {
                format!(
                    "distortion coefficient {name} = {c} is not used by the {} model and must be 0",
                    self.model
                )
            } else {
                continue;
            };
            return Err(CaptureError::InvalidIntrinsics { reason });
        }
        Ok(())
    }

    /// The coefficients with the ones the model does not use forced to 0,
    /// so the general rational formula evaluates every model.
    fn effective(&self) -> [f64; 8] {
        let mut c = self.coefficients;
        c[self.model.coefficient_count()..].fill(0.0);
        c
    }

    /// Maps ideal normalised image coordinates `(x/z, y/z)` to distorted
    /// ones, OpenCV's formula with `r² = x² + y²`:
    /// `x' = x R + 2 p1 x y + p2 (r² + 2x²)`,
    /// `y' = y R + p1 (r² + 2y²) + 2 p2 x y`,
    /// `R = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)`.
    pub fn distort_normalised(&self, p: DVec2) -> DVec2 {
        if self.model == DistortionModel::None {
            return p;
        }
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.effective();
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial =
            (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2) / (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2);
        DVec2::new(
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        )
    }

    /// The distorted point and the Jacobian of [`Self::distort_normalised`]
    /// at `p` (symmetric: ∂x'/∂y = ∂y'/∂x).
    fn distort_with_jacobian(&self, p: DVec2) -> (DVec2, DMat2) {
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.effective();
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let num = 1.0 + ((k3 * r2 + k2) * r2 + k1) * r2;
        let den = 1.0 + ((k6 * r2 + k5) * r2 + k4) * r2;
        let dnum = k1 + (2.0 * k2 + 3.0 * k3 * r2) * r2;
        let dden = k4 + (2.0 * k5 + 3.0 * k6 * r2) * r2;
        let radial = num / den;
        // dR/d(r²)
        let dradial = (dnum * den - num * dden) / (den * den);
        let distorted = DVec2::new(
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        );
        let dxdx = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
        let dxdy = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        let dydy = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
        (
            distorted,
            DMat2::from_cols(DVec2::new(dxdx, dxdy), DVec2::new(dxdy, dydy)),
        )
    }

    /// The inverse of [`Self::distort_normalised`]: distorted normalised
    /// coordinates to ideal ones. Fixed-point iterations as OpenCV's
    /// `undistortPoints` (up to 20, stopping when the change is below
    /// 1e-12), then Newton steps where those have not converged, which
    /// happens in the corners of strongly distorted images. Where the model
    /// has no inverse (the radial factor turns negative, far outside the
    /// calibrated field of view) the point is returned as OpenCV does:
    /// unchanged at first, or the last finite estimate. Identity for `None`.
    pub fn undistort_normalised(&self, p: DVec2) -> DVec2 {
        if self.is_none() || !p.is_finite() {
            return p;
        }
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.effective();
        let mut q = p;
        let mut converged = false;
        for _ in 0..FIXED_POINT_ITERATIONS {
            let (x, y) = (q.x, q.y);
            let r2 = x * x + y * y;
            let inverse_radial =
                (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2) / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2);
            if !(inverse_radial > 0.0 && inverse_radial.is_finite()) {
                return if q == p { p } else { q };
            }
            let tangential = DVec2::new(
                2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
            );
            let next = (p - tangential) * inverse_radial;
            if !next.is_finite() {
                return q;
            }
            let change = (next - q).length();
            q = next;
            if change < CONVERGED {
                converged = true;
                break;
            }
        }
        if !converged {
            // Newton on distort(q) = p; a step is kept only if it lowers the residual.
            let (mut distorted, mut jacobian) = self.distort_with_jacobian(q);
            let mut residual = (distorted - p).length();
            for _ in 0..NEWTON_STEPS {
                if jacobian.determinant().abs() < 1e-300 {
                    break;
                }
                let step = jacobian.inverse() * (distorted - p);
                let next = q - step;
                let (d, j) = self.distort_with_jacobian(next);
                let r = (d - p).length();
                if !(r.is_finite() && next.is_finite() && r < residual) {
                    break;
                }
                (q, distorted, jacobian, residual) = (next, d, j, r);
                if step.length() < CONVERGED {
                    break;
                }
            }
        }
        q
    }

    /// A pixel of the raw (distorted) image to the pixel an ideal pinhole
    /// camera with the same K would see: normalise with K, undistort,
    /// re-apply K. The seed uses this, so that the ray it casts with
    /// [`Intrinsics::ray`] goes through the undistorted point, i.e. through
    /// the scene point that was really imaged there.
    pub fn undistort_pixel(&self, k: &Intrinsics, pixel: DVec2) -> DVec2 {
        if self.is_none() {
            return pixel;
        }
        let n = DVec2::new((pixel.x - k.cx) / k.fx, (pixel.y - k.cy) / k.fy);
        let u = self.undistort_normalised(n);
        DVec2::new(k.fx * u.x + k.cx, k.fy * u.y + k.cy)
    }

    /// The inverse of [`Self::undistort_pixel`]: where a pixel of the ideal
    /// pinhole image lands in the raw image (for drawing onto raw frames).
    pub fn distort_pixel(&self, k: &Intrinsics, pixel: DVec2) -> DVec2 {
        if self.is_none() {
            return pixel;
        }
        let n = DVec2::new((pixel.x - k.cx) / k.fx, (pixel.y - k.cy) / k.fy);
        let d = self.distort_normalised(n);
        DVec2::new(k.fx * d.x + k.cx, k.fy * d.y + k.cy)
    }
}

/// A camera calibration: pinhole intrinsics (K and the image size) and lens
/// distortion, as read from a ROS camera_info or OpenCV FileStorage YAML file.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Calibration {
    /// K and the image size the calibration was made at.
    pub intrinsics: Intrinsics,
    /// The lens distortion of the raw images.
    pub distortion: Distortion,
}

/// Calibration files are a few kilobytes; anything much larger is the wrong file.
const MAX_FILE_BYTES: u64 = 1 << 20;

/// The two file layouts, told apart by OpenCV's `%YAML:1.0` first line or
/// its `!!opencv-matrix` tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ros,
    OpenCv,
}

impl Format {
    fn detect(text: &str) -> Format {
        let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
        if first.trim_start().starts_with("%YAML:") || text.contains("!!opencv-matrix") {
            Format::OpenCv
        } else {
            Format::Ros
        }
    }

    /// Key names tried in order: ROS files use exactly the
    /// camera_calibration_parsers names; OpenCV files, written by many
    /// programs, also get the common aliases.
    fn keys(self, key: Key) -> &'static [&'static str] {
        match (self, key) {
            (Format::Ros, Key::Width) => &["image_width"],
            (Format::Ros, Key::Height) => &["image_height"],
            (Format::Ros, Key::CameraMatrix) => &["camera_matrix"],
            (Format::Ros, Key::Distortion) => &["distortion_coefficients"],
            (Format::OpenCv, Key::Width) => &["image_width", "image_Width", "imageWidth"],
            (Format::OpenCv, Key::Height) => &["image_height", "image_Height", "imageHeight"],
            (Format::OpenCv, Key::CameraMatrix) => {
                &["camera_matrix", "K", "cameraMatrix", "Camera_Matrix"]
            }
            (Format::OpenCv, Key::Distortion) => &[
                "distortion_coefficients",
                "D",
                "distCoeffs",
                "dist_coeffs",
                "Distortion_Coefficients",
            ],
        }
    }

    fn name(self) -> &'static str {
        match self {
            Format::Ros => "ROS camera_info",
            Format::OpenCv => "OpenCV FileStorage",
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Key {
    Width,
    Height,
    CameraMatrix,
    Distortion,
}

impl Calibration {
    /// Reads a ROS camera_info YAML file (camera_calibration_parsers) or an
    /// OpenCV FileStorage YAML file (`%YAML:1.0`, `!!opencv-matrix`); see
    /// [`Calibration::parse`]. Every error names the file.
    pub fn load(path: &Path) -> Result<Calibration, CaptureError> {
        let fail = |reason: String| CaptureError::Calibration {
            path: path.to_path_buf(),
            reason,
        };
        let file = std::fs::File::open(path).map_err(|e| CaptureError::io(path, e))?;
        let mut bytes = Vec::new();
        file.take(MAX_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| CaptureError::io(path, e))?;
        if bytes.len() as u64 > MAX_FILE_BYTES {
            return Err(fail(format!(
                "larger than {} KiB: not a camera calibration YAML file",
                MAX_FILE_BYTES / 1024
            )));
        }
        let text = std::str::from_utf8(&bytes).map_err(|_| {
            fail("not a camera calibration YAML file: it is not UTF-8 text".to_string())
        })?;
        Calibration::parse(text).map_err(fail)
    }

    /// Parses the text of a calibration file, in either layout:
    /// - ROS camera_info: `image_width`, `image_height`, `camera_matrix`
    ///   (`rows`, `cols`, `data`), `distortion_model`,
    ///   `distortion_coefficients`; `camera_name`, `rectification_matrix`
    ///   and `projection_matrix` are ignored (R and P describe the
    ///   rectified image; raw images are undistorted with K and D).
    /// - OpenCV FileStorage (`%YAML:1.0` first line, `!!opencv-matrix`):
    ///   `image_width`, `image_height`, `camera_matrix` (or `K`,
    ///   `cameraMatrix`), `distortion_coefficients` (or `D`, `distCoeffs`);
    ///   the model follows from the number of coefficients.
    ///
    /// Errors say what is wrong (a missing key by name, a matrix shape,
    /// a coefficient count, invalid focal lengths) without the file name,
    /// which [`Calibration::load`] adds.
    pub fn parse(text: &str) -> Result<Calibration, String> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let format = Format::detect(text);
        let docs = YamlLoader::load_from_str(&strip_opencv_directive(text))
            .map_err(|e| format!("not a valid YAML file: {e}"))?;
        let root = docs.first().unwrap_or(&Yaml::Null);
        let Yaml::Hash(map) = root else {
            return Err(format!(
                "not a camera calibration: expected a YAML mapping with keys such as image_width and camera_matrix, found {}",
                describe(root)
            ));
        };

        let (width_key, width) = required(map, format, Key::Width, "the image size")?;
        let width = pixels(width_key, width)?;
        let (height_key, height) = required(map, format, Key::Height, "the image size")?;
        let height = pixels(height_key, height)?;

        let (k_key, k_value) = required(map, format, Key::CameraMatrix, "the 3x3 camera matrix K")?;
        let k = matrix(k_key, k_value)?;
        if (k.rows, k.cols) != (3, 3) {
            return Err(format!(
                "{k_key} must be a 3x3 matrix, this one is {}x{} with {} data values",
                k.rows,
                k.cols,
                k.data.len()
            ));
        }
        let d = &k.data;
        let tolerance = 1e-9 * d[0].abs().max(d[4].abs()).max(1.0);
        for (i, expected, what) in [
            (1, 0.0, "skew K[0][1]"),
            (3, 0.0, "K[1][0]"),
            (6, 0.0, "K[2][0]"),
            (7, 0.0, "K[2][1]"),
            (8, 1.0, "K[2][2]"),
        ] {
            let off = (d[i] - expected).abs();
            if off.is_nan() || off > tolerance {
                return Err(format!(
                    "{k_key} must have the form [fx 0 cx; 0 fy cy; 0 0 1], but {what} = {} (only zero skew is supported)",
                    d[i]
                ));
            }
        }
        let intrinsics = Intrinsics {
            width,
            height,
            fx: d[0],
            fy: d[4],
            cx: d[2],
            cy: d[5],
        };
        intrinsics.validate().map_err(|e| format!("{k_key}: {e}"))?;

        let model = match map.get(&Yaml::String("distortion_model".into())) {
            None | Some(Yaml::Null) => None,
            Some(Yaml::String(s)) => Some(
                s.parse::<DistortionModel>()
                    .map_err(|e| format!("distortion_model: {e}"))?,
            ),
            Some(other) => {
                return Err(format!(
                    "distortion_model must be a name such as plumb_bob, not {}",
                    describe(other)
                ));
            }
        };
        let (d_key, d_value) = required(
            map,
            format,
            Key::Distortion,
            "the lens distortion coefficients",
        )?;
        let dist = matrix(d_key, d_value)?;
        if dist.rows != 1 && dist.cols != 1 && !dist.data.is_empty() {
            return Err(format!(
                "{d_key} must be a 1xN or Nx1 vector, this one is {}x{} with {} data values",
                dist.rows,
                dist.cols,
                dist.data.len()
            ));
        }
        let distortion = Distortion::from_coefficients(model, &dist.data)
            .map_err(|e| format!("{d_key}: {e}"))?;
        distortion.validate().map_err(|e| format!("{d_key}: {e}"))?;

        Ok(Calibration {
            intrinsics,
            distortion,
        })
    }

    /// Checks that the calibration was made at the stream's image size: K
    /// does not carry over to another resolution. The message names both
    /// sizes ("the calibration is for 1280x720 images, the stream is
    /// 640x480"); callers prefix the file name.
    pub fn check_size(&self, width: u32, height: u32) -> Result<(), String> {
        let k = &self.intrinsics;
        if (k.width, k.height) == (width, height) {
            Ok(())
        } else {
            Err(format!(
                "the calibration is for {}x{} images, the stream is {width}x{height}",
                k.width, k.height
            ))
        }
    }

    /// [`Distortion::undistort_pixel`] with this calibration's K.
    pub fn undistort_pixel(&self, pixel: DVec2) -> DVec2 {
        self.distortion.undistort_pixel(&self.intrinsics, pixel)
    }
}

/// Comments out OpenCV's `%YAML:1.0` first line, which YAML parsers refuse
/// (the directive needs a space), keeping line numbers for error messages.
fn strip_opencv_directive(text: &str) -> Cow<'_, str> {
    let start = text.len() - text.trim_start().len();
    if text[start..].starts_with("%YAML:") {
        let mut out = String::with_capacity(text.len() + 2);
        out.push_str(&text[..start]);
        out.push_str("# ");
        out.push_str(&text[start..]);
        Cow::Owned(out)
    } else {
        Cow::Borrowed(text)
    }
}

/// The first of the format's names for `key` that the file has, or an error
/// naming the key (and its aliases).
fn required<'a>(
    map: &'a Hash,
    format: Format,
    key: Key,
    what: &str,
) -> Result<(&'static str, &'a Yaml), String> {
    let names = format.keys(key);
    for &name in names {
        if let Some(value) = map.get(&Yaml::String(name.to_string())) {
            return Ok((name, value));
        }
    }
    let aliases = if names.len() > 1 {
        format!(" (or {})", names[1..].join(", "))
    } else {
        String::new()
    };
    Err(format!(
        "missing key '{}'{aliases}: {what} ({} calibration file)",
        names[0],
        format.name()
    ))
}

/// An image dimension in pixels.
fn pixels(key: &str, value: &Yaml) -> Result<u32, String> {
    match value {
        Yaml::Integer(i) => u32::try_from(*i).ok(),
        _ => None,
    }
    .ok_or_else(|| {
        format!(
            "{key} must be a whole number of pixels, not {}",
            describe(value)
        )
    })
}

/// A matrix as both formats write it: a mapping with `rows`, `cols` and a
/// row-major `data` list (OpenCV adds `dt`, the element type).
struct Matrix {
    rows: usize,
    cols: usize,
    data: Vec<f64>,
}

fn matrix(key: &str, value: &Yaml) -> Result<Matrix, String> {
    let Yaml::Hash(m) = value else {
        return Err(format!(
            "{key} must be a matrix with rows, cols and data, not {}",
            describe(value)
        ));
    };
    let dim = |name: &str| -> Result<usize, String> {
        match m.get(&Yaml::String(name.to_string())) {
            None => Err(format!("{key}: missing '{name}'")),
            Some(Yaml::Integer(i)) => usize::try_from(*i)
                .ok()
                .filter(|&n| n <= 1000)
                .ok_or_else(|| format!("{key}: {name} = {i} is not a matrix dimension")),
            Some(other) => Err(format!(
                "{key}: {name} must be a whole number, not {}",
                describe(other)
            )),
        }
    };
    let rows = dim("rows")?;
    let cols = dim("cols")?;
    let data = match m.get(&Yaml::String("data".into())) {
        None => return Err(format!("{key}: missing 'data'")),
        Some(Yaml::Array(items)) => items
            .iter()
            .enumerate()
            .map(|(i, item)| {
                number(item)
                    .ok_or_else(|| format!("{key}: data[{i}] = {} is not a number", describe(item)))
            })
            .collect::<Result<Vec<f64>, String>>()?,
        Some(other) => {
            return Err(format!(
                "{key}: data must be a list of numbers, not {}",
                describe(other)
            ));
        }
    };
    if rows * cols != data.len() {
        return Err(format!(
            "{key} is declared {rows}x{cols} (rows x cols) but has {} data values instead of {}",
            data.len(),
            rows * cols
        ));
    }
    Ok(Matrix { rows, cols, data })
}

/// A YAML number (OpenCV writes floats such as `0.` and `5.25e+02`).
fn number(value: &Yaml) -> Option<f64> {
    match value {
        Yaml::Integer(i) => Some(*i as f64),
        Yaml::Real(_) => value.as_f64(),
        _ => None,
    }
}

/// A YAML value as an error message shows it.
fn describe(value: &Yaml) -> String {
    match value {
        Yaml::Real(s) => s.clone(),
        Yaml::Integer(i) => i.to_string(),
        Yaml::String(s) => {
            let short: String = s.chars().take(40).collect();
            let dots = if short.len() < s.len() { "..." } else { "" };
            format!("the text '{short}{dots}'")
        }
        Yaml::Boolean(b) => b.to_string(),
        Yaml::Array(a) => format!("a list of {} items", a.len()),
        Yaml::Hash(_) => "a mapping".to_string(),
        Yaml::Null => "nothing".to_string(),
        Yaml::Alias(_) | Yaml::BadValue => "an unreadable value".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plumb() -> Distortion {
        Distortion::plumb_bob([-0.28, 0.09, 0.0012, -0.0007, -0.011])
    }

    fn rational() -> Distortion {
        Distortion::rational_polynomial([0.61, 0.05, 0.0009, -0.0004, 0.001, 0.69, 0.11, 0.004])
    }

    #[test]
    fn model_names_round_trip() {
        for m in [
            DistortionModel::None,
            DistortionModel::PlumbBob,
            DistortionModel::RationalPolynomial,
        ] {
            assert_eq!(m.to_string().parse::<DistortionModel>(), Ok(m));
        }
        assert_eq!("".parse::<DistortionModel>(), Ok(DistortionModel::None));
        let err = "equidistant".parse::<DistortionModel>().unwrap_err();
        assert!(
            err.contains("equidistant") && err.contains("plumb_bob"),
            "{err}"
        );
        assert!(
            "bogus"
                .parse::<DistortionModel>()
                .unwrap_err()
                .contains("bogus")
        );
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let h = 1e-6;
        for d in [plumb(), rational()] {
            for p in [
                DVec2::new(0.3, -0.2),
                DVec2::new(-0.55, 0.41),
                DVec2::new(0.01, 0.6),
            ] {
                let (_, j) = d.distort_with_jacobian(p);
                let dx = (d.distort_normalised(p + DVec2::X * h)
                    - d.distort_normalised(p - DVec2::X * h))
                    / (2.0 * h);
                let dy = (d.distort_normalised(p + DVec2::Y * h)
                    - d.distort_normalised(p - DVec2::Y * h))
                    / (2.0 * h);
                assert!((j.x_axis - dx).length() < 1e-8, "{:?} vs {dx:?}", j.x_axis);
                assert!((j.y_axis - dy).length() < 1e-8, "{:?} vs {dy:?}", j.y_axis);
            }
        }
    }

    #[test]
    fn undistort_inverts_distort_in_normalised_coordinates() {
        for d in [plumb(), rational()] {
            for p in [
                DVec2::new(0.0, 0.0),
                DVec2::new(0.5, -0.4),
                DVec2::new(-0.7, 0.5),
            ] {
                let back = d.distort_normalised(d.undistort_normalised(p));
                assert!((back - p).length() < 1e-12, "{d:?} {p:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn newton_finishes_slow_fixed_point_iterations() {
        // Strong barrel distortion at an image corner: 20 fixed-point
        // iterations alone leave a residual of about 4e-10 (2e-7 px).
        let d = Distortion::plumb_bob([-0.42, 0.2, 0.0, 0.0, -0.04]);
        let p = DVec2::new(-0.607, -0.459);
        let back = d.distort_normalised(d.undistort_normalised(p));
        assert!((back - p).length() < 1e-13, "{:e}", (back - p).length());
    }

    #[test]
    fn no_distortion_is_identity() {
        let d = Distortion::default();
        assert!(d.is_none());
        let p = DVec2::new(0.3, -0.9);
        assert_eq!(d.distort_normalised(p), p);
        assert_eq!(d.undistort_normalised(p), p);
        assert!(Distortion::plumb_bob([0.0; 5]).is_none());
        assert!(!plumb().is_none());
    }

    #[test]
    fn unused_coefficients_do_not_count_and_are_refused() {
        let mut d = plumb();
        d.coefficients[6] = 0.5;
        let p = DVec2::new(0.4, 0.3);
        assert_eq!(d.distort_normalised(p), plumb().distort_normalised(p));
        let err = d.validate().unwrap_err().to_string();
        assert!(err.contains("k5") && err.contains("plumb_bob"), "{err}");
    }

    #[test]
    fn validate_refuses_non_finite_coefficients() {
        assert!(plumb().validate().is_ok());
        let mut d = rational();
        d.coefficients[3] = f64::NAN;
        let err = d.validate().unwrap_err().to_string();
        assert!(err.contains("p2") && err.contains("finite"), "{err}");
        d.coefficients[3] = f64::INFINITY;
        assert!(d.validate().is_err());
    }

    #[test]
    fn coefficient_counts() {
        let four = Distortion::from_coefficients(None, &[0.1, 0.2, 0.3, 0.4]).unwrap();
        assert_eq!(four.model, DistortionModel::PlumbBob);
        assert_eq!(four.coefficients, [0.1, 0.2, 0.3, 0.4, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            Distortion::from_coefficients(None, &[]).unwrap(),
            Distortion::default()
        );
        let eight = Distortion::from_coefficients(None, &[1.0; 8]).unwrap();
        assert_eq!(eight.model, DistortionModel::RationalPolynomial);
        for n in [1, 2, 3, 6, 7, 12, 14] {
            let err = Distortion::from_coefficients(None, &vec![0.1; n]).unwrap_err();
            assert!(
                err.starts_with(&format!("{n} distortion coefficients")),
                "{err}"
            );
        }
        let err =
            Distortion::from_coefficients(Some(DistortionModel::RationalPolynomial), &[0.1; 5])
                .unwrap_err();
        assert!(
            err.contains("rational_polynomial") && err.contains("5 are given"),
            "{err}"
        );
        assert!(
            Distortion::from_coefficients(Some(DistortionModel::None), &[0.0; 5])
                .unwrap()
                .is_none()
        );
        assert!(Distortion::from_coefficients(Some(DistortionModel::None), &[0.1; 5]).is_err());
    }

    #[test]
    fn opencv_directive_is_commented_out() {
        assert_eq!(
            strip_opencv_directive("%YAML:1.0\n---\na: 1\n"),
            "# %YAML:1.0\n---\na: 1\n"
        );
        assert_eq!(strip_opencv_directive("a: 1\n"), "a: 1\n");
        assert_eq!(Format::detect("\n%YAML:1.0\n"), Format::OpenCv);
        assert_eq!(Format::detect("k: !!opencv-matrix\n"), Format::OpenCv);
        assert_eq!(Format::detect("image_width: 3\n"), Format::Ros);
    }

    const OPENCV_4: &str = "%YAML:1.0\n---\nimage_width: 320\nimage_height: 240\n\
        K: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 300., 0., 160., 0., 301., 120.,\n       0., 0., 1. ]\n\
        D: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n   data: [ -1.0e-01, 2.e-02, 1.0e-03,\n       -2.0e-03 ]\n";

    #[test]
    fn opencv_aliases_and_four_coefficients() {
        let c = Calibration::parse(OPENCV_4).unwrap();
        assert_eq!((c.intrinsics.width, c.intrinsics.height), (320, 240));
        assert_eq!(
            (
                c.intrinsics.fx,
                c.intrinsics.fy,
                c.intrinsics.cx,
                c.intrinsics.cy
            ),
            (300.0, 301.0, 160.0, 120.0)
        );
        assert_eq!(c.distortion.model, DistortionModel::PlumbBob);
        assert_eq!(
            c.distortion.coefficients,
            [-0.1, 0.02, 0.001, -0.002, 0.0, 0.0, 0.0, 0.0]
        );
    }

    #[test]
    fn ros_files_do_not_take_opencv_aliases() {
        let ros = OPENCV_4
            .replace("%YAML:1.0\n", "")
            .replace(" !!opencv-matrix", "");
        let err = Calibration::parse(&ros).unwrap_err();
        assert!(err.contains("missing key 'camera_matrix'"), "{err}");
    }

    #[test]
    fn skew_and_non_finite_values_are_refused() {
        let skewed = OPENCV_4.replace("300., 0., 160.", "300., 2., 160.");
        let err = Calibration::parse(&skewed).unwrap_err();
        assert!(err.contains("skew") && err.contains("K"), "{err}");
        let nan = OPENCV_4.replace("300., 0., 160.", ".nan, 0., 160.");
        let err = Calibration::parse(&nan).unwrap_err();
        assert!(err.contains("focal"), "{err}");
        let nan_d = OPENCV_4.replace("-1.0e-01", ".nan");
        let err = Calibration::parse(&nan_d).unwrap_err();
        assert!(
            err.contains("D:") && err.contains("k1") && err.contains("finite"),
            "{err}"
        );
    }

    #[test]
    fn non_mapping_text_is_not_a_calibration() {
        let err = Calibration::parse("hello world").unwrap_err();
        assert!(
            err.contains("not a camera calibration") && err.contains("hello world"),
            "{err}"
        );
        let err = Calibration::parse("").unwrap_err();
        assert!(err.contains("not a camera calibration"), "{err}");
        // Deep nesting is an error, not a stack overflow.
        let err = Calibration::parse(&"[".repeat(100_000)).unwrap_err();
        assert!(err.contains("not a valid YAML file"), "{err}");
    }
}
