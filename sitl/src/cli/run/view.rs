//! The live view of `sitl run` (one vehicle or a swarm): the viewer bridge, the sender of the plants'
//! truth and the forwarder of the autopilots' frames, started together and ended in order.

use anyhow::Result;
use sitl::view::{Delivery, Forwarder, VehiclePlacement, ViewSender, Viewer, ViewerOptions, meta_frame};

use crate::cli::view::{finish_viewer, start_viewer};

/// A running view of a live run.
pub(crate) struct LiveView {
    viewer: Viewer,
    pub(crate) sender: ViewSender,
    pub(crate) forwarder: Forwarder,
}

/// The view of `what` (`opts`; none without), its vehicles `v<N>` placed by `placements`: the bridge
/// started (live: never waiting on it), the stream's meta frame sent and the autopilots' port open.
pub(crate) fn start_view(
    opts: Option<&ViewerOptions>,
    what: &str,
    placements: Vec<(String, VehiclePlacement)>,
) -> Result<Option<LiveView>> {
    let Some(opts) = opts else { return Ok(None) };
    let viewer = start_viewer(opts, Delivery::Live, what)?;
    let sender = viewer.sender();
    sender.send(&meta_frame(format!("sitl run: {what}"), placements.iter().map(|(s, _)| s.clone()).collect()));
    let forwarder = Forwarder::start(sender.clone(), placements)?;
    Ok(Some(LiveView { viewer, sender, forwarder }))
}

impl LiveView {
    /// Ends the stream (the autopilots' port closed, the last truth sent) and the view.
    pub(crate) fn finish(self, opts: &ViewerOptions) -> Result<()> {
        let Self { viewer, sender, forwarder } = self;
        drop(forwarder);
        drop(sender);
        finish_viewer(viewer, opts)
    }
}
