"""CARLA's substepping semantics through the gateway, with CARLA 0.9.16's
own client: CARLA's examples set `fixed_delta_seconds = 0.2` with the
default substepping (0.01 s x 10). CARLA accepts that (its client only
warns) and Unreal then runs at most 10 substeps of 0.01 s, so physics
advances 0.1 s per 0.2 s frame. The gateway does the same (the substep rule
`clamp`): the settings are accepted, a free-falling sphere falls exactly as
it does in 0.1 s frames while the timestamps advance twice as far, and the
gateway's log carries CARLA's warning and what it means in numbers."""


import carla
import pytest

from conftest import kill_all, start, synced, world_name

CARLA_WARNING = (
    "synchronous mode and substepping are enabled but the values for the simulation "
    "are not valid. The values should fulfil fixed_delta_seconds <= "
    "max_substep_delta_time * max_substeps. Be very careful about that, the time "
    "deltas are not guaranteed."
)

TICKS = 6


def start_logged(world, log_path, procs):
    """A sim-server on the `empty` scene and a gateway in front of it whose
    log (stderr) goes to `log_path`; both appended to `procs`."""
    with open(log_path, "w") as log:
        return start(world, ["--scene", "empty"], procs, log=log)


@pytest.fixture
def logged_pair(request, tmp_path):
    """Two server + gateway pairs whose gateway logs can be read."""
    procs = []
    try:
        yield [
            (start_logged(world_name(request, f"-{i}"), tmp_path / f"gateway-{i}.log", procs),
             tmp_path / f"gateway-{i}.log")
            for i in range(2)
        ]
    finally:
        kill_all(procs)


def fall(gateway, delta):
    """Synchronous mode with `delta` as CARLA's examples set it, a sphere
    spawned 100 m up, TICKS ticks: the settings read back, and per tick the
    sphere's height and the frame's delta."""
    client, world = synced(gateway, delta)
    applied = world.get_settings()
    blueprint = world.get_blueprint_library().find("static.prop.sphere")
    sphere = world.spawn_actor(blueprint, carla.Transform(carla.Location(x=0.0, y=0.0, z=100.0)))
    heights, deltas = [], []
    for _ in range(TICKS):
        frame = world.tick()
        snapshot = world.get_snapshot()
        assert snapshot.frame == frame
        heights.append(snapshot.find(sphere.id).get_transform().location.z)
        deltas.append(snapshot.timestamp.delta_seconds)
    applied.synchronous_mode = False
    world.apply_settings(applied)
    applied.synchronous_mode = True
    return applied, heights, deltas


def test_a_fifth_of_a_second_frame_falls_as_ten_hundredths_and_carla_is_warned(logged_pair):
    (fifth_gateway, fifth_log), (tenth_gateway, tenth_log) = logged_pair
    applied, fifth, fifth_deltas = fall(fifth_gateway, 0.2)
    # Accepted as CARLA accepts it, with CARLA's default substepping.
    assert applied.synchronous_mode
    assert applied.fixed_delta_seconds == pytest.approx(0.2)
    assert applied.substepping
    assert applied.max_substep_delta_time == pytest.approx(0.01)
    assert applied.max_substeps == 10
    _, tenth, tenth_deltas = fall(tenth_gateway, 0.1)
    # The same fall, height for height, each tick...
    assert fifth == tenth
    assert fifth[-1] < 99.0, fifth
    # ...while the frames' time advanced twice as far.
    assert fifth_deltas == [pytest.approx(0.2)] * TICKS
    assert tenth_deltas == [pytest.approx(0.1)] * TICKS
    # The gateway said what CARLA's client says, and what it means.
    log = fifth_log.read_text()
    assert CARLA_WARNING in log, log
    assert "physics advances 0.100 s per 0.200 s frame (10 substeps of 0.010 s" in log, log
    assert CARLA_WARNING not in tenth_log.read_text()
