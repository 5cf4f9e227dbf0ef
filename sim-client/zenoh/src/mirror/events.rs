//! What wakes the mirror besides its local clients: the events Zenoh's
//! callbacks queue before they ring this host's wake-up event.

use zenoh::bytes::ZBytes;

use crate::error::QueryError;

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
