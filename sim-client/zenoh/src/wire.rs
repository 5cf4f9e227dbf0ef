//! What travels between hosts: the Zenoh key expressions of a world, the
//! frame as one Zenoh payload, the request envelope of the forwarded
//! services, and ROS 2's `rosgraph_msgs/msg/Clock` in CDR.
//!
//! A frame on Zenoh is the frame sample's bytes as they lie in shared
//! memory: the [`FrameHeader`] (little-endian, `#[repr(C)]`, its layout
//! pinned by a test and documented in docs/src/wire.md) followed by
//! `actor_count` [`ActorState`]s. A sensor capture is its
//! [`SensorHeader`] followed by the payload bytes. A forwarded request or
//! answer is the service's request (or answer) bytes, a slice service's
//! header first; every one starts with the sender's protocol version.

use bytemuck::{Pod, Zeroable};

use shared_types::{ActorState, FrameHeader, SensorHeader, WorldName, PROTOCOL_VERSION};

/// The Zenoh key expressions of one world.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BridgeKeys {
    prefix: String,
}

/// The services a bridge forwards, each a queryable under
/// `simbus/<world>/rpc/<name>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Forwarded {
    /// [`shared_types::ControlRequest`] → [`shared_types::ControlResponse`].
    Control,
    /// [`shared_types::TickRequest`] → [`shared_types::TickResponse`] (possibly an interim
    /// answer first).
    Tick,
    /// [`shared_types::BatchHeader`] and [`shared_types::Command`]s → a
    /// [`shared_types::BatchResponseHeader`] and [`shared_types::CommandResult`]s.
    Batch,
    /// [`shared_types::LockstepRequest`] → [`shared_types::LockstepResponse`].
    Lockstep,
    /// [`shared_types::SensorRequest`] → a [`shared_types::SensorResponseHeader`] and
    /// [`shared_types::SensorInfo`]s.
    Sensors,
    /// [`shared_types::RecorderRequest`] → [`shared_types::RecorderResponse`].
    Recorder,
}

impl Forwarded {
    /// Every forwarded service.
    pub const ALL: [Forwarded; 6] = [
        Self::Control,
        Self::Tick,
        Self::Batch,
        Self::Lockstep,
        Self::Sensors,
        Self::Recorder,
    ];

    /// The last segment of its key.
    pub fn name(self) -> &'static str {
        match self {
            Self::Control => "control",
            Self::Tick => "tick",
            Self::Batch => "batch",
            Self::Lockstep => "lockstep",
            Self::Sensors => "sensors",
            Self::Recorder => "recorder",
        }
    }
}

impl BridgeKeys {
    /// The keys of `world`.
    pub fn new(world: &WorldName) -> Self {
        Self {
            prefix: format!("simbus/{world}"),
        }
    }

    /// Every key of the world (`simbus/<world>/**`).
    pub fn all(&self) -> String {
        format!("{}/**", self.prefix)
    }

    /// Frames, one publication each ([`encode_frame`]).
    pub fn frames(&self) -> String {
        format!("{}/frames", self.prefix)
    }

    /// Queryable: the last frame the exporting bridge published.
    pub fn latest_frame(&self) -> String {
        format!("{}/frames/latest", self.prefix)
    }

    /// Captures of sensor `id` ([`encode_capture`]).
    pub fn sensor(&self, id: u64) -> String {
        format!("{}/sensor/{id}", self.prefix)
    }

    /// Every sensor's captures.
    pub fn sensors(&self) -> String {
        format!("{}/sensor/*", self.prefix)
    }

    /// Queryable of a forwarded service.
    pub fn rpc(&self, service: Forwarded) -> String {
        format!("{}/rpc/{}", self.prefix, service.name())
    }

    /// Publications: a mirror's tick requests, tagged with the mirror and
    /// the request id.
    pub fn tick_asks(&self) -> String {
        format!("{}/tick/ask", self.prefix)
    }

    /// Publications: the exporter's answers to them.
    pub fn tick_answers(&self) -> String {
        format!("{}/tick/answer", self.prefix)
    }

    /// Every forwarded service's queryable.
    pub fn every_rpc(&self) -> String {
        format!("{}/rpc/*", self.prefix)
    }

