"""Type stubs of simbus's extension module (re-exported by `simbus`)."""

from types import TracebackType
from os import PathLike
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Type, Union

import numpy as np
import numpy.typing as npt

PROTOCOL_VERSION: int

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]

def connect(world: str = "default", timeout: float = 5.0, wait_mode: str = "hybrid") -> Client:
    """Connects to the server of `world`, waiting up to `timeout` seconds.

    `wait_mode`: "hybrid" (poll 100 µs, then sleep), "block" or "spin".
    Raises simbus.TimeoutError when no server answers, ValueError for a bad
    name, timeout or wait mode."""

class Settings:
    """The world's time-step and synchrony settings (CARLA's names)."""

    @property
    def synchronous_mode(self) -> bool: ...
    @property
    def fixed_delta_seconds(self) -> Optional[float]:
        """Seconds per frame; None: the variable step."""
    @property
    def substepping(self) -> bool: ...
    @property
    def max_substep_delta_time(self) -> float: ...
    @property
    def max_substeps(self) -> int: ...
    @property
    def substep_rule(self) -> str:
        """What a fixed step longer than max_substeps * max_substep_delta_time
        does: "refuse", "clamp" (CARLA's: physics advances only that much) or
        "stretch" (longer substeps)."""
    def __eq__(self, other: object) -> bool: ...

class TickerInfo:
    """Who holds tick ownership."""

    @property
    def pid(self) -> int: ...
    @property
    def node_name(self) -> str: ...
    @property
    def since_frame(self) -> int: ...

class ParticipantStatus:
    """One lockstep participant, as the server reports it."""

    @property
    def name(self) -> str: ...
    @property
    def pid(self) -> int: ...
    @property
    def window(self) -> int: ...
    @property
    def done_frame(self) -> int: ...
    @property
    def lag(self) -> Optional[int]:
        """Frames the world is ahead of its last `done` (None before its
        first report in this episode)."""

class Status:
    """The world's state when the server answered."""

    @property
    def frame(self) -> int: ...
    @property
    def elapsed_ns(self) -> int: ...
    @property
    def elapsed_seconds(self) -> float: ...
    @property
    def episode(self) -> int: ...
    @property
    def server_pid(self) -> int: ...
    @property
    def run_pid(self) -> int:
        """The pid of the server that began this run: `server_pid` unless the server resumed a journal."""
    @property
    def actor_count(self) -> int: ...
    @property
    def settings(self) -> Settings: ...
    @property
    def scene(self) -> str: ...
    @property
    def ticker(self) -> Optional[TickerInfo]: ...
    @property
    def seed(self) -> int: ...
    @property
    def participants(self) -> int: ...
    @property
    def lockstep(self) -> List[ParticipantStatus]:
        """The first eight participants, in joining order."""
    @property
    def journal(self) -> Optional[JournalStatus]:
        """The server's journal (`sim-server --journal DIR`), or None."""
    @property
    def snapshots(self) -> int:
        """Snapshots held in the server's memory."""

class JournalStatus:
    """A server's journal: being written, or stopped (the world runs on)."""

    @property
    def writing(self) -> bool: ...
    @property
    def dir(self) -> Optional[str]:
        """Its directory while it is written."""
    @property
    def reason(self) -> Optional[str]:
        """Why it stopped (a full disk...)."""
    @property
    def durable_frame(self) -> int:
        """The last frame made durable: where a resume would start."""

class Loan:
    """A sample the server lent: the base object of arrays over shared memory."""

