//! A database trained on one CPU is the one trained on another: glibc picks
//! its `exp` and `tanh` code by the CPU's features (AVX2, FMA, AVX-512), and
//! the confidence network, trained with the system's, came out different
//! when those features were hidden. Hiding them with `GLIBC_TUNABLES` on
//! this machine stands in for an older CPU. On a CPU without the features,
//! or a C library that ignores the variable, both runs would take the same
//! path and prove nothing: the test first asks the dynamic loader
//! (`ld.so --list-diagnostics`) which features are active with and without
//! the variable, and fails when hiding changed nothing.

mod common;

use common::ok;
use std::process::Command;

/// The features glibc hides: what its math functions dispatch on.
const HIDDEN: &str = "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F,-AVX_Fast_Unaligned_Load";

/// The CPU features the dynamic loader reports active (its
/// `x86.cpu_features...active` lines), with the features hidden when
/// `hide` holds.
fn active_features(hide: bool) -> Vec<String> {
    let mut cmd = Command::new("ld.so");
    cmd.arg("--list-diagnostics");
    if hide {
        cmd.env("GLIBC_TUNABLES", HIDDEN);
    } else {
        cmd.env_remove("GLIBC_TUNABLES");
    }
    let out = cmd
        .output()
        .expect("run `ld.so --list-diagnostics` (glibc 2.33 or later): it tells whether hiding the CPU's features takes effect");
    ok(&out);
    let lines: Vec<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| l.starts_with("x86.cpu_features.") && l.contains(".active["))
        .map(str::to_owned)
        .collect();
    assert!(
        !lines.is_empty(),
        "ld.so lists no x86 CPU features: this test needs an x86-64 glibc to hide them"
    );
    lines
}

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
        cmd.env("GLIBC_TUNABLES", HIDDEN);
    } else {
        cmd.env_remove("GLIBC_TUNABLES");
    }
    ok(&cmd.output().expect("run acch"));
    std::fs::read(dir.join(out)).unwrap()
}

#[test]
fn a_database_trained_with_the_cpus_math_features_hidden_is_the_same_bytes() {
    assert_ne!(
        active_features(false),
        active_features(true),
        "hiding the CPU's features with GLIBC_TUNABLES changed nothing on this machine: both trainings would take one path"
    );
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
