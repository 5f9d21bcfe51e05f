//! The on-disk label format of a view dataset: a CSV file with one row per
//! image, written by `acch render` and also used to label real images.
//!
//! ```text
//! file,theta_deg,phi_deg,distance_m,bbox_x,bbox_y,bbox_w,bbox_h,mask,roll_deg
//! view_0000.png,45,0,1.03,270,180,101,121,view_0000_mask.png,0
//! ```
//!
//! Paths are relative to the directory of the labels file. The bounding box
//! (all four columns) and the mask may be empty or the columns absent; the
//! camera roll `roll_deg` (degrees about the optical axis, see
//! [`crate::ViewPose::roll_deg`]) reads as 0 when empty or absent, so files
//! written before it existed still load. The columns may come in any order
//! and unknown columns are ignored. Fields
//! containing commas or quotes are quoted the usual CSV way.

use std::fmt::Write as _;
use std::path::Path;

use crate::camera::{wrap_deg, wrap_roll_deg};
use crate::{BBox, CaptureError, GroundTruth};

/// The header line written by [`write_labels`].
pub const HEADER: &str =
    "file,theta_deg,phi_deg,distance_m,bbox_x,bbox_y,bbox_w,bbox_h,mask,roll_deg";

/// One labelled image.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelRow {
    /// Image path, relative to the labels file's directory.
    pub file: String,
    /// Camera elevation in degrees, [0, 90].
    pub theta_deg: f64,
    /// Camera azimuth in degrees, [0, 360).
    pub phi_deg: f64,
    /// Camera distance to the object centre, metres.
    pub distance_m: f64,
    /// Bounding box of the object in the image, if known.
    pub bbox: Option<BBox>,
    /// Object mask image path (relative, 255 = object), if known.
    pub mask: Option<String>,
    /// Camera roll about its optical axis in degrees, (-180, 180]; 0 when
    /// the file has no `roll_deg` column.
    pub roll_deg: f64,
}

impl LabelRow {
    /// A row for a rendered image from its ground truth, of an object
    /// whose real bounding radius is `radius_m` (the renderer's distances
    /// are in bounding radii).
    pub fn from_truth(
        file: impl Into<String>,
        mask: Option<String>,
        truth: &GroundTruth,
        radius_m: f64,
    ) -> Self {
        LabelRow {
            file: file.into(),
            theta_deg: truth.theta_deg,
            phi_deg: truth.phi_deg,
            distance_m: truth.distance * radius_m,
            bbox: truth.bbox,
            mask,
            roll_deg: truth.roll_deg,
        }
    }
}

fn quote(field: &str) -> String {
    if field.contains([',', '"', '\n', '\r']) || field.trim() != field {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}

/// Writes rows to a labels file (with [`HEADER`]). Numbers are written so
/// that they read back exactly.
pub fn write_labels(path: impl AsRef<Path>, rows: &[LabelRow]) -> Result<(), CaptureError> {
    let path = path.as_ref();
    let mut s = String::with_capacity(64 * (rows.len() + 1));
    s.push_str(HEADER);
    s.push('\n');
    for r in rows {
        let _ = write!(
            s,
            "{},{},{},{},",
            quote(&r.file),
            r.theta_deg,
            r.phi_deg,
            r.distance_m
        );
        match r.bbox {
            Some(b) => {
                let _ = write!(s, "{},{},{},{},", b.x, b.y, b.width, b.height);
            }
            None => s.push_str(",,,,"),
        }
        if let Some(m) = &r.mask {
            s.push_str(&quote(m));
        }
        let _ = write!(s, ",{}", r.roll_deg);
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|e| CaptureError::io(path, e))
}

/// Splits one CSV line into fields (double quotes, "" escapes).
fn split_csv(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    let mut was_quoted = false;
    while let Some(c) = chars.next() {
        if quoted {
            match c {
                '"' if chars.peek() == Some(&'"') => {
                    cur.push('"');
                    chars.next();
                }
                '"' => quoted = false,
                _ => cur.push(c),
            }
        } else {
            match c {
                '"' if cur.trim().is_empty() => {
                    cur.clear();
                    quoted = true;
                    was_quoted = true;
                }
                ',' => {
                    fields.push(if was_quoted {
                        std::mem::take(&mut cur)
                    } else {
                        cur.trim().to_string()
                    });
                    cur.clear();
                    was_quoted = false;
                }
                _ => cur.push(c),
            }
        }
    }
    if quoted {
        return Err("unterminated quoted field".to_string());
    }
    fields.push(if was_quoted {
        cur
    } else {
        cur.trim().to_string()
    });
    Ok(fields)
}

/// Reads a labels file. Errors name the file, the 1-based line and what is
/// wrong (missing column, bad number, angle out of range, partial bbox...).
pub fn read_labels(path: impl AsRef<Path>) -> Result<Vec<LabelRow>, CaptureError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| CaptureError::io(path, e))?;
    parse_labels(&text, path)
}

