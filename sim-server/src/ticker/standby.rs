//! Standby tickers: claims queued (first come, first served) while another
//! process owns the world, answered at the moment ownership becomes free.

use std::collections::VecDeque;

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::identifiers::UniqueClientId;
use shared_types::{TickRequest, TickResponse};
use simbus_transport::Bus;
use tracing::debug;

use super::ownership::Owner;

/// A standby's claim on the tick service, answered when granted.
type PendingTick = ActiveRequest<Bus, TickRequest, (), TickResponse, ()>;

/// One queued standby claim: the request (answered when granted) and the
/// owner it would become (its `since_frame` is set when granted).
#[derive(Debug)]
pub(crate) struct Waiting {
    pub request: PendingTick,
    pub candidate: Owner,
}

/// The standby claims, oldest first.
#[derive(Debug, Default)]
pub(crate) struct Standbys {
    queue: VecDeque<Waiting>,
}

impl Standbys {
    /// Whether no standby waits.
    pub(crate) fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Queues a standby claim behind the others.
    pub(crate) fn push(&mut self, request: PendingTick, candidate: Owner) {
        self.queue.push_back(Waiting { request, candidate });
    }

    /// Withdraws the standby claims of `client` (it released, or gave up
    /// waiting); returns whether there were any.
    pub(crate) fn withdraw(&mut self, client: UniqueClientId) -> bool {
        let before = self.queue.len();
        self.queue.retain(|w| w.candidate.client != client);
        before != self.queue.len()
    }

    /// The oldest standby still waiting: one whose sender stopped waiting
    /// (its answer dropped) or whose process died (by `alive`) is dropped.
    pub(crate) fn next_alive(&mut self, alive: impl Fn(u32) -> bool) -> Option<Waiting> {
        while let Some(waiting) = self.queue.pop_front() {
            if waiting.request.is_connected() && alive(waiting.candidate.pid) {
                return Some(waiting);
            }
            debug!(
                pid = waiting.candidate.pid,
                node = %waiting.candidate.node_name,
                "dropped a standby ticker that stopped waiting"
            );
        }
        None
    }
}
