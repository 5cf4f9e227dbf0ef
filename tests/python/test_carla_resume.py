"""CARLA's own client rides through a simbus server restart behind the
gateway: the server journals (`--journal DIR`), is killed with SIGKILL
between two ticks, and `sim-server --resume DIR` brings the world back.
The script does not notice beyond a slower `world.tick()`: the next tick
steps the frame after the last one it was answered for, the world keeps
its CARLA episode id (the gateway keys episodes by the run the resumed
server continues, not by the server's pid), the vehicle and the camera
keep their ids, and the camera's listener goes on receiving images.
A fresh server on the world (no resume) is a new episode, as in CARLA."""

import json
import os
import queue
import signal
import subprocess

import carla

from conftest import BIN, Raw, kill_all, start, synced, world_name

CAPTURE_WAIT = 10.0


def kill(proc):
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)


def frame_captured(images, frame):
    """Waits for the image of `frame` among the listener's `images`."""
    while True:
        got = images.get(timeout=CAPTURE_WAIT)
        if got >= frame:
            return got


def test_a_carla_script_ticks_on_through_a_server_resumed_from_its_journal(request, tmp_path):
    procs = []
    journal = str(tmp_path / "journal")
    try:
        gateway = start(world_name(request), ["--journal", journal], procs)
        client, world = synced(gateway)
        episode = world.id
        library = world.get_blueprint_library()
        vehicle = world.spawn_actor(
            library.find("vehicle.simbus.car"), world.get_map().get_spawn_points()[0])
        camera_bp = library.find("sensor.camera.depth")
        camera_bp.set_attribute("image_size_x", "32")
        camera_bp.set_attribute("image_size_y", "24")
        camera = world.spawn_actor(
            camera_bp, carla.Transform(carla.Location(x=-6.0, z=3.0)), attach_to=vehicle)
        images = queue.Queue()
        camera.listen(lambda image: images.put(image.frame))
        vehicle.apply_control(carla.VehicleControl(throttle=0.6))
        ticked = [world.tick() for _ in range(10)]
        assert frame_captured(images, ticked[-1]) == ticked[-1]

        kill(procs[0])
        resumed = subprocess.Popen(
            [os.path.join(BIN, "sim-server"), "--resume", journal],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        procs.append(resumed)
        up = gateway.sim_client("--timeout", "30", "status")
        assert up.returncode == 0, up.stderr
        assert "resumed the run of pid" in up.stdout, up.stdout

        after = [world.tick() for _ in range(5)]
        assert after == list(range(ticked[-1] + 1, ticked[-1] + 6)), (ticked, after)
        assert frame_captured(images, after[-1]) == after[-1]
        assert world.id == episode
        assert episode_id(Raw(gateway.port)) == episode
        ids = {actor.id for actor in world.get_actors()}
        assert {vehicle.id, camera.id} <= ids
        assert vehicle.is_alive and camera.is_alive
        assert world.get_snapshot().frame == after[-1]
        camera.stop()
    finally:
        kill_all(procs)


def episode_id(raw):
    """The episode id the gateway's `get_episode_info` answers."""
    result = raw.call("get_episode_info")
    assert result[0][0] == 1, result
    return result[0][1][0]


def restart_fresh(gateway, procs):
    """Kills the gateway's server and starts a fresh one on its world (no
    resume); returns it once it answers."""
    kill(procs[0])
    fresh = subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", gateway.world],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    procs.append(fresh)
    up = gateway.sim_client("--timeout", "30", "status")
    assert up.returncode == 0, up.stderr
    return fresh


def test_a_fresh_server_on_the_world_is_a_new_carla_episode(request):
    procs = []
    try:
        gateway = start(world_name(request), [], procs)
        raw = Raw(gateway.port)
        before = episode_id(raw)
        fresh = restart_fresh(gateway, procs)
        assert episode_id(raw) == (fresh.pid << 32) | 1 != before
    finally:
        kill_all(procs)


def test_a_ticker_gives_back_a_fresh_servers_world_and_says_why(request):
    """A fresh server is not the run the script ticked: `world.tick()`
    fails naming the restart, and the fresh world is left without a
    ticker (the gateway's ticker claimed it on its way back and gave it
    back), so another client may tick it."""
    procs = []
    try:
        gateway = start(world_name(request), [], procs)
        client, world = synced(gateway)
        ticked = [world.tick() for _ in range(3)]
        restart_fresh(gateway, procs)
        try:
            frame = world.tick()
        except RuntimeError as e:
            assert "without resuming the world from its journal" in str(e), e
        else:
            raise AssertionError(f"ticked frame {frame} of a fresh server after {ticked}")
        status = gateway.sim_client("status", "--json")
        assert status.returncode == 0, status.stderr
        assert json.loads(status.stdout)["ticker"] is None, status.stdout
    finally:
        kill_all(procs)
