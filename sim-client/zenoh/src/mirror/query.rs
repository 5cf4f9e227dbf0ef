//! The mirror's queries to the exporting bridge: a local request
//! forwarded (its replies come back as events), and the questions asked
//! once at the start (the world's status, its current frame).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use shared_types::{
    ActorState, ControlRequest, ControlResponse, FrameHeader, RequestKind, ServiceNames,
    TickRequest, WorldName,
};
use tracing::info;
use tracing::warn;
use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::query::{ConsolidationMode, Reply};
use zenoh::sample::{Locality, SampleKind};
use zenoh::{Session, Wait as _};

use super::events::Event;
use super::local;
use crate::error::{MirrorError, QueryError, ZenohError};
use crate::tagged;
use crate::wire::{self, BridgeKeys, Forwarded};

/// How soon a wait for the exporter's token notices `stop` (and how long a
/// query that found no route while the token is there waits to be asked
/// again).
const STOP_CHECK: Duration = Duration::from_millis(100);

/// The way to the exporter for forwarded requests.
pub(super) struct Link<'a> {
    pub session: &'a Session,
    pub keys: &'a BridgeKeys,
    pub names: &'a ServiceNames,
    /// This mirror's Zenoh id, named in every query.
    pub zid: &'a str,
    pub events: Sender<Event>,
    /// How long a forwarded request may wait for its answer.
    pub timeout: Duration,
    /// How long the mirror looks for a tick's next event before it sleeps.
    pub poll: Duration,
    /// Publishes tick requests on `tick/ask`.
    pub asks: Publisher<'static>,
}

/// A reply's payload (as received, not copied), or the text of an error
/// reply.
fn reply_payload(reply: &Reply) -> Result<ZBytes, QueryError> {
    match reply.result() {
        Ok(sample) => Ok(sample.payload().clone()),
        Err(e) => Err(QueryError::Refused(
            String::from_utf8_lossy(&e.payload().to_bytes()).into_owned(),
        )),
    }
}

impl Link<'_> {
    /// Publishes tick request `id` to the exporter; its answers come as
    /// publications (or attached to its frame), named by `id`.
    pub(super) fn ask_tick(&self, request: &TickRequest, id: u64) {
        let mut bytes = Vec::new();
        tagged::encode(self.zid, id, request, &mut bytes);
        if let Err(e) = self.asks.put(bytes).wait() {
            warn!("cannot forward a tick: {}", ZenohError::from(e));
        }
    }

    /// Sends `bytes` to the exporter's `service` as a query; its replies
    /// come back as [`Event::Reply`], each as it arrives (no consolidation:
    /// an interim tick answer is not held back until the last), and its
    /// end as [`Event::Done`]; a reply wakes the mirror, the end only when
    /// no reply came (the exporter is out of reach).
    pub(super) fn forward(&self, service: Forwarded, bytes: Vec<u8>, id: u64) {
        /// Sends [`Event::Done`] when Zenoh drops the callback (no more replies).
        struct Finished(u64, Sender<Event>, ServiceNames, AtomicBool);
        impl Drop for Finished {
            fn drop(&mut self) {
                let _ = self.1.send(Event::Done(self.0));
                if !self.3.load(Ordering::Relaxed) {
                    local::wake(&self.2);
                }
            }
        }
        let finished = Finished(
            id,
            self.events.clone(),
            self.names.clone(),
            AtomicBool::new(false),
        );
        let (to_main, wake_names) = (self.events.clone(), self.names.clone());
        // The id comes back with a tick's answer attached to its frame.
        let selector = format!("{}?mirror={};id={id}", self.keys.rpc(service), self.zid);
        let sent = self
            .session
            .get(selector)
            .payload(bytes)
            .timeout(self.timeout)
            .express(true)
            .consolidation(ConsolidationMode::None)
            .allowed_destination(Locality::Remote)
            .callback(move |reply| {
                finished.3.store(true, Ordering::Relaxed);
                let _ = to_main.send(Event::Reply(id, reply_payload(&reply)));
                local::wake(&wake_names);
            })
            .wait();
        if let Err(e) = sent {
            warn!("cannot forward a request: {}", ZenohError::from(e));
        }
    }
}