    /// Queryable: the world's status as JSON, for Zenoh tools.
    pub fn status(&self) -> String {
        format!("{}/status", self.prefix)
    }

    /// Queryable: the world's settings as JSON, for Zenoh tools.
    pub fn settings(&self) -> String {
        format!("{}/settings", self.prefix)
    }

    /// Liveliness token of the exporting bridge.
    pub fn exporter(&self) -> String {
        format!("{}/alive/exporter", self.prefix)
    }

    /// Liveliness token of the mirror `zid` (a Zenoh session id).
    pub fn mirror(&self, zid: &str) -> String {
        format!("{}/alive/mirror/{zid}", self.prefix)
    }

    /// Every mirror's liveliness token.
    pub fn mirrors(&self) -> String {
        format!("{}/alive/mirror/*", self.prefix)
    }
}

/// The Zenoh key ROS 2's `/clock` has under zenoh-bridge-ros2dds.
pub const ROS2_CLOCK_KEY: &str = "clock";

/// The most commands one forwarded batch (and its answer) may hold.
pub const MAX_FORWARDED_BATCH: usize = 65_536;

/// The size of the [`FrameHeader`] at the start of a frame payload.
pub const FRAME_HEADER_BYTES: usize = std::mem::size_of::<FrameHeader>();

/// The bytes of a frame payload of `actors` actors.
pub fn frame_len(actors: usize) -> usize {
    FRAME_HEADER_BYTES + actors * std::mem::size_of::<ActorState>()
}

/// The bytes of a capture payload of `payload` bytes.
pub fn capture_len(payload: usize) -> usize {
    std::mem::size_of::<SensorHeader>() + payload
}

/// Appends the frame (`header` then `actors`) to `out` as one payload.
pub fn encode_frame(header: &FrameHeader, actors: &[ActorState], out: &mut Vec<u8>) {
    out.extend_from_slice(bytemuck::bytes_of(header));
    out.extend_from_slice(bytemuck::cast_slice(actors));
}

/// Why a payload from another host is not a frame, a capture or a request.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PayloadError {
    /// Shorter than its header.
    #[error("{len} bytes cannot hold a {what} header of {need} bytes")]
    TooShort {
        /// What was expected.
        what: &'static str,
        /// Bytes received.
        len: usize,
        /// Bytes the header needs.
        need: usize,
    },
    /// The sender's protocol version is not this one.
    #[error("protocol version {peer} is not this version's {ours}")]
    ProtocolMismatch {
        /// The sender's.
        peer: u32,
        /// [`PROTOCOL_VERSION`].
        ours: u32,
    },
    /// The header's element count does not match the bytes after it.
    #[error("the {what} header announces {announced} bytes after it; {actual} arrived")]
    WrongLength {
        /// What was expected.
        what: &'static str,
        /// Bytes the header announces.
        announced: usize,
        /// Bytes that came.
        actual: usize,
    },
}

/// Reads a `T` from the start of `bytes` (any alignment).
fn read_header<T: Pod>(bytes: &[u8], what: &'static str) -> Result<T, PayloadError> {
    let need = std::mem::size_of::<T>();
    bytes
        .get(..need)
        .map(bytemuck::pod_read_unaligned)
        .ok_or(PayloadError::TooShort {
            what,
            len: bytes.len(),
            need,
        })
}

/// The header and the actors of a frame payload, checked: protocol version,
/// and exactly `actor_count` actors after the header.
///
/// # Errors
///
/// Returns [`PayloadError::TooShort`] if `bytes` cannot hold a frame header,
/// [`PayloadError::ProtocolMismatch`] if the header is of another protocol
/// version, and [`PayloadError::WrongLength`] if the bytes after it are not
/// exactly `actor_count` actors.
pub fn decode_frame(bytes: &[u8]) -> Result<(FrameHeader, Vec<ActorState>), PayloadError> {
    let mut reader = Slices::new([bytes]);
    let header = frame_header(&mut reader, bytes.len())?;
    let actors = (0..header.actor_count)
        .map_while(|_| reader.read::<ActorState>())
        .collect();
    Ok((header, actors))
}

