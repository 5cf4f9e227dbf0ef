//! Wire enums: `#[repr(u32)]` enums that travel as a `u32` field, declared
//! once with [`wire_enum!`], and the error for a value this version does not
//! know ([`UnknownWireValue`]).

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

#[cfg(test)]
mod tests {
    use std::fmt::Debug;

    use super::UnknownWireValue;
    use crate::*;

    /// Every variant of `all` survives `u32` and back; the smallest value
    /// that is no variant, and `u32::MAX`, are refused with an error naming
    /// the type and the value.
    fn round_trips<T>(type_name: &'static str, all: &[T])
    where
        T: Copy + PartialEq + Debug + Into<u32> + TryFrom<u32, Error = UnknownWireValue>,
    {
        assert!(!all.is_empty(), "{type_name}::ALL is empty");
        for &variant in all {
            let value: u32 = variant.into();
            assert_eq!(T::try_from(value), Ok(variant), "{type_name} value {value}");
        }
        let unknown = (0..).find(|v| all.iter().all(|&k| k.into() != *v));
        for value in [unknown.unwrap(), u32::MAX] {
            let error = T::try_from(value).unwrap_err();
            assert_eq!(error, UnknownWireValue { type_name, value });
            assert_eq!(
                error.to_string(),
                format!("{value} is not a {type_name} known to this version of simbus")
            );
        }
    }

    #[test]
    fn every_wire_enum_round_trips_and_refuses_unknown_values() {
        round_trips("RequestKind", &RequestKind::ALL);
        round_trips("Doorbell", &Doorbell::ALL);
        round_trips("ResponseStatus", &ResponseStatus::ALL);
        round_trips("TickRequestKind", &TickRequestKind::ALL);
        round_trips("LockstepKind", &LockstepKind::ALL);
        round_trips("SensorKind", &SensorKind::ALL);
        round_trips("SensorRequestKind", &SensorRequestKind::ALL);
        round_trips("SensorEnd", &SensorEnd::ALL);
        round_trips("SensorRefusal", &SensorRefusal::ALL);
        round_trips("CommandKind", &CommandKind::ALL);
        round_trips("CommandStatus", &CommandStatus::ALL);
        round_trips("ActorKind", &ActorKind::ALL);
        round_trips("SettingsField", &SettingsField::ALL);
        round_trips("SubstepRule", &crate::SubstepRule::ALL);
        round_trips("RecorderKind", &crate::RecorderKind::ALL);
        round_trips("ReplayMode", &crate::ReplayMode::ALL);
        round_trips("ReplayState", &crate::ReplayState::ALL);
        round_trips("RecorderRefusal", &crate::RecorderRefusal::ALL);
        // `from_u32` is `try_from(..).ok()`.
        assert_eq!(
            ResponseStatus::from_u32(9),
            Some(ResponseStatus::NotParticipant)
        );
        assert_eq!(
            ResponseStatus::from_u32(13),
            Some(ResponseStatus::Unreachable)
        );
        assert_eq!(
            ResponseStatus::from_u32(15),
            Some(ResponseStatus::SnapshotsFull)
        );
        assert_eq!(ResponseStatus::from_u32(16), None);
    }
}

/// An answer of a request service: the server's protocol version and a
/// [`crate::ResponseStatus`]. Every request service's answer (or answer
/// header) implements it, so a client checks all of them the same way.
pub trait Response {
    /// The server's [`crate::PROTOCOL_VERSION`].
    fn protocol_version(&self) -> u32;
    /// A [`crate::ResponseStatus`] as `u32`.
    fn status(&self) -> u32;
}

macro_rules! responses {
    ($($t:ty),*) => {$(
        impl Response for $t {
            fn protocol_version(&self) -> u32 {
                self.protocol_version
            }
            fn status(&self) -> u32 {
                self.status
            }
        }
    )*};
}
responses!(
    crate::ControlResponse,
    crate::TickResponse,
    crate::LockstepResponse,
    crate::BatchResponseHeader,
    crate::SensorResponseHeader,
    crate::RecorderResponse
);
