//! The GNSS receiver: where on the Earth the sensor is
//! ([`shared_types::gnss::geolocation`]), plus CARLA's bias and a normal
//! error per component drawn from a generator seeded with the sensor's
//! `noise_seed` (the same seed, the same errors, run after run:
//! [`Random`]).

use rapier3d::prelude::Pose;
use shared_types::{Gnss, GnssMeasurement};

use super::random::Random;

/// The reading of a receiver with `params` at `pose`, its errors drawn
/// from `noise`.
pub(super) fn reading(params: &Gnss, pose: Pose, noise: &mut Random) -> GnssMeasurement {
    let [x, y, z] = pose.translation.to_array().map(f64::from);
    let place = shared_types::gnss::geolocation([x, y, z]);
    let (lat_error, lon_error, alt_error) = (
        noise.normal(params.lat_stddev),
        noise.normal(params.lon_stddev),
        noise.normal(params.alt_stddev),
    );
    GnssMeasurement {
        latitude: place.latitude + f64::from(params.lat_bias) + lat_error,
        longitude: place.longitude + f64::from(params.lon_bias) + lon_error,
        altitude: place.altitude + f64::from(params.alt_bias) + alt_error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rapier3d::prelude::Vector;

    fn at(x: f32, y: f32, z: f32) -> Pose {
        Pose::from_translation(Vector::new(x, y, z))
    }

    #[test]
    fn without_noise_it_reads_the_place_and_the_bias() {
        let params = Gnss {
            alt_bias: 2.0,
            ..Gnss::default()
        };
        let mut noise = Random::new(0);
        let origin = reading(&params, at(0.0, 1.5, 0.0), &mut noise);
        assert_eq!(
            (origin.latitude, origin.longitude, origin.altitude),
            (0.0, 0.0, 3.5)
        );
        let north = reading(&params, at(0.0, 0.0, 100.0), &mut noise);
        let place = shared_types::gnss::geolocation([0.0, 0.0, 100.0]);
        assert_eq!(north.latitude, place.latitude);
    }

    #[test]
    fn the_same_seed_draws_the_same_errors_and_their_spread_is_the_deviation() {
        let params = Gnss {
            lat_stddev: 1e-5,
            seed: 7,
            ..Gnss::default()
        };
        let draw = |seed| {
            let mut noise = Random::new(seed);
            (0..2000)
                .map(|_| reading(&params, at(0.0, 0.0, 0.0), &mut noise).latitude)
                .collect::<Vec<_>>()
        };
        let (a, b, c) = (draw(7), draw(7), draw(8));
        assert_eq!(a, b);
        assert_ne!(a, c);
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        let spread = (a.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / a.len() as f64).sqrt();
        assert!((spread / 1e-5 - 1.0).abs() < 0.1, "spread {spread}");
        assert!(mean.abs() < 1e-6, "mean {mean}");
    }
}
