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
    ApplyVehicleControl,
    ApplyWalkerControl,
    Command,
    CommandResult,
    DestroyActor,
    Participant,
    RecorderStatus,
    ReplayStatus,
    SetEnableGravity,
    SetSimulatePhysics,
    SetTargetVelocity,
    SetTransform,
    SpawnActor,
)
from ._simbus import Capture, Listening, Sensor, SensorInfo  # sensors
from . import recording

__all__ = [
    "PROTOCOL_VERSION",
    "ApplyForce",
    "ApplyImpulse",
    "ApplyTorque",
    "ApplyVehicleControl",
    "ApplyWalkerControl",
    "Capture",
    "Client",
    "Command",
    "CommandError",
    "CommandResult",
    "DestroyActor",
    "Error",
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
    "connect",
    "recording",
]
