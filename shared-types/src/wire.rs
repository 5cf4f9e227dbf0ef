//! Wire enums: `#[repr(u32)]` enums that travel as a `u32` field, declared
//! once with [`wire_enum!`], and the error for a value this version does not
//! know ([`UnknownWireValue`]).

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

/// A `u32` from a peer that names no variant of a wire enum: the peer speaks
/// a newer (or broken) protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{value} is not a {type_name} known to this version of simbus")]
pub struct UnknownWireValue {
    /// The enum the value was read as (`"RequestKind"`).
    pub type_name: &'static str,
    /// The value read.
    pub value: u32,
}

/// `text` in a fixed field of `N` bytes, cut at a character boundary:
/// (bytes used, the zero-padded field).
pub(crate) fn text_field<const N: usize>(text: &str) -> (u32, [u8; N]) {
    let mut end = text.len().min(N);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    let mut bytes = [0; N];
    bytes[..end].copy_from_slice(&text.as_bytes()[..end]);
    (end as u32, bytes)
}

/// The text of a fixed field whose first `len` bytes are used; a length
/// past the field, or invalid UTF-8 from a misbehaving peer, reads safely.
pub(crate) fn text_of(len: u32, bytes: &[u8]) -> String {
    let len = (len as usize).min(bytes.len());
    String::from_utf8_lossy(&bytes[..len]).into_owned()
}

/// Declares a `#[repr(u32)]` wire enum — doc comments, derives and
/// variants with explicit wire values, written as for a plain enum — and
/// generates its conversions:
///
/// - `impl TryFrom<u32>`, refusing unknown values with [`UnknownWireValue`];
/// - `impl From<Enum> for u32`;
/// - `Enum::from_u32(value) -> Option<Enum>`;
/// - `Enum::ALL`, every variant in declaration order.
///
/// Every variant needs an explicit `= value`: the values are the protocol.
macro_rules! wire_enum {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $(
                $(#[$variant_meta:meta])*
                $variant:ident = $value:literal
            ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[repr(u32)]
        $vis enum $name {
            $(
                $(#[$variant_meta])*
                $variant = $value,
            )+
        }

        impl $name {
            /// Every variant, in declaration order.
            pub const ALL: [Self; [$(stringify!($variant)),+].len()] = [$(Self::$variant),+];

            #[doc = concat!(
                "The [`", stringify!($name), "`] with wire value `value`, if this version knows it."
            )]
            pub fn from_u32(value: u32) -> Option<Self> {
                Self::try_from(value).ok()
            }
        }

        impl TryFrom<u32> for $name {
            type Error = $crate::wire::UnknownWireValue;

            fn try_from(value: u32) -> ::core::result::Result<Self, Self::Error> {
                match value {
                    $($value => ::core::result::Result::Ok(Self::$variant),)+
                    _ => ::core::result::Result::Err($crate::wire::UnknownWireValue {
                        type_name: stringify!($name),
                        value,
                    }),
                }
            }
        }

        impl From<$name> for u32 {
            fn from(value: $name) -> u32 {
                value as u32
            }
        }
    };
}

pub(crate) use wire_enum;

wire_enum! {
    /// How the server answered a request (a
    /// [`ControlRequest`](crate::control::ControlRequest), a tick, a batch, ...).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum ResponseStatus {
        /// Done.
        Ok = 0,
        /// The request's protocol version is not the server's; nothing was done.
        ProtocolMismatch = 1,
        /// The settings were refused ([`ControlResponse::settings_error`]); nothing changed.
        InvalidSettings = 2,
        /// The request kind is unknown to this server; nothing was done.
        UnknownRequest = 3,
        /// Synchronous mode is entered by the tick owner, not by settings alone.
        SyncNeedsTicker = 4,
        /// Only the tick owner may do this (or the sender is not the owner).
        NotTicker = 5,
        /// The scene name is not one the server knows; nothing changed.
        UnknownScene = 6,
        /// Tick service: this client's tick ownership ended because another
        /// client left synchronous mode (`TickResponse::revoked_by` names it).
        Revoked = 7,
        /// Tick service, an interim answer: the tick waits for a lockstep
        /// participant (`TickResponse::waiting_for`), which the server drops
        /// after `TickResponse::lockstep_timeout_ns`. The final answer follows.
        WaitingForParticipants = 8,
        /// Lockstep service: the sender is not (or no longer) a participant;
        /// the server dropped it or it never joined.
        NotParticipant = 9,
        /// Loading or reloading the world failed on the server (its log says
        /// why); the world is unchanged.
        LoadFailed = 10,
        /// The request was refused; the answer's error code says why (a
        /// sensor request: [`SensorRefusal`](crate::sensor::SensorRefusal)). Nothing changed.
        Refused = 11,
        /// Batch service: the world is replaying a recording, whose actors
        /// follow the recording; commands are refused until the replay ends.
        Replaying = 12,
        /// A mirroring bridge answers for a server on another host that it
        /// cannot reach now (the link is down or the exporting bridge is
        /// gone); nothing was done.
        Unreachable = 13,
        /// No snapshot has the id asked for; nothing changed.
        UnknownSnapshot = 14,
        /// The server holds as many snapshots as it keeps
        /// ([`MAX_SNAPSHOTS`]); drop one first. Nothing changed.
        SnapshotsFull = 15,
    }
}

/// Up to 64 bytes of UTF-8 text in a fixed-size field (scene names).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::FixedText/1")]
pub struct FixedText {
    /// Bytes in use.
    pub len: u32,
    /// Zero.
    pub reserved: u32,
    /// The text, zero-padded.
    pub bytes: [u8; 64],
}

impl FixedText {
    /// `text` cut to at most 64 bytes at a character boundary.
    pub fn new(text: &str) -> Self {
        let (len, bytes) = crate::wire::text_field(text);
        Self {
            len,
            reserved: 0,
            bytes,
        }
    }

    /// The text; invalid bytes from a misbehaving peer read as `?`.
    pub fn to_string_lossy(&self) -> String {
        crate::wire::text_of(self.len, &self.bytes)
    }
}

/// An answer of a request service: the server's protocol version and a
/// [`ResponseStatus`](crate::wire::ResponseStatus). Every request service's answer (or answer
/// header) implements it, so a client checks all of them the same way.
pub trait Response {
    /// The server's [`PROTOCOL_VERSION`](crate::wire::PROTOCOL_VERSION).
    fn protocol_version(&self) -> u32;
    /// A [`ResponseStatus`](crate::wire::ResponseStatus) as `u32`.
    fn status(&self) -> u32;
}

/// Implements [`Response`] for answer types with `protocol_version` and
/// `status` fields.
macro_rules! responses {
    ($($t:ty),*) => {$(
        impl $crate::wire::Response for $t {
            fn protocol_version(&self) -> u32 {
                self.protocol_version
            }
            fn status(&self) -> u32 {
                self.status
            }
        }
    )*};
}
pub(crate) use responses;

/// Version of the simbus wire protocol. Every payload carries it; a peer that
/// speaks another version gets [`ResponseStatus::ProtocolMismatch`] (or a
/// service it cannot open) instead of misread bytes.
pub const PROTOCOL_VERSION: u32 = 10;

/// This process's id, read once: every request carries it, and asking the
/// kernel for it on every request would be a syscall on the hot path.
pub fn this_process_id() -> u32 {
    static PID: std::sync::OnceLock<u32> = std::sync::OnceLock::new();
    *PID.get_or_init(std::process::id)
}

#[cfg(test)]
#[path = "wire_tests.rs"]
mod tests;
