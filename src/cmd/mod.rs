//! One module per subcommand: argument parsing and I/O around the stage crates.

pub mod bench;
pub mod common;
pub mod estimate;
pub mod eval;
pub mod features;
pub mod launch;
pub mod listen;
pub(crate) mod observe;
pub mod record;
pub mod render;
pub mod run;
pub mod sequence;
pub mod stage;
pub mod table2;
pub mod train;
pub mod viz;