class Frame:
    """One frame; its actors and poses view shared memory until it is released."""

    @property
    def frame(self) -> int: ...
    @property
    def elapsed_ns(self) -> int:
        """Simulation time in integer nanoseconds."""
    @property
    def elapsed_seconds(self) -> float: ...
    @property
    def delta_seconds(self) -> float: ...
    @property
    def timestamp(self) -> float:
        """Wall-clock seconds at which the server published the frame."""
    @property
    def episode(self) -> int: ...
    @property
    def missed(self) -> int: ...
    @property
    def physics_clamped(self) -> bool:
        """Physics advanced less than delta_seconds (substep rule "clamp")."""
    @property
    def physics_seconds(self) -> float:
        """Seconds physics advanced: delta_seconds, or less when clamped."""
    @property
    def digest(self) -> int:
        """Equal digests, bit-identical worlds."""
    @property
    def actors(self) -> npt.NDArray[np.void]:
        """Read-only structured array over the frame's shared memory: id,
        kind, flags, position, rotation, linear_velocity, angular_velocity,
        acceleration, extent, detail (a traffic light's milliseconds in its
        phase; `simbus.traffic_lights(frame)` reads the lights). Raises
        simbus.ReleasedError once released."""
    @property
    def poses(self) -> npt.NDArray[np.void]:
        """The actors' poses in the order of ``actors``, packed: a read-only
        structured array over the frame's shared memory (id, kind, flags,
        position, rotation), half the bytes of ``actors``. Raises
        simbus.ReleasedError once released."""
    @property
    def held(self) -> bool: ...
    def copy(self) -> Frame:
        """A frame with its own copy of the actors and poses (no shared memory)."""
    def release(self) -> None:
        """Gives the memory back; BufferError while arrays still view it."""
    def __enter__(self) -> Frame: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class Frames(Iterator[Frame]):
    """`client.frames()`: wait_for_frame(timeout) for ever."""

    def __iter__(self) -> Frames: ...
    def __next__(self) -> Frame: ...

