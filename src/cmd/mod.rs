//! One module per subcommand: argument parsing and I/O around the stage crates.

pub mod common;
pub mod estimate;
pub mod eval;
pub mod features;
pub mod render;
pub mod run;
pub mod train;
