//! The GNSS sensor: its parameters' limits, its reading, and where on the
//! Earth a place of a simbus world is.
//!
//! Every simbus road network carries one geographic reference
//! ([`crate::roads::GEO_REFERENCE`]: a transverse Mercator projection of a
//! sphere of radius 6 378 137 m, centred at 0°, 0°, scale 0.9996 on its
//! meridian, no offsets). A place's latitude and longitude are that
//! projection's inverse (Snyder's series to the sixth order) applied to the
//! place in CARLA's axes (x forward, y right, z up; simbus's X, Z, Y, with
//! CARLA's `y` taken as it is); the altitude is the place's height. It is
//! what CARLA 0.9.16's client computes on that map
//! (`Map.transform_to_geolocation`); it computed the WGS84 `k=1` reference
//! simbus carried before the same way, 0.6 % away from what that reference
//! says.
//!
//! ```
//! use shared_types::gnss::geolocation;
//!
//! let origin = geolocation([0.0, 0.0, 0.0]);
//! assert_eq!([origin.latitude, origin.longitude], [0.0, 0.0]);
//! // 100 m along CARLA's y: a degree is 0.9996 x 6 378 137 m x pi / 180.
//! let moved = geolocation([0.0, 0.0, 100.0]);
//! assert!((moved.latitude - 100.0 / 111_274.955).abs() < 1e-9);
//! ```

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

/// The largest `noise_seed`: an `f32` on the wire holds every whole number
/// up to it.
pub const MAX_GNSS_SEED: u32 = 1 << 24;

/// A GNSS sensor's parameters: CARLA's noise attributes. Degrees for
/// latitude and longitude, metres for altitude; each reading adds the bias
/// and a normal error of that standard deviation, drawn from a generator
/// seeded with `seed` (the same seed, the same errors).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Gnss {
    /// Added to every latitude, degrees.
    pub lat_bias: f32,
    /// Standard deviation of the latitude's error, degrees.
    pub lat_stddev: f32,
    /// Added to every longitude, degrees.
    pub lon_bias: f32,
    /// Standard deviation of the longitude's error, degrees.
    pub lon_stddev: f32,
    /// Added to every altitude, metres.
    pub alt_bias: f32,
    /// Standard deviation of the altitude's error, metres.
    pub alt_stddev: f32,
    /// The noise generator's seed, `0..=`[`MAX_GNSS_SEED`].
    pub seed: u32,
}

impl Gnss {
    /// Whether every bias is finite, every deviation finite and not
    /// negative, and the seed in range (the wire's `f32` checked as sent:
    /// `seed_on_wire`).
    pub(crate) fn valid(&self, seed_on_wire: f32) -> bool {
        let biases = [self.lat_bias, self.lon_bias, self.alt_bias];
        let deviations = [self.lat_stddev, self.lon_stddev, self.alt_stddev];
        biases.iter().all(|b| b.is_finite())
            && deviations.iter().all(|d| d.is_finite() && *d >= 0.0)
            && seed_on_wire >= 0.0
            && seed_on_wire <= MAX_GNSS_SEED as f32
            && seed_on_wire.fract() == 0.0
    }

    /// Whether any reading gets an error drawn.
    pub fn noisy(&self) -> bool {
        self.lat_stddev > 0.0 || self.lon_stddev > 0.0 || self.alt_stddev > 0.0
    }
}

/// One GNSS reading: CARLA's `GnssMeasurement` (its `GeoLocation`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::GnssMeasurement/1")]
pub struct GnssMeasurement {
    /// Degrees north.
    pub latitude: f64,
    /// Degrees east.
    pub longitude: f64,
    /// Metres.
    pub altitude: f64,
}

/// The projection's sphere: its radius, metres.
const RADIUS: f64 = 6_378_137.0;
/// The projection's scale on its central meridian.
const SCALE: f64 = 0.9996;

/// Where on the Earth simbus position `position` (X forward, Y up, Z
/// right) is, by [`crate::roads::GEO_REFERENCE`] (see the module).
pub fn geolocation(position: [f64; 3]) -> GnssMeasurement {
    // CARLA's axes: x = X, y = Z, z = Y.
    let [x, height, y] = position;
    // Snyder's inverse on a sphere: the footpoint latitude is the northing
    // over the scaled radius; T = tan² of it, C = 0.
    let phi1 = y / (SCALE * RADIUS);
    let d = x / (SCALE * RADIUS);
    let tan1 = phi1.tan();
    let t = tan1 * tan1;
    let latitude = phi1
        - tan1
            * (d * d / 2.0 - (5.0 + 3.0 * t) * d.powi(4) / 24.0
                + (61.0 + 90.0 * t + 45.0 * t * t) * d.powi(6) / 720.0);
    let longitude = (d - (1.0 + 2.0 * t) * d.powi(3) / 6.0
        + (5.0 + 28.0 * t + 24.0 * t * t) * d.powi(5) / 120.0)
        / phi1.cos();
    GnssMeasurement {
        latitude: latitude.to_degrees(),
        longitude: longitude.to_degrees(),
        altitude: height,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn places_read_as_carla_0916s_client_reads_them_on_the_same_map() {
        // `Map.transform_to_geolocation` of the real carla==0.9.16 client on
        // a map with this reference (CARLA's x, y, z -> latitude, longitude).
        let carla = [
            ([0.0, 100.0, 0.0], [0.000_898_674_754_021_13, 0.0]),
            (
                [1000.0, 2000.0, 3.0],
                [0.017_973_494_859_336_02, 0.008_986_747_945_536_683],
            ),
            ([-300.0, 0.0, 0.0], [0.0, -0.002_696_024_261_068_499_7]),
            ([0.0, 1e6, 0.0], [8.986_747_540_211_299, 0.0]),
            (
                [5e5, -2e5, 0.0],
                [-1.791_834_671_877_87, 4.490_975_341_707_704],
            ),
        ];
        for ([x, y, z], [latitude, longitude]) in carla {
            let got = geolocation([x, z, y]);
            // Exact at a town's scale; within 2e-8 degrees 500 km out.
            assert!(
                (got.latitude - latitude).abs() < 2e-8,
                "{got:?} at {x}, {y}"
            );
            assert!(
                (got.longitude - longitude).abs() < 2e-8,
                "{got:?} at {x}, {y}"
            );
            assert_eq!(got.altitude, z);
        }
    }

    #[test]
    fn noise_parameters_are_checked_as_sent() {
        let quiet = Gnss::default();
        assert!(quiet.valid(0.0) && !quiet.noisy());
        let noisy = Gnss {
            lat_stddev: 1e-6,
            ..quiet
        };
        assert!(noisy.valid(7.0) && noisy.noisy());
        assert!(!Gnss {
            alt_stddev: -1.0,
            ..quiet
        }
        .valid(0.0));
        assert!(!Gnss {
            lon_bias: f32::NAN,
            ..quiet
        }
        .valid(0.0));
        assert!(!quiet.valid(0.5) && !quiet.valid(-1.0) && !quiet.valid(1e9));
    }
}
