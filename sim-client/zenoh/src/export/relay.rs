//! The exporting side of a forwarded service: a request that came as a
//! Zenoh query is sent through an ordinary simbus request port, and the
//! server's answers go back as the query's replies.
//!
//! Every request is checked before it is sent (its size, its protocol
//! version, a slice's length); a bad one is answered with a Zenoh error
//! reply naming what is wrong, counted, and never reaches the server.

use std::time::{Duration, Instant};

use crate::error::{Chain, LocalError, TransportError};
use crate::wire::{self, PayloadError};
use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::client::Client as RequestClient;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, ResponseStatus, SensorInfo,
    SensorRequest, SensorResponseHeader, TickResponse,
};
use simbus_transport::spec::{BatchSpec, RequestSpec, SensorsSpec};
use simbus_transport::Bus;
use tracing::warn;
use zenoh::bytes::ZBytes;
use zenoh::query::Query;
use zenoh::Wait as _;

/// How long a forwarded request may wait for the server's answer.
pub(super) const ANSWER_TIMEOUT: Duration = Duration::from_secs(120);

/// A request waiting for its answer, with the query to answer.
struct InFlight<P> {
    pending: P,
    query: Query,
    since: Instant,
}

/// Why a request from another host was refused before it reached the
/// server (the text goes back to the querier as the error reply).
#[derive(Debug, thiserror::Error)]
pub(super) enum Refusal {
    /// Its key names no forwarded service.
    #[error("no such service")]
    NoSuchService,
    /// It does not name its mirror.
    #[error("a request must name its mirror (?mirror=<zenoh id>)")]
    NoMirror,
    /// Its bytes are not a request of the service.
    #[error("malformed {what}: {error}")]
    Malformed {
        /// What it should have been.
        what: &'static str,
        /// What is wrong.
        error: PayloadError,
    },
    /// No lockstep port could be opened for its participant.
    #[error("no lockstep port for this participant: {}", Chain(.0))]
    NoLockstepPort(LocalError),
    /// iceoryx2 could not send it.
    #[error("cannot send the request to the server: {0:?}")]
    NotSent(TransportError),
}

/// A request refused before it reached the server: its query and why.
pub(super) type Refused = Box<(Query, Refusal)>;

/// A [`Refused`] request.
pub(super) fn refused(query: Query, why: Refusal) -> Refused {
    Box::new((query, why))
}

/// A request of `what` that is not one.
pub(super) fn malformed(query: Query, what: &'static str, error: PayloadError) -> Refused {
    refused(query, Refusal::Malformed { what, error })
}

/// A final answer: the query, the answer's bytes, and for a tick the
/// frame it produced (its reply waits until that frame is published).
pub(super) struct Answer {
    pub query: Query,
    pub bytes: Vec<u8>,
    pub frame: Option<u64>,
}

impl std::fmt::Debug for Answer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Answer")
            .field("key", &self.query.key_expr().as_str())
            .field("bytes", &self.bytes.len())
            .field("frame", &self.frame)
            .finish()
    }
}

/// Replies `payload` to `query` on its own key (a `Vec` or a `ZBytes`
/// is sent as it is, a slice copied once).
pub(super) fn reply(query: &Query, payload: impl Into<ZBytes>) {
    // Express: sent at once, not batched with what may follow.
    if let Err(e) = query
        .reply(query.key_expr().clone(), payload)
        .express(true)
        .wait()
    {
        tracing::debug!("reply to {} not sent: {e}", query.key_expr());
    }
}

/// Replies an error `message` to `query`.
pub(super) fn refuse(query: &Query, message: &str) {
    if let Err(e) = query.reply_err(message.to_owned()).wait() {
        tracing::debug!("error reply to {} not sent: {e}", query.key_expr());
    }
}

/// Malformed or refused inputs, counted and logged.
#[derive(Debug, Default)]
pub(super) struct Dropped {
    pub count: u64,
    last_warning: Option<Instant>,
    unwarned: u64,
}

impl Dropped {
    /// After forwarding a request: rings the server's wake-up event if it
    /// went (an idle server answers at once), else counts and refuses it.
    pub(super) fn settle(&mut self, sent: Result<(), Refused>, wake: &Notifier<Bus>) {
        match sent {
            Ok(()) => {
                if let Err(e) = wake.notify() {
                    tracing::debug!("wake-up not delivered: {e:?}");
                }
            }
            Err(refused) => {
                let (query, why) = *refused;
                self.note(&query, &why);
            }
        }
    }