class Ticker:
    """The world's single ticker; the `with` block's end gives the world back."""

    def tick(self, timeout: Optional[float] = None) -> int:
        """Computes the next frame; returns its id once it is published."""
    def tick_and_read(self, client: Client, timeout: Optional[float] = None) -> Frame:
        """Computes the next frame and returns it, read in place from
        `client`'s frames (one wait, on the frame itself)."""
    def follow_restarts(self, timeout: Optional[float] = 30.0) -> None:
        """When the server exits, wait up to `timeout` s for one to come back
        (`sim-server --resume`) and claim it: the tick that noticed raises
        `simbus.Restarted`, the next computes the frame after `resumed_at`."""
    @property
    def last_frame(self) -> Optional[int]: ...
    @property
    def settings(self) -> Settings: ...
    def apply_settings(
        self,
        *,
        synchronous_mode: Optional[bool] = None,
        fixed_delta_seconds: Optional[float] = None,
        substepping: Optional[bool] = None,
        max_substep_delta_time: Optional[float] = None,
        max_substeps: Optional[int] = None,
        substep_rule: Optional[str] = None,
    ) -> int: ...
    def release(self) -> None:
        """Puts the settings back as before the claim and gives the world back."""
    def __enter__(self) -> Ticker: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class Client:
    """A connection to one world, bound to the thread that connected."""

    @property
    def world(self) -> str: ...
    @property
    def server_pid(self) -> int: ...
    @property
    def wait_mode(self) -> str:
        """How this client's (and its ticker's and sensors') waits wait."""
    def status(self) -> Status: ...
    def settings(self) -> Settings: ...
    def apply_settings(
        self,
        *,
        synchronous_mode: Optional[bool] = None,
        fixed_delta_seconds: Optional[float] = None,
        substepping: Optional[bool] = None,
        max_substep_delta_time: Optional[float] = None,
        max_substeps: Optional[int] = None,
        substep_rule: Optional[str] = None,
    ) -> int:
        """Changes the given settings; returns the first frame with them."""
    def reload_world(self, *, reset_settings: bool = False) -> Status: ...
    def load_world(self, scene: str, *, reset_settings: bool = False) -> Status: ...
    def wait_for_frame(self, timeout: float = 5.0) -> Frame: ...
    def frames(self, timeout: float = 5.0) -> Frames: ...
    def ticker(
        self,
        delta_seconds: Optional[float] = None,
        *,
        synchronous_mode: bool = True,
        timeout: float = 5.0,
    ) -> Ticker:
        """Claims tick ownership; with delta_seconds, synchronous mode with that step."""
    def spawn(
        self,
        kind: str,
        *,
        at: Optional[Sequence[float]] = None,
        rotation: Optional[Sequence[float]] = None,
        half_extents: Optional[Sequence[float]] = None,
        radius: Optional[float] = None,
        half_height: Optional[float] = None,
    ) -> int:
        """Spawns a box, sphere, capsule, vehicle or walker; returns its id."""
    def destroy(self, actor_id: int) -> None: ...
    def apply_batch(self, commands: Sequence[Command]) -> None:
        """Sends the commands; applied before the next frame (no answer)."""
    def apply_batch_sync(self, commands: Sequence[Command], tick: bool = False) -> List[CommandResult]:
        """Applies the commands; one result per command (and a frame, with tick)."""
    def draw_point(
        self, location: Sequence[float], size: float = 0.1,
        color: Sequence[int] = (255, 0, 0), life_time: float = -1.0,
    ) -> None:
        """A dot the viewers show for life_time s of simulation time (< 0: one frame; 0: for good)."""
    def draw_line(
        self, begin: Sequence[float], end: Sequence[float], thickness: float = 0.1,
        color: Sequence[int] = (255, 0, 0), life_time: float = -1.0,
    ) -> None:
        """A line the viewers show."""
    def draw_arrow(
        self, begin: Sequence[float], end: Sequence[float], thickness: float = 0.1,
        arrow_size: float = 0.1, color: Sequence[int] = (255, 0, 0), life_time: float = -1.0,
    ) -> None:
        """An arrow the viewers show."""
    def draw_box(
        self, center: Sequence[float], half_extents: Sequence[float],
        rotation: Sequence[float] = (0.0, 0.0, 0.0, 1.0), thickness: float = 0.1,
        color: Sequence[int] = (255, 0, 0), life_time: float = -1.0,
    ) -> None:
        """A box's edges the viewers show."""
    def draw_string(
        self, location: Sequence[float], text: str,
        color: Sequence[int] = (255, 0, 0), life_time: float = -1.0,
    ) -> None:
        """Text (at most 64 bytes) the viewers show."""
    def debug_shapes(self) -> List[Dict[str, Any]]:
        """The debug shapes the current frame shows."""
    def clear_debug_shapes(self) -> None:
        """Forgets every debug shape."""
    def spawn_sensor(
        self,
        kind: str,
        *,
        parent: Optional[int] = None,
        at: Sequence[float] = (0.0, 2.0, 0.0),
        rotation: Optional[Sequence[float]] = None,
        sensor_tick: float = 0.0,
        width: Optional[float] = None,
        height: Optional[float] = None,
        fov: Optional[float] = None,
        range: Optional[float] = None,
        channels: Optional[float] = None,
        points: Optional[float] = None,
        upper_fov: Optional[float] = None,
        lower_fov: Optional[float] = None,
        rotation_frequency: Optional[float] = None,
        noise: Optional[Dict[str, float]] = None,
        hit_radius: Optional[float] = None,
        only_dynamics: Optional[bool] = None,
        vertical_fov: Optional[float] = None,
        points_per_second: Optional[float] = None,
    ) -> Sensor:
        """Spawns a "depth", "rgb", "semantic", "instance", "lidar",
        "semantic_lidar", "radar", "imu", "gnss", "collision" or "obstacle"
        sensor and opens a reader of it. Cameras take width, height, fov and
        range (depth 100 m, the others 1000 m); cameras of one parent, pose,
        size, fov and range share one ray cast. Lidars take channels,
        points, range, upper_fov, lower_fov and rotation_frequency; a lidar's
        `noise`: stddev, dropoff_general_rate, dropoff_intensity_limit,
        dropoff_zero_intensity, atmosphere_attenuation_rate and seed (CARLA's
        attributes without "noise_"; all 0: exact). A radar
        takes fov and vertical_fov (30 degrees each), range (100 m),
        points_per_second (1500) and noise={"seed": N}. An obstacle detector
        takes range (5 m), hit_radius (0.5 m) and only_dynamics. A GNSS
        receiver's `noise`: CARLA's noise attributes without their "noise_"
        prefix (lat_bias, lat_stddev, lon_bias, lon_stddev, alt_bias,
        alt_stddev, seed), each 0 unless given."""
    def sensor(self, id: int) -> Sensor:
        """Opens a reader of an existing sensor."""
    def list_sensors(self) -> List[SensorInfo]: ...
    def destroy_sensor(self, id: int) -> None: ...
    def participant(self, name: str, *, window: int = 0) -> Participant:
        """Joins the lockstep: in synchronous mode no frame is computed
        before this participant says it is done with the previous one (with
        `window=W`, with the frame W before: it may fall W frames behind
        without holding the ticker; at most 1000)."""
    def start_recorder(self, path: Union[str, PathLike], *, sensors: bool = False) -> str:
        """Starts recording to an MCAP file; returns its absolute path."""
    def stop_recorder(self) -> RecorderStatus: ...
    def recorder_status(self) -> RecorderStatus: ...
    def replay(
        self,
        path: Union[str, PathLike],
        *,
        mode: Optional[str] = None,
        start: float = 0.0,
        duration: float = 0.0,
        follow_id: int = 0,
        replay_sensors: bool = False,
        time_factor: float = 1.0,
        keep_actors: bool = False,
    ) -> RecorderStatus:
        """Replays a recording: mode "exact", "interpolate" or "resimulate"
        (None: exact for a fixed step, interpolate otherwise)."""
    def set_replayer_time_factor(self, factor: float) -> RecorderStatus: ...
    def stop_replayer(self, keep_actors: bool = False) -> RecorderStatus: ...
    def reconnect(self, timeout: float = 30.0) -> Reconnected:
        """Talks to the server that came back on this world after its
        predecessor exited; raises `simbus.ServerGone` if none did in time."""
    def next_event(self, timeout: float = 5.0) -> Union[Frame, Reconnected]:
        """The next frame, or a `Reconnected` when the server restarted."""
    def save_snapshot(self) -> int:
        """Saves the whole world in the server's memory; returns its id."""
    def restore_snapshot(self, id: int) -> int:
        """Restores a snapshot as a new episode; returns the frame published."""
    def drop_snapshot(self, id: int) -> None: ...
    def snapshots(self) -> List[SnapshotInfo]: ...
    def __enter__(self) -> Client: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class Command:
    """A command for apply_batch / apply_batch_sync (one of the classes below)."""

    @property
    def actor_id(self) -> Optional[int]: ...

