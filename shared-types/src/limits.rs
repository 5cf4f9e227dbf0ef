//! Capacity limits of the services of one world, shared by server and
//! clients so both open a service with the same quality of service.
//!
//! The server sizes every service of its world from one [`WorldLimits`]
//! (`sim-server --max-clients N --max-sensor-readers M`); a client past a
//! limit gets an error naming the flag that raises it.

/// The fastest a walker may be told to walk, m/s (CARLA's runners do
/// about 3; a sprinter 10).
pub const MAX_WALKER_SPEED: f32 = 20.0;
/// A walker's radius, metres: at least this...
pub const MIN_WALKER_RADIUS: f32 = 0.05;
/// ...and at most this.
pub const MAX_WALKER_RADIUS: f32 = 2.0;
/// The tallest walker's half height, metres.
pub const MAX_WALKER_HALF_HEIGHT: f32 = 5.0;

/// The longest a traffic light may be told to stay green, yellow or
/// red, seconds (CARLA sets no bound; scripts that hold a light use a
/// few thousand).
pub const MAX_LIGHT_SECONDS: f32 = 1_000_000.0;

/// The fastest an Ackermann target may ask a vehicle to go, m/s.
pub const MAX_ACKERMANN_SPEED: f32 = 100.0;

/// The most clients a world admits by default (`--max-clients`).
pub const DEFAULT_MAX_CLIENTS: usize = 64;
/// The most readers one sensor admits by default (`--max-sensor-readers`).
pub const DEFAULT_MAX_SENSOR_READERS: usize = 16;
/// The largest `--max-clients` a server accepts.
pub const MAX_MAX_CLIENTS: usize = 1024;
/// The largest `--max-sensor-readers` a server accepts.
pub const MAX_MAX_SENSOR_READERS: usize = 256;
/// The flag that raises the number of clients.
pub const MAX_CLIENTS_FLAG: &str = "--max-clients";
/// The flag that raises the number of readers per sensor.
pub const MAX_SENSOR_READERS_FLAG: &str = "--max-sensor-readers";

/// How many clients (and readers per sensor) a world admits, and what
/// that means for each service.
///
/// Every per-client service admits `max_clients` ports of its kind:
/// frame subscribers, control, batch, lockstep and sensor-request
/// clients, wake-up notifiers. A client and each sensor it reads hold a
/// frame-ready listener, so event services admit `2 × max_clients`
/// listeners, and `2 × max_clients + 16` processes' nodes may open a
/// service (a client, its ticker, its participant, its sensors).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WorldLimits {
    /// Clients of each kind (`--max-clients`).
    pub max_clients: usize,
    /// Readers of each sensor (`--max-sensor-readers`).
    pub max_sensor_readers: usize,
}

impl Default for WorldLimits {
    fn default() -> Self {
        Self {
            max_clients: DEFAULT_MAX_CLIENTS,
            max_sensor_readers: DEFAULT_MAX_SENSOR_READERS,
        }
    }
}

impl WorldLimits {
    /// Listeners of each event service.
    pub fn event_listeners(&self) -> usize {
        2 * self.max_clients
    }

    /// Nodes (processes' iceoryx2 nodes) that may open one service.
    pub fn nodes(&self) -> usize {
        2 * self.max_clients + 16
    }

    /// Checks both limits against `1..=MAX_*`.
    ///
    /// # Errors
    ///
    /// Returns [`LimitsError::MaxClients`] if `max_clients` is outside
    /// `1..=`[`MAX_MAX_CLIENTS`], and [`LimitsError::MaxSensorReaders`] if
    /// `max_sensor_readers` is outside `1..=`[`MAX_MAX_SENSOR_READERS`]
    /// (`max_clients` is checked first).
    pub fn validate(&self) -> Result<(), LimitsError> {
        if !(1..=MAX_MAX_CLIENTS).contains(&self.max_clients) {
            return Err(LimitsError::MaxClients(self.max_clients));
        }
        if !(1..=MAX_MAX_SENSOR_READERS).contains(&self.max_sensor_readers) {
            return Err(LimitsError::MaxSensorReaders(self.max_sensor_readers));
        }
        Ok(())
    }
}

/// Why [`WorldLimits::validate`] refused a limit (the value given).
///
/// ```
/// use shared_types::limits::{LimitsError, WorldLimits};
///
/// let limits = WorldLimits { max_clients: 0, ..WorldLimits::default() };
/// assert_eq!(limits.validate(), Err(LimitsError::MaxClients(0)));
/// assert_eq!(
///     limits.validate().unwrap_err().to_string(),
///     "--max-clients must be in 1..=1024, got 0"
/// );
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum LimitsError {
    /// `max_clients` outside `1..=`[`MAX_MAX_CLIENTS`].
    #[error("{MAX_CLIENTS_FLAG} must be in 1..={MAX_MAX_CLIENTS}, got {0}")]
    MaxClients(usize),
    /// `max_sensor_readers` outside `1..=`[`MAX_MAX_SENSOR_READERS`].
    #[error("{MAX_SENSOR_READERS_FLAG} must be in 1..={MAX_MAX_SENSOR_READERS}, got {0}")]
    MaxSensorReaders(usize),
}

/// How many snapshots a subscriber may have queued before the oldest is
/// dropped (async) — a reader that drains this often never loses a frame.
pub const FRAME_SUBSCRIBER_BUFFER: usize = 16;
/// How many snapshots a subscriber may hold at once.
pub const FRAME_SUBSCRIBER_BORROWED: usize = 4;
/// Actor slots reserved in the first frame sample; the publisher grows
/// its memory when the world holds more.
pub const INITIAL_MAX_ACTORS: usize = 64;
/// Commands reserved in the first batch sample; it grows as needed.
pub const INITIAL_MAX_BATCH: usize = 64;
/// Batches one client may have in flight.
pub const MAX_BATCHES_IN_FLIGHT: usize = 4;
/// Captures a sensor subscriber may have queued (a reader that drains
/// this often never loses one).
pub const SENSOR_SUBSCRIBER_BUFFER: usize = 4;
/// The largest size (half extent, radius) of an actor, metres.
pub const MAX_ACTOR_EXTENT: f32 = 1000.0;
/// The farthest an actor may be placed from the origin on any axis, metres.
pub const MAX_ACTOR_POSITION: f32 = 100_000.0;
/// The longest wait any command-line flag accepts, seconds (about 31
/// years: longer than any run, short enough to add to a clock).
pub const MAX_WAIT_SECONDS: f64 = 1e9;