    pub(super) fn note(&mut self, query: &Query, why: &Refusal) {
        let why = why.to_string();
        refuse(query, &why);
        self.warn(query.key_expr().as_str(), &why);
    }

    /// Counts a refused input that came on `key`, warning at most once a
    /// second.
    pub(super) fn warn(&mut self, key: &str, why: &str) {
        self.count += 1;
        // At most one warning a second, with the count since the last.
        self.unwarned += 1;
        if self
            .last_warning
            .is_none_or(|t| t.elapsed() >= Duration::from_secs(1))
        {
            warn!(
                key,
                dropped = self.unwarned,
                total = self.count,
                "dropped a request from another host: {why}"
            );
            self.last_warning = Some(Instant::now());
            self.unwarned = 0;
        }
    }
}

/// The mirror's Zenoh id a query names in its `mirror` parameter.
pub(super) fn mirror_of(query: &Query) -> Option<String> {
    query
        .parameters()
        .get("mirror")
        .filter(|m| !m.is_empty() && m.len() <= 64)
        .map(str::to_owned)
}

/// The requests of one port waiting for their answers.
struct Flights<P>(Vec<InFlight<P>>);

impl<P> Default for Flights<P> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

impl<P> Flights<P> {
    /// Keeps a sent request until its answer comes; a request that could
    /// not be sent is refused.
    fn admit<E: Into<TransportError>>(
        &mut self,
        sent: Result<P, E>,
        query: Query,
    ) -> Result<(), Refused> {
        match sent {
            Ok(pending) => {
                self.0.push(InFlight {
                    pending,
                    query,
                    since: Instant::now(),
                });
                Ok(())
            }
            Err(e) => Err(refused(query, Refusal::NotSent(e.into()))),
        }
    }

    /// Moves the answers that finished to `answers`; requests that timed
    /// out or lost the server are answered with an error.
    fn drain<T, E: std::fmt::Debug>(
        &mut self,
        mut receive: impl FnMut(&P) -> Result<Option<T>, E>,
        mut finish: impl FnMut(&Query, T) -> Option<(Vec<u8>, Option<u64>)>,
        connected: impl Fn(&P) -> bool,
        answers: &mut Vec<Answer>,
    ) {
        let flights = &mut self.0;
        let mut i = 0;
        while i < flights.len() {
            let flight = &flights[i];
            // Asked before receiving: a server that answers and then lets go
            // of the request between the two calls is not taken for gone.
            let connected = connected(&flight.pending);
            let done = match receive(&flight.pending) {
                Ok(Some(answer)) => finish(&flight.query, answer),
                Ok(None) if !connected => {
                    refuse(&flight.query, "the server of the world is gone");
                    Some((Vec::new(), None))
                }
                Ok(None) if flight.since.elapsed() > ANSWER_TIMEOUT => {
                    refuse(&flight.query, "the server did not answer in time");
                    Some((Vec::new(), None))
                }
                Ok(None) => None,
                Err(e) => {
                    refuse(
                        &flight.query,
                        &format!("receiving the server's answer: {e:?}"),
                    );
                    Some((Vec::new(), None))
                }
            };
            match done {
                Some((bytes, frame)) => {
                    let flight = flights.swap_remove(i);
                    if !bytes.is_empty() {
                        answers.push(Answer {
                            query: flight.query,
                            bytes,
                            frame,
                        });
                    }
                }
                None => i += 1,
            }
        }
    }
}

impl<P> std::fmt::Debug for Flights<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} in flight", self.0.len())
    }
}

/// The service `name` could not be opened.
fn opening(name: &str, e: impl Into<TransportError>) -> LocalError {
    LocalError::transport(format!("service {name}"), e)
}

/// No client port of the service `name` could be created.
fn client_of(name: &str, e: impl Into<TransportError>) -> LocalError {
    LocalError::transport(format!("client of {name}"), e)
}

/// A fixed-size request waiting for its answer.
pub(super) type Pending<Req, Resp> = PendingResponse<Bus, Req, (), Resp, ()>;

