"""Traffic lights from Python against a real server on the town: every
frame holds its 16 lights and 16 signs, a junction's lights take turns in
simulation time (`simbus.traffic_lights` reads them), the light commands
act and read back, a semantic camera sees a light as a traffic light, and
bad light commands are refused and change nothing."""

import numpy as np

import simbus

from simbus_support import frame_at, server  # noqa: F401 (a fixture)

LIGHT, SIGN = 7, 8  # ActorKind::TrafficLight, TrafficSign


def test_the_towns_lights_take_turns_and_obey_their_commands(server):
    client = server("--scene", "town").client()
    with client.ticker(delta_seconds=0.05) as ticker:
        # The lights ran with the world before this ticker took it: start
        # their cycles now.
        client.apply_batch_sync([simbus.ResetTrafficLights()])
        first = ticker.tick()
        frame = frame_at(client, first)
        kinds = frame.actors["kind"]
        assert (kinds == LIGHT).sum() == 16 and (kinds == SIGN).sum() == 16
        lights = simbus.traffic_lights(frame)
        states = sorted(state for state, _, _ in lights.values())
        assert states.count("green") == 4 and states.count("red") == 12
        # The lowest id of each junction is its first pole (the town's
        # lights are placed junction by junction, pole by pole).
        ids = sorted(lights)
        groups = [ids[i:i + 4] for i in range(0, 16, 4)]
        assert all(lights[g[0]][0] == "green" for g in groups)

        for _ in range(199):
            last = ticker.tick()
        lights = simbus.traffic_lights(frame_at(client, last))
        assert [lights[a][0] for a in groups[0]] == ["yellow", "red", "red", "red"]
        assert lights[groups[0][0]][1] == 0.0  # its phase just began

        light = groups[0][2]
        results = client.apply_batch_sync([
            simbus.SetTrafficLightState(light, "green"),
            simbus.FreezeTrafficLights(True),
            simbus.SetTrafficLightTimes(light, green=1.5, red=0.0),
        ])
        assert [r.status for r in results] == ["ok"] * 3
        for _ in range(100):
            last = ticker.tick()
        lights = simbus.traffic_lights(frame_at(client, last))
        assert [lights[a][0] for a in groups[0]] == ["yellow", "red", "green", "red"]
        assert all(frozen for _, _, frozen in lights.values())

        client.apply_batch_sync([simbus.FreezeTrafficLights(False),
                                 simbus.ResetTrafficLights(groups[0][1])])
        last = ticker.tick()
        lights = simbus.traffic_lights(frame_at(client, last))
        assert [lights[a][0] for a in groups[0]] == ["green", "red", "red", "red"]
        assert not any(frozen for _, _, frozen in lights.values())

        # Bad input: refused, nothing changed.
        sign = int(frame.actors["id"][kinds == SIGN][0])
        results = client.apply_batch_sync([
            simbus.SetTrafficLightState(sign, "red"),
            simbus.SetTrafficLightTimes(light, green=-1.0),
            simbus.SetTrafficLightState(10**9, "red"),
            simbus.DestroyActor(light),
            simbus.SetTransform(sign, (0.0, 5.0, 0.0)),
        ])
        assert [r.status for r in results] == [
            "not_a_traffic_light", "invalid_argument", "unknown_actor",
            "static_actor", "static_actor"]
        last = ticker.tick()
        after = frame_at(client, last)
        assert (after.actors["kind"] == LIGHT).sum() == 16


def test_light_commands_read_back_and_bad_states_raise(server):
    assert repr(simbus.SetTrafficLightState(5, "red")) == "SetTrafficLightState(5, 'red')"
    assert repr(simbus.SetTrafficLightTimes(5, green=2.0)) == (
        "SetTrafficLightTimes(5, green=2.0, yellow=None, red=None)")
    assert repr(simbus.FreezeTrafficLights(True)) == "FreezeTrafficLights(True, actor_id=0)"
    assert repr(simbus.ResetTrafficLights()) == "ResetTrafficLights(actor_id=0)"
    try:
        simbus.SetTrafficLightState(5, "blue")
    except ValueError as e:
        assert "unknown light state 'blue'" in str(e)
    else:
        raise AssertionError("a blue light was accepted")


def test_a_semantic_camera_sees_a_light_as_a_traffic_light(server):
    client = server("--scene", "town").client()
    with client.ticker(delta_seconds=0.05) as ticker:
        first = ticker.tick()
        frame = frame_at(client, first)
        light = frame.actors[frame.actors["kind"] == LIGHT][0]
        x, y, z = (float(v) for v in light["position"])
        # The light's +X is the way its traffic drives: a camera 5 m back
        # along it, turned as the light is, looks at its head.
        q = [float(v) for v in light["rotation"]]
        forward = (1 - 2 * (q[1] ** 2 + q[2] ** 2), 2 * (q[0] * q[1] + q[3] * q[2]),
                   2 * (q[0] * q[2] - q[3] * q[1]))
        at = (x - 5 * forward[0], y, z - 5 * forward[2])
        camera = client.spawn_sensor("semantic", at=at, rotation=q, width=64, height=48, fov=60.0)
        ticker.tick()
        with camera.read(timeout=10) as capture:
            tags = capture.array[..., 2]
            assert (tags == 7).sum() > 20, np.unique(tags)
            del tags
