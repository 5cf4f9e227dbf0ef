//! Every wire enum round-trips through `u32` and refuses unknown values.

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
    round_trips("SubstepRule", &crate::substep_rule::SubstepRule::ALL);
    round_trips("RecorderKind", &crate::recorder::RecorderKind::ALL);
    round_trips("ReplayMode", &crate::recorder::ReplayMode::ALL);
    round_trips("ReplayState", &crate::recorder::ReplayState::ALL);
    round_trips("RecorderRefusal", &crate::recorder::RecorderRefusal::ALL);
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
