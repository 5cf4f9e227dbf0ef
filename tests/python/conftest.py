"""Fixtures for the CARLA gateway tests: each test gets its own sim-server
and carla-gateway on a unique world and free ports (`--port 0`: the
gateway picks them and names them), killed after it."""

import hashlib
import json
import os
import signal
import socket
import subprocess
import time

import msgpack

import pytest

BIN = os.environ["SIMBUS_BIN_DIR"]


class Gateway:
    def __init__(self, world, port, streaming_port, procs):
        self.world = world
        self.port = port
        self.streaming_port = streaming_port
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


class Raw:
    """A raw msgpack-RPC connection, for what the carla module never sends."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.settimeout(10)
        self.unpacker = msgpack.Unpacker(raw=False)
        self.msgid = 0

    def call(self, method, *args):
        self.msgid += 1
        self.sock.sendall(msgpack.packb([0, self.msgid, method, [[False], *args]]))
        while True:
            for message in self.unpacker:
                assert message[0] == 1 and message[1] == self.msgid, message
                return message[3]
            data = self.sock.recv(65536)
            assert data, "the gateway closed the connection"
            self.unpacker.feed(data)


def synced(gateway, delta=0.05):
    """A client of `gateway` and its world, in synchronous mode with a
    `delta` step (this connection ticks)."""
    client = gateway.client()
    world = client.get_world()
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = delta
    world.apply_settings(settings)
    return client, world


def wait_line(proc, needle, timeout=30):
    deadline = time.time() + timeout
    while time.time() < deadline:
        line = proc.stdout.readline()
        if needle in line:
            return line
        if not line and proc.poll() is not None:
            break
    raise RuntimeError(f"{proc.args} never said {needle!r}")


def start(world, server_args, procs, gateway_args=(), log=subprocess.DEVNULL, env=None,
          server_log=subprocess.DEVNULL):
    """Starts a sim-server on `world` and a gateway in front of it (with
    `gateway_args`, its log to `log`: a file, or subprocess.STDOUT to read
    it with the ports), on two free ports the gateway picks and prints; both
    are appended to `procs` (killed by the caller). The gateway's process
    is the Gateway's `proc`. The server logs to `server_log` (a file);
    `env` is added to both processes' environment."""
    server = subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", world, *server_args],
        stdout=subprocess.DEVNULL, stderr=server_log, start_new_session=True,
        env=None if env is None else {**os.environ, **env},
    )
    procs.append(server)
    wait_until_up(world, server)
    gateway = subprocess.Popen(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "10",
         "carla-gateway", "--port", "0", "--json", *gateway_args],
        stdout=subprocess.PIPE, stderr=log, text=True, start_new_session=True,
        env=None if env is None else {**os.environ, **env},
    )
    procs.append(gateway)
    listening = json.loads(wait_line(gateway, '"streaming_port"'))
    started = Gateway(world, listening["port"], listening["streaming_port"], procs)
    started.proc = gateway
    return started


def wait_until_up(world, server, timeout=60):
    """Waits until the server of `world` answers `status`: the gateway's
    first call waits only 2 s for a server (CARLA's client fails fast on a
    world with none), and a server still starting on a loaded machine can
    take longer."""
    up = subprocess.run(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", str(timeout), "status"],
        capture_output=True, text=True, timeout=timeout + 30,
    )
    if up.returncode != 0:
        exited = server.poll()
        raise RuntimeError(f"the server of {world} did not come up (exit status {exited}): {up.stderr}")


def kill_all(procs):
    for proc in reversed(procs):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=10)


def world_name(request, suffix=""):
    """A world of this test's own: the test's name cut to fit, and a hash
    of its whole id, so parametrized tests (whose names differ only at the
    end) never share a world."""
    digest = hashlib.sha1(request.node.nodeid.encode()).hexdigest()[:8]
    name = f"py-{os.getpid()}-{digest}-{request.node.name[:32]}{suffix}"
    return name.replace("[", "-").replace("]", "")


@pytest.fixture
def gateway(request):
    """A server + gateway pair; parametrized (indirect) with the server's
    arguments, or {"server": [...], "gateway": [...]}."""
    param = getattr(request, "param", [])
    server_args, gateway_args = ((param.get("server", []), param.get("gateway", []))
                                 if isinstance(param, dict) else (param, []))
    procs = []
    try:
        yield start(world_name(request), server_args, procs, gateway_args=gateway_args)
    finally:
        kill_all(procs)


class Logs:
    """The server's and the gateway's logs of a test, in its tmp_path."""

    def __init__(self, directory):
        self.server = directory / "sim-server.log"
        self.gateway = directory / "carla-gateway.log"

    def tails(self, lines=60):
        """The last `lines` lines of each log, for a failure's message."""
        parts = []
        for path in (self.server, self.gateway):
            text = path.read_text(errors="replace").splitlines() if path.exists() else []
            parts.append(f"--- {path.name} (last {lines} of {len(text)} lines)\n"
                         + "\n".join(text[-lines:]))
        return "\n".join(parts)


@pytest.fixture
def logged_gateway(request, tmp_path):
    """A `gateway` whose server and gateway log (`RUST_LOG=debug`, no
    colour) into the test's tmp_path: `gateway.logs.tails()` for the
    failure message of a test that fails seldom, so it says where the
    time went."""
    procs = []
    logs = Logs(tmp_path)
    env = {"RUST_LOG": "debug", "NO_COLOR": "1"}
    with open(logs.server, "w") as server_log, open(logs.gateway, "w") as gateway_log:
        try:
            started = start(world_name(request), getattr(request, "param", []), procs,
                            log=gateway_log, env=env, server_log=server_log)
            started.logs = logs
            yield started
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
