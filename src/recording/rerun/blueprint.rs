//! The layout a recording opens on in the viewer.

use re_sdk::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial2DView, Spatial3DView, Tabs, TextLogView,
    TimePanel, TimeSeriesView, Vertical,
};
use re_sdk_types::blueprint::components::PlayState;

/// The layout the recording opens on: the bodies and contacts on the left; the solver
/// residuals, the energies and the text log on the right; the `iteration` timeline selected.
pub(super) fn blueprint<const D: usize>() -> Blueprint {
    let contents = ["bodies/**", "obstacles/**", "contacts/**"];
    let scene: ContainerLike = if D == 2 {
        Spatial2DView::new("Bodies and contacts")
            .with_contents(contents)
            .into()
    } else {
        Spatial3DView::new("Bodies and contacts")
            .with_contents(contents)
            .into()
    };
    let residuals = Tabs::new([
        TimeSeriesView::new("Residual norm [N]")
            .with_contents(["solver/residual_norm"])
            .into(),
        TimeSeriesView::new("Relative residual")
            .with_contents(["solver/relative_residual"])
            .into(),
        TimeSeriesView::new("Increment norm [m/s]")
            .with_contents(["solver/increment_norm"])
            .into(),
    ]);
    let plots = Vertical::new([
        residuals.into(),
        TimeSeriesView::new("Active set")
            .with_contents(["solver/active_set_size", "solver/candidates"])
            .into(),
        TimeSeriesView::new("Energy [J]")
            .with_origin("energy")
            .into(),
        TextLogView::new("Log").with_origin("log").into(),
    ]);
    // Following: the viewer opens on the last iteration recorded (live: the newest).
    let time = TimePanel::new()
        .with_timeline("iteration")
        .with_play_state(PlayState::Following);
    Blueprint::new(Horizontal::new([scene, plots.into()]).with_column_shares(vec![2.0, 1.0]))
        .with_time_panel(time)
}
