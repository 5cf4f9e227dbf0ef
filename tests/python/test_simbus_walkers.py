"""Walkers from Python against a real server: one spawned with its feet in
the ground stands on it, walks where `ApplyWalkerControl` points it at its
speed, is a walker (kind 6) with its size in every frame, a depth camera
and a semantic camera see it as a pedestrian, and bad walker commands
raise and change nothing."""

import numpy as np
import pytest

import simbus

from simbus_support import frame_at, server  # noqa: F401 (a fixture)

WALKER = 6  # ActorKind::Walker
PEDESTRIANS = 12  # CARLA's semantic tag


def actor(frame, actor_id):
    rows = frame.actors[frame.actors["id"] == actor_id]
    assert len(rows) == 1, f"actor {actor_id} in frame {frame.frame}"
    return rows[0]


def test_a_walker_stands_walks_and_is_seen_as_a_pedestrian(server):
    client = server("--scene", "flat").client()
    with client.ticker(delta_seconds=0.05) as ticker:
        # Its centre on the ground's surface: it stands on it.
        walker = client.spawn("walker", at=(0.0, 0.0, 0.0))
        camera = client.spawn_sensor(
            "semantic", at=(-6.0, 1.0, 0.0), width=64, height=48, fov=60.0)
        for _ in range(5):
            last = ticker.tick()
        standing = actor(frame_at(client, last), walker)
        assert standing["kind"] == WALKER
        assert tuple(standing["extent"]) == (np.float32(0.25), np.float32(0.9), np.float32(0.25))
        assert abs(standing["position"][1] - 0.9) < 0.06
        with camera.read(timeout=10) as capture:
            tags = capture.array[..., 2]  # CARLA's tag in red
            assert (tags == PEDESTRIANS).sum() > 20, np.unique(tags)
            del tags

        client.apply_batch_sync([simbus.ApplyWalkerControl(walker, (0.0, 0.0, 1.0), speed=1.5)])
        start = last
        for _ in range(20):
            last = ticker.tick()
        walked = actor(frame_at(client, last), walker)
        seconds = (last - start) * 0.05
        assert abs(walked["position"][2] - 1.5 * seconds) < 0.15, walked
        assert abs(walked["linear_velocity"][2] - 1.5) < 0.05, walked
        assert abs(walked["position"][1] - 0.9) < 0.06


def test_walker_commands_read_back_and_bad_ones_are_refused(server):
    control = simbus.ApplyWalkerControl(5, [1, 0, 0], speed=2.0, jump=True)
    assert (control.actor_id, control.direction, control.speed, control.jump) == (
        5, (1.0, 0.0, 0.0), 2.0, True)
    assert repr(control) == "ApplyWalkerControl(5, direction=(1.0, 0.0, 0.0), speed=2.0, jump=True)"
    spawn = simbus.SpawnActor("walker", (1, 2, 3))
    assert (spawn.kind, spawn.at) == ("walker", (1.0, 2.0, 3.0))

    client = server("--scene", "flat").client()
    with client.ticker(delta_seconds=0.05) as ticker:
        walker = client.spawn("walker", at=(0.0, 0.9, 0.0))
        box = client.spawn("box", at=(5.0, 0.5, 0.0))
        results = client.apply_batch_sync([
            simbus.ApplyWalkerControl(walker, (1.0, 0.0, 0.0), speed=25.0),
            simbus.ApplyWalkerControl(box, (1.0, 0.0, 0.0), speed=1.0),
            simbus.SpawnActor("walker", (9.0, 0.9, 0.0), radius=0.3, half_height=0.2),
        ])
        assert [r.status for r in results] == [
            "invalid_argument", "not_a_walker", "invalid_argument"]
        with pytest.raises(simbus.CommandError, match="invalid argument"):
            client.spawn("walker", at=(9.0, 0.9, 0.0), half_height=9.0)
        last = ticker.tick()
        assert abs(actor(frame_at(client, last), walker)["position"][0]) < 1e-4
