//! What wakes the mirror besides its local clients: the events Zenoh's
//! callbacks queue before they ring this host's wake-up event, and the
//! subscriptions whose callbacks those are.

use std::sync::mpsc::Sender;

use shared_types::ServiceNames;
use simbus_transport::stamps::{self, Stage};
use zenoh::bytes::ZBytes;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, Wait as _};

use super::local;
use crate::error::{MirrorError, QueryError};
use crate::wire::BridgeKeys;

/// What wakes the mirror. Payloads are kept as Zenoh received them (no
/// copy) and read straight into this host's loaned samples.
pub(super) enum Event {
    /// A frame from the exporter, and the tick answers attached to it.
    Frame(ZBytes, Option<ZBytes>),
    /// A capture from the exporter.
    Capture(ZBytes),
    /// Tick answers the exporter published.
    TickAnswers(ZBytes),
    /// A reply to forwarded request `id` (an error reply as its text).
    Reply(u64, Result<ZBytes, QueryError>),
    /// Forwarded request `id` will get no more replies.
    Done(u64),
    /// The exporter's liveliness token appeared (`true`) or went.
    Exporter(bool),
}

/// What the mirror declared on Zenoh, undeclared when dropped.
pub(super) struct Declared {
    _token: LivelinessToken,
    _subscribers: [Subscriber<()>; 4],
}

/// Declares the mirror's liveliness token and its subscribers (the
/// exporter's token, frames, captures); each event wakes the mirror.
pub(super) fn declare(
    session: &Session,
    keys: &BridgeKeys,
    names: &ServiceNames,
    events: &Sender<Event>,
) -> Result<Declared, MirrorError> {
    let token = session
        .liveliness()
        .declare_token(keys.mirror(&session.zid().to_string()))
        .wait()
        .map_err(MirrorError::zenoh(
            "declaring the mirror's liveliness token",
        ))?;
    let (to_main, wake_names) = (events.clone(), names.clone());
    let exporter = session
        .liveliness()
        .declare_subscriber(keys.exporter())
        .history(true)
        .callback(move |sample| {
            let _ = to_main.send(Event::Exporter(sample.kind() == SampleKind::Put));
            local::wake(&wake_names);
        })
        .wait()
        .map_err(MirrorError::zenoh("watching the exporter's liveliness"))?;
    let subscriber = |key: String, event: fn(&Sample) -> Event| {
        let (to_main, wake_names) = (events.clone(), names.clone());
        session
            .declare_subscriber(key)
            .callback(move |sample| {
                let _ = to_main.send(event(&sample));
                local::wake(&wake_names);
            })
            .wait()
            .map_err(MirrorError::zenoh("declaring a subscriber"))
    };
    Ok(Declared {
        _token: token,
        _subscribers: [
            exporter,
            subscriber(keys.frames(), |s| {
                stamps::stamp_expected(Stage::MirrorGets);
                Event::Frame(s.payload().clone(), s.attachment().cloned())
            })?,
            subscriber(keys.sensors(), |s| Event::Capture(s.payload().clone()))?,
            subscriber(keys.tick_answers(), |s| {
                Event::TickAnswers(s.payload().clone())
            })?,
        ],
    })
}
