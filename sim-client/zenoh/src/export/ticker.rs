//! The single-ticker rule among remote tickers: the exporter holds the
//! world's tick ownership on behalf of one remote ticker (by mirror and
//! pid), refuses every other remote claimant naming it, and releases it
//! when that ticker's mirror goes. The tick service itself is forwarded
//! by the exporter's frame thread (`ticks.rs`).

use shared_types::{
    FixedText, LockstepKind, LockstepRequest, LockstepResponse, ResponseStatus, TickRequest,
    TickRequestKind, TickResponse, TickerInfo,
};
use tracing::{info, warn};
use zenoh::query::Query;

use super::relay::{self, FixedRelay, Refused};
use crate::error::Chain;
use crate::wire;

/// The tick service's relay.
pub(super) type TickRelay = FixedRelay<TickRequest, TickResponse>;

/// The lockstep service's relay (one per remote participant).
pub(super) type LockstepRelay = FixedRelay<LockstepRequest, LockstepResponse>;

/// A ticker on another host, as its mirror named it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RemoteTicker {
    mirror: String,
    pid: u32,
    node_name: String,
}

/// Remote claimants remembered until the server's answer names the owner.
const MAX_CLAIMANTS: usize = 16;

/// The remote ticker that owns the world, if any, and those who claimed.
#[derive(Debug, Default)]
pub(super) struct RemoteTickers {
    owner: Option<RemoteTicker>,
    claimants: Vec<RemoteTicker>,
}

impl RemoteTickers {
    /// Forwards a remote ticker's request on `port`, or replies the
    /// refusal [`Self::admit`] gives.
    pub(super) fn forward(
        &mut self,
        request: TickRequest,
        mirror: String,
        query: Query,
        port: &mut TickRelay,
        forwarded: u64,
    ) -> Result<(), Refused> {
        match self.admit(request, mirror, forwarded) {
            Ok(request) => port.send(request, query),
            Err(refusal) => {
                relay::reply(&query, wire::bytes_of(&*refusal));
                Ok(())
            }
        }
    }

    /// A remote ticker's request as it is to be sent to the server, keeping
    /// the single-ticker rule among remote tickers: only the remote owner
    /// (by mirror and pid) may tick, set, or release; a claim by anyone
    /// else while it holds is refused naming it (the answer to send back).
    /// `forwarded` is the last frame on Zenoh.
    pub(super) fn admit(
        &mut self,
        mut request: TickRequest,
        mirror: String,
        forwarded: u64,
    ) -> Result<TickRequest, Box<TickResponse>> {
        let kind = TickRequestKind::from_u32(request.kind);
        let me = RemoteTicker {
            mirror,
            pid: request.pid,
            node_name: request.node_name.to_string_lossy(),
        };
        if let Some(current) = self.owner.as_ref().filter(|o| **o != me) {
            let info = TickerInfo {
                active: 1,
                pid: current.pid,
                since_frame: 0,
                node_name: FixedText::new(&current.node_name),
            };
            return Err(Box::new(TickResponse::new(
                ResponseStatus::NotTicker,
                forwarded,
                0,
                info,
            )));
        }
        request.flags |= TickRequest::ON_BEHALF;
        // Across hosts every tick is answered: the relay waits for the
        // answer it carries back, and the remote ticker's frame arrives
        // through the mirror whenever it does.
        request.flags &= !TickRequest::BY_FRAME;
        if kind == Some(TickRequestKind::Claim) && !self.claimants.contains(&me) {
            // The server's answer says whether it became the owner.
            if self.claimants.len() >= MAX_CLAIMANTS {
                self.claimants.remove(0);
            }
            self.claimants.push(me);
        }
        Ok(request)
    }

    /// The server's word on who ticks now, in a tick answer, decides the
    /// remote owner: one of the claimants, or nobody (a local ticker).
    pub(super) fn answered(&mut self, answer: &TickResponse) {
        self.owner = answer.ticker.active().and_then(|ticker| {
            let name = ticker.node_name.to_string_lossy();
            self.claimants
                .iter()
                .rev()
                .find(|c| c.pid == ticker.pid && c.node_name == name)
                .cloned()
        });
    }

    /// The remote ticker that owns the world, taken: its server is gone,
    /// and the export goes on with the server resumed from its journal
    /// ([`RemoteTickers::claim_again`]).
    pub(super) fn take_owner(&mut self) -> Option<RemoteTicker> {
        self.claimants.clear();
        self.owner.take()
    }

    /// Claims the world again for `owner`, the remote ticker that owned it
    /// when its server exited, from the server resumed from its journal:
    /// its next tick goes on as if nothing happened. The answer is not
    /// awaited; the server's word in the next tick answer settles who owns
    /// the world ([`RemoteTickers::answered`]).
    pub(super) fn claim_again(&mut self, owner: RemoteTicker, port: &mut TickRelay) {
        let mut request = TickRequest::new(TickRequestKind::Claim, &owner.node_name);
        request.flags |= TickRequest::ON_BEHALF;
        request.pid = owner.pid;
        match port.send_detached(request) {
            Ok(()) => {
                info!(
                    pid = owner.pid,
                    node = %owner.node_name,
                    "claimed the world again for the remote ticker that held it"
                );
                self.claimants.push(owner.clone());
                self.owner = Some(owner);
            }
            Err(e) => warn!(
                "claiming the world again for the remote ticker: {}",
                Chain(&e)
            ),
        }
    }

    /// Mirror `zid` is gone: the ownership held for its ticker is released.
    pub(super) fn mirror_left(&mut self, zid: &str, port: &mut TickRelay) {
        if self.owner.as_ref().is_some_and(|o| o.mirror == zid) {
            self.release(port);
        }
    }

    /// Releases the ownership the bridge holds for a remote ticker, if it
    /// holds one.
    pub(super) fn release(&mut self, port: &mut TickRelay) {
        let Some(lost) = self.owner.take() else {
            return;
        };
        let mut request = TickRequest::new(TickRequestKind::Release, &lost.node_name);
        request.flags |= TickRequest::ON_BEHALF;
        request.pid = lost.pid;
        info!(
            pid = lost.pid,
            node = %lost.node_name,
            "releasing the tick ownership held for a ticker whose mirror is gone"
        );
        // The answer is not awaited: the next claim is answered after it.
        if let Err(e) = port.send_detached(request) {
            warn!(
                "releasing the lost remote ticker's ownership: {}",
                Chain(&e)
            );
        }
    }
}

/// Makes the remote participant `pid` leave the lockstep, so the server
/// stops waiting for it.
pub(super) fn leave_for(mut port: LockstepRelay, pid: u32) {
    let mut request = LockstepRequest::new(LockstepKind::Leave, "", 0, 0);
    request.pid = pid;
    if let Err(e) = port.send_detached(request) {
        warn!("removing a lost remote participant: {}", Chain(&e));
    }
}
