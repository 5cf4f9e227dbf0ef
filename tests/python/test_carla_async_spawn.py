"""Spawn-then-destroy in asynchronous mode with the real `carla` wheel:
CARLA 0.9.16's client drops `actor.destroy()` for an actor no world state
has held yet, so the gateway sends a world state holding a new actor
before it answers the spawn."""

import carla


def test_an_actor_destroyed_right_after_its_spawn_is_gone(gateway):
    client = gateway.client()
    world = client.get_world()
    assert not world.get_settings().synchronous_mode
    blueprint = world.get_blueprint_library().find("static.prop.box")
    before = len(world.get_actors())
    for i in range(5):
        actor = world.spawn_actor(blueprint, carla.Transform(carla.Location(x=20.0 + 2 * i, y=20.0, z=1.0)))
        # The world state holding the actor was sent before the answer;
        # the client reads it on its streaming connection, so whether it
        # has read it when the answer arrives is a race the gateway only
        # shortens. What must hold: the destroy is sent, nothing leaks.
        actor.destroy()
    batch = [carla.command.SpawnActor(blueprint, carla.Transform(carla.Location(x=30.0, y=30.0 + 2 * i, z=1.0)))
             for i in range(3)]
    ids = [r.actor_id for r in client.apply_batch_sync(batch)]
    assert all(ids)
    for actor in world.get_actors(ids):
        actor.destroy()
    # Every one of them is gone from the world the next frames show.
    for _ in range(50):
        world.wait_for_tick(10.0)
        if len(world.get_actors()) == before:
            break
    assert len(world.get_actors()) == before
