"""Fixtures for the CARLA gateway tests: each test gets its own sim-server
and carla-gateway on a unique world and free ports, killed after it."""

import os
import signal
import socket
import subprocess
import time

import pytest

BIN = os.environ["SIMBUS_BIN_DIR"]


def free_port_pair():
    """Two consecutive free ports (RPC and streaming)."""
    for _ in range(100):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port >= 65534:
            continue
        try:
            with socket.socket() as a, socket.socket() as b:
                a.bind(("127.0.0.1", port))
                b.bind(("127.0.0.1", port + 1))
            return port
        except OSError:
            continue
    raise RuntimeError("no free port pair")


class Gateway:
    def __init__(self, world, port, procs):
        self.world = world
        self.port = port
        self.procs = procs

    def client(self, timeout=10.0):
        import carla

        client = carla.Client("127.0.0.1", self.port)
        client.set_timeout(timeout)
        return client

    def sim_client(self, *args):
        return subprocess.run(
            [os.path.join(BIN, "sim-client"), "--world", self.world, *args],
            capture_output=True, text=True, timeout=60,
        )


def wait_line(proc, needle, timeout=30):
    deadline = time.time() + timeout
    while time.time() < deadline:
        line = proc.stdout.readline()
        if needle in line:
            return line
        if not line and proc.poll() is not None:
            break
    raise RuntimeError(f"{proc.args} never said {needle!r}")


def start(world, server_args, procs):
    """Starts a sim-server on `world` and a gateway in front of it; both
    are appended to `procs` (killed by the caller)."""
    port = free_port_pair()
    server = subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", world, *server_args],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    procs.append(server)
    gateway = subprocess.Popen(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "10", "carla-gateway", "--port", str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, start_new_session=True,
    )
    procs.append(gateway)
    wait_line(gateway, "carla-gateway:")
    return Gateway(world, port, procs)


def kill_all(procs):
    for proc in reversed(procs):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=10)


def world_name(request, suffix=""):
    name = f"py-{os.getpid()}-{request.node.name[:40]}{suffix}"
    return name.replace("[", "-").replace("]", "")


@pytest.fixture
def gateway(request):
    procs = []
    try:
        yield start(world_name(request), getattr(request, "param", []), procs)
    finally:
        kill_all(procs)


@pytest.fixture
def gateway_pair(request):
    """Two independent server + gateway pairs on the same scene."""
    procs = []
    try:
        args = getattr(request, "param", [])
        yield start(world_name(request, "-a"), args, procs), start(world_name(request, "-b"), args, procs)
    finally:
        kill_all(procs)
