//! One module per subcommand: arguments, printing and dispatch into the
//! library crates.

pub mod bench;
pub mod common;
pub mod estimate;
pub mod eval;
pub mod features;
pub mod listen;
pub mod render;
pub mod run;
pub mod stage;
pub mod train;