class SpawnActor(Command):
    def __init__(
        self,
        kind: str,
        at: Optional[Sequence[float]] = None,
        *,
        rotation: Optional[Sequence[float]] = None,
        half_extents: Optional[Sequence[float]] = None,
        radius: Optional[float] = None,
        half_height: Optional[float] = None,
    ) -> None: ...
    @property
    def kind(self) -> str: ...
    @property
    def at(self) -> Vec3: ...
    @property
    def rotation(self) -> Quat: ...

class DestroyActor(Command):
    def __init__(self, actor_id: int) -> None: ...

class SetTransform(Command):
    def __init__(self, actor_id: int, position: Sequence[float], rotation: Optional[Sequence[float]] = None) -> None: ...
    @property
    def position(self) -> Vec3: ...
    @property
    def rotation(self) -> Quat: ...

class SetTargetVelocity(Command):
    def __init__(self, actor_id: int, velocity: Sequence[float], angular_velocity: Optional[Sequence[float]] = None) -> None: ...
    @property
    def velocity(self) -> Vec3: ...
    @property
    def angular_velocity(self) -> Vec3: ...

class ApplyForce(Command):
    def __init__(self, actor_id: int, force: Sequence[float]) -> None: ...
    @property
    def force(self) -> Vec3: ...

class ApplyImpulse(Command):
    def __init__(self, actor_id: int, impulse: Sequence[float]) -> None: ...
    @property
    def impulse(self) -> Vec3: ...

class ApplyTorque(Command):
    def __init__(self, actor_id: int, torque: Sequence[float]) -> None: ...
    @property
    def torque(self) -> Vec3: ...

class SetSimulatePhysics(Command):
    def __init__(self, actor_id: int, enabled: bool = True) -> None: ...
    @property
    def enabled(self) -> bool: ...

class SetEnableGravity(Command):
    def __init__(self, actor_id: int, enabled: bool = True) -> None: ...
    @property
    def enabled(self) -> bool: ...

