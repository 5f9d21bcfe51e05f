//! The observers: the rerun viewer and the MCAP recorder, each an
//! [`Observe`](crate::Observe) that runs in one process with the chain or as
//! a process of its own.

pub mod record;
pub mod viz;

pub use record::{RecordSummary, Recording, run_record};
pub use viz::{ViewerThread, Viewing, VizSummary, run_viz};
