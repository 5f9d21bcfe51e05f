//! `acch features`: an image's histogram as a NumPy `.npy` array, so Python
//! users can work with exactly what the estimator sees.

use super::estimate::{Input, load_input};
use anyhow::{Context, Result};
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `acch features`.
#[derive(Args)]
pub struct FeaturesArgs {
    #[command(flatten)]
    input: Input,
    /// Output `.npy` file: float32, shape (D, C, C) indexed [orientation,
    /// colour at the reference pixel, colour at the other pixel].
    #[arg(long, value_name = "FILE.npy")]
    out: PathBuf,
}

/// Runs `acch features`.
pub fn run(args: FeaturesArgs) -> Result<()> {
    let Some(mut loaded) = load_input(&args.input, None)? else {
        anyhow::bail!("{}: the object was not found", args.input.image.display());
    };
    let pairs = loaded.respond();
    let params = loaded.estimator.database().params;
    let shape = [
        params.geometric_bins(),
        params.colours as usize,
        params.colours as usize,
    ];
    write_npy(&args.out, loaded.estimator.histogram(), &shape)?;
    println!(
        "{} pixel pairs -> {} ({}x{}x{} float32)",
        pairs,
        args.out.display(),
        shape[0],
        shape[1],
        shape[2]
    );
    Ok(())
}

/// Writes a little-endian float32 array in NumPy's format version 1.0.
pub fn write_npy(path: &Path, data: &[f32], shape: &[usize]) -> Result<()> {
    assert_eq!(data.len(), shape.iter().product::<usize>());
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is a multiple of 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + data.len() * 4);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(&out))
        .with_context(|| format!("writing {}", path.display()))
}
