//! A lidar's noise, drop-off and intensity, as CARLA's `RayCastLidar.cpp`
//! applies them: a share of the rays dropped at random before they are
//! cast (`dropoff_general_rate`); each return's intensity
//! `exp(-rate × distance)` (or simbus's `1 - distance / range` at rate 0);
//! a normal error of `noise_stddev` along the ray; and a return whose
//! intensity is at most `dropoff_intensity_limit` kept with a chance
//! falling linearly from 1 at the limit to `1 - dropoff_zero_intensity` at
//! 0. The intensity is taken before the error is added, as CARLA does.
//!
//! Every draw is a hash of the seed, the capture and the ray (channel,
//! column), not a generator stepped ray by ray: the channels are cast in
//! parallel, and the same seed gives the same points on any number of
//! render threads.

use shared_types::LidarNoise;

/// What to do with one ray of one capture.
#[derive(Debug, Clone, Copy)]
pub(super) struct Effects {
    noise: LidarNoise,
    range: f32,
    /// The seed and the capture's sequence number, mixed.
    key: u64,
}

/// SplitMix64's finaliser: a well-mixed 64-bit hash of `z`.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Which draw of a ray: each its own stream.
#[derive(Debug, Clone, Copy)]
enum Draw {
    General = 1,
    Kept = 2,
    Noise = 3,
}

impl Effects {
    /// The effects of a lidar of `range` with `noise`, for its capture
    /// number `capture`.
    pub(super) fn new(noise: LidarNoise, range: f32, capture: u64) -> Self {
        Self {
            noise,
            range,
            key: mix(u64::from(noise.seed) ^ mix(capture)),
        }
    }

    /// A uniform number in (0, 1] for `draw` of the ray at (`channel`,
    /// `column`).
    fn uniform(&self, (channel, column): (usize, usize), draw: Draw) -> f32 {
        let ray = ((channel as u64) << 32) ^ column as u64;
        let bits = mix(self.key ^ mix(ray) ^ ((draw as u64) << 56));
        ((bits >> 40) + 1) as f32 / (1u64 << 24) as f32
    }

    /// Whether the ray is dropped before it is cast.
    pub(super) fn drops_ray(&self, ray: (usize, usize)) -> bool {
        self.noise.dropoff_general_rate > 0.0
            && self.uniform(ray, Draw::General) <= self.noise.dropoff_general_rate
    }

    /// A return's intensity at `distance`.
    pub(super) fn intensity(&self, distance: f32) -> f32 {
        match self.noise.atmosphere_attenuation_rate {
            rate if rate > 0.0 => (-rate * distance).exp(),
            _ => 1.0 - distance / self.range,
        }
    }

    /// Whether a return of `intensity` is kept.
    pub(super) fn keeps(&self, ray: (usize, usize), intensity: f32) -> bool {
        let (limit, zero) = (
            self.noise.dropoff_intensity_limit,
            self.noise.dropoff_zero_intensity,
        );
        if zero <= 0.0 || limit <= 0.0 || intensity > limit {
            return true;
        }
        // CARLA: kept when uniform < alpha × intensity + beta.
        let (alpha, beta) = (zero / limit, 1.0 - zero);
        self.uniform(ray, Draw::Kept) < alpha * intensity + beta
    }

    /// The error added along the ray, metres.
    pub(super) fn error(&self, ray: (usize, usize)) -> f32 {
        let deviation = self.noise.noise_stddev;
        if deviation <= 0.0 {
            return 0.0;
        }
        // Box–Muller on two draws of the ray.
        let u1 = self.uniform(ray, Draw::Noise);
        let u2 = self.uniform((ray.0, ray.1 ^ (1 << 31)), Draw::Noise);
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos() * deviation
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn carla_defaults(seed: u32) -> LidarNoise {
        LidarNoise {
            noise_stddev: 0.0,
            dropoff_general_rate: 0.45,
            dropoff_intensity_limit: 0.8,
            dropoff_zero_intensity: 0.4,
            atmosphere_attenuation_rate: 0.004,
            seed,
        }
    }

    fn rays() -> impl Iterator<Item = (usize, usize)> {
        (0..32).flat_map(|c| (0..1000).map(move |p| (c, p)))
    }

    #[test]
    fn the_general_rate_drops_that_share_the_same_way_for_the_same_seed() {
        let drops = |seed, capture| {
            let effects = Effects::new(carla_defaults(seed), 50.0, capture);
            rays().map(|r| effects.drops_ray(r)).collect::<Vec<_>>()
        };
        let a = drops(7, 1);
        let share = a.iter().filter(|&&d| d).count() as f32 / a.len() as f32;
        assert!((share - 0.45).abs() < 0.01, "{share}");
        assert_eq!(a, drops(7, 1));
        assert_ne!(a, drops(8, 1));
        assert_ne!(a, drops(7, 2), "each capture draws anew");
    }

    #[test]
    fn intensity_attenuates_as_carla_or_falls_linearly_without_a_rate() {
        let effects = Effects::new(carla_defaults(0), 50.0, 0);
        assert!((effects.intensity(100.0) - (-0.4f32).exp()).abs() < 1e-6);
        let linear = Effects::new(LidarNoise::default(), 50.0, 0);
        assert_eq!(linear.intensity(25.0), 0.5);
    }

    #[test]
    fn returns_below_the_limit_are_kept_with_carlas_chance() {
        let effects = Effects::new(carla_defaults(3), 50.0, 0);
        // Above the limit: always; at intensity 0: 1 - 0.4; at 0.4:
        // 0.5 × 0.4 + 0.6 = 0.8.
        let kept = |intensity: f32| {
            rays().filter(|&r| effects.keeps(r, intensity)).count() as f32 / 32_000.0
        };
        assert_eq!(kept(0.9), 1.0);
        assert!((kept(0.0) - 0.6).abs() < 0.01, "{}", kept(0.0));
        assert!((kept(0.4) - 0.8).abs() < 0.01, "{}", kept(0.4));
        // No drop-off at zero intensity drops nothing (CARLA's recipe).
        let none = LidarNoise {
            dropoff_zero_intensity: 0.0,
            dropoff_intensity_limit: 1.0,
            ..carla_defaults(3)
        };
        let effects = Effects::new(none, 50.0, 0);
        assert!(rays().all(|r| effects.keeps(r, 0.0)));
    }

    #[test]
    fn the_error_along_the_ray_has_the_deviation() {
        let noisy = LidarNoise {
            noise_stddev: 0.2,
            ..LidarNoise::default()
        };
        let effects = Effects::new(noisy, 50.0, 5);
        let errors: Vec<f32> = rays().map(|r| effects.error(r)).collect();
        let n = errors.len() as f32;
        let mean = errors.iter().sum::<f32>() / n;
        let spread = (errors.iter().map(|e| (e - mean).powi(2)).sum::<f32>() / n).sqrt();
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((spread - 0.2).abs() < 0.01, "{spread}");
        let exact = Effects::new(LidarNoise::default(), 50.0, 5);
        assert!(rays().all(|r| exact.error(r) == 0.0));
    }
}
