//! The tick service as the exporter's frame thread forwards it: a remote
//! tick is sent to the server from the frame thread, and its answer goes
//! back with the frame it produced, attached to that frame's publication
//! (one Zenoh message to the mirror), no other thread in between.
//!
//! A mirror's tick comes as a publication on `tick/ask` tagged with its
//! Zenoh id and its request id (no Zenoh query: no timeout task started
//! per tick); the answers that do not ride on a frame (an interim one, a
//! refusal) are published on `tick/answer` with the same tags. A tick that
//! comes as a query (any other Zenoh peer, a mirror's claim or release) is
//! replied as before; an OK answer of one that names `mirror` and `id` is
//! attached to its frame too.

use std::time::Instant;

use iceoryx2::node::Node;
use iceoryx2::port::notifier::Notifier;
use shared_types::{ResponseStatus, TickRequest, TickResponse, TickerInfo};
use simbus_transport::spec::WorldServices;
use simbus_transport::stamps::{self, Stage};
use simbus_transport::Bus;
use tracing::{debug, info};
use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::query::Query;
use zenoh::Wait as _;

use super::relay::{self, mirror_of, Answer, Dropped, Pending, Refusal, ANSWER_TIMEOUT};
use super::ticker::{RemoteTicker, RemoteTickers, TickRelay};
use crate::error::LocalError;
use crate::{ports, tagged, wire};

/// Where a tick's answer goes.
enum Asker {
    /// The query's reply.
    Query(Query),
    /// A publication on `tick/answer`, tagged for the mirror's request.
    Put { mirror: String, id: u64 },
}

/// A final answer whose frame is not on Zenoh yet.
struct Held {
    to: Asker,
    answer: TickResponse,
    /// Sent attached to its frame's publication.
    attached: bool,
}

/// A tick request that came as a publication, waiting for the server.
struct PutFlight {
    pending: Pending<TickRequest, TickResponse>,
    mirror: String,
    id: u64,
    since: Instant,
}

/// What a tick publication is logged as.
const ASKS: &str = "tick/ask";

/// The tick service as the frame thread forwards it: remote tickers'
/// requests, the server's answers, and the ownership held for a remote
/// ticker.
pub(super) struct Ticks {
    port: TickRelay,
    tickers: RemoteTickers,
    /// Wakes an idle (paced or waiting) server after a request.
    wake: Notifier<Bus>,
    /// Publishes the answers to tick publications that ride on no frame.
    answers: Publisher<'static>,
    /// Final answers whose frame is not on Zenoh yet.
    held: Vec<Held>,
    /// Answers taken from the port, reused (the tick path allocates
    /// nothing once warm).
    taken: Vec<Answer>,
    /// Tick publications sent to the server, not answered yet.
    puts: Vec<PutFlight>,
    dropped: Dropped,
}

/// An answer with `status` and nothing else.
fn status_answer(status: ResponseStatus) -> TickResponse {
    TickResponse::new(status, 0, 0, TickerInfo::none())
}

/// Publishes `answer` for request `id` of `mirror` on `tick/answer`.
fn publish(answers: &Publisher<'_>, mirror: &str, id: u64, answer: &TickResponse) {
    let mut bytes = Vec::new();
    tagged::encode(mirror, id, answer, &mut bytes);
    if let Err(e) = answers.put(bytes).wait() {
        debug!("tick answer not published: {e}");
    }
}

impl Ticks {
    /// Opens a client port of the tick service on `node`; `answers`
    /// publishes on `tick/answer`.
    pub(super) fn open(
        node: &Node<Bus>,
        specs: &WorldServices,
        answers: Publisher<'static>,
    ) -> Result<Self, LocalError> {
        Ok(Self {
            port: TickRelay::open(node, &specs.tick)?,
            tickers: RemoteTickers::default(),
            wake: ports::wake_notifier_on(node, specs)?,
            answers,
            held: Vec::new(),
            taken: Vec::new(),
            puts: Vec::new(),
            dropped: Dropped::default(),
        })
    }

    /// A remote tick query: sent to the server (which is woken), or
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

    /// A mirror's tick publication: each request sent to the server (which
    /// is woken), or refused with an answer published for it; a
    /// malformed one is dropped, counted.
    pub(super) fn on_put(&mut self, payload: &ZBytes, forwarded: u64) {
        let bytes = payload.to_bytes();
        let asks = match tagged::decode::<TickRequest>(&bytes, "tick request") {
            Ok(asks) => asks,
            Err(error) => {
                let why = Refusal::Malformed {
                    what: "tick request",
                    error,
                };
                return self.dropped.warn(ASKS, &why.to_string());
            }
        };
        for ask in asks {
            let mirror = String::from_utf8_lossy(ask.mirror).into_owned();
            if mirror.is_empty() || mirror.len() > 64 {
                self.dropped.warn(ASKS, &Refusal::NoMirror.to_string());
                continue;
            }
            let request = match self.tickers.admit(ask.value, mirror.clone(), forwarded) {
                Ok(request) => request,
                Err(refusal) => {
                    publish(&self.answers, &mirror, ask.id, &refusal);
                    continue;
                }
            };
            match self.port.send_pending(request) {
                Ok(pending) => {
                    stamps::stamp(Stage::ExportSends, forwarded + 1);
                    self.puts.push(PutFlight {
                        pending,
                        mirror,
                        id: ask.id,
                        since: Instant::now(),
                    });
                    if let Err(e) = self.wake.notify() {
                        debug!("wake-up not delivered: {e:?}");
                    }
                }
                Err(e) => {
                    self.dropped.warn(ASKS, &Refusal::NotSent(e).to_string());
                    let refused = status_answer(ResponseStatus::Refused);
                    publish(&self.answers, &mirror, ask.id, &refused);
                }
            }
        }
    }