/// Parses the text of a labels file; `path` only names it in errors.
pub fn parse_labels(text: &str, path: &Path) -> Result<Vec<LabelRow>, CaptureError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let err = |line: usize, reason: String| CaptureError::Labels {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((hline, header)) = lines.next() else {
        return Err(err(
            1,
            format!("empty file; expected the header '{HEADER}'"),
        ));
    };
    let names = split_csv(header).map_err(|e| err(hline, e))?;
    let col = |name: &str| names.iter().position(|n| n == name);
    if col("distance").is_some() && col("distance_m").is_none() {
        // The column was in object bounding radii before distances became
        // metric: reading it as metres would be silently wrong.
        return Err(err(
            hline,
            "the column 'distance' (object bounding radii) is now 'distance_m', in metres: \
             multiply by the object's bounding radius in metres and rename it"
                .to_string(),
        ));
    }
    let need = |name: &str| {
        col(name).ok_or_else(|| {
            err(
                hline,
                format!("header lacks the column '{name}' (expected '{HEADER}')"),
            )
        })
    };
    let (c_file, c_theta, c_phi, c_dist) = (
        need("file")?,
        need("theta_deg")?,
        need("phi_deg")?,
        need("distance_m")?,
    );
    let c_bbox = [col("bbox_x"), col("bbox_y"), col("bbox_w"), col("bbox_h")];
    let c_mask = col("mask");
    let c_roll = col("roll_deg");

    let mut rows = Vec::new();
    for (ln, line) in lines {
        let f = split_csv(line).map_err(|e| err(ln, e))?;
        if f.len() != names.len() {
            return Err(err(
                ln,
                format!(
                    "expected {} fields like the header, found {}",
                    names.len(),
                    f.len()
                ),
            ));
        }
        let num = |c: usize| -> Result<f64, CaptureError> {
            f[c].parse::<f64>().map_err(|_| {
                err(
                    ln,
                    format!("column {}: '{}' is not a number", names[c], f[c]),
                )
            })
        };
        let file = f[c_file].clone();
        if file.is_empty() {
            return Err(err(ln, "column file is empty".to_string()));
        }
        let theta_deg = num(c_theta)?;
        if !(0.0..=90.0).contains(&theta_deg) {
            return Err(err(ln, format!("theta_deg {theta_deg} is outside [0, 90]")));
        }
        let phi_deg = num(c_phi)?;
        if !phi_deg.is_finite() {
            return Err(err(ln, format!("phi_deg {phi_deg} is not finite")));
        }
        let distance_m = num(c_dist)?;
        if !(distance_m.is_finite() && distance_m > 0.0) {
            return Err(err(
                ln,
                format!("distance_m {distance_m} must be a positive number of metres"),
            ));
        }
        let bvals: Vec<Option<&str>> = c_bbox
            .iter()
            .map(|c| c.map(|c| f[c].as_str()).filter(|v| !v.is_empty()))
            .collect();
        let bbox = if bvals.iter().all(Option::is_none) {
            None
        } else if let [Some(x), Some(y), Some(w), Some(h)] = bvals[..] {
            let int = |name: &str, v: &str| {
                v.parse::<u32>().map_err(|_| {
                    err(
                        ln,
                        format!("column {name}: '{v}' is not a whole number >= 0"),
                    )
                })
            };
            let b = BBox {
                x: int("bbox_x", x)?,
                y: int("bbox_y", y)?,
                width: int("bbox_w", w)?,
                height: int("bbox_h", h)?,
            };
            if b.width == 0 || b.height == 0 {
                return Err(err(ln, "bbox_w and bbox_h must be at least 1".to_string()));
            }
            Some(b)
        } else {
            return Err(err(
                ln,
                "bbox_x, bbox_y, bbox_w, bbox_h must be all set or all empty".to_string(),
            ));
        };
        let mask = c_mask.map(|c| f[c].clone()).filter(|m| !m.is_empty());
        let roll_deg = match c_roll.filter(|&c| !f[c].is_empty()) {
            None => 0.0,
            Some(c) => {
                let roll = num(c)?;
                if !roll.is_finite() {
                    return Err(err(ln, format!("roll_deg {roll} is not finite")));
                }
                wrap_roll_deg(roll)
            }
        };
        rows.push(LabelRow {
            file,
            theta_deg,
            phi_deg: wrap_deg(phi_deg),
            distance_m,
            bbox,
            mask,
            roll_deg,
        });
    }
    Ok(rows)
}
