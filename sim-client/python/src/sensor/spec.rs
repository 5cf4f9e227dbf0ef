//! What `spawn_sensor`'s keyword arguments describe: the [`SensorSpec`],
//! checked by the Rust client before anything is sent; a keyword a kind
//! does not take, or a noise setting it does not know, is a `ValueError`.

use std::collections::HashMap;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::gnss::MAX_GNSS_SEED;
use shared_types::{
    Camera, Gnss, Lidar, LidarNoise, Radar, SensorKind, SensorParams, SensorSpec, SensorSpecError,
};
use sim_client::SensorError;

use super::{kind_name, sensor_error};

/// A size given as a number: a whole one, or the Rust check's error
/// (`not_whole`, or NaN's) as a `ValueError`. The check bounds it.
fn whole(value: f64, not_whole: SensorSpecError) -> PyResult<u32> {
    let error = match value {
        v if !v.is_finite() => SensorSpecError::NotFinite,
        v if v.fract() != 0.0 || !(1.0..=f64::from(u32::MAX)).contains(&v) => not_whole,
        v => return Ok(v as u32),
    };
    Err(sensor_error(SensorError::InvalidSpec(error)))
}

/// The spec `kind` and the keyword arguments of `spawn_sensor` describe
/// (checked by the Rust client before anything is sent).
pub(super) fn spec_for(kind: &str, p: &SpawnParams) -> PyResult<SensorSpec> {
    use SensorKind as Kind;
    // `semantic_lidar` reads as the command line's `semantic-lidar`.
    let Some(kind) = Kind::from_name(&kind.replace('_', "-")) else {
        return Err(PyValueError::new_err(format!(
            "unknown sensor kind {kind:?}: expected 'depth', 'rgb', 'semantic', 'instance', 'lidar', 'semantic_lidar', 'radar', 'imu', 'gnss', 'collision' or 'obstacle'"
        )));
    };
    const CAMERAS: &[Kind] = &[Kind::Depth, Kind::Rgb, Kind::Semantic, Kind::Instance];
    const LIDARS: &[Kind] = &[Kind::Lidar, Kind::SemanticLidar];
    const RANGED: &[Kind] = &[
        Kind::Depth,
        Kind::Rgb,
        Kind::Semantic,
        Kind::Instance,
        Kind::Lidar,
        Kind::SemanticLidar,
        Kind::Radar,
        Kind::Obstacle,
    ];
    const WIDE: &[Kind] = &[
        Kind::Depth,
        Kind::Rgb,
        Kind::Semantic,
        Kind::Instance,
        Kind::Radar,
    ];
    let given: [(&str, bool, &[Kind]); 14] = [
        ("hit_radius", p.hit_radius.is_some(), &[Kind::Obstacle]),
        (
            "only_dynamics",
            p.only_dynamics.is_some(),
            &[Kind::Obstacle],
        ),
        ("width", p.width.is_some(), CAMERAS),
        ("height", p.height.is_some(), CAMERAS),
        ("fov", p.fov.is_some(), WIDE),
        ("vertical_fov", p.vertical_fov.is_some(), &[Kind::Radar]),
        (
            "points_per_second",
            p.points_per_second.is_some(),
            &[Kind::Radar],
        ),
        ("range", p.range.is_some(), RANGED),
        ("channels", p.channels.is_some(), LIDARS),
        ("points", p.points.is_some(), LIDARS),
        ("upper_fov", p.upper_fov.is_some(), LIDARS),
        ("lower_fov", p.lower_fov.is_some(), LIDARS),
        ("rotation_frequency", p.rotation_frequency.is_some(), LIDARS),
        (
            "noise",
            p.noise.is_some(),
            &[Kind::Gnss, Kind::Lidar, Kind::Radar],
        ),
    ];
    for (name, present, kinds) in given {
        if present && !kinds.contains(&kind) {
            return Err(PyValueError::new_err(format!(
                "{name} applies to {} sensors, not to {}",
                // Python's spelling: `semantic_lidar`.
                SensorKind::listed(kinds).replace('-', "_"),
                kind_name(kind as u32)
            )));
        }
    }
    let at = p.at.map(|v| v as f32);
    let mut spec = match kind {
        Kind::Depth | Kind::Rgb | Kind::Semantic | Kind::Instance => {
            let far = if kind == Kind::Depth { 100.0 } else { 1000.0 };
            let camera = Camera {
                width: whole(p.width.unwrap_or(640.0), SensorSpecError::CameraSize)?,
                height: whole(p.height.unwrap_or(480.0), SensorSpecError::CameraSize)?,
                fov: p.fov.unwrap_or(90.0) as f32,
                range: p.range.unwrap_or(far) as f32,
            };
            let params = SensorParams::camera_of(kind, camera).expect("a camera kind");
            SensorSpec::with_params(at, params)
        }
        Kind::Lidar | Kind::SemanticLidar => {
            let lidar = Lidar {
                channels: whole(p.channels.unwrap_or(32.0), SensorSpecError::LidarSize)?,
                points: whole(p.points.unwrap_or(512.0), SensorSpecError::LidarSize)?,
                range: p.range.unwrap_or(50.0) as f32,
                upper_fov: p.upper_fov.unwrap_or(10.0) as f32,
                lower_fov: p.lower_fov.unwrap_or(-30.0) as f32,
                rotation_hz: p.rotation_frequency.unwrap_or(0.0) as f32,
                noise: Default::default(),
            };
            match kind {
                Kind::Lidar => SensorSpec::with_params(
                    at,
                    Lidar {
                        noise: lidar_noise(p.noise.as_ref())?,
                        ..lidar
                    },
                ),
                _ => SensorSpec::semantic_lidar(at, lidar),
            }
        }
        Kind::Radar => SensorSpec::with_params(at, radar(p)?),
        Kind::Imu => SensorSpec::imu(at),
        Kind::Gnss => SensorSpec::with_params(at, gnss_noise(p.noise.as_ref())?),
        Kind::Collision => SensorSpec::with_params(at, shared_types::Collision),
        Kind::Obstacle => {
            let defaults = shared_types::Obstacle::default();
            let obstacle = shared_types::Obstacle {
                distance: p.range.map_or(defaults.distance, |v| v as f32),
                hit_radius: p.hit_radius.map_or(defaults.hit_radius, |v| v as f32),
                only_dynamics: p.only_dynamics.unwrap_or(defaults.only_dynamics),
            };
            SensorSpec::with_params(at, obstacle)
        }
    };
    spec.rotation = p.rotation.unwrap_or_default().map(|v| v as f32);
    Ok(spec.attached_to(p.parent.unwrap_or(0)).every(p.sensor_tick))
}

