//! The viewer's default layout (a rerun blueprint), sent by the `viz`
//! process when it opens its sink, so a recording opens as a debugging
//! view instead of rerun's automatic grid:
//!
//! ```text
//! +------------------------------+-----------------+---------------+
//! |                              |                 | θ             |
//! |  camera: frame, detection,   |  3-D: frustum,  +---------------+
//! |  ROI, mask, seed axes        |  seed, fused,   | φ             |
//! |                              |  truth          +---------------+
//! |                              |                 | confidence    |
//! +------------------------------+----------+------+---------------+
//! |  match-value response (θ slices)        |  latency (stacked)   |
//! |                                         |  viewer drops        |
//! +-----------------------------------------+----------------------+
//! ```
//!
//! [`PANELS`] lists every view with the entities it shows; a test checks
//! each against what [`crate::Logger`] logs.

use rerun::blueprint::components::{PanelState, PlayState};
use rerun::blueprint::{
    Blueprint, BlueprintActivation, BlueprintOpts, BlueprintPanel, ContainerLike, Horizontal,
    SelectionPanel, Spatial2DView, Spatial3DView, TimePanel, TimeSeriesView, Vertical,
};

/// What kind of rerun view a panel is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A 2-D spatial view.
    Spatial2D,
    /// A 3-D spatial view.
    Spatial3D,
    /// Scalars over the `frame` timeline.
    TimeSeries,
}

/// One view of the layout.
#[derive(Clone, Copy, Debug)]
pub struct Panel {
    /// Its title.
    pub name: &'static str,
    /// Its kind.
    pub kind: Kind,
    /// The entity it is rooted at; it shows everything below.
    pub origin: &'static str,
}

/// The camera view.
pub const CAMERA: Panel = Panel {
    name: "camera: detection, ROI, mask, seed axes",
    kind: Kind::Spatial2D,
    origin: "world/camera/image",
};
/// The 3-D view.
pub const SCENE: Panel = Panel {
    name: "3-D: camera, seed, fused, truth",
    kind: Kind::Spatial3D,
    origin: "world",
};
/// θ over time.
pub const THETA: Panel = Panel {
    name: "θ (deg): estimate, fused, truth",
    kind: Kind::TimeSeries,
    origin: "plot/theta",
};
/// φ over time.
pub const PHI: Panel = Panel {
    name: "φ (deg): estimate, fused, truth",
    kind: Kind::TimeSeries,
    origin: "plot/phi",
};
/// Confidence and threshold over time.
pub const CONFIDENCE: Panel = Panel {
    name: "confidence, threshold, rejected",
    kind: Kind::TimeSeries,
    origin: "plot/confidence",
};
/// The current frame's response.
pub const RESPONSE: Panel = Panel {
    name: "match value per database view (θ slice by θ slice, φ ascending)",
    kind: Kind::Spatial2D,
    origin: "response",
};
/// Latency, stacked.
pub const LATENCY: Panel = Panel {
    name: "latency (ms since capture, stacked by stage)",
    kind: Kind::TimeSeries,
    origin: "plot/latency",
};
/// The viewer's drops.
pub const DROPPED: Panel = Panel {
    name: "frames the viewer dropped",
    kind: Kind::TimeSeries,
    origin: "plot/dropped",
};

/// Every view of the layout.
pub const PANELS: [Panel; 8] = [
    CAMERA, SCENE, THETA, PHI, CONFIDENCE, RESPONSE, LATENCY, DROPPED,
];

fn view(p: Panel) -> ContainerLike {
    let contents = ["$origin/**"];
    match p.kind {
        Kind::Spatial2D => Spatial2DView::new(p.name)
            .with_origin(p.origin)
            .with_contents(contents)
            .into(),
        Kind::Spatial3D => Spatial3DView::new(p.name)
            .with_origin(p.origin)
            .with_contents(contents)
            .into(),
        Kind::TimeSeries => TimeSeriesView::new(p.name)
            .with_origin(p.origin)
            .with_contents(contents)
            .into(),
    }
}

/// The layout above, made the default and active one. The side panels
/// start collapsed so the views get the window; the time panel follows
/// the newest frame while a run streams.
pub fn blueprint() -> BlueprintOpts {
    let plots = Vertical::new([view(THETA), view(PHI), view(CONFIDENCE)]);
    let top = Horizontal::new([view(CAMERA), view(SCENE), plots.into()])
        .with_column_shares([0.47, 0.27, 0.26]);
    let health = Vertical::new([view(LATENCY), view(DROPPED)]).with_row_shares([0.72, 0.28]);
    let bottom = Horizontal::new([view(RESPONSE), health.into()]).with_column_shares([0.62, 0.38]);
    let root = Vertical::new([top.into(), bottom.into()]).with_row_shares([0.62, 0.38]);
    BlueprintOpts {
        blueprint: Blueprint::new(root)
            .with_auto_views(false)
            .with_auto_layout(false)
            .with_blueprint_panel(BlueprintPanel::from_state(PanelState::Collapsed))
            .with_selection_panel(SelectionPanel::from_state(PanelState::Collapsed))
            .with_time_panel(
                TimePanel::new()
                    .with_state(PanelState::Collapsed)
                    .with_timeline("frame")
                    .with_play_state(PlayState::Following),
            ),
        activation: BlueprintActivation {
            make_active: true,
            make_default: true,
        },
    }
}
