//! CARLA's `EpisodeSettings` as simbus's settings and back, with the
//! fields simbus does not have kept as a script last set them.

use rmpv::Value;
use shared_types::{SubstepRule, WorldSettings};

/// The warning CARLA 0.9.16's client logs (`Simulator::SetEpisodeSettings`)
/// when synchronous mode and substepping are on and `fixed_delta_seconds >
/// max_substep_delta_time * max_substeps`; CARLA applies the settings
/// anyway, and so does the gateway (the substep rule `clamp`).
pub(crate) const CARLA_SUBSTEP_WARNING: &str = "synchronous mode and substepping are enabled but the values for the simulation are not valid. The values should fulfil fixed_delta_seconds <= max_substep_delta_time * max_substeps. Be very careful about that, the time deltas are not guaranteed.";

/// The positions in CARLA's `EpisodeSettings` of the fields simbus does not
/// have (rendering, culling, ragdolls, large-map distances, spectator as
/// ego), and CARLA's defaults for them.
const OTHER_FIELDS: [usize; 6] = [1, 6, 7, 8, 9, 10];

/// CARLA's defaults of [`OTHER_FIELDS`].
pub(crate) fn default_other_fields() -> Vec<Value> {
    vec![
        Value::Boolean(false),
        Value::F32(0.0),
        Value::Boolean(true),
        Value::F32(3000.0),
        Value::F32(2000.0),
        Value::Boolean(false),
    ]
}

/// The [`OTHER_FIELDS`] of CARLA settings, if each has its default's type.
pub(crate) fn other_fields(value: Option<&Value>) -> Option<Vec<Value>> {
    let fields = value?.as_array()?;
    OTHER_FIELDS
        .iter()
        .zip(default_other_fields())
        .map(|(&i, default)| {
            let v = fields.get(i)?;
            let same = match default {
                Value::Boolean(_) => v.is_bool(),
                _ => v.as_f64().is_some() || v.as_i64().is_some(),
            };
            same.then(|| v.clone())
        })
        .collect()
}

/// simbus settings as CARLA's `EpisodeSettings` (11 fields; `other` holds
/// the ones simbus does not have, as a script last set them).
pub(crate) fn episode_settings(s: &WorldSettings, other: &[Value]) -> Value {
    let fixed = match s.fixed_delta_seconds {
        Some(dt) => Value::Array(vec![Value::Boolean(true), Value::F64(dt)]),
        None => Value::Array(vec![Value::Boolean(false)]),
    };
    let mut fields = vec![
        Value::Boolean(s.synchronous_mode),
        Value::Nil,
        fixed,
        Value::Boolean(s.substepping),
        Value::F64(s.max_substep_delta_time),
        Value::from(s.max_substeps),
    ];
    fields.resize(11, Value::Nil);
    let defaults = default_other_fields();
    for (k, &i) in OTHER_FIELDS.iter().enumerate() {
        fields[i] = other.get(k).unwrap_or(&defaults[k]).clone();
    }
    Value::Array(fields)
}

/// CARLA's `EpisodeSettings` as simbus settings (the fields simbus does not
/// have are ignored), with the substep rule `clamp`: a frame longer than
/// substepping allows runs CARLA's way.
pub(crate) fn parse_settings(value: Option<&Value>) -> Option<WorldSettings> {
    let fields = value?.as_array()?;
    let number = |v: &Value| v.as_f64().or_else(|| v.as_i64().map(|i| i as f64));
    let fixed = fields.get(2)?.as_array()?;
    let fixed_delta_seconds = match fixed.first()?.as_bool()? {
        true => Some(number(fixed.get(1)?)?),
        false => None,
    };
    Some(WorldSettings {
        synchronous_mode: fields.first()?.as_bool()?,
        fixed_delta_seconds,
        substepping: fields.get(3)?.as_bool()?,
        max_substep_delta_time: number(fields.get(4)?)?,
        max_substeps: u32::try_from(fields.get(5)?.as_u64()?).ok()?,
        substep_rule: SubstepRule::Clamp,
    })
}

/// CARLA's warning and what it means in numbers, when CARLA's client would
/// warn about `s` (synchronous, substepping, a fixed step longer than
/// `max_substep_delta_time * max_substeps`); `None` otherwise.
pub(crate) fn carla_substep_warning(s: &WorldSettings) -> Option<String> {
    let delta = s.fixed_delta_seconds.filter(|_| s.synchronous_mode)?;
    if !s.substepping || delta / s.max_substep_delta_time <= f64::from(s.max_substeps) {
        return None;
    }
    let what = if s.clamps_physics() {
        format!(
            "physics advances {:.3} s per {delta:.3} s frame ({} substeps of {:.3} s; substep rule '{}')",
            s.max_substep_delta_time * f64::from(s.max_substeps),
            s.max_substeps,
            s.max_substep_delta_time,
            s.substep_rule
        )
    } else {
        format!("substep rule '{}'", s.substep_rule)
    };
    Some(format!("{CARLA_SUBSTEP_WARNING} simbus: {what}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_round_trip_through_carlas_shape() {
        let s = WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.05),
            substepping: true,
            max_substep_delta_time: 0.01,
            max_substeps: 10,
            substep_rule: SubstepRule::Clamp,
        };
        assert_eq!(parse_settings(Some(&episode_settings(&s, &[]))), Some(s));
        let variable = WorldSettings {
            substep_rule: SubstepRule::Clamp,
            ..WorldSettings::default()
        };
        assert_eq!(
            parse_settings(Some(&episode_settings(&variable, &[]))),
            Some(variable)
        );
        // The fields simbus does not have come back as they were set.
        let mut other = default_other_fields();
        other[0] = Value::Boolean(true);
        other[3] = Value::F32(500.0);
        let carla = episode_settings(&s, &other);
        assert_eq!(other_fields(Some(&carla)), Some(other));
        assert_eq!(other_fields(Some(&Value::from(3))), None);
        assert_eq!(parse_settings(Some(&Value::from("nonsense"))), None);
    }

    #[test]
    fn carlas_warning_comes_with_its_numbers_only_when_carla_would_warn() {
        let carla = WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.2),
            substep_rule: SubstepRule::Clamp,
            ..WorldSettings::default()
        };
        assert_eq!(
            carla_substep_warning(&carla).as_deref(),
            Some(
                "synchronous mode and substepping are enabled but the values for the simulation \
                 are not valid. The values should fulfil fixed_delta_seconds <= \
                 max_substep_delta_time * max_substeps. Be very careful about that, the time \
                 deltas are not guaranteed. simbus: physics advances 0.100 s per 0.200 s frame \
                 (10 substeps of 0.010 s; substep rule 'clamp')"
            )
        );
        for quiet in [
            WorldSettings {
                fixed_delta_seconds: Some(0.1),
                ..carla
            },
            WorldSettings {
                synchronous_mode: false,
                ..carla
            },
            WorldSettings {
                substepping: false,
                ..carla
            },
        ] {
            assert_eq!(carla_substep_warning(&quiet), None, "{quiet}");
        }
    }
}
