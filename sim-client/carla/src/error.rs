//! The gateway's errors: why it could not serve ([`GatewayError`], public),
//! and why one CARLA call failed ([`CallError`]: its message is what the
//! script's `RuntimeError` carries) or a blueprint was refused
//! ([`BlueprintError`]).

use std::error::Error;
use std::sync::Arc;
use std::time::Duration;

use shared_types::{CommandStatus, SensorSpecError};

/// Why the gateway could not serve.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GatewayError {
    /// `port + 1`, the default streaming port, is past 65535: refused input.
    #[error(
        "--port {port} leaves no port for the streams (--port + 1 is past 65535): \
         give --streaming-port PORT, or --port 0 for two free ports"
    )]
    NoStreamingPort {
        /// The RPC port asked for.
        port: u16,
    },
    /// `port + 1`, the default streaming port, is privileged (below 1024)
    /// and nobody asked for it: refused input.
    #[error(
        "--port {port} would put the streams on port {next} (--port + 1), a privileged port \
         (below 1024): give --streaming-port {next} to mean it, or another --port"
    )]
    PrivilegedStreamingPort {
        /// The RPC port asked for.
        port: u16,
        /// The streaming port it implies.
        next: u16,
    },
    /// A listener could not be bound.
    #[error("listening for CARLA {what} on {host}:{port}")]
    Listen {
        /// `clients` (the RPC port) or `streams`.
        what: &'static str,
        /// The address asked for.
        host: String,
        /// The port asked for.
        port: u16,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A bound listener has no address to report.
    #[error("the {what} listener's address")]
    Address {
        /// `RPC` or `streaming`.
        what: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The RPC listener and the stop could not be waited on.
    #[error("waiting for CARLA clients")]
    Wait(#[source] std::io::Error),
}

impl GatewayError {
    /// Whether the input was refused (nothing was started), as opposed to
    /// a failure of the network.
    pub fn is_refused(&self) -> bool {
        matches!(
            self,
            Self::NoStreamingPort { .. } | Self::PrivilegedStreamingPort { .. }
        )
    }
}

/// A lower-level error, shared between the results of one batch.
pub(crate) type Source = Arc<dyn Error + Send + Sync>;

/// Why a CARLA call, or one command of a batch, failed. Its message is
/// what the script's `RuntimeError` carries.
#[derive(Debug, Clone, thiserror::Error)]
pub(crate) enum CallError {
    /// simbus failed or refused the request.
    #[error("simbus: {0}")]
    Simbus(#[source] Source),
    /// A recording could not be read (`show_recorder_*`).
    #[error("{0}")]
    Recording(#[source] Source),
    /// Argument `index` of `method` is not of the type it takes.
    #[error("{method}: argument {index} is not {expected}")]
    Argument {
        method: &'static str,
        index: usize,
        /// `a number`, `an integer`, `a string`.
        expected: &'static str,
    },
    /// `method` (a call, or a batch command's name) got arguments of the
    /// wrong shape; `what` says which.
    #[error("{method}: {what}")]
    Shape {
        method: &'static str,
        what: &'static str,
    },
    /// A batch command that is not `[[variant, body]]`.
    #[error("a batch command of the wrong shape")]
    BatchShape,
    /// `get_sensor_token` for a stream id past 32 bits.
    #[error("get_sensor_token: no stream {0}")]
    NoStream(u64),
    /// A blueprint refused in a batch's `SpawnActor`.
    #[error(transparent)]
    Blueprint(#[from] BlueprintError),
    /// A blueprint refused in a spawn call.
    #[error("simbus: {0}")]
    Spawn(#[source] BlueprintError),
    /// A description refused by `spawn_actor`/`spawn_actor_with_parent`.
    #[error("simbus: {method}: {source}")]
    Description {
        method: &'static str,
        #[source]
        source: BlueprintError,
    },
    /// The ticker's server exited and a server that did not resume its
    /// run came back (a fresh start, not `--resume`): a new episode, which
    /// this connection's ticker gave back.
    #[error(
        "simbus: the server restarted (pid {previous} -> {server}) without resuming the world \
         from its journal: a new episode, not the one this client ticked; the world was given \
         back (connect again, or resume the server with --resume)"
    )]
    NewRun { previous: u32, server: u32 },
    /// A CARLA call simbus does not serve.
    #[error(
        "simbus: CARLA's `{0}` is not supported by simbus (its CARLA gateway serves the world, \
         its settings and ticks, actors, batches, sensors and the recorder)"
    )]
    UnsupportedCall(String),
    /// A batch command simbus does not serve.
    #[error("simbus: CARLA's command {0} is not supported by simbus")]
    UnsupportedCommand(&'static str),
    /// A spawn inside `.then(...)`.
    #[error("simbus: SpawnActor inside .then() is not supported by simbus")]
    SpawnInThen,
    /// A body blueprint spawned with a parent.
    #[error(
        "simbus: {blueprint} cannot be attached to actor {parent}: simbus attaches only sensors"
    )]
    OnlySensorsAttach { blueprint: String, parent: u32 },
    /// A `controller.ai.walker` spawned on no actor (CARLA: "not attached
    /// to walker" at its `start()`; simbus says so at the spawn).
    #[error("simbus: controller.ai.walker must be spawned attached to its walker")]
    ControllerWithoutWalker,
    /// A `controller.ai.walker` on an actor that is not a walker.
    #[error("simbus: controller.ai.walker must be attached to a walker; actor {0} is not one")]
    ControllerNotOnAWalker(u32),
    /// A sensor spawned on a sensor.
    #[error("simbus: a sensor cannot ride on sensor {0}: attach it to an actor")]
    SensorOnSensor(u32),
    /// A simbus sensor id past CARLA's actor ids.
    #[error("simbus: sensor id {0} is out of CARLA's range")]
    SensorIdRange(u64),
    /// A simbus actor id past CARLA's actor ids.
    #[error("simbus: actor id {0} is out of CARLA's range")]
    ActorIdRange(u64),
    /// An actor spawned but missing at once.
    #[error("simbus: actor {0} vanished at once")]
    Vanished(u32),
    /// A sensor's call on an actor that is not a sensor.
    #[error("simbus: actor {0} is not a sensor")]
    NotASensor(u32),
    /// A body's command on a sensor.
    #[error("simbus: actor {0} is a sensor: simbus sensors stay where they were spawned")]
    IsASensor(u32),
    /// A command on the spectator other than moving it.
    #[error("simbus: the spectator has no body: only set_transform and set_location move it")]
    SpectatorHasNoBody,
    /// A vehicle's call on an actor that is not a vehicle.
    #[error("simbus: actor {0} is not a vehicle")]
    NotAVehicle(u32),
    /// A walker's call on an actor that is not a walker.
    #[error("simbus: actor {0} is not a walker")]
    NotAWalker(u32),
    /// A traffic light's call on an actor that is not one.
    #[error("simbus: actor {0} is not a traffic light")]
    NotATrafficLight(u32),
    /// `apply_physics_control`.
    #[error(
        "simbus: apply_physics_control is not supported: a simbus vehicle is built from its \
         blueprint's size and mass (get_physics_control says how)"
    )]
    PhysicsControl,
    /// A command that needs the actor's last state, for an actor not seen.
    #[error("simbus: unknown actor {0}")]
    UnknownActor(u32),
    /// A spawn where another body is, in CARLA's words (scripts such as
    /// `generate_traffic.py` skip an occupied spawn point by this error,
    /// and `try_spawn_actor` answers `None`).
    #[error("Spawn failed because of collision at spawn position")]
    SpawnCollision,
    /// The server refused a spawn.
    #[error("simbus: spawn refused: {0}")]
    SpawnRefused(CommandStatus),
    /// The server refused a command on an actor.
    #[error("simbus: actor {actor}: {status}")]
    CommandRefused { actor: u64, status: CommandStatus },
    /// The server refused to move the sun to a weather's.
    #[error("simbus: the weather's sun refused: {0}")]
    SunRefused(CommandStatus),
    /// A batch answered fewer results than it had commands.
    #[error("simbus: no answer")]
    NoAnswer,
    /// No simbus connection.
    #[error("simbus: no connection")]
    NoConnection,
    /// A sensor token for a stream no sensor has.
    #[error("simbus: no sensor has stream {0}")]
    NoSensorStream(u32),
    /// A sensor's forwarder did not open it in time.
    #[error("simbus: sensor {id} did not open within {timeout:?}")]
    SensorTimeout { id: u64, timeout: Duration },
    /// A sensor's forwarder could not open it.
    #[error("simbus: sensor {id}: {source}")]
    SensorOpen {
        id: u64,
        #[source]
        source: Source,
    },
}