/// The header of a frame payload of `len` bytes, read from `reader` and checked.
///
/// Checked: protocol version, and exactly `actor_count` actors after it.
/// The actors follow in `reader` (the mirror reads them straight into its
/// loaned sample).
///
/// # Errors
///
/// Returns [`PayloadError::TooShort`] if fewer than a frame header's bytes are
/// left in `reader`, [`PayloadError::ProtocolMismatch`] if the header is of
/// another protocol version, and [`PayloadError::WrongLength`] if `len` is not
/// exactly the header and `actor_count` actors.
pub fn frame_header<'a>(
    reader: &mut Slices<'a, impl Iterator<Item = &'a [u8]>>,
    len: usize,
) -> Result<FrameHeader, PayloadError> {
    let header: FrameHeader = reader.read().ok_or(PayloadError::TooShort {
        what: "frame",
        len,
        need: FRAME_HEADER_BYTES,
    })?;
    if header.protocol_version != PROTOCOL_VERSION {
        return Err(PayloadError::ProtocolMismatch {
            peer: header.protocol_version,
            ours: PROTOCOL_VERSION,
        });
    }
    let body = len.saturating_sub(FRAME_HEADER_BYTES);
    let announced = (header.actor_count as usize).saturating_mul(std::mem::size_of::<ActorState>());
    if body != announced {
        return Err(PayloadError::WrongLength {
            what: "frame",
            announced,
            actual: body,
        });
    }
    Ok(header)
}

/// `Pod` values read one after another from a payload that may lie in
/// several slices (a Zenoh payload as it arrived, not assembled): nothing
/// is copied but the values read.
#[derive(Debug)]
pub struct Slices<'a, I> {
    rest: I,
    current: &'a [u8],
}

impl<'a, I: Iterator<Item = &'a [u8]>> Slices<'a, I> {
    /// A reader of `slices`, in order.
    pub fn new(slices: impl IntoIterator<IntoIter = I>) -> Self {
        Self {
            rest: slices.into_iter(),
            current: &[],
        }
    }

    /// The next `T`, or `None` if fewer bytes are left.
    pub fn read<T: Pod>(&mut self) -> Option<T> {
        let size = std::mem::size_of::<T>();
        if let Some((bytes, rest)) = self.current.split_at_checked(size) {
            self.current = rest;
            return Some(bytemuck::pod_read_unaligned(bytes));
        }
        // Across slices.
        let mut value = T::zeroed();
        let mut out = bytemuck::bytes_of_mut(&mut value);
        while !out.is_empty() {
            if self.current.is_empty() {
                self.current = self.rest.next()?;
                continue;
            }
            let n = out.len().min(self.current.len());
            out[..n].copy_from_slice(&self.current[..n]);
            out = &mut out[n..];
            self.current = &self.current[n..];
        }
        Some(value)
    }
}

/// Appends a capture (`header` then its payload bytes) to `out`.
pub fn encode_capture(header: &SensorHeader, payload: &[u8], out: &mut Vec<u8>) {
    out.extend_from_slice(bytemuck::bytes_of(header));
    out.extend_from_slice(payload);
}

/// The header and payload bytes of a capture, checked: protocol version,
/// and at most [`shared_types::MAX_CAPTURE_BYTES`] after the header.
///
/// # Errors
///
/// Returns [`PayloadError::TooShort`] if `bytes` cannot hold a capture header,
/// [`PayloadError::ProtocolMismatch`] if the header is of another protocol
/// version, and [`PayloadError::WrongLength`] if more than
/// [`shared_types::MAX_CAPTURE_BYTES`] follow it.
pub fn decode_capture(bytes: &[u8]) -> Result<(SensorHeader, &[u8]), PayloadError> {
    let header: SensorHeader = read_header(bytes, "sensor capture")?;
    if header.protocol_version != PROTOCOL_VERSION {
        return Err(PayloadError::ProtocolMismatch {
            peer: header.protocol_version,
            ours: PROTOCOL_VERSION,
        });
    }
    let body = &bytes[std::mem::size_of::<SensorHeader>()..];
    if body.len() > shared_types::MAX_CAPTURE_BYTES {
        return Err(PayloadError::WrongLength {
            what: "sensor capture",
            announced: shared_types::MAX_CAPTURE_BYTES,
            actual: body.len(),
        });
    }
    Ok((header, body))
}

