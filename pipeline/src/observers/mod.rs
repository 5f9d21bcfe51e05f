//! The observers: the rerun viewer and the MCAP recorder, each an
//! [`Observe`](crate::Observe) that runs in one process with the chain or as
//! a process of its own.

pub mod record;
pub mod viz;

pub use record::{RecordSummary, Recording, RunRecording, run_record};
pub use viz::{ViewerThread, Viewing, VizSummary, run_viz};

/// (θ, φ) of every view of `db`, degrees, in database order: what the
/// viewer lays the response out by.
pub fn view_angles(db: &acch_core::ViewDatabase) -> Vec<(f32, f32)> {
    db.views()
        .iter()
        .map(|v| (v.theta_deg, v.phi_deg))
        .collect()
}
