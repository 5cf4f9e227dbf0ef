//! simbus recordings: the file format (an MCAP file) and [`inspect`], which
//! answers questions about a recording without a server. Kept out of
//! `shared-types` so the client library does not build MCAP and zstd.
//!
//! The recording file: an MCAP file whose channels, schemas and message
//! layouts are defined here, so the server that writes it, the server that
//! replays it and the client that inspects it agree on every byte.
//!
//! Channels (topic → schema → message bytes):
//!
//! | topic | schema | message |
//! |---|---|---|
//! | `/simbus/header` | `simbus::RecordingHeader/1` (JSON) | [`RecordingHeader`], once, first |
//! | `/simbus/frames` | `simbus::FrameHeader/3` | a [`FrameHeader`] then `actor_count` [`ActorState`]s |
//! | `/simbus/commands` | `simbus::RecordedCommand/1` | one [`RecordedCommand`] |
//! | `/simbus/events` | `simbus::RecordedEvent/1` (JSON) | one [`RecordedEvent`] |
//! | `/simbus/collisions` | `simbus::RecordedCollision/1` | one [`RecordedCollision`] |
//! | `/simbus/sensors` | `simbus::RecordedSensor/2` | one [`RecordedSensor`] (a sensor's spawn) |
//! | `/simbus/sensor/{id}` | `simbus::SensorHeader/2` | a [`SensorHeader`] then the capture's bytes |
//! | `/simbus/keyframes` | `simbus::Keyframe/2` (postcard) | the server's serialized world |
//! | `/foxglove/scene` | `foxglove.SceneUpdate` (JSON) | a cube, sphere or capsule per actor |
//!
//! Messages are written in the order things happened; a message's log time
//! is the recording's own simulation time (nanoseconds since the recording
//! started, summed over episodes, so it never goes back), its publish time
//! the frame's `elapsed_ns`, its sequence the frame id (modulo 2^32, as
//! MCAP's sequence is 32 bits; the full id is in the message).
//!
//! Compatibility: a schema name ends in its layout version. A later simbus
//! only ever adds channels and appends fields; a reader skips channels it
//! does not know and refuses a known schema of a newer version than its own,
//! naming it ([`RecordingError::FutureSchema`]).

mod format;
pub mod inspect;
mod json_f64;
mod read;

pub use format::*;
pub use read::{Entry, RecordingReader};
