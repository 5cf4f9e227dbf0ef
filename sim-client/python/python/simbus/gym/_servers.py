"""The sim-server processes `simbus.gym` starts for its worlds, and reaps."""

from __future__ import annotations

import itertools
import os
import shutil
import signal
import subprocess
import tempfile
import uuid
from typing import Optional, Sequence

_counter = itertools.count()

#: Linux's prctl option that signals a child when its parent dies.
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """In the child, before exec: SIGKILL when the process that started it
    dies, so a killed trainer leaves no server behind."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def unique_world(prefix: str = "gym") -> str:
    """A world name no other process on this machine uses."""
    return f"{prefix}-{os.getpid()}-{next(_counter)}-{uuid.uuid4().hex[:6]}"


def find_server(binary: Optional[str] = None) -> str:
    """The sim-server binary: `binary`, else $SIMBUS_SERVER, else
    $SIMBUS_BIN_DIR/sim-server, else the one on PATH."""
    candidates = [binary, os.environ.get("SIMBUS_SERVER")]
    bin_dir = os.environ.get("SIMBUS_BIN_DIR")
    if bin_dir:
        candidates.append(os.path.join(bin_dir, "sim-server"))
    candidates.append(shutil.which("sim-server"))
    for path in candidates:
        if path and os.path.isfile(path) and os.access(path, os.X_OK):
            return path
    raise FileNotFoundError(
        "no sim-server binary: pass server_binary=..., set SIMBUS_SERVER or "
        "SIMBUS_BIN_DIR, or put sim-server on PATH (cargo install --path sim-server)"
    )


class ServerProcess:
    """One `sim-server` of one world, started here and killed and reaped by
    `close()` (or when the interpreter exits)."""

    def __init__(self, world: str, *, scene: str = "town", binary: Optional[str] = None,
                 args: Sequence[str] = ()):
        self.world = world
        self.scene = scene
        self.binary = find_server(binary)
        self.args = list(args)
        self.process: Optional[subprocess.Popen] = None
        self._log = tempfile.TemporaryFile(prefix="simbus-gym-server-")
        self.start()

    def start(self) -> None:
        """Starts the server (after killing a previous one)."""
        self.kill()
        self.process = subprocess.Popen(
            [self.binary, "--world", self.world, "--scene", self.scene, *self.args],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self._log,
            preexec_fn=_die_with_parent,
        )

    @property
    def pid(self) -> Optional[int]:
        return self.process.pid if self.process else None

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def log_tail(self, lines: int = 5) -> str:
        """The last lines the server wrote (for error messages)."""
        self._log.seek(0)
        return "\n".join(self._log.read().decode(errors="replace").splitlines()[-lines:])

    def kill(self, sig: int = signal.SIGKILL) -> None:
        """Kills the server and reaps it."""
        if self.process is None:
            return
        if self.process.poll() is None:
            self.process.send_signal(sig)
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.process = None

    def close(self) -> None:
        """Stops the server (SIGTERM, then SIGKILL) and reaps it."""
        self.kill(signal.SIGTERM)
        self._log.close()

    def __del__(self):
        try:
            self.kill()
        except Exception:
            pass
