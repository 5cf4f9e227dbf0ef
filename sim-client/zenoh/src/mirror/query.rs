//! The mirror's queries to the exporting bridge: a local request
//! forwarded (its replies come back as events), and the questions asked
//! once at the start (the world's status, its current frame).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::time::{Duration, Instant};

use shared_types::ServiceNames;
use tracing::warn;
use zenoh::query::Reply;
use zenoh::{Session, Wait as _};

use super::local;
use super::Event;
use crate::error::{QueryError, ZenohError};
use crate::wire::{BridgeKeys, Forwarded};

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
}

/// A reply's bytes, or the text of an error reply.
fn reply_bytes(reply: &Reply) -> Result<Vec<u8>, QueryError> {
    match reply.result() {
        Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
        Err(e) => Err(QueryError::Refused(
            String::from_utf8_lossy(&e.payload().to_bytes()).into_owned(),
        )),
    }
}

impl Link<'_> {
    /// Sends `bytes` to the exporter's `service` as a query; its replies
    /// come back as [`Event::Reply`] and its end as [`Event::Done`], each
    /// waking the mirror.
    pub(super) fn forward(&self, service: Forwarded, bytes: Vec<u8>, id: u64) {
        /// Sends [`Event::Done`] when Zenoh drops the callback (no more replies).
        struct Finished(u64, Sender<Event>, ServiceNames);
        impl Drop for Finished {
            fn drop(&mut self) {
                let _ = self.1.send(Event::Done(self.0));
                local::wake(&self.2);
            }
        }
        let finished = Finished(id, self.events.clone(), self.names.clone());
        let (to_main, wake_names) = (self.events.clone(), self.names.clone());
        let selector = format!("{}?mirror={}", self.keys.rpc(service), self.zid);
        let sent = self
            .session
            .get(selector)
            .payload(bytes)
            .timeout(self.timeout)
            .express(true)
            .callback(move |reply| {
                let _ = &finished;
                let _ = to_main.send(Event::Reply(id, reply_bytes(&reply)));
                local::wake(&wake_names);
            })
            .wait();
        if let Err(e) = sent {
            warn!("cannot forward a request: {}", ZenohError::from(e));
        }
    }
}

/// [`query_once`] asked again until something answers, `timeout` is over
/// or `stop` is set: while the link is still being made (the exporter not
/// up yet, or Zenoh retrying the connection), a query finds no route and
/// ends at once, which is not "nothing answered within `timeout`".
pub(super) fn query_until(
    session: &Session,
    key: &str,
    zid: &str,
    payload: &[u8],
    timeout: Duration,
    stop: &AtomicBool,
) -> Result<Vec<u8>, QueryError> {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match query_once(session, key, zid, payload, left) {
            Err(QueryError::NoAnswer)
                if Instant::now() < deadline && !stop.load(Ordering::Relaxed) =>
            {
                // The next try after Zenoh's own connection retry (250 ms).
                std::thread::sleep(left.min(Duration::from_millis(100)));
            }
            other => return other,
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
        Ok(reply) => reply_bytes(&reply),
        Err(_) => Err(QueryError::NoAnswer),
    }
}
