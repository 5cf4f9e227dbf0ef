"""The spectator, as CARLA 0.9.16's own client sees it through the gateway:
`world.get_spectator()` is one pose-only actor per gateway (type id
`spectator`, the same id for every client), `set_transform` moves it and
the next world state carries the pose back, and moving it changes nothing
else in the world (no simbus body)."""

import carla
import pytest


def sync(world, delta=0.05):
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = delta
    world.apply_settings(settings)


def pose(transform):
    """A transform as a tuple (metres, degrees)."""
    l, r = transform.location, transform.rotation
    return (l.x, l.y, l.z, r.pitch, r.yaw, r.roll)


def close(a, b):
    return all(x == pytest.approx(y, abs=1e-3) for x, y in zip(a, b, strict=True))


WHERE = carla.Transform(carla.Location(x=12.5, y=-3.25, z=40.0),
                        carla.Rotation(pitch=-30.0, yaw=75.0, roll=2.5))


def others(world):
    """The world's actors but the spectator: id and pose."""
    return sorted((a.id, a.type_id, pose(a.get_transform()))
                  for a in world.get_actors() if a.type_id != "spectator")


def test_get_spectator_is_one_actor_of_type_spectator_for_every_client(gateway):
    first = gateway.client().get_world()
    second = gateway.client().get_world()
    spectator = first.get_spectator()
    assert spectator.type_id == "spectator"
    assert second.get_spectator().id == spectator.id
    first.wait_for_tick()
    listed = [a for a in first.get_actors() if a.type_id == "spectator"]
    assert [a.id for a in listed] == [spectator.id]
    simbus = [a.id for a in first.get_actors() if a.type_id != "spectator"]
    assert simbus and spectator.id not in simbus


def test_set_transform_round_trips_after_a_tick(gateway):
    client = gateway.client()
    world = client.get_world()
    sync(world)
    spectator = world.get_spectator()
    spectator.set_transform(WHERE)
    world.tick()
    assert close(pose(spectator.get_transform()), pose(WHERE)), pose(spectator.get_transform())
    location = spectator.get_location()
    assert close((location.x, location.y, location.z), (12.5, -3.25, 40.0))
    assert close(pose(world.get_snapshot().find(spectator.id).get_transform()), pose(WHERE))
    spectator.set_location(carla.Location(x=1.0, y=2.0, z=3.0))
    world.tick()
    assert close(pose(spectator.get_transform()), (1.0, 2.0, 3.0, -30.0, 75.0, 2.5))


def seen_by(world, spectator_id):
    """The spectator's poses in `world`'s next frames, up to the first at
    WHERE (frames already on their way may carry the old pose)."""
    seen = []
    for _ in range(20):
        seen.append(pose(world.wait_for_tick().find(spectator_id).get_transform()))
        if close(seen[-1], pose(WHERE)):
            break
    return seen


def test_set_transform_shows_in_a_later_frame_for_every_client_in_asynchronous_mode(gateway):
    world = gateway.client().get_world()
    other = gateway.client().get_world()
    spectator = world.get_spectator()
    spectator.set_transform(WHERE)
    for w in (world, other):
        seen = seen_by(w, spectator.id)
        assert close(seen[-1], pose(WHERE)), seen
    assert close(pose(spectator.get_transform()), pose(WHERE))
    assert close(pose(other.get_spectator().get_transform()), pose(WHERE))


def test_the_spectator_has_no_body_to_destroy(gateway, capfd):
    world = gateway.client().get_world()
    spectator = world.get_spectator()
    assert spectator.destroy() is False
    assert "the spectator has no body" in capfd.readouterr().err
    assert world.get_spectator().id == spectator.id


def run(gateway, move_spectator):
    """Sync, reload, 30 ticks; the spectator moved before each tick if
    asked. The frame and the other actors' poses after."""
    client = gateway.client()
    world = client.get_world()
    sync(world)
    world = client.reload_world(False)
    spectator = world.get_spectator()
    # The new episode's first frame, so both runs read their actors from it.
    world.tick()
    before = others(world)
    for i in range(30):
        if move_spectator:
            spectator.set_transform(carla.Transform(carla.Location(x=float(i), z=5.0 + i)))
        world.tick()
    after = others(world)
    assert [a[:2] for a in after] == [a[:2] for a in before]
    return world.get_snapshot().frame, after


def test_moving_the_spectator_changes_nothing_else(gateway_pair):
    a, b = gateway_pair
    frame_a, moved = run(a, True)
    frame_b, still = run(b, False)
    assert frame_a == frame_b
    assert moved
    assert moved == still