    /// The server rang: takes the answers that came (an interim one is
    /// sent at once), before the frames they produced are published.
    pub(super) fn take(&mut self) {
        self.port
            .poll(relay::tick_interim, relay::tick_frame, &mut self.taken);
        for answer in self.taken.drain(..) {
            match wire::decode_fixed::<TickResponse>(&answer.bytes, "tick answer") {
                Ok(response) => {
                    // The server's word on who ticks now decides the owner.
                    self.tickers.answered(&response);
                    self.held.push(Held {
                        to: Asker::Query(answer.query),
                        answer: response,
                        attached: false,
                    });
                }
                Err(_) => relay::reply(&answer.query, answer.bytes),
            }
        }
        self.take_puts();
    }

    /// Whether a tick was sent to the server and its answer has not come:
    /// the frame thread then looks for the server's ring before it sleeps.
    pub(super) fn awaiting_server(&self) -> bool {
        !self.puts.is_empty() || self.port.in_flight() > 0
    }

    /// The answers to tick publications that came; a request whose server
    /// is gone or silent for too long is answered `Refused`.
    fn take_puts(&mut self) {
        let mut i = 0;
        while i < self.puts.len() {
            let flight = &self.puts[i];
            // Asked before receiving (see the relay's `drain`).
            let connected = flight.pending.is_connected();
            let answer = match flight.pending.receive() {
                Ok(Some(answer)) => *answer.payload(),
                Ok(None) if connected && flight.since.elapsed() <= ANSWER_TIMEOUT => {
                    i += 1;
                    continue;
                }
                Ok(None) => status_answer(ResponseStatus::Refused),
                Err(e) => {
                    debug!("receiving the server's answer to a tick: {e:?}");
                    status_answer(ResponseStatus::Refused)
                }
            };
            if relay::tick_interim(&answer) {
                // The final answer follows; looked for at once.
                publish(&self.answers, &flight.mirror, flight.id, &answer);
                continue;
            }
            stamps::stamp(Stage::ExportTakes, answer.frame);
            let PutFlight { mirror, id, .. } = self.puts.swap_remove(i);
            self.tickers.answered(&answer);
            self.held.push(Held {
                to: Asker::Put { mirror, id },
                answer,
                attached: false,
            });
        }
    }

    /// The tick answers frame `frame` produced, for its publication's
    /// attachment: a mirror gets the frame and its answer in one message.
    pub(super) fn attachment(&mut self, frame: u64) -> Option<Vec<u8>> {
        let mut bytes = Vec::new();
        for held in self.held.iter_mut() {
            if relay::tick_frame(&held.answer) != Some(frame) {
                continue;
            }
            held.attached = match &held.to {
                Asker::Put { mirror, id } => tagged::encode(mirror, *id, &held.answer, &mut bytes),
                Asker::Query(query) => {
                    let id = query.parameters().get("id").and_then(|id| id.parse().ok());
                    match (mirror_of(query), id) {
                        (Some(mirror), Some(id)) => {
                            tagged::encode(&mirror, id, &held.answer, &mut bytes)
                        }
                        _ => false,
                    }
                }
            };
        }
        (!bytes.is_empty()).then_some(bytes)
    }

    /// Every frame up to `forwarded` is on Zenoh: sends the answers whose
    /// frame is out and that did not ride on it (a query is replied in any
    /// case, after its frame, so a remote reader that sees the answer
    /// finds the frame).
    pub(super) fn reply_due(&mut self, forwarded: u64) {
        let due = |held: &mut Held| relay::tick_frame(&held.answer).is_none_or(|f| f <= forwarded);
        for held in self.held.extract_if(.., due) {
            match held.to {
                Asker::Query(query) => relay::reply(&query, wire::bytes_of(&held.answer)),
                Asker::Put { .. } if held.attached => {}
                Asker::Put { mirror, id } => publish(&self.answers, &mirror, id, &held.answer),
            }
        }
    }

    /// Mirror `zid` is gone: the ownership held for its ticker is released.
    pub(super) fn mirror_left(&mut self, zid: &str) {
        self.tickers.mirror_left(zid, &mut self.port);
    }

    /// The server is gone: the remote ticker that owned the world, to
    /// claim it again from a resumed server.
    pub(super) fn take_owner(&mut self) -> Option<RemoteTicker> {
        self.tickers.take_owner()
    }

    /// Claims the world again for `owner` ([`RemoteTickers::claim_again`]).
    pub(super) fn claim_again(&mut self, owner: RemoteTicker) {
        self.tickers.claim_again(owner, &mut self.port);
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
            .field("puts", &self.puts.len())
            .finish()
    }
}
