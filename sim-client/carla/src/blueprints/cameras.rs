//! The cameras' blueprints: CARLA 0.9.16's attributes with their
//! defaults.
//! simbus's cameras are ray cast, so the size, field of view and
//! `sensor_tick` shape the image; the lens, exposure and post-processing
//! attributes are listed (scripts read and set them) and change nothing
//! (the CARLA table in the docs says so).

use super::{float, int, Attribute, Kind, ROLE_NAME};

pub(super) const fn text(id: &'static str, kind: Kind, default: &'static str) -> Attribute {
    Attribute {
        id,
        kind,
        default,
        modifiable: true,
    }
}

/// What every CARLA camera has: size, field of view, tick and lens.
macro_rules! camera_attributes {
    ($($more:expr),* $(,)?) => {
        &[
            ROLE_NAME,
            int("image_size_x", "800"),
            int("image_size_y", "600"),
            float("fov", "90.0"),
            float("sensor_tick", "0.0"),
            float("lens_circle_falloff", "5.0"),
            float("lens_circle_multiplier", "0.0"),
            float("lens_k", "-1.0"),
            float("lens_kcube", "0.0"),
            float("lens_x_size", "0.08"),
            float("lens_y_size", "0.08"),
            $($more),*
        ]
    };
}

/// The depth, semantic and instance segmentation cameras' attributes.
pub(super) const SEGMENTATION: &[Attribute] = camera_attributes!();

/// The RGB camera's attributes (`sensor.camera.rgb`).
pub(super) const RGB: &[Attribute] = camera_attributes!(
    float("bloom_intensity", "0.675"),
    float("blur_amount", "1.0"),
    float("blur_radius", "0.0"),
    float("chromatic_aberration_intensity", "0.0"),
    float("chromatic_aberration_offset", "0.0"),
    text("enable_postprocess_effects", Kind::Bool, "True"),
    float("exposure_compensation", "0.0"),
    float("exposure_max_bright", "12.0"),
    float("exposure_min_bright", "10.0"),
    text("exposure_mode", Kind::String, "histogram"),
    float("exposure_speed_down", "1.0"),
    float("exposure_speed_up", "3.0"),
    float("focal_distance", "1000.0"),
    float("fstop", "1.4"),
    float("gamma", "2.2"),
    float("iso", "100.0"),
    float("lens_flare_intensity", "0.1"),
    int("min_fps", "0"),
    float("motion_blur_intensity", "0.45"),
    float("motion_blur_max_distortion", "0.35"),
    float("motion_blur_min_object_screen_size", "0.1"),
    float("shoulder", "0.26"),
    float("shutter_speed", "200.0"),
    float("slope", "0.88"),
    float("temp", "6500.0"),
    float("tint", "0.0"),
    float("toe", "0.55"),
    float("white_clip", "0.04"),
    int("blade_count", "5"),
);

/// The DVS camera's attributes (`sensor.camera.dvs`): an RGB camera's and
/// its event thresholds (CARLA's defaults).
pub(super) const DVS: &[Attribute] = camera_attributes!(
    float("positive_threshold", "0.3"),
    float("negative_threshold", "0.3"),
    float("sigma_positive_threshold", "0.0"),
    float("sigma_negative_threshold", "0.0"),
    int("refractory_period_ns", "0"),
    text("use_log", Kind::Bool, "true"),
    float("log_eps", "0.001"),
);