/// A noise `seed` given as a number: a whole one in `0..=`[`MAX_GNSS_SEED`],
/// else `error`.
fn noise_seed(value: f64, error: SensorSpecError) -> PyResult<u32> {
    if value.fract() == 0.0 && (0.0..=f64::from(MAX_GNSS_SEED)).contains(&value) {
        Ok(value as u32)
    } else {
        Err(sensor_error(SensorError::InvalidSpec(error)))
    }
}

/// A GNSS receiver's `noise` keyword argument: CARLA's attribute names
/// without their `noise_` prefix (`lat_bias`, `lat_stddev`, `lon_bias`,
/// `lon_stddev`, `alt_bias`, `alt_stddev`, `seed`), each 0 unless given.
fn gnss_noise(noise: Option<&HashMap<String, f64>>) -> PyResult<Gnss> {
    let mut gnss = Gnss::default();
    for (name, &value) in noise.into_iter().flatten() {
        let slot = match name.as_str() {
            "lat_bias" => &mut gnss.lat_bias,
            "lat_stddev" => &mut gnss.lat_stddev,
            "lon_bias" => &mut gnss.lon_bias,
            "lon_stddev" => &mut gnss.lon_stddev,
            "alt_bias" => &mut gnss.alt_bias,
            "alt_stddev" => &mut gnss.alt_stddev,
            "seed" => {
                gnss.seed = noise_seed(value, SensorSpecError::GnssNoise)?;
                continue;
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown noise setting '{other}': expected lat_bias, lat_stddev, lon_bias, lon_stddev, alt_bias, alt_stddev or seed"
                )))
            }
        };
        *slot = value as f32;
    }
    Ok(gnss)
}