/// [`query_once`] asked of the exporter once its liveliness token is
/// seen, until something answers, `timeout` is over or `stop` is set:
/// while the link is still being made (the exporter not up yet, or Zenoh
/// retrying the connection), a query finds no route and ends at once,
/// which is not "nothing answered within `timeout`". The exporter declares
/// its token after its queryables, so the token's coming is the event to
/// wait for.
pub(super) fn query_until(
    session: &Session,
    keys: &BridgeKeys,
    zid: &str,
    payload: &[u8],
    timeout: Duration,
    stop: &AtomicBool,
) -> Result<Vec<u8>, QueryError> {
    let deadline = Instant::now() + timeout;
    let tokens = session
        .liveliness()
        .declare_subscriber(keys.exporter())
        .history(true)
        .wait()
        .map_err(|e| QueryError::Zenoh(e.into()))?;
    let key = keys.rpc(Forwarded::Control);
    let mut alive = false;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || stop.load(Ordering::Relaxed) {
            return Err(QueryError::NoAnswer);
        }
        if alive {
            match query_once(session, &key, zid, payload, left) {
                Err(QueryError::NoAnswer) => {}
                other => return other,
            }
        }
        // The one wait: the token's next word, or how soon `stop` is seen.
        match tokens.recv_timeout(left.min(STOP_CHECK)) {
            Ok(Some(sample)) => alive = sample.kind() == SampleKind::Put,
            Ok(None) => {}
            Err(e) => return Err(QueryError::Zenoh(e.into())),
        }
    }
}

/// One query and its first reply.
pub(super) fn query_once(
    session: &Session,
    key: &str,
    zid: &str,
    payload: &[u8],
    timeout: Duration,
) -> Result<Vec<u8>, QueryError> {
    let replies = session
        .get(format!("{key}?mirror={zid}"))
        .payload(payload.to_vec())
        .timeout(timeout)
        .wait()
        .map_err(|e| QueryError::Zenoh(e.into()))?;
    match replies.recv() {
        Ok(reply) => reply_payload(&reply).map(|p| p.to_bytes().into_owned()),
        Err(_) => Err(QueryError::NoAnswer),
    }
}

/// What the exporter said first: the world's status, then its frame.
pub(super) struct Hello {
    pub status: ControlResponse,
    pub header: FrameHeader,
    pub actors: Vec<ActorState>,
}

/// Asks the exporter at `endpoint` for the world's status and its current
/// frame, for up to `timeout`.
pub(super) fn hello(
    session: &Session,
    keys: &BridgeKeys,
    world: &WorldName,
    endpoint: &str,
    timeout: Duration,
    stop: &AtomicBool,
) -> Result<Hello, MirrorError> {
    let zid = session.zid().to_string();
    let request = ControlRequest::new(RequestKind::Status);
    info!(%world, %endpoint, "asking for the world's status (waiting up to {timeout:?})");
    let status = match query_until(session, keys, &zid, wire::bytes_of(&request), timeout, stop) {
        Ok(bytes) => bytes,
        Err(QueryError::NoAnswer) => {
            return Err(MirrorError::NotExported {
                world: world.clone(),
                endpoint: endpoint.to_owned(),
                timeout,
            })
        }
        Err(e) => return Err(MirrorError::Refused(e)),
    };
    let status =
        wire::decode_fixed::<ControlResponse>(&status, "status answer").map_err(|error| {
            MirrorError::Incompatible {
                world: world.clone(),
                endpoint: endpoint.to_owned(),
                error,
            }
        })?;
    let first =
        query_once(session, &keys.latest_frame(), &zid, &[], timeout).map_err(|source| {
            MirrorError::NoFrame {
                world: world.clone(),
                source,
            }
        })?;
    let (header, actors) = wire::decode_frame(&first).map_err(MirrorError::UnreadableFrame)?;
    Ok(Hello {
        status,
        header,
        actors,
    })
}
