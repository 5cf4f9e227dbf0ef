//! Whether client processes still live, by iceoryx2's dead-node detection
//! (it works for SIGKILL too). One node list answers for every process the
//! server watches in one sweep.

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// The process ids of every live iceoryx2 node, or `None` when the node
/// list cannot be read (then nobody is declared dead).
pub fn living_pids() -> Option<Vec<u32>> {
    let mut pids = Vec::new();
    let listed = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Alive(view) = &state {
            if let Some(details) = view.details() {
                pids.push(details.process_id().value() as u32);
            }
        }
        CallbackProgression::Continue
    });
    listed.ok().map(|()| pids)
}

/// A liveness check over one node list: `alive(pid)` is true unless the
/// list was read and holds no live node of `pid`.
#[derive(Debug)]
pub struct LiveProcesses(Option<Vec<u32>>);

impl LiveProcesses {
    /// Reads the node list once.
    pub fn now() -> Self {
        Self(living_pids())
    }

    /// Whether `pid` has a live node (or the list could not be read).
    pub fn alive(&self, pid: u32) -> bool {
        self.0.as_ref().is_none_or(|pids| pids.contains(&pid))
    }
}
