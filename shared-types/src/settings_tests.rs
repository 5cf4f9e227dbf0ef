//! Unit tests of [`super`]: validation, warnings, display and the wire.

use super::*;
use crate::settings_wire::{WireSettings, WireSettingsError};

fn fixed(dt: f64) -> WorldSettings {
    WorldSettings {
        fixed_delta_seconds: Some(dt),
        ..Default::default()
    }
}

#[test]
fn defaults_are_carla_defaults_and_valid() {
    let s = WorldSettings::default();
    assert!(!s.synchronous_mode);
    assert_eq!(s.fixed_delta_seconds, None);
    assert!(s.substepping);
    assert_eq!(s.max_substep_delta_time, 0.01);
    assert_eq!(s.max_substeps, 10);
    assert_eq!(s.validate(), Ok(()));
}

#[test]
fn non_finite_and_negative_values_are_refused() {
    let field = SettingsField::FixedDeltaSeconds;
    assert!(matches!(
        fixed(f64::NAN).validate(),
        Err(SettingsError::NotFinite { field: f, .. }) if f == field
    ));
    assert!(matches!(
        fixed(f64::INFINITY).validate(),
        Err(SettingsError::NotFinite { .. })
    ));
    assert_eq!(
        fixed(-0.1).validate(),
        Err(SettingsError::Negative { field, value: -0.1 })
    );
    let s = WorldSettings {
        max_substep_delta_time: -1.0,
        ..Default::default()
    };
    assert!(matches!(
        s.validate(),
        Err(SettingsError::Negative {
            field: SettingsField::MaxSubstepDeltaTime,
            ..
        })
    ));
    assert!(matches!(
        fixed(1e-9).validate(),
        Err(SettingsError::TooSmall { .. })
    ));
}

#[test]
fn zero_fixed_delta_means_variable_step() {
    assert_eq!(fixed(0.0).validate(), Ok(()));
    assert_eq!(fixed(0.0).normalized().fixed_delta_seconds, None);
    assert_eq!(fixed(0.0).fixed_delta_nanos(), None);
    assert_eq!(WorldSettings::delta_from_fps(0.0), Ok(None));
    assert_eq!(WorldSettings::delta_from_fps(20.0), Ok(Some(0.05)));
    assert!(WorldSettings::delta_from_fps(-1.0).is_err());
    assert!(WorldSettings::delta_from_fps(f64::NAN).is_err());
}

#[test]
fn max_substeps_must_be_within_1_to_16() {
    for (n, ok) in [(0, false), (1, true), (16, true), (17, false)] {
        let s = WorldSettings {
            max_substeps: n,
            fixed_delta_seconds: Some(0.001),
            ..Default::default()
        };
        assert_eq!(s.validate().is_ok(), ok, "max_substeps = {n}");
    }
}

#[test]
fn substep_rule_is_checked_exactly_and_named() {
    assert_eq!(fixed(0.1).validate(), Ok(()), "0.1 = 0.01 * 10 holds");
    let err = fixed(0.100_000_001).validate().unwrap_err();
    assert_eq!(
        err,
        SettingsError::SubstepRule {
            fixed: 0.100_000_001,
            max_dt: 0.01,
            max_substeps: 10
        }
    );
    assert!(err.to_string().contains("substep rule"));
    assert!(err
        .to_string()
        .contains("max_substep_delta_time (0.01 s) * max_substeps (10)"));
    let off = WorldSettings {
        substepping: false,
        ..fixed(0.5)
    };
    assert_eq!(
        off.validate(),
        Ok(()),
        "the rule binds only with substepping"
    );
}

#[test]
fn warnings_follow_the_limits() {
    assert!(fixed(0.05).warnings().is_empty());
    assert!(matches!(
        fixed(0.12).warnings()[..],
        [SettingsWarning::LongFrame { .. }]
    ));
    let coarse = WorldSettings {
        substepping: false,
        ..fixed(0.05)
    };
    assert!(matches!(
        coarse.warnings()[..],
        [SettingsWarning::LongSubstep { .. }]
    ));
}

#[test]
fn errors_survive_the_wire() {
    let errors = [
        SettingsError::NotFinite {
            field: SettingsField::Fps,
            value: f64::INFINITY,
        },
        SettingsError::Negative {
            field: SettingsField::FixedDeltaSeconds,
            value: -2.0,
        },
        SettingsError::TooSmall {
            field: SettingsField::MaxSubstepDeltaTime,
            value: 1e-9,
            min: MIN_DELTA_SECONDS,
        },
        SettingsError::MaxSubstepsOutOfRange { value: 17, max: 16 },
        SettingsError::SubstepRule {
            fixed: 0.5,
            max_dt: 0.01,
            max_substeps: 10,
        },
        SettingsError::UnknownSubstepRule { value: 7 },
    ];
    for e in errors {
        let (c, f, v) = e.to_wire();
        assert_eq!(SettingsError::from_wire(c, f, v), Some(e));
        assert_eq!(WireSettingsError::from(&e).error(), Some(e));
    }
    assert_eq!(SettingsError::from_wire(99, 0, [0.0; 3]), None);
    assert_eq!(WireSettingsError::NONE.error(), None);
    assert_eq!(WireSettingsError::default(), WireSettingsError::NONE);
    let unknown_field = WireSettingsError {
        field: 99,
        ..WireSettingsError::from(&errors[0])
    };
    assert_eq!(unknown_field.error(), None);
}

#[test]
fn wire_settings_error_layout_is_fixed() {
    assert_eq!(std::mem::size_of::<WireSettingsError>(), 32);
    assert_eq!(std::mem::align_of::<WireSettingsError>(), 8);
}

#[test]
fn long_thresholds_agree_in_seconds_and_nanoseconds() {
    assert_eq!(seconds_to_nanos(LONG_FRAME_SECONDS), LONG_FRAME_NS);
    assert_eq!(seconds_to_nanos(LONG_SUBSTEP_SECONDS), LONG_SUBSTEP_NS);
    // A frame of exactly 0.1 s is not long; one nanosecond more is.
    assert!(fixed(0.1).warnings().is_empty());
    assert!(seconds_to_nanos(0.1) <= LONG_FRAME_NS);
    assert!(seconds_to_nanos(0.100_000_001) > LONG_FRAME_NS);
    assert!(!fixed(0.100_000_001).warnings().is_empty());
}

#[test]
fn settings_display_as_one_line() {
    assert_eq!(
        WorldSettings::default().to_string(),
        "async, variable step, substepping <= 0.01 s x 10"
    );
    let sync = WorldSettings {
        synchronous_mode: true,
        ..fixed(0.05)
    };
    assert_eq!(
        sync.to_string(),
        "sync, fixed step 0.05 s, substepping <= 0.01 s x 10"
    );
    let coarse = WorldSettings {
        substepping: false,
        ..fixed(0.0)
    };
    assert_eq!(coarse.to_string(), "async, variable step, no substepping");
}

#[test]
fn settings_survive_the_wire() {
    let s = WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(0.05),
        substepping: false,
        max_substep_delta_time: 0.002,
        max_substeps: 3,
        substep_rule: SubstepRule::Stretch,
    };
    assert_eq!(WorldSettings::from(WireSettings::from(s)), s);
    assert_eq!(
        WorldSettings::from(WireSettings::from(WorldSettings::default())),
        WorldSettings::default()
    );
}