/// A forwarded service of fixed-size requests and answers.
pub(super) struct FixedRelay<Req, Resp>
where
    Req: std::fmt::Debug + ZeroCopySend + Copy + bytemuck::Pod,
    Resp: std::fmt::Debug + ZeroCopySend + Copy + bytemuck::Pod,
{
    client: RequestClient<Bus, Req, (), Resp, ()>,
    flights: Flights<Pending<Req, Resp>>,
}

impl<Req, Resp> FixedRelay<Req, Resp>
where
    Req: std::fmt::Debug + ZeroCopySend + Copy + bytemuck::Pod,
    Resp: std::fmt::Debug + ZeroCopySend + Copy + bytemuck::Pod,
{
    /// Opens a client port of the service `spec` describes.
    pub(super) fn open(
        node: &Node<Bus>,
        spec: &RequestSpec<Req, (), Resp, ()>,
    ) -> Result<Self, LocalError> {
        let client = spec
            .open(node)
            .map_err(|e| opening(spec.name.as_str(), e))?
            .client_builder()
            .create()
            .map_err(|e| client_of(spec.name.as_str(), e))?;
        Ok(Self {
            client,
            flights: Flights::default(),
        })
    }

    /// Checks `bytes` as a `Req`.
    pub(super) fn decode(bytes: &[u8]) -> Result<Req, PayloadError> {
        wire::decode_fixed::<Req>(bytes, std::any::type_name::<Req>())
    }

    /// Sends `request`; its answer will go to `query`.
    pub(super) fn send(&mut self, request: Req, query: Query) -> Result<(), Refused> {
        self.flights.admit(self.client.send_copy(request), query)
    }

    /// Sends `request`; its answer is for the caller to poll.
    pub(super) fn send_pending(
        &mut self,
        request: Req,
    ) -> Result<Pending<Req, Resp>, TransportError> {
        self.client.send_copy(request).map_err(Into::into)
    }

    /// Requests sent and not yet answered.
    pub(super) fn in_flight(&self) -> usize {
        self.flights.0.len()
    }

    /// Sends `request` without awaiting its answer.
    pub(super) fn send_detached(&mut self, request: Req) -> Result<(), LocalError> {
        self.client
            .send_copy(request)
            .map(drop)
            .map_err(|e| LocalError::transport("sending a request to the server", e))
    }

    /// Moves the final answers that came to `answers`; an interim answer
    /// (`interim` says which) is replied at once.
    pub(super) fn poll(
        &mut self,
        interim: impl Fn(&Resp) -> bool,
        frame_of: impl Fn(&Resp) -> Option<u64>,
        answers: &mut Vec<Answer>,
    ) {
        self.flights.drain(
            |p| p.receive().map(|r| r.map(|r| *r.payload())),
            |query, answer| {
                if interim(&answer) {
                    reply(query, bytemuck::bytes_of(&answer));
                    None
                } else {
                    Some((bytemuck::bytes_of(&answer).to_vec(), frame_of(&answer)))
                }
            },
            |p| p.is_connected(),
            answers,
        );
    }
}

impl<Req, Resp> std::fmt::Debug for FixedRelay<Req, Resp>
where
    Req: std::fmt::Debug + ZeroCopySend + Copy + bytemuck::Pod,
    Resp: std::fmt::Debug + ZeroCopySend + Copy + bytemuck::Pod,
{
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FixedRelay")
            .field("flights", &self.flights)
            .finish()
    }
}

/// Whether a tick answer is interim (a final one follows).
pub(super) fn tick_interim(answer: &TickResponse) -> bool {
    answer.status == ResponseStatus::WaitingForParticipants as u32
}

/// The frame an OK tick answer produced.
pub(super) fn tick_frame(answer: &TickResponse) -> Option<u64> {
    (answer.status == ResponseStatus::Ok as u32).then_some(answer.frame)
}

/// A forwarded service answered by a header and a slice of `T`: its
/// client port and the requests waiting for their answers.
pub(super) struct SliceRelay<Req, ReqH, T, H>
where
    Req: std::fmt::Debug + IceoryxSend + ?Sized,
    ReqH: std::fmt::Debug + ZeroCopySend,
    T: std::fmt::Debug + ZeroCopySend + bytemuck::Pod,
    H: std::fmt::Debug + ZeroCopySend + bytemuck::Pod,
{
    client: RequestClient<Bus, Req, ReqH, [T], H>,
    flights: Flights<PendingResponse<Bus, Req, ReqH, [T], H>>,
}

