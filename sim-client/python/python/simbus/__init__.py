"""simbus for Python: ticks, frames and sensor captures of a simbus world at
shared-memory speed, frames' actors and captures as numpy arrays over the
shared memory itself.

>>> import simbus
>>> client = simbus.connect("default")            # doctest: +SKIP
>>> with client.ticker(delta_seconds=0.05) as ticker:  # doctest: +SKIP
...     frame_id = ticker.tick()
...     with client.wait_for_frame() as frame:
...         print(frame.frame, frame.actors["position"][:3])
"""

from . import _errors
from ._errors import (
    CommandError,
    Error,
    Full,
    NotTickerError,
    ProtocolMismatch,
    ReleasedError,
    SensorEnded,
    Restarted,
    ServerGone,
    SettingsError,
    TimeoutError,
)
from ._simbus import (
    PROTOCOL_VERSION,
    Client,
    Frame,
    Frames,
    JournalStatus,
    ParticipantStatus,
    Reconnected,
    Settings,
    SnapshotInfo,
    Status,
    Ticker,
    TickerInfo,
    connect,
)
from ._simbus import (  # actors and batches, lockstep, the recorder
    ApplyForce,
    ApplyImpulse,
    ApplyTorque,
    ApplyVehicleAckermannControl,
    ApplyVehicleControl,
    ApplyWalkerControl,
    Command,
    CommandResult,
    DestroyActor,
    FreezeTrafficLights,
    Participant,
    RecorderStatus,
    ReplayStatus,
    ResetTrafficLights,
    SetEnableGravity,
    SetSimulatePhysics,
    SetTargetVelocity,
    SetTrafficLightState,
    SetTrafficLightTimes,
    SetTransform,
    SpawnActor,
)
from ._simbus import Capture, Listening, Sensor, SensorInfo  # sensors
from . import recording

#: Actor kinds, as a frame's ``actors["kind"]`` holds them.
TRAFFIC_LIGHT_KIND = 7
#: What a traffic light shows, by the code in ``flags`` bits 8 to 15.
LIGHT_STATES = ("red", "yellow", "green", "off")
#: A light whose junction is frozen (``flags`` bit 2).
LIGHT_FROZEN = 4


def traffic_lights(frame):
    """The traffic lights of `frame`: ``{actor id: (state, elapsed
    seconds in its phase, frozen)}``, the state one of `LIGHT_STATES`.
    Reads the frame's actors (hold the frame, or a ``copy()``)."""
    actors = frame.actors
    lights = actors[actors["kind"] == TRAFFIC_LIGHT_KIND]
    codes = (lights["flags"] >> 8) & 0xFF
    return {
        int(a["id"]): (LIGHT_STATES[int(c)] if c < len(LIGHT_STATES) else "unknown",
                       int(a["detail"]) / 1000.0, bool(a["flags"] & LIGHT_FROZEN))
        for a, c in zip(lights, codes)
    }


__all__ = [
    "PROTOCOL_VERSION",
    "ApplyForce",
    "ApplyImpulse",
    "ApplyTorque",
    "ApplyVehicleAckermannControl",
    "ApplyVehicleControl",
    "ApplyWalkerControl",
    "Capture",
    "Client",
    "Command",
    "CommandError",
    "CommandResult",
    "DestroyActor",
    "Error",
    "FreezeTrafficLights",
    "LIGHT_STATES",
    "Frame",
    "Frames",
    "Full",
    "JournalStatus",
    "Listening",
    "NotTickerError",
    "Participant",
    "ParticipantStatus",
    "Reconnected",
    "SnapshotInfo",
    "ProtocolMismatch",
    "RecorderStatus",
    "ReleasedError",
    "ReplayStatus",
    "Sensor",
    "SensorEnded",
    "SensorInfo",
    "Restarted",
    "ServerGone",
    "SetEnableGravity",
    "SetSimulatePhysics",
    "SetTargetVelocity",
    "SetTransform",
    "Settings",
    "SettingsError",
    "SpawnActor",
    "Status",
    "Ticker",
    "TickerInfo",
    "TimeoutError",
    "ResetTrafficLights",
    "SetTrafficLightState",
    "SetTrafficLightTimes",
    "connect",
    "recording",
    "traffic_lights",
]
