//! What wakes the exporter: the one channel its main thread waits on, fed
//! by Zenoh's callbacks and by the frame thread.

use zenoh::query::Query;

use crate::error::FramesError;

/// What wakes the exporter.
pub(super) enum Event {
    /// A query on one of the world's keys.
    Query(Query),
    /// A mirror's liveliness token appeared (`true`) or went.
    Mirror(String, bool),
    /// The frame thread published the frames the server announced.
    Forwarded,
    /// The server rang its frame-ready event without a new frame: it
    /// answered a request.
    Answered,
    /// The frame thread ended: stopped, or the server is gone (why).
    FramesEnded(Option<FramesError>),
}