/// A request (or answer) of a fixed-size type `T`, checked: exactly
/// `size_of::<T>()` bytes, starting with [`PROTOCOL_VERSION`].
///
/// # Errors
///
/// Returns [`PayloadError::ProtocolMismatch`] if the payload does not start
/// with [`PROTOCOL_VERSION`] (checked first: another version's types may have
/// other sizes), [`PayloadError::TooShort`] if it is shorter than a `T`, and
/// [`PayloadError::WrongLength`] if it is longer.
pub fn decode_fixed<T: Pod>(bytes: &[u8], what: &'static str) -> Result<T, PayloadError> {
    // The version first: another version's types may have other sizes.
    if bytes.len() >= 4 {
        check_version(bytes)?;
    }
    let value: T = read_header(bytes, what)?;
    if bytes.len() != std::mem::size_of::<T>() {
        return Err(PayloadError::WrongLength {
            what,
            announced: std::mem::size_of::<T>(),
            actual: bytes.len(),
        });
    }
    Ok(value)
}

/// A slice request (or answer): its header `H`, checked to start with
/// [`PROTOCOL_VERSION`], and whole `T`s after it (at most `max`).
///
/// # Errors
///
/// Returns [`PayloadError::ProtocolMismatch`] if the payload does not start
/// with [`PROTOCOL_VERSION`], [`PayloadError::TooShort`] if it is shorter than
/// an `H`, and [`PayloadError::WrongLength`] if the bytes after the header are
/// not whole `T`s or are more than `max` of them.
pub fn decode_slice<H: Pod, T: Pod>(
    bytes: &[u8],
    what: &'static str,
    max: usize,
) -> Result<(H, Vec<T>), PayloadError> {
    if bytes.len() >= 4 {
        check_version(bytes)?;
    }
    let header: H = read_header(bytes, what)?;
    let body = &bytes[std::mem::size_of::<H>()..];
    let size = std::mem::size_of::<T>().max(1);
    if !body.len().is_multiple_of(size) || body.len() / size > max {
        return Err(PayloadError::WrongLength {
            what,
            announced: (body.len() / size).min(max) * size,
            actual: body.len(),
        });
    }
    Ok((
        header,
        body.chunks_exact(size)
            .map(bytemuck::pod_read_unaligned)
            .collect(),
    ))
}

/// Appends a slice request (or answer) to `out`: `header`, then `items`.
pub fn encode_slice<H: Pod, T: Pod>(header: &H, items: &[T], out: &mut Vec<u8>) {
    out.extend_from_slice(bytemuck::bytes_of(header));
    out.extend_from_slice(bytemuck::cast_slice(items));
}

fn check_version(bytes: &[u8]) -> Result<(), PayloadError> {
    let peer: u32 = read_header(bytes, "request")?;
    if peer != PROTOCOL_VERSION {
        return Err(PayloadError::ProtocolMismatch {
            peer,
            ours: PROTOCOL_VERSION,
        });
    }
    Ok(())
}

/// ROS 2's `rosgraph_msgs/msg/Clock` (one `builtin_interfaces/msg/Time`)
/// for simulation time `elapsed_ns`, serialized as CDR little-endian with
/// its encapsulation header: what a ROS 2 node with `use_sim_time` reads
/// on `/clock`. Seconds past `i32::MAX` (68 years) saturate.
pub fn ros2_clock_cdr(elapsed_ns: u64) -> [u8; 12] {
    let sec = i32::try_from(elapsed_ns / shared_types::NANOS_PER_SECOND).unwrap_or(i32::MAX);
    let nanosec = (elapsed_ns % shared_types::NANOS_PER_SECOND) as u32;
    let mut out = [0u8; 12];
    // CDR_LE encapsulation: representation id 0x0001, options 0.
    out[..4].copy_from_slice(&[0x00, 0x01, 0x00, 0x00]);
    out[4..8].copy_from_slice(&sec.to_le_bytes());
    out[8..].copy_from_slice(&nanosec.to_le_bytes());
    out
}

/// The bytes of a fixed-size wire value.
pub fn bytes_of<T: Pod>(value: &T) -> &[u8] {
    bytemuck::bytes_of(value)
}

/// A zeroed `T` (for tests and answers built from scratch).
pub fn zeroed<T: Zeroable>() -> T {
    T::zeroed()
}

#[cfg(test)]
#[path = "wire_tests.rs"]
mod tests;