/// A lidar's `noise` keyword argument: CARLA's attribute names without
/// their `noise_` prefix (`stddev`, `dropoff_general_rate`,
/// `dropoff_intensity_limit`, `dropoff_zero_intensity`,
/// `atmosphere_attenuation_rate`, `seed`), each 0 unless given.
fn lidar_noise(noise: Option<&HashMap<String, f64>>) -> PyResult<LidarNoise> {
    let mut lidar = LidarNoise::default();
    for (name, &value) in noise.into_iter().flatten() {
        let slot = match name.as_str() {
            "stddev" => &mut lidar.noise_stddev,
            "dropoff_general_rate" => &mut lidar.dropoff_general_rate,
            "dropoff_intensity_limit" => &mut lidar.dropoff_intensity_limit,
            "dropoff_zero_intensity" => &mut lidar.dropoff_zero_intensity,
            "atmosphere_attenuation_rate" => &mut lidar.atmosphere_attenuation_rate,
            "seed" => {
                lidar.seed = noise_seed(value, SensorSpecError::LidarNoise)?;
                continue;
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown noise setting '{other}' for a lidar: expected stddev, dropoff_general_rate, dropoff_intensity_limit, dropoff_zero_intensity, atmosphere_attenuation_rate or seed"
                )))
            }
        };
        *slot = value as f32;
    }
    Ok(lidar)
}

/// A radar's parameters from `spawn_sensor`'s keyword arguments: `fov`
/// and `vertical_fov` (30 each), `range` (100), `points_per_second`
/// (1500) and `noise={"seed": N}` (0).
fn radar(p: &SpawnParams) -> PyResult<Radar> {
    let defaults = Radar::default();
    let mut seed = defaults.seed;
    for (name, &value) in p.noise.iter().flatten() {
        match name.as_str() {
            "seed" => seed = noise_seed(value, SensorSpecError::Radar)?,
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown noise setting '{other}' for a radar: expected seed"
                )))
            }
        }
    }
    Ok(Radar {
        horizontal_fov: p.fov.map_or(defaults.horizontal_fov, |v| v as f32),
        vertical_fov: p.vertical_fov.map_or(defaults.vertical_fov, |v| v as f32),
        range: p.range.map_or(defaults.range, |v| v as f32),
        points_per_second: match p.points_per_second {
            Some(n) => whole(n, SensorSpecError::Radar)?,
            None => defaults.points_per_second,
        },
        seed,
    })
}

/// `spawn_sensor`'s keyword arguments.
pub(super) struct SpawnParams {
    pub(super) parent: Option<u64>,
    pub(super) at: [f64; 3],
    pub(super) rotation: Option<[f64; 4]>,
    pub(super) sensor_tick: f64,
    pub(super) width: Option<f64>,
    pub(super) height: Option<f64>,
    pub(super) fov: Option<f64>,
    pub(super) range: Option<f64>,
    pub(super) channels: Option<f64>,
    pub(super) points: Option<f64>,
    pub(super) upper_fov: Option<f64>,
    pub(super) lower_fov: Option<f64>,
    pub(super) rotation_frequency: Option<f64>,
    pub(super) noise: Option<HashMap<String, f64>>,
    pub(super) hit_radius: Option<f64>,
    pub(super) only_dynamics: Option<bool>,
    pub(super) vertical_fov: Option<f64>,
    pub(super) points_per_second: Option<f64>,
}
