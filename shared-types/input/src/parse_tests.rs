//! The value parsers' tests: each refuses what it must, with the flag's
//! range in its message.

use super::*;
use crate::sensor_values::*;
use shared_types::{MAX_IMAGE_SIDE, MAX_LIDAR_CHANNELS, MAX_LIDAR_POINTS};

#[test]
fn huge_tiny_and_odd_values_are_refused_not_panicked_on() {
    assert_eq!(render_threads("3").unwrap().get(), 3);
    for refused in ["0", "-1", "1025", "1.5", "many", "18446744073709551616"] {
        assert!(render_threads(refused).is_err(), "{refused}");
    }
    assert!(timeout("1e20").is_err());
    assert!(timeout("0").is_err());
    assert!(timeout("-1").is_err());
    assert!(timeout("nan").is_err());
    assert!(timeout("inf").is_err());
    assert_eq!(timeout("1e9").unwrap(), Duration::from_secs(1_000_000_000));
    assert!(rate("1e-30")
        .unwrap_err()
        .to_string()
        .contains("one tick every"));
    assert!(rate("1e300")
        .unwrap_err()
        .to_string()
        .contains("at most 1e6 Hz"));
    assert_eq!(rate("20").unwrap(), 20.0);
    assert_eq!(rate_limit("0").unwrap(), 0.0);
    assert!(rate_limit("NaN").is_err());
    assert!(sim_time("inf").unwrap_err().to_string().contains("finite"));
    assert!(sim_time("-1").is_err());
    assert_eq!(sim_time("2.5").unwrap(), 2.5);
    assert_eq!(sim_offset("-2.5").unwrap(), -2.5);
    assert!(sim_offset("-1e300").is_err());
    assert!(max_substeps("-1")
        .unwrap_err()
        .to_string()
        .contains("1..=16"));
    assert!(max_substeps("17").is_err());
    assert!(max_substeps("99999999999999999999").is_err());
    assert_eq!(max_substeps("16").unwrap(), 16);
    assert!(wait(1e30).is_err());
    assert!(micros("-5").is_err());
    assert!(hybrid_window("99999999999")
        .unwrap_err()
        .to_string()
        .contains("0..=1000000"));
    assert_eq!(hybrid_window("0").unwrap(), Duration::ZERO);
    assert!(keyframe_seconds("NaN").is_err());
    assert!(keyframe_seconds("0").is_err());
    assert_eq!(keyframe_seconds("10").unwrap(), 10.0);
    assert!(count("0").unwrap_err().to_string().contains(">= 1"));
    assert_eq!(count("3").unwrap(), 3);
    assert!(max_clients("0")
        .unwrap_err()
        .to_string()
        .contains("1..=1024"));
    assert!(field_of_view("180").is_err());
    assert!(sensor_range("1e300").is_err());
    assert!(position("1e9,0,0")
        .unwrap_err()
        .to_string()
        .contains("+-100000 m"));
    assert!(position("NaN,0,0").is_err());
    assert!(position("1,2").is_err());
    assert_eq!(position("-1, 2,3").unwrap(), [-1.0, 2.0, 3.0]);
}

#[test]
fn settings_flags_name_their_rule_and_range() {
    assert_eq!(fixed_delta_seconds("0").unwrap(), 0.0);
    let huge = fixed_delta_seconds("1e300").unwrap_err().to_string();
    assert!(
        huge.contains("1e300 s is longer than the maximum of 3600 s"),
        "{huge}"
    );
    assert!(huge.len() < 200, "no 300-digit numbers: {huge}");
    assert!(fixed_delta_seconds("-1")
        .unwrap_err()
        .to_string()
        .contains("negative"));
    assert!(fixed_delta_seconds("NaN")
        .unwrap_err()
        .to_string()
        .contains("not a finite number"));
    assert!(fixed_step("0")
        .unwrap_err()
        .to_string()
        .contains("1e-6..=3600 s"));
    assert_eq!(fps("0").unwrap(), 0.0);
    assert_eq!(fps("30").unwrap(), 30.0);
    let tiny = fps("1e-300").unwrap_err().to_string();
    assert!(tiny.contains("fps = 1e-300 is out of range"), "{tiny}");
    assert!(tiny.contains("0.000277778..=1e6"), "{tiny}");
    assert!(fps("1e300").is_err());
    // The range said once (issue 44, item 12: "it must be" twice).
    assert_eq!(
        fps("-20").unwrap_err().to_string(),
        "fps = -20 is negative: it must be 0 (variable step) or in 0.000277778..=1e6 \
         (a fixed step is 1e-6..=3600 s)"
    );
    assert!(max_substep_delta_time("0")
        .unwrap_err()
        .to_string()
        .contains("1e-6..=3600 s"));
}

#[test]
fn sensor_flags_accept_exactly_what_a_spec_accepts() {
    let side = format!("{MAX_IMAGE_SIDE}");
    assert_eq!(image_size(&format!("{side},1")), Ok([MAX_IMAGE_SIDE, 1]));
    assert!(image_size(&format!("{},1", MAX_IMAGE_SIDE + 1)).is_err());
    let channels = format!("{}", MAX_LIDAR_CHANNELS + 1);
    assert!(lidar_channels(&channels).is_err());
    let points = format!("{}", MAX_LIDAR_POINTS + 1);
    assert!(lidar_points(&points).is_err());
}
