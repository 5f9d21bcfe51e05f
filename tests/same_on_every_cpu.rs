//! A database trained on one CPU is the one trained on another: glibc picks
//! its `exp` and `tanh` code by the CPU's features (AVX2, FMA, AVX-512), and
//! the confidence network, trained with the system's, came out different
//! when those features were hidden. Hiding them with `GLIBC_TUNABLES` on
//! this machine stands in for an older CPU. On a CPU without the features,
//! or a C library that ignores the variable, both runs take the same path.

mod common;

use common::ok;
use std::process::Command;

/// Trains fruitbox into `out` in `dir`, with the CPU features glibc
/// dispatches on hidden when `hide` holds.
fn train(dir: &std::path::Path, out: &str, hide: bool) -> Vec<u8> {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_acch"));
    cmd.args([
        "train",
        "--object",
        "fruitbox",
        "--views",
        "grid:45,60,90:10",
        // Enough scenes that the old network's training differed (30 did
        // not show it).
        "--confidence-scenes",
        "60",
        "--out",
        out,
    ])
    .current_dir(dir)
    .env("RUST_LOG", "warn");
    if hide {
        cmd.env(
            "GLIBC_TUNABLES",
            "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F,-AVX_Fast_Unaligned_Load",
        );
    } else {
        cmd.env_remove("GLIBC_TUNABLES");
    }
    ok(&cmd.output().expect("run acch"));
    std::fs::read(dir.join(out)).unwrap()
}

#[test]
fn a_database_trained_with_the_cpus_math_features_hidden_is_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let with = train(dir.path(), "with.acchdb", false);
    let without = train(dir.path(), "without.acchdb", true);
    assert!(with.len() > 1000, "a database was written");
    assert!(
        with == without,
        "the database differs with the CPU's features hidden ({} and {} bytes)",
        with.len(),
        without.len()
    );
}
