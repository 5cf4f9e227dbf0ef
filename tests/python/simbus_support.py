"""What the `simbus` package's tests share: a sim-server on a world of its
own (its log kept, to wait for a line), the `server` fixture that starts
them and kills and reaps every one, and `frame_at`."""

import itertools
import os
import subprocess
import threading

import pytest

import simbus

BIN = os.environ["SIMBUS_BIN_DIR"]
_counter = itertools.count()


def unique_world(tag):
    return f"py-{tag}-{os.getpid()}-{next(_counter)}"


class SimbusServer:
    """A sim-server on a world of its own whose log lines are kept (to wait
    for one); killed and reaped by `stop`."""

    def __init__(self, *args, tag="server", world=None):
        self.world = world or unique_world(tag)
        self.proc = subprocess.Popen(
            [os.path.join(BIN, "sim-server"), "--world", self.world, *args],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            start_new_session=True, env={**os.environ, "RUST_LOG": "info", "NO_COLOR": "1"},
        )
        self.lines = []
        self.said = threading.Condition()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.proc.stderr:
            with self.said:
                self.lines.append(line)
                self.said.notify_all()

    def wait_line(self, needle, timeout=30):
        """The first log line holding `needle`, waiting up to `timeout` s."""
        found = lambda: next((l for l in self.lines if needle in l), None)
        with self.said:
            if not self.said.wait_for(found, timeout):
                raise AssertionError(f"the server never said {needle!r}:\n{''.join(self.lines)}")
            return found()

    def client(self, **kwargs):
        return simbus.connect(self.world, timeout=10.0, **kwargs)

    def sim_client(self, *args, **kwargs):
        """`sim-client --world <this world> ARGS` as a child process."""
        return subprocess.Popen(
            [os.path.join(BIN, "sim-client"), "--world", self.world, *args],
            start_new_session=True, **kwargs,
        )

    def stop(self):
        self.proc.kill()
        self.proc.wait()
        self.reader.join()


@pytest.fixture
def server(request):
    """`server(*ARGS)` starts a SimbusServer with those sim-server flags;
    every one started is killed and reaped after the test."""
    started = []
    tag = request.node.name[:20].replace("[", "-").replace("]", "")

    def start(*args, world=None):
        started.append(SimbusServer(*args, tag=tag, world=world))
        return started[-1]

    yield start
    for s in started:
        s.stop()


def frame_at(client, frame_id):
    """Frame `frame_id` (skipping older ones), its actors copied."""
    while True:
        with client.wait_for_frame(timeout=10) as frame:
            if frame.frame >= frame_id:
                assert frame.frame == frame_id
                return frame.copy()
