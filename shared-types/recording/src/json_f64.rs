//! The `f64` fields of a recording's JSON messages (the header, the
//! settings of its events), written so that every value reads back.
//!
//! JSON has no NaN or infinity, and `serde_json` writes them as `null`,
//! which no `f64` reads back: a header holding one made a recording that
//! the server had closed cleanly unreadable ("not a simbus recording").
//! Here a finite number is written as a JSON number, as before, and NaN,
//! `inf` and `-inf` as the strings `"NaN"`, `"inf"` and `"-inf"`. Reading
//! takes both, and `null` as NaN, so the recordings written before this
//! encoding read too.

use serde::{Deserialize, Deserializer, Serializer};

/// A finite number, or the name of a non-finite one.
#[derive(Deserialize)]
#[serde(untagged)]
enum Repr {
    Number(f64),
    Name(String),
}

fn name(value: f64) -> &'static str {
    if value.is_nan() {
        "NaN"
    } else if value > 0.0 {
        "inf"
    } else {
        "-inf"
    }
}

fn from_repr<E: serde::de::Error>(repr: Option<Repr>) -> Result<f64, E> {
    match repr {
        None => Ok(f64::NAN),
        Some(Repr::Number(value)) => Ok(value),
        Some(Repr::Name(text)) => match text.as_str() {
            "NaN" => Ok(f64::NAN),
            "inf" => Ok(f64::INFINITY),
            "-inf" => Ok(f64::NEG_INFINITY),
            other => Err(E::custom(format!(
                "expected a number, \"NaN\", \"inf\" or \"-inf\", found \"{other}\""
            ))),
        },
    }
}

/// Writes `value` as a number, or as its name if it is not finite.
pub(super) fn serialize<S: Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
    if value.is_finite() {
        serializer.serialize_f64(*value)
    } else {
        serializer.serialize_str(name(*value))
    }
}

/// Reads a number, a name (`"NaN"`, `"inf"`, `"-inf"`) or `null` (NaN).
pub(super) fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    from_repr(Option::<Repr>::deserialize(deserializer)?)
}

/// The same for an `Option<f64>`: `None` is `null`, as before.
pub(super) mod option {
    use super::*;

    /// Writes `None` as `null`, a value as [`super::serialize`] does.
    pub(crate) fn serialize<S: Serializer>(
        value: &Option<f64>,
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        match value {
            None => serializer.serialize_none(),
            Some(v) if v.is_finite() => serializer.serialize_some(v),
            Some(v) => serializer.serialize_some(name(*v)),
        }
    }

    /// Reads `null` as `None`, anything else as [`super::deserialize`] does.
    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<Option<f64>, D::Error> {
        match Option::<Repr>::deserialize(deserializer)? {
            None => Ok(None),
            repr => from_repr(repr).map(Some),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::format::{RecordingHeader, RECORDING_VERSION};
    use shared_types::WorldSettings;

    fn header(keyframe_seconds: f64, fixed: Option<f64>) -> RecordingHeader {
        RecordingHeader {
            recording_version: RECORDING_VERSION,
            simbus_version: "0".into(),
            protocol_version: shared_types::PROTOCOL_VERSION,
            world: "w".into(),
            scene: "default".into(),
            seed: 0,
            settings: WorldSettings {
                fixed_delta_seconds: fixed,
                ..WorldSettings::default()
            }
            .into(),
            start_frame: 0,
            start_elapsed_ns: 0,
            episode: 0,
            start_platform_timestamp: 1.5,
            sensors: true,
            keyframe_seconds,
            journal_sync_frames: 0,
            run_pid: 0,
        }
    }

    #[test]
    fn non_finite_numbers_are_named_and_read_back() {
        for (value, name) in [
            (f64::NAN, "\"NaN\""),
            (f64::INFINITY, "\"inf\""),
            (f64::NEG_INFINITY, "\"-inf\""),
        ] {
            let json = serde_json::to_string(&header(value, Some(value))).unwrap();
            assert!(
                json.contains(&format!("\"keyframe_seconds\":{name}")),
                "{json}"
            );
            assert!(
                json.contains(&format!("\"fixed_delta_seconds\":{name}")),
                "{json}"
            );
            let back: RecordingHeader = serde_json::from_str(&json).unwrap();
            assert_eq!(back.keyframe_seconds.to_string(), value.to_string());
            let fixed = back.settings.fixed_delta_seconds.expect("kept as Some");
            assert_eq!(fixed.to_string(), value.to_string());
        }
        // Finite numbers and None are written as before.
        let json = serde_json::to_string(&header(10.0, None)).unwrap();
        assert!(json.contains("\"keyframe_seconds\":10.0"), "{json}");
        assert!(json.contains("\"fixed_delta_seconds\":null"), "{json}");
        assert_eq!(
            serde_json::from_str::<RecordingHeader>(&json).unwrap(),
            header(10.0, None)
        );
    }

    #[test]
    fn every_finite_number_reads_back_bit_for_bit() {
        // Subnormals and the extremes too: the recorder's header round trip
        // found -1.031589542038677e-308 read back a few ULPs off.
        for value in [
            -1.031589542038677e-308,
            f64::MIN_POSITIVE / 3.0,
            -f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            0.1 + 0.2,
            -0.0,
            1.0 / 3.0,
        ] {
            let json = serde_json::to_string(&header(value, Some(value))).unwrap();
            let back: RecordingHeader = serde_json::from_str(&json).unwrap();
            assert_eq!(
                back.keyframe_seconds.to_bits(),
                value.to_bits(),
                "{value:e}"
            );
            let fixed = back.settings.fixed_delta_seconds.expect("kept as Some");
            assert_eq!(fixed.to_bits(), value.to_bits(), "{value:e}");
        }
    }

    #[test]
    fn headers_written_with_null_before_this_encoding_read() {
        // What `--keyframe-seconds NaN` wrote before (issue #24).
        let json = serde_json::to_string(&header(10.0, None))
            .unwrap()
            .replace("\"keyframe_seconds\":10.0", "\"keyframe_seconds\":null");
        let back: RecordingHeader = serde_json::from_str(&json).unwrap();
        assert!(back.keyframe_seconds.is_nan());
        let bad = json.replace("null", "\"fast\"");
        assert!(serde_json::from_str::<RecordingHeader>(&bad).is_err());
    }

    #[test]
    fn a_header_without_fixed_delta_seconds_reads_as_variable_step() {
        // `with = ...` on an Option field makes the key required unless the
        // field also has `default`: a header (or settings event) written
        // without it must read, as a plain `Option<f64>` would.
        let json = serde_json::to_string(&header(10.0, None))
            .unwrap()
            .replace("\"fixed_delta_seconds\":null,", "");
        assert!(!json.contains("fixed_delta_seconds"), "{json}");
        let back: RecordingHeader = serde_json::from_str(&json).unwrap();
        assert_eq!(back, header(10.0, None));
        assert_eq!(back.settings.fixed_delta_seconds, None);
    }
}
