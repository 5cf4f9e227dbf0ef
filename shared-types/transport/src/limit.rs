//! A service's limits, resolved against the server's [`WorldLimits`].

use shared_types::limits::WorldLimits;

/// A limit of a service, resolved against the server's [`WorldLimits`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    /// `--max-clients`.
    Clients,
    /// Listeners of an event: [`WorldLimits::event_listeners`].
    EventListeners,
    /// Nodes that may open a world service: [`WorldLimits::nodes`].
    Nodes,
    /// `--max-sensor-readers`.
    SensorReaders,
    /// Nodes that may open a sensor's service: its readers and 16 more.
    SensorNodes,
    /// This many, whatever the flags.
    Fixed(usize),
}

impl Limit {
    /// The number this limit stands for under `limits`.
    pub fn of(self, limits: &WorldLimits) -> usize {
        match self {
            Self::Clients => limits.max_clients,
            Self::EventListeners => limits.event_listeners(),
            Self::Nodes => limits.nodes(),
            Self::SensorReaders => limits.max_sensor_readers,
            Self::SensorNodes => limits.max_sensor_readers + 16,
            Self::Fixed(n) => n,
        }
    }
}
