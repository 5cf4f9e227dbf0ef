//! The bounds the values people type are checked against, beyond the
//! wire's own (which [`shared_types`] holds).

/// The highest rate any flag accepts (`--rate`, `--max-fps`, `--max-hz`,
/// `--rotation-frequency`): one per microsecond, the shortest step the
/// clock keeps ([`MIN_DELTA_SECONDS`]).
pub const MAX_RATE_HZ: f64 = 1e6;
/// The longest `--hybrid-window-us`: a server polls at most one second
/// after a frame before it sleeps.
pub const MAX_HYBRID_WINDOW_MICROS: u64 = 1_000_000;
/// The slowest replay time factor.
pub const MIN_TIME_FACTOR: f64 = 1e-3;
/// The fastest replay time factor.
pub const MAX_TIME_FACTOR: f64 = 1e3;
/// The longest sensor range or distance a flag accepts, metres (ten times
/// the world's reach, [`MAX_ACTOR_POSITION`]).
pub const MAX_DISTANCE_METRES: f64 = 1e6;
/// The shortest `top --interval`, seconds.
pub const MIN_REFRESH_SECONDS: f64 = 0.05;
/// The longest `top --interval`, seconds.
pub const MAX_REFRESH_SECONDS: f64 = 3600.0;
/// The most render threads a server starts.
pub const MAX_RENDER_THREADS: usize = 1024;
