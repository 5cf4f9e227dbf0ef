"""Reading a simbus recording without a server (CARLA's
``show_recorder_file_info``).

>>> import simbus
>>> info = simbus.recording.info("run.mcap")      # doctest: +SKIP
>>> info.frames, info.duration_seconds, info.header.scene  # doctest: +SKIP
"""

from ._simbus import RecordedEpisode, RecordingHeader, RecordingInfo
from ._simbus import recording_info as _recording_info


def info(path, show_all=False):
    """What the recording at ``path`` (a str or os.PathLike) holds, as a
    ``RecordingInfo``: frames, first and last frame ids, simulation seconds,
    episodes, commands, actors, captures, collisions, keyframes, bytes, and
    its ``header`` (world, scene, seed, settings, start frame). With
    ``show_all``, ``frame_list`` holds every frame as (frame, episode,
    elapsed_seconds, delta_seconds, substeps, actors). A file that is not a
    readable simbus recording (missing, not MCAP, damaged, another
    program's, cut short) raises ``simbus.Error`` saying why."""
    return _recording_info(path, show_all)


__all__ = ["RecordedEpisode", "RecordingHeader", "RecordingInfo", "info"]
