//! The exporter's face on Zenoh: what it declares (its liveliness token,
//! its watch on the mirrors' tokens, its queryables), and how it refuses
//! a query.

use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::time::{Duration, Instant};

use tracing::warn;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::query::{Query, Queryable};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait as _};

use super::frames::Shared;
use super::relay::{self, Refusal};
use super::Event;
use crate::error::ExportError;
use crate::wire::BridgeKeys;

/// Malformed or refused inputs, counted and logged.
#[derive(Debug, Default)]
pub(super) struct Dropped {
    pub count: u64,
    last_warning: Option<Instant>,
    unwarned: u64,
}

impl Dropped {
    pub(super) fn note(&mut self, query: &Query, why: &Refusal) {
        self.count += 1;
        let why = why.to_string();
        relay::refuse(query, &why);
        // At most one warning a second, with the count since the last.
        self.unwarned += 1;
        if self
            .last_warning
            .is_none_or(|t| t.elapsed() >= Duration::from_secs(1))
        {
            warn!(
                key = %query.key_expr(),
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

/// What the exporter declared on Zenoh, undeclared when dropped.
pub(super) struct Declared {
    _token: LivelinessToken,
    _mirrors: Subscriber<()>,
    _queryables: [Queryable<()>; 4],
}

/// Declares the exporter's liveliness token, its watch on the mirrors'
/// tokens and its queryables; events go to `events`.
pub(super) fn declare(
    session: &Session,
    keys: &BridgeKeys,
    events: &Sender<Event>,
    shared: &Arc<Shared>,
) -> Result<Declared, ExportError> {
    let token = session
        .liveliness()
        .declare_token(keys.exporter())
        .wait()
        .map_err(ExportError::zenoh(
            "declaring the exporter's liveliness token",
        ))?;
    let to_main = events.clone();
    let mirrors = session
        .liveliness()
        .declare_subscriber(keys.mirrors())
        .history(true)
        .callback(move |sample| {
            let zid = sample.key_expr().as_str().rsplit('/').next().unwrap_or("");
            let alive = sample.kind() == SampleKind::Put;
            let _ = to_main.send(Event::Mirror(zid.to_owned(), alive));
        })
        .wait()
        .map_err(ExportError::zenoh("watching the mirrors' liveliness"))?;
    let queryable = |key: String| {
        let to_main = events.clone();
        session
            .declare_queryable(key)
            .callback(move |query| {
                let _ = to_main.send(Event::Query(query));
            })
            .wait()
            .map_err(ExportError::zenoh("declaring a queryable"))
    };
    let shared = shared.clone();
    let latest = session
        .declare_queryable(keys.latest_frame())
        .callback(move |query| {
            let bytes = shared.latest.lock().map(|b| b.clone()).unwrap_or_default();
            if bytes.is_empty() {
                relay::refuse(&query, "no frame published yet");
            } else {
                relay::reply(&query, &bytes);
            }
        })
        .wait()
        .map_err(ExportError::zenoh("declaring a queryable"))?;
    Ok(Declared {
        _token: token,
        _mirrors: mirrors,
        _queryables: [
            queryable(keys.every_rpc())?,
            queryable(keys.status())?,
            queryable(keys.settings())?,
            latest,
        ],
    })
}
