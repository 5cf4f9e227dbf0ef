//! # simbus wire layer
//!
//! Everything that crosses a process boundary in simbus is defined here and
//! nowhere else: the `#[repr(C)]` zero-copy payloads ([`FrameHeader`],
//! [`ActorState`], [`ControlRequest`], [`ControlResponse`]), the names of the
//! iceoryx2 services of one world ([`ServiceNames`]), the [`PROTOCOL_VERSION`]
//! and the validation of [`WorldSettings`].
//!
//! The crate holds no logic beyond validation and conversion, so a server and
//! a client built from the same version agree on every byte.
//!
//! ```
//! use shared_types::{ServiceNames, WorldName, WorldSettings};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let world = WorldName::new("lab")?;
//! let names = ServiceNames::new(&world);
//! assert_eq!(names.frames, "simbus/lab/frames");
//!
//! let settings = WorldSettings { fixed_delta_seconds: Some(0.05), ..Default::default() };
//! settings.validate()?;
//! // 0.2 s frames need 20 substeps of 0.01 s: more than the 10 allowed.
//! let too_long = WorldSettings { fixed_delta_seconds: Some(0.2), ..Default::default() };
//! assert!(too_long.validate().is_err());
//! # Ok(())
//! # }
//! ```

#![deny(unsafe_code)]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

mod wire;

pub mod limits;

mod command;
mod control;
pub mod debug_shapes;
pub use debug_shapes::{
    DebugRequest, DebugRequestKind, DebugResponseHeader, DebugShape, DebugShapeError, ShapeKind,
};
mod frame;
mod lockstep;
mod names;
mod number;
pub use number::{Exact, Readable};
mod recorder;
pub mod roads;
pub mod scene;
pub use recorder::{
    PathText, RecorderKind, RecorderRefusal, RecorderRequest, RecorderResponse, ReplayMode,
    ReplayState, DEFAULT_KEYFRAME_SECONDS, MAX_KEYFRAME_SECONDS, MIN_KEYFRAME_SECONDS,
};
pub mod camera;
pub mod events;
pub use camera::{Bgra, SemanticTag, Sun};
pub use events::{Collision, CollisionEvent, Obstacle, ObstacleDetection};
pub mod gnss;
pub use gnss::{Gnss, GnssMeasurement};
pub mod ranging;
pub use ranging::{Radar, RadarDetection, SemanticLidarPoint};
mod sensor;
mod sensor_check;
mod sensor_params;
mod sensor_spec;
mod settings;
mod settings_wire;
mod signals;
pub use settings_wire::{WireSettings, WireSettingsError};
pub use signals::{LightReading, LightState, SignKind, SignReading};
mod substep_rule;
pub use substep_rule::{SubstepRule, UnknownSubstepRule};
mod tick;
mod vehicle;
mod wait_mode;
pub use vehicle::{
    full_throttle_acceleration, VehicleSpec, VehicleSpecError, DEFAULT_VEHICLE_HALF_EXTENTS,
    DEFAULT_VEHICLE_MASS, FRICTION_SLIP, FULL_BRAKE_DECELERATION, MAX_VEHICLE_HALF_EXTENT,
    MAX_VEHICLE_MASS, MIN_VEHICLE_HALF_EXTENT, MIN_VEHICLE_MASS, SUSPENSION_DAMPING,
    SUSPENSION_STIFFNESS,
};

pub use command::{
    BatchHeader, BatchResponseHeader, Command, CommandKind, CommandResult, CommandStatus,
};
pub use control::{
    ControlRequest, ControlResponse, ParticipantStatus, RequestKind, SnapshotInfo, SnapshotList,
    StatusReport, MAX_SNAPSHOTS, REPORTED_PARTICIPANTS,
};
pub use frame::{
    fill_frame_slice, frame_parts, frame_slice_len, nanos_to_seconds, ActorKind, ActorPose,
    ActorState, FrameHeader, Timestamp,
};
pub use lockstep::{LockstepKind, LockstepRequest, LockstepResponse, MAX_LOCKSTEP_WINDOW};
pub use names::{Doorbell, ServiceNames, WorldName, WorldNameError};
pub use sensor::{
    ImuMeasurement, LidarPoint, SensorEnd, SensorHeader, SensorInfo, SensorKind, SensorRefusal,
    SensorRequest, SensorRequestKind, SensorResponseHeader, SensorSpec, LEGACY_SENSOR_PARAMS,
    MAX_CAPTURE_BYTES, MAX_IMAGE_SIDE, MAX_LIDAR_CHANNELS, MAX_LIDAR_POINTS,
    MAX_SENSOR_TICK_SECONDS, SENSOR_PARAMS,
};
pub use sensor_check::SensorSpecError;
pub use sensor_params::{Camera, Imu, Lidar, LidarNoise, SensorParams};
pub use settings::{
    seconds_to_nanos, SettingsError, SettingsField, SettingsWarning, WorldSettings, LONG_FRAME_NS,
    LONG_FRAME_SECONDS, LONG_SUBSTEP_NS, LONG_SUBSTEP_SECONDS, MAX_DELTA_SECONDS,
    MAX_SUBSTEPS_LIMIT, MIN_DELTA_SECONDS, NANOS_PER_SECOND,
};
pub use tick::{TickRequest, TickRequestKind, TickResponse, TickerInfo};
pub use wait_mode::WaitMode;
pub use wire::{
    this_process_id, FixedText, Response, ResponseStatus, UnknownWireValue, PROTOCOL_VERSION,
};
