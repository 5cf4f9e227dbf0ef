//! The single-ticker rule among remote tickers: the exporter holds the
//! world's tick ownership on behalf of one remote ticker (by mirror and
//! pid), refuses every other remote claimant naming it, and releases it
//! when that ticker's mirror goes. The tick service is forwarded by the
//! exporter's frame thread ([`Ticks`]): it sends a remote tick to the
//! server, publishes the frame the server rings for, and replies the
//! tick's answer right after it, with no hand-off to another thread.

use iceoryx2::node::Node;
use iceoryx2::port::notifier::Notifier;
use shared_types::{
    FixedText, LockstepKind, LockstepRequest, LockstepResponse, ResponseStatus, TickRequest,
    TickRequestKind, TickResponse, TickerInfo,
};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;
use tracing::{info, warn};
use zenoh::query::Query;

use super::relay::{self, mirror_of, Answer, Dropped, FixedRelay, Refusal, Refused};
use crate::error::{Chain, LocalError};
use crate::{ports, wire};

/// The tick service's relay.
pub(super) type TickRelay = FixedRelay<TickRequest, TickResponse>;

/// The lockstep service's relay (one per remote participant).
pub(super) type LockstepRelay = FixedRelay<LockstepRequest, LockstepResponse>;

/// A ticker on another host, as its mirror named it.
#[derive(Debug, Clone, PartialEq)]
struct RemoteTicker {
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
    /// Forwards a remote ticker's request on `port`, keeping the
    /// single-ticker rule among remote tickers: only the remote owner (by
    /// mirror and pid) may tick, set, or release; a claim by anyone else
    /// while it holds is refused naming it.
    pub(super) fn forward(
        &mut self,
        mut request: TickRequest,
        mirror: String,
        query: Query,
        port: &mut TickRelay,
        forwarded: u64,
    ) -> Result<(), Refused> {
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
            let answer = TickResponse::new(ResponseStatus::NotTicker, forwarded, 0, info);
            relay::reply(&query, wire::bytes_of(&answer));
            return Ok(());
        }
        request.flags |= TickRequest::ON_BEHALF;
        if kind == Some(TickRequestKind::Claim) && !self.claimants.contains(&me) {
            // The server's answer says whether it became the owner.
            if self.claimants.len() >= MAX_CLAIMANTS {
                self.claimants.remove(0);
            }
            self.claimants.push(me);
        }
        port.send(request, query)
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

/// The tick service as the frame thread forwards it: remote tickers'
/// requests, the server's answers, and the ownership held for a remote
/// ticker.
pub(super) struct Ticks {
    port: TickRelay,
    tickers: RemoteTickers,
    /// Wakes an idle (paced or waiting) server after a request.
    wake: Notifier<Bus>,
    /// Final answers whose frame is not on Zenoh yet.
    held: Vec<Answer>,
    /// Answers taken from the port, reused (the tick path allocates
    /// nothing once warm).
    taken: Vec<Answer>,
    dropped: Dropped,
}

impl Ticks {
    /// Opens a client port of the tick service on `node`.
    pub(super) fn open(node: &Node<Bus>, specs: &WorldServices) -> Result<Self, LocalError> {
        Ok(Self {
            port: FixedRelay::open(node, &specs.tick)?,
            tickers: RemoteTickers::default(),
            wake: ports::wake_notifier_on(node, specs)?,
            held: Vec::new(),
            taken: Vec::new(),
            dropped: Dropped::default(),
        })
    }

    /// A remote tick request: sent to the server (which is woken), or
    /// refused naming why. `forwarded` is the last frame on Zenoh.
    pub(super) fn on_query(&mut self, query: Query, forwarded: u64) {
        let Some(mirror) = mirror_of(&query) else {
            self.dropped.note(&query, &Refusal::NoMirror);
            return;
        };
        let request = match query.payload().map(|p| p.to_bytes()) {
            Some(bytes) => TickRelay::decode(&bytes),
            None => TickRelay::decode(&[]),
        };
        let sent = match request {
            Ok(request) => self
                .tickers
                .forward(request, mirror, query, &mut self.port, forwarded),
            Err(e) => Err(relay::malformed(query, "tick request", e)),
        };
        self.dropped.settle(sent, &self.wake);
    }

    /// The server rang and every frame up to `forwarded` is on Zenoh:
    /// replies the answers that came whose frame is out (an interim one
    /// at once).
    pub(super) fn on_ring(&mut self, forwarded: u64) {
        self.port
            .poll(relay::tick_interim, relay::tick_frame, &mut self.taken);
        for answer in self.taken.drain(..) {
            // The server's word on who ticks now decides the remote owner.
            if let Ok(response) = wire::decode_fixed::<TickResponse>(&answer.bytes, "tick answer") {
                self.tickers.answered(&response);
            }
            self.held.push(answer);
        }
        // A tick's answer goes once its frame is on Zenoh, so a remote
        // reader that sees the answer finds the frame.
        for answer in self.held.extract_if(.., |answer| {
            answer.frame.is_none_or(|frame| frame <= forwarded)
        }) {
            relay::reply(&answer.query, answer.bytes);
        }
    }

    /// Mirror `zid` is gone: the ownership held for its ticker is released.
    pub(super) fn mirror_left(&mut self, zid: &str) {
        self.tickers.mirror_left(zid, &mut self.port);
    }

    /// The export ends: the ownership held for a remote ticker goes back.
    pub(super) fn finish(&mut self) {
        self.tickers.release(&mut self.port);
        if self.dropped.count > 0 {
            info!(dropped = self.dropped.count, "tick requests refused");
        }
    }
}

impl std::fmt::Debug for Ticks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ticks")
            .field("tickers", &self.tickers)
            .field("held", &self.held.len())
            .finish()
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