impl<Req, ReqH, T, H> SliceRelay<Req, ReqH, T, H>
where
    Req: std::fmt::Debug + IceoryxSend + ?Sized,
    ReqH: std::fmt::Debug + ZeroCopySend,
    T: std::fmt::Debug + ZeroCopySend + bytemuck::Pod,
    H: std::fmt::Debug + ZeroCopySend + bytemuck::Pod,
{
    /// Requests sent and not yet answered.
    pub(super) fn in_flight(&self) -> usize {
        self.flights.0.len()
    }

    /// Moves the answers that came to `answers`, each as its header's
    /// bytes and then its items'. None is held for a frame (a batch's
    /// frame may be one still to come, the next tick's).
    pub(super) fn poll(&mut self, answers: &mut Vec<Answer>) {
        self.flights.drain(
            |p| {
                p.receive().map(|r| {
                    r.map(|r| {
                        let mut bytes = Vec::new();
                        wire::encode_slice(r.user_header(), r.payload(), &mut bytes);
                        bytes
                    })
                })
            },
            |_, bytes| Some((bytes, None)),
            |p| p.is_connected(),
            answers,
        );
    }
}

impl<Req, ReqH, T, H> std::fmt::Debug for SliceRelay<Req, ReqH, T, H>
where
    Req: std::fmt::Debug + IceoryxSend + ?Sized,
    ReqH: std::fmt::Debug + ZeroCopySend,
    T: std::fmt::Debug + ZeroCopySend + bytemuck::Pod,
    H: std::fmt::Debug + ZeroCopySend + bytemuck::Pod,
{
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SliceRelay")
            .field("flights", &self.flights)
            .finish()
    }
}

/// The batch service: a header and commands, answered by a header and
/// one result per command.
pub(super) type BatchRelay = SliceRelay<[Command], BatchHeader, CommandResult, BatchResponseHeader>;

impl BatchRelay {
    /// Opens a client port of the batch service.
    pub(super) fn open(node: &Node<Bus>, spec: &BatchSpec) -> Result<Self, LocalError> {
        let name = spec.name.as_str();
        let factory = spec.open(node).map_err(|e| opening(name, e))?;
        let client = spec.client(&factory).map_err(|e| client_of(name, e))?;
        Ok(Self {
            client,
            flights: Flights::default(),
        })
    }

    /// Checks `bytes` as a batch and sends it; its answer will go to `query`.
    pub(super) fn forward(&mut self, bytes: &[u8], query: Query) -> Result<(), Refused> {
        let (header, commands) = match wire::decode_slice::<BatchHeader, Command>(
            bytes,
            "batch",
            wire::MAX_FORWARDED_BATCH,
        ) {
            Ok(batch) => batch,
            Err(e) => return Err(malformed(query, "batch", e)),
        };
        let sent = self
            .client
            .loan_slice_uninit(commands.len())
            .map_err(TransportError::from)
            .and_then(|mut request| {
                *request.user_header_mut() = header;
                request
                    .write_from_slice(&commands)
                    .send()
                    .map_err(TransportError::from)
            });
        self.flights.admit(sent, query)
    }
}

/// The sensor service: a request, answered by a header and sensor infos.
pub(super) type SensorRelay = SliceRelay<SensorRequest, (), SensorInfo, SensorResponseHeader>;

impl SensorRelay {
    /// Opens a client port of the sensor service.
    pub(super) fn open(node: &Node<Bus>, spec: &SensorsSpec) -> Result<Self, LocalError> {
        let name = spec.name.as_str();
        let client = spec
            .open(node)
            .map_err(|e| opening(name, e))?
            .client_builder()
            .create()
            .map_err(|e| client_of(name, e))?;
        Ok(Self {
            client,
            flights: Flights::default(),
        })
    }

    /// Checks `bytes` as a sensor request and sends it.
    pub(super) fn forward(&mut self, bytes: &[u8], query: Query) -> Result<(), Refused> {
        let request = match wire::decode_fixed::<SensorRequest>(bytes, "sensor request") {
            Ok(request) => request,
            Err(e) => return Err(malformed(query, "sensor request", e)),
        };
        self.flights.admit(self.client.send_copy(request), query)
    }
}
