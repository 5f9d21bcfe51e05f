//! One module per subcommand: argument parsing and I/O around the stage crates.

pub mod render;