impl CallError {
    /// simbus's error `e`, as the call's.
    pub(crate) fn simbus(e: impl Error + Send + Sync + 'static) -> Self {
        Self::Simbus(Arc::new(e))
    }

    /// A recording's error `e`, as the call's.
    pub(crate) fn recording(e: impl Error + Send + Sync + 'static) -> Self {
        Self::Recording(Arc::new(e))
    }
}

/// Why a CARLA actor description cannot spawn in simbus.
#[derive(Debug, Clone, thiserror::Error)]
pub(crate) enum BlueprintError {
    #[error("the actor description is not an array")]
    NotArray,
    #[error("the actor description has no blueprint id")]
    NoId,
    /// Not in the library (listed, comma-separated, in `known`).
    #[error("blueprint '{id}' is not in simbus's library ({known})")]
    Unknown { id: String, known: String },
    #[error("{blueprint}: attribute {name} = '{text}' is not a number")]
    NotANumber {
        blueprint: String,
        name: String,
        text: String,
    },
    /// A noise or drop-off attribute set: simbus's sensors are exact.
    #[error("{blueprint}: {name} must be 0: simbus's sensors are exact (no noise, no drop-off)")]
    NotZero { blueprint: String, name: String },
    #[error("{0}: horizontal_fov must be 360: simbus's lidar scans all around")]
    HorizontalFov(String),
    #[error("{0}: channels must be at least 1 and rotation_frequency above 0")]
    LidarRates(String),
    /// The sensor the attributes make breaks one of simbus's limits.
    #[error("{blueprint}: {source}")]
    Sensor {
        blueprint: String,
        #[source]
        source: SensorSpecError,
    },
}
