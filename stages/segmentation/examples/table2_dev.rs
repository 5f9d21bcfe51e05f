//! TEMP: compiles and runs src/cmd/table2.rs outside the `acch` binary.
#![allow(dead_code)]
mod cmd {
    #[path = "/work/main/src/cmd/common.rs"]
    pub mod common;
    pub mod eval {
        pub const PAPER_GRID: &str = "grid:45,50,60,70,80,90:10";
        pub const FAIL_THETA_DEG: f32 = 10.0;
        pub const FAIL_PHI_DEG: f32 = 20.0;
    }
    #[path = "/work/main/src/cmd/table2.rs"]
    pub mod table2;
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(String::as_str).unwrap_or("fruitbox");
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(50);
    let q: f32 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0.99);
    let object = std::sync::Arc::new(acch_capture::Object::builtin(name)?);
    let mut config = acch_pose::train::TrainConfig::default();
    config.reject_quantile = Some(q);
    let json = std::path::PathBuf::from(format!("/tmp/table2_{name}.json"));
    cmd::table2::table2(object, n, 1, &config, Some(&json))
}