class ApplyVehicleControl(Command):
    def __init__(
        self,
        actor_id: int,
        throttle: float = 0.0,
        steer: float = 0.0,
        brake: float = 0.0,
        hand_brake: bool = False,
        reverse: bool = False,
    ) -> None: ...
    @property
    def throttle(self) -> float: ...
    @property
    def steer(self) -> float: ...
    @property
    def brake(self) -> float: ...
    @property
    def hand_brake(self) -> bool: ...
    @property
    def reverse(self) -> bool: ...

class ApplyVehicleAckermannControl(Command):
    """Drives a vehicle to a steering angle (rad, positive left) and a speed
    (m/s, negative backwards)."""

    def __init__(
        self,
        actor_id: int,
        steer: float = 0.0,
        steer_speed: float = 0.0,
        speed: float = 0.0,
        acceleration: float = 0.0,
    ) -> None: ...

class ApplyWalkerControl(Command):
    def __init__(
        self, actor_id: int, direction: Sequence[float] | None = None, speed: float = 0.0, jump: bool = False
    ) -> None: ...
    @property
    def direction(self) -> tuple[float, float, float]: ...
    @property
    def speed(self) -> float: ...
    @property
    def jump(self) -> bool: ...

class SetTrafficLightState(Command):
    """Shows `state` ("red", "yellow", "green", "off") on a traffic light
    until its junction's cycle next changes that light."""

    def __init__(self, actor_id: int, state: str) -> None: ...

class SetTrafficLightTimes(Command):
    """Sets a light's green, yellow and red seconds (None: unchanged)."""

    def __init__(
        self, actor_id: int, *, green: float | None = None, yellow: float | None = None, red: float | None = None
    ) -> None: ...

class FreezeTrafficLights(Command):
    """Freezes or unfreezes a light's junction (actor_id None: every one)."""

    def __init__(self, frozen: bool, actor_id: int | None = None) -> None: ...

class ResetTrafficLights(Command):
    """Starts a light's junction's cycle again (actor_id None: every one)."""

    def __init__(self, actor_id: int | None = None) -> None: ...

class CommandResult:
    """How one command of apply_batch_sync ended."""

    @property
    def status(self) -> str:
        """"ok", "unknown_actor", "invalid_argument", ..."""
    @property
    def ok(self) -> bool: ...
    @property
    def actor_id(self) -> Optional[int]: ...
    @property
    def error(self) -> Optional[str]: ...
    @property
    def frame(self) -> int: ...

class SensorInfo:
    """A sensor as the server describes it."""

    @property
    def id(self) -> int: ...
    @property
    def kind(self) -> str: ...
    @property
    def parent(self) -> Optional[int]: ...
    @property
    def position(self) -> Vec3: ...
    @property
    def rotation(self) -> Quat: ...
    @property
    def sensor_tick(self) -> float: ...
    @property
    def captures(self) -> int: ...
    @property
    def width(self) -> Optional[int]: ...
    @property
    def height(self) -> Optional[int]: ...
    @property
    def fov(self) -> Optional[float]: ...
    @property
    def range(self) -> Optional[float]: ...
    @property
    def channels(self) -> Optional[int]: ...
    @property
    def points(self) -> Optional[int]: ...
    @property
    def upper_fov(self) -> Optional[float]: ...
    @property
    def lower_fov(self) -> Optional[float]: ...
    @property
    def rotation_frequency(self) -> Optional[float]: ...

