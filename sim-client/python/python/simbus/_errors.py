"""simbus's exceptions: one base, ``simbus.Error``, and a subclass for each
failure a caller handles differently. Waits that time out raise
``simbus.TimeoutError``, which is also Python's ``TimeoutError``; settings
refused as invalid raise ``simbus.SettingsError``, also a ``ValueError``."""

import builtins


class Error(Exception):
    """Every error simbus raises (the Rust client's message as text)."""


class TimeoutError(Error, builtins.TimeoutError):
    """A wait (connect, tick, frame, capture, answer) ran past its timeout."""


class ServerGone(Error):
    """The world's server process has exited."""


class Restarted(Error):
    """The server exited and another came back on the world (``sim-server
    --resume``); the ticker that raised it claimed the resumed world. The
    world resumed at frame ``resumed_at`` of ``episode``: the next tick
    computes the frame after it."""

    def __init__(self, message, resumed_at=0, episode=0, server_pid=0, previous_pid=0):
        super().__init__(message)
        self.resumed_at = resumed_at
        self.episode = episode
        self.server_pid = server_pid
        self.previous_pid = previous_pid


class ProtocolMismatch(Error):
    """The server speaks another protocol version than this package."""


class NotTickerError(Error):
    """Another client holds the world's tick ownership (its message names
    the owner), or this ticker lost it."""


class SettingsError(Error, ValueError):
    """The settings were refused (invalid, or the world's state does not
    allow them); nothing changed."""


class SensorEnded(Error):
    """The sensor's stream ended; ``reason`` says why (``"destroyed"``,
    ``"parent destroyed"``, ``"episode ended"``, ``"server stopped"``)."""

    def __init__(self, message, reason=None):
        super().__init__(message)
        self.reason = reason


class ReleasedError(Error):
    """A frame or capture was used after it was released (its shared
    memory went back to the server)."""


class CommandError(Error):
    """A command of a batch, or a spawn, was refused (unknown actor,
    invalid value)."""


class Full(Error):
    """The world admits no more clients, readers or frames held of this
    kind; close one, or start the server with a larger limit."""
