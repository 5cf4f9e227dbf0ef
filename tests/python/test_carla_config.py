"""What CARLA's `PythonAPI/util/config.py` asks of a server, asked of the
gateway with CARLA 0.9.16's own client, and the answers config.py prints
checked: `--delta-seconds`, `--fps` (and 0 for a variable step),
`--no-sync`, `--rendering` / `--no-rendering`, `--inspect`, `--list`,
`-b FILTER`, `-m SCENE` and `-r`.

Each `run` is one invocation of config.py as that script makes it: a client
of its own with one worker thread and a 10 s timeout, the world it works on
(the current one, or one `-m` loads or `-r` reloads), that world's settings
read, changed by the options and applied, changed or not."""

import re

import carla
import pytest


def run(gateway, change=None, world_of=None):
    """One config.py invocation against `gateway`; returns its client, its
    world and the frame `apply_settings` answered."""
    client = carla.Client("127.0.0.1", gateway.port, worker_threads=1)
    client.set_timeout(10.0)
    world = world_of(client) if world_of else client.get_world()
    settings = world.get_settings()
    if change:
        change(settings)
    return client, world, world.apply_settings(settings)


def setting(**values):
    """A `change` for `run` that sets the named settings."""
    def change(settings):
        for name, value in values.items():
            setattr(settings, name, value)
    return change


def frame_rate(delta):
    """The frame rate as `--inspect` shows it."""
    if delta is None:
        return "variable"
    return f"{1000.0 * delta:.2f} ms ({int(1.0 / delta)} FPS)"


WEATHER_PRESETS = [name for name in dir(carla.WeatherParameters) if re.fullmatch("[A-Z].+", name)]
ACTOR_KINDS = ["spectator", "static.*", "traffic.*", "vehicle.*", "walker.*"]


def inspect(client):
    """The calls of `--inspect` after its run, and what it prints from
    their answers."""
    world = client.get_world()
    elapsed = world.get_snapshot().timestamp.elapsed_seconds
    actors = world.get_actors()
    settings = world.get_settings()
    weather = world.get_weather()
    return {
        "version": client.get_server_version(),
        "map": world.get_map().name,
        "weather": next((name for name in WEATHER_PRESETS
                         if weather == getattr(carla.WeatherParameters, name)), "Custom"),
        "elapsed": elapsed,
        "frame rate": frame_rate(settings.fixed_delta_seconds),
        "rendering": not settings.no_rendering_mode,
        "sync mode": settings.synchronous_mode,
        "actors": len(actors),
        "kinds": {kind: len(actors.filter(kind)) for kind in ACTOR_KINDS},
        "type ids": [actor.type_id for actor in actors],
    }


def test_the_settings_options_change_what_inspect_shows(gateway):
    holder = gateway.client().get_world()
    # --delta-seconds 0.05
    _, world, frame = run(gateway, setting(fixed_delta_seconds=0.05))
    assert isinstance(frame, int) and frame >= 0
    assert world.get_settings().fixed_delta_seconds == 0.05
    assert frame_rate(holder.get_settings().fixed_delta_seconds) == "50.00 ms (20 FPS)"
    # --fps 10
    run(gateway, setting(fixed_delta_seconds=1.0 / 10))
    assert holder.get_settings().fixed_delta_seconds == 0.1
    # --no-sync, from another connection than the one that entered sync.
    settings = holder.get_settings()
    settings.synchronous_mode = True
    holder.apply_settings(settings)
    assert holder.get_settings().synchronous_mode is True
    run(gateway, setting(synchronous_mode=False))
    assert holder.get_settings().synchronous_mode is False
    # --no-rendering, then --inspect.
    run(gateway, setting(no_rendering_mode=True))
    client, _, _ = run(gateway)
    shown = inspect(client)
    assert shown["version"] == "0.9.16"
    assert shown["map"] == "default"
    assert shown["weather"] in WEATHER_PRESETS + ["Custom"]
    assert shown["elapsed"] > 0.0
    assert shown["frame rate"] == "100.00 ms (10 FPS)"
    assert (shown["rendering"], shown["sync mode"]) == (False, False)
    assert shown["actors"] == len(shown["type ids"]) > 0
    for kind in ACTOR_KINDS:
        prefix = kind.rstrip("*")
        expected = sum(1 for type_id in shown["type ids"]
                       if (type_id.startswith(prefix) if kind.endswith("*") else type_id == kind))
        assert shown["kinds"][kind] == expected, (kind, shown)
    assert shown["kinds"]["vehicle.*"] > 0, shown
    # --rendering
    client, _, _ = run(gateway, setting(no_rendering_mode=False))
    assert inspect(client)["rendering"] is True
    # --fps 0: a variable step, which config.py sets as None.
    client, _, _ = run(gateway, setting(fixed_delta_seconds=None))
    assert inspect(client)["frame rate"] == "variable"


def test_list_names_the_scenes_and_blueprints_filter(gateway):
    # --list
    client, _, _ = run(gateway)
    maps = client.get_available_maps()
    assert {"default", "empty", "boxes:100"} <= set(maps), maps
    # -b 'sensor.*'
    _, world, _ = run(gateway)
    ids = sorted(bp.id for bp in world.get_blueprint_library().filter("sensor.*"))
    assert ids == ["sensor.camera.cosmos_visualization", "sensor.camera.depth",
                   "sensor.camera.dvs", "sensor.camera.instance_segmentation",
                   "sensor.camera.normals", "sensor.camera.optical_flow",
                   "sensor.camera.rgb", "sensor.camera.semantic_segmentation",
                   "sensor.lidar.ray_cast", "sensor.lidar.ray_cast_semantic",
                   "sensor.other.collision", "sensor.other.gnss", "sensor.other.imu",
                   "sensor.other.lane_invasion", "sensor.other.obstacle", "sensor.other.radar"]
    # -b '*'
    everything = {bp.id for bp in world.get_blueprint_library().filter("*")}
    assert set(ids) < everything and "static.prop.box" in everything


def test_map_options_load_and_reload_scenes_as_new_episodes(gateway):
    before = gateway.client().get_world()
    assert before.get_actors().filter("vehicle.*"), "the default scene has vehicles"
    run(gateway, setting(fixed_delta_seconds=0.02))
    # -m empty: a new episode of the other scene, with the default settings
    # (`load_world` resets them, as in CARLA).
    _, world, _ = run(gateway, world_of=lambda client: client.load_world("empty"))
    assert world.id != before.id
    assert world.get_map().name == "empty"
    assert gateway.client().get_world().get_map().name == "empty"
    assert len(world.get_actors().filter("vehicle.*")) == 0
    assert world.get_settings().fixed_delta_seconds is None
    # -r: a new episode of the same scene, the settings reset too.
    run(gateway, setting(fixed_delta_seconds=0.02))
    _, reloaded, _ = run(gateway, world_of=lambda client: client.reload_world())
    assert reloaded.id not in (before.id, world.id)
    assert reloaded.get_map().name == "empty"
    assert reloaded.get_settings().fixed_delta_seconds is None