class Capture:
    """One capture; its array views shared memory until it is released."""

    @property
    def frame(self) -> int: ...
    @property
    def elapsed_ns(self) -> int: ...
    @property
    def elapsed_seconds(self) -> float: ...
    @property
    def episode(self) -> int: ...
    @property
    def sequence(self) -> int: ...
    @property
    def sensor_id(self) -> int: ...
    @property
    def kind(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def count(self) -> int: ...
    @property
    def position(self) -> Vec3: ...
    @property
    def rotation(self) -> Quat: ...
    @property
    def timestamp(self) -> float:
        """Wall-clock seconds at which the server sent the capture."""
    @property
    def held(self) -> bool: ...
    @property
    def array(self) -> npt.NDArray[np.generic]:
        """Read-only, over shared memory: depth float32 (H, W); rgb, semantic
        and instance uint8 (H, W, 4) blue, green, red, alpha (semantic: CARLA's
        tag in red; instance: the tag in red, the actor id in green and
        blue); lidar float32
        (N, 4), IMU one record (accelerometer, gyroscope), GNSS one record
        (latitude, longitude, altitude; float64)."""
    def copy(self) -> Capture: ...
    def release(self) -> None: ...
    def __enter__(self) -> Capture: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class Listening:
    """A sensor's captures handed to a callback on a thread of its own."""

    @property
    def running(self) -> bool: ...
    @property
    def captures(self) -> int: ...
    @property
    def errors(self) -> int: ...
    @property
    def ended(self) -> Optional[str]: ...
    def stop(self) -> None: ...
    def wait(self, timeout: Optional[float] = None) -> bool: ...
    def __enter__(self) -> Listening: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class Sensor:
    """A reader of one sensor, bound to the thread that opened it."""

    @property
    def id(self) -> int: ...
    @property
    def kind(self) -> str: ...
    @property
    def missed(self) -> int: ...
    @property
    def closed(self) -> bool: ...
    def read(self, timeout: float = 5.0) -> Capture:
        """The next capture (TimeoutError; SensorEnded once the sensor is gone)."""
    def try_read(self) -> Optional[Capture]: ...
    def listen(self, callback: Callable[[Capture], object], *, timeout: float = 5.0) -> Listening: ...
    def destroy(self) -> None: ...
    def close(self) -> None: ...
    def __enter__(self) -> Sensor: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class Participant:
    """A lockstep participant: `with client.participant(name) as p: p.done(frame)`."""

    @property
    def name(self) -> str: ...
    @property
    def joined_at(self) -> Tuple[int, int]: ...
    @property
    def active(self) -> bool: ...
    def done(self, frame: Union[int, Frame], *, episode: Optional[int] = None) -> None: ...
    def check(self) -> None: ...
    def leave(self) -> None: ...
    def __enter__(self) -> Participant: ...
    def __exit__(
        self,
        kind: Optional[Type[BaseException]],
        value: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> None: ...

class ReplayStatus:
    @property
    def state(self) -> str: ...
    @property
    def mode(self) -> str: ...
    @property
    def frames(self) -> int: ...
    @property
    def total(self) -> int: ...
    @property
    def verified(self) -> int: ...
    @property
    def mismatch(self) -> Optional[str]: ...
    @property
    def time_factor(self) -> float: ...

class RecorderStatus:
    @property
    def recording(self) -> bool: ...
    @property
    def recorded(self) -> bool:
        """The server recorded since it started (else `path` is the last replay's file)."""
    @property
    def path(self) -> Optional[str]: ...
    @property
    def frames(self) -> int: ...
    @property
    def bytes(self) -> int: ...
    @property
    def replay(self) -> ReplayStatus: ...
    @property
    def message(self) -> str: ...

class RecordedEpisode:
    @property
    def episode(self) -> int: ...
    @property
    def first_frame(self) -> int: ...
    @property
    def last_frame(self) -> int: ...
    @property
    def frames(self) -> int: ...

class RecordingHeader:
    @property
    def world(self) -> str: ...
    @property
    def scene(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def settings(self) -> Settings: ...
    @property
    def episode(self) -> int: ...
    @property
    def start_frame(self) -> int: ...
    @property
    def start_elapsed_ns(self) -> int: ...
    @property
    def start_platform_timestamp(self) -> float: ...
    @property
    def keyframe_seconds(self) -> float: ...
    @property
    def sensors(self) -> bool: ...
    @property
    def protocol_version(self) -> int: ...
    @property
    def recording_version(self) -> int: ...
    @property
    def simbus_version(self) -> str: ...

class RecordingInfo:
    """What a recording holds (simbus.recording.info)."""

    @property
    def path(self) -> str: ...
    @property
    def header(self) -> RecordingHeader: ...
    @property
    def frames(self) -> int: ...
    @property
    def first_frame(self) -> int: ...
    @property
    def last_frame(self) -> int: ...
    @property
    def duration_seconds(self) -> float: ...
    @property
    def episodes(self) -> int: ...
    @property
    def episode_list(self) -> List[RecordedEpisode]: ...
    @property
    def frame_list(self) -> List[Tuple[int, int, float, float, int, int]]: ...
    @property
    def commands(self) -> int: ...
    @property
    def actors_spawned(self) -> int: ...
    @property
    def actors_destroyed(self) -> int: ...
    @property
    def max_actors(self) -> int: ...
    @property
    def settings_changes(self) -> int: ...
    @property
    def sensors(self) -> int: ...
    @property
    def captures(self) -> int: ...
    @property
    def collisions(self) -> int: ...
    @property
    def keyframes(self) -> int: ...
    @property
    def bytes(self) -> int: ...
    @property
    def raw_bytes(self) -> int: ...
    @property
    def compression_ratio(self) -> float: ...
    @property
    def stopped(self) -> Optional[str]: ...
    @property
    def truncated(self) -> bool: ...

def recording_info(path: Union[str, PathLike], show_all: bool = False) -> RecordingInfo:
    """What a recording holds, without a server (simbus.recording.info)."""


class Reconnected:
    """The server exited and another came back on the world."""

    @property
    def resumed_at(self) -> int: ...
    @property
    def episode(self) -> int: ...
    @property
    def server_pid(self) -> int: ...
    @property
    def previous_pid(self) -> int: ...

class SnapshotInfo:
    """A snapshot the server holds."""

    @property
    def id(self) -> int: ...
    @property
    def frame(self) -> int: ...
    @property
    def source_frame(self) -> int: ...
    @property
    def episode(self) -> int: ...
    @property
    def elapsed_seconds(self) -> float: ...
    @property
    def actors(self) -> int: ...
    @property
    def sensors(self) -> int: ...


# simbus.gym's hot path (used by simbus.gym; documented there).
DRIVING_REWARD_TERMS: Sequence[str]
DRIVING_EGO_VALUES: int
DRIVING_ACTOR_VALUES: int

class DrivingWorld:
    """One world of simbus.gym's driving task, stepped from Rust: each ego's
    observation written into a row of the caller's float32 arrays."""

    def __init__(
        self, world: str, *, scene: str = "town", egos: int = 1, vehicles: int = 0, walkers: int = 0,
        cross_factor: float = 0.5,
        delta_seconds: float = 0.1, max_substep_delta_time: float = 0.02, actors: int = 6,
        route_points: int = 10, route_length: float = 300.0,
        weights: Sequence[float] = (1.0, 10.0, 0.1, 5.0, 5.0), end_on_collision: bool = True,
        max_episode_steps: int = 1000, camera: Optional[Tuple[int, int]] = None,
        lidar: Optional[Tuple[int, int]] = None, discrete: bool = False, timeout: float = 10.0,
    ) -> None: ...
    @property
    def row(self) -> int: ...
    @property
    def world(self) -> str: ...
    @property
    def server_pid(self) -> int: ...
    @property
    def frame(self) -> int: ...
    @property
    def egos(self) -> List[int]: ...
    @property
    def traffic(self) -> Tuple[List[int], List[int]]: ...
    @property
    def episode_steps(self) -> int: ...
    @property
    def crossings(self) -> int: ...
    @property
    def elapsed_seconds(self) -> float: ...
    def reset(self, seed: int, obs: npt.NDArray[np.float32],
              camera: Optional[npt.NDArray[np.uint8]] = None,
              lidar: Optional[npt.NDArray[np.float32]] = None) -> int: ...
    def send(self, actions: npt.NDArray[np.float32]) -> None: ...
    def ready(self) -> bool: ...
    def finish(self, obs: npt.NDArray[np.float32], reward: npt.NDArray[np.float32],
               terminated: npt.NDArray[np.bool_], truncated: npt.NDArray[np.bool_],
               terms: npt.NDArray[np.float32], camera: Optional[npt.NDArray[np.uint8]] = None,
               lidar: Optional[npt.NDArray[np.float32]] = None) -> int: ...
    def close(self) -> None: ...
