//! The exporter's face on Zenoh: what it declares (its liveliness token,
//! its watch on the mirrors' tokens, its queryables, its subscriber to the
//! mirrors' tick publications) and where each query goes: a tick to the
//! frame thread, the rest to the main thread.

use std::sync::mpsc::Sender;
use std::sync::Arc;

use shared_types::ServiceNames;
use simbus_transport::stamps::{self, Stage};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::query::Queryable;
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait as _};

use super::events::Event;
use super::frame_forwarder::{Order, Shared};
use super::relay;
use crate::error::ExportError;
use crate::ports::{self, Bell};
use crate::wire::{BridgeKeys, Forwarded};

/// What the exporter declared on Zenoh, undeclared when dropped.
pub(super) struct Declared {
    _token: LivelinessToken,
    _mirrors: Subscriber<()>,
    _asks: Subscriber<()>,
    _queryables: [Queryable<()>; 4],
}

/// Where the exporter's Zenoh callbacks send what comes: the main
/// thread's events, the frame thread's orders (rung as the frame-ready
/// event of the world `names` names), what the frame thread shares.
pub(super) struct Routes<'a> {
    pub events: &'a Sender<Event>,
    pub orders: &'a Sender<Order>,
    pub names: &'a ServiceNames,
    pub shared: &'a Arc<Shared>,
}

/// Declares the exporter's watch on the mirrors' tokens, its queryables
/// and then its liveliness token. A tick query goes straight to the frame
/// thread, which forwards the tick and replies its answer; every other
/// event to the main thread.
pub(super) fn declare(
    session: &Session,
    keys: &BridgeKeys,
    routes: Routes<'_>,
) -> Result<Declared, ExportError> {
    let mirrors = watch_mirrors(session, keys, routes.events)?;
    let asks = tick_asks(session, keys, &routes)?;
    let queryable = |key: String| {
        let to_main = routes.events.clone();
        session
            .declare_queryable(key)
            .callback(move |query| {
                let _ = to_main.send(Event::Query(query));
            })
            .wait()
            .map_err(ExportError::zenoh("declaring a queryable"))
    };
    let queryables = [
        rpc(session, keys, &routes)?,
        queryable(keys.status())?,
        queryable(keys.settings())?,
        latest_frame(session, keys, routes.shared)?,
    ];
    // Last: a mirror that sees the token finds the queryables declared.
    let token = session
        .liveliness()
        .declare_token(keys.exporter())
        .wait()
        .map_err(ExportError::zenoh(
            "declaring the exporter's liveliness token",
        ))?;
    Ok(Declared {
        _token: token,
        _mirrors: mirrors,
        _asks: asks,
        _queryables: queryables,
    })
}

/// The mirrors' liveliness tokens, as events to the main thread.
fn watch_mirrors(
    session: &Session,
    keys: &BridgeKeys,
    events: &Sender<Event>,
) -> Result<Subscriber<()>, ExportError> {
    let to_main = events.clone();
    session
        .liveliness()
        .declare_subscriber(keys.mirrors())
        .history(true)
        .callback(move |sample| {
            let zid = sample.key_expr().as_str().rsplit('/').next().unwrap_or("");
            let alive = sample.kind() == SampleKind::Put;
            let _ = to_main.send(Event::Mirror(zid.to_owned(), alive));
        })
        .wait()
        .map_err(ExportError::zenoh("watching the mirrors' liveliness"))
}

/// The mirrors' tick publications, straight to the frame thread.
fn tick_asks(
    session: &Session,
    keys: &BridgeKeys,
    routes: &Routes<'_>,
) -> Result<Subscriber<()>, ExportError> {
    let (to_frames, names) = (routes.orders.clone(), routes.names.clone());
    session
        .declare_subscriber(keys.tick_asks())
        .callback(move |sample| {
            stamps::stamp_expected(Stage::ExportGets);
            if to_frames
                .send(Order::TickPut(sample.payload().clone()))
                .is_ok()
            {
                // The frame thread sleeps on the frame-ready event.
                ports::ring(&names, Bell::FrameReady);
            }
        })
        .wait()
        .map_err(ExportError::zenoh("declaring a subscriber"))
}

/// Every request service: a tick query to the frame thread, the rest to
/// the main thread.
fn rpc(
    session: &Session,
    keys: &BridgeKeys,
    routes: &Routes<'_>,
) -> Result<Queryable<()>, ExportError> {
    let (to_main, to_frames) = (routes.events.clone(), routes.orders.clone());
    let names = routes.names.clone();
    let tick_key = keys.rpc(Forwarded::Tick);
    session
        .declare_queryable(keys.every_rpc())
        .callback(move |query| {
            if query.key_expr().as_str() != tick_key {
                let _ = to_main.send(Event::Query(query));
            } else if to_frames.send(Order::Tick(query)).is_ok() {
                // The frame thread sleeps on the frame-ready event.
                ports::ring(&names, Bell::FrameReady);
            }
        })
        .wait()
        .map_err(ExportError::zenoh("declaring a queryable"))
}

/// The last frame, for Zenoh tools (and a mirror's first look).
fn latest_frame(
    session: &Session,
    keys: &BridgeKeys,
    shared: &Arc<Shared>,
) -> Result<Queryable<()>, ExportError> {
    let shared = shared.clone();
    session
        .declare_queryable(keys.latest_frame())
        .callback(move |query| {
            let bytes = shared.latest.lock().map(|b| b.clone()).unwrap_or_default();
            if bytes.is_empty() {
                relay::refuse(&query, "no frame published yet");
            } else {
                relay::reply(&query, bytes);
            }
        })
        .wait()
        .map_err(ExportError::zenoh("declaring a queryable"))
}
