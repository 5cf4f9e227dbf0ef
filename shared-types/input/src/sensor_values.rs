//! The values of a sensor's flags: ranges, fields of view, lidar and radar
//! parameters, noise seeds, image sizes, positions.

use shared_types::gnss::MAX_GNSS_SEED;
use shared_types::limits::MAX_ACTOR_POSITION;
use shared_types::{MAX_IMAGE_SIDE, MAX_LIDAR_CHANNELS, MAX_LIDAR_POINTS};

use crate::bounds::MAX_RATE_HZ;
use crate::error::InputError;
use crate::parse::{metres, number, real_in, whole_in};

/// A sensor's range, metres: a [`metres`] value.
///
/// # Errors
///
/// Returns the errors of [`metres`]: [`InputError::NotANumber`] if `text` does
/// not read as a number, [`InputError::Metres`] if it is not a positive, finite
/// distance of at most [`MAX_DISTANCE_METRES`].
pub fn sensor_range(text: &str) -> Result<f32, InputError> {
    metres(text).map(|m| m as f32)
}

/// A depth camera's horizontal field of view, degrees: above 0, below 180.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::FieldOfView`] if it is not finite, not above 0 or not below
/// 180.
pub fn field_of_view(text: &str) -> Result<f32, InputError> {
    let degrees = number(text)?;
    if degrees.is_finite() && degrees > 0.0 && degrees < 180.0 {
        return Ok(degrees as f32);
    }
    Err(InputError::FieldOfView {
        text: text.to_owned(),
    })
}

/// A lidar's channel count: `1..=`[`MAX_LIDAR_CHANNELS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_LIDAR_CHANNELS`].
pub fn lidar_channels(text: &str) -> Result<u32, InputError> {
    whole_in(text, 1..=u64::from(MAX_LIDAR_CHANNELS)).map(|n| n as u32)
}

/// A lidar's points per channel: `1..=`[`MAX_LIDAR_POINTS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_LIDAR_POINTS`].
pub fn lidar_points(text: &str) -> Result<u32, InputError> {
    whole_in(text, 1..=u64::from(MAX_LIDAR_POINTS)).map(|n| n as u32)
}

/// A GNSS receiver's noise seed: `0..=`[`MAX_GNSS_SEED`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `0..=`[`MAX_GNSS_SEED`].
pub fn gnss_seed(text: &str) -> Result<u32, InputError> {
    whole_in(text, 0..=u64::from(MAX_GNSS_SEED)).map(|n| n as u32)
}

/// A radar's rays per simulated second:
/// `1..=`[`shared_types::ranging::MAX_RADAR_POINTS_PER_SECOND`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`shared_types::ranging::MAX_RADAR_POINTS_PER_SECOND`].
pub fn radar_points_per_second(text: &str) -> Result<u32, InputError> {
    let max = shared_types::ranging::MAX_RADAR_POINTS_PER_SECOND;
    whole_in(text, 1..=u64::from(max)).map(|n| n as u32)
}

/// A lidar's atmosphere attenuation rate, per metre: 0 up to
/// [`MAX_RATE_HZ`] (the intensity is `exp(-rate × distance)`).
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is negative, not finite or above
/// [`MAX_RATE_HZ`].
pub fn attenuation_rate(text: &str) -> Result<f32, InputError> {
    real_in(text, 0.0..=MAX_RATE_HZ, " per metre").map(|rate| rate as f32)
}

/// An obstacle detector's hit radius, metres: above 0, at most 100.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is not finite, not above 0 or above 100.
pub fn hit_radius(text: &str) -> Result<f32, InputError> {
    let radius = number(text)?;
    if !(radius.is_finite() && radius > 0.0 && radius <= 100.0) {
        return Err(InputError::OutOfRange {
            text: text.to_owned(),
            start: 0.0,
            end: 100.0,
            unit: " of metres, above 0",
        });
    }
    Ok(radius as f32)
}

/// A lidar's rotation frequency: 0 (a full turn every capture) up to
/// [`MAX_RATE_HZ`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is negative, not finite or above
/// [`MAX_RATE_HZ`].
pub fn rotation_frequency(text: &str) -> Result<f32, InputError> {
    real_in(
        text,
        0.0..=MAX_RATE_HZ,
        " of Hz (0: a full turn every capture)",
    )
    .map(|hz| hz as f32)
}

/// An image size `W,H` in pixels, each a whole number in
/// `1..=`[`MAX_IMAGE_SIDE`] (the spec's check bounds their product).
///
/// # Errors
///
/// Returns [`InputError::ImageSize`] if `text` is not two comma-separated whole
/// numbers, each in `1..=`[`MAX_IMAGE_SIDE`].
pub fn image_size(text: &str) -> Result<[u32; 2], InputError> {
    let refused = || InputError::ImageSize {
        text: text.to_owned(),
    };
    let sides: Vec<u32> = text
        .split(',')
        .map(|part| {
            whole_in(part, 1..=u64::from(MAX_IMAGE_SIDE))
                .ok()
                .map(|n| n as u32)
        })
        .collect::<Option<_>>()
        .ok_or_else(refused)?;
    sides.try_into().map_err(|_| refused())
}

/// A position `x,y,z` in metres, each within ±[`MAX_ACTOR_POSITION`] of
/// the origin (the world's reach).
///
/// # Errors
///
/// Returns [`InputError::Position`] if `text` is not three comma-separated
/// numbers, or if any of them is not finite or is further than
/// [`MAX_ACTOR_POSITION`] metres from the origin.
pub fn position(text: &str) -> Result<[f32; 3], InputError> {
    let refused = || InputError::Position {
        text: text.to_owned(),
    };
    let values: Vec<f64> = text
        .split(',')
        .map(|part| number(part).ok())
        .collect::<Option<_>>()
        .ok_or_else(refused)?;
    let limit = f64::from(MAX_ACTOR_POSITION);
    let [x, y, z]: [f64; 3] = values.try_into().map_err(|_| refused())?;
    if [x, y, z].iter().all(|v| v.is_finite() && v.abs() <= limit) {
        Ok([x as f32, y as f32, z as f32])
    } else {
        Err(refused())
    }
}

/// A scene name (`default`, `empty`, `town`, `flat` or `boxes:N`, N in
/// `1..=`[`MAX_SCENE_BOXES`](shared_types::scene::MAX_SCENE_BOXES)),
/// checked as the server reads it.
///
/// # Errors
///
/// Returns [`InputError::Scene`] holding the
/// [`SceneNameError`](shared_types::scene::SceneNameError): `Unknown` for a
/// name the server does not know, `BoxCount` for a `boxes:N` whose N is not a
/// whole number in
/// `1..=`[`MAX_SCENE_BOXES`](shared_types::scene::MAX_SCENE_BOXES).
pub fn scene(text: &str) -> Result<String, InputError> {
    let name = text.parse::<shared_types::scene::SceneName>()?;
    Ok(name.to_string())
}
